"""A slid region's size and place from the flow (find_defects): exact against a drawn disc."""

from __future__ import annotations

import numpy as np
import pytest

from workbench.validate.dense.defects import find_defects
from workbench.validate.print_warp import PrintGrid

PX_PER_MM = 8.0
WIN = 3.0  # the flow's window, grid px (TENSOR_SIGMA_PX)


def _grid(shape: tuple[int, int]) -> PrintGrid:
    h, w = shape
    zeros = np.zeros((h, w), np.float32)
    return PrintGrid(
        X=np.zeros((h, w, 3)), owner=np.zeros((h, w), np.int32), px_per_mm=PX_PER_MM, factor=1,
        surface_per_print=zeros + 1.0, reference=np.zeros((h, w, 3), np.uint8), face=np.zeros((h, w), np.int32),
    )  # fmt: skip


def _found(evidence: np.ndarray, extent: np.ndarray, core: np.ndarray) -> list[dict]:
    """find_defects on a slide of 0.5 mm measured (z 10) over ``evidence``, every pixel scored."""
    shape = evidence.shape
    zeros = np.zeros(shape, bool)
    shift = np.where(evidence, 0.5, np.nan).astype(np.float32)
    z = np.where(evidence, 10.0, np.nan).astype(np.float32)
    _, found = find_defects(
        evidence, zeros, zeros, shift, np.zeros(shape, np.float32), _grid(shape), None, evidence, z, None,
        WIN, extent, np.ones(shape, bool), core,
    )  # fmt: skip
    return found


def _disc(shape, centre_mm, radius_mm) -> np.ndarray:
    ii, jj = np.mgrid[: shape[0], : shape[1]]
    x, y = (jj + 0.5) / PX_PER_MM, (ii + 0.5) / PX_PER_MM
    return np.hypot(x - centre_mm[0], y - centre_mm[1]) <= radius_mm


@pytest.mark.parametrize("textured", ["whole", "right third"])
def test_a_bubble_is_sized_over_all_its_evidence(textured):
    # a bubble of 3 mm radius slid 0.5 mm; the flow's own vector is 0.5 mm over it (DIS spreads
    # it over plain patches) and 0 beyond. Its pixels measure the slide on their own only where
    # the print has texture (``core``); a window's slide, eroded to stay inside what it
    # measured, supplies evidence over the rest of it. Both kinds of evidence lie inside the
    # bubble, so the region is the bubble whichever part of it has texture: on a print textured
    # only over the bubble's right third, the hull of the pixels' own evidence alone left the
    # region at 14.8 mm² of 28.3 and its centre 1.2 mm to the right
    shape, centre, r = (96, 96), (6.0, 6.0), 3.0
    disc = _disc(shape, centre, r)
    x = (np.mgrid[: shape[0], : shape[1]][1] + 0.5) / PX_PER_MM
    core = disc & (x >= centre[0] + r / 3) if textured != "whole" else disc
    evidence = _disc(shape, centre, r - 2 * WIN / PX_PER_MM) | core  # the windows' evidence, eroded
    found = _found(evidence, np.where(disc, 0.5, 0.0).astype(np.float32), core)
    assert len(found) == 1 and found[0]["kind"] == "shift"
    d = found[0]
    assert d["area_mm2"] == pytest.approx(np.pi * r * r, rel=0.03)
    assert np.hypot(d["centre_mm"][0] - centre[0], d["centre_mm"][1] - centre[1]) <= 0.5 / PX_PER_MM


def test_a_bubble_does_not_grow_over_the_flow_beyond_its_evidence():
    # the flow's own vector also 0.5 mm over a plain band beside the bubble (DIS drifting over a
    # soft background): the region stops at its evidence's reach (3 windows), not at the band's end
    shape, centre, r = (96, 200), (6.0, 6.0), 3.0
    disc = _disc(shape, centre, r)
    ii, jj = np.mgrid[: shape[0], : shape[1]]
    band = (np.abs((ii + 0.5) / PX_PER_MM - centre[1]) <= 1.0) & ((jj + 0.5) / PX_PER_MM >= centre[0])
    (d,) = _found(disc, np.where(disc | band, 0.5, 0.0).astype(np.float32), disc)
    reach_mm = np.ceil(3 * WIN) / PX_PER_MM
    assert d["bbox_mm"][2] <= centre[0] + r + reach_mm + 1 / PX_PER_MM
    assert d["bbox_mm"][2] >= centre[0] + r + reach_mm - 1 / PX_PER_MM
