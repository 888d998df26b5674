"""Pictures of results, for people who would rather look than read."""

from __future__ import annotations

import io

import numpy as np

# Every picture of the print reads it the way the design writes it: millimetres from the top-left
# corner, x right, y down (print.png's rows, --defect, validation.json's positions). A film's own
# pictures (the forming profile's panels) read the same from that film's top-left corner.
PRINT_X_LABEL = "x (mm, from the {}'s left edge)"
PRINT_Y_LABEL = "y (mm, down from the {}'s top edge)"
# a picture of a photo or a view stays in its pixels, y down as every image
PHOTO_X_LABEL = "x (px, from the {}'s left edge)"
PHOTO_Y_LABEL = "y (px, down from the {}'s top edge)"


def print_axes(ax, width_mm: float, height_mm: float, what: str = "print") -> None:
    """Make ``ax`` a picture of the print: [0, width_mm] x [0, height_mm] mm, y down from the top edge.

    Every figure over print coordinates goes through here, so that none draws y up: the limits
    put y = 0 at the top, the aspect is true, both axes carry tick labels and say what they count.
    Draw images with ``extent=print_extent(width_mm, height_mm)`` (row 0 at y = 0).

    Parameters
    ----------
    ax : matplotlib Axes
    width_mm, height_mm : float
        The rectangle shown, mm.
    what : str
        What the corner is the corner of, in the axis labels: "print" or "film".
    """
    ax.set_xlim(0.0, width_mm)
    ax.set_ylim(height_mm, 0.0)
    ax.set_aspect("equal")
    ax.tick_params(axis="both", labelbottom=True, labelleft=True)
    ax.set_xlabel(PRINT_X_LABEL.format(what))
    ax.set_ylabel(PRINT_Y_LABEL.format(what))


def print_extent(width_mm: float, height_mm: float) -> tuple[float, float, float, float]:
    """imshow's extent for an image whose row 0 is the print's top edge (with ``origin="upper"``)."""
    return (0.0, width_mm, height_mm, 0.0)


def photo_axes(ax, width_px: int, height_px: int, what: str = "photo") -> None:
    """Make ``ax`` a picture of an image in its own pixels, y down from its top edge, labelled so."""
    ax.set_xlim(0, width_px)
    ax.set_ylim(height_px, 0)
    ax.set_aspect("equal")
    ax.set_xlabel(PHOTO_X_LABEL.format(what))
    ax.set_ylabel(PHOTO_Y_LABEL.format(what))


def _figure():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def _label_films(ax, labels) -> None:
    """Write each film's name at its centre: ``labels`` is a list of (x_mm, y_mm, text)."""
    for x, y, text in labels:
        ax.text(
            x,
            y,
            text,
            ha="center",
            va="center",
            fontsize=8,
            color="black",
            bbox={"boxstyle": "round,pad=0.15", "fc": "white", "ec": "none", "alpha": 0.7},
        )


def figure_png(fig) -> bytes:
    """A matplotlib figure as PNG bytes (no software stamp: reproducible), and closed."""
    buf = io.BytesIO()
    # light zlib compression: the pictures are small either way, and level 6 costs 0.1 s
    fig.savefig(buf, format="png", metadata={"Software": None}, pil_kwargs={"compress_level": 1})
    _figure().close(fig)
    return buf.getvalue()


def face_image(
    uv: np.ndarray, F: np.ndarray, values: np.ndarray, width_mm: float, height_mm: float, max_px: int = 800
) -> np.ndarray:
    """Rasterise per-face values over the flat rectangle, top row = top of the print.

    Parameters
    ----------
    uv : (#V, 2) float
        Flat positions, mm, y up, rectangle [0, width_mm] x [0, height_mm].
    F : (#F, 3) int
        Triangles.
    values : (#F,) float
        Value per face.
    width_mm, height_mm : float
        Rectangle size.
    max_px : int
        Size of the longer side of the image.

    Returns
    -------
    img : (h, w) float
        Values per pixel, NaN outside the mesh.
    """
    from workbench.raster import rasterize_triangles

    px_per_mm = max_px / max(width_mm, height_mm)
    w = max(int(round(width_mm * px_per_mm)), 1)
    h = max(int(round(height_mm * px_per_mm)), 1)
    # pixel centre (j, i) sits at x = (j + 0.5) / px_per_mm, y = height - (i + 0.5) / px_per_mm
    P = np.stack([uv[:, 0] * px_per_mm - 0.5, (height_mm - uv[:, 1]) * px_per_mm - 0.5], axis=1)
    face, _ = rasterize_triangles(P, F, w, h)
    img = np.full(face.shape, np.nan)
    img[face >= 0] = values[face[face >= 0]]
    return img


def stretch_figure(uv, F, stretch, corners, width_mm, height_mm, title, limit=None, labels=()) -> bytes:
    """PNG of the film stretch over the flat print (:func:`stretch_plot`)."""
    return figure_png(stretch_plot(uv, F, stretch, corners, width_mm, height_mm, title, limit, labels))


def stretch_plot(uv, F, stretch, corners, width_mm, height_mm, title, limit=None, labels=()):
    """The film stretch over the print, y down from its top-left corner, with a colour bar and the corners.

    Parameters
    ----------
    uv : (#V, 2) float
        Flat positions, mm, y up (the flat layout's; drawn at print y = height_mm - y).
    F : (#F, 3) int
        Triangles.
    stretch : (#F,) float
        3D length / flat length per face.
    corners : (4,) int
        Vertices A, B, C, D.
    width_mm, height_mm : float
        Rectangle size.
    title : str
        Figure title.
    limit : float, optional
        The material's stretch limit, marked on the colour bar.
    labels : list of (x_mm, y_mm, text)
        Names written on the picture, print mm (x right, y down).

    Returns
    -------
    matplotlib Figure
        Its first axes is the print (:func:`print_axes`).
    """
    plt = _figure()
    img = face_image(uv, F, stretch, width_mm, height_mm)
    aspect = height_mm / width_mm
    fig, ax = plt.subplots(figsize=(8, max(8 * aspect, 3) + 0.8), dpi=120)
    lo, hi = np.nanmin(img) if np.isfinite(img).any() else 1.0, np.nanmax(img) if np.isfinite(img).any() else 1.0
    if hi - lo < 1e-6:
        lo, hi = lo - 1e-3, hi + 1e-3
    if limit is not None and limit > hi:
        hi = limit + 0.08 * (limit - lo)  # show how far the part stays below the limit
    im = ax.imshow(
        img,
        extent=print_extent(width_mm, height_mm),
        origin="upper",
        cmap="viridis",
        vmin=lo,
        vmax=hi,
        interpolation="nearest",
    )
    print_axes(ax, width_mm, height_mm)
    bar = fig.colorbar(im, ax=ax, fraction=0.046, pad=0.04)
    bar.set_label("film stretch (3D length / print length)")
    if limit is not None:
        bar.ax.axhline(limit, color="red", lw=2)
        bar.ax.text(
            0.5,
            limit,
            "limit",
            color="red",
            va="bottom",
            ha="center",
            fontsize=8,
            transform=bar.ax.get_yaxis_transform(),
            clip_on=True,
        )
    _label_films(ax, labels)
    for name, v in zip("ABCD"[: len(corners)], corners, strict=True):
        x, y = uv[v][0], height_mm - uv[v][1]
        ax.plot([x], [y], "o", color="red", ms=6, clip_on=False)
        # labels point inwards so they stay clear of the colour bar and the title
        right, bottom = x > 0.5 * width_mm, y > 0.5 * height_mm
        ax.annotate(
            f"{name} ({v})",
            (x, y),
            textcoords="offset points",
            xytext=(-6 if right else 6, 6 if bottom else -6),
            ha="right" if right else "left",
            va="bottom" if bottom else "top",
            color="red",
            fontsize=10,
            fontweight="bold",
        )
    ax.set_title(title, fontsize=10)
    return fig


VIEW_COLOURS = [
    (31, 119, 180),
    (255, 127, 14),
    (44, 160, 44),
    (214, 39, 40),
    (148, 103, 189),
    (140, 86, 75),
    (227, 119, 194),
    (127, 127, 127),
    (188, 189, 34),
    (23, 190, 207),
]


def views_figure(
    owner: np.ndarray,
    names: list[str],
    shares: list[float],
    width_mm: float,
    height_mm: float,
    title: str,
    max_px: int = 1000,
    film: np.ndarray | None = None,
    labels=(),
) -> bytes:
    """PNG of which view owns each print pixel, with a legend (:func:`views_plot`)."""
    return figure_png(views_plot(owner, names, shares, width_mm, height_mm, title, max_px, film, labels))


def views_plot(
    owner: np.ndarray,
    names: list[str],
    shares: list[float],
    width_mm: float,
    height_mm: float,
    title: str,
    max_px: int = 1000,
    film: np.ndarray | None = None,
    labels=(),
):
    """Which view owns each print pixel, y down from the print's top-left corner, with a legend.

    Parameters
    ----------
    owner : (rows, cols) int8
        Owning view per print pixel, -1 for none.
    names : list of str
        View names.
    shares : list of float
        Share of the print each view owns.
    width_mm, height_mm : float
        Design rectangle.
    title : str
        Figure title.
    max_px : int
        Longer side of the picture's raster.
    film : (rows, cols) bool, optional
        Pixels inside the film's outline; the rest is drawn white, outside the
        shares. None: the whole rectangle is film.
    labels : list of (x_mm, y_mm, text)
        Names written on the picture (the films of a design with several), print mm (x right, y down).

    Returns
    -------
    matplotlib Figure
        Its first axes is the print (:func:`print_axes`).
    """
    import cv2
    from matplotlib.patches import Patch

    plt = _figure()
    rows, cols = owner.shape
    s = min(1.0, max_px / max(rows, cols))
    small = cv2.resize(owner, (max(int(cols * s), 1), max(int(rows * s), 1)), interpolation=cv2.INTER_NEAREST)
    palette = np.array(VIEW_COLOURS * (len(names) // len(VIEW_COLOURS) + 1), dtype=np.uint8)
    img = np.full(small.shape + (3,), 235, dtype=np.uint8)
    img[small >= 0] = palette[small[small >= 0]]
    if film is not None:
        small_film = cv2.resize(film.astype(np.uint8), small.shape[::-1], interpolation=cv2.INTER_NEAREST) > 0
        img[~small_film] = 255
    fig, ax = plt.subplots(figsize=(8, max(8 * height_mm / width_mm, 3) + 1.2), dpi=110)
    ax.imshow(img, extent=print_extent(width_mm, height_mm), origin="upper", interpolation="nearest")
    print_axes(ax, width_mm, height_mm)
    _label_films(ax, labels)
    handles = [
        Patch(color=palette[i] / 255, label=f"{n} ({100 * sh:.1f} %)")
        for i, (n, sh) in enumerate(zip(names, shares, strict=True))
    ]
    unowned = float((owner < 0).mean() if film is None else (owner[film] < 0).mean())
    handles.append(Patch(color=(235 / 255,) * 3, label=f"no view, background ({100 * unowned:.1f} %)"))
    ax.legend(handles=handles, loc="upper center", bbox_to_anchor=(0.5, -0.12), ncol=min(len(handles), 3), fontsize=9)
    ax.set_title(title, fontsize=10)
    fig.tight_layout()
    return fig


# the selection's classes (workbench.mesh.selection.CLASS_WORDS): not printed grey, seen blue,
# margin amber, hole filled green, seen but left apart red
SURFACE_RGB = np.array(
    [[0.70, 0.70, 0.70], [0.22, 0.52, 0.85], [0.98, 0.68, 0.18], [0.30, 0.72, 0.35], [0.86, 0.22, 0.22]]
)
SURFACE_PANEL_PX = 480  # the width each view's panel is drawn at


def surface_image(V: np.ndarray, F: np.ndarray, face_class: np.ndarray, camera) -> tuple[np.ndarray, np.ndarray]:
    """A part seen from a view's camera, each face in its selection class's colour, shaded.

    Parameters
    ----------
    V : (#V, 3) float
        The part, mm.
    F : (#F, 3) int
        Its triangles.
    face_class : (#F,) int
        Each face's class, an index into :data:`SURFACE_RGB`.
    camera : workbench.camera.Camera
        The view's camera (drawn at :data:`SURFACE_PANEL_PX` wide).

    Returns
    -------
    img : (h, w, 3) float
        RGB in 0-1, white off the part; a face's colour times 0.35 + 0.65 |cos| of the angle
        between its normal and the ray from it to the camera.
    depth : (h, w) float
        The nearest surface's depth, mm, +inf off the part (for what lies in front of a seam).
    """
    from workbench.raster import depth_buffer

    cam = camera.scaled(SURFACE_PANEL_PX / camera.width)
    xy, z = cam.project(V)
    face, depth = depth_buffer(xy, z, F, cam.width, cam.height)
    img = np.ones((cam.height, cam.width, 3))
    on = face >= 0
    f = face[on]
    # (the faces seen only: a part of 360k faces shows a few tens of thousands at this size)
    shown, at = np.unique(f, return_inverse=True)
    T = V[F[shown]]
    n = np.cross(T[:, 1] - T[:, 0], T[:, 2] - T[:, 0])
    ray = cam.center.reshape(1, 3) - T.mean(axis=1)
    cos = np.abs((n * ray).sum(axis=1)) / np.maximum(np.linalg.norm(n, axis=1) * np.linalg.norm(ray, axis=1), 1e-300)
    img[on] = SURFACE_RGB[face_class[f]] * (0.35 + 0.65 * cos[at])[:, None]
    return img, depth


def surface_figure(V, F, face_class, cameras, names, seams, legend, title) -> bytes:
    """What of a part is printed and why, seen from each view (``surface.png``).

    Parameters
    ----------
    V : (#V, 3) float
        The part, mm.
    F : (#F, 3) int
        Its triangles.
    face_class : (#F,) int
        Each face's selection class (:data:`workbench.mesh.selection.CLASS_WORDS`).
    cameras : list of Camera
        The views' cameras, one panel each.
    names : list of str
        What each camera is ("view top", "the far side").
    seams : list of (k,) int
        Each seam's vertices in order (indices of ``V``), drawn red where no surface is in front.
    legend : list of (int, str)
        Each class shown and its words (with its area).
    title : str

    Returns
    -------
    bytes
        PNG.
    """
    from matplotlib.patches import Patch

    plt = _figure()
    n = max(len(cameras), 1)
    fig, axes = plt.subplots(1, n, figsize=(4.2 * n, 4.4), squeeze=False)
    for ax, camera, name in zip(axes[0], cameras, names, strict=True):
        img, depth = surface_image(V, F, face_class, camera)
        ax.imshow(img, interpolation="nearest")
        panel = camera.scaled(SURFACE_PANEL_PX / camera.width)  # (the camera surface_image drew with)
        for seam in seams:
            xy, z = panel.project(V[np.asarray(seam)])
            i = np.clip(np.round(xy[:, 1]).astype(int), 0, depth.shape[0] - 1)
            j = np.clip(np.round(xy[:, 0]).astype(int), 0, depth.shape[1] - 1)
            # in front: no nearer surface at its pixel (a pixel spans a millimetre or so of depth)
            front = z <= depth[i, j] + 0.01 * z + 1.0
            shown = np.where(front, xy[:, 0], np.nan)
            ax.plot(shown, np.where(front, xy[:, 1], np.nan), color="red", lw=1.6)
        ax.set_title(f"from {name}", fontsize=9)
        ax.set_axis_off()
    handles = [Patch(color=SURFACE_RGB[k], label=words) for k, words in legend]
    if seams:
        from matplotlib.lines import Line2D

        handles.append(Line2D([0], [0], color="red", lw=1.6, label=f"seam cut to make it one disc ({len(seams)})"))
    fig.legend(handles=handles, loc="lower center", ncol=min(len(handles), 3), fontsize=8, frameon=False)
    fig.suptitle(title, fontsize=9)
    fig.tight_layout(rect=(0, 0.12, 1, 0.93))
    return figure_png(fig)
