"""Pictures of the dense validation: defects over the print, over a view and over the photo; the coverage map."""

from __future__ import annotations

import cv2
import numpy as np

from workbench.validate import dense

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
    """The photo on the print with each defect outlined and numbered; (rows, cols, 3) uint8 RGB."""
    img = cv2.cvtColor(warped, cv2.COLOR_RGB2BGR)
    thick = max(1, int(round(px_per_mm * 0.2)))
    for k, c in enumerate(outlines(labels)):
        if len(c):
            cv2.polylines(img, [c.reshape(-1, 1, 2)], True, DEFECT_BGR, thick, cv2.LINE_AA)
            x, y = c.max(axis=0)
            cv2.putText(img, str(k + 1), (int(x) + 3, int(y)), cv2.FONT_HERSHEY_SIMPLEX, 0.6, DEFECT_BGR, 2)
    return cv2.cvtColor(img, cv2.COLOR_BGR2RGB)


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
    """The print's coverage map with a legend (share of the part per state) and numbered defects, PNG."""
    from matplotlib.patches import Patch

    from workbench.figures import _figure, figure_png

    plt = _figure()
    rows, cols = state.shape
    w_mm, h_mm = cols / px_per_mm, rows / px_per_mm
    fig, ax = plt.subplots(figsize=(9, 9 * h_mm / w_mm * 0.8 + 2.2), dpi=110)
    fig.subplots_adjust(bottom=0.3, top=0.93)
    ax.imshow(coverage_image(state), extent=(0, w_mm, h_mm, 0), interpolation="nearest")
    on = state != dense.OFF_PART
    n_on = max(int(on.sum()), 1)
    handles = []
    for k, name in enumerate(dense.STATE_NAMES):
        if k == dense.OFF_PART:
            continue
        share = float((state == k).sum()) / n_on
        if share > 0:
            handles.append(Patch(color=STATE_COLOURS[k] / 255, label=f"{name}: {100 * share:.1f} %"))
    for k, d in enumerate(defects):
        x, y = d["centre_mm"]
        ax.annotate(
            str(k + 1),
            (x, y),
            color="black",
            fontsize=8,
            fontweight="bold",
            ha="center",
            va="center",
            bbox={"boxstyle": "circle,pad=0.2", "fc": "white", "ec": "red", "lw": 1.2},
        )
    ax.legend(handles=handles, loc="upper center", bbox_to_anchor=(0.5, -0.12), ncol=2, fontsize=8, frameon=False)
    ax.set_xlabel("print x (mm)")
    ax.set_ylabel("print y (mm)")
    ax.set_title(title, fontsize=9)
    return figure_png(fig)


def dense_heatmap(
    reference: np.ndarray, shift_mm: np.ndarray, labels: np.ndarray, px_per_mm: float, vmax: float, title: str
) -> bytes:
    """The dense misregistration over the print (mm on the surface), defects outlined, with a colour bar; PNG.

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
    """
    from workbench.figures import _figure, figure_png

    plt = _figure()
    rows, cols = shift_mm.shape
    w_mm, h_mm = cols / px_per_mm, rows / px_per_mm
    fig, ax = plt.subplots(figsize=(9, 9 * h_mm / w_mm + 0.8), dpi=110)
    grey = cv2.cvtColor(cv2.cvtColor(reference, cv2.COLOR_RGB2GRAY), cv2.COLOR_GRAY2RGB)
    ext = (0, w_mm, h_mm, 0)
    ax.imshow(grey, extent=ext, alpha=0.5, interpolation="bilinear")
    im = ax.imshow(
        np.ma.masked_invalid(shift_mm), extent=ext, cmap="inferno", vmin=0, vmax=vmax, interpolation="nearest"
    )
    for k, c in enumerate(outlines(labels)):
        if len(c):
            xy = (c + 0.5) / px_per_mm
            ax.plot(np.r_[xy[:, 0], xy[0, 0]], np.r_[xy[:, 1], xy[0, 1]], color="cyan", lw=1.2)
            ax.annotate(str(k + 1), (xy[:, 0].max(), xy[:, 1].min()), color="cyan", fontsize=9, fontweight="bold")
    fig.colorbar(im, ax=ax, fraction=0.046, pad=0.04).set_label("misregistration on the surface (mm)")
    ax.set_xlabel("print x (mm)")
    ax.set_ylabel("print y (mm)")
    ax.set_title(title, fontsize=9)
    return figure_png(fig)


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
        Grid resolution: a tick every 10 mm along the top and left edges.
    vmax : float
        Top of the scale ('inferno': black 0 to yellow ``vmax``; twice the tolerance puts it mid-scale).

    Drawn with OpenCV rather than matplotlib (a tenth of the time, on every photo).
    """
    import matplotlib

    lut = (matplotlib.colormaps["inferno"](np.linspace(0, 1, 256))[:, :3] * 255).astype(np.uint8)
    filled = np.where(np.isfinite(de_map), de_map, -1.0).astype(np.float32)
    grown = cv2.dilate(filled, np.ones((3, 3), np.uint8))
    shown = np.where(filled >= 0, filled, grown)
    grey = cv2.cvtColor(reference, cv2.COLOR_RGB2GRAY) // 2 + 64
    img = np.repeat(grey[..., None], 3, axis=2)
    on = shown >= 0
    img[on] = lut[np.clip(shown[on] / vmax * 255, 0, 255).astype(np.uint8)]
    rows, cols = de_map.shape
    for k in range(0, int(max(rows, cols) / px_per_mm) + 1, 10):
        t = int(round(k * px_per_mm))
        img[:6, t : t + 2] = 0
        img[t : t + 2, :6] = 0
    # the scale: a bar beside the map, its ends and middle labelled in ΔE00
    bar_w = max(60, cols // 12)
    bar = np.full((rows, bar_w, 3), 255, np.uint8)
    top, bottom = rows // 10, rows - rows // 10
    ramp = np.linspace(255, 0, bottom - top).astype(np.uint8)
    bar[top:bottom, 8 : bar_w // 3] = lut[ramp][:, None, :]
    scale = max(0.4, rows / 1500)
    for v, y in ((vmax, top), (vmax / 2, (top + bottom) // 2), (0.0, bottom)):
        cv2.putText(bar, f"{v:g}", (bar_w // 3 + 4, y + 5), cv2.FONT_HERSHEY_SIMPLEX, scale, (0, 0, 0), 1, cv2.LINE_AA)
    cv2.putText(bar, "dE00", (4, top - 30), cv2.FONT_HERSHEY_SIMPLEX, scale, (0, 0, 0), 1, cv2.LINE_AA)
    return np.concatenate([img, bar], axis=1)


def tile_heatmap(design_rgb, sc, title: str) -> bytes:
    """The view's image in grey with each tile coloured by its misregistration (mm), and a colour bar."""
    from workbench.figures import _figure, figure_png

    plt = _figure()
    grey = cv2.cvtColor(cv2.cvtColor(design_rgb, cv2.COLOR_RGB2GRAY), cv2.COLOR_GRAY2RGB)
    H, W = grey.shape[:2]
    fig, ax = plt.subplots(figsize=(8, 8 * H / W + 0.6), dpi=100)
    ax.imshow(grey, alpha=0.6)
    vmax = max(float(sc.shift_mm.max()) if len(sc.shift_mm) else 0.1, 0.1)
    sca = ax.scatter(
        sc.centres[:, 0], sc.centres[:, 1], c=sc.shift_mm, cmap="inferno", vmin=0, vmax=vmax, s=60, marker="s"
    )
    if len(sc.centres):
        ax.quiver(
            sc.centres[:, 0],
            sc.centres[:, 1],
            sc.shift_px[:, 0],
            -sc.shift_px[:, 1],
            color="cyan",
            angles="xy",
            scale_units="xy",
            scale=0.05,
            width=0.002,
        )
    fig.colorbar(sca, ax=ax, fraction=0.046, pad=0.04).set_label("misregistration on the surface (mm)")
    ax.set_title(title, fontsize=9)
    ax.set_axis_off()
    return figure_png(fig)


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
        Grid resolution: a tick every 10 mm along the top and left edges.
    tolerance_mm : float
        The bottom of the scale.
    """
    import matplotlib

    step = 2 if reference.shape[0] * reference.shape[1] > 1_000_000 else 1
    ref = reference[::step, ::step]
    lim = limit_mm[::step, ::step]
    drop = dropout[::step, ::step]
    ppm = px_per_mm / step
    lut = (matplotlib.colormaps["viridis"](np.linspace(0, 1, 256))[:, :3] * 255).astype(np.uint8)
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
    for img in (left, right):
        for k in range(0, int(max(rows, cols) / ppm) + 1, 10):
            t = int(round(k * ppm))
            img[:6, t : t + 2] = 0
            img[t : t + 2, :6] = 0
    bar_w = max(70, cols // 10)
    bar = np.full((rows, bar_w, 3), 255, np.uint8)
    top, bottom = rows // 10, rows - rows // 10
    bar[top:bottom, 8 : bar_w // 3] = lut[np.linspace(255, 0, bottom - top).astype(np.uint8)][:, None, :]
    scale = max(0.4, rows / 1500)
    font = cv2.FONT_HERSHEY_SIMPLEX
    for v, y in ((vmax, top), ((vmax + tolerance_mm) / 2, (top + bottom) // 2), (tolerance_mm, bottom)):
        cv2.putText(bar, f"{v:.2g}", (bar_w // 3 + 4, y + 5), font, scale, (0, 0, 0), 1, cv2.LINE_AA)
    cv2.putText(bar, "mm", (4, top - 30), cv2.FONT_HERSHEY_SIMPLEX, scale, (0, 0, 0), 1, cv2.LINE_AA)
    right = np.concatenate([right, np.full((rows, bar_w, 3), 255, np.uint8)], axis=1)
    panels = []
    for text, img in (("smallest slide of the film found", np.concatenate([left, bar], axis=1)),
                      ("ink gone found (green; a scratch only: pale green)", right)):  # fmt: skip
        head = np.full((max(24, int(30 * scale)), img.shape[1], 3), 255, np.uint8)
        cv2.putText(head, text, (6, head.shape[0] - 8), cv2.FONT_HERSHEY_SIMPLEX, scale, (0, 0, 0), 1, cv2.LINE_AA)
        panels += [head, img]
    return np.concatenate(panels, axis=0)
