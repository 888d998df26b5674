"""Control limits and alarms: individuals and moving-range (I-MR) charts, the u-chart of defect counts.

Limits come from a baseline, the first parts recorded: centre line the baseline's mean, sigma
``MRbar / d2`` (d2 = 1.128 for moving ranges of two), limits ±3 sigma; the moving-range chart's
upper limit ``D4 MRbar`` (D4 = 3.267). Defect counts are a u-chart: a count of nonconformities
per inspected part (one part a point), not a p-chart, which charts the share of defective
items in subgroups of many (with one part a point its share is 0 or 1, and three defects count
as one). Its upper limit is the Poisson probability limit, the smallest count as unlikely as a
point beyond 3 sigma (one-sided 0.135 %): with the few defects of a good process the normal
limit ``u + 3 sqrt(u)`` flags two defects where one in fifty parts has them by chance.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from workbench.trend import nelson

D2 = 1.128
D4 = 3.267
SIGMA_LIMIT = 3.0
# a count as unlikely as one point beyond +3 sigma of a normal distribution
POISSON_TAIL = 0.00135
# parts in a drift's least-squares trend: eight points give the slope six degrees of freedom, and
# a drift four parts old already fills half of them (a longer window lags a fresh drift: with ten,
# the 0.025 mm-per-part drift of a 0.03 mm process was caught a part later)
WINDOW = 8


@dataclass(frozen=True)
class IMRLimits:
    """An I-MR chart's limits (the figure's units)."""

    centre: float
    sigma: float
    lcl: float
    ucl: float
    mr_centre: float
    mr_ucl: float


@dataclass(frozen=True)
class ULimits:
    """A u-chart's limits, one part a point: defects per part."""

    centre: float
    ucl: float  # a part with more defects than this is beyond the limit


@dataclass(frozen=True)
class Tolerance:
    """What a figure may reach before a part fails: ``lo``/``hi`` (None: no bound on that side)."""

    lo: float | None
    hi: float | None


@dataclass(frozen=True)
class AlarmOptions:
    """Which rules raise alarms, and how a drift is projected to the tolerance.

    rules : the Nelson rules applied to individuals charts (numbers 1-8)
    window : parts in the least-squares trend (the last ones up to the alarm's point)
    horizon : an alarm is raised when the trend reaches the tolerance within this many parts
    min_t : the trend's slope must be this many of its standard errors from zero
    every_signal : every rule's firing is an alarm, whatever the tolerance (the classical chart)
    """

    rules: tuple[int, ...] = (1, 2, 3, 4, 5, 6, 7, 8)
    window: int = WINDOW
    horizon: float = 25.0
    min_t: float = 3.0
    every_signal: bool = False


def imr_limits(baseline: np.ndarray) -> IMRLimits:
    """I-MR limits from ``baseline`` (at least two values, in recording order)."""
    x = np.asarray(baseline, dtype=np.float64)
    mr_bar = float(np.abs(np.diff(x)).mean())
    centre = float(x.mean())
    sigma = mr_bar / D2
    return IMRLimits(centre, sigma, centre - SIGMA_LIMIT * sigma, centre + SIGMA_LIMIT * sigma, mr_bar, D4 * mr_bar)


def u_limits(baseline: np.ndarray) -> ULimits:
    """u-chart limits from the baseline's defect counts per part.

    A baseline without a defect has no rate to scale by: it counts as half a defect over its
    parts (the rate no smaller than a count of zero makes plausible), so one defect is not
    beyond the limit by construction.
    """
    counts = np.asarray(baseline, dtype=np.float64)
    u = max(float(counts.mean()), 0.5 / len(counts))
    return ULimits(u, float(poisson_limit(u)))


def poisson_limit(mean: float, tail: float = POISSON_TAIL) -> int:
    """The largest count ``c`` with P(X > c) > ``tail`` for X ~ Poisson(``mean``): more than ``c`` is beyond.

    (Summed term by term, as scipy's ``poisson.isf(tail, mean)`` gives it, without loading scipy.stats:
    half a second of the command's two.)
    """
    term = math.exp(-mean)
    below = term  # P(X <= c)
    c = 0
    while 1.0 - below > tail:
        c += 1
        term *= mean / c
        below += term
    return c


def standardized(x: np.ndarray, limits: IMRLimits) -> np.ndarray:
    """``(x - centre) / sigma``; a baseline without scatter (sigma 0) gives ±inf off the centre, 0 on it."""
    with np.errstate(divide="ignore", invalid="ignore"):
        z = (x - limits.centre) / limits.sigma
    return np.where(x == limits.centre, 0.0, z)


def rolling_trend(x: np.ndarray, window: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Least-squares line over the last ``window`` points at each point (NaN before the first full window).

    Returns
    -------
    slope : per point, figure units per part
    now : the line's value at the point itself
    t : the slope over its standard error (inf where the points lie on the line)
    """
    n = len(x)
    slope = np.full(n, np.nan)
    now = np.full(n, np.nan)
    t = np.full(n, np.nan)
    if n < window or window < 3:
        return slope, now, t
    tc = np.arange(window, dtype=np.float64) - (window - 1) / 2
    sxx = float((tc**2).sum())
    # sums over each window by cumulative sums (vectorised over 100,000 parts), of the values less
    # their mean: the residual sum of squares is a difference of sums, which the offset would swamp
    shift = float(np.mean(x))
    x = x - shift
    c1 = np.concatenate([[0.0], np.cumsum(x)])
    c2 = np.concatenate([[0.0], np.cumsum(x * x)])
    sy = c1[window:] - c1[:-window]
    syy = c2[window:] - c2[:-window]
    sty = np.convolve(x, tc[::-1], mode="valid")
    b = sty / sxx
    mean = sy / window
    ss_res = np.maximum(syy - window * mean**2 - b * b * sxx, 0.0)
    se = np.sqrt(ss_res / (window - 2) / sxx)
    with np.errstate(divide="ignore", invalid="ignore"):
        tt = np.where(se > 0, np.abs(b) / se, np.inf)
    slope[window - 1 :] = b
    now[window - 1 :] = mean + b * tc[-1] + shift
    t[window - 1 :] = tt
    return slope, now, t


def parts_to_tolerance(slope: np.ndarray, now: np.ndarray, tol: Tolerance) -> np.ndarray:
    """Parts until the trend line reaches the tolerance (0 when beyond it already; inf when heading away).

    Parameters
    ----------
    slope : figure units per part
    now : the line's value at the current part
    tol : the bounds
    """
    out = np.full(len(slope), np.inf)
    with np.errstate(divide="ignore", invalid="ignore"):
        if tol.hi is not None:
            up = slope > 0
            out = np.where(up, np.maximum((tol.hi - now) / slope, 0.0), out)
            out = np.where(now >= tol.hi, 0.0, out)
        if tol.lo is not None:
            down = slope < 0
            out = np.where(down, np.maximum((tol.lo - now) / slope, 0.0), out)
            out = np.where(now <= tol.lo, 0.0, out)
    return np.where(np.isfinite(slope), out, np.inf)


def firings(fires: np.ndarray, window: int, start: int, shown: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Each run of consecutive firings from index ``start`` on that completes first at a shown point.

    Returns
    -------
    first : where each run's pattern first completed (index into the series)
    lo, hi : the first and the last index of the points its windows span
    """
    fires = fires.copy()
    fires[:start] = False
    idx = np.flatnonzero(fires)
    if not len(idx):
        empty = np.zeros(0, dtype=np.int64)
        return empty, empty, empty
    breaks = np.flatnonzero(np.diff(idx) > 1)
    first = np.concatenate([[idx[0]], idx[breaks + 1]])
    last = np.concatenate([idx[breaks], [idx[-1]]])
    keep = shown[first]
    first, last = first[keep], last[keep]
    return first, np.maximum(first - window + 1, 0), last


def rule_fires(z: np.ndarray, rules: tuple[int, ...]) -> dict[int, np.ndarray]:
    """Each rule's firings over the standardized series."""
    return {r: nelson.RULES[r](z) for r in rules}
