"""Images read as viewers show them (EXIF orientation), under any file name; text as each medium shows it."""

from __future__ import annotations

import io
import json
import os
import shutil
from pathlib import Path

import cv2
import numpy as np
import pytest
from PIL import Image, ImageOps
from test_fuzz import make_base

from workbench.cli import main
from workbench.design_dir import read_image
from workbench.image_file import decode_upright, exif_orientation, imread
from workbench.text import ascii_text, one_line, printable


def with_orientation(rgb: np.ndarray, orientation: int, fmt: str = "PNG") -> bytes:
    """``rgb`` encoded as stored, with EXIF orientation ``orientation``."""
    exif = Image.Exif()
    exif[0x0112] = orientation
    buf = io.BytesIO()
    Image.fromarray(rgb).save(buf, format=fmt, exif=exif.tobytes())
    return buf.getvalue()


@pytest.mark.parametrize("orientation", range(1, 9))
def test_each_orientation_turns_as_pillow_turns_it(orientation):
    # an image that is its own in none of the eight turns: random, 5 x 7, three channels
    rgb = np.random.default_rng(orientation).integers(0, 256, (5, 7, 3), dtype=np.uint8)
    data = with_orientation(rgb, orientation)
    assert exif_orientation(data) == orientation
    truth = np.asarray(ImageOps.exif_transpose(Image.open(io.BytesIO(data))))
    got = decode_upright(data, cv2.IMREAD_UNCHANGED)[..., ::-1]  # BGR as OpenCV decodes
    assert got.shape == truth.shape and np.array_equal(got, truth)
    # the colour read (which OpenCV would turn by itself for a JPEG) turns once, the same way
    assert np.array_equal(decode_upright(data, cv2.IMREAD_COLOR)[..., ::-1], truth)
    grey = decode_upright(data, cv2.IMREAD_GRAYSCALE).astype(int)  # the decoder's own rounding: within 1
    assert grey.shape == truth.shape[:2]
    assert np.abs(grey - cv2.cvtColor(truth, cv2.COLOR_RGB2GRAY)).max() <= 1


def test_a_jpeg_turned_by_opencv_alone_would_turn_twice_or_never(tmp_path):
    """A phone's JPEG with orientation 6: stored sideways, shown upright; read_image shows it upright."""
    upright_rgb = np.zeros((60, 80, 3), np.uint8)
    upright_rgb[:20, :40] = (250, 20, 20)  # a red block at the top left of the upright image
    stored = np.ascontiguousarray(np.rot90(upright_rgb, 1))  # the sensor's order: a quarter counter-clockwise
    path = tmp_path / "phone.jpg"
    path.write_bytes(with_orientation(stored, 6, "JPEG"))
    got = read_image(path, "photo")
    assert got.shape == (60, 80, 3)
    assert got[:20, :40, 0].mean() > 200 and got[40:, 40:, 0].mean() < 30


def test_a_file_name_that_is_not_utf8_is_read(tmp_path):
    """OpenCV's imread took the name as UTF-8 and crashed the process on a Latin-1 byte."""
    folder = Path(os.fsdecode(os.fsencode(tmp_path) + b"/Teil \xfc"))
    folder.mkdir()
    rgb = np.random.default_rng(0).integers(0, 256, (9, 11, 3), dtype=np.uint8)
    (folder / "a.png").write_bytes(with_orientation(rgb, 1))
    assert np.array_equal(imread(folder / "a.png")[..., ::-1], rgb)
    assert imread(folder / "missing.png") is None


def test_text_for_each_medium():
    undecodable = os.fsdecode(b"Teil \xfc")  # a Latin-1 name read under UTF-8: a lone surrogate
    assert printable(undecodable) == "Teil \ufffd"
    printable(undecodable).encode("utf-8")  # what a PDF or a font takes
    assert one_line("a\nb.png") == "a\\nb.png" and one_line("mm²") == "mm²"
    assert ascii_text("12.5 mm² at 30° ✓ Grün") == "12.5 mm2 at 30 deg ok Grun"
    assert ascii_text(undecodable) == "Teil ?"


@pytest.fixture(scope="module")
def base(tmp_path_factory):
    return make_base(tmp_path_factory.mktemp("exif-base"))


def test_a_photo_stored_sideways_is_validated_upright(base, tmp_path):
    """A phone's photo: the sensor's order with EXIF orientation 8, judged as the upright photo is.

    Before: INVALID, "photo is 480 x 640 px, the camera profile is for 640 x 480"."""
    rgb = cv2.cvtColor(cv2.imread(str(base / "photo.png")), cv2.COLOR_BGR2RGB)
    stored = np.ascontiguousarray(np.rot90(rgb, -1))  # orientation 8: turn a quarter counter-clockwise to show
    photo = tmp_path / "phone.png"
    photo.write_bytes(with_orientation(stored, 8))
    shutil.copy(base / "photo.json", tmp_path / "phone.json")
    entries = []
    for shot, camera in ((photo, tmp_path / "phone.json"), (base / "photo.png", base / "photo.json")):
        out = tmp_path / shot.stem
        argv = ["validate", base / "design", shot, "--camera", camera, "--out", out, "-q", "--jobs", "1"]
        assert main([str(a) for a in argv]) == 0
        entries.append(json.loads((out / "validation.json").read_text())["photos"][0])
    turned, upright_entry = entries
    assert turned["exif_orientation"] == 8 and upright_entry["exif_orientation"] == 1
    assert "px, the camera profile is for" not in (turned["reason"] or "")
    assert turned["pose"] == upright_entry["pose"] and turned["reason"] == upright_entry["reason"]


def test_a_view_image_stored_sideways_prints_as_the_upright_one(base, tmp_path):
    job = tmp_path / "job"
    shutil.copytree(base, job, ignore=shutil.ignore_patterns("design", "photo*"))
    rgb = cv2.cvtColor(cv2.imread(str(job / "top.png")), cv2.COLOR_BGR2RGB)
    (job / "top.png").write_bytes(with_orientation(np.ascontiguousarray(np.rot90(rgb, 1)), 6))
    assert main(["design", str(job / "job.toml"), "--out", str(tmp_path / "d"), "-q"]) == 0
    assert (tmp_path / "d" / "print.png").read_bytes() == (base / "design" / "print.png").read_bytes()
    assert json.loads((tmp_path / "d" / "design.json").read_text())["view_image_orientation"] == [6]


def test_a_pngs_exif_after_its_image_data_is_read_without_decoding_it():
    # Pillow decodes a whole PNG to find its EXIF; the chunk is found by the chunks' headers, before
    # or after the image data (the PNG specification allows both)
    rgb = np.random.default_rng(1).integers(0, 256, (5, 7, 3), dtype=np.uint8)
    data = with_orientation(rgb, 6)
    chunks, at = [], 8
    while at < len(data):
        n = int.from_bytes(data[at : at + 4], "big")
        chunks.append(data[at : at + 12 + n])
        at += 12 + n
    kinds = [c[4:8] for c in chunks]
    exif = chunks.pop(kinds.index(b"eXIf"))
    moved = data[:8] + b"".join(chunks[:-1]) + exif + chunks[-1]  # just before IEND
    assert exif_orientation(moved) == 6
    assert exif_orientation(data[:8] + b"".join(chunks)) == 1  # none
