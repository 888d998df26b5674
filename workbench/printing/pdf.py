"""The calibrated print PDF: the design at true size, bleed, crop and registration marks, scale bars.

The print PDF is a PDF/X-4 (ISO 15930-7) file, what a print shop's preflight expects: PDF 1.6,
an OutputIntent (``GTS_PDFX``) carrying the output ICC profile, XMP metadata naming PDF/X-4,
every font embedded (DejaVu Sans, shipped with matplotlib), the print image ICC-tagged
(sRGB, for late binding in the RIP) or converted to CMYK through the output profile, the
marks in black ink only, and the cut line a spot colour that overprints. ReportLab writes
the page; :func:`pdfx` adds with pikepdf what ReportLab cannot write.
"""

from __future__ import annotations

import datetime
import io
import os
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

from workbench import __version__, schemas
from workbench.environment import source_date_epoch
from workbench.jsonfile import read_json
from workbench.printing.paper import choose_sheet
from workbench.texture.outline import bleed_beyond_outline

PT_PER_MM = 72.0 / 25.4
LINE_PT = 0.25  # hairline marks: about 2 px wide at 600 dpi, easy to measure
CROP_LEN_MM = 6.0
REG_RADIUS_MM = 3.0
BAR_MM = 100.0
CHECK_MM = 10.0


@dataclass(frozen=True)
class PrinterProfile:
    """How a printer scales what it prints: printed length / intended length, per axis.

    Attributes
    ----------
    name : str
        Shown on the page.
    scale_x, scale_y : float
        For example 1.015: the printer prints x 1.5 % too long.
    path : Path or None
        Where it was read from.
    """

    name: str = "none"
    scale_x: float = 1.0
    scale_y: float = 1.0
    path: Path | None = None


def load_printer_profile(path: str | Path) -> PrinterProfile:
    """Read a printer profile (JSON written by ``workbench calibrate printer``).

    Raises
    ------
    WorkbenchError
        Missing, not JSON, or a key missing or out of range; names the file and key.
    """
    path = Path(path)
    data = read_json(path, "printer profile", schemas.PRINTER_PROFILE)
    return PrinterProfile(
        name=data["name"] or path.stem, path=path, scale_x=float(data["scale_x"]), scale_y=float(data["scale_y"])
    )


@dataclass(frozen=True)
class PrintSheet:
    """Where everything goes, in physical millimetres on the sheet (y up, origin bottom-left).

    Attributes
    ----------
    paper : str
        Sheet name and orientation.
    page_w, page_h : float
        Sheet size, mm.
    trim : (x0, y0, x1, y1)
        The design rectangle.
    bleed_mm : float
        How far the texture extends beyond the trim.
    """

    paper: str
    page_w: float
    page_h: float
    trim: tuple[float, float, float, float]
    bleed_mm: float

    @property
    def bar_x(self) -> tuple[float, float]:
        """Start (left end) of the horizontal 100 mm bar, below the trim and below the vertical bar's end."""
        x0, y0, _, y1 = self.trim
        return x0, min(y0, y1 - BAR_MM) - self.bleed_mm - 12.0

    @property
    def bar_y(self) -> tuple[float, float]:
        """Start (top end) of the vertical 100 mm bar: it counts down from the trim's top edge, y down as the design."""
        x0, y1 = self.trim[0], self.trim[3]
        return x0 - self.bleed_mm - 12.0, y1

    @property
    def check_square(self) -> tuple[float, float]:
        """Bottom-left corner of the 10 mm check square."""
        bx, by = self.bar_y
        cx, cy = self.bar_x
        return bx - 6.0 - CHECK_MM, cy - 6.0 - CHECK_MM


def layout_sheet(width_mm: float, height_mm: float, bleed_mm: float, margin_mm: float, paper) -> PrintSheet:
    """Place a design rectangle and its marks on a sheet.

    Around the trim: crop marks beyond the bleed, registration crosshairs mid-side,
    a horizontal 100 mm bar below and a vertical one on the left (counting down from the
    trim's top edge), the check square in the corner between them, and a line of text at
    the bottom. The whole block is centred on the sheet.

    Parameters
    ----------
    width_mm, height_mm : float
        Design rectangle.
    bleed_mm, margin_mm : float
        Bleed around the trim; free border to the sheet's edge.
    paper : str or (w, h)
        See :func:`workbench.printing.paper.choose_sheet`.

    Returns
    -------
    PrintSheet
    """
    b = bleed_mm
    left = b + 12.0 + 6.0 + CHECK_MM  # vertical bar, its labels, the check square
    bottom = b + 12.0 + 6.0 + CHECK_MM + 6.0  # bar, labels, check square, text line
    right = top = b + 1.0 + CROP_LEN_MM + REG_RADIUS_MM
    span_w = left + max(width_mm, BAR_MM) + right
    span_h = bottom + max(height_mm, BAR_MM) + top
    paper_name, pw, ph = choose_sheet(paper, span_w + 2 * margin_mm, span_h + 2 * margin_mm)
    x0 = (pw - span_w) / 2 + left
    # the trim's top edge: the vertical bar hangs 100 mm from it, so on a print shorter than
    # the bar the marks below start under the bar's end
    y1 = (ph - span_h) / 2 + bottom + max(height_mm, BAR_MM)
    return PrintSheet(paper_name, pw, ph, (x0, y1 - height_mm, x0 + width_mm, y1), bleed_mm)


def build_date() -> str:
    """Date printed on pages: SOURCE_DATE_EPOCH when set (reproducible builds), else today (UTC)."""
    epoch = source_date_epoch(os.environ)
    now = datetime.datetime.now(datetime.UTC)
    when = datetime.datetime.fromtimestamp(epoch, datetime.UTC) if epoch is not None else now
    return when.strftime("%Y-%m-%d")


class _Page:
    """A ReportLab canvas drawn in physical mm, pre-compensated for the printer's scale."""

    def __init__(self, canvas, sheet_w: float, sheet_h: float, profile: PrinterProfile):
        self.c, self.w, self.h, self.p = canvas, sheet_w, sheet_h, profile
        # scale about the sheet's centre by 1 / (printer scale): the printer's own
        # scaling then brings every length back to its intended size
        c = canvas
        c.translate(sheet_w / 2 * PT_PER_MM, sheet_h / 2 * PT_PER_MM)
        c.scale(PT_PER_MM / profile.scale_x, PT_PER_MM / profile.scale_y)
        c.translate(-sheet_w / 2, -sheet_h / 2)
        c.setLineWidth(LINE_PT / PT_PER_MM)
        # marks and text in the black ink alone: a hairline on four plates would not register
        c.setStrokeColorCMYK(0, 0, 0, 1)
        c.setFillColorCMYK(0, 0, 0, 1)

    def to_pdf(self, x: float, y: float) -> tuple[float, float]:
        """Physical mm on the sheet → PDF points (what page boxes are given in)."""
        return (
            (self.w / 2 + (x - self.w / 2) / self.p.scale_x) * PT_PER_MM,
            (self.h / 2 + (y - self.h / 2) / self.p.scale_y) * PT_PER_MM,
        )

    def box(self, x0: float, y0: float, x1: float, y1: float) -> tuple[float, float, float, float]:
        return (*self.to_pdf(x0, y0), *self.to_pdf(x1, y1))

    def line(self, x0, y0, x1, y1):
        self.c.line(x0, y0, x1, y1)

    def text(self, x, y, s, size=2.2, anchor="left"):
        self.c.setFont(embedded_font(), size)
        {"left": self.c.drawString, "centre": self.c.drawCentredString, "right": self.c.drawRightString}[anchor](
            x, y, s
        )


def crop_marks(page: _Page, trim, bleed_mm: float) -> None:
    """Marks on the extensions of the trim lines, outside the bleed, at the four corners."""
    x0, y0, x1, y1 = trim
    g = bleed_mm + 1.0
    for x, sx in ((x0, -1), (x1, 1)):
        for y, sy in ((y0, -1), (y1, 1)):
            page.line(x, y + sy * g, x, y + sy * (g + CROP_LEN_MM))
            page.line(x + sx * g, y, x + sx * (g + CROP_LEN_MM), y)


def registration_marks(page: _Page, trim, bleed_mm: float) -> None:
    """Crosshair and circle at the middle of each side, outside the bleed."""
    x0, y0, x1, y1 = trim
    d = bleed_mm + 1.0 + REG_RADIUS_MM
    xm, ym = (x0 + x1) / 2, (y0 + y1) / 2
    for cx, cy in ((xm, y1 + d), (x1 + d, ym), (xm, y0 - d), (x0 - d, ym)):
        page.c.circle(cx, cy, REG_RADIUS_MM * 0.6, stroke=1, fill=0)
        page.line(cx - REG_RADIUS_MM, cy, cx + REG_RADIUS_MM, cy)
        page.line(cx, cy - REG_RADIUS_MM, cx, cy + REG_RADIUS_MM)


def orientation_mark(page: _Page, trim, bleed_mm: float, where: str) -> None:
    """Which way the film goes on the part: an arrow and "this edge: WHERE" above the trim's top edge, outside the
    bleed, between the top-left crop mark and the registration mark."""
    x0, _, _, y1 = trim
    x, y = x0 + 2.0, y1 + bleed_mm + 1.5
    path = page.c.beginPath()  # a small arrow pointing at the edge
    path.moveTo(x, y + 2.2)
    path.lineTo(x + 2.0, y + 2.2)
    path.lineTo(x + 1.0, y + 0.4)
    path.close()
    page.c.drawPath(path, stroke=0, fill=1)
    page.text(x + 3.0, y + 0.6, f"this edge: {where}", size=2.6)


def scale_bar(page: _Page, x: float, y: float, vertical: bool) -> None:
    """A 100 mm bar with mm ticks (long every 10 mm, labelled) from (x, y): rightwards, or down when vertical."""

    # the vertical bar runs down the page from (x, y): its millimetres count y down, as the
    # design's, every figure's and every defect position's do
    def seg(a0, b0, a1, b1):
        page.line(x + b0, y - a0, x + b1, y - a1) if vertical else page.line(x + a0, y - b0, x + a1, y - b1)

    seg(0.0, 0.0, BAR_MM, 0.0)
    for mm in range(int(BAR_MM) + 1):
        length = 4.0 if mm % 10 == 0 else (2.5 if mm % 5 == 0 else 1.5)
        seg(mm, 0.0, mm, -length if vertical else length)
        if mm % 10 == 0:
            if vertical:
                page.text(x - 5.5, y - mm - 0.7, f"{mm}", anchor="right")
            else:
                page.text(x + mm, y - 7.0, f"{mm}", anchor="centre")
    label = "100 mm" if not vertical else ""
    if label:
        page.text(x + BAR_MM + 2.0, y - 1.0, label)


def check_square(page: _Page, x: float, y: float) -> None:
    """A 10 mm square outline with its size written under it."""
    page.c.rect(x, y, CHECK_MM, CHECK_MM, stroke=1, fill=0)
    page.text(x + CHECK_MM / 2, y - 3.0, "10 mm", size=1.8, anchor="centre")


FONT = "DejaVuSans"


def embedded_font() -> str:
    """The name of the text font, registered with ReportLab as an embedded TrueType font.

    DejaVu Sans ships with matplotlib (a dependency; its licence allows embedding and
    redistribution). ReportLab embeds the subset of glyphs a document uses; the standard
    14 fonts (Helvetica) would not be embedded, which PDF/X forbids.
    """
    from reportlab.pdfbase import pdfmetrics
    from reportlab.pdfbase.ttfonts import TTFont

    if FONT not in pdfmetrics.getRegisteredFontNames():
        import matplotlib

        pdfmetrics.registerFont(
            TTFont(FONT, str(Path(matplotlib.get_data_path()) / "fonts" / "ttf" / "DejaVuSans.ttf"))
        )
    return FONT


# The spot colour print-and-cut workflows cut along (its on-screen stand-in: magenta).
CUT_SPOT = "CutContour"
CUT_LINE_MM = 0.1


# the cut line's optional content group (layer) and its name in the page's resources
CUT_LAYER = "CutContour"
_CUT_LAYER_RESOURCE = "OCCut"


def _cut_layer(canvas) -> None:
    """Declare the optional content group (layer) of the cut line in the document.

    ReportLab (4.x) has no optional-content API, so the group is added to its object
    tree directly: the OCG object, the catalog's ``/OCProperties`` (the layer listed
    and on), and, after the page is finished, the page resources' ``/Properties``
    entry that the marked content ``/OC /OCCut BDC … EMC`` refers to. PDF 1.5.
    """
    from reportlab.pdfbase import pdfdoc

    doc = canvas._doc
    if getattr(doc, "_workbench_cut_layer", False):
        return  # declared once per document; every page gets the resource entry
    doc._workbench_cut_layer = True
    ocg = doc.Reference(
        pdfdoc.PDFDictionary({"Type": pdfdoc.PDFName("OCG"), "Name": pdfdoc.PDFString(CUT_LAYER)}), "OCGCutContour"
    )
    catalog = doc.Catalog
    # the catalog writes only the keys it lists; an instance list adds ours
    catalog.__NoDefault__ = [*type(catalog).__NoDefault__, "OCProperties"]
    catalog.OCProperties = pdfdoc.PDFDictionary(
        {
            "OCGs": pdfdoc.PDFArray([ocg]),
            "D": pdfdoc.PDFDictionary(
                {"Name": pdfdoc.PDFString("workbench"), "Order": pdfdoc.PDFArray([ocg]), "ON": pdfdoc.PDFArray([ocg])}
            ),
        }
    )

    def add_to_page(_page_number):
        page = doc.Pages.pages[-1]
        build = page.check_format

        def check_format(document):
            build(document)
            page.Resources.Properties = {_CUT_LAYER_RESOURCE: ocg}

        page.check_format = check_format

    canvas.setPageCallBack(add_to_page)


def cut_line(page: _Page, trim, outline_mm: np.ndarray | None, spot: str = CUT_SPOT) -> None:
    """The cut line: the outline (or the trim) stroked in a spot colour (``CutContour``), on its own layer.

    The stroke overprints (ExtGState ``/OP true``, overprint mode 1): the process plates
    under it keep the print, so a RIP that strips the cut plate leaves no white hairline.
    """
    from reportlab.lib.colors import CMYKColorSep

    x0, y0, x1, y1 = trim
    pts = np.array([[0, 0], [x1 - x0, 0], [x1 - x0, y1 - y0], [0, y1 - y0]]) if outline_mm is None else outline_mm
    c = page.c
    _cut_layer(c)
    c.addLiteral(f"/OC /{_CUT_LAYER_RESOURCE} BDC")
    c.saveState()
    c.setStrokeColor(CMYKColorSep(0, 1, 0, 0, spotName=spot, density=1))
    c.setStrokeOverprint(True)
    c.setOverprintMask(1)
    c.setLineWidth(CUT_LINE_MM)
    c.setLineJoin(1)
    path = c.beginPath()
    path.moveTo(x0 + pts[0, 0], y0 + pts[0, 1])
    for x, y in pts[1:]:
        path.lineTo(x0 + x, y0 + y)
    path.close()
    c.drawPath(path, stroke=1, fill=0)
    c.restoreState()
    c.addLiteral("EMC")


def print_pdf(
    rgb: np.ndarray,
    dpi: float,
    width_mm: float,
    height_mm: float,
    job_name: str,
    job_sha256: str,
    paper,
    bleed_mm: float = 3.0,
    margin_mm: float = 10.0,
    profile: PrinterProfile = PrinterProfile(),
    outline_mm: np.ndarray | None = None,
    cut: bool = True,
    film: np.ndarray | None = None,
    pdfx: PdfxOptions | None = None,
) -> tuple[bytes, PrintSheet]:
    """The print PDF of a design.

    Parameters
    ----------
    rgb : (rows, cols, 3) uint8
        The print texture; pixel (i, j) centre at ((j + 0.5), (i + 0.5)) · 25.4 / dpi
        mm from the trim's top-left corner.
    dpi : float
        Its resolution.
    width_mm, height_mm : float
        The design rectangle (the trim).
    job_name, job_sha256 : str
        Printed on the page and stored in the metadata.
    paper : str or (w, h)
        Sheet, or ``'auto'``.
    bleed_mm, margin_mm : float
        Texture beyond the trim; free border to the sheet's edge.
    profile : PrinterProfile
        Printer scale to pre-compensate.
    outline_mm : (k, 2) float, optional
        The film's outline in the design's flat coordinates (mm, x right, y up, the
        trim's bottom-left corner at the origin), a closed polygon; None: the trim.
    cut : bool
        Draw the outline as the cut line: a hairline stroked in the spot colour
        ``CutContour`` (the name print-and-cut workflows look for), at true scale,
        on its own layer (optional content group) named ``CutContour``.
    film : (rows, cols) bool, optional
        The pixels inside the film's outline (a free outline); the bleed then follows
        the outline (nearest pixel inside repeated outward) and nothing is printed
        beyond it. None: the film is the whole rectangle.
    pdfx : PdfxOptions, optional
        Output profile, colour conversion and cut spot name (default: :class:`PdfxOptions`).

    Returns
    -------
    pdf : bytes
        Reproducible: the same inputs (and date) give the same bytes.
    sheet : PrintSheet
        Where everything went (physical mm).
    """
    page = FilmPage(rgb, width_mm, height_mm, outline_mm, film)
    pdf, sheets, _ = print_pdf_pages([page], dpi, job_name, job_sha256, paper, bleed_mm, margin_mm, profile, cut, pdfx)
    return pdf, sheets[0]


@dataclass(frozen=True)
class PdfxOptions:
    """What makes the print PDF a print shop's PDF/X-4.

    Attributes
    ----------
    output_profile : Path or None
        The output ICC profile (the shop's press or printer, CMYK or RGB), carried in the
        OutputIntent. None: :data:`workbench.printing.icc.DEFAULT_CMYK_PROFILE`.
    cmyk : bool
        Convert the print to CMYK through the output profile (relative colorimetric with
        black point compensation) instead of leaving it ICC-tagged sRGB for the RIP.
    max_ink_pct : float
        With ``cmyk``: the most ink a pixel may carry (C + M + Y + K, percent); above it
        C, M and Y are scaled down, K kept.
    cut_spot : str
        The cut line's spot colour name (``CutContour``; ``PerfCutContour`` to perforate).
    """

    output_profile: Path | None = None
    cmyk: bool = False
    max_ink_pct: float = 300.0
    cut_spot: str = CUT_SPOT


@dataclass(frozen=True)
class InkReport:
    """Total ink (C + M + Y + K, percent) over the film's pixels of a CMYK print.

    Attributes
    ----------
    max_pct_before, max_pct : float
        Largest total ink out of the profile, and after the limit.
    p99_pct : float
        99th percentile after the limit.
    limited_share : float
        Share of the film's pixels whose ink the limit reduced.
    max_ink_pct : float
        The limit.
    """

    max_pct_before: float
    max_pct: float
    p99_pct: float
    limited_share: float
    max_ink_pct: float


def limit_ink(cmyk: np.ndarray, max_ink_pct: float) -> np.ndarray:
    """Scale C, M and Y down where C + M + Y + K exceeds the limit (K kept: it holds the shadows' detail).

    Parameters
    ----------
    cmyk : (..., 4) uint8
        Ink coverage, 255 = 100 %.
    max_ink_pct : float
        Limit, percent (at least 100: K alone always fits).

    Returns
    -------
    (..., 4) uint8
        Every pixel at or under the limit (rounded down, never over).
    """
    c = cmyk.astype(np.float64)
    limit = np.floor(max_ink_pct / 100 * 255 + 1e-9)
    cmy, k = c[..., :3], c[..., 3:]
    room = np.maximum(limit - k, 0)
    total = cmy.sum(axis=-1, keepdims=True)
    scaled = cmy * np.where(total > room, room / np.maximum(total, 1e-12), 1.0)
    base = np.floor(scaled + 1e-9)
    # the levels rounding down lost go back to the inks with the largest remainders: the
    # total lands on the limit itself, never above it
    deficit = np.where(total > room, room - base.sum(axis=-1, keepdims=True), 0)
    rank = np.argsort(np.argsort(-(scaled - base), axis=-1), axis=-1)
    base += rank < deficit
    return np.concatenate([base, k], axis=-1).astype(np.uint8)


def _xmp(pdf, title: str) -> None:
    """XMP metadata naming PDF/X-4, consistent with the document information dictionary."""
    import hashlib

    import pikepdf

    # the same document, the same id: reproducible bytes
    doc_id = "uuid:" + hashlib.sha256(title.encode()).hexdigest()[:32]
    with pdf.open_metadata(set_pikepdf_as_editor=False, update_docinfo=False) as meta:
        # ReportLab writes /Trapped, which load_from_docinfo does not map (pdf:Trapped is set below)
        meta.load_from_docinfo({k: v for k, v in pdf.docinfo.items() if k not in ("/Trapped", "/GTS_PDFXVersion")})
        meta["pdfxid:GTS_PDFXVersion"] = "PDF/X-4"
        meta["pdf:Trapped"] = "False"
        meta["xmpMM:DocumentID"] = doc_id
        meta["xmpMM:InstanceID"] = doc_id
        meta["xmpMM:VersionID"] = "1"
        meta["xmpMM:RenditionClass"] = "default"
        meta["xmp:MetadataDate"] = meta["xmp:ModifyDate"]
    # the information dictionary says the same (keys with no XMP twin that load_from_docinfo would know)
    pdf.docinfo[pikepdf.Name.Trapped] = pikepdf.Name("/False")
    pdf.docinfo[pikepdf.Name.GTS_PDFXVersion] = pikepdf.String("PDF/X-4")


def finish_pdfx(data: bytes, opts: PdfxOptions) -> tuple[bytes, InkReport | None]:
    """Make ReportLab's PDF a PDF/X-4: OutputIntent, ICC-tagged or CMYK images, XMP.

    Parameters
    ----------
    data : bytes
        The PDF ReportLab wrote (PDF 1.6, fonts embedded, marks in DeviceCMYK).
    opts : PdfxOptions
        Output profile, CMYK conversion, ink limit.

    Returns
    -------
    pdf : bytes
        Reproducible (deterministic document id).
    ink : InkReport or None
        With ``opts.cmyk``.

    Raises
    ------
    WorkbenchError
        The output profile is missing, unreadable, or not for CMYK or RGB output.
    """
    import zlib

    import pikepdf
    from PIL import Image, ImageCms

    from workbench.errors import WorkbenchError
    from workbench.printing import icc

    path = Path(opts.output_profile) if opts.output_profile is not None else icc.DEFAULT_CMYK_PROFILE
    if not path.is_file():
        raise WorkbenchError(f"{path}: no such output profile (--output-profile: the shop's ICC profile)")
    profile = path.read_bytes()
    space, desc = icc.profile_info(profile, str(path))
    if space not in ("CMYK", "RGB"):
        raise WorkbenchError(f"{path}: a {space} profile; the output profile must be for CMYK or RGB output")
    if opts.cmyk and space != "CMYK":
        raise WorkbenchError(f"{path}: an RGB profile; --cmyk needs a CMYK output profile")
    pdf = pikepdf.open(io.BytesIO(data))
    dest = pdf.make_stream(profile, N=4 if space == "CMYK" else 3)
    pdf.Root.OutputIntents = pikepdf.Array(
        [
            pikepdf.Dictionary(
                Type=pikepdf.Name.OutputIntent,
                S=pikepdf.Name.GTS_PDFX,
                OutputConditionIdentifier=pikepdf.String("Custom"),
                OutputCondition=pikepdf.String(desc or path.stem),
                Info=pikepdf.String(desc or path.stem),
                RegistryName=pikepdf.String("http://www.color.org"),
                DestOutputProfile=dest,
            )
        ]
    )
    srgb = pdf.make_stream(icc.srgb_profile(), N=3, Alternate=pikepdf.Name.DeviceRGB)
    srgb_cs = pikepdf.Array([pikepdf.Name.ICCBased, srgb])
    to_cmyk = None
    if opts.cmyk:
        to_cmyk = ImageCms.buildTransform(
            ImageCms.createProfile("sRGB"),
            ImageCms.ImageCmsProfile(io.BytesIO(profile)),
            "RGB",
            "CMYK",
            renderingIntent=ImageCms.Intent.RELATIVE_COLORIMETRIC,
            flags=ImageCms.Flags.BLACKPOINTCOMPENSATION,
        )
    totals, before = [], []
    for page in pdf.pages:
        for img in page.get_images().values():
            if img.get("/ColorSpace") != pikepdf.Name.DeviceRGB:
                continue
            if to_cmyk is None:
                img.ColorSpace = srgb_cs
                continue
            rgb = np.asarray(pikepdf.PdfImage(img).as_pil_image().convert("RGB"))
            cmyk = np.asarray(ImageCms.applyTransform(Image.fromarray(rgb), to_cmyk))
            limited = limit_ink(cmyk, opts.max_ink_pct)
            inside = np.ones(rgb.shape[:2], bool)
            if "/SMask" in img:
                inside = np.asarray(pikepdf.PdfImage(img.SMask).as_pil_image().convert("L")) > 0
            before.append(cmyk[inside].astype(np.int32).sum(axis=1))
            totals.append(limited[inside].astype(np.int32).sum(axis=1))
            img.write(zlib.compress(limited.tobytes(), 6), filter=pikepdf.Name.FlateDecode)
            img.ColorSpace = pikepdf.Name.DeviceCMYK
            for key in ("/DecodeParms", "/Decode"):
                if key in img:
                    del img[key]
    title = str(pdf.docinfo.get("/Title", ""))
    _xmp(pdf, title + str(pdf.docinfo.get("/Subject", "")))
    out = io.BytesIO()
    pdf.save(out, deterministic_id=True, object_stream_mode=pikepdf.ObjectStreamMode.preserve)
    ink = None
    if to_cmyk is not None:
        b = np.concatenate(before) / 2.55 if before else np.zeros(1)
        t = np.concatenate(totals) / 2.55 if totals else np.zeros(1)
        ink = InkReport(
            max_pct_before=float(b.max()),
            max_pct=float(t.max()),
            p99_pct=float(np.percentile(t, 99)),
            limited_share=float(np.mean(t < b - 1e-9)),
            max_ink_pct=opts.max_ink_pct,
        )
    return out.getvalue(), ink


@dataclass(frozen=True)
class FilmPage:
    """One film's page of a print PDF (see :func:`print_pdf` for the fields).

    ``label``: printed on the page, e.g. "film 2 of 5: cheek". ``top_edge``: where the trim's top
    edge goes on the part, printed above it, e.g. "part +y" ("": no mark).
    """

    rgb: np.ndarray
    width_mm: float
    height_mm: float
    outline_mm: np.ndarray | None = None
    film: np.ndarray | None = None
    label: str = ""
    top_edge: str = ""


def print_pdf_pages(
    pages: list[FilmPage],
    dpi: float,
    job_name: str,
    job_sha256: str,
    paper,
    bleed_mm: float = 3.0,
    margin_mm: float = 10.0,
    profile: PrinterProfile = PrinterProfile(),
    cut: bool = True,
    pdfx: PdfxOptions | None = None,
) -> tuple[bytes, list[PrintSheet], InkReport | None]:
    """The print PDF of a design with one page per film (arguments as :func:`print_pdf`).

    Returns
    -------
    pdf : bytes
        A PDF/X-4 file.
    sheets : list of PrintSheet
        Per page.
    ink : InkReport or None
        With ``pdfx.cmyk``: the total ink of the converted print.
    """
    pdfx = pdfx or PdfxOptions()
    from reportlab.pdfgen import canvas as rl_canvas

    buf = io.BytesIO()
    sheets = [layout_sheet(p.width_mm, p.height_mm, bleed_mm, margin_mm, paper) for p in pages]
    c = rl_canvas.Canvas(
        buf,
        pagesize=(sheets[0].page_w * PT_PER_MM, sheets[0].page_h * PT_PER_MM),
        invariant=1,
        pageCompression=1,
        pdfVersion=(1, 6),  # PDF/X-4 is PDF 1.6 (optional content, the cut line's layer: 1.5)
        initialFontName=embedded_font(),  # else every page lists Helvetica, not embedded
    )
    sizes = "; ".join(f"{p.width_mm:.2f} x {p.height_mm:.2f} mm" for p in pages)
    c.setTitle(f"workbench print: {job_name}")
    c.setAuthor(f"workbench {__version__}")
    c.setSubject(f"{job_name}: {sizes} at {dpi:g} dpi; job sha256 {job_sha256}")
    c.setKeywords(f"workbench, print, job={job_name}, sha256={job_sha256}, printer-profile={profile.name}")
    c.setCreator(f"workbench {__version__}")
    c.setViewerPreference("PrintScaling", "None")
    for film_page, sheet in zip(pages, sheets, strict=True):
        c.setPageSize((sheet.page_w * PT_PER_MM, sheet.page_h * PT_PER_MM))
        _draw_page(c, film_page, sheet, dpi, job_name, job_sha256, bleed_mm, profile, cut, pdfx.cut_spot)
        c.showPage()
    c.save()
    pdf, ink = finish_pdfx(buf.getvalue(), pdfx)
    return pdf, sheets, ink


def _draw_page(c, fp: FilmPage, sheet: PrintSheet, dpi, job_name, job_sha256, bleed_mm, profile, cut, spot) -> None:
    """Everything on one film's page: texture with its bleed, cut line, marks, bars, the note line."""
    from PIL import Image
    from reportlab.lib.utils import ImageReader

    rgb, film, outline_mm, width_mm, height_mm = fp.rgb, fp.film, fp.outline_mm, fp.width_mm, fp.height_mm
    page = _Page(c, sheet.page_w, sheet.page_h, profile)
    x0, y0, x1, y1 = sheet.trim
    b = bleed_mm
    c.setTrimBox(page.box(x0, y0, x1, y1))
    c.setBleedBox(page.box(x0 - b, y0 - b, x1 + b, y1 + b))

    # texture: padded by replication to cover the bleed, placed so that its top-left
    # pixel corner is the trim's top-left corner, clipped to the bleed box
    pitch = 25.4 / dpi
    pad = int(np.ceil(b / pitch)) + 1
    padded = cv2.copyMakeBorder(rgb, pad, pad, pad, pad, cv2.BORDER_REPLICATE)
    if film is not None:
        inside = cv2.copyMakeBorder(film.astype(np.uint8), pad, pad, pad, pad, cv2.BORDER_CONSTANT, value=0) > 0
        filled, alpha = bleed_beyond_outline(padded, inside, b / pitch)
        padded = np.dstack([filled, alpha])  # an RGBA image: ReportLab writes the alpha as a soft mask
    rows, cols = padded.shape[:2]
    c.saveState()
    clip = c.beginPath()
    clip.rect(x0 - b, y0 - b, (x1 - x0) + 2 * b, (y1 - y0) + 2 * b)
    c.clipPath(clip, stroke=0, fill=0)
    c.drawImage(
        ImageReader(Image.fromarray(padded)),
        x0 - pad * pitch,
        y1 + pad * pitch - rows * pitch,
        width=cols * pitch,
        height=rows * pitch,
        mask="auto" if film is not None else None,
    )
    c.restoreState()

    if cut:
        cut_line(page, sheet.trim, outline_mm, spot)
    crop_marks(page, sheet.trim, b)
    registration_marks(page, sheet.trim, b)
    scale_bar(page, *sheet.bar_x, vertical=False)
    scale_bar(page, *sheet.bar_y, vertical=True)
    check_square(page, *sheet.check_square)
    if fp.top_edge:
        orientation_mark(page, sheet.trim, b, fp.top_edge)
    note = (
        (f"{fp.label} | " if fp.label else "")
        + f"{job_name} | {width_mm:.2f} x {height_mm:.2f} mm | {dpi:g} dpi | {build_date()} | job {job_sha256[:12]} | "
        f"printer profile: {profile.name} | print at 100 % (actual size): each bar must measure 100 mm"
    )
    cx, cy = sheet.check_square
    page.text(cx, cy - 7.5, note, size=2.0)
