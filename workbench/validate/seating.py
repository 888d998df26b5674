"""Seating: the part's rigid motion on its plate, measured from what the part itself shows.

The board poses the camera; the part is set down by hand inside the outline the fixture
draws, a millimetre off and turned a little. Film placement must be judged on the part, so
the part's own motion is measured first, from its outline against the plate (the design
rim and the occluding contours of the surface), never from its decoration (the film's
placement is what is being judged).

The motion and its convention: :mod:`workbench.part_motion`.

Method (model-based edge alignment, as in RAPiD / moving-edge trackers):

1. the contour of the moved part in the board-posed camera: boundary (rim) edges and edges
   between faces that face the camera and faces that do not, sampled every few pixels,
   kept where a z-buffer of the part says the part lies on one side and nothing of it on the
   other (so the far side is the plate);
2. along each sample's image normal, the photo's profile against the plate's predicted
   profile (the fixture's own board image through the camera, at the photo's scale and at
   the blur that best predicts the photo's plate, with an affine gain per channel; beyond
   the plate, the table as one colour): where the photo stops looking like the plate is the
   part's edge; the decoration's own edges lie inside it and are never taken (the outermost
   departure from the plate is; samples where the print's rim colour is the plate's, or
   where the photo inside the edge is not the rim's colour, are dropped), the board's edges
   are in the prediction;
3. the edge to sub-pixel by the peak of the residual's derivative along the normal;
4. Gauss-Newton over the 6-DoF motion on the samples' normal distances, Tukey-weighted,
   a wide search at a coarse step on a halved photo first, then a narrow band at half a
   pixel, with the plate's contact as a prior (:data:`PLATE_MM`); several photos of one part
   in one system (:func:`estimate_seating`) or combined by their information (:func:`fuse`).

Observability: the Gauss-Newton normal matrix, in units of vertex displacement (rotations
scaled by the part's RMS radius), gives each direction of motion a standard deviation; a
direction the photos determine worse than :data:`UNDETERMINED_MM` (a part symmetric about
an axis turning about it; a rim out of frame; a lift off the plate seen from one side) is
reported as undetermined and not applied: it stays at zero motion.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import cv2
import numpy as np

from workbench.camera import Camera
from workbench.part_motion import motion_parameters, part_centre, rodrigues, skew
from workbench.raster import depth_buffer

# a direction of motion known worse than this (1 sigma, mm of vertex displacement) is not applied
UNDETERMINED_MM = 0.05
# contour samples this far apart along the contour, photo pixels (at most MAX_SAMPLES per photo)
SPACING_PX = 3.0
MAX_SAMPLES = 1000
# the widest search: 2 mm of offset and 1 degree over the part, with a margin
SEARCH_MM = 4.0
# profile sample step, photo pixels (the finest; a wide search takes about COARSE_SAMPLES each side)
STEP_PX = 0.5
COARSE_SAMPLES = 24
# the plate's contact, as a measurement: the part rests on it (no lift, no tilt) to this, mm
PLATE_MM = 0.002
# the motion's out-of-plane terms: rotation about x and y (times rho), translation along z
OUT_OF_PLANE = (0, 1, 5)
# the least difference (RGB, 0-255) between the print at the rim and the plate beside it
MIN_RIM_CONTRAST = 60.0
# the camera blur assumed for the plate's prediction, photo pixels
BLUR_PX = 1.0


@dataclass
class Seating:
    """The part's motion on its plate: ``X_photo = R X_design + t`` (mesh frame, mm).

    Attributes
    ----------
    R : (3, 3) float
    t : (3,) float, mm
    centre : (3,) float
        The rotation's centre (the design's bounding-box centre), mm.
    uncertainty_mm : float
        Largest 1-sigma displacement of a vertex of the part, mm (determined directions).
    undetermined : list of dict
        Directions of motion the photos do not determine (set to zero motion).
    samples : int
        Contour samples used (weight > 0) in the last iteration.
    rms_px : float
        Their weighted RMS residual, photo pixels.
    H : (6, 6) float
        The photos' information about the motion (normal matrix over the residual variance),
        in (rotation * rho, translation) mm units, mm^-2.
    rho : float
        The part's RMS radius about ``centre``, mm.
    """

    R: np.ndarray
    t: np.ndarray
    centre: np.ndarray
    uncertainty_mm: float = 0.0
    undetermined: list = field(default_factory=list)
    samples: int = 0
    rms_px: float = float("nan")
    H: np.ndarray | None = None
    rho: float = 1.0
    determined: bool = True
    held_by_plate: list = field(default_factory=list)

    def offset_mm(self) -> np.ndarray:
        return motion_parameters(self.R, self.t, self.centre)[0]

    def rotation_deg(self) -> np.ndarray:
        return motion_parameters(self.R, self.t, self.centre)[1]

    def to_dict(self) -> dict:
        off, rot = motion_parameters(self.R, self.t, self.centre)
        return {
            "R": self.R.tolist(),
            "t_mm": self.t.tolist(),
            "offset_mm": off.tolist(),
            "rotation_deg": rot.tolist(),
            "centre_mm": self.centre.tolist(),
            "uncertainty_mm": float(self.uncertainty_mm),
            "undetermined": self.undetermined,
            "held_by_plate": self.held_by_plate,
            "contour_samples": int(self.samples),
            "contour_rms_px": None if not np.isfinite(self.rms_px) else float(self.rms_px),
        }

    def moved(self, V: np.ndarray) -> np.ndarray:
        """Design vertices where the part sits; (n, 3)."""
        return V @ self.R.T + self.t


def _edges(F: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Unique edges (e, 2) and their faces (e, 2), -1 for the missing face of a boundary edge."""
    F = np.asarray(F)
    he = np.concatenate([F[:, [0, 1]], F[:, [1, 2]], F[:, [2, 0]]])
    fid = np.tile(np.arange(len(F)), 3)
    key = np.sort(he, axis=1)
    order = np.lexsort((key[:, 1], key[:, 0]))
    key, fid = key[order], fid[order]
    first = np.ones(len(key), bool)
    first[1:] = (key[1:] != key[:-1]).any(axis=1)
    idx = np.flatnonzero(first)
    counts = np.diff(np.append(idx, len(key)))
    faces = np.full((len(idx), 2), -1)
    faces[:, 0] = fid[idx]
    two = counts >= 2
    faces[two, 1] = fid[idx[two] + 1]
    return key[idx], faces


@dataclass
class Plate:
    """The fixture's plate as the photo should see it: board image blurred to the photo's scale.

    Attributes
    ----------
    image : (h, w, 3) float32
        The plate's image (0-255), pixel (i, j) centre at board mm ((j + 0.5) / ppm - margin, ...).
    ppm : float
        Its pixels per mm.
    margin_mm : float
        White margin before the board's top-left corner.
    origin : (3,) float
        Board's top-left corner in the mesh frame (board point (x, y) at origin + (x, -y, 0)).
    corner_px : (2,) int
        The whole plate image's pixel (column, row) at this image's pixel (0, 0).
    """

    image: np.ndarray
    ppm: float
    margin_mm: float
    origin: np.ndarray
    corner_px: tuple = (0, 0)


def plate_model(fixture: dict, px_per_mm: float, around=None, blur_px: float = BLUR_PX, drawn=None) -> Plate:
    """The plate as a photo of ``px_per_mm`` (on the plate) and ``blur_px`` sees it.

    ``around``: (x0, y0, x1, y1) in the mesh frame, mm: only that part of the plate (where the
    part's outline can be) is drawn and blurred. ``drawn``: a dict that keeps the drawing
    (unblurred) for the next call with another blur.

    The board image the renderer draws (:func:`workbench.render.photo.board_texture`),
    at about twice the photo's scale, blurred with the photo's blur and its pixel's
    footprint (a box of 1 px: variance 1/12).
    """
    from workbench.render.photo import PLATE_MARGIN_MM

    key = (round(float(px_per_mm), 3), None if around is None else tuple(np.round(around, 3)))
    if drawn is not None and key in drawn:
        img, ppm, origin, corner = drawn[key]
    else:
        img, ppm, origin, corner = _draw_plate(fixture, px_per_mm, around)
        if drawn is not None:
            drawn[key] = (img, ppm, origin, corner)
    sigma = np.sqrt(blur_px**2 + 1.0 / 12.0) * ppm / px_per_mm
    img = cv2.GaussianBlur(img, (0, 0), sigma, borderType=cv2.BORDER_REPLICATE)
    if img.ndim == 2:
        img = img[..., None]
    return Plate(img, ppm, PLATE_MARGIN_MM, origin, corner)


def _draw_plate(fixture: dict, px_per_mm: float, around):
    """The plate's image (float32, one channel without a colour chart nearby), its px/mm, origin and corner."""
    from workbench.render.photo import PLATE_MARGIN_MM, board_texture

    # drawn at an even number of pixels per mm, at least twice the photo's (whole pixels for
    # squares and markers in 0.5 mm steps): drawing at the renderer's 20 px/mm took a second
    # (a plate image at the photo's own scale: the photo's blur and pixel make it smooth enough
    # to interpolate; at twice the scale its blur took half a second of a 12 Mpx photo)
    ppm = float(min(20, max(4, 2 * int(np.ceil(px_per_mm / 2)))))
    chart = fixture.get("colour_chart")
    if chart is not None and around is not None:
        # the colour chart is painted only where it can be beside the part (its colours need
        # colour-science, a second's import)
        origin0 = np.asarray(fixture["origin_mm"], dtype=np.float64)
        cx0, cy0, cx1, cy1 = chart["frame_board_mm"]
        x0, y0, x1, y1 = around
        bx0, bx1, by0, by1 = x0 - origin0[0], x1 - origin0[0], origin0[1] - y1, origin0[1] - y0
        if cx1 < bx0 or cx0 > bx1 or cy1 < by0 or cy0 > by1:
            fixture = {**fixture, "colour_chart": None}
    img, ppm = board_texture(fixture, ppm)
    origin = np.asarray(fixture["origin_mm"], dtype=np.float64)
    j0 = i0 = 0
    if around is not None:
        x0, y0, x1, y1 = around
        # mesh (x, y) is board (x - ox, oy - y); plate pixel = (board + margin) * ppm - 0.5
        j0 = int(np.clip(np.floor((x0 - origin[0] + PLATE_MARGIN_MM) * ppm), 0, img.shape[1] - 1))
        j1 = int(np.clip(np.ceil((x1 - origin[0] + PLATE_MARGIN_MM) * ppm) + 1, j0 + 1, img.shape[1]))
        i0 = int(np.clip(np.floor((origin[1] - y1 + PLATE_MARGIN_MM) * ppm), 0, img.shape[0] - 1))
        i1 = int(np.clip(np.ceil((origin[1] - y0 + PLATE_MARGIN_MM) * ppm) + 1, i0 + 1, img.shape[0]))
        img = img[i0:i1, j0:j1]
    if fixture.get("colour_chart") is None:
        img = img[..., 0]  # black and white: one channel
    return np.ascontiguousarray(img, dtype=np.float32), ppm, origin, (j0, i0)


def print_reference(flat_mm: np.ndarray, height_mm: float, rgb: np.ndarray, dpi: float, px_per_mm: float = 4.0):
    """Each vertex's print pixel and the print at ``px_per_mm`` (for the rim's colour).

    Parameters
    ----------
    flat_mm : (n, 2) float
        Flat layout, mm (y up from the design rectangle's bottom-left).
    height_mm : float
        The design rectangle's height.
    rgb : (rows, cols, 3) uint8
        The print at ``dpi``.
    dpi : float
    px_per_mm : float
        Resolution of the returned print (area-averaged: the rim's colour over a quarter mm).

    Returns
    -------
    uv_px : (n, 2) float
        Pixel of each vertex in the returned print (centres at integers).
    image : (h, w, 3) float32
    """
    ppm = dpi / 25.4
    s = min(1.0, px_per_mm / ppm)
    rows, cols = rgb.shape[:2]
    small = cv2.resize(rgb, (max(int(round(cols * s)), 1), max(int(round(rows * s)), 1)), interpolation=cv2.INTER_AREA)
    k = small.shape[1] / cols * ppm  # its pixels per mm
    uv = np.stack([flat_mm[:, 0], height_mm - flat_mm[:, 1]], axis=1) * k - 0.5
    return uv, small.astype(np.float32)


@dataclass
class PhotoData:
    """One photo for seating: its camera (posed by the board), its image and its plate model.

    Attributes
    ----------
    camera : Camera
    photo : (H, W, 3) uint8 or float32
        RGB.
    plate : Plate
    pyramid : list
        The photo halved once and twice (``cv2.pyrDown``), made when first asked for.
    """

    camera: Camera
    photo: np.ndarray
    plate: Plate
    pyramid: list = field(default_factory=list)

    def level(self, k: int) -> np.ndarray:
        """The photo at 2**-k of its size (0: itself)."""
        if not self.pyramid:
            self.pyramid.append(self.photo)
        while len(self.pyramid) <= k:
            self.pyramid.append(cv2.pyrDown(self.pyramid[-1]))
        return self.pyramid[k]


def prepare(photo_rgb: np.ndarray, camera: Camera, fixture: dict, V: np.ndarray, cache: dict | None = None):
    """:class:`PhotoData` of a photo: the plate model at the photo's scale and blur (cached).

    The photo's blur is the one of :data:`BLURS_PX` whose plate model best predicts the photo
    on the plate around the part (an affine gain per photo): a sharp photo against a plate
    predicted blurred moved the outline by a pixel beside every edge of the board.
    """
    c = part_centre(V)
    # the photo's scale on the plate near the part: mm per pixel at the centre's depth
    z = camera.to_camera(c[None])[0, 2]
    px_per_mm = camera.K[0, 0] / max(z, 1e-6)
    m = 2 * SEARCH_MM + 5.0
    around = (V[:, 0].min() - m, V[:, 1].min() - m, V[:, 0].max() + m, V[:, 1].max() + m)
    photo = np.ascontiguousarray(photo_rgb)
    best, plate = np.inf, None
    for blur in BLURS_PX:
        key = ("seating plate", round(float(px_per_mm), 1), blur)
        if cache is not None and key in cache:
            model = cache[key]
        else:
            drawn = cache.setdefault("seating plate drawings", {}) if cache is not None else {}
            model = plate_model(fixture, px_per_mm, around, blur, drawn)
            if cache is not None:
                cache[key] = model
        misfit = _plate_misfit(PhotoData(camera, photo, model), V, around)
        if misfit < best:
            best, plate = misfit, model
    return PhotoData(camera, photo, plate)


# the photo blurs (Gaussian sigma, photo pixels) the plate's prediction is tried with
BLURS_PX = (0.0, 0.35, 0.7, 1.0, 1.4)


def _plate_misfit(data: PhotoData, V: np.ndarray, around) -> float:
    """RMS of the photo against the plate model (affine grey gain) on a ring of the plate around the part."""
    x0, y0, x1, y1 = around
    # points of the plate between the part's footprint (plus the search) and the plate model's edge
    gx, gy = np.meshgrid(np.linspace(x0, x1, 160), np.linspace(y0, y1, 120))
    inner = SEARCH_MM + 1.0
    off = (
        (gx < V[:, 0].min() - inner) | (gx > V[:, 0].max() + inner) | (gy < V[:, 1].min() - inner)
        | (gy > V[:, 1].max() + inner)
    )  # fmt: skip
    X = np.stack([gx[off], gy[off], np.full(off.sum(), data.plate.origin[2])], axis=1)
    cam = data.camera
    pts, _ = cv2.projectPoints(X, cv2.Rodrigues(cam.R)[0], cam.t, cam.K, cam.dist)
    pts = pts.reshape(-1, 2)
    xy, _ = Camera(cam.K, cam.R, cam.t, cam.width, cam.height).project(X)
    I = _sample(data.photo, pts[:, 0], pts[:, 1]).mean(axis=1)
    P = _plate_colour(data, xy)[:, 0]
    ok = np.isfinite(I) & np.isfinite(P)
    if ok.sum() < 50:
        return np.inf
    A = np.stack([P[ok], np.ones(ok.sum())], axis=1)
    sol, *_ = np.linalg.lstsq(A, I[ok], rcond=None)
    return float(np.sqrt(np.mean((A @ sol - I[ok]) ** 2)))


def contour_samples(camera: Camera, Vm: np.ndarray, F: np.ndarray, V: np.ndarray, edges, spacing_px: float,
                    buffers=None):  # fmt: skip
    """Samples of the moved part's outline in the undistorted photo camera.

    Parameters
    ----------
    camera : Camera
        Board-posed photo camera (its distortion unused here).
    Vm : (n, 3) float
        Moved vertices, mm.
    F : (m, 3) int
    V : (n, 3) float
        Design vertices, mm (the samples' design points).
    edges : tuple
        :func:`_edges` of ``F``.
    spacing_px : float
        Distance between samples along the contour, pixels.
    buffers : dict, optional
        Where the part's z-buffer is kept between calls (``"buffer"``); a call with
        ``buffers["reuse"]`` true uses the kept one (the part has moved less than a buffer pixel).

    Returns
    -------
    q : (k, 2) float
        Undistorted pixel positions.
    n : (k, 2) float
        Unit image normals, pointing away from the part.
    X : (k, 3) float
        The samples' design points, mm.
    ends : (k, 2) int
        The vertices of each sample's edge.
    a : (k,) float
        Where along it (0 at the first vertex, 1 at the second).
    """
    ideal = Camera(camera.K, camera.R, camera.t, camera.width, camera.height)
    xy, z = ideal.project(Vm)
    E, EF = edges
    fn = np.cross(Vm[F[:, 1]] - Vm[F[:, 0]], Vm[F[:, 2]] - Vm[F[:, 0]])
    view = camera.center - Vm[F].mean(axis=1)
    front = np.einsum("ij,ij->i", fn, view) > 0
    boundary = EF[:, 1] < 0
    f0 = front[EF[:, 0]]
    f1 = np.where(boundary, ~f0, front[np.maximum(EF[:, 1], 0)])
    cand = boundary | (f0 != f1)
    cand &= (z[E[:, 0]] > 0) & (z[E[:, 1]] > 0)
    E = E[cand]
    a, b = xy[E[:, 0]], xy[E[:, 1]]
    length = np.linalg.norm(b - a, axis=1)
    ok = np.isfinite(length) & (length > 1e-9)
    E, a, b, length = E[ok], a[ok], b[ok], length[ok]
    total = length.sum()
    spacing = max(spacing_px, total / MAX_SAMPLES)
    k = np.maximum(np.floor(length / spacing).astype(int), 0)
    # samples at (i + 0.5) / k of each edge long enough for one
    rep = np.repeat(np.arange(len(E)), k)
    start = np.cumsum(k) - k
    i = np.arange(len(rep)) - start[rep]
    s = (i + 0.5) / k[rep]
    q = a[rep] + s[:, None] * (b - a)[rep]
    d = (b - a)[rep] / length[rep, None]
    n = np.stack([-d[:, 1], d[:, 0]], axis=1)
    X = V[E[rep, 0]] * (1 - s[:, None]) + V[E[rep, 1]] * s[:, None]
    Xm = Vm[E[rep, 0]] * (1 - s[:, None]) + Vm[E[rep, 1]] * s[:, None]
    ends = E[rep]
    if not len(q):
        return q, n, X, ends, s
    # which side is the part: a z-buffer at about 1000 px across
    sc = min(1.0, 1000.0 / max(camera.width, camera.height))
    small = ideal.scaled(sc)
    if buffers is not None and buffers.get("reuse") and "buffer" in buffers:
        face, depth = buffers["buffer"]
    else:
        sxy, sz = small.project(Vm)
        face, depth = depth_buffer(sxy, sz, F, small.width, small.height)
        if buffers is not None:
            buffers["buffer"] = (face, depth)
    part = face >= 0
    step = 1.5 / sc  # photo px: 1.5 buffer pixels

    def on_part(p):
        ij = np.round((p + 0.5) * sc - 0.5).astype(int)
        inside = (ij[:, 0] >= 0) & (ij[:, 1] >= 0) & (ij[:, 0] < small.width) & (ij[:, 1] < small.height)
        out = np.zeros(len(p), bool)
        out[inside] = part[ij[inside, 1], ij[inside, 0]]
        return out, inside

    plus, in_p = on_part(q + step * n)
    plus2, in_p2 = on_part(q + 2 * step * n)
    minus, in_m = on_part(q - step * n)
    minus2, in_m2 = on_part(q - 2 * step * n)
    keep_as_is = minus & ~plus & ~plus2 & in_p & in_p2
    flipped = plus & ~minus & ~minus2 & in_m & in_m2
    n = np.where(flipped[:, None], -n, n)
    # the sample itself not hidden by a nearer part of the surface (where it projects, the
    # nearest surface is the sample's own, to the depth a buffer pixel spans at a grazing angle)
    ij = np.clip(np.round((q + 0.5) * sc - 0.5).astype(int), 0, [small.width - 1, small.height - 1])
    zq = ideal.to_camera(Xm)[:, 2]
    seen = zq <= depth[ij[:, 1], ij[:, 0]] + 0.01 * zq + 2.0
    keep = (keep_as_is | flipped) & seen
    return q[keep], n[keep], X[keep], ends[keep], s[keep]


def _distort(camera: Camera, q: np.ndarray) -> np.ndarray:
    """Undistorted pixel positions (..., 2) to photo pixels through the camera's lens."""
    shape = q.shape
    K = camera.K
    if not np.any(camera.dist):
        return q
    x = (q.reshape(-1, 2) - K[:2, 2]) @ np.linalg.inv(K[:2, :2]).T
    pts = np.concatenate([x, np.ones((len(x), 1))], axis=1)
    out, _ = cv2.projectPoints(pts, np.zeros(3), np.zeros(3), K, camera.dist)
    return out.reshape(shape)


def _plate_colour(data: PhotoData, q: np.ndarray) -> np.ndarray:
    """The plate's predicted colour at undistorted pixels q (..., 2); (..., c) float32 (NaN off the plate).

    The plate is a plane: its image pixel and the photo's undistorted pixel are related by a
    homography ``q ~ K (R M + t e3^T) [u, v, 1]``, M the plate pixel's mesh point.
    """
    cam, pl = data.camera, data.plate
    shape = q.shape[:-1]
    k = 1.0 / pl.ppm
    ox, oy, oz = pl.origin
    M = np.array(
        [
            [k, 0.0, ox - pl.margin_mm + (0.5 + pl.corner_px[0]) * k],
            [0.0, -k, oy + pl.margin_mm - (0.5 + pl.corner_px[1]) * k],
            [0.0, 0.0, oz],
        ]
    )
    A = cam.R @ M
    A[:, 2] += cam.t  # camera coordinates of plate pixel (u, v): A [u, v, 1]
    G = np.linalg.inv(cam.K @ A)
    qq = q.reshape(-1, 2).astype(np.float64)
    h = qq @ G[:, :2].T + G[:, 2]
    with np.errstate(divide="ignore", invalid="ignore"):
        u = h[:, 0] / h[:, 2]
        v = h[:, 1] / h[:, 2]
    # in front of the camera: the plate point's depth
    depth = A[2, 0] * u + A[2, 1] * v + A[2, 2]
    u = np.where(np.isfinite(u) & (depth > 0), u, -1e6)
    return _sample(pl.image, u, np.where(np.isfinite(v), v, -1e6)).reshape(*shape, pl.image.shape[2])


def _sample(img: np.ndarray, x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Bilinear samples of an (h, w, 3) image at pixel positions x, y (any shape); (n, 3) float32, NaN outside.

    (``cv2.remap`` takes maps of fewer than 32767 rows: the points are laid out 1024 a row.)
    """
    x, y = np.ravel(x).astype(np.float32), np.ravel(y).astype(np.float32)
    n = len(x)
    cols = 1024
    pad = (-n) % cols
    mx = np.concatenate([x, np.full(pad, -1e6, np.float32)]).reshape(-1, cols)
    my = np.concatenate([y, np.full(pad, -1e6, np.float32)]).reshape(-1, cols)
    out = cv2.remap(img, mx, my, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)
    out = out.reshape(-1, img.shape[2] if img.ndim == 3 else 1)[:n].astype(np.float32)
    h, w = img.shape[:2]
    outside = ~((x >= 0) & (y >= 0) & (x <= w - 1) & (y <= h - 1))
    out[outside] = np.nan
    return out


def measure_edges(data: PhotoData, q: np.ndarray, n: np.ndarray, half_px: float, rim: np.ndarray | None = None):
    """Where, along each sample's normal, the photo stops looking like the plate.

    Parameters
    ----------
    data : PhotoData
    q, n : (k, 2) float
        Predicted contour samples (undistorted px) and outward normals.
    half_px : float
        Search half-width, pixels.
    rim : (k, 3) float, optional
        The design's print colour at each sample (0-255): where it is the plate's own colour
        beside it, the part's outline is invisible there and the sample is not used (the
        nearest edge would be the decoration's).

    Returns
    -------
    s : (k,) float
        Observed edge minus predicted, along ``n``, undistorted pixels (NaN: not found).
    """
    k = len(q)
    if k == 0:
        return np.zeros(0)
    # coarse to fine: a wide search at a coarse step on a smaller photo (the pyramid's level
    # whose pixel is about the step), the narrow band at STEP_PX on the photo itself
    st = max(STEP_PX, half_px / COARSE_SAMPLES)
    level = 0 if st < 1.5 else 1 if st < 3.0 else 2
    m = int(np.ceil(half_px / st))
    u = np.arange(-m - 8, m + 9) * st  # a margin for the derivative and the part's side
    pts = q[:, None, :] + u[None, :, None] * n[:, None, :]
    ph = _distort(data.camera, pts).astype(np.float32)
    img = data.level(level)
    f = 0.5**level
    I = _sample(img, (ph[..., 0] + 0.5) * f - 0.5, (ph[..., 1] + 0.5) * f - 0.5).reshape(k, len(u), 3)
    P = _plate_colour(data, pts)
    # beyond the plate: the table, one colour (the photo's median there)
    off = ~np.isfinite(P).all(axis=2)
    seen = off & np.isfinite(I).all(axis=2)
    table = np.median(I[seen], axis=0) if seen.sum() >= 20 else np.full(3, np.nan)
    inside = np.isfinite(I).all(axis=(1, 2)) & (~off | bool(np.isfinite(table).all())).all(axis=1)
    # affine gain per channel from the photo's plate beyond the search (outer quarter)
    outer = u > half_px * 0.5
    on = inside[:, None] & outer[None] & ~off
    Io, Po = I[on], P[on]
    a, b = np.ones(3), np.zeros(3)
    if len(Io) > 20:
        for c in range(3):
            A = np.stack([Po[:, min(c, Po.shape[1] - 1)], np.ones(len(Po))], axis=1)
            sol, *_ = np.linalg.lstsq(A, Io[:, c], rcond=None)
            if np.isfinite(sol).all() and sol[0] > 0.05:
                a[c], b[c] = sol
    pred = np.where(off[..., None], table, P * a + b)
    # a local gain per profile (shading, vignetting): bright plate samples beyond the edge
    # (least squares over them: a median per profile cost a tenth of a second at 12 Mpx)
    pm, im = pred.mean(axis=2), I.mean(axis=2)
    use = (pm > 60) & outer[None] & np.isfinite(im) & np.isfinite(pm)
    pm, im = np.where(use, pm, 0.0), np.where(use, im, 0.0)
    with np.errstate(invalid="ignore", divide="ignore"):
        g = (pm * im).sum(axis=1) / (pm * pm).sum(axis=1)
    g = np.where(np.isfinite(g), np.clip(g, 0.6, 1.4), 1.0)
    e = I - g[:, None, None] * pred
    if rim is not None:
        # the outline's predicted contrast: the print at the rim against the plate just outside
        j_out = np.searchsorted(u, 2.0)
        rim_ok = np.linalg.norm(np.asarray(rim) - P[:, j_out], axis=1) >= MIN_RIM_CONTRAST
    else:
        rim_ok = np.ones(k, bool)
    r = np.linalg.norm(e, axis=2)
    s = np.full(k, np.nan)
    ro = r[:, outer]
    ro = ro[np.isfinite(ro)]
    noise = np.median(ro) if len(ro) else 5.0
    tau = max(20.0, 4.0 * float(noise) if np.isfinite(noise) else 20.0)
    rr = np.where(np.isfinite(r), r, 0.0)
    bad = rr >= tau
    # change point: samples at or below index i are the part, beyond it the plate
    cb = np.cumsum(bad, axis=1)
    cg = np.cumsum(~bad, axis=1)
    after_bad = cb[:, -1:] - cb
    cost = after_bad + cg
    lo, hi = 8, len(u) - 9
    cost[:, :lo] = 10**9
    cost[:, hi:] = 10**9
    i0 = np.argmin(cost, axis=1)
    best = cost[np.arange(k), i0]
    ok = inside & rim_ok & (best <= 0.15 * len(u))
    # the part's contrast against the plate just inside the edge, and its direction
    rows = np.arange(k)
    win_in = np.clip(i0[:, None] - np.arange(3, 9)[None], 0, len(u) - 1)
    win_out = np.clip(i0[:, None] + np.arange(3, 9)[None], 0, len(u) - 1)
    e_in, e_out = e[rows[:, None], win_in], e[rows[:, None], win_out]
    d_in = e_in.mean(axis=1)
    d_out = e_out.mean(axis=1)
    step = d_in - d_out
    D = np.linalg.norm(step, axis=1)
    ok &= D >= 2 * tau
    # a clean step only: the part's side of one colour (no print edge beside the rim) and the
    # plate's side as predicted (no board edge mispredicted there), each within a share of the step
    spread_in = np.linalg.norm(e_in - d_in[:, None], axis=2).max(axis=1)
    spread_out = np.linalg.norm(e_out, axis=2).max(axis=1)
    ok &= (spread_in <= 0.5 * D) & (spread_out <= np.maximum(0.5 * D, tau))
    if rim is not None and ok.any():
        # the part's side must show the print's rim colour: where it shows another, the film's own
        # edge lies beside the rim (a film off its place) and was taken for the outline
        # (compared by hue and by brightness against the photo's typical ratio: shading darkens a
        # surface seen at a grazing angle, at its silhouette, and leaves its hue)
        I_in = I[rows[:, None], win_in].mean(axis=1)
        rim = np.asarray(rim, dtype=np.float64)
        a_, b_ = I_in + 10.0, rim + 10.0
        cos = np.einsum("kc,kc->k", a_, b_) / (np.linalg.norm(a_, axis=1) * np.linalg.norm(b_, axis=1))
        ratio = np.linalg.norm(a_, axis=1) / np.linalg.norm(b_, axis=1)
        typical = np.median(ratio[ok]) if ok.any() else 1.0
        ok &= (cos >= 0.97) & (ratio >= 0.4 * typical) & (ratio <= 1.6 * typical)
    dirn = step / np.maximum(D, 1e-9)[:, None]
    h = np.einsum("kuc,kc->ku", np.where(np.isfinite(e), e, 0.0), dirn)
    # derivative over +-1 sample, its peak near the change point (falling: part to plate); (a
    # wider span gives a sharp photo's step a flat-topped peak, whose first maximum was taken:
    # 0.12 mm off on an unblurred photo)
    dh = np.zeros_like(h)
    dh[:, 2:-2] = h[:, 1:-3] - h[:, 3:-1]
    win = np.clip(i0[:, None] + np.arange(-4, 6)[None], 2, len(u) - 3)
    j = win[rows, np.argmax(dh[rows[:, None], win], axis=1)]
    y0, y1, y2 = dh[rows, j - 1], dh[rows, j], dh[rows, j + 1]
    den = y0 - 2 * y1 + y2
    with np.errstate(invalid="ignore", divide="ignore"):
        frac = np.where(den < 0, 0.5 * (y0 - y2) / den, 0.0)
    frac = np.clip(frac, -1, 1)
    ok &= y1 > 0.15 * D * min(1.0, 2 * st)  # a real step, not noise (a step of D falls by D over the blur)
    s[ok] = (u[j] + frac * st)[ok]
    s[np.abs(s) > half_px] = np.nan
    return s


def _jacobian(camera: Camera, Xm: np.ndarray, n: np.ndarray, centre_m: np.ndarray, rho: float) -> np.ndarray:
    """d(normal position, undistorted px) / d(motion), motion as (rotation * rho, translation) in mm; (k, 6)."""
    Xc = camera.to_camera(Xm)
    z = Xc[:, 2]
    fx, fy = camera.K[0, 0], camera.K[1, 1]
    # d(pixel)/d(Xc): (k, 2, 3)
    Jp = np.zeros((len(Xm), 2, 3))
    Jp[:, 0, 0] = fx / z
    Jp[:, 0, 2] = -fx * Xc[:, 0] / z**2
    Jp[:, 1, 1] = fy / z
    Jp[:, 1, 2] = -fy * Xc[:, 1] / z**2
    Jn = np.einsum("kj,kjl->kl", n, Jp) @ camera.R  # (k, 3): d(normal px)/d(world point)
    # a world point moves by w x (X - c) + v
    arm = Xm - centre_m
    Jw = np.cross(arm, Jn)  # n.(w x a) = w.(a x n)
    return np.concatenate([Jw / rho, Jn], axis=1)


def _name(direction: np.ndarray) -> str:
    """A direction of (rotation * rho, translation) in words, by its dominant mesh axis."""
    rot, tr = direction[:3], direction[3:]
    kind, v = ("rotation about", rot) if np.linalg.norm(rot) >= np.linalg.norm(tr) else ("translation along", tr)
    v = v / max(np.linalg.norm(v), 1e-12)
    ax = int(np.argmax(np.abs(v)))
    if abs(v[ax]) >= np.cos(np.radians(15)):
        return f"{kind} {'xyz'[ax]}"
    return f"{kind} ({v[0]:+.2f}, {v[1]:+.2f}, {v[2]:+.2f})"


def estimate_seating(
    photos: list[PhotoData],
    V: np.ndarray,
    F: np.ndarray,
    undetermined_mm: float = UNDETERMINED_MM,
    iterations: int = 10,
    start: tuple[np.ndarray, np.ndarray] | None = None,
    print_uv_px: np.ndarray | None = None,
    print_rgb: np.ndarray | None = None,
    plate_mm: float | None = PLATE_MM,
) -> Seating:
    """The part's rigid motion on the plate from its outline in one or several photos.

    Parameters
    ----------
    photos : list of PhotoData
        Each photo with its board-posed camera: one part, one motion for all.
    V : (n, 3) float
        Design vertices, mm (mesh frame).
    F : (m, 3) int
        Triangles.
    undetermined_mm : float
        A direction of motion determined worse than this (1 sigma, mm of vertex
        displacement) is undetermined: reported and held at zero.
    iterations : int
        Gauss-Newton iterations at most.
    start : (R, t), optional
        A motion to start from (a narrow search band only); default none.
    print_uv_px, print_rgb : (n, 2) float and (h, w, 3) float32, optional
        Each vertex's print pixel and the print (blurred to the photos' scale): the
        outline is not measured where the print there has the plate's colour.
    plate_mm : float or None
        The plate's contact as a prior: the part's lift and tilts are zero to this (mm of
        vertex displacement), so what the photos cannot tell apart from a lift (a move
        along the line of sight of a single photo) is settled by the plate, not set to an
        arbitrary zero. None: no prior (6 free degrees).

    Returns
    -------
    Seating
    """
    V = np.asarray(V, dtype=np.float64)
    c = part_centre(V)
    rho = float(np.sqrt(np.mean(np.sum((V - c) ** 2, axis=1))))
    edges = _edges(F)
    R, t = (np.eye(3), np.zeros(3)) if start is None else (np.asarray(start[0], float), np.asarray(start[1], float))
    # the search band of each photo in its pixels: SEARCH_MM, then narrower
    ppm = []
    for d in photos:
        z = d.camera.to_camera(c[None])[0, 2]
        ppm.append(d.camera.K[0, 0] / max(z, 1e-6))
    H = np.zeros((6, 6))
    sigma_px, n_used = 1.0, 0
    H_last = H
    halves = [SEARCH_MM * p if start is None else 6.0 for p in ppm]
    zbuf = [{} for _ in photos]
    for it in range(iterations):
        Js = []
        H = np.zeros((6, 6))
        g = np.zeros(6)
        res_all, w_all = [], []
        Vm = V @ R.T + t
        cm = R @ c + t
        for k, d in enumerate(photos):
            half = min(halves[k], 0.25 * min(d.camera.width, d.camera.height))
            q, n, X, ends, a = contour_samples(d.camera, Vm, F, V, edges, SPACING_PX, zbuf[k])
            if not len(q):
                continue
            rim = None
            if print_uv_px is not None and print_rgb is not None:
                uv = print_uv_px[ends[:, 0]] * (1 - a[:, None]) + print_uv_px[ends[:, 1]] * a[:, None]
                # the rim lies on the print's own edge: read the nearest pixel inside
                h, w = print_rgb.shape[:2]
                rim = _sample(print_rgb, np.clip(uv[:, 0], 0, w - 1), np.clip(uv[:, 1], 0, h - 1))
                rim = np.where(np.isfinite(rim), rim, 0.0)
            s = measure_edges(d, q, n, half, rim)
            okk = np.isfinite(s)
            if okk.sum() < 6:
                continue
            q, n, X, s = q[okk], n[okk], X[okk], s[okk]
            J = _jacobian(d.camera, X @ R.T + t, n, cm, rho)
            # Tukey weights on the residuals, scale from their spread
            mad = 1.4826 * np.median(np.abs(s - np.median(s)))
            scale = 4.685 * max(mad, 0.3 if it > 1 else 1.0)
            w = np.where(np.abs(s) < scale, (1 - (s / scale) ** 2) ** 2, 0.0)
            Js.append(J)
            H += (J * w[:, None]).T @ J
            g += (J * w[:, None]).T @ s
            res_all.append(s)
            w_all.append(w)
        if not res_all:
            if it == 0:
                return Seating(np.eye(3), np.zeros(3), c, float("nan"), [{"motion": "all", "sigma_mm": None}], 0,
                               float("nan"), H, rho, False)  # fmt: skip
            H = H_last
            break
        H_last = H
        r = np.concatenate(res_all)
        w = np.concatenate(w_all)
        n_used = int((w > 0).sum())
        sigma_px = float(np.sqrt(np.sum(w * r**2) / max(np.sum(w) - 6, 1)))
        # while far off, the residuals are the misfit, not the noise: steps take at most 0.5 px
        s_step = min(max(sigma_px, 0.05), 0.5)
        x = _parameters(R, t, c, rho)
        delta, _, _ = _solve(H / s_step**2, g / s_step**2, x, plate_mm, undetermined_mm)
        w_rot = delta[:3] / rho
        dR = rodrigues(w_rot)
        R = dR @ R
        t = dR @ (t - cm) + cm + delta[3:]
        # the next search band: twice what this step moved the contour, and 6 px at least
        moved = [float(np.abs(J @ delta).max()) for J in Js]
        for k, px in enumerate(moved):
            halves[k] = max(6.0, min(halves[k], 2.0 * px + 6.0))
            # the part's z-buffer (about 1000 px across) is redrawn only while the part moves
            zbuf[k]["reuse"] = px < 0.5
        if max(moved, default=0.0) < 0.05 and it >= 2:
            break
    info = H / max(sigma_px, 0.05) ** 2
    # what the final information leaves undetermined is held at zero, as reported: the steps
    # weigh the contour at most at half a pixel, and a contour that never fitted (a lily's grazing
    # photo: 23 samples at 17 px) walked the part 4.8 mm along directions its information then
    # determined to 0.5 to 2 mm only, and that motion was applied
    _, vec, sd = _solve(info, np.zeros(6), np.zeros(6), plate_mm, undetermined_mm)
    good = vec[:, sd <= undetermined_mm]
    x = good @ (good.T @ _parameters(R, t, c, rho))
    R = rodrigues(x[:3] / rho)
    t = c + x[3:] - R @ c
    return _seating(R, t, c, rho, info, plate_mm, undetermined_mm, V, n_used, sigma_px)


def _parameters(R: np.ndarray, t: np.ndarray, c: np.ndarray, rho: float) -> np.ndarray:
    """A motion as (rotation vector * rho, the centre's offset), mm; (6,)."""
    return np.concatenate([cv2.Rodrigues(np.asarray(R, dtype=np.float64))[0].ravel() * rho, R @ c + t - c])


def _solve(info: np.ndarray, g: np.ndarray, x: np.ndarray, plate_mm: float | None, undetermined_mm: float):
    """The Gauss-Newton step over the determined directions, with the plate's contact as a prior.

    ``info`` (mm^-2) and ``g`` are the photos' normal equations for a step from ``x``; the prior
    pulls the out-of-plane terms of ``x + step`` to zero with a standard deviation of
    ``plate_mm`` (None: no prior). Directions whose standard deviation exceeds
    ``undetermined_mm`` get no step.

    Returns
    -------
    step : (6,) float
    vec : (6, 6) float
        Eigenvectors of the total information.
    sd : (6,) float
        Their standard deviations, mm.
    """
    Hp = np.zeros((6, 6))
    if plate_mm is not None:
        for i in OUT_OF_PLANE:
            Hp[i, i] = 1.0 / plate_mm**2
    Ht = info + Hp
    gt = g - Hp @ x
    lam, vec = np.linalg.eigh(Ht)
    sd = 1.0 / np.sqrt(np.maximum(lam, 1e-300))
    good = sd <= undetermined_mm
    step = vec[:, good] @ ((vec[:, good].T @ gt) / lam[good]) if good.any() else np.zeros(6)
    return step, vec, sd


def _seating(R, t, c, rho, info, plate_mm, undetermined_mm, V, n_used=0, sigma_px=float("nan")) -> Seating:
    """The seating ``(R, t)`` with its uncertainty and undetermined directions from the photos' information."""
    x = _parameters(R, t, c, rho)
    _, vec, sd = _solve(info, np.zeros(6), x, plate_mm, undetermined_mm)
    good = sd <= undetermined_mm
    undet = [
        {"motion": _name(vec[:, i]), "direction": np.round(vec[:, i], 6).tolist(),
         "sigma_mm": float(sd[i]) if sd[i] < 1e6 else None}
        for i in np.flatnonzero(~good)
    ]  # fmt: skip
    # what the photos alone leave open and the plate's contact holds
    lam0, vec0 = np.linalg.eigh(info)
    sd0 = 1.0 / np.sqrt(np.maximum(lam0, 1e-300))
    held = []
    if plate_mm is not None:
        for i in np.flatnonzero(sd0 > undetermined_mm):
            # a direction the photos leave open that is mostly a lift or tilt: the plate settles it
            if np.linalg.norm(vec0[list(OUT_OF_PLANE), i]) >= 0.5:
                held.append(_name(vec0[:, i]))
    # each vertex's 1-sigma displacement over the determined directions
    cov = (vec[:, good] / sd[good] ** -2) @ vec[:, good].T if good.any() else np.zeros((6, 6))
    Vs = V[:: max(1, len(V) // 2000)] @ R.T + t
    arm = Vs - (R @ c + t)
    A = np.concatenate([-skew(arm) / rho, np.broadcast_to(np.eye(3), (len(arm), 3, 3))], axis=2)  # (k, 3, 6)
    var = np.einsum("kij,jl,kil->k", A, cov, A)
    unc = float(np.sqrt(var.max())) if len(var) else float("nan")
    seat = Seating(R, t, c, unc, undet, n_used, sigma_px, info, rho, bool(good.all()))
    seat.held_by_plate = held
    return seat


def largest_displacement(V: np.ndarray, R: np.ndarray, t: np.ndarray) -> float:
    """How far the motion moves the farthest-moved vertex of the part, mm."""
    return float(np.linalg.norm(V @ (R - np.eye(3)).T + t, axis=1).max()) if len(V) else 0.0


def seating_entry(seat: Seating, V: np.ndarray, max_seating_mm: float) -> dict:
    """validation.json's ``seating``: the motion, its uncertainty, what is undetermined, and the warning."""
    out = seat.to_dict()
    out["largest_vertex_motion_mm"] = largest_displacement(V, seat.R, seat.t)
    out["max_seating_mm"] = float(max_seating_mm)
    moved = float(np.linalg.norm(out["offset_mm"]))
    out["warning"] = (
        f"the part was not set in its outline: its centre sits {moved:.2f} mm from where the fixture puts it "
        f"(more than {max_seating_mm:g} mm); the film is judged on the part where it sits"
        if moved > max_seating_mm
        else None
    )
    return out


def seating_text(s: dict | None) -> str:
    """One line for the QA report: how the part sat on its plate."""
    if not s:
        return "seating: not measured"
    if s.get("mode") == "off":
        return "seating: off (the part is taken where the fixture puts it)"
    off, rot = s["offset_mm"], s["rotation_deg"]
    line = (
        f"part seated {off[0]:+.2f}, {off[1]:+.2f}, {off[2]:+.2f} mm, turned {rot[0]:+.2f}, {rot[1]:+.2f}, "
        f"{rot[2]:+.2f}° (±{s['uncertainty_mm']:.3f} mm)"
    )
    if s.get("undetermined"):
        line += "; undetermined, held at zero: " + ", ".join(u["motion"] for u in s["undetermined"])
    if s.get("applied") is False:
        line += f"; under {s['min_applied_mm']:g} mm a vertex, within what seating measures: not applied"
    if s.get("warning"):
        line += "; WARNING: " + s["warning"]
    return line


def held_vertices(V: np.ndarray, held: dict | None) -> np.ndarray:
    """The design's vertices where the fixture holds the part: ``R V + t`` of ``held`` (its ``R``, ``t_mm``).

    Parameters
    ----------
    V : (n, 3) float
        Design vertices, mm (mesh frame).
    held : dict or None
        ``{"R": (3, 3), "t_mm": (3,)}``; None: as designed.

    Returns
    -------
    (n, 3) float
    """
    if held is None:
        return V
    return V @ np.asarray(held["R"], dtype=np.float64).T + np.asarray(held["t_mm"], dtype=np.float64)


def seat_photo(photo_rgb: np.ndarray, camera: Camera, design, cache: dict, max_seating_mm: float,
               given: tuple[np.ndarray, np.ndarray] | None = None,
               held: dict | None = None) -> tuple[Seating, dict]:  # fmt: skip
    """The seating of the part in one photo of ``design`` (a :class:`workbench.design_dir.Design`).

    ``given``: a motion measured already (from all photos of the part): it is used as it is.
    ``held``: where the fixture holds the part (validate ``--part-rotation-deg``,
    ``--part-offset-mm``: ``R``, ``t_mm``); the seating is the motion from there, with the
    stand's contact as the prior, and ``camera`` the board's.
    Returns the seating and its ``seating`` entry (with ``"_H"``, the normal matrix, for the
    part's joint estimate; the caller removes it).
    """
    V = held_vertices(design.V, held)
    p = design.info["print"]
    if "seating print" not in cache:
        rgb = design.rgb
        if design.alpha is not None and (design.alpha > 0).any():
            # the film's colours carried past its outline, as the film is printed (with a bleed):
            # the rim's colour is read at the outline, where the transparent pixels would darken it
            from workbench.texture.outline import bleed_beyond_outline

            rgb, _ = bleed_beyond_outline(design.rgb, design.alpha > 0, 2.0 * p["dpi"] / 25.4)
        cache["seating print"] = print_reference(design.flat, p["height_mm"], rgb, p["dpi"])
    if given is not None:
        seat = Seating(np.asarray(given[0]), np.asarray(given[1]), part_centre(V))
        entry = seating_entry(seat, V, max_seating_mm)
        entry["source"] = "all photos of the part"
        return seat, entry
    data = prepare(photo_rgb, camera, design.fixture, V, cache)
    uv, prgb = cache["seating print"]
    seat = estimate_seating([data], V, design.F, print_uv_px=uv, print_rgb=prgb)
    entry = seating_entry(seat, V, max_seating_mm)
    entry["source"] = "this photo"
    entry["_H"] = None if seat.H is None else seat.H.tolist()
    entry["_rho"] = seat.rho
    return seat, entry


def fuse(entries: list[dict], V: np.ndarray, undetermined_mm: float = UNDETERMINED_MM, plate_mm=PLATE_MM):
    """One motion for the part from each photo's seating and information (information-weighted).

    Each photo's motion, as (rotation vector * rho, the centre's offset), weighted by the
    information its contour gave (``"_H"`` of its entry), with the plate's contact as in
    :func:`estimate_seating`; the directions no photo determines stay undetermined.

    Returns
    -------
    (Seating, int) or None
        The part's seating and the photos it combines; None without any measured photo.
    """
    c = part_centre(V)
    info, g, used, rho = np.zeros((6, 6)), np.zeros(6), 0, None
    for e in entries:
        if not e or e.get("_H") is None:
            continue
        H = np.asarray(e["_H"])
        rho = float(e["_rho"])
        info += H
        g += H @ _parameters(np.asarray(e["R"]), np.asarray(e["t_mm"]), c, rho)
        used += 1
    if not used:
        return None
    x, _, _ = _solve(info, g, np.zeros(6), plate_mm, undetermined_mm)
    R = rodrigues(x[:3] / rho)
    t = c + x[3:] - R @ c
    return _seating(R, t, c, rho, info, plate_mm, undetermined_mm, V), used
