"""How much a flat layout stretches or shears each triangle."""

from __future__ import annotations

import numpy as np


def flat_to_surface_singular_values(V: np.ndarray, F: np.ndarray, uv: np.ndarray) -> np.ndarray:
    """Singular values of the linear map from each flat triangle to its 3D triangle.

    Parameters
    ----------
    V : (#V, 3) float
        Surface positions (mm).
    F : (#F, 3) int
        Triangles.
    uv : (#V, 2) float
        Flat positions (mm).

    Returns
    -------
    sigma : (#F, 2) float
        ``σ₁ ≥ σ₂``: the largest and smallest ratio of 3D length to flat length over
        all directions in the triangle. A film printed flat and formed onto the part
        is stretched by σ₂ to σ₁; ``σ₁ / σ₂`` is the conformal distortion.
    """
    # J maps flat edge vectors onto surface edge vectors: J M = S with M = [m1 m2]
    # (2x2) and S = [s1 s2] (3x2), so JᵀJ = M⁻ᵀ (SᵀS) M⁻¹ and σ² are its eigenvalues.
    m1 = uv[F[:, 1]] - uv[F[:, 0]]
    m2 = uv[F[:, 2]] - uv[F[:, 0]]
    s1 = V[F[:, 1]] - V[F[:, 0]]
    s2 = V[F[:, 2]] - V[F[:, 0]]
    g11, g12, g22 = np.einsum("ij,ij->i", s1, s1), np.einsum("ij,ij->i", s1, s2), np.einsum("ij,ij->i", s2, s2)
    # M⁻¹ = [[d, -b], [-c, a]] / det for M = [[a, b], [c, d]] = [m1 m2]; written out per
    # entry, T = M⁻ᵀ G M⁻¹ costs a few vector operations instead of batched 2x2 products
    a, c, b, d = m1[:, 0], m1[:, 1], m2[:, 0], m2[:, 1]
    det = a * d - b * c
    p11, p12, p21, p22 = d / det, -b / det, -c / det, a / det  # M⁻¹
    # G M⁻¹, then M⁻ᵀ (G M⁻¹)
    q11, q12 = g11 * p11 + g12 * p21, g11 * p12 + g12 * p22
    q21, q22 = g12 * p11 + g22 * p21, g12 * p12 + g22 * p22
    T00 = p11 * q11 + p21 * q21
    T01 = p11 * q12 + p21 * q22
    T11 = p12 * q12 + p22 * q22
    # eigenvalues of a symmetric 2x2: mean ± sqrt(half-difference² + off-diagonal²)
    mean = 0.5 * (T00 + T11)
    rad = np.hypot(0.5 * (T00 - T11), T01)
    lam = np.stack([mean + rad, np.maximum(mean - rad, 0.0)], axis=1)
    return np.sqrt(lam)


def weighted_quantiles(x: np.ndarray, w: np.ndarray, q: np.ndarray) -> np.ndarray:
    """Quantiles of ``x`` where each sample counts with weight ``w``.

    Parameters
    ----------
    x, w : (n,) float
        Samples and non-negative weights (for per-face values: face areas).
    q : (k,) float
        Quantiles in [0, 1].

    Returns
    -------
    (k,) float
        The smallest ``x`` whose cumulative weight share reaches each ``q``.
    """
    order = np.argsort(x, kind="stable")
    cw = np.cumsum(w[order])
    idx = np.searchsorted(cw, np.asarray(q) * cw[-1], side="left")
    return x[order][np.minimum(idx, len(x) - 1)]
