"""One photo of the part: pose, warps into its view and onto the print, tiles, dense field, figures and verdict."""

from __future__ import annotations

import functools
import gc
import hashlib
import sys
import time
from concurrent.futures import Future, ThreadPoolExecutor
from pathlib import Path

import cv2
import numba
import numpy as np
from PIL import Image

from workbench import progress
from workbench.atomic import safe_name
from workbench.camera import Camera
from workbench.design_dir import Design, read_image
from workbench.errors import WorkbenchError
from workbench.export import png_bytes
from workbench.image_file import exif_orientation, read_file_bytes
from workbench.raster import depth_buffer
from workbench.validate import dense, detection, pictures, print_warp
from workbench.validate.colour import photo_colour
from workbench.validate.films import film_seams, fit_per_film, seam_misregistration, seams_seen
from workbench.validate.landing import film_of_face, photo_landing
from workbench.validate.photo_quality import photo_quality, read_jpeg_quality
from workbench.validate.placement import dense_placement, placed_print
from workbench.validate.pose import PoseError, estimate_pose
from workbench.validate.report import page_names, page_picture
from workbench.validate.rule import (
    MAX_DEFECT_MM2,
    MAX_DELTA_E,
    MAX_RMS_PX,
    MIN_DENSE_WINDOWS,
    MIN_TILES,
    colour_verdict,
    defect_decision,
    photo_verdict,
    placement,
)
from workbench.validate.score import (
    TILE,
    TILE_SIGMA_SHARE,
    _bilinear,
    printed_view,
    score,
    view_surface,
    warp_photo,
)

# the smallest seating applied: twice what the seating is specified to measure a vertex to (0.05 mm,
# or 0.035 % of a part larger than 150 mm)
SEATING_MIN_MM = 0.1
SEATING_MIN_SHARE = 0.0007


def sha256(path: Path) -> str:
    """The file's SHA-256, hex."""
    return hashlib.sha256(path.read_bytes()).hexdigest()


def markers_under_the_part(pose, design: Design, face: np.ndarray | None = None, board=None) -> list[int]:
    """Markers seen where the part, if it sat where the fixture says, would hide them.

    ``face``: the part's face buffer in the undistorted photo camera, when the caller has it
    (seen through ``pose.camera``, the camera composed with the part's motion). ``board``: the
    board-posed camera, through which the markers are seen (default ``pose.camera``: the part
    as designed).
    """
    cam = Camera(pose.camera.K, pose.camera.R, pose.camera.t, pose.camera.width, pose.camera.height)
    if face is None:
        xy, z = cam.project(design.V)
        face, _ = depth_buffer(xy, z, design.F, cam.width, cam.height)
    if board is not None:
        cam = Camera(board.K, board.R, board.t, board.width, board.height)
    fx = design.fixture
    mesh = np.asarray(fx["markers"]["corners_mesh_mm"])
    index = {int(i): k for k, i in enumerate(fx["markers"]["ids"])}
    hidden = []
    for mid in pose.marker_ids:
        k = index.get(int(mid))
        if k is None:
            continue
        pts, _ = cam.project(mesh[k])
        # the whole marker, shrunk a little, inside the part's silhouette
        c = pts.mean(axis=0)
        inner = c + 0.7 * (pts - c)
        ij = np.round(inner).astype(int)
        if ((ij >= 0).all(1) & (ij[:, 0] < cam.width) & (ij[:, 1] < cam.height)).all() and (
            face[ij[:, 1], ij[:, 0]] >= 0
        ).all():
            hidden.append(int(mid))
    return hidden


def stats(values: np.ndarray) -> dict:
    if len(values) == 0:
        return {"median": None, "p95": None, "max": None}
    return {"median": float(np.median(values)), "p95": float(np.percentile(values, 95)), "max": float(values.max())}


def one_photo_at_a_time(fn):
    """``fn`` with BLAS on one thread, the cyclic garbage collector paused and the GIL passed on sooner.

    A photo's linear algebra is small (a 6-column least squares per tile and per step, 3 x 3
    products): on two cores OpenBLAS's second thread, spinning beside OpenCV's and numba's,
    made each tile's least squares 15 to 30 times slower (measured on the shared machine: the
    tiles' stage 2 to 3 times). The collector finds no garbage in a photo's work (none, on the
    demo's photos) but scanned numba's compiler objects again and again as the first photo
    loaded its kernels (0.3 s); what a photo leaves (those objects, the command's caches) is
    then moved out of its way (``gc.freeze``) rather than scanned by the next collection.
    The photo's threads take turns on the GIL every 0.5 ms rather than 5: a thread back from a
    numpy or OpenCV call waits for the turn while another runs Python (the tiles' small arrays
    beside the dense analysis; 300 numpy additions of a million floats took 270 ms beside a
    Python loop at 5 ms, 180 to 230 ms at 0.5 ms, 70 ms alone). BLAS, the collector and the
    turns come back as they were; the figures are the same either way.
    """

    @functools.wraps(fn)
    def one_photo(*args, **kwargs):
        from threadpoolctl import threadpool_limits

        collecting = gc.isenabled()
        gc.disable()
        turn = sys.getswitchinterval()
        sys.setswitchinterval(min(turn, 0.0005))
        try:
            with threadpool_limits(limits=1, user_api="blas"):
                return fn(*args, **kwargs)
        finally:
            sys.setswitchinterval(turn)
            gc.freeze()
            if collecting:
                gc.enable()

    return one_photo


@one_photo_at_a_time
def validate_photo(
    path: Path,
    design: Design,
    profile,
    view_name,
    tolerance_mm,
    cache,
    stem: str | None = None,
    max_defect_mm2: float = MAX_DEFECT_MM2,
    seating="on",
    max_seating_mm: float = 2.0,
    max_delta_e: float = MAX_DELTA_E,
    output_profile: bytes | None = None,
    held: dict | None = None,
    finish: str = "glossy",
) -> tuple[dict, dict, np.ndarray | None, dict]:
    """Score one photo; never raises for a bad photo (its verdict says why).

    ``profile`` is the camera profile, or the reason it cannot be used (every photo is then INVALID).
    ``output_profile``: the ICC profile the colour's soft proof goes through (None: the design's sRGB).
    ``seating``: ``"on"`` measures the part's motion on its plate from this photo
    (:mod:`workbench.validate.seating`) and judges the film on the part where it sits, ``"off"``
    takes the part where the fixture puts it, an ``(R, t)`` pair is a motion measured already.
    ``held``: where the fixture holds the part (``R``, ``t_mm``: a stand that tilts it;
    ``validate --part-rotation-deg``); the seating is measured from there. None: as designed.
    ``finish``: the film's, ``"glossy"`` or ``"matte"``: ink gone that no test tells from light
    is open on a glossy film (``unresolved``: the photo cannot tell it from a glint), a defect on
    a matte one, which adds no light; a slide no test tells from a smooth light is open on both.

    Returns
    -------
    entry : dict
        The photo's part of validation.json.
    files : dict
        File name to bytes (pictures).
    state : (rows, cols) uint8 or None
        The photo's state per print grid pixel (:mod:`workbench.validate.dense`), None
        when the photo was not scored.
    pages : dict
        Picture file name to the JPEG bytes its page of the QA report shows
        (:func:`workbench.validate.report.page_picture`): made here, where the pictures are,
        rather than by the report, which waits for every photo.
    """
    entry: dict = {"photo": str(path), "verdict": "INVALID", "reason": None}  # made relative by run()
    # side threads for what does not need the step before it (two cores: numpy, OpenCV, numba and
    # the encoders release the GIL): the print grid while the photo is read, posed and seated, the
    # view's surface while its z-buffer is drawn, the tiles beside the dense analysis, the pictures'
    # encoding beside their drawing (two of them: the encoding takes longer than the drawing)
    # (numba's thread count is each thread's own: the side threads take the caller's, one in a worker)
    side = ThreadPoolExecutor(
        max_workers=2, thread_name_prefix="validate-photo", initializer=numba.set_num_threads,
        initargs=(numba.get_num_threads(),),
    )  # fmt: skip
    try:
        return _validate_photo(
            path, design, profile, view_name, tolerance_mm, cache, stem, max_defect_mm2, seating, max_seating_mm,
            max_delta_e, output_profile, entry, side, held, finish,
        )  # fmt: skip
    finally:
        # (a job still running, the print grid of a photo that is not scored, finishes on its
        # own: the cache keeps its future for the next photo and the command)
        side.shutdown(wait=False)


def _validate_photo(
    path, design, profile, view_name, tolerance_mm, cache, stem, max_defect_mm2, seating, max_seating_mm,
    max_delta_e, output_profile, entry, side, held=None, finish="glossy",
):  # fmt: skip
    """:func:`validate_photo`, with ``side`` the executor of the work that can go beside the photo's own."""
    files: dict = {}
    if "grid" not in cache and not isinstance(profile, str):
        cache["grid"] = side.submit(design_print_grid, design)
    try:
        if path.is_dir():
            raise WorkbenchError(f"{path}: is a directory, not a photo")
        data = read_file_bytes(path)  # once: its hash, its EXIF orientation, its pixels
        entry["sha256"] = hashlib.sha256(data).hexdigest()
        # turned upright as its EXIF tag says (a phone's photo), as every viewer shows it
        entry["exif_orientation"] = exif_orientation(data)
        photo = read_image(path, "photo", data=data)
    except (OSError, WorkbenchError) as exc:
        entry["reason"] = f"unreadable image: {exc}"
        return entry, files, None, {}
    if isinstance(profile, str):
        entry["reason"] = f"unusable camera profile: {profile}"
        return entry, files, None, {}
    if photo.shape[1] != profile.width or photo.shape[0] != profile.height:
        entry["reason"] = (
            f"photo is {photo.shape[1]} x {photo.shape[0]} px, the camera profile is for "
            f"{profile.width} x {profile.height}"
        )
        return entry, files, None, {}
    clock = [time.perf_counter()]  # stage timings, for the benchmark
    gray = cv2.cvtColor(photo, cv2.COLOR_RGB2GRAY)
    try:
        pose = estimate_pose(gray, design.fixture, profile.K, profile.dist)
    except PoseError as exc:
        entry["reason"] = str(exc)
        return entry, files, None, {}
    entry["pose"] = {
        "R": pose.camera.R.tolist(),
        "t": pose.camera.t.tolist(),
        "camera_center_mm": pose.camera.center.tolist(),
    }
    entry["reprojection_rms_px"] = pose.rms_px
    entry["corners_used"] = pose.n_corners
    entry["corners_dropped"] = pose.n_dropped
    if pose.rms_px > MAX_RMS_PX:
        entry["reason"] = (
            f"reprojection error {pose.rms_px:.2f} px is too high (> {MAX_RMS_PX} px): wrong camera profile?"
        )
        return entry, files, None, {}
    tick(clock, path.name)  # pose
    from workbench.part_motion import seated_camera
    from workbench.validate.seating import seat_photo

    board = pose.camera  # (the fixture's markers are where the board camera sees them, whatever the part does)
    # the part's motion: where the fixture holds it (a stand; as designed by default), then its own
    # seating from there; the camera composed with it sees the design where the part is
    R, t, moved = np.eye(3), np.zeros(3), held is not None
    if moved:
        R, t = np.asarray(held["R"], dtype=np.float64), np.asarray(held["t_mm"], dtype=np.float64)
    if seating == "off":
        entry["seating"] = {"mode": "off"}
    else:
        seat, entry["seating"] = seat_photo(
            photo, board, design, cache, max_seating_mm, None if isinstance(seating, str) else seating, held
        )
        # a motion within what the seating can measure is not applied: its own error (0.005 to
        # 0.06 mm a vertex on real meshes, measured) would move the film measured on a part that
        # sits where the fixture says; a part set down by hand is off by a millimetre
        size = float(np.linalg.norm(design.V.max(axis=0) - design.V.min(axis=0)))
        least = max(SEATING_MIN_MM, SEATING_MIN_SHARE * size)
        entry["seating"]["min_applied_mm"] = round(least, 4)
        entry["seating"]["applied"] = bool(entry["seating"]["largest_vertex_motion_mm"] >= least)
        if entry["seating"]["applied"]:
            # X_photo = Rs (R X + t) + ts
            R, t, moved = seat.R @ R, seat.R @ t + seat.t, True
    if moved:
        pose.camera = seated_camera(board, R, t)
    tick(clock, path.name)  # seating
    views = design.info["views"]
    if view_name is None:
        dists = [np.linalg.norm(np.asarray(_centre(v)) - pose.camera.center) for v in views]
        vi = int(np.argmin(dists))
    else:
        vi = [v["name"] for v in views].index(view_name)
    name = views[vi]["name"]
    if vi not in cache:
        cache[vi] = side.submit(_view, design, vi)
    # one z-buffer of the part in the photo: for this check and for both warps
    face_buffer, depth = print_warp.photo_buffers(pose.camera, design.V, design.F)
    hidden = markers_under_the_part(pose, design, face_buffer, board)
    if hidden:
        entry["reason"] = (
            f"the object is not where the fixture says: marker {hidden[0]} is visible where the part "
            f"should hide it ({len(hidden)} such markers)"
        )
        return entry, files, None, {}
    entry["view"] = name
    surface, view_rgb, printed_rgb = cache[vi] = _done(cache.pop(vi))
    tick(clock, path.name)  # checks and the view
    warped, valid = warp_photo(photo, pose.camera, surface, design.V, design.F, depth)
    p = design.info["print"]
    tick(clock, path.name)  # warps
    # the tiles (the view) beside the print warp and the dense analysis (the print)
    tiles = side.submit(
        _timed, score, view_rgb, warped, valid, surface, (p["image_width_mm"], p["image_height_mm"]), tolerance_mm,
        printed_rgb,
    )  # fmt: skip
    grid = cache["grid"] = _done(cache.pop("grid"))
    pw = print_warp.warp_to_print(photo, pose.camera, grid, design.V, design.F, depth)
    on_print, state, scale, footprint = pw.warped, pw.state, pw.scale, pw.footprint
    tick(clock, path.name)  # print warp
    dr = dense.analyse(
        grid, on_print, state, tolerance_mm, scale, footprint, pose.camera.center, pw.footprint_axes, finish
    )
    sc, tiles_s = tiles.result()
    px_mag = np.linalg.norm(sc.shift_px, axis=1) if len(sc.shift_px) else np.zeros(0)
    entry.update(
        {
            "misregistration_mm": stats(sc.shift_mm),
            "misregistration_uncertainty_mm": float(np.median(sc.sigma_mm)) if len(sc.sigma_mm) else None,
            "misregistration_px": stats(px_mag),
            "tiles": int(len(sc.shift_mm)),
            # (beyond the tolerance by more than SIGNIFICANCE_Z of their own uncertainty)
            "tiles_beyond": int((sc.shift_mm - dense.SIGNIFICANCE_Z * sc.sigma_mm > tolerance_mm).sum()),
            "tiles_examined": sc.tiles_examined,
            "ssim": sc.ssim,
            "coverage": sc.coverage,
            "blur_px": sc.blur_px,
            "film_offset_mm": sc.film.get("offset_mm"),
            "film_rotation_deg": sc.film.get("rotation_deg"),
            "film_scale_pct": sc.film.get("scale_pct"),
            "film_fit_rms_mm": sc.film.get("rms_mm"),
        }
    )
    if design.info.get("films"):
        # several films: each film's placement from its own tiles
        films = design.info["films"]
        entry["films"] = fit_per_film(sc, surface, films, p["dpi"] / 25.4)
        # the seams this photo shows: how far apart the two films' inks land there
        if "seams" not in cache:
            cache["seams"] = film_seams(design.V, design.F, design.flat, p["height_mm"], films)
        edges = cache["seams"]
        seen = seams_seen(edges.X, design.view_camera(name), surface, valid)
        entry["seams"] = seam_misregistration(edges, entry["films"], films, p["dpi"] / 25.4, seen)
    entry["misregistration_source"] = "tiles"
    if len(sc.shift_mm) < MIN_TILES:
        # too few tiles: the dense field measures placement where its pixels measure the full
        # vector or the component across an edge (each within a third of the tolerance, as for
        # its defects), when together they hold MIN_DENSE_WINDOWS independent windows and place
        # the film as accurately as a tile: within TILE_SIGMA_SHARE of the tolerance
        place = dense_placement(
            dr, grid, tolerance_mm / dense.SIGNIFICANCE_Z, (p["image_width_mm"], p["image_height_mm"])
        )
        entry["dense_windows"] = round(place["windows"], 1)
        fit_sigma = place["uncertainty_mm"]
        entry["dense_placement_uncertainty_mm"] = round(fit_sigma, 4) if np.isfinite(fit_sigma) else None
        film = place["film"]
        if film is not None and place["windows"] >= MIN_DENSE_WINDOWS and fit_sigma <= TILE_SIGMA_SHARE * tolerance_mm:
            entry.update(
                {
                    "misregistration_source": "dense",
                    "misregistration_mm": stats(place["shift_mm"]),
                    "misregistration_uncertainty_mm": float(np.nanmedian(dr.sigma_mm)),
                    "film_offset_mm": film["offset_mm"],
                    "film_rotation_deg": film["rotation_deg"],
                    "film_scale_pct": film["scale_pct"],
                    "film_fit_rms_mm": film["rms_mm"],
                }
            )
        else:
            entry["misregistration_source"] = None
    tick(clock, path.name)  # dense analysis
    # (the ink's colour where no lamp is mirrored towards the camera: a glossy film's sheen adds
    # light below any glint within the lamp's mirror cone, and the chart, seen apart, carries none;
    # leaving the cone out took perfect glossy renders of the cow, the lily and the face under a
    # lamp from 4.6, 8.3 and 5.3 ΔE00 without the shading to 3.3, 4.4 and 3.4)
    colour_state = dr.state
    if dr.lamp_cone is not None and dr.lamp_cone.any():
        colour_state = np.where(dr.lamp_cone, np.uint8(print_warp.HIGHLIGHT), dr.state).astype(np.uint8)
    # (the ink's colour where the film is: a film placed 0.8 mm off, compared where the design puts
    # each ink, read every edge of its print as a colour difference, 7.6 ΔE00 on the demo's part;
    # its placement is judged, and reported, as placement)
    placed = None if dr.placement_px is None else placed_print(grid.reference, dr.placement_px)
    entry["colour"], de_map, seen_colour = photo_colour(
        photo, pose.camera, design, grid, on_print, colour_state, footprint, depth, output_profile, reference=placed
    )
    entry["colour"]["verdict"] = colour_verdict(entry["colour"], max_delta_e)[0]
    seen = state >= print_warp.GRAZING
    entry["photo_quality"] = photo_quality(photo, on_print, grid.reference, seen, read_jpeg_quality(path))
    tick(clock, path.name)  # colour
    entry["dense"] = dense_summary(dr, grid, design, sc, surface)
    # arrays: the command moves them to landing.npz; a photo at fault lands nothing
    entry["landing"] = (
        None
        if entry["photo_quality"]["problems"]
        # (the calibration film's pattern is locally unique: its rim is measured too)
        else photo_landing(dr, grid, film_of_face(design.info, len(design.F)), scale, rim="pattern" in design.info)
    )
    if de_map is not None and not entry["photo_quality"]["problems"]:
        # (the part judges its colour pixel by pixel from the photo that sees each most squarely)
        entry["colour_maps"] = {"delta_e00": de_map, **seen_colour}
    if not entry["photo_quality"]["problems"]:
        entry["detection_maps"] = {
            "shift_limit_um": detection.to_stored(dr.shift_limit_mm),
            "slide_sigma_um": detection.to_stored(dr.shift_sigma_mm),
            "window_sigma_um": detection.to_stored(dr.window_sigma_mm),
            "dropout": dr.dropout_found.astype(np.uint8),
            "scratch": dr.scratch_found.astype(np.uint8),
        }
        # (what the flow measured of the film's slide: the part compares its photos' measures)
        entry["slide_measure"] = dr.slide
    entry["defects"] = defect_entries(dr, grid, design, pose.camera)
    # ink gone, or a slide, that no test told from light is open: the photo cannot tell it. Ink
    # gone on a glossy film (its colour is the ink's with a glint added as well as the film's);
    # on a matte one, which adds no light, it is ink gone (what the model of its diffuse light
    # misses, interreflections and cast shadows, scales the ink, and dark ink never reaches the
    # film's white: the photometric model weighs that gain, docs/validation.md). A slide
    # on either: its residual is a smooth light's as well, and a smooth light is what the matte
    # film's shading model misses too (the scanned face's perfect photo, the lens look: a
    # 0.48 mm "slide" over 61 mm² of skin-smooth artwork, where moving the print explained 10 %
    # of what a smooth light leaves, once the print was blurred as the photo is). (Its detection
    # maps still state the defect flagged there: found, or open, and an open region never lets
    # the part pass.)
    for d in entry["defects"]:
        if d.get("told") is False and (finish == "glossy" or d["kind"] == "shift"):
            d["unresolved"] = True
    for d in entry["defects"]:
        d["decided_by"] = defect_decision(d, max_defect_mm2)
    # the regions taken for light, and the test that took each
    entry["not_counted"] = dr.not_counted or []
    entry["placement"] = placement(entry, tolerance_mm)
    entry["verdict"], entry["reason"] = photo_verdict(entry, tolerance_mm, max_defect_mm2, max_delta_e)
    tick(clock, path.name)  # summary
    stem = stem or safe_name(path.stem)
    entry["pictures"] = stem  # the name the warped photo, overlay and heat map start with

    def encoded(img: np.ndarray):
        # (light compression, one PNG filter: level 3 and libpng's search for the best filter of
        # each row cost a few tenths of a second per photo)
        return side.submit(png_bytes, img, compression=1, fast=True)

    files[f"{stem}_warped_{name}.png"] = encoded(warped)
    overlay = view_rgb.copy()
    overlay[valid] = (0.5 * view_rgb[valid] + 0.5 * warped[valid]).astype(np.uint8)
    files[f"{stem}_overlay_{name}.png"] = encoded(overlay)
    files[f"{stem}_heatmap_{name}.png"] = encoded(
        pictures.tile_heatmap(view_rgb, sc, f"{path.name} in view {name}: {entry['verdict']}")
    )
    files[f"{stem}_defects_print.png"] = encoded(
        pictures.defects_on_print(dr.warped, dr.labels, dr.defects, grid.px_per_mm)
    )
    dense_map = pictures.dense_heatmap(
        grid.reference,
        dr.shift_mm,
        dr.labels,
        grid.px_per_mm,
        2 * tolerance_mm,
        f"{path.name} on the print: dense misregistration (the tolerance is mid-scale), defects outlined",
    )
    # over what the part shows from the view (the print), not the view's own image: where another
    # view decorates, the view's image is not on the part
    as_printed = pictures.print_seen_from_view(design.rgb, surface.print_mm, p["dpi"] / 25.4, view_rgb)
    in_view = pictures.defects_on_image(
        as_printed, pictures.labels_in_view(dr.labels, surface.print_mm, grid.px_per_mm)
    )
    centres = np.array([d["photo_px"] for d in entry["defects"]], dtype=np.float64).reshape(-1, 2)
    radii = np.array([d["photo_radius_px"] for d in entry["defects"]], dtype=np.float64)
    # the part, not the whole fixture: the photo cropped to the part's outline and a margin
    x0, y0, x1, y1 = part_box(pose.camera, design.V, photo.shape[:2])
    circled = pictures.photo_circled(photo[y0:y1, x0:x1], centres - [x0, y0], radii)
    files[f"{stem}_dense_print.png"] = encoded(dense_map)
    files[f"{stem}_defects_{name}.png"] = encoded(in_view)
    files[f"{stem}_defects_photo.png"] = encoded(circled)
    shown = (dense_map, circled, in_view)
    pages = {k: side.submit(_page, img) for k, img in zip(page_names(stem, name), shown, strict=True)}
    detectable = pictures.detectable_print(
        grid.reference, dr.shift_limit_mm, dr.dropout_found, grid.px_per_mm, tolerance_mm, dr.scratch_found
    )
    files[f"{stem}_detectable_print.png"] = encoded(detectable)
    pages[f"{stem}_detectable_print.png"] = side.submit(_page, detectable)
    if de_map is not None:
        shown_de = pictures.colour_difference(grid.reference, de_map, grid.px_per_mm, 2 * max_delta_e)
        files[f"{stem}_colour_print.png"] = encoded(shown_de)
        pages[f"{stem}_colour_print.png"] = side.submit(_page, shown_de)
    files.update({k: v.result() for k, v in files.items()})
    pages.update({k: v.result() for k, v in pages.items()})
    tick(clock, path.name)  # pictures
    # each stage's seconds on the photo's own thread; the tiles ran beside the print warp and the
    # dense analysis (their own seconds: the stages then add up to more than the photo's)
    timings = {k: round(b - a, 3) for k, a, b in zip(STAGES, clock[:-1], clock[1:], strict=True)}
    timings = {**dict(list(timings.items())[:4]), "tiles": round(tiles_s, 3), **dict(list(timings.items())[4:])}
    entry["timings_s"] = timings
    # a photo at fault says nothing of the part's print: neither its coverage nor its defects count
    return entry, files, None if entry["photo_quality"]["problems"] else dr.state, pages


# a photo's stages, in order: each one's seconds in its entry's timings_s, and a progress line at its end
STAGES = (
    *("pose", "seating", "checks and view", "view warp", "print warp"),
    *("dense analysis", "colour", "figures and verdict", "pictures"),
)


def tick(clock: list[float], photo: str) -> None:
    """The end of a photo's next stage: its time on ``clock`` and, on a terminal, a progress line."""
    clock.append(time.perf_counter())
    k = len(clock) - 2
    progress.say(f"{photo}: {STAGES[k]} done ({k + 1}/{len(STAGES)}, {clock[-1] - clock[-2]:.1f} s)")


def part_box(cam: Camera, V: np.ndarray, shape: tuple[int, int], margin: float = 0.1) -> tuple[int, int, int, int]:
    """The part's box in a photo: its vertices projected, widened by ``margin`` of its size on each side.

    Parameters
    ----------
    cam : Camera
        The photo's camera, the part where it sits (lens distortion aside: the margin covers it).
    V : (n, 3) float
        The part's vertices, mm.
    shape : (rows, cols)
        The photo's size, px.
    margin : float
        Share of the box's width and height added on each side.

    Returns
    -------
    (x0, y0, x1, y1) : int
        Column and row bounds (end exclusive), within the photo; the whole photo when the part
        does not project into it.
    """
    rows, cols = shape
    xy, z = cam.project(V)
    px = xy[(z > 0) & np.isfinite(xy).all(axis=1)]
    if not len(px):
        return 0, 0, cols, rows
    lo, hi = px.min(axis=0), px.max(axis=0)
    pad = margin * (hi - lo)
    x0, y0 = np.floor(np.clip(lo - pad, 0, [cols, rows])).astype(int)
    x1, y1 = np.ceil(np.clip(hi + pad, 0, [cols, rows])).astype(int)
    if x1 - x0 < 8 or y1 - y0 < 8:
        return 0, 0, cols, rows
    return int(x0), int(y0), int(x1), int(y1)


def _done(value):
    """A cached value, waited for when a side thread is still making it (the caller pops it from the
    cache first: a job that failed is then made again by the next photo, as before)."""
    return value.result() if isinstance(value, Future) else value


def _timed(fn, *args):
    """``fn(*args)`` and its seconds."""
    t0 = time.perf_counter()
    out = fn(*args)
    return out, time.perf_counter() - t0


def _page(rgb: np.ndarray) -> bytes:
    """A picture as a photo's page of the QA report embeds it (:func:`page_picture`)."""
    return page_picture(Image.fromarray(rgb))


def design_print_grid(design: Design) -> print_warp.PrintGrid:
    """The print's analysis grid of ``design``, its films labelled (:func:`print_warp.print_grid`)."""
    p = design.info["print"]
    return print_warp.print_grid(
        design.V, design.F, design.flat, p["height_mm"], design.rgb, p["dpi"], design.owner,
        film_of_face(design.info, len(design.F)),
    )  # fmt: skip


def print_grid_of(cache: dict) -> print_warp.PrintGrid | None:
    """The print grid the photos of one command made (None when none did)."""
    if "grid" in cache:
        cache["grid"] = _done(cache.pop("grid"))
    return cache.get("grid")


def _view(design: Design, vi: int) -> tuple:
    """A designed view's surface (:func:`view_surface`), its image and its image as the print carries it."""
    cam = design.view_camera(design.info["views"][vi]["name"])
    p = design.info["print"]
    surface = view_surface(cam, design.V, design.F, design.flat, p["height_mm"], design.owner, vi, p["dpi"] / 25.4)
    image = design.view_image(vi)
    return surface, image, printed_view(surface, design.rgb, p["dpi"] / 25.4, image)


def dense_summary(dr, grid, design: Design, sc, surface) -> dict:
    """The dense field's figures: misregistration, agreement with the tiles, coverage of every view."""
    full = dr.texture == 2  # (a defect pixel keeps what its texture lets the flow know)
    measured_shift = np.isfinite(dr.shift_mm)
    agree = {"tiles": 0, "median_mm": None, "p95_mm": None}
    if len(sc.centres):
        c, d = sc.centres, sc.shift_px
        p0 = _bilinear(surface.print_mm, c[:, 0], c[:, 1])
        p1 = _bilinear(surface.print_mm, c[:, 0] + d[:, 0], c[:, 1] + d[:, 1])
        # each tile's footprint on the print: the box of its corners' print points
        h = (TILE - 1) / 2
        corners = [_bilinear(surface.print_mm, c[:, 0] + sx * h, c[:, 1] + sy * h) for sx in (-1, 1) for sy in (-1, 1)]
        corners = np.stack(corners, axis=1)
        boxes = np.concatenate([corners.min(axis=1), corners.max(axis=1)], axis=1)
        ok = np.isfinite(p0).all(1) & np.isfinite(p1).all(1) & np.isfinite(boxes).all(1)
        agree = dense.agreement(dr.flow_px, dr.texture == 2, grid.px_per_mm, p0[ok], p1[ok], boxes[ok])
    return {
        "grid_px_per_mm": grid.px_per_mm,
        "blur_px": dr.blur_px,
        "noise_grey_levels": dr.noise,
        "uncertainty_mm": stats(dr.sigma_mm[np.isfinite(dr.sigma_mm)]),
        "significance_z": dense.SIGNIFICANCE_Z,
        "resolution": dr.resolution,
        "detection_limit": dr.detection_limit,
        "misregistration_mm": stats(dr.shift_mm[measured_shift]),
        "misregistration_full_vector_mm": stats(dr.shift_mm[full & measured_shift]),
        "note": (
            "misregistration per print pixel from dense optical flow; where the texture has one direction only "
            "(along an edge) the component across the edge is reported (state 'normal'), where it has none only "
            "the colour is scored"
        ),
        "agreement_with_tiles_mm": agree,
        "coverage": dense.coverage_by_view(dr.state, grid.owner, [v["name"] for v in design.info["views"]]),
    }


def defect_entries(dr, grid, design: Design, cam: Camera) -> list[dict]:
    """Defects for validation.json: on the print (mm), in which view's region, and where in the photo."""
    names = [v["name"] for v in design.info["views"]]
    out = []
    rvec = cv2.Rodrigues(cam.R)[0]
    for k, d in enumerate(dr.defects):
        ii, jj = np.nonzero(dr.labels == k + 1)
        X = grid.X[ii, jj]
        X = X[np.isfinite(X).all(1)]
        c_ij = (
            min(max(int(d["centre_mm"][1] * grid.px_per_mm), 0), grid.owner.shape[0] - 1),
            min(max(int(d["centre_mm"][0] * grid.px_per_mm), 0), grid.owner.shape[1] - 1),
        )
        vi = int(grid.owner[c_ij])
        px = np.full(2, np.nan)
        radius = area_px2 = 0.0
        if len(X):
            proj, _ = cv2.projectPoints(np.ascontiguousarray(X[:: max(1, len(X) // 500)]), rvec, cam.t, cam.K, cam.dist)
            proj = proj.reshape(-1, 2)
            px = proj.mean(axis=0)
            radius = float(np.linalg.norm(proj - px, axis=1).max())
            # (its area in the photo: the hull of its projected points, foreshortened where the photo sees it obliquely)
            if len(proj) >= 3:
                area_px2 = float(cv2.contourArea(cv2.convexHull(proj.astype(np.float32))))
        out.append(
            {
                "id": k + 1,
                **{key: v for key, v in d.items()},
                "view": names[vi] if vi >= 0 else None,
                "photo_px": px.tolist(),
                "photo_radius_px": radius,
                "photo_area_px2": round(area_px2, 1),
            }
        )
    return out


def _centre(view: dict) -> list:
    c = view["camera"]
    return (-np.asarray(c["R"]).T @ np.asarray(c["t"])).tolist()
