"""``workbench calibrate forming``: a forming profile from validations of formed sheets."""

from __future__ import annotations

import json
import sys
from pathlib import Path

from workbench import __version__
from workbench import forming as fm
from workbench.atomic import check_outputs, write_files
from workbench.calibration_forming import (
    calibrate_forming,
    check_distinct_sheets,
    check_same_design,
    profile_picture,
    read_sheet,
)
from workbench.design_dir import design_files
from workbench.jsonfile import recorded_path


def add_parser(s) -> None:
    f = s.add_parser(
        "forming",
        help="a forming profile (how the film really lands) from validations of formed sheets",
        description="Fit a smooth landing field d(p) (print mm: the film point printed at p lands where the design "
        "puts p + d) to the landings `workbench validate` measured, one validation folder per formed sheet; the "
        "sheets' spread is the repeatability. Writes PROFILE.json and its picture PROFILE.png; `workbench design "
        "--forming-profile PROFILE.json` pre-compensates the print with it.",
    )
    f.add_argument("validations", metavar="VALIDATION_DIR", nargs="+", help="one folder per formed sheet")
    f.add_argument("-o", "--output", metavar="PROFILE.json", required=True)
    f.add_argument("--material", help="the film (default: the design's material)")
    f.add_argument("--process", default="thermoforming", help="how the sheets were formed (default thermoforming)")
    f.add_argument(
        "--placement",
        choices=("always", "never", "auto"),
        default="auto",
        help="the sheets' mean film placement (shift and turn) in the print: auto (default: when the sheets show "
        "it beyond their own random placement, F test at 95 %%; random scatter stays out of the profile); always "
        "(unbiased, it adds its standard error to every part); never (the forming station's registration corrects "
        "it). Each sheet's own placement is never part of the profile",
    )
    f.add_argument("-q", "--quiet", action="store_true")
    f.set_defaults(run=run_forming)


def run_forming(args) -> int:
    log = (lambda _m: None) if args.quiet else (lambda m: print(m, file=sys.stderr, flush=True))
    out = Path(args.output)
    folders = [Path(v) for v in args.validations]
    designs: dict = {}  # (each design folder read once)
    sheets = [read_sheet(f, designs) for f in folders]
    check_same_design(sheets)
    check_distinct_sheets(sheets)
    inputs = [*folders, *(f / "validation.json" for f in folders), *(f / "landing.npz" for f in folders)]
    inputs += design_files(sheets[0].design_dir)
    check_outputs(out, out.with_suffix(".png"), inputs=inputs)
    res = calibrate_forming(sheets, args.placement, designs)
    info = sheets[0].design
    base = (info.get("forming") or {}).get("base_print") or info["print"]
    material = dict(info.get("material") or {})
    if args.material:
        material["name"] = args.material
    design_films = info.get("films") or []
    films = []
    for k, r in enumerate(res["films"]):
        films.append(
            {
                "name": r["name"],
                "base_print": {"width_mm": r["size_mm"][0], "height_mm": r["size_mm"][1]},
                **({"material": design_films[k].get("material")} if design_films else {}),
                "field": r["field"].to_dict(),
                "placement": r["placement"],
                **{
                    key: r[key]
                    for key in (
                        "smoothing",
                        "points",
                        "outliers",
                        "cv_rms_mm",
                        "fit_rms_mm",
                        "repeatability_mm",
                        "deformation_repeatability_mm",
                        "measured_share",
                        "measured_share_on_part",
                        "on_part_share",
                        "extrapolated_share",
                        "extrapolated_share_on_part",
                        "max_extrapolation_mm",
                        "d_median_mm",
                        "d_p95_mm",
                        "d_max_mm",
                    )
                },
                "per_sheet": r["per_sheet"],
            }
        )
    profile = {
        "kind": "forming profile",
        "note": (
            "per film, d(p), mm on the film's uncompensated print (x right, y down from its top-left corner): the "
            "film point printed at p lands where the design's conformal map puts p + d(p) (field: the deformation, "
            "the sheets' mean placement taken out); placement: the sheets' mean film placement (shift, turn about "
            "centre_mm), its standard error and spread, and what of it the profile compensates (applied); "
            "repeatability_mm: the sheets' spread about the profile (standard deviation per axis, the random part "
            "no compensation removes; deformation_repeatability_mm: the same, each sheet's placement taken out); "
            "measured_share_on_part: the share of the film that lands on the part within 1 mm of a measured point"
        ),
        "design": {
            **fm.design_identity(info),
            "job_sha256": (info.get("job") or {}).get("sha256"),
            "name": (info.get("job") or {}).get("name"),
            **({} if design_films else {"base_print": {"width_mm": base["width_mm"], "height_mm": base["height_mm"]}}),
            "round": 1 + int((info.get("forming") or {}).get("round", 0)),
        },
        "material": material,
        "process": {"name": args.process},
        "sheets": [
            {
                "validation": recorded_path(Path(s.validation["file"]), out.parent),
                "sha256": s.validation["sha256"],
                "points": int(len(s.p)),
            }
            for s in sheets
        ],
        "films": films,
        "warnings": res["warnings"],
        "picture": out.with_suffix(".png").name,
        "software": {"name": "workbench", "version": __version__},
    }
    reps = [r["repeatability_mm"] for r in res["films"] if r["repeatability_mm"] is not None]
    pic = profile_picture(
        res,
        f"{out.name}: forming profile from {len(sheets)} sheet(s)"
        + (f", repeatability {max(reps):.3f} mm" if reps else ""),
    )
    write_files({out: (json.dumps(profile, indent=1) + "\n").encode(), out.with_suffix(".png"): pic}, inputs=inputs)
    for w in res["warnings"]:
        log(f"warning: {w}")
    for r in res["films"]:
        pl, rep = r["placement"], r["repeatability_mm"]
        se = pl.get("standard_error_mm")
        log(
            (f"{r['name']}: " if len(res["films"]) > 1 else "")
            + f"{len(sheets)} sheet(s), {r['points']} points ({r['outliers']} outliers dropped): deformation |d| "
            f"median {r['d_median_mm']:.3f} p95 {r['d_p95_mm']:.3f} max {r['d_max_mm']:.3f} mm; cross-validated RMS "
            f"{r['cv_rms_mm']:.4f} mm; measured {100 * r['measured_share_on_part']:.1f} % of the film that lands on "
            f"the part ({100 * r['measured_share']:.1f} % of the film as printed); mean placement "
            f"({pl['shift_mm'][0]:.3f}, {pl['shift_mm'][1]:.3f}) mm, {pl['rotation_deg']:.4f}°"
            + (f" ± {se:.3f} mm" if se is not None else "")
            + (
                ""
                if pl.get("systematic") is None
                else ", beyond the sheets' random placement"
                if pl["systematic"]["shift"]
                else ", within the sheets' random placement"
            )
            + (", compensated" if pl["compensated"] else ", not compensated")
            + "; repeatability "
            + (
                f"{rep:.4f} mm per axis ({r['deformation_repeatability_mm']:.4f} mm without the placements)"
                if rep is not None
                else "not measured (one sheet)"
            )
        )
    log(f"wrote {out} and {out.with_suffix('.png')}")
    return 0
