"""A posed photo warped into a designed view through the mesh, and scored against the view's image."""

from __future__ import annotations

from dataclasses import dataclass, field

import cv2
import numba
import numpy as np

from workbench.camera import Camera
from workbench.raster import depth_buffer
from workbench.validate.pictures import print_seen_from_view
from workbench.validate.print_warp import photo_buffers, surface_in_photo

TILE = 64
# a tile counts when its registration's standard uncertainty, on the surface, is below this
# share of the tolerance: then the photo's noise moves the tiles' p95 by a few per cent of the
# tolerance at most, and the film fit over tens of tiles is ten times finer still
TILE_SIGMA_SHARE = 0.1
# the correlation a registered tile must reach, as a share of what the photo's blur and noise
# allow for that tile (a low-contrast tile correlates less however well it is placed): well
# above what unrelated content reaches (the correlation's standard error over a 60² px tile's
# independent samples is about 0.06) and below what a photographed photograph reaches through
# shading, JPEG and the print's resampling (0.53 to 0.79 seen on the face mask's portrait)
MIN_CORRELATION = 0.5
NOISE_FLOOR = 0.5  # grey levels: the least noise assumed (8-bit quantisation of photo and design)
# a tile whose correlation has a second peak (beyond an eighth of a tile from the first)
# within this many standard errors of the correlation of the first is ambiguous: a periodic
# pattern, rings, lines of text (a lily's rings registered 1.9 mm off without the test)
AMBIGUITY_Z = 3.0
ECC_MAX_PX = 250_000  # pixels of the similarity's alignment
MAX_TILES = 160  # tiles registered per photo at most, spread evenly over the view (about 40 ms each)
REGISTRATION_BLUR_PX = 1.0
MARGIN = 24  # largest shift a tile can measure, view pixels


@dataclass
class ViewSurface:
    """What a designed view sees of the part, per view pixel.

    Attributes
    ----------
    X : (H, W, 3) float
        Surface point seen at each pixel centre, mm (NaN: none).
    print_mm : (H, W, 2) float
        Its design print coordinates (x right, y down from the trim's top-left), mm.
    owned : (H, W) bool
        Pixels whose surface point the print gives to this view.
    face : (H, W) int
        Triangle seen at each pixel (-1: none).
    """

    X: np.ndarray
    print_mm: np.ndarray
    owned: np.ndarray
    face: np.ndarray


def view_surface(
    camera: Camera, V, F, flat_uv_mm, rect_height_mm, owner: np.ndarray, view_index: int, px_per_mm: float
) -> ViewSurface:
    """Surface points, print coordinates and ownership of every pixel of a designed view.

    Parameters
    ----------
    camera : Camera
        The designed view.
    V, F : arrays
        Mesh, mm.
    flat_uv_mm : (#V, 2) float
        Flat layout, mm (y up).
    rect_height_mm : float
        Height of the design rectangle.
    owner : (rows, cols) int8
        Owning view per print pixel (-1: none).
    view_index : int
        This view's index.
    px_per_mm : float
        Print resolution.

    Returns
    -------
    ViewSurface
    """
    xy, z = camera.project(V)
    face, depth = depth_buffer(xy, z, F, camera.width, camera.height)
    H, W = face.shape
    jj, ii = np.meshgrid(np.arange(W, dtype=np.float64), np.arange(H, dtype=np.float64))
    # the pixel's ray at camera depth 1 is K⁻¹ [x y 1]; the point is depth times that
    rays = np.stack([jj, ii, np.ones_like(jj)], axis=-1) @ np.linalg.inv(camera.K).T
    with np.errstate(invalid="ignore"):  # inf depth where no face: NaN, masked below
        X = camera.center + (depth[..., None] * rays) @ camera.R
    X[face < 0] = np.nan
    pm = np.full((H, W, 2), np.nan)
    owned = np.zeros((H, W), dtype=bool)
    # per pixel, in one compiled pass (numpy's temporaries took 0.3 s a view, this 10 ms)
    _print_coordinates(
        X,
        face,
        np.ascontiguousarray(V, dtype=np.float64),
        np.ascontiguousarray(F, dtype=np.int64),
        np.ascontiguousarray(flat_uv_mm, dtype=np.float64),
        float(rect_height_mm),
        float(px_per_mm),
        np.ascontiguousarray(owner),
        view_index,
        pm,
        owned,
    )
    return ViewSurface(X, pm, owned, face)


@numba.njit(cache=True, nogil=True, error_model="numpy")
def _print_coordinates(X, face, V, F, uv, rect_height_mm, px_per_mm, owner, view_index, pm, owned):
    rows, cols = owner.shape
    for i in range(face.shape[0]):
        for j in range(face.shape[1]):
            f = face[i, j]
            if f < 0:
                continue
            a, b, c = F[f, 0], F[f, 1], F[f, 2]
            # barycentrics of the point in its 3D triangle (least squares in the triangle's plane)
            d00 = d01 = d11 = d20 = d21 = 0.0
            for k in range(3):
                v0 = V[b, k] - V[a, k]
                v1 = V[c, k] - V[a, k]
                v2 = X[i, j, k] - V[a, k]
                d00 += v0 * v0
                d01 += v0 * v1
                d11 += v1 * v1
                d20 += v2 * v0
                d21 += v2 * v1
            den = d00 * d11 - d01 * d01
            l1 = (d11 * d20 - d01 * d21) / den
            l2 = (d00 * d21 - d01 * d20) / den
            l0 = 1.0 - l1 - l2
            x = l0 * uv[a, 0] + l1 * uv[b, 0] + l2 * uv[c, 0]
            y = rect_height_mm - (l0 * uv[a, 1] + l1 * uv[b, 1] + l2 * uv[c, 1])
            pm[i, j, 0] = x
            pm[i, j, 1] = y
            # the owning view at the print pixel nearest the point (rounded half to even, clamped)
            pi = np.rint(y * px_per_mm - 0.5)
            pj = np.rint(x * px_per_mm - 0.5)
            pi = min(max(pi, 0.0), rows - 1.0) if np.isfinite(pi) else 0.0
            pj = min(max(pj, 0.0), cols - 1.0) if np.isfinite(pj) else 0.0
            owned[i, j] = owner[int(pi), int(pj)] == view_index


def warp_photo(
    photo: np.ndarray, photo_cam: Camera, surface: ViewSurface, V, F, depth: np.ndarray | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """The photo seen from the designed view: each view pixel takes the photo's colour of its surface point.

    Only surface points the photo's camera sees (in front, inside the photo, on a triangle
    that faces it, not hidden behind another part of the mesh) are taken. ``depth``: the part's depth buffer in the
    undistorted photo camera, when the caller has it already.

    Returns
    -------
    warped : (H, W, 3) uint8
    valid : (H, W) bool
    """
    H, W = surface.owned.shape
    finite = np.isfinite(surface.X[..., 0])
    pts = surface.X[finite]
    if depth is None:
        _, depth = photo_buffers(photo_cam, V, F)
    _, proj, inside, _, shown = surface_in_photo(photo_cam, pts, surface.face[finite], V, F, depth)
    mapx = np.full((H, W), -1e4, dtype=np.float32)
    mapy = np.full((H, W), -1e4, dtype=np.float32)
    mapx[finite], mapy[finite] = proj[:, 0], proj[:, 1]
    warped = cv2.remap(photo, mapx, mapy, cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT, borderValue=0)
    valid = np.zeros((H, W), dtype=bool)
    valid[finite] = inside & shown
    return warped, valid


def printed_view(surface: ViewSurface, print_rgb: np.ndarray, px_per_mm: float, view_rgb: np.ndarray) -> np.ndarray:
    """The view's image as the print carries it: each pixel of the view's own region takes the print's colour there.

    The print samples its views at its own dpi, so what a photo of the part can show is the
    view's image at the print's resolution, not finer: registered against detail the print
    does not carry, a tile is pulled by a pixel or two (seen on the face mask at 100 dpi).

    Parameters
    ----------
    surface : ViewSurface
        The view's print coordinates per pixel.
    print_rgb : (rows, cols, 3) uint8
        The print.
    px_per_mm : float
        Its resolution.
    view_rgb : (H, W, 3) uint8
        The view's image (kept where the view does not own the surface).

    Returns
    -------
    (H, W, 3) uint8
    """
    return print_seen_from_view(print_rgb, surface.print_mm, px_per_mm, view_rgb, where=surface.owned)


def _bilinear(field: np.ndarray, x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Bilinear samples of an (H, W, C) field at points (x, y); NaN propagates."""
    H, W = field.shape[:2]
    j = np.clip(np.floor(x).astype(int), 0, W - 2)
    i = np.clip(np.floor(y).astype(int), 0, H - 2)
    fx, fy = (x - j)[:, None], (y - i)[:, None]
    return (field[i, j] * (1 - fx) + field[i, j + 1] * fx) * (1 - fy) + (
        field[i + 1, j] * (1 - fx) + field[i + 1, j + 1] * fx
    ) * fy


def register_tile(template: np.ndarray, image: np.ndarray, x0: int, y0: int) -> tuple[np.ndarray | None, float]:
    """Where a tile of the design is in the photo: (dx, dy) with image(x + d) ≈ gain · template(x) + offset.

    Normalised cross-correlation over a ±MARGIN window (``cv2.matchTemplate``) finds the
    integer peak, also on periodic patterns; Lucas-Kanade iterations on the translation,
    with gain and offset refitted at each step, take it to a small fraction of a pixel.
    (OpenCV's ECC was tried first: on tiles with the film shifted by 4.4 px it settled at
    0.2 px with a correlation of 0.93 where the correlation peaks at 4.4.)

    Parameters
    ----------
    template : (T, T) float32
        Design tile.
    image : (H, W) float32
        Warped photo (same smoothing as the template).
    x0, y0 : int
        Tile's top-left corner in both.

    Returns
    -------
    d : (2,) float or None
        Displacement, view pixels; None when the refinement does not settle or the tile is
        ambiguous.
    cc : float
        Normalised correlation at ``d`` (NaN: ambiguous, the correlation has two peaks).
    sigma : float
        Standard uncertainty of ``d`` along its least certain direction, view pixels: the
        fit's own residual variance through its normal equations, the shift's block of
        s² (KᵀK)⁻¹ (K: the shift's Jacobian J beside the light's nine unknowns) with
        s² = |r|² / (n - 11) (what the photo's noise and whatever the model does not explain
        leave in the fit), scaled by the residual's correlation length beyond the noise's.
    """
    T = template.shape[0]
    window = image[y0 - MARGIN : y0 + T + MARGIN, x0 - MARGIN : x0 + T + MARGIN]
    res = cv2.matchTemplate(window, template, cv2.TM_CCOEFF_NORMED)
    iy, ix = np.unravel_index(int(np.argmax(res)), res.shape)
    # a second peak nearly as high elsewhere (a periodic pattern, rings, lines of text): the
    # tile cannot tell which one is its place, whatever the refinement does
    far = res.copy()
    r = TILE // 8
    far[max(iy - r, 0) : iy + r + 1, max(ix - r, 0) : ix + r + 1] = -1.0
    # (the correlation's standard error over N independent samples is about (1 - cc²) / √N;
    # the tile's smoothed pixels hold N = T² / (4π s²) of them: a second peak within three
    # of those of the first is not told apart from it)
    # (only for a tile that matches somewhere: a photo that shows nothing of the tile, painted
    # over or torn away, correlates equally badly everywhere, and that is a tile that fails)
    best = float(res[iy, ix])
    if not np.isfinite(best) or best < MIN_CORRELATION / 2:
        return None, 0.0, np.inf
    n_ind = T * T / (4.0 * np.pi * REGISTRATION_BLUR_PX**2)
    if float(far.max()) > best - AMBIGUITY_Z * max(1.0 - best * best, 0.0) / np.sqrt(n_ind):
        return None, np.nan, np.inf
    d = np.array([ix - MARGIN, iy - MARGIN], dtype=np.float64)
    jj, ii = np.meshgrid(np.arange(T, dtype=np.float32) + x0, np.arange(T, dtype=np.float32) + y0)
    t = template.astype(np.float64).ravel()
    # tile coordinates of the core's pixels, -1 to 1
    u, v = np.meshgrid(np.linspace(-1, 1, T - 4), np.linspace(-1, 1, T - 4))
    u, v = u.ravel(), v.ravel()
    for _ in range(30):
        warped = cv2.remap(image, jj + np.float32(d[0]), ii + np.float32(d[1]), cv2.INTER_LINEAR)
        gx = cv2.Sobel(warped, cv2.CV_32F, 1, 0, ksize=3) / 8
        gy = cv2.Sobel(warped, cv2.CV_32F, 0, 1, ksize=3) / 8
        core = (slice(2, -2), slice(2, -2))
        w = warped[core].astype(np.float64).ravel()
        # the photo over the tile is gain · design + offset, the light a surface receives and the
        # light it adds: the gain a plane (a curved part's shading changes across a tile, and a
        # constant gain would read that ramp as a shift of a faint texture) and the added light
        # a quadric, the second-order Taylor term of a glossy film's sheen, a lobe smooth over a
        # tile whose curvature planes read as a shift of a faint edge (perfect glossy renders of
        # the lily: three tiles on its ring's faint edge 0.33 to 0.43 mm off with a plane, and a
        # part's median 0.06 mm, 0.02 with the quadric)
        A = np.column_stack([w, w * u, w * v, np.ones_like(w), u, v, u * u, u * v, v * v])
        coef, *_ = np.linalg.lstsq(A, t.reshape(T, T)[core].ravel(), rcond=None)
        gain = coef[0] + coef[1] * u + coef[2] * v
        r = t.reshape(T, T)[core].ravel() - A @ coef
        J = gain[:, None] * np.column_stack([gx[core].ravel(), gy[core].ravel()])
        step = np.linalg.lstsq(J, r, rcond=None)[0]
        # image(x + d + δ) ≈ w + g δ, so r ≈ gain g δ: the step solves J δ = r
        d += step
        if np.abs(step).max() < 1e-4:
            break
    else:
        return None, 0.0, np.inf
    wv = w - w.mean()
    tv = t.reshape(T, T)[core].ravel() - t.reshape(T, T)[core].mean()
    cc = float((wv * tv).sum() / np.sqrt((wv * wv).sum() * (tv * tv).sum() + 1e-12))
    K = np.column_stack([J, A])  # the shift's two columns and the light's nine
    s2 = float((r * r).sum()) / max(len(r) - K.shape[1], 1)
    # the residual's own correlation length: s² (KᵀK)⁻¹ holds for independent residuals; the
    # photo's noise, smoothed like the template, is correlated over about REGISTRATION_BLUR_PX,
    # but what the model does not explain (a highlight, shading the gain planes miss) is
    # correlated over its own breadth, and holds as many fewer independent samples as its
    # correlation area is larger (for a Gaussian-correlated field var(∇r) = var(r) / (2 ℓ²))
    rr = r.reshape(T - 4, T - 4)
    gyr, gxr = np.gradient(rr)
    ell = float(np.sqrt(np.var(rr) / (np.var(gxr) + np.var(gyr) + 1e-12)))
    s2 *= max(1.0, ell / REGISTRATION_BLUR_PX) ** 2
    # (the shift's block of the joint covariance s² (KᵀK)⁻¹: what the light's unknowns could take
    # of a shift, a texture as smooth as the light, is the shift's uncertainty, not its measure)
    try:
        cov = np.linalg.inv(K.T @ K)[:2, :2]
        sigma = float(np.sqrt(s2 * max(float(np.linalg.eigvalsh(cov).max()), 0.0)))
    except np.linalg.LinAlgError:
        sigma = np.inf
    return d, cc, sigma


@dataclass
class Score:
    """How the photo compares with the view's image.

    Attributes
    ----------
    centres : (n, 2) float
        Tile centres, view pixels.
    shift_px : (n, 2) float
        Where each tile's content is in the photo relative to the design, view pixels.
    shift_mm : (n,) float
        The same as a distance on the surface, mm.
    coverage : float
        Share of the view's own region the photo shows.
    ssim : float or None
        Similarity after alignment, exposure normalised, design blurred like the photo; None
        where the photo shows the view's own region in too few pixels to say.
    blur_px : float
        Blur of the photo as seen in the view, sigma in view pixels.
    film : dict
        Film placement fitted in print coordinates: offset_mm, rotation_deg, scale_pct, rms_mm.
    tiles_examined : int
        Textured tiles of the region tried; those that matched the design are ``centres``.
    sigma_mm : (n,) float
        Each matched tile's standard uncertainty, mm on the surface.
    """

    centres: np.ndarray
    shift_px: np.ndarray
    shift_mm: np.ndarray
    coverage: float
    ssim: float | None
    blur_px: float
    film: dict = field(default_factory=dict)
    tiles_examined: int = 0
    sigma_mm: np.ndarray = field(default_factory=lambda: np.zeros(0))


def estimate_blur(design_gray: np.ndarray, warped_gray: np.ndarray, mask: np.ndarray) -> float:
    """The Gaussian sigma (view px) that makes the design look most like the warped photo."""
    best, best_s = -2.0, 0.0
    m = mask.astype(bool)
    if m.sum() < 100:
        return 0.0
    w = warped_gray[m] - warped_gray[m].mean()
    for s in (0.0, 0.5, 0.75, 1.0, 1.5, 2.0, 3.0, 4.0):
        g = cv2.GaussianBlur(design_gray, (0, 0), s) if s else design_gray
        d = g[m] - g[m].mean()
        ncc = float((d * w).sum() / np.sqrt((d * d).sum() * (w * w).sum() + 1e-12))
        if ncc > best:
            best, best_s = ncc, s
    return best_s


def ssim(a: np.ndarray, b: np.ndarray, mask: np.ndarray) -> float:
    """Mean SSIM (Gaussian window, sigma 1.5) of two grey images over a mask."""
    C1, C2 = (0.01 * 255) ** 2, (0.03 * 255) ** 2
    a, b = a.astype(np.float64), b.astype(np.float64)

    def blur(x):
        return cv2.GaussianBlur(x, (0, 0), 1.5)

    ma, mb = blur(a), blur(b)
    va, vb, cov = blur(a * a) - ma * ma, blur(b * b) - mb * mb, blur(a * b) - ma * mb
    s = ((2 * ma * mb + C1) * (2 * cov + C2)) / ((ma * ma + mb * mb + C1) * (va + vb + C2))
    return float(s[mask].mean()) if mask.any() else 0.0


def fit_film(p_design: np.ndarray, p_shown: np.ndarray, print_size_mm, jacobians: np.ndarray | None = None) -> dict:
    """Film placement (offset, rotation, scale) that explains the misregistration.

    Each tile gives a pair: the design print point p at its centre, and p' at the place
    where the photo shows that content. A film moved by d, rotated by θ and scaled by
    k about the print's centre c shows print point q = c + M (p' - c - d) at a surface
    point whose design print point is p', with M = R(θ)⁻¹ / k (as the renderer's
    :func:`workbench.render.imperfections.film_transform`); there q = p. The similarity
    p = M p' + t is fitted by least squares on the residuals in view pixels (each tile's
    mm residual through the inverse of its 2x2 Jacobian, print mm per view pixel: a
    view seeing the print at a grazing angle measures one axis much less precisely),
    tiles beyond 3 median residuals dropped; then θ = atan2(M10, M00),
    k = 1 / sqrt(det M), d = M⁻¹ (c - t) - c.

    Parameters
    ----------
    p_design, p_shown : (n, 2) float
        Print mm (x right, y down).
    print_size_mm : (2,) float
        The print's size; its centre is the film's centre.
    jacobians : (n, 2, 2) float, optional
        Print mm per view pixel at each tile (columns: along view x, along view y).

    Returns
    -------
    dict
        offset_mm [x, y] (print coordinates, x right, y down), rotation_deg
        (counter-clockwise seen on the print), scale_pct, rms_mm, tiles.
    """
    c = 0.5 * np.asarray(print_size_mm, dtype=np.float64)
    n = len(p_design)
    Winv = np.tile(np.eye(2), (n, 1, 1)) if jacobians is None else np.linalg.inv(jacobians)
    x, y = p_shown[:, 0], p_shown[:, 1]
    # p = [[a, -b], [b, a]] p' + t, as rows of 2 equations per tile
    A = np.zeros((n, 2, 4))
    A[:, 0] = np.stack([x, -y, np.ones_like(x), np.zeros_like(x)], 1)
    A[:, 1] = np.stack([y, x, np.zeros_like(x), np.ones_like(x)], 1)
    Aw = np.einsum("nij,njk->nik", Winv, A)
    bw = np.einsum("nij,nj->ni", Winv, p_design)
    keep = np.ones(n, dtype=bool)
    for _ in range(2):
        sol, *_ = np.linalg.lstsq(Aw[keep].reshape(-1, 4), bw[keep].ravel(), rcond=None)
        res_px = np.linalg.norm(np.einsum("nik,k->ni", Aw, sol) - bw, axis=1)
        keep = res_px <= max(3.0 * np.median(res_px), 1e-3)
    a, b, tx, ty = sol
    M = np.array([[a, -b], [b, a]])
    res = np.linalg.norm(p_shown @ M.T + [tx, ty] - p_design, axis=1)
    theta = np.degrees(np.arctan2(M[1, 0], M[0, 0]))
    k = 1.0 / np.sqrt(np.linalg.det(M))
    d = np.linalg.solve(M, c - np.array([tx, ty])) - c
    return {
        "offset_mm": d.tolist(),
        "rotation_deg": float(theta),
        "scale_pct": float((k - 1) * 100),
        "rms_mm": float(np.sqrt(np.mean(res[keep] ** 2))),
        "tiles": int(keep.sum()),
    }


def tile_print_points(surface: ViewSurface, centres: np.ndarray, shifts: np.ndarray):
    """Where each tile's design content and its shown content are on the print, and the local Jacobian.

    Parameters
    ----------
    surface : ViewSurface
        The view's print coordinates per pixel.
    centres, shifts : (n, 2) float
        Tile centres and measured shifts, view pixels.

    Returns
    -------
    p_design, p_shown : (n, 2) float
        Print mm (x right, y down) of the tile's centre and of where the photo shows its content.
    jacobians : (n, 2, 2) float
        Print mm per view pixel along view x (column 0) and view y (column 1).
    good : (n,) bool
        Tiles where all of these are finite and the Jacobian invertible.
    """
    p0 = _bilinear(surface.print_mm, centres[:, 0], centres[:, 1])
    p1 = _bilinear(surface.print_mm, centres[:, 0] + shifts[:, 0], centres[:, 1] + shifts[:, 1])
    jx = _bilinear(surface.print_mm, centres[:, 0] + 1, centres[:, 1]) - p0
    jy = _bilinear(surface.print_mm, centres[:, 0], centres[:, 1] + 1) - p0
    J = np.stack([jx, jy], axis=2)
    good = np.isfinite(p0).all(1) & np.isfinite(p1).all(1) & np.isfinite(J).all((1, 2))
    good &= np.abs(np.linalg.det(np.nan_to_num(J))) > 1e-12
    return p0, p1, J, good


def surface_step(X: np.ndarray, y: int, x: int, size: int) -> np.ndarray:
    """Surface mm per view pixel over a tile: at each pixel the larger of the two axes' steps.

    The whole view's ``np.gradient`` took a tenth of a second for the few tiles that ask; a
    tile's, from the tile and its one-pixel rim, gives the same numbers there.

    Parameters
    ----------
    X : (H, W, 3) float
        The view's surface points, mm (NaN: none).
    y, x : int
        The tile's top-left pixel.
    size : int
        Its side, pixels.

    Returns
    -------
    (size, size) float
    """
    H, W = X.shape[:2]
    y0, x0 = max(y - 1, 0), max(x - 1, 0)
    sub = X[y0 : min(y + size + 1, H), x0 : min(x + size + 1, W)]
    with np.errstate(invalid="ignore"):
        step = np.maximum(
            np.linalg.norm(np.gradient(sub, axis=1), axis=2), np.linalg.norm(np.gradient(sub, axis=0), axis=2)
        )
    return step[y - y0 : y - y0 + size, x - x0 : x - x0 + size]


def photo_noise(gray: np.ndarray, mask: np.ndarray) -> float:
    """The photo's noise, grey levels (standard deviation), from its pixels in ``mask``.

    Immerkær's estimator ("Fast noise variance estimation", 1996) made robust: the
    difference of two Laplacians [[1, -2, 1], [-2, 4, -2], [1, -2, 1]] cancels every
    image's locally planar part and leaves 6 σ of white noise (the kernel's norm); its
    median absolute value over the mask (which the minority of pixels on edges does not
    move), times 1.4826, over 6, is σ.

    Parameters
    ----------
    gray : (H, W) float32
        Grey levels.
    mask : (H, W) bool
        Pixels to use.

    Returns
    -------
    float
        σ, at least NOISE_FLOOR.
    """
    k = np.array([[1, -2, 1], [-2, 4, -2], [1, -2, 1]], np.float32)
    resp = cv2.filter2D(gray.astype(np.float32), -1, k)
    inner = cv2.erode(mask.astype(np.uint8), np.ones((3, 3), np.uint8)).astype(bool)
    if inner.sum() < 100:
        return NOISE_FLOOR
    return max(float(1.4826 * np.median(np.abs(resp[inner])) / 6.0), NOISE_FLOOR)


def score(
    design_rgb: np.ndarray,
    warped: np.ndarray,
    valid: np.ndarray,
    surface: ViewSurface,
    print_size_mm,
    tolerance_mm: float = 0.5,
    printed_rgb: np.ndarray | None = None,
) -> Score:
    """Misregistration field, similarity, coverage and film fit of a warped photo.

    Parameters
    ----------
    design_rgb : (H, W, 3) uint8
        The view's image.
    warped : (H, W, 3) uint8
        The photo warped into the view.
    valid : (H, W) bool
        Where the warp has data.
    surface : ViewSurface
        The view's surface points, print coordinates and own region.
    print_size_mm : (2,) float
        Size of the print image, mm (its centre is the film's centre).
    tolerance_mm : float
        The misregistration tolerance: a tile counts when its uncertainty on the surface is
        below TILE_SIGMA_SHARE of it.
    printed_rgb : (H, W, 3) uint8, optional
        The view's image as the print carries it (:func:`printed_view`): the tiles' templates
        (the similarity still compares with the view's image itself).

    Returns
    -------
    Score
    """
    mask = surface.owned & valid
    coverage = float(mask.sum() / max(surface.owned.sum(), 1))
    dg = cv2.cvtColor(design_rgb, cv2.COLOR_RGB2GRAY).astype(np.float32)
    wg = cv2.cvtColor(warped, cv2.COLOR_RGB2GRAY).astype(np.float32)
    inner = cv2.erode(mask.astype(np.uint8), np.ones((5, 5), np.uint8)).astype(bool)
    # registration on both images smoothed alike: unbiased whatever the photo's blur
    # (estimating that blur first is not: misregistration makes more blur look better)
    ref = cv2.GaussianBlur(dg, (0, 0), REGISTRATION_BLUR_PX)
    wr = cv2.GaussianBlur(wg, (0, 0), REGISTRATION_BLUR_PX)
    tref = ref
    if printed_rgb is not None:
        pgr = cv2.cvtColor(printed_rgb, cv2.COLOR_RGB2GRAY).astype(np.float32)
        tref = cv2.GaussianBlur(pgr, (0, 0), REGISTRATION_BLUR_PX)
    gx = cv2.Sobel(tref, cv2.CV_32F, 1, 0, ksize=3) / 8
    gy = cv2.Sobel(tref, cv2.CV_32F, 0, 1, ksize=3) / 8
    H, W = ref.shape
    # the photo's noise after the registration's smoothing: white noise through a Gaussian of
    # sigma s keeps 1 / (2 √π s) of its standard deviation
    noise = photo_noise(wg, mask) / (2.0 * np.sqrt(np.pi) * REGISTRATION_BLUR_PX)
    n_core = (TILE - 4) ** 2
    max_sigma_mm = TILE_SIGMA_SHARE * tolerance_mm
    # the photo's blur beyond the template's, view px (from the whole region, before any tile)
    blur_view = estimate_blur(tref, wr, inner) if inner.sum() > 1000 else 0.0
    centres, shifts, sigmas, examined, candidates = [], [], [], 0, []
    crit = (cv2.TERM_CRITERIA_EPS | cv2.TERM_CRITERIA_COUNT, 100, 1e-6)
    # tiles keep clear of the region's border by the largest shift they can measure:
    # a shifted film brings the neighbouring view's content into a band that wide
    clear = cv2.erode(mask.astype(np.uint8), np.ones((2 * MARGIN + 1, 2 * MARGIN + 1), np.uint8)).astype(bool)
    for y in range(0, H - TILE + 1, TILE // 2):
        for x in range(0, W - TILE + 1, TILE // 2):
            if not clear[y : y + TILE, x : x + TILE].all():
                continue
            if y < MARGIN or x < MARGIN or y + TILE + MARGIN > H or x + TILE + MARGIN > W:
                continue
            a, b = gx[y : y + TILE, x : x + TILE], gy[y : y + TILE, x : x + TILE]
            S = np.array([[(a * a).mean(), (a * b).mean()], [(a * b).mean(), (b * b).mean()]])
            # the registration's uncertainty the photo's noise allows, σ / √(N λ_min): one
            # straight edge (λ_min 0) fixes only the shift across it, and low contrast fixes
            # it less well than high contrast, in proportion to the noise
            lam = max(float(np.linalg.eigvalsh(S)[0]), 1e-12)
            mm_per_px = float(np.nanmedian(surface_step(surface.X, y, x, TILE)))
            if not np.isfinite(mm_per_px) or noise / np.sqrt(n_core * lam) * mm_per_px > max_sigma_mm:
                continue
            candidates.append((y, x, mm_per_px))
    # evenly thinned in raster order where there are more than MAX_TILES
    keep = max(1, int(np.ceil(len(candidates) / MAX_TILES)))
    for y, x, mm_per_px in candidates[::keep]:
        examined += 1
        tpl = tref[y : y + TILE, x : x + TILE]
        d, cc, sigma = register_tile(tpl, wr, x, y)
        if np.isnan(cc):
            examined -= 1  # ambiguous: says nothing of whether the decoration matches
            continue
        # the correlation a perfectly placed tile reaches under the photo's blur and noise: the
        # template against itself blurred like the photo, and that signal against the noise
        core = (slice(2, -2), slice(2, -2))
        tb = cv2.GaussianBlur(tpl, (0, 0), blur_view)[core] if blur_view > 0 else tpl[core]
        a, b = tpl[core] - tpl[core].mean(), tb - tb.mean()
        var_t = float((b * b).mean())
        cc_blur = float((a * b).sum() / np.sqrt((a * a).sum() * (b * b).sum() + 1e-12))
        cc_noise = cc_blur * np.sqrt(var_t / (var_t + noise * noise))
        if d is not None and cc >= MIN_CORRELATION * cc_noise and sigma * mm_per_px > max_sigma_mm:
            # it matches, but too loosely to measure: says nothing of a missing decoration
            examined -= 1
            continue
        if d is not None and cc >= MIN_CORRELATION * cc_noise and np.abs(d).max() < MARGIN - 1:
            centres.append((x + (TILE - 1) / 2, y + (TILE - 1) / 2))
            shifts.append(d)
            sigmas.append(sigma * mm_per_px)
    centres = np.array(centres).reshape(-1, 2)
    sigmas = np.array(sigmas, dtype=np.float64)
    shifts = np.array(shifts).reshape(-1, 2)
    film: dict = {}
    shift_mm = np.zeros(len(centres))
    if len(centres):
        X0 = _bilinear(surface.X, centres[:, 0], centres[:, 1])
        X1 = _bilinear(surface.X, centres[:, 0] + shifts[:, 0], centres[:, 1] + shifts[:, 1])
        shift_mm = np.linalg.norm(X1 - X0, axis=1)
        ok = np.isfinite(shift_mm)
        centres, shifts, shift_mm, sigmas = centres[ok], shifts[ok], shift_mm[ok], sigmas[ok]
        if len(centres) >= 4:
            p0, p1, J, good = tile_print_points(surface, centres, shifts)
            if good.sum() >= 4:
                film = fit_film(p0[good], p1[good], print_size_mm, jacobians=J[good])
    # similarity after alignment: the photo aligned on the design by one homography,
    # then the design blurred like the photo, exposure matched by a linear fit
    # (a view whose own region the photo shows in fewer pixels than this has no similarity:
    # None, not 0, which would read as a wrong print)
    sim, blur = None, 0.0
    if inner.sum() > 1000:
        aligned = wg
        try:
            # at most a quarter megapixel: the homography only needs to align the pair to a
            # fraction of a pixel for SSIM, which barely moves under small misregistration
            # (a full-size view took 5 to 15 s)
            q = max(1, int(np.ceil(np.sqrt(H * W / ECC_MAX_PX))))
            small = (W // q, H // q)
            Hs = np.eye(3, dtype=np.float32)
            _, Hs = cv2.findTransformECC(
                cv2.resize(ref, small, interpolation=cv2.INTER_AREA),
                cv2.resize(wr, small, interpolation=cv2.INTER_AREA),
                Hs,
                cv2.MOTION_HOMOGRAPHY,
                crit,
                cv2.resize(inner.astype(np.uint8), small, interpolation=cv2.INTER_NEAREST),
                1,
            )
            # full-size pixel x is small pixel (x + 0.5) / q - 0.5
            A = np.array([[1 / q, 0, 0.5 / q - 0.5], [0, 1 / q, 0.5 / q - 0.5], [0, 0, 1]], np.float64)
            Hm = (np.linalg.inv(A) @ Hs.astype(np.float64) @ A).astype(np.float32)
            moved = cv2.warpPerspective(wg, Hm, (W, H), flags=cv2.INTER_LINEAR + cv2.WARP_INVERSE_MAP)
            kept = cv2.warpPerspective(np.ones_like(wg), Hm, (W, H), flags=cv2.INTER_LINEAR + cv2.WARP_INVERSE_MAP)
            # (ECC can converge far away over a smooth, glossy view: a homography that moves the photo
            # off the view's own region aligns nothing; on a perfect 12 Mpx lens photo of a soft part it
            # kept 0.7 % of the view and left one grey over it)
            if kept[inner].mean() >= 0.9:
                aligned = moved
        except cv2.error:
            pass
        blur = estimate_blur(dg, aligned, inner)
        design_like = cv2.GaussianBlur(dg, (0, 0), blur) if blur else dg
        shown = aligned[inner]
        # (a photo that shows one grey over the whole view, black where a glossy lens photo's warp
        # fell outside it, has no exposure to fit: no similarity, where the fit's SVD failed and the
        # photo lost its verdict)
        if np.isfinite(shown).all() and np.ptp(shown) > 0:
            gain, off = np.polyfit(shown, design_like[inner], 1)
            sim = ssim(design_like, aligned * gain + off, inner)
    return Score(centres, shifts, shift_mm, coverage, sim, float(blur), film, examined, sigmas)
