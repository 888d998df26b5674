"""``workbench trend --json`` over a store of 100,000 parts: the time it answers in (at most 2 s).

    .venv/bin/python benchmarks/bench_trend.py [--parts 100000] [--repeat 3] [--keep DB]

Fills a SQLite store (the schema made by the store's own migrations) with the parts of one design
in one executemany (a production run of tests/trend_run.py: film scattered by 0.03 mm, then
drifting), then times the command as a user runs it, a fresh process each time (Python's start
and the imports included), and prints the best and the worst of ``--repeat``.
"""

from __future__ import annotations

import argparse
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path[:0] = [str(ROOT), str(ROOT / "tests")]

LIMIT_S = 2.0


def fill(db: Path, parts: int) -> None:
    """``parts`` validations of one design, inserted in one transaction."""
    from sqlalchemy import create_engine
    from trend_run import DESIGN_SHA, TOLERANCE_MM, production_run

    from workbench.store.record import recorded_at
    from workbench.store.schema import migrate, validations

    run = production_run(seed=0, parts=parts, drift_mm=0.0)
    engine = create_engine(f"sqlite:///{db}")
    rows = [
        {
            "part_id": f"P{i + 1:06d}",
            "lot": f"L{i // 1000}",
            "station": "line-1",
            "operator": "qa",
            "recorded_at": recorded_at(1_700_000_000 + 60 * i),
            "software_version": "bench",
            "job": "bench",
            "design_json_sha256": DESIGN_SHA,
            "verdict": "PASS",
            "photos": 1,
            "photos_pass": 1,
            "photos_fail": 0,
            "photos_invalid": 0,
            "worst_p95_mm": float(run.p95[i]),
            "defects": int(run.defects[i]),
            "tolerance_mm": TOLERANCE_MM,
            "max_delta_e": 3.0,
            "out_dir": "/bench",
            "validation_json": "{}",
            "film_offset_x_mm": float(run.x[i]),
            "film_offset_y_mm": float(run.y[i]),
            "film_rotation_deg": float(run.rotation[i]),
            "delta_e00_mean": float(run.delta_e[i]),
        }
        for i in range(parts)
    ]
    with engine.begin() as conn:
        migrate(conn)
        conn.execute(validations.insert(), rows)
    engine.dispose()


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--parts", type=int, default=100_000)
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--keep", metavar="DB", help="fill this store (kept) instead of a temporary one")
    a = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        db = Path(a.keep) if a.keep else Path(tmp) / "bench.db"
        db.unlink(missing_ok=True)
        t0 = time.perf_counter()
        fill(db, a.parts)
        print(
            f"filled {db} with {a.parts:,} parts in {time.perf_counter() - t0:.1f} s ({db.stat().st_size / 1e6:.0f} MB)"
        )
        times = []
        for _ in range(a.repeat):
            t0 = time.perf_counter()
            p = subprocess.run(
                [sys.executable, "-m", "workbench", "trend", "--store", str(db), "--json"],
                capture_output=True,
                cwd=ROOT,
                check=False,
            )
            times.append(time.perf_counter() - t0)
            if p.returncode != 0:
                print(p.stderr.decode(), file=sys.stderr)
                return 1
        print(
            f"workbench trend --json over {a.parts:,} parts: best {min(times):.2f} s, worst {max(times):.2f} s "
            f"(limit {LIMIT_S:g} s; {len(p.stdout) / 1e3:.0f} kB of JSON)"
        )
        return 0 if max(times) <= LIMIT_S else 1


if __name__ == "__main__":
    sys.exit(main())
