"""Reading and writing triangle meshes without reordering their vertices."""

from __future__ import annotations

import re
import tempfile
from collections.abc import Callable
from pathlib import Path

import numpy as np

from workbench.errors import WorkbenchError, exhausted

UNITS_MM = {"mm": 1.0, "cm": 10.0, "m": 1000.0, "in": 25.4}
MESH_SUFFIXES = (".obj", ".ply", ".stl", ".off", ".glb", ".gltf", ".step", ".stp")
# formats that store no shared vertices (a triangle soup, or one tessellated CAD face after
# another): their vertices are always merged by position
SOUP_SUFFIXES = (".stl", ".step", ".stp")
STEP_SUFFIXES = (".step", ".stp")
# the STEP tessellation's largest distance from the CAD surface, mm: a tenth of a 300-dpi print
# pixel (0.085 mm), so that the facets never show in a print
STEP_DEFLECTION_MM = 0.01
# STEP's SI prefixes of the metre, as mm
_SI_PREFIX_MM = {"": 1000.0, "KILO": 1e6, "DECI": 100.0, "CENTI": 10.0, "MILLI": 1.0, "MICRO": 1e-3, "NANO": 1e-6}


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


def read_mesh(
    path: str | Path, units: str = "mm", log: Callable[[str], None] | None = None, solid: bool = True
) -> tuple[np.ndarray, np.ndarray]:
    """Read a triangle mesh, keeping the file's vertex order.

    OBJ is parsed here: trimesh's OBJ loader splits vertices at texture seams and
    drops unreferenced ones, which would renumber vertices silently. Polygons are
    fan-triangulated in file order. STL stores no shared vertices: identical
    positions are merged and numbered by first appearance. Other formats go through
    trimesh with ``process=False``.

    STEP is tessellated by OpenCASCADE through ``cascadio`` (the package trimesh itself uses for
    STEP: wheels for every platform, no system library, kept up with OpenCASCADE's releases),
    at most :data:`STEP_DEFLECTION_MM` from the CAD surface; OpenCASCADE converts the file's own
    length unit to mm, and a file that states none is refused. Its vertices are merged by
    position (each CAD face is tessellated on its own) and triangles that collapse are dropped.

    A closed mesh (no boundary edge) is read as a solid (with ``solid``): its faces are turned
    so that normals point out of it, and it is refused if it is several bodies, one-sided or
    intersects itself (:func:`~workbench.mesh.solid.check_solid`). An OBJ, PLY, OFF or glTF
    made of several pieces that close into one solid once their vertices are merged by
    position (a CAD export splitting vertices at sharp edges) is merged; vertices a single
    open piece repeats are a cut the user made, and stay. An open surface is returned as read.

    Parameters
    ----------
    path : str or Path
        OBJ, PLY, STL, OFF, GLB/glTF or STEP file.
    units : {'mm', 'cm', 'm', 'in'}
        Unit of the file's coordinates; the result is in millimetres. Not used for STEP,
        which states its unit.
    log : callable(str), optional
        Receives a line for each repair of a solid (faces turned outward).
    solid : bool
        Check and orient closed meshes as solids; False for the workbench's own outputs, read
        again vertex for vertex.

    Returns
    -------
    V : (#V, 3) float64
        Vertex positions in mm.
    F : (#F, 3) int64
        Triangles, as in the file (those of a solid counter-clockwise seen from outside).

    Raises
    ------
    WorkbenchError
        The file is missing, empty, unreadable, of an unknown type or holds no triangles; a
        STEP file states no length unit; a closed mesh is not one solid.
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
    if path.stat().st_size == 0:
        raise WorkbenchError(f"{path}: the file is empty")
    scale = 1.0 if suffix in STEP_SUFFIXES else UNITS_MM[units]
    try:
        if suffix == ".obj":
            V, F = _read_obj(path)
        elif suffix in STEP_SUFFIXES:
            V, F = _read_step(path)
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
    V = V * scale
    if solid:
        V, F = _as_solid(V, F, path, suffix, log)
    return V, F


def _as_solid(V, F, path: Path, suffix: str, log) -> tuple[np.ndarray, np.ndarray]:
    """A closed mesh checked and oriented as a solid; an open one as it is (see :func:`read_mesh`)."""
    from workbench.mesh.solid import check_solid, is_closed, weld
    from workbench.mesh.topology import face_components

    if not is_closed(F):
        if suffix in SOUP_SUFFIXES:
            return V, F
        W, G = weld(V, F)
        # only pieces that close into a solid are merged: a disc's repeated vertices are a seam
        # the user cut on purpose, and its vertex numbers are the user's (corners, faces files)
        if len(W) == len(V) or not is_closed(G) or face_components(F).max() == 0:
            return V, F
        V, F = W, G
    return V, check_solid(V, F, MeshName(path), log)


def step_length_unit(text: str, path: Path | str = "STEP file") -> float:
    """The length unit of a STEP file's geometry, in mm.

    The unit is the ``LENGTH_UNIT`` of the ``GLOBAL_UNIT_ASSIGNED_CONTEXT`` of the file's
    representations: an SI unit (``SI_UNIT(.MILLI.,.METRE.)``) or a conversion-based one (an
    inch: ``CONVERSION_BASED_UNIT('INCH', #n)`` with ``#n`` 25.4 mm).

    Parameters
    ----------
    text : str
        The STEP file's content (ISO 10303-21).
    path : Path or str
        How to name the file in messages.

    Returns
    -------
    mm : float
        Millimetres per unit of the file's coordinates.

    Raises
    ------
    WorkbenchError
        The file states no length unit, several different ones, or one that is not a length.
    """
    text = re.sub(r"/\*.*?\*/", "", text, flags=re.S)  # comments

    def entity(ref: str) -> str:
        m = re.search(rf"#{ref}\s*=", text)
        if m is None:
            raise WorkbenchError(f"{path}: the STEP file refers to #{ref}, which it does not define")
        # the entity runs to the first ';' outside a string ('' is a quote inside one)
        end = re.compile(r"(?:[^;']|'(?:[^']|'')*')*;").match(text, m.end())
        return text[m.end() : end.end() - 1] if end else text[m.end() :]

    def to_mm(body: str, depth: int = 0) -> float:
        si = re.search(r"SI_UNIT\s*\(\s*(?:\$|\.(\w+)\.)\s*,\s*\.(\w+)\.\s*\)", body)
        if si and si.group(2).upper() == "METRE" and (si.group(1) or "").upper() in _SI_PREFIX_MM:
            return _SI_PREFIX_MM[(si.group(1) or "").upper()]
        conv = re.search(r"CONVERSION_BASED_UNIT\s*\(\s*'(?:[^']|'')*'\s*,\s*#(\d+)", body)
        if conv and depth < 8:
            measure = entity(conv.group(1))
            m = re.search(r"\(\s*([-+0-9.Ee]+)\s*\)\s*,\s*#(\d+)", measure)
            if m:
                return float(m.group(1)) * to_mm(entity(m.group(2)), depth + 1)
        raise WorkbenchError(f"{path}: the STEP file's length unit is not one known here ({' '.join(body.split())})")

    found = set()
    for context in re.finditer(r"GLOBAL_UNIT_ASSIGNED_CONTEXT\s*\(\s*\(([^)]*)\)", text):
        bodies = [entity(ref) for ref in re.findall(r"#(\d+)", context.group(1))]
        lengths = [b for b in bodies if "LENGTH_UNIT" in b.upper()]
        if not lengths:
            found.add(None)
        found.update(round(to_mm(b), 12) for b in lengths)
    if not found or None in found:
        raise WorkbenchError(
            f"{path}: the STEP file states no length unit (its geometry could be in mm or inches); "
            "export it again with units"
        )
    if len(found) > 1:
        shown = ", ".join(f"{u:g} mm" for u in sorted(found))
        raise WorkbenchError(f"{path}: the STEP file's shapes are in different length units ({shown})")
    return found.pop()


def _tessellate_step(path: Path, obj: Path) -> None:
    """OpenCASCADE's tessellation of a STEP file, written to ``obj`` (OBJ, mm).

    In a process of its own: OpenCASCADE crashes on some broken files (a reference to an entity
    the file lacks) and prints its messages on standard output; neither may reach the command.
    OpenCASCADE's OBJ (not trimesh's GLB route): coordinates in mm as doubles, where glTF holds
    float32 metres (a micrometre off on a 100 mm part). Serial meshing: the same tessellation on
    every machine.
    """
    import signal
    import subprocess
    import sys

    code = (
        "import sys, cascadio; sys.exit(cascadio.step_to_obj(sys.argv[1], sys.argv[2], tol_linear=float(sys.argv[3]), "
        "use_parallel=False, use_colors=False))"
    )
    cmd = [sys.executable, "-c", code, str(path), str(obj), repr(STEP_DEFLECTION_MM)]
    run = subprocess.run(cmd, capture_output=True, stdin=subprocess.DEVNULL)
    if run.returncode < 0:
        name = signal.Signals(-run.returncode).name if -run.returncode in signal.valid_signals() else -run.returncode
        raise WorkbenchError(f"{path}: OpenCASCADE failed on the STEP file ({name}); is it complete?")
    if run.returncode != 0 or not obj.is_file() or obj.stat().st_size == 0:
        # its last message, without the terminal colours
        said = re.sub(r"\x1b\[[0-9;]*m|\*+", "", (run.stderr or run.stdout).decode("utf-8", "replace")).split("\n")
        said = [line.strip() for line in said if line.strip()]
        why = f": {said[-1]}" if said else ""
        raise WorkbenchError(f"{path}: OpenCASCADE could not tessellate the STEP file (no solid in it?){why}")


def _read_step(path: Path) -> tuple[np.ndarray, np.ndarray]:
    import importlib.util

    from workbench.mesh.solid import weld

    if importlib.util.find_spec("cascadio") is None:
        raise WorkbenchError(f"{path}: reading STEP needs the cascadio package (pip install cascadio)")
    text = path.read_bytes().decode("latin-1")
    if not text.lstrip().startswith("ISO-10303-21"):
        raise WorkbenchError(f"{path}: not a STEP file (it does not start with ISO-10303-21)")
    if "END-ISO-10303-21" not in text[-4096:]:
        raise WorkbenchError(f"{path}: the STEP file is cut short (it does not end with END-ISO-10303-21;)")
    step_length_unit(text, path)
    with tempfile.TemporaryDirectory(prefix="workbench-step-") as tmp:
        obj = Path(tmp) / "tessellated.obj"
        _tessellate_step(path, obj)
        data = obj.read_text(encoding="utf-8", errors="replace")
    lines = data.splitlines()
    vtext = " ".join(line[2:] for line in lines if line.startswith("v "))
    flines = [line[2:] for line in lines if line.startswith("f ")]
    # faces as "v/vt/vn": the vertex index is what comes before the first slash
    ftext = re.sub(r"/\S*", "", " ".join(flines))
    V = np.array(vtext.split(), dtype=np.float64).reshape(-1, 3)
    F = np.array(ftext.split(), dtype=np.int64)
    if F.size != 3 * len(flines):
        raise WorkbenchError(f"{path}: the STEP tessellation has faces that are not triangles")
    # OBJ's indices are 1-based; its 6 decimals round at 1e-6 mm: 1e-5 mm merges one position
    # written twice, nothing else
    V, F = weld(V, F.reshape(-1, 3) - 1, tol=1e-5)
    # a tessellation's triangles that collapse once merged (at the pole of a spherical corner)
    return V, F[(F[:, 0] != F[:, 1]) & (F[:, 1] != F[:, 2]) & (F[:, 2] != F[:, 0])]


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


def _ply_strips(path: Path) -> str:
    """Why a PLY file read as no mesh, when its header says: triangle strips in place of faces."""
    with open(path, "rb") as f:
        head = f.read(4096)
    header = head.split(b"end_header", 1)[0]
    if b"element tristrips" in header and b"element face" not in header:
        return " (it stores triangle strips, element tristrips, which are not read: export it with faces)"
    return ""


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
        raise WorkbenchError(f"{path}: holds no triangle mesh{_ply_strips(path) if suffix == '.ply' else ''}")
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
