"""Every picture of the print reads it as the design writes it: mm from its top-left corner, y down.

Each figure is drawn with one mark at a known print position near the top-left corner, and read back
from its pixels: the mark must sit where the picture's own tick labels put that position, and the
labels must grow downward. A picture drawn y up puts the mark near the bottom, or its labels the other
way, and fails. Pictures of a photo keep the photo's pixels, y down as every image, and say so.
"""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from workbench.figures import (
    PHOTO_X_LABEL,
    PHOTO_Y_LABEL,
    PRINT_X_LABEL,
    PRINT_Y_LABEL,
    VIEW_COLOURS,
    stretch_plot,
    views_plot,
)
from workbench.validate import pictures, print_warp

W_MM, H_MM = 80.0, 50.0  # the print
MARK_MM = (15.0, 10.0)  # the mark's centre, print mm (x right, y down): near the top-left corner
MARK_R_MM = 4.0


def near_mark(x_mm: np.ndarray, y_mm: np.ndarray) -> np.ndarray:
    """Where the mark is, for print positions in mm (y down)."""
    return np.hypot(x_mm - MARK_MM[0], y_mm - MARK_MM[1]) <= MARK_R_MM


# --- matplotlib figures: read through their axes and their rendered pixels


def rendered(fig) -> np.ndarray:
    """The figure as the PNG holds it: (rows, cols, 3) uint8, row 0 at the top."""
    fig.canvas.draw()
    return np.asarray(fig.canvas.buffer_rgba())[..., :3].copy()


def pixel_of(fig, ax, x: float, y: float) -> tuple[int, int]:
    """(row, col) of the rendered picture where ``ax`` draws data point (x, y)."""
    px, py = ax.transData.transform((x, y))
    return int(round(fig.bbox.height - py)), int(round(px))


def colour_at(img: np.ndarray, rc: tuple[int, int], r: int = 2) -> np.ndarray:
    """Median colour of the (2r + 1)² pixels around ``rc`` (thin arrows or grid lines drawn over it aside)."""
    i, j = rc
    return np.median(img[i - r : i + r + 1, j - r : j + r + 1].reshape(-1, 3), axis=0)


def tick_values(fig, axis) -> list[tuple[float, float]]:
    """(value, position in the rendered picture: row for y, column for x) of each visible tick label."""
    fig.canvas.draw()
    out = []
    for t in axis.get_ticklabels():
        text = t.get_text().replace("\N{MINUS SIGN}", "-")
        if t.get_visible() and text:
            box = t.get_window_extent()
            out.append((float(text), fig.bbox.height - 0.5 * (box.y0 + box.y1) if axis.axis_name == "y" else box.x0))
    return out


def assert_reads_y_down(fig, ax, width: float, height: float, xlabel: str, ylabel: str) -> None:
    """The axes show [0, width] x [0, height] with y = 0 at the top, both axes labelled and ticked."""
    assert ax.get_xlim() == pytest.approx((0.0, width)) and ax.get_ylim() == pytest.approx((height, 0.0))
    assert ax.get_xlabel() == xlabel and ax.get_ylabel() == ylabel
    top, bottom = pixel_of(fig, ax, 0.5 * width, 0.0), pixel_of(fig, ax, 0.5 * width, height)
    assert top[0] < bottom[0]  # y = 0 is drawn above y = height
    for axis, grows in ((ax.yaxis, "down"), (ax.xaxis, "right")):
        ticks = sorted(tick_values(fig, axis))
        assert len(ticks) >= 3, f"{axis.axis_name}: tick labels"
        positions = [p for _, p in ticks]
        assert positions == sorted(positions), f"{axis.axis_name} labels do not grow {grows}"
    ys = tick_values(fig, ax.yaxis)
    assert min(ys, key=lambda t: t[1])[0] == pytest.approx(0.0)  # the top label reads 0


def assert_mark_where_drawn(fig, ax, colour, tol: float = 40.0) -> None:
    """The mark's colour is at the mark's print position in the rendered picture, not at its mirror."""
    img = rendered(fig)
    here = colour_at(img, pixel_of(fig, ax, *MARK_MM))
    mirror = colour_at(img, pixel_of(fig, ax, MARK_MM[0], H_MM - MARK_MM[1]))
    assert np.abs(here - colour).max() <= tol, f"{here} at the mark, {colour} drawn"
    assert np.abs(mirror - colour).max() > tol, "the mark shows at its mirror image too"


def flat_grid(nx: int = 41, ny: int = 26):
    """A flat layout over the print: uv in mm, y up (the flat layout's own convention), and its triangles."""
    x, y = np.meshgrid(np.linspace(0, W_MM, nx), np.linspace(0, H_MM, ny))
    uv = np.stack([x.ravel(), y.ravel()], axis=1)
    idx = np.arange(nx * ny).reshape(ny, nx)
    a, b, c, d = idx[:-1, :-1].ravel(), idx[:-1, 1:].ravel(), idx[1:, 1:].ravel(), idx[1:, :-1].ravel()
    F = np.concatenate([np.stack([a, b, c], 1), np.stack([a, c, d], 1)])
    return uv, F, (0, nx - 1, nx * ny - 1, nx * (ny - 1))


def test_stretch_figure_reads_y_down():
    uv, F, corners = flat_grid()
    centre = uv[F].mean(axis=1)
    # the flat layout counts y up: the print's y is the height less it
    stretch = np.where(near_mark(centre[:, 0], H_MM - centre[:, 1]), 1.2, 1.0)
    fig = stretch_plot(uv, F, stretch, corners, W_MM, H_MM, "stretch")
    ax = fig.axes[0]
    assert_reads_y_down(fig, ax, W_MM, H_MM, PRINT_X_LABEL.format("print"), PRINT_Y_LABEL.format("print"))
    assert_mark_where_drawn(fig, ax, (253, 231, 37))  # viridis at the top of its scale
    # corner A, the flat layout's origin, is the print's bottom-left corner
    a = next(t for t in ax.texts if t.get_text().startswith("A"))
    assert tuple(a.xy) == pytest.approx((0.0, H_MM))


def test_views_figure_reads_y_down():
    ppm = 4.0
    rows, cols = int(H_MM * ppm), int(W_MM * ppm)
    i, j = np.mgrid[0:rows, 0:cols]
    owner = np.where(near_mark((j + 0.5) / ppm, (i + 0.5) / ppm), 0, 1).astype(np.int8)
    fig = views_plot(owner, ["mark", "rest"], [0.1, 0.9], W_MM, H_MM, "views", labels=[(60.0, 40.0, "film")])
    ax = fig.axes[0]
    assert_reads_y_down(fig, ax, W_MM, H_MM, PRINT_X_LABEL.format("print"), PRINT_Y_LABEL.format("print"))
    assert_mark_where_drawn(fig, ax, VIEW_COLOURS[0])
    # a film's name is written where its print mm put it
    assert [tuple(t.get_position()) for t in ax.texts] == [(60.0, 40.0)]


def test_forming_profile_reads_y_down():
    from workbench.calibration_forming import profile_plot

    def field(g):
        # |d| 1 mm on the mark, 0 elsewhere; along y, so that the (white) arrows, drawn every 3.3 mm
        # from x = 13.3 and 16.7 mm, pass either side of the mark's centre
        d = np.zeros((len(g), 2))
        d[near_mark(g[:, 0], g[:, 1]), 1] = 1.0
        return d

    xs, ys = np.meshgrid(np.linspace(0, W_MM, 81), np.linspace(0, H_MM, 51))
    film = {
        "name": "film-1",
        "size_mm": [W_MM, H_MM],
        "field": field,
        "points_mm": np.stack([xs.ravel(), ys.ravel()], axis=1),
        "placement": {"shift_mm": [0.0, 0.0], "rotation_deg": 0.0, "compensated": False},
        "measured_share_on_part": 1.0,
        "measured_share": 1.0,
    }
    fig = profile_plot({"films": [film]}, "profile")
    ax = fig.axes[0]
    assert_reads_y_down(fig, ax, W_MM, H_MM, PRINT_X_LABEL.format("film"), PRINT_Y_LABEL.format("film"))
    assert_mark_where_drawn(fig, ax, (253, 231, 37), tol=60.0)


def test_calibration_pictures_read_photo_pixels_y_down():
    from workbench.commands.calibrate import coverage_plot, residual_plot

    w, h = 1200, 900
    cells = np.full((6, 8), 5)
    cells[0, 0] = 0  # the frame's top-left cell has no corner: shaded pink there
    coverage = {
        "cells": cells.tolist(),
        "missing": [],
        "share": 47 / 48,
        "tilt_x_deg": [10.0],
        "tilt_y_deg": [-20.0],
        "next": [],
    }
    fig = coverage_plot([], coverage, w, h, "coverage")
    ax = fig.axes[0]
    assert_reads_y_down(fig, ax, w, h, PHOTO_X_LABEL.format("photo"), PHOTO_Y_LABEL.format("photo"))
    img = rendered(fig)
    pink = np.array([255, 217, 217])
    assert np.abs(colour_at(img, pixel_of(fig, ax, 75, 75)) - pink).max() <= 3
    assert np.abs(colour_at(img, pixel_of(fig, ax, 75, h - 75)) - pink).max() > 3

    class Calibration:
        image_size = (w, h)
        residuals = [(np.array([[100.0, 100.0], [1100.0, 800.0]]), np.array([[0.1, 0.0], [0.0, 0.2]]))]

    fig = residual_plot(Calibration(), "residuals")
    assert_reads_y_down(fig, fig.axes[0], w, h, PHOTO_X_LABEL.format("photo"), PHOTO_Y_LABEL.format("photo"))


# --- OpenCV pictures: read from the PNG's pixels alone

PPM = 4.0  # grid px per mm
ROWS, COLS = int(H_MM * PPM), int(W_MM * PPM)


def decoded(png) -> np.ndarray:
    """A picture (PNG bytes or an RGB array) as (rows, cols, 3) uint8 RGB."""
    if isinstance(png, bytes | bytearray):
        return cv2.cvtColor(cv2.imdecode(np.frombuffer(png, np.uint8), cv2.IMREAD_COLOR), cv2.COLOR_BGR2RGB)
    return png


def label_centres(img: np.ndarray, text: str, scale: float = 0.45) -> list[tuple[float, float]]:
    """(row, col) centres of every exact copy of the tick label ``text`` as the pictures draw it."""
    canvas = np.full((40, 120, 3), 255, np.uint8)
    pictures._text(canvas, text, (10, 30), scale)
    ink = np.argwhere(canvas.min(axis=2) < 255)
    (r0, c0), (r1, c1) = ink.min(axis=0) - 1, ink.max(axis=0) + 2
    tpl = cv2.cvtColor(canvas[r0:r1, c0:c1], cv2.COLOR_RGB2GRAY).astype(np.float32)
    grey = cv2.cvtColor(img, cv2.COLOR_RGB2GRAY).astype(np.float32)
    diff = cv2.matchTemplate(grey, tpl, cv2.TM_SQDIFF)
    hits = np.argwhere(diff <= 0.5 * tpl.size)  # (exact copies: the FFT leaves a few tenths)
    return [(r + 0.5 * (r1 - r0 - 1), c + 0.5 * (c1 - c0 - 1)) for r, c in hits]


def read_axes(img: np.ndarray, panel: int = 0):
    """The picture's print axes, from its tick labels 10 and 20: mm to (row, col) of the picture.

    The y labels are the copies at the picture's left, the x labels the others (below the map);
    ``panel``: which of several maps stacked one above the other, from the top.
    """
    at = {}
    for k in ("10", "20"):
        hits = label_centres(img, k)
        left = min(c for _, c in hits)
        ys = sorted(r for r, c in hits if c - left < 3)
        xs = sorted((r, c) for r, c in hits if c - left >= 3)
        assert len(ys) > panel and len(xs) > panel, f"tick label {k}: {hits}"
        at[k] = (ys[panel], xs[panel][1])
    row_per_mm = (at["20"][0] - at["10"][0]) / 10.0
    col_per_mm = (at["20"][1] - at["10"][1]) / 10.0
    # labels 10 and 20 are each at their tick: y grows downward, x rightward, at the grid's resolution
    assert row_per_mm == pytest.approx(PPM, abs=0.6), "the y axis does not grow downward"
    assert col_per_mm == pytest.approx(PPM, abs=0.6), "the x axis does not grow rightward"

    def to_pixel(x_mm: float, y_mm: float) -> tuple[float, float]:
        return at["10"][0] + (y_mm - 10.0) * row_per_mm, at["10"][1] + (x_mm - 10.0) * col_per_mm

    return to_pixel


def assert_mark_at(img: np.ndarray, colour, panel: int = 0, tol: int = 0) -> None:
    """The mark's pixels (``colour``, within the map the axes frame) centre on the mark's print position."""
    to_pixel = read_axes(img, panel)
    (r0, c0), (r1, c1) = to_pixel(0.0, 0.0), to_pixel(W_MM, H_MM)
    inside = img[int(r0) : int(r1), int(c0) : int(c1)].astype(int)
    rr, cc = np.nonzero(np.abs(inside - np.asarray(colour)).max(axis=2) <= tol)
    assert len(rr) > 0.5 * np.pi * (MARK_R_MM * PPM) ** 2, "the mark is not in the map"
    want = to_pixel(*MARK_MM)
    assert r0 + rr.mean() == pytest.approx(want[0], abs=2.0) and c0 + cc.mean() == pytest.approx(want[1], abs=2.0)


def mark_mask() -> np.ndarray:
    i, j = np.mgrid[0:ROWS, 0:COLS]
    return near_mark((j + 0.5) / PPM, (i + 0.5) / PPM)


def test_coverage_map_reads_y_down():
    state = np.full((ROWS, COLS), print_warp.STATE_NAMES.index("measured: colour and full shift"), np.uint8)
    state[mark_mask()] = len(print_warp.STATE_NAMES) - 1  # defective: red
    img = decoded(pictures.coverage_figure(state, PPM, "coverage", []))
    assert_mark_at(img, pictures.STATE_COLOURS[-1])


def test_uncovered_map_reads_y_down():
    empty = np.zeros((ROWS, COLS), bool)
    slide = mark_mask()
    reference = np.full((ROWS, COLS, 3), 255, np.uint8)
    png = pictures.uncovered_figure(reference, {"slide": slide, "ink_gone": empty, "scratch": empty}, [], PPM, "where")
    shown = (0.35 * 255 + 0.65 * np.asarray(pictures.UNCOVERED_COLOURS["slide"])).astype(np.uint8)
    assert_mark_at(decoded(png), shown)


def test_dense_map_reads_y_down():
    shift = np.full((ROWS, COLS), np.nan)
    shift[mark_mask()] = 1.0  # the top of the scale: yellow
    reference = np.full((ROWS, COLS, 3), 255, np.uint8)
    img = pictures.dense_heatmap(reference, shift, np.zeros((ROWS, COLS), int), PPM, 1.0, "dense")
    assert_mark_at(img, pictures.colour_table("inferno")[255])


def test_colour_map_reads_y_down():
    de = np.full((ROWS, COLS), np.nan)
    de[mark_mask()] = 6.0  # the top of the scale
    reference = np.full((ROWS, COLS, 3), 255, np.uint8)
    assert_mark_at(pictures.colour_difference(reference, de, PPM, 6.0), pictures.colour_table("inferno")[255])


def test_detectable_maps_read_y_down():
    limit = np.full((ROWS, COLS), np.nan, np.float32)
    limit[mark_mask()] = 0.1  # the tolerance: the bottom of the scale
    dropout = mark_mask()
    reference = np.full((ROWS, COLS, 3), 255, np.uint8)
    img = pictures.detectable_print(reference, limit, dropout, PPM, 0.1)
    assert_mark_at(img, pictures.colour_table("viridis")[0], panel=0)
    grey = 255 // 2 + 96
    green = (0.4 * grey + 0.6 * np.array([30, 170, 60])).astype(np.uint8)
    assert_mark_at(img, green, panel=1)


def test_defects_over_the_print_read_y_down():
    warped = np.full((ROWS, COLS, 3), 200, np.uint8)
    warped[mark_mask()] = (0, 200, 0)
    img = pictures.defects_on_print(warped, np.zeros((ROWS, COLS), int), [], PPM)
    assert_mark_at(img, (0, 200, 0))


def test_defects_over_the_view_drawn_over_what_is_printed():
    """A defect in a region another view decorates is outlined over the print there, not over this view's sky."""
    # the view: 120 x 200 px, its left 150 columns see the print through an affine map (2.5 px
    # per mm, the print's (2, 1) mm at the view's top-left corner); the rest is off the part
    s, rows_v, cols_v, part_cols = 2.5, 120, 200, 150
    r, c = np.mgrid[0:rows_v, 0:cols_v].astype(np.float64)
    print_mm = np.stack([(c + 0.5) / s + 2.0, (r + 0.5) / s + 1.0], axis=-1)
    print_mm[:, part_cols:] = np.nan
    sky = np.zeros((rows_v, cols_v, 3), np.uint8)
    sky[...] = (40, 90, 230)  # the view's own image: sky, where the print carries a logo
    printed = np.full((ROWS, COLS, 3), 200, np.uint8)
    printed[mark_mask()] = (0, 200, 0)  # the logo, drawn by another view
    labels = mark_mask().astype(np.int32)  # a dropout over the logo
    shown = pictures.print_seen_from_view(printed, print_mm, PPM, sky)
    img = pictures.defects_on_image(shown, pictures.labels_in_view(labels, print_mm, PPM))
    # the mark's centre, in the view: (MARK - (2, 1)) * s
    col, row = round((MARK_MM[0] - 2.0) * s), round((MARK_MM[1] - 1.0) * s)
    assert np.abs(img[row, col].astype(int) - (0, 200, 0)).max() <= 2  # the logo under the outline
    assert np.abs(img[row, part_cols + 20].astype(int) - (40, 90, 230)).max() == 0  # off the part: the view
    assert np.abs(img[5, 5].astype(int) - (200, 200, 200)).max() <= 2  # the print, away from the mark
    # the outline in the defect colour, on the mark's rim: MARK_R_MM * s px from its centre
    red = np.all(img == pictures.DEFECT_BGR[::-1], axis=-1)
    rr, cc = np.nonzero(red)
    dist = np.hypot(rr - row, cc - col)
    assert len(dist) and np.median(np.abs(dist - MARK_R_MM * s)) < 2.0
