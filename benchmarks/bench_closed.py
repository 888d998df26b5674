"""Speed of ``workbench design`` on a closed CAD part against its decorated surface given as a disc.

Run from the repository root::

    .venv/bin/python benchmarks/bench_closed.py [--triangles 200000] [--runs 2]

The part: the bundled lid (``fixtures/lid/lid.step``, 100 x 60 x 30 mm, every edge rounded to
5 mm), tessellated by OpenCASCADE as ``design`` reads it, then each triangle split at its edges'
midpoints (the shape unchanged) until the solid has at least ``--triangles`` triangles, written
as a binary STL. Its job is the lid's: three views at 300 dpi, free outline.

1. The closed part: ``workbench design`` selects what the views see, grows it by the margin,
   checks the solid (one body, outward, not self-intersecting) and cuts the selection out into
   a disc, then designs the print.
2. The same surface given as a disc: the design's ``decorated.obj`` (the cut-out surface, in
   mm) as the job's mesh, the same views and print; ``design`` designs the print from it.

Each command runs ``--runs`` times as a child process (the first may include numba's cache
warm-up); the faster run's wall time and every run's peak RSS are printed, with the stages of
``design.json``. The target: the closed part in at most 1.5 times the disc's time.
"""

from __future__ import annotations

import argparse
import json
import shutil
import sys
import tempfile
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "benchmarks"))

from bench_flatten import Timing, run_child  # noqa: E402

from workbench.mesh.io import read_mesh  # noqa: E402

TARGET_RATIO = 1.5
LID = ROOT / "fixtures" / "lid"


def split_at_midpoints(V: np.ndarray, F: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Each triangle split into four at its edges' midpoints (shared edges share their midpoint).

    Parameters
    ----------
    V : (n, 3) float
        Vertices, mm.
    F : (m, 3) int
        Triangles.

    Returns
    -------
    V2 : (n + e, 3) float
        The vertices, then one midpoint per edge (``e`` edges).
    F2 : (4 m, 3) int
        The triangles, wound as their parents.
    """
    half = np.concatenate([F[:, [0, 1]], F[:, [1, 2]], F[:, [2, 0]]])  # (3m, 2): corner k's edge to k + 1
    edges, inverse = np.unique(np.sort(half, axis=1), axis=0, return_inverse=True)
    mid = len(V) + inverse.reshape(3, len(F)).T  # (m, 3): midpoint of edge (0,1), (1,2), (2,0)
    V2 = np.concatenate([V, 0.5 * (V[edges[:, 0]] + V[edges[:, 1]])])
    a, b, c = F.T
    ab, bc, ca = mid.T
    F2 = np.concatenate([np.stack(t, axis=1) for t in ((a, ab, ca), (ab, b, bc), (ca, bc, c), (ab, bc, ca))])
    return V2, F2


def write_stl(path: Path, V: np.ndarray, F: np.ndarray) -> None:
    """A binary STL of a triangle mesh (normals from the winding)."""
    tri = V[F].astype(np.float32)
    n = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    n /= np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-30)
    rec = np.zeros(len(F), dtype=[("n", "<f4", 3), ("v", "<f4", (3, 3)), ("attr", "<u2")])
    rec["n"], rec["v"] = n, tri
    with open(path, "wb") as f:
        f.write(b"bench_closed: the lid, split".ljust(80, b" "))
        f.write(np.uint32(len(F)).tobytes())
        f.write(rec.tobytes())


def job_text(mesh: str) -> str:
    """The lid's job with another mesh (its views and print as they are)."""
    text = (LID / "job.toml").read_text()
    return text.replace('mesh = "lid.step"', f'mesh = "{mesh}"\nunits = "mm"', 1)


def timed_design(job: Path, out: Path, runs: int) -> tuple[Timing, dict]:
    """``runs`` designs of a job; the timing and the fastest run's design.json."""
    timing, info = Timing(), {}
    for k in range(runs):
        dest = out.with_name(f"{out.name}-{k}")
        seconds, peak = run_child([sys.executable, "-m", "workbench", "design", str(job), "--out", str(dest), "-q"])
        if timing.add(seconds, peak):
            info = json.loads((dest / "design.json").read_text())
            shutil.rmtree(out, ignore_errors=True)
            shutil.copytree(dest, out)
    return timing, info


def stages(info: dict) -> str:
    """design.json's stage times, one line."""
    t = info.get("timings_s") or info.get("timings") or {}
    return ", ".join(f"{k} {v:.1f}" for k, v in t.items() if isinstance(v, (int, float))) or "(no stage times)"


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--triangles", type=int, default=200_000, help="the closed part's least triangle count")
    ap.add_argument("--runs", type=int, default=2, help="runs of each command (the fastest counts)")
    args = ap.parse_args()
    with tempfile.TemporaryDirectory(prefix="bench_closed_") as tmp:
        tmp = Path(tmp)
        V, F = read_mesh(LID / "lid.step")
        while len(F) < args.triangles:
            V, F = split_at_midpoints(V, F)
        for name in ("top.png", "front.png", "right.png"):
            shutil.copy(LID / name, tmp / name)
        write_stl(tmp / "closed.stl", V, F)
        (tmp / "closed.toml").write_text(job_text("closed.stl"))
        print(f"closed part: the lid split to {len(F):,} triangles ({len(V):,} vertices)", flush=True)
        closed, info_closed = timed_design(tmp / "closed.toml", tmp / "closed-design", args.runs)
        disc_mesh = tmp / "disc.obj"
        shutil.copy(tmp / "closed-design" / "decorated.obj", disc_mesh)
        (tmp / "disc.toml").write_text(job_text("disc.obj"))
        Vd, Fd = read_mesh(disc_mesh, solid=False)
        print(f"its decorated surface as a disc: {len(Fd):,} triangles", flush=True)
        disc, info_disc = timed_design(tmp / "disc.toml", tmp / "disc-design", args.runs)
    ratio = closed.seconds / disc.seconds
    print()
    print(f"| design of | triangles | wall s (best of {args.runs}) | peak RSS MiB |")
    print("|---|---:|---:|---:|")
    print(f"| the closed part | {len(F):,} | {closed.seconds:.1f} | {closed.peak_mib:.0f} |")
    print(f"| its surface as a disc | {len(Fd):,} | {disc.seconds:.1f} | {disc.peak_mib:.0f} |")
    print()
    print(f"stages, closed: {stages(info_closed)}")
    print(f"stages, disc:   {stages(info_disc)}")
    verdict = "PASS" if ratio <= TARGET_RATIO else "FAIL"
    print(f"closed / disc: {ratio:.2f} (target at most {TARGET_RATIO:g}): {verdict}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
