"""Several films: the automatic split of the bundled face mask, and the two-film lid.

Run from the repository root::

    .venv/bin/python benchmarks/bench_films.py

For ``fixtures/face-mask-films`` (the scanned face, 51,712 triangles, ``films = "auto"``
with ``max_stretch = 1.3``) and for the default lid with one film per view, prints: the
number of films, their sizes in faces, the smallest share of a film within [0.8,
max_stretch] and the whole surface's (design.json's ``within_material``), the seams (total
and inside a view), the design's wall time in this process, and the closed loop through the
films' atlas in every view (median and p95 misregistration, view px, and coverage, against
the independent ray caster of the tests).
"""

from __future__ import annotations

import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "tests"))

from test_design import view_check  # noqa: E402
from test_films import HAND as LID_FILMS  # noqa: E402

from workbench.commands.design import within_material  # noqa: E402
from workbench.design import design  # noqa: E402
from workbench.export import texture_uv  # noqa: E402
from workbench.job import load_job  # noqa: E402


def report(name: str, job_path: Path) -> None:
    job = load_job(job_path)
    t0 = time.perf_counter()
    r = design(job)
    seconds = time.perf_counter() - t0
    sizes = sorted(len(f.faces) for f in r.films)
    print(f"{name}: {len(r.films)} films in {seconds:.1f} s; faces per film {sizes[0]} to {sizes[-1]}")
    plan = within_material(r, job.object.material.max_stretch) if job.object.material.max_stretch else None
    print(
        f"  smallest share of a film within [0.8, max_stretch]: {min(f.within for f in r.films):.4f}"
        + (f"; of the whole surface: {plan['share']:.4f}" if plan else "")
    )
    print(f"  seams {r.seams['length_mm']:.0f} mm, {r.seams['in_view_mm']:.0f} mm of them inside one view's region")
    rows, cols = r.grid.shape
    vt = texture_uv(r.flat.uv, cols / r.grid.px_per_mm, rows / r.grid.px_per_mm, r.flat.height_mm)
    for v, spec in enumerate(job.views):
        mis, coverage = view_check(job, r, vt, v)
        print(
            f"  view {spec.name}: {len(mis)} tiles, misregistration median {np.median(mis):.3f} px, "
            f"p95 {np.percentile(mis, 95):.3f} px, coverage {coverage:.4f}"
        )


def main() -> None:
    report("face-mask-films (auto, max_stretch 1.3, 100 dpi)", ROOT / "fixtures" / "face-mask-films" / "job.toml")
    with tempfile.TemporaryDirectory() as tmp:
        text = (ROOT / "fixtures" / "default" / "job.toml").read_text()
        for f in ("part.obj", "logo.png", "front.png"):
            text = text.replace(f'"{f}"', f'"{ROOT / "fixtures" / "default" / f}"')
        job = Path(tmp) / "lid-films.toml"
        job.write_text(text + LID_FILMS)
        report("default lid, one film per view (300 dpi)", job)


if __name__ == "__main__":
    main()
