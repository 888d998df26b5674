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


def make_design(tmp_path, width_mm=100.0, height_mm=60.0, dpi=300.0, square_mm=5.0, stretch_max=None):
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
    if stretch_max is not None:
        info["stretch"] = {"min": 0.9, "p50": 1.0, "max": stretch_max, "weighting": "surface area"}
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
    # the vertical bar hangs from the trim's top edge: its 100 mm tick lies below its 0
    y_at = [sheet.page_h - (cy + (vy - mm - cy) / sy) for mm in (0.0, 100.0)]
    ys = [line_centre(ink, (px(y - 0.4), px(y + 0.4)), cols, "y") for y in y_at]
    return xs[1] - xs[0], ys[1] - ys[0]


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


@pytest.mark.parametrize("height_mm", [60.0, 140.0])
def test_vertical_bar_counts_down_from_the_top_edge(tmp_path, height_mm):
    """The y bar reads as every figure does (y down from the trim's top), clear of the check square."""
    import pypdfium2 as pdfium

    from workbench.printing.pdf import CHECK_MM

    d = make_design(tmp_path, height_mm=height_mm)
    out = tmp_path / "p.pdf"
    assert main(["pdf", str(d), "-o", str(out), "--paper", "A3", "-q"]) == 0
    sheet = layout_sheet(100.0, height_mm, 3.0, 10.0, "A3")
    vx, vy = sheet.bar_y
    assert vy == pytest.approx(sheet.trim[3])  # it starts at the trim's top edge
    text = pdfium.PdfDocument(str(out))[0].get_textpage()
    pt = 72 / 25.4
    for mm in range(0, 101, 10):
        # each label sits left of the bar at its own tick, mm below the top edge (a y-up bar puts
        # "100" 100 mm above the edge, and "0" at the bottom)
        y = vy - mm
        got = text.get_text_bounded(left=(vx - 14) * pt, bottom=(y - 2.0) * pt, right=(vx - 4) * pt, top=(y + 2.0) * pt)
        assert got.strip() == str(mm), (mm, got)
    # the bar's end and its labels stay above the check square and the horizontal bar
    cx, cy = sheet.check_square
    assert vy - 100.0 - 2.0 > cy + CHECK_MM
    assert vy - 100.0 - 2.0 > sheet.bar_x[1]
    square = text.get_text_bounded(left=cx * pt, bottom=cy * pt, right=(cx + CHECK_MM) * pt, top=(cy + CHECK_MM) * pt)
    assert square.strip() == ""


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


# ---------------------------------------------------------------- PDF/X-4 preflight


def preflight(path):
    """What a PDF/X-4 preflight checks, item by item, read with pikepdf (one dict entry per item)."""
    import io

    import pikepdf
    from PIL import ImageCms

    pdf = pikepdf.open(path)
    items = {"version": pdf.pdf_version}
    (intent,) = pdf.Root.OutputIntents
    profile = intent.DestOutputProfile.read_bytes()
    prof = ImageCms.ImageCmsProfile(io.BytesIO(profile)).profile
    items["output_intent"] = (
        str(intent.S),
        prof.device_class,
        prof.xcolor_space.strip(),
        int(intent.DestOutputProfile.N),
    )
    items["output_profile"] = profile
    meta = pdf.open_metadata()
    items["xmp_pdfx"] = meta.get("pdfxid:GTS_PDFXVersion")
    items["trapped"] = (str(pdf.docinfo.get("/Trapped")), meta.get("pdf:Trapped"))
    fonts, images, boxes, cut = [], [], [], []
    for page in pdf.pages:
        for font in page.Resources.Font.values():
            desc = font.DescendantFonts[0].FontDescriptor if "/DescendantFonts" in font else font.get("/FontDescriptor")
            embedded = desc is not None and any(k in desc for k in ("/FontFile", "/FontFile2", "/FontFile3"))
            fonts.append((str(font.BaseFont), embedded))
        for img in page.get_images().values():
            cs = img.ColorSpace
            if isinstance(cs, pikepdf.Array):
                space = ImageCms.ImageCmsProfile(io.BytesIO(cs[1].read_bytes())).profile.xcolor_space.strip()
                images.append((str(cs[0]), space))
            else:
                images.append((str(cs), None))
        boxes.append(("/TrimBox" in page, "/BleedBox" in page))
        # the cut line: the marked content of its layer sets an overprinting ExtGState and a spot colour
        content = (
            page.Contents.read_bytes()
            if not isinstance(page.Contents, pikepdf.Array)
            else b"".join(c.read_bytes() for c in page.Contents)
        )
        ops = pikepdf.parse_content_stream(page)
        inside, gs_op, spots = False, False, []
        for operands, op in ops:
            op = str(op)
            if op == "BDC":
                inside = True
            elif op == "EMC":
                inside = False
            elif inside and op == "gs":
                gs_op |= bool(page.Resources.ExtGState[operands[0]].get("/OP", False))
            elif inside and op == "CS":
                c = page.Resources.ColorSpace[operands[0]]
                spots.append((str(c[0]), str(c[1])))
        cut.append((gs_op, spots))
        items["device_rgb_ops"] = items.get("device_rgb_ops", 0) + sum(str(op) in ("rg", "RG") for _, op in ops)
        assert content
    items.update(fonts=fonts, images=images, boxes=boxes, cut=cut)
    return items


def test_preflight_pdfx4(tmp_path, capsys):
    from workbench.printing.icc import DEFAULT_CMYK_PROFILE

    d = make_design(tmp_path)
    out = tmp_path / "p.pdf"
    assert main(["pdf", str(d), "-o", str(out), "--paper", "A4", "-q"]) == 0
    assert out.read_bytes().startswith(b"%PDF-1.6")
    items = preflight(out)
    assert items["version"] == "1.6"
    assert items["output_intent"] == ("/GTS_PDFX", "prtr", "CMYK", 4)
    assert items["output_profile"] == DEFAULT_CMYK_PROFILE.read_bytes()
    assert items["xmp_pdfx"] == "PDF/X-4"
    assert items["trapped"] == ("/False", "False")
    assert items["fonts"] and all(embedded for _, embedded in items["fonts"]), items["fonts"]
    assert items["images"] == [("/ICCBased", "RGB")]  # the print, sRGB for late binding
    assert items["boxes"] == [(True, True)]
    assert items["cut"] == [(True, [("/Separation", "/CutContour")])]
    assert items["device_rgb_ops"] == 0  # marks and text in DeviceCMYK black, no uncalibrated RGB


def test_preflight_cmyk_ink_limit_spot_name_and_shop_profile(tmp_path, capsys):
    import shutil

    import pikepdf

    from workbench.printing.icc import DEFAULT_CMYK_PROFILE

    d = make_design(tmp_path)
    shop = tmp_path / "shop.icc"
    shutil.copy(DEFAULT_CMYK_PROFILE, shop)
    out = tmp_path / "p.pdf"
    args = ["pdf", str(d), "-o", str(out), "--paper", "A4", "--output-profile", str(shop), "--cmyk"]
    assert main([*args, "--max-ink", "250", "--cut-spot-name", "PerfCutContour"]) == 0
    err = capsys.readouterr().err
    # the checker's black out of the profile (black point compensated) is 307 %: the limit takes it to 250 %
    assert "total ink at most 250 % (limit 250 %; 307 % out of the profile" in err
    items = preflight(out)
    assert items["images"] == [("/DeviceCMYK", None)] and items["output_intent"][2] == "CMYK"
    assert items["cut"] == [(True, [("/Separation", "/PerfCutContour")])]
    doc = pikepdf.open(out)
    img = next(iter(doc.pages[0].get_images().values()))
    cmyk = np.asarray(pikepdf.PdfImage(img).as_pil_image()).astype(int)
    total = cmyk.sum(axis=2) / 2.55
    assert total.max() <= 250.0 and total.max() > 248.0
    # white stays paper; the limit takes C, M and Y down and leaves K as the profile separated it
    free = tmp_path / "free.pdf"
    assert main([*args, "-o", str(free), "--max-ink", "400", "-q"]) == 0
    doc_free = pikepdf.open(free)
    unlimited = np.asarray(pikepdf.PdfImage(next(iter(doc_free.pages[0].get_images().values()))).as_pil_image())
    assert (total == 0).any()
    np.testing.assert_array_equal(cmyk[..., 3], unlimited[..., 3])
    assert unlimited.astype(int).sum(axis=2).max() / 2.55 > 300


def test_limit_ink_keeps_black_and_never_exceeds():
    from workbench.printing.pdf import limit_ink

    cmyk = np.array([[255, 255, 255, 255], [100, 50, 20, 0], [200, 200, 200, 229], [0, 0, 0, 255]], np.uint8)
    out = limit_ink(cmyk, 300.0).astype(int)
    assert (out.sum(axis=1) <= 765).all()
    np.testing.assert_array_equal(out[:, 3], cmyk[:, 3])  # K kept
    np.testing.assert_array_equal(out[1], cmyk[1])  # under the limit: untouched
    assert out[0].sum() >= 763 and out[2].sum() >= 763  # limited to the limit, not below


@pytest.mark.parametrize(
    ("stretch", "args", "warned"), [(3.0, [], True), (1.5, [], False), (1.5, ["--min-ppi", "250"], True)]
)
def test_effective_resolution_warning(tmp_path, capsys, stretch, args, warned):
    d = make_design(tmp_path, stretch_max=stretch)
    out = tmp_path / "p.pdf"
    assert main(["pdf", str(d), "-o", str(out), "--paper", "A4", "-q", *args]) == 0
    err = capsys.readouterr().err
    ppi = 300 / stretch
    assert (f"the print's 300 dpi is {ppi:.0f} ppi on the part where the film stretches most" in err) == warned


@pytest.mark.parametrize(
    ("args", "fragment"),
    [
        (["--output-profile", "MISSING"], "no such output profile"),
        (["--output-profile", "NOTICC"], "not an ICC profile LittleCMS can read"),
        (["--output-profile", "SRGB", "--cmyk"], "--cmyk needs a CMYK output profile"),
        (["--max-ink", "50", "--cmyk"], "--max-ink 50: must be between 100 and 400"),
        (["--cut-spot-name", "Cut Contour"], "--cut-spot-name 'Cut Contour': give a plain name"),
    ],
)
def test_pdfx_bad_input(tmp_path, capsys, args, fragment):
    from workbench.printing.icc import srgb_profile

    d = make_design(tmp_path)
    (tmp_path / "bad.icc").write_bytes(b"not a profile")
    (tmp_path / "srgb.icc").write_bytes(srgb_profile())
    subst = {
        "MISSING": str(tmp_path / "none.icc"),
        "NOTICC": str(tmp_path / "bad.icc"),
        "SRGB": str(tmp_path / "srgb.icc"),
    }
    out = tmp_path / "p.pdf"
    assert main(["pdf", str(d), "-o", str(out), "-q", *[subst.get(a, a) for a in args]]) != 0
    err = capsys.readouterr().err.strip()
    assert fragment in err and len(err.splitlines()) == 1 and not out.exists()


def test_default_profile_is_reproducible_and_models_pt1():
    from PIL import Image, ImageCms

    from workbench.printing import icc

    assert icc.build_cmyk_profile() == icc.DEFAULT_CMYK_PROFILE.read_bytes()
    # the profile's A2B0 through LittleCMS (absolute colorimetric): paper and solids at their ISO aims
    t = ImageCms.buildTransform(
        ImageCms.ImageCmsProfile(str(icc.DEFAULT_CMYK_PROFILE)),
        ImageCms.createProfile("LAB"),
        "CMYK",
        "LAB",
        renderingIntent=ImageCms.Intent.ABSOLUTE_COLORIMETRIC,
    )
    inks = np.array([[[0, 0, 0, 0], [255, 0, 0, 0], [0, 255, 0, 0], [0, 0, 255, 0], [0, 0, 0, 255]]], np.uint8)
    lab = np.asarray(ImageCms.applyTransform(Image.fromarray(inks, "CMYK"), t)).astype(np.float64)[0]
    lab = np.column_stack([lab[:, 0] / 2.55, lab[:, 1:].astype(np.uint8).view(np.int8)])
    aims = [icc.PT1_LAB[k] for k in ("paper", "C", "M", "Y")]
    # within 1.5 CIEDE2000 of the aims (the surface reflection takes a little chroma); the black
    # solid carries that floor: a little lighter than the ink's own 16
    import colour

    assert colour.delta_E(lab[:4], np.array(aims), method="CIE 2000").max() < 1.5
    assert 16.0 <= lab[4, 0] <= 22.0


@pytest.mark.slow
def test_cut_overprints_the_process_plates(tmp_path):
    """ghostscript's separations: under the cut line the C, M, Y, K plates are those of the PDF without the cut."""
    import shutil
    import subprocess

    from PIL import Image

    gs = shutil.which("gs")
    if gs is None:
        pytest.skip("ghostscript (gs) is not installed: apt-get install ghostscript")
    d = make_design(tmp_path, square_mm=2.0)
    plates = {}
    for tag, extra in (("cut", []), ("bare", ["--no-cut"])):
        out = tmp_path / f"{tag}.pdf"
        assert main(["pdf", str(d), "-o", str(out), "--paper", "A4", "-q", *extra]) == 0
        subprocess.run(
            [
                gs,
                "-q",
                "-dNOPAUSE",
                "-dBATCH",
                "-sDEVICE=tiffsep",
                "-r600",
                f"-sOutputFile={tmp_path / tag}%d.tif",
                out,
            ],
            check=True,
        )
        plates[tag] = {
            c: 255 - np.asarray(Image.open(tmp_path / f"{tag}1({c}).tif"), dtype=int)
            for c in ("Cyan", "Magenta", "Yellow", "Black")
        }
    cut = np.asarray(Image.open(tmp_path / "cut1(CutContour).tif"), dtype=int) < 128
    assert cut.sum() > 10_000  # the line is there: 2 x 160 mm at 600 dpi, about 0.1 mm wide
    for c in ("Cyan", "Magenta", "Yellow", "Black"):
        under, bare = plates["cut"][c][cut], plates["bare"][c][cut]
        assert bare.mean() > 20  # the checker's black puts ink of every plate along the cut
        assert np.abs(under - bare).max() <= 2, c  # not knocked out


def write_layout(d, to_mesh, width_mm=100.0, height_mm=60.0):
    """A flat layout (flat.obj, mm, y up) of the print's rectangle and the part it lands on (decorated.obj:
    each flat point (x, y) at ``to_mesh(x, y)``), the same vertices."""
    xs, ys = np.linspace(0, width_mm, 3), np.linspace(0, height_mm, 3)
    flat = [(x, y) for y in ys for x in xs]
    faces = [(r * 3 + c + 1, r * 3 + c + 2, r * 3 + c + 5) for r in range(2) for c in range(2)]
    faces += [(r * 3 + c + 1, r * 3 + c + 5, r * 3 + c + 4) for r in range(2) for c in range(2)]
    tail = "".join(f"f {a} {b} {c}\n" for a, b, c in faces)
    (d / "flat.obj").write_text("".join(f"v {x} {y} 0\n" for x, y in flat) + tail)
    (d / "decorated.obj").write_text("".join("v {} {} {}\n".format(*to_mesh(x, y)) for x, y in flat) + tail)


@pytest.mark.parametrize(
    "to_mesh, where",
    [
        (lambda x, y: (x, y, 0.0), "part +y"),  # laid flat as printed
        (lambda x, y: (-x, -y, 0.0), "part -y"),  # turned half a turn
        (lambda x, y: (y, -x, 0.0), "part +x"),  # a quarter turn clockwise: the print's top towards +x
        (lambda x, y: (x, 0.0, y), "part +z"),  # standing up, as on a box's front
    ],
)
def test_the_print_says_where_its_top_edge_goes(tmp_path, to_mesh, where):
    d = make_design(tmp_path)
    write_layout(d, to_mesh)
    out = tmp_path / "p.pdf"
    assert main(["pdf", str(d), "-o", str(out), "-q"]) == 0
    import pypdfium2 as pdfium

    page = pdfium.PdfDocument(str(out))[0]
    text = page.get_textpage().get_text_range()
    assert f"this edge: {where}" in text and text.count("this edge:") == 1
