"""``workbench calibrate forming``: a forming profile from validations of formed sheets."""

from __future__ import annotations

import json
import sys
from pathlib import Path

from workbench import __version__
from workbench import forming as fm
from workbench.atomic import check_outputs, write_files
from workbench.calibration_forming import calibrate_forming, check_same_design, profile_picture, read_sheet
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
    f.add_argument("-q", "--quiet", action="store_true")
    f.set_defaults(run=run_forming)


def run_forming(args) -> int:
    log = (lambda _m: None) if args.quiet else (lambda m: print(m, file=sys.stderr, flush=True))
    out = Path(args.output)
    folders = [Path(v) for v in args.validations]
    sheets = [read_sheet(f) for f in folders]
    check_same_design(sheets)
    inputs = [*folders, *(f / "validation.json" for f in folders), *(f / "landing.npz" for f in folders)]
    inputs += design_files(sheets[0].design_dir)
    check_outputs(out, out.with_suffix(".png"), inputs=inputs)
    res = calibrate_forming(sheets)
    info = sheets[0].design
    base = (info.get("forming") or {}).get("base_print") or info["print"]
    material = dict(info.get("material") or {})
    if args.material:
        material["name"] = args.material
    film = {
        "name": "film-1",
        "field": res["field"].to_dict(),
        "smoothing": res["smoothing"],
        "points": res["points"],
        "outliers": res["outliers"],
        "cv_rms_mm": res["cv_rms_mm"],
        "fit_rms_mm": res["fit_rms_mm"],
        "repeatability_mm": res["repeatability_mm"],
        "measured_share": res["measured_share"],
        "measured_share_on_part": res["measured_share_on_part"],
        "extrapolated_share": res["extrapolated_share"],
        "max_extrapolation_mm": res["max_extrapolation_mm"],
        "d_median_mm": res["d_median_mm"],
        "d_p95_mm": res["d_p95_mm"],
        "d_max_mm": res["d_max_mm"],
    }
    profile = {
        "kind": "forming profile",
        "note": (
            "d(p), mm on the uncompensated print (x right, y down from its top-left corner): the film point printed "
            "at p lands where the design's conformal map puts p + d(p); repeatability_mm: the sheets' spread about "
            "the profile (standard deviation per axis, the random part no compensation removes)"
        ),
        "design": {
            **fm.design_identity(info),
            "job_sha256": (info.get("job") or {}).get("sha256"),
            "name": (info.get("job") or {}).get("name"),
            "base_print": {"width_mm": base["width_mm"], "height_mm": base["height_mm"]},
            "round": 1 + int((info.get("forming") or {}).get("round", 0)),
        },
        "material": material,
        "process": {"name": args.process},
        "sheets": [
            {
                "validation": recorded_path(Path(s.validation["file"]), out.parent),
                "sha256": s.validation["sha256"],
                **ps,
            }
            for s, ps in zip(sheets, res["per_sheet"], strict=True)
        ],
        "films": [film],
        "warnings": res["warnings"],
        "picture": out.with_suffix(".png").name,
        "software": {"name": "workbench", "version": __version__},
    }
    rep = res["repeatability_mm"]
    pic = profile_picture(
        res,
        f"{out.name}: forming profile from {len(sheets)} sheet(s); |d| p95 {res['d_p95_mm']:.2f} mm"
        + (f", repeatability {rep:.3f} mm" if rep is not None else ""),
    )
    write_files({out: (json.dumps(profile, indent=1) + "\n").encode(), out.with_suffix(".png"): pic}, inputs=inputs)
    for w in res["warnings"]:
        log(f"warning: {w}")
    log(
        f"{len(sheets)} sheet(s), {res['points']} points ({res['outliers']} outliers dropped): |d| median "
        f"{res['d_median_mm']:.3f} p95 {res['d_p95_mm']:.3f} max {res['d_max_mm']:.3f} mm; cross-validated RMS "
        f"{res['cv_rms_mm']:.4f} mm; measured {100 * res['measured_share']:.1f} % of the film "
        f"({100 * res['measured_share_on_part']:.1f} % of what lands on the part); repeatability "
        + (f"{rep:.4f} mm" if rep is not None else "not measured (one sheet)")
        + f"; wrote {out} and {out.with_suffix('.png')}"
    )
    return 0
