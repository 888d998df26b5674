"""The forming calibration loop against its truth: printed figures.

    .venv/bin/python benchmarks/bench_forming.py [--job fixtures/default/job.toml] [--scale 2]
        [--law creep:2,1.5+wave:0.5,0.5,40] [--random-mm 0] [--sheets 2] [--rounds 2]
        [--renderer workbench|mitsuba] [--work DIR] [--calibration-film]
        [--orbit-views "AZ,EL,DIST;..."] [--no-check0]

Designs the job; forms sheets by the known law (``render --forming``, each designed view at
``--scale`` times its image size, a little noise, each sheet its own seed), validates each
sheet's photos (one validation folder per view, under one folder per sheet), fits a forming
profile from ``--sheets`` sheets (``calibrate forming``), designs with it and forms a new
sheet of the compensated design. Per round it prints the new sheet's misregistration p95 as
validate measures it (tiles, mm on the part) and the truth: where each film point lands
against where the compensated design wants it (print mm, p95 over the film), with the times
of ``calibrate forming`` and of ``design`` with and without the profile. ``--orbit-views``
photographs each calibration sheet from those orbit positions too (``render --orbit``): the
film the designed views do not see.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))


SPP = 8  # Mitsuba's samples per pixel (--spp): the face mask's front view needs 24 for its pose (8: 2.3 px RMS)
RESUME = False  # --resume: a step whose outputs are there is not run again (its time is then None)


def done(*paths) -> bool:
    return RESUME and all(Path(p).exists() for p in paths)


def wb(*args, cwd=None) -> float:
    t0 = time.perf_counter()
    r = subprocess.run(
        [sys.executable, "-m", "workbench", *map(str, args), "-q"], cwd=cwd, capture_output=True, text=True
    )
    if r.returncode != 0:
        raise SystemExit(f"workbench {' '.join(map(str, args))}: {r.stderr.strip()}")
    return time.perf_counter() - t0


def views(design: Path) -> list[tuple[str, list[int]]]:
    info = json.loads((design / "design.json").read_text())
    return [(v["name"], v["camera"]["image_size"]) for v in info["views"]]


MIN_FOV_DEG = 45.0  # a narrower designed view sees no fixture marker: widened about its own axis


def view_camera(design: Path, name: str, scale: float, out: Path, min_fov_deg: float = MIN_FOV_DEG) -> Path:
    """The designed view's camera (its position and direction), its image ``scale`` times larger, and
    at least MIN_FOV_DEG wide so that the photo shows the fixture's markers; written to ``out``."""
    info = json.loads((design / "design.json").read_text())
    cam = next(v["camera"] for v in info["views"] if v["name"] == name)
    w, h = (int(round(x * scale)) for x in cam["image_size"])
    K = np.asarray(cam["K"], dtype=np.float64)
    K[:2] *= scale
    fov = np.degrees(2 * np.arctan(w / 2 / K[0, 0]))
    if fov < min_fov_deg:
        f = w / 2 / np.tan(np.radians(min_fov_deg / 2))
        K = np.array([[f, 0, (w - 1) / 2], [0, f, (h - 1) / 2], [0, 0, 1]])
    else:
        K[:2, 2] = [(w - 1) / 2, (h - 1) / 2]
    out.write_text(json.dumps({"K": K.tolist(), "dist": [0] * 5, "image_size": [w, h], "R": cam["R"], "t": cam["t"]}))
    return out


ORBIT_SIZE = "2400x1800"  # an orbit photo's pixels (--orbit-views), 40 degrees wide


def form_sheet(
    design: Path,
    out: Path,
    law: str,
    seed: int,
    scale: float,
    random_mm: float,
    renderer: str,
    min_fov=MIN_FOV_DEG,
    orbits=(),
) -> dict:
    """Photos of one formed sheet from every designed view (and from each ``orbits`` position: (az, el,
    dist) of ``render --orbit``), each validated in its own folder."""
    truth = None
    out.mkdir(parents=True, exist_ok=True)
    shots = [(name, None, None) for name, _ in views(design)]
    for o in orbits:
        az, el, dist = o[:3]
        held = o[3:] or None  # the part held turned by rx, ry, rz and moved by dx, dy, dz (a stand)
        tag = "" if held is None else "_held" + "_".join(f"{x:g}" for x in held)
        shots.append((f"orbit{az:g}_{el:g}{tag}", (az, el, dist), held))
    for name, orbit, held in shots:
        photo = out / f"{name}.png"
        if done(photo.with_suffix(".json"), out / name / "validation.json"):
            truth = json.loads(photo.with_suffix(".json").read_text())["forming"]
            continue
        if orbit is None:
            where = ["--camera", view_camera(design, name, scale, out / f"{name}-camera.json", min_fov)]
        else:
            where = ["--orbit", ",".join(f"{x:g}" for x in orbit), "--size", ORBIT_SIZE, "--fov-deg", "40"]
        extra = ["--renderer", "mitsuba", "--spp", str(SPP)] if renderer == "mitsuba" else ["--noise", "1"]
        hold = []
        if held is not None:
            hold = ["--part-rotation-deg", ",".join(f"{x:g}" for x in held[:3])]
            hold += ["--part-offset-mm", ",".join(f"{x:g}" for x in held[3:6])]
        wb("render", design, *where, "--forming", law, "--seed", seed,
           *(["--forming-random-mm", random_mm] if random_mm else []), *extra, *hold, "-o", photo)  # fmt: skip
        wb("validate", design, photo, "--camera", photo.with_suffix(".json"), "--out", out / name, "--jobs", "1",
           *hold)  # fmt: skip
        truth = json.loads(photo.with_suffix(".json").read_text())["forming"]
    return truth


def misregistration(sheet: Path) -> list[float]:
    """Each view's misregistration p95 (mm on the part) as validate measured it."""
    out = []
    for v in sorted(sheet.iterdir()):
        if (v / "validation.json").is_file():
            rep = json.loads((v / "validation.json").read_text())
            out += [(e.get("misregistration_mm") or {}).get("p95") for e in rep["photos"]]
    return out


def truth_residual(design: Path, law: str, shift=None, within: Path | None = None) -> float:
    """p95 of |where the film lands - where the design wants it|, print mm: over the films as printed,
    or ``within`` the blocks a sheet's validations measured. ``shift``: each film's random placement
    ((2,) for one film, (films, 2) for several)."""
    from workbench import forming as fm
    from workbench.calibration_forming import film_grids
    from workbench.design_dir import Design

    des = Design(design)
    frames = des.film_frames()
    shifts = np.zeros((len(frames), 2)) if shift is None else np.asarray(shift, dtype=np.float64).reshape(-1, 2)
    if within is None:
        pts = [g.points for g in film_grids(design)]
    else:
        pts = [[] for _ in frames]
        for v in within.iterdir():
            if (v / "landing.npz").is_file():
                z = np.load(v / "landing.npz")
                film = z["fused_film"] if "fused_film" in z.files else np.zeros(len(z["fused_q_mm"]), int)
                for k, fr in enumerate(frames):
                    pts[k].append(z["fused_q_mm"][film == k] - fr.origin_mm)
        pts = [np.concatenate(x) if x else np.zeros((0, 2)) for x in pts]
    comps = des.compensations()
    err = []
    for k, fr in enumerate(frames):
        g = pts[k]
        true = fm.parse_law(law, fr.size_mm)(g) + shifts[k]
        want = comps[k](g) if comps is not None else np.zeros_like(g)
        err.append(np.linalg.norm(true - want, axis=1))
    return float(np.percentile(np.concatenate(err), 95))


def run_loop(
    work: Path,
    job=ROOT / "fixtures" / "default" / "job.toml",
    law="creep:2,1.5+wave:0.5,0.5,40",
    scale=2.0,
    random_mm=0.0,
    sheets=2,
    rounds=2,
    renderer="workbench",
    calibration_film=False,
    log=print,
    min_fov=MIN_FOV_DEG,
    placement=None,
    seed0=1,
    check0=True,
    orbits=(),
) -> dict:
    """The loop; returns per round (0: uncompensated) the check sheet's figures and the times.

    The calibration sheets take the seeds ``seed0``, ``seed0 + 1``, ... (their noise and random
    placement); the check sheets 1000 + the round. ``check0``: form and measure the uncompensated
    check sheet (round 0). ``orbits``: (az, el, dist) of further photos of each calibration sheet.
    """
    work.mkdir(parents=True, exist_ok=True)
    t_plain = None if done(work / "d0" / "design.json") else wb("design", job, "--out", work / "d0")
    design, seed = work / "d0", seed0
    out: dict = {"design_s": t_plain, "rounds": []}
    log(f"design without a profile: {t_plain} s; law {law}, random {random_mm} mm, {sheets} sheets, {renderer}")
    r0 = {"truth_p95_mm": truth_residual(design, law)}
    if check0:
        check = work / "r0-check"
        form_sheet(design, check, law, 1000, scale, 0.0, renderer, min_fov)
        r0.update(
            misregistration_p95_mm=misregistration(check), truth_seen_p95_mm=truth_residual(design, law, within=check)
        )
    out["rounds"].append(r0)
    log(f"round 0: {r0}")
    for rnd in range(1, rounds + 1):
        film = design
        if calibration_film:
            film = work / f"calib{rnd}-design"
            if not done(film / "design.json"):
                wb("pdf", design, "--pattern", "forming", "-o", work / f"calib{rnd}.pdf")
        folders, truths = [], []
        for k in range(sheets):
            f = work / f"r{rnd}-sheet{k}"
            truths.append(form_sheet(film, f, law, seed, scale, random_mm, renderer, min_fov, orbits))
            seed += 1
            folders.append(f)
        prof = work / f"profile{rnd}.json"
        t_cal = None
        if not done(prof):
            t_cal = wb("calibrate", "forming", *folders, "-o", prof, *(["--placement", placement] if placement else []))
        films = json.loads(prof.read_text())["films"]
        p = films[0]
        t_des = None
        if not done(work / f"d{rnd}" / "design.json"):
            t_des = wb("design", job, "--forming-profile", prof, "--out", work / f"d{rnd}")
        design = work / f"d{rnd}"
        check = work / f"r{rnd}-check"
        form_sheet(design, check, law, 1000 + rnd, scale, 0.0, renderer, min_fov)
        # (sheets, films, 2): each sheet's random placement of each film
        shifts = np.array([np.reshape(t.get("random_shift_mm", [0.0, 0.0] * len(films)), (-1, 2)) for t in truths])
        r = {
            "calibrate_s": t_cal,
            "design_s": t_des,
            "design_ratio": t_des / t_plain if t_des and t_plain else None,
            "points": p["points"],
            "measured_share": p["measured_share"],
            "measured_share_on_part": p["measured_share_on_part"],
            "cv_rms_mm": p["cv_rms_mm"],
            "repeatability_mm": p["repeatability_mm"],
            "placement": {
                k: p["placement"].get(k)
                for k in ("shift_mm", "rotation_deg", "standard_error_mm", "systematic", "applied")
            },  # fmt: skip
            # what the sheets' random placements did: their spread per axis, and their mean (the profile
            # compensates it only when the sheets show it beyond their spread)
            "random_spread_mm": float(np.sqrt(shifts[:, 0].var(axis=0, ddof=1).mean())) if len(shifts) > 1 else None,
            "random_mean_mm": shifts[:, 0].mean(axis=0).tolist(),
            "misregistration_p95_mm": misregistration(check),
            "truth_p95_mm": truth_residual(design, law),
            "truth_seen_p95_mm": truth_residual(design, law, within=check),
        }
        if len(films) > 1:
            r["films"] = {
                f["name"]: {
                    k: f[k]
                    for k in ("points", "measured_share", "measured_share_on_part", "cv_rms_mm", "repeatability_mm")
                }
                for f in films
            }
        out["rounds"].append(r)
        log(f"round {rnd}: " + json.dumps(r))
    out["work"] = str(work)
    return out


def profile_difference(a: Path, b: Path, design: Path, within: Path) -> np.ndarray:
    """Mean over the blocks ``within`` measured of what profile ``a`` applies less what ``b`` does,
    per film; (films, 2) mm: how far the one print is moved from the other there."""
    from workbench import forming as fm
    from workbench.design_dir import Design

    pa, pb = fm.profile_fields(fm.read_profile(a)), fm.profile_fields(fm.read_profile(b))
    frames = Design(design).film_frames()
    out = np.zeros((len(frames), 2))
    for v in within.iterdir():
        if not (v / "landing.npz").is_file():
            continue
        z = np.load(v / "landing.npz")
        film = z["fused_film"] if "fused_film" in z.files else np.zeros(len(z["fused_q_mm"]), int)
        for k, fr in enumerate(frames):
            g = z["fused_q_mm"][film == k] - fr.origin_mm
            if len(g):
                out[k] = (pa[k](g) - pb[k](g)).mean(axis=0)
    return out


def placement_draws(work: Path, draws: int, sheets=5, random_mm=0.1, log=print, **kw) -> dict:
    """The random component through the whole loop: a noise-free reference (``sheets`` sheets without
    a random placement) and ``draws`` independent draws (seeds 100 j + 1 ...) with it; per draw, the
    reported repeatability against the draws' own spread and the nominal, the mean placement and the
    profile's, and how far the compensated print moves from the reference's (mean over the check
    sheet's measured blocks) in standard errors (random_mm / √sheets)."""
    se = random_mm / np.sqrt(sheets)
    ref = run_loop(work / "reference", sheets=sheets, rounds=1, random_mm=0.0, log=log, seed0=1, **kw)
    rows = []
    for j in range(1, draws + 1):
        res = run_loop(work / f"draw{j}", sheets=sheets, rounds=1, random_mm=random_mm, log=log, seed0=100 * j + 1,
                       check0=False, **kw)  # fmt: skip
        r1 = res["rounds"][1]
        diff = profile_difference(
            work / f"draw{j}" / "profile1.json",
            work / "reference" / "profile1.json",
            work / f"draw{j}" / "d0",
            work / f"draw{j}" / "r1-check",
        )[0]
        row = {
            "draw": j,
            "random_spread_mm": r1["random_spread_mm"],
            "repeatability_mm": r1["repeatability_mm"],
            "random_mean_mm": r1["random_mean_mm"],
            "placement": r1["placement"],
            "difference_mm": diff.tolist(),
            "difference_se": (diff / se).tolist(),
            # what the profile took in beyond the placements' own mean (which it cannot tell from a bias)
            "beyond_mean_mm": (diff - np.asarray(r1["random_mean_mm"])).tolist(),
            "misregistration_p95_mm": r1["misregistration_p95_mm"],
        }
        rows.append(row)
        log(f"draw {j}: " + json.dumps(row))
    d = np.array([r["difference_se"] for r in rows])  # (draws, 2): per axis, in SE
    summary = {
        "se_mm": se,
        "reference_misregistration_p95_mm": ref["rounds"][1]["misregistration_p95_mm"],
        "axes_within_one_se": int((np.abs(d) <= 1.0).sum()),
        "draws_within_one_se": int((np.linalg.norm(d, axis=1) <= 1.0).sum()),
        "draws": draws,
        "rms_difference_se_per_axis": float(np.sqrt((d * d).mean())),
        "beyond_mean_max_mm": float(np.abs([r["beyond_mean_mm"] for r in rows]).max()),
        "repeatability_within_20pct_of_spread": int(
            sum(abs(r["repeatability_mm"] / r["random_spread_mm"] - 1) <= 0.2 for r in rows)
        ),
        "repeatability_within_20pct_of_nominal": int(
            sum(abs(r["repeatability_mm"] / random_mm - 1) <= 0.2 for r in rows)
        ),
    }
    log("summary: " + json.dumps(summary))
    return {"reference": ref, "draws": rows, "summary": summary}


def synthetic_draws(design: Path, draws: int, sheets=5, random_mm=0.1, noise_mm=0.01, n=12000, law=None, seed=0):
    """The placement rule's statistics without photos: ``draws`` sets of ``sheets`` synthetic sheets
    (the law at ``n`` random film points, noise ``noise_mm`` per axis, a random placement each),
    each against the same sheets without the placements. Returns per draw the compensated print's
    shift from the noise-free one (mean over the film, mm), in standard errors, and whether the
    mean placement was compensated."""
    from workbench import forming as fm
    from workbench.calibration_forming import Sheet, calibrate_forming, film_grids
    from workbench.design_dir import Design

    des = Design(design)
    (fr,) = des.film_frames()
    g = film_grids(design)[0].points
    lw = fm.parse_law(law or "creep:2,1.5+wave:0.5,0.5,40", fr.size_mm)
    rng = np.random.default_rng(seed)
    se = random_mm / np.sqrt(sheets)
    out = []
    n = min(n, len(g))  # (the film's grid holds a point every few mm: at most all of them)
    for _ in range(draws):
        p = g[rng.choice(len(g), n, replace=False)] + rng.uniform(-0.5, 0.5, (n, 2))
        noise = [rng.normal(0, noise_mm, (n, 2)) for _ in range(sheets)]
        shifts = rng.normal(0, random_mm, (sheets, 2))

        def sheets_of(sh, p=p, noise=noise):
            return [
                Sheet(f"s{k}", p, lw(p) + sh[k] + noise[k], np.full(n, noise_mm), des.info, design, {"file": f"s{k}"})
                for k in range(sheets)
            ]

        b = calibrate_forming(sheets_of(np.zeros_like(shifts)))["films"][0]
        row = {
            "mean_placement_se": (shifts.mean(axis=0) / se).tolist(),
            "random_spread_mm": float(np.sqrt(shifts.var(axis=0, ddof=1).mean())),
        }
        for mode in ("always", "auto"):
            a = calibrate_forming(sheets_of(shifts), mode)["films"][0]
            diff = (a["applied"](g) - b["applied"](g)).mean(axis=0)
            row[mode] = {
                "difference_se": (diff / se).tolist(),  # per axis
                "compensated": bool(a["placement"]["compensated_parts"]["shift"]),
                "repeatability_mm": a["repeatability_mm"],
            }
        out.append(row)
    return out


def main() -> None:
    global RESUME, SPP
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--job", default=str(ROOT / "fixtures" / "default" / "job.toml"))
    ap.add_argument("--scale", type=float, default=2.0)
    ap.add_argument("--law", default="creep:2,1.5+wave:0.5,0.5,40")
    ap.add_argument("--random-mm", type=float, default=0.0)
    ap.add_argument("--sheets", type=int, default=2)
    ap.add_argument("--rounds", type=int, default=2)
    ap.add_argument("--renderer", default="workbench", choices=("workbench", "mitsuba"))
    ap.add_argument("--work", help="keep the files here (default: a temporary folder)")
    ap.add_argument(
        "--calibration-film",
        action="store_true",
        help="the calibration sheets are the calibration film (pdf --pattern forming), the check sheet the part",
    )
    ap.add_argument(
        "--min-fov-deg",
        type=float,
        default=MIN_FOV_DEG,
        help=f"a narrower designed view is widened to this about its own axis (default {MIN_FOV_DEG:g}; 0: never)",
    )
    ap.add_argument(
        "--orbit-views",
        metavar="AZ,EL,DIST[@RX,RY,RZ,DX,DY,DZ][;...]",
        help="the calibration sheets are photographed from these orbit positions too (render --orbit; "
        f"{ORBIT_SIZE} px, 40 degrees wide): the film the designed views do not see; after @, the part held on a "
        "stand turned by RX, RY, RZ degrees and moved by DX, DY, DZ mm (render and validate --part-rotation-deg, "
        "--part-offset-mm): film the plate hides",
    )
    ap.add_argument("--no-check0", action="store_true", help="do not form the uncompensated check sheet (round 0)")
    ap.add_argument("--placement", choices=("auto", "always", "never"), help="calibrate forming --placement")
    ap.add_argument("--draws", type=int, help="the random component over this many independent draws (the loop)")
    ap.add_argument("--synthetic-draws", type=int, help="the placement rule over this many draws without photos")
    ap.add_argument("--resume", action="store_true", help="keep the steps whose outputs are in --work")
    ap.add_argument("--spp", type=int, default=SPP, help=f"Mitsuba's samples per pixel (default {SPP})")
    a = ap.parse_args()
    RESUME, SPP = a.resume, a.spp
    work = Path(a.work) if a.work else Path(tempfile.mkdtemp(prefix="bench-forming-"))
    if a.synthetic_draws:
        wb("design", a.job, "--out", work / "d0")
        rows = synthetic_draws(work / "d0", a.synthetic_draws, a.sheets, a.random_mm or 0.1)
        (work / "synthetic-draws.json").write_text(json.dumps(rows, indent=1))
        m = np.array([r["mean_placement_se"] for r in rows])
        for mode in ("always", "auto"):
            d = np.array([r[mode]["difference_se"] for r in rows])  # (draws, 2) per axis, in SE
            comp = np.array([r[mode]["compensated"] for r in rows])
            rep = np.array([r[mode]["repeatability_mm"] / r["random_spread_mm"] for r in rows])
            nominal = np.abs(np.array([r[mode]["repeatability_mm"] for r in rows]) / (a.random_mm or 0.1) - 1) <= 0.2
            print(
                f"--placement {mode}, {len(rows)} draws of {a.sheets} sheets: the compensated print's shift from the "
                f"noise-free one within 1 SE per axis in {(np.abs(d) <= 1).mean():.1%} of axes, as a vector in "
                f"{(np.linalg.norm(d, axis=1) <= 1).mean():.1%} of draws; RMS per axis {np.sqrt((d * d).mean()):.3f} "
                f"SE; less the placements' own mean: at most {np.abs(d - m * comp[:, None]).max():.3f} SE; mean "
                f"placement compensated in {comp.mean():.1%}; repeatability / realised spread {rep.min():.3f} to "
                f"{rep.max():.3f}; / nominal within 20 % in {nominal.mean():.1%}"
            )
        return
    if a.draws:
        placement_draws(
            work, a.draws, a.sheets, a.random_mm or 0.1, log=lambda m: print(m, flush=True), job=a.job,
            scale=a.scale, law=a.law, renderer=a.renderer, min_fov=a.min_fov_deg, placement=a.placement,
        )  # fmt: skip
        return
    res = run_loop(
        work, a.job, a.law, a.scale, a.random_mm, a.sheets, a.rounds, a.renderer, a.calibration_film,
        log=lambda m: print(m, flush=True), min_fov=a.min_fov_deg, placement=a.placement, check0=not a.no_check0,
        orbits=[orbit_view(o) for o in a.orbit_views.split(";")] if a.orbit_views else (),
    )  # fmt: skip
    print(f"files in {res['work']}")


def orbit_view(text: str) -> tuple[float, ...]:
    """``AZ,EL,DIST`` or ``AZ,EL,DIST@RX,RY,RZ,DX,DY,DZ`` (the part held on a stand, turned and moved so)."""
    where, _, held = text.partition("@")
    out = tuple(float(x) for x in where.split(","))
    if held:
        h = tuple(float(x) for x in held.split(","))
        if len(h) != 6:
            raise SystemExit(f"--orbit-views {text}: after @, RX,RY,RZ,DX,DY,DZ (6 numbers)")
        out += h
    return out


if __name__ == "__main__":
    main()
