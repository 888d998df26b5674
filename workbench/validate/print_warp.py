"""The print's analysis grid and the photo warped onto it: visibility states, masks from the photo's optics.

Each print pixel of the analysis grid knows its surface point; a photo is warped onto the grid
through its posed camera and lens, and each grid pixel gets a visibility state: off the part,
not seen, occluded (or turned away), too oblique, at the edge of what is seen (where the
photo's pixels mix two surfaces: a step in its own depth buffer) or scored. Numeric functions
only: arrays in, arrays out.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numba
import numpy as np

from workbench.camera import Camera
from workbench.mesh.normals import vertex_normals
from workbench.raster import depth_buffer, interpolate, rasterize_triangles
from workbench.views.visibility import surface_faces_facing, unoccluded_many

MAX_GRID_PX = 4.0e6  # analysis grid: the print, reduced by a whole factor to at most this many pixels
EDGE_PX = 6  # band along the edge of what a photo sees (the film's rim included) that is not scored
DEPTH_STEP = 0.05  # relative depth jump between neighbouring photo pixels that is an outline or a fold
DEPTH_STEP_BAND_PX = 3.0  # photo pixels not scored on each side of such a step, plus twice the pre-blur
MAX_GRAZING = 3.0  # a photo pixel covering more print pixels than this (along its long axis) is too oblique

# states of a print pixel in one photo, in increasing order of what it says (the combined map keeps the highest)
OFF_PART, NOT_SEEN, OCCLUDED, GRAZING, EDGE, SHADOWED, HIGHLIGHT = range(7)
COLOUR_ONLY, UNRESOLVED, NORMAL, FULL, DEFECT = range(7, 12)
STATE_NAMES = [
    "off the part",
    "not seen",
    "occluded",
    "too oblique",
    "at the edge of what is seen",
    "deep shadow",
    "highlight",
    "measured: colour only (too little texture for the photo's noise)",
    "measured: colour only (detail finer than the photo resolves)",
    "measured: colour and shift across an edge",
    "measured: colour and full shift",
    "defective",
]
MEASURED = (COLOUR_ONLY, UNRESOLVED, NORMAL, FULL, DEFECT)


@dataclass
class PrintGrid:
    """The print's analysis grid and the surface under it.

    Attributes
    ----------
    X : (rows, cols, 3) float
        Surface point under each pixel centre, mm (NaN: off the part).
    owner : (rows, cols) int
        Owning view per pixel (-1: none).
    px_per_mm : float
        Grid resolution (the print's, divided by ``factor``).
    factor : int
        Print pixels per grid pixel along each axis.
    surface_per_print : (rows, cols) float
        Surface mm per print mm (the film's local stretch, geometric mean of both axes).
    reference : (rows, cols, 3) uint8
        The print on this grid.
    face : (rows, cols) int
        Triangle under each pixel (-1: off the part).
    crease_deg : (rows, cols) float32 or None
        How far the surface's own normal turns from its mean around each pixel, degrees
        (:func:`workbench.validate.dense.light.grid_creases`), made on first use: it is the
        surface's, the same for every photo of the part (a quarter of a second on a 1.4 Mpx grid).
    film : (rows, cols) int16 or None
        With several films, the film (0-based) under each pixel (-1: off the part); None for
        a design of one film. Each film is placed on its own (:func:`placement_field`).
    normal : (rows, cols, 3) float32 or None
        Unit surface normal under each pixel centre, interpolated from the area-weighted vertex
        normals as both renderers and a smooth real part shade (NaN off the part).
    """

    X: np.ndarray
    owner: np.ndarray
    px_per_mm: float
    factor: int
    surface_per_print: np.ndarray
    reference: np.ndarray
    face: np.ndarray
    crease_deg: np.ndarray | None = None
    film: np.ndarray | None = None
    normal: np.ndarray | None = None


def print_grid(V, F, flat_uv_mm, rect_height_mm, print_rgb, dpi, owner, face_film=None) -> PrintGrid:
    """Surface points, ownership and stretch of every pixel of the print's analysis grid.

    Parameters
    ----------
    V : (#V, 3) float
        Part, mm.
    F : (#F, 3) int
        Triangles.
    flat_uv_mm : (#V, 2) float
        Flat layout, mm (y up, the design rectangle's bottom-left at the origin).
    rect_height_mm : float
        Height of the design rectangle.
    print_rgb : (rows, cols, 3) uint8
        The print.
    dpi : float
        Its resolution.
    owner : (rows, cols) int
        Owning view per print pixel (-1: none).
    face_film : (#F,) int, optional
        With several films, the film of each face (-1: none).

    Returns
    -------
    PrintGrid
    """
    rows, cols = print_rgb.shape[:2]
    factor = max(1, int(np.ceil(np.sqrt(rows * cols / MAX_GRID_PX))))
    ppm = dpi / 25.4 / factor
    gr, gc = rows // factor, cols // factor
    # grid pixel centre (j, i) is at ((j + 0.5) / ppm, (i + 0.5) / ppm) mm
    P = np.stack([flat_uv_mm[:, 0] * ppm - 0.5, (rect_height_mm - flat_uv_mm[:, 1]) * ppm - 0.5], axis=1)
    face, bary = rasterize_triangles(P, F, gc, gr)
    X = interpolate(face, bary, F, V)
    N = interpolate(face, bary, F, vertex_normals(np.asarray(V, np.float64), np.asarray(F)))
    N = (N / np.maximum(np.linalg.norm(N, axis=-1, keepdims=True), 1e-12)).astype(np.float32)
    on = face >= 0
    # stretch: |∂X/∂x| and |∂X/∂y| per grid pixel, in mm per mm
    with np.errstate(invalid="ignore"):
        dx = _length(np.gradient(X, axis=1)) * ppm
        dy = _length(np.gradient(X, axis=0)) * ppm
    stretch = np.sqrt(dx * dy)
    stretch = np.where(np.isfinite(stretch), stretch, 1.0)
    ref = print_rgb[: gr * factor, : gc * factor]
    if factor > 1:
        ref = cv2.resize(ref, (gc, gr), interpolation=cv2.INTER_AREA)
    own = -np.ones((gr, gc), dtype=np.int16)
    if owner is not None:
        own = owner[factor // 2 :: factor, factor // 2 :: factor][:gr, :gc].astype(np.int16)
    own[~on] = -1
    film = None
    if face_film is not None:
        film = np.where(on, np.asarray(face_film)[np.maximum(face, 0)], -1).astype(np.int16)
    return PrintGrid(X, own, ppm, factor, stretch, np.ascontiguousarray(ref), face, film=film, normal=N)


@dataclass(frozen=True)
class PrintWarp:
    """The photo seen on the print (:func:`warp_to_print`).

    Attributes
    ----------
    warped : (rows, cols, 3) uint8
        0 where the photo does not see the point.
    state : (rows, cols) uint8
        Visibility states (see :func:`warp_to_print`).
    scale : float
        Photo pixels per grid pixel (median over the part; below 1 the photo is coarser).
    footprint : (rows, cols) float32
        Photo pixels per grid pixel at each grid pixel, along the grid axis the photo samples
        least (obliquity included): how finely the photo sees the print there; 0 where not seen.
    footprint_axes : (rows, cols, 2) float32
        The same for the camera's blur along x (axis 1) and y (axis 0): the photo's round blur
        of sigma s photo px lies on the grid as an ellipse whose spread along x is
        ``s / footprint_axes[..., 0]`` grid px and along y ``s / footprint_axes[..., 1]``; 0
        where not seen.
    """

    warped: np.ndarray
    state: np.ndarray
    scale: float
    footprint: np.ndarray
    footprint_axes: np.ndarray


def warp_to_print(photo: np.ndarray, cam: Camera, grid: PrintGrid, V, F, depth: np.ndarray | None = None) -> PrintWarp:
    """The photo seen on the print: each grid pixel takes the photo's colour of its surface point.

    Parameters
    ----------
    photo : (h, w, 3) uint8
        The photo.
    cam : Camera
        Its posed camera, with the lens's distortion.
    grid : PrintGrid
    V, F : arrays
        The part.
    depth : (h, w) float, optional
        Depth buffer of the part in the undistorted photo camera (computed when not given).

    Returns
    -------
    PrintWarp
        ``warped``; ``state``: OFF_PART, NOT_SEEN (outside the photo or behind the camera), OCCLUDED (hidden
        by another part of the mesh, or on a triangle that turns its back to the camera),
        EDGE (seen within a few photo pixels of a step in depth: the part's outline or a
        fold, where the photo's pixels mix two surfaces), GRAZING (seen too obliquely to
        measure) or FULL (seen: to be scored); ``scale``, ``footprint`` and ``footprint_axes``.
    """
    rows, cols = grid.X.shape[:2]
    on = np.isfinite(grid.X[..., 0])
    pts = grid.X[on]
    ideal = Camera(cam.K, cam.R, cam.t, cam.width, cam.height)
    pdepth = photo_buffers(cam, V, F)[1] if depth is None else depth
    # (the surface faces the camera by its smooth normal, as both renderers and a real part
    # show it: on a faceted mesh, a triangle beside the contour may face the camera while the
    # surface there has already turned away, and the photo shows the film's back)
    facing = None if grid.normal is None else facing_camera(pts, grid.normal[on], ideal.center)
    xy, proj, inside, inside_ideal, shown = surface_in_photo(cam, pts, grid.face[on], V, F, pdepth, facing)
    mapx = np.full((rows, cols), -1e4, dtype=np.float32)
    mapy = np.full((rows, cols), -1e4, dtype=np.float32)
    mapx[on], mapy[on] = proj[:, 0], proj[:, 1]
    # how many photo pixels one grid pixel spans: the photo is smoothed to about one grid pixel
    # first (no aliasing), and a grid pixel seen far too obliquely is not scored
    gxx, gxy = np.gradient(mapx, axis=1), np.gradient(mapy, axis=1)
    gyx, gyy = np.gradient(mapx, axis=0), np.gradient(mapy, axis=0)
    along_x, along_y = np.hypot(gxx, gxy), np.hypot(gyx, gyy)
    ok = on & (np.abs(mapx) < 1e4)
    scale = float(np.median(np.sqrt(along_x[ok] * along_y[ok]))) if ok.any() else 1.0
    src = photo
    if scale > 1.5:
        src = cv2.GaussianBlur(photo, (0, 0), 0.5 * np.sqrt(scale * scale - 1.0))
    warped = cv2.remap(src, mapx, mapy, cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT, borderValue=0)
    state = np.full((rows, cols), OFF_PART, dtype=np.uint8)
    st = np.full(len(pts), NOT_SEEN, dtype=np.uint8)
    st[inside & inside_ideal & ~shown] = OCCLUDED
    st[inside & shown] = FULL
    # where the photo's pixels mix two surfaces (the part's outline against the background,
    # a fold in front of what lies behind it), the blur spreads the nearer surface's colour
    # over the other: a band there, measured in the photo, is not scored
    pre_blur = 0.5 * np.sqrt(scale * scale - 1.0) if scale > 1.5 else 0.0
    band_px = DEPTH_STEP_BAND_PX + 2.0 * pre_blur
    steps = depth_steps(pdepth, band_px, float(cam.K[0, 0]))
    if facing is not None and not facing.all():
        # and where the smooth surface turns its back while the depth buffer goes on over it
        # (a shell that curls under: the film's side and its back side meet at the contour with
        # no step in depth), the photo's pixels mix the two as well: a band as wide as a step's
        # around the back the photo shows
        turned = np.flatnonzero(~facing & inside_ideal)
        # (shown by the depth test and the mesh's own facing test: the back only where a
        # triangle or its neighbours face the camera too. The depth test alone widens the band:
        # on Mitsuba's glossy cow it also masks an 81.5 mm² "slide" where the photo shows the back,
        # a change for the corpus to measure first)
        back = surface_in_photo(cam, pts[turned], grid.face[on][turned], V, F, pdepth)[4]
        steps |= contour_band(xy[turned[back]], band_px, steps.shape)
    at = inside_ideal & (st == FULL)
    ix = np.clip(np.rint(xy[at, 0]).astype(np.int64), 0, ideal.width - 1)
    iy = np.clip(np.rint(xy[at, 1]).astype(np.int64), 0, ideal.height - 1)
    st[np.flatnonzero(at)[steps[iy, ix]]] = EDGE
    state[on] = st
    with np.errstate(divide="ignore", invalid="ignore"):
        # a grid pixel whose photo footprint is much thinner along one axis than the other
        oblique = np.maximum(along_x, along_y) / np.minimum(along_x, along_y) > MAX_GRAZING
    # (too oblique whatever else: beside an outline the surface turns away, and what keeps it
    # from being measured there is how obliquely it is seen)
    state[((state == FULL) | (state == EDGE)) & oblique] = GRAZING
    footprint = np.where(ok, np.minimum(along_x, along_y), 0.0).astype(np.float32)
    return PrintWarp(warped, state, scale, footprint, footprint_axes(gxx, gxy, gyx, gyy, ok))


def footprint_axes(gxx, gxy, gyx, gyy, ok: np.ndarray) -> np.ndarray:
    """Photo pixels per grid pixel that the camera's blur sees along the grid's x (axis 1) and y (axis 0).

    The map from the grid to the photo has the Jacobian J = [[gxx, gyx], [gxy, gyy]] (photo px
    per grid px; its columns are the steps of one grid column and one grid row). A round blur
    of variance s² in the photo is, pulled back to the grid, a Gaussian of covariance
    s² (JᵀJ)⁻¹, whose spread along x is s sqrt([(JᵀJ)⁻¹]ₓₓ) = s |J_y| / |det J| (|J_y| the
    length of J's second column) and along y s |J_x| / |det J|: so the photo samples the blur
    along x at |det J| / |J_y| photo px per grid px, and along y at |det J| / |J_x|. Where the
    photo sees the print from the side, the two differ by the obliquity (2.3 times over a
    scanned elephant's flank seen from above), and one round blur, as wide as the coarser
    axis needs, blurred the print's text across its strokes that the photo shows sharp.

    Parameters
    ----------
    gxx, gxy, gyx, gyy : (rows, cols) float
        Photo x and y per grid column (gxx, gxy) and per grid row (gyx, gyy).
    ok : (rows, cols) bool
        Where the photo sees the grid.

    Returns
    -------
    (rows, cols, 2) float32
        Along x and y; 0 where not ``ok``.
    """
    det = np.abs(gxx * gyy - gxy * gyx)
    with np.errstate(divide="ignore", invalid="ignore"):
        fx = det / np.hypot(gyx, gyy)
        fy = det / np.hypot(gxx, gxy)
    out = np.stack([np.where(ok, fx, 0.0), np.where(ok, fy, 0.0)], axis=-1)
    return np.nan_to_num(out, nan=0.0, posinf=0.0).astype(np.float32)


def box_slices(bbox_mm, px_per_mm: float) -> tuple[slice, slice]:
    """A box on the print as the grid's rows and columns, its far edges included.

    Parameters
    ----------
    bbox_mm : (4,) float
        ``x0, y0, x1, y1``, print mm (y down), as a defect's ``bbox_mm``.
    px_per_mm : float
        The grid's resolution.

    Returns
    -------
    (slice, slice)
        Rows and columns, clipped at 0 (the far edges clip as numpy clips a slice).
    """
    x0, y0, x1, y1 = (int(round(v * px_per_mm)) for v in bbox_mm)
    return slice(max(y0, 0), y1 + 1), slice(max(x0, 0), x1 + 1)


def facing_camera(X: np.ndarray, normals: np.ndarray, center: np.ndarray) -> np.ndarray:
    """Surface points whose normal faces a camera centre.

    Parameters
    ----------
    X : (n, 3) float
        Surface points, mm.
    normals : (n, 3) float
        Their unit normals (NaN: none, which faces nothing).
    center : (3,) float
        Camera centre, mm.

    Returns
    -------
    (n,) bool
        True where the camera lies on the normal's side of the point's tangent plane.
    """
    return np.einsum("ij,ij->i", normals, np.asarray(center, np.float64) - X) > 0


def contour_band(xy: np.ndarray, radius_px: float, shape: tuple[int, int]) -> np.ndarray:
    """Photo pixels within ``radius_px`` of points the photo shows turned away (the film's back).

    Parameters
    ----------
    xy : (n, 2) float
        The turned-away points the depth test keeps, photo pixels through the ideal camera.
        Points a grid pixel apart lie at most the grid's scale in photo pixels apart, which the
        band (a step's: its width plus twice the pre-blur, about that scale) closes over.
    radius_px : float
        Width of the band, photo pixels.
    shape : (h, w)
        The photo's size.

    Returns
    -------
    (h, w) bool
    """
    h, w = shape
    out = np.zeros((h, w), np.uint8)
    if not len(xy):
        return out.astype(bool)
    ix = np.clip(np.rint(xy[:, 0]).astype(np.int64), 0, w - 1)
    iy = np.clip(np.rint(xy[:, 1]).astype(np.int64), 0, h - 1)
    out[iy, ix] = 1
    r = max(int(np.ceil(radius_px)), 1)
    # (only the points' bounding box and the band around it can change)
    y0, y1 = max(int(iy.min()) - r, 0), min(int(iy.max()) + r + 1, h)
    x0, x1 = max(int(ix.min()) - r, 0), min(int(ix.max()) + r + 1, w)
    k = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * r + 1, 2 * r + 1))
    out[y0:y1, x0:x1] = cv2.dilate(out[y0:y1, x0:x1], k)
    return out.astype(bool)


def surface_in_photo(
    cam: Camera, X: np.ndarray, faces: np.ndarray, V, F, depth: np.ndarray, facing: np.ndarray | None = None
):
    """Where surface points fall in a photo, and which of them the photo shows.

    Parameters
    ----------
    cam : Camera
        The photo's posed camera, with its lens.
    X : (n, 3) float
        Surface points, mm.
    faces : (n,) int
        The triangle of ``F`` each point lies on.
    V, F : arrays
        The part.
    depth : (h, w) float
        Depth buffer of the part in the undistorted photo camera (:func:`photo_buffers`).
    facing : (n,) bool, optional
        Which points face the camera (:func:`facing_camera` of the smooth normal); without
        it, those on a part of the mesh that faces it
        (:func:`workbench.views.visibility.surface_faces_facing`).

    Returns
    -------
    xy : (n, 2) float
        Pixel positions through the ideal (undistorted) camera.
    lens : (n, 2) float
        Pixel positions through the lens: where to read the photo.
    inside : (n,) bool
        In front of the camera and inside the photo, through the lens.
    inside_ideal : (n,) bool
        The same through the ideal camera (where the depth buffer can say what hides them).
    shown : (n,) bool
        Not hidden by another part of the mesh and facing the camera (``facing``, or by
        :func:`workbench.views.visibility.surface_faces_facing`): just behind a fold,
        the surface that turns its back is within the depth test's tolerance of the surface in
        front of it, while a scan's tiny triangle folded over inside a surface that faces the
        camera is shown by it.
    """
    ideal = Camera(cam.K, cam.R, cam.t, cam.width, cam.height)
    xy, z, lens = project_through_lens(cam, X)
    seen = np.zeros(len(X), dtype=np.bool_)
    unoccluded_many(depth, ideal.width, ideal.height, ideal.K[0, 0], xy, z, seen)
    in_front = z > 0

    def framed(p):
        return in_front & (p[:, 0] >= 0) & (p[:, 1] >= 0) & (p[:, 0] <= cam.width - 1) & (p[:, 1] <= cam.height - 1)

    shown = seen & (surface_faces_facing(V, F, ideal.center)[faces] if facing is None else facing)
    return xy, lens, framed(lens), framed(xy), shown


def depth_steps(depth: np.ndarray, radius_px: float, fx: float | None = None) -> np.ndarray:
    """Photo pixels near a step in depth: the part's outline, or one surface in front of another.

    A step is where the photo's pixels mix two surfaces: a change in depth between neighbouring
    pixels that the surface's slope on neither side predicts. A steep surface changes depth
    fast but steadily (its slope, extrapolated from either side, predicts the next pixel) and
    mixes nothing: it is too oblique where it is (``warp_to_print``), not an edge.

    Parameters
    ----------
    depth : (h, w) float
        Depth buffer of the part in the undistorted photo camera, mm (+inf where no part).
    radius_px : float
        Width of the band on each side of a step, photo pixels.
    fx : float, optional
        The camera's focal length, pixels. With it, a change is a step when it departs from
        both sides' slopes by more than the depth one pixel spans on a surface at the largest
        obliquity that is scored: one pixel spans z / fx mm at depth z, and such a surface
        (cos θ = 1 / MAX_GRAZING) changes depth by tan θ · z / fx across it; a curved surface's
        slope changes by far less from one pixel to the next (a 5 mm fillet at that obliquity,
        0.1 mm pixels: 0.05 mm against 0.28 mm). Without it, by DEPTH_STEP of the depth.

    Returns
    -------
    (h, w) bool
        True within ``radius_px`` of a step.
    """
    h, w = depth.shape
    r = max(int(np.ceil(radius_px)), 1)
    out = np.zeros((h, w), bool)
    # a step needs the part on one side: only the part's bounding box, with a margin of the band
    # and of the pairs' reach, can hold one (a 12 Mpx photo's part fills a quarter of it).
    # The result is the same: the margin's pixels hold no part, so the pairs there see what
    # they see in the whole image, and the band reaches no farther than the margin
    rows = np.flatnonzero(np.isfinite(depth).any(axis=1))
    if not len(rows):
        return out
    cols = np.flatnonzero(np.isfinite(depth[rows[0] : rows[-1] + 1]).any(axis=0))
    m = r + 3
    y0, y1 = max(rows[0] - m, 0), min(rows[-1] + 1 + m, h)
    x0, x1 = max(cols[0] - m, 0), min(cols[-1] + 1 + m, w)
    out[y0:y1, x0:x1] = _depth_steps(depth[y0:y1, x0:x1], r, fx)
    return out


def _depth_steps(depth: np.ndarray, r: int, fx: float | None) -> np.ndarray:
    """:func:`depth_steps` within a crop whose border rows and columns hold no part; (h, w) bool."""
    # (no part: a depth far beyond any, finite, so that differences stay numbers)
    d = np.where(np.isfinite(depth), depth, 1e12)
    near = np.minimum(d, np.minimum(np.roll(d, 1, 0), np.roll(d, 1, 1)))
    if fx is None:
        limit = DEPTH_STEP * near
    else:
        tan_max = np.sqrt(MAX_GRAZING**2 - 1.0)
        limit = np.minimum(DEPTH_STEP, tan_max / fx) * near
    step = np.zeros(d.shape, bool)
    for axis in (0, 1):
        a = np.moveaxis(d, axis, 0)
        lim = np.moveaxis(limit, axis, 0)[1:-2]
        s = np.moveaxis(step, axis, 0)
        # the pair (k, k + 1), and the depth at k + 1 predicted from the slope on its left
        # (2 d[k] - d[k - 1]) and at k from the slope on its right (2 d[k + 1] - d[k + 2])
        d0, d1, dm, dp = a[1:-2], a[2:-1], a[:-3], a[3:]
        # (a jump that either slope predicts is one surface; a ledge on a steep slope can make
        # the jump itself small, so it is not asked for)
        pair = (np.abs(d1 - (2.0 * d0 - dm)) > lim) & (np.abs(d0 - (2.0 * d1 - dp)) > lim)
        s[1:-2] |= pair
        s[2:-1] |= pair
    # (the crop's border rows and columns hold no part: a pair there has none to mix)
    k = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * r + 1, 2 * r + 1))
    return cv2.dilate(step.astype(np.uint8), k).astype(bool)


def project_through_lens(cam: Camera, X: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Pixel positions of world points without and with the lens, in one pass.

    The lens as ``cv2.projectPoints`` (five coefficients). One compiled loop rather than numpy
    or OpenCV: ``projectPoints`` takes about a second for the 1.4 million points of a 300 dpi
    print, numpy (a dozen temporary arrays of that length) 0.2 to 1 s, this 20 ms.

    Parameters
    ----------
    cam : Camera
        Pose, intrinsics and distortion (k1, k2, p1, p2, k3).
    X : (n, 3) float
        World points, mm.

    Returns
    -------
    xy : (n, 2) float
        Pixel coordinates through the ideal (undistorted) camera, as :meth:`Camera.project`.
    z : (n,) float
        Depth along the optical axis, mm (≤ 0 behind the camera).
    lens : (n, 2) float
        Pixel coordinates through the lens (NaN behind the camera).
    """
    n = len(X)
    dist = np.zeros(5)
    d = np.ravel(cam.dist)[:5]
    dist[: len(d)] = d
    xy, z, lens = np.empty((n, 2)), np.empty(n), np.empty((n, 2))
    _project_through_lens(
        np.ascontiguousarray(X, dtype=np.float64),
        np.ascontiguousarray(cam.R, dtype=np.float64),
        np.ascontiguousarray(cam.t, dtype=np.float64).reshape(3),
        np.ascontiguousarray(cam.K, dtype=np.float64),
        dist,
        xy,
        z,
        lens,
    )
    return xy, z, lens


@numba.njit(cache=True, nogil=True, error_model="numpy")
def _project_through_lens(X, R, t, K, dist, xy, z, lens):
    k1, k2, p1, p2, k3 = dist[0], dist[1], dist[2], dist[3], dist[4]
    for i in range(X.shape[0]):
        x0, x1, x2 = X[i, 0], X[i, 1], X[i, 2]
        c0 = x0 * R[0, 0] + x1 * R[0, 1] + x2 * R[0, 2] + t[0]
        c1 = x0 * R[1, 0] + x1 * R[1, 1] + x2 * R[1, 2] + t[1]
        c2 = x0 * R[2, 0] + x1 * R[2, 1] + x2 * R[2, 2] + t[2]
        z[i] = c2
        x = c0 / c2
        y = c1 / c2
        xy[i, 0] = x * K[0, 0] + y * K[0, 1] + K[0, 2]
        xy[i, 1] = x * K[1, 0] + y * K[1, 1] + K[1, 2]
        if c2 <= 0:
            lens[i, 0] = np.nan
            lens[i, 1] = np.nan
            continue
        r2 = x * x + y * y
        radial = 1 + r2 * (k1 + r2 * (k2 + r2 * k3))
        xd = x * radial + 2 * p1 * x * y + p2 * (r2 + 2 * x * x)
        yd = y * radial + p1 * (r2 + 2 * y * y) + 2 * p2 * x * y
        lens[i, 0] = K[0, 0] * xd + K[0, 1] * yd + K[0, 2]
        lens[i, 1] = K[1, 1] * yd + K[1, 2]


def photo_buffers(cam: Camera, V, F) -> tuple[np.ndarray, np.ndarray]:
    """Face and depth buffers (h, w) of the part seen by the undistorted photo camera (-1, +inf: none)."""
    ideal = Camera(cam.K, cam.R, cam.t, cam.width, cam.height)
    pxy, pz = ideal.project(V)
    return depth_buffer(pxy, pz, F, ideal.width, ideal.height)


def rim_band(state: np.ndarray) -> np.ndarray:
    """The states with a band of EDGE_PX grid pixels along the film's rim and the photo's frame made EDGE.

    Along the film's outline (beyond it: OFF_PART) the photo's pixels mix the film with what
    lies beyond it, and the film's landing is measured there apart (``landing``); along the
    photo's frame (NOT_SEEN) nothing of the print lies on the far side. Nothing else opens a
    band: where the photo mixes two surfaces, the depth step already made its pixels EDGE, in
    the photo's own pixels (:func:`depth_steps`); a surface too oblique, hidden or turned
    away beside a scored one mixes nothing into it, and the fits and the flow's
    normalisation weigh only scored pixels.

    Parameters
    ----------
    state : (rows, cols) uint8
        Visibility states (:func:`warp_to_print`).

    Returns
    -------
    (rows, cols) uint8
        A copy, FULL pixels within EDGE_PX of OFF_PART or NOT_SEEN made EDGE.
    """
    state = state.copy()
    k = 2 * EDGE_PX + 1
    beyond = np.isin(state, (OFF_PART, NOT_SEEN)).astype(np.uint8)
    near = cv2.dilate(beyond, np.ones((k, k), np.uint8), borderValue=1).astype(bool)
    state[(state == FULL) & near] = EDGE
    return state


def _length(a: np.ndarray) -> np.ndarray:
    """Length of (..., 3) vectors: ``np.linalg.norm(a, axis=-1)``'s numbers at a quarter of its time."""
    return np.sqrt(_csum(a * a))


def _csum(a: np.ndarray) -> np.ndarray:
    """Sum over the last (short) axis, channel by channel: the same numbers as ``a.sum(axis=-1)`` (which adds
    them in this order too) at a fifth of its time."""
    out = a[..., 0] + a[..., 1]
    for c in range(2, a.shape[-1]):
        out += a[..., c]
    return out
