"""The part: what all its photos show together on its print, and its verdict."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from workbench.validate import dense, print_warp
from workbench.validate.dense import APART_DEG
from workbench.validate.rule import defect_decision, judged_delta_e, significant
from workbench.validate.slide_evidence import claim_seen_in_place
from workbench.validate.slide_fusion import angle_deg, camera_rays


def light_in_one_photo(
    entries: list[dict],
    states: list,
    maps: dict,
    px_per_mm: float,
    max_defect_mm2: float,
    X: np.ndarray | None = None,
    slides: list | None = None,
) -> list:
    """Ink gone, or a slide, that another photo of the part sees intact: light in the photo that found it.

    Ink that is gone stays at its print position in every photo, and so does a slid film; a
    glint or a reflection moves with the camera. A region a photo takes for ink gone
    (``missing``) is light when another photo of the part measured it, found no defect there, and
    states that it finds ink gone there (its detection map, ``photoK_dropout`` or
    ``photoK_scratch``, over at least DROPOUT_SHARE of the region: the share at which the stated
    limit counts a dropout as found). A region it takes for a slide (``shift``) is light when
    another photo measured it, found no defect there, and states that it finds a slide as large
    as the region's there (``photoK_shift_limit_um`` at most its peak, over at least SHIFT_SHARE
    of the region): a glint on a glossy cow pulled one photo's flow up to 0.44 mm over 17 mm²
    where three others, which state slides from 0.40 to 0.43 mm there, saw the print in place.
    A slide is light too where another photo *measured* the print there in place: the film's
    slide is one field on the print, and each photo measures a projection of it (the full vector,
    or the component across an edge); where another photo measured the same component at the
    claim's pixels significantly smaller and its own slide there within the tolerance, over at
    least SHIFT_SHARE of them (:mod:`workbench.validate.slide_evidence`), the slide moved with
    the camera. Its stated limit there may be coarse for a slide in any direction (a ring's edge
    tells only the component across it) while its measure across the edge is fine (a glint along
    the lily's ring pulled a suggested photo's flow 2.97 mm across it, z 122, where the four other
    photos, stating 6.7 to 9 mm for a slide in any direction, measured the ring in place).
    The other photo must see the region from more than MIRROR_DEG away (seen from the surface):
    from nearly the same direction it would show the same reflection, and a disagreement there
    says the two photos are not of one print under one light. The defect stays in its photo's
    entry as its photo found it; for the part it is dismissed, with what decided it.

    Unless a third photo, from another direction, found it there too: the same glint at the
    same print position in two photos needs one lamp mirrored into both cameras, and reflection
    keeps the angle between two rays, so the two photos' mirror directions there lie as far apart
    as their cameras seen from the surface point. Cameras more than twice MIRROR_DEG apart (the
    lamp's reach either side, as :func:`workbench.validate.dense.mirrors_highlights` takes it)
    cannot share it: their agreement is the print's, and one photo that saw nothing there is overruled
    (a 20 mm scratch on the scanned face, Mitsuba, glossy: found in three photos 30° apart,
    14 to 21 mm², and dismissed in all three by the photo from above, which saw nothing of it).

    Parameters
    ----------
    entries : list of dict
        The photos' entries (``defects`` with ``kind``, ``area_mm2``, ``bbox_mm``).
    states : list of (H, W) uint8 or None
        Each photo's state map on the print's grid (None: not scored).
    maps : dict
        The detection maps (:func:`workbench.validate.detection.part_maps`), ``photoK_*`` by entry.
    px_per_mm : float
        The grid's resolution.
    max_defect_mm2 : float
        Only defects over the verdict's area are checked (the others do not fail the part).
    X : (H, W, 3) float, optional
        The surface point under each grid pixel, mm: with the photos' ``pose.camera_center_mm``,
        the directions from which each photo saw a region (without it, no photo is overruled).
    slides : list of SlideMeasure or None, optional
        Each photo's measure of the slide (``DenseResult.slide``); None: not compared.

    Returns
    -------
    list of dict
        One per defect dismissed: ``photo_index``, ``photo`` (its file name), ``id`` (the
        defect's in that photo), ``kind``, ``area_mm2``, ``centre_mm`` and ``decided_by``
        (``hypothesis`` light, the ``photo`` that sees the ink, the ``share`` of the region it
        measured and would find ink gone, or the slide, in, ``found_as``: what the photo that
        found it decided, ``words``).
    """
    from workbench.validate.detection import DROPOUT_SHARE, SHIFT_SHARE

    out = []
    for a, (ea, sa) in enumerate(zip(entries, states, strict=True)):
        if sa is None:
            continue
        for d in ea.get("defects", []):
            # (the slide as the photo states it: "up to" its peak)
            slide_um = 1000.0 * float(d.get("peak_mm") or 0.0)
            if d["area_mm2"] <= max_defect_mm2 or not (d["kind"] == "missing" or (d["kind"] == "shift" and slide_um)):
                continue
            box = print_warp.box_slices(d["bbox_mm"], px_per_mm)
            region = sa[box] == print_warp.DEFECT
            n = int(region.sum())
            if n == 0:
                continue
            if _found_from_elsewhere(a, d, region, box, entries, states, X, px_per_mm) is not None:
                continue  # (kept: two photos from directions no one lamp serves both found it)
            for b, sb in enumerate(states):
                if b == a or sb is None or f"photo{b}_dropout" not in maps:
                    continue
                if (
                    apart := _apart_deg(entries[a], entries[b], d, X, px_per_mm)
                ) is not None and apart <= dense.MIRROR_DEG:
                    continue  # (a light one photo shows, another from the same direction shows too)
                # (where the other photo measured and found no defect: only there does it overrule)
                clean = np.isin(sb[box], print_warp.MEASURED) & (sb[box] != print_warp.DEFECT)
                if d["kind"] == "shift":
                    finds, need, what = maps[f"photo{b}_shift_limit_um"][box] <= slide_um, SHIFT_SHARE, "a slide"
                    if (measured := _measured_in_place(a, b, d, box, clean, entries, slides)) is not None:
                        out.append(measured)
                        break
                else:
                    finds = maps[f"photo{b}_dropout"][box].astype(bool) | maps[f"photo{b}_scratch"][box].astype(bool)
                    need, what = DROPOUT_SHARE, "ink gone"
                share = float((region & finds & clean).sum()) / n
                if share >= need:
                    seen_by, found_in = Path(entries[b]["photo"]).name, Path(ea["photo"]).name
                    words = (
                        f"{seen_by} measured {100 * share:.0f} % of it, finds {what} there and found "
                        f"none: {what} stays on the print in every photo, so this is light in {found_in}"
                    )
                    out.append(_as_light(a, d, found_in, seen_by, share, words))
                    break
    return out


def _as_light(a: int, d: dict, found_in: str, seen_by: str, share: float, words: str, **more) -> dict:
    """Defect ``d`` of photo ``a`` dismissed for the part as light, with what decided it (``more``: its figures)."""
    return _decided(a, d, found_in, seen_by, "light", words, share=round(share, 3), **more)


def _decided(a: int, d: dict, found_in: str, seen_by: str, hypothesis: str, words: str, **more) -> dict:
    """Defect ``d`` of photo ``a`` as the part decided it, by photo ``seen_by`` (``more``: the figures that decided)."""
    return {
        "photo_index": a,
        "photo": found_in,
        "id": d.get("id"),
        "kind": d["kind"],
        "area_mm2": d["area_mm2"],
        "centre_mm": d["centre_mm"],
        "decided_by": {
            "hypothesis": hypothesis,
            "photo": seen_by,
            **more,
            "found_as": d.get("decided_by"),
            "words": words,
        },
    }


def _measured_in_place(
    a: int, b: int, d: dict, box: tuple, clean: np.ndarray, entries: list[dict], slides: list | None
) -> dict | None:
    """Photo ``b`` measured in place the slide photo ``a`` found in defect ``d``: ``a``'s light.

    None when it did not (or either measure is missing). The share is of ``a``'s claim pixels in
    the defect's ``box`` (:func:`workbench.validate.slide_evidence.claim_seen_in_place`), at
    SHIFT_SHARE at least, where ``b`` measured and found no defect (``clean``, over the box).
    """
    from workbench.validate.detection import SHIFT_SHARE

    if not slides or slides[a] is None or slides[b] is None or d.get("id") is None:
        return None
    share, b_mm = claim_seen_in_place(slides[a], slides[b], int(d["id"]), dense.SIGNIFICANCE_Z, box, clean)
    if share < SHIFT_SHARE:
        return None
    seen_by, found_in = Path(entries[b]["photo"]).name, Path(entries[a]["photo"]).name
    peak = float(d.get("peak_mm") or 0.0)
    words = (
        f"{seen_by} measured the print in place over {100 * share:.0f} % of where {found_in} has it slid "
        f"(a slide of {b_mm:.2f} mm there, median, against up to {peak:.2f} mm): a slide of the film moves "
        f"the print in every photo, so this is light in {found_in}"
    )
    return _as_light(a, d, found_in, seen_by, share, words, measured_there_mm=round(b_mm, 3))


def _apart_deg(ea: dict, eb: dict, d: dict, X: np.ndarray | None, px_per_mm: float) -> float | None:
    """The angle between two photos' cameras seen from a defect's centre on the surface, degrees.

    A light moves with the camera only as far as the camera moves: seen from the surface, two
    cameras within MIRROR_DEG of each other see one lamp's reflection alike. None: no angle
    known (without ``X``, or a camera or the point not known).
    """
    if X is None:
        return None
    cx, cy = (int(np.clip(v * px_per_mm, 0, n - 1)) for v, n in zip(d["centre_mm"], X.shape[1::-1], strict=True))
    va, vb = (camera_rays(X[cy, cx], (e.get("pose") or {}).get("camera_center_mm"), np.float64) for e in (ea, eb))
    if va is None or vb is None or not (np.isfinite(va).all() and np.isfinite(vb).all()):
        return None
    return angle_deg(va, vb)


def _found_from_elsewhere(a, d, region, box, entries, states, X, px_per_mm) -> int | None:
    """Another photo that found ink gone over most of a region, from a direction no lamp shares with photo ``a``."""
    if X is None:
        return None
    for c, sc in enumerate(states):
        if c == a or sc is None or (entries[c].get("photo_quality") or {}).get("problems"):
            continue
        if float((region & (sc[box] == print_warp.DEFECT)).sum()) < 0.5 * region.sum():
            continue
        if (apart := _apart_deg(entries[a], entries[c], d, X, px_per_mm)) is not None and apart > APART_DEG:
            return c
    return None


def open_told_elsewhere(
    entries: list[dict],
    states: list,
    px_per_mm: float,
    max_defect_mm2: float,
    X: np.ndarray | None = None,
    dismissed: list | None = None,
) -> list[dict]:
    """Open regions (a defect a photo cannot tell from light) another photo found at the same print position: defects.

    On a glossy film a photo cannot tell ink that is gone from a glint where the ink's colour
    with light added is the film's, nor a slide from a smooth light (``unresolved``). A glint at
    one print position in two photos needs one lamp mirrored into both cameras there, and
    reflection keeps the angle between two rays: cameras more than APART_DEG apart, seen from the
    surface, cannot share it. Another photo from that far that found a defect over most of the
    region (:func:`_found_from_elsewhere`) shows that it stays on the print: ink gone (or the film
    slid), which fails the part like any other.

    Parameters
    ----------
    entries : list of dict
        The photos' entries (``defects`` with ``unresolved``, ``area_mm2``, ``bbox_mm``, ``centre_mm``).
    states : list of (H, W) uint8 or None
        Each photo's state map on the print's grid.
    px_per_mm : float
        The grid's resolution.
    max_defect_mm2 : float
        Only regions over the verdict's area are decided (the others do not fail the part).
    X : (H, W, 3) float, optional
        The surface point under each grid pixel, mm (without it, no region is decided).
    dismissed : list of dict, optional
        The defects already dismissed as light (:func:`light_in_one_photo`).

    Returns
    -------
    list of dict
        One per region decided: ``photo_index``, ``photo``, ``id``, ``kind``, ``area_mm2``,
        ``centre_mm`` and ``decided_by`` (``hypothesis`` ink gone or the film slid, the
        ``photo`` that found it too, ``apart_deg``, ``words``).
    """
    gone = {(x["photo_index"], x["id"]) for x in dismissed or []}
    out = []
    for a, (ea, sa) in enumerate(zip(entries, states, strict=True)):
        if sa is None:
            continue
        for d in ea.get("defects", []):
            if not d.get("unresolved") or d["area_mm2"] <= max_defect_mm2 or (a, d.get("id")) in gone:
                continue
            box = print_warp.box_slices(d["bbox_mm"], px_per_mm)
            region = sa[box] == print_warp.DEFECT
            c = _found_from_elsewhere(a, d, region, box, entries, states, X, px_per_mm) if region.any() else None
            if c is None:
                continue
            apart = _apart_deg(ea, entries[c], d, X, px_per_mm)
            found_in, seen_by = Path(ea["photo"]).name, Path(entries[c]["photo"]).name
            what = "ink gone" if d["kind"] == "missing" else "the film slid"
            words = (
                f"{seen_by} found it too, at the same print position, from {apart:.0f}° away seen from the surface "
                f"(more than {APART_DEG:g}°: no one lamp is mirrored into both cameras there): it stays on the "
                f"print, {what}, not a glint in {found_in}"
            )
            out.append(_decided(a, d, found_in, seen_by, what, words, apart_deg=round(apart, 1)))
    return out


def decided_in_part(d: dict, told: dict | None, max_defect_mm2: float) -> dict:
    """A photo's defect as the part decided it: an open region another photo told is a defect.

    Parameters
    ----------
    d : dict
        The photo's defect.
    told : dict or None
        Its entry of :func:`open_told_elsewhere`; None: the part leaves it as the photo found it.
    max_defect_mm2 : float
        The verdict's area, print mm².

    Returns
    -------
    dict
        ``d`` (as it is), or a copy without ``unresolved``, decided again, with the part's words
        under ``decided_by.by_part``.
    """
    if told is None:
        return d
    kept = {k: v for k, v in d.items() if k != "unresolved"}
    kept["decided_by"] = {**defect_decision(kept, max_defect_mm2), "by_part": told["decided_by"]["words"]}
    return kept


def part_summary(
    states: list,
    grid,
    names: list[str],
    entries: list[dict],
    dismissed: list | None = None,
    in_part: dict | None = None,
    colour: dict | None = None,
) -> tuple[dict, np.ndarray, list]:
    """What all photos of the part show together, on its print.

    Each print pixel keeps the most telling state any photo gives it (defective over measured
    over masked over unseen); defects are the connected defective regions of that map.

    ``dismissed``: the photos' defects the part decided (:func:`light_in_one_photo`, light: not
    the part's; :func:`open_told_elsewhere`, ink gone: no longer open).

    Returns
    -------
    summary : dict
        verdict (FAIL when any photo fails, by its verdict in the part, ``in_part``, where another
        photo showed one of its defects to be light or ink gone or its colour is the part's to
        judge, or when the part's ``colour`` (:func:`workbench.validate.part_colour.fused_colour`)
        fails; else INCOMPLETE when a photo is, a region it cannot tell ink gone from light on
        still open; PASS when every scored photo passes, INVALID when none was scored), coverage
        of the part's print and of each view's region, defects (``unresolved`` when open),
        ``colour`` (:func:`colour_summary`) and, when its colour fails it, ``reason``.
    combined : (rows, cols) uint8
        The combined state map.
    defects : list of dict
        Part defects: centre_mm, area_mm2 (print), and the photos that show each.
    """
    scored = [s for s in states if s is not None]
    # (a photo's verdict in the part: without what another photo showed to be light in it)
    in_part = in_part or {}
    gone = {(x["photo_index"], x["id"]) for x in dismissed or [] if x["decided_by"]["hypothesis"] == "light"}
    told = {(x["photo_index"], x["id"]) for x in dismissed or [] if x["decided_by"]["hypothesis"] != "light"}
    verdicts = [in_part.get(k, (e["verdict"], None))[0] for k, e in enumerate(entries)]
    if "FAIL" in verdicts:
        verdict = "FAIL"
    elif "INCOMPLETE" in verdicts:
        verdict = "INCOMPLETE"
    elif "PASS" in verdicts:
        verdict = "PASS"
    else:
        verdict = "INVALID"
    colour_failed = verdict != "INVALID" and colour is not None and colour["verdict"] == "FAIL"
    verdict = "FAIL" if colour_failed else verdict
    if not scored:
        return {"verdict": verdict, "photos_scored": 0, "colour": colour_summary(entries, colour)}, None, []
    combined = np.maximum.reduce(scored)
    on = combined != print_warp.OFF_PART
    n_on = max(int(on.sum()), 1)
    # one defect seen in several photos is one defect of the part: photos' defects whose
    # boxes on the print overlap are merged (:func:`fused_view`)
    defects: list = []
    for k, e in enumerate(entries):
        if (e.get("photo_quality") or {}).get("problems"):
            continue  # the photo's fault (its colour defects are its clipping, its blocks)
        for d in e.get("defects", []):
            if (k, d.get("id")) in gone:
                continue  # light in this photo: another photo sees the ink (light_in_one_photo)
            x0, y0, x1, y1 = d["bbox_mm"]
            seen = _seen(d, e)
            seen["open"] = bool(d.get("unresolved")) and (k, d.get("id")) not in told
            seen["significant"] = significant(d)
            # (into the part defect whose box it overlaps most, among those this photo has not shown
            # yet: what one photo found apart stays apart, two dropouts 14 mm apart whose boxes
            # touched included; what several photos found at one place is one defect)
            best, most = None, 0.0
            for m in defects:
                a0, b0, a1, b1 = m["bbox_mm"]
                overlap = max(0.0, min(x1, a1) - max(x0, a0)) * max(0.0, min(y1, b1) - max(y0, b0))
                if overlap > most and seen["photo"] not in m["photos"]:
                    best, most = m, overlap
            if best is not None:
                a0, b0, a1, b1 = best["bbox_mm"]
                best["bbox_mm"] = [min(x0, a0), min(y0, b0), max(x1, a1), max(y1, b1)]
                best["photos"].append(seen["photo"])
                best["seen"].append(seen)
            else:
                defects.append(
                    {
                        "kind": d["kind"],
                        "centre_mm": d["centre_mm"],
                        "area_mm2": d["area_mm2"],
                        "bbox_mm": list(d["bbox_mm"]),
                        "view": d.get("view"),
                        "photos": [seen["photo"]],
                        "seen": [seen],
                    }
                )
    for m in defects:
        seen = m.pop("seen")
        best = fused_view(seen)
        m.update(centre_mm=best["centre_mm"], area_mm2=best["area_mm2"], kind=best["kind"])
        if all(x["open"] for x in seen):
            # (no photo told it: a defect or light, open; significant where a photo found it so)
            m["unresolved"] = True
            m["significant"] = any(x["significant"] for x in seen)
        if len(seen) > 1:
            m["located_by"] = best["photo"]
            m["area_mm2_by_photo"] = {x["photo"]: round(x["area_mm2"], 2) for x in seen}
    defects.sort(key=lambda d: (-d["area_mm2"], d["centre_mm"]))
    summary = {
        "verdict": verdict,
        "photos_scored": len(scored),
        "coverage_print": {
            print_warp.STATE_NAMES[k]: float((combined == k).sum() / n_on)
            for k in range(1, len(print_warp.STATE_NAMES))
        },
        "measured_share_of_part": float(np.isin(combined, print_warp.MEASURED).sum() / n_on),
        "coverage_by_view": dense.coverage_by_view(combined, grid.owner, names),
        "defects": defects,
        "colour": colour_summary(entries, colour),
    }
    if colour_failed:
        summary["reason"] = colour["words"]
    return summary, combined, defects


def add_found_together(part: dict, together: list[dict]) -> None:
    """The slides only the part's photos together find, into its summary (in place).

    Each is a defect of the part (``located_by`` ``fused``) and fails it: a slide larger than
    the verdict's area, beyond the tolerance significantly.

    Parameters
    ----------
    part : dict
        The part's summary (:func:`part_summary`): its ``defects``, ``verdict`` and ``reason``.
    together : list of dict
        The slides (:func:`workbench.validate.slide_fusion.slides_found_together`).
    """
    if not together:
        return
    for d in together:
        part.setdefault("defects", []).append({**d, "located_by": "fused"})
    part["defects"].sort(key=lambda d: (-d["area_mm2"], d["centre_mm"]))
    if part["verdict"] != "FAIL":
        part["verdict"] = "FAIL"
        part["reason"] = together[0]["decided_by"]["words"]


def _seen(d: dict, e: dict) -> dict:
    """One photo's view of a defect: its kind, centre and area on the print, and how finely the photo samples it."""
    x0, y0, x1, y1 = d["bbox_mm"]
    # photo px per print mm over the defect: the root of its area in the photo (the hull of its
    # projected points, foreshortened where the photo sees it obliquely) over its box's on the print
    return {
        "photo": Path(e["photo"]).name,
        "kind": d["kind"],
        "centre_mm": d["centre_mm"],
        "area_mm2": d["area_mm2"],
        "px_per_mm": float(np.sqrt(float(d.get("photo_area_px2") or 0.0) / max((x1 - x0) * (y1 - y0), 1e-6))),
    }


# a photo that finds less than this share of the largest area any photo finds sees only part of the
# defect (a band of it masked, at its edge or too oblique): it does not size it
SIZES_SHARE = 0.5


def fused_view(seen: list[dict]) -> dict:
    """A defect seen in several photos: its kind, and the median of its centres and areas over the photos.

    A photo that finds less than SIZES_SHARE of the largest area any photo finds sees only part of
    the defect (a band of it masked, at its edge or too oblique) and says nothing of its size or
    centre. Each of the others sizes it to within its rim's blur, which errs either way with the
    angle and the sampling (a 20 mm² dropout on the scanned face came out at 15.8, 26.1, 17.4 and
    27.5 mm² in four photos; the largest, which the part took, 37 % over; the finest, 30 % over):
    the median of those areas (21.8 mm² there), and of their centres, coordinate by coordinate (one
    photo's slid region may lie a millimetre off a 6 mm bubble's centre where another's does not).
    Ink gone that any photo finds is ink gone ("missing"): a photo of a glossy film that shows it
    partly under light finds a "colour" defect there.

    Parameters
    ----------
    seen : list of dict
        Per photo: ``photo``, ``kind``, ``centre_mm``, ``area_mm2`` and ``px_per_mm``.

    Returns
    -------
    dict
        ``photo`` (the finest view's: photo px per print mm), ``kind``, ``centre_mm`` and ``area_mm2``.
    """
    largest = max(x["area_mm2"] for x in seen)
    whole = [x for x in seen if x["area_mm2"] >= SIZES_SHARE * largest]
    finest = max(whole, key=lambda x: (x["px_per_mm"], x["area_mm2"]))
    kinds = [x["kind"] for x in seen]
    kind = "missing" if "missing" in kinds else finest["kind"]
    centre = np.median(np.array([x["centre_mm"] for x in whole], np.float64), axis=0).tolist()
    return {**finest, "kind": kind, "centre_mm": centre, "area_mm2": float(np.median([x["area_mm2"] for x in whole]))}


def colour_summary(entries: list[dict], fused: dict | None = None) -> dict:
    """The part's colour over its photos: each measured photo's mean ΔE00, the worst, and the colour's verdict.

    With ``fused`` (:func:`workbench.validate.part_colour.fused_colour`: each print pixel from the
    photo that sees it most squarely) the verdict is the fused colour's, its figures and the
    photos that decided them beside; without it, FAIL when any photo's colour fails, PASS when
    every measured one passes. "not measured" (with each photo's reason) when none was; INVALID
    photos do not count.
    """
    # an INVALID photo's colour is no more the print's than its other figures
    measured = [e for e in entries if (e.get("colour") or {}).get("measured") and e["verdict"] != "INVALID"]
    if not measured:
        reasons = sorted({e["colour"]["reason"] for e in entries if e.get("colour") and e["colour"].get("reason")}) or [
            "colour not measured: no valid photo measured it"
        ]
        return {"verdict": "not measured", "photos_measured": 0, "reasons": reasons}
    # (each photo's figures as its verdict judges them: under a directional light, without the shading)
    means = {Path(e["photo"]).name: judged_delta_e(e["colour"])["mean"] for e in measured}
    worst = max(measured, key=lambda e: judged_delta_e(e["colour"])["mean"])
    verdicts = [e["colour"].get("verdict") for e in measured]
    part = {"verdict": "FAIL" if "FAIL" in verdicts else "PASS"}
    if fused is not None:
        part = {
            "verdict": fused["verdict"],
            "delta_e00": fused["delta_e00"],
            "decided_by_photo": fused["decided_by_photo"],
            "words": fused["words"],
        }
    return {
        **part,
        "photos_measured": len(measured),
        "delta_e00_mean_by_photo": means,
        "worst_photo": Path(worst["photo"]).name,
        "worst_delta_e00": judged_delta_e(worst["colour"]),
        "chart_fit_delta_e00": max(e["colour"]["chart_fit_delta_e00"] for e in measured),
        "shading_directional": any((e["colour"].get("shading") or {}).get("directional") for e in measured),
    }
