"""A simulated production run for the control charts: each part's figures, recorded as validations.

Film placement scattered by ``scatter_mm`` (one standard deviation in x and in y) from part to
part, drifting in x by ``drift_mm`` per part after part ``drift_after``; the misregistration p95
is the film's offset plus the tiles' own scatter (a 95th percentile of |shift| over the tiles:
about 0.02 mm); ΔE00 1.5 ± 0.15; defects Poisson, 0.1 per part, each 0.5 mm² (under the
defect limit). A part FAILs when |offset| or p95 is beyond the tolerance.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np

DESIGN_SHA = "d" * 64
TOLERANCE_MM = 0.5
MAX_DELTA_E = 3.0


@dataclass(frozen=True)
class Run:
    """The figures of a run's parts, in order (mm, degrees, ΔE00, counts)."""

    x: np.ndarray
    y: np.ndarray
    rotation: np.ndarray
    p95: np.ndarray
    delta_e: np.ndarray
    defects: np.ndarray

    def fails(self) -> np.ndarray:
        """Which parts FAIL: |offset| or p95 beyond the tolerance."""
        return (np.abs(self.x) > TOLERANCE_MM) | (np.abs(self.y) > TOLERANCE_MM) | (self.p95 > TOLERANCE_MM)


def production_run(
    seed: int, parts: int, drift_mm: float = 0.0, drift_after: int = 15, scatter_mm: float = 0.03
) -> Run:
    """The figures of ``parts`` parts (seeded): see the module's docstring."""
    rng = np.random.default_rng(seed)
    k = np.arange(1, parts + 1)
    x = rng.normal(0.0, scatter_mm, parts) + drift_mm * np.maximum(k - drift_after, 0)
    y = rng.normal(0.0, scatter_mm, parts)
    p95 = np.hypot(x, y) + np.abs(rng.normal(0.02, 0.005, parts))
    return Run(
        x=x,
        y=y,
        rotation=rng.normal(0.0, 0.01, parts),
        p95=p95,
        delta_e=rng.normal(1.5, 0.15, parts),
        defects=rng.poisson(0.1, parts),
    )


def report_text(run: Run, i: int) -> str:
    """Part ``i``'s validation.json, as much of it as the store reads."""
    fail = bool(run.fails()[i])
    return json.dumps(
        {
            "software": {"version": "sim"},
            "design": {"job": {"name": "sim", "sha256": "j" * 64}, "design_json_sha256": DESIGN_SHA},
            "tolerance_mm": TOLERANCE_MM,
            "max_defect_mm2": 2.0,
            "max_delta_e": MAX_DELTA_E,
            "part": {
                "verdict": "FAIL" if fail else "PASS",
                "defects": [{"kind": "bubble", "area_mm2": 0.5, "photos": ["p.jpg"]}] * int(run.defects[i]),
                "colour": {"verdict": "PASS", "delta_e00": {"mean": float(run.delta_e[i])}},
            },
            "photos": [
                {
                    "photo": "p.jpg",
                    "verdict": "FAIL" if fail else "PASS",
                    "misregistration_mm": {"p95": float(run.p95[i]), "median": float(run.p95[i]) / 2},
                    "film_offset_mm": [float(run.x[i]), float(run.y[i])],
                    "film_rotation_deg": float(run.rotation[i]),
                }
            ],
        }
    )


def part_id(i: int) -> str:
    return f"P{i + 1:04d}"


def record_run(run: Run, url, out: Path, station: str = "line-1") -> None:
    """Record every part through the store's own functions (validation.json to rows, one transaction each)."""
    from workbench.store.record import Recorder, record_validation, recorded_at, validation_rows

    for i in range(len(run.x)):
        rec = Recorder(url, part_id(i), "lot-1", station, "qa")
        rows = validation_rows(report_text(run, i), out, [], rec, recorded_at(1_700_000_000 + 60 * i))
        record_validation(rows, url)
