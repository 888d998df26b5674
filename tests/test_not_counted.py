"""Every region taken for light says which test took it (validation.json's not_counted)."""

from __future__ import annotations

import numpy as np

from workbench.validate.dense import LIGHT_RULES, not_counted_regions

PPM = 10.0  # grid px per print mm


def test_each_region_names_the_test_that_took_most_of_it():
    H, W = 200, 300
    light = np.zeros((H, W), bool)
    light[20:60, 30:80] = True  # 40 x 50 px: 20 mm², centre (5.5, 4.0) mm
    light[100:120, 200:210] = True  # 20 x 10 px: 2 mm²
    light[150:152, 10:12] = True  # 0.04 mm²: below the listed size
    why = {"beyond_film": np.zeros((H, W), bool), "photometric": np.zeros((H, W), bool)}
    why["beyond_film"][20:30, 30:80] = True  # a quarter of the first region clipped ...
    why["photometric"][30:60, 30:80] = True  # ... the rest taken by photometric
    why["beyond_film"][100:120, 200:210] = True
    out = not_counted_regions(why, light, PPM, 1.0)
    assert [x["area_mm2"] for x in out] == [20.0, 2.0]
    assert out[0]["centre_mm"] == [5.5, 4.0]
    assert out[0]["decided_by"] == {"rule": "photometric", "words": LIGHT_RULES["photometric"]}
    assert out[1]["decided_by"]["rule"] == "beyond_film"


def test_a_region_no_test_took_is_not_listed_and_the_list_is_capped():
    H, W = 100, 100
    light = np.zeros((H, W), bool)
    light[::4, ::4] = True  # 625 regions of one pixel
    why = {"along_fold": light.copy()}
    assert not_counted_regions({"along_fold": np.zeros_like(light)}, light, 1.0, 0.5) == []
    out = not_counted_regions(why, light, 1.0, 0.5)
    assert len(out) == 50 and all(x["decided_by"]["rule"] == "along_fold" for x in out)


def test_a_region_half_in_a_mask_is_mostly_in_it():
    from workbench.validate.dense import regions_mostly_in

    regions = np.zeros((20, 40), bool)
    regions[5:10, 2:12] = True  # 50 px, 30 of them in the mask
    regions[5:10, 20:30] = True  # 50 px, 20 of them in the mask
    mask = np.zeros_like(regions)
    mask[5:10, 2:8] = True
    mask[5:10, 20:24] = True
    got = regions_mostly_in(regions, mask)
    assert got[5:10, 2:12].all() and not got[5:10, 20:30].any()
