"""Is the photo fit to judge the print? Clipping, JPEG blocks, no colour: the photo's fault, not the print's.

A photo over-exposed until the ink clips, compressed until its 8 x 8 blocks show, or without
colour (a greyscale file) makes the print look wrong everywhere: the dense analysis then finds
colour defects that are the photo's. Each check here looks at what the print cannot cause:

- **Clipping**: the share of the part's print, where the design has no channel near the top
  (not white, not a fully saturated ink), that the photo shows with a channel at the sensor's
  top. Such ink does not clip under a sound exposure; a glossy highlight covers a few per cent.
- **JPEG blocks**: the quality a JPEG was saved at, from its quantisation tables (exact for
  libjpeg's; a camera's own tables read as the nearest standard quality). Below 30 its 8 x 8
  blocks show at the print's detail (the photo's pixel statistics could not tell that apart
  from noise reliably: a noisy photo at quality 90 steps across its block edges too).
- **No colour**: the photo has no chroma anywhere (every pixel's channels within a few levels:
  the fixture's chart, its markers' surroundings and the print alike) while the design has
  colour. A print that lost its colour still sits in a coloured photo.

Pure functions: arrays in, figures out.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class QualityOptions:
    """Thresholds of the photo checks.

    Attributes
    ----------
    clipped_level : int
        A channel at or above this (0 to 255) is clipped.
    design_white : int
        Design pixels with any channel at or above this (white, a saturated ink) may clip in a
        sound photo; they are left out of the clipping share.
    max_clipped_share : float
        Largest share of the part's inked print the photo may show clipped.
    min_jpeg_quality : float
        Lowest JPEG quality (libjpeg's scale) whose blocks do not show.
    grey_chroma : float
        A photo whose 99th percentile of chroma (a pixel's largest channel minus its smallest,
        grey levels) is below this has no colour.
    design_chroma : float
        Chroma of a design pixel that counts as coloured.
    min_coloured_share : float
        Share of the design's pixels that must be coloured for a photo without colour to be at fault.
    """

    clipped_level: int = 250
    design_white: int = 230
    max_clipped_share: float = 0.3
    min_jpeg_quality: float = 30.0
    grey_chroma: float = 6.0
    design_chroma: float = 40.0
    min_coloured_share: float = 0.05


def clipped_share(warped: np.ndarray, reference: np.ndarray, seen: np.ndarray, opts: QualityOptions) -> float | None:
    """Share of the seen, inked print pixels that the photo shows clipped.

    Parameters
    ----------
    warped, reference : (rows, cols, 3) uint8
        The photo on the print grid and the design there.
    seen : (rows, cols) bool
        Grid pixels where the photo sees the part.
    opts : QualityOptions

    Returns
    -------
    float or None
        None when no inked pixel is seen.
    """
    import cv2

    # channel reductions with OpenCV: numpy's over the last axis of a 1.4 Mpx grid are slow
    inked = seen & (cv2.max(cv2.max(reference[..., 0], reference[..., 1]), reference[..., 2]) < opts.design_white)
    n = int(inked.sum())
    if n == 0:
        return None
    top = cv2.max(cv2.max(warped[..., 0], warped[..., 1]), warped[..., 2])
    return float(np.count_nonzero(inked & (top >= opts.clipped_level)) / n)


# the JPEG standard's luminance quantisation table (ITU-T T.81, annex K), natural order: what
# libjpeg scales by its quality setting (50: as is; q < 50: 5000 / q %; q > 50: 200 - 2q %)
STANDARD_LUMA_TABLE = np.array(
    [
        [16, 11, 10, 16, 24, 40, 51, 61],
        [12, 12, 14, 19, 26, 58, 60, 55],
        [14, 13, 16, 24, 40, 57, 69, 56],
        [14, 17, 22, 29, 51, 87, 80, 62],
        [18, 22, 37, 56, 68, 109, 103, 77],
        [24, 35, 55, 64, 81, 104, 113, 92],
        [49, 64, 78, 87, 103, 121, 120, 101],
        [72, 92, 95, 98, 112, 100, 103, 99],
    ],
    dtype=np.float64,
).ravel()


def jpeg_quality(luma_table) -> float | None:
    """The libjpeg quality (1 to 100) a JPEG's luminance quantisation table was scaled for; None without one.

    The median ratio of the table to the standard one over the entries not clipped at 255
    (at quality 5 most are), inverted through libjpeg's scaling. Cameras and editors that
    use their own tables get the quality of the standard table nearest theirs.

    Parameters
    ----------
    luma_table : sequence of 64 int, natural order (Pillow's ``Image.quantization[0]``), or None
    """
    if luma_table is None or len(luma_table) != 64:
        return None
    t = np.asarray(luma_table, dtype=np.float64)
    keep = t < 255
    if not keep.any():
        return 1.0
    scale = 100 * float(np.median(t[keep] / STANDARD_LUMA_TABLE[keep]))
    q = (200 - scale) / 2 if scale <= 100 else 5000 / scale
    return float(min(max(q, 1.0), 100.0))


def read_jpeg_quality(path) -> float | None:
    """:func:`jpeg_quality` of an image file (None: not a JPEG, or unreadable)."""
    from PIL import Image

    try:
        with Image.open(path) as im:
            tables = getattr(im, "quantization", None)
    except (OSError, ValueError):
        return None
    return jpeg_quality(tables.get(0)) if tables else None


def chroma_p99(rgb: np.ndarray, step: int = 4) -> float:
    """99th percentile of the chroma (largest channel minus smallest) of every ``step``-th pixel, grey levels."""
    sub = np.ascontiguousarray(rgb[::step, ::step])
    r, g, b = sub[..., 0], sub[..., 1], sub[..., 2]
    chroma = (np.maximum(np.maximum(r, g), b) - np.minimum(np.minimum(r, g), b)).ravel()
    return float(np.percentile(chroma, 99))


def photo_quality(
    photo: np.ndarray,
    warped: np.ndarray,
    reference: np.ndarray,
    seen: np.ndarray,
    jpeg: float | None = None,
    opts: QualityOptions = QualityOptions(),
) -> dict:
    """The photo's checks, and what is wrong with it.

    Parameters
    ----------
    photo : (H, W, 3) uint8
        The photo, sRGB-encoded.
    warped, reference : (rows, cols, 3) uint8
        The photo on the print grid and the design there.
    seen : (rows, cols) bool
        Grid pixels where the photo sees the part.
    jpeg : float or None
        The photo file's JPEG quality (:func:`read_jpeg_quality`), None when it is no JPEG.
    opts : QualityOptions

    Returns
    -------
    dict
        JSON-ready: ``clipped_share``, ``jpeg_quality``, ``chroma_p99``,
        ``design_coloured_share`` and ``problems`` (a list of sentences; empty when the photo
        is fit to judge the print).
    """
    clipped = clipped_share(warped, reference, seen, opts)
    chroma = chroma_p99(photo)
    ref = reference[::4, ::4]  # the design's share of colour: a sixteenth of its pixels tells
    ref_on = seen[::4, ::4] if seen.any() else np.ones(ref.shape[:2], bool)
    r, g, b = (ref[..., k].astype(np.int16) for k in range(3))
    design_chroma = np.maximum(np.maximum(r, g), b) - np.minimum(np.minimum(r, g), b)
    coloured = float((design_chroma[ref_on] >= opts.design_chroma).mean()) if ref_on.any() else 0.0
    problems = []
    if clipped is not None and clipped > opts.max_clipped_share:
        problems.append(
            f"over-exposed: {100 * clipped:.0f} % of the inked print it sees is clipped (a channel at "
            f"{opts.clipped_level} or more; at most {100 * opts.max_clipped_share:.0f} %): reduce the exposure"
        )
    if jpeg is not None and jpeg < opts.min_jpeg_quality:
        problems.append(
            f"a JPEG of quality {jpeg:.0f} (its quantisation tables; at least {opts.min_jpeg_quality:g}): its 8 x 8 "
            "blocks show at the print's detail; save the photo at a higher quality, or lossless"
        )
    if chroma < opts.grey_chroma and coloured >= opts.min_coloured_share:
        problems.append(
            f"the photo has no colour (chroma p99 {chroma:.1f} grey levels) where {100 * coloured:.0f} % of the "
            "design is coloured: a greyscale photo; take it in colour"
        )
    return {
        "clipped_share": None if clipped is None else round(clipped, 4),
        "jpeg_quality": None if jpeg is None else round(jpeg, 1),
        "chroma_p99": round(chroma, 2),
        "design_coloured_share": round(coloured, 4),
        "problems": problems,
    }
