"""The acceptance rule: a photo's figures to PASS, FAIL, INCOMPLETE or INVALID, and the rule's text for the report."""

from __future__ import annotations

import numpy as np

from workbench.validate import dense
from workbench.validate.photo_quality import QualityOptions

MAX_RMS_PX = 1.0
MIN_TILES = 5
MIN_TILES_BEYOND = 2  # tiles beyond the tolerance a misregistration FAIL needs (see photo_verdict)
MIN_SSIM = 0.5
# below this share of the view's textured tiles matching, the verdict's reason says so: on
# low-contrast artwork a perfect part matches 39 to 68 % of them, half a part painted over 41 %
# (measured), so the share tells nothing; what is painted over, torn or covered is the dense
# colour test's to find
MIN_MATCHED_SHARE = 0.7
MAX_DEFECT_MM2 = 4.0
# with fewer than MIN_TILES tiles, the dense field measures placement where it holds at least
# this many independent accurate flow windows (each about a millimetre across): four times the
# tiles' minimum, since a window holds about a tenth of a tile's pixels
MIN_DENSE_WINDOWS = 4 * MIN_TILES
# mean CIEDE2000 between the photo, corrected by the fixture's chart, and the design's soft proof:
# about what a trained eye sees side by side; a wrong ink or profile gives 4 to 9
MAX_DELTA_E = 3.0
TOO_LITTLE_TEXTURE = "too little texture to measure misregistration here; add texture or a calibration film"
# what decides a region one photo cannot tell ink gone from light on (a glossy film's glint)
OPEN_WORDS = (
    f"a photo from more than {dense.APART_DEG:g}° away (seen from the surface) tells: a defect stays at its print "
    "position in both, a glint does not (or --finish matte, if the film adds no light)"
)
# ... and a slide one photo cannot tell from a smooth light on, on either finish
OPEN_SLIDE_WORDS = (
    f"a photo from more than {dense.APART_DEG:g}° away (seen from the surface) tells: a slide stays at its print "
    "position in both, a glint does not (a light the film's shading model misses, on a matte film, may not move)"
)


def verdict_rule(
    tolerance_mm: float,
    max_defect_mm2: float,
    max_delta_e: float = MAX_DELTA_E,
    min_coverage: float | None = None,
    finish: str = "glossy",
) -> dict:
    """The acceptance rule, as it goes into validation.json and the QA report.

    Parameters
    ----------
    tolerance_mm, max_defect_mm2, max_delta_e : float
        The verdict's limits: misregistration (mm), a defect's area (print mm²), mean ΔE00.
    min_coverage : float, optional
        The part's coverage needed for a PASS (0 to 1); None: the photos' rule alone.
    finish : str
        The film's, ``"glossy"`` or ``"matte"``: what a region no photo tells from light is.

    Returns
    -------
    dict
        ``text`` and the figures it names.
    """
    z = dense.SIGNIFICANCE_Z
    if finish == "matte":
        untold = (
            "one the photo cannot tell is ink gone: a matte film adds no light of its own and mirrors no lamp "
            "(light on its ink is a gain of the ink, within the shading allowance); a slide a smooth light explains "
            "as well is open (the matte film's shading model misses light too)"
        )
    else:
        untold = (
            "one the photo cannot tell is light only where the surface mirrors the photo's lamp, and not measured "
            "there; elsewhere it is open (the film is glossy): the photo is INCOMPLETE, and the part decides it, "
            f"ink gone where another photo from more than {dense.APART_DEG:g}° away finds it at the same print "
            "position, light where another photo sees the ink intact"
        )
    part = (
        ""
        if min_coverage is None
        else (
            " The part: FAIL when any photo fails (ink gone or a slide that another photo of the part measures "
            "and sees intact is light in the photo that found it, and does not count), when its photos' measures "
            "of the film's slide, fused, find a slide that no photo found alone (measured by two photos from "
            f"more than {2 * dense.MIRROR_DEG:g}° apart, beyond the tolerance by {z:g} of its uncertainty, over more "
            f"than {max_defect_mm2:g} mm²), or its colour fails (each "
            "print pixel from the photo that sees it most squarely, the mean against the limit; a photo's own "
            "colour then does not fail the part); PASS when its photos pass and "
            f"together can find a slide, ink gone and a scratch on at least {100 * min_coverage:.0f} % of each film "
            "where each would show; INCOMPLETE when they pass and cover less (the uncovered regions, why, and the "
            "next photo are reported), or when a region over that area no photo tells ink gone from light on "
            "stays open. A misregistration the film's fitted placement explains is reported as "
            "the placement, with the move that corrects it; local defects are sought in what remains."
        )
    )
    return {
        **({"min_coverage": min_coverage} if min_coverage is not None else {}),
        "finish": finish,
        "text": (
            f"FAIL when any defect is larger than {max_defect_mm2:g} mm² on the print, or the misregistration "
            f"p95 exceeds {tolerance_mm:g} mm by more than {z:g} times a measurement's uncertainty (from the tiles, "
            f"at least {MIN_TILES_BEYOND} of them and 5 % each beyond it by more than {z:g} times their own; "
            f"with fewer than {MIN_TILES} tiles, from the dense field where it is accurate), or the decoration "
            f"does not match the design (SSIM < {MIN_SSIM}), or the colour "
            f"differs from the design's soft proof by a mean CIEDE2000 above {max_delta_e:g} (the photo corrected "
            "by the fixture's colour chart; lightness that follows the surface's orientation, shading under a "
            "directional light, taken out and reported, and under such a light the print's overall lightness "
            "not judged; without a usable chart colour is not measured, which "
            "is no FAIL); INVALID when the photo is at fault (over-exposed: more than "
            f"{100 * QualityOptions.max_clipped_share:.0f} % of the inked print it sees clipped; a JPEG below "
            f"quality {QualityOptions.min_jpeg_quality:g}; no colour in the photo where the design has colour), or "
            "when neither "
            f"tiles nor the dense field can measure misregistration and no defect is found ({TOO_LITTLE_TEXTURE}); "
            "otherwise PASS. Tiles "
            "and dense pixels count by their own uncertainty against the photo's measured noise, not by a fixed "
            "contrast. A defect is a connected region of "
            f"at least {dense.MIN_DEFECT_MM2:g} mm² where the dense misregistration exceeds {tolerance_mm:g} mm "
            f"by more than {z:g} standard uncertainties (one-sided, 0.13 % per pixel), or where the colour "
            f"differs from the design by more than {dense.COLOUR_TOL:g} grey levels beyond what the photo's "
            "noise, its local blur and a half-pixel placement explain, after a local gain and offset fit per "
            "channel; each defect carries its significance and confidence, and one whose significance as a "
            f"region is below {z:g} does not fail the part. A colour region is ink gone or light by a "
            "photometric model (a likelihood ratio with the photo's noise: light keeps the ink's texture or goes "
            f"beyond the bare film, ink gone shows the film); {untold}. Light beyond the bare film, deep "
            "shadows, surface turned away from the camera, the photo's pixels along the part's outline and its folds, "
            "and detail finer than the photo resolves are masked, not scored for misregistration." + part
        ),
        "tolerance_mm": tolerance_mm,
        "max_defect_mm2": max_defect_mm2,
        "max_delta_e00_mean": max_delta_e,
        "min_defect_mm2": dense.MIN_DEFECT_MM2,
        "colour_tolerance_grey_levels": dense.COLOUR_TOL,
        "significance_z": z,
        "min_tiles": MIN_TILES,
        "min_tiles_beyond": MIN_TILES_BEYOND,
        "min_dense_windows": MIN_DENSE_WINDOWS,
        "min_ssim": MIN_SSIM,
    }


def significant(defect: dict) -> bool:
    """Whether a defect's region is beyond chance at the stated significance (``significance_z``)."""
    z = defect.get("significance_z")
    return z is None or z >= dense.SIGNIFICANCE_Z


def _number(v) -> float | None:
    """A finite number as float, else None."""
    try:
        f = float(v)
    except (TypeError, ValueError):
        return None
    return f if np.isfinite(f) else None


def defect_decision(defect: dict, max_defect_mm2: float) -> dict:
    """What decided a defect the analysis kept, and whether it fails the part, in values and in words.

    Parameters
    ----------
    defect : dict
        A photo's defect (``kind``, ``area_mm2``, ``significance_z``, and for a slide
        ``explained_share``, ``peak_mm``; for ink, ``colour_area_mm2``).
    max_defect_mm2 : float
        The verdict's largest accepted defect.

    Returns
    -------
    dict
        ``hypothesis`` (the film slid, ink gone, another colour; for a defect the photo cannot
        tell from light, ``unresolved``: the film slid or light, ink gone or light), ``z`` (its
        significance as a region), ``fails`` (bool), ``open`` (True for such a region over the
        verdict's area, significant: it fails nothing and passes nothing), ``words``.
    """
    # (any figure may be missing or None: a region the colour test found has no slide)
    z, peak, share = (_number(defect.get(k)) for k in ("significance_z", "peak_mm", "explained_share"))
    at_z = f" (z = {z:.1f})" if z is not None else ""
    kind = defect["kind"]
    if kind == "shift" and defect.get("unresolved"):
        hyp = "the film slid or light"
        under = _number(defect.get("explained_under_light_share"))
        what = (
            "its slide" + (f" (up to {peak:.2f} mm)" if peak is not None else "") + " exceeds the tolerance" + at_z
            + (f", but a smooth light explains the residual there as well ({100 * under:.0f} % with the light)"
               if under is not None else "")
            + ", with no lamp the photo shows mirrored there: this photo cannot tell them"
        )  # fmt: skip
    elif kind == "shift":
        hyp = "the film slid"
        what = "its slide" + (f" (up to {peak:.2f} mm)" if peak is not None else "") + " exceeds the tolerance" + at_z
        if share:
            what += f"; the print moved by the flow explains {100 * share:.0f} % of the residual there"
    elif kind == "missing" and defect.get("unresolved"):
        hyp = "ink gone or light"
        sep = _number((defect.get("photometric") or {}).get("separation_sigma"))
        what = (
            "the photo steps from the ink towards the bare film's colour there, and light added over the ink "
            "looks the same"
            + (f" (the two {sep:.2f} σ of the photo's noise apart)" if sep is not None else "")
            + ", with no lamp the photo shows mirrored there: on a glossy film this photo cannot tell them"
            + at_z
        )
    elif kind == "missing":
        hyp = "ink gone"
        what = "the photo steps from the ink to the bare film's colour there and the light tests took it for no light"
        what += at_z
    else:
        hyp = "another colour"
        what = "the colour differs from the design's beyond the colour test's limit" + at_z
    big, sig = defect["area_mm2"] > max_defect_mm2, significant(defect)
    if big and sig and defect.get("unresolved"):
        words = OPEN_SLIDE_WORDS if kind == "shift" else OPEN_WORDS
        verdict = f"open: {defect['area_mm2']:.1f} mm² > {max_defect_mm2:g} mm², {words}"
        return {"hypothesis": hyp, "z": z, "fails": False, "open": True, "words": f"{what}; {verdict}"}
    if big and sig:
        verdict = f"fails: {defect['area_mm2']:.1f} mm² > {max_defect_mm2:g} mm²"
    elif not big:
        verdict = f"does not fail: {defect['area_mm2']:.1f} mm² is within the accepted {max_defect_mm2:g} mm²"
    else:
        verdict = f"does not fail: as a region it is not significant (z {z or 0.0:.2f} < {dense.SIGNIFICANCE_Z:g})"
    return {"hypothesis": hyp, "z": z, "fails": bool(big and sig), "words": f"{what}; {verdict}"}


def defects_reason(big: list[dict], max_defect_mm2: float) -> str:
    """The verdict's words for the defects over the limit (largest first)."""
    d = big[0]
    return (
        f"{len(big)} defect{'s' if len(big) > 1 else ''} > {max_defect_mm2:g} mm² (largest: {d['kind']}, "
        f"{d['area_mm2']:.1f} mm² at ({d['centre_mm'][0]:.1f}, {d['centre_mm'][1]:.1f}) mm on the print)"
    )


def judged_delta_e(colour: dict) -> dict:
    """A measured photo's ΔE00 figures as its verdict judges them: without the shading under a directional light."""
    shading = colour.get("shading") or {}
    return shading["delta_e00"] if shading.get("directional") else colour["delta_e00"]


def colour_verdict(colour: dict | None, max_delta_e: float = MAX_DELTA_E) -> tuple[str, str]:
    """The colour's part of the verdict: 'PASS', 'FAIL' or 'not measured', and its words.

    Parameters
    ----------
    colour : dict or None
        The photo's ``colour`` entry (:func:`workbench.validate.colour.measure_colour`).
    max_delta_e : float
        Largest accepted mean ΔE00. Under a directional light (``shading.directional``) the
        mean without the shading is judged, and the words say how much of it was shading.

    Returns
    -------
    status : str
    words : str
    """
    if not colour or not colour.get("measured"):
        return "not measured", (colour or {}).get("reason") or "colour not measured"
    de = colour["delta_e00"]["mean"]
    shading = colour.get("shading") or {}
    words = f"colour mean ΔE00 {de:.2f}"
    judged = judged_delta_e(colour)["mean"]
    if shading.get("directional"):
        words += (
            f", {judged:.2f} without the shading it cannot tell from ink ({100 * shading['share']:.0f} % of it is "
            f"lightness that follows the surface's orientation, mean |ΔL*| {shading['mean_abs_delta_l']:.1f}: "
            "a directional light)"
        )
    if judged > max_delta_e:
        return "FAIL", f"{words} > {max_delta_e:g}"
    return "PASS", f"{words} <= {max_delta_e:g}"


def placement(entry: dict, tolerance_mm: float) -> dict | None:
    """The film's placement as the technician acts on it: where it lies, the move that corrects it, and its verdict.

    The misregistration's p95 is the placement's when the film's fitted placement (offset,
    rotation, scale) explains it: once the film is moved as said, what remains, whose p95 is
    about twice the fit's rms residual (a normal scatter's 95th percentile is 1.96 σ), is
    within the tolerance. Then a p95 beyond the tolerance is a placement FAIL; otherwise it
    is the film's shape (forming), not where it lies.

    Parameters
    ----------
    entry : dict
        The photo's entry: ``film_offset_mm`` [x, y] (print mm, y down), ``film_rotation_deg``,
        ``film_scale_pct``, ``film_fit_rms_mm``, ``misregistration_mm``.
    tolerance_mm : float
        Largest accepted misregistration, mm.

    Returns
    -------
    dict or None
        ``verdict`` (PASS or FAIL), ``offset_mm``, ``rotation_deg``, ``scale_pct``, ``move_mm``
        and ``turn_deg`` (the correction: the opposite), ``explains`` (bool) and ``decided_by``
        (the figures that decided); None without a fitted placement.
    """
    off, rms = entry.get("film_offset_mm"), entry.get("film_fit_rms_mm")
    mis = entry.get("misregistration_mm") or {}
    if off is None or rms is None or mis.get("p95") is None:
        return None
    rot, scale, p95 = entry.get("film_rotation_deg") or 0.0, entry.get("film_scale_pct") or 0.0, mis["p95"]
    explains = 2.0 * rms <= tolerance_mm
    fail = explains and p95 > tolerance_mm
    decided = (
        f"misregistration p95 {p95:.3f} mm {'>' if p95 > tolerance_mm else '<='} tolerance {tolerance_mm:g} mm; "
        f"the film's fitted placement leaves an rms of {rms:.3f} mm (p95 about {2 * rms:.3f} mm), "
        + (
            "so the placement explains it"
            if explains
            else "more than the tolerance: the film's shape, not where it lies"
        )
    )
    return {
        "verdict": "FAIL" if fail else "PASS",
        "offset_mm": [float(off[0]), float(off[1])],
        "rotation_deg": float(rot),
        "scale_pct": float(scale),
        "move_mm": [-float(off[0]), -float(off[1])],
        "turn_deg": -float(rot),
        "explains": bool(explains),
        "decided_by": decided,
    }


def placement_words(place: dict) -> str:
    """The placement's action in words: where the film lies and the move that corrects it."""
    (x, y), r = place["offset_mm"], place["rotation_deg"]
    (mx, my), t = place["move_mm"], place["turn_deg"]
    return (
        f"film placed off by ({x:+.2f}, {y:+.2f}) mm, turned {r:+.2f}°, scaled {place['scale_pct']:+.2f} %: "
        f"move it by ({mx:+.2f}, {my:+.2f}) mm and turn it by {t:+.2f}° (print mm, x right, y down)"
    )


def photo_verdict(
    entry: dict, tolerance_mm: float, max_defect_mm2: float, max_delta_e: float = MAX_DELTA_E
) -> tuple[str, str]:
    """PASS, FAIL or INCOMPLETE of one scored photo, and why, from its figures in validation.json.

    INCOMPLETE: nothing fails it, and a region over the verdict's area is ``unresolved``: the
    photo cannot tell ink gone from light there (:func:`defect_decision`).

    Parameters
    ----------
    entry : dict
        The photo's entry: ``tiles``, ``tiles_examined``, ``ssim``, ``misregistration_mm``,
        ``misregistration_source`` ("tiles", "dense" or None) and ``defects`` (each with
        ``kind``, ``area_mm2``, ``centre_mm``), ``colour`` and ``photo_quality`` when measured
        (a photo with ``photo_quality.problems`` is INVALID, whatever else it shows).
    tolerance_mm : float
        Largest accepted misregistration, mm on the surface.
    max_defect_mm2 : float
        Largest accepted defect, mm² on the print.
    max_delta_e : float
        Largest accepted mean ΔE00 (:func:`colour_verdict`).

    Returns
    -------
    verdict : str
    reason : str
    """
    tiles, examined, sim = entry["tiles"], entry["tiles_examined"], entry["ssim"]
    counted = [d for d in entry["defects"] if d["area_mm2"] > max_defect_mm2 and significant(d)]
    # (a region the photo cannot tell ink gone from light on fails nothing and passes nothing: open)
    big = [d for d in counted if not d.get("unresolved")]
    undecided = [d for d in counted if d.get("unresolved")]
    colour, colour_words = colour_verdict(entry.get("colour"), max_delta_e)
    if "colour" not in entry:
        colour_words = ""
    problems = (entry.get("photo_quality") or {}).get("problems")
    if problems:
        # what the photo shows of the print is the photo's fault: no figure of it judges the print
        return "INVALID", f"the photo is at fault, not the print: {'; '.join(problems)}"
    if sim is not None and sim < MIN_SSIM:
        return "FAIL", (
            f"the decoration does not match the design (SSIM {sim:.2f}, {tiles} tiles "
            "matched): wrong print, or badly damaged"
        )
    if tiles < MIN_TILES and entry.get("misregistration_source") != "dense":
        # the decoration matches (SSIM) but nothing measures where it lies; a defect the photo
        # does find still fails the part
        found = [defects_reason(big, max_defect_mm2)] if big else []
        found += [colour_words] if colour == "FAIL" else []
        if found:
            return "FAIL", f"{'; '.join(found)}; misregistration not measured: {TOO_LITTLE_TEXTURE}"
        if undecided:
            # (nor does a region it cannot tell from light pass, or let the part pass)
            return "INCOMPLETE", (
                f"{open_reason(undecided, max_defect_mm2)}; misregistration not measured: {TOO_LITTLE_TEXTURE}"
            )
        return "INVALID", f"{TOO_LITTLE_TEXTURE} ({tiles} tiles, SSIM {'-' if sim is None else f'{sim:.2f}'})"
    p95 = entry["misregistration_mm"]["p95"]
    src = "" if entry.get("misregistration_source", "tiles") == "tiles" else " (dense field)"
    # beyond the tolerance by more than SIGNIFICANCE_Z of what one measurement is uncertain by:
    # a perfect part's p95 must not fail on its tiles' own scatter
    unc = entry.get("misregistration_uncertainty_mm") or 0.0
    margin = dense.SIGNIFICANCE_Z * unc
    why = []
    # (and carried by tiles each beyond it by more than its own uncertainty, two at least: one
    # tile is one measurement, whose tails its uncertainty does not describe, as a shift defect
    # needs two flow windows; a glossy sheen pulled one tile of sixteen over a faint logo by 0.32
    # mm on a perfect part, and what is local is the defects' business)
    beyond = entry.get("tiles_beyond")
    carried = src != "" or beyond is None or beyond >= max(MIN_TILES_BEYOND, 0.05 * tiles)
    if p95 > tolerance_mm + margin and carried:
        beyond_words = f"misregistration p95{src} {p95:.3f} mm > tolerance {tolerance_mm} mm" + (
            f" by more than {dense.SIGNIFICANCE_Z:g} x its uncertainty {unc:.3f} mm" if unc else ""
        )
        place = placement(entry, tolerance_mm)
        # (the action first: where the film lies and how to move it, when its placement explains it)
        why.append(f"{placement_words(place)} ({beyond_words})" if place and place["explains"] else beyond_words)
    if big:
        why.append(defects_reason(big, max_defect_mm2))
    if colour == "FAIL":
        why.append(colour_words)
    if why:
        return "FAIL", "; ".join(why)
    few = ""
    if src == "" and tiles < MIN_MATCHED_SHARE * examined:
        few = f" (from the {tiles} of {examined} textured tiles that match the design)"
    # (the defects told: the open regions are said apart)
    told = [d for d in entry["defects"] if not d.get("unresolved")]
    over = [d for d in told if d["area_mm2"] > max_defect_mm2]
    # (a p95 over the tolerance but within its uncertainty says so: "0.222 <= 0.2" is no reason)
    if p95 <= tolerance_mm:
        within = f"<= tolerance {tolerance_mm} mm"
    elif p95 <= tolerance_mm + margin:
        within = f"within tolerance {tolerance_mm} mm + {dense.SIGNIFICANCE_Z:g} x its uncertainty {unc:.3f} mm"
    else:
        within = (
            f"> tolerance {tolerance_mm} mm in {beyond} tile{'s' if beyond != 1 else ''} only: "
            "not the part's misregistration"
        )
    passed = (
        f"misregistration p95{src} {p95:.3f} mm{few} {within}, "
        + (
            f"no defect > {max_defect_mm2:g} mm²"
            if not told
            else f"{len(told)} defect(s), none > {max_defect_mm2:g} mm²"
            + (f" at significance {dense.SIGNIFICANCE_Z:g} ({len(over)} larger but not significant)" if over else "")
        )
        + (f"; {colour_words}" if colour_words else "")
    )
    if undecided:
        return "INCOMPLETE", f"{open_reason(undecided, max_defect_mm2)}; {passed}"
    return "PASS", passed


def still_open(defect: dict, max_defect_mm2: float) -> bool:
    """Whether a part's defect is still open and counts for its verdict.

    No photo told it from light (``unresolved``), a photo found it significant
    (``significant``), and it is larger than ``max_defect_mm2`` (print mm²).
    """
    return bool(defect.get("unresolved")) and bool(defect.get("significant")) and defect["area_mm2"] > max_defect_mm2


def open_reason(undecided: list[dict], max_defect_mm2: float) -> str:
    """The verdict's words for the regions over the limit a photo cannot tell a defect from light on.

    Parameters
    ----------
    undecided : list of dict
        The open regions (``area_mm2``, ``centre_mm``, print mm), at least one.
    max_defect_mm2 : float
        The verdict's area, print mm².

    Returns
    -------
    str
        How many, the largest with its place, and what decides them.
    """
    d = max(undecided, key=lambda x: x["area_mm2"])
    n = len(undecided)
    words = OPEN_SLIDE_WORDS if all(x.get("kind") == "shift" for x in undecided) else OPEN_WORDS
    return (
        f"{n} region{'s' if n > 1 else ''} > {max_defect_mm2:g} mm² the photo cannot tell a defect from light on "
        f"(largest: {d['area_mm2']:.1f} mm² at ({d['centre_mm'][0]:.1f}, {d['centre_mm'][1]:.1f}) mm on the "
        f"print): {words}"
    )
