"""workbench board: boards rasterised at 600 dpi, detected by OpenCV and measured against their definition."""

from __future__ import annotations

import json

import cv2
import numpy as np
import pytest
from conftest import ROOT

from workbench.calibration import detect_corners
from workbench.cli import main
from workbench.mesh.io import read_mesh
from workbench.printing.boards import CharucoSpec

DPI = 600
PX_PER_MM = DPI / 25.4


def rasterise(pdf_path, dpi=DPI):
    import pypdfium2 as pdfium

    page = pdfium.PdfDocument(str(pdf_path))[0]
    return np.asarray(page.render(scale=dpi / 72, grayscale=True).to_pil().convert("L"))


def detect(img, info):
    if info.get("board") == "chessboard":  # what calibrate reads: numbered from the black top-left square
        px, ids, problem = detect_corners(img, info)
        assert problem is None, problem
        return px, ids
    spec = CharucoSpec.from_definition(info)
    det = cv2.aruco.CharucoDetector(spec.opencv())
    corners, ids, _, _ = det.detectBoard(img)
    assert ids is not None
    return corners.reshape(-1, 2), ids.ravel()


def check_board(pdf, info, dpi=DPI):
    """Detected corners (mm on the sheet) against the definition: absolute and relative."""
    img = rasterise(pdf, dpi)
    px, ids = detect(img, info)
    # OpenCV's pixel centres are at integers: position on the sheet = (px + 0.5) / px_per_mm
    got = (px + 0.5) / (dpi / 25.4)
    key = "corners" if info.get("board") == "chessboard" else "charuco_corners"
    want = np.asarray(info["page_origin_mm"]) + np.asarray(info[key]["board_mm"])[ids]
    n_corners = len(info[key]["ids"])
    assert len(ids) == n_corners
    assert np.abs(got - want).max() <= 0.1
    # scale: the two most distant corners, within 0.05 %
    i, j = np.argmin(want.sum(1)), np.argmax(want.sum(1))
    assert np.linalg.norm(got[i] - got[j]) == pytest.approx(np.linalg.norm(want[i] - want[j]), rel=5e-4)
    return np.abs(got - want).max()


def test_charuco_board(tmp_path):
    out = tmp_path / "c.pdf"
    assert main(["board", "charuco", "--squares", "7x5", "--square-mm", "30", "-o", str(out), "-q"]) == 0
    info = json.loads(out.with_suffix(".json").read_text())
    assert info["kind"] == "charuco" and info["squares"] == [7, 5] and info["marker_mm"] == 22.5
    assert len(info["markers"]["ids"]) == 17
    check_board(out, info)


def test_legacy_charuco_board(tmp_path):
    # an even number of rows: the pre-4.6 layout starts with a white square, today's with a black one
    out = tmp_path / "legacy.pdf"
    assert main(["board", "charuco", "--squares", "8x6", "--square-mm", "25", "--legacy", "-o", str(out), "-q"]) == 0
    info = json.loads(out.with_suffix(".json").read_text())
    assert info["legacy"] is True and info["squares"] == [8, 6]
    check_board(out, info)
    # the first marker sits in the top-left square, where today's layout has a black square
    first = np.asarray(info["markers"]["corners_board_mm"][0])
    assert first[:, 0].max() < 25 and first[:, 1].max() < 25
    # read as today's layout, the markers are found and the corners are not
    img = rasterise(out)
    today = CharucoSpec.from_definition({**info, "legacy": False})
    _, ids, _, mids = cv2.aruco.CharucoDetector(today.opencv()).detectBoard(img)
    assert mids is not None and len(mids) == 24 and (ids is None or len(ids) < 5)


def test_chessboard(tmp_path):
    out = tmp_path / "chess.pdf"
    assert main(["board", "chessboard", "--squares", "10x7", "--square-mm", "20", "-o", str(out), "-q"]) == 0
    info = json.loads(out.with_suffix(".json").read_text())
    assert info["kind"] == "chessboard" and info["board"] == "chessboard" and len(info["corners"]["board_mm"]) == 54
    assert info["corners"]["board_mm"][:2] == [[20.0, 20.0], [40.0, 20.0]]
    # 200 dpi: the chessboard detector's time grows with the image (40 s at 600 dpi)
    assert check_board(out, info, dpi=200) <= 0.1


def test_printer_target_fills_the_sheet(tmp_path):
    out = tmp_path / "t.pdf"
    assert main(["board", "printer-target", "--paper", "A4", "-o", str(out), "-q"]) == 0
    info = json.loads(out.with_suffix(".json").read_text())
    nx, ny = info["squares"]
    assert nx * 15 >= 170 and ny * 15 >= 240  # most of an A4 sheet
    check_board(out, info)


def test_fixture_board_positions_in_the_mesh_frame(tmp_path):
    out = tmp_path / "f.pdf"
    job = ROOT / "fixtures" / "default" / "job.toml"
    assert main(["board", "fixture", str(job), "-o", str(out), "-q"]) == 0
    info = json.loads(out.with_suffix(".json").read_text())
    check_board(out, info)
    V, _ = read_mesh(ROOT / "fixtures" / "default" / "part.obj")
    mesh = np.asarray(info["charuco_corners"]["mesh_mm"])
    board = np.asarray(info["charuco_corners"]["board_mm"])
    o = np.asarray(info["origin_mm"])
    np.testing.assert_allclose(mesh, np.stack([o[0] + board[:, 0], o[1] - board[:, 1], np.full(len(board), o[2])], 1))
    # the plate lies under the part, in the plane of its lowest point, and surrounds it
    assert o[2] == pytest.approx(V[:, 2].min())
    assert mesh[:, 0].min() < V[:, 0].min() and mesh[:, 0].max() > V[:, 0].max()
    assert mesh[:, 1].min() < V[:, 1].min() and mesh[:, 1].max() > V[:, 1].max()
    # the footprint outline is the mesh boundary in the board frame
    fp = np.asarray(info["footprint_board_mm"])
    assert fp[:, 0].min() == pytest.approx(V[:, 0].min() - o[0]) and fp[:, 1].min() == pytest.approx(
        o[1] - V[:, 1].max()
    )


def test_printer_profile_applies_to_boards(tmp_path):
    prof = tmp_path / "p.json"
    prof.write_text(json.dumps({"name": "laser", "scale_x": 1.02, "scale_y": 0.99}))
    out = tmp_path / "c.pdf"
    assert main(["board", "charuco", "-o", str(out), "--printer-profile", str(prof), "-q"]) == 0
    info = json.loads(out.with_suffix(".json").read_text())
    img = rasterise(out)
    px, ids = detect(img, info)
    want = np.asarray(info["charuco_corners"]["board_mm"])[ids]
    got = (px + 0.5) / PX_PER_MM
    # fitted scale per axis between definition and the PDF: 1 / printer scale
    sx = np.polyfit(want[:, 0], got[:, 0], 1)[0]
    sy = np.polyfit(want[:, 1], got[:, 1], 1)[0]
    assert sx == pytest.approx(1 / 1.02, rel=5e-4) and sy == pytest.approx(1 / 0.99, rel=5e-4)


@pytest.mark.parametrize(
    ("args", "fragment", "status"),
    # impossible values of options are usage errors (exit 2), as everywhere (README: exit status)
    [
        (["charuco", "--marker-mm", "40", "--square-mm", "30"], "--marker-mm 40: marker_mm 40 must be", 2),
        (["charuco", "--squares", "2x9"], "at least 3 x 3 squares", 2),
        (["charuco", "--squares", "seven"], "--squares 'seven': give NXxNY", 2),
        (["charuco", "--dictionary", "DICT_9X9_1"], "unknown ArUco dictionary", 2),
        (
            ["charuco", "--square-mm", "60", "--squares", "9x9", "--paper", "A4"],
            "A4 is too small: use --paper A1 (or auto)",
            1,
        ),
        (["fixture"], "board fixture needs the job file", 2),
        (["chessboard", "--legacy"], "--legacy is a ChArUco layout: board chessboard has none", 2),
        (["chessboard", "--marker-mm", "10"], "board chessboard has no markers", 2),
        (["chessboard", "--squares", "2x5"], "a chessboard needs at least 3 x 3 squares", 2),
        (["fixture", "missing.toml"], "no such job file", 1),
    ],
)
def test_bad_input(tmp_path, capsys, args, fragment, status):
    out = tmp_path / "b.pdf"
    assert main(["board", *args, "-o", str(out), "-q"]) == status
    err = capsys.readouterr().err.strip()
    assert fragment in err and len(err.splitlines()) == 1 and not out.exists()


def outline_touching_black(pdf_path) -> tuple[int, float]:
    """The part's red outline on a fixture PDF: its pixels, and the share of them next to a black pixel."""
    import pypdfium2 as pdfium

    page = pdfium.PdfDocument(str(pdf_path))[0]
    rgb = np.asarray(page.render(scale=8 * 25.4 / 72).to_pil().convert("RGB")).astype(int)
    red = (rgb[..., 0] > 150) & (rgb[..., 1] < 100) & (rgb[..., 2] < 100)
    black = cv2.dilate((rgb.max(axis=2) < 80).astype(np.uint8), np.ones((3, 3), np.uint8)).astype(bool)
    return int(red.sum()), float((red & black).sum() / max(red.sum(), 1))


def test_the_parts_outline_shows_over_the_black_squares(tmp_path):
    # red on a white casing: at 8 px per mm no pixel of the red line touches a black square (the default
    # part's outline crosses ten of them; a bare red line touches black along a fifth of its length)
    out = tmp_path / "f.pdf"
    assert main(["board", "fixture", str(ROOT / "fixtures" / "default" / "job.toml"), "-o", str(out), "-q"]) == 0
    n, share = outline_touching_black(out)
    assert n > 2000 and share == 0.0, (n, share)
