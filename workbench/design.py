"""The paper's method end to end: views, conformal map, per-pixel print synthesis."""

from __future__ import annotations

import os
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import cv2
import numpy as np

from workbench.camera import Camera
from workbench.conformal.flatten import (
    CrowdingError,
    FlattenOptions,
    FlattenResult,
    crowding_advice,
    flatten,
    flatten_auto_corners,
)
from workbench.errors import WorkbenchError
from workbench.job import Job
from workbench.mesh.io import read_mesh
from workbench.mesh.topology import unique_edges
from workbench.mesh.validate import face_areas
from workbench.texture.synthesis import PrintGrid, synthesize_print
from workbench.views.visibility import ViewVisibility, assign_views, face_adjacency, view_visibility

# bytes per print pixel at the peak: RGB + owner map + the PNG encoder's copy and output
BYTES_PER_PRINT_PIXEL = 10


@dataclass
class DesignResult:
    """Everything ``workbench design`` computes.

    Attributes
    ----------
    V : (#V, 3) float
        Mesh vertices, mm.
    F : (#F, 3) int
        Triangles.
    flat : FlattenResult
        Conformal map and stretch.
    grid : PrintGrid
        Print pixels.
    rgb : (rows, cols, 3) uint8
        The print.
    owner : (rows, cols) int8
        Owning view per print pixel, -1 for background.
    cameras : list of Camera
        Designed views' cameras, in priority order.
    status : (#F, #views) int8
        Face ownership (see :func:`workbench.views.visibility.assign_views`).
    visibilities : list of ViewVisibility
        Depth buffers and visible faces per view.
    view_px_per_print_px : list of float
        Per view, view pixels per print pixel (linear).
    timings_s : dict
        Seconds per stage.
    """

    V: np.ndarray
    F: np.ndarray
    flat: FlattenResult
    grid: PrintGrid
    rgb: np.ndarray
    owner: np.ndarray
    cameras: list[Camera]
    status: np.ndarray
    visibilities: list[ViewVisibility]
    view_px_per_print_px: list[float]
    timings_s: dict = field(default_factory=dict)


def read_image(path, what: str) -> np.ndarray:
    """An image file as RGB uint8, or a WorkbenchError naming it."""
    if Path(path).is_dir():
        raise WorkbenchError(f"{what}: {path} is a directory, not an image")
    try:
        data = np.fromfile(str(path), dtype=np.uint8)
    except OSError:
        data = np.zeros(0, np.uint8)
    img = cv2.imdecode(data, cv2.IMREAD_COLOR) if data.size else None
    if img is None:
        raise WorkbenchError(f"{what}: cannot read image {path} (missing, empty or not an image)")
    return cv2.cvtColor(img, cv2.COLOR_BGR2RGB)


def physical_memory() -> int:
    """The memory this command can have, bytes: what Linux says is available, else the machine's (16 GiB
    where the system does not say). Available, not installed: on a shared machine the rest is in use."""
    try:
        with open("/proc/meminfo") as fh:
            for line in fh:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        pass
    try:
        return os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES")
    except (ValueError, OSError, AttributeError):
        return 16 * 2**30


def check_print_fits(grid: PrintGrid, where: str) -> None:
    """Refuse, before allocating, a print that would not fit in this machine's memory."""
    rows, cols = grid.shape
    need = rows * cols * BYTES_PER_PRINT_PIXEL
    have = physical_memory()
    if need > 0.7 * have:
        raise WorkbenchError(
            f"{where}: a {grid.width_mm:.1f} x {grid.height_mm:.1f} mm print at {grid.dpi:g} dpi is "
            f"{cols:,} x {rows:,} px ({rows * cols / 1e6:,.0f} Mpx) and needs about {need / 2**30:,.1f} GiB; "
            f"this machine has {have / 2**30:.1f} GiB available: lower [print].dpi"
        )


def design(job: Job, log: Callable[[str], None] | None = None) -> DesignResult:
    """Compute the print of a job.

    Parameters
    ----------
    job : Job
        Parsed job file.
    log : callable(str), optional
        Receives progress lines.

    Returns
    -------
    DesignResult

    Raises
    ------
    WorkbenchError
        Bad mesh, unreadable images, a camera with the part behind it, a view that
        sees nothing, or a print too large for memory.
    """
    say = log or (lambda _m: None)
    t: dict[str, float] = {}
    t0 = time.perf_counter()
    V, F = read_mesh(job.object.mesh, job.object.units)
    images = [read_image(v.image, f"{job.path}: views[{i}].image") for i, v in enumerate(job.views)]
    t["read"] = time.perf_counter() - t0
    say(f"read {job.object.mesh.name}: {len(V)} vertices, {len(F)} faces; {len(images)} view images")

    t0 = time.perf_counter()
    auto = job.object.corners == "auto"
    options = FlattenOptions(
        corners=None if auto else job.object.corners,
        scale=job.print.scale,
        min_print_mm=0.5 * 25.4 / job.print.dpi,
        outline=job.print.outline,
    )
    if auto and job.print.outline == "rectangle":
        flat, _ = flatten_auto_corners(V, F, options, str(job.object.mesh), log=say)
    else:
        try:
            flat = flatten(V, F, options, str(job.object.mesh), log=say)
        except CrowdingError as exc:
            raise crowding_advice(exc, V, F, options, str(job.object.mesh), say) from None
    t["flatten"] = time.perf_counter() - t0
    # from here on the part is the flattened mesh: the input, or its common subdivision
    # with the flat triangulation (input vertices first), on which the map is exact
    V, F = flat.V, flat.F
    grid = PrintGrid(flat.width_mm, flat.height_mm, job.print.dpi)
    check_print_fits(grid, f"{job.path}: [print].dpi")

    t0 = time.perf_counter()
    cameras, visibilities = [], []
    for i, (spec, img) in enumerate(zip(job.views, images, strict=True)):
        cam = spec.make_camera(img.shape[1], img.shape[0])
        xy, z = cam.project(V)
        behind = np.flatnonzero(z <= 1e-6 * np.abs(z).max())
        if len(behind):
            where = (np.round(cam.center, 2) + 0.0).tolist()  # + 0.0: print -0.0 as 0.0
            raise WorkbenchError(
                f"{job.path}: views[{i}] ({spec.name!r}): the camera at {where} mm has part "
                f"of the object level with or behind it (vertex {int(behind[0])}); a view camera must see the whole "
                "object in front of it, not from inside or among it"
            )
        cameras.append(cam)
        visibilities.append(view_visibility(V, F, cam))
    E, FE, _ = unique_edges(F)
    area = face_areas(V, F)
    status = assign_views(visibilities, [v.region for v in job.views], face_adjacency(FE), area)
    for i, spec in enumerate(job.views):
        if not status[:, i].any():
            seen = int((visibilities[i].full | visibilities[i].partial).sum())
            why = "it sees no front face of the object" if seen == 0 else "earlier views own everything it sees"
            raise WorkbenchError(
                f"{job.path}: views[{i}] ({spec.name!r}) sees nothing of the object to decorate: {why}"
            )
    t["views"] = time.perf_counter() - t0
    say("views: " + ", ".join(f"{s.name} {int((status[:, i] != 0).sum())} faces" for i, s in enumerate(job.views)))

    t0 = time.perf_counter()
    rows, cols = grid.shape
    say(f"synthesising {cols} x {rows} px print at {job.print.dpi:g} dpi ({rows * cols / 1e6:.1f} Mpx)")
    rgb, owner, scales = synthesize_print(grid, flat.uv, V, F, status, visibilities, images, job.print.background)
    t["synthesis"] = time.perf_counter() - t0
    return DesignResult(
        V=V,
        F=F,
        flat=flat,
        grid=grid,
        rgb=rgb,
        owner=owner,
        cameras=cameras,
        status=status,
        visibilities=visibilities,
        view_px_per_print_px=scales,
        timings_s=t,
    )


def view_statistics(result: DesignResult, names: list[str]) -> list[dict]:
    """Per view: faces and surface owned, share of the print, share of its image used.

    Parameters
    ----------
    result : DesignResult
        A computed design.
    names : list of str
        View names, priority order.

    Returns
    -------
    list of dict
    """
    area = face_areas(result.V, result.F)
    first = np.argmax(result.status != 0, axis=1)
    owned_any = (result.status != 0).any(axis=1)
    rows, cols = result.grid.shape
    stats = []
    for v, name in enumerate(names):
        mine = owned_any & (first == v)
        fb = result.visibilities[v].face_buffer
        seen = fb >= 0
        used = np.zeros_like(seen)
        used[seen] = result.status[fb[seen], v] != 0
        stats.append(
            {
                "name": name,
                "faces_owned": int(mine.sum()),
                "surface_owned_mm2": float(area[mine].sum()),
                "print_share": float((result.owner == v).sum() / (rows * cols)),
                "image_share_used": float(used.mean()),
                "view_px_per_print_px": result.view_px_per_print_px[v],
                "camera": result.cameras[v].to_dict(),
            }
        )
    return stats


# The film fits the part when its stretch stays within [MIN_STRETCH, material limit]
# almost everywhere (film stretches; it barely shrinks), the print is mostly part, and
# the print is not much larger than the part's developed area.
MIN_STRETCH = 0.8
MAX_OFF_STRETCH_SHARE = 0.01
MAX_BACKGROUND_SHARE = 0.5
MAX_PRINT_TO_SURFACE = 2.0


def fit_warnings(result: DesignResult, max_stretch: float | None) -> list[str]:
    """Why this print will not make a good part, one sentence each; empty when it will.

    Parameters
    ----------
    result : DesignResult
        A computed design.
    max_stretch : float or None
        The material's stretch limit (3D length / print length); None: no upper check.

    Returns
    -------
    list of str
        Warnings: stretch outside [0.8, limit] on more than 1 % of the surface,
        background over half the print, a print more than twice the developed area.
    """
    flat = result.flat
    ok = ~flat.collapsed
    area, stretch = flat.area_3d[ok], flat.stretch[ok]
    surface = float(flat.area_3d.sum())
    hi = np.inf if max_stretch is None else max_stretch
    off = float(area[(stretch < MIN_STRETCH) | (stretch > hi)].sum() + flat.area_3d[flat.collapsed].sum())
    out = []
    if off > MAX_OFF_STRETCH_SHARE * surface:
        band = f"[{MIN_STRETCH:g}, {'∞' if max_stretch is None else f'{max_stretch:g}'}]"
        out.append(
            f"the film stretch leaves {band} on {100 * off / surface:.1f} % of the surface "
            f"(from {np.nanmin(stretch):.3g} to {np.nanmax(stretch):.3g}): the film would tear or wrinkle there"
        )
    background = float((result.owner < 0).mean())
    if background > MAX_BACKGROUND_SHARE:
        out.append(f"background is {100 * background:.1f} % of the print: the outline does not fit the part")
    print_area = flat.width_mm * flat.height_mm
    if print_area > MAX_PRINT_TO_SURFACE * surface:
        out.append(
            f"the print ({flat.width_mm:.0f} x {flat.height_mm:.0f} mm) is {print_area / surface:.1f} times the "
            "part's developed area"
        )
    return out
