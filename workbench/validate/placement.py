"""The film's placement from the dense field: each film's affine field, and its offset, rotation and scale.

A film placed off (moved, turned, scaled) shows a misregistration affine in print
coordinates; what remains after it is the film's shape and its local defects.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import cv2
import numpy as np

if TYPE_CHECKING:
    from workbench.validate.dense import DenseResult
    from workbench.validate.print_warp import PrintGrid

PLACEMENT_STRIDE = 8  # every 8th grid pixel each way: 20,000 samples on a 1.4 Mpx grid fit six terms
PLACEMENT_TRIM = 3.0  # a sample beyond this many median normalised residuals is a local defect's, not the film's


def placed_print(image: np.ndarray, field_px: np.ndarray, interpolation: int = cv2.INTER_LINEAR) -> np.ndarray:
    """An image on the print's grid moved as the films' placement moves the film.

    The photo shows at grid pixel p what the print holds at p - d(p) (the film moved by d), so
    the placed print samples the print there.

    Parameters
    ----------
    image : (rows, cols) or (rows, cols, C) array
        On the print's grid (the print, or a mask as uint8).
    field_px : (rows, cols, 2) float
        The placement per grid pixel (:func:`placement_field`), grid px (x, y).
    interpolation : int
        OpenCV's interpolation (``cv2.INTER_NEAREST`` for a mask).

    Returns
    -------
    array, the shape and type of ``image``
        Beyond the grid, the nearest edge pixel.
    """
    rows, cols = field_px.shape[:2]
    jj, ii = np.meshgrid(np.arange(cols, dtype=np.float32), np.arange(rows, dtype=np.float32))
    mx = jj - field_px[..., 0].astype(np.float32)
    my = ii - field_px[..., 1].astype(np.float32)
    return cv2.remap(image, mx, my, interpolation, borderMode=cv2.BORDER_REPLICATE)


def placement_field(
    flow_px: np.ndarray,
    across: np.ndarray,
    full: np.ndarray,
    normal: np.ndarray,
    sigma_px: np.ndarray,
    film: np.ndarray | None,
    max_sigma_px: np.ndarray | float,
    window_px: float,
) -> tuple[np.ndarray, np.ndarray]:
    """The misregistration each film's placement explains: a robust affine fit of the flow per film.

    A film placed off (moved, turned, scaled, or printed at another scale along each axis)
    shows, at the print point y, a misregistration affine in y: m(y) = A y + t. A local defect
    (a bubble, a fold) is what remains: m(y) - A y - t. The fit takes every PLACEMENT_STRIDE-th
    pixel that measures the full vector (two equations) or the component across an edge
    (n · m(y), one), each weighted by its own uncertainty, and drops samples beyond
    PLACEMENT_TRIM median normalised residuals, three times: a bubble of 6 mm on a film of
    100 mm is a few per cent of the samples and goes with the trimmed ones. A film whose
    samples cannot determine the six terms to a third of ``max_sigma_px`` at its farthest
    sample keeps no field (nothing is taken from its flow).

    Parameters
    ----------
    flow_px : (H, W, 2) float32
        The dense flow, grid px (x, y).
    across : (H, W, 2) float32
        Unit vector across the edge where only that component is measured.
    full, normal : (H, W) bool
        Pixels that measure the full vector; those that measure the component across an edge.
    sigma_px : (H, W) float32
        Each pixel's standard uncertainty, grid px (of the full vector's weaker direction, or
        of the component across the edge).
    film : (H, W) int or None
        The film under each pixel (-1: none); None for one film.
    max_sigma_px : float or (H, W) float
        The uncertainty a measuring pixel may have (grid px): the fitted field must be known
        to a third of it.
    window_px : float
        The flow window's Gaussian sigma, grid px: samples closer than a window share their
        evidence.

    Returns
    -------
    field : (H, W, 2) float32
        The placement's misregistration, grid px (0 where a film's placement is undetermined).
    fitted : (H, W) bool
        The pixels of films whose placement was fitted.
    """
    H, W = full.shape
    field = np.zeros((H, W, 2), np.float32)
    fitted = np.zeros((H, W), bool)
    labels = np.zeros((H, W), np.int16) if film is None else film
    sub = np.zeros((H, W), bool)
    sub[::PLACEMENT_STRIDE, ::PLACEMENT_STRIDE] = True
    limit = np.broadcast_to(np.asarray(max_sigma_px, np.float32), (H, W))
    ok = np.isfinite(sigma_px) & (sigma_px > 0)
    for k in np.unique(labels[(full | normal) & ok & sub]):
        if k < 0:
            continue
        mine = labels == k
        fi, fj = np.nonzero(full & ok & sub & mine)
        ei, ej = np.nonzero(normal & ok & sub & mine)
        if len(fi) + len(ei) < 12:
            continue
        # centred and scaled coordinates: the normal equations stay well conditioned
        ii, jj = np.nonzero(mine)
        c = np.array([jj.mean(), ii.mean()])
        r = max(float(np.hypot(jj - c[0], ii - c[1]).max()), 1.0)

        bf, be = _affine_terms(fi, fj, c, r), _affine_terms(ei, ej, c, r)
        zf = np.zeros_like(bf)
        n = across[ei, ej].astype(np.float64)
        # unknowns (a_xx, a_xy, t_x, a_yx, a_yy, t_y): x component (bf, 0), y component (0, bf),
        # across an edge n_x (be, 0) + n_y (0, be)
        A = np.concatenate(
            [np.concatenate([bf, zf], 1), np.concatenate([zf, bf], 1),
             np.concatenate([n[:, :1] * be, n[:, 1:] * be], 1)]
        )  # fmt: skip
        b = np.concatenate(
            [flow_px[fi, fj, 0], flow_px[fi, fj, 1], (flow_px[ei, ej] * across[ei, ej]).sum(axis=1)]
        ).astype(np.float64)
        s = np.concatenate([sigma_px[fi, fj], sigma_px[fi, fj], sigma_px[ei, ej]]).astype(np.float64)
        A, b = A / s[:, None], b / s
        keep = np.ones(len(b), bool)
        for _ in range(3):
            sol = np.linalg.lstsq(A[keep], b[keep], rcond=None)[0]
            res = np.abs(A @ sol - b)
            keep = res <= max(PLACEMENT_TRIM * float(np.median(res[keep])), 1e-6)
        AtA = A[keep].T @ A[keep]
        if keep.sum() < 12 or np.linalg.cond(AtA) > 1e12:
            continue
        # the field's uncertainty at the film's farthest point (|y| = 1): each sample counts as
        # the share of an independent flow window it is, so the covariance is scaled by the
        # samples per window and by the reduced chi² where that exceeds 1
        dof = max(int(keep.sum()) - 6, 1)
        chi2 = float((res[keep] ** 2).sum()) / dof
        cov = np.linalg.inv(AtA) * max(chi2, 1.0) * max(1.0, 4.0 * np.pi * window_px**2 / PLACEMENT_STRIDE**2)
        corner = np.array([1.0, 1.0, 1.0])
        sd = np.sqrt(max(corner @ cov[:3, :3] @ corner, corner @ cov[3:, 3:] @ corner))
        if sd > float(np.median(limit[mine])) / 3.0:
            continue
        Y = _affine_terms(ii, jj, c, r)
        field[ii, jj, 0] = Y @ sol[:3]
        field[ii, jj, 1] = Y @ sol[3:]
        fitted |= mine
    return field, fitted


def _affine_terms(i: np.ndarray, j: np.ndarray, c: np.ndarray, r: float) -> np.ndarray:
    """Terms (y_x, y_y, 1) of one component of m = A y + t at pixels (i, j), y = ((j, i) - c) / r; (n, 3)."""
    return np.stack([(j - c[0]) / r, (i - c[1]) / r, np.ones(len(i))], axis=1)


def dense_placement(dr: DenseResult, grid: PrintGrid, max_sigma_mm: float, print_size_mm, stride: int = 4) -> dict:
    """The film's placement from the dense field: its full vectors and its components across edges.

    The film moved by t', rotated and scaled by M = [[a, -b], [b, a]] about the print's centre
    c shows, at the print point y, the content designed at M (y - c) + c - t' (the convention of
    :func:`workbench.validate.score.fit_film`): a misregistration m(y) = K (y - c) + t' with
    K = I - M, linear in (K, t'). A pixel with the full vector gives both components; one on
    an edge gives the component across it, n · m(y) (a logo's outline, edges in every
    direction, fixes the placement as a textured patch does). Weighted least squares (each
    pixel by its own uncertainty), pixels beyond 3 median normalised residuals dropped twice.
    The film's offset is M⁻¹ t'. Its uncertainty is the fit's covariance, each pixel counted
    as the share of an independent flow window it is (neighbours share their window), scaled
    by the fit's reduced chi² where that exceeds 1.

    Parameters
    ----------
    dr : DenseResult
    grid : PrintGrid
    max_sigma_mm : float
        Largest uncertainty (mm on the surface) of a pixel taken.
    print_size_mm : (2,) float
        The print's size; its centre is the film's centre.
    stride : int
        Every ``stride``-th pixel along each axis.

    Returns
    -------
    dict
        ``film``: offset_mm [x, y] (print mm), rotation_deg, scale_pct, rms_mm (print mm), samples;
        or None when fewer than 4 samples or a degenerate fit. ``uncertainty_mm``: the offset's
        standard uncertainty (print mm, the worse axis; inf when undetermined). ``windows``:
        independent flow windows taken (an edge pixel counts half). ``shift_mm`` (n,): the
        misregistration at each sample, mm on the surface (on an edge: the fitted vector with
        its measured component across the edge).
    """
    ppm = grid.px_per_mm
    sig = np.nan_to_num(dr.sigma_mm, nan=np.inf)
    full = (dr.texture == 2) & (sig <= max_sigma_mm)
    edge = (dr.texture == 1) & (sig <= max_sigma_mm) & (dr.normal_dir is not None)
    area = 4.0 * np.pi * dr.window_px**2
    windows = float(full.sum() + 0.5 * edge.sum()) / area
    out = {"film": None, "uncertainty_mm": float("inf"), "windows": windows, "shift_mm": np.zeros(0)}
    sub = np.zeros_like(full)
    sub[::stride, ::stride] = True
    fi, fj = np.nonzero(full & sub)
    ei, ej = np.nonzero(edge & sub)
    if len(fi) + len(ei) < 4:
        return out
    c = 0.5 * np.asarray(print_size_mm, dtype=np.float64)
    stretch = grid.surface_per_print

    def centred(ii, jj):
        return np.stack([jj + 0.5, ii + 0.5], axis=1) / ppm - c

    # rows of m = K y + t' with K = [[u, v], [-v, u]]: (x, y, 1, 0) and (y, -x, 0, 1)
    yf, ye = centred(fi, fj), centred(ei, ej)
    Af = np.stack(
        [np.stack([yf[:, 0], yf[:, 1], np.ones(len(yf)), np.zeros(len(yf))], 1),
         np.stack([yf[:, 1], -yf[:, 0], np.zeros(len(yf)), np.ones(len(yf))], 1)], 1,
    )  # fmt: skip
    mf = dr.flow_px[fi, fj].astype(np.float64) / ppm
    sf = (sig[fi, fj] / stretch[fi, fj]).astype(np.float64)
    n = dr.normal_dir[ei, ej].astype(np.float64) if len(ei) else np.zeros((0, 2))
    Ae = np.stack(
        [np.stack([ye[:, 0], ye[:, 1], np.ones(len(ye)), np.zeros(len(ye))], 1),
         np.stack([ye[:, 1], -ye[:, 0], np.zeros(len(ye)), np.ones(len(ye))], 1)], 1,
    )  # fmt: skip
    Ae = np.einsum("nk,nkp->np", n, Ae)
    se_n = (dr.shift_px[ei, ej].astype(np.float64) * n).sum(axis=1) / ppm
    se = (sig[ei, ej] / stretch[ei, ej]).astype(np.float64)
    A = np.concatenate([Af.reshape(-1, 4), Ae]) / np.concatenate([np.repeat(sf, 2), se])[:, None]
    b = np.concatenate([mf.ravel(), se_n]) / np.concatenate([np.repeat(sf, 2), se])
    keep = np.ones(len(b), bool)
    for _ in range(3):
        sol, *_ = np.linalg.lstsq(A[keep], b[keep], rcond=None)
        r = np.abs(A @ sol - b)
        keep = r <= max(3.0 * float(np.median(r[keep])), 1e-6)
    AtA = A[keep].T @ A[keep]
    if np.linalg.cond(AtA) > 1e12:
        return out
    dof = max(int(keep.sum()) - 4, 1)
    chi2 = float((r[keep] ** 2).sum()) / dof
    samples_per_window = max(1.0, area / stride**2)
    cov = np.linalg.inv(AtA) * max(chi2, 1.0) * samples_per_window
    u, v, tx, ty = sol
    M = np.array([[1.0 - u, -v], [v, 1.0 - u]])
    Minv = np.linalg.inv(M)
    d = Minv @ np.array([tx, ty])
    cov_d = Minv @ cov[2:, 2:] @ Minv.T
    model_f = np.einsum("nkp,p->nk", Af, sol)
    model_e = np.einsum("nkp,p->nk", np.stack([
        np.stack([ye[:, 0], ye[:, 1], np.ones(len(ye)), np.zeros(len(ye))], 1),
        np.stack([ye[:, 1], -ye[:, 0], np.zeros(len(ye)), np.ones(len(ye))], 1)], 1), sol)  # fmt: skip
    # an edge pixel's vector: the fit's, with the component across the edge as measured
    vec_e = model_e + (se_n - (model_e * n).sum(axis=1))[:, None] * n
    res_f = np.linalg.norm(mf - model_f, axis=1)
    res_e = np.abs(se_n - (model_e * n).sum(axis=1))
    kf = keep[: 2 * len(fi)].reshape(-1, 2).all(axis=1)
    ke = keep[2 * len(fi) :]
    out["film"] = {
        "offset_mm": d.tolist(),
        "rotation_deg": float(np.degrees(np.arctan2(M[1, 0], M[0, 0]))),
        "scale_pct": float((1.0 / np.sqrt(np.linalg.det(M)) - 1.0) * 100.0),
        "rms_mm": float(np.sqrt(np.mean(np.concatenate([res_f[kf], res_e[ke]]) ** 2))),
        "samples": int(kf.sum() + ke.sum()),
    }
    out["uncertainty_mm"] = float(np.sqrt(np.linalg.eigvalsh(cov_d).max()))
    out["shift_mm"] = np.concatenate(
        [np.linalg.norm(mf, axis=1) * stretch[fi, fj], np.linalg.norm(vec_e, axis=1) * stretch[ei, ej]]
    )
    return out
