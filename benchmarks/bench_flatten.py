"""Accuracy and speed of ``workbench flatten`` against closed-form maps and libigl's harmonic map.

Run from the repository root::

    .venv/bin/python benchmarks/bench_flatten.py [--big]

Prints three blocks:

1. Convergence: the flat map of two meshes whose exact conformal map onto a rectangle
   is known in closed form (a planar annular sector, whose map is ``log z``, and a
   sphere patch, whose map is Mercator's projection), for n x n vertices,
   n = 25 ... 400. The error is the largest vertex distance after the best complex
   similarity, divided by the rectangle's diagonal; it should fall as O(h²).
2. Timings of the whole ``workbench flatten`` command on the sphere patch at 40k and
   160k vertices (1M with ``--big``): wall time and peak RSS of the child process,
   best of several runs, with the per-stage times from ``flatten.json``; against a
   peer process doing libigl's harmonic map onto the same rectangle (boundary by arc
   length between the same four corners) on the same OBJ file.
3. One line per size for the README table.
4. The real-mesh corpus (``tests/data/corpus`` and, when present, the shared meshes
   beside the checkout), each as a 150 mm part at 300 dpi: how many flatten, how many needed
   Ptolemy flips, how many flips, and the time they cost (whole ``flatten`` against the
   solve on the input triangulation alone, where that one succeeds); for each one the
   automatic corners crowd, what ``--corners auto`` makes of it.

Notes
-----
Meshes are deterministic (seeded generators). Peak RSS is ``ru_maxrss`` of the
waited-for child (KiB on Linux), reported in MiB; the child is started by a bare
interpreter so that this process's own memory does not leak into that figure.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
import textwrap
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from fixtures.make_fixtures import grid_mesh  # noqa: E402
from workbench.conformal.flatten import FlattenOptions, flatten  # noqa: E402
from workbench.mesh.io import format_obj, read_mesh  # noqa: E402

CONVERGENCE_SIZES = (25, 50, 100, 200, 400)
TIMING_SIZES = (200, 400)
BIG_SIZE = 1000
SPHERE_RADIUS_MM = 50.0
WORKBENCH = Path(sys.executable).with_name("workbench")

PEER_SCRIPT = textwrap.dedent(
    '''
    """libigl harmonic map onto a rectangle: mesh corners(A,B,C,D) width height out."""
    import sys

    import igl
    import numpy as np

    path, corners, width, height, out = sys.argv[1:6]
    corners = [int(c) for c in corners.split(",")]
    width, height = float(width), float(height)
    V, F = igl.read_triangle_mesh(path)
    loop = igl.boundary_loop(F)
    loop = np.roll(loop, -int(np.flatnonzero(loop == corners[0])[0]))
    pos = {int(v): i for i, v in enumerate(loop)}
    if pos[corners[1]] > pos[corners[3]]:  # walk A -> B -> C -> D
        loop = np.roll(loop[::-1], 1)
        pos = {int(v): i for i, v in enumerate(loop)}
    ends = [pos[c] for c in corners] + [len(loop)]
    seg = np.linalg.norm(V[np.roll(loop, -1)] - V[loop], axis=1)
    rect = np.array([[0.0, 0.0], [width, 0.0], [width, height], [0.0, height], [0.0, 0.0]])
    bc = np.empty((len(loop), 2))
    for k in range(4):
        s = np.concatenate([[0.0], np.cumsum(seg[ends[k]:ends[k + 1]])])
        t = (s[:-1] / s[-1])[:, None]
        bc[ends[k]:ends[k + 1]] = (1 - t) * rect[k] + t * rect[k + 1]
    uv = igl.harmonic(V, F, loop, bc, 1)
    igl.write_triangle_mesh(out, np.column_stack([uv, np.zeros(len(uv))]), F)
    '''
).lstrip()

# Runs argv[1:] with stdout discarded; prints [wall s, exit status, child's ru_maxrss KiB].
LAUNCHER = textwrap.dedent(
    """
    import json, os, subprocess, sys, time
    t0 = time.perf_counter()
    proc = subprocess.Popen(sys.argv[1:], stdout=subprocess.DEVNULL)
    _, status, usage = os.wait4(proc.pid, 0)
    seconds = time.perf_counter() - t0
    proc.returncode = os.waitstatus_to_exitcode(status)
    print(json.dumps([seconds, proc.returncode, usage.ru_maxrss]))
    """
)


@dataclass
class ExactCase:
    """A mesh with its exact conformal map onto a rectangle.

    Attributes
    ----------
    V : (#V, 3) float
        Surface positions.
    F : (#F, 3) int
        Triangles.
    exact : (#V,) complex
        Exact flat positions.
    corners : tuple of 4 int
        Grid corners A, B, C, D, counter-clockwise.
    diagonal : float
        Diagonal of the exact rectangle.
    """

    V: np.ndarray
    F: np.ndarray
    exact: np.ndarray
    corners: tuple[int, int, int, int]
    diagonal: float


def grid(n: int, seed: int) -> tuple[np.ndarray, np.ndarray, tuple[int, int, int, int]]:
    """Jittered n x n unit-square grid (jitter 0.2) and its corner vertices."""
    P, F = grid_mesh(n, n, np.random.default_rng(seed), jitter=0.2)
    return P, F, (0, n - 1, n * n - 1, n * (n - 1))


def sector_mesh(n: int, r0: float = 1.0, r1: float = 2.0, t0: float = 0.0, t1: float = 1.0) -> ExactCase:
    """Planar annular sector r0 <= |z| <= r1, t0 <= arg z <= t1; exact map ``log z``."""
    P, F, corners = grid(n, seed=n)
    w = np.log(r0) + P[:, 0] * (np.log(r1) - np.log(r0)) + 1j * (t0 + P[:, 1] * (t1 - t0))
    z = np.exp(w)
    V = np.column_stack([z.real, z.imag, np.zeros(len(z))])
    return ExactCase(V, F, w, corners, abs(complex(np.log(r1 / r0), t1 - t0)))


def mercator(lat: np.ndarray | float) -> np.ndarray | float:
    """Mercator's y of a latitude in radians."""
    return np.log(np.tan(np.pi / 4 + np.asarray(lat) / 2))


def sphere_mesh(n: int, radius: float = SPHERE_RADIUS_MM, lon1: float = 1.2, lat1: float = 0.6) -> ExactCase:
    """Sphere patch 0 <= lon <= lon1, |lat| <= lat1; exact map Mercator's (lon, y)."""
    P, F, corners = grid(n, seed=10_000 + n)
    y0, y1 = float(mercator(-lat1)), float(mercator(lat1))
    lon = lon1 * P[:, 0]
    y = y0 + P[:, 1] * (y1 - y0)
    lat = 2 * np.arctan(np.exp(y)) - np.pi / 2
    V = radius * np.column_stack([np.cos(lat) * np.cos(lon), np.cos(lat) * np.sin(lon), np.sin(lat)])
    return ExactCase(V, F, lon + 1j * y, corners, abs(complex(lon1, y1 - y0)))


def similarity_error(uv: np.ndarray, mesh: ExactCase) -> float:
    """Max vertex error of ``uv`` after the least-squares similarity onto ``mesh.exact``, over the diagonal."""
    A = np.column_stack([uv[:, 0] + 1j * uv[:, 1], np.ones(len(uv))])
    coef, *_ = np.linalg.lstsq(A, mesh.exact, rcond=None)
    return float(np.abs(A @ coef - mesh.exact).max() / mesh.diagonal)


def convergence_table() -> None:
    """Print error, observed order, Newton iterations and time for both closed-form cases."""
    print("1. Convergence: max vertex error / rectangle diagonal after best similarity (expected order 2)")
    print(f"{'case':<8} {'n':>4} {'vertices':>9} {'faces':>9} {'error':>10} {'order':>6} {'newton':>6} {'time s':>7}")
    for name, make in (("sector", sector_mesh), ("sphere", sphere_mesh)):
        prev = None
        for n in CONVERGENCE_SIZES:
            mesh = make(n)
            t0 = time.perf_counter()
            result = flatten(mesh.V, mesh.F, FlattenOptions(corners=mesh.corners))
            seconds = time.perf_counter() - t0
            err = similarity_error(result.uv, mesh)
            order = f"{np.log2(prev / err):6.2f}" if prev else f"{'':>6}"
            iters = result.newton.iterations
            print(f"{name:<8} {n:>4} {len(mesh.V):>9} {len(mesh.F):>9} {err:10.2e} {order} {iters:>6} {seconds:7.2f}")
            prev = err
    print()


def run_child(cmd: list[str]) -> tuple[float, float]:
    """Run a command to completion; wall seconds and the child's peak RSS in MiB. Raises if it fails.

    The command is started by a bare interpreter (:data:`LAUNCHER`, about 11 MiB) rather
    than by this process: on Linux a child's ``ru_maxrss`` includes the high-water mark
    of the address space it was forked from, here hundreds of MiB of benchmark meshes.
    """
    launcher = subprocess.run([sys.executable, "-I", "-S", "-c", LAUNCHER, *cmd], capture_output=True, check=True)
    seconds, code, maxrss_kib = json.loads(launcher.stdout)
    if code != 0:
        raise RuntimeError(f"{' '.join(cmd)} exited {code}:\n{launcher.stderr.decode(errors='replace')}")
    return seconds, maxrss_kib / 1024.0


@dataclass
class Timing:
    """Best-of-runs wall time and peak RSS of one command."""

    seconds: float = float("inf")
    peak_mib: float = 0.0
    runs: int = 0

    def add(self, seconds: float, peak_mib: float) -> bool:
        """Record one run; True if it is the fastest so far."""
        self.runs += 1
        self.peak_mib = max(self.peak_mib, peak_mib)
        if seconds < self.seconds:
            self.seconds = seconds
            return True
        return False


def read_flat_uv(path: Path) -> np.ndarray:
    """First two coordinates of a flat OBJ."""
    V, _ = read_mesh(path)
    return V[:, :2]


def time_size(n: int, tmp: Path, repeats: int) -> dict:
    """Time workbench and the peer on the n x n sphere patch, alternating runs; a summary row."""
    mesh = sphere_mesh(n)
    mesh_path, out_dir, peer_out = tmp / f"sphere{n}.obj", tmp / f"out{n}", tmp / f"peer{n}.obj"
    mesh_path.write_bytes(format_obj(mesh.V, mesh.F, header=f"sphere patch R={SPHERE_RADIUS_MM:g} mm, {n}x{n}"))
    corners = ",".join(map(str, mesh.corners))
    wb_cmd = [str(WORKBENCH), "flatten", str(mesh_path), "--corners", corners, "--out", str(out_dir), "-q"]
    wb, peer, stages, info = Timing(), Timing(), {}, {}
    for _ in range(repeats):
        if wb.add(*run_child(wb_cmd)):
            info = json.loads((out_dir / "flatten.json").read_text())
            stages = info["timings_s"]
        peer_cmd = [sys.executable, str(tmp / "peer.py"), str(mesh_path), corners]
        peer_cmd += [repr(info["width_mm"]), repr(info["height_mm"]), str(peer_out)]
        peer.add(*run_child(peer_cmd))
    return {
        "n": n,
        "vertices": len(mesh.V),
        "faces": len(mesh.F),
        "wb": wb,
        "peer": peer,
        "stages": stages,
        "newton": info["newton_iterations"],
        "wb_error": similarity_error(read_flat_uv(out_dir / "flat.obj"), mesh),
        "peer_error": similarity_error(read_flat_uv(peer_out), mesh),
    }


def print_timing(row: dict) -> None:
    """Print one size's timings, stages and the workbench/peer ratio."""
    wb, peer = row["wb"], row["peer"]
    stages = ", ".join(f"{k} {v:.2f}" for k, v in row["stages"].items())
    print(f"{row['n']}x{row['n']}: {row['vertices']} vertices, {row['faces']} faces, best of {wb.runs}")
    print(f"  workbench flatten  {wb.seconds:7.2f} s  peak {wb.peak_mib:7.0f} MiB  ({row['newton']} Newton steps)")
    print(f"    stages s: {stages}")
    print(f"  libigl harmonic    {peer.seconds:7.2f} s  peak {peer.peak_mib:7.0f} MiB")
    print(f"  ratio workbench/peer {wb.seconds / peer.seconds:.2f} (time), {wb.peak_mib / peer.peak_mib:.2f} (memory)")
    print(f"  error vs Mercator / diagonal: workbench {row['wb_error']:.2e}, peer {row['peer_error']:.2e}")


def timings(sizes: list[int]) -> list[dict]:
    """Run and print the timing block for each size; the rows."""
    print("2. Timings of the whole command (sphere patch R = 50 mm, same OBJ for both; wall s, peak RSS)")
    rows = []
    with tempfile.TemporaryDirectory(prefix="bench_flatten_") as tmp:
        (Path(tmp) / "peer.py").write_text(PEER_SCRIPT)
        for n in sizes:
            rows.append(time_size(n, Path(tmp), repeats=1 if n >= BIG_SIZE else 3))
            print_timing(rows[-1])
    print()
    return rows


def readme_lines(rows: list[dict]) -> None:
    """Print the README table."""
    print("3. README table")
    print("| vertices | faces | workbench s | libigl harmonic s | ratio | workbench MiB | libigl MiB |")
    print("|---:|---:|---:|---:|---:|---:|---:|")
    for r in rows:
        wb, peer = r["wb"], r["peer"]
        print(
            f"| {r['vertices']:,} | {r['faces']:,} | {wb.seconds:.2f} | {peer.seconds:.2f} "
            f"| {wb.seconds / peer.seconds:.2f} | {wb.peak_mib:.0f} | {peer.peak_mib:.0f} |"
        )


def real_meshes() -> None:
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
    from workbench.conformal.flatten import CrowdingError, flatten, flatten_auto_corners
    from workbench.errors import WorkbenchError
    from workbench.mesh.io import read_mesh

    root = Path(__file__).resolve().parents[1]
    paths = sorted((root / "tests" / "data" / "corpus").glob("*.npz"))
    shared = root.parent / "shared" / "meshes"
    if shared.is_dir():
        paths += sorted(p for p in shared.iterdir() if p.suffix in (".obj", ".off"))
    print("\nreal disc meshes as 150 mm parts at 300 dpi: flattened / refused for crowding, Ptolemy flips, cost")
    ok = refused = flipped_runs = auto_ok = crowded = rescued = 0
    total_flips, t_flip = 0, 0.0
    for p in paths:
        if p.suffix == ".npz":
            d = np.load(p)
            V, F = d["V"].astype(np.float64), d["F"].astype(np.int64)
        else:
            V, F = read_mesh(p)
        V = V * (150.0 / np.linalg.norm(V.max(0) - V.min(0)))
        t0 = time.perf_counter()
        try:
            r = flatten(V, F, name=p.name)
        except WorkbenchError as exc:
            refused += 1
            print(f"  {p.stem:32s} refused: {str(exc)[len(p.name) + 2 :][:90]}")
            if not isinstance(exc, CrowdingError):
                continue
            crowded += 1
            # what --corners auto makes of it
            t1 = time.perf_counter()
            try:
                auto, search = flatten_auto_corners(V, F, name=p.name)
            except WorkbenchError as exc2:
                tail = str(exc2).split("(of ")[-1].split(");")[0] if "(of " in str(exc2) else "no prediction"
                print(f"  {'':32s} --corners auto refused in {time.perf_counter() - t1:.1f} s: {tail}")
            else:
                auto_ok += 1
                rescued += 1
                print(
                    f"  {'':32s} --corners auto: {search['predicted']} quadruples predicted, "
                    f"{len(search['candidates'])} flattened, {time.perf_counter() - t1:.1f} s, "
                    f"flipped faces {auto.flipped_faces}"
                )
            continue
        dt = time.perf_counter() - t0
        ok += 1
        auto_ok += 1
        if r.intrinsic_flips:
            flipped_runs += 1
            total_flips += r.intrinsic_flips
            t_flip += dt
        print(
            f"  {p.stem:32s} {len(F):6d} faces  flips {r.intrinsic_flips:6d}  subdivision {len(r.F):6d} faces  "
            f"flipped faces {r.flipped_faces}  {dt:5.2f} s (newton {r.timings_s['newton']:.2f}, "
            f"overlay {r.timings_s['overlay']:.2f})"
        )
    print(
        f"  {ok} of {len(paths)} flatten with no flipped face, {refused} refused for crowding; {flipped_runs} needed "
        f"flips ({total_flips} in all, {t_flip:.1f} s for those meshes); with --corners auto {auto_ok} flatten "
        f"({rescued} of the {crowded} the automatic corners crowd)"
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--big", action="store_true", help=f"also time {BIG_SIZE}x{BIG_SIZE} vertices (1 run)")
    args = parser.parse_args()
    convergence_table()
    rows = timings(list(TIMING_SIZES) + ([BIG_SIZE] if args.big else []))
    readme_lines(rows)
    real_meshes()


if __name__ == "__main__":
    main()
