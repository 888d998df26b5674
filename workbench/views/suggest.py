"""Which view next: ranked viewpoints for the surface no view owns yet.

The paper's next step ("the remaining points/faces can give guidelines, allowing us to
choose the next viewpoint more efficiently"): the job's views, in priority order, own
what :func:`workbench.views.visibility.assign_views` gives them; a new view appended
after them claims, by the same rules, what it sees of the rest and keeps one connected
region. Each candidate camera is scored by the surface it would own that no view owns
yet, counted only where it sees that surface at a good angle (a grazing view decorates
poorly); the search runs over the viewing sphere around the part at the designer's
distance, and the suggestions are the best cameras at least ``min_separation_deg``
apart, so the designer has real alternatives.

Every figure a suggestion reports comes from the same visibility and ownership code
``design`` runs (:func:`view_visibility`, :func:`claim_faces`), at the suggestion's own
image size, so that ``design`` owns what ``covers_share`` says once the view is added.
"""

from __future__ import annotations

from contextlib import contextmanager
from dataclasses import dataclass

import numpy as np

from workbench.camera import Camera
from workbench.errors import WorkbenchError
from workbench.mesh.topology import unique_edges
from workbench.mesh.validate import face_areas
from workbench.raster import depth_buffer
from workbench.views.visibility import ViewVisibility, claim_faces, face_adjacency, points_unoccluded, view_visibility

# a favoured face counts this many times its area; an avoided one counts minus its area
FAVOUR_WEIGHT = 2.0


@dataclass(frozen=True)
class SuggestOptions:
    """What the designer asks of the suggestions.

    Attributes
    ----------
    count : int
        How many suggestions (ranked).
    distance_mm : (lo, hi) or None
        Distance from the part's centre, mm, or a range searched; None: the median
        distance of the job's cameras.
    min_elevation_deg : float
        Lowest elevation above the plane normal to ``up``, degrees (-90: anywhere).
    up : (3,) float or None
        The direction towards the top of every suggested image; None: the first view's.
    fov_deg : float or None
        Horizontal field of view, degrees; None: the part's bounding sphere fits across
        the image's shorter side at the nearest distance.
    size_px : (width, height) or None
        Image size; None: what the print's dpi needs (a view pixel no larger on the
        surface than a print pixel), with the first view's aspect ratio.
    max_obliquity_deg : float
        Surface seen more obliquely than this (angle between its normal and the line of
        sight) does not count towards a suggestion's score.
    min_separation_deg : float
        Least angle between two suggestions' viewing directions.
    search_directions : int
        Directions of the coarse search over the sphere.
    search_px : int
        Long side of the search's depth buffers, px.
    max_px : int
        Longest image side a suggestion may ask for.
    """

    count: int = 3
    distance_mm: tuple[float, float] | None = None
    min_elevation_deg: float = -90.0
    up: tuple[float, float, float] | None = None
    fov_deg: float | None = None
    size_px: tuple[int, int] | None = None
    max_obliquity_deg: float = 60.0
    min_separation_deg: float = 20.0
    search_directions: int = 192
    search_px: int = 192
    max_px: int = 8192


@dataclass
class Remaining:
    """The part as the job's views leave it, and the frame of every suggestion.

    Attributes
    ----------
    V : (#V, 3) float
        Vertices, mm.
    F : (#F, 3) int
        Triangles, counter-clockwise seen from the decorated side.
    area : (#F,) float
        Face areas, mm².
    normal : (#F, 3) float
        Unit face normals (decorated side).
    centroid : (#F, 3) float
        Face centroids, mm.
    adjacency : (#F, #F) sparse
        Faces sharing an edge.
    taken : (#F,) bool
        Faces a job view claims and sees whole: no later view may claim them.
    claimed : (#F,) bool
        Faces a job view claims (whole or in part): owned.
    free : (k,) int
        Faces not taken: all a new view may claim.
    free_adjacency : (k, k) sparse
        ``adjacency`` among them.
    weight : (#F,) float
        Score weight per face: 1, ``FAVOUR_WEIGHT`` where favoured, -1 where avoided.
    center : (3,) float
        What every suggestion looks at: the centre of the part's bounding box, mm.
    distance_mm : (lo, hi)
        Distance range of the cameras from ``center``, mm.
    up : (3,) float
        Unit up direction.
    fov_deg : float
        Horizontal field of view, degrees.
    aspect : float
        Image height / width.
    dpi : float
        The print's resolution.
    """

    V: np.ndarray
    F: np.ndarray
    area: np.ndarray
    normal: np.ndarray
    centroid: np.ndarray
    adjacency: object
    taken: np.ndarray
    claimed: np.ndarray
    free: np.ndarray
    free_adjacency: object
    weight: np.ndarray
    center: np.ndarray
    distance_mm: tuple[float, float]
    up: np.ndarray
    fov_deg: float
    aspect: float
    dpi: float

    @property
    def undecorated_mm2(self) -> float:
        """Surface no view owns, mm²."""
        return float(self.area[~self.claimed].sum())


@dataclass
class Coverage:
    """What one candidate camera would own, appended after the job's views.

    Attributes
    ----------
    camera : Camera
    direction : (3,) float
        Unit vector from the part's centre towards the camera.
    distance_mm : float
    up : (3,) float
        The up vector the camera was built with (its image's up, when not built by
        :func:`view_camera`).
    status : (#F,) int8
        What it claims (:func:`claim_faces`): 0 none, 1 whole, 2 where it sees it.
    new : (#F,) bool
        Faces it would own that no view owns yet.
    good : (#F,) bool
        Of those, seen within the obliquity limit.
    covers_mm2 : float
        Area of ``new``, mm².
    good_mm2 : float
        Area of ``good``, mm².
    score : float
        Weighted area of ``good``, less the avoided area it would own.
    face_buffer : (H, W) int32
        Nearest face per pixel.
    position, look_at : (3,) float or None
        As the job file writes them (:func:`view_camera`), for the suggestions.
    """

    camera: Camera
    direction: np.ndarray
    distance_mm: float
    up: np.ndarray
    status: np.ndarray
    new: np.ndarray
    good: np.ndarray
    covers_mm2: float
    good_mm2: float
    score: float
    face_buffer: np.ndarray
    position: np.ndarray | None = None
    look_at: np.ndarray | None = None


def remaining_surface(
    V: np.ndarray,
    F: np.ndarray,
    status: np.ndarray,
    cameras: list[Camera],
    dpi: float,
    options: SuggestOptions,
    favour: np.ndarray | None = None,
    avoid: np.ndarray | None = None,
) -> Remaining:
    """What the job's views leave undecorated, and the frame of the suggestions.

    Parameters
    ----------
    V : (#V, 3) float
        Vertices, mm.
    F : (#F, 3) int
        Triangles.
    status : (#F, #views) int8
        The job's ownership (:func:`workbench.views.visibility.assign_views`).
    cameras : list of Camera
        The job's cameras, priority order.
    dpi : float
        The print's resolution.
    options : SuggestOptions
    favour, avoid : (#F,) bool, optional
        Faces the designer wants decorated first, or not by a new view.

    Returns
    -------
    Remaining
    """
    area = face_areas(V, F)
    a, b, c = V[F[:, 0]], V[F[:, 1]], V[F[:, 2]]
    n = np.cross(b - a, c - a)
    normal = n / np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-300)
    _, FE, _ = unique_edges(F)
    adjacency = face_adjacency(FE)
    taken = (status == 1).any(axis=1)
    free = np.flatnonzero(~taken)
    weight = np.ones(len(F))
    if favour is not None:
        weight[favour] = FAVOUR_WEIGHT
    if avoid is not None:
        weight[avoid] = -1.0
    center = 0.5 * (V.min(axis=0) + V.max(axis=0))
    if options.distance_mm is None:
        d = float(np.median([np.linalg.norm(cam.center - center) for cam in cameras]))
        distance = (d, d)
    else:
        distance = (float(options.distance_mm[0]), float(options.distance_mm[1]))
    radius = float(np.linalg.norm(V - center, axis=1).max())
    if distance[0] <= 1.05 * radius:
        raise WorkbenchError(
            f"--distance-mm {distance[0]:g}: a camera this close to the part's centre is among the part "
            f"(it reaches {radius:.0f} mm from its centre); give at least {1.05 * radius:.0f} mm"
        )
    # the first view's image up, in the world: minus its camera's y axis
    up = np.asarray(options.up if options.up is not None else -cameras[0].R[1], dtype=np.float64)
    up = up / np.linalg.norm(up)
    if options.size_px is not None:
        aspect = options.size_px[1] / options.size_px[0]
    else:
        aspect = cameras[0].height / cameras[0].width
    if options.fov_deg is not None:
        fov = float(options.fov_deg)
    else:
        # the whole part in the frame from every direction: its bounding sphere, 5 % wider,
        # across the image's shorter side at the nearest distance
        half = np.arcsin(min(1.0, 1.05 * radius / distance[0]))
        fov = float(np.degrees(2 * np.arctan(np.tan(half) / min(aspect, 1.0))))
    return Remaining(
        V=V,
        F=F,
        area=area,
        normal=normal,
        centroid=(a + b + c) / 3.0,
        adjacency=adjacency,
        taken=taken,
        claimed=(status != 0).any(axis=1),
        free=free,
        free_adjacency=adjacency[free][:, free].tocsr(),
        weight=weight,
        center=center,
        distance_mm=distance,
        up=up,
        fov_deg=fov,
        aspect=aspect,
        dpi=float(dpi),
    )


@contextmanager
def one_thread():
    """Run the search's thousands of small kernels on one thread each.

    BLAS's threads, spinning beside numba's on a shared machine, made each
    ``(n, 3) @ (3, 3)`` of :meth:`Camera.project` 5 to 20 times slower (0.12 s against
    0.026 s per evaluation of the face mask), and numba's parallel depth test on a few
    thousand points waits for a second thread more than it gains from it (the face
    mask's search: 13.1 s with two threads on the busy machine, 8.9 s with one).
    """
    import numba
    from threadpoolctl import threadpool_limits

    threads = numba.get_num_threads()
    numba.set_num_threads(1)
    try:
        with threadpool_limits(limits=1, user_api="blas"):
            yield
    finally:
        numba.set_num_threads(threads)


def sphere_directions(n: int) -> np.ndarray:
    """``n`` unit vectors spread evenly over the sphere (Fibonacci lattice); (n, 3) float.

    Deterministic; neighbours are about ``sqrt(4 pi / n)`` radians apart.
    """
    k = np.arange(n) + 0.5
    z = 1.0 - 2.0 * k / n
    phi = np.pi * (3.0 - np.sqrt(5.0)) * k
    r = np.sqrt(1.0 - z * z)
    return np.stack([r * np.cos(phi), r * np.sin(phi), z], axis=1)


def elevation_deg(rem: Remaining, directions: np.ndarray) -> np.ndarray:
    """Elevation of viewing directions (n, 3) above the plane normal to ``up``, degrees; (n,)."""
    return np.degrees(np.arcsin(np.clip(np.asarray(directions) @ rem.up, -1.0, 1.0)))


def camera_up(rem: Remaining, direction: np.ndarray) -> np.ndarray:
    """The up vector for a camera in ``direction``: ``rem.up``, unless the camera looks
    along it (within 5°), then the horizontal axis of the world least aligned with it."""
    d = direction / np.linalg.norm(direction)
    if np.linalg.norm(np.cross(d, rem.up)) > np.sin(np.radians(5.0)):
        return rem.up
    axis = np.eye(3)[int(np.argmin(np.abs(np.eye(3) @ d)))]
    return axis - (axis @ d) * d


def view_camera(
    rem: Remaining, direction: np.ndarray, distance: float, width: int, height: int
) -> tuple[Camera, np.ndarray, np.ndarray, np.ndarray]:
    """The camera at ``distance`` from the part's centre in ``direction``, looking at it.

    Position, target and up are rounded as the job file writes them (0.001 mm, 1e-6),
    and the camera is built from the rounded values, so that the job's own reading of a
    written suggestion gives the very same camera.

    Returns
    -------
    camera : Camera
    position, look_at, up : (3,) float
        As written to the job file.
    """
    d = direction / np.linalg.norm(direction)
    look_at = np.round(rem.center, 3) + 0.0
    position = np.round(look_at + distance * d, 3) + 0.0
    up = np.round(camera_up(rem, d), 6) + 0.0
    fov = round(rem.fov_deg, 6)
    return Camera.look_at(position, look_at, up, fov, width, height), position, look_at, up


def evaluate(rem: Remaining, camera: Camera, max_obliquity_deg: float) -> Coverage:
    """What ``camera`` would own appended after the job's views, and its score.

    The same visibility (:func:`view_visibility`, tested on the faces not yet taken:
    every face still occludes) and the same one-region rule (:func:`claim_faces`,
    ``'largest'``) as ``design``.

    Parameters
    ----------
    rem : Remaining
    camera : Camera
    max_obliquity_deg : float
        The obliquity limit of the score.

    Returns
    -------
    Coverage
    """
    vis = view_visibility(rem.V, rem.F, camera, faces=rem.free)
    status = claim_faces(vis, "largest", rem.taken, rem.adjacency, rem.area)
    new = (status != 0) & ~rem.claimed
    sight = camera.center - rem.centroid
    cos = np.einsum("ij,ij->i", rem.normal, sight) / np.maximum(np.linalg.norm(sight, axis=1), 1e-300)
    good = new & (cos >= np.cos(np.radians(max_obliquity_deg)))
    w = rem.weight * rem.area
    score = float(w[good & (rem.weight > 0)].sum() + w[new & (rem.weight < 0)].sum())
    direction = camera.center - rem.center
    dist = float(np.linalg.norm(direction))
    return Coverage(
        camera=camera,
        direction=direction / dist,
        distance_mm=dist,
        up=-camera.R[1],
        status=status,
        new=new,
        good=good,
        covers_mm2=float(rem.area[new].sum()),
        good_mm2=float(rem.area[good].sum()),
        score=score,
        face_buffer=vis.face_buffer,
    )


def search_score(rem: Remaining, camera: Camera, max_obliquity_deg: float) -> float:
    """The score of :func:`evaluate`, quickly and approximately: each face not yet taken
    is seen or not by its centroid alone (the same depth buffer and depth test), and the
    region is the largest connected set of those. About four times cheaper; the search
    ranks directions with it, and every figure reported comes from :func:`evaluate`."""
    xy, z = camera.project(rem.V)
    face_buffer, depth = depth_buffer(xy, z, rem.F, camera.width, camera.height)
    vis = ViewVisibility(camera, depth, face_buffer, rem.taken, rem.taken)
    free = rem.free
    sight = camera.center - rem.centroid[free]
    cos = np.einsum("ij,ij->i", rem.normal[free], sight) / np.maximum(np.linalg.norm(sight, axis=1), 1e-300)
    seen = (cos > 0) & points_unoccluded(vis, rem.centroid[free])
    if not seen.any():
        return 0.0
    from scipy.sparse.csgraph import connected_components

    idx = np.flatnonzero(seen)
    _, label = connected_components(rem.free_adjacency[idx][:, idx], directed=False)
    region = idx[label == int(np.argmax(np.bincount(label, weights=rem.area[free][idx])))]
    faces = free[region]
    new = ~rem.claimed[faces]
    good = new & (cos[region] >= np.cos(np.radians(max_obliquity_deg)))
    w = rem.weight[faces] * rem.area[faces]
    return float(w[good & (w > 0)].sum() + w[new & (w < 0)].sum())


def search_size(rem: Remaining, long_side: int) -> tuple[int, int]:
    """Image size with the suggestions' aspect ratio and ``long_side`` px on its long side."""
    if rem.aspect <= 1.0:
        return long_side, max(int(round(long_side * rem.aspect)), 8)
    return max(int(round(long_side / rem.aspect)), 8), long_side


def needed_size(rem: Remaining, cov: Coverage, options: SuggestOptions) -> tuple[int, int]:
    """The image size a view needs for the print's dpi: one view pixel no larger, on the
    surface it owns, than one print pixel (at its farthest face, seen face on).

    Returns
    -------
    (width, height) : int
        ``options.size_px`` when given; at most ``options.max_px`` on the long side.
    """
    if options.size_px is not None:
        return options.size_px
    faces = cov.new if cov.new.any() else ~rem.claimed
    depth = float(np.max((rem.centroid[faces] - cov.camera.center) @ cov.camera.R[2]))
    f = depth * rem.dpi / 25.4
    width = int(np.ceil(2.0 * f * np.tan(0.5 * np.radians(rem.fov_deg))))
    height = int(np.ceil(width * rem.aspect))
    s = min(1.0, options.max_px / max(width, height))
    return max(int(width * s), 8), max(int(height * s), 8)


def _angle(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.degrees(np.arccos(np.clip(a @ b / (np.linalg.norm(a) * np.linalg.norm(b)), -1.0, 1.0))))


def _refine(rem, direction, distance, size, options, score0, step_deg):
    """Pattern search on the sphere from ``direction``: a step either way along each
    tangent axis, the best kept, the step halved when none improves, down to 2°."""
    d = direction / np.linalg.norm(direction)
    best = score0
    step = np.radians(step_deg)
    lo = options.min_elevation_deg
    while step >= np.radians(2.0):
        e1 = np.cross(d, rem.up if abs(d @ rem.up) < 0.99 else np.eye(3)[int(np.argmin(np.abs(d)))])
        e1 /= np.linalg.norm(e1)
        e2 = np.cross(d, e1)
        trial = None
        for u, v in ((1, 0), (-1, 0), (0, 1), (0, -1)):
            t = d + np.tan(step) * (u * e1 + v * e2)
            t /= np.linalg.norm(t)
            if elevation_deg(rem, t[None])[0] < lo:
                continue
            s = search_score(rem, view_camera(rem, t, distance, *size)[0], options.max_obliquity_deg)
            if s > best + 1e-9:
                best, trial = s, t
        if trial is None:
            step *= 0.5
        else:
            d = trial
    return d, best


def suggest_views(rem: Remaining, options: SuggestOptions, log=None) -> list[Coverage]:
    """Ranked viewpoints for the surface no view owns yet.

    1. Coarse: ``options.search_directions`` directions over the sphere (above the
       minimum elevation) at the middle of the distance range, scored at low resolution.
    2. Seeds: the best directions, spread apart; each refined by a pattern search, then
       at each end of the distance range.
    3. Final: each candidate at the image size the dpi needs, scored at that size (the
       figures the suggestion reports); ranked; the best taken greedily, each at least
       ``min_separation_deg`` from those before (the coarse directions fill in when the
       seeds are too few).

    Parameters
    ----------
    rem : Remaining
    options : SuggestOptions
    log : callable(str), optional

    Returns
    -------
    list of Coverage
        Best first; fewer than ``options.count`` when the sphere has no more distinct
        directions that own anything.
    """
    with one_thread():
        return _suggest_views(rem, options, log or (lambda _m: None))


def _suggest_views(rem: Remaining, options: SuggestOptions, say) -> list[Coverage]:
    if rem.undecorated_mm2 <= 0:
        return []
    lo, hi = rem.distance_mm
    mid = float(np.sqrt(lo * hi))
    small = search_size(rem, options.search_px)
    dirs = sphere_directions(options.search_directions)
    dirs = dirs[elevation_deg(rem, dirs) >= options.min_elevation_deg]
    if len(dirs) == 0:
        raise WorkbenchError(f"--min-elevation-deg {options.min_elevation_deg:g}: leaves no viewing direction")
    coarse = np.array([search_score(rem, view_camera(rem, d, mid, *small)[0], options.max_obliquity_deg) for d in dirs])
    spacing = float(np.degrees(np.sqrt(4 * np.pi / options.search_directions)))
    say(f"searched {len(dirs)} directions (every {spacing:.0f}°); best covers {coarse.max():.0f} mm² at a good angle")

    # seeds: the best coarse directions, each at least two lattice steps from a better one
    seeds: list[int] = []
    for i in np.argsort(-coarse, kind="stable"):
        if coarse[i] <= 0 or len(seeds) >= options.count + 1:
            break
        if all(_angle(dirs[i], dirs[j]) >= 2 * spacing for j in seeds):
            seeds.append(int(i))
    candidates = []
    for i in seeds:
        d, s = _refine(rem, dirs[i], mid, small, options, coarse[i], 0.5 * spacing)
        best_dist = mid
        for dist in {lo, hi} - {mid}:
            t = search_score(rem, view_camera(rem, d, dist, *small)[0], options.max_obliquity_deg)
            if t > s:
                s, best_dist = t, dist
        candidates.append((d, best_dist))

    def final(d, dist):
        probe = evaluate(rem, view_camera(rem, d, dist, *small)[0], options.max_obliquity_deg)
        cam, position, look_at, up = view_camera(rem, d, dist, *needed_size(rem, probe, options))
        cov = evaluate(rem, cam, options.max_obliquity_deg)
        cov.position, cov.look_at, cov.up = position, look_at, up
        return cov

    finals = sorted((final(d, dist) for d, dist in candidates), key=lambda c: -c.score)
    chosen: list[Coverage] = []
    for c in finals:
        if len(chosen) < options.count and c.score > 0 and _far(c.direction, chosen, options.min_separation_deg):
            chosen.append(c)
    # too few distinct seeds: the best coarse directions far enough from those chosen (a
    # few tries each: every one costs a scoring at full size)
    tries = 3 * options.count
    for i in np.argsort(-coarse, kind="stable"):
        if len(chosen) >= options.count or coarse[i] <= 0 or tries == 0:
            break
        if _far(dirs[i], chosen, options.min_separation_deg):
            tries -= 1
            c = final(dirs[i], mid)
            if c.score > 0 and _far(c.direction, chosen, options.min_separation_deg):
                chosen.append(c)
    return sorted(chosen, key=lambda c: -c.score)


def _far(direction: np.ndarray, chosen: list[Coverage], min_deg: float) -> bool:
    return all(_angle(direction, c.direction) >= min_deg for c in chosen)


def sphere_search(
    rem: Remaining, n_directions: int, distance: float, size: tuple[int, int], options: SuggestOptions
) -> tuple[np.ndarray, np.ndarray]:
    """Every direction of a dense lattice, scored as the suggestions are: the reference
    the suggestions are measured against.

    Returns
    -------
    directions : (k, 3) float
        Those above the minimum elevation.
    good_mm2 : (k,) float
        Surface each would own at a good angle that no view owns yet, mm² (the score
        without favour or avoid weights).
    """
    dirs = sphere_directions(n_directions)
    dirs = dirs[elevation_deg(rem, dirs) >= options.min_elevation_deg]
    with one_thread():
        good = [
            evaluate(rem, view_camera(rem, d, distance, *size)[0], options.max_obliquity_deg).good_mm2 for d in dirs
        ]
    return dirs, np.array(good)


def template_image(rem: Remaining, cov: Coverage) -> np.ndarray:
    """An image template for a suggestion: the view's picture of the part, so a designer
    knows where to draw.

    White outside the part, light grey on the part, pale yellow on what the view would
    own; the part's outline in dark grey, the owned region's in orange.

    Returns
    -------
    (H, W, 3) uint8
    """
    import cv2

    fb = cov.face_buffer
    part = fb >= 0
    own = np.zeros_like(part)
    own[part] = cov.new[fb[part]]
    img = np.full((*fb.shape, 3), 255, np.uint8)
    img[part] = (228, 228, 228)
    img[own] = (255, 240, 190)
    k = np.ones((3, 3), np.uint8)
    width = max(1, int(round(max(fb.shape) / 800)))
    for mask, colour in ((part, (60, 60, 60)), (own, (230, 120, 0))):
        # the band just inside the mask's edge
        inner = cv2.erode(mask.astype(np.uint8), k, iterations=width, borderType=cv2.BORDER_REPLICATE) != 0
        img[mask & ~inner] = colour
    return img
