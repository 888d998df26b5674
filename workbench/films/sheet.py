"""Several films on one sheet: the seams between them and their prints' places."""

from __future__ import annotations

import numpy as np

from workbench.films.regions import face_graph


def seams(F: np.ndarray, V: np.ndarray, film_of_face: np.ndarray, owner_view: np.ndarray) -> dict:
    """Seams between films: total length and the part inside one view's region.

    Parameters
    ----------
    F : (#F, 3) int
    V : (#V, 3) float
    film_of_face : (#F,) int
        Film per face, -1 for none.
    owner_view : (#F,) int
        First owning view per face, -1 for none.

    Returns
    -------
    dict
        ``length_mm`` (all seams), ``in_view_mm`` (seams with the same view on both
        sides: visible in that view's image), ``per_film_mm`` (seam length around
        each film).
    """
    _, E, edge_faces = face_graph(F)
    inner = edge_faces[:, 1] >= 0
    a, b = edge_faces[inner, 0], edge_faces[inner, 1]
    fa, fb = film_of_face[a], film_of_face[b]
    seam = (fa != fb) & (fa >= 0) & (fb >= 0)
    length = np.linalg.norm(V[E[inner, 0]] - V[E[inner, 1]], axis=1)
    in_view = seam & (owner_view[a] == owner_view[b]) & (owner_view[a] >= 0)
    n = int(film_of_face.max()) + 1
    per = np.bincount(fa[seam], weights=length[seam], minlength=n) + np.bincount(
        fb[seam], weights=length[seam], minlength=n
    )
    return {
        "length_mm": float(length[seam].sum()),
        "in_view_mm": float(length[in_view].sum()),
        "per_film_mm": per.tolist(),
    }


def pack_films(sizes_px: list[tuple[int, int]], gap_px: int) -> tuple[list[tuple[int, int]], tuple[int, int]]:
    """Places for film prints on one sheet of pixels (shelf packing, tallest first).

    Parameters
    ----------
    sizes_px : list of (rows, cols)
        Print size of each film, pixels.
    gap_px : int
        Free pixels between films.

    Returns
    -------
    offsets : list of (row, col)
        Top-left pixel of each film, in the input order.
    shape : (rows, cols)
        The sheet.
    """
    total = sum((r + gap_px) * (c + gap_px) for r, c in sizes_px)
    width = max(max(c for _, c in sizes_px), int(np.sqrt(total) * 1.2))
    order = sorted(range(len(sizes_px)), key=lambda k: (-sizes_px[k][0], k))
    offsets: list[tuple[int, int]] = [(0, 0)] * len(sizes_px)
    row = col = shelf = 0
    for k in order:
        r, c = sizes_px[k]
        if col > 0 and col + c > width:
            row, col, shelf = row + shelf + gap_px, 0, 0
        offsets[k] = (row, col)
        col += c + gap_px
        shelf = max(shelf, r)
    rows = max(o[0] + s[0] for o, s in zip(offsets, sizes_px, strict=True))
    cols = max(o[1] + s[1] for o, s in zip(offsets, sizes_px, strict=True))
    return offsets, (rows, cols)
