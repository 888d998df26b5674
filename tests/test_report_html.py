"""qa_report.html: the part in 3D with its defects and coverage, one file, opened in a real headless Chromium."""

from __future__ import annotations

import base64
import gzip
import json
import os
import re
import struct

import cv2
import numpy as np
import pytest
import trimesh
from browser import chromium, open_page, page_url
from conftest import ROOT

from workbench.cli import main
from workbench.design_dir import Design
from workbench.validate.part_glb import grid_on_texture, print_uv
from workbench.validate.pictures import STATE_COLOURS
from workbench.validate.print_warp import STATE_NAMES
from workbench.validate.report_html import surface_point

# the demo's defective part: a bubble that slid the film 1 mm over 12 mm, and ink gone over 10 mm²
DEFECTS = ["bubble:45,30,6,1", "dropout:60,25,1.784"]
MARKER_RGB = (255, 0, 200)  # qa_report.css: .marker
BACKGROUND_RGB = (238, 240, 243)  # qa_report.js: the scene's background
DEFECTIVE_RGB = tuple(int(c) for c in STATE_COLOURS[STATE_NAMES.index("defective")])


@pytest.fixture(scope="module")
def validated(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("html")
    design = tmp / "design"
    assert main(["design", str(ROOT / "fixtures" / "default" / "job.toml"), "--out", str(design), "-q"]) == 0
    photo = tmp / "defects.png"
    extra = [a for spec in DEFECTS for a in ("--defect", spec)]
    render = ["render", str(design), "--orbit=10,55,330", "--size", "2000x1500", "--realistic", "--gloss", "0.5"]
    assert main([*render, *extra, "-o", str(photo), "-q"]) == 0
    outs = []
    for k in range(2):  # twice: the same inputs, the same bytes
        out = tmp / f"out{k}"
        args = ["validate", str(design), str(photo), "--camera", str(photo.with_suffix(".json")), "--out", str(out)]
        assert main([*args, "--tolerance-mm", "0.2", "-q"]) == 0
        outs.append(out)
    return Design(design), outs


def embedded(html: str, name: str) -> str:
    return re.search(rf'<script type="[^"]+" id="{name}">(.*?)</script>', html, re.S).group(1)


def page_data(out) -> dict:
    return json.loads(embedded((out / "qa_report.html").read_text(), "qa-data"))


def glb_of(out) -> tuple[dict, bytes]:
    glb = gzip.decompress(base64.b64decode(embedded((out / "qa_report.html").read_text(), "qa-glb")))
    magic, version, length = struct.unpack("<4sII", glb[:12])
    assert (magic, version, length) == (b"glTF", 2, len(glb))
    n = struct.unpack("<I", glb[12:16])[0]
    gltf = json.loads(glb[20 : 20 + n])
    return gltf, glb[20 + n + 8 :]


def view_bytes(gltf: dict, binary: bytes, index: int) -> bytes:
    v = gltf["bufferViews"][index]
    return binary[v["byteOffset"] : v["byteOffset"] + v["byteLength"]]


def test_the_report_is_written_listed_and_the_same_each_run(validated):
    _, (out, again) = validated
    assert (out / "qa_report.html").read_bytes() == (again / "qa_report.html").read_bytes()
    assert "qa_report.html" in (out / ".workbench-files").read_text().split()
    html = (out / "qa_report.html").read_text()
    # nothing outside the file: no URL but data: in any attribute, no http(s) anywhere in the page's own text
    assert not re.search(r'(src|href)="(?!data:)', html)
    page = re.sub(r'<script type="[^"]+" id="qa-(modules|glb|data)">.*?</script>', "", html, flags=re.S)
    assert "http://" not in page and "https://" not in page


def flat_position(design: Design, point: np.ndarray) -> np.ndarray:
    """Where a point on the part's surface lies in the design's flat layout (flat.obj's mm); fails off the surface."""
    tri = design.V[design.F]
    normal = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    normal /= np.maximum(np.linalg.norm(normal, axis=1, keepdims=True), 1e-300)
    to_plane = np.abs(((point - tri[:, 0]) * normal).sum(axis=1))
    with np.errstate(invalid="ignore", divide="ignore"):
        bary = trimesh.triangles.points_to_barycentric(tri, np.repeat(point[None], len(tri), axis=0))
    inside = np.flatnonzero((bary >= -1e-9).all(axis=1) & (to_plane < 1e-6))
    assert len(inside), f"{point} is on no triangle of the part"
    k = inside[0]
    return bary[k] @ design.flat[design.F[k]]


def test_each_marker_sits_on_the_part_where_its_defect_is_on_the_print(validated):
    design, (out, _) = validated
    report = json.loads((out / "validation.json").read_text())
    defects = page_data(out)["defects"]
    assert [d["centre_mm"] for d in defects] == [
        [round(v, 2) for v in d["centre_mm"]] for d in report["part"]["defects"]
    ]
    assert len(defects) == 2
    flat = np.array([flat_position(design, np.asarray(d["point"])) for d in defects])
    on_print = np.stack([flat[:, 0], design.info["print"]["height_mm"] - flat[:, 1]], axis=1)
    grid_px_mm = 1 / report["photos"][0]["dense"]["grid_px_per_mm"]
    assert np.abs(on_print - [d["centre_mm"] for d in defects]).max() <= grid_px_mm


def test_the_glb_is_the_part_with_its_print_and_its_coverage(validated):
    design, (out, _) = validated
    gltf, binary = glb_of(out)
    assert [n["name"] for n in gltf["nodes"]] == ["print", "coverage"]
    position, _, uv, index = (gltf["accessors"][k] for k in range(4))
    V = np.frombuffer(view_bytes(gltf, binary, position["bufferView"]), np.float32).reshape(-1, 3)
    F = np.frombuffer(view_bytes(gltf, binary, index["bufferView"]), np.uint32).reshape(-1, 3)
    UV = np.frombuffer(view_bytes(gltf, binary, uv["bufferView"]), np.float32).reshape(-1, 2)
    assert np.array_equal(V, design.V.astype(np.float32)) and np.array_equal(F, design.F)
    p = design.info["print"]
    assert np.allclose(
        UV, print_uv(design.flat, p["height_mm"], (p["image_width_mm"], p["image_height_mm"])), atol=1e-6
    )
    pictures = []
    for image in gltf["images"]:
        data = np.frombuffer(view_bytes(gltf, binary, image["bufferView"]), np.uint8)
        pictures.append(cv2.cvtColor(cv2.imdecode(data, cv2.IMREAD_COLOR), cv2.COLOR_BGR2RGB))
    assert [i["mimeType"] for i in gltf["images"]] == ["image/jpeg", "image/png"]
    assert max(pictures[0].shape[:2]) <= 2048 and pictures[0].shape == pictures[1].shape
    # the coverage layer: defective at each part defect's centre, through the same texture coordinates
    h, w = pictures[1].shape[:2]
    for d in json.loads((out / "validation.json").read_text())["part"]["defects"]:
        x, y = d["centre_mm"]
        pixel = pictures[1][int(y / p["image_height_mm"] * h), int(x / p["image_width_mm"] * w)]
        assert tuple(int(c) for c in pixel) == DEFECTIVE_RGB


def near(img: np.ndarray, rgb, tol: int) -> np.ndarray:
    return (np.abs(img.astype(np.int16) - np.array(rgb, np.int16)) <= tol).all(axis=-1)


def ring(img: np.ndarray, x: int, y: int, r0: float, r1: float) -> np.ndarray:
    yy, xx = np.mgrid[: img.shape[0], : img.shape[1]]
    d = np.hypot(xx - x, yy - y)
    return img[(d >= r0) & (d <= r1)]


VIEWER_BOX = "JSON.stringify(document.getElementById('viewer').getBoundingClientRect())"
SHOW_COVERAGE = "document.querySelector('[data-layer=coverage]').click(); 1"


def test_the_page_opens_offline_and_shows_the_part_its_markers_and_its_coverage(validated):
    if chromium() is None:
        if os.environ.get("CI") or os.environ.get("WORKBENCH_REQUIRE_BROWSER"):
            pytest.fail("no Chromium: /usr/bin/chromium is needed (apt-get install chromium)")
        pytest.skip("no Chromium (/usr/bin/chromium)")
    _, (out, _) = validated
    run = open_page(page_url(out / "qa_report.html"), "loaded", steps=(VIEWER_BOX, SHOW_COVERAGE))
    assert run.errors == []
    # no request but the page's own file and what it unpacks from itself
    own = page_url(out / "qa_report.html")
    assert [u for u in run.requests if u != own and not u.startswith(("data:", "blob:"))] == []
    assert run.body.get("loaded") == "part" and "error" not in run.body
    defects = page_data(out)["defects"]
    markers = json.loads(run.body["markers"])
    assert int(run.body["markersDrawn"]) == len(markers) == len(defects)
    shot = cv2.cvtColor(cv2.imdecode(np.frombuffer(run.screenshot, np.uint8), cv2.IMREAD_COLOR), cv2.COLOR_BGR2RGB)
    box = json.loads(run.step_values[0])
    x0, y0 = int(box["left"]) + 2, int(box["top"]) + 2
    x1, y1 = int(box["right"]) - 2, int(box["bottom"]) - 2
    canvas = shot[y0:y1, x0:x1]
    # the part is drawn: a good share of the view is not the background
    drawn = ~near(canvas, BACKGROUND_RGB, 6)
    assert drawn.mean() > 0.1, drawn.mean()
    for m in markers:
        assert x0 < m["x"] < x1 and y0 < m["y"] < y1 and not m["behind"]
        # the marker's disc, in its colour, where the page says it drew it
        assert near(ring(shot, m["x"], m["y"], 6, 9), MARKER_RGB, 40).mean() > 0.8
        # on the part: what surrounds it is the part, not the background
        assert (~near(ring(shot, m["x"], m["y"], 16, 22), BACKGROUND_RGB, 6)).mean() > 0.9
    # the coverage layer: the defects' places turn the map's "defective" colour (shown unlit, as its legend)
    covered = cv2.cvtColor(
        cv2.imdecode(np.frombuffer(run.step_screenshots[1], np.uint8), cv2.IMREAD_COLOR), cv2.COLOR_BGR2RGB
    )
    big = markers[0]  # the bubble, 117 mm², about 12 mm across: its marker hides its middle
    yy, xx = np.mgrid[: shot.shape[0], : shot.shape[1]]
    around = np.hypot(xx - big["x"], yy - big["y"]) <= 40
    red = near(covered, DEFECTIVE_RGB, 12) & around
    assert red.sum() >= 100 and not (near(shot, DEFECTIVE_RGB, 12) & around).any()
    assert np.hypot(xx[red].mean() - big["x"], yy[red].mean() - big["y"]) <= 8  # around the marker


def test_a_defect_whose_centre_is_off_the_part_takes_the_nearest_point_of_its_box():
    # a 10 x 10 grid at 2 px/mm whose point under pixel (i, j) is (j, i, 0), with a hole in the middle
    ii, jj = np.mgrid[:10, :10]
    X = np.stack([jj, ii, np.zeros_like(ii)], axis=-1).astype(np.float64)
    X[3:7, 3:7] = np.nan
    # under its centre: that pixel's point
    assert surface_point(X, 2.0, (1.3, 4.6), (0, 0, 5, 5)) == [2.0, 9.0, 0.0]
    # a ring's centre in the hole: the nearest pixel of its box that is on the part
    assert surface_point(X, 2.0, (2.3, 2.3), (1.0, 1.0, 3.6, 3.6)) == [4.0, 2.0, 0.0]
    # no part under its box at all
    assert surface_point(X, 2.0, (2.3, 2.3), (1.6, 1.6, 3.4, 3.4)) is None


def test_the_coverage_map_is_resampled_onto_the_print_texture_by_print_millimetres():
    # a 4 x 6 grid at 2 px/mm (3 x 2 mm) onto a texture of 12 x 8 px over 3.5 x 2.5 mm
    grid = np.arange(24, dtype=np.uint8).reshape(4, 6, 1).repeat(3, axis=2)
    texture = grid_on_texture(grid, 2.0, (12, 8), (3.5, 2.5))
    assert texture.shape == (8, 12, 3)
    for i, j in [(0, 0), (3, 5), (5, 7), (7, 11)]:
        x, y = (j + 0.5) * 3.5 / 12, (i + 0.5) * 2.5 / 8  # the texture pixel's centre, print mm
        gi, gj = min(int(y * 2.0), 3), min(int(x * 2.0), 5)  # the grid pixel under it (the last beyond)
        assert texture[i, j, 0] == grid[gi, gj, 0]
