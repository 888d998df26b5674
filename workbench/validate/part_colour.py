"""The part's colour: each print pixel judged in the photo that sees it most squarely."""

from __future__ import annotations

from pathlib import Path

import numpy as np


def take_colour_maps(entries: list[dict]) -> list[dict | None]:
    """Take each photo's colour maps out of its entry (``colour_maps``: ``delta_e00``, ``facing``); None where none."""
    return [e.pop("colour_maps", None) for e in entries]


def fused_colour(
    maps: list[dict | None], photos: list[str], max_delta_e: float
) -> tuple[dict | None, np.ndarray | None]:
    """The print's colour difference over the part's photos: at each pixel, the squarest view's.

    The print has one colour; each photo measures it through its own light and its own angle.
    A film's surface reflects the room as a dielectric does (Fresnel, refractive index about
    1.5): 4 % of the light at normal incidence, 5 % at 45°, 9 % at 60°, 17 % at 70°, 39 % at
    80°. That reflection (the room, a lamp's sheen) adds to the ink's light and washes it out,
    and a surface seen obliquely is sampled more coarsely too: of the photos that score a print
    pixel, the one that sees it at the smallest angle from its normal measures the ink most
    truly, and the part takes that photo's samples there (Mitsuba's glossy lily, photographed
    from 50° and 20° elevation: the first decided 81 % of the print it measured, at a mean of
    2.39 ΔE00, the grazing one the rest, at 3.02). Each photo compared an even subsample of its
    pixels: a sample stands for its photo's ``weight`` pixels, and the figures are weighted so.

    Parameters
    ----------
    maps : list of dict or None
        Per photo, ``delta_e00`` (rows, cols) float (the ΔE00 its verdict judges at its samples,
        NaN elsewhere), ``facing`` (rows, cols) float (the cosine of the viewing angle at every
        pixel it scores, NaN elsewhere) and ``weight`` (compared pixels per sample); None: the
        photo measured no colour.
    photos : list of str
        The photos' names, in the same order.
    max_delta_e : float
        The largest accepted mean ΔE00.

    Returns
    -------
    summary : dict or None
        ``delta_e00`` {mean, median, p95, max, pixels} over the kept samples (weighted; pixels:
        the compared pixels they stand for), ``verdict`` (FAIL when the mean exceeds
        ``max_delta_e``), ``decided_by_photo`` {photo: {share, mean}}: the share of those pixels
        each photo saw most squarely and its mean ΔE00 there, and ``words``. None when no photo
        measured colour.
    fused : (rows, cols) float32 or None
        The kept samples' ΔE00 (NaN elsewhere), for a picture.
    """
    have = [(k, m) for k, m in enumerate(maps) if m is not None]
    if not have:
        return None, None
    facing = np.stack([np.nan_to_num(m["facing"], nan=-np.inf) for _, m in have])
    # (the first photo wins a tie: the same inputs give the same choice)
    best = np.argmax(facing, axis=0)
    fused = np.full(facing.shape[1:], np.nan, np.float32)
    values, weights, decided = [], [], {}
    for j, (k, m) in enumerate(have):
        kept = np.isfinite(m["delta_e00"]) & (best == j)
        v = m["delta_e00"][kept].astype(np.float64)
        fused[kept] = v
        values.append(v)
        weights.append(np.full(len(v), m["weight"]))
        if len(v):
            decided[photos[k]] = {"pixels": float(m["weight"] * len(v)), "mean": round(float(v.mean()), 3)}
    v, w = np.concatenate(values), np.concatenate(weights)
    if len(v) == 0:
        return None, None
    total = float(w.sum())
    for d in decided.values():
        d["share"] = round(d.pop("pixels") / total, 4)
    order = np.argsort(v, kind="stable")
    # a weighted percentile: the smallest value whose cumulative weight reaches the share
    cum = np.cumsum(w[order]) / total

    def pct(q: float) -> float:
        return round(float(v[order][min(np.searchsorted(cum, q), len(v) - 1)]), 3)

    mean = round(float((v * w).sum() / total), 3)
    verdict = "FAIL" if mean > max_delta_e else "PASS"
    words = (
        f"part colour mean ΔE00 {mean:.2f} {'>' if verdict == 'FAIL' else '<='} {max_delta_e:g} "
        f"(each print pixel from the photo that sees it most squarely, of {len(have)} that measured colour)"
    )
    summary = {
        "delta_e00": {
            "mean": mean,
            "median": pct(0.5),
            "p95": pct(0.95),
            "max": round(float(v.max()), 3),
            "pixels": int(round(total)),
        },
        "verdict": verdict,
        "decided_by_photo": decided,
        "words": words,
    }
    return summary, fused


def photo_names(entries: list[dict]) -> list[str]:
    """The photos' file names, as the part's summary names them."""
    return [Path(e["photo"]).name for e in entries]
