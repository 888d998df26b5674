"""Checks that a mesh is a clean topological disc, with messages that say where it is not."""

from __future__ import annotations

import numpy as np

from workbench.errors import WorkbenchError
from workbench.mesh.topology import (
    boundary_half_edges,
    boundary_loops,
    face_components,
    half_edges,
    unique_edges,
)


def _first(idx: np.ndarray, limit: int = 3) -> str:
    shown = ", ".join(str(int(i)) for i in idx[:limit])
    return shown + (", ..." if len(idx) > limit else "")


def _faces(name: str, idx, limit: int = 3) -> str:
    """Triangles named for a message: by the file's lines where ``name`` can say (:class:`MeshName`)."""
    if hasattr(name, "faces"):
        return name.faces(idx, limit)
    return f"face {_first(np.asarray(idx), limit)}"


def face_areas(V: np.ndarray, F: np.ndarray) -> np.ndarray:
    """Area of every triangle.

    Parameters
    ----------
    V : (#V, 3) float
        Vertex positions.
    F : (#F, 3) int
        Triangles.

    Returns
    -------
    A : (#F,) float
        Areas, in squared units of ``V``.
    """
    e1 = V[F[:, 1]] - V[F[:, 0]]
    e2 = V[F[:, 2]] - V[F[:, 0]]
    return 0.5 * np.linalg.norm(np.cross(e1, e2), axis=1)


# a face of at most this share of the square of the part's diagonal has zero area: relative to
# the bounding box, a face 1e-12 the size of the part is rounding noise
ZERO_AREA = 1e-12


def zero_area_faces(V: np.ndarray, F: np.ndarray) -> np.ndarray:
    """Faces of (numerically) zero area: three corners on one line, which no map flattens.

    Parameters
    ----------
    V : (#V, 3) float
        Vertex positions.
    F : (#F, 3) int
        Triangles.

    Returns
    -------
    (k,) int
        Their indices, ascending.
    """
    diag = float(np.linalg.norm(V.max(axis=0) - V.min(axis=0)))
    return np.flatnonzero(face_areas(V, F) <= ZERO_AREA * diag * diag)


def check_disc(V: np.ndarray, F: np.ndarray, name: str = "mesh") -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Raise unless ``(V, F)`` is a clean, consistently oriented topological disc.

    Parameters
    ----------
    V : (#V, 3) float
        Vertex positions.
    F : (#F, 3) int
        Triangles.
    name : str
        How to name the mesh in messages (usually its file).

    Returns
    -------
    loop : (#B,) int
        The boundary loop, interior on the left, starting at its smallest index.
    E, FE : arrays
        :func:`unique_edges` of ``F`` (computed here anyway, handed on).

    Raises
    ------
    WorkbenchError
        Naming the first problem found and the elements at fault.
    """
    nV = len(V)
    bad = np.flatnonzero(~np.isfinite(V).all(axis=1))
    if len(bad):
        raise WorkbenchError(f"{name}: {len(bad)} vertices have NaN or infinite coordinates (vertex {_first(bad)})")
    repeated = np.flatnonzero((F[:, 0] == F[:, 1]) | (F[:, 1] == F[:, 2]) | (F[:, 2] == F[:, 0]))
    if len(repeated):
        raise WorkbenchError(f"{name}: {len(repeated)} faces repeat a vertex ({_faces(name, repeated)})")
    unused = np.flatnonzero(np.bincount(F.ravel(), minlength=nV) == 0)
    if len(unused):
        raise WorkbenchError(
            f"{name}: {len(unused)} vertices are not used by any face (vertex {_first(unused)}); "
            "remove them (vertex numbers are kept as given, so they cannot be dropped silently)"
        )
    flat = zero_area_faces(V, F)
    if len(flat):
        raise WorkbenchError(f"{name}: {len(flat)} faces have zero area ({_faces(name, flat)})")

    E, FE, count = unique_edges(F)
    over = np.flatnonzero(count > 2)
    if len(over):
        e = E[over[0]]
        faces = np.flatnonzero((FE == over[0]).any(axis=1))
        raise WorkbenchError(
            f"{name}: {len(over)} non-manifold edges; edge ({e[0]}, {e[1]}) is shared by "
            f"{count[over[0]]} faces ({_faces(name, faces, 4)})"
        )
    # consistently oriented: the two faces of an interior edge run it in opposite
    # directions, so the directions (+1 when from < to) of its half-edges sum to 0
    H = half_edges(F).reshape(-1, 2)
    direction = np.where(H[:, 0] < H[:, 1], 1.0, -1.0)
    twisted = np.flatnonzero(np.abs(np.bincount(FE.ravel(), weights=direction, minlength=len(E))) > 1)
    if len(twisted):
        e = int(twisted[0])
        faces = np.flatnonzero(FE.ravel() == e) // 3
        a, b = H[np.flatnonzero(FE.ravel() == e)[0]]
        raise WorkbenchError(
            f"{name}: faces are inconsistently oriented: {_faces(name, faces[:2])} both run "
            f"edge ({a}, {b}) the same way"
        )
    labels = face_components(F, FE)
    n_comp = int(labels.max()) + 1
    if n_comp > 1:
        sizes = np.bincount(labels)
        raise WorkbenchError(
            f"{name}: mesh has {n_comp} connected components (sizes {_first(sizes, 4)} faces); a disc has 1"
        )
    # each open fan of faces around a vertex starts one boundary edge there: two or
    # more mark a vertex where separate sheets touch (pinches between closed fans
    # show up in the Euler characteristic below)
    B = boundary_half_edges(F, FE, count)
    pinched = np.flatnonzero(np.bincount(B[:, 0], minlength=nV) > 1)
    if len(pinched):
        raise WorkbenchError(
            f"{name}: {len(pinched)} non-manifold vertices where separate fans of faces meet (vertex {_first(pinched)})"
        )
    loops = boundary_loops(F, B)
    if not loops:
        raise WorkbenchError(f"{name}: mesh is closed (no boundary); cut it open into a disc")
    if len(loops) > 1:
        raise WorkbenchError(
            f"{name}: mesh has {len(loops)} boundary loops; a disc has 1 (hole along vertices {_first(loops[1])})"
        )
    chi = nV - len(E) + len(F)
    if chi != 1:
        raise WorkbenchError(
            f"{name}: mesh is not a disc: Euler characteristic {chi} with one boundary loop "
            f"(genus {(1 - chi) // 2}, or vertices where sheets touch); cut it along handles first"
        )
    return loops[0], E, FE
