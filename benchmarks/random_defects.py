"""Defects placed at random over each film: ``workbench validate`` on whole parts, as a QA engineer sees it.

    python benchmarks/random_defects.py [--parts a,b] [--renderer workbench|mitsuba|both]
                                        [--looks matte,glossy] [--defects-per-part K] [--seed S]
                                        [--dark-dropouts [--dark-grey G]] [--size WxH] [--spp N]
                                        [--tolerance-mm T] [--design-cache DIR] [--out DIR]
                                        [--revalidate] [--name NAME]

For each part of ``tests/data/validate_corpus/`` (default: cow, face, lilium, bunny, beetle,
fertility), each renderer (``workbench render``, and Mitsuba 3 with ``--renderer mitsuba --spp
N``) and each look (matte: workbench ``--realistic``, Mitsuba ``--gloss 0``; glossy: workbench
``--realistic --gloss 0.5``, Mitsuba ``--gloss 0.5``), two *part-runs* of the same poses (one
photo a few degrees off each designed view, as ``validate_corpus.py`` takes it, and two more from
azimuth +30° and -30° of the first view at elevation 60°, each framing the fixture plate), each
validated as one part (``workbench validate DESIGN P1 P2 ... --camera P1.json --tolerance-mm T
--jobs 1 --out DIR -q``):

* *perfect*: the part as designed;
* *defects*: K defects (``workbench render --defect``, repeated) placed at random, uniformly over
  the decorated print (alpha of ``print.png`` > 0), seeded by ``--seed``, each at least 3 mm inside
  the print's outline and 2 mm clear of the others, a mix of a 20 mm² dropout
  (``dropout:X,Y,2.52``), a 6 mm bubble slid 0.5 mm (``bubble:X,Y,3,0.5``) and a 20 mm scratch
  0.5 mm wide in a random direction (``scratch:X0,Y0,X1,Y1,0.5``). With ``--dark-dropouts`` the
  defects are dropouts only, placed at random among print pixels whose ink is dark (mean grey
  < 80 over the disc, ``--dark-grey``): a white dropout on dark ink.

Each true defect (the truth in the photos' ``PHOTO.json``) is judged against the part's report:
*covered* when the part's detection maps (``detection.npz``, ``part_*`` on the analysis grid of
``photos[k].dense.grid_px_per_mm``) find its class over at least 75 % of its footprint (dropout:
``part_dropout``; scratch: ``part_scratch``) or, for a bubble, a shift limit at or below its slide
over at least 50 % of it; *found* when a part defect of a matching kind (dropout: ``missing``;
bubble: ``shift``; scratch: ``missing`` or ``scratch``) lies within 1 mm of its centre (a disc;
a dropout's area within 25 %) or within 2 mm of its segment (a scratch); an *escape* is covered
and not found. Writes ``OUT/NAME.json`` and ``OUT/NAME.md`` (NAME: random_defects, or
random_defects_dark with ``--dark-dropouts``): per part-run the part verdict, coverage shares and
reason, per true defect covered / found / escape with what validate said there, and the rates:
false rejects (perfect part-runs that FAIL), perfect part-runs INCOMPLETE or INVALID, escapes
among covered defects (must be 0), defect part-runs that PASS (must be 0), dark dropouts found
with their area within 25 % among those a photo sees face-on (the surface's mean normal over the
disc within 30° of the direction to a photo's camera; occlusion not considered).

Designs are reused from ``DIR/designs/NAME`` (``--design-cache``, default OUT; made with
``workbench design`` when missing), photos are cached in ``OUT/photos`` (a photo whose image and
JSON exist, rendered by the same command, is not rendered again) and part reports in
``OUT/runs`` (``--revalidate`` validates again). ``workbench`` runs as ``sys.executable -m
workbench`` with PYTHONPATH the checkout this script lives in. One process at a time.
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
import zlib
from pathlib import Path

import cv2
import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "benchmarks"))
from validate_corpus import design_part, footprint, photo_orbit, view_direction  # noqa: E402

PARTS = ("cow", "face", "lilium", "bunny", "beetle", "fertility")
LOOKS = {
    "workbench": {"matte": ["--realistic"], "glossy": ["--realistic", "--gloss", "0.5"]},
    "mitsuba": {"matte": ["--gloss", "0"], "glossy": ["--gloss", "0.5"]},
}
DROPOUT_R = 2.52  # mm: 20 mm²
BUBBLE_R, BUBBLE_SLIDE = 3.0, 0.5  # a 6 mm bubble slid 0.5 mm
SCRATCH_LEN, SCRATCH_W = 20.0, 0.5
INSIDE_MM = 3.0  # each defect this far inside the print's outline
APART_MM = 2.0  # ... and this far clear of the others
DARK_GREY = 80  # (--dark-grey) a dark dropout: mean grey of the print over its disc below this
LOCATE_MM = 1.0  # found: a disc's centre within this
SCRATCH_LOCATE_MM = 2.0  # ... a scratch's segment within this
AREA_SHARE = 0.25  # ... a dropout's area within this share
DROPOUT_SHARE, SHIFT_SHARE = 0.75, 0.5  # covered: share of the footprint the part's maps find it on
FACE_ON_DEG = 30.0
MATCH_KINDS = {"dropout": ("missing",), "bubble": ("shift",), "scratch": ("missing", "scratch")}


# ---------------------------------------------------------------------------------------------- placement


def print_masks(design: Path) -> tuple[np.ndarray, np.ndarray, float, np.ndarray]:
    """The print's alpha > 0, each pixel's distance to its outline (mm), px per mm and its grey."""
    img = cv2.imread(str(design / "print.png"), cv2.IMREAD_UNCHANGED)
    alpha = img[..., 3] > 0 if img.shape[2] == 4 else np.ones(img.shape[:2], bool)
    ppm = json.loads((design / "design.json").read_text())["print"]["dpi"] / 25.4
    # (the border counts as outside: a print that reaches its image's edge ends there)
    padded = np.pad(alpha, 1).astype(np.uint8)
    dist = cv2.distanceTransform(padded, cv2.DIST_L2, 5)[1:-1, 1:-1] / ppm
    grey = cv2.cvtColor(img[..., :3], cv2.COLOR_BGR2GRAY)
    return alpha, dist, ppm, grey


def shape_points(d: dict) -> tuple[np.ndarray, float]:
    """A defect as points (mm) and their radius: a disc's centre and radius, a scratch's axis and half its width."""
    if d["kind"] == "scratch":
        a, b = np.asarray(d["from"]), np.asarray(d["to"])
        n = int(math.ceil(np.linalg.norm(b - a) / 0.1)) + 1
        return a + np.linspace(0, 1, n)[:, None] * (b - a), SCRATCH_W / 2
    return np.asarray([d["centre"]]), d["radius"]


def clear_of(d: dict, others: list[dict]) -> bool:
    p, r = shape_points(d)
    for o in others:
        q, s = shape_points(o)
        gap = np.linalg.norm(p[:, None, :] - q[None, :, :], axis=2).min() - r - s
        if gap < APART_MM:
            return False
    return True


def inside(d: dict, dist: np.ndarray, ppm: float) -> bool:
    """Every point of the defect at least INSIDE_MM plus its radius inside the outline."""
    p, r = shape_points(d)
    j = np.floor(p[:, 0] * ppm).astype(int)
    i = np.floor(p[:, 1] * ppm).astype(int)
    if (i < 0).any() or (j < 0).any() or (i >= dist.shape[0]).any() or (j >= dist.shape[1]).any():
        return False
    return bool((dist[i, j] >= INSIDE_MM + r).all())


def place_defects(
    design: Path, part: str, k: int, seed: int, dark: bool, dark_grey: float = DARK_GREY
) -> tuple[list[dict], str]:
    """K defects at random over the print (deterministic in ``seed`` and the part), and a note.

    A centre is drawn uniformly among the print's pixels (``dark``: among those whose disc's
    mean grey is below DARK_GREY), a scratch's direction uniformly; a draw that is not inside
    the outline by INSIDE_MM or not APART_MM clear of the defects already placed is drawn again
    (up to 5000 times per defect).
    """
    alpha, dist, ppm, grey = print_masks(design)
    rng = np.random.default_rng([seed, zlib.crc32(part.encode()), 1 if dark else 0])
    kinds = ["dropout"] * k if dark else [("dropout", "bubble", "scratch")[n % 3] for n in range(k)]
    cand = alpha.copy()
    note = ""
    if dark:
        r = int(math.ceil(DROPOUT_R * ppm))
        disc = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * r + 1, 2 * r + 1)).astype(np.float32)
        mean = cv2.filter2D(grey.astype(np.float32), -1, disc / disc.sum(), borderType=cv2.BORDER_REPLICATE)
        ok = alpha & (dist >= INSIDE_MM + DROPOUT_R)
        cand = ok & (mean < dark_grey)
        darkest = float(mean[ok].min()) if ok.any() else float("nan")
        note = f"{int(cand.sum())} print px with a disc of mean grey < {dark_grey:g} (darkest disc: {darkest:.0f})"
    ii, jj = np.nonzero(cand)
    placed: list[dict] = []
    for kind in kinds:
        for _ in range(5000):
            if len(ii) == 0:
                break
            n = int(rng.integers(len(ii)))
            c = np.array([(jj[n] + rng.random()) / ppm, (ii[n] + rng.random()) / ppm])
            if kind == "scratch":
                a = rng.uniform(0, 2 * math.pi)
                h = 0.5 * SCRATCH_LEN * np.array([math.cos(a), math.sin(a)])
                d = {"kind": kind, "from": (c - h).tolist(), "to": (c + h).tolist()}
            else:
                d = {"kind": kind, "centre": c.tolist(), "radius": DROPOUT_R if kind == "dropout" else BUBBLE_R}
            if inside(d, dist, ppm) and clear_of(d, placed):
                placed.append(d)
                break
        else:
            note += f"; no room for another {kind} after 5000 draws"
        if len(ii) == 0:
            note += f"; no candidate pixel for a {kind}"
            break
    for d in placed:
        if d["kind"] == "dropout":
            d["spec"] = f"dropout:{d['centre'][0]:.2f},{d['centre'][1]:.2f},{DROPOUT_R}"
        elif d["kind"] == "bubble":
            d["spec"] = f"bubble:{d['centre'][0]:.2f},{d['centre'][1]:.2f},{BUBBLE_R:g},{BUBBLE_SLIDE}"
        else:
            x0, y0 = d["from"]
            x1, y1 = d["to"]
            d["spec"] = f"scratch:{x0:.2f},{y0:.2f},{x1:.2f},{y1:.2f},{SCRATCH_W}"
    return placed, note.strip("; ")


# ---------------------------------------------------------------------------------------------- poses


def poses(part: str, design: Path, size: str) -> list[tuple[str, tuple]]:
    """(name, orbit (az, el, dist, fov)): a few degrees off each designed view, and az ±30° at el 60."""
    info = json.loads((design / "design.json").read_text())
    out = []
    for k, v in enumerate(info["views"]):
        az, el = view_direction(part, v["name"])
        out.append((v["name"], photo_orbit(design, az, el, size, k)))
    az0, _ = view_direction(part, info["views"][0]["name"])
    _, _, dist, fov = photo_orbit(design, az0, 60.0, size, 0)
    out.append(("az+30", (az0 + 30.0, 60.0, dist, fov)))
    out.append(("az-30", (az0 - 30.0, 60.0, dist, fov)))
    return out


_GRIDS: dict = {}


def face_on_deg(design: Path, centre_mm, cameras: list[tuple], radius_mm: float = 2.5) -> float | None:
    """The smallest angle (deg) between the surface's normal at a print point and the direction to a photo's camera.

    The normal is the mean of the triangles' unit normals under the grid pixels within
    ``radius_mm`` of the print point (one triangle's normal swings on a faceted mesh);
    occlusion is not considered.
    """
    from workbench.design_dir import Design
    from workbench.validate.print_warp import print_grid

    if design not in _GRIDS:
        d = Design(design)
        p = d.info["print"]
        _GRIDS[design] = (d, print_grid(d.V, d.F, d.flat, p["height_mm"], d.rgb, p["dpi"], d.owner))
    d, grid = _GRIDS[design]
    ppm = grid.px_per_mm
    ii, jj = np.mgrid[0 : grid.face.shape[0], 0 : grid.face.shape[1]]
    near = np.hypot((jj + 0.5) / ppm - centre_mm[0], (ii + 0.5) / ppm - centre_mm[1]) <= radius_mm
    near &= grid.face >= 0
    if not near.any():
        return None
    tri = d.V[d.F[grid.face[near]]]
    n = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    n /= np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-12)
    n = n.mean(axis=0)
    n /= max(np.linalg.norm(n), 1e-12)
    X = grid.X[near].mean(axis=0)
    best = 180.0
    for az, el, dist, fov, w, h in cameras:
        cam = d.orbit_camera(az, el, dist, w, h, fov, None)
        v = cam.center - X
        c = float(np.dot(n, v / max(np.linalg.norm(v), 1e-12)))
        best = min(best, math.degrees(math.acos(max(-1.0, min(1.0, c)))))
    return best


# ---------------------------------------------------------------------------------------------- running


def render_photo(design: Path, orbit: tuple, size: str, renderer: str, look: str, specs, seed, img: Path, args, env):
    """Render one photo unless the same command made it already; returns (seconds, rendered now)."""
    cmd = [sys.executable, "-m", "workbench", "render", str(design)]
    cmd += [f"--orbit={orbit[0]:g},{orbit[1]:g},{orbit[2]:.1f}", "--fov-deg", f"{orbit[3]:g}", "--size", size]
    cmd += [*LOOKS[renderer][look], "--seed", str(seed)]
    if renderer == "workbench":
        cmd += ["--supersample", "2"]
    else:
        cmd += ["--renderer", "mitsuba", "--spp", str(args.spp)]
    for s in specs:
        cmd += ["--defect", s]
    cmd += ["-o", str(img), "-q"]
    stamp = img.with_suffix(".cmd")
    # (the design by its content and the render's options, not the paths: a cache copied to
    # another --out, or a design cache moved, stays valid)
    options = cmd[cmd.index(str(design)) + 1 : cmd.index("-o")]
    key = json.dumps([hashlib.sha256((design / "design.json").read_bytes()).hexdigest(), "render", *options])
    if img.is_file() and img.with_suffix(".json").is_file() and stamp.is_file() and stamp.read_text() == key:
        return 0.0, False
    img.parent.mkdir(parents=True, exist_ok=True)
    t0 = time.perf_counter()
    r = subprocess.run(cmd, env=env, cwd=str(ROOT), capture_output=True, text=True, timeout=3600)
    if r.returncode != 0:
        raise RuntimeError(f"render failed: {' '.join(cmd[3:])}: {r.stderr.strip().splitlines()[-1:]}")
    stamp.write_text(key)
    return time.perf_counter() - t0, True


def run_part(run: dict, design: Path, args, env) -> dict:
    """Render a part-run's photos, validate them as one part, judge each true defect.

    With ``--add-suggested K``, a part INCOMPLETE gets the photo its validation suggests
    (``part.coverage.next_photo``: an orbit on the fixture, the first photo's lens), rendered as
    the others, and is validated again, up to K times; the verdict before is kept beside.
    """
    res = _run_part(run, design, args, env)
    before, added = res.get("verdict"), 0
    while "error" not in res and res["verdict"] == "INCOMPLETE" and added < args.add_suggested:
        nxt = json.loads((Path(res["validation_dir"]) / "validation.json").read_text())["part"].get("coverage") or {}
        orbit = (nxt.get("next_photo") or {}).get("orbit")
        if not orbit:
            break
        added += 1
        fov = run["poses"][0][1][3]
        run["poses"] = [*run["poses"], (f"suggested-{added}", (orbit[0], orbit[1], orbit[2], fov))]
        res = _run_part(run, design, args, env)
    return {**res, "verdict_before_suggested": before, "suggested_photos_added": added}


def _run_part(run: dict, design: Path, args, env) -> dict:
    folder = args.out / "photos" / run["id"]
    ext = ".jpg" if run["renderer"] == "workbench" else ".png"
    imgs, fresh, cams = [], False, []
    w, h = (int(v) for v in args.size.split("x"))
    for k, (name, orbit) in enumerate(run["poses"]):
        img = folder / f"{name}{ext}"
        secs, now = render_photo(
            design, orbit, args.size, run["renderer"], run["look"], [d["spec"] for d in run["truth_placed"]], k, img,
            args, env,
        )  # fmt: skip
        fresh |= now
        imgs.append(img)
        cams.append((*orbit, w, h))
        print(f"  {run['id']}/{img.name}: {f'rendered in {secs:.0f} s' if now else 'cached'}", flush=True)
    vdir = args.out / "runs" / run["id"] / "validation"
    cmd = [sys.executable, "-m", "workbench", "validate", str(design), *map(str, imgs)]
    cmd += ["--camera", str(imgs[0].with_suffix(".json")), "--tolerance-mm", str(args.tolerance_mm)]
    cmd += ["--jobs", "1", "--out", str(vdir), "-q"]
    # (the film the look renders: glossy or matte; or one finish for every run)
    cmd += ["--finish", run["look"] if args.finish == "look" else args.finish]
    t0 = time.perf_counter()
    if fresh or args.revalidate or not (vdir / "validation.json").is_file():
        r = subprocess.run(cmd, env=env, cwd=str(ROOT), capture_output=True, text=True, timeout=3600)
        if r.returncode != 0 and not (vdir / "validation.json").is_file():
            return {**public(run), "error": f"validate failed: {r.stderr.strip().splitlines()[-1:]}"}
    secs = time.perf_counter() - t0
    report = json.loads((vdir / "validation.json").read_text())
    truth = json.loads(imgs[0].with_suffix(".json").read_text()).get("defects", [])
    return {
        **public(run),
        **judge(report, vdir, truth, design, cams),
        "validate_s": round(secs, 1),
        "validate_cmd": " ".join(cmd[1:]),
        "validation_dir": str(vdir),
    }


def public(run: dict) -> dict:
    return {k: v for k, v in run.items() if k != "truth_placed"} | {"specs": [d["spec"] for d in run["truth_placed"]]}


def part_reason(report: dict) -> str:
    """The part's reason as the QA report gives it: its own (INCOMPLETE), else its first failing photo's."""
    part = report.get("part") or {}
    if part.get("reason"):
        return part["reason"]
    in_part = part.get("photo_verdicts_in_part") or {}
    photos = report.get("photos", [])
    fails = [e for e in photos if in_part.get(Path(e["photo"]).name, e["verdict"]) == "FAIL"]
    if fails:
        name = Path(fails[0]["photo"]).name
        return f"{name}: {(part.get('photo_reasons_in_part') or {}).get(name, fails[0]['reason'])}"
    bad = [e for e in photos if e["verdict"] != "PASS"]
    return "; ".join(f"{Path(e['photo']).name}: {e['verdict']}: {e['reason']}" for e in bad)


def seg_distance(p, a, b) -> float:
    p, a, b = (np.asarray(v, np.float64) for v in (p, a, b))
    ab = b - a
    t = float(np.clip(np.dot(p - a, ab) / max(np.dot(ab, ab), 1e-12), 0, 1))
    return float(np.linalg.norm(p - (a + t * ab)))


def distance_to(t: dict, c) -> float:
    if t["kind"] == "scratch":
        return seg_distance(c, t["from_mm"], t["to_mm"])
    return float(np.linalg.norm(np.asarray(c, np.float64) - np.asarray(t["centre_mm"], np.float64)))


def visible_part(t: dict, design: Path) -> tuple[float, list[float]] | None:
    """A dropout's visible part: its area (mm²) and centroid (print mm) where the design's ink shows when gone.

    Where the design is the bare film's colour (within the colour tolerance, ΔE 3 as
    :func:`workbench.validate.coverage.where_defects_show` takes it), ink gone changes nothing: a disc
    across the design's white is found, and sized, by its inked part alone.
    """
    from workbench.render.defects import FILM_RGB
    from workbench.validate.coverage import design_lab

    img = cv2.imread(str(design / "print.png"), cv2.IMREAD_UNCHANGED)
    ppm = json.loads((design / "design.json").read_text())["print"]["dpi"] / 25.4
    (cx, cy), r = t["centre_mm"], t["radius_mm"]
    i0, i1 = max(int((cy - r) * ppm) - 1, 0), min(int((cy + r) * ppm) + 2, img.shape[0])
    j0, j1 = max(int((cx - r) * ppm) - 1, 0), min(int((cx + r) * ppm) + 2, img.shape[1])
    ii, jj = np.mgrid[i0:i1, j0:j1]
    disc = np.hypot((jj + 0.5) / ppm - cx, (ii + 0.5) / ppm - cy) <= r
    rgb = np.ascontiguousarray(img[i0:i1, j0:j1, 2::-1]).astype(np.float32)
    film = design_lab(np.asarray(FILM_RGB, np.float32).reshape(1, 1, 3))[0, 0]
    shows = disc & (np.linalg.norm(design_lab(rgb) - film, axis=-1) > 3.0)
    if not shows.any():
        return None
    centre = [float((jj[shows] + 0.5).mean() / ppm), float((ii[shows] + 0.5).mean() / ppm)]
    return float(shows.sum() / ppm**2), centre


def judge(report: dict, vdir: Path, truth: list[dict], design: Path, cams: list[tuple]) -> dict:
    part = report.get("part") or {}
    films = (part.get("coverage") or {}).get("films", [])
    out = {
        "verdict": part.get("verdict"),
        "max_defect_mm2": report.get("max_defect_mm2", 4.0),
        "reason": part_reason(report),
        "photo_verdicts": {Path(e["photo"]).name: e["verdict"] for e in report.get("photos", [])},
        "coverage": [{c: (f.get(c) or {}).get("share") for c in ("slide", "ink_gone", "scratch")} for f in films],
        "part_defects": [
            {k: d.get(k) for k in ("kind", "area_mm2", "centre_mm", "photos", "unresolved")}
            for d in part.get("defects", [])
        ],
        "dismissed": [
            {k: x.get(k) for k in ("photo", "kind", "area_mm2", "centre_mm")} for x in part.get("dismissed", [])
        ],
    }
    maps = None
    info = report.get("detection")
    if info and (vdir / info["file"]).is_file():
        maps = np.load(vdir / info["file"])
    grids = [(e.get("dense") or {}).get("grid_px_per_mm") for e in report.get("photos", [])]
    ppm = next((float(g) for g in grids if g), None)
    regions = ((part.get("coverage") or {}).get("uncovered") or {}).get("regions", [])
    defects = part.get("defects", [])
    judged = []
    for t in truth:
        rec: dict = {"kind": t["kind"], "spec": t["spec"], "centre_mm": t["centre_mm"], "area_mm2": t["area_mm2"]}
        # covered: the part's maps over the footprint
        if maps is not None and ppm and "part_dropout" in maps:
            limit = maps["part_shift_limit_um"]
            fp = footprint(t, limit.shape, ppm)
            n = max(int(fp.sum()), 1)
            if t["kind"] == "bubble":
                slide_um = 1000.0 * float(np.hypot(*t["shift_mm"]))
                share = float((fp & (limit <= slide_um)).sum()) / n
                need = SHIFT_SHARE
            else:
                m = maps["part_scratch"] if t["kind"] == "scratch" else maps["part_dropout"]
                share = float((fp & m.astype(bool)).sum()) / n
                need = DROPOUT_SHARE
            rec["covered_share"] = round(share, 3)
            rec["covered"] = share >= need
            per = {}
            for key in maps.files:
                if key.startswith("photo") and key.endswith("_dropout"):
                    k = key.split("_")[0]
                    if t["kind"] == "bubble":
                        s = float((fp & (maps[f"{k}_shift_limit_um"] <= slide_um)).sum()) / n
                    else:
                        mk = maps[f"{k}_scratch"] if t["kind"] == "scratch" else maps[key]
                        s = float((fp & mk.astype(bool)).sum()) / n
                    per[k] = round(s, 2)
            rec["covered_share_per_photo"] = per
        else:
            rec["covered_share"], rec["covered"] = None, False
        # found: a part defect of a matching kind near it (a dropout: near its visible part, and
        # that part's size)
        reach = SCRATCH_LOCATE_MM if t["kind"] == "scratch" else LOCATE_MM
        seen = {**t}
        if t["kind"] == "dropout" and (vis := visible_part(t, design)) is not None:
            seen["area_mm2"], seen["centre_mm"] = vis
            rec["visible_area_mm2"], rec["visible_centre_mm"] = round(vis[0], 2), [round(v, 2) for v in vis[1]]
        match = None
        for d in sorted(defects, key=lambda d: distance_to(seen, d["centre_mm"])):
            if d["kind"] not in MATCH_KINDS[t["kind"]] or distance_to(seen, d["centre_mm"]) > reach:
                continue
            if t["kind"] == "dropout" and abs(d["area_mm2"] / seen["area_mm2"] - 1) > AREA_SHARE:
                continue
            match = d
            break
        # (a region the part's photos could not tell ink gone from light on is open: located, not found)
        rec["open"] = bool(match is not None and match.get("unresolved"))
        rec["found"] = match is not None and not rec["open"]
        near = min(defects, key=lambda d: distance_to(t, d["centre_mm"]), default=None)
        if near is not None:
            rec["nearest"] = {
                "kind": near["kind"],
                "area_mm2": round(near["area_mm2"], 2),
                "distance_mm": round(distance_to(t, near["centre_mm"]), 2),
            }
        rec["escape"] = bool(rec["covered"] and not rec["found"] and not rec["open"])
        rec["face_on_deg"] = face_on_deg(design, t["centre_mm"], cams)
        if rec["face_on_deg"] is not None:
            rec["face_on_deg"] = round(rec["face_on_deg"], 1)
        rec["why"] = why(t, rec, match, near, out["dismissed"], regions, report)
        judged.append(rec)
    out["truth"] = judged
    return out


def why(t: dict, rec: dict, match, near, dismissed: list, regions: list, report: dict) -> str:
    """What validate said at a true defect: the part defect that matches it, or what it found near it and why not."""
    if match is not None:
        return (
            f"found: {match['kind']} {match['area_mm2']:.1f} mm² at {distance_to(t, match['centre_mm']):.2f} mm "
            f"(in {', '.join(match.get('photos', []))})"
        )
    words = []
    if near is not None and distance_to(t, near["centre_mm"]) <= 5.0:
        dist = distance_to(t, near["centre_mm"])
        words.append(f"nearest part defect {near['kind']} {near['area_mm2']:.1f} mm² at {dist:.2f} mm")
    for x in dismissed:
        if distance_to(t, x["centre_mm"]) <= 5.0:
            words.append(f"dismissed as light: {x['kind']} {x['area_mm2']:.1f} mm² in {x['photo']}")
    for e in report.get("photos", []):
        for d in e.get("defects", []):
            if distance_to(t, d["centre_mm"]) <= 5.0 and (near is None or d["centre_mm"] != near["centre_mm"]):
                words.append(f"{Path(e['photo']).name} found {d['kind']} {d['area_mm2']:.1f} mm²")
    x, y = t["centre_mm"]
    for r in regions:
        x0, y0, x1, y1 = r["bbox_mm"]
        if x0 <= x <= x1 and y0 <= y <= y1 and r["area_mm2"] < 2000:
            words.append(f"in an uncovered region ({'/'.join(r['classes'])}): {r['why']}")
            break
    if not words:
        words.append("nothing reported within 5 mm")
    if not rec["covered"]:
        words.append(f"maps cover {100 * (rec['covered_share'] or 0):.0f} % of it (not covered)")
    return "; ".join(words)


# ---------------------------------------------------------------------------------------------- the tables


def rates(runs: list[dict], dark: bool) -> dict:
    ok = [r for r in runs if "error" not in r]
    perfect = [r for r in ok if r["kind"] == "perfect"]
    defect = [r for r in ok if r["kind"] != "perfect"]
    truth = [t for r in defect for t in r["truth"]]
    covered = [t for t in truth if t["covered"]]
    out = {
        "perfect_part_runs": len(perfect),
        "false_rejects": sum(r["verdict"] == "FAIL" for r in perfect),
        "perfect_incomplete": sum(r["verdict"] == "INCOMPLETE" for r in perfect),
        "perfect_incomplete_before_suggested": sum(
            r.get("verdict_before_suggested", r["verdict"]) == "INCOMPLETE" for r in perfect
        ),
        "suggested_photos_added": sum(r.get("suggested_photos_added", 0) for r in ok),
        "perfect_open": sum(
            any(d.get("unresolved") and d["area_mm2"] > r.get("max_defect_mm2", 4.0) for d in r["part_defects"])
            for r in perfect
        ),
        "perfect_invalid": sum(r["verdict"] == "INVALID" for r in perfect),
        "defect_part_runs": len(defect),
        "defect_part_runs_pass": sum(r["verdict"] == "PASS" for r in defect),
        "defect_part_runs_incomplete": sum(r["verdict"] == "INCOMPLETE" for r in defect),
        "defect_part_runs_invalid": sum(r["verdict"] == "INVALID" for r in defect),
        "defect_part_runs_fail": sum(r["verdict"] == "FAIL" for r in defect),
        "defects": len(truth),
        "covered": len(covered),
        "found": sum(t["found"] for t in truth),
        "found_of_covered": sum(t["found"] for t in covered),
        "open": sum(t.get("open", False) for t in truth),
        "escapes": sum(t["escape"] for t in truth),
        "found_not_covered": sum(t["found"] and not t["covered"] for t in truth),
        "errors": len(runs) - len(ok),
        "per_kind": {},
    }
    for kind in ("dropout", "bubble", "scratch"):
        ts = [t for t in truth if t["kind"] == kind]
        if ts:
            out["per_kind"][kind] = {
                "defects": len(ts),
                "covered": sum(t["covered"] for t in ts),
                "found": sum(t["found"] for t in ts),
                "escapes": sum(t["escape"] for t in ts),
                "open": sum(t.get("open", False) for t in ts),
            }
    if dark:
        face_on = [t for t in truth if t["face_on_deg"] is not None and t["face_on_deg"] <= FACE_ON_DEG]
        out["dark_dropouts"] = len(truth)
        out["dark_face_on"] = len(face_on)
        out["dark_face_on_found"] = sum(t["found"] for t in face_on)
        out["dark_face_on_covered"] = sum(t["covered"] for t in face_on)
    return out


def pct(a: int, b: int) -> str:
    return f"{a}/{b} ({100 * a / b:.0f} %)" if b else "0/0"


def markdown(runs: list[dict], s: dict, command: str, args) -> str:
    lines = [
        "# validate: defects placed at random" + (" (dark dropouts)" if args.dark_dropouts else ""),
        "",
        f"`{command}`",
        "",
        f"Photos {args.size}, tolerance {args.tolerance_mm} mm, Mitsuba spp {args.spp}. A true defect is *covered* "
        f"when the part's detection maps find its class over ≥ {100 * DROPOUT_SHARE:.0f} % of its footprint "
        f"(dropout, scratch) or a shift limit ≤ its slide over ≥ {100 * SHIFT_SHARE:.0f} % (bubble); *found* when a "
        f"part defect of a matching kind lies within {LOCATE_MM:g} mm of its centre (disc; dropout area within "
        f"{100 * AREA_SHARE:.0f} %) or {SCRATCH_LOCATE_MM:g} mm of its segment (scratch); an *escape* is covered "
        "and not found.",
        "",
        "## Rates",
        "",
        "| measure | value |",
        "|---|---|",
        f"| false rejects (perfect part-runs that FAIL) | {pct(s['false_rejects'], s['perfect_part_runs'])} |",
        f"| perfect part-runs INCOMPLETE | {pct(s['perfect_incomplete'], s['perfect_part_runs'])} |",
        f"| perfect part-runs INCOMPLETE before the suggested photos ({s['suggested_photos_added']} added in all) | "
        f"{pct(s['perfect_incomplete_before_suggested'], s['perfect_part_runs'])} |",
        f"| perfect part-runs with a region over the verdict's area still open (a defect or light, not told) | "
        f"{pct(s.get('perfect_open', 0), s['perfect_part_runs'])} |",
        f"| perfect part-runs INVALID | {pct(s['perfect_invalid'], s['perfect_part_runs'])} |",
        f"| defect part-runs that PASS (must be 0) | {pct(s['defect_part_runs_pass'], s['defect_part_runs'])} |",
        f"| defect part-runs INCOMPLETE / INVALID / FAIL | {s['defect_part_runs_incomplete']} / "
        f"{s['defect_part_runs_invalid']} / {s['defect_part_runs_fail']} of {s['defect_part_runs']} |",
        f"| true defects covered | {pct(s['covered'], s['defects'])} |",
        f"| escapes among covered defects (must be 0) | {pct(s['escapes'], s['covered'])} |",
        f"| found among covered | {pct(s['found_of_covered'], s['covered'])} |",
        f"| found, all defects | {pct(s['found'], s['defects'])} |",
        f"| open (located, no photo told ink gone from light: the part INCOMPLETE) | "
        f"{pct(s.get('open', 0), s['defects'])} |",
        f"| runs that failed to render/validate | {s['errors']} |",
    ]
    for kind, k in s["per_kind"].items():
        lines.append(
            f"| {kind}: covered / found / escapes / open | {k['covered']} / {k['found']} / {k['escapes']} / "
            f"{k.get('open', 0)} of {k['defects']} |"
        )
    if "dark_dropouts" in s:
        lines.append(
            f"| dark dropouts found (area within {100 * AREA_SHARE:.0f} %) / seen face-on (≤ {FACE_ON_DEG:g}° from a "
            f"photo) | {pct(s['dark_face_on_found'], s['dark_face_on'])} (of {s['dark_dropouts']} placed; "
            f"{s['dark_face_on_covered']} of the face-on covered) |"
        )
    lines += [
        "",
        "## Part-runs",
        "",
        "| part-run | photos | verdict | coverage slide / ink gone / scratch | part defects | reason |",
        "|---|---|---|---|---|---|",
    ]
    for r in runs:
        if "error" in r:
            lines.append(f"| {r['id']} | | ERROR | | | {r['error']} |")
            continue
        cov = "; ".join(
            "/".join("-" if c.get(k) is None else f"{100 * c[k]:.0f}%" for k in ("slide", "ink_gone", "scratch"))
            for c in r["coverage"]
        )
        pv = ", ".join(f"{k}: {v}" for k, v in r["photo_verdicts"].items())
        found = "; ".join(
            f"{d['kind']} {d['area_mm2']:.1f} ({d['centre_mm'][0]:.1f}, {d['centre_mm'][1]:.1f})"
            for d in r["part_defects"][:6]
        )
        if len(r["part_defects"]) > 6:
            found += f"; ... ({len(r['part_defects'])})"
        lines.append(f"| {r['id']} | {pv} | {r['verdict']} | {cov} | {found} | {md(r['reason'])} |")
    lines += [
        "",
        "## True defects",
        "",
        "| part-run | defect | centre mm | covered (share) | found | escape | face-on ° | what validate said |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for r in runs:
        for t in r.get("truth", []):
            share = "-" if t["covered_share"] is None else f"{100 * t['covered_share']:.0f} %"
            lines.append(
                f"| {r['id']} | {t['spec']} | ({t['centre_mm'][0]:.1f}, {t['centre_mm'][1]:.1f}) | "
                f"{'yes' if t['covered'] else 'no'} ({share}) | {'yes' if t['found'] else 'no'} | "
                f"{'**ESCAPE**' if t['escape'] else 'no'} | {t['face_on_deg']} | {md(t['why'])} |"
            )
    notes = [r for r in runs if r.get("placement_note")]
    if notes:
        lines += ["", "## Placement notes", ""]
        lines += [f"- {r['id']}: {r['placement_note']}" for r in notes]
    return "\n".join(lines) + "\n"


def md(text) -> str:
    return str(text or "").replace("|", "/").replace("\n", " ")


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--parts", default=",".join(PARTS))
    ap.add_argument("--renderer", choices=("workbench", "mitsuba", "both"), default="both")
    ap.add_argument("--looks", default="matte,glossy")
    ap.add_argument("--defects-per-part", type=int, default=4)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--dark-dropouts", action="store_true", help="only dropouts, on dark ink")
    ap.add_argument(
        "--dark-grey", type=float, default=DARK_GREY, help=f"dark ink: mean grey over the disc below this ({DARK_GREY})"
    )
    ap.add_argument("--size", default="2000x1500")
    ap.add_argument("--spp", type=int, default=8, help="Mitsuba samples per pixel (default 8)")
    ap.add_argument("--tolerance-mm", type=float, default=0.2)
    ap.add_argument(
        "--finish",
        choices=("look", "glossy", "matte"),
        default="look",
        help="validate --finish: the film each look renders (default), or one for every run",
    )
    ap.add_argument("--design-cache", type=Path, help="designs in DIR/designs/NAME (default: OUT)")
    ap.add_argument("--out", type=Path, default=ROOT / "out" / "random_defects")
    ap.add_argument("--revalidate", action="store_true")
    ap.add_argument("--name", help="the tables' file name (default random_defects[_dark])")
    ap.add_argument(
        "--add-suggested", type=int, default=0, metavar="K",
        help="a part INCOMPLETE gets the photo its validation suggests, up to K times (default 0)",
    )  # fmt: skip
    args = ap.parse_args(argv)
    args.out = args.out.resolve()
    args.out.mkdir(parents=True, exist_ok=True)
    name = args.name or ("random_defects_dark" if args.dark_dropouts else "random_defects")
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    renderers = ["workbench", "mitsuba"] if args.renderer == "both" else [args.renderer]
    looks = args.looks.split(",")
    t0 = time.perf_counter()
    runs: list[dict] = []
    plan = []
    for part in args.parts.split(","):
        design = design_part(part, (args.design_cache or args.out).resolve(), env)
        placed, note = place_defects(design, part, args.defects_per_part, args.seed, args.dark_dropouts, args.dark_grey)
        what = (
            ("dark" if args.dark_grey == DARK_GREY else f"dark{args.dark_grey:g}") if args.dark_dropouts else "random"
        )
        for renderer in renderers:
            for look in looks:
                ps = poses(part, design, args.size)
                base = f"{part}-{renderer}-{look}"
                plan.append(
                    (design, {"id": f"{base}-perfect", "kind": "perfect", "truth_placed": []}, part, renderer, look, ps)
                )
                defect_run = {
                    "id": f"{base}-{what}-s{args.seed}-k{args.defects_per_part}",
                    "kind": what,
                    "truth_placed": placed,
                    "placement_note": note,
                }
                plan.append((design, defect_run, part, renderer, look, ps))
    print(f"{len(plan)} part-runs", flush=True)
    for n, (design, run, part, renderer, look, ps) in enumerate(plan):
        run.update(part=part, renderer=renderer, look=look, poses=ps)
        if run["kind"] != "perfect" and not run["truth_placed"]:
            runs.append({**public(run), "error": f"no defect placed: {run.get('placement_note')}"})
            print(f"[{n + 1}/{len(plan)}] {run['id']}: skipped, {run.get('placement_note')}", flush=True)
            continue
        print(f"[{n + 1}/{len(plan)}] {run['id']}: {len(ps)} photos, {len(run['truth_placed'])} defects", flush=True)
        try:
            res = run_part(run, design, args, env)
        except (RuntimeError, subprocess.TimeoutExpired) as exc:
            res = {**public(run), "error": str(exc)}
        runs.append(res)
        if "error" in res:
            print(f"  ERROR {res['error']}", flush=True)
            continue
        print(f"  part {res['verdict']} ({res['validate_s']:.0f} s): {res['reason'][:200]}", flush=True)
        for t in res["truth"]:
            flag = "ESCAPE" if t["escape"] else ("found" if t["found"] else "not found")
            print(
                f"    {t['spec']}: covered {t['covered']} ({t['covered_share']}), {flag}: {t['why'][:160]}", flush=True
            )
    summary = rates(runs, args.dark_dropouts)
    command = "python benchmarks/random_defects.py " + " ".join(argv if argv is not None else sys.argv[1:])
    report = {"command": command, "seconds": round(time.perf_counter() - t0, 1), "rates": summary, "runs": runs}
    (args.out / f"{name}.json").write_text(json.dumps(report, indent=1, default=float) + "\n")
    (args.out / f"{name}.md").write_text(markdown(runs, summary, command, args))
    print(json.dumps(summary, indent=1))
    print(f"wrote {args.out / name}.json and .md ({report['seconds']} s)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
