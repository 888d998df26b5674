"""The interactive QA report: qa_report.html, the part in 3D with its defects, coverage and photos, in one file."""

from __future__ import annotations

import base64
import functools
import gzip
import html
import json
import re
from dataclasses import dataclass
from importlib import resources
from pathlib import Path

import cv2
import numpy as np

from workbench.validate import print_warp
from workbench.validate.part_glb import grid_on_texture, layered_glb, print_uv
from workbench.validate.pictures import STATE_COLOURS, coverage_image

# three.js as vendored (viewer/three/README.md): each module by the name the page imports it as
THREE_MODULES = {
    "three": "build/three.module.js",
    "three/core": "build/three.core.js",
    "three/addons/controls/OrbitControls.js": "examples/jsm/controls/OrbitControls.js",
    "three/addons/loaders/GLTFLoader.js": "examples/jsm/loaders/GLTFLoader.js",
    "three/addons/utils/BufferGeometryUtils.js": "examples/jsm/utils/BufferGeometryUtils.js",
    "three/addons/utils/SkeletonUtils.js": "examples/jsm/utils/SkeletonUtils.js",
}
# the relative imports among them, renamed as the page's import map names them
RELATIVE_IMPORTS = {
    "build/three.module.js": {"'./three.core.js'": "'three/core'"},
    "examples/jsm/loaders/GLTFLoader.js": {
        "'../utils/BufferGeometryUtils.js'": "'three/addons/utils/BufferGeometryUtils.js'",
        "'../utils/SkeletonUtils.js'": "'three/addons/utils/SkeletonUtils.js'",
    },
}


@dataclass(frozen=True)
class HtmlOptions:
    """Sizes of what qa_report.html embeds.

    Attributes
    ----------
    photo_px : int
        Longer side of each photo with its circles, pixels.
    texture_px : int
        Longer side of the part's print and coverage textures, pixels (WebGL takes 2048 everywhere).
    closeup_px : int
        Longer side of each close-up, pixels.
    jpeg_quality : int
        JPEG quality of the photos, close-ups and the print's texture (0-100).
    """

    photo_px: int = 1600
    texture_px: int = 2048
    closeup_px: int = 360
    jpeg_quality: int = 85


@dataclass(frozen=True)
class PartSurface:
    """The decorated part as the page draws it, and where its print's pixels lie on it.

    Attributes
    ----------
    V : (#V, 3) float
        Vertex positions, mm.
    F : (#F, 3) int
        Triangles.
    uv : (#V, 2) float
        Texture coordinates of the print's picture, glTF's (:func:`print_uv`).
    print_rgb : (rows, cols, 3) uint8
        The print.
    print_size_mm : (float, float)
        Width and height the print's picture covers, mm.
    X : (rows, cols, 3) float or None
        The surface point under each pixel of the print's analysis grid, mm (NaN: off the part);
        None when no photo was scored.
    px_per_mm : float
        That grid's resolution.
    """

    V: np.ndarray
    F: np.ndarray
    uv: np.ndarray
    print_rgb: np.ndarray
    print_size_mm: tuple[float, float]
    X: np.ndarray | None = None
    px_per_mm: float = 1.0


def part_surface(design, grid) -> PartSurface:
    """:class:`PartSurface` of a :class:`~workbench.design_dir.Design` and its print grid (None: no photo scored)."""
    p = design.info["print"]
    size_mm = (float(p["image_width_mm"]), float(p["image_height_mm"]))
    return PartSurface(
        V=design.V,
        F=design.F,
        uv=print_uv(design.flat, p["height_mm"], size_mm),
        print_rgb=design.rgb,
        print_size_mm=size_mm,
        X=None if grid is None else grid.X,
        px_per_mm=1.0 if grid is None else grid.px_per_mm,
    )


def surface_point(X: np.ndarray, px_per_mm: float, centre_mm, bbox_mm) -> list[float] | None:
    """The surface point of a position on the print, mm (None: no part under its box).

    Parameters
    ----------
    X : (rows, cols, 3) float
        Surface point under each grid pixel (NaN: off the part).
    px_per_mm : float
        The grid's resolution; pixel (i, j) is centred at ((j + 0.5) / px_per_mm, (i + 0.5) / px_per_mm).
    centre_mm : (x, y)
        Print mm, y down from the print's top-left corner.
    bbox_mm : (x0, y0, x1, y1)
        The box around it; where no part lies under the centre (a ring's centre), the point of
        the box nearest to it that has one.

    Returns
    -------
    [x, y, z] or None
    """
    rows, cols = X.shape[:2]
    i = int(np.clip(np.floor(centre_mm[1] * px_per_mm), 0, rows - 1))
    j = int(np.clip(np.floor(centre_mm[0] * px_per_mm), 0, cols - 1))
    if np.isfinite(X[i, j]).all():
        return [float(v) for v in X[i, j]]
    i0, j0 = (
        int(np.clip(np.floor(v * px_per_mm), 0, n - 1)) for v, n in zip(bbox_mm[1::-1], (rows, cols), strict=True)
    )
    i1 = int(np.clip(np.ceil(bbox_mm[3] * px_per_mm), i0 + 1, rows))
    j1 = int(np.clip(np.ceil(bbox_mm[2] * px_per_mm), j0 + 1, cols))
    box = X[i0:i1, j0:j1]
    ii, jj = np.nonzero(np.isfinite(box).all(axis=-1))
    if not len(ii):
        return None
    k = int(np.argmin((ii + i0 - i) ** 2 + (jj + j0 - j) ** 2))
    return [float(v) for v in box[ii[k], jj[k]]]


def _jpeg(rgb: np.ndarray, max_side: int, quality: int) -> bytes:
    s = min(1.0, max_side / max(rgb.shape[:2]))
    if s < 1.0:
        size = (max(1, round(rgb.shape[1] * s)), max(1, round(rgb.shape[0] * s)))
        rgb = cv2.resize(rgb, size, interpolation=cv2.INTER_AREA)
    ok, buf = cv2.imencode(".jpg", cv2.cvtColor(rgb, cv2.COLOR_RGB2BGR), [cv2.IMWRITE_JPEG_QUALITY, quality])
    if not ok:
        raise RuntimeError("JPEG encoding failed")
    return buf.tobytes()


def _png(rgb: np.ndarray) -> bytes:
    ok, buf = cv2.imencode(".png", cv2.cvtColor(rgb, cv2.COLOR_RGB2BGR), [cv2.IMWRITE_PNG_COMPRESSION, 9])
    if not ok:
        raise RuntimeError("PNG encoding failed")
    return buf.tobytes()


def _data_url(data: bytes, mime: str) -> str:
    return f"data:{mime};base64,{base64.b64encode(data).decode()}"


def _decoded(png: bytes) -> np.ndarray:
    return cv2.cvtColor(cv2.imdecode(np.frombuffer(png, np.uint8), cv2.IMREAD_COLOR), cv2.COLOR_BGR2RGB)


def _crop(img: np.ndarray, centre, half: float) -> np.ndarray | None:
    """The square of ``img`` around ``centre`` (pixels) with half-side ``half``, cut at the picture's edges."""
    h, w = img.shape[:2]
    x0, y0 = int(max(0, np.floor(centre[0] - half))), int(max(0, np.floor(centre[1] - half)))
    x1, y1 = int(min(w, np.ceil(centre[0] + half))), int(min(h, np.ceil(centre[1] + half)))
    return img[y0:y1, x0:x1] if x1 - x0 >= 4 and y1 - y0 >= 4 else None


def _closeup(label: str, crop: np.ndarray, options: HtmlOptions) -> dict:
    # a small crop (a coarse print grid) enlarged by a whole factor, each of its pixels a square
    k = options.closeup_px // max(crop.shape[:2])
    if k > 1:
        crop = cv2.resize(crop, None, fx=k, fy=k, interpolation=cv2.INTER_NEAREST)
    return {"label": label, "src": _data_url(_jpeg(crop, options.closeup_px, options.jpeg_quality), "image/jpeg")}


def closeups(
    defect: dict, entries: list[dict], pictures: dict[str, bytes], photo_sides: dict[str, int], options: HtmlOptions
) -> list[dict]:
    """A part defect's close-ups: in each photo that shows it, around its circle, and on the print around its box.

    Parameters
    ----------
    defect : dict
        A part defect of validation.json (``part.defects[k]``).
    entries : list of dict
        The photos' entries (``photos``).
    pictures : dict of name to PNG bytes
        The pictures validate wrote (``{stem}_defects_photo.png``: the photo with its circles,
        reduced; ``{stem}_defects_print.png``: the photo on the print, defects outlined).
    photo_sides : dict of str to int
        Each photo's longer side, pixels, by its ``pictures`` stem (its circles' scale).
    options : HtmlOptions

    Returns
    -------
    list of dict
        ``label`` and ``src`` (a data: URL) of each close-up.
    """
    out: list[dict] = []
    x0, y0, x1, y1 = defect["bbox_mm"]
    for e in entries:
        stem = e.get("pictures")
        if Path(e["photo"]).name not in defect["photos"] or not stem:
            continue
        # the photo's own defect under the part's: the one whose box overlaps it most
        best, most = None, 0.0
        for k, d in enumerate(e.get("defects", [])):
            a0, b0, a1, b1 = d["bbox_mm"]
            overlap = max(0.0, min(x1, a1) - max(x0, a0)) * max(0.0, min(y1, b1) - max(y0, b0))
            if overlap > most:
                best, most = (k, d), overlap
        if best is None:
            continue
        k, d = best
        circled = pictures.get(f"{stem}_defects_photo.png")
        if circled is not None and stem in photo_sides and np.isfinite(d["photo_px"]).all():
            img = _decoded(circled)
            s = max(img.shape[:2]) / photo_sides[stem]
            centre = [(v + 0.5) * s - 0.5 for v in d["photo_px"]]
            crop = _crop(img, centre, max(2.0 * max(d["photo_radius_px"] * s, 12.0) + 40.0, 80.0))
            if crop is not None:
                out.append(_closeup(f"{Path(e['photo']).name}, circle {k + 1}", crop, options))
        on_print = pictures.get(f"{stem}_defects_print.png")
        ppm = (e.get("dense") or {}).get("grid_px_per_mm")
        if on_print is not None and ppm:
            img = _decoded(on_print)
            half = (max(x1 - x0, y1 - y0) / 2 + 4.0) * ppm  # the box and 4 mm around it
            crop = _crop(img, [(x0 + x1) / 2 * ppm - 0.5, (y0 + y1) / 2 * ppm - 0.5], half)
            if crop is not None:
                out.append(_closeup(f"{Path(e['photo']).name} on the print, outlined", crop, options))
    return out


def start_camera(entries: list[dict], V: np.ndarray, held: dict | None = None) -> dict:
    """Where the page's camera starts: the first posed photo's camera, its up the photo's up; else above the part.

    Parameters
    ----------
    entries : list of dict
        The photos' entries of validation.json (``pose``: ``R`` and ``camera_center_mm``, fixture frame).
    V : (#V, 3) float
        The design's vertices, mm: the page draws the part as designed.
    held : dict, optional
        validation.json's ``part_held`` (the fixture holds the part at ``R X + t``): the camera
        is taken into the design's frame, so that the part shows as the photo saw it.

    Returns
    -------
    dict
        ``position``, ``target`` (the part's box centre) and ``up``, mesh frame, mm.
    """
    lo, hi = V.min(axis=0), V.max(axis=0)
    target = ((lo + hi) / 2).tolist()
    R_held = np.asarray(held["R"], np.float64) if held else np.eye(3)
    t_held = np.asarray(held["t_mm"], np.float64) if held else np.zeros(3)
    for e in entries:
        pose = e.get("pose") or {}
        if pose.get("camera_center_mm") and pose.get("R"):
            # the photo's up, -y of the camera, is minus R's second row; both back through the holding motion
            up = R_held.T @ -np.asarray(pose["R"], np.float64)[1]
            centre = R_held.T @ (np.asarray(pose["camera_center_mm"], np.float64) - t_held)
            return {"position": centre.tolist(), "target": target, "up": up.tolist()}
    size = float(np.linalg.norm(hi - lo))
    return {"position": [target[0], target[1] - 1.5 * size, target[2] + 1.5 * size], "target": target, "up": [0, 0, 1]}


def page_data(
    report: dict, pictures: dict[str, bytes], surface: PartSurface, photo_sides: dict[str, int], options: HtmlOptions
) -> dict:
    """What the page shows, as its script reads it: the part's verdict, defects (with their surface points
    and close-ups), coverage legend, photos and start camera."""
    part = report["part"]
    entries = report["photos"]
    defects = []
    for n, d in enumerate(part.get("defects") or []):
        point = (
            surface_point(surface.X, surface.px_per_mm, d["centre_mm"], d["bbox_mm"]) if surface.X is not None else None
        )
        defects.append(
            {
                "number": n + 1,
                # (a region no photo told ink gone, or a slide, from light on: open, not failed)
                "kind": f"{_open_kind(d)} or light? (open)" if d.get("unresolved") else d["kind"],
                "area_mm2": round(float(d["area_mm2"]), 2),
                "centre_mm": [round(float(v), 2) for v in d["centre_mm"]],
                "view": d.get("view"),
                "photos": list(d["photos"]),
                "point": point,
                "closeups": closeups(d, entries, pictures, photo_sides, options),
            }
        )
    shares = part.get("coverage_print") or {}
    legend = [
        {"name": name, "colour": "#" + bytes(int(c) for c in colour).hex(), "share": shares[name]}
        for name, colour in zip(print_warp.STATE_NAMES, STATE_COLOURS, strict=True)
        if shares.get(name)
    ]
    photos = []
    for e in entries:
        stem = e.get("pictures")
        circled = pictures.get(f"{stem}_defects_photo.png") if stem else None
        photos.append(
            {
                "name": Path(e["photo"]).name,
                "verdict": e["verdict"],
                "reason": e.get("reason") or "",
                "src": None
                if circled is None
                else _data_url(_jpeg(_decoded(circled), options.photo_px, options.jpeg_quality), "image/jpeg"),
            }
        )
    job = report["design"].get("job") or {}
    return {
        "job": job.get("name") or "design",
        "verdict": part["verdict"],
        "reason": part.get("reason") or "",
        "photos_scored": part.get("photos_scored", 0),
        "tolerance_mm": report.get("tolerance_mm"),
        "max_defect_mm2": report.get("max_defect_mm2"),
        "defects": defects,
        "legend": legend,
        "photos": photos,
        "camera": start_camera(entries, surface.V, report.get("part_held")),
    }


def part_model(surface: PartSurface, coverage: np.ndarray | None, options: HtmlOptions) -> bytes:
    """The part's GLB: its print (JPEG, at most ``texture_px``) and, when measured, its coverage map (PNG)."""
    rgb = surface.print_rgb
    s = min(1.0, options.texture_px / max(rgb.shape[:2]))
    size = (max(1, round(rgb.shape[1] * s)), max(1, round(rgb.shape[0] * s)))
    texture = cv2.resize(rgb, size, interpolation=cv2.INTER_AREA) if s < 1.0 else rgb
    ok, buf = cv2.imencode(".jpg", cv2.cvtColor(texture, cv2.COLOR_RGB2BGR), [cv2.IMWRITE_JPEG_QUALITY, 90])
    layers = [("print", buf.tobytes(), "image/jpeg", True)]
    if coverage is not None:
        shown = grid_on_texture(coverage_image(coverage), surface.px_per_mm, size, surface.print_size_mm)
        layers.append(("coverage", _png(shown), "image/png", False))
    return layered_glb(surface.V, surface.F, surface.uv, layers)


def photo_sides(photos: list[Path], entries: list[dict]) -> dict[str, int]:
    """Each photo's longer side, pixels, by its pictures' stem (read from its header; unreadable: left out)."""
    from PIL import Image

    sides = {}
    for path, e in zip(photos, entries, strict=True):
        if not e.get("pictures"):
            continue
        try:
            with Image.open(path) as img:
                sides[e["pictures"]] = max(img.size)
        except (OSError, ValueError):
            continue
    return sides


def interactive_report(report: dict, pictures: dict[str, bytes], design, grid, coverage, photos: list[Path]) -> bytes:
    """qa_report.html of a validation (:func:`qa_report_html`), from what ``workbench validate`` holds.

    Parameters
    ----------
    report : dict
        validation.json's content.
    pictures : dict of name to PNG bytes
        The pictures validate writes.
    design : Design
        The design folder.
    grid : PrintGrid or None
        The print's analysis grid (None: no photo scored).
    coverage : (rows, cols) uint8 or None
        The part's coverage state per grid pixel.
    photos : list of Path
        The photos, in the report's order.
    """
    return qa_report_html(report, pictures, part_surface(design, grid), coverage, photo_sides(photos, report["photos"]))


def _viewer_file(name: str) -> str:
    return (resources.files("workbench.validate") / "viewer" / name).read_text(encoding="utf-8")


def _packed(data: bytes) -> str:
    # gzip (no time stamp: the same bytes every run), base64: the page unpacks it with the browser's
    # DecompressionStream; three.js takes a fifth of its size (2.3 MB of JavaScript, 0.47 MB packed)
    return base64.b64encode(gzip.compress(data, compresslevel=9, mtime=0)).decode()


@functools.cache
def packed_modules() -> str:
    """The page's three.js modules, packed (:func:`_packed`), by the name its import map gives each, as JSON.

    A module read from a blob: URL has no folder to resolve ``'./three.core.js'`` against: each
    relative import is renamed to the name the import map resolves.
    """
    modules = {}
    for name, path in THREE_MODULES.items():
        text = _viewer_file(f"three/{path}")
        for old, new in RELATIVE_IMPORTS.get(path, {}).items():
            if old not in text:
                raise RuntimeError(f"viewer/three/{path}: no import of {old}; the vendored three.js changed")
            text = text.replace(old, new)
        modules[name] = _packed(text.encode())
    return json.dumps(modules, indent=1)


def _script_safe(text: str) -> str:
    # inside a <script> element only "</" can end it early (and "<!--" change how it is parsed)
    return text.replace("</", "<\\/").replace("<!--", "<\\!--")


def qa_report_html(
    report: dict,
    pictures: dict[str, bytes],
    surface: PartSurface,
    coverage: np.ndarray | None,
    photo_sides: dict[str, int],
    options: HtmlOptions = HtmlOptions(),
) -> bytes:
    """qa_report.html: one self-contained page, with no request to any network or file.

    Parameters
    ----------
    report : dict
        validation.json's content.
    pictures : dict of name to PNG bytes
        The pictures validate writes, by file name.
    surface : PartSurface
        The part, its print and its print grid's surface points.
    coverage : (rows, cols) uint8 or None
        The part's coverage state per grid pixel (:mod:`workbench.validate.print_warp`'s states);
        None: no photo was scored.
    photo_sides : dict of str to int
        Each photo's longer side, pixels, by its pictures' stem.
    options : HtmlOptions

    Returns
    -------
    bytes
        UTF-8 HTML; the same bytes for the same inputs (no date, no random name).
    """
    data = page_data(report, pictures, surface, photo_sides, options)
    glb = _packed(part_model(surface, coverage, options))
    title = f"QA report: {data['job']}"
    page = _viewer_file("qa_report.html")
    parts = {
        "{{title}}": html.escape(title),
        "{{style}}": _viewer_file("qa_report.css"),
        "{{modules}}": packed_modules(),
        "{{data}}": _script_safe(json.dumps(data, indent=None, separators=(",", ":"))),
        "{{glb}}": glb,
        "{{script}}": _script_safe(_viewer_file("qa_report.js")),
    }
    # one pass: what a placeholder brings in is not searched for placeholders
    return re.sub(r"\{\{\w+\}\}", lambda m: parts[m.group(0)], page).encode("utf-8")


def _open_kind(d: dict) -> str:
    """What an open region may be besides light: a slide (``shift``) or ink gone (``missing``)."""
    return "shift" if d["kind"] == "shift" else "missing"
