"""Per-pixel synthesis of the print: print pixel → surface point → owning view → image sample."""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numba
import numpy as np

from workbench.camera import Camera
from workbench.raster import _JIT, _face_edges, _row_span, _setup, _weight
from workbench.views.visibility import ViewVisibility, project_point, unoccluded

MM_PER_INCH = 25.4
BAND_ROWS = 256  # print rows synthesised at a time


@dataclass(frozen=True)
class PrintGrid:
    """The print's pixel grid over the design rectangle.

    Pixel (i, j) has its centre at x = (j + 0.5) · 25.4 / dpi mm from the left edge
    and y = (i + 0.5) · 25.4 / dpi mm down from the top edge of the design rectangle
    (DESIGN.md). The image covers the rectangle with whole pixels: it is
    ``ceil(size · dpi / 25.4)`` pixels, so it reaches less than one pixel beyond the
    right and bottom edges.

    Attributes
    ----------
    width_mm, height_mm : float
        Design rectangle.
    dpi : float
        Pixels per inch.
    """

    width_mm: float
    height_mm: float
    dpi: float

    @property
    def px_per_mm(self) -> float:
        return self.dpi / MM_PER_INCH

    @property
    def shape(self) -> tuple[int, int]:
        """(rows, columns)."""
        s = self.px_per_mm
        # 1e-9: a size that is a whole number of pixels up to rounding stays that number
        return int(np.ceil(self.height_mm * s - 1e-9)), int(np.ceil(self.width_mm * s - 1e-9))

    def to_pixels(self, uv_mm: np.ndarray) -> np.ndarray:
        """Flat positions (x right, y up, mm; A at the origin) to pixel coordinates (x right, y down)."""
        s = self.px_per_mm
        return np.stack([uv_mm[:, 0] * s - 0.5, (self.height_mm - uv_mm[:, 1]) * s - 0.5], axis=1)


def prefilter(image: np.ndarray, camera: Camera, view_px_per_print_px: float) -> tuple[np.ndarray, Camera]:
    """Area-filter a view image where the print is coarser than it.

    Parameters
    ----------
    image : (H, W, 3) uint8
        View image.
    camera : Camera
        Its camera.
    view_px_per_print_px : float
        Typical number of view pixels one print pixel spans (linear).

    Returns
    -------
    image, camera
        Unchanged when a print pixel spans at most 1.5 view pixels; else the image
        reduced with pixel-area averaging to about one view pixel per print pixel,
        and the camera that sees that reduced image.
    """
    if view_px_per_print_px <= 1.5:
        return image, camera
    cam = camera.scaled(1.0 / view_px_per_print_px)
    return cv2.resize(image, (cam.width, cam.height), interpolation=cv2.INTER_AREA), cam


@numba.njit(**_JIT)
def _inside(e0, e1, e2, x, y):
    _, ok0 = _weight(e0, x, y)
    _, ok1 = _weight(e1, x, y)
    _, ok2 = _weight(e2, x, y)
    return ok0 and ok1 and ok2


@numba.njit(parallel=True, **_JIT)
def _maps(P, F, V, orient, status, cams, offsets, isize, dcams, depth, dsize, decor, faces, row0, mapx, mapy, owner):
    """For the print rows [row0, row0 + band height): owning view and atlas position of every pixel.

    Pixels no view owns keep the caller's values (a position outside the atlas). ``decor``
    (#views, H, W) is nonzero at each view's decoration pixels: a view claiming a face in
    part paints a pixel only where the surface point lands nearest one of them.
    """
    n_views = status.shape[1]
    Hb, W = mapx.shape[0], mapx.shape[1]
    for k in numba.prange(faces.shape[0]):
        f = faces[k]
        first = -1  # the first view claiming f
        for v in range(n_views):
            if status[f, v] != 0:
                first = v
                break
        if first < 0:
            continue
        x0, x1, y0, y1, area2 = _setup(P, F, f, W, row0 + Hb)
        y0 = max(y0, row0)
        if area2 * orient <= 0.0 or x1 < x0 or y1 < y0:
            continue  # collapsed or folded in the print (covered by its neighbours), or not in this band
        inv = 1.0 / abs(area2)
        e0, e1, e2 = _face_edges(P, F, f, orient)
        i0, i1, i2 = F[f, 0], F[f, 1], F[f, 2]
        whole = status[f, first] == 1
        # A face the first view claims whole maps print pixels to view pixels by one
        # homography: barycentrics are affine in (x, y), the surface point affine in
        # them, the camera projective. H = K [R | t] · (V_face · L) with L the 3x3
        # affine map from (x, y, 1) to barycentrics; evaluated incrementally per row.
        h = np.empty(9)
        if whole:
            cam = cams[first]
            L = np.empty((3, 3))
            for r in range(3):
                e = e0 if r == 0 else (e1 if r == 1 else e2)
                # w_r = s (dx (y - ly) - dy (x - lx)) = a x + b y + c
                L[r, 0] = -e[0] * e[4] * inv
                L[r, 1] = e[0] * e[3] * inv
                L[r, 2] = e[0] * (e[4] * e[1] - e[3] * e[2]) * inv
            for r in range(3):
                # row r of K [R | t] (fx, fy, cx, cy; R row-major; t)
                if r == 0:
                    m0 = cam[0] * cam[4] + cam[2] * cam[10]
                    m1 = cam[0] * cam[5] + cam[2] * cam[11]
                    m2 = cam[0] * cam[6] + cam[2] * cam[12]
                    m3 = cam[0] * cam[13] + cam[2] * cam[15]
                elif r == 1:
                    m0 = cam[1] * cam[7] + cam[3] * cam[10]
                    m1 = cam[1] * cam[8] + cam[3] * cam[11]
                    m2 = cam[1] * cam[9] + cam[3] * cam[12]
                    m3 = cam[1] * cam[14] + cam[3] * cam[15]
                else:
                    m0, m1, m2, m3 = cam[10], cam[11], cam[12], cam[15]
                for col in range(3):
                    acc = 0.0
                    for q in range(3):
                        vq = F[f, q]
                        acc += (m0 * V[vq, 0] + m1 * V[vq, 1] + m2 * V[vq, 2]) * L[q, col]
                    # the translation column multiplies the barycentrics' sum, 1: the constant term
                    h[3 * r + col] = acc + (m3 if col == 2 else 0.0)
        wv, hv = isize[first, 0], isize[first, 1]
        ox, oy = offsets[first, 0], offsets[first, 1]
        for py in range(y0, y1 + 1):
            y = float(py)
            xs, xe = _row_span(e0, e1, e2, y, x0, x1)
            # exact tests only at the two ends: the row's inside is one interval
            while xs <= xe and not _inside(e0, e1, e2, float(xs), y):
                xs += 1
            while xe >= xs and not _inside(e0, e1, e2, float(xe), y):
                xe -= 1
            row = py - row0
            if whole:
                U = h[0] * xs + h[1] * y + h[2]
                Vv = h[3] * xs + h[4] * y + h[5]
                Z = h[6] * xs + h[7] * y + h[8]
                for px in range(xs, xe + 1):
                    iz = 1.0 / Z
                    mapx[row, px] = min(max(U * iz, -0.5), wv - 0.5) + ox
                    mapy[row, px] = min(max(Vv * iz, -0.5), hv - 0.5) + oy
                    owner[row, px] = first
                    U += h[0]
                    Vv += h[3]
                    Z += h[6]
                continue
            for px in range(xs, xe + 1):
                x = float(px)
                w0, _ = _weight(e0, x, y)
                w1, _ = _weight(e1, x, y)
                w2, _ = _weight(e2, x, y)
                l0, l1, l2 = w0 * inv, w1 * inv, w2 * inv
                X0 = l0 * V[i0, 0] + l1 * V[i1, 0] + l2 * V[i2, 0]
                X1 = l0 * V[i0, 1] + l1 * V[i1, 1] + l2 * V[i2, 1]
                X2 = l0 * V[i0, 2] + l1 * V[i1, 2] + l2 * V[i2, 2]
                chosen = -1
                for v in range(first, n_views):
                    st = status[f, v]
                    if st == 0:
                        continue
                    if st == 2:
                        xd, yd, zd = project_point(dcams[v], X0, X1, X2)
                        if not unoccluded(depth[v], dsize[v, 0], dsize[v, 1], dcams[v, 0], xd, yd, zd):
                            continue
                        # the pixel nearest the point (inside the image: unoccluded says so)
                        jd = min(max(int(np.floor(xd + 0.5)), 0), dsize[v, 0] - 1)
                        id_ = min(max(int(np.floor(yd + 0.5)), 0), dsize[v, 1] - 1)
                        if decor[v, id_, jd] == 0:
                            continue  # transparent there: the next view that sees it, else background
                    chosen = v
                    break
                if chosen >= 0:
                    xv, yv, _ = project_point(cams[chosen], X0, X1, X2)
                    mapx[row, px] = min(max(xv, -0.5), isize[chosen, 0] - 0.5) + offsets[chosen, 0]
                    mapy[row, px] = min(max(yv, -0.5), isize[chosen, 1] - 0.5) + offsets[chosen, 1]
                    owner[row, px] = chosen


def synthesize_print(
    grid: PrintGrid,
    uv_mm: np.ndarray,
    V: np.ndarray,
    F: np.ndarray,
    status: np.ndarray,
    visibilities: list[ViewVisibility],
    images: list[np.ndarray],
    background: tuple[int, int, int],
) -> tuple[np.ndarray, np.ndarray, list[float]]:
    """The print texture, one surface point per print pixel, sampled in its owning view.

    Parameters
    ----------
    grid : PrintGrid
        The print's pixels.
    uv_mm : (#V, 2) float
        Flat layout, mm (y up).
    V : (#V, 3) float
        Surface positions, mm.
    F : (#F, 3) int
        Triangles.
    status : (#F, #views) int8
        Ownership from :func:`workbench.views.visibility.assign_views`.
    visibilities : list of ViewVisibility
        Per view, in priority order (cameras, depth buffers and decoration pixels: a view
        paints only where the surface point lands on one of them).
    images : list of (H, W, 3) uint8
        View images, RGB.
    background : (3,) int
        Colour of pixels no view owns.

    Returns
    -------
    rgb : (rows, cols, 3) uint8
        The print.
    owner : (rows, cols) int8
        Owning view per pixel, -1 for background.
    view_px_per_print_px : list of float
        Per view, the median number of view pixels a print pixel spans (above 1.5 the
        view image was area-filtered first).
    """
    rows, cols = grid.shape
    P = grid.to_pixels(uv_mm)
    # the print's faces share one orientation (the layout's, mirrored by y down)
    a, b, c = P[F[:, 0]], P[F[:, 1]], P[F[:, 2]]
    area2 = (b[:, 0] - a[:, 0]) * (c[:, 1] - a[:, 1]) - (b[:, 1] - a[:, 1]) * (c[:, 0] - a[:, 0])
    orient = -1.0 if np.median(area2) < 0 else 1.0
    scales, cams, used = [], [], []
    for v, (vis, img) in enumerate(zip(visibilities, images, strict=True)):
        claimed = status[:, v] != 0
        xy, _ = vis.camera.project(V)
        s = _median_scale(xy, P, F[claimed], np.abs(area2[claimed]))
        scales.append(s)
        img2, cam2 = prefilter(img, vis.camera, s)
        used.append(img2)
        cams.append(cam2)
    # the views stacked into one atlas, each with a one-pixel replicated border, so that one
    # cv2.remap samples them all; view pixel (i, j) is at atlas (offset_y + i, 1 + j)
    width = max(im.shape[1] for im in used) + 2
    offsets, rows_at = [], 1
    for im in used:
        offsets.append((1.0, float(rows_at)))
        rows_at += im.shape[0] + 2
    atlas = np.zeros((rows_at - 1, width, 3), dtype=np.uint8)
    for (_, oy), im in zip(offsets, used, strict=True):
        y = int(oy) - 1
        atlas[y : y + im.shape[0] + 2, : im.shape[1] + 2] = cv2.copyMakeBorder(im, 1, 1, 1, 1, cv2.BORDER_REPLICATE)
    dh = max(vis.depth.shape[0] for vis in visibilities)
    dw = max(vis.depth.shape[1] for vis in visibilities)
    depth = np.full((len(visibilities), dh, dw), np.inf)
    decor = np.ones((len(visibilities), dh, dw), np.uint8)
    for v, vis in enumerate(visibilities):
        depth[v, : vis.depth.shape[0], : vis.depth.shape[1]] = vis.depth
        if vis.decoration is not None:
            decor[v, : vis.depth.shape[0], : vis.depth.shape[1]] = vis.decoration
    # bands of rows: the maps of a band stay in cache, and memory stays small at any size
    y_lo = np.ceil(np.min(P[F, 1], axis=1)).astype(np.int64)
    y_hi = np.floor(np.max(P[F, 1], axis=1)).astype(np.int64)
    order = np.argsort(y_lo, kind="stable")
    y_sorted = y_lo[order]
    tallest = int(max((y_hi - y_lo).max(), 0)) + 1
    out = np.empty((rows, cols, 3), dtype=np.uint8)
    owner = np.empty((rows, cols), dtype=np.int8)
    mapx = np.empty((BAND_ROWS, cols), dtype=np.float32)
    mapy = np.empty((BAND_ROWS, cols), dtype=np.float32)
    args = (
        np.ascontiguousarray(P),
        np.ascontiguousarray(F, dtype=np.int64),
        np.ascontiguousarray(V, dtype=np.float64),
        orient,
        np.ascontiguousarray(status),
        np.stack([c.packed() for c in cams]),
        np.asarray(offsets),
        np.array([[c.width, c.height] for c in cams], dtype=np.int64),
        np.stack([vis.camera.packed() for vis in visibilities]),
        depth,
        np.array([[vis.camera.width, vis.camera.height] for vis in visibilities], dtype=np.int64),
        decor,
    )
    bg = tuple(int(c) for c in background)
    for row0 in range(0, rows, BAND_ROWS):
        n = min(BAND_ROWS, rows - row0)
        mx, my, ow = mapx[:n], mapy[:n], owner[row0 : row0 + n]
        mx.fill(-1e4)  # outside the atlas: the background colour
        my.fill(-1e4)
        ow.fill(-1)
        # faces reaching into the band: first row before its end, last row after its start
        lo = np.searchsorted(y_sorted, row0 - tallest, side="left")
        hi = np.searchsorted(y_sorted, row0 + n, side="left")
        faces = order[lo:hi]
        faces = np.ascontiguousarray(faces[y_hi[faces] >= row0])
        _maps(*args, faces, row0, mx, my, ow)
        cv2.remap(
            atlas, mx, my, cv2.INTER_LINEAR, dst=out[row0 : row0 + n], borderMode=cv2.BORDER_CONSTANT, borderValue=bg
        )
    return out, owner, scales


def _median_scale(xy: np.ndarray, P: np.ndarray, F: np.ndarray, print_area2: np.ndarray) -> float:
    """Area-weighted median over faces of sqrt(view area / print area), in pixels."""
    if len(F) == 0:
        return 1.0
    a, b, c = xy[F[:, 0]], xy[F[:, 1]], xy[F[:, 2]]
    view_area2 = np.abs((b[:, 0] - a[:, 0]) * (c[:, 1] - a[:, 1]) - (b[:, 1] - a[:, 1]) * (c[:, 0] - a[:, 0]))
    ratio = np.sqrt(view_area2 / np.maximum(print_area2, 1e-300))
    order = np.argsort(ratio)
    cw = np.cumsum(print_area2[order])
    return float(ratio[order][np.searchsorted(cw, 0.5 * cw[-1])])
