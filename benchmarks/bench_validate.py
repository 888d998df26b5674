"""Benchmark of workbench validate: seconds per 12-megapixel photo (target <= 5 s).

    .venv/bin/python benchmarks/bench_validate.py

Designs the default job, renders two 4000 x 3000 photos (realistic imperfections; one with
the film 0.8 mm off), then times the whole `workbench validate` command through the bare
launcher of bench_flatten.py and reads the per-photo seconds from validation.json.
"""

from __future__ import annotations

import json
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "benchmarks"))

from bench_flatten import run_child  # noqa: E402

WB = str(ROOT / ".venv" / "bin" / "workbench")
TARGET_S = 5.0


def main() -> None:
    with tempfile.TemporaryDirectory(prefix="bench_validate_") as tmp:
        tmp = Path(tmp)
        design = tmp / "design"
        subprocess.run([WB, "design", str(ROOT / "fixtures/default/job.toml"), "--out", str(design), "-q"], check=True)
        photos = []
        for name, extra in (("perfect", []), ("offset", ["--film-offset-mm", "0.8,0"])):
            p = tmp / f"{name}.jpg"
            subprocess.run(
                [
                    WB,
                    "render",
                    str(design),
                    "--orbit",
                    "10,55,330",
                    "--size",
                    "4000x3000",
                    "--realistic",
                    *extra,
                    "-o",
                    str(p),
                    "-q",
                ],
                check=True,
            )
            photos.append(str(p))
        cmd = [
            WB,
            "validate",
            str(design),
            *photos,
            "--camera",
            str(tmp / "perfect.json"),
            "--out",
            str(tmp / "v"),
            "-q",
        ]
        seconds, peak = run_child(cmd)
        report = json.loads((tmp / "v" / "validation.json").read_text())
        per = [e["seconds"] for e in report["photos"]]
        print("workbench validate: 2 photos of 4000 x 3000 px (12 Mpx), realistic imperfections")
        print(f"  whole command {seconds:.2f} s (with start-up, QA report), peak {peak:.0f} MiB")
        print(
            f"  per photo {', '.join(f'{s:.2f} s' for s in per)}; verdicts "
            f"{', '.join(e['verdict'] for e in report['photos'])}"
        )
        print(f"  target <= {TARGET_S:.0f} s per photo: {'PASS' if max(per) <= TARGET_S else 'FAIL'}")


if __name__ == "__main__":
    main()
