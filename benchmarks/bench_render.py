"""Benchmark of workbench render: a 4000 x 3000 photo of a 100k-face part with 2 x 2 supersampling.

    .venv/bin/python benchmarks/bench_render.py

Builds the benchmark design of bench_design.py (an A4 dome, 99,458 faces) at 300 dpi, then
times the whole `workbench render` command (realistic imperfections and lens distortion on,
fixture plate included) through the bare launcher of bench_flatten.py, best of two runs.
"""

from __future__ import annotations

import json
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "benchmarks"))
sys.path.insert(0, str(ROOT))

from bench_design import write_job  # noqa: E402
from bench_flatten import run_child  # noqa: E402

WB = str(ROOT / ".venv" / "bin" / "workbench")
TARGET_S = 20.0


def main() -> None:
    with tempfile.TemporaryDirectory(prefix="bench_render_") as tmp:
        tmp = Path(tmp)
        job, _, _ = write_job(tmp)
        text = job.read_text().replace("dpi = 600", "dpi = 300")
        job.write_text(text)
        design = tmp / "design"
        subprocess.run([WB, "design", str(job), "--out", str(design), "-q"], check=True)
        faces = json.loads((design / "design.json").read_text())["mesh"]["faces"]
        cmd = [
            WB,
            "render",
            str(design),
            "--orbit",
            "25,40,700",
            "--size",
            "4000x3000",
            "--supersample",
            "2",
            "--realistic",
            "--distortion=-0.08,0.03,0,0,0",
            "-o",
            str(tmp / "photo.jpg"),
            "-q",
        ]
        runs = [run_child(cmd) for _ in range(2)]
        best = min(r[0] for r in runs)
        peak = max(r[1] for r in runs)
        print(f"workbench render: {faces:,} faces, 4000 x 3000 px, 2 x 2 supersampling, realistic, lens distortion")
        print(f"  runs {', '.join(f'{s:.2f} s' for s, _ in runs)}; best {best:.2f} s, peak {peak:.0f} MiB")
        print(f"  target <= {TARGET_S:.0f} s: {'PASS' if best <= TARGET_S else 'FAIL'}")


if __name__ == "__main__":
    main()
