"""Reading a design directory (the output of ``workbench design``): what render and validate need."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

from workbench import schemas
from workbench.atomic import MANIFEST, folder_manifest, safe_name
from workbench.camera import Camera
from workbench.errors import WorkbenchError
from workbench.image_file import decode_upright, imread, read_file_bytes
from workbench.jsonfile import read_json
from workbench.mesh.io import read_mesh
from workbench.printing.boards import load_board


def read_design_json(path: Path, fields: dict = schemas.DESIGN) -> dict:
    """design.json of a design folder, checked (:data:`workbench.schemas.DESIGN`); view names unique."""
    info = read_json(path, "design.json of workbench design", fields)
    names = [v["name"] for v in info["views"]] if "views" in fields else []
    for k, name in enumerate(names):
        if name in names[:k]:
            raise WorkbenchError(f"{path}: views[{k}].name: {name!r} is used twice")
    check_print_extent(info.get("print") or {}, path)
    return info


def check_print_extent(p: dict, path: Path) -> None:
    """Refuse a design.json whose print dpi, pixel size and extent in mm disagree (one edited by hand).

    design writes ``image_width_mm = width_px / (dpi / 25.4)`` (and so for the height); an edited
    dpi would scale every print position validate and pdf compute, and a wrong print would be
    judged as a wrong part.
    """
    if not all(k in p for k in ("dpi", "width_px", "height_px", "image_width_mm", "image_height_mm")):
        return
    for axis in ("width", "height"):
        px, mm = p[f"{axis}_px"], p[f"image_{axis}_mm"]
        implied = mm * p["dpi"] / 25.4
        # design computed mm from px: they agree to rounding (1e-6 px); an edit is off by whole pixels
        if not abs(implied - px) <= 1e-6 * max(px, 1):
            raise WorkbenchError(
                f"{path}: print.dpi {p['dpi']:g} and print.{axis}_px {px} disagree with print.image_{axis}_mm "
                f"{mm:g} (they give {implied:.1f} px): the file was edited; rerun workbench design"
            )


# what workbench design writes, for a folder written before it listed them in .workbench-files
_DESIGN_FILES = ("design.json", "print.png", "owner.png", "flat.obj", "decorated.obj", "decorated.mtl", "decorated.glb",
                 "fixture.json", "views.png", "stretch.png", "view-*.png", "print-*.png", "flat-*.obj")  # fmt: skip


def design_files(directory: Path) -> list[Path]:
    """The files of a design folder, with the folder itself: the inputs no output of pdf, render or
    validate may replace (``render -o DESIGN/print.png``) and no output folder may be."""
    directory = Path(directory)
    names = folder_manifest(directory)
    files = [directory / n for n in names] or [p for pat in _DESIGN_FILES for p in sorted(directory.glob(pat))]
    return [directory, *files, *([directory / MANIFEST] if names else [])]


def fm_sizes(info: dict) -> list[tuple[float, float]]:
    from workbench.forming import film_base_sizes

    return film_base_sizes(info)


@dataclass(frozen=True)
class FilmFrame:
    """One film's uncompensated print in a design's print.

    Attributes
    ----------
    name : str
    origin_mm : (2,) float
        Its uncompensated print's top-left corner in the design's print, mm (x right, y down).
    size_mm : (2,) float
        Its uncompensated print's width and height, mm: what its forming field is defined on.
    corner_mm : (2,) float
        Its own print's top-left corner in the design's print (the atlas place; 0 for one film), mm.
    print_mm : (2,) float
        Its own print's width and height (compensated: grown), mm.
    index : int or None
        Its index in design.json's ``films`` (None: a design of one film).
    """

    name: str
    origin_mm: np.ndarray
    size_mm: tuple
    corner_mm: np.ndarray
    print_mm: tuple
    index: int | None


class Design:
    """A design directory: the part, its flat layout, print, ownership, views and fixture."""

    def __init__(self, directory: Path):
        if not directory.is_dir():
            raise WorkbenchError(f"{directory}: no such design directory (run workbench design first)")
        need = ("design.json", "print.png", "flat.obj", "decorated.obj", "fixture.json")
        for name in need:
            if not (directory / name).is_file():
                raise WorkbenchError(f"{directory / name}: missing; is {directory} the output of workbench design?")
        self.dir = directory
        self.info = read_design_json(directory / "design.json")
        self.fixture = load_board(directory / "fixture.json", "fixture definition", schemas.FIXTURE)
        # the decorated mesh: the part in mm, in the input's vertex order
        self.V, self.F = read_mesh(directory / "decorated.obj", solid=False)
        flat, flat_F = read_mesh(directory / "flat.obj", solid=False)
        # the same triangles, vertex for vertex: the print's layout of the decorated part
        if flat.shape != self.V.shape or not np.array_equal(flat_F, self.F):
            raise WorkbenchError(
                f"{directory / 'flat.obj'}: {len(flat)} vertices and {len(flat_F)} faces do not match decorated.obj's "
                f"{len(self.V)} and {len(self.F)}; rerun workbench design"
            )
        for name, arr in (("decorated.obj", self.V), ("flat.obj", flat)):
            if not np.isfinite(arr).all():
                raise WorkbenchError(f"{directory / name}: vertices have NaN or infinite coordinates")
        self.flat = flat[:, :2]
        img = imread(directory / "print.png")
        if img is not None and img.dtype == np.uint16:  # as IMREAD_COLOR would: 8 bits
            img = (img // 257).astype(np.uint8)
        if img is not None and img.ndim == 2:
            img = cv2.cvtColor(img, cv2.COLOR_GRAY2BGR)
        if img is None or img.dtype != np.uint8 or img.shape[2] not in (3, 4):
            raise WorkbenchError(f"{directory / 'print.png'}: cannot read (an RGB or RGBA image expected)")
        # a free outline's print is RGBA: transparent beyond the film
        self.alpha = img[..., 3] if img.shape[2] == 4 else None
        self.rgb = cv2.cvtColor(img[..., :3], cv2.COLOR_BGR2RGB)
        p = self.info["print"]
        if self.rgb.shape[:2] != (p["height_px"], p["width_px"]):
            raise WorkbenchError(
                f"{directory / 'print.png'}: {self.rgb.shape[1]} x {self.rgb.shape[0]} px, design.json says "
                f"{p['width_px']} x {p['height_px']}"
            )
        owner = imread(directory / "owner.png")
        # owning view + 1 per print pixel, 0 for none (see design); validate needs it, render does not
        self.owner = None if owner is None else owner.astype(np.int16) - 1
        if self.owner is not None and (
            self.owner.shape != self.rgb.shape[:2] or self.owner.max() >= len(self.info["views"])
        ):
            raise WorkbenchError(
                f"{directory / 'owner.png'}: not the view ownership of this print (its size or view numbers "
                "differ); rerun workbench design"
            )

    def view_image(self, index: int) -> np.ndarray:
        """The image of designed view ``index`` (RGB), as the design used it."""
        name = self.info["views"][index]["name"]
        path = self.dir / f"view-{safe_name(name)}.png"
        img = imread(path, cv2.IMREAD_COLOR)
        if img is None:
            raise WorkbenchError(f"{path}: missing; rerun workbench design")
        return cv2.cvtColor(img, cv2.COLOR_BGR2RGB)

    def scene(self, imp, fixture: bool = True, forming=None):
        """The render scene (:func:`workbench.render.photo.build_scene`) of this design with ``imp``.

        ``forming``: a field of :mod:`workbench.forming`: the film lands by it (the truth of a formed sheet).
        """
        from workbench.render.photo import build_scene  # numba kernels: loaded by the commands that render

        p = self.info["print"]
        rgb = self.rgb
        if self.alpha is not None and (self.alpha > 0).any():
            # the film as printed carries a bleed beyond its outline (see workbench pdf): a
            # texture lookup at the cut then shows the film's own colours, not the transparent
            # pixels' (which drew a hairline along every seam); 2 mm stays within half the gap
            # between films in the atlas
            from workbench.texture.outline import bleed_beyond_outline

            rgb, _ = bleed_beyond_outline(self.rgb, self.alpha > 0, 2.0 * p["dpi"] / 25.4)
        return build_scene(
            self.V,
            self.F,
            self.flat if forming is None else self.formed_flat(forming),
            p["height_mm"],
            rgb,
            p["dpi"],
            imp,
            self.fixture if fixture else None,
            vertex_film=self.vertex_film(),
        )

    def film_frames(self) -> list[FilmFrame]:
        """Where each film's uncompensated print sits in this design's print (one film: the print).

        Forming fields are defined per film on its uncompensated print (x right, y down from its
        top-left corner): this print's point q is that film's ``q - origin_mm``.
        """
        p = self.info["print"]
        mm = 25.4 / p["dpi"]
        films = self.info.get("films")
        sizes = fm_sizes(self.info)
        if not films:
            off = np.asarray(p.get("frame_offset_px", [0, 0]), dtype=np.float64) * mm
            return [FilmFrame("film-1", off, sizes[0], np.zeros(2), (p["width_mm"], p["height_mm"]), None)]
        out = []
        for k, f in enumerate(films):
            r0, c0 = f["atlas_px"]
            off = np.asarray((f.get("forming") or {}).get("frame_offset_px", [0, 0]), dtype=np.float64)
            corner = np.array([c0, r0], dtype=np.float64) * mm
            out.append(FilmFrame(f["name"], corner + off * mm, sizes[k], corner, (f["width_mm"], f["height_mm"]), k))
        return out

    def film_of_print_mm(self, q: np.ndarray) -> np.ndarray:
        """The film (0-based) whose print holds each point ``q`` of this print (mm, x right, y down); -1: none."""
        q = np.asarray(q, dtype=np.float64).reshape(-1, 2)
        out = np.full(len(q), -1)
        for k, fr in enumerate(self.film_frames()):
            inside = ((q >= fr.corner_mm) & (q <= fr.corner_mm + np.asarray(fr.print_mm))).all(axis=1)
            out[inside & (out < 0)] = k
        return out

    def compensations(self) -> list | None:
        """Each film's forming field this design pre-compensates for (its ``forming-profile.json``), or None."""
        rec = self.info.get("forming")
        if not rec:
            return None
        from workbench import forming as fm

        path = self.dir / "forming-profile.json"
        if not path.is_file() or fm.file_sha256(path) != rec["profile"]["sha256"]:
            raise WorkbenchError(f"{path}: missing or not the profile design.json records; rerun workbench design")
        fields = fm.profile_fields(fm.read_profile(path))
        if len(fields) != len(self.film_frames()):
            raise WorkbenchError(
                f"{path}: {len(fields)} films, the design {len(self.film_frames())}; rerun workbench design"
            )
        return fields

    def vertex_films(self) -> np.ndarray:
        """The film (0-based) of each vertex of decorated.obj (all 0 with one film)."""
        vf = self.vertex_film()
        return np.zeros(len(self.V), int) if vf is None else vf

    def nominal_print_mm(self) -> np.ndarray:
        """Each vertex's design print position on its film's uncompensated print (mm, x right, y down):
        where the conformal map puts it (for a compensated design: x + d(x), x its print point)."""
        p = np.stack([self.flat[:, 0], self.info["print"]["height_mm"] - self.flat[:, 1]], axis=1)
        vf = self.vertex_films()
        comps = self.compensations()
        out = np.full_like(p, np.nan)
        for k, fr in enumerate(self.film_frames()):
            on = vf == k
            x = p[on] - fr.origin_mm
            out[on] = x if comps is None else x + comps[k](x)
        return out

    def formed_flat(self, forming) -> np.ndarray:
        """The flat layout (y up, mm) films formed by ``forming`` (one field per film; or one field, for a
        design of one film) have: each vertex shows the film point that lands at its nominal position,
        p with p + d(p) = nominal."""
        from workbench import forming as fm

        fields = forming if isinstance(forming, (list, tuple)) else [forming]
        frames = self.film_frames()
        if len(fields) != len(frames):
            raise WorkbenchError(f"{len(fields)} forming fields for a design of {len(frames)} films")
        nominal = self.nominal_print_mm()
        vf = self.vertex_films()
        p = np.full_like(nominal, np.nan)
        for k, fr in enumerate(frames):
            on = vf == k
            p[on] = fm.invert(fields[k], nominal[on]) + fr.origin_mm
        # (a vertex on no film, if any: where it is)
        off = ~np.isfinite(p).all(axis=1)
        p[off] = np.stack([self.flat[off, 0], self.info["print"]["height_mm"] - self.flat[off, 1]], axis=1)
        return np.stack([p[:, 0], self.info["print"]["height_mm"] - p[:, 1]], axis=1)

    def vertex_film(self) -> np.ndarray | None:
        """With several films, the film (0-based) of each vertex of decorated.obj; else None."""
        films = self.info.get("films")
        if not films:
            return None
        out = np.full(len(self.V), -1)
        for k, f in enumerate(films):
            lo, hi = f["atlas_faces"]
            out[self.F[lo:hi].ravel()] = k
        return out

    def view_camera(self, name: str) -> Camera:
        for v in self.info["views"]:
            if v["name"] == name:
                c = v["camera"]
                return Camera(np.asarray(c["K"]), np.asarray(c["R"]), np.asarray(c["t"]), *c["image_size"])
        names = ", ".join(v["name"] for v in self.info["views"])
        raise WorkbenchError(f"no view named {name!r} in {self.dir / 'design.json'} (views: {names})")

    def orbit_camera(self, az_deg, el_deg, dist_mm, width, height, fov_deg, intrinsics: Camera | None) -> Camera:
        centre = 0.5 * (self.V.min(axis=0) + self.V.max(axis=0))
        a, e = np.radians(az_deg), np.radians(el_deg)
        # azimuth 0: in front of the part (towards -y), counter-clockwise seen from above
        eye = centre + dist_mm * np.array([np.sin(a) * np.cos(e), -np.cos(a) * np.cos(e), np.sin(e)])
        up = [0.0, 0.0, 1.0] if abs(el_deg) < 89 else [0.0, 1.0, 0.0]
        cam = Camera.look_at(eye, centre, up, fov_deg, width, height)
        if intrinsics is not None:
            cam = Camera(intrinsics.K, cam.R, cam.t, intrinsics.width, intrinsics.height, intrinsics.dist)
        return cam


# the largest view image read: a camera's (today's largest sensors: about 100 Mpx). Decoding
# needs about 30 bytes a pixel (the file, the image, its colour conversion and the
# sampling's copies): a 20000 x 20000 px image took 12.5 GB.
MAX_VIEW_PIXELS = 100_000_000


def read_image(
    path, what: str, background: tuple[int, int, int] = (255, 255, 255), data: bytes | None = None
) -> np.ndarray:
    """An image file as RGB uint8, or a WorkbenchError naming it.

    Parameters
    ----------
    path : Path
        The image (PNG, JPEG, ... any bit depth, grey, RGB or RGBA).
    what : str
        The file's role, for errors (``JOB.toml: views[0].image``).
    background : (3,) int
        RGB under the transparent pixels of an image with alpha: the print's background,
        not the black that dropping the alpha channel shows.
    data : bytes, optional
        The file's contents, when the caller has read them already (for its hash).

    Returns
    -------
    (H, W, 3) uint8
    """
    return read_image_alpha(path, what, background, data)[0]


def read_image_alpha(
    path, what: str, background: tuple[int, int, int] = (255, 255, 255), data: bytes | None = None
) -> tuple[np.ndarray, np.ndarray | None]:
    """An image file as RGB uint8 and which of its pixels are not transparent, or a WorkbenchError naming it.

    Parameters
    ----------
    path : Path
        The image (PNG, JPEG, ... any bit depth, grey, RGB or RGBA).
    what : str
        The file's role, for errors (``JOB.toml: views[0].image``).
    background : (3,) int
        RGB under the transparent pixels (see :func:`read_image`).
    data : bytes, optional
        The file's contents, when the caller has read them already.

    Returns
    -------
    rgb : (H, W, 3) uint8
        As :func:`read_image` returns it.
    opaque : (H, W) bool or None
        Alpha above 0, at the file's own bit depth (a 16-bit alpha of 1 is not transparent);
        None for an image without an alpha channel.
    """
    if Path(path).is_dir():
        raise WorkbenchError(f"{what}: {path} is a directory, not an image")
    check_image_size(path, what)
    if data is None:
        try:
            data = read_file_bytes(path)
        except OSError:
            data = b""
    img = decode_upright(data)  # upright as its EXIF orientation says, as every viewer shows it
    if img is None:
        raise WorkbenchError(f"{what}: cannot read image {path} (missing, empty or not an image)")
    opaque = img[..., 3] > 0 if img.ndim == 3 and img.shape[2] == 4 else None
    if img.dtype != np.uint8:  # 16-bit or float: as IMREAD_COLOR would, 8 bits
        img = np.clip(img.astype(np.float64) / (257.0 if img.dtype == np.uint16 else 1.0 / 255.0), 0, 255)
        img = np.round(img).astype(np.uint8)
    if img.ndim == 2:
        img = cv2.cvtColor(img, cv2.COLOR_GRAY2BGR)
    if img.shape[2] == 4:
        alpha = img[..., 3:4].astype(np.float32) / 255.0
        under = np.asarray(background[::-1], np.float32)  # BGR, as OpenCV reads
        img = np.round(img[..., :3] * alpha + under * (1.0 - alpha)).astype(np.uint8)
    elif img.shape[2] != 3:
        img = cv2.cvtColor(img[..., :1], cv2.COLOR_GRAY2BGR)
    return cv2.cvtColor(img, cv2.COLOR_BGR2RGB), opaque


def read_mask(path, what: str, size: tuple[int, int], image_name: str) -> np.ndarray:
    """A view's decoration mask (``[[views]] mask``): which pixels of its image are decoration.

    Parameters
    ----------
    path : Path
        A grey, binary, RGB or RGBA image (any bit depth) the size of the view image.
    what : str
        The key, for errors (``JOB.toml: views[0].mask``).
    size : (width, height)
        The view image's size, px (upright).
    image_name : str
        The view image's file name, for errors.

    Returns
    -------
    (height, width) bool
        True where the mask is nonzero: its alpha above 0 when it has an alpha channel (a logo
        given as its own mask), else any channel above 0.
    """
    if Path(path).is_dir():
        raise WorkbenchError(f"{what}: {path} is a directory, not an image")
    check_image_size(path, what)
    try:
        data = read_file_bytes(path)
    except OSError:
        data = b""
    img = decode_upright(data)
    if img is None:
        raise WorkbenchError(f"{what}: cannot read image {path} (missing, empty or not an image)")
    h, w = img.shape[:2]
    if (w, h) != tuple(size):
        raise WorkbenchError(
            f"{what}: {Path(path).name} is {w} x {h} px, but the image {image_name} is {size[0]} x {size[1]} px: "
            "a mask marks the image's pixels one for one"
        )
    if img.ndim == 2:
        return img > 0
    return img[..., 3] > 0 if img.shape[2] == 4 else (img > 0).any(axis=2)


def check_image_size(path, what: str) -> None:
    """Refuse, from its header alone, an image of more than MAX_VIEW_PIXELS pixels."""
    from PIL import Image

    limit, Image.MAX_IMAGE_PIXELS = Image.MAX_IMAGE_PIXELS, None  # this check is ours, and says which file
    try:
        with Image.open(path) as im:  # the header only: no pixel decoded
            w, h = im.size
    except Exception:  # not an image PIL knows: OpenCV says so next
        return
    finally:
        Image.MAX_IMAGE_PIXELS = limit
    if w * h > MAX_VIEW_PIXELS:
        raise WorkbenchError(
            f"{what}: {path} is {w} x {h} px ({w * h / 1e6:,.0f} Mpx): more than a view image needs "
            f"(at most {MAX_VIEW_PIXELS / 1e6:.0f} Mpx, whose decoding alone takes gigabytes): scale it down"
        )
