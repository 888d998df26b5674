"""Per-pixel reductions over the three colour channels."""

from __future__ import annotations

import numpy as np


def _cmax(a: np.ndarray) -> np.ndarray:
    """Largest of the three channels (numpy's reduction along a short last axis is several times slower)."""
    return np.maximum(np.maximum(a[..., 0], a[..., 1]), a[..., 2])


def _cmin(a: np.ndarray) -> np.ndarray:
    """Smallest of the three channels."""
    return np.minimum(np.minimum(a[..., 0], a[..., 1]), a[..., 2])
