"""The smallest drift a camera check catches, from its own photos and the profile's uncertainty."""

from __future__ import annotations

import numpy as np

from workbench.calibration import MIN_VIEWS

# the drift a check states it catches is caught with this probability (one-sided normal quantile
# beyond its limit: a drift exactly at the limit is caught half the time)
POWER_PROBABILITY = 0.95


def check_power(remeasured: dict | None, K0: np.ndarray, focal_tolerance_pct: float, pp_tolerance_px: float) -> dict:
    """The smallest drift a camera check catches, from its own photos and the profile's uncertainty.

    A drift d of an intrinsic moves its z by d / σ (σ the combined standard deviation of the
    profile and the re-measurement); the check fails it when |z| exceeds its limit, so it is
    caught with probability POWER_PROBABILITY when d = (limit + q) σ, q the quantile of the
    same t distribution (the combined deviation's degrees of freedom) that leaves 1 -
    POWER_PROBABILITY below. The re-measurement's variance falls as 1 / photos, the
    profile's does not: a check of n photos reaches a tolerance T with
    n σ_photos² / ((T / (limit + q))² - σ_profile²) photos, when the profile's own
    uncertainty leaves room for it.

    Parameters
    ----------
    remeasured : dict or None
        :class:`workbench.calibration.CameraCheck`'s ``remeasured``.
    K0 : (3, 3) float
        The profile's camera matrix, px.
    focal_tolerance_pct, pp_tolerance_px : float
        The lab's tolerances: a focal length drift, %; a principal point move, px.

    Returns
    -------
    dict
        ``probability``; ``focal_pct`` (the larger of fx, fy, % of the profile's) and
        ``pp_px`` (the larger of cx, cy), None where not re-measured; ``caught_px``: each
        re-measured intrinsic's, px; ``short``: a sentence for
        each tolerance the check cannot see; ``photos_needed`` (None: no count of photos
        reaches it, the profile's own uncertainty is too large).
    """
    from scipy.stats import t

    out = {
        "probability": POWER_PROBABILITY,
        "focal_pct": None,
        "pp_px": None,
        "caught_px": {},
        "short": [],
        "photos_needed": None,
    }
    if remeasured is None:
        out["short"].append("no intrinsic was re-measured: the check sees no drift of them")
        return out
    n = int(remeasured["views"])
    focal = {"fx": float(K0[0, 0]), "fy": float(K0[1, 1])}
    caught, needed = {}, []
    for k in remeasured["measured"]:
        r = remeasured[k]
        reach = r["limit"] + float(t.isf(1 - POWER_PROBABILITY, r["dof"]))
        caught[k] = reach * r["sigma"]
        tol = focal_tolerance_pct / 100 * focal[k] if k in focal else pp_tolerance_px
        if caught[k] > tol:
            room = (tol / reach) ** 2 - r["sigma_profile"] ** 2
            needed.append(int(np.ceil(n * r["sigma_photos"] ** 2 / room)) if room > 0 else None)
    out["caught_px"] = caught
    focal_pct = [100 * caught[k] / focal[k] for k in focal if k in caught]
    pp = [caught[k] for k in ("cx", "cy") if k in caught]
    out["focal_pct"] = max(focal_pct) if focal_pct else None
    out["pp_px"] = max(pp) if pp else None
    if out["focal_pct"] is not None and out["focal_pct"] > focal_tolerance_pct:
        out["short"].append(
            f"this check cannot see a {focal_tolerance_pct:g} % focal drift with {n} photos "
            f"(it sees {out['focal_pct']:.2f} %)"
        )
    if out["pp_px"] is None:
        out["short"].append(f"the principal point is not re-measured with {n} photos (it needs {MIN_VIEWS}, tilted)")
    elif out["pp_px"] > pp_tolerance_px:
        out["short"].append(
            f"this check cannot see the principal point move by {pp_tolerance_px:g} px with {n} photos "
            f"(it sees {out['pp_px']:.1f} px)"
        )
    if needed:
        out["photos_needed"] = None if None in needed else max(needed)
    elif out["pp_px"] is None:
        out["photos_needed"] = MIN_VIEWS
    return out
