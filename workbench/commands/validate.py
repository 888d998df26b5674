"""``workbench validate``: photos of the decorated part, posed on the fixture, scored against each view."""

from __future__ import annotations

import hashlib
import io
import json
import os
import sys
import time
from concurrent.futures import ProcessPoolExecutor
from multiprocessing import get_context
from pathlib import Path

import cv2
import numpy as np
from PIL import Image

from workbench import __version__
from workbench.atomic import check_output_dir, check_outputs, safe_name, write_folder
from workbench.camera import Camera, load_camera_profile
from workbench.design_dir import Design, design_files, read_image
from workbench.errors import UsageError, WorkbenchError
from workbench.export import png_bytes
from workbench.jsonfile import recorded_path
from workbench.options import Number
from workbench.raster import depth_buffer
from workbench.validate import dense, pictures
from workbench.validate.films import film_seams, fit_per_film, seam_misregistration, seams_seen
from workbench.validate.pose import PoseError, estimate_pose
from workbench.validate.report import page_names, page_picture, qa_report
from workbench.validate.score import TILE, _bilinear, score, view_surface, warp_photo

MAX_RMS_PX = 1.0
MIN_TILES = 5
MIN_SSIM = 0.5
# share of the textured tiles of the view's region that must match the design: a decoration
# painted over or torn in part matches where it is intact and nowhere else (measured: 41 % of
# the tiles for half the part painted over, 82 % and more for an intact film 2 mm off)
MIN_MATCHED_SHARE = 0.7
MAX_DEFECT_MM2 = 4.0


def verdict_rule(tolerance_mm: float, max_defect_mm2: float) -> dict:
    """The acceptance rule, as it goes into validation.json and the QA report."""
    return {
        "text": (
            f"FAIL when any defect is larger than {max_defect_mm2:g} mm² on the print, or the misregistration "
            f"p95 (tiles) exceeds {tolerance_mm:g} mm, or the decoration does not match the design (fewer than "
            f"{MIN_TILES} tiles match, or SSIM < {MIN_SSIM}, or fewer than {100 * MIN_MATCHED_SHARE:.0f} % of the "
            "view's textured tiles match); otherwise PASS. A defect is a connected region of "
            f"at least {dense.MIN_DEFECT_MM2:g} mm² where the dense misregistration exceeds {tolerance_mm:g} mm, "
            f"or where the colour differs from the design by more than {dense.COLOUR_TOL:g} grey levels after a "
            "local gain and offset fit per channel and a blur matched to the photo. Highlights, deep shadows, "
            "surface turned away from the camera and the photo's pixels along the part's outline and its folds "
            "are masked, not scored."
        ),
        "tolerance_mm": tolerance_mm,
        "max_defect_mm2": max_defect_mm2,
        "min_defect_mm2": dense.MIN_DEFECT_MM2,
        "colour_tolerance_grey_levels": dense.COLOUR_TOL,
        "min_tiles": MIN_TILES,
        "min_ssim": MIN_SSIM,
        "min_matched_tile_share": MIN_MATCHED_SHARE,
    }


def add_parser(sub) -> None:
    p = sub.add_parser(
        "validate",
        help="score photos of the decorated part against the designed views; QA report",
        description=(
            "For each photo: pose from the fixture's markers, the photo warped into the designed view through "
            "the mesh, misregistration (px in the view, mm on the surface), similarity, coverage, the film "
            "placement error that explains it, and a verdict (PASS, FAIL, or INVALID with the reason). Writes "
            "validation.json, per photo the warped photo, an overlay and a heat map, and qa_report.pdf."
        ),
    )
    p.add_argument("design", metavar="DESIGN_DIR")
    p.add_argument("photos", metavar="PHOTO", nargs="+")
    p.add_argument("--camera", metavar="PROFILE.json", required=True, help="camera profile: K, dist, image_size")
    p.add_argument("--view", metavar="NAME", help="compare with this view (default: the view nearest each photo)")
    p.add_argument(
        "--tolerance-mm",
        action=Number,
        lo=0,
        lo_open=True,
        hi=1000,
        unit="mm",
        default=0.5,
        help="largest accepted misregistration, p95 (default 0.5)",
    )
    p.add_argument(
        "--max-defect-mm2",
        action=Number,
        lo=0,
        lo_open=True,
        hi=1e6,
        unit="mm²",
        default=MAX_DEFECT_MM2,
        help=f"largest accepted local defect, area on the print in mm² (default {MAX_DEFECT_MM2:g})",
    )
    p.add_argument(
        "--jobs",
        action=Number,
        lo=0,
        hi=1024,
        integer=True,
        default=0,
        help="photos scored in parallel, one process each (default: every core; 1: in this process)",
    )
    p.add_argument("--out", metavar="DIR", help="output directory (default: DESIGN_DIR/validation)")
    p.add_argument("-q", "--quiet", action="store_true")
    p.set_defaults(run=run)


def _sha(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def markers_under_the_part(pose, design: Design, face: np.ndarray | None = None) -> list[int]:
    """Markers seen where the part, if it sat where the fixture says, would hide them.

    ``face``: the part's face buffer in the undistorted photo camera, when the caller has it.
    """
    cam = Camera(pose.camera.K, pose.camera.R, pose.camera.t, pose.camera.width, pose.camera.height)
    if face is None:
        xy, z = cam.project(design.V)
        face, _ = depth_buffer(xy, z, design.F, cam.width, cam.height)
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


def heatmap_png(design_rgb, sc, title: str) -> bytes:
    """The view's image in grey with each tile coloured by its misregistration (mm), and a colour bar."""
    from workbench.figures import _figure, figure_png

    plt = _figure()
    grey = cv2.cvtColor(cv2.cvtColor(design_rgb, cv2.COLOR_RGB2GRAY), cv2.COLOR_GRAY2RGB)
    H, W = grey.shape[:2]
    fig, ax = plt.subplots(figsize=(8, 8 * H / W + 0.6), dpi=100)
    ax.imshow(grey, alpha=0.6)
    vmax = max(float(sc.shift_mm.max()) if len(sc.shift_mm) else 0.1, 0.1)
    sca = ax.scatter(
        sc.centres[:, 0], sc.centres[:, 1], c=sc.shift_mm, cmap="inferno", vmin=0, vmax=vmax, s=60, marker="s"
    )
    if len(sc.centres):
        ax.quiver(
            sc.centres[:, 0],
            sc.centres[:, 1],
            sc.shift_px[:, 0],
            -sc.shift_px[:, 1],
            color="cyan",
            angles="xy",
            scale_units="xy",
            scale=0.05,
            width=0.002,
        )
    fig.colorbar(sca, ax=ax, fraction=0.046, pad=0.04).set_label("misregistration on the surface (mm)")
    ax.set_title(title, fontsize=9)
    ax.set_axis_off()
    return figure_png(fig)


def output_stems(photos: list[Path]) -> list[str]:
    """One distinct, safe file-name stem per photo, for its pictures in the output folder.

    The photo's own stem where it is unique; photos of one name from different folders
    get their folder's name in front, and what still collides its position in the list.
    Characters other than letters, digits, ``.``, ``_`` and ``-`` become ``_``, so that no
    name leaves the output folder.
    """
    own = [safe_name(p.stem) for p in photos]
    stems = [
        safe_name(f"{p.resolve().parent.name}_{p.stem}") if own.count(s) > 1 else s
        for p, s in zip(photos, own, strict=True)
    ]
    return [f"{s}-{k + 1}" if stems.count(s) > 1 else s for k, s in enumerate(stems)]


def validate_photo(
    path: Path,
    design: Design,
    profile,
    view_name,
    tolerance_mm,
    cache,
    stem: str | None = None,
    max_defect_mm2: float = MAX_DEFECT_MM2,
) -> tuple[dict, dict, np.ndarray | None, dict]:
    """Score one photo; never raises for a bad photo (its verdict says why).

    ``profile`` is the camera profile, or the reason it cannot be used (every photo is then INVALID).

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
    files: dict = {}
    try:
        if path.is_dir():
            raise WorkbenchError(f"{path}: is a directory, not a photo")
        entry["sha256"] = _sha(path)
        photo = read_image(path, "photo")
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
    if pose.rms_px > MAX_RMS_PX:
        entry["reason"] = (
            f"reprojection error {pose.rms_px:.2f} px is too high (> {MAX_RMS_PX} px): wrong camera profile?"
        )
        return entry, files, None, {}
    # one z-buffer of the part in the photo: for this check and for both warps
    face_buffer, depth = dense.photo_buffers(pose.camera, design.V, design.F)
    hidden = markers_under_the_part(pose, design, face_buffer)
    if hidden:
        entry["reason"] = (
            f"the object is not where the fixture says: marker {hidden[0]} is visible where the part "
            f"should hide it ({len(hidden)} such markers)"
        )
        return entry, files, None, {}
    views = design.info["views"]
    if view_name is None:
        dists = [np.linalg.norm(np.asarray(_centre(v)) - pose.camera.center) for v in views]
        vi = int(np.argmin(dists))
    else:
        vi = [v["name"] for v in views].index(view_name)
    name = views[vi]["name"]
    entry["view"] = name
    if vi not in cache:
        cam = design.view_camera(name)
        p = design.info["print"]
        cache[vi] = (
            view_surface(cam, design.V, design.F, design.flat, p["height_mm"], design.owner, vi, p["dpi"] / 25.4),
            design.view_image(vi),
        )
    surface, view_rgb = cache[vi]
    clock.append(time.perf_counter())  # pose
    warped, valid = warp_photo(photo, pose.camera, surface, design.V, design.F, depth)
    p = design.info["print"]
    clock.append(time.perf_counter())  # warps
    sc = score(view_rgb, warped, valid, surface, (p["image_width_mm"], p["image_height_mm"]))
    if "grid" not in cache:
        cache["grid"] = dense.print_grid(
            design.V, design.F, design.flat, p["height_mm"], design.rgb, p["dpi"], design.owner
        )
    grid = cache["grid"]
    clock.append(time.perf_counter())  # tiles
    on_print, state, scale = dense.warp_to_print(photo, pose.camera, grid, design.V, design.F, depth)
    clock.append(time.perf_counter())  # print warp
    dr = dense.analyse(grid, on_print, state, tolerance_mm, scale)
    px_mag = np.linalg.norm(sc.shift_px, axis=1) if len(sc.shift_px) else np.zeros(0)
    entry.update(
        {
            "misregistration_mm": stats(sc.shift_mm),
            "misregistration_px": stats(px_mag),
            "tiles": int(len(sc.shift_mm)),
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
    clock.append(time.perf_counter())  # dense analysis
    entry["dense"] = dense_summary(dr, grid, design, sc, surface)
    entry["defects"] = defect_entries(dr, grid, design, pose.camera)
    big = [d for d in entry["defects"] if d["area_mm2"] > max_defect_mm2]
    if len(sc.shift_mm) < MIN_TILES or sc.ssim < MIN_SSIM:
        entry["verdict"] = "FAIL"
        entry["reason"] = (
            f"the decoration does not match the design (SSIM {sc.ssim:.2f}, {len(sc.shift_mm)} tiles "
            "matched): wrong print, or badly damaged"
        )
    elif len(sc.shift_mm) < MIN_MATCHED_SHARE * sc.tiles_examined:
        entry["verdict"] = "FAIL"
        entry["reason"] = (
            f"only {len(sc.shift_mm)} of {sc.tiles_examined} textured tiles match the design: part of the "
            "decoration is missing, covered or damaged"
        )
    else:
        p95 = entry["misregistration_mm"]["p95"]
        why = []
        if p95 > tolerance_mm:
            why.append(f"misregistration p95 {p95:.3f} mm > tolerance {tolerance_mm} mm")
        if big:
            d = big[0]
            why.append(
                f"{len(big)} defect{'s' if len(big) > 1 else ''} > {max_defect_mm2:g} mm² (largest: {d['kind']}, "
                f"{d['area_mm2']:.1f} mm² at ({d['centre_mm'][0]:.1f}, {d['centre_mm'][1]:.1f}) mm on the print)"
            )
        entry["verdict"] = "FAIL" if why else "PASS"
        entry["reason"] = "; ".join(why) or (
            f"misregistration p95 {p95:.3f} mm <= tolerance {tolerance_mm} mm, "
            + (
                f"no defect > {max_defect_mm2:g} mm²"
                if not entry["defects"]
                else f"{len(entry['defects'])} defect(s), none > {max_defect_mm2:g} mm²"
            )
        )
    clock.append(time.perf_counter())  # summary
    stem = stem or safe_name(path.stem)
    entry["pictures"] = stem  # the name the warped photo, overlay and heat map start with
    overlay = view_rgb.copy()
    overlay[valid] = (0.5 * view_rgb[valid] + 0.5 * warped[valid]).astype(np.uint8)
    files[f"{stem}_warped_{name}.png"] = png_bytes(warped)
    files[f"{stem}_overlay_{name}.png"] = png_bytes(overlay)
    files[f"{stem}_heatmap_{name}.png"] = heatmap_png(view_rgb, sc, f"{path.name} in view {name}: {entry['verdict']}")
    # light compression for the pictures: level 3 costs a few tenths of a second per photo
    files[f"{stem}_defects_print.png"] = png_bytes(
        pictures.defects_on_print(dr.warped, dr.labels, dr.defects, grid.px_per_mm), compression=1
    )
    dense_png = pictures.dense_heatmap(
        grid.reference,
        dr.shift_mm,
        dr.labels,
        grid.px_per_mm,
        2 * tolerance_mm,
        f"{path.name} on the print: dense misregistration (the tolerance is mid-scale), defects outlined",
    )
    in_view = pictures.defects_on_image(view_rgb, pictures.labels_in_view(dr.labels, surface.print_mm, grid.px_per_mm))
    centres = np.array([d["photo_px"] for d in entry["defects"]], dtype=np.float64).reshape(-1, 2)
    radii = np.array([d["photo_radius_px"] for d in entry["defects"]], dtype=np.float64)
    circled = pictures.photo_circled(photo, centres, radii)
    files[f"{stem}_dense_print.png"] = dense_png
    files[f"{stem}_defects_{name}.png"] = png_bytes(in_view, compression=1)
    files[f"{stem}_defects_photo.png"] = png_bytes(circled, compression=1)
    shown = (Image.open(io.BytesIO(dense_png)), Image.fromarray(circled), Image.fromarray(in_view))
    pages = {k: page_picture(img) for k, img in zip(page_names(stem, name), shown, strict=True)}
    clock.append(time.perf_counter())  # pictures
    stages = ("pose", "view warp", "tiles", "print warp", "dense analysis", "figures and verdict", "pictures")
    entry["timings_s"] = {k: round(b - a, 3) for k, a, b in zip(stages, clock[:-1], clock[1:], strict=True)}
    return entry, files, dr.state, pages


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
        "misregistration_mm": stats(dr.shift_mm[measured_shift]),
        "misregistration_full_vector_mm": stats(dr.shift_mm[full & measured_shift]),
        "note": (
            "misregistration per print pixel from dense optical flow; where the texture has one direction only "
            "(along an edge) the component across the edge is reported (state 'normal'), where it has none only "
            "the colour is scored"
        ),
        "agreement_with_tiles_mm": agree,
        "coverage": coverage_by_view(dr.state, grid.owner, [v["name"] for v in design.info["views"]]),
    }


def coverage_by_view(state: np.ndarray, owner: np.ndarray, names: list[str]) -> dict:
    """Per view, the shares of its own region on the print: measured (colour, shift) and unmeasured by reason."""
    out = {}
    for vi, name in enumerate(names):
        own = state[owner == vi]
        n = max(len(own), 1)
        out[name] = {
            "measured": float(np.isin(own, dense.MEASURED).sum() / n),
            "shift_measured": float(np.isin(own, (dense.NORMAL, dense.FULL, dense.DEFECT)).sum() / n),
            "shift_full_vector": float(np.isin(own, (dense.FULL, dense.DEFECT)).sum() / n),
            "defective": float((own == dense.DEFECT).sum() / n),
            "unmeasured": {
                dense.STATE_NAMES[k]: float((own == k).sum() / n)
                for k in range(dense.COLOUR_ONLY)
                if k != dense.OFF_PART and (own == k).any()
            },
        }
    return out


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
        radius = 0.0
        if len(X):
            proj, _ = cv2.projectPoints(np.ascontiguousarray(X[:: max(1, len(X) // 500)]), rvec, cam.t, cam.K, cam.dist)
            proj = proj.reshape(-1, 2)
            px = proj.mean(axis=0)
            radius = float(np.linalg.norm(proj - px, axis=1).max())
        out.append(
            {
                "id": k + 1,
                **{key: v for key, v in d.items()},
                "view": names[vi] if vi >= 0 else None,
                "photo_px": px.tolist(),
                "photo_radius_px": radius,
            }
        )
    return out


def _centre(view: dict) -> list:
    c = view["camera"]
    return (-np.asarray(c["R"]).T @ np.asarray(c["t"])).tolist()


_WORKER: dict = {}


def _one_thread() -> None:
    # one process per core, each on one thread: with their own thread pools too, two photos
    # at once oversubscribe the cores (measured here: every stage two to three times slower)
    import numba

    cv2.setNumThreads(1)
    numba.set_num_threads(1)


def _init_worker(design_dir: str, camera: str) -> None:
    """A spawned worker: loads the design and the camera profile itself."""
    _one_thread()
    _WORKER.update(design=Design(Path(design_dir)), profile=usable_profile(Path(camera)), cache={})


def _adopt(design: Design, profile, cache: dict) -> None:
    """A forked worker: keeps the parent's design, profile and print grid (shared, copy on write).

    OpenCV is on one thread already (see :func:`validate_in_pool`): reconfiguring its pool here
    would wait forever for the parent's pool threads, which a fork does not copy.
    """
    import numba

    numba.set_num_threads(1)
    _WORKER.update(design=design, profile=profile, cache=cache)


def validate_in_pool(jobs: int, work: list[tuple], design: Design, profile, profile_path: Path, cache: dict) -> list:
    """Photos scored by ``jobs`` worker processes, each on one thread; results in the photos' order.

    Processes, not threads: most of the work holds the GIL between numpy calls. The results
    come back in the order of ``work``, so the outputs do not depend on the scheduling.
    Where :func:`fork_is_safe`, the workers are forked once this process has what every photo
    needs (the print grid, which the part's summary needs here too, and matplotlib for the heat
    maps), and ``cache`` then holds the grid; elsewhere they are spawned and load the design.
    """
    if not fork_is_safe():
        context, initargs = get_context("spawn"), (str(design.dir), str(profile_path))
        with ProcessPoolExecutor(jobs, mp_context=context, initializer=_init_worker, initargs=initargs) as pool:
            return list(pool.map(_validate_in_worker, work))
    p = design.info["print"]
    cache["grid"] = dense.print_grid(
        design.V, design.F, design.flat, p["height_mm"], design.rgb, p["dpi"], design.owner
    )
    from workbench.figures import _figure

    _figure()
    # OpenCV's thread pool stopped before the fork (the workers inherit one thread): a forked
    # worker that reconfigured it hung, waiting on a condition variable of pool threads that
    # exist only here
    threads = cv2.getNumThreads()
    cv2.setNumThreads(1)
    try:
        with ProcessPoolExecutor(
            jobs, mp_context=get_context("fork"), initializer=_adopt, initargs=(design, profile, cache)
        ) as pool:
            return list(pool.map(_validate_in_worker, work))
    finally:
        cv2.setNumThreads(threads)


def fork_is_safe() -> bool:
    """Whether worker processes may be forked from this one (else they are spawned).

    Forking saves each worker its start-up (Python, NumPy, OpenCV, numba, matplotlib, the
    design and the print grid: about 4 CPU s each) but needs every thread pool the parent
    has started to survive a fork. OpenCV's does once stopped (:func:`validate_in_pool`);
    numba's OpenMP layer (GNU libgomp) does not: forked workers hung in their first parallel
    loop. So fork only on Linux (macOS frameworks are not fork-safe either), and only where
    numba has not started a layer yet (it is then told to pick a fork-safe one: TBB, or its
    own work queue) or started a fork-safe one.
    """
    if not sys.platform.startswith("linux"):
        return False
    import numba

    try:
        layer = numba.threading_layer()
    except ValueError:  # no parallel loop has run in this process yet
        numba.config.THREADING_LAYER = "forksafe"
        return True
    return layer in ("tbb", "workqueue")


def usable_profile(path: Path):
    """The camera profile, or why no camera has it (every photo is then INVALID with that reason)."""
    try:
        return load_camera_profile(path)
    except WorkbenchError as exc:
        return str(exc)


def _validate_in_worker(job: tuple) -> tuple[dict, dict, np.ndarray | None, dict]:
    photo, stem, view, tolerance_mm, max_defect_mm2 = job
    return _timed(
        Path(photo), _WORKER["design"], _WORKER["profile"], view, tolerance_mm, _WORKER["cache"], stem, max_defect_mm2
    )


def _timed(path, design, profile, view, tolerance_mm, cache, stem, max_defect_mm2):
    t0 = time.perf_counter()
    entry, pics, state, pages = validate_photo(path, design, profile, view, tolerance_mm, cache, stem, max_defect_mm2)
    entry["seconds"] = round(time.perf_counter() - t0, 3)
    return entry, pics, state, pages


def part_summary(states: list, grid, names: list[str], entries: list[dict]) -> tuple[dict, np.ndarray, list]:
    """What all photos of the part show together, on its print.

    Each print pixel keeps the most telling state any photo gives it (defective over measured
    over masked over unseen); defects are the connected defective regions of that map.

    Returns
    -------
    summary : dict
        verdict (FAIL when any photo fails, PASS when every scored photo passes, INVALID when
        none was scored), coverage of the part's print and of each view's region, defects.
    combined : (rows, cols) uint8
        The combined state map.
    defects : list of dict
        Part defects: centre_mm, area_mm2 (print), and the photos that show each.
    """
    scored = [s for s in states if s is not None]
    verdicts = [e["verdict"] for e in entries]
    if "FAIL" in verdicts:
        verdict = "FAIL"
    elif "PASS" in verdicts:
        verdict = "PASS"
    else:
        verdict = "INVALID"
    if not scored:
        return {"verdict": verdict, "photos_scored": 0}, None, []
    combined = np.maximum.reduce(scored)
    on = combined != dense.OFF_PART
    n_on = max(int(on.sum()), 1)
    # one defect seen in several photos is one defect of the part: photos' defects whose
    # boxes on the print overlap are merged (the largest area, the centre of the largest)
    defects: list = []
    for e in entries:
        for d in e.get("defects", []):
            x0, y0, x1, y1 = d["bbox_mm"]
            for m in defects:
                a0, b0, a1, b1 = m["bbox_mm"]
                if x0 < a1 and a0 < x1 and y0 < b1 and b0 < y1:
                    if d["area_mm2"] > m["area_mm2"]:
                        m.update(centre_mm=d["centre_mm"], area_mm2=d["area_mm2"], kind=d["kind"])
                    m["bbox_mm"] = [min(x0, a0), min(y0, b0), max(x1, a1), max(y1, b1)]
                    m["photos"].append(Path(e["photo"]).name)
                    break
            else:
                defects.append(
                    {
                        "kind": d["kind"],
                        "centre_mm": d["centre_mm"],
                        "area_mm2": d["area_mm2"],
                        "bbox_mm": list(d["bbox_mm"]),
                        "view": d.get("view"),
                        "photos": [Path(e["photo"]).name],
                    }
                )
    defects.sort(key=lambda d: (-d["area_mm2"], d["centre_mm"]))
    summary = {
        "verdict": verdict,
        "photos_scored": len(scored),
        "coverage_print": {
            dense.STATE_NAMES[k]: float((combined == k).sum() / n_on) for k in range(1, len(dense.STATE_NAMES))
        },
        "measured_share_of_part": float(np.isin(combined, dense.MEASURED).sum() / n_on),
        "coverage_by_view": coverage_by_view(combined, grid.owner, names),
        "defects": defects,
    }
    return summary, combined, defects


def run(args) -> int:
    log = (lambda _m: None) if args.quiet else (lambda m: print(m, file=sys.stderr, flush=True))
    if not (np.isfinite(args.tolerance_mm) and args.tolerance_mm > 0):
        raise UsageError(f"--tolerance-mm {args.tolerance_mm:g}: must be a positive number of mm")
    if not (np.isfinite(args.max_defect_mm2) and args.max_defect_mm2 > 0):
        raise UsageError(f"--max-defect-mm2 {args.max_defect_mm2:g}: must be a positive number of mm²")
    if args.jobs < 0:
        raise UsageError(f"--jobs {args.jobs}: must be 0 (every core) or more")
    profile_path = Path(args.camera)
    if not profile_path.is_file():
        load_camera_profile(profile_path)  # raises: missing, or a directory, in one line
    # a profile no camera has (K zero, NaN, negative fx): every photo INVALID with the reason, the report written
    profile = usable_profile(profile_path)
    design = Design(Path(args.design))
    if design.owner is None:
        raise WorkbenchError(f"{design.dir / 'owner.png'}: missing or unreadable; rerun workbench design")
    names = [v["name"] for v in design.info["views"]]
    if args.view is not None and args.view not in names:
        raise WorkbenchError(f"no view named {args.view!r} in {design.dir / 'design.json'} (views: {', '.join(names)})")
    out = Path(args.out) if args.out else design.dir / "validation"
    jobs = args.jobs or os.cpu_count() or 1
    jobs = min(jobs, len(args.photos))
    entries, files, states = [], {}, []
    cache: dict = {}
    photos = [Path(p) for p in args.photos]
    inputs = [*design_files(design.dir), profile_path, *photos]
    check_output_dir(out, inputs)
    check_outputs(out / "validation.json", out / "qa_report.pdf", inputs=inputs)
    stems = output_stems(photos)
    work = [(p, stem, args.view, args.tolerance_mm, args.max_defect_mm2) for p, stem in zip(photos, stems, strict=True)]
    if jobs > 1:
        results = validate_in_pool(jobs, work, design, profile, profile_path, cache)
    else:
        results = (_timed(Path(p), design, profile, v, t, cache, stem, m) for p, stem, v, t, m in work)
    pages: dict = {}
    for photo, (entry, pics, state, shown) in zip(photos, results, strict=True):
        entry["photo"] = recorded_path(photo, out)  # relative to the report's folder, beside its sha256
        entries.append(entry)
        states.append(state)
        files.update({out / k: v for k, v in pics.items()})
        pages.update(shown)
        mm = entry.get("misregistration_mm", {}) or {}
        log(
            f"{Path(photo).name}: {entry['verdict']}"
            + (f" ({entry.get('view')}, p95 {mm['p95']:.3f} mm)" if mm.get("p95") is not None else "")
            + f": {entry['reason']}"
        )
    p = design.info["print"]
    grid = cache.get("grid")
    if grid is None and any(s is not None for s in states):
        grid = dense.print_grid(design.V, design.F, design.flat, p["height_mm"], design.rgb, p["dpi"], design.owner)
    part, combined, part_defects = part_summary(states, grid, names, entries)
    if combined is not None:
        files[out / "coverage_print.png"] = pictures.coverage_figure(
            combined,
            grid.px_per_mm,
            f"the part's print over {part['photos_scored']} photo(s): {part['verdict']}",
            part_defects,
        )
    report = {
        "software": {"name": "workbench", "version": __version__},
        "design": {
            "dir": recorded_path(design.dir, out),
            "job": design.info.get("job"),
            "design_json_sha256": _sha(design.dir / "design.json"),
            "print_sha256": _sha(design.dir / "print.png"),
        },
        "camera_profile": {"file": recorded_path(profile_path, out), "sha256": _sha(profile_path)},
        "tolerance_mm": args.tolerance_mm,
        "max_defect_mm2": args.max_defect_mm2,
        "verdict_rule": verdict_rule(args.tolerance_mm, args.max_defect_mm2),
        "part": part,
        "photos": entries,
    }
    files[out / "validation.json"] = (json.dumps(report, indent=1) + "\n").encode()
    files[out / "qa_report.pdf"] = qa_report(report, {k.name: v for k, v in files.items() if k.suffix == ".png"}, pages)
    write_folder(out, files, inputs)
    log(
        f"{len(entries)} photo(s), part: {part['verdict']}; wrote {out / 'validation.json'} and {out / 'qa_report.pdf'}"
    )
    return 0
