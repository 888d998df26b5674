"""The decorated surface chosen on a part: what the views see, grown by a margin, holes filled, islands dropped."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import connected_components, dijkstra

from workbench.errors import WorkbenchError

# A hole in the selection (a piece of the rest of the part it encloses) is filled when its
# area is at most this share of the selection, and an island (a piece of the selection apart
# from its largest) that is dropped is said to be dropped when it is larger. Filling a hole
# prints the part's background colour over it, dropping an island leaves it bare: both are
# surface no view decorates, and design tolerates 2 % of the decorated surface left undecorated
# before it warns (design.MAX_BARE_SHARE); the same share is the limit here.
SMALL_SHARE = 0.02


@dataclass(frozen=True)
class SelectionOptions:
    """How the decorated surface is grown and cleaned.

    Attributes
    ----------
    margin_mm : float
        Surface grown around what the views see, mm along the surface.
    small_share : float
        Holes at most this share of the selection's area are filled; islands are dropped
        (one film is one piece) and those above it are reported as decoration left bare.
    """

    margin_mm: float = 3.0
    small_share: float = SMALL_SHARE


def edge_faces(F: np.ndarray, FE: np.ndarray, n_edges: int) -> np.ndarray:
    """The two faces of every edge.

    Parameters
    ----------
    F : (#F, 3) int
        Triangles.
    FE : (#F, 3) int
        Edge opposite each corner (:func:`workbench.mesh.topology.unique_edges`).
    n_edges : int
        Number of edges.

    Returns
    -------
    (#E, 2) int
        The faces of each edge in increasing order, -1 for the missing one of a boundary edge.
    """
    out = np.full((n_edges, 2), -1, dtype=np.int64)
    e = FE.ravel()
    f = np.repeat(np.arange(len(F)), 3)
    order = np.argsort(e, kind="stable")
    e, f = e[order], f[order]
    first = np.r_[True, e[1:] != e[:-1]]
    out[e[first], 0] = f[first]
    out[e[~first], 1] = f[~first]
    return out


def vertex_distance(V: np.ndarray, E: np.ndarray, seed: np.ndarray, limit: float) -> np.ndarray:
    """Distance along the mesh's edges from a set of vertices to every vertex, mm.

    Dijkstra over the edges, each as long as it is: a path along edges is never shorter than
    the geodesic, and longer by at most the zigzag of the triangles it crosses (nothing along a
    grid line, about 8 % across a grid of right triangles).

    Parameters
    ----------
    V : (#V, 3) float
        Vertices, mm.
    E : (#E, 2) int
        Edges.
    seed : (#V,) bool
        The vertices measured from.
    limit : float
        Distances beyond it are not computed (infinite), mm.

    Returns
    -------
    (#V,) float
        Distance per vertex, mm; 0 on the seed, inf beyond ``limit`` or unreachable.
    """
    n = len(V)
    sources = np.flatnonzero(seed)
    if len(sources) == 0:
        return np.full(n, np.inf)
    w = np.linalg.norm(V[E[:, 0]] - V[E[:, 1]], axis=1)
    G = sp.csr_matrix((np.r_[w, w], (np.r_[E[:, 0], E[:, 1]], np.r_[E[:, 1], E[:, 0]])), shape=(n, n))
    return dijkstra(G, indices=sources, min_only=True, limit=limit)


def face_components(ef: np.ndarray, mask: np.ndarray) -> np.ndarray:
    """Connected components of some faces, through shared edges.

    Parameters
    ----------
    ef : (#E, 2) int
        Faces of each edge (:func:`edge_faces`).
    mask : (#F,) bool
        The faces.

    Returns
    -------
    (#F,) int
        Component per face of ``mask``, numbered by their lowest face; -1 elsewhere.
    """
    n = len(mask)
    inner = ef[:, 1] >= 0
    a, b = ef[inner, 0], ef[inner, 1]
    both = mask[a] & mask[b]
    G = sp.csr_matrix((np.ones(int(both.sum())), (a[both], b[both])), shape=(n, n))
    _, labels = connected_components(G, directed=False)
    out = np.full(n, -1, dtype=np.int64)
    idx = np.flatnonzero(mask)
    if len(idx) == 0:
        return out
    # renumbered by their lowest face, so that the numbering does not depend on scipy's
    uniq, first, inverse = np.unique(labels[idx], return_index=True, return_inverse=True)
    rank = np.empty(len(uniq), dtype=np.int64)
    rank[np.argsort(first)] = np.arange(len(uniq))
    out[idx] = rank[inverse.ravel()]
    return out


# what the selection made of each face (SelectionReport.face_class), and the words for it
LEFT, SEEN, MARGIN, HOLE, APART = 0, 1, 2, 3, 4
CLASS_WORDS = (
    "not printed",
    "seen by a view",
    "margin beyond what is seen",
    "hole filled",
    "seen, but apart from the rest (left bare)",
)


@dataclass(frozen=True)
class SelectionReport:
    """What the selection did, in figures (mm² of surface; counts of faces or pieces).

    ``face_class`` (#F,) uint8 says it per face: :data:`LEFT`, :data:`SEEN`, :data:`MARGIN`,
    :data:`HOLE` or :data:`APART` (words in :data:`CLASS_WORDS`); not in :meth:`to_dict`.
    """

    seen_faces: int
    seen_mm2: float
    margin_mm: float
    margin_faces: int
    margin_mm2: float
    holes_filled: int
    holes_filled_mm2: float
    hole_limit_mm2: float
    islands_dropped: int
    islands_dropped_mm2: float
    islands_over_limit_mm2: float
    selected_faces: int
    selected_mm2: float
    mesh_mm2: float
    opened_faces: int
    face_class: np.ndarray | None = field(default=None, repr=False, compare=False)

    def to_dict(self) -> dict:
        """JSON-ready, the shares of the mesh included."""
        d = {k: v for k, v in self.__dict__.items() if k != "face_class"}
        d["selected_share"] = self.selected_mm2 / max(self.mesh_mm2, 1e-300)
        d["seen_share"] = self.seen_mm2 / max(self.mesh_mm2, 1e-300)
        return d


def select_surface(
    V: np.ndarray,
    F: np.ndarray,
    E: np.ndarray,
    ef: np.ndarray,
    seen: np.ndarray,
    options: SelectionOptions,
    cost: np.ndarray | None = None,
) -> tuple[np.ndarray, SelectionReport]:
    """The decorated surface: the faces seen, grown by the margin, small holes filled, one piece.

    In this order: grow (faces within the margin, :func:`vertex_distance`), fill the holes (pieces of
    the rest of the mesh that the selection encloses: every piece but the largest, and, on an
    open mesh, those that reach its boundary) of at most ``small_share`` of the selection's
    area, and keep the largest piece (by area), dropping the islands. A selection that is the
    whole of a closed mesh is opened at its least seen face (``cost``), so that it has a rim.

    Parameters
    ----------
    V : (#V, 3) float
        Vertices, mm.
    F : (#F, 3) int
        Triangles.
    E : (#E, 2) int
        Edges (:func:`workbench.mesh.topology.unique_edges`).
    ef : (#E, 2) int
        Faces of each edge (:func:`edge_faces`).
    seen : (#F,) bool
        Faces the views see (the seed).
    options : SelectionOptions
        Margin and size limit.
    cost : (#F,) float, optional
        How well the views see each face (larger: better); opens a closed selection at its least.

    Returns
    -------
    region : (#F,) bool
        The selected faces.
    report : SelectionReport
    """
    area = 0.5 * np.linalg.norm(np.cross(V[F[:, 1]] - V[F[:, 0]], V[F[:, 2]] - V[F[:, 0]]), axis=1)
    # the margin: every face that comes nearer than the margin to the seen faces. A face left
    # out then has all its corners at least the margin away, so the rim of the selection (edges
    # of faces left out) lies at least the margin from what the views see, and less than the
    # margin and one edge
    on_seen = np.zeros(len(V), bool)
    on_seen[F[seen].ravel()] = True
    dist = vertex_distance(V, E, on_seen, options.margin_mm)
    region = seen | (dist[F].min(axis=1) < options.margin_mm)
    grown = region & ~seen
    # holes: the pieces of the rest; the largest is the part's outside, and so is any piece
    # that reaches an open mesh's own boundary (the film's rim may lie there)
    rest = face_components(ef, ~region)
    holes_n, holes_mm2 = 0, 0.0
    limit = options.small_share * float(area[region].sum())
    if rest.max() >= 0:
        size = np.bincount(rest[~region], weights=area[~region])
        on_rim = np.zeros(len(size), bool)
        open_edge = ef[:, 1] < 0
        on_rim[rest[ef[open_edge, 0]][rest[ef[open_edge, 0]] >= 0]] = True
        outside = on_rim.copy()
        outside[int(np.argmax(size))] = True
        small = ~outside & (size <= limit)
        fill = small[np.maximum(rest, 0)] & (rest >= 0)
        holes_n, holes_mm2 = int(small.sum()), float(size[small].sum())
        region |= fill
    pieces = face_components(ef, region)
    if pieces.max() < 0:
        raise WorkbenchError("the views see no face of the mesh")
    size = np.bincount(pieces[region], weights=area[region])
    keep = int(np.argmax(size))
    dropped = np.delete(size, keep)
    region = pieces == keep
    opened = 0
    if region.all() and not (ef[:, 1] < 0).any():
        # the whole closed surface: a disc needs a rim; open it where the views see least
        c = np.zeros(len(F)) if cost is None else cost
        region[int(np.lexsort((area, c))[0])] = False
        opened = 1
    face_class = np.full(len(F), LEFT, np.uint8)
    face_class[seen] = APART  # (seen, and not kept: an island, or the face a closed surface is opened at)
    face_class[region & seen] = SEEN
    face_class[region & grown] = MARGIN
    face_class[region & ~seen & ~grown] = HOLE
    report = SelectionReport(
        seen_faces=int(seen.sum()),
        seen_mm2=float(area[seen].sum()),
        margin_mm=float(options.margin_mm),
        margin_faces=int((grown & region).sum()),
        margin_mm2=float(area[grown & region].sum()),
        holes_filled=holes_n,
        holes_filled_mm2=holes_mm2,
        hole_limit_mm2=limit,
        islands_dropped=len(dropped),
        islands_dropped_mm2=float(dropped.sum()),
        islands_over_limit_mm2=float(dropped[dropped > limit].sum()),
        selected_faces=int(region.sum()),
        selected_mm2=float(area[region].sum()),
        mesh_mm2=float(area.sum()),
        opened_faces=opened,
        face_class=face_class,
    )
    return region, report


def read_face_list(path: Path, n_faces: int, where: str) -> np.ndarray:
    """0-based face indices from a text file (whitespace or comma separated), checked against the mesh.

    Parameters
    ----------
    path : Path
        The text file.
    n_faces : int
        Faces of the mesh they index.
    where : str
        The job key that named the file, for messages (``job.toml: films[0] ('logo'): faces``).

    Returns
    -------
    (k,) int64
        The indices, as in the file.

    Raises
    ------
    WorkbenchError
        Not a list of integers, empty, or an index outside the mesh.
    """
    text = path.read_text(encoding="utf-8", errors="replace").replace(",", " ")
    try:
        idx = np.array([int(tok) for tok in text.split()], dtype=np.int64)
    except ValueError as exc:
        raise WorkbenchError(f"{where}: {path}: not a list of face indices ({exc})") from None
    if len(idx) == 0 or idx.min() < 0 or idx.max() >= n_faces:
        raise WorkbenchError(f"{where}: {path}: indices must lie in 0..{n_faces - 1}")
    return idx
