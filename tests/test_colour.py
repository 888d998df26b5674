"""Colour QA (workbench.validate.colour) on `workbench render` photos with known colour truth.

The default job designed once; photos rendered from a camera that sees the part and the
fixture's ColorChecker; the pure module called directly with the photo's pose (found from
the markers, as validate finds it), the print grid and the photo warped onto it.
"""

from __future__ import annotations

import numpy as np
import pytest
from conftest import ROOT

from workbench.validate import colour as col
from workbench.validate import print_warp

SHIFT = (-6.0, 6.0, 8.0)  # the wrong ink: L* -6, a* +6, b* +8
WARM = (1.0, 0.9, 0.72)  # a warm light (linear gains; no channel clipped)
COOL = (0.8, 0.92, 1.0)


def test_delta_e00_and_conversions_match_colour_science():
    import colour

    rng = np.random.default_rng(1)
    a = np.column_stack([rng.uniform(0, 100, 5000), rng.uniform(-90, 90, 5000), rng.uniform(-90, 90, 5000)])
    b = a + rng.normal(0, 6, a.shape)
    np.testing.assert_allclose(col.delta_e00(a, b), colour.delta_E(a, b, method="CIE 2000"), atol=1e-9)
    # Sharma, Wu, Dalal (2005), table 1, pairs 1, 7 and 17: 2.0425, 2.3669, 27.1492
    sharma = np.array([[50, 2.6772, -79.7751], [50, 0, 0], [50, 2.5, 0]])
    other = np.array([[50, 0, -82.7485], [50, -1, 2], [73, 25, -18]])
    np.testing.assert_allclose(col.delta_e00(sharma, other), [2.0425, 2.3669, 27.1492], atol=1e-4)
    rgb = rng.random((1000, 3))
    want = colour.XYZ_to_Lab(
        colour.RGB_to_XYZ(rgb, "sRGB", chromatic_adaptation_transform="Bradford", illuminant=col.D50_XY),
        col.D50_XY,
    )
    np.testing.assert_allclose(col.linear_srgb_to_lab(rgb), want, atol=0.02)
    np.testing.assert_allclose(col.linear_srgb_to_lab([1.0, 1.0, 1.0]), [100, 0, 0], atol=2e-3)
    np.testing.assert_allclose(col.lab_to_linear_srgb(col.linear_srgb_to_lab(rgb)), rgb, atol=1e-9)


@pytest.fixture(scope="module")
def scene(tmp_path_factory):
    """The default job's design, its print grid, and a camera seeing the part and the chart."""
    from workbench.camera import Camera
    from workbench.cli import main
    from workbench.design_dir import Design

    out = tmp_path_factory.mktemp("colour") / "design"
    assert main(["design", str(ROOT / "fixtures" / "default" / "job.toml"), "--out", str(out), "-q"]) == 0
    d = Design(out)
    p = d.info["print"]
    grid = print_warp.print_grid(d.V, d.F, d.flat, p["height_mm"], d.rgb, p["dpi"], d.owner)
    cam = Camera.look_at([0, -330, 380], [0, -45, 0], [0, 1, 0], 45, 1600, 1200)
    return d, grid, cam


def photo_of(scene, **imperfections):
    from workbench.render.imperfections import Imperfections
    from workbench.render.photo import render_photo

    d, _, cam = scene
    imp = Imperfections(**imperfections)
    return render_photo(d.scene(imp, True), cam, imp)


def measure(scene, photo, chart="fixture", pose=True, **kw):
    """The colour entry of a photo as validate's hook would compute it: pose from the markers, warp, measure."""
    import cv2

    from workbench.validate.pose import estimate_pose

    d, grid, cam = scene
    if pose:
        cam = estimate_pose(cv2.cvtColor(photo, cv2.COLOR_RGB2GRAY), d.fixture, cam.K, cam.dist).camera
    depth = print_warp.photo_buffers(cam, d.V, d.F)[1]
    pw = print_warp.warp_to_print(photo, cam, grid, d.V, d.F, depth)
    warped, state = pw.warped, pw.state
    names = [v["name"] for v in d.info["views"]]
    regions = {f"view {n}": grid.owner == k for k, n in enumerate(names)}
    return col.measure_colour(
        photo,
        cam,
        d.fixture.get("colour_chart") if chart == "fixture" else chart,
        warped,
        state == print_warp.FULL,
        grid.reference,
        regions=regions,
        part_depth=depth,
        surface_mm=grid.X,
        **kw,
    )


def truth(scene, de_map, shift):
    """The true ΔE00 of a shifted print on the pixels the measurement compared: mean and p95."""
    from workbench.render.photo import shift_colours

    ref = scene[1].reference
    lab = col.linear_srgb_to_lab(col.srgb_decode(ref / 255.0))
    shifted = col.linear_srgb_to_lab(col.srgb_decode(shift_colours(ref, shift) / 255.0))
    de = col.delta_e00(lab, shifted)[np.isfinite(de_map)]
    return de.mean(), np.percentile(de, 95)


def test_perfect_print_and_a_drifted_one_under_even_light(scene):
    perfect, de_map = measure(scene, photo_of(scene, blur_px=1.0, noise=3.0))
    assert perfect["measured"], perfect
    # the bar: a perfect print at most 1.0 mean ΔE00 (measured: about 0.5)
    assert perfect["delta_e00"]["mean"] <= 1.0 and perfect["delta_e00"]["p95"] <= 2.0
    # the chart fit's own residual: the render's 8-bit patches (and cyan, out of sRGB) keep about 0.35
    assert perfect["chart_fit_delta_e00"] <= 0.6 and perfect["chart"]["patches_used"] == 24
    assert perfect["delta_e00"]["pixels"] > 20_000
    assert set(perfect["regions"]) == {"view logo", "view front"}
    # the front's large squares; the logo's small ones, 0.26 photo px per print px here, see the blur
    # of their neighbours (a mean of about 2.7 with 1 px of blur: a finer photo is needed there)
    assert perfect["regions"]["view front"]["mean"] <= 1.0
    drifted, de_map = measure(scene, photo_of(scene, blur_px=1.0, noise=3.0, colour_shift_lab=SHIFT))
    mean, p95 = truth(scene, de_map, SHIFT)
    assert mean > 5.0  # a drift the verdict must catch (FAIL at a 3.0 mean)
    assert abs(drifted["delta_e00"]["mean"] - mean) <= 1.0 and abs(drifted["delta_e00"]["p95"] - p95) <= 1.0
    assert drifted["lightness"]["mean_delta_l"] == pytest.approx(SHIFT[0], abs=1.0)
    assert drifted["chart_fit_delta_e00"] == pytest.approx(perfect["chart_fit_delta_e00"], abs=0.1)


@pytest.mark.parametrize("light", [WARM, pytest.param(COOL, marks=pytest.mark.slow)], ids=["warm", "cool"])
def test_a_coloured_light_changes_neither(scene, light):
    perfect, _ = measure(scene, photo_of(scene, white_balance=light))
    assert perfect["measured"] and perfect["delta_e00"]["mean"] <= 1.0, perfect
    drifted, de_map = measure(scene, photo_of(scene, white_balance=light, colour_shift_lab=SHIFT))
    mean, _ = truth(scene, de_map, SHIFT)
    assert abs(drifted["delta_e00"]["mean"] - mean) <= 1.0


def test_directional_light_says_what_is_lightness(scene):
    """Shading moves L*: the figures say how much of the difference is lightness, which the chart cannot separate."""
    shaded, _ = measure(scene, photo_of(scene, shading=True))
    assert shaded["measured"]
    assert shaded["delta_e00"]["mean"] > 1.5  # shading on the curved part: counted as difference ...
    assert shaded["delta_e00_chromatic"]["mean"] <= 1.0  # ... but it is lightness, not hue or chroma
    assert shaded["lightness"]["mean_abs_delta_l"] > 2.0


def test_soft_proof_through_the_output_profile(scene):
    """A press that prints what the profile says: its photo matches the proof; the sRGB design itself does not."""
    from workbench.printing.icc import DEFAULT_CMYK_PROFILE

    profile = DEFAULT_CMYK_PROFILE.read_bytes()
    d, grid, _ = scene
    pressed = col.proof_srgb(d.rgb, profile)  # the print as the press reproduces it
    orig = d.rgb
    try:
        d.rgb = pressed
        photo = photo_of(scene)
    finally:
        d.rgb = orig
    res, _ = measure(scene, photo, output_profile=profile)
    assert res["measured"] and res["soft_proof"] == "output profile"
    assert res["delta_e00"]["mean"] <= 1.0, res["delta_e00"]
    vs_design, _ = measure(scene, photo)
    assert vs_design["delta_e00"]["mean"] > res["delta_e00"]["mean"] + 1.0  # out of the press's gamut


def test_not_measured_and_why(scene):
    d, grid, cam = scene
    photo = photo_of(scene)
    res, m = measure(scene, photo, chart=None)
    assert not res["measured"] and res["reason"].startswith("colour not measured: the fixture has no colour chart")
    assert m is None
    # the chart's patches where the pose puts them, for painting a highlight or a shadow on them
    sample = col.sample_chart(photo, cam, d.fixture["colour_chart"])
    lo = np.floor(sample.quads.reshape(-1, 2).min(axis=0)).astype(int) - 15
    hi = np.ceil(sample.quads.reshape(-1, 2).max(axis=0)).astype(int) + 15
    lit = photo.copy()
    lit[lo[1] : hi[1], lo[0] : (lo[0] + hi[0]) // 2] = 255  # a highlight over half the chart
    res, _ = measure(scene, lit)
    assert not res["measured"] and "highlight" in res["reason"], res
    dark = photo.copy()
    dark[lo[1] : hi[1], lo[0] : hi[0]] = (dark[lo[1] : hi[1], lo[0] : hi[0]] * 0.12).astype(np.uint8)
    res, _ = measure(scene, dark)
    assert not res["measured"] and "shadow" in res["reason"], res
    uneven = photo.copy()
    band = uneven[lo[1] : hi[1], lo[0] : hi[0]].astype(np.float64)
    band *= np.linspace(0.45, 1.0, band.shape[1])[None, :, None]  # light falling off across the chart
    uneven[lo[1] : hi[1], lo[0] : hi[0]] = band.astype(np.uint8)
    res, _ = measure(scene, uneven)
    assert not res["measured"] and "the chart fit does not hold" in res["reason"], res


def test_no_chart_in_the_photo(scene):
    from workbench.camera import Camera

    d, grid, _ = scene
    cam = Camera.look_at([0, 120, 330], [0, 20, 0], [0, 1, 0], 38, 1200, 900)  # the part and board, not the chart
    from workbench.render.imperfections import Imperfections
    from workbench.render.photo import render_photo

    photo = render_photo(d.scene(Imperfections(), True), cam, Imperfections())
    res, _ = measure((d, grid, cam), photo)
    assert not res["measured"] and "the colour chart is not in the photo" in res["reason"], res


def test_render_options(tmp_path, capsys, scene):
    import json

    from workbench.cli import main

    d = scene[0]
    out = tmp_path / "p.png"
    args = ["render", str(d.dir), "--orbit", "0,70,500", "--size", "320x240", "-o", str(out), "-q"]
    assert main([*args, "--colour-shift-lab=-6,6,8", "--white-balance", "1,0.9,0.72"]) == 0
    imp = json.loads(out.with_suffix(".json").read_text())["imperfections"]
    assert imp["colour_shift_lab"] == [-6.0, 6.0, 8.0] and imp["white_balance"] == [1.0, 0.9, 0.72]
    assert main([*args, "--colour-shift-lab", "60,0,0"]) == 2
    assert "--colour-shift-lab 60: must be between -50 and 50" in capsys.readouterr().err


def test_a_broken_chart_in_fixture_json_is_refused(scene, tmp_path):
    import json
    import shutil

    from workbench.design_dir import Design
    from workbench.errors import WorkbenchError

    d = tmp_path / "design"
    shutil.copytree(scene[0].dir, d)
    info = json.loads((d / "fixture.json").read_text())
    info["colour_chart"]["patches"][3]["lab_d50"] = [50, 0]
    (d / "fixture.json").write_text(json.dumps(info))
    with pytest.raises(WorkbenchError, match=r"fixture.json: colour_chart.patches\[3\].lab_d50: must be"):
        Design(d)


@pytest.mark.parametrize(("method", "degree"), [("matrix", 1), ("root-polynomial", 2), ("root-polynomial", 3)])
def test_the_chart_fit_is_colour_sciences(method, degree):
    """The correction fitted and applied in numpy equals colour-science's (which validate need not import)."""
    import colour

    from workbench.printing.boards import colour_chart_reference

    names, lab = colour_chart_reference()
    np.testing.assert_allclose(col.CHART_LAB_D50, lab, atol=1e-3)
    rng = np.random.default_rng(3)
    # a camera's linear RGB of the chart: its reference through a mixing matrix, a gain and noise
    truth = col.lab_to_linear_srgb(lab).clip(0.001, None)
    camera = truth @ np.array([[0.8, 0.15, 0.05], [0.1, 0.85, 0.05], [0.05, 0.2, 0.75]]).T * 0.7
    camera *= 1 + rng.normal(0, 0.01, camera.shape)
    rgb = 255 * col.srgb_encode(camera)
    usable = np.ones(24, bool)
    usable[[3, 17]] = False  # two patches left out
    sample = col.ChartSample(np.where(usable[:, None], rgb, np.nan), np.full(24, 100), usable, [""] * 24, None)
    corr = col.fit_correction(sample, lab, col.ColourOptions(method=method, degree=degree))
    name, kw = ("Cheung 2004", {"terms": 3}) if method == "matrix" else ("Finlayson 2015", {"degree": degree})
    want = colour.matrix_colour_correction(camera[usable], truth[usable], method=name, **kw)
    np.testing.assert_allclose(corr.ccm, want, atol=1e-9)
    probe = rng.random((500, 3))
    np.testing.assert_allclose(
        corr.apply(probe), colour.apply_matrix_colour_correction(probe, want, method=name, **kw), atol=1e-12
    )
    assert np.isnan(corr.fit_delta_e00[~usable]).all() and (corr.fit_delta_e00[usable] < 3).all()
