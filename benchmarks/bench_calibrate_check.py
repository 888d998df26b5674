"""What drift ``workbench calibrate check`` can catch on a set of real photos: printed figures.

    .venv/bin/python benchmarks/bench_calibrate_check.py PHOTO... --board BOARD.json
        [--profile-photos N] [--splits 20] [--seed 0] [--fx-pct 1] [--pp-px 8] [--tolerance-sigma 3]
        [--block 1]

The photos of one camera are dealt at random, ``--splits`` times, into a profile made from
N of them (``calibrate camera``'s code: :func:`workbench.calibration.calibrate_views`) and
the check on the others (``calibrate check``'s code: :func:`workbench.calibration.check_views`).
Each split checks the true profile, and the same profile with its focal lengths scaled by
1 + fx-pct / 100, with cx moved by pp-px and with cy moved by pp-px. Printed:

- how often each fails the check (the true profile: false alarms), and how often it would
  with the plain limit |z| > tolerance-sigma (no Student's t for few photos);
- the null scatter: the RMS over the splits of (re-measured - profile) for the true profile,
  in px, which no statistic can beat (a drift well inside it is not in the photos);
- the RMS of the check's z for the true profile (near 1: the check's standard deviations
  are honest; well above 1: false alarms), and what it would be with OpenCV's own
  standard deviations alone (``calibrateCameraExtended``, which assume independent corner
  errors);
- the drift the check catches at its tolerance: tolerance-sigma x the median combined
  standard deviation;
- how often the drift each check states it catches (``calibrate check``'s power,
  :func:`workbench.calibration_power.check_power`), put in one intrinsic at a time, is caught.

Corners are detected once; photos of another size than most are left out, by name.
"""

from __future__ import annotations

import argparse
import sys
import time
from collections import Counter
from pathlib import Path

import cv2
import numpy as np

from workbench.calibration import (
    HOLD_DISTORTION,
    INTRINSICS,
    TOLERANCE_SIGMA,
    board_views,
    calibrate_views,
    check_views,
    fit_intrinsics,
)
from workbench.calibration_power import POWER_PROBABILITY, check_power
from workbench.errors import WorkbenchError
from workbench.printing.boards import load_board


def profile_of(cal) -> dict:
    """The fields of a ``calibrate camera`` profile that the check reads."""
    return {
        "K": cal.K.tolist(),
        "dist": cal.dist.tolist(),
        "image_size": list(cal.image_size),
        "rms_px": cal.rms_px,
        "intrinsics_std": dict(zip(INTRINSICS, map(float, cal.std), strict=True)),
        "view_rms_limit_px": cal.view_limit_px,
        "views": [{"name": v["name"], "used": v["used"]} for v in cal.per_view],
    }


def drifted(profile: dict, fx: float = 1.0, cx: float = 0.0, cy: float = 0.0) -> dict:
    """The profile with fx and fy scaled by ``fx`` and the principal point moved by (cx, cy) px."""
    K = np.asarray(profile["K"], dtype=np.float64).copy()
    K[0, 0] *= fx
    K[1, 1] *= fx
    K[0, 2] += cx
    K[1, 2] += cy
    return {**profile, "K": K.tolist()}


def fresh(views: list) -> tuple[list, list]:
    """Copies of views and their per-view records (calibrate_views and check_views change them)."""
    return list(views), [{"name": v[0], "corners": len(v[1]), "used": True} for v in views]


def measure(
    views: list,
    W: int,
    H: int,
    n_profile: int,
    splits: int = 20,
    seed: int = 0,
    fx_pct: float = 1.0,
    pp_px: float = 8.0,
    tolerance_sigma: float = TOLERANCE_SIGMA,
    block: int = 1,
) -> dict:
    """The check's false alarms and power over random splits of the views.

    Parameters
    ----------
    views : list of (name, (n, 3) board points, (n, 2) pixels)
        Every usable photo of one camera (:func:`workbench.calibration.board_views`).
    W, H : int
        Image size.
    n_profile : int
        Photos the profile is made from; the others are checked.
    splits, seed : int
        How many random splits, and their seed.
    fx_pct, pp_px, tolerance_sigma : float
        The drifts to catch, and the check's tolerance.
    block : int
        Views dealt in blocks of this many in their order: frames of one video, neighbours
        near duplicates of each other, go to one side as a lab's two days would (1: each alone).

    Returns
    -------
    dict
        ``splits`` (those where the profile could be made), ``fail`` (share of splits that
        fail, per case: true, fx, cx, cy), ``caught_by`` (share failing through the
        re-measured intrinsics), ``caught_plain`` (share whose re-measure has some
        |z| > tolerance_sigma: the limit without Student's t), ``null_rms_px`` and ``z_rms`` / ``z_rms_opencv`` (per
        intrinsic, true profile), ``sigma_median`` (combined, px), ``detectable``
        (tolerance x sigma_median: px, and for fx and fy also %), ``fx`` (the median
        profile focal length).
    """
    rng = np.random.default_rng(seed)
    cases = {"true": {}, "fx": {"fx": 1 + fx_pct / 100}, "cx": {"cx": pp_px}, "cy": {"cy": pp_px}}
    fail = {k: [] for k in cases}
    caught = {k: [] for k in cases}
    plain = {k: [] for k in cases}  # the re-measure's verdict with |z| > tolerance_sigma, Student's t left aside
    deltas, zs, zs_cv, sigmas, fxs = [], [], [], [], []
    at_limit = {k: [] for k in INTRINSICS}  # the stated drift caught, per split
    for _ in range(splits):
        blocks = [list(range(i, min(i + block, len(views)))) for i in range(0, len(views), block)]
        order = [i for b in rng.permutation(len(blocks)) for i in blocks[b]]
        P = [views[i] for i in sorted(order[:n_profile])]
        C = [views[i] for i in sorted(order[n_profile:])]
        try:
            cal = calibrate_views(*fresh(P), W, H)
        except WorkbenchError:
            continue  # a subset too alike to calibrate: calibrate camera would refuse it too
        prof = profile_of(cal)
        fxs.append(cal.K[0, 0])
        for case, drift in cases.items():
            chk = check_views(*fresh(C), drifted(prof, **drift), None, tolerance_sigma)
            fail[case].append(bool(chk.drift))
            caught[case].append(any(d.startswith("re-measured") for d in chk.drift))
            r = chk.remeasured
            if r is not None:
                plain[case].append(any(abs(r[k]["z"]) > tolerance_sigma for k in r["measured"]))
            if case == "true" and r is not None:
                # the drift the check states it catches (POWER_PROBABILITY of the time), put in
                # one intrinsic at a time: is it caught that often?
                stated = check_power(r, np.asarray(prof["K"]), fx_pct, pp_px)["caught_px"]
                for k, d in stated.items():
                    moved = {**prof, "K": [list(row) for row in prof["K"]]}
                    i, j = {"fx": (0, 0), "fy": (1, 1), "cx": (0, 2), "cy": (1, 2)}[k]
                    moved["K"][i][j] += d
                    at_limit[k].append(bool(check_views(*fresh(C), moved, None, tolerance_sigma).drift))
            if case == "true" and r is not None and len(r["measured"]) == len(INTRINSICS):
                deltas.append([r[k]["delta"] for k in INTRINSICS])
                zs.append([r[k]["z"] for k in INTRINSICS])
                sigmas.append([r[k]["sigma"] for k in INTRINSICS])
                # OpenCV's standard deviations alone, profile and re-measurement (same fit as the check's)
                K0, d0 = np.asarray(prof["K"]), np.asarray(prof["dist"])
                *_, std_m, _ = fit_intrinsics(C, W, H, HOLD_DISTORTION, (K0.copy(), d0.copy()))
                zs_cv.append(np.array(deltas[-1]) / np.sqrt(cal.std_opencv**2 + std_m**2))
    n = len(fail["true"])
    if not deltas:
        raise WorkbenchError("no split re-measured fx, fy, cx, cy: too few photos to check, or too little tilt")
    deltas, zs, zs_cv, sigmas = map(np.asarray, (deltas, zs, zs_cv, sigmas))
    sig = np.median(sigmas, axis=0)
    fx = float(np.median(fxs))
    return {
        "splits": n,
        "fail": {k: float(np.mean(v)) for k, v in fail.items()},
        "caught_by": {k: float(np.mean(v)) for k, v in caught.items()},
        "caught_plain": {k: float(np.mean(v)) if v else 0.0 for k, v in plain.items()},
        "null_rms_px": dict(zip(INTRINSICS, np.sqrt((deltas**2).mean(axis=0)).tolist(), strict=True)),
        "z_rms": dict(zip(INTRINSICS, np.sqrt((zs**2).mean(axis=0)).tolist(), strict=True)),
        "z_rms_opencv": dict(zip(INTRINSICS, np.sqrt((zs_cv**2).mean(axis=0)).tolist(), strict=True)),
        "sigma_median": dict(zip(INTRINSICS, sig.tolist(), strict=True)),
        "detectable": {
            **dict(zip(INTRINSICS, (tolerance_sigma * sig).tolist(), strict=True)),
            "fx_pct": float(100 * tolerance_sigma * sig[0] / fx),
        },
        "fx": fx,
        "at_stated_limit": {k: (float(np.mean(v)), len(v)) for k, v in at_limit.items() if v},
    }


def load_views(photos: list[str], board: dict) -> tuple[list, int, int, list[str]]:
    """Corners of every photo of the commonest size; the names of the others."""
    images = [(p, cv2.imread(p, cv2.IMREAD_GRAYSCALE)) for p in photos]
    bad = [p for p, g in images if g is None]
    if bad:
        raise WorkbenchError(f"{bad[0]}: cannot read image")
    (H, W), _ = Counter(g.shape[:2] for _, g in images).most_common(1)[0]
    odd = [f"{p}: {g.shape[1]} x {g.shape[0]} pixels, most are {W} x {H}" for p, g in images if g.shape[:2] != (H, W)]
    views, per_view = board_views([(p, g) for p, g in images if g.shape[:2] == (H, W)], board)
    left = [f"{v['name']}: {v['reason']}" for v in per_view if not v["used"]]
    return views, W, H, odd + left


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("photos", nargs="+")
    ap.add_argument("--board", required=True)
    ap.add_argument("--profile-photos", type=int, default=None, help="default: 60 %% of the usable photos")
    ap.add_argument("--splits", type=int, default=20)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--fx-pct", type=float, default=1.0)
    ap.add_argument("--pp-px", type=float, default=8.0)
    ap.add_argument("--tolerance-sigma", type=float, default=TOLERANCE_SIGMA)
    ap.add_argument("--block", type=int, default=1, help="deal the photos in blocks of this many, in their order")
    a = ap.parse_args(argv)
    t0 = time.perf_counter()
    views, W, H, left = load_views(a.photos, load_board(Path(a.board)))
    for why in left:
        print(f"left out {why}", file=sys.stderr)
    n_profile = a.profile_photos or int(round(0.6 * len(views)))
    print(f"{len(views)} usable photos of {W} x {H}: profiles from {n_profile}, checks on {len(views) - n_profile}")
    m = measure(views, W, H, n_profile, a.splits, a.seed, a.fx_pct, a.pp_px, a.tolerance_sigma, max(1, a.block))
    print(
        f"{m['splits']} splits (seed {a.seed}, blocks of {max(1, a.block)}), tolerance {a.tolerance_sigma:g} sigma; "
        f"median fx {m['fx']:.1f} px"
    )
    labels = {
        "true": "true profile",
        "fx": f"fx, fy x {1 + a.fx_pct / 100:g}",
        "cx": f"cx + {a.pp_px:g} px",
        "cy": f"cy + {a.pp_px:g} px",
    }
    for k, label in labels.items():
        fails, by, plain = 100 * m["fail"][k], 100 * m["caught_by"][k], 100 * m["caught_plain"][k]
        print(
            f"  {label:16s} fails {fails:5.1f} % of splits ({by:.1f} % by the re-measure; "
            f"{plain:.1f} % with |z| > {a.tolerance_sigma:g} alone)"
        )
    row = lambda key, fmt: "  ".join(f"{i} {fmt.format(m[key][i])}" for i in INTRINSICS)  # noqa: E731
    print("  null scatter (RMS re-measured - profile, px): " + row("null_rms_px", "{:.2f}"))
    print("  RMS z, true profile, the check's sigma:      " + row("z_rms", "{:.2f}"))
    print("  RMS z, true profile, OpenCV's sigma alone:   " + row("z_rms_opencv", "{:.2f}"))
    print("  median combined sigma (px):                  " + row("sigma_median", "{:.2f}"))
    d = m["detectable"]
    print(
        f"  caught at {a.tolerance_sigma:g} sigma: fx {d['fx']:.1f} px ({d['fx_pct']:.2f} %), "
        f"cx {d['cx']:.1f} px, cy {d['cy']:.1f} px"
    )
    stated = "  ".join(f"{k} {100 * share:.0f} % of {n}" for k, (share, n) in m["at_stated_limit"].items())
    print(f"  the drift each check states it catches ({100 * POWER_PROBABILITY:.0f} %), caught: {stated}")
    print(f"  {time.perf_counter() - t0:.0f} s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
