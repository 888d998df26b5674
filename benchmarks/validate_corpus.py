"""The validate corpus: false reject and escape rates of ``workbench validate`` on real parts and artwork.

    python benchmarks/validate_corpus.py [--subset fast|bench|full] [--renderer workbench|mitsuba|both]
                                         [--jobs N] [--out DIR] [--parts a,b] [--limit N]
                                         [--perfect-only | --defects-only] [--sizes WxH,...]
                                         [--render-root CHECKOUT] [--spp N]

Designs every part of ``tests/data/validate_corpus/`` (cached in ``OUT/designs``; regenerate the
parts with ``tests/data/make_validate_corpus.py``), renders photos over a grid of conditions,
perfect and with one defect each (``workbench render --defect``: bubbles of several sizes and
slides, ink dropouts, scratches), matte and glossy, blur, noise, JPEG quality, lens distortion
known to the profile, 2000 x 1500 to 6000 x 4000 px, by ``workbench render`` and, with
``--renderer mitsuba|both``, by Mitsuba 3 (``workbench render --renderer mitsuba --spp N``, when
the render command of ``--render-root`` accepts it). Each photo is validated on its own
(``workbench validate DESIGN PHOTO --camera PHOTO.json --view VIEW --tolerance-mm 0.2``, the
default max defect) and compared with the truth in ``PHOTO.json``: a true defect is *found*
when a reported defect lies within 1 mm of its centre with its area within 25 % and the photo
FAILs.

Writes ``OUT/validate_corpus.json`` (every photo: condition, verdict, reason, defects found
against the truth, the detection limit validate states if its report has one) and
``OUT/validate_corpus.md`` (the table and the rates: false rejects on perfect photos, escapes
per defect kind and size). Photos and reports are cached per condition: a second run only
re-validates (``--revalidate``) or does nothing. Progress is printed per photo.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import math
import os
import subprocess
import sys
import time
from concurrent.futures import ThreadPoolExecutor
from dataclasses import asdict, dataclass, field
from pathlib import Path

import cv2
import numpy as np

ROOT = Path(__file__).resolve().parents[1]
CORPUS = ROOT / "tests" / "data" / "validate_corpus"
TOLERANCE_MM = 0.2
LOCATE_MM = 1.0  # a found defect within this distance of the true centre ...
AREA_SHARE = 0.25  # ... and with its area within this share of the true one

# photo sizes (px) and the looks of a photo: render options beyond the camera
SIZES = ("2000x1500", "3000x2250", "4000x3000", "6000x4000")
LOOKS = {
    "matte": [],
    "realistic": ["--realistic"],
    "glossy": ["--realistic", "--gloss", "0.5"],
    "soft": ["--blur-px", "1.6", "--noise", "4", "--jpeg-quality", "80", "--shading"],
    "lens": ["--realistic", "--distortion=-0.1,0,0,0,0"],
    "glossy-lens": ["--realistic", "--gloss", "0.4", "--distortion=-0.1,0,0,0,0", "--jpeg-quality", "85"],
}


def look_finish(look: str) -> str:
    """The film's finish a look renders (``validate --finish``): glossy where the renderer is given a gloss."""
    return "glossy" if "--gloss" in LOOKS[look] else "matte"


# defects: (name, kind, size) -> what the renderer is told, given a centre (x, y) in print mm
DEFECTS = {
    "bubble-12mm-1.0": ("bubble", lambda x, y: f"bubble:{x:.2f},{y:.2f},6,1"),
    "bubble-6mm-0.5": ("bubble", lambda x, y: f"bubble:{x:.2f},{y:.2f},3,0.5"),
    "bubble-4mm-0.3": ("bubble", lambda x, y: f"bubble:{x:.2f},{y:.2f},2,0.3"),
    "dropout-10mm2": ("dropout", lambda x, y: f"dropout:{x:.2f},{y:.2f},1.784"),
    "dropout-5mm2": ("dropout", lambda x, y: f"dropout:{x:.2f},{y:.2f},1.262"),
    "scratch-20mm": ("scratch", lambda x, y: f"scratch:{x - 10:.2f},{y:.2f},{x + 10:.2f},{y:.2f},0.5"),
}
# each defect's footprint (print mm: half extents x, y), to keep it inside its view's region
EXTENT = {
    "bubble-12mm-1.0": (7.0, 7.0),
    "bubble-6mm-0.5": (3.5, 3.5),
    "bubble-4mm-0.3": (2.5, 2.5),
    "dropout-10mm2": (1.8, 1.8),
    "dropout-5mm2": (1.3, 1.3),
    "scratch-20mm": (10.3, 0.3),
}


@dataclass
class Photo:
    """One photo of the corpus: its part, view, condition and renderer."""

    part: str
    view: str
    size: str
    look: str
    renderer: str
    defect: str | None = None  # a key of DEFECTS
    spec: str | None = None  # the --defect string
    orbit: tuple = ()
    seed: int = 0
    result: dict = field(default_factory=dict)

    @property
    def id(self) -> str:
        what = self.defect or "perfect"
        return f"{self.part}-{self.view}-{what}-{self.look}-{self.size}-{self.renderer}"


# ---------------------------------------------------------------------------------------------- designs


def design_part(name: str, out: Path, env: dict) -> Path:
    """``workbench design`` of one corpus part, cached by the job file's sha256."""
    job = CORPUS / name / "job.toml"
    d = out / "designs" / name
    sha = hashlib.sha256(job.read_bytes()).hexdigest()
    if (d / "design.json").is_file() and json.loads((d / "design.json").read_text())["job"].get("sha256") == sha:
        return d
    cmd = [sys.executable, "-m", "workbench", "design", str(job), "--out", str(d), "-q"]
    subprocess.run(cmd, check=True, env=env, capture_output=True, timeout=1200)
    return d


def print_px_per_mm(design: Path) -> float:
    return json.loads((design / "design.json").read_text())["print"]["dpi"] / 25.4


def defect_centre(design: Path, view: str, defect: str) -> tuple[float, float] | None:
    """Where on the print (mm) the defect goes: inside ``view``'s own region, where it shows best.

    A bubble slides the print: it shows only over texture, so it goes where the print's
    gradient energy over its footprint is highest. A dropout or a scratch uncovers the white
    film: it goes where the ink is darkest over its footprint. Both keep clear of the region's
    border (the footprint plus 3 mm) and of the outline, and go where the view sees the
    surface within 60° of head-on over the footprint plus 1 mm (near a fold or the silhouette
    a photo a few degrees off the view sees the surface at a grazing angle or not at all: what
    such a photo cannot see is no test of validate). None when nowhere fits.
    """
    info = json.loads((design / "design.json").read_text())
    names = [v["name"] for v in info["views"]]
    owner = cv2.imread(str(design / "owner.png"), cv2.IMREAD_UNCHANGED).astype(np.int32) - 1
    img = cv2.imread(str(design / "print.png"), cv2.IMREAD_UNCHANGED)
    alpha = img[..., 3] > 0 if img.shape[2] == 4 else np.ones(img.shape[:2], bool)
    rgb = img[..., :3].astype(np.float32)
    ppm = info["print"]["dpi"] / 25.4
    hx, hy = EXTENT[defect]
    region = ((owner == names.index(view)) & alpha).astype(np.uint8)
    kx, ky = 2 * int(math.ceil((hx + 3) * ppm)) + 1, 2 * int(math.ceil((hy + 3) * ppm)) + 1
    inside = cv2.erode(region, cv2.getStructuringElement(cv2.MORPH_RECT, (kx, ky)), borderValue=0) > 0
    fx_, fy_ = 2 * int(math.ceil((hx + 1) * ppm)) + 1, 2 * int(math.ceil((hy + 1) * ppm)) + 1
    frontal = cv2.erode(
        facing_view(design, view, rgb.shape[:2]).astype(np.uint8),
        cv2.getStructuringElement(cv2.MORPH_RECT, (fx_, fy_)),
        borderValue=0,
    )
    inside &= frontal > 0
    if not inside.any():
        return None
    fx, fy = 2 * int(math.ceil(hx * ppm)) + 1, 2 * int(math.ceil(hy * ppm)) + 1
    if DEFECTS[defect][0] == "bubble":
        grey = cv2.cvtColor(rgb, cv2.COLOR_BGR2GRAY)
        gx, gy = cv2.Sobel(grey, cv2.CV_32F, 1, 0), cv2.Sobel(grey, cv2.CV_32F, 0, 1)
        # the smaller eigenvalue of the structure tensor over the footprint: texture in both directions
        sxx, syy, sxy = (cv2.boxFilter(a, -1, (fx, fy)) for a in (gx * gx, gy * gy, gx * gy))
        score = 0.5 * (sxx + syy) - np.sqrt(0.25 * (sxx - syy) ** 2 + sxy**2)
    else:
        score = cv2.boxFilter(765.0 - rgb.sum(axis=2), -1, (fx, fy))
    score = np.where(inside, score, -np.inf)
    i, j = np.unravel_index(int(np.argmax(score)), score.shape)
    return (j + 0.5) / ppm, (i + 0.5) / ppm


def facing_view(design: Path, view: str, shape: tuple, max_deg: float = 60.0) -> np.ndarray:
    """Print pixels whose surface the view sees within ``max_deg`` of head-on; (rows, cols) bool at the print's size."""
    from workbench.design_dir import Design
    from workbench.validate.print_warp import print_grid

    d = Design(design)
    p = d.info["print"]
    grid = print_grid(d.V, d.F, d.flat, p["height_mm"], d.rgb, p["dpi"], d.owner)
    cam = d.view_camera(view)
    on = grid.face >= 0
    tri = d.V[d.F[grid.face[on]]]
    n = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    n /= np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-12)
    to_cam = cam.center - grid.X[on]
    to_cam /= np.maximum(np.linalg.norm(to_cam, axis=1, keepdims=True), 1e-12)
    ok = np.zeros(grid.face.shape, np.uint8)
    ok[on] = (n * to_cam).sum(axis=1) >= math.cos(math.radians(max_deg))
    return cv2.resize(ok, (shape[1], shape[0]), interpolation=cv2.INTER_NEAREST) > 0


def view_direction(part: str, view: str) -> tuple[float, float]:
    """The view's azimuth and elevation (degrees) from the corpus index."""
    index = json.loads((CORPUS / "corpus.json").read_text())
    p = next(p for p in index["parts"] if p["name"] == part)
    v = next(v for v in p["views"] if v["name"] == view)
    return float(v["az_deg"]), float(v["el_deg"])


def photo_orbit(design: Path, az: float, el: float, size: str, k: int) -> tuple[float, float, float, float]:
    """An orbit (az, el, distance mm, fov deg) near the view's direction that frames the fixture plate.

    The photo is taken 4 to 8 degrees off the view's direction (the photographer does not
    stand where the designer's camera did), from the distance at which the fixture plate's
    longer side fills the image's height with 5 % to spare.
    """
    fx = json.loads((design / "fixture.json").read_text())
    P = np.asarray(fx["charuco_corners"]["mesh_mm"], dtype=np.float64)
    sq = float(fx["square_mm"])
    r = 0.5 * float(np.ptp(P[:, :2], axis=0).max()) + sq
    w, h = (int(v) for v in size.split("x"))
    fov = 40.0
    tan_v = math.tan(math.radians(fov / 2)) * h / w
    dist = 1.05 * r / tan_v
    off = (4.0, 6.0, 8.0, 5.0)[k % 4]
    az2 = az + (off if k % 2 == 0 else -off)
    el2 = min(el - 6.0, 84.0) if el >= 89 else el + (3.0 if k % 2 else -3.0)
    return az2, el2, dist, fov


# ---------------------------------------------------------------------------------------------- the grid


def parts_and_views() -> list[tuple[str, str]]:
    index = json.loads((CORPUS / "corpus.json").read_text())
    return [(p["name"], v["name"]) for p in index["parts"] for v in p["views"]]


def grid(subset: str, renderers: list[str]) -> list[Photo]:
    """The photos of a subset, deterministic.

    ``full``: per view of every part, one perfect photo per look and one photo per defect,
    sizes and looks cycled so that every size meets every look and every defect kind.
    ``fast``: a handful at 2000 x 1500 for the test suite. ``bench``: the issue's acceptance
    cases at 12 Mpx (4000 x 3000): perfect photos of 8 parts, and the 1 mm bubble of 12 mm, the
    0.5 mm bubble of 6 mm, a 10 mm² dropout and a 20 mm scratch on a checker and on a photograph.
    """
    photos: list[Photo] = []
    looks = list(LOOKS)
    if subset == "fast":
        chosen = [
            ("lilium", "top", None, "realistic"),
            ("face", "top", None, "glossy"),
            ("arm", "top", None, "lens"),
            ("bunny", "top", "bubble-12mm-1.0", "realistic"),
            ("fertility", "top", "dropout-10mm2", "glossy"),
            # (fine text: the lion's side leaves no room within 60° of head-on for a 20 mm line)
            ("camel_b", "top", "scratch-20mm", "lens"),
            # (a scratch across a glossy sheen on a checker: found, 10.5 mm² of 10.2 at 0.02 mm)
            ("bunny", "top", "scratch-20mm", "glossy-lens"),
        ]
        for n, (part, view, defect, look) in enumerate(chosen):
            # Mitsuba's path tracing costs a minute a photo here: two of them (a perfect part, a bubble)
            both = (part, defect) in (("lilium", None), ("bunny", "bubble-12mm-1.0"))
            for r in renderers if both else [r for r in renderers if r == "workbench"]:
                photos.append(Photo(part, view, "2000x1500", look, r, defect, seed=n))
        return photos
    if subset == "bench":
        perfect = [
            ("face", "top", "glossy-lens"),
            ("lilium", "top", "realistic"),
            ("camelhead", "top", "glossy"),
            ("camel_b", "top", "lens"),
            ("cow", "top", "realistic"),
            ("elephant", "side1", "glossy"),
            ("fandisk", "top", "lens"),
            ("cheburashka", "top", "realistic"),
        ]
        chosen = [(part, view, None, look) for part, view, look in perfect]
        for part, look in (("bunny", "glossy-lens"), ("cow", "realistic")):
            for defect in ("bubble-12mm-1.0", "bubble-6mm-0.5", "dropout-10mm2", "scratch-20mm"):
                chosen.append((part, "top", defect, look))
        for n, (part, view, defect, look) in enumerate(chosen):
            for r in renderers:
                photos.append(Photo(part, view, "4000x3000", look, r, defect, seed=100 + n))
        return photos
    n = 0
    for v, (part, view) in enumerate(parts_and_views()):
        # the v-th view shifts the cycles by v: each look and defect meets every size across views
        for k, look in enumerate(looks):
            size = SIZES[(k + v) % len(SIZES)]
            for r in renderers:
                photos.append(Photo(part, view, size, look, r, None, seed=n))
            n += 1
        for k, defect in enumerate(DEFECTS):
            size = SIZES[(k + v + 1) % len(SIZES)]
            look = looks[(k + v) % len(looks)]
            for r in renderers:
                photos.append(Photo(part, view, size, look, r, defect, seed=n))
            n += 1
    return photos


# ---------------------------------------------------------------------------------------------- running


def accepts_renderer(env: dict) -> bool:
    """Whether the render command of this environment takes ``--renderer``."""
    cmd = [sys.executable, "-m", "workbench", "render", "--help"]
    out = subprocess.run(cmd, env=env, cwd=env["PYTHONPATH"], capture_output=True, text=True, timeout=120)
    return "--renderer" in out.stdout


def find_detection_limit(entry: dict) -> dict:
    """Whatever validate states about its detection limit in a photo's entry; {} if nothing.

    Every value under a key named ``detection...`` (at any depth), flattened to dotted key
    paths (``dense.detection_limit.min_area_mm2``): the runner reads what validate writes and
    invents nothing.
    """
    found = {}

    def leaves(obj, path):
        if isinstance(obj, dict):
            for k, v in obj.items():
                leaves(v, f"{path}.{k}")
        else:
            found[path] = obj

    def walk(obj, path):
        if isinstance(obj, dict):
            for k, v in obj.items():
                if "detection" in k.lower():
                    leaves(v, f"{path}{k}")
                else:
                    walk(v, f"{path}{k}.")

    walk(entry, "")
    return found


def footprint(t: dict, shape: tuple, px_per_mm: float) -> np.ndarray:
    """A true defect's pixels on the print's analysis grid: a disc (bubble, dropout) or a stroke (scratch)."""
    mask = np.zeros(shape, np.uint8)
    s = 16  # cv2's sub-pixel drawing: coordinates in 1/16 px
    if t["kind"] == "scratch":
        a = np.rint((np.asarray(t["from_mm"]) * px_per_mm - 0.5) * s).astype(int)
        b = np.rint((np.asarray(t["to_mm"]) * px_per_mm - 0.5) * s).astype(int)
        cv2.line(mask, tuple(a), tuple(b), 1, max(1, int(round(t["width_mm"] * px_per_mm))), cv2.LINE_8, 4)
    else:
        c = np.rint((np.asarray(t["centre_mm"]) * px_per_mm - 0.5) * s).astype(int)
        cv2.circle(mask, tuple(c), int(round(t["radius_mm"] * px_per_mm * s)), 1, -1, cv2.LINE_8, 4)
    return mask.astype(bool)


def stated_limit(truth: list[dict], vdir: Path, report: dict, index: int = 0) -> list[dict] | None:
    """Per true defect, whether validate states it can find it there (its ``detection.npz`` maps).

    None when validate wrote no maps (an earlier validate, or a photo it could not score).
    The rule is validate's own (:func:`workbench.validate.detection.above_limit`): missing ink
    over at least 75 % of its footprint, a slide over at least half of it, what is found there
    larger than the verdict's area, and the defect at least ``min_area_mm2``.
    """
    from workbench.validate import detection

    info = report.get("detection")
    entry = report["photos"][index]
    if not info or not (vdir / info["file"]).is_file() or "dense" not in entry:
        return None
    maps = np.load(vdir / info["file"])
    if f"photo{index}_dropout" not in maps:
        return None
    limit, drop = maps[f"photo{index}_shift_limit_um"], maps[f"photo{index}_dropout"]
    scratch = maps[f"photo{index}_scratch"] if f"photo{index}_scratch" in maps else None
    ppm = float(entry["dense"]["grid_px_per_mm"])
    min_area = float(entry["dense"]["detection_limit"]["min_area_mm2"])
    out = []
    for t in truth:
        fp = footprint(t, limit.shape, ppm)
        slide = float(np.hypot(*t["shift_mm"])) if "shift_mm" in t else 0.0
        above, share = detection.above_limit(
            t["kind"], fp, limit, drop, slide, scratch, t["area_mm2"], float(report.get("max_defect_mm2", 4.0))
        )
        above = above and t["area_mm2"] >= min_area
        rec = {"above": bool(above), "share_found": round(share, 3)}
        if t["kind"] == "bubble" and fp.any():
            # the part of a slide the photo measures at all (a face it sees at a grazing angle,
            # or the band along what it sees, measures none): validate reports what it sees
            seen = fp & (limit < detection.NONE_UM)
            rec["seen_share"] = round(float(seen.sum() / fp.sum()), 3)
            if seen.any():
                ii, jj = np.nonzero(seen)
                rec["seen_centre_mm"] = [float((jj.mean() + 0.5) / ppm), float((ii.mean() + 0.5) / ppm)]
                rec["seen_area_mm2"] = float(t["area_mm2"] * seen.sum() / fp.sum())
        out.append(rec)
    return out


def below_stated_limit(truth: list[dict], limit: dict, stated: list[dict] | None = None) -> bool:
    """Whether a true defect is under the detection limit validate states.

    From validate's maps where it writes them (``stated``: :func:`stated_limit`); else from
    the figures it states (keys ending in ``min_area_mm2`` and ``min_shift_mm``). False when
    validate states none.
    """
    if stated is not None:
        return not all(s["above"] for s in stated)
    areas = [v for k, v in limit.items() if k.endswith("min_area_mm2") and isinstance(v, int | float)]
    shifts = [v for k, v in limit.items() if k.endswith("min_shift_mm") and isinstance(v, int | float)]
    for t in truth:
        if areas and t["area_mm2"] < max(areas):
            return True
        if shifts and "shift_mm" in t and float(np.hypot(*t["shift_mm"])) < max(shifts):
            return True
    return False


def brief(d: dict) -> dict:
    """What the table shows of a reported defect."""
    return {k: d.get(k) for k in ("kind", "area_mm2", "centre_mm", "peak_mm", "view")}


def match(truth: list[dict], found: list[dict], stated: list[dict] | None = None) -> list[dict]:
    """Each true defect against the found defect nearest its centre.

    A slide (bubble) is judged against the part of it the photo measures (``stated``'s
    ``seen_centre_mm`` and ``seen_area_mm2``, where it sees under all of it); the distance to
    its whole centre and the error against its whole area are kept beside.
    """
    out = []
    for k, t in enumerate(truth):
        s = stated[k] if stated is not None and k < len(stated) else {}
        whole = np.asarray(t["centre_mm"], dtype=np.float64)
        c = np.asarray(s.get("seen_centre_mm", t["centre_mm"]), dtype=np.float64)
        area = float(s.get("seen_area_mm2", t["area_mm2"]))
        if not found:
            out.append({"truth": t, "found": None, "distance_mm": None, "area_error": None, "located": False})
            continue
        f = min(found, key=lambda d: np.linalg.norm(np.asarray(d["centre_mm"]) - c))
        dist = float(np.linalg.norm(np.asarray(f["centre_mm"]) - c))
        err = float(f["area_mm2"] / area - 1)
        ok = dist <= LOCATE_MM and abs(err) <= AREA_SHARE
        rec = {"truth": t, "found": brief(f), "distance_mm": dist, "area_error": err, "located": ok}
        if "seen_centre_mm" in s:
            rec["seen_share"] = s["seen_share"]
            rec["distance_to_whole_mm"] = float(np.linalg.norm(np.asarray(f["centre_mm"]) - whole))
            rec["area_error_whole"] = float(f["area_mm2"] / t["area_mm2"] - 1)
        out.append(rec)
    return out


def false_defects(truth: list[dict], found: list[dict], max_defect_mm2: float, stated: list[dict] | None = None) -> int:
    """Reported defects over the verdict's area that are none of the true ones: more than 1 mm away
    from each one's centre, and from the centre of the part of it the photo measures (``stated``)."""
    centres = [np.asarray(t["centre_mm"], dtype=np.float64) for t in truth]
    centres += [np.asarray(s["seen_centre_mm"], dtype=np.float64) for s in stated or [] if "seen_centre_mm" in s]
    n = 0
    for f in found:
        if f["area_mm2"] <= max_defect_mm2:
            continue
        c = np.asarray(f["centre_mm"], dtype=np.float64)
        n += not any(np.linalg.norm(t - c) <= LOCATE_MM for t in centres)
    return n


def outcome(photo: Photo, entry: dict, truth: list[dict], stated: list[dict] | None = None) -> str:
    """``pass`` / ``incomplete`` / ``false reject`` / ``invalid`` for a perfect photo; ``found`` / ``open`` / ...

    A defect photo that is INCOMPLETE with the defect located among its open regions (ink gone
    or light: the photo cannot tell) is ``open``; one that is INCOMPLETE otherwise counts as a PASS.

    A defect photo that PASSes is an ``escape`` when validate states it finds the defect
    there, ``below stated limit`` otherwise; one that FAILs without locating it is ``fail, not
    located`` (``fail, not located, below stated limit`` when validate states it cannot); one
    that is INVALID is ``invalid`` (``invalid, above stated limit`` when validate states it finds
    the defect there: it was not found, and the part was not failed).
    """
    v = entry.get("verdict")
    if photo.defect is None:
        return {"INVALID": "invalid", "PASS": "pass", "INCOMPLETE": "incomplete"}.get(v, "false reject")
    below = below_stated_limit(truth, find_detection_limit(entry), stated)
    still = [d for d in entry.get("defects", []) if d.get("unresolved")]
    if v == "INCOMPLETE" and still and all(m["located"] for m in match(truth, still, stated)):
        # (located, as a region the photo cannot tell ink gone from light on: the part's other photos decide)
        return "open"
    if v == "INVALID":
        # a defect the photo states it finds there, not found: INVALID says "not judged", not FAIL
        return "invalid" if below or stated is None else "invalid, above stated limit"
    if v in ("PASS", "INCOMPLETE"):
        return "below stated limit" if below else "escape"
    if all(m["located"] for m in match(truth, entry.get("defects", []), stated)):
        return "found"
    return "fail, not located, below stated limit" if below else "fail, not located"


def run_photo(photo: Photo, out: Path, designs: dict, env_validate: dict, env_render: dict, args) -> Photo:
    design = designs[photo.part]
    folder = out / "photos" / photo.id
    folder.mkdir(parents=True, exist_ok=True)
    ext = ".jpg" if any("jpeg" in a or a == "--realistic" for a in LOOKS[photo.look]) else ".png"
    img = folder / f"photo{ext}"
    truth_file = img.with_suffix(".json")
    t0 = time.perf_counter()
    if photo.defect is not None:
        centre = defect_centre(design, photo.view, photo.defect)
        if centre is None:
            photo.result = {"outcome": "skipped", "why": f"no room in view {photo.view!r} for {photo.defect}"}
            return photo
        photo.spec = DEFECTS[photo.defect][1](*centre)
    az, el = view_direction(photo.part, photo.view)
    photo.orbit = photo_orbit(design, az, el, photo.size, photo.seed)
    w, h = (int(v) for v in photo.size.split("x"))
    render = [sys.executable, "-m", "workbench", "render", str(design)]
    render += [
        f"--orbit={photo.orbit[0]:g},{photo.orbit[1]:g},{photo.orbit[2]:.1f}",
        "--fov-deg",
        f"{photo.orbit[3]:g}",
    ]
    render += ["--size", photo.size, *LOOKS[photo.look], "--seed", str(photo.seed)]
    if photo.renderer == "workbench":
        # 2 x 2 samples up to 12 Mpx; beyond, one (the buffers of 24 Mpx at 2 x 2 take 7.7 GB)
        render += ["--supersample", "2" if w * h <= 12_000_000 else "1"]
    if photo.spec:
        render += ["--defect", photo.spec]
    if photo.renderer == "mitsuba":
        render += ["--renderer", "mitsuba", "--spp", str(args.spp)]
    render += ["-o", str(img), "-q"]
    stamp = folder / "render.cmd"
    # the command and the design it renders (a design made again from a changed job differs)
    key = json.dumps([hashlib.sha256((design / "design.json").read_bytes()).hexdigest(), *render[3:]])
    if args.report_only:
        if not (folder / args.validation / "validation.json").is_file():
            photo.result = {"outcome": "not run", "why": "--report-only: no validation.json yet"}
            return photo
    elif not (img.is_file() and truth_file.is_file() and stamp.is_file() and stamp.read_text() == key):
        # in the render checkout: ``python -m`` puts the working directory first on the path
        r = subprocess.run(
            render, env=env_render, cwd=env_render["PYTHONPATH"], capture_output=True, text=True, timeout=3600
        )
        if r.returncode != 0:
            photo.result = {"outcome": "render failed", "why": r.stderr.strip().splitlines()[-1:]}
            return photo
        stamp.write_text(key)
        for old in folder.glob("validation*/validation.json"):  # of an earlier photo
            old.unlink()
    t1 = time.perf_counter()
    vdir = folder / args.validation
    validate = [sys.executable, "-m", "workbench", "validate", str(design), str(img), "--camera", str(truth_file)]
    validate += ["--view", photo.view, "--tolerance-mm", str(TOLERANCE_MM), "--jobs", "1", "--out", str(vdir), "-q"]
    validate += ["--finish", look_finish(photo.look) if args.finish == "look" else args.finish]
    if not args.report_only and (args.revalidate or not (vdir / "validation.json").is_file()):
        r = subprocess.run(validate, env=env_validate, capture_output=True, text=True, timeout=3600)
        if r.returncode != 0:
            photo.result = {"outcome": "validate failed", "why": r.stderr.strip().splitlines()[-1:]}
            return photo
    t2 = time.perf_counter()
    report = json.loads((vdir / "validation.json").read_text())
    entry = report["photos"][0]
    truth = json.loads(truth_file.read_text()).get("defects", [])
    stated = stated_limit(truth, vdir, report) if truth else None
    photo.result = {
        "outcome": outcome(photo, entry, truth, stated),
        "stated": stated,
        "verdict": entry.get("verdict"),
        "reason": entry.get("reason"),
        # (the part of one photo: INCOMPLETE where the photo passes and covers too little of a film)
        "part_verdict": (report.get("part") or {}).get("verdict"),
        "coverage": [
            {c: (f.get(c) or {}).get("share") for c in ("slide", "ink_gone", "scratch")}
            for f in ((report.get("part") or {}).get("coverage") or {}).get("films", [])
        ],
        "defects_found": [
            {k: d.get(k) for k in ("kind", "area_mm2", "centre_mm", "peak_mm", "view")}
            for d in entry.get("defects", [])
        ],
        "truth": truth,
        "match": match(truth, entry.get("defects", []), stated),
        "false_defects": false_defects(truth, entry.get("defects", []), report.get("max_defect_mm2", 4.0), stated),
        "detection_limit": find_detection_limit(entry),
        "misregistration_p95_mm": (entry.get("misregistration_mm") or {}).get("p95"),
        "tiles": entry.get("tiles_matched", entry.get("tiles")),
        "ssim": entry.get("ssim"),
        "render_s": round(t1 - t0, 2),
        "validate_s": round(t2 - t1, 2),
        "render_cmd": " ".join(render[1:]),
        "validate_cmd": " ".join(validate[1:]),
    }
    return photo


# ---------------------------------------------------------------------------------------------- the table


def rates(photos: list[Photo]) -> dict:
    """False reject rate on perfect photos, escape rate per defect and renderer, found rate."""
    out: dict = {"perfect": {}, "defects": {}}
    for r in sorted({p.renderer for p in photos}):
        perf = [p for p in photos if p.renderer == r and p.defect is None and p.result.get("outcome") in OUTCOMES]
        fr = sum(p.result["outcome"] == "false reject" for p in perf)
        inv = sum(p.result["outcome"] == "invalid" for p in perf)
        inc = sum(p.result["outcome"] == "incomplete" for p in perf)
        # whatever the verdict's first reason, how many perfect photos report a defect over the verdict's area
        fd = sum(p.result["false_defects"] > 0 for p in perf)
        out["perfect"][r] = {
            "photos": len(perf), "false_rejects": fr, "incomplete": inc, "invalid": inv, "with_false_defects": fd,
        }  # fmt: skip
        for d in DEFECTS:
            dp = [p for p in photos if p.renderer == r and p.defect == d and p.result.get("outcome") in OUTCOMES]
            if not dp:
                continue
            out["defects"].setdefault(d, {})[r] = {
                "photos": len(dp),
                "found": sum(p.result["outcome"] == "found" for p in dp),
                "open": sum(p.result["outcome"] == "open" for p in dp),
                "fail_not_located": sum(p.result["outcome"] == "fail, not located" for p in dp),
                "fail_not_located_below": sum(
                    p.result["outcome"] == "fail, not located, below stated limit" for p in dp
                ),
                "escapes": sum(p.result["outcome"] == "escape" for p in dp),
                "below_stated_limit": sum(p.result["outcome"] == "below stated limit" for p in dp),
                "found_with_false_defects": sum(
                    p.result["outcome"] == "found" and p.result["false_defects"] > 0 for p in dp
                ),
                "invalid": sum(p.result["outcome"] == "invalid" for p in dp),
                "invalid_above": sum(p.result["outcome"] == "invalid, above stated limit" for p in dp),
            }
    return out


OUTCOMES = (
    "pass",
    "incomplete",
    "false reject",
    "open",
    "invalid",
    "found",
    "fail, not located",
    "fail, not located, below stated limit",
    "escape",
    "below stated limit",
    "invalid, above stated limit",
)


def pct(a: int, b: int) -> str:
    return f"{a}/{b} ({100 * a / b:.0f} %)" if b else "-"


def markdown(photos: list[Photo], summary: dict, command: str) -> str:
    lines = [
        "# validate corpus",
        "",
        f"`{command}`; tolerance {TOLERANCE_MM} mm, default max defect; a defect is found when a reported "
        f"one lies within {LOCATE_MM} mm of its centre with its area within {100 * AREA_SHARE:.0f} % and the photo "
        "FAILs.",
        "",
        "## Rates",
        "",
        "| renderer | perfect photos | false rejects | INCOMPLETE (open regions) | with a defect > max reported "
        "| invalid |",
        "|---|---:|---:|---:|---:|---:|",
    ]
    for r, s in summary["perfect"].items():
        lines.append(
            f"| {r} | {s['photos']} | {pct(s['false_rejects'], s['photos'])} | {s.get('incomplete', 0)} | "
            f"{pct(s['with_false_defects'], s['photos'])} | {s['invalid']} |"
        )
    lines += [
        "",
        "| defect | renderer | photos | found | open (located, not told from light) | of which with false defects "
        "beside it | FAIL, not located (of which below the stated limit) | escapes (PASS above the stated limit) | "
        "PASS below the stated limit | invalid |",
        "|---|---|---:|---:|---:|---:|---:|---:|---:|---:|",
    ]
    for d, per in summary["defects"].items():
        for r, s in per.items():
            lines.append(
                f"| {d} | {r} | {s['photos']} | {pct(s['found'], s['photos'])} | {s.get('open', 0)} | "
                f"{s['found_with_false_defects']} | "
                f"{s['fail_not_located'] + s['fail_not_located_below']} ({s['fail_not_located_below']}) | "
                f"{pct(s['escapes'], s['photos'])} | {s['below_stated_limit']} | "
                f"{s['invalid'] + s['invalid_above']} ({s['invalid_above']}) |"
            )
    lines += ["", "## The detection limit validate states, per photo size", ""]
    lines += stated_limits(photos)
    lines += ["", "## Why photos get the wrong verdict", ""]
    lines += ["| reason (figures as #) | perfect photos | defect photos |", "|---|---:|---:|"]
    for reason, (n_perfect, n_defect) in wrong_verdict_reasons(photos).items():
        lines.append(f"| {reason} | {n_perfect} | {n_defect} |")
    lines += [
        "",
        "## Photos",
        "",
        "| photo | artwork | verdict | outcome | found (kind, area mm², centre mm) | truth | error | "
        "detection limit | reason |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    art = artwork_of()
    for p in photos:
        res = p.result
        found = "; ".join(
            f"{d['kind']} {d['area_mm2']:.1f} ({d['centre_mm'][0]:.1f}, {d['centre_mm'][1]:.1f})"
            for d in res.get("defects_found", [])[:4]
        )
        if len(res.get("defects_found", [])) > 4:
            found += f"; ... ({len(res['defects_found'])})"
        truth = "; ".join(
            f"{t['kind']} {t['area_mm2']:.1f} ({t['centre_mm'][0]:.1f}, {t['centre_mm'][1]:.1f})"
            for t in res.get("truth", [])
        )
        err = "; ".join(
            f"{m['distance_mm']:.2f} mm, {100 * m['area_error']:+.0f} %" if m["found"] else "none"
            for m in res.get("match", [])
        )
        limit = json.dumps(res.get("detection_limit")) if res.get("detection_limit") else ""
        reason = res.get("reason") or res.get("why") or ""
        reason = ("; ".join(map(str, reason)) if isinstance(reason, list) else str(reason)).replace("|", "/")
        lines.append(
            f"| {p.id} | {art.get((p.part, p.view), '')} | {res.get('verdict', '')} | {res.get('outcome', '')} | "
            f"{found} | {truth} | {err} | {limit} | {reason} |"
        )
    return "\n".join(lines) + "\n"


def stated_limits(photos: list[Photo]) -> list[str]:
    """Markdown rows: per renderer and photo size, the medians of what validate states it can find."""
    keys = (
        ("dense.detection_limit.min_area_mm2", "smallest defect mm²", "{:.2f}"),
        ("dense.detection_limit.min_shift_mm_median", "smallest slide found mm (median over the print)", "{:.3f}"),
        ("dense.detection_limit.shift_found_share", "share where a slide is found", "{:.0%}"),
        ("dense.detection_limit.dropout_found_share_of_inked", "share of the inked print: ink gone found", "{:.0%}"),
        ("dense.detection_limit.scratch_found_share", "share where a scratch is found", "{:.0%}"),
    )
    rows = [
        "| renderer | photo size | photos | " + " | ".join(k[1] for k in keys) + " |",
        "|---|---|---:|" + "---:|" * len(keys),
    ]
    for r in sorted({p.renderer for p in photos}):
        for size in SIZES:
            got = [p.result.get("detection_limit") or {} for p in photos if p.renderer == r and p.size == size]
            got = [g for g in got if g]
            if not got:
                continue
            cells = []
            for key, _, fmt in keys:
                vals = [g[key] for g in got if isinstance(g.get(key), int | float)]
                cells.append(fmt.format(float(np.median(vals))) if vals else "-")
            rows.append(f"| {r} | {size} | {len(got)} | " + " | ".join(cells) + " |")
    return rows


def wrong_verdict_reasons(photos: list[Photo]) -> dict:
    """Validate's reasons for the false rejects (perfect photos) and misses (defect photos), figures as #."""
    import re

    out: dict = {}
    for p in photos:
        o = p.result.get("outcome")
        if o not in (
            "false reject",
            "fail, not located",
            "fail, not located, below stated limit",
            "escape",
            "invalid",
            "invalid, above stated limit",
        ):
            continue
        text = p.result.get("reason") or o
        # one line per rule: "a; b" are two reasons
        for part in text.split("; "):
            key = re.sub(r"-?\d+(\.\d+)?", "#", part).strip()
            n = out.setdefault(key, [0, 0])
            n[0 if p.defect is None else 1] += 1
    return dict(sorted(out.items(), key=lambda kv: -sum(kv[1])))


def artwork_of() -> dict:
    index = json.loads((CORPUS / "corpus.json").read_text())
    return {(p["name"], v["name"]): v["artwork"] for p in index["parts"] for v in p["views"]}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--subset", choices=("fast", "bench", "full"), default="full")
    ap.add_argument("--renderer", choices=("workbench", "mitsuba", "both"), default="workbench")
    ap.add_argument("--jobs", type=int, default=1, help="photos rendered and validated at once (default 1)")
    ap.add_argument("--only", help="only these photo ids (comma-separated)")
    ap.add_argument("--out", type=Path, default=ROOT / "out" / "validate_corpus")
    ap.add_argument("--parts", help="only these parts (comma-separated)")
    ap.add_argument("--sizes", help="only these photo sizes (comma-separated WxH)")
    ap.add_argument("--perfect-only", action="store_true")
    ap.add_argument("--defects-only", action="store_true")
    ap.add_argument("--limit", type=int, help="only the first N photos of the grid")
    ap.add_argument("--revalidate", action="store_true", help="validate again even where a report exists")
    ap.add_argument("--name", default="validate_corpus", help="the tables' file name, without suffix")
    ap.add_argument(
        "--validation",
        default="validation",
        help="each photo's validation folder (default validation): another name keeps another validate's reports",
    )
    ap.add_argument(
        "--report-only", action="store_true", help="no rendering or validation: the tables from the photos in OUT"
    )
    ap.add_argument("--render-root", type=Path, help="a checkout whose workbench renders (default: this one)")
    ap.add_argument("--spp", type=int, default=16, help="Mitsuba samples per pixel (default 16)")
    ap.add_argument(
        "--finish",
        choices=("look", "glossy", "matte"),
        default="look",
        help="validate --finish: the film each look renders (default: glossy where it has a gloss), or one for all",
    )
    args = ap.parse_args(argv)
    args.out = args.out.resolve()
    env_validate = {**os.environ, "PYTHONPATH": str(ROOT)}
    env_render = {**os.environ, "PYTHONPATH": str((args.render_root or ROOT).resolve())}
    renderers = ["workbench", "mitsuba"] if args.renderer == "both" else [args.renderer]
    if "mitsuba" in renderers and not accepts_renderer(env_render):
        print(
            f"validate_corpus: the render command of {args.render_root or ROOT} has no --renderer: Mitsuba photos "
            "are left out (give --render-root a checkout that has it)",
            file=sys.stderr,
        )
        renderers = [r for r in renderers if r != "mitsuba"]
        if not renderers:
            return 1
    photos = grid(args.subset, renderers)
    if args.parts:
        keep = set(args.parts.split(","))
        photos = [p for p in photos if p.part in keep]
    if args.sizes:
        keep = set(args.sizes.split(","))
        photos = [p for p in photos if p.size in keep]
    if args.perfect_only:
        photos = [p for p in photos if p.defect is None]
    if args.defects_only:
        photos = [p for p in photos if p.defect is not None]
    if args.only:
        keep = set(args.only.split(","))
        photos = [p for p in photos if p.id in keep]
    if args.limit:
        photos = photos[: args.limit]
    args.out.mkdir(parents=True, exist_ok=True)
    t0 = time.perf_counter()
    designs = {}
    for part in sorted({p.part for p in photos}):
        designs[part] = design_part(part, args.out, env_validate)
    print(f"{len(designs)} designs ready ({time.perf_counter() - t0:.0f} s); {len(photos)} photos", flush=True)
    done = [0]

    def one(photo: Photo) -> Photo:
        run_photo(photo, args.out, designs, env_validate, env_render, args)
        done[0] += 1
        r = photo.result
        extra = ""
        if r.get("defects_found"):
            extra = " | " + "; ".join(f"{d['kind']} {d['area_mm2']:.1f} mm²" for d in r["defects_found"][:3])
        print(
            f"[{done[0]}/{len(photos)}] {photo.id}: {r.get('verdict', '-')} {r.get('outcome')} "
            f"({r.get('render_s', 0):.0f} + {r.get('validate_s', 0):.0f} s) {r.get('reason') or r.get('why') or ''}"
            f"{extra}",
            flush=True,
        )
        return photo

    with ThreadPoolExecutor(max(1, args.jobs)) as pool:
        photos = list(pool.map(one, photos))
    summary = rates(photos)
    command = "python benchmarks/validate_corpus.py " + " ".join(argv if argv is not None else sys.argv[1:])
    report = {
        "command": command,
        "seconds": round(time.perf_counter() - t0, 1),
        "tolerance_mm": TOLERANCE_MM,
        "rates": summary,
        "photos": [{**{k: v for k, v in asdict(p).items() if k != "result"}, "id": p.id, **p.result} for p in photos],
    }
    (args.out / f"{args.name}.json").write_text(json.dumps(report, indent=1) + "\n")
    (args.out / f"{args.name}.md").write_text(markdown(photos, summary, command))
    for r, s in summary["perfect"].items():
        print(f"{r}: false rejects {pct(s['false_rejects'], s['photos'])}, invalid {s['invalid']}")
    for d, per in summary["defects"].items():
        for r, s in per.items():
            print(f"{d} ({r}): found {pct(s['found'], s['photos'])}, escapes {pct(s['escapes'], s['photos'])}")
    print(f"wrote {args.out / args.name}.json and .md ({report['seconds']} s)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
