"""What a photo can find: its detection limit at every print pixel, stated before any defect is sought.

A photo finds a defect only where it measures what the defect changes. A film that slid
(a bubble) changes the misregistration, which the flow measures where the print has texture
the photo resolves, to a standard uncertainty set by the photo's noise through that texture
(and, for a window's slide, by what the photo's windows err by beyond it over the whole photo:
a median, which a defect does not move); ink that is gone changes the colour, which the
colour test sees where the step from the ink to the bare film exceeds the test's limit. Both
are known from the design, the photo's noise, its blur and its sampling of the print, so the
limit is stated for a sound part: the terms a defect itself raises where it is (the pixel's
own mismatch, the flow back's disagreement) are left out, and so are the masks that depend on the defect (light that is
told from ink). A defect the photo states it can find and does not find is an escape; one it
states it cannot find is below its stated limit.

validate writes the maps to ``detection.npz`` beside validation.json (referenced with its
sha256 under ``detection``; per photo ``photoK_shift_limit_um``, the smallest slide found,
µm on the surface, 65535 where none is, ``photoK_slide_sigma_um`` and
``photoK_window_sigma_um``, the stated uncertainties of its own full vector and of its window's
slide, ``photoK_dropout``, 1 where ink that is gone is found, and
``photoK_scratch``, 1 where a scratch is; the part's, best over its photos, as ``part_*``), the
figures to each photo's ``dense.detection_limit``, and a picture, ``*_detectable_print.png``.

A slide of the film is one field on the print, which every photo that measures it measures
(:mod:`workbench.validate.slide_fusion`): the part's smallest slide found is the best of each
photo's and of the photos' measures fused, whose uncertainty is that of their inverse-variance
mean, ``(Σ σ_k⁻²)^-½``.
"""

from __future__ import annotations

import hashlib

import numpy as np

NONE_UM = 65535  # shift_limit_um where no slide is found (uint16's largest)
# a true defect is above the stated limit when the maps find it over at least this share of
# its footprint (missing ink: then its area comes out within 25 %; a slid film: half of it
# textured, the rest between its textured parts, which sizing closes) and what they find
# exceeds the verdict's area (a smaller part of it seen passes by the rule)
DROPOUT_SHARE = 0.75
SHIFT_SHARE = 0.5


def expected_flow_sigma(noise: float, l1: np.ndarray, l2: np.ndarray, n_eff, floor_px):
    """The flow's standard uncertainty on a sound part: the photo's noise through the print's texture.

    σ² = σ_n² / (N λ) + floor² along an eigenvector of the structure tensor with eigenvalue
    λ, N the window's independent noise samples (:func:`workbench.validate.dense.flow_uncertainty`
    without its mismatch term, which a defect raises).

    Parameters
    ----------
    noise : float
        The photo's noise, grey levels.
    l1, l2 : (H, W) float32
        The model's structure tensor eigenvalues (strongest, weakest), grey levels² per px².
    n_eff : float or (H, W) float
        Independent noise samples in the flow's window
        (:func:`workbench.validate.dense.effective_samples`).
    floor_px : float or (H, W) float
        The flow's own floor, grid px (:func:`workbench.validate.dense.flow_floor`).

    Returns
    -------
    weak, strong : (H, W) float32
        Grid px along the weakest and the strongest direction (inf without texture).
    """
    with np.errstate(divide="ignore", invalid="ignore"):
        weak = np.sqrt(noise * noise / (n_eff * l2) + floor_px * floor_px)
        strong = np.sqrt(noise * noise / (n_eff * l1) + floor_px * floor_px)
    return (
        np.where(np.isfinite(weak), weak, np.inf).astype(np.float32),
        np.where(np.isfinite(strong), strong, np.inf).astype(np.float32),
    )


def shift_limit(
    tolerance_mm: float,
    z: float,
    weak_mm: np.ndarray,
    window_mm: np.ndarray,
    two_way: np.ndarray,
    measurable: np.ndarray,
    usable_mm: float,
    window_gain: float | np.ndarray = 1.0,
) -> np.ndarray:
    """The smallest slide of the film, in any direction, found at each print pixel, mm on the surface.

    A slide is found where the pixel measures the full vector (its texture has two
    directions, to within ``usable_mm``), or where the window of about a millimetre around it
    measures the slide its texture supports (:func:`workbench.validate.dense.tensor_weighted_flow`:
    edges that turn within it), and the slide exceeds the tolerance by ``z`` of the better of
    the two uncertainties. (A pixel on a single edge measures only the component across it,
    which a slide along the edge leaves 0: it finds a slide in some directions, and is not
    counted.)

    Parameters
    ----------
    tolerance_mm, z, usable_mm : float
        The tolerance (mm), the significance (standard uncertainties) and the largest
        uncertainty a measuring pixel may have (mm).
    weak_mm, window_mm : (H, W) float32
        Expected uncertainties, mm on the surface: the pixel's full vector
        (:func:`expected_flow_sigma`) and the window's slide.
    two_way, measurable : (H, W) bool
        Scored pixels the photo resolves whose print texture has two directions; all of them.
    window_gain : float or (H, W) float
        The share of a slide the window's slide answers: a slide s is found where
        ``window_gain`` s exceeds the tolerance by ``z`` of the window's uncertainty.

    Returns
    -------
    (H, W) float32
        mm; NaN where no slide is found.
    """
    limit = np.full(weak_mm.shape, np.inf, np.float32)
    full = two_way & (weak_mm <= usable_mm)
    limit[full] = tolerance_mm + z * weak_mm[full]
    window = measurable & (window_mm <= usable_mm)
    gain = np.broadcast_to(np.asarray(window_gain, np.float32), weak_mm.shape)
    limit[window] = np.minimum(limit[window], (tolerance_mm + z * window_mm[window]) / gain[window])
    return np.where(np.isfinite(limit), limit, np.nan).astype(np.float32)


def fused_shift_limit(sigmas_um: list, tolerance_mm: float, z: float, gain: float = 1.0) -> np.ndarray:
    """The smallest slide of the film found by the photos' measures fused, mm on the surface.

    Independent measures of one vector, each with standard uncertainty σ_k, fuse in their
    inverse-variance mean, whose uncertainty is ``(Σ σ_k⁻²)^-½``; a slide s is found where
    ``gain`` s exceeds the tolerance by ``z`` of that (as :func:`shift_limit` states a photo's
    own: ``gain`` 1 for the pixel's own vectors, the window's gain for the windows' slides).

    Parameters
    ----------
    sigmas_um : list of (H, W) uint16
        Each photo's stated uncertainty of one kind of measure (``photoK_slide_sigma_um``,
        the pixel's own full vector, or ``photoK_window_sigma_um``, the window's slide), µm;
        NONE_UM where it measures none.
    tolerance_mm, z : float
        The tolerance (mm) and the significance at which the limit is stated (standard
        uncertainties).
    gain : float
        The share of a slide the measure answers.

    Returns
    -------
    (H, W) float32
        mm; NaN where fewer than two photos measure the full vector.
    """
    info = np.zeros(sigmas_um[0].shape, np.float64)
    count = np.zeros(sigmas_um[0].shape, np.int32)
    for s in sigmas_um:
        ok = (s != NONE_UM) & (s > 0)
        info[ok] += 1.0 / (s[ok].astype(np.float64) * 1e-3) ** 2
        count += ok
    out = np.full(info.shape, np.nan, np.float32)
    two = count >= 2
    out[two] = (tolerance_mm + z / np.sqrt(info[two])) / gain
    return out


def summary(
    shift_mm: np.ndarray,
    dropout: np.ndarray,
    scored: np.ndarray,
    inked: np.ndarray,
    ink_step: float,
    scratch: np.ndarray | None = None,
) -> dict:
    """The detection limit's figures over what the photo scores.

    Parameters
    ----------
    shift_mm : (H, W) float32
        :func:`shift_limit`.
    dropout : (H, W) bool
        Where ink that is gone is found.
    scored, inked : (H, W) bool
        Scored pixels; scored pixels whose ink differs from the bare film.
    ink_step : float
        The smallest step from the ink to the bare film a dropout needs, grey levels (median).
    scratch : (H, W) bool, optional
        Where a scratch (a thin line of ink gone) is found.

    Returns
    -------
    dict
    """
    n = max(int(scored.sum()), 1)
    found = np.isfinite(shift_mm) & scored
    vals = shift_mm[found]
    return {
        "shift_found_share": round(float(found.sum() / n), 4),
        "min_shift_mm_p10": round(float(np.percentile(vals, 10)), 4) if len(vals) else None,
        "min_shift_mm_median": round(float(np.median(vals)), 4) if len(vals) else None,
        "dropout_found_share": round(float((dropout & scored).sum() / n), 4),
        "dropout_found_share_of_inked": (
            round(float((dropout & inked).sum() / max(int(inked.sum()), 1)), 4) if inked.any() else None
        ),
        "min_ink_step_grey_levels": round(float(ink_step), 1),
        **({"scratch_found_share": round(float((scratch & scored).sum() / n), 4)} if scratch is not None else {}),
    }


def to_stored(shift_mm: np.ndarray) -> np.ndarray:
    """``shift_limit`` as stored: µm, uint16, NONE_UM where no slide is found."""
    um = np.where(np.isfinite(shift_mm), np.rint(shift_mm * 1000.0), NONE_UM)
    return np.clip(um, 0, NONE_UM).astype(np.uint16)


def footprint_share(found: np.ndarray, footprint: np.ndarray) -> float:
    """Share of a defect's footprint (bool, grid pixels) where ``found`` holds; 0 for an empty footprint."""
    n = int(footprint.sum())
    return float((found & footprint).sum() / n) if n else 0.0


def above_limit(
    kind: str,
    footprint: np.ndarray,
    limit_um: np.ndarray,
    dropout: np.ndarray,
    slide_mm: float = 0.0,
    scratch: np.ndarray | None = None,
    area_mm2: float = 0.0,
    max_defect_mm2: float = 0.0,
):
    """Whether the photo states it finds a true defect of this kind over this footprint.

    Parameters
    ----------
    kind : str
        ``bubble`` (a slide of ``slide_mm``), ``dropout`` or ``scratch`` (ink gone; a
        scratch by the scratch map where there is one).
    footprint : (H, W) bool
        The defect's pixels on the grid.
    limit_um, dropout, scratch : (H, W)
        A photo's stored maps (``photoK_shift_limit_um``, ``photoK_dropout``, ``photoK_scratch``).
    area_mm2, max_defect_mm2 : float
        The defect's area and the verdict's: the share of it found must exceed the latter.

    Returns
    -------
    above : bool
    share : float
        The share of the footprint found.
    """
    if kind == "bubble":
        share = footprint_share(limit_um < slide_mm * 1000.0, footprint)
        need = SHIFT_SHARE
    else:
        found = scratch if kind == "scratch" and scratch is not None else dropout
        share = footprint_share(found.astype(bool), footprint)
        need = DROPOUT_SHARE
    return share >= need and share * area_mm2 > max_defect_mm2, share


def part_maps(entries: list[dict]) -> dict:
    """Take each photo's detection maps out of its entry; they and the part's, the best over its photos.

    Parameters
    ----------
    entries : list of dict
        The photos' entries; their ``detection_maps`` are taken out.

    Returns
    -------
    dict of name to (H, W) array
        ``photoK_shift_limit_um``, ``photoK_slide_sigma_um``, ``photoK_window_sigma_um``,
        ``photoK_dropout``, ``photoK_scratch`` per scored photo K, and ``part_*``: the smallest slide any photo
        finds (:func:`workbench.validate.slide_fusion.fused_part_limit` adds their fusion's), ink gone and
        scratches any photo finds; empty when no photo was scored.
    """
    arrays: dict = {}
    part_limit = part_drop = part_scratch = None
    for k, e in enumerate(entries):
        got = e.pop("detection_maps", None)
        if got is None:
            continue
        arrays[f"photo{k}_shift_limit_um"] = got["shift_limit_um"]
        if "slide_sigma_um" in got:
            arrays[f"photo{k}_slide_sigma_um"] = got["slide_sigma_um"]
        if "window_sigma_um" in got:
            arrays[f"photo{k}_window_sigma_um"] = got["window_sigma_um"]
        arrays[f"photo{k}_dropout"] = got["dropout"]
        arrays[f"photo{k}_scratch"] = got["scratch"]
        part_limit = got["shift_limit_um"] if part_limit is None else np.minimum(part_limit, got["shift_limit_um"])
        part_drop = got["dropout"] if part_drop is None else (part_drop | got["dropout"])
        part_scratch = got["scratch"] if part_scratch is None else (part_scratch | got["scratch"])
    if part_limit is None:
        return {}
    arrays["part_shift_limit_um"] = part_limit
    arrays["part_dropout"] = part_drop
    arrays["part_scratch"] = part_scratch
    return arrays


def add_to_report(report: dict, arrays: dict, out) -> dict:
    """The side file ``detection.npz`` of :func:`part_maps`' arrays, and ``report["detection"]``: its name,
    sha256 and what it holds."""
    from workbench.validate.landing import npz_bytes

    if not arrays:
        return {}
    data = npz_bytes(arrays)
    report["detection"] = {
        "file": "detection.npz",
        "sha256": hashlib.sha256(data).hexdigest(),
        "note": (
            "what each photo can find, per pixel of the print's analysis grid (dense.grid_px_per_mm): "
            f"photoK_shift_limit_um, the smallest slide of the film it finds (µm on the surface, {NONE_UM}: none), "
            "photoK_slide_sigma_um and photoK_window_sigma_um, the stated uncertainties of its own full vector "
            "and of the window's slide (µm), "
            "photoK_dropout, 1 where it finds ink that is gone, and photoK_scratch, 1 where it finds a scratch; "
            "part_*: the best over the photos (a slide: also their measures fused). Stated for "
            "a sound part, from the design, the photo's noise, blur and sampling: a defect found nowhere here is "
            "below the stated limit"
        ),
    }
    return {out / "detection.npz": data}
