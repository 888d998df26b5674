"""``workbench calibrate``: camera intrinsics, printer scale, and the weekly regression check."""

from __future__ import annotations

import hashlib
import json
import sys
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

from workbench import __version__, schemas
from workbench.atomic import check_outputs, write_files
from workbench.calibration import (
    INTRINSICS,
    TOLERANCE_SIGMA,
    calibrate_camera,
    check_camera,
    check_printer_scale,
    measure_printer,
    name_list,
    printer_scale_warnings,
)
from workbench.calibration_power import check_power
from workbench.camera import intrinsics_problem
from workbench.errors import UsageError, WorkbenchError
from workbench.export import png_dpi
from workbench.image_file import imread
from workbench.jsonfile import check, read_json, recorded_path, resolve_recorded
from workbench.options import Number
from workbench.printing.boards import load_board


def add_parser(sub) -> None:
    p = sub.add_parser("calibrate", help="camera and printer calibration, and their regression check")
    s = p.add_subparsers(dest="what", metavar="WHAT", required=True)
    c = s.add_parser(
        "camera",
        help="intrinsics from photos of a ChArUco board",
        description="Camera matrix and distortion from photos of a ChArUco board (workbench board "
        "charuco). Writes the profile (JSON) and a picture of the residuals beside it.",
    )
    c.add_argument("photos", metavar="PHOTO", nargs="+")
    c.add_argument("--board", metavar="BOARD.json", required=True, help="board definition")
    c.add_argument("-o", "--output", metavar="PROFILE.json", required=True)
    c.add_argument("-q", "--quiet", action="store_true")
    c.set_defaults(run=run_camera)
    r = s.add_parser(
        "printer",
        help="a printer's scale from a scan of its printed target",
        description="Print `workbench board printer-target` at 100 %, scan it flat at a known dpi, and "
        "measure the printer's scale in x and y and its skew. Writes the printer profile "
        "that `workbench pdf --printer-profile` applies.",
    )
    r.add_argument("scan", metavar="SCAN.png")
    r.add_argument("--board", metavar="BOARD.json", required=True, help="definition of the printed target")
    r.add_argument("--dpi", action=Number, lo=1, hi=100_000, required=True, help="resolution of the scan")
    r.add_argument("--name", help="printer name shown on pages (default: the profile's file name)")
    r.add_argument(
        "--strict",
        action="store_true",
        help="treat a scale unlike a printer's (beyond ±2 %%, a wrong target or definition) as an error: exit 1",
    )
    r.add_argument("-o", "--output", metavar="PROFILE.json", required=True)
    r.add_argument("-q", "--quiet", action="store_true")
    r.set_defaults(run=run_printer)
    k = s.add_parser(
        "check",
        help="re-measure against a stored profile; fail on drift",
        description="Re-measure a camera profile (photos of its board) or a printer profile (scans of "
        "its target) and fail (exit 1) when the drift exceeds the tolerance.",
    )
    k.add_argument("profile", metavar="PROFILE.json")
    k.add_argument("inputs", metavar="PHOTO_OR_SCAN", nargs="+")
    positive = {"action": Number, "lo": 0, "lo_open": True}
    k.add_argument(
        "--tolerance-pct", **positive, hi=100, default=0.05, help="printer: largest scale drift (default 0.05 %%)"
    )
    k.add_argument(
        "--tolerance-px",
        **positive,
        hi=1000,
        default=None,
        help="camera: largest reprojection RMS of a photo posed with the stored intrinsics "
        "(default: the profile's own limit, 3 x its median view RMS and at least 0.5 px)",
    )
    k.add_argument(
        "--tolerance-sigma",
        **positive,
        hi=1e6,
        default=TOLERANCE_SIGMA,
        help="camera: largest difference between re-measured and stored fx, fy, cx, cy, in standard "
        f"deviations of the two (default {TOLERANCE_SIGMA:g}); a confidence in the units of a normal "
        "distribution, widened to Student's t where a standard deviation comes from the scatter of few photos",
    )
    k.add_argument(
        "--focal-tolerance-pct",
        **positive,
        hi=100,
        default=1.0,
        help="camera: the focal length drift the lab must catch, %% (default 1); a check whose photos cannot "
        "see it says so",
    )
    k.add_argument(
        "--pp-tolerance-px",
        **positive,
        hi=1e5,
        default=8.0,
        help="camera: the principal point move the lab must catch, px (default 8)",
    )
    k.add_argument(
        "--strict",
        action="store_true",
        help="camera: fail (exit 1) a check whose photos cannot see the drifts above, not only warn",
    )
    k.add_argument(
        "--coverage",
        metavar="PICTURE.png",
        default=None,
        help="camera: write a picture of what of the frame and which tilts the photos cover, and what to add",
    )
    k.add_argument(
        "--store",
        metavar="URL",
        help="record the check (focal length, principal point or printer scale, the verdict, the profile's "
        "name and hash, the time) in a store: a SQLite file's path or a SQLAlchemy URL; default: "
        "$WORKBENCH_STORE, else no store (workbench trend --calibration charts them)",
    )
    k.add_argument("-q", "--quiet", action="store_true")
    k.set_defaults(run=run_check)
    from workbench.commands import calibrate_forming

    calibrate_forming.add_parser(s)


def _log(args):
    return (lambda _m: None) if args.quiet else (lambda m: print(m, file=sys.stderr, flush=True))


def _gray(path: Path) -> np.ndarray:
    if path.is_dir():
        raise WorkbenchError(f"{path}: is a directory, not an image")
    img = imread(path, cv2.IMREAD_GRAYSCALE) if path.is_file() else None
    if img is None:
        raise WorkbenchError(f"{path}: cannot read image" + ("" if path.exists() else " (no such file)"))
    return img


def _sha(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


MAX_ARROWS = 1500


def arrow_layout(magnitudes: np.ndarray, width: int) -> tuple[float, int]:
    """How to draw residual arrows: magnification and stride.

    Parameters
    ----------
    magnitudes : (n,) float
        Residual lengths, px.
    width : int
        Image width, px.

    Returns
    -------
    gain : float
        A round 1, 2 or 5 x 10^k, the largest that draws the 95th percentile residual at
        most 3 % of the width long (between 1 and 100,000).
    step : int
        Draw every step-th arrow: at most MAX_ARROWS.
    """
    p95 = float(np.percentile(magnitudes, 95)) if len(magnitudes) else 0.0
    raw = float(np.clip(0.03 * width / max(p95, 1e-6), 1, 1e5))
    decade = 10 ** np.floor(np.log10(raw))
    gain = float(decade * max(m for m in (1, 2, 5) if decade * m <= raw))
    return gain, max(1, int(np.ceil(len(magnitudes) / MAX_ARROWS)))


def residual_picture(cal, title: str) -> bytes:
    """PNG of the corner residuals over the image (:func:`residual_plot`)."""
    from workbench.figures import figure_png

    return figure_png(residual_plot(cal, title))


def residual_plot(cal, title: str):
    """Corner residuals over the image, in its pixels (y down), coloured by size; a matplotlib Figure.

    The arrows are magnified so that the 95th percentile residual is drawn at most 3 % of
    the image width long, and at most MAX_ARROWS of them are drawn (every k-th corner),
    so that thousands of corners stay readable (:func:`arrow_layout`).
    """
    from workbench.figures import _figure, photo_axes

    plt = _figure()
    W, H = cal.image_size
    fig, ax = plt.subplots(figsize=(8, 8 * H / W + 0.5), dpi=100)
    pts = np.concatenate([p for p, _ in cal.residuals])
    res = np.concatenate([r for _, r in cal.residuals])
    mag = np.linalg.norm(res, axis=1)
    gain, step = arrow_layout(mag, W)
    sel = slice(None, None, step)
    q = ax.quiver(
        pts[sel, 0],
        pts[sel, 1],
        res[sel, 0],
        -res[sel, 1],
        mag[sel],
        cmap="viridis",
        angles="xy",
        scale_units="xy",
        scale=1 / gain,
    )
    shown = f"; 1 in {step} of {len(pts)} corners" if step > 1 else ""
    fig.colorbar(q, ax=ax, fraction=0.046, pad=0.04).set_label(f"residual (px); arrows x{gain:g}{shown}")
    photo_axes(ax, W, H)
    ax.set_title(title, fontsize=9)
    return fig


def coverage_picture(views: list, coverage: dict, width: int, height: int, title: str) -> bytes:
    """PNG of what of the frame and which tilts the photos cover (:func:`coverage_plot`)."""
    from workbench.figures import figure_png

    return figure_png(coverage_plot(views, coverage, width, height, title))


def coverage_plot(views: list, coverage: dict, width: int, height: int, title: str):
    """What of the frame and which tilts the photos cover, and what the next photos should add; a Figure.

    Left: the frame with :data:`~workbench.calibration.COVERAGE_GRID`'s cells shaded by how many
    corners fall in them (red where none), every corner a dot; the frame's corners and borders
    without any named in red. Right: each photo's board tilt about the image's vertical (x of
    the plot) and horizontal axis, degrees, with the advised band from
    :data:`~workbench.calibration.TILT_ADVISED_DEG` to 45.
    """
    from matplotlib.patches import Rectangle

    from workbench.calibration_coverage import TILT_ADVISED_DEG
    from workbench.figures import _figure, photo_axes

    plt = _figure()
    cells = np.asarray(coverage["cells"])
    rows, cols = cells.shape
    fig, (ax, at) = plt.subplots(
        1, 2, figsize=(12, 5.2), dpi=100, gridspec_kw={"width_ratios": [width / height * 1.0, 0.8]}
    )
    shade = np.log1p(cells) / max(np.log1p(cells.max()), 1e-9)
    ax.imshow(shade, cmap="Greens", vmin=0, vmax=1.2, extent=(0, width, height, 0), interpolation="nearest")
    for r, c in zip(*np.nonzero(cells == 0), strict=True):
        w, h = width / cols, height / rows
        ax.add_patch(Rectangle((c * w, r * h), w, h, facecolor=(1, 0.85, 0.85), edgecolor="none"))
    for _, _, px in views:
        ax.plot(np.asarray(px)[:, 0], np.asarray(px)[:, 1], ".", ms=1.5, color="0.25")
    for k in range(1, cols):
        ax.axvline(k * width / cols, color="0.8", lw=0.5)
    for k in range(1, rows):
        ax.axhline(k * height / rows, color="0.8", lw=0.5)
    spots = {
        "top-left": (0.12, 0.1), "top-right": (0.88, 0.1), "bottom-left": (0.12, 0.9), "bottom-right": (0.88, 0.9),
        "top": (0.5, 0.06), "bottom": (0.5, 0.94), "left": (0.06, 0.5), "right": (0.94, 0.5),
    }  # fmt: skip
    for name in coverage["missing"]:
        x, y = spots[name]
        ax.text(x * width, y * height, "none here", color="red", ha="center", va="center", fontsize=8)
    photo_axes(ax, width, height)
    ax.set_title(f"corners over the frame: {100 * coverage['share']:.0f} % of its {cols} x {rows} cells", fontsize=9)
    ty, tx = np.asarray(coverage["tilt_y_deg"]), np.asarray(coverage["tilt_x_deg"])
    lo, hi = TILT_ADVISED_DEG, 45.0
    for a in (lo, hi):
        at.add_patch(Rectangle((-a, -a), 2 * a, 2 * a, fill=False, ls="--", color="0.6", lw=0.8))
    at.plot(ty, tx, "o", ms=4, color="tab:blue")
    at.set_xlim(-70, 70)
    at.set_ylim(-70, 70)
    at.set_aspect("equal")
    at.axhline(0, color="0.85", lw=0.5)
    at.axvline(0, color="0.85", lw=0.5)
    at.set_xlabel("tilt about the image's vertical axis (deg)")
    at.set_ylabel("tilt about its horizontal axis (deg)")
    at.set_title(f"board tilts (dashed: {lo:g} and {hi:g} deg)", fontsize=9)
    advice = coverage["next"]
    fig.suptitle(title + ("\nnext: " + "; ".join(advice) if advice else "\nframe and tilts covered"), fontsize=9)
    fig.tight_layout()
    return fig


def coverage_path(out: Path) -> Path:
    """Where a profile's coverage picture goes: beside it, NAME-coverage.png."""
    return out.with_name(out.stem + "-coverage.png")


def run_camera(args) -> int:
    log = _log(args)
    board_path = Path(args.board)
    board = load_board(board_path)
    out = Path(args.output)
    inputs = [board_path, *map(Path, args.photos)]
    # before the calibration, not after it; `-o cam.png` would give the profile and its picture one name
    check_outputs(out, out.with_suffix(".png"), coverage_path(out), inputs=inputs)
    images = [(str(p), _gray(Path(p))) for p in args.photos]
    try:
        cal = calibrate_camera(images, board)
    except WorkbenchError as exc:  # "2 usable views of the board": of which photos (unless it says), which board
        named = any(Path(p).name in str(exc) for p in args.photos)
        photos = ", ".join(args.photos[:3]) + (f" and {len(args.photos) - 3} more" if len(args.photos) > 3 else "")
        raise WorkbenchError(f"{board_path}: {exc}" if named else f"{photos} (board {board_path}): {exc}") from None
    profile = {
        "kind": "camera-profile",
        "K": cal.K.tolist(),
        "dist": cal.dist.tolist(),
        "image_size": list(cal.image_size),
        "rms_px": cal.rms_px,
        "k3_fixed": cal.k3_fixed,
        "corner_coverage": cal.coverage,
        "tilt_spread_deg": cal.tilt_spread_deg,
        # which parts of the frame and which tilts the used photos cover, and what to add
        "frame_coverage": cal.frame_coverage,
        # standard deviations of fx, fy, cx, cy (px): what calibrate check measures drift against
        "intrinsics_std": dict(zip(INTRINSICS, map(float, cal.std), strict=True)),
        "intrinsics_std_opencv": dict(zip(INTRINSICS, map(float, cal.std_opencv), strict=True)),
        "view_rms_limit_px": cal.view_limit_px,
        "warnings": cal.warnings,
        # photos as paths relative to the profile's folder (each with its sha256): the profile travels
        "views": [{**v, "name": recorded_path(v["name"], out.parent)} for v in cal.per_view],
        "board": {"file": recorded_path(board_path, out.parent), "sha256": _sha(board_path)},
        "photos_sha256": {recorded_path(p, out.parent): _sha(Path(p)) for p in args.photos},
        "software": {"name": "workbench", "version": __version__},
    }
    pic = residual_picture(
        cal, f"{out.name}: RMS {cal.rms_px:.3f} px over {sum(v['used'] for v in cal.per_view)} views"
    )
    cover = coverage_picture(
        cal.used_views, cal.frame_coverage, *cal.image_size, f"{out.name}: {len(cal.used_views)} photos"
    )
    write_files(
        {
            out: (json.dumps(profile, indent=1) + "\n").encode(),
            out.with_suffix(".png"): pic,
            coverage_path(out): cover,
        },
        inputs=inputs,
    )
    for v in cal.per_view:
        if not v["used"]:
            log(f"left out {v['name']}: {v['reason']}")
    for w in cal.warnings:
        log(f"warning: {w}")
    log(coverage_line(cal.frame_coverage) + f" (picture: {coverage_path(out).name})")
    log(
        f"fx {cal.K[0, 0]:.2f} fy {cal.K[1, 1]:.2f} cx {cal.K[0, 2]:.2f} cy {cal.K[1, 2]:.2f} px; dist "
        f"{np.round(cal.dist, 5).tolist()}; RMS {cal.rms_px:.3f} px; wrote {out}"
    )
    return 0


def coverage_line(coverage: dict) -> str:
    """One line: the share of the frame the corners reach, and what the next photos should add."""
    advice = coverage["next"]
    return f"coverage: corners reach {100 * coverage['share']:.0f} % of the frame's cells; " + (
        "next photos: " + "; ".join(advice) if advice else "the frame's corners and borders and both tilts are covered"
    )


def _check_dpi(path: Path, dpi: float) -> None:
    if not (np.isfinite(dpi) and 1 <= dpi <= 100_000):
        raise UsageError(f"--dpi {dpi:g}: must be a scan resolution from 1 to 100000")
    recorded = png_dpi(path.read_bytes()) if path.suffix.lower() == ".png" and path.is_file() else None
    if recorded is not None and abs(recorded - dpi) > 0.01 * dpi:
        raise WorkbenchError(f"{path}: the scan says {recorded:.1f} dpi, --dpi says {dpi:g}: which is right?")


def run_printer(args) -> int:
    log = _log(args)
    board_path, scan_path = Path(args.board), Path(args.scan)
    board = load_board(board_path)
    _check_dpi(scan_path, args.dpi)
    out = Path(args.output)
    check_outputs(out, inputs=[board_path, scan_path])
    m = _measure(scan_path, board, args.dpi)
    check_printer_scale(m, args.dpi, png_dpi(scan_path.read_bytes()) is not None, str(scan_path))
    warnings = printer_scale_warnings(m)
    if warnings and args.strict:
        raise WorkbenchError(f"{scan_path}: not a printer's scale (--strict): " + "; ".join(warnings))
    profile = {
        "kind": "printer-profile",
        "name": args.name or out.stem,
        "scale_x": m.scale_x,
        "scale_y": m.scale_y,
        "skew_deg": m.skew_deg,
        "scan_rotation_deg": m.rotation_deg,
        "fit_rms_mm": m.rms_mm,
        "warnings": warnings,
        "corners": m.corners,
        "dpi": args.dpi,
        "board": {"file": recorded_path(board_path, out.parent), "sha256": _sha(board_path)},
        "scan": {"file": recorded_path(scan_path, out.parent), "sha256": _sha(scan_path)},
        "software": {"name": "workbench", "version": __version__},
    }
    write_files({out: (json.dumps(profile, indent=1) + "\n").encode()}, inputs=[board_path, scan_path])
    for w in warnings:
        log(f"warning: {w}")
    log(
        f"scale x {100 * (m.scale_x - 1):+.3f} %, y {100 * (m.scale_y - 1):+.3f} %, skew {m.skew_deg:+.3f}°, "
        f"fit {m.rms_mm * 1000:.1f} µm over {m.corners} corners; wrote {out}"
    )
    return 0


def _measure(scan: Path, board: dict, dpi: float):
    """The printer's scale in one scan; its errors name the scan."""
    try:
        return measure_printer(_gray(scan), board, dpi)
    except WorkbenchError as exc:
        raise WorkbenchError(str(exc) if str(exc).startswith(str(scan)) else f"{scan}: {exc}") from None


@dataclass(frozen=True)
class CameraCheck:
    """The camera half of ``calibrate check``: what drifted (empty when within tolerance), on what, what
    drift of the lab's tolerances the photos cannot see (empty when they see both), and fx, fy, cx, cy
    as re-measured (px; None where not re-measured)."""

    drift: list[str]
    on: str
    short: str
    remeasured: dict


def _check_camera(args, path: Path, prof: dict, board: dict, log) -> CameraCheck:
    """The camera half of ``calibrate check`` (:class:`CameraCheck`)."""
    K = np.asarray(prof["K"], dtype=np.float64)
    problem = intrinsics_problem(K, *prof["image_size"])
    if problem:
        raise WorkbenchError(f"{path}: {problem}")
    if args.coverage is not None:
        check_outputs(Path(args.coverage), inputs=[path, *map(Path, args.inputs)])
    images = [(str(p), _gray(Path(p))) for p in args.inputs]
    c = check_camera(images, board, prof, args.tolerance_px, args.tolerance_sigma)
    used = sum(v["used"] for v in c.per_photo)
    for v in c.per_photo:
        name = Path(v["name"]).name
        if not v["used"]:
            log(f"left out {v['name']}: {v['reason']}")
        elif v["rms_px"] is None:
            log(f"{name}: no pose of the board with the stored intrinsics: DRIFT")
        else:
            log(
                f"{name}: reprojection RMS {v['rms_px']:.3f} px with the stored intrinsics "
                f"(limit {c.limit_px:.2f} px): {'OK' if v['ok'] else 'DRIFT'}"
            )
    r = c.remeasured
    if c.why_not:
        log(f"fx, fy, cx, cy not all re-measured ({c.why_not})")
    if r is not None:
        names = r["measured"]
        parts = [
            f"{k} {r[k]['value']:.2f} ({r[k]['delta']:+.2f} px, {r[k]['z']:+.1f} sigma, limit {r[k]['limit']:.1f})"
            for k in names
        ]
        held = "" if len(names) == len(INTRINSICS) else ", principal point and aspect held"
        log(
            f"re-measured on {r['views']} photos{held} (RMS {r['rms_px']:.3f} px): {', '.join(parts)}; "
            f"largest shift across the image {r['ray_shift_px']:.2f} px "
            f"(tolerance {c.tolerance_sigma:g} sigma, widened for standard deviations taken from few photos): "
            f"{'DRIFT' if any('re-measured' in d for d in c.drift) else 'OK'}"
        )
        if not r["profile_uncertainty"]:
            log("the profile records no uncertainty of its intrinsics (made before it did): the photos' alone counts")
    log(coverage_line(c.frame_coverage))
    if args.coverage is not None:
        W, H = (int(v) for v in prof["image_size"])
        pic = coverage_picture(c.used_views, c.frame_coverage, W, H, f"check of {path.name}: {used} photos")
        write_files({Path(args.coverage): pic}, inputs=[path, *map(Path, args.inputs)])
        log(f"wrote {args.coverage}")
    power = check_power(r, K, args.focal_tolerance_pct, args.pp_tolerance_px)
    sees = [f"a focal drift of {power['focal_pct']:.2f} %"] if power["focal_pct"] is not None else []
    sees += [f"a principal point move of {power['pp_px']:.1f} px"] if power["pp_px"] is not None else []
    if sees:
        log(f"this check catches {' and '.join(sees)} ({100 * power['probability']:.0f} % of the time)")
    short = ""
    if power["short"]:
        need = power["photos_needed"]
        short = "; ".join(power["short"]) + (
            f"; about {need} photos are needed"
            if need
            else "; no number of photos will do: the profile's own "
            "uncertainty is larger than the tolerance (recalibrate with more photos)"
        )
        if not args.strict:
            log(f"warning: {short}")
    left_out = len(c.per_photo) - used
    values = {k: (float(r[k]["value"]) if r is not None and k in r["measured"] else None) for k in INTRINSICS}
    return CameraCheck(c.drift, f"{used} photos" + (f" ({left_out} left out)" if left_out else ""), short, values)


def _store_url(args):
    """The store the check is recorded in (``--store``, else ``WORKBENCH_STORE``), checked; None: no store."""
    from workbench.store.database import check_store, store_text, store_url

    text = store_text(args.store)
    if text is None:
        return None
    option = "--store" if args.store is not None else "WORKBENCH_STORE"
    url = store_url(text, option)
    check_store(url, option)
    return url


def _record_check(url, path: Path, prof: dict, args, verdict: str, reason: str | None, figures: dict) -> None:
    """The check recorded (one row of ``calibrations``), its time ``SOURCE_DATE_EPOCH`` when set."""
    import os

    from workbench.environment import source_date_epoch
    from workbench.store.record import default_operator, default_station, record_calibration, recorded_at

    K = prof.get("K") or [[None] * 3] * 3
    row = {
        "kind": prof["kind"],
        "camera": path.stem,
        "profile_sha256": _sha(path),
        "station": default_station(),
        "operator": default_operator(),
        "recorded_at": recorded_at(source_date_epoch(os.environ)),
        "software_version": __version__,
        "verdict": verdict,
        "reason": reason,
        "inputs": len(args.inputs),
        "profile_fx": K[0][0] if prof["kind"] == "camera-profile" else None,
        "profile_fy": K[1][1] if prof["kind"] == "camera-profile" else None,
        "profile_cx": K[0][2] if prof["kind"] == "camera-profile" else None,
        "profile_cy": K[1][2] if prof["kind"] == "camera-profile" else None,
        "focal_tolerance_pct": args.focal_tolerance_pct if prof["kind"] == "camera-profile" else None,
        "pp_tolerance_px": args.pp_tolerance_px if prof["kind"] == "camera-profile" else None,
        "profile_scale_x": prof.get("scale_x"),
        "profile_scale_y": prof.get("scale_y"),
        "scale_tolerance_pct": args.tolerance_pct if prof["kind"] == "printer-profile" else None,
        **figures,
    }
    row["check_json"] = json.dumps({k: v for k, v in row.items() if k != "check_json"}, sort_keys=True)
    record_calibration(row, url)


def run_check(args) -> int:
    log = _log(args)
    for flag, v in (
        ("--tolerance-pct", args.tolerance_pct),
        ("--tolerance-px", args.tolerance_px),
        ("--tolerance-sigma", args.tolerance_sigma),
        ("--focal-tolerance-pct", args.focal_tolerance_pct),
        ("--pp-tolerance-px", args.pp_tolerance_px),
    ):
        if v is not None and not (np.isfinite(v) and v > 0):
            raise UsageError(f"{flag} {v:g}: must be a positive number")
    path = Path(args.profile)
    what = "profile of workbench calibrate (camera-profile or printer-profile)"
    prof = read_json(path, what, schemas.CALIBRATION_PROFILE)
    kind = prof["kind"]
    check(prof, schemas.CALIBRATION_KINDS[kind], path)
    board_path = resolve_recorded(prof["board"]["file"], path)
    board = load_board(board_path)
    url = _store_url(args)
    if kind == "camera-profile":
        cam = _check_camera(args, path, prof, board, log)
        drift, on, short = cam.drift, cam.on, cam.short
        if url is not None:
            reason = "; ".join(drift) if drift else (short or None)
            _record_check(url, path, prof, args, "DRIFT" if drift else "OK", reason, cam.remeasured)
        if drift:
            raise WorkbenchError(f"{path.name}: the camera drifted: {'; '.join(drift)}: recalibrate")
        if short and args.strict:
            raise WorkbenchError(f"{path.name}: the check cannot see the lab's tolerance (--strict): {short}")
        log(f"{path.name}: within tolerance on {on}" + (f"; warning: {short}" if short else ""))
        return 0
    failures = []
    scales = []
    for item in args.inputs:
        p = Path(item)
        _check_dpi(p, prof["dpi"])
        m = _measure(p, board, prof["dpi"])
        dx, dy = 100 * (m.scale_x - prof["scale_x"]), 100 * (m.scale_y - prof["scale_y"])
        ok = max(abs(dx), abs(dy)) <= args.tolerance_pct
        log(
            f"{p.name}: scale drift x {dx:+.3f} %, y {dy:+.3f} % (tolerance {args.tolerance_pct} %): "
            f"{'OK' if ok else 'DRIFT'}"
        )
        if not ok:
            failures.append(p.name)
        scales.append((m.scale_x, m.scale_y))
    if url is not None:
        # the scans' mean scale: one check, one point on the chart
        sx, sy = (float(np.mean(v)) for v in zip(*scales, strict=True))
        reason = f"drifted in {name_list(failures)}" if failures else None
        _record_check(url, path, prof, args, "DRIFT" if failures else "OK", reason, {"scale_x": sx, "scale_y": sy})
    if failures:
        raise WorkbenchError(
            f"calibration drifted beyond tolerance in {len(failures)} of {len(args.inputs)} "
            f"({name_list(failures)}): recalibrate"
        )
    log(f"{path.name}: within tolerance on all {len(args.inputs)} inputs")
    return 0
