"""A part's placement and colour figures from its validation.json, as the store keeps them for the charts."""

from __future__ import annotations


def _number(x) -> float | None:
    return float(x) if isinstance(x, int | float) and not isinstance(x, bool) else None


def _mean(values: list[float | None]) -> float | None:
    kept = [v for v in values if v is not None]
    return sum(kept) / len(kept) if kept else None


def part_delta_e(colour: dict | None) -> float | None:
    """The part's mean ΔE00: the fused colour's when there is one, else its worst photo's; None unmeasured."""
    if not isinstance(colour, dict):
        return None
    fused = colour.get("delta_e00")
    if isinstance(fused, dict) and _number(fused.get("mean")) is not None:
        return _number(fused["mean"])
    worst = colour.get("worst_delta_e00")
    return _number(worst.get("mean")) if isinstance(worst, dict) else None


def part_figures(report: dict) -> dict:
    """The part's film offset (mm), rotation (degrees) and mean ΔE00 from a validation report.

    Each scored photo (not INVALID) measures the same film placement in the print's frame: the
    part's offset and rotation are their mean over those photos. None where no photo measured one.

    Returns
    -------
    dict
        ``film_offset_x_mm``, ``film_offset_y_mm``, ``film_rotation_deg``, ``delta_e00_mean``.
    """
    scored = [e for e in report.get("photos") or [] if isinstance(e, dict) and e.get("verdict") != "INVALID"]
    offsets = [e.get("film_offset_mm") if isinstance(e.get("film_offset_mm"), list) else [] for e in scored]
    return {
        "film_offset_x_mm": _mean([_number(o[0]) if len(o) > 0 else None for o in offsets]),
        "film_offset_y_mm": _mean([_number(o[1]) if len(o) > 1 else None for o in offsets]),
        "film_rotation_deg": _mean([_number(e.get("film_rotation_deg")) for e in scored]),
        "delta_e00_mean": part_delta_e((report.get("part") or {}).get("colour")),
    }
