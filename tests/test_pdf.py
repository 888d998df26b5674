"""workbench pdf: rasterised at 600 dpi by a real PDF renderer and measured."""

from __future__ import annotations

import json

import numpy as np
import pytest

from workbench.cli import main
from workbench.export import png_bytes
from workbench.printing.pdf import layout_sheet

DPI = 600
PX_PER_MM = DPI / 25.4


def make_design(tmp_path, width_mm=100.0, height_mm=60.0, dpi=300.0, square_mm=5.0):
    """A design directory whose print is a black/white checker of square_mm squares."""
    d = tmp_path / "design"
    d.mkdir()
    cols, rows = int(np.ceil(width_mm * dpi / 25.4)), int(np.ceil(height_mm * dpi / 25.4))
    jj, ii = np.meshgrid(np.arange(cols), np.arange(rows))
    # pixel centres at (j + 0.5) * 25.4 / dpi mm
    odd = ((((jj + 0.5) * 25.4 / dpi) // square_mm) + (((ii + 0.5) * 25.4 / dpi) // square_mm)) % 2 == 1
    rgb = np.where(odd[..., None], 0, 255).astype(np.uint8).repeat(3, axis=2)
    (d / "print.png").write_bytes(png_bytes(rgb, dpi))
    info = {
        "job": {"name": "checker", "sha256": "ab" * 32},
        "print": {
            "width_mm": width_mm,
            "height_mm": height_mm,
            "dpi": dpi,
            "width_px": cols,
            "height_px": rows,
            "bleed_mm": 3.0,
            "margin_mm": 10.0,
        },
    }
    (d / "design.json").write_text(json.dumps(info))
    return d


def render(pdf_path):
    import pypdfium2 as pdfium

    doc = pdfium.PdfDocument(str(pdf_path))
    img = np.asarray(doc[0].render(scale=DPI / 72, grayscale=True).to_pil().convert("L"), dtype=np.float64)
    return 255.0 - img  # ink


def line_centre(ink, rows, cols, axis):
    """Ink-weighted centre (mm from the page's left or top edge) of a line crossing a window."""
    win = ink[rows[0] : rows[1], cols[0] : cols[1]]
    profile = win.sum(axis=0 if axis == "x" else 1)
    profile = np.where(profile > 0.2 * profile.max(), profile, 0)
    idx = np.arange(len(profile)) + (cols[0] if axis == "x" else rows[0])
    # pixel k covers [k, k + 1): its centre is k + 0.5
    return float(((idx + 0.5) * profile).sum() / profile.sum()) / PX_PER_MM


def px(mm):
    return int(round(mm * PX_PER_MM))


def measure_trim(ink, sheet, sx=1.0, sy=1.0):
    """Trim width and height from the crop marks (page y down in the raster)."""
    page_h = sheet.page_h
    x0, y0, x1, y1 = sheet.trim
    cx, cy = sheet.page_w / 2, sheet.page_h / 2

    def pdf_x(x):
        return cx + (x - cx) / sx

    def pdf_y(y):
        return cy + (y - cy) / sy

    g = sheet.bleed_mm + 1.0
    # vertical crop marks above the top edge: window in rows over their length
    top = page_h - pdf_y(y1 + g + 3.0)
    rows = (px(top - 2.0), px(top + 2.0))
    xl = line_centre(ink, rows, (px(pdf_x(x0) - 1.5), px(pdf_x(x0) + 1.5)), "x")
    xr = line_centre(ink, rows, (px(pdf_x(x1) - 1.5), px(pdf_x(x1) + 1.5)), "x")
    # horizontal crop marks left of the left edge
    left = pdf_x(x0 - g - 3.0)
    cols = (px(left - 2.0), px(left + 2.0))
    yb = line_centre(ink, (px(page_h - pdf_y(y0) - 1.5), px(page_h - pdf_y(y0) + 1.5)), cols, "y")
    yt = line_centre(ink, (px(page_h - pdf_y(y1) - 1.5), px(page_h - pdf_y(y1) + 1.5)), cols, "y")
    return xr - xl, yb - yt


def measure_bars(ink, sheet, sx=1.0, sy=1.0):
    """Lengths of the two 100 mm bars between their 0 and 100 ticks."""
    cx, cy = sheet.page_w / 2, sheet.page_h / 2
    bx, by = sheet.bar_x
    # ticks hang below the bar's line (mm 0 and 100 are 4 mm long): window 2..3.5 mm below it
    row_mm = sheet.page_h - (cy + (by - 2.75 - cy) / sy)
    rows = (px(row_mm - 0.7), px(row_mm + 0.7))
    x_at = [cx + (bx + mm - cx) / sx for mm in (0.0, 100.0)]
    xs = [line_centre(ink, rows, (px(x - 0.4), px(x + 0.4)), "x") for x in x_at]
    vx, vy = sheet.bar_y
    col_mm = cx + (vx - 2.75 - cx) / sx
    cols = (px(col_mm - 0.7), px(col_mm + 0.7))
    y_at = [sheet.page_h - (cy + (vy + mm - cy) / sy) for mm in (0.0, 100.0)]
    ys = [line_centre(ink, (px(y - 0.4), px(y + 0.4)), cols, "y") for y in y_at]
    return xs[1] - xs[0], ys[0] - ys[1]


def test_trim_bars_and_texture_at_true_size(tmp_path):
    d = make_design(tmp_path)
    out = tmp_path / "p.pdf"
    assert main(["pdf", str(d), "-o", str(out), "--paper", "A4", "-q"]) == 0
    ink = render(out)
    sheet = layout_sheet(100.0, 60.0, 3.0, 10.0, "A4")
    w, h = measure_trim(ink, sheet)
    assert w == pytest.approx(100.0, abs=0.05) and h == pytest.approx(60.0, abs=0.05)
    bar_x, bar_y = measure_bars(ink, sheet)
    assert bar_x == pytest.approx(100.0, rel=5e-4) and bar_y == pytest.approx(100.0, rel=5e-4)
    # the texture: the checker's 5 mm corners where the trim says (x from the left
    # crop mark, y down from the top one), within 0.1 mm
    x0, y0, x1, y1 = sheet.trim
    top = sheet.page_h - y1
    gray = 255 - ink
    for cx_mm, cy_mm in [(5.0, 5.0), (50.0, 30.0), (95.0, 55.0)]:
        X, Y = px(x0 + cx_mm), px(top + cy_mm)
        win = gray[Y - 40 : Y + 40, X - 40 : X + 40].astype(np.float32)
        # a checker corner: the sign of the quadrant products flips there
        gx = np.diff((win > 127).astype(int), axis=1)
        gy = np.diff((win > 127).astype(int), axis=0)
        col = np.argmax(np.abs(gx).sum(axis=0)) + 0.5 + 0.5  # edge between columns k and k+1 -> x = k + 1
        row = np.argmax(np.abs(gy).sum(axis=1)) + 0.5 + 0.5
        assert abs((X - 40 + col) / PX_PER_MM - (x0 + cx_mm)) < 0.1
        assert abs((Y - 40 + row) / PX_PER_MM - (top + cy_mm)) < 0.1


def test_printer_profile_precompensates(tmp_path):
    d = make_design(tmp_path)
    prof = tmp_path / "laser.json"
    prof.write_text(json.dumps({"name": "lab laser", "scale_x": 1.015, "scale_y": 1.0}))
    out = tmp_path / "p.pdf"
    assert main(["pdf", str(d), "-o", str(out), "--paper", "A4", "--printer-profile", str(prof), "-q"]) == 0
    ink = render(out)
    sheet = layout_sheet(100.0, 60.0, 3.0, 10.0, "A4")
    w, h = measure_trim(ink, sheet, sx=1.015)
    # the PDF is 1.5 % short in x so that the printer's +1.5 % brings it to 100 mm
    assert w == pytest.approx(100.0 / 1.015, rel=5e-4)
    assert h == pytest.approx(60.0, rel=5e-4)
    bar_x, bar_y = measure_bars(ink, sheet, sx=1.015)
    assert bar_x == pytest.approx(100.0 / 1.015, rel=5e-4) and bar_y == pytest.approx(100.0, rel=5e-4)


def test_page_boxes_metadata_and_reproducibility(tmp_path, monkeypatch):
    from pypdf import PdfReader

    monkeypatch.setenv("SOURCE_DATE_EPOCH", "1795000000")
    d = make_design(tmp_path)
    a, b = tmp_path / "a.pdf", tmp_path / "b.pdf"
    for out in (a, b):
        assert main(["pdf", str(d), "-o", str(out), "--paper", "A4", "-q"]) == 0
    assert a.read_bytes() == b.read_bytes()
    reader = PdfReader(str(a))
    page = reader.pages[0]
    sheet = layout_sheet(100.0, 60.0, 3.0, 10.0, "A4")
    pt = 72 / 25.4
    x0, y0, x1, y1 = sheet.trim
    np.testing.assert_allclose([float(v) for v in page.trimbox], [x0 * pt, y0 * pt, x1 * pt, y1 * pt], atol=1e-3)
    np.testing.assert_allclose(
        [float(v) for v in page.bleedbox], [(x0 - 3) * pt, (y0 - 3) * pt, (x1 + 3) * pt, (y1 + 3) * pt], atol=1e-3
    )
    np.testing.assert_allclose([float(v) for v in page.mediabox], [0, 0, 210 * pt, 297 * pt], atol=1e-3)
    meta = reader.metadata
    assert "checker" in meta.title and "ab" * 32 in meta.subject and "sha256=" + "ab" * 32 in meta["/Keywords"]
    assert reader.trailer["/Root"]["/ViewerPreferences"]["/PrintScaling"] == "/None"
    text = page.extract_text()
    assert "print at 100 % (actual size)" in text and "2026-11-18" in text


def test_auto_paper_and_refusal(tmp_path, capsys):
    d = make_design(tmp_path, width_mm=260.0, height_mm=180.0, dpi=50.0)
    out = tmp_path / "p.pdf"
    assert main(["pdf", str(d), "-o", str(out), "--paper", "A4", "-q"]) == 1
    err = capsys.readouterr().err
    assert "A4 is too small: use --paper A3 (or auto)" in err and not out.exists()
    assert main(["pdf", str(d), "-o", str(out), "-q"]) == 0  # auto
    from pypdf import PdfReader

    box = PdfReader(str(out)).pages[0].mediabox
    assert sorted([round(float(box.width) * 25.4 / 72), round(float(box.height) * 25.4 / 72)]) == [297, 420]


@pytest.mark.parametrize(
    ("setup", "args", "fragment", "status"),
    [
        ("none", [], "no such design directory", 1),
        ("design", ["--printer-profile", "PROFILE"], "scale_x: must be a number", 1),
        ("design", ["--printer-profile", "NOPROFILE"], "no such printer profile", 1),
        ("design", ["--paper", "B7"], "--paper 'B7': use A5, A4", 2),
        ("design", ["--paper", "100x50"], "100x50 mm is too small", 1),
        ("nopng", [], "print.png: missing", 1),
    ],
)
def test_bad_input(tmp_path, capsys, setup, args, fragment, status):
    d = tmp_path / "design"
    if setup != "none":
        d = make_design(tmp_path)
    if setup == "nopng":
        (d / "print.png").unlink()
    prof = tmp_path / "bad.json"
    prof.write_text(json.dumps({"scale_x": "big", "scale_y": 1.0}))
    args = [str(prof) if a == "PROFILE" else (str(tmp_path / "missing.json") if a == "NOPROFILE" else a) for a in args]
    out = tmp_path / "p.pdf"
    assert main(["pdf", str(d), "-o", str(out), "-q", *args]) == status
    err = capsys.readouterr().err.strip()
    assert fragment in err and len(err.splitlines()) == 1 and not out.exists()
