"""Issue 36, item 3: a view says what it decorates (its image's alpha, or ``mask``), and a region
rule that drops much of what a view could claim is said."""

from __future__ import annotations

import json

import cv2
import numpy as np
import pytest
from matplotlib.tri import LinearTriInterpolator, Triangulation
from test_fuzz import toml_text

from fixtures.make_fixtures import domed_part
from workbench.cli import main
from workbench.design import design
from workbench.job import load_job
from workbench.mesh.io import format_obj
from workbench.mesh.validate import face_areas
from workbench.views.visibility import region_drops

W, H = 400, 300  # view images, px
LOGO_CENTRE, LOGO_RADIUS = (230.0, 140.0), 55.0  # the logo: an opaque disc, px of the logo view
VIEW = {"position": [0, 0, 200], "look_at": [0, 0, 0], "up": [0, 1, 0], "fov_deg": 25}
LOGO_VIEW = {"position": [8, -5, 190], "look_at": [0, 0, 0], "up": [0, 1, 0], "fov_deg": 24}


def photo(seed: int = 7) -> np.ndarray:
    """A photo-like base image: smooth random colour, (H, W, 3) uint8 RGB."""
    rng = np.random.default_rng(seed)
    small = rng.integers(0, 256, (12, 16, 3)).astype(np.uint8)
    return cv2.resize(small, (W, H), interpolation=cv2.INTER_CUBIC)


def logo_alpha() -> np.ndarray:
    """The logo's alpha, (H, W) uint8: 255 on the disc, 0 around it."""
    yy, xx = np.mgrid[0:H, 0:W]
    disc = (xx - LOGO_CENTRE[0]) ** 2 + (yy - LOGO_CENTRE[1]) ** 2 <= LOGO_RADIUS**2
    return np.where(disc, 255, 0).astype(np.uint8)


def write_rgb(path, rgb: np.ndarray) -> None:
    cv2.imwrite(str(path), cv2.cvtColor(rgb, cv2.COLOR_RGB2BGR))


def job_files(folder, logo: str = "alpha", region: str = "largest") -> dict:
    """The lid, a base view from above (a photo) and a logo view before it (a red disc).

    ``logo``: "alpha" (an RGBA image, transparent around the disc) or "mask" (the same picture
    as RGB, the disc in a grey mask.png).
    """
    V, F = domed_part(24, 18, 60.0, 40.0, 6.0)
    (folder / "part.obj").write_bytes(format_obj(V, F))
    write_rgb(folder / "base.png", photo())
    alpha = logo_alpha()
    red = np.zeros((H, W, 3), np.uint8)
    red[:] = (200, 30, 40)
    if logo == "alpha":
        cv2.imwrite(str(folder / "logo.png"), np.dstack([cv2.cvtColor(red, cv2.COLOR_RGB2BGR), alpha]))
    else:
        # as the alpha version reads: transparent pixels laid over the background (white)
        write_rgb(folder / "logo.png", np.where(alpha[..., None] > 0, red, 255).astype(np.uint8))
        cv2.imwrite(str(folder / "mask.png"), alpha)
    logo_view = {"name": "logo", "image": "logo.png", "region": region, **LOGO_VIEW}
    if logo == "mask":
        logo_view["mask"] = "mask.png"
    job = {
        "object": {"mesh": "part.obj", "material": {"name": "film", "max_stretch": 1.1}},
        "print": {"dpi": 60, "background": "#ffffff"},
        "views": [logo_view, {"name": "base", "image": "base.png", **VIEW}],
    }
    (folder / "job.toml").write_bytes(toml_text(job))
    return job


def logo_footprint(r, alpha: np.ndarray) -> np.ndarray:
    """Print pixels whose surface point the logo view sees on its disc, found independently.

    Print pixel centres are carried to the surface through the flat layout (linear per
    triangle, matplotlib's interpolation), projected by the logo view's camera and looked up
    at the nearest logo pixel; (rows, cols) bool.
    """
    rows, cols = r.grid.shape
    P = r.grid.to_pixels(r.flat.uv)
    tri = Triangulation(P[:, 0], P[:, 1], r.F)
    jj, ii = np.meshgrid(np.arange(cols, dtype=float), np.arange(rows, dtype=float))
    X = np.stack([np.ma.filled(LinearTriInterpolator(tri, r.V[:, d])(jj, ii), np.nan) for d in range(3)], axis=-1)
    on = np.isfinite(X).all(axis=-1)
    xy, _ = r.cameras[0].project(X[on])
    j = np.clip(np.floor(xy[:, 0] + 0.5).astype(int), 0, W - 1)
    i = np.clip(np.floor(xy[:, 1] + 0.5).astype(int), 0, H - 1)
    out = np.zeros((rows, cols), bool)
    out[on] = alpha[i, j] > 0
    return out


def one_line(capsys) -> str:
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "Traceback" not in err[0], err
    return err[0]


@pytest.fixture(scope="module")
def alpha_job(tmp_path_factory):
    folder = tmp_path_factory.mktemp("logo-alpha")
    job_files(folder, "alpha")
    assert main(["design", str(folder / "job.toml"), "--out", str(folder / "out"), "-q"]) == 0
    return folder


def test_a_logo_with_a_transparent_background_owns_only_the_logo(alpha_job):
    r = design(load_job(alpha_job / "job.toml"))
    footprint = logo_footprint(r, logo_alpha())
    logo = r.owner == 0
    # the logo view paints the disc and nothing else: the surface around it is the base view's
    assert footprint.sum() > 1500 and (r.owner[~footprint] == 1).mean() > 0.99
    differ = logo ^ footprint
    one_px = np.ones((3, 3), np.uint8)
    near_edge = cv2.dilate(footprint.astype(np.uint8), one_px) > cv2.erode(footprint.astype(np.uint8), one_px)
    assert int(differ.sum()) <= 4, int(differ.sum())  # measured: 0 of 2,034 logo pixels
    assert not (differ & ~near_edge).any()  # and any difference within one print pixel of the disc's edge
    # what the user sees: owner.png (view + 1) and the print's colour on the logo
    owner_png = cv2.imread(str(alpha_job / "out" / "owner.png"), cv2.IMREAD_UNCHANGED)
    np.testing.assert_array_equal(owner_png, r.owner + 1)
    rgb = cv2.cvtColor(cv2.imread(str(alpha_job / "out" / "print.png")), cv2.COLOR_BGR2RGB)
    inner = cv2.erode(footprint.astype(np.uint8), np.ones((5, 5), np.uint8)).astype(bool)
    assert (rgb[inner] == (200, 30, 40)).all()
    info = json.loads((alpha_job / "out" / "design.json").read_text())
    assert info["warnings"] == []
    share = info["views"][0]["print_share"]
    assert share == pytest.approx(footprint.sum() / footprint.size, abs=1e-9)
    # of its image, the logo view uses the disc (which lies on the lid), not its transparent rest
    assert info["views"][0]["image_share_used"] == pytest.approx((logo_alpha() > 0).mean(), abs=1e-9)


def test_a_mask_file_gives_the_same_print_as_the_alpha(alpha_job, tmp_path):
    job_files(tmp_path, "mask")
    assert main(["design", str(tmp_path / "job.toml"), "--out", str(tmp_path / "out"), "-q"]) == 0
    for name in ("print.png", "owner.png", "decorated.obj", "decorated.glb"):  # (views.png: its title names the job)
        assert (tmp_path / "out" / name).read_bytes() == (alpha_job / "out" / name).read_bytes(), name


@pytest.mark.parametrize("case", ["wrong size", "unreadable", "with alpha", "missing", "marks nothing"])
def test_a_bad_mask_is_one_line_and_nothing_is_written(case, tmp_path, capsys):
    job = job_files(tmp_path, "alpha" if case == "with alpha" else "mask")
    if case == "wrong size":
        cv2.imwrite(str(tmp_path / "mask.png"), np.full((H // 2, W // 2), 255, np.uint8))
        expect = "views[0].mask: mask.png is 200 x 150 px, but the image logo.png is 400 x 300 px"
    elif case == "unreadable":
        (tmp_path / "mask.png").write_bytes(b"not a png")
        expect = "views[0].mask: cannot read image"
    elif case == "with alpha":
        cv2.imwrite(str(tmp_path / "mask.png"), logo_alpha())
        job["views"][0]["mask"] = "mask.png"
        (tmp_path / "job.toml").write_bytes(toml_text(job))
        expect = "views[0].mask: the image logo.png has transparent pixels of its own"
    elif case == "missing":
        (tmp_path / "mask.png").unlink()
        expect = "views[0].mask: file 'mask.png' not found"
    else:
        cv2.imwrite(str(tmp_path / "mask.png"), np.zeros((H, W), np.uint8))
        expect = "views[0].mask: mask.png marks no pixel as decoration"
    assert main(["design", str(tmp_path / "job.toml"), "--out", str(tmp_path / "out"), "-q"]) == 1
    line = one_line(capsys)
    assert expect in line and str(tmp_path / "job.toml") in line, line
    assert not (tmp_path / "out").exists()


# --- region = "largest": said when it drops more than 5 % -------------------------------------

PLATE_MM, CELL_MM = (60.0, 40.0), 2.0  # a flat plate in squares of 2 mm, two triangles each
PX_PER_MM = 10.0  # the views look straight down from 200 mm: 10 px per mm on the plate


def plate() -> tuple[np.ndarray, np.ndarray]:
    nx, ny = int(PLATE_MM[0] / CELL_MM) + 1, int(PLATE_MM[1] / CELL_MM) + 1
    x, y = np.meshgrid(np.linspace(-30, 30, nx), np.linspace(-20, 20, ny))
    V = np.column_stack([x.ravel(), y.ravel(), np.zeros(nx * ny)])
    a = (np.arange(ny - 1)[:, None] * nx + np.arange(nx - 1)[None, :]).ravel()
    F = np.concatenate([np.stack([a, a + 1, a + nx + 1], 1), np.stack([a, a + nx + 1, a + nx], 1)])
    return V, F


def strip_job(folder, strip_mm: tuple[float, float]) -> list[str]:
    """A strip view first (its mask: the plate's x in ``strip_mm``), then a base view of the whole
    plate, which the strip cuts in two; its design."""
    V, F = plate()
    (folder / "part.obj").write_bytes(format_obj(V, F))
    w, h = 800, 600
    f = 200.0 * PX_PER_MM  # px: the plate at 200 mm, 10 px per mm
    fov = float(np.degrees(2 * np.arctan(w / 2 / f)))
    write_rgb(folder / "base.png", cv2.resize(photo(), (w, h)))
    write_rgb(folder / "strip.png", np.full((h, w, 3), (20, 20, 160), np.uint8))
    x_mm = (np.arange(w) - (w - 1) / 2) / PX_PER_MM  # the plate's x at each pixel column's centre
    mask = np.zeros((h, w), np.uint8)
    mask[:, (x_mm >= strip_mm[0]) & (x_mm <= strip_mm[1])] = 255
    cv2.imwrite(str(folder / "mask.png"), mask)
    top = {"position": [0, 0, 200], "look_at": [0, 0, 0], "up": [0, 1, 0], "fov_deg": fov}
    job = {
        "object": {"mesh": "part.obj"},
        "print": {"dpi": 20},
        "views": [
            {"name": "strip", "image": "strip.png", "mask": "mask.png", **top},
            {"name": "base", "image": "base.png", **top},
        ],
    }
    (folder / "job.toml").write_bytes(toml_text(job))
    return design(load_job(folder / "job.toml"))


def test_a_region_that_drops_more_than_5_percent_is_said(tmp_path, capsys):
    # the strip covers x from 10 to 16 mm (on grid lines; its image one flat colour: the mask
    # makes the picture, no warning). Its edge columns of squares are the strip's only where the
    # mask says, so the base view could claim the plate but the inner squares (x 12 to 14):
    # 60 x 40 - 2 x 40 = 2320 mm²; it keeps the left piece (x -30 to 12, 1680 mm²) and drops the
    # right one (x 14 to 30): 640 mm², 27.6 %
    r = strip_job(tmp_path, (10.0, 16.0))
    np.testing.assert_allclose(region_drops(r.visibilities, r.status, face_areas(r.V, r.F))[1], [2320, 640])
    assert r.warnings == [
        "view 'base' (views[1]) keeps its largest connected region and drops 27.6 % of the surface it could "
        'claim (640 of 2320 mm²): region = "all" keeps every region'
    ], r.warnings
    # said on the terminal and in design.json (and --strict refuses it)
    assert main(["design", str(tmp_path / "job.toml"), "--out", str(tmp_path / "out")]) == 0
    assert f"warning: {r.warnings[0]}" in capsys.readouterr().err.splitlines()
    assert json.loads((tmp_path / "out" / "design.json").read_text())["warnings"] == r.warnings
    assert main(["design", str(tmp_path / "job.toml"), "--out", str(tmp_path / "strict"), "--strict", "-q"]) == 1
    assert 'region = "all"' in one_line(capsys) and not (tmp_path / "strict").exists()


def test_a_region_that_drops_little_is_not_said(tmp_path):
    # the strip from 20 mm to the plate's end (30 mm): the base view drops the strip's last
    # column of squares (x 28 to 30, the strip's only in part), 80 of 2160 mm², 3.7 %: not said
    r = strip_job(tmp_path, (20.0, 30.0))
    np.testing.assert_allclose(region_drops(r.visibilities, r.status, face_areas(r.V, r.F))[1], [2160, 80])
    assert r.warnings == [], r.warnings
