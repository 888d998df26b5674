"""ChArUco boards: geometry, definition files and vector drawing at true scale.

Board frame (OpenCV's): origin at the board's top-left corner, x right, y down, mm.
ChArUco corner k sits at ((i + 1) · square, (j + 1) · square) with i = k mod (nx - 1);
the top-left square is black and the markers fill the white squares.

A fixture board lies on the table under the part, its top edge towards the mesh's +y:
mesh = origin + (x, -y, 0), with ``origin`` the board's top-left corner in the job's
mesh frame (mm).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

from workbench.errors import WorkbenchError

DICTIONARIES = sorted(k for k in dir(cv2.aruco) if k.startswith("DICT_"))


def dictionary_size(name: str) -> int:
    """How many marker ids an OpenCV ArUco dictionary holds (DICT_ARUCO_ORIGINAL: 1024, no number in its name)."""
    return int(cv2.aruco.getPredefinedDictionary(getattr(cv2.aruco, name)).bytesList.shape[0])


class BoardError(WorkbenchError):
    """An impossible board; ``key``: the field at fault (``squares``, ``marker_mm``, ``dictionary``, ``first_id``)."""

    def __init__(self, key: str, message: str):
        super().__init__(message)
        self.key = key


@dataclass(frozen=True)
class CharucoSpec:
    """A ChArUco board.

    Attributes
    ----------
    squares : (nx, ny)
        Squares across and down.
    square_mm, marker_mm : float
        Square side and marker side.
    dictionary : str
        OpenCV ArUco dictionary name, e.g. ``DICT_5X5_250``.
    first_id : int
        Id of the first marker (boards of one lab use disjoint id ranges).
    """

    squares: tuple[int, int] = (7, 5)
    square_mm: float = 30.0
    marker_mm: float = 22.0
    dictionary: str = "DICT_5X5_250"
    first_id: int = 0

    def __post_init__(self):
        nx, ny = self.squares
        if nx < 3 or ny < 3:
            raise BoardError("squares", f"a ChArUco board needs at least 3 x 3 squares, got {nx} x {ny}")
        if not 0 < self.marker_mm < self.square_mm:
            raise BoardError(
                "marker_mm", f"marker_mm {self.marker_mm:g} must be between 0 and square_mm {self.square_mm:g}"
            )
        if self.dictionary not in DICTIONARIES:
            raise BoardError(
                "dictionary", f"unknown ArUco dictionary {self.dictionary!r}; e.g. DICT_5X5_250, DICT_6X6_1000"
            )
        n_markers = (nx * ny) // 2
        size = dictionary_size(self.dictionary)
        if self.first_id < 0 or self.first_id + n_markers > size:
            raise BoardError(
                "first_id", f"{n_markers} markers from id {self.first_id} do not fit in {self.dictionary} ({size} ids)"
            )

    @classmethod
    def from_definition(cls, d: dict) -> CharucoSpec:
        """The board of a definition file written by ``workbench board`` (or ``fixture.json``)."""
        return cls(
            tuple(int(n) for n in d["squares"]),
            float(d["square_mm"]),
            float(d["marker_mm"]),
            d["dictionary"],
            int(d.get("first_id") or 0),
        )

    @property
    def size_mm(self) -> tuple[float, float]:
        return self.squares[0] * self.square_mm, self.squares[1] * self.square_mm

    def opencv(self):
        """The ``cv2.aruco.CharucoBoard`` (mm units)."""
        d = cv2.aruco.getPredefinedDictionary(getattr(cv2.aruco, self.dictionary))
        nx, ny = self.squares
        ids = np.arange(self.first_id, self.first_id + (nx * ny) // 2, dtype=np.int32)
        return cv2.aruco.CharucoBoard((nx, ny), self.square_mm, self.marker_mm, d, ids)


def board_geometry(spec: CharucoSpec) -> dict:
    """Every corner of a board in its own frame.

    Returns
    -------
    dict
        ``charuco_ids`` (n,), ``charuco_mm`` (n, 2); ``marker_ids`` (m,),
        ``marker_corners_mm`` (m, 4, 2) in OpenCV's order (clockwise from top-left).
    """
    b = spec.opencv()
    cc = np.asarray(b.getChessboardCorners())[:, :2]
    op = np.asarray(b.getObjPoints())[:, :, :2]
    return {
        "charuco_ids": np.arange(len(cc)),
        "charuco_mm": cc,
        "marker_ids": np.asarray(b.getIds()).ravel(),
        "marker_corners_mm": op,
    }


def board_to_mesh(points_mm: np.ndarray, origin_mm) -> np.ndarray:
    """Board-frame points (n, 2) of a fixture to the job's mesh frame (n, 3), mm."""
    o = np.asarray(origin_mm, dtype=np.float64)
    return np.stack([o[0] + points_mm[:, 0], o[1] - points_mm[:, 1], np.full(len(points_mm), o[2])], axis=1)


def definition(spec: CharucoSpec, kind: str, origin_mm=None, page_origin_mm=None, extra: dict | None = None) -> dict:
    """The board definition file's content (JSON-ready).

    Parameters
    ----------
    spec : CharucoSpec
        The board.
    kind : {'charuco', 'fixture', 'printer-target'}
        What it is for.
    origin_mm : (3,) float, optional
        Fixture: the board's top-left corner in the job's mesh frame; every corner
        then also gets its mesh position.
    page_origin_mm : (2,) float, optional
        Where the board's top-left corner is on the printed sheet, mm from the
        sheet's top-left corner (x right, y down).
    extra : dict, optional
        More entries (job, footprint, ...).
    """
    g = board_geometry(spec)
    out = {
        "kind": kind,
        "board": "charuco",
        "dictionary": spec.dictionary,
        "squares": list(spec.squares),
        "square_mm": spec.square_mm,
        "marker_mm": spec.marker_mm,
        "first_id": spec.first_id,
        "frame": "board: origin at the top-left corner, x right, y down, mm",
        "charuco_corners": {"ids": g["charuco_ids"].tolist(), "board_mm": g["charuco_mm"].tolist()},
        "markers": {"ids": g["marker_ids"].tolist(), "corners_board_mm": g["marker_corners_mm"].tolist()},
    }
    if origin_mm is not None:
        out["origin_mm"] = list(map(float, origin_mm))
        out["mesh_frame"] = "job mesh frame, mm: mesh = origin + (x, -y, 0)"
        out["charuco_corners"]["mesh_mm"] = board_to_mesh(g["charuco_mm"], origin_mm).tolist()
        mc = g["marker_corners_mm"].reshape(-1, 2)
        out["markers"]["corners_mesh_mm"] = board_to_mesh(mc, origin_mm).reshape(-1, 4, 3).tolist()
    if page_origin_mm is not None:
        out["page_origin_mm"] = list(map(float, page_origin_mm))
    if extra:
        out.update(extra)
    return out


def draw_board(canvas, spec: CharucoSpec, left_mm: float, top_mm: float) -> None:
    """Draw a board as vector shapes on a canvas whose unit is the mm, y up.

    Parameters
    ----------
    canvas : reportlab canvas
        Scaled so that one unit is 1 mm, origin at the sheet's bottom-left.
    spec : CharucoSpec
        The board.
    left_mm, top_mm : float
        Position of the board's top-left corner (sheet x; sheet y from the bottom).
    """
    g = board_geometry(spec)
    d = cv2.aruco.getPredefinedDictionary(getattr(cv2.aruco, spec.dictionary))
    n = d.markerSize + 2
    nx, ny = spec.squares
    s = spec.square_mm
    canvas.setFillColorRGB(0, 0, 0)
    has_marker = np.zeros((ny, nx), dtype=bool)
    for corners in g["marker_corners_mm"]:
        has_marker[int(corners[0, 1] // s), int(corners[0, 0] // s)] = True
    for j in range(ny):
        for i in range(nx):
            if not has_marker[j, i]:
                canvas.rect(left_mm + i * s, top_mm - (j + 1) * s, s, s, stroke=0, fill=1)
    cell = spec.marker_mm / n
    for mid, corners in zip(g["marker_ids"], g["marker_corners_mm"], strict=True):
        bits = d.generateImageMarker(int(mid), n) > 0  # True = white cell
        x0, y0 = corners[0]
        for r in range(n):
            for c in range(n):
                if not bits[r, c]:
                    canvas.rect(left_mm + x0 + c * cell, top_mm - (y0 + (r + 1) * cell), cell, cell, stroke=0, fill=1)


def fixture_from_job(fixture: dict | None, V: np.ndarray, F: np.ndarray, where: str):
    """The fixture board of a job: its spec, its top-left corner in the mesh frame, the footprint.

    ``[fixture]`` keys: dictionary, squares [nx, ny], square_mm, marker_mm, first_id,
    origin_mm [x, y, z] (the board's top-left corner in the mesh frame). Without them
    the board covers the part's footprint with two squares of margin, 20 mm squares,
    in the plane of the part's lowest point.

    Parameters
    ----------
    fixture : dict or None
        The job's ``[fixture]`` table.
    V : (#V, 3) float
        Mesh vertices, mm.
    F : (#F, 3) int
        Triangles.
    where : str
        Prefix of error messages (file and table).

    Returns
    -------
    spec : CharucoSpec
    origin : (3,) float
    footprint : (#B, 2) float
        The mesh boundary projected on the plate, board frame (x right, y down), mm.
    """
    from workbench import schemas
    from workbench.jsonfile import check
    from workbench.mesh.topology import boundary_loops

    fx = dict(fixture or {})
    known = set(schemas.JOB_FIXTURE)
    unknown = sorted(set(fx) - known)
    if unknown:
        raise WorkbenchError(f"{where}: unknown key {unknown[0]!r} (known keys: {', '.join(sorted(known))})")
    # the job's [fixture] table, checked like every file the workbench reads: "FILE: fixture.KEY: ..."
    file, _, table = where.rpartition(": ")
    check(fx, schemas.JOB_FIXTURE, file or where, table or "fixture")
    square = fx["square_mm"]
    lo, hi = V.min(axis=0), V.max(axis=0)
    if fx["squares"] is not None:
        squares = (int(fx["squares"][0]), int(fx["squares"][1]))
    else:
        # two squares of margin on each side: the markers around the part stay visible
        squares = (int(np.ceil((hi[0] - lo[0]) / square)) + 4, int(np.ceil((hi[1] - lo[1]) / square)) + 4)
    if fx["origin_mm"] is not None:
        origin = np.asarray(fx["origin_mm"], dtype=np.float64)
    else:
        cx, cy = (lo[0] + hi[0]) / 2, (lo[1] + hi[1]) / 2
        origin = np.array([cx - squares[0] * square / 2, cy + squares[1] * square / 2, lo[2]])
    try:
        spec = CharucoSpec(
            squares=squares,
            square_mm=float(square),
            marker_mm=float(fx["marker_mm"] or 0.75 * square),
            dictionary=fx["dictionary"],
            first_id=fx["first_id"],
        )
    except WorkbenchError as exc:
        raise WorkbenchError(f"{where}: {exc}") from None
    loop = boundary_loops(F)[0]
    footprint = np.stack([V[loop, 0] - origin[0], origin[1] - V[loop, 1]], axis=1)
    return spec, origin, footprint


def load_board(path: str | Path, what: str = "board definition", fields: dict | None = None) -> dict:
    """A board definition (``workbench board``'s FILE.json) or a design's ``fixture.json``, checked.

    Beyond the schema (:data:`workbench.schemas.BOARD`, or ``fields``), the board must be
    one OpenCV can build, with as many ChArUco corners and markers as its squares give.

    Raises
    ------
    WorkbenchError
        Naming the file and the key at fault.
    """
    from workbench import schemas
    from workbench.jsonfile import read_json

    path = Path(path)
    d = read_json(path, what, fields or schemas.BOARD)
    try:
        spec = CharucoSpec.from_definition(d)
    except WorkbenchError as exc:
        raise WorkbenchError(f"{path}: {exc}") from None
    nx, ny = spec.squares
    counts = {
        "charuco_corners.board_mm": (len(d["charuco_corners"]["board_mm"]), (nx - 1) * (ny - 1)),
        "markers.ids": (len(d["markers"]["ids"]), (nx * ny) // 2),
    }
    if "mesh_mm" in d["charuco_corners"]:
        counts["charuco_corners.mesh_mm"] = (len(d["charuco_corners"]["mesh_mm"]), (nx - 1) * (ny - 1))
    if "corners_mesh_mm" in d["markers"]:
        counts["markers.corners_mesh_mm"] = (len(d["markers"]["corners_mesh_mm"]), (nx * ny) // 2)
    for key, (got, want) in counts.items():
        if got != want:
            raise WorkbenchError(f"{path}: {key}: {got} entries, a {nx} x {ny} board has {want}")
    return d
