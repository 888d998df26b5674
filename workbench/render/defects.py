"""Local defects of a decorated film, as truth for validation tests: bubbles, scratches, ink dropouts.

Every defect is given in print coordinates (mm from the trim's top-left corner, x right,
y down: the convention of ``print.png``) and applied to the print texture itself, so the
renderer's texture lookup shows it wherever the part is seen, through every film and lens
imperfection. The defect belongs to the film: a film moved by ``--film-offset-mm`` carries
its defects with it.

Specification strings (``workbench render --defect``):

- ``bubble:X,Y,R,SHIFT`` or ``bubble:X,Y,R,DX,DY``: a disc of radius R mm centred at (X, Y)
  where the print slid by SHIFT mm along +x (or by (DX, DY) mm, print coordinates): the
  surface inside the disc shows the print content from ``p - shift``.
- ``scratch:X0,Y0,X1,Y1,W``: the ink is gone within W / 2 mm of the segment (X0, Y0)-(X1, Y1)
  (a capsule: area L W + π W² / 4); the film's own colour shows (:data:`FILM_RGB`).
- ``dropout:X,Y,R``: the ink is missing in a disc of radius R mm; the film's colour shows.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

FILM_RGB = (255, 255, 255)  # what shows where the ink is gone: the clear film over a white part
SUBSAMPLES = 4  # per texture pixel and axis, for the defects' anti-aliased outlines
KINDS = {"bubble": (4, 5), "scratch": (5,), "dropout": (3,)}


@dataclass(frozen=True)
class Defect:
    """One local defect of the film, print mm (x right, y down).

    Attributes
    ----------
    kind : str
        ``bubble``, ``scratch`` or ``dropout``.
    params : tuple of float
        As in the specification string (a bubble's SHIFT form is stored as DX, 0).
    """

    kind: str
    params: tuple

    @classmethod
    def parse(cls, spec: str) -> Defect:
        """A defect from ``KIND:a,b,c,...``; ValueError with the reason when malformed."""
        kind, _, rest = spec.partition(":")
        kind = kind.strip().lower()
        if kind not in KINDS:
            raise ValueError(f"unknown defect kind {kind!r} (bubble, scratch, dropout)")
        try:
            vals = tuple(float(v) for v in rest.split(","))
        except ValueError:
            vals = ()
        if len(vals) not in KINDS[kind] or not all(np.isfinite(vals)):
            forms = {"bubble": "X,Y,R,SHIFT or X,Y,R,DX,DY", "scratch": "X0,Y0,X1,Y1,W", "dropout": "X,Y,R"}
            raise ValueError(f"{kind} needs {forms[kind]} (mm, print coordinates)")
        if kind == "bubble" and len(vals) == 4:
            vals = (*vals[:3], vals[3], 0.0)
        size = vals[2] if kind != "scratch" else vals[4]
        if not size > 0:
            raise ValueError(f"{kind}: the radius or width must be positive")
        return cls(kind, vals)

    def spec(self) -> str:
        return f"{self.kind}:" + ",".join(f"{v:g}" for v in self.params)

    def truth(self) -> dict:
        """Centre (print mm), area (print mm²) and what was done, for the photo's truth file."""
        p = self.params
        if self.kind == "scratch":
            length = float(np.hypot(p[2] - p[0], p[3] - p[1]))
            centre = [(p[0] + p[2]) / 2, (p[1] + p[3]) / 2]
            area = length * p[4] + np.pi * p[4] ** 2 / 4
            extra = {"from_mm": [p[0], p[1]], "to_mm": [p[2], p[3]], "width_mm": p[4], "length_mm": length}
        else:
            centre = [p[0], p[1]]
            area = np.pi * p[2] ** 2
            extra = {"radius_mm": p[2]}
            if self.kind == "bubble":
                extra["shift_mm"] = [p[3], p[4]]
        return {"kind": self.kind, "spec": self.spec(), "centre_mm": centre, "area_mm2": float(area), **extra}


def coverage(defect: Defect, shape: tuple[int, int], px_per_mm: float) -> tuple[np.ndarray, tuple[slice, slice]]:
    """Share of each texture pixel covered by the defect (anti-aliased), within its bounding box.

    Parameters
    ----------
    defect : Defect
    shape : (rows, cols)
        Texture size.
    px_per_mm : float
        Texture resolution.

    Returns
    -------
    alpha : (h, w) float32
        Covered share (0 to 1) of each pixel of the box.
    box : (slice, slice)
        Rows and columns of the box in the texture.
    """
    p = defect.params
    if defect.kind == "scratch":
        lo = np.array([min(p[0], p[2]), min(p[1], p[3])]) - p[4] / 2
        hi = np.array([max(p[0], p[2]), max(p[1], p[3])]) + p[4] / 2
    else:
        lo, hi = np.array(p[:2]) - p[2], np.array(p[:2]) + p[2]
    rows, cols = shape
    # pixel (i, j) covers [j, j + 1] x [i, i + 1] / px_per_mm mm
    j0, i0 = (max(int(np.floor(v * px_per_mm)) - 1, 0) for v in lo)
    j1 = min(int(np.ceil(hi[0] * px_per_mm)) + 1, cols)
    i1 = min(int(np.ceil(hi[1] * px_per_mm)) + 1, rows)
    if j1 <= j0 or i1 <= i0:
        return np.zeros((0, 0), np.float32), (slice(0, 0), slice(0, 0))
    s = SUBSAMPLES
    xs = (j0 + (np.arange((j1 - j0) * s) + 0.5) / s) / px_per_mm
    ys = (i0 + (np.arange((i1 - i0) * s) + 0.5) / s) / px_per_mm
    x, y = np.meshgrid(xs, ys)
    if defect.kind == "scratch":
        a, b = np.array(p[:2]), np.array(p[2:4])
        d = b - a
        t = np.clip(((x - a[0]) * d[0] + (y - a[1]) * d[1]) / max(float(d @ d), 1e-12), 0, 1)
        inside = np.hypot(x - a[0] - t * d[0], y - a[1] - t * d[1]) <= p[4] / 2
    else:
        inside = np.hypot(x - p[0], y - p[1]) <= p[2]
    alpha = inside.reshape(i1 - i0, s, j1 - j0, s).mean(axis=(1, 3)).astype(np.float32)
    return alpha, (slice(i0, i1), slice(j0, j1))


def apply_defects(print_rgb: np.ndarray, dpi: float, defects) -> np.ndarray:
    """The print texture with the film's defects, in the order given.

    Parameters
    ----------
    print_rgb : (rows, cols, 3) uint8
        The print.
    dpi : float
        Its resolution.
    defects : iterable of Defect

    Returns
    -------
    (rows, cols, 3) uint8
        A new texture (the input is not changed).
    """
    out = print_rgb.copy()
    ppm = dpi / 25.4
    for d in defects:
        alpha, box = coverage(d, out.shape[:2], ppm)
        if alpha.size == 0:
            continue
        region = out[box].astype(np.float32)
        if d.kind == "bubble":
            # the print slid by s inside the disc: a pixel there shows the content from p - s
            # (sampled from the whole texture, so the content comes from outside the box too)
            h, w = alpha.shape
            jj, ii = np.meshgrid(np.arange(w, dtype=np.float32) + box[1].start, np.arange(h, dtype=np.float32))
            ii += box[0].start
            src = cv2.remap(
                out,
                jj - np.float32(d.params[3] * ppm),
                ii - np.float32(d.params[4] * ppm),
                cv2.INTER_LINEAR,
                borderMode=cv2.BORDER_REPLICATE,
            ).astype(np.float32)
        else:
            src = np.broadcast_to(np.asarray(FILM_RGB, np.float32), region.shape)
        a = alpha[..., None]
        out[box] = np.clip(np.round(region * (1 - a) + src * a), 0, 255).astype(np.uint8)
    return out
