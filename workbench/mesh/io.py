"""Reading and writing triangle meshes without reordering their vertices."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from workbench.errors import WorkbenchError, exhausted

UNITS_MM = {"mm": 1.0, "cm": 10.0, "m": 1000.0, "in": 25.4}
MESH_SUFFIXES = (".obj", ".ply", ".stl", ".off", ".glb", ".gltf")


class MeshName(str):
    """A mesh file's name, for messages, that can say where in the file a triangle came from.

    A polygon of an OBJ is fan-triangulated: triangle numbers are not the file's faces, and a
    user looks for the line. ``faces(idx)`` names triangles by the file's lines (OBJ), else by number.
    """

    def faces(self, idx, limit: int = 3) -> str:
        """``face 7, 9`` or, for an OBJ, ``the faces on lines 31, 33 of the file (triangles 7, 9)``."""
        idx = np.asarray(idx, np.int64).ravel()
        shown = ", ".join(str(int(i)) for i in idx[:limit]) + (", ..." if len(idx) > limit else "")
        lines = face_lines(Path(self))
        if lines is None or not len(idx) or idx[:limit].max() >= len(lines):
            return f"face {shown}"
        where = ", ".join(str(int(lines[i])) for i in idx[:limit]) + (", ..." if len(idx) > limit else "")
        s = "s" if len(idx) > 1 else ""
        return f"the face{s} on line{s} {where} of the file (triangle{s} {shown})"


def face_lines(path: Path) -> np.ndarray | None:
    """The file line (1-based) of each triangle :func:`read_mesh` makes of an OBJ; None for other formats.

    Read again only for a message: a polygon's triangles share its line.
    """
    if Path(path).suffix.lower() != ".obj":
        return None
    try:
        text = Path(path).read_bytes().decode("utf-8", "replace")
    except OSError:
        return None
    out = []
    for lineno, line in enumerate(text.replace("\t", " ").splitlines(), 1):
        line = line.lstrip()
        if line.startswith("f "):
            out += [lineno] * max(len(line[2:].split()) - 2, 0)
    return np.asarray(out, np.int64)


def read_mesh(path: str | Path, units: str = "mm") -> tuple[np.ndarray, np.ndarray]:
    """Read a triangle mesh, keeping the file's vertex order.

    OBJ is parsed here: trimesh's OBJ loader splits vertices at texture seams and
    drops unreferenced ones, which would renumber vertices silently. Polygons are
    fan-triangulated in file order. STL stores no shared vertices: identical
    positions are merged and numbered by first appearance. Other formats go through
    trimesh with ``process=False``.

    Parameters
    ----------
    path : str or Path
        OBJ, PLY, STL, OFF or GLB/glTF file.
    units : {'mm', 'cm', 'm', 'in'}
        Unit of the file's coordinates; the result is in millimetres.

    Returns
    -------
    V : (#V, 3) float64
        Vertex positions in mm.
    F : (#F, 3) int64
        Triangles, as in the file.

    Raises
    ------
    WorkbenchError
        The file is missing, unreadable, of an unknown type or holds no triangles.
    """
    path = Path(path)
    if units not in UNITS_MM:
        raise WorkbenchError(f"unknown units {units!r}; use one of {', '.join(UNITS_MM)}")
    if path.is_dir():
        raise WorkbenchError(f"{path}: is a directory, not a mesh file")
    if not path.is_file():
        raise WorkbenchError(f"{path}: no such file")
    suffix = path.suffix.lower()
    if suffix not in MESH_SUFFIXES:
        raise WorkbenchError(f"{path}: unknown mesh type {suffix!r}; use {', '.join(MESH_SUFFIXES)}")
    try:
        if suffix == ".obj":
            V, F = _read_obj(path)
        else:
            V, F = _read_trimesh(path, suffix)
    except WorkbenchError:
        raise
    except Exception as exc:  # every parser failure is the file's fault here (but the machine's memory)
        if exhausted(exc):
            raise
        raise WorkbenchError(f"{path}: cannot read mesh: {exc}") from None
    if len(F) == 0:
        raise WorkbenchError(f"{path}: the file holds no triangles")
    if F.min() < 0 or F.max() >= len(V):
        bad = int(np.flatnonzero((F < 0).any(1) | (F >= len(V)).any(1))[0])
        raise WorkbenchError(f"{path}: {MeshName(path).faces([bad])} refers to a vertex that does not exist")
    return V * UNITS_MM[units], F


def _read_obj(path: Path) -> tuple[np.ndarray, np.ndarray]:
    data = path.read_bytes()
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError:
        raise WorkbenchError(f"{path}: not a text OBJ file") from None
    # OBJ separates fields by any white space; tabs (seen in exported files) as spaces,
    # and leading blanks dropped, so that no vertex or face line is skipped unseen
    lines = text.splitlines()
    if "\t" in text or "\n " in text or text.startswith(" "):
        lines = [line.lstrip() for line in text.replace("\t", " ").splitlines()]
    vlines = [line[2:] for line in lines if line.startswith("v ")]
    flines = [line[2:] for line in lines if line.startswith("f ")]
    # Fast path for the common file (x y z vertices, triangles without slashes):
    # numpy parses the joined text in one call; anything else, or any parse
    # failure, takes the line-by-line path, which also says where a file is wrong.
    ftext = " ".join(flines)
    try:
        V = np.fromstring(" ".join(vlines), sep=" ") if vlines else np.zeros(0)
        F = np.fromstring(ftext, dtype=np.int64, sep=" ") if flines and "/" not in ftext else None
    except ValueError:  # numpy refuses text it cannot parse to its end
        V, F = np.zeros(0), None
    if V.size == 3 * len(vlines) and F is not None and F.size == 3 * len(flines):
        F = F.reshape(-1, 3)
        # OBJ indices are 1-based; negative ones count back from the last vertex
        # (exact only when all vertices precede all faces, as in every file the
        # fast path takes: otherwise the slow path resolves them line by line)
        if (F > 0).all():
            return V.reshape(-1, 3), F - 1
    return _read_obj_lines(path, lines)


def _read_obj_lines(path: Path, lines: list[str]) -> tuple[np.ndarray, np.ndarray]:
    verts: list[list[str]] = []
    tris: list[tuple[int, int, int]] = []
    for lineno, line in enumerate(lines, 1):
        if line.startswith("v "):
            tokens = line[2:].split()
            if len(tokens) < 3:
                raise WorkbenchError(f"{path}:{lineno}: a vertex needs x, y and z")
            verts.append(tokens[:3])
        elif line.startswith("f "):
            try:
                idx = [int(tok.split("/", 1)[0]) for tok in line[2:].split()]
            except ValueError:
                raise WorkbenchError(f"{path}:{lineno}: malformed face line {line.strip()!r}") from None
            if len(idx) < 3:
                raise WorkbenchError(f"{path}:{lineno}: a face needs at least 3 vertices")
            n = len(verts)
            # OBJ indices are 1-based; negative ones count back from the last vertex
            idx = [i - 1 if i > 0 else n + i for i in idx]
            tris.extend((idx[0], idx[j], idx[j + 1]) for j in range(1, len(idx) - 1))
    try:
        V = np.array(verts, dtype=np.float64)
    except ValueError:
        raise WorkbenchError(f"{path}: malformed vertex line") from None
    return V.reshape(-1, 3), np.array(tris, dtype=np.int64).reshape(-1, 3)


def _read_trimesh(path: Path, suffix: str) -> tuple[np.ndarray, np.ndarray]:
    import trimesh

    loaded = trimesh.load(path, process=False, force=None)
    if isinstance(loaded, trimesh.Scene):
        meshes = [g for g in loaded.dump() if isinstance(g, trimesh.Trimesh)]
        if not meshes or all(len(m.faces) == 0 for m in meshes):
            raise WorkbenchError(f"{path}: the file holds no triangles (an empty mesh)")
        if len(meshes) != 1:
            raise WorkbenchError(f"{path}: the scene holds {len(meshes)} meshes; give one mesh")
        loaded = meshes[0]
    if not isinstance(loaded, trimesh.Trimesh):
        raise WorkbenchError(f"{path}: holds no triangle mesh")
    V = np.asarray(loaded.vertices, dtype=np.float64)
    F = np.asarray(loaded.faces, dtype=np.int64)
    if suffix == ".stl":
        # STL is a triangle soup: merge exact duplicates, numbered by first appearance
        _, first, inverse = np.unique(V, axis=0, return_index=True, return_inverse=True)
        rank = np.empty(len(first), dtype=np.int64)
        rank[np.argsort(first)] = np.arange(len(first))
        V = V[np.sort(first)]
        F = rank[inverse.ravel()][F]
    return V, F


def format_obj(V: np.ndarray, F: np.ndarray, header: str = "") -> bytes:
    """OBJ text of a triangle mesh, byte-for-byte reproducible.

    Parameters
    ----------
    V : (#V, 3) float
        Vertex positions.
    F : (#F, 3) int
        Triangles (0-based; written 1-based).
    header : str
        Comment lines to put first (without the leading '#').

    Returns
    -------
    data : bytes
        The file's content.
    """
    lines = [f"# {h}" for h in header.splitlines()]
    # %.17g would round-trip exactly but doubles the size; 1e-9 mm is below any print
    vtxt = "\n".join(f"v {x:.12g} {y:.12g} {z:.12g}" for x, y, z in V.tolist())
    ftxt = "\n".join(map("f {} {} {}".format, *(F + 1).T.tolist()))
    return ("\n".join(lines + [vtxt, ftxt]) + "\n").encode()
