"""The part: what all its photos show together on its print, and its verdict."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from workbench.validate import dense


def part_summary(states: list, grid, names: list[str], entries: list[dict]) -> tuple[dict, np.ndarray, list]:
    """What all photos of the part show together, on its print.

    Each print pixel keeps the most telling state any photo gives it (defective over measured
    over masked over unseen); defects are the connected defective regions of that map.

    Returns
    -------
    summary : dict
        verdict (FAIL when any photo fails, PASS when every scored photo passes, INVALID when
        none was scored), coverage of the part's print and of each view's region, defects.
    combined : (rows, cols) uint8
        The combined state map.
    defects : list of dict
        Part defects: centre_mm, area_mm2 (print), and the photos that show each.
    """
    scored = [s for s in states if s is not None]
    verdicts = [e["verdict"] for e in entries]
    if "FAIL" in verdicts:
        verdict = "FAIL"
    elif "PASS" in verdicts:
        verdict = "PASS"
    else:
        verdict = "INVALID"
    if not scored:
        return {"verdict": verdict, "photos_scored": 0}, None, []
    combined = np.maximum.reduce(scored)
    on = combined != dense.OFF_PART
    n_on = max(int(on.sum()), 1)
    # one defect seen in several photos is one defect of the part: photos' defects whose
    # boxes on the print overlap are merged (the largest area, the centre of the largest)
    defects: list = []
    for e in entries:
        for d in e.get("defects", []):
            x0, y0, x1, y1 = d["bbox_mm"]
            for m in defects:
                a0, b0, a1, b1 = m["bbox_mm"]
                if x0 < a1 and a0 < x1 and y0 < b1 and b0 < y1:
                    if d["area_mm2"] > m["area_mm2"]:
                        m.update(centre_mm=d["centre_mm"], area_mm2=d["area_mm2"], kind=d["kind"])
                    m["bbox_mm"] = [min(x0, a0), min(y0, b0), max(x1, a1), max(y1, b1)]
                    m["photos"].append(Path(e["photo"]).name)
                    break
            else:
                defects.append(
                    {
                        "kind": d["kind"],
                        "centre_mm": d["centre_mm"],
                        "area_mm2": d["area_mm2"],
                        "bbox_mm": list(d["bbox_mm"]),
                        "view": d.get("view"),
                        "photos": [Path(e["photo"]).name],
                    }
                )
    defects.sort(key=lambda d: (-d["area_mm2"], d["centre_mm"]))
    summary = {
        "verdict": verdict,
        "photos_scored": len(scored),
        "coverage_print": {
            dense.STATE_NAMES[k]: float((combined == k).sum() / n_on) for k in range(1, len(dense.STATE_NAMES))
        },
        "measured_share_of_part": float(np.isin(combined, dense.MEASURED).sum() / n_on),
        "coverage_by_view": dense.coverage_by_view(combined, grid.owner, names),
        "defects": defects,
    }
    return summary, combined, defects
