"""The part's colour: each print pixel from its squarest photo, each sample weighted by what it stands for."""

from __future__ import annotations

import numpy as np
import pytest

from workbench.validate.part_colour import fused_colour


def _photo(facing: np.ndarray, value: float, step: int) -> dict:
    """A photo's maps: ``value`` ΔE00 at every ``step``-th scored pixel (an even subsample), seen at ``facing``."""
    de = np.full(facing.shape, np.nan, np.float32)
    flat = de.reshape(-1)
    seen = np.flatnonzero(np.isfinite(facing))
    flat[seen[::step]] = value
    return {"delta_e00": de, "facing": facing.astype(np.float32), "weight": float(step)}


def test_each_pixel_from_the_squarest_photo_and_each_sample_weighted_by_its_share():
    """Photo A sees the left half squarely (cos 0.9) and the right half obliquely (0.3), at 1 ΔE00;
    photo B sees everything at cos 0.5, at 5 ΔE00, every second pixel sampled. The left half is A's,
    the right half B's: a mean of 3 over equal areas, whatever the sampling."""
    rows, cols = 40, 60
    fa = np.full((rows, cols), 0.3)
    fa[:, : cols // 2] = 0.9
    fb = np.full((rows, cols), 0.5)
    summary, fused = fused_colour([_photo(fa, 1.0, 1), _photo(fb, 5.0, 2)], ["a.jpg", "b.jpg"], 2.9)
    assert summary["delta_e00"]["mean"] == pytest.approx(3.0, abs=1e-6)
    assert summary["delta_e00"]["pixels"] == rows * cols
    assert summary["verdict"] == "FAIL"
    assert summary["decided_by_photo"] == {"a.jpg": {"mean": 1.0, "share": 0.5}, "b.jpg": {"mean": 5.0, "share": 0.5}}
    assert np.all(fused[:, : cols // 2] == 1.0)
    assert np.nanmax(fused[:, cols // 2 :]) == 5.0
    # the median and p95 by weight: half the area at 1, half at 5
    assert summary["delta_e00"]["median"] == 1.0 and summary["delta_e00"]["p95"] == 5.0


def test_a_photo_that_saw_less_squarely_everywhere_decides_nothing_and_one_without_colour_is_left_out():
    rows, cols = 20, 30
    good = _photo(np.full((rows, cols), 0.95), 1.2, 3)
    grazing = _photo(np.full((rows, cols), 0.2), 7.2, 1)
    summary, _ = fused_colour([grazing, None, good], ["grazing.png", "no chart.png", "front.png"], 3.0)
    assert summary["verdict"] == "PASS" and summary["delta_e00"]["mean"] == pytest.approx(1.2, abs=1e-6)
    assert list(summary["decided_by_photo"]) == ["front.png"]
    assert fused_colour([None, None], ["a", "b"], 3.0) == (None, None)


def test_where_only_the_oblique_photo_scores_it_counts():
    """The squarest photo decides only where it scores the pixel: elsewhere the oblique one's samples count."""
    rows, cols = 10, 10
    fa = np.full((rows, cols), np.nan)
    fa[:5] = 0.9
    summary, _ = fused_colour([_photo(fa, 1.0, 1), _photo(np.full((rows, cols), 0.4), 4.0, 1)], ["a", "b"], 3.0)
    assert summary["delta_e00"]["mean"] == pytest.approx(2.5, abs=1e-6)
    assert summary["decided_by_photo"]["b"]["share"] == 0.5
