"""The eight Nelson rules, each a pure function over a standardized series.

Every rule takes ``z``, the series standardized by the chart's centre line and sigma
(``z = (x - centre) / sigma``; NaN where a part has no value), and returns a boolean array
``fires`` of the same length: ``fires[i]`` is True when the pattern the rule looks for ends at
point ``i``. :data:`WINDOWS` gives how many points each pattern spans, so the parts that
triggered it are ``i - window + 1 ... i``. A window with a missing point never fires.

Rates given are per point for an in-control normal series with known limits (L. S. Nelson,
"The Shewhart control chart: tests for special causes", J. Quality Technology 16 (1984)).
"""

from __future__ import annotations

import numpy as np

NAMES = {
    1: "one point beyond 3 sigma",
    2: "nine points in a row on one side of the centre line",
    3: "six points in a row steadily increasing or decreasing",
    4: "fourteen points in a row alternating up and down",
    5: "two of three points in a row beyond 2 sigma on one side",
    6: "four of five points in a row beyond 1 sigma on one side",
    7: "fifteen points in a row within 1 sigma",
    8: "eight points in a row beyond 1 sigma, on both sides",
}
WINDOWS = {1: 1, 2: 9, 3: 6, 4: 14, 5: 3, 6: 5, 7: 15, 8: 8}


def _counts(flags: np.ndarray, n: int) -> np.ndarray:
    """How many of each ``n`` consecutive flags are set, one per window (a running sum: linear time)."""
    if len(flags) < n:
        return np.zeros(0, dtype=np.int64)
    c = np.concatenate([[0], np.cumsum(flags, dtype=np.int64)])
    return c[n:] - c[:-n]


def _all(flags: np.ndarray, n: int) -> np.ndarray:
    return _counts(flags, n) == n


def _at_ends(hits: np.ndarray, length: int, n: int) -> np.ndarray:
    """Per-window results placed at each window's last point (False before the first full window)."""
    out = np.zeros(length, dtype=bool)
    out[n - 1 : n - 1 + len(hits)] = hits
    return out


def _finite_windows(z: np.ndarray, n: int) -> np.ndarray:
    return _all(np.isfinite(z), n)


def rule_1(z: np.ndarray) -> np.ndarray:
    """A point more than 3 sigma from the centre line (0.27 %: a large shift, an outlier)."""
    return np.abs(np.nan_to_num(z, nan=0.0)) > 3.0


def rule_2(z: np.ndarray) -> np.ndarray:
    """Nine points in a row on the same side of the centre line (0.39 %: a sustained small shift)."""
    n = WINDOWS[2]
    zz = np.nan_to_num(z, nan=0.0)
    hits = (_all(zz > 0, n) | _all(zz < 0, n)) & _finite_windows(z, n)
    return _at_ends(hits, len(z), n)


def rule_3(z: np.ndarray) -> np.ndarray:
    """Six points in a row steadily increasing or decreasing (0.28 %: a trend, a drift)."""
    n = WINDOWS[3]
    d = np.diff(np.nan_to_num(z, nan=0.0))
    hits = (_all(d > 0, n - 1) | _all(d < 0, n - 1)) & _finite_windows(z, n)
    return _at_ends(hits, len(z), n)


def rule_4(z: np.ndarray) -> np.ndarray:
    """Fourteen points in a row alternating up and down (0.46 %: two alternating sources, over-adjustment)."""
    n = WINDOWS[4]
    s = np.sign(np.diff(np.nan_to_num(z, nan=0.0)))
    flips = (s[1:] * s[:-1]) < 0  # each consecutive pair of steps changes direction
    hits = _all(flips, n - 2) & _finite_windows(z, n)
    return _at_ends(hits, len(z), n)


def _k_of_n_beyond(z: np.ndarray, k: int, n: int, level: float) -> np.ndarray:
    zz = np.nan_to_num(z, nan=0.0)
    return _at_ends((_counts(zz > level, n) >= k) | (_counts(zz < -level, n) >= k), len(z), n)


def rule_5(z: np.ndarray) -> np.ndarray:
    """Two of three points in a row beyond 2 sigma, on the same side (0.31 %: a medium shift)."""
    return _k_of_n_beyond(z, 2, WINDOWS[5], 2.0)


def rule_6(z: np.ndarray) -> np.ndarray:
    """Four of five points in a row beyond 1 sigma, on the same side (0.55 %: a small shift)."""
    return _k_of_n_beyond(z, 4, WINDOWS[6], 1.0)


def rule_7(z: np.ndarray) -> np.ndarray:
    """Fifteen points in a row within 1 sigma, either side (0.33 %: limits too wide, stratified data)."""
    n = WINDOWS[7]
    return _at_ends(_all(np.abs(np.nan_to_num(z, nan=np.inf)) < 1.0, n), len(z), n)


def rule_8(z: np.ndarray) -> np.ndarray:
    """Eight points in a row beyond 1 sigma, with points on both sides (0.01 %: a mixture of two processes)."""
    n = WINDOWS[8]
    zz = np.nan_to_num(z, nan=0.0)
    outside = _all(np.abs(zz) > 1.0, n)
    both = (_counts(zz > 1.0, n) > 0) & (_counts(zz < -1.0, n) > 0)
    return _at_ends(outside & both, len(z), n)


RULES = {1: rule_1, 2: rule_2, 3: rule_3, 4: rule_4, 5: rule_5, 6: rule_6, 7: rule_7, 8: rule_8}
