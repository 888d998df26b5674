"""``workbench pdf``: the print of a design as a PDF at true physical scale, with marks."""

from __future__ import annotations

import sys
from pathlib import Path

import cv2
import numpy as np

from workbench import schemas
from workbench.atomic import check_outputs, write_files
from workbench.design_dir import design_files, read_design_json
from workbench.errors import WorkbenchError
from workbench.mesh.io import read_mesh
from workbench.mesh.topology import boundary_loops
from workbench.options import Number
from workbench.printing.paper import parse_paper
from workbench.printing.pdf import FilmPage, PrinterProfile, load_printer_profile, print_pdf, print_pdf_pages


def add_parser(sub) -> None:
    p = sub.add_parser(
        "pdf",
        help="the print of a design as a PDF at true scale, with crop and registration marks",
        description=(
            "Write the print of a design directory as a PDF: the texture at exactly width_mm x height_mm, "
            "a bleed beyond the trim, crop marks at the four corners, registration crosshairs, 100 mm scale "
            "bars along x and y, a 10 mm check square and a line identifying the job. Print it at 100 %% "
            "(actual size). A printer profile pre-compensates the printer's own scale error."
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
    p.add_argument("-q", "--quiet", action="store_true", help="no progress lines")
    p.set_defaults(run=run)


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
    img = cv2.imread(str(png_path), cv2.IMREAD_UNCHANGED)
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
    V, F = read_mesh(path)
    try:
        loops = boundary_loops(F)
    except (KeyError, IndexError, ValueError):  # a boundary that branches: not a manifold
        loops = []
    if len(loops) != 1 or not np.isfinite(V[loops[0]]).all():
        raise WorkbenchError(f"{path}: not the flat layout of a disc (one boundary loop); rerun workbench design")
    return V[loops[0], :2]


def film_pages(directory: Path, info: dict) -> list[FilmPage]:
    """One page per film of a design with several: its print, outline and label."""
    pages = []
    films = info["films"]
    for k, f in enumerate(films):
        try:
            png, flat = directory / f["print"], directory / f["flat"]
            size = (f["height_px"], f["width_px"])
            width_mm, height_mm, name = f["width_mm"], f["height_mm"], f["name"]
        except (KeyError, TypeError) as exc:
            raise WorkbenchError(f"{directory / 'design.json'}: films[{k}]: missing {exc}") from None
        img = cv2.imread(str(png), cv2.IMREAD_UNCHANGED)
        if img is None or img.ndim != 3 or img.shape[:2] != size:
            raise WorkbenchError(f"{png}: missing, unreadable or not {size[1]} x {size[0]} px; rerun workbench design")
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
    out = Path(args.output) if args.output else Path("prints") / f"{name}.pdf"
    # the design folder's files and the profile: `-o DESIGN/print.png` would destroy the design
    inputs = [*design_files(Path(args.design)), *([Path(args.printer_profile)] if args.printer_profile else [])]
    check_outputs(out, inputs=inputs)
    if info.get("films"):
        pages = film_pages(Path(args.design), info)
        pdf, sheets = print_pdf_pages(
            pages, pr["dpi"], name, job.get("sha256", "unknown"), paper, bleed, margin, profile, cut=not args.no_cut
        )
        write_files({out: pdf}, inputs=inputs)
        log(f"wrote {out}: {len(pages)} films, one page each ({', '.join(sorted({s.paper for s in sheets}))})")
        log("print at 100 % (actual size, no fit-to-page) and check that both bars measure 100 mm")
        return 0
    outline = None if args.no_cut else film_outline(Path(args.design) / "flat.obj")
    pdf, sheet = print_pdf(
        rgb,
        pr["dpi"],
        pr["width_mm"],
        pr["height_mm"],
        name,
        job.get("sha256") or "unknown",
        paper,
        bleed,
        margin,
        profile,
        outline_mm=outline,
        cut=not args.no_cut,
        film=film,
    )
    write_files({out: pdf}, inputs=inputs)
    log(
        f"wrote {out}: {pr['width_mm']:.2f} x {pr['height_mm']:.2f} mm on {sheet.paper}, bleed {bleed:g} mm, "
        f"printer profile {profile.name}"
    )
    log("print at 100 % (actual size, no fit-to-page) and check that both bars measure 100 mm")
    return 0
