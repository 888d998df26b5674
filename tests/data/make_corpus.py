"""Build the real-mesh disc corpus of ``tests/data/corpus/`` from public closed and open scans.

Source: the libigl tutorial data set (github.com/libigl/libigl-tutorial-data), research test
meshes of scans (bunny, cow, lion, beetle, ...) and CAD models (fandisk, screwdriver); see
``tests/data/README.md`` for credits. Run once with the path of a checkout::

    python tests/data/make_corpus.py /path/to/libigl-tutorial-data

Each disc is a geodesic disc (Dijkstra along edges) cut around a vertex chosen with a
fixed seed, shrunk until it is a clean topological disc. Some are made harder on purpose:
vertex noise, needles and caps (vertices slid almost onto a neighbour), valence-3 vertices
(faces split at their centroid) and a valence-30 fan. Stored as compressed ``.npz``
(``V`` float32 in the file's own units, ``F`` int32) to keep the repository small.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import scipy.sparse as sp
import trimesh
from scipy.sparse.csgraph import connected_components, dijkstra

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))

from workbench.errors import WorkbenchError  # noqa: E402
from workbench.mesh.topology import unique_edges  # noqa: E402
from workbench.mesh.validate import check_disc  # noqa: E402

OUT = Path(__file__).resolve().parent / "corpus"

# source file -> (number of discs, target faces per disc)
SOURCES = {
    "bunny.off": (2, 3000),
    "cow.off": (2, 3000),
    "fertility.off": (2, 3000),
    "cheburashka.off": (2, 3000),
    "fandisk.off": (2, 2500),
    "decimated-knight.off": (2, 1500),
    "lion.off": (2, 3000),
    "elephant.obj": (2, 3000),
    "arm.obj": (2, 3000),
    "beetle.off": (2, 3000),
    "bumpy.off": (1, 2000),
    "snail.obj": (2, 2000),
    "screwdriver.off": (2, 2500),
    "decimated-max.obj": (2, 3000),
    "truck.obj": (1, 2500),
    "horse_quad.obj": (2, 3000),
}


def load(path: Path) -> tuple[np.ndarray, np.ndarray]:
    m = trimesh.load(path, process=False, force="mesh")
    m.merge_vertices()
    m.remove_unreferenced_vertices()
    return np.asarray(m.vertices, dtype=np.float64), np.asarray(m.faces, dtype=np.int64)


def compact(V: np.ndarray, F: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    used = np.unique(F)
    remap = np.full(len(V), -1)
    remap[used] = np.arange(len(used))
    return V[used], remap[F]


def geodesic_disc(V, F, centre, target_faces):
    E, _, _ = unique_edges(F)
    w = np.linalg.norm(V[E[:, 0]] - V[E[:, 1]], axis=1)
    G = sp.coo_matrix((w, (E[:, 0], E[:, 1])), shape=(len(V), len(V))).tocsr()
    d = dijkstra(G, directed=False, indices=centre)
    face_d = d[F].max(axis=1)
    order = np.sort(face_d[np.isfinite(face_d)])
    radius = order[min(target_faces, len(order) - 1)]
    for _ in range(40):
        keep = F[face_d <= radius]
        if len(keep) >= 50:
            Vd, Fd = compact(V, keep)
            # largest face component
            _, FE, _ = unique_edges(Fd)
            e = FE.ravel()
            f = np.repeat(np.arange(len(Fd)), 3)
            A = sp.coo_matrix((np.ones(len(e)), (f, e)), shape=(len(Fd), int(e.max()) + 1)).tocsr()
            n, labels = connected_components(A @ A.T, directed=False)
            big = np.argmax(np.bincount(labels))
            Vd, Fd = compact(Vd, Fd[labels == big])
            try:
                check_disc(Vd, Fd, "disc")
                return Vd, Fd
            except WorkbenchError:
                pass
        radius *= 0.93
    return None


def noisy(V, F, rng, amount=0.3):
    E, _, _ = unique_edges(F)
    h = np.linalg.norm(V[E[:, 0]] - V[E[:, 1]], axis=1).mean()
    return V + amount * h * rng.standard_normal(V.shape), F


def needles(V, F, rng, share=0.05):
    # slide some vertices 95 % of the way towards a neighbour: needles and caps
    E, _, _ = unique_edges(F)
    V = V.copy()
    for i in rng.choice(len(E), int(share * len(E)), replace=False):
        a, b = E[i]
        V[a] = V[a] + 0.95 * (V[b] - V[a])
    return V, F


def valence3(V, F, rng, share=0.05):
    split = np.zeros(len(F), dtype=bool)
    split[rng.choice(len(F), int(share * len(F)), replace=False)] = True
    c = V[F[split]].mean(axis=1)
    ids = len(V) + np.arange(len(c))
    a, b, d = F[split].T
    new = np.concatenate([np.stack([a, b, ids], 1), np.stack([b, d, ids], 1), np.stack([d, a, ids], 1)])
    return np.vstack([V, c]), np.vstack([F[~split], new])


def valence30(V, F, centre):
    # replace the k-ring of a vertex by one fan from the vertex to the ring's boundary
    ring = {centre}
    for _ in range(8):
        faces = np.flatnonzero(np.isin(F, list(ring)).any(axis=1))
        inner = F[faces]
        Vd, _ = V, None
        # boundary of the patch, in order
        from workbench.mesh.topology import boundary_loops

        loops = boundary_loops(inner)
        if len(loops) == 1 and len(loops[0]) >= 30:
            loop = loops[0]
            fan = np.stack([np.full(len(loop), centre), loop, np.roll(loop, -1)], 1)
            rest = np.delete(F, faces, axis=0)
            return compact(Vd, np.vstack([rest, fan]))
        ring |= set(np.unique(inner).tolist())
    return None


def main(src: Path) -> None:
    OUT.mkdir(parents=True, exist_ok=True)
    rng = np.random.default_rng(2026)
    made = 0
    for name, (count, faces) in SOURCES.items():
        V, F = load(src / name)
        for i in range(count):
            centre = int(rng.integers(len(V)))
            disc = geodesic_disc(V, F, centre, faces * (1 + i))
            if disc is None:
                print(f"{name}: no disc around {centre}")
                continue
            Vd, Fd = disc
            stem = f"{Path(name).stem}-{i}"
            variants = {stem: (Vd, Fd)}
            if i == 0:
                variants[stem + "-noise"] = noisy(Vd, Fd, rng)
            if i == 1:
                variants[stem + "-needles"] = needles(Vd, Fd, rng)
                variants[stem + "-valence3"] = valence3(Vd, Fd, rng)
            for key, (Vv, Fv) in variants.items():
                try:
                    check_disc(Vv, Fv, key)
                except WorkbenchError as exc:
                    print(f"skip {exc}")
                    continue
                np.savez_compressed(OUT / f"{key}.npz", V=Vv.astype(np.float32), F=Fv.astype(np.int32))
                made += 1
                print(f"{key}: {len(Vv)} vertices, {len(Fv)} faces")
    # one valence-30 fan in a scanned face region
    V, F = load(src / "cow.off")
    disc = geodesic_disc(V, F, 100, 3000)
    if disc is not None:
        fan = valence30(*disc, centre=int(np.argmin(np.linalg.norm(disc[0] - disc[0].mean(0), axis=1))))
        if fan is not None:
            check_disc(*fan, "fan")
            np.savez_compressed(OUT / "cow-valence30.npz", V=fan[0].astype(np.float32), F=fan[1].astype(np.int32))
            made += 1
            print(f"cow-valence30: {len(fan[0])} vertices")
    print(f"{made} discs in {OUT}")


if __name__ == "__main__":
    main(Path(sys.argv[1]))
