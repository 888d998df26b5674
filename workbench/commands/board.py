"""``workbench board``: ChArUco boards at true scale, each with its definition file."""

from __future__ import annotations

import io
import json
import sys
from pathlib import Path

import numpy as np

from workbench import __version__
from workbench.atomic import check_outputs, write_files
from workbench.errors import UsageError, WorkbenchError
from workbench.jsonfile import recorded_path
from workbench.options import Number, parse_numbers
from workbench.printing.boards import (
    BoardError,
    CharucoSpec,
    ChessboardSpec,
    chessboard_definition,
    colour_chart_from_job,
    definition,
    draw_board,
    draw_chart_slot,
    draw_chessboard,
    fixture_from_job,
)
from workbench.printing.paper import choose_sheet, parse_paper
from workbench.printing.pdf import PT_PER_MM, PrinterProfile, _Page, build_date, load_printer_profile, scale_bar

BOARD_MARGIN_MM = 10.0
BELOW_MM = 22.0  # scale bar and text line under the board
OUTLINE_MM = 0.5  # the part's red outline on the fixture, line width
CASING_MM = 0.4  # the white casing on each side of it, so that it shows over black squares
# no outline, casing included, nearer than this to a ChArUco corner: a line through a corner pulls its
# sub-pixel position (seen: 0.1 mm)
CORNER_GAP_MM = 2.75


def add_parser(sub) -> None:
    p = sub.add_parser(
        "board",
        help="print a board: fixture plate, camera calibration board (ChArUco or chessboard) or printer target",
        description=(
            "Write a ChArUco board as a PDF at true scale, and its definition file (JSON, beside the PDF: "
            "dictionary, sizes, ids and every corner's position). 'fixture' is the plate the part stands on "
            "for validation photos ([fixture] of the job; corners also in the job's mesh frame, and the part's "
            "footprint drawn for placement); 'charuco' a camera calibration board (--legacy: the pre-4.6 OpenCV "
            "layout); 'chessboard' a plain chessboard for camera calibration; 'printer-target' a board "
            "filling the sheet, to measure a printer's scale."
        ),
    )
    p.add_argument("kind", choices=("fixture", "charuco", "chessboard", "printer-target"))
    p.add_argument("job", nargs="?", metavar="JOB.toml", help="for 'fixture': the job file")
    p.add_argument(
        "-o", "--output", metavar="FILE.pdf", help="default calib/boards/<kind>.pdf (fixture: prints/<job>-fixture.pdf)"
    )
    p.add_argument("--squares", metavar="NXxNY", help="squares across and down (charuco default 7x5, chessboard 10x7)")
    size = {"action": Number, "lo": 0, "lo_open": True, "hi": 1000, "unit": "mm"}
    p.add_argument("--square-mm", **size, help="square side, mm")
    p.add_argument("--marker-mm", **size, help="marker side, mm (default 0.75 of the square)")
    p.add_argument("--dictionary", default=None, help="ArUco dictionary (default DICT_5X5_250)")
    p.add_argument(
        "--first-id",
        action=Number,
        lo=0,
        hi=2**20,
        integer=True,
        default=None,
        help="id of the first marker (default 0)",
    )
    p.add_argument(
        "--legacy",
        action="store_true",
        help="charuco: the pre-4.6 OpenCV layout (differs for an even number of rows; many printed boards use it)",
    )
    p.add_argument("--paper", default="auto", help="A4, A3, letter, ..., auto or WxH in mm")
    p.add_argument("--printer-profile", metavar="FILE", help="printer scale profile to pre-compensate")
    p.add_argument("-q", "--quiet", action="store_true")
    p.set_defaults(run=run)


def _squares(text: str | None, default: tuple[int, int]) -> tuple[int, int]:
    if text is None:
        return default
    if len(text.lower().split("x")) != 2:
        raise UsageError(f"--squares {text!r}: give NXxNY, e.g. 7x5")
    return parse_numbers(text.lower(), 2, "--squares", sep="x", lo=1, hi=1000, integer=True)


def board_pdf(
    spec: CharucoSpec | ChessboardSpec,
    title: str,
    paper,
    profile: PrinterProfile,
    footprint=None,
    chart: dict | None = None,
) -> tuple[bytes, tuple]:
    """PDF of a board centred on a sheet with a 100 mm bar and a line of text under it.

    With ``chart`` (a fixture's ``colour_chart``), the chart's slot is drawn under the board,
    where the definition puts it, and the bar and text go under the slot.

    Returns
    -------
    pdf : bytes
    page_origin_mm : (2,)
        The board's top-left corner, mm from the sheet's top-left corner (x right, y down).
    paper : str
        The sheet used.
    """
    from reportlab.pdfgen import canvas as rl_canvas

    bw, bh = spec.size_mm
    # the slot's extent below the board's bottom edge
    below_board = 0.0 if chart is None else chart["frame_board_mm"][3] - bh
    side = 0.0 if chart is None else max(chart["frame_board_mm"][2] - bw, -chart["frame_board_mm"][0], 0.0)
    need_w = max(bw + 2 * side, 110.0) + 2 * BOARD_MARGIN_MM
    need_h = bh + below_board + BELOW_MM + 2 * BOARD_MARGIN_MM
    paper_name, pw, ph = choose_sheet(paper, need_w, need_h)
    buf = io.BytesIO()
    c = rl_canvas.Canvas(buf, pagesize=(pw * PT_PER_MM, ph * PT_PER_MM), invariant=1, pageCompression=1)
    c.setTitle(title)
    c.setCreator(f"workbench {__version__}")
    pattern = spec.dictionary if isinstance(spec, CharucoSpec) else "chessboard"
    c.setKeywords(f"workbench, board, {pattern}, {spec.squares[0]}x{spec.squares[1]}, printer-profile={profile.name}")
    c.setViewerPreference("PrintScaling", "None")
    page = _Page(c, pw, ph, profile)
    left = (pw - bw) / 2
    top = ph - (ph - bh - below_board - BELOW_MM) / 2  # sheet y (up) of the board's top edge
    (draw_board if isinstance(spec, CharucoSpec) else draw_chessboard)(c, spec, left, top)
    if chart is not None:
        draw_chart_slot(c, chart, left, top)
    if footprint is not None:
        # the outline leaves a gap around every ChArUco corner (CORNER_GAP_MM)
        from workbench.printing.boards import board_geometry

        corners = board_geometry(spec)["charuco_mm"]
        closed = np.vstack([footprint, footprint[:1]])
        seg = np.linalg.norm(np.diff(closed, axis=0), axis=1)
        t = np.concatenate([[0.0], np.cumsum(seg)])
        s_ = np.arange(0.0, t[-1], 0.25)
        pts = np.stack([np.interp(s_, t, closed[:, 0]), np.interp(s_, t, closed[:, 1])], axis=1)
        gap = CORNER_GAP_MM + OUTLINE_MM / 2 + CASING_MM  # (to the line's centre)
        near = (np.linalg.norm(pts[:, None, :] - corners[None], axis=2) < gap).any(axis=1)
        paths, start = [], None
        for k in range(len(pts) + 1):
            if k < len(pts) and not near[k]:
                start = k if start is None else start
                continue
            if start is not None and k - start > 1:
                path = c.beginPath()
                path.moveTo(left + pts[start, 0], top - pts[start, 1])
                for x, y in pts[start + 1 : k]:
                    path.lineTo(left + x, top - y)
                paths.append(path)
            start = None
        # red on a white casing: the line shows over the black squares as over the white ones
        # (the casing's ends squared beyond the red's, so that no red end meets a black square either)
        for rgb, width, cap in (((1.0, 1.0, 1.0), OUTLINE_MM + 2 * CASING_MM, 2), ((0.85, 0.1, 0.1), OUTLINE_MM, 0)):
            c.setStrokeColorRGB(*rgb)
            c.setLineWidth(width)
            c.setLineCap(cap)
            for path in paths:
                c.drawPath(path, stroke=1, fill=0)
        c.setStrokeColorRGB(0, 0, 0)
        c.setLineCap(0)
        c.setLineWidth(0.25 / PT_PER_MM)
        page.text(left, top + 2.0, "top edge: mesh +y. Place the part inside the red outline.", size=2.6)
    bottom = top - bh - below_board
    scale_bar(page, left, bottom - 6.0, vertical=False)
    page.text(
        left,
        bottom - 17.0,
        f"{title} | {build_date()} | printer profile: {profile.name} | "
        "print at 100 % (actual size): the bar must measure 100 mm",
        size=2.2,
    )
    c.showPage()
    c.save()
    return buf.getvalue(), (left, ph - top), paper_name


def run(args) -> int:
    log = (lambda _m: None) if args.quiet else (lambda m: print(m, file=sys.stderr, flush=True))
    paper = parse_paper(args.paper)
    profile = load_printer_profile(args.printer_profile) if args.printer_profile else PrinterProfile()
    extra: dict = {"software": {"name": "workbench", "version": __version__}}
    footprint = origin = chart = None
    inputs = [Path(args.printer_profile)] if args.printer_profile else []
    if args.kind == "fixture":
        if args.legacy:
            raise UsageError("--legacy is for board charuco: a fixture board is always in today's layout")
        if args.job is None:
            raise UsageError("board fixture needs the job file: workbench board fixture JOB.toml")
        from workbench.job import load_job
        from workbench.mesh.io import MeshName, read_mesh
        from workbench.mesh.validate import check_disc

        job = load_job(args.job)
        inputs += [job.path, job.object.mesh, *(v.image for v in job.views)]
        V, F = read_mesh(job.object.mesh, job.object.units)
        check_disc(V, F, MeshName(job.object.mesh))  # the footprint is the disc's boundary
        spec, origin, footprint = fixture_from_job(job.fixture, V, F, f"{job.path}: fixture")
        extra["job"] = {"file": str(job.path), "sha256": job.sha256, "name": job.name}
        extra["footprint_board_mm"] = footprint.tolist()
        chart = colour_chart_from_job(job.fixture, spec, origin)
        if chart is not None:
            extra["colour_chart"] = chart
        default_out = Path("prints") / f"{job.name}-fixture.pdf"
        title = f"workbench fixture board for job {job.name}"
    else:
        if args.job is not None:
            raise UsageError(f"board {args.kind} takes options, not a job file")
        if args.legacy and args.kind != "charuco":
            raise UsageError(f"--legacy is a ChArUco layout: board {args.kind} has none")
        if args.kind == "chessboard":
            if args.marker_mm is not None or args.dictionary is not None or args.first_id is not None:
                raise UsageError("board chessboard has no markers: --marker-mm, --dictionary, --first-id do not apply")
            square = 25.0 if args.square_mm is None else args.square_mm
            squares = _squares(args.squares, (10, 7))
        elif args.kind == "charuco":
            square = 30.0 if args.square_mm is None else args.square_mm
            squares = _squares(args.squares, (7, 5))
        else:  # a printer target fills the sheet, to measure scale over the longest lengths
            square = 15.0 if args.square_mm is None else args.square_mm
            sheet_w, sheet_h = (210.0, 297.0) if paper == "auto" else choose_sheet(paper, 1, 1)[1:]
            default = (
                int((sheet_w - 2 * BOARD_MARGIN_MM) // square),
                int((sheet_h - 2 * BOARD_MARGIN_MM - BELOW_MM) // square),
            )
            squares = _squares(args.squares, default)
        try:
            if args.kind == "chessboard":
                spec = ChessboardSpec(squares=squares, square_mm=square)
            else:
                spec = CharucoSpec(
                    squares=squares,
                    square_mm=square,
                    marker_mm=args.marker_mm or 0.75 * square,
                    dictionary=args.dictionary or "DICT_5X5_250",
                    first_id=args.first_id or 0,
                    legacy=bool(args.legacy),
                )
        except BoardError as exc:  # every value came from an option (or its default): name it
            flag = "--" + exc.key.replace("_", "-")
            given = getattr(args, exc.key, None)
            given = "" if given is None else f" {given:g}" if isinstance(given, float) else f" {given}"
            raise UsageError(f"{flag}{given}: {exc}") from None
        except WorkbenchError as exc:  # every value came from an option: a usage error
            raise UsageError(str(exc)) from None
        layout = "-legacy" if args.legacy else ""
        default_out = Path("calib") / "boards" / f"{args.kind}-{squares[0]}x{squares[1]}-{square:g}mm{layout}.pdf"
        pattern = "chessboard" if args.kind == "chessboard" else spec.dictionary + (", legacy layout" * args.legacy)
        title = f"workbench {args.kind} board {squares[0]}x{squares[1]}, {square:g} mm squares, {pattern}"
    out = Path(args.output) if args.output else default_out
    # `-o b.json`: the PDF and its definition would get one name; the job's files are inputs
    check_outputs(out, out.with_suffix(".json"), inputs=inputs)
    if "job" in extra:  # relative to the definition's folder, with its hash: the pair travels
        extra["job"]["file"] = recorded_path(extra["job"]["file"], out.parent)
    pdf, page_origin, paper_name = board_pdf(spec, title, paper, profile, footprint, chart)
    extra["paper"] = paper_name
    extra["printer_profile"] = {"name": profile.name, "scale_x": profile.scale_x, "scale_y": profile.scale_y}
    if isinstance(spec, ChessboardSpec):
        info = chessboard_definition(spec, page_origin_mm=page_origin, extra=extra)
    else:
        info = definition(spec, args.kind, origin_mm=origin, page_origin_mm=page_origin, extra=extra)
    write_files({out: pdf, out.with_suffix(".json"): (json.dumps(info, indent=1) + "\n").encode()}, inputs=inputs)
    pattern = "chessboard" if isinstance(spec, ChessboardSpec) else spec.dictionary + (", legacy layout" * spec.legacy)
    log(
        f"wrote {out} ({paper_name}) and {out.with_suffix('.json')}: {spec.squares[0]} x {spec.squares[1]} squares "
        f"of {spec.square_mm:g} mm, {pattern}"
    )
    return 0
