"""``workbench validate``: photos of the decorated part, posed on the fixture, scored against each view."""

from __future__ import annotations

import hashlib
import json
import sys
import time
from pathlib import Path

import cv2
import numpy as np

from workbench import __version__
from workbench.atomic import check_output_dir, check_outputs, safe_name, write_folder
from workbench.camera import Camera, load_camera_profile
from workbench.design import read_image
from workbench.design_dir import Design
from workbench.errors import UsageError, WorkbenchError
from workbench.export import png_bytes
from workbench.jsonfile import recorded_path
from workbench.raster import depth_buffer
from workbench.validate.films import fit_per_film
from workbench.validate.pose import PoseError, estimate_pose
from workbench.validate.score import score, view_surface, warp_photo

MAX_RMS_PX = 1.0
MIN_TILES = 5
MIN_SSIM = 0.5
# share of the textured tiles of the view's region that must match the design: a decoration
# painted over or torn in part matches where it is intact and nowhere else (measured: 41 % of
# the tiles for half the part painted over, 82 % and more for an intact film 2 mm off)
MIN_MATCHED_SHARE = 0.7


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
        "--tolerance-mm", type=float, default=0.5, help="largest accepted misregistration, p95 (default 0.5)"
    )
    p.add_argument("--out", metavar="DIR", help="output directory (default: DESIGN_DIR/validation)")
    p.add_argument("-q", "--quiet", action="store_true")
    p.set_defaults(run=run)


def _sha(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def markers_under_the_part(pose, design: Design) -> list[int]:
    """Markers seen where the part, if it sat where the fixture says, would hide them."""
    cam = Camera(pose.camera.K, pose.camera.R, pose.camera.t, pose.camera.width, pose.camera.height)
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
    path: Path, design: Design, profile, view_name, tolerance_mm, cache, stem: str | None = None
) -> tuple[dict, dict]:
    """Score one photo; never raises for a bad photo (its verdict says why).

    ``profile`` is the camera profile, or the reason it cannot be used (every photo is then INVALID).
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
        return entry, files
    if isinstance(profile, str):
        entry["reason"] = f"unusable camera profile: {profile}"
        return entry, files
    if photo.shape[1] != profile.width or photo.shape[0] != profile.height:
        entry["reason"] = (
            f"photo is {photo.shape[1]} x {photo.shape[0]} px, the camera profile is for "
            f"{profile.width} x {profile.height}"
        )
        return entry, files
    gray = cv2.cvtColor(photo, cv2.COLOR_RGB2GRAY)
    try:
        pose = estimate_pose(gray, design.fixture, profile.K, profile.dist)
    except PoseError as exc:
        entry["reason"] = str(exc)
        return entry, files
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
        return entry, files
    hidden = markers_under_the_part(pose, design)
    if hidden:
        entry["reason"] = (
            f"the object is not where the fixture says: marker {hidden[0]} is visible where the part "
            f"should hide it ({len(hidden)} such markers)"
        )
        return entry, files
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
    warped, valid = warp_photo(photo, pose.camera, surface, design.V, design.F)
    p = design.info["print"]
    sc = score(view_rgb, warped, valid, surface, (p["image_width_mm"], p["image_height_mm"]))
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
        entry["films"] = fit_per_film(sc, surface, design.info["films"], p["dpi"] / 25.4)
    if len(sc.shift_mm) < MIN_TILES or sc.ssim < MIN_SSIM:
        entry["verdict"] = "FAIL"
        entry["reason"] = (
            f"the decoration does not match the design (SSIM {sc.ssim:.2f}, {len(sc.shift_mm)} tiles "
            "matched): wrong print, or badly damaged"
        )
    elif entry["misregistration_mm"]["p95"] > tolerance_mm:
        entry["verdict"] = "FAIL"
        entry["reason"] = (
            f"misregistration p95 {entry['misregistration_mm']['p95']:.3f} mm > tolerance {tolerance_mm} mm"
        )
    elif len(sc.shift_mm) < MIN_MATCHED_SHARE * sc.tiles_examined:
        entry["verdict"] = "FAIL"
        entry["reason"] = (
            f"only {len(sc.shift_mm)} of {sc.tiles_examined} textured tiles match the design: part of the "
            "decoration is missing, covered or damaged"
        )
    else:
        entry["verdict"] = "PASS"
        entry["reason"] = (
            f"misregistration p95 {entry['misregistration_mm']['p95']:.3f} mm <= tolerance {tolerance_mm} mm"
        )
    stem = stem or safe_name(path.stem)
    entry["pictures"] = stem  # the name the warped photo, overlay and heat map start with
    overlay = view_rgb.copy()
    overlay[valid] = (0.5 * view_rgb[valid] + 0.5 * warped[valid]).astype(np.uint8)
    files[f"{stem}_warped_{name}.png"] = png_bytes(warped)
    files[f"{stem}_overlay_{name}.png"] = png_bytes(overlay)
    files[f"{stem}_heatmap_{name}.png"] = heatmap_png(view_rgb, sc, f"{path.name} in view {name}: {entry['verdict']}")
    return entry, files


def _centre(view: dict) -> list:
    c = view["camera"]
    return (-np.asarray(c["R"]).T @ np.asarray(c["t"])).tolist()


def run(args) -> int:
    log = (lambda _m: None) if args.quiet else (lambda m: print(m, file=sys.stderr, flush=True))
    if not (np.isfinite(args.tolerance_mm) and args.tolerance_mm > 0):
        raise UsageError(f"--tolerance-mm {args.tolerance_mm:g}: must be a positive number of mm")
    profile_path = Path(args.camera)
    if not profile_path.is_file():
        load_camera_profile(profile_path)  # raises: missing, or a directory, in one line
    try:
        profile = load_camera_profile(profile_path)
    except WorkbenchError as exc:
        # a profile no camera has (K zero, NaN, negative fx): every photo INVALID with the reason, the report written
        profile = str(exc)
    design = Design(Path(args.design))
    if design.owner is None:
        raise WorkbenchError(f"{design.dir / 'owner.png'}: missing or unreadable; rerun workbench design")
    names = [v["name"] for v in design.info["views"]]
    if args.view is not None and args.view not in names:
        raise WorkbenchError(f"no view named {args.view!r} in {design.dir / 'design.json'} (views: {', '.join(names)})")
    out = Path(args.out) if args.out else design.dir / "validation"
    cache: dict = {}
    entries, files = [], {}
    check_output_dir(out)
    check_outputs(out / "validation.json", out / "qa_report.pdf")
    photos = [Path(p) for p in args.photos]
    for photo, stem in zip(photos, output_stems(photos), strict=True):
        t0 = time.perf_counter()
        entry, pics = validate_photo(photo, design, profile, args.view, args.tolerance_mm, cache, stem)
        entry["seconds"] = round(time.perf_counter() - t0, 3)
        entry["photo"] = recorded_path(photo, out)  # relative to the report's folder, beside its sha256
        entries.append(entry)
        files.update({out / k: v for k, v in pics.items()})
        mm = entry.get("misregistration_mm", {}) or {}
        log(
            f"{Path(photo).name}: {entry['verdict']}"
            + (f" ({entry.get('view')}, p95 {mm['p95']:.3f} mm)" if mm.get("p95") is not None else "")
            + f": {entry['reason']}"
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
        "photos": entries,
    }
    from workbench.validate.report import qa_report

    files[out / "validation.json"] = (json.dumps(report, indent=1) + "\n").encode()
    files[out / "qa_report.pdf"] = qa_report(report, {k.name: v for k, v in files.items() if k.suffix == ".png"})
    write_folder(out, files)
    log(f"wrote {out / 'validation.json'} and {out / 'qa_report.pdf'}")
    return 0
