"""A photo at fault (over-exposed, JPEG blocks, no colour) is INVALID with the reason, not a FAIL of the print."""

from __future__ import annotations

import io
import json

import numpy as np
import pytest
from conftest import ROOT
from PIL import Image

from workbench.cli import main
from workbench.validate import photo_quality as pq

SIZE = "1200x900"
ORBIT = "--orbit=10,55,330"


@pytest.fixture(scope="module")
def design(tmp_path_factory):
    d = tmp_path_factory.mktemp("pq") / "design"
    assert main(["design", str(ROOT / "fixtures" / "default" / "job.toml"), "--out", str(d), "-q"]) == 0
    return d


def render(design, path, *extra):
    assert main(["render", str(design), ORBIT, "--size", SIZE, "-o", str(path), "-q", *extra]) == 0
    return path


@pytest.mark.parametrize("quality", [5, 10, 30, 50, 75, 90, 95])
def test_the_jpeg_quality_is_read_from_its_tables(quality):
    rng = np.random.default_rng(0)
    buf = io.BytesIO()
    Image.fromarray(rng.integers(0, 255, (64, 64, 3), dtype=np.uint8)).save(buf, format="JPEG", quality=quality)
    assert pq.read_jpeg_quality(io.BytesIO(buf.getvalue())) == pytest.approx(quality, abs=0.6)
    png = io.BytesIO()
    Image.fromarray(np.zeros((8, 8, 3), np.uint8)).save(png, format="PNG")
    assert pq.read_jpeg_quality(io.BytesIO(png.getvalue())) is None


def test_the_checks_on_arrays():
    ref = np.zeros((40, 60, 3), np.uint8)
    ref[:, :30] = (40, 140, 60)  # ink
    ref[:4, :4] = (0, 255, 0)  # a saturated ink: it may clip
    ref[:, 30:] = 255  # the film's white: it may clip
    seen = np.ones((40, 60), bool)
    good = ref.copy()
    assert pq.clipped_share(good, ref, seen, pq.QualityOptions()) == 0.0
    over = np.clip(ref.astype(int) * 3, 0, 255).astype(np.uint8)
    assert pq.clipped_share(over, ref, seen, pq.QualityOptions()) == 1.0  # the green channel of every other inked pixel
    q = pq.photo_quality(good, good, ref, seen)
    assert q["problems"] == [] and q["design_coloured_share"] == pytest.approx(0.5, abs=0.05)
    grey = np.repeat(good.mean(axis=2, keepdims=True).astype(np.uint8), 3, axis=2)
    assert "no colour" in pq.photo_quality(grey, grey, ref, seen)["problems"][0]
    # a design without colour: a grey photo of it is not at fault
    assert pq.photo_quality(grey, grey, np.repeat(ref[..., :1], 3, axis=2), seen)["problems"] == []
    assert "quality 12" in pq.photo_quality(good, good, ref, seen, jpeg=12.0)["problems"][0]


def test_bad_photos_are_invalid_with_the_reason(design, tmp_path):
    photos = [
        render(design, tmp_path / "perfect.png"),
        render(design, tmp_path / "over.png", "--exposure", "3"),
        render(design, tmp_path / "q5.jpg", "--jpeg-quality", "5"),
        render(design, tmp_path / "q90.jpg", "--realistic"),
    ]
    grey = tmp_path / "grey.png"
    Image.open(photos[0]).convert("L").save(grey)
    photos.append(grey)
    for p in photos[1:]:
        p.with_suffix(".json").write_text(photos[0].with_suffix(".json").read_text())
    out = tmp_path / "out"
    cmd = ["validate", str(design), *map(str, photos), "--camera", str(photos[0].with_suffix(".json"))]
    assert main([*cmd, "--out", str(out), "--jobs", "1", "-q"]) == 0
    got = {e["photo"].rsplit("/", 1)[-1]: e for e in json.loads((out / "validation.json").read_text())["photos"]}
    assert got["perfect.png"]["verdict"] == "PASS" and got["q90.jpg"]["verdict"] == "PASS", got["q90.jpg"]["reason"]
    assert got["q90.jpg"]["photo_quality"]["jpeg_quality"] == pytest.approx(90, abs=0.6)
    want = {"over.png": "over-exposed", "q5.jpg": "a JPEG of quality 5", "grey.png": "the photo has no colour"}
    for name, words in want.items():
        e = got[name]
        assert e["verdict"] == "INVALID", (name, e["reason"])
        assert e["reason"].startswith("the photo is at fault, not the print: ") and words in e["reason"], e["reason"]
    # measured: 94 % of the inked print clipped at x3 exposure, 2 % in the perfect photo
    assert got["over.png"]["photo_quality"]["clipped_share"] > 0.8
    assert got["perfect.png"]["photo_quality"]["clipped_share"] < 0.1
    # the part: its photos at fault count for nothing (their defects are theirs, not the print's):
    # it is what its two good photos make of it alone, nothing found (its verdict PASS, or
    # INCOMPLETE where two photos cover less than min_coverage of the film for a class: the
    # default job's two cover 94 to 97 %, at the line)
    part = json.loads((out / "validation.json").read_text())["part"]
    alone = tmp_path / "alone"
    good = [str(photos[0]), str(photos[3])]
    assert main(["validate", str(design), *good, "--camera", cmd[-1], "--out", str(alone), "--jobs", "1", "-q"]) == 0
    two = json.loads((alone / "validation.json").read_text())["part"]
    assert part["photos_scored"] == 2 and part["defects"] == [] and part["verdict"] in ("PASS", "INCOMPLETE")
    assert (part["verdict"], part["coverage"]["films"]) == (two["verdict"], two["coverage"]["films"])
