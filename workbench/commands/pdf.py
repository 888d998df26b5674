"""``workbench pdf``: the print of a design as a PDF at true physical scale, with marks."""

from __future__ import annotations

import sys
from pathlib import Path

import cv2
import numpy as np

from workbench import schemas
from workbench.atomic import check_output_dir, check_outputs, write_files, write_folder
from workbench.design_dir import design_files, read_design_json
from workbench.errors import UsageError, WorkbenchError
from workbench.image_file import imread
from workbench.mesh.io import read_mesh
from workbench.mesh.topology import boundary_loops
from workbench.options import Number
from workbench.printing.paper import parse_paper
from workbench.printing.pdf import (
    CUT_SPOT,
    FilmPage,
    PdfxOptions,
    PrinterProfile,
    load_printer_profile,
    print_pdf_pages,
)

MIN_PPI = 150.0


def add_parser(sub) -> None:
    p = sub.add_parser(
        "pdf",
        help="the print of a design as a PDF at true scale, with crop and registration marks",
        description=(
            "Write the print of a design directory as a PDF: the texture at exactly width_mm x height_mm, "
            "a bleed beyond the trim, crop marks at the four corners, registration crosshairs, 100 mm scale "
            "bars along x and y, a 10 mm check square and a line identifying the job. Print it at 100 %% "
            "(actual size). A printer profile pre-compensates the printer's own scale error. The file is a "
            "PDF/X-4 (ISO 15930-7): PDF 1.6, an OutputIntent with the output ICC profile, XMP metadata, fonts "
            "embedded, the print ICC-tagged sRGB (or converted to CMYK with --cmyk), the cut line an "
            "overprinting spot colour."
        ),
    )
    p.add_argument("design", metavar="DESIGN_DIR", help="output directory of workbench design")
    p.add_argument("-o", "--output", metavar="FILE.pdf", help="default prints/<job name>.pdf")
    p.add_argument(
        "--paper", default="auto", help="A4, A3, letter, ..., auto (default: smallest that fits) or WxH in mm"
    )
    p.add_argument("--printer-profile", metavar="FILE", help="printer scale profile (workbench calibrate printer)")
    p.add_argument(
        "--bleed-mm", action=Number, lo=0, hi=50, unit="mm", help="texture beyond the trim (default: the job's, 3 mm)"
    )
    p.add_argument(
        "--margin-mm",
        action=Number,
        lo=0,
        hi=50,
        unit="mm",
        help="free border to the sheet's edge (default: the job's, 10 mm)",
    )
    p.add_argument(
        "--no-cut",
        action="store_true",
        help="leave out the cut line (the film's outline in the spot colour CutContour)",
    )
    p.add_argument(
        "--output-profile",
        metavar="PROFILE.icc",
        help="the output ICC profile of the press or printer (the shop's), carried in the PDF/X OutputIntent "
        "(default: the bundled workbench-coated-pt1.icc, a model of ISO 12647-2 paper type 1 coated offset)",
    )
    p.add_argument(
        "--cmyk",
        action="store_true",
        help="convert the print to CMYK through the output profile (relative colorimetric, black point "
        "compensation) instead of leaving it ICC-tagged sRGB for the RIP; reports the total ink",
    )
    p.add_argument(
        "--max-ink",
        action=Number,
        lo=100,
        hi=400,
        default=300.0,
        metavar="PERCENT",
        help="with --cmyk: the most ink a pixel may carry, C+M+Y+K in percent (default 300)",
    )
    p.add_argument(
        "--cut-spot-name",
        default=CUT_SPOT,
        metavar="NAME",
        help=f"the cut line's spot colour (default {CUT_SPOT}; PerfCutContour to perforate, or your RIP's name)",
    )
    p.add_argument(
        "--min-ppi",
        action=Number,
        lo=0,
        hi=1e6,
        default=MIN_PPI,
        metavar="PPI",
        help="warn when the print's resolution on the part (dpi divided by the film's largest stretch) falls "
        f"below this (default {MIN_PPI:g} ppi)",
    )
    p.add_argument(
        "--pattern",
        choices=("forming",),
        help="forming: the calibration film instead of the print: the film's outline, marks and cut line as the "
        "design prints them, filled with dense random dots; beside the PDF, FILE-design/, the design with the "
        "pattern as its print (its definition in design.json's pattern), to validate photos of the formed film",
    )
    p.add_argument("-q", "--quiet", action="store_true", help="no progress lines")
    p.set_defaults(run=run)


def resolution_warnings(info: dict, min_ppi: float) -> list[str]:
    """Where the film's stretch brings the print's resolution on the part under ``min_ppi``.

    The film stretches by s (3D length / print length) where it is formed over the part:
    a print of d dpi has d / s pixels per inch there. design.json records the stretch's
    area-weighted range, for the whole print and per film; the largest stretch is the
    lowest effective resolution.
    """
    dpi = float(info["print"]["dpi"])
    films = info.get("films") or [{"name": None, "stretch": info.get("stretch")}]
    out = []
    for f in films:
        stretch = (f.get("stretch") or {}).get("max")
        if not isinstance(stretch, int | float) or not stretch > 0:
            continue
        ppi = dpi / stretch
        if ppi < min_ppi:
            where = f"film {f['name']}: " if f.get("name") else ""
            out.append(
                f"{where}the print's {dpi:g} dpi is {ppi:.0f} ppi on the part where the film stretches most "
                f"(x {stretch:.2f}), under {min_ppi:g} ppi: print at {np.ceil(min_ppi * stretch):.0f} dpi or more"
            )
    return out


def load_design(directory: Path) -> tuple[dict, np.ndarray, np.ndarray | None]:
    """design.json and print.png of a design directory, or an error naming what is missing.

    Returns the design's information, the print (rows, cols, 3) uint8 RGB and the
    film mask (rows, cols) bool from the print's alpha channel (None: no alpha, the
    film is the whole rectangle).
    """
    if not directory.is_dir():
        raise WorkbenchError(f"{directory}: no such design directory (run workbench design first)")
    info_path, png_path = directory / "design.json", directory / "print.png"
    for path in (info_path, png_path):
        if not path.is_file():
            raise WorkbenchError(f"{path}: missing; is {directory} the output of workbench design?")
    info = read_design_json(info_path, schemas.DESIGN_PRINT)
    img = imread(png_path)
    if img is None:
        raise WorkbenchError(f"{png_path}: cannot read the print image")
    expected = (info["print"]["height_px"], info["print"]["width_px"])
    if img.shape[:2] != expected:
        raise WorkbenchError(
            f"{png_path}: {img.shape[1]} x {img.shape[0]} px, design.json says {expected[1]} x {expected[0]}"
        )
    if img.ndim != 3 or img.shape[2] not in (3, 4) or img.dtype != np.uint8:
        raise WorkbenchError(f"{png_path}: not an 8-bit RGB or RGBA print")
    film = None if img.shape[2] == 3 else img[:, :, 3] > 127
    if film is not None and not film.any():
        raise WorkbenchError(f"{png_path}: the alpha channel leaves no film")
    return info, cv2.cvtColor(img[:, :, :3], cv2.COLOR_BGR2RGB), film


def film_outline(path: Path) -> np.ndarray | None:
    """The boundary of a design's flat layout (``flat.obj`` or a film's ``flat-NAME.obj``; mm, y up), or None
    when the file is not there."""
    if not path.is_file():
        return None
    V, F = read_mesh(path, solid=False)
    try:
        loops = boundary_loops(F)
    except (KeyError, IndexError, ValueError):  # a boundary that branches: not a manifold
        loops = []
    if len(loops) != 1 or not np.isfinite(V[loops[0]]).all():
        raise WorkbenchError(f"{path}: not the flat layout of a disc (one boundary loop); rerun workbench design")
    return V[loops[0], :2]


def top_edge(directory: Path) -> str:
    """Where the print's top edge goes on the part, "part +y" and the like, from the design's flat layout.

    The linear map from the flat layout (``flat.obj``, mm, y up: the print's top is its +y)
    to the part (``decorated.obj``, the same vertices), fitted over every vertex; the print's
    up direction lands along the mesh axis it is nearest. "" when the layout cannot say
    (the files missing or not matching, or the up direction along no axis within 45°).
    """
    try:
        flat, _ = read_mesh(directory / "flat.obj", solid=False)
        V, _ = read_mesh(directory / "decorated.obj", solid=False)
    except (OSError, WorkbenchError):
        return ""
    if flat.shape != V.shape or len(V) < 3:
        return ""
    A = np.column_stack([flat[:, :2] - flat[:, :2].mean(axis=0), np.ones(len(flat))])
    M, *_ = np.linalg.lstsq(A, V - V.mean(axis=0), rcond=None)
    up = M[1]  # the mesh displacement of one mm up the print
    k = int(np.argmax(np.abs(up)))
    if not np.isfinite(up).all() or abs(up[k]) < np.linalg.norm(up) * np.sqrt(0.5):
        return ""
    return f"part {'+' if up[k] > 0 else '-'}{'xyz'[k]}"


def film_pages(directory: Path, info: dict, pattern: np.ndarray | None = None) -> list[FilmPage]:
    """One page per film of a design with several: its print, outline and label; with ``pattern``
    (the atlas's calibration pattern, RGB), each film's part of it instead of its print."""
    pages = []
    films = info["films"]
    for k, f in enumerate(films):
        try:
            png, flat = directory / f["print"], directory / f["flat"]
            size = (f["height_px"], f["width_px"])
            width_mm, height_mm, name = f["width_mm"], f["height_mm"], f["name"]
        except (KeyError, TypeError) as exc:
            raise WorkbenchError(f"{directory / 'design.json'}: films[{k}]: missing {exc}") from None
        img = imread(png)
        if img is None or img.ndim != 3 or img.shape[:2] != size:
            raise WorkbenchError(f"{png}: missing, unreadable or not {size[1]} x {size[0]} px; rerun workbench design")
        if pattern is not None:
            r0, c0 = f["atlas_px"]
            img = np.dstack([cv2.cvtColor(pattern[r0 : r0 + size[0], c0 : c0 + size[1]], cv2.COLOR_RGB2BGR),
                             img[:, :, 3] if img.shape[2] == 4 else np.full(size, 255, np.uint8)])  # fmt: skip
        outline = film_outline(flat)
        if outline is None:
            raise WorkbenchError(f"{flat}: missing; rerun workbench design")
        pages.append(
            FilmPage(
                rgb=cv2.cvtColor(img[:, :, :3], cv2.COLOR_BGR2RGB),
                width_mm=width_mm,
                height_mm=height_mm,
                outline_mm=outline,
                film=img[:, :, 3] > 127 if img.shape[2] == 4 else None,
                label=f"film {k + 1} of {len(films)}: {name}",
            )
        )
    return pages


def calibration_design(directory: Path, info: dict, film, out: Path) -> tuple[np.ndarray, dict]:
    """The calibration film's print and the files of its design folder (the design's, the print replaced)."""
    import hashlib
    import json

    from workbench.export import png_bytes
    from workbench.printing.pattern import dot_pattern, pattern_for

    pr = info["print"]
    definition = pattern_for(pr["height_px"], pr["width_px"], pr["dpi"])
    rgb = dot_pattern(pr["height_px"], pr["width_px"], pr["dpi"], definition)
    png = png_bytes(rgb if film is None else np.dstack([rgb, np.where(film, 255, 0).astype(np.uint8)]), pr["dpi"])
    full = json.loads((directory / "design.json").read_bytes())
    full["pattern"] = {
        **definition,
        "note": "the forming calibration film (workbench pdf --pattern forming): this print replaces the design's; "
        "the map, views and fixture are the design's",
        "design_json_sha256": hashlib.sha256((directory / "design.json").read_bytes()).hexdigest(),
        "print_sha256": hashlib.sha256(png).hexdigest(),
    }
    files = {}
    for p in design_files(directory)[1:]:
        if p.is_file() and p.name not in ("print.png", "design.json", ".workbench-files"):
            files[out / p.name] = p.read_bytes()
    files[out / "print.png"] = png
    for f in info.get("films") or []:
        # each film's print: its part of the atlas's pattern, its own outline
        r0, c0 = f["atlas_px"]
        own = imread(directory / f["print"])
        if own is None or own.shape[:2] != (f["height_px"], f["width_px"]):
            raise WorkbenchError(f"{directory / f['print']}: missing or not the film's print; rerun workbench design")
        crop = rgb[r0 : r0 + f["height_px"], c0 : c0 + f["width_px"]]
        files[out / f["print"]] = png_bytes(crop if own.shape[2] == 3 else np.dstack([crop, own[:, :, 3]]), pr["dpi"])
    files[out / "design.json"] = (json.dumps(full, indent=2) + "\n").encode()
    return rgb, files


def run(args) -> int:
    log = (lambda _m: None) if args.quiet else (lambda m: print(m, file=sys.stderr, flush=True))
    paper = parse_paper(args.paper)
    profile = load_printer_profile(args.printer_profile) if args.printer_profile else PrinterProfile()
    info, rgb, film = load_design(Path(args.design))
    pr = info["print"]
    job = info["job"]
    name = job.get("name") or Path(args.design).name
    bleed = args.bleed_mm if args.bleed_mm is not None else pr["bleed_mm"]
    margin = args.margin_mm if args.margin_mm is not None else pr["margin_mm"]
    for key, v in (("--bleed-mm", args.bleed_mm), ("--margin-mm", args.margin_mm)):
        # the design's own values are checked where design.json is read
        if v is not None and not (np.isfinite(v) and 0 <= v <= 50):
            raise UsageError(f"{key} {v:g}: must be between 0 and 50 mm")
    if not (np.isfinite(args.max_ink) and 100 <= args.max_ink <= 400):
        raise UsageError(f"--max-ink {args.max_ink:g}: must be between 100 and 400 percent")
    if not (np.isfinite(args.min_ppi) and args.min_ppi >= 0):
        raise UsageError(f"--min-ppi {args.min_ppi:g}: must be a resolution in ppi, 0 or more")
    spot = args.cut_spot_name
    if not spot or not spot.isascii() or not spot.isprintable() or any(ch in spot for ch in " /()<>[]{}%#"):
        raise UsageError(f"--cut-spot-name {spot!r}: give a plain name, e.g. CutContour or PerfCutContour")
    pdfx = PdfxOptions(
        output_profile=Path(args.output_profile) if args.output_profile else None,
        cmyk=args.cmyk,
        max_ink_pct=args.max_ink,
        cut_spot=spot,
    )
    out = Path(args.output) if args.output else Path("prints") / f"{name}.pdf"
    # the design folder's files and the profiles: `-o DESIGN/print.png` would destroy the design
    inputs = [*design_files(Path(args.design)), *(Path(p) for p in (args.printer_profile, args.output_profile) if p)]
    check_outputs(out, inputs=inputs)
    pattern = None
    if args.pattern:
        calib_dir = out.with_name(out.stem + "-design")
        check_output_dir(calib_dir, inputs)
        rgb, folder = calibration_design(Path(args.design), info, film, calib_dir)
        pattern = rgb
        write_folder(calib_dir, folder, inputs)
        log(f"wrote {calib_dir}/: the design with the calibration film as its print (validate photos against it)")
    if info.get("films"):
        pages = film_pages(Path(args.design), info, pattern)
    else:
        outline = None if args.no_cut else film_outline(Path(args.design) / "flat.obj")
        pages = [FilmPage(rgb, pr["width_mm"], pr["height_mm"], outline, film, top_edge=top_edge(Path(args.design)))]
    pdf, sheets, ink = print_pdf_pages(
        pages, pr["dpi"], name, job.get("sha256") or "unknown", paper, bleed, margin, profile, not args.no_cut, pdfx
    )
    write_files({out: pdf}, inputs=inputs)
    if len(pages) > 1:
        log(f"wrote {out}: {len(pages)} films, one page each ({', '.join(sorted({s.paper for s in sheets}))})")
    else:
        log(
            f"wrote {out}: {pr['width_mm']:.2f} x {pr['height_mm']:.2f} mm on {sheets[0].paper}, bleed {bleed:g} mm, "
            f"printer profile {profile.name}"
        )
    log(f"PDF/X-4, output profile {pdfx.output_profile or 'workbench-coated-pt1.icc (bundled)'}")
    if ink is not None:
        log(
            f"CMYK: total ink at most {ink.max_pct:.0f} % (limit {ink.max_ink_pct:g} %; {ink.max_pct_before:.0f} % out "
            f"of the profile, {100 * ink.limited_share:.1f} % of the pixels limited), p99 {ink.p99_pct:.0f} %"
        )
    for w in resolution_warnings(info, args.min_ppi):
        print(f"warning: {w}", file=sys.stderr, flush=True)
    log("print at 100 % (actual size, no fit-to-page) and check that both bars measure 100 mm")
    return 0
