"""The job file (TOML): the object, the print and the views, every error naming its key and file."""

from __future__ import annotations

import hashlib
import math
import re
import tomllib
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from workbench.camera import Camera
from workbench.conformal.flatten import ScaleMode
from workbench.errors import UsageError, WorkbenchError
from workbench.mesh.io import UNITS_MM
from workbench.text import printable


@dataclass(frozen=True)
class Material:
    """The film or paper: its name and how far it may stretch (3D length / print length)."""

    name: str = "unspecified"
    max_stretch: float | None = None
    # films = "auto": the share of the surface the films keep within [0.8, max_stretch]
    within_share: float = 0.99


@dataclass(frozen=True)
class ObjectSpec:
    """``[object]``: the part's mesh."""

    mesh: Path
    units: str = "mm"
    corners: tuple[int, int, int, int] | str | None = None  # or "auto"
    material: Material = Material()
    forming_profile: Path | None = None  # a forming profile the print pre-compensates (workbench calibrate forming)
    # the surface to print: None (the default: "seen" for a closed mesh, the whole mesh for an open
    # one), "seen" (what the views see, grown by surface_margin_mm), "whole", or a file of face indices
    surface: str | Path | None = None
    surface_margin_mm: float | None = None  # None: the print's bleed_mm


@dataclass(frozen=True)
class PrintSpec:
    """``[print]``: resolution, scale and colours of the print."""

    dpi: float = 300.0
    scale: ScaleMode = ScaleMode()
    outline: str = "rectangle"
    background: tuple[int, int, int] = (255, 255, 255)
    margin_mm: float = 10.0
    bleed_mm: float = 3.0


@dataclass(frozen=True)
class ViewSpec:
    """``[[views]]``: one viewpoint and the image the part must show from it."""

    name: str
    image: Path
    camera: dict
    region: str = "largest"
    # which of the image's pixels are decoration (nonzero), one for one; None: the image's own
    # alpha says (alpha above 0), and an image without alpha decorates with every pixel
    mask: Path | None = None
    # the image size the view was planned for (suggest-views writes it): checked against the image
    size_px: tuple[int, int] | None = None

    def make_camera(self, width: int, height: int) -> Camera:
        """The camera for an image of this size (the image's pixel grid is the sensor)."""
        c = self.camera
        if "position" in c:
            return Camera.look_at(c["position"], c["look_at"], c["up"], c["fov_deg"], width, height)
        K = np.array([[c["fx"], 0.0, c["cx"]], [0.0, c["fy"], c["cy"]], [0.0, 0.0, 1.0]])
        return Camera(
            K=K, R=c["rotation"], t=np.asarray(c["translation"], dtype=np.float64), width=width, height=height
        )


@dataclass(frozen=True)
class FilmSpec:
    """``[[films]]``: one film, the surface it covers and how it is cut.

    Attributes
    ----------
    name : str
        Shown in outputs ("film k of n").
    views : tuple of str, or None
        The film covers the surface these views own.
    faces : Path or None
        Or a text file of 0-based face indices (whitespace or comma separated).
    outline : {'rectangle', 'free'}
        Its outline (default: ``[print] outline``).
    corners : tuple of 4 int, or None
        Corner vertices of a rectangle (vertex indices of the part's mesh).
    material : Material
        Its material (default: ``[object] material``).
    """

    name: str
    views: tuple[str, ...] | None = None
    faces: Path | None = None
    outline: str = "rectangle"
    corners: tuple[int, int, int, int] | None = None
    material: Material = Material()


@dataclass(frozen=True)
class Job:
    """A parsed job file; paths are absolute.

    ``films``: None (one film over the whole part), ``"auto"`` (split so that every
    film stays within the material's ``max_stretch``), or the films given by hand.
    """

    path: Path
    sha256: str
    object: ObjectSpec
    print: PrintSpec
    views: tuple[ViewSpec, ...]
    fixture: dict | None
    films: tuple[FilmSpec, ...] | str | None = None
    given_name: str | None = None

    @property
    def name(self) -> str:
        """The job's ``name`` key; without one the file's name, or its folder's when the file is just ``job.toml``.

        It names the design folder, the print and fixture files and every report's title.
        """
        if self.given_name is not None:
            return printable(self.given_name)
        return printable(self.path.parent.name if self.path.stem == "job" else self.path.stem)


def _finite(value: float) -> bool:
    """Finite, and within a float's range (TOML integers are unbounded)."""
    try:
        return math.isfinite(float(value))
    except OverflowError:
        return False


# the farthest a job's camera or fixture may be from the mesh's origin, mm (1 km): beyond it no
# photo sees the part, and a typo (a unit, an exponent) is the likelier reading
MAX_COORDINATE_MM = 1e6


def real_path(path: Path, key: str = "") -> Path:
    """``path`` absolute with every symbolic link followed; a link that loops is one line naming it (and ``key``)."""
    try:
        return Path(path).resolve()
    except (RuntimeError, OSError):  # Python 3.11 raises RuntimeError("Symlink loop ...")
        at = f"{key}: " if key else ""
        raise WorkbenchError(f"{at}{path}: a symbolic link that loops back on itself") from None


class _Reader:
    """Typed access to one TOML table, with errors that name the file and the key."""

    def __init__(self, path: Path, where: str, table: object, known: set[str]):
        self.path, self.where = path, where
        if not isinstance(table, dict):
            self.fail(f"must be a table, got {type(table).__name__}")
        self.table = table
        unknown = sorted(set(table) - known)
        if unknown:
            self.fail(f"unknown key {unknown[0]!r} (known keys: {', '.join(sorted(known))})")

    def fail(self, message: str, key: str | None = None):
        at = f"{self.where}.{key}" if key else self.where
        raise WorkbenchError(f"{self.path}: {at}: {message}")

    def has(self, key: str) -> bool:
        return key in self.table

    def get(self, key: str, default=None, required: bool = False):
        if key not in self.table:
            if required:
                self.fail("missing", key)
            return default
        return self.table[key]

    def number(self, key: str, default=None, lo=None, hi=None, required=False, integer=False) -> float | None:
        value = self.get(key, default, required)
        if value is None:
            return None
        if isinstance(value, bool) or not isinstance(value, int | float) or (integer and not isinstance(value, int)):
            self.fail(f"must be {'an integer' if integer else 'a number'}, got {value!r}", key)
        if not _finite(value) or (lo is not None and value <= lo) or (hi is not None and value >= hi):
            bounds = (
                f" between {lo} and {hi}"
                if lo is not None and hi is not None
                else (f" above {lo}" if lo is not None else "")
            )
            self.fail(f"must be a number{bounds}, got {value!r}", key)
        return value

    def string(self, key: str, default=None, required=False, choices=None) -> str | None:
        value = self.get(key, default, required)
        if value is None:
            return None
        if not isinstance(value, str):
            self.fail(f"must be a string, got {value!r}", key)
        if choices is not None and value not in choices:
            self.fail(f"must be one of {', '.join(choices)}, got {value!r}", key)
        return value

    def vector(self, key: str, n: int, required=False, default=None) -> np.ndarray | None:
        value = self.get(key, default, required)
        if value is None:
            return None
        try:
            arr = np.asarray(value, dtype=np.float64)
        except (TypeError, ValueError, OverflowError):
            self.fail(f"must be a list of {n} numbers, got {value!r}", key)
        if arr.shape != (n,) or not np.isfinite(arr).all():
            self.fail(f"must be a list of {n} numbers, got {value!r}", key)
        return arr

    def file(self, key: str, required=True) -> Path | None:
        value = self.string(key, required=required)
        if value is None:
            return None
        path = real_path(self.path.parent / value, f"{self.path}: {self.where}.{key}")
        if path.is_dir():
            self.fail(f"{value!r} is a directory, not a file ({path})", key)
        if not path.is_file():
            self.fail(f"file {value!r} not found (looked for {path})", key)
        return path


def _colour(r: _Reader, key: str, default) -> tuple[int, int, int]:
    value = r.get(key, default)
    if isinstance(value, str) and len(value) == 7 and value.startswith("#"):
        try:
            return tuple(int(value[i : i + 2], 16) for i in (1, 3, 5))  # type: ignore[return-value]
        except ValueError:
            pass
    elif (
        isinstance(value, list | tuple) and len(value) == 3 and all(isinstance(v, int) and 0 <= v <= 255 for v in value)
    ):
        return tuple(value)  # type: ignore[return-value]
    r.fail(f'must be "#rrggbb" or [r, g, b] with values 0 to 255, got {value!r}', key)


def _rotation(r: _Reader) -> np.ndarray:
    value = r.get("rotation", required=True)
    try:
        arr = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError, OverflowError):
        arr = np.zeros(0)
    if arr.shape == (3,) and np.isfinite(arr).all():
        import cv2  # a rotation vector (Rodrigues, radians), as OpenCV writes them

        return cv2.Rodrigues(arr)[0]
    if arr.shape == (3, 3) and np.isfinite(arr).all():
        if np.abs(arr @ arr.T - np.eye(3)).max() > 1e-6 or np.linalg.det(arr) < 0:
            r.fail("must be a proper rotation matrix (orthonormal, determinant +1)", "rotation")
        return arr
    r.fail("must be a 3x3 rotation matrix or a rotation vector [rx, ry, rz] in radians", "rotation")


VIEW_POSE_KEYS = {"position", "look_at", "up", "fov_deg"}
VIEW_NAME = re.compile(r"[A-Za-z0-9][A-Za-z0-9._-]{0,63}")
VIEW_K_KEYS = {"fx", "fy", "cx", "cy", "rotation", "translation"}
# written by suggest-views beside the camera: the image size it needs (checked against the
# image), and what it would own (a note for the designer; design reports what it owns)
VIEW_PLAN_KEYS = {"width_px", "height_px", "covers_share", "covers_mm2"}


def _view(path: Path, i: int, table: object, names: set[str]) -> ViewSpec:
    r = _Reader(
        path, f"views[{i}]", table, {"name", "image", "region", "mask"} | VIEW_POSE_KEYS | VIEW_K_KEYS | VIEW_PLAN_KEYS
    )
    name = r.string("name", required=True)
    if not VIEW_NAME.fullmatch(name):
        # the name becomes file names (view-NAME.png): nothing that leaves the output folder or hides a file
        r.fail(
            f"must be 1 to 64 letters, digits, '.', '_' or '-', starting with a letter or digit, got {name!r}",
            "name",
        )
    if name in names:
        r.fail(f"view name {name!r} is used twice", "name")
    image = r.file("image")
    region = r.string("region", "largest", choices=("largest", "all"))
    mask = r.file("mask", required=False)
    pose, intr = VIEW_POSE_KEYS & set(r.table), VIEW_K_KEYS & set(r.table)
    if pose and intr:
        r.fail(
            f"give the camera as {', '.join(sorted(VIEW_POSE_KEYS))} or as {', '.join(sorted(VIEW_K_KEYS))}, not both"
        )
    if pose:
        for k in sorted(VIEW_POSE_KEYS - pose):
            r.fail("missing", k)
        camera = {
            "position": r.vector("position", 3),
            "look_at": r.vector("look_at", 3),
            "up": r.vector("up", 3),
            "fov_deg": r.number("fov_deg", lo=0, hi=180),
        }
        for k in ("position", "look_at"):
            far = float(np.abs(camera[k]).max())
            if far > MAX_COORDINATE_MM:
                r.fail(f"{far:g} mm from the origin: a camera beyond {MAX_COORDINATE_MM / 1e6:g} km sees no part", k)
        d = camera["look_at"] - camera["position"]
        if np.linalg.norm(d) == 0:
            r.fail("look_at must differ from position", "look_at")
        if not np.any(camera["up"]):
            r.fail("must not be zero", "up")
        # the sine of the angle between the two, each scaled to length 1 first (no overflow, no units)
        d_unit, up_unit = d / np.linalg.norm(d), camera["up"] / np.linalg.norm(camera["up"])
        if np.linalg.norm(np.cross(d_unit, up_unit)) <= 1e-9:
            r.fail("up must not be parallel to the viewing direction", "up")
    elif intr:
        for k in sorted(VIEW_K_KEYS - intr):
            r.fail("missing", k)
        camera = {k: r.number(k, lo=0 if k in ("fx", "fy") else None) for k in ("fx", "fy", "cx", "cy")}
        camera["rotation"] = _rotation(r)
        camera["translation"] = r.vector("translation", 3)
    else:
        r.fail(f"no camera: give {', '.join(sorted(VIEW_POSE_KEYS))} or {', '.join(sorted(VIEW_K_KEYS))}")
    width, height = (r.number(k, lo=0, integer=True) for k in ("width_px", "height_px"))
    if (width is None) != (height is None):
        r.fail("give width_px and height_px together, or neither", "width_px" if width is None else "height_px")
    r.number("covers_share", lo=-1e-300, hi=1 + 1e-12)
    r.number("covers_mm2", lo=-1e-300)
    size = None if width is None else (int(width), int(height))
    return ViewSpec(name=name, image=image, camera=camera, region=region, mask=mask, size_px=size)


def load_job(path: str | Path) -> Job:
    """Read and check a job file.

    Parameters
    ----------
    path : str or Path
        The TOML file; paths inside it are relative to it.

    Returns
    -------
    Job

    Raises
    ------
    WorkbenchError
        Unreadable TOML, unknown keys, missing files, impossible values; the message
        names the file and the key.
    """
    path = real_path(Path(path))
    if path.is_dir():
        raise WorkbenchError(f"{path}: is a directory, not a job file")
    if not path.is_file():
        raise WorkbenchError(f"{path}: no such job file")
    data = path.read_bytes()
    try:
        # utf-8-sig: an editor's byte-order mark is not the first statement of the file
        doc = tomllib.loads(data.decode("utf-8-sig"))
    except (UnicodeDecodeError, tomllib.TOMLDecodeError) as exc:
        raise WorkbenchError(f"{path}: not valid TOML: {exc}") from None
    except RecursionError:
        raise WorkbenchError(f"{path}: not valid TOML: nested deeper than a job can be") from None
    top = _Reader(path, "job", doc, {"name", "object", "print", "views", "fixture", "films"})
    given_name = top.string("name")
    if given_name is not None and not given_name.strip():
        top.fail("must name the job (it names the design folder and the reports)", "name")

    o = _Reader(
        path,
        "object",
        top.get("object", required=True),
        {"mesh", "units", "corners", "material", "forming_profile", "surface", "surface_margin_mm"},
    )
    corners = o.get("corners")
    if corners is not None and corners != "auto":
        if not (isinstance(corners, list) and len(corners) == 4 and all(_vertex_index(c) for c in corners)):
            o.fail(f'must be a list of 4 vertex indices or "auto", got {corners!r}', "corners")
        corners = tuple(corners)
    m = _Reader(path, "object.material", o.get("material", {}), {"name", "max_stretch", "within_share"})
    material = Material(
        name=m.string("name", "unspecified"),
        max_stretch=m.number("max_stretch", None, lo=0),
        within_share=m.number("within_share", 0.99, lo=0.5, hi=1),
    )
    obj = ObjectSpec(
        mesh=o.file("mesh"),
        units=o.string("units", "mm", choices=tuple(UNITS_MM)),
        corners=corners,
        material=material,
        forming_profile=o.file("forming_profile", required=False),
        surface=_surface(o),
        surface_margin_mm=o.number("surface_margin_mm", None, lo=-1e-300, hi=1e6),
    )
    if obj.surface_margin_mm is not None and obj.surface == "whole":
        o.fail(
            'a margin grows the surface the views see; surface = "whole" takes the mesh as it is', "surface_margin_mm"
        )
    if isinstance(obj.corners, tuple) and obj.surface not in (None, "whole"):
        o.fail(
            "corner vertices are the mesh's, but a surface cut out of it is numbered anew: "
            'use corners = "auto" or leave them out',
            "corners",
        )

    p = _Reader(path, "print", top.get("print", {}), {"dpi", "scale", "outline", "background", "margin_mm", "bleed_mm"})
    outline = p.string("outline", "rectangle", choices=("rectangle", "free"))
    try:
        scale = ScaleMode.parse(p.string("scale", str(ScaleMode.default(outline))))
    except UsageError as exc:
        p.fail(str(exc).replace("--scale ", ""), "scale")
    dpi = p.number("dpi", 300.0, lo=0)
    # a denormal: a print pixel wider than any part, and a division by it overflows; 1e308: the
    # print's size in pixels overflows before the memory check can refuse it
    if not 1 <= dpi <= 1e6:
        p.fail(f"must be from 1 to 1000000 dpi, got {dpi!r}", "dpi")
    spec = PrintSpec(
        dpi=dpi,
        scale=scale,
        outline=outline,
        background=_colour(p, "background", "#ffffff"),
        margin_mm=p.number("margin_mm", 10.0, lo=-1e-300),
        bleed_mm=p.number("bleed_mm", 3.0, lo=-1e-300),
    )

    views_raw = top.get("views", required=True)
    if not isinstance(views_raw, list) or not views_raw:
        top.fail("must be one or more [[views]] tables", "views")
    views: list[ViewSpec] = []
    for i, v in enumerate(views_raw):
        views.append(_view(path, i, v, {x.name for x in views}))

    fixture = top.get("fixture")
    if fixture is not None and not isinstance(fixture, dict):
        top.fail("must be a table", "fixture")
    films = _films(path, top, obj, spec, {v.name for v in views})
    return Job(
        path=path,
        sha256=hashlib.sha256(data).hexdigest(),
        object=obj,
        print=spec,
        views=tuple(views),
        fixture=fixture,
        films=films,
        given_name=given_name.strip() if given_name is not None else None,
    )


def _surface(o: _Reader) -> str | Path | None:
    """``[object] surface``: "seen", "whole" or a text file of 0-based face indices (None: not given)."""
    value = o.string("surface")
    if value is None or value in ("seen", "whole"):
        return value
    if not (o.path.parent / value).exists():
        o.fail(
            f'must be "seen", "whole" or a file of face indices; no file {value!r} (looked beside the job)', "surface"
        )
    return o.file("surface")


def _vertex_index(c) -> bool:
    """Whether ``c`` can be a vertex index: a whole number from 0 below 2**31 (a 20-digit one overflowed numpy)."""
    return isinstance(c, int) and not isinstance(c, bool) and 0 <= c < 2**31


def _films(path: Path, top: _Reader, obj: ObjectSpec, spec: PrintSpec, view_names: set[str]):
    """``films = "auto"`` or ``[[films]]`` tables; None without either."""
    raw = top.get("films")
    if raw is None:
        return None
    if raw == "auto":
        if obj.material.max_stretch is None:
            top.fail(
                '"auto" splits the part so that each film stays within the material: set [object].material.max_stretch',
                "films",
            )
        if obj.corners is not None:
            top.fail('"auto" films have free outlines: leave out [object].corners', "films")
        return "auto"
    if not isinstance(raw, list) or not raw or not all(isinstance(t, dict) for t in raw):
        top.fail('must be "auto" or one or more [[films]] tables', "films")
    films: list[FilmSpec] = []
    for i, table in enumerate(raw):
        r = _Reader(path, f"films[{i}]", table, {"name", "views", "faces", "outline", "corners", "material"})
        name = r.string("name", f"film-{i + 1}")
        if not re.fullmatch(r"[A-Za-z0-9][A-Za-z0-9_.-]{0,63}", name) or any(f.name == name for f in films):
            r.fail(
                f"film name {name!r}: use letters, digits, '_', '-' and '.' (not first), once per job; it names files",
                "name",
            )
        views = r.get("views")
        if views is not None:
            if not isinstance(views, list) or not views or not all(isinstance(v, str) for v in views):
                r.fail("must be a list of view names", "views")
            unknown = [v for v in views if v not in view_names]
            if unknown:
                r.fail(f"no view named {unknown[0]!r} (views: {', '.join(sorted(view_names))})", "views")
            views = tuple(views)
        faces = r.file("faces", required=False)
        if (views is None) == (faces is None):
            r.fail('give the surface as views = [...] or as faces = "file.txt" (one of them)')
        outline = r.string("outline", spec.outline, choices=("rectangle", "free"))
        corners = r.get("corners")
        if corners is not None:
            if outline != "rectangle":
                r.fail("corners belong to a rectangle; a free outline has none", "corners")
            if not (isinstance(corners, list) and len(corners) == 4 and all(_vertex_index(c) for c in corners)):
                r.fail(f"must be a list of 4 vertex indices, got {corners!r}", "corners")
            corners = tuple(corners)
        material = obj.material
        if r.has("material"):
            m = _Reader(path, f"films[{i}].material", r.get("material"), {"name", "max_stretch"})
            material = Material(
                name=m.string("name", obj.material.name), max_stretch=m.number("max_stretch", None, lo=0)
            )
        films.append(FilmSpec(name, views, faces, outline, corners, material))
    return tuple(films)
