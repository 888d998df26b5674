"""Pictures of the dense validation: defects over the print, over a view and over the photo; the coverage map."""

from __future__ import annotations

import cv2
import numpy as np

from workbench.figures import PRINT_X_LABEL, PRINT_Y_LABEL
from workbench.text import ascii_text
from workbench.validate import print_warp

# one colour per state of a print pixel (RGB), in dense's order
STATE_COLOURS = np.array(
    [
        (255, 255, 255),  # off the part
        (150, 150, 150),  # not seen
        (120, 90, 160),  # occluded
        (190, 160, 100),  # too oblique
        (200, 200, 200),  # at the edge of what is seen
        (60, 60, 60),  # deep shadow
        (250, 230, 60),  # highlight
        (150, 200, 150),  # measured: colour only
        (120, 190, 200),  # measured: colour only, detail unresolved
        (70, 170, 90),  # measured: colour and normal shift
        (20, 120, 40),  # measured: colour and full shift
        (220, 30, 30),  # defective
    ],
    dtype=np.uint8,
)
DEFECT_BGR = (0, 0, 255)


def outlines(labels: np.ndarray) -> list[np.ndarray]:
    """Outer contour of each defect, (n, 2) int arrays of (x, y) grid pixels, in defect order."""
    out = []
    for k in range(1, int(labels.max()) + 1):
        cs, _ = cv2.findContours((labels == k).astype(np.uint8), cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_NONE)
        out.append(max(cs, key=len).reshape(-1, 2) if cs else np.zeros((0, 2), int))
    return out


def defects_on_print(warped: np.ndarray, labels: np.ndarray, defects: list, px_per_mm: float) -> np.ndarray:
    """The photo on the print with each defect outlined and numbered, with the print's axes; RGB uint8.

    Parameters
    ----------
    warped : (rows, cols, 3) uint8
        The photo on the print grid.
    labels : (rows, cols) int
        Defect number + 1 per grid pixel.
    defects : list
        The defects (their order numbers them).
    px_per_mm : float
        Grid resolution.

    Returns
    -------
    (H, W, 3) uint8
        The print with its x and y axes in mm (:func:`print_axes_image`).
    """
    img = cv2.cvtColor(warped, cv2.COLOR_RGB2BGR)
    thick = max(1, int(round(px_per_mm * 0.2)))
    for k, c in enumerate(outlines(labels)):
        if len(c):
            cv2.polylines(img, [c.reshape(-1, 1, 2)], True, DEFECT_BGR, thick, cv2.LINE_AA)
            x, y = c.max(axis=0)
            cv2.putText(img, str(k + 1), (int(x) + 3, int(y)), cv2.FONT_HERSHEY_SIMPLEX, 0.6, DEFECT_BGR, 2)
    img = cv2.cvtColor(img, cv2.COLOR_BGR2RGB)
    return print_axes_image(img, px_per_mm, _unit(img.shape[1]))


def coverage_image(state: np.ndarray) -> np.ndarray:
    """States as colours (:data:`STATE_COLOURS`); (rows, cols, 3) uint8 RGB."""
    return STATE_COLOURS[state]


def labels_in_view(labels: np.ndarray, print_mm: np.ndarray, px_per_mm: float) -> np.ndarray:
    """Defect labels of the print grid seen in a view: (H, W) int32 through the view's print coordinates."""
    pm = np.nan_to_num(print_mm, nan=-1e4)
    j = np.round(pm[..., 0] * px_per_mm - 0.5).astype(np.int64)
    i = np.round(pm[..., 1] * px_per_mm - 0.5).astype(np.int64)
    rows, cols = labels.shape
    ok = (i >= 0) & (j >= 0) & (i < rows) & (j < cols)
    out = np.zeros(pm.shape[:2], np.int32)
    out[ok] = labels[i[ok], j[ok]]
    return out


def print_seen_from_view(
    print_rgb: np.ndarray, print_mm: np.ndarray, px_per_mm: float, view_rgb: np.ndarray, where=None
) -> np.ndarray:
    """The part as its print makes it look from a view: the print wherever the view sees it, the view's image elsewhere.

    A view's image is the design's wish for what it owns only; over a part another view
    decorates (a logo on the photo view's sky), the print carries that other view's image,
    and a defect drawn there must be drawn over what is printed there.

    Parameters
    ----------
    print_rgb : (rows, cols, 3) uint8
        The print.
    print_mm : (H, W, 2) float
        Print position (mm, x right, y down from the print's top-left corner) of each view
        pixel; NaN off the part.
    px_per_mm : float
        The print's resolution, pixels per mm.
    view_rgb : (H, W, 3) uint8
        The view's image (kept off the part and off the print).
    where : (H, W) bool, optional
        The view pixels that take the print (by default every one on the print; the border
        pixels beyond it replicated).

    Returns
    -------
    (H, W, 3) uint8
    """
    rows, cols = print_rgb.shape[:2]
    # print pixel (i, j) has its centre at ((j + 0.5), (i + 0.5)) / px_per_mm mm
    mx = np.nan_to_num(print_mm[..., 0] * px_per_mm - 0.5, nan=-1.0)
    my = np.nan_to_num(print_mm[..., 1] * px_per_mm - 0.5, nan=-1.0)
    on = (mx >= -0.5) & (my >= -0.5) & (mx <= cols - 0.5) & (my <= rows - 0.5) if where is None else where
    seen = cv2.remap(
        np.ascontiguousarray(print_rgb[..., :3]), mx.astype(np.float32), my.astype(np.float32),
        cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE,
    )  # fmt: skip
    return np.where(on[..., None], seen, view_rgb)


def defects_on_image(rgb: np.ndarray, labels: np.ndarray) -> np.ndarray:
    """An image (a view) with defect outlines and numbers; (H, W, 3) uint8 RGB."""
    img = cv2.cvtColor(rgb, cv2.COLOR_RGB2BGR)
    for k, c in enumerate(outlines(labels)):
        if len(c):
            cv2.polylines(img, [c.reshape(-1, 1, 2)], True, DEFECT_BGR, 2, cv2.LINE_AA)
            x, y = c.max(axis=0)
            cv2.putText(img, str(k + 1), (int(x) + 3, int(y)), cv2.FONT_HERSHEY_SIMPLEX, 0.6, DEFECT_BGR, 2)
    return cv2.cvtColor(img, cv2.COLOR_BGR2RGB)


def photo_circled(photo: np.ndarray, centres_px: np.ndarray, radii_px: np.ndarray, max_side: int = 2000) -> np.ndarray:
    """The photo (reduced to ``max_side``) with a numbered circle around each defect.

    Parameters
    ----------
    photo : (h, w, 3) uint8
    centres_px : (n, 2) float
        Defect centres in the photo, pixels.
    radii_px : (n,) float
        Circle radii, photo pixels.
    """
    s = min(1.0, max_side / max(photo.shape[:2]))
    img = cv2.resize(photo, None, fx=s, fy=s, interpolation=cv2.INTER_AREA) if s < 1 else photo.copy()
    img = cv2.cvtColor(img, cv2.COLOR_RGB2BGR)
    for k, (c, r) in enumerate(zip(centres_px, radii_px, strict=True)):
        if not np.isfinite(c).all():
            continue
        x, y = int(round((c[0] + 0.5) * s - 0.5)), int(round((c[1] + 0.5) * s - 0.5))
        rr = int(round(max(r * s, 12)))
        cv2.circle(img, (x, y), rr, DEFECT_BGR, 3, cv2.LINE_AA)
        cv2.putText(img, str(k + 1), (x + rr + 4, y), cv2.FONT_HERSHEY_SIMPLEX, 1.0, DEFECT_BGR, 2)
    return cv2.cvtColor(img, cv2.COLOR_BGR2RGB)


def coverage_figure(state: np.ndarray, px_per_mm: float, title: str, defects: list) -> bytes:
    """The print's coverage map with a legend (share of the part per state) and numbered defects, PNG.

    Drawn with OpenCV at the grid's own resolution, as the photos' pictures (matplotlib's import
    and figure took 0.6 to 0.8 s of the command).
    """
    from workbench.export import png_bytes

    img = coverage_image(state).copy()
    u = _unit(img.shape[1])
    for k, d in enumerate(defects):
        # a white disc ringed in red with the defect's number, at its centre
        x, y = (int(round(v * px_per_mm)) for v in d["centre_mm"])
        cv2.circle(img, (x, y), int(11 * u), (255, 255, 255), cv2.FILLED, cv2.LINE_AA)
        cv2.circle(img, (x, y), int(11 * u), (220, 30, 30), max(2, int(2 * u)), cv2.LINE_AA)
        (tw, th), _ = _text_size(str(k + 1), _FONT, 0.45 * u, _weight(u))
        _text(img, str(k + 1), (x - tw // 2, y + th // 2), 0.45 * u, (0, 0, 0), _weight(u))
    img = print_axes_image(img, px_per_mm, u)
    on = state != print_warp.OFF_PART
    n_on = max(int(on.sum()), 1)
    entries = []
    for k, name in enumerate(print_warp.STATE_NAMES):
        if k == print_warp.OFF_PART:
            continue
        share = float((state == k).sum()) / n_on
        if share > 0:
            entries.append((STATE_COLOURS[k], f"{name}: {100 * share:.1f} %"))
    # the legend below the map, in two columns filled one after the other where its lines fit
    col_w = img.shape[1] // 2
    widest = max((_text_size(t, _FONT, 0.45 * u, _weight(u))[0][0] for _, t in entries), default=0)
    line = int(22 * u)
    half = (len(entries) + 1) // 2 if widest + int(80 * u) <= col_w else len(entries)
    legend = np.full((line * max(half, 1) + int(16 * u), img.shape[1], 3), 255, np.uint8)
    for i, (colour, text) in enumerate(entries):
        x0, y0 = int(40 * u) + (i // half) * col_w, int(8 * u) + (i % half) * line
        box = ((x0, y0 + int(4 * u)), (x0 + int(26 * u), y0 + int(15 * u)))
        cv2.rectangle(legend, *box, tuple(int(c) for c in colour), cv2.FILLED)
        _text(legend, text, (x0 + int(34 * u), y0 + int(15 * u)), 0.45 * u, thickness=_weight(u))
    return png_bytes(_titled(np.concatenate([img, legend], axis=0), title, u), compression=1, fast=True)


# the uncovered print: a slide not found (blue), ink gone or a scratch not found (magenta), both (red)
UNCOVERED_COLOURS = {"slide": (40, 90, 220), "ink": (200, 40, 200), "both": (220, 30, 30)}


def uncovered_figure(reference: np.ndarray, uncovered: dict, regions: list, px_per_mm: float, title: str) -> bytes:
    """Where the part's photos cannot find a defect class, over the greyed print, regions numbered; PNG.

    Parameters
    ----------
    reference : (rows, cols, 3) uint8
        The print on the analysis grid.
    uncovered : dict of (rows, cols) bool
        Per class (``slide``, ``ink_gone``, ``scratch``): where it would show and no photo finds it.
    regions : list of dict
        The listed regions (``centre_mm``), numbered from 1 as in validation.json.
    px_per_mm : float
        Grid resolution.
    title : str
    """
    from workbench.export import png_bytes

    grey = cv2.cvtColor(reference, cv2.COLOR_RGB2GRAY) // 2 + 128
    img = np.repeat(grey[..., None], 3, axis=2)
    slide = uncovered["slide"]
    ink = uncovered["ink_gone"] | uncovered["scratch"]
    for mask, key in ((slide & ~ink, "slide"), (ink & ~slide, "ink"), (slide & ink, "both")):
        img[mask] = (0.35 * img[mask] + 0.65 * np.asarray(UNCOVERED_COLOURS[key])).astype(np.uint8)
    u = _unit(img.shape[1])
    for k, r in enumerate(regions):
        x, y = (int(round(v * px_per_mm)) for v in r["centre_mm"])
        _text(img, str(k + 1), (x, y), 0.5 * u, (0, 0, 0), _weight(u), outline=True)
    img = print_axes_image(img, px_per_mm, u)
    words = [
        (UNCOVERED_COLOURS["slide"], "a slide of the film is not found here"),
        (UNCOVERED_COLOURS["ink"], "ink gone or a scratch is not found here"),
        (UNCOVERED_COLOURS["both"], "neither is found here"),
    ]
    line = int(22 * u)
    legend = np.full((line * len(words) + int(16 * u), img.shape[1], 3), 255, np.uint8)
    for i, (colour, text) in enumerate(words):
        x0, y0 = int(40 * u), int(8 * u) + i * line
        cv2.rectangle(legend, (x0, y0 + int(4 * u)), (x0 + int(26 * u), y0 + int(15 * u)), colour, cv2.FILLED)
        _text(legend, text, (x0 + int(34 * u), y0 + int(15 * u)), 0.45 * u, thickness=_weight(u))
    return png_bytes(_titled(np.concatenate([img, legend], axis=0), title, u), compression=1, fast=True)


def dense_heatmap(
    reference: np.ndarray, shift_mm: np.ndarray, labels: np.ndarray, px_per_mm: float, vmax: float, title: str
) -> np.ndarray:
    """The dense misregistration over the print (mm on the surface), defects outlined, with a scale; RGB image.

    Drawn with OpenCV at the grid's own resolution (one picture pixel a grid pixel), as
    :func:`colour_difference`: matplotlib's import and figure took 0.6 to 0.8 s of every photo.

    Parameters
    ----------
    reference : (rows, cols, 3) uint8
        The print on the grid (shown in grey under the field).
    shift_mm : (rows, cols) float
        Misregistration (NaN where not measured).
    labels : (rows, cols) int
        Defect number + 1 per pixel.
    px_per_mm : float
        Grid resolution.
    vmax : float
        Top of the colour scale, mm (the tolerance, typically: yellow is at the limit).
    title : str

    Returns
    -------
    (H, W, 3) uint8
        The map with its print x and y axes in mm, the scale at its right and the title above.
    """
    lut = _inferno()
    grey = cv2.cvtColor(reference, cv2.COLOR_RGB2GRAY) // 2 + 128
    img = np.repeat(grey[..., None], 3, axis=2)
    on = np.isfinite(shift_mm)
    img[on] = lut[np.clip(shift_mm[on] / vmax * 255, 0, 255).astype(np.uint8)]
    u = _unit(img.shape[1])
    for k, c in enumerate(outlines(labels)):
        if len(c):
            cv2.polylines(img, [c.reshape(-1, 1, 2)], True, CYAN, max(2, int(1.5 * u)), cv2.LINE_AA)
            # beside the outline's top right, kept inside the picture
            (tw, th), _ = _text_size(str(k + 1), _FONT, 0.6 * u, 2 * _weight(u))
            x = min(int(c[:, 0].max()) + 3, img.shape[1] - tw - 2)
            y = max(int(c[:, 1].min()), th + 2)
            _text(img, str(k + 1), (x, y), 0.6 * u, CYAN, 2 * _weight(u), outline=True)
    img = print_axes_image(img, px_per_mm, u)
    bar = _colour_bar(img.shape[0], vmax, "misregistration on the surface (mm)", lut, u)
    return _titled(np.concatenate([img, bar], axis=1), title, u)


def colour_difference(reference: np.ndarray, de_map: np.ndarray, px_per_mm: float, vmax: float) -> np.ndarray:
    """ΔE00 over the print where colour was compared, over the print in grey, with a scale; (rows, cols + bar, 3) uint8.

    Parameters
    ----------
    reference : (rows, cols, 3) uint8
        The print on the grid.
    de_map : (rows, cols) float
        ΔE00 per grid pixel, NaN where not compared (an even subsample of the compared
        pixels: each also shows in its 3 x 3 neighbours that were not compared).
    px_per_mm : float
        Grid resolution: the axes' ticks every 10 mm (:func:`print_axes_image`).
    vmax : float
        Top of the scale ('inferno': black 0 to yellow ``vmax``; twice the tolerance puts it mid-scale).

    Drawn with OpenCV rather than matplotlib (a tenth of the time, on every photo).
    """
    lut = _inferno()
    filled = np.where(np.isfinite(de_map), de_map, -1.0).astype(np.float32)
    grown = cv2.dilate(filled, np.ones((3, 3), np.uint8))
    shown = np.where(filled >= 0, filled, grown)
    grey = cv2.cvtColor(reference, cv2.COLOR_RGB2GRAY) // 2 + 64
    img = np.repeat(grey[..., None], 3, axis=2)
    on = shown >= 0
    img[on] = lut[np.clip(shown[on] / vmax * 255, 0, 255).astype(np.uint8)]
    rows, cols = de_map.shape
    img = print_axes_image(img, px_per_mm, _unit(cols))
    # the scale: a bar beside the map (as tall as the map, the axes below it), its ends and middle
    # labelled in ΔE00
    bar_w = max(60, cols // 12)
    bar = np.full((img.shape[0], bar_w, 3), 255, np.uint8)
    top, bottom = rows // 10, rows - rows // 10
    ramp = np.linspace(255, 0, bottom - top).astype(np.uint8)
    bar[top:bottom, 8 : bar_w // 3] = lut[ramp][:, None, :]
    scale = max(0.4, rows / 1500)
    for v, y in ((vmax, top), (vmax / 2, (top + bottom) // 2), (0.0, bottom)):
        cv2.putText(bar, f"{v:g}", (bar_w // 3 + 4, y + 5), cv2.FONT_HERSHEY_SIMPLEX, scale, (0, 0, 0), 1, cv2.LINE_AA)
    cv2.putText(bar, "dE00", (4, top - 30), cv2.FONT_HERSHEY_SIMPLEX, scale, (0, 0, 0), 1, cv2.LINE_AA)
    return np.concatenate([img, bar], axis=1)


def tile_heatmap(design_rgb, sc, title: str) -> np.ndarray:
    """The view's image in grey with each tile coloured by its misregistration (mm) and its shift drawn, and a scale.

    Each registered tile is a square of the tiles' step at its centre, coloured on 'inferno' from 0
    to its largest misregistration (at least 0.1 mm); its arrow, from the tile's centre, is
    :data:`ARROW_SCALE` times the shift of its content in the view (x right, y down). Drawn with
    OpenCV at the view's own resolution, as :func:`dense_heatmap`.

    Returns
    -------
    (H, W, 3) uint8
        RGB: the view, the scale at its right, the title above.
    """
    from workbench.validate.score import TILE

    lut = _inferno()
    u = _unit(design_rgb.shape[1])
    grey = cv2.cvtColor(design_rgb, cv2.COLOR_RGB2GRAY).astype(np.float32)
    # the view at 0.6 over white: the tiles and arrows stand out
    img = np.repeat((0.6 * grey + 0.4 * 255).astype(np.uint8)[..., None], 3, axis=2)
    vmax = max(float(sc.shift_mm.max()) if len(sc.shift_mm) else 0.1, 0.1)
    h = TILE // 4
    for (x, y), v in zip(sc.centres, sc.shift_mm, strict=True):
        x0, y0 = int(round(x)) - h, int(round(y)) - h
        colour = tuple(int(c) for c in lut[int(np.clip(v / vmax * 255, 0, 255))])
        cv2.rectangle(img, (x0, y0), (x0 + 2 * h - 1, y0 + 2 * h - 1), colour, cv2.FILLED)
        cv2.rectangle(img, (x0, y0), (x0 + 2 * h - 1, y0 + 2 * h - 1), (60, 60, 60), 1)
    for (x, y), (dx, dy) in zip(sc.centres, sc.shift_px, strict=True):
        tip = (int(round(x + ARROW_SCALE * dx)), int(round(y + ARROW_SCALE * dy)))
        length = max(ARROW_SCALE * float(np.hypot(dx, dy)), 1.0)
        start = (int(round(x)), int(round(y)))
        cv2.arrowedLine(img, start, tip, CYAN, 2, cv2.LINE_AA, tipLength=min(8.0 / length, 0.5))
    bar = _colour_bar(img.shape[0], vmax, "misregistration on the surface (mm)", lut, u)
    return _titled(np.concatenate([img, bar], axis=1), f"{title} (arrows: {ARROW_SCALE:g} x the shift)", u)


CYAN = (0, 255, 255)  # RGB
ARROW_SCALE = 20.0  # a tile's arrow is this many times its shift
_FONT = cv2.FONT_HERSHEY_SIMPLEX


# matplotlib's colour maps as (256, 3) uint8 RGB tables, as matplotlib makes them for a picture
# ((colormap(np.linspace(0, 1, 256))[:, :3] * 255).astype(np.uint8): truncated), written out:
# importing matplotlib for a table cost 0.2 to 0.4 s of a photo, and OpenCV's copies of them round
# where matplotlib's truncate (a channel 1 off in most entries). tests/test_validate.py checks
# them against matplotlib's
_TABLES = {
    "inferno": (
        "00000300000400000601000701010901010b02010e02021003021204031404031605041806041b07051d08061f090621"
        "0a07230b07260d08280e082a0f092d10092f120a32130a34140b36160b39170b3b190b3e1a0b401c0c431d0c451f0c47"
        "200c4a220b4c240b4e260b50270b52290b542b0a562d0a582e0a5a300a5c32095d34095f3509603709613909623b0964"
        "3c09653e0966400966410967430a68450a69460a69480b6a4a0b6a4b0c6b4d0c6b4f0d6c500d6c520e6c530e6d550f6d"
        "570f6d58106d5a116d5b116e5d126e5f126e60136e62146e63146e65156e66156e68166e6a176e6b176e6d186e6e186e"
        "70196e72196d731a6d751b6d761b6d781c6d7a1c6d7b1d6c7d1d6c7e1e6c801f6b811f6b83206b85206a86216a88216a"
        "8922698b22698d23698e24689024689125679325679526669626669827659928649b28649c29639e2963a02a62a12b61"
        "a32b61a42c60a62c5fa72d5fa92e5eab2e5dac2f5cae305baf315bb1315ab23259b43358b53357b73456b83556ba3655"
        "bb3754bd3753be3852bf3951c13a50c23b4fc43c4ec53d4dc73e4cc83e4bc93f4acb4049cc4148cd4247cf4446d04544"
        "d14643d24742d44841d54940d64a3fd74b3ed94d3dda4e3bdb4f3adc5039dd5238de5337df5436e05634e25733e35832"
        "e45a31e55b30e65c2ee65e2de75f2ce8612be9622aea6428eb6527ec6726ed6825ed6a23ee6c22ef6d21f06f1ff0701e"
        "f1721df2741cf2751af37719f37918f47a16f57c15f57e14f68012f68111f78310f7850ef8870df8880cf88a0bf98c09"
        "f98e08f99008fa9107fa9306fa9506fa9706fb9906fb9b06fb9d06fb9e07fba007fba208fba40afba60bfba80dfbaa0e"
        "fbac10fbae12fbb014fbb116fbb318fbb51afbb71cfbb91efabb21fabd23fabf25fac128f9c32af9c52cf9c72ff8c931"
        "f8cb34f8cd37f7cf3af7d13cf6d33ff6d542f5d745f5d948f4db4bf4dc4ff3de52f3e056f3e259f2e45df2e660f1e864"
        "f1e968f1eb6cf1ed70f1ee74f1f079f1f27df2f381f2f485f3f689f4f78df5f891f6fa95f7fb99f9fc9dfafda0fcfea4"
    ),
    "viridis": (
        "44015444025544035745055845065a45085b46095c460b5e460c5f460e61470f62471163471265471466471567471669"
        "47186a48196b481a6c481c6e481d6f481e70482071482172482273482374472575472676472777472878472a79472b7a"
        "472c7b462d7c462f7c46307d46317e45327f45347f453580453681443781443982433a83433b83433c84423d84423e85"
        "4240854141864142864043874044873f45873f47883e48883e49893d4a893d4b893d4c893c4d8a3c4e8a3b508a3b518a"
        "3a528b3a538b39548b39558b38568b38578c37588c37598c365a8c365b8c355c8c355d8c345e8d345f8d33608d33618d"
        "32628d32638d31648d31658d31668d30678d30688d2f698d2f6a8d2e6b8e2e6c8e2e6d8e2d6e8e2d6f8e2c708e2c718e"
        "2c728e2b738e2b748e2a758e2a768e2a778e29788e29798e287a8e287a8e287b8e277c8e277d8e277e8e267f8e26808e"
        "26818e25828e25838d24848d24858d24868d23878d23888d23898d22898d228a8d228b8d218c8d218d8c218e8c208f8c"
        "20908c20918c1f928c1f938b1f948b1f958b1f968b1e978a1e988a1e998a1e998a1e9a891e9b891e9c891e9d881e9e88"
        "1e9f881ea0871fa1871fa2861fa38620a48520a58521a68521a78422a78423a88323a98224aa8225ab8126ac8127ad80"
        "28ae7f29af7f2ab07e2bb17d2cb17d2eb27c2fb37b30b47a32b57a33b67935b77836b87738b97639b9763bba753dbb74"
        "3ebc7340bd7242be7144be7045bf6f47c06e49c16d4bc26c4dc26b4fc36951c46853c56755c66657c66559c7645bc862"
        "5ec96160c96062ca5f64cb5d67cc5c69cc5b6bcd596dce5870ce5672cf5574d05477d05279d1517cd24f7ed24e81d34c"
        "83d34b86d44988d5478bd5468dd64490d64392d74195d73f97d83e9ad83c9dd93a9fd938a2da37a5da35a7db33aadb32"
        "addc30afdc2eb2dd2cb5dd2bb7dd29bade27bdde26bfdf24c2df22c5df21c7e01fcae01ecde01dcfe11cd2e11bd4e11a"
        "d7e219dae218dce218dfe318e1e318e4e318e7e419e9e419ece41aeee51bf1e51cf3e51ef6e61ff8e621fae622fde724"
    ),
}


def colour_table(name: str) -> np.ndarray:
    """matplotlib's colour map ``name`` ('inferno' or 'viridis') as a (256, 3) uint8 RGB table."""
    return np.frombuffer(bytes.fromhex(_TABLES[name]), np.uint8).reshape(256, 3)


def _inferno() -> np.ndarray:
    """matplotlib's 'inferno' as a (256, 3) uint8 RGB table (:func:`colour_table`)."""
    return colour_table("inferno")


def _unit(width: int) -> float:
    """The type's and the margins' size for a picture ``width`` pixels wide: the QA report shows every
    picture at a third of a page, so the type grows with the picture (1 up to 800 px)."""
    return max(1.0, width / 800.0)


def _weight(u: float) -> int:
    """Stroke width of text at size ``u``."""
    return max(1, int(round(u)))


def _text_size(text: str, font: int, scale: float, thickness: int):
    """``cv2.getTextSize`` of the text :func:`_text` draws (its ASCII spelling)."""
    return cv2.getTextSize(ascii_text(text), font, scale, thickness)


def _text(img, text: str, org, scale: float, colour=(0, 0, 0), thickness: int = 1, outline: bool = False) -> None:
    """Text at ``org`` (its baseline's left end); ``outline``: a dark rim first, readable over any colour.

    OpenCV's fonts draw ASCII only (and crash on a file name's undecodable byte): the text is spelled in ASCII.
    """
    text = ascii_text(text)
    if outline:
        cv2.putText(img, text, org, _FONT, scale, (0, 0, 0), thickness + 2, cv2.LINE_AA)
    cv2.putText(img, text, org, _FONT, scale, colour, thickness, cv2.LINE_AA)


def _vertical_text(text: str, scale: float, height: int, thickness: int = 1) -> np.ndarray:
    """A white strip with ``text`` written upwards, centred on ``height`` rows; (height, w, 3) uint8.

    Text longer than the strip is written smaller (a small map's y caption would lose its ends)."""
    (tw, th), base = _text_size(text, _FONT, scale, thickness)
    if tw > height - 8:
        scale *= max(height - 8, 1) / tw
        (tw, th), base = _text_size(text, _FONT, scale, thickness)
    strip = np.full((th + base + 8, max(tw + 8, height), 3), 255, np.uint8)
    _text(strip, text, ((strip.shape[1] - tw) // 2, th + 4), scale, thickness=thickness)
    strip = np.rot90(strip)  # reads from the bottom up
    return np.ascontiguousarray(strip[(strip.shape[0] - height) // 2 :][:height])


def _colour_bar(height: int, vmax: float, label: str, lut: np.ndarray, u: float = 1.0) -> np.ndarray:
    """A vertical scale from 0 (bottom) to ``vmax`` (top) with five labelled ticks and its caption; (height, w, 3)."""
    top, bottom = max(height // 10, 12), height - max(height // 10, 12)
    x0, x1 = int(10 * u), int(34 * u)
    bar = np.full((height, int(90 * u), 3), 255, np.uint8)
    ramp = np.linspace(255, 0, bottom - top).astype(np.uint8)
    bar[top:bottom, x0:x1] = lut[ramp][:, None, :]
    cv2.rectangle(bar, (x0, top), (x1 - 1, bottom - 1), (0, 0, 0), 1)
    for k in range(5):
        y = int(round(bottom - 1 - k * (bottom - 1 - top) / 4))
        bar[y : y + _weight(u), x1 : x1 + int(6 * u)] = 0
        _text(bar, f"{k * vmax / 4:.2f}", (x1 + int(9 * u), y + int(5 * u)), 0.45 * u, thickness=_weight(u))
    return np.concatenate([bar, _vertical_text(label, 0.5 * u, height, _weight(u))], axis=1)


def print_axes_image(img: np.ndarray, px_per_mm: float, u: float = 1.0, what: str = "print") -> np.ndarray:
    """A picture of the print with its axes: mm from its top-left corner, x right, y down.

    Every OpenCV picture over print coordinates goes through here (as matplotlib's through
    :func:`workbench.figures.print_axes`): row 0 of ``img`` is the print's top edge, so y counts
    down; a tick every 10 mm along the left and bottom edges, each labelled, and the captions.

    Parameters
    ----------
    img : (rows, cols, 3) uint8
        The print on a grid of ``px_per_mm`` pixels per mm, pixel (0, 0) at its top-left corner.
    px_per_mm : float
        Grid resolution.
    u : float
        Type size (:func:`_unit`).
    what : str
        What the corner is the corner of, in the captions ("print" or "film").

    Returns
    -------
    (rows + below, cols + left, 3) uint8
        ``img`` at the top right, the y axis at its left, the x axis below.
    """
    return _with_axes(img, px_per_mm, PRINT_X_LABEL.format(what), PRINT_Y_LABEL.format(what), u)


def _with_axes(img: np.ndarray, px_per_mm: float, xlabel: str, ylabel: str, u: float = 1.0) -> np.ndarray:
    """The image with a tick every 10 mm along its left and bottom edges, labelled, and the axes' captions."""
    rows, cols = img.shape[:2]
    left, below, t = int(34 * u), int(44 * u), _weight(u)
    out = np.full((rows + below, cols + left, 3), 255, np.uint8)
    out[:rows, left:] = img
    for k in range(0, int(cols / px_per_mm) + 1, 10):
        x = left + int(round(k * px_per_mm))
        out[rows : rows + int(6 * u), x : x + 2 * t] = 0
        (tw, th), _ = _text_size(str(k), _FONT, 0.45 * u, t)
        # (centred on its tick, the last kept inside the picture)
        _text(out, str(k), (min(x - tw // 2, out.shape[1] - tw - 1), rows + int(8 * u) + th), 0.45 * u, thickness=t)
    for k in range(0, int(rows / px_per_mm) + 1, 10):
        y = int(round(k * px_per_mm))
        out[y : y + 2 * t, left - int(6 * u) : left] = 0
        (tw, th), _ = _text_size(str(k), _FONT, 0.45 * u, t)
        _text(out, str(k), (left - int(8 * u) - tw, min(max(y + th // 2, th + 1), rows - 1)), 0.45 * u, thickness=t)
    (tw, _), _ = _text_size(xlabel, _FONT, 0.5 * u, t)
    _text(out, xlabel, (left + (cols - tw) // 2, rows + int(38 * u)), 0.5 * u, thickness=t)
    return np.concatenate([_vertical_text(ylabel, 0.5 * u, out.shape[0], t), out], axis=1)


def _titled(img: np.ndarray, title: str, u: float = 1.0) -> np.ndarray:
    """The image under a white band with the title, centred (smaller type when it is wider than the image)."""
    scale, t = 0.55 * u, _weight(u)
    (tw, th), _ = _text_size(title, _FONT, scale, t)
    if tw > img.shape[1] - 10:
        scale *= (img.shape[1] - 10) / tw
        (tw, th), _ = _text_size(title, _FONT, scale, t)
    band = np.full((th + int(18 * u), img.shape[1], 3), 255, np.uint8)
    _text(band, title, ((img.shape[1] - tw) // 2, th + int(8 * u)), scale, thickness=t)
    return np.concatenate([band, img], axis=0)


def detectable_print(
    reference: np.ndarray,
    limit_mm: np.ndarray,
    dropout: np.ndarray,
    px_per_mm: float,
    tolerance_mm: float,
    scratch: np.ndarray | None = None,
) -> np.ndarray:
    """What the photo can find over the print: two panels with a scale; (rows', cols', 3) uint8 RGB.

    Above, the smallest slide of the film found at each pixel ('viridis': the tolerance dark
    blue to three times it yellow; the print in grey where none is found), with its scale.
    Below, in green, where ink that is gone is found, and in pale green where only a
    scratch (a thin line of it) is. (One above the other: the page of the QA report is
    portrait.) Halved when the grid exceeds a megapixel (a picture to
    look at, not a measurement: the numbers are in ``detection.npz``).

    Parameters
    ----------
    reference : (rows, cols, 3) uint8
        The print on the grid.
    limit_mm : (rows, cols) float32
        Smallest slide found, mm on the surface, NaN where none is.
    dropout, scratch : (rows, cols) bool
        Where ink that is gone is found, and a scratch.
    px_per_mm : float
        Grid resolution: the axes' ticks every 10 mm (:func:`print_axes_image`).
    tolerance_mm : float
        The bottom of the scale.
    """
    step = 2 if reference.shape[0] * reference.shape[1] > 1_000_000 else 1
    ref = reference[::step, ::step]
    lim = limit_mm[::step, ::step]
    drop = dropout[::step, ::step]
    ppm = px_per_mm / step
    lut = colour_table("viridis")
    grey = cv2.cvtColor(ref, cv2.COLOR_RGB2GRAY) // 2 + 96
    left = np.repeat(grey[..., None], 3, axis=2)
    on = np.isfinite(lim)
    vmax = 3.0 * tolerance_mm
    left[on] = lut[np.clip((lim[on] - tolerance_mm) / (vmax - tolerance_mm) * 255, 0, 255).astype(np.uint8)]
    right = np.repeat(grey[..., None], 3, axis=2)
    if scratch is not None:
        thin = scratch[::step, ::step] & ~drop
        right[thin] = (0.5 * right[thin] + 0.5 * np.array([170, 230, 170])).astype(np.uint8)
    right[drop] = (0.4 * right[drop] + 0.6 * np.array([30, 170, 60])).astype(np.uint8)
    rows, cols = lim.shape
    left, right = (print_axes_image(img, ppm, _unit(cols)) for img in (left, right))
    bar_w = max(70, cols // 10)
    bar = np.full((left.shape[0], bar_w, 3), 255, np.uint8)
    top, bottom = rows // 10, rows - rows // 10
    bar[top:bottom, 8 : bar_w // 3] = lut[np.linspace(255, 0, bottom - top).astype(np.uint8)][:, None, :]
    scale = max(0.4, rows / 1500)
    font = cv2.FONT_HERSHEY_SIMPLEX
    for v, y in ((vmax, top), ((vmax + tolerance_mm) / 2, (top + bottom) // 2), (tolerance_mm, bottom)):
        cv2.putText(bar, f"{v:.2g}", (bar_w // 3 + 4, y + 5), font, scale, (0, 0, 0), 1, cv2.LINE_AA)
    cv2.putText(bar, "mm", (4, top - 30), cv2.FONT_HERSHEY_SIMPLEX, scale, (0, 0, 0), 1, cv2.LINE_AA)
    right = np.concatenate([right, np.full((right.shape[0], bar_w, 3), 255, np.uint8)], axis=1)
    panels = []
    for text, img in (("smallest slide of the film found", np.concatenate([left, bar], axis=1)),
                      ("ink gone found (green; a scratch only: pale green)", right)):  # fmt: skip
        head = np.full((max(24, int(30 * scale)), img.shape[1], 3), 255, np.uint8)
        cv2.putText(head, text, (6, head.shape[0] - 8), cv2.FONT_HERSHEY_SIMPLEX, scale, (0, 0, 0), 1, cv2.LINE_AA)
        panels += [head, img]
    return np.concatenate(panels, axis=0)
