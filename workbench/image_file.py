"""Image files read as every viewer shows them: by Python's own file calls, turned upright by their EXIF orientation.

Two things made reading an image file wrong before this module:

- OpenCV's ``imread`` takes the path as UTF-8; a name that is not (a folder ``Teil \\xfc``
  made under a Latin-1 locale, read back under another) crashed the process with a
  segmentation fault. Here the bytes are read by Python, which handles every name the
  file system has, and decoded in memory.
- A phone stores its photo as the sensor saw it and says in the EXIF orientation tag how to
  turn it; every viewer turns it. OpenCV turns it for some read flags and not others (never
  for an image read unchanged, with its alpha). Here it is always turned, the same way.
"""

from __future__ import annotations

import io
import warnings
from pathlib import Path

import cv2
import numpy as np

# EXIF tag 0x0112: how the stored image is to be turned to stand upright (1 = as stored)
ORIENTATION_TAG = 0x0112


def read_file_bytes(path) -> bytes:
    """The bytes of ``path`` (OSError as Python raises it: missing, a loop, no permission)."""
    with open(Path(path), "rb") as f:
        return f.read()


def exif_orientation(data: bytes) -> int:
    """The EXIF orientation (1 to 8) of an encoded image; 1 when it has none or it cannot be read.

    Parameters
    ----------
    data : bytes
        The image file's contents (JPEG, PNG, TIFF, WebP: whatever carries EXIF).

    Returns
    -------
    int
        1 upright; 2 mirrored left-right; 3 turned half a turn; 4 mirrored top-bottom; 5 mirrored
        about the main diagonal; 6 to be turned a quarter clockwise; 7 mirrored about the other
        diagonal; 8 to be turned a quarter counter-clockwise.
    """
    from PIL import Image

    try:
        if data[:8] == PNG_SIGNATURE:
            # Pillow decodes a whole PNG to look for its EXIF (0.08 s for a 4 Mpx print, twice
            # OpenCV's decoding): the eXIf chunk is found by its chunk's header instead
            raw = _png_exif(data)
            if raw is None:
                return 1
            exif = Image.Exif()
            exif.load(raw)
            value = exif.get(ORIENTATION_TAG, 1)
        else:
            # (the header only; the image's size is checked where it is read, not by PIL's bomb warning)
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", Image.DecompressionBombWarning)
                with Image.open(io.BytesIO(data)) as im:
                    value = im.getexif().get(ORIENTATION_TAG, 1)
    except Exception:  # a file PIL does not know, or a damaged EXIF block: as stored, as OpenCV would
        return 1
    return int(value) if isinstance(value, int) and 1 <= value <= 8 else 1


PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"


def _png_exif(data: bytes) -> bytes | None:
    """The contents of a PNG's eXIf chunk (before or after its image data), or None.

    A chunk is its length (4 bytes, big-endian), its type (4), its data and a CRC (4).
    """
    at = len(PNG_SIGNATURE)
    while at + 8 <= len(data):
        n = int.from_bytes(data[at : at + 4], "big")
        kind = data[at + 4 : at + 8]
        if kind == b"eXIf":
            return data[at + 8 : at + 8 + n]
        if kind == b"IEND":
            return None
        at += 12 + n
    return None


def upright(img: np.ndarray, orientation: int) -> np.ndarray:
    """``img`` turned as its EXIF ``orientation`` says (the rows and columns of any channels).

    Parameters
    ----------
    img : (H, W) or (H, W, C) array
        The image as stored.
    orientation : int
        1 to 8 (:func:`exif_orientation`).

    Returns
    -------
    (H, W, ...) or (W, H, ...) array
        Upright; a view of ``img`` made contiguous.
    """
    # the eight are the dihedral group of the square; each as numpy writes it (rows first):
    # a quarter clockwise is rot90 by -1, the main diagonal is the transpose of rows and columns
    turned = {
        1: lambda a: a,
        2: lambda a: a[:, ::-1],
        3: lambda a: a[::-1, ::-1],
        4: lambda a: a[::-1],
        5: lambda a: np.swapaxes(a, 0, 1),
        6: lambda a: np.rot90(a, -1),
        7: lambda a: np.swapaxes(a, 0, 1)[::-1, ::-1],
        8: lambda a: np.rot90(a, 1),
    }[orientation if orientation in range(1, 9) else 1](img)
    return np.ascontiguousarray(turned)


def decode_upright(data: bytes, flags: int = cv2.IMREAD_UNCHANGED) -> np.ndarray | None:
    """Decode an image file's bytes with OpenCV's ``flags`` and turn it upright by its EXIF orientation.

    Parameters
    ----------
    data : bytes
        The encoded image.
    flags : int
        ``cv2.IMREAD_UNCHANGED``, ``cv2.IMREAD_COLOR`` or ``cv2.IMREAD_GRAYSCALE``.

    Returns
    -------
    array or None
        As ``cv2.imdecode`` returns it (BGR order), upright; None when it is not an image.
    """
    if not data:
        return None
    buf = np.frombuffer(data, np.uint8)
    # OpenCV turns some reads itself: never here, so that every flag turns once, the same way
    own = flags if flags == cv2.IMREAD_UNCHANGED else flags | cv2.IMREAD_IGNORE_ORIENTATION
    img = cv2.imdecode(buf, own)
    if img is None or img.size == 0:
        return None
    return upright(img, exif_orientation(data))


def imread(path, flags: int = cv2.IMREAD_UNCHANGED) -> np.ndarray | None:
    """``cv2.imread`` for any file name, upright: None when missing, unreadable or not an image.

    Parameters
    ----------
    path : Path or str
        The image file.
    flags : int
        As :func:`decode_upright`.

    Returns
    -------
    array or None
        BGR (or grey, or BGRA) as OpenCV decodes it, upright.
    """
    try:
        data = read_file_bytes(path)
    except OSError:
        return None
    return decode_upright(data, flags)
