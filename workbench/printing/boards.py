"""ChArUco boards and chessboards: geometry, definition files and vector drawing at true scale.

Board frame (OpenCV's): origin at the board's top-left corner, x right, y down, mm.
ChArUco corner k sits at ((i + 1) · square, (j + 1) · square) with i = k mod (nx - 1);
the top-left square is black and the markers fill the white squares. In the legacy
layout (OpenCV before 4.6, and many printed boards) a board with an even number of rows
starts with a white square instead: the markers sit in the other squares, and a detector
given the wrong layout finds markers but no corners. A chessboard's inner corners are
numbered the same way; its top-left square is black.

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


# the smallest board square: a ChArUco marker (0.75 of the square, 7 cells across with its border)
# then has cells of 0.21 mm, 5 dots of a 600 dpi printer, and a camera that resolves the board
# whole sees each cell in under a pixel; below it the board cannot be printed or found
MIN_SQUARE_MM = 2.0


def check_square_mm(square_mm: float) -> None:
    """Refuse a board square smaller than :data:`MIN_SQUARE_MM` (BoardError on ``square_mm``)."""
    if square_mm < MIN_SQUARE_MM:
        raise BoardError(
            "square_mm",
            f"{square_mm:g} mm is below {MIN_SQUARE_MM:g} mm: a board that small can be neither printed "
            "nor found in a photo",
        )


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
    legacy : bool
        The pre-4.6 OpenCV layout (``CharucoBoard.setLegacyPattern``): differs from
        today's for an even number of rows.
    """

    squares: tuple[int, int] = (7, 5)
    square_mm: float = 30.0
    marker_mm: float = 22.0
    dictionary: str = "DICT_5X5_250"
    first_id: int = 0
    legacy: bool = False

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
        check_square_mm(self.square_mm)
        n_markers = (nx * ny) // 2
        size = dictionary_size(self.dictionary)
        if n_markers > size:  # too many squares whatever the first id: the squares are at fault
            raise BoardError(
                "squares", f"{nx} x {ny} squares need {n_markers} markers; {self.dictionary} has {size} ids"
            )
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
            bool(d.get("legacy", False)),
        )

    @property
    def size_mm(self) -> tuple[float, float]:
        return self.squares[0] * self.square_mm, self.squares[1] * self.square_mm

    def opencv(self):
        """The ``cv2.aruco.CharucoBoard`` (mm units)."""
        d = cv2.aruco.getPredefinedDictionary(getattr(cv2.aruco, self.dictionary))
        nx, ny = self.squares
        ids = np.arange(self.first_id, self.first_id + (nx * ny) // 2, dtype=np.int32)
        board = cv2.aruco.CharucoBoard((nx, ny), self.square_mm, self.marker_mm, d, ids)
        board.setLegacyPattern(self.legacy)
        return board


@dataclass(frozen=True)
class ChessboardSpec:
    """A plain chessboard (no markers): OpenCV's ``findChessboardCornersSB`` reads it.

    Attributes
    ----------
    squares : (nx, ny)
        Squares across and down; the inner corners are (nx - 1) x (ny - 1).
    square_mm : float
        Square side.
    """

    squares: tuple[int, int] = (10, 7)
    square_mm: float = 25.0

    def __post_init__(self):
        nx, ny = self.squares
        if nx < 3 or ny < 3:
            raise WorkbenchError(f"a chessboard needs at least 3 x 3 squares, got {nx} x {ny}")
        if not self.square_mm > 0:
            raise WorkbenchError(f"square_mm {self.square_mm} must be positive")
        check_square_mm(self.square_mm)

    @classmethod
    def from_definition(cls, d: dict) -> ChessboardSpec:
        return cls(tuple(int(n) for n in d["squares"]), float(d["square_mm"]))

    @property
    def size_mm(self) -> tuple[float, float]:
        return self.squares[0] * self.square_mm, self.squares[1] * self.square_mm

    @property
    def inner(self) -> tuple[int, int]:
        """Inner corners across and down: OpenCV's pattern size."""
        return self.squares[0] - 1, self.squares[1] - 1

    def corners_mm(self) -> np.ndarray:
        """(n, 2) float: inner corner k at ((i + 1) · square, (j + 1) · square), i = k mod (nx - 1)."""
        cx, cy = self.inner
        j, i = np.divmod(np.arange(cx * cy), cx)
        return np.stack([(i + 1) * self.square_mm, (j + 1) * self.square_mm], axis=1).astype(np.float64)


def is_chessboard(definition: dict) -> bool:
    """Whether a board definition is a plain chessboard (``"board": "chessboard"``)."""
    return definition.get("board") == "chessboard"


def board_points_mm(definition: dict) -> np.ndarray:
    """(n, 2) float: the corners a detector finds on the board (ChArUco or inner chessboard corners), mm."""
    key = "corners" if is_chessboard(definition) else "charuco_corners"
    return np.asarray(definition[key]["board_mm"], dtype=np.float64)


def chessboard_definition(spec: ChessboardSpec, page_origin_mm=None, extra: dict | None = None) -> dict:
    """A chessboard's definition file content (JSON-ready): squares, square size, every inner corner."""
    out = {
        "kind": "chessboard",
        "board": "chessboard",
        "squares": list(spec.squares),
        "square_mm": spec.square_mm,
        "frame": "board: origin at the top-left corner, x right, y down, mm",
        "corners": {"ids": list(range(len(spec.corners_mm()))), "board_mm": spec.corners_mm().tolist()},
    }
    if page_origin_mm is not None:
        out["page_origin_mm"] = list(map(float, page_origin_mm))
    if extra:
        out.update(extra)
    return out


def draw_chessboard(canvas, spec: ChessboardSpec, left_mm: float, top_mm: float) -> None:
    """Draw a chessboard (top-left square black) as vector squares on a canvas in mm, y up."""
    nx, ny = spec.squares
    s = spec.square_mm
    canvas.setFillColorRGB(0, 0, 0)
    for j in range(ny):
        for i in range(nx):
            if (i + j) % 2 == 0:
                canvas.rect(left_mm + i * s, top_mm - (j + 1) * s, s, s, stroke=0, fill=1)


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
        "legacy": spec.legacy,
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

    A definition with ``"board": "chessboard"`` is a plain chessboard
    (:data:`workbench.schemas.CHESSBOARD`); every other is a ChArUco board.

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
    d = read_json(path, what)
    if fields is None and is_chessboard(d):
        d = read_json(path, what, schemas.CHESSBOARD)
        try:
            spec = ChessboardSpec.from_definition(d)
        except WorkbenchError as exc:
            raise WorkbenchError(f"{path}: {exc}") from None
        got, want = len(d["corners"]["board_mm"]), spec.inner[0] * spec.inner[1]
        if got != want:
            raise WorkbenchError(
                f"{path}: corners.board_mm: {got} entries, "
                f"a {spec.squares[0]} x {spec.squares[1]} chessboard has {want}"
            )
        return d
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


# ------------------------------------------------------------------ colour chart slot

CHART_KIND = "ColorChecker Classic 24"
CHART_REFERENCE = "ColorChecker24 - After November 2014"  # colour-science's name of X-Rite's reference data
CHART_COLUMNS, CHART_ROWS = 6, 4
CHART_GAP_MM = 12.0  # from the board's bottom edge (the plate's white margin lies between)
CHART_PITCH_MM = 16.0
CHART_PATCH_SHARE = 0.8  # patch side / pitch: the chart's black frame shows between patches
CHART_FRAME_MM = 4.0  # black frame around the patches


def colour_chart_reference() -> tuple[list[str], np.ndarray]:
    """The ColorChecker Classic's 24 patches, in reading order, and their CIELAB (D50, 2°).

    Reference values: X-Rite's data for charts made after November 2014, as colour-science
    ships them (``colour.CCS_COLOURCHECKERS``, CIE xyY under D50), converted to CIELAB
    with the D50 white of that data.

    Returns
    -------
    names : list of str
        ``dark skin`` ... ``black 2 (1.5 D)``, row by row from the top-left.
    lab_d50 : (24, 3) float
    """
    import colour

    cc = colour.CCS_COLOURCHECKERS[CHART_REFERENCE]
    xyY = np.array(list(cc.data.values()), dtype=np.float64)
    return list(cc.data.keys()), colour.XYZ_to_Lab(colour.xyY_to_XYZ(xyY), cc.illuminant)


def chart_patch_corners(spec: CharucoSpec, pitch_mm: float = CHART_PITCH_MM) -> np.ndarray:
    """Corners of the chart's patches in the board frame (x right, y down, mm).

    The chart lies centred under the board (beyond its bottom edge, y > board height),
    :data:`CHART_GAP_MM` below it: outside the part's footprint and clear of every marker.

    Returns
    -------
    (24, 4, 2) float
        Per patch in reading order, its corners clockwise from the top-left (as markers).
    """
    bw, bh = spec.size_mm
    x0 = (bw - CHART_COLUMNS * pitch_mm) / 2
    y0 = bh + CHART_GAP_MM + CHART_FRAME_MM
    side = CHART_PATCH_SHARE * pitch_mm
    inset = (pitch_mm - side) / 2
    r, c = np.divmod(np.arange(CHART_COLUMNS * CHART_ROWS), CHART_COLUMNS)
    tl = np.stack([x0 + c * pitch_mm + inset, y0 + r * pitch_mm + inset], axis=1)
    return tl[:, None, :] + np.array([[0, 0], [side, 0], [side, side], [0, side]], dtype=np.float64)[None]


def chart_extent_mm(pitch_mm: float) -> tuple[float, float]:
    """Width and height of the chart with its frame, mm."""
    return CHART_COLUMNS * pitch_mm + 2 * CHART_FRAME_MM, CHART_ROWS * pitch_mm + 2 * CHART_FRAME_MM


def colour_chart_definition(spec: CharucoSpec, origin_mm, pitch_mm: float = CHART_PITCH_MM) -> dict:
    """The fixture definition's ``colour_chart`` entry (JSON-ready).

    ``{"kind", "reference", "illuminant", "pitch_mm", "patch_mm", "frame_board_mm",
    "patches": [{"name", "lab_d50": [L, a, b], "corners_board_mm", "corners_mesh_mm":
    [[x, y, z] x 4]}, ...]}``: each patch's reference colour and where it lies, in the
    board frame and the job's mesh frame.
    """
    names, lab = colour_chart_reference()
    corners = chart_patch_corners(spec, pitch_mm)
    mesh = board_to_mesh(corners.reshape(-1, 2), origin_mm).reshape(-1, 4, 3)
    lo = corners.reshape(-1, 2).min(axis=0) - (pitch_mm * (1 - CHART_PATCH_SHARE) / 2 + CHART_FRAME_MM)
    hi = corners.reshape(-1, 2).max(axis=0) + (pitch_mm * (1 - CHART_PATCH_SHARE) / 2 + CHART_FRAME_MM)
    return {
        "kind": CHART_KIND,
        "reference": f"colour-science {CHART_REFERENCE} (X-Rite), CIELAB D50 2 degree",
        "illuminant": "D50",
        "pitch_mm": float(pitch_mm),
        "patch_mm": float(CHART_PATCH_SHARE * pitch_mm),
        "frame_board_mm": [*map(float, lo), *map(float, hi)],
        "patches": [
            {
                "name": n,
                "lab_d50": [round(float(v), 4) for v in lab[k]],
                "corners_board_mm": corners[k].tolist(),
                "corners_mesh_mm": mesh[k].tolist(),
            }
            for k, n in enumerate(names)
        ],
    }


def colour_chart_from_job(fixture: dict | None, spec: CharucoSpec, origin_mm) -> dict | None:
    """The job's colour chart slot (``[fixture] colour_chart``, ``colour_chart_pitch_mm``), or None for ``"none"``.

    The keys are checked by :func:`fixture_from_job` (call it first).
    """
    fx = dict(fixture or {})
    if fx.get("colour_chart", CHART_KIND) == "none":
        return None
    return colour_chart_definition(spec, origin_mm, float(fx.get("colour_chart_pitch_mm") or CHART_PITCH_MM))


def chart_srgb(lab_d50: np.ndarray) -> np.ndarray:
    """sRGB (uint8, (n, 3)) of D50 CIELAB colours: Bradford-adapted to D65, clipped to the gamut."""
    import colour

    d50 = colour.CCS_ILLUMINANTS["CIE 1931 2 Degree Standard Observer"]["D50"]
    xyz = colour.Lab_to_XYZ(np.asarray(lab_d50, dtype=np.float64), d50)
    rgb = colour.XYZ_to_sRGB(xyz, d50, chromatic_adaptation_transform="Bradford")
    return np.clip(np.round(rgb * 255), 0, 255).astype(np.uint8)


def draw_chart_slot(canvas, chart: dict, left_mm: float, top_mm: float) -> None:
    """Draw the chart's slot on a fixture sheet: its frame and each patch outlined and named.

    A slot, not a chart: a printed ColorChecker is not the reference; the lab places a real
    one here (dark skin at the top-left). Canvas unit: 1 mm, y up; ``left_mm``, ``top_mm``:
    the board's top-left corner on the sheet.
    """
    from workbench.printing.pdf import embedded_font

    font = embedded_font()
    x0, y0, x1, y1 = chart["frame_board_mm"]
    canvas.saveState()
    canvas.setLineWidth(0.3)
    canvas.rect(left_mm + x0, top_mm - y1, x1 - x0, y1 - y0, stroke=1, fill=0)
    canvas.setLineWidth(0.15)
    size = min(1.6, chart["patch_mm"] / 9)
    for p in chart["patches"]:
        c = np.asarray(p["corners_board_mm"])
        canvas.rect(left_mm + c[0, 0], top_mm - c[2, 1], c[1, 0] - c[0, 0], c[2, 1] - c[0, 1], stroke=1, fill=0)
        canvas.setFont(font, size)
        words = p["name"].split(" (")[0]
        canvas.drawCentredString(left_mm + (c[0, 0] + c[1, 0]) / 2, top_mm - (c[0, 1] + c[2, 1]) / 2, words)
    canvas.setFont(font, 2.4)
    canvas.drawString(
        left_mm + x0,
        top_mm - y0 + 1.5,
        f"{chart['kind']} here, dark skin top-left, patch pitch {chart['pitch_mm']:g} mm (a real chart: a print of "
        "one is no reference)",
    )
    canvas.restoreState()
