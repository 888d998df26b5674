"""Benchmark of `workbench render --renderer mitsuba`: photo sizes and samples per pixel.

    .venv/bin/python benchmarks/bench_render_mitsuba.py [--sizes 2000x1500,...] [--spp 4,8,16] [--repeat N]

Designs the bundled default job (fixtures/default), then times the whole `workbench render`
command with Mitsuba 3 (scalar_rgb, CPU) at each size and sample count: the default job's
photo from the orbit of the validate tests, on its fixture plate, with k1 = -0.10 and the
realistic finish (blur, noise, JPEG, vignetting, the lamp's shading). Prints wall seconds,
CPU seconds (user + system of the command: what the machine's other work cannot inflate),
peak RSS and Mitsuba's samples per CPU second; best of ``--repeat`` runs.
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PY = sys.executable


def run(cmd: list[str], env: dict) -> tuple[float, float, float]:
    """Run a command to completion; its wall seconds, CPU seconds and peak RSS (MiB). Raises if it fails."""
    t0 = time.perf_counter()
    proc = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, env=env)
    _, status, usage = os.wait4(proc.pid, 0)
    wall = time.perf_counter() - t0
    proc.returncode = os.waitstatus_to_exitcode(status)
    if proc.returncode != 0:
        raise RuntimeError(f"{' '.join(cmd)} exited {proc.returncode}:\n{proc.stderr.read().decode(errors='replace')}")
    return wall, usage.ru_utime + usage.ru_stime, usage.ru_maxrss / 1024.0


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", default="2000x1500,3000x2250,4000x3000")
    ap.add_argument("--spp", default="4,8,16")
    ap.add_argument("--repeat", type=int, default=1)
    args = ap.parse_args()
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    wb = [PY, "-m", "workbench"]
    with tempfile.TemporaryDirectory(prefix="bench_render_mitsuba_") as tmp:
        tmp = Path(tmp)
        design = tmp / "design"
        job = ROOT / "fixtures" / "default" / "job.toml"
        subprocess.run([*wb, "design", str(job), "--out", str(design), "-q"], check=True, env=env)
        print(
            "workbench render --renderer mitsuba: default job, orbit 10,55,330, k1 -0.10, realistic; "
            f"{os.cpu_count()} cores"
        )
        print(f"  {'size':>10} {'spp':>4} {'wall s':>8} {'CPU s':>8} {'peak MiB':>9} {'Msamples/CPU s':>15}")
        for size in args.sizes.split(","):
            w, h = (int(v) for v in size.split("x"))
            for spp in (int(s) for s in args.spp.split(",")):
                cmd = [
                    *wb,
                    "render",
                    str(design),
                    "--orbit",
                    "10,55,330",
                    "--size",
                    size,
                    "--renderer",
                    "mitsuba",
                    "--spp",
                    str(spp),
                    "--realistic",
                    "--distortion=-0.1,0,0,0,0",
                    "-o",
                    str(tmp / "photo.jpg"),
                    "-q",
                ]
                runs = [run(cmd, env) for _ in range(args.repeat)]
                wall, cpu, peak = min(runs)
                print(
                    f"  {size:>10} {spp:>4} {wall:8.1f} {cpu:8.1f} {peak:9.0f} {w * h * spp / cpu / 1e6:15.2f}",
                    flush=True,
                )


if __name__ == "__main__":
    main()
