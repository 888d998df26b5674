"""What every JSON file the workbench reads must hold: one schema per kind of file.

Declared with :class:`workbench.jsonfile.Field` and checked by
:func:`workbench.jsonfile.read_json`, so that a file missing a key, or holding a value of
the wrong type, shape or range, is refused in one line naming the file and the key before
any of it is used. Consistency between keys (as many corners as the board's squares give)
is checked by the readers that know it.
"""

from __future__ import annotations

from workbench.jsonfile import Field

_K = Field("array", shape=(3, 3), hint="intrinsics in pixels")
_R = Field("array", shape=(3, 3), hint="world-to-camera rotation")
_T = Field("array", shape=(3,), hint="world-to-camera translation, mm")
_SIZE = Field("array", shape=(2,), integer=True, lo=8, hi=100_000, hint="[W, H] in pixels")
_DIST = Field("array", required=False, default=[0.0] * 5, shape=(None,), hint="k1, k2, p1, p2, k3")

# a camera profile (calibrate camera, or a render's PHOTO.json): intrinsics and image size
CAMERA_PROFILE = {"K": _K, "image_size": _SIZE, "dist": _DIST}

# a camera file (render --camera, a PHOTO.json): intrinsics and pose
CAMERA_FILE = {**CAMERA_PROFILE, "R": _R, "t": _T}

# a printer profile (calibrate printer; pdf --printer-profile, board --printer-profile)
_SCALE = Field("number", lo=0.8, hi=1.25, hint="printed length / intended length")
PRINTER_PROFILE = {"scale_x": _SCALE, "scale_y": _SCALE, "name": Field("string", required=False)}

# a board definition (workbench board ... -o FILE.pdf writes FILE.json)
BOARD = {
    "dictionary": Field("string", hint="an OpenCV ArUco dictionary, e.g. DICT_5X5_250"),
    "squares": Field("array", shape=(2,), integer=True, lo=3, hi=1000, hint="[nx, ny]"),
    "square_mm": Field("number", lo=2.0, hi=10_000),
    "marker_mm": Field("number", lo=1e-3, hi=10_000),
    "first_id": Field("integer", required=False, default=0, lo=0),
    "charuco_corners": Field("object", fields={"board_mm": Field("array", shape=(None, 2), min_len=4)}),
    "markers": Field("object", fields={"ids": Field("array", shape=(None,), integer=True, lo=0, min_len=1)}),
    "legacy": Field("bool", required=False, default=False, hint="the pre-4.6 OpenCV layout (even rows differ)"),
}

# a chessboard definition (workbench board chessboard): "board": "chessboard", inner corners only
CHESSBOARD = {
    "squares": Field("array", shape=(2,), integer=True, lo=3, hi=1000, hint="[nx, ny] squares"),
    "square_mm": Field("number", lo=1e-3, hi=10_000),
    "corners": Field("object", fields={"board_mm": Field("array", shape=(None, 2), min_len=4)}),
}

# the [fixture] table of a job file (TOML): every key optional
JOB_FIXTURE = {
    # at least 2 mm: below it a board can be neither printed nor found (printing.boards.MIN_SQUARE_MM)
    "square_mm": Field("number", required=False, default=20.0, lo=2.0, hi=1000),
    "squares": Field("array", required=False, shape=(2,), integer=True, lo=3, hi=1000, hint="[nx, ny]"),
    "marker_mm": Field("number", required=False, lo=0.01, hi=1000),
    "dictionary": Field("string", required=False, default="DICT_5X5_250"),
    "first_id": Field("integer", required=False, default=0, lo=0),
    # within 1 km of the mesh's origin (job.MAX_COORDINATE_MM): farther, no photo sees board and part
    "origin_mm": Field("array", required=False, shape=(3,), lo=-1e6, hi=1e6, hint="[x, y, z] in mm"),
    # the colour chart's slot beside the board (validate's colour QA), or "none"
    "colour_chart": Field(
        "string", required=False, default="ColorChecker Classic 24", choices=("ColorChecker Classic 24", "none")
    ),
    "colour_chart_pitch_mm": Field("number", required=False, default=16.0, lo=4.0, hi=100.0),
}

# the colour chart's slot of a fixture (fixture.json: colour_chart), read by colour QA
COLOUR_CHART = {
    "kind": Field("string"),
    "patches": Field(
        "list",
        min_len=6,
        items=Field(
            "object",
            fields={
                "name": Field("string"),
                "lab_d50": Field("array", shape=(3,), hint="[L, a, b], CIELAB D50"),
                "corners_mesh_mm": Field("array", shape=(4, 3), hint="four corners in the mesh frame"),
            },
        ),
    ),
}

# fixture.json of a design folder: a board definition placed in the mesh frame
FIXTURE = {
    **BOARD,
    "origin_mm": Field("array", shape=(3,), hint="the board's top-left corner in the mesh frame"),
    "charuco_corners": Field(
        "object",
        fields={
            "board_mm": Field("array", shape=(None, 2), min_len=4),
            "mesh_mm": Field("array", shape=(None, 3), min_len=4),
        },
    ),
    "markers": Field(
        "object",
        fields={
            "ids": Field("array", shape=(None,), integer=True, lo=0, min_len=1),
            "corners_mesh_mm": Field("array", shape=(None, 4, 3), min_len=1),
        },
    ),
    "colour_chart": Field("object", required=False, fields=COLOUR_CHART),
}

# design.json of a design folder: what pdf reads back (the print and the job) ...
_POSITIVE_MM = Field("number", lo=1e-6, hi=1e6)
_PRINT = {
    "width_mm": _POSITIVE_MM,
    "height_mm": _POSITIVE_MM,
    "dpi": Field("number", lo=1, hi=10_000),
    "width_px": Field("integer", lo=1),
    "height_px": Field("integer", lo=1),
    "bleed_mm": Field("number", required=False, default=3.0, lo=0, hi=50),
    "margin_mm": Field("number", required=False, default=10.0, lo=0, hi=50),
}
_JOB = Field(
    "object",
    required=False,
    default={},
    fields={
        "name": Field("string", required=False),
        "sha256": Field("string", required=False),
        "file": Field("string", required=False),
    },
)
DESIGN_PRINT = {"print": Field("object", fields=_PRINT), "job": _JOB}

# ... and what render and validate read back (the views' cameras, the print image's extent)
DESIGN = {
    "print": Field("object", fields={**_PRINT, "image_width_mm": _POSITIVE_MM, "image_height_mm": _POSITIVE_MM}),
    "job": _JOB,
    "views": Field(
        "list",
        min_len=1,
        items=Field(
            "object",
            fields={
                "name": Field("string"),
                "camera": Field("object", fields={"K": _K, "R": _R, "t": _T, "image_size": _SIZE}),
            },
        ),
    ),
}

# a profile that calibrate check re-measures: what kind, and the board it was measured on
CALIBRATION_PROFILE = {
    "kind": Field("string", choices=("camera-profile", "printer-profile"), hint="written by workbench calibrate"),
    "board": Field("object", fields={"file": Field("string"), "sha256": Field("string", required=False)}),
}
# what calibrate check reads of a camera profile beyond the intrinsics (all optional: older profiles lack them)
_STD = Field("number", required=False, default=0.0, lo=0, hi=1e6, hint="standard deviation, px")
_INTRINSICS_STD = {k: _STD for k in ("fx", "fy", "cx", "cy")}
CAMERA_CHECK = {
    **CAMERA_PROFILE,
    "rms_px": Field("number", required=False, lo=0, hi=1e6),
    "view_rms_limit_px": Field("number", required=False, lo=0, hi=1e6),
    "k3_fixed": Field("bool", required=False, default=True),
    "intrinsics_std": Field("object", required=False, fields=_INTRINSICS_STD),
    "intrinsics_std_opencv": Field("object", required=False, fields=_INTRINSICS_STD),
    "views": Field("list", required=False, default=[], items=Field("object", fields={"used": Field("bool")})),
}

CALIBRATION_KINDS = {
    "camera-profile": CAMERA_CHECK,
    "printer-profile": {
        "scale_x": Field("number", lo=0.5, hi=2.0),
        "scale_y": Field("number", lo=0.5, hi=2.0),
        "dpi": Field("number", lo=1, hi=100_000, hint="the scans' resolution"),
    },
}
