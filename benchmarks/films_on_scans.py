"""Benchmark of ``films = "auto"`` on scanned parts: films, the share kept within the material, where the rest lies.

    .venv/bin/python benchmarks/films_on_scans.py --meshes DIR [--within-share 0.99] [--out DIR]

Five scans of about 120 mm (the longest side), each a part to decorate with a film of
``max_stretch = 1.5``: a bust, a figure, a beast, an ogre and a cow. ``DIR`` holds their source
files as published (not in this repository: see SCANS for where each comes from; a missing one is
skipped and said). Each is read as published, its vertices merged by position (texture seams
split them), centred and scaled to 120 mm, and designed with three views (the front and 60° to
either side, 400 mm away, y up) of a photograph (matplotlib's ``grace_hopper.jpg``, public
domain), ``surface = "seen"``, ``films = "auto"``. Reports per scan: films, the share of the
surface within [0.8, 1.5] (``design.json``'s ``within_material``), the surface outside it and its
largest region, and seconds; a Markdown table and JSON beside it in ``--out``.
"""

from __future__ import annotations

import argparse
import json
import math
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
WB = str(ROOT / ".venv" / "bin" / "workbench")

# name, file, what it is, where it is published (and its licence where it states one)
SCANS = (
    ("bust", "decimated-max.obj", "Max Planck's bust, 10,540 faces",
     "github.com/libigl/libigl-tutorial-data (MPI; libigl's tutorial data)"),
    ("figure", "homer.obj", "Homer, 12,000 faces", "github.com/alecjacobson/common-3d-test-models"),
    ("beast", "armadillo.obj", "the Stanford armadillo, 86,482 faces",
     "github.com/libigl/libigl-tutorial-data (Stanford 3D scanning repository)"),
    ("ogre", "ogre.obj", "an ogre, 124,008 faces in 40 bodies (eyes, teeth)",
     "github.com/alecjacobson/common-3d-test-models (Kiaran Ritchie)"),
    ("cow", "spot.obj", "Spot, 5,856 faces", "github.com/alecjacobson/common-3d-test-models (Keenan Crane, CC0)"),
)  # fmt: skip
SIZE_MM = 120.0
MAX_STRETCH = 1.5
TARGET_FILMS = 8


def part_mesh(src: Path, dst: Path) -> int:
    """The scan merged by position, centred and scaled to SIZE_MM; its faces."""
    import numpy as np
    import trimesh

    m = trimesh.load(src, process=False, force="mesh")
    m = trimesh.Trimesh(np.asarray(m.vertices, np.float64), np.asarray(m.faces), process=True)
    m.merge_vertices(merge_tex=True, merge_norm=True)
    lo, hi = m.bounds
    m.apply_translation(-(lo + hi) / 2)
    m.apply_scale(SIZE_MM / float((hi - lo).max()))
    m.export(dst)
    return len(m.faces)


def job_text(mesh: str, within_share: float) -> str:
    views = []
    for name, deg in (("front", 0.0), ("left", -60.0), ("right", 60.0)):
        x, z = 400.0 * math.sin(math.radians(deg)), 400.0 * math.cos(math.radians(deg))
        views.append(
            f'[[views]]\nname = "{name}"\nimage = "art.jpg"\nposition = [{x:.1f}, 0, {z:.1f}]\n'
            "look_at = [0, 0, 0]\nup = [0, 1, 0]\nfov_deg = 20\n"
        )
    return (
        f'films = "auto"\n\n[object]\nmesh = "{mesh}"\nsurface = "seen"\n'
        f'material = {{ name = "PET-G", max_stretch = {MAX_STRETCH}, within_share = {within_share} }}\n\n'
        '[print]\ndpi = 150\noutline = "free"\n\n' + "\n".join(views)
    )


def run(scan: tuple, meshes: Path, out: Path, within_share: float) -> dict:
    name, file, what, source = scan
    src = meshes / file
    rec = {"scan": name, "file": file, "what": what, "source": source, "within_share": within_share}
    if not src.is_file():
        return {**rec, "error": f"{src} not found"}
    folder = out / name
    folder.mkdir(parents=True, exist_ok=True)
    rec["faces"] = part_mesh(src, folder / "part.obj")
    import matplotlib.cbook

    with matplotlib.cbook.get_sample_data("grace_hopper.jpg") as f:
        (folder / "art.jpg").write_bytes(f.read())
    (folder / "job.toml").write_text(job_text("part.obj", within_share))
    t0 = time.perf_counter()
    r = subprocess.run(
        [WB, "design", str(folder / "job.toml"), "--out", str(folder / "design")], capture_output=True, text=True
    )
    rec["seconds"] = round(time.perf_counter() - t0, 1)
    if r.returncode != 0:
        return {**rec, "error": (r.stderr.strip().splitlines() or ["?"])[-1]}
    info = json.loads((folder / "design" / "design.json").read_text())
    plan = info["within_material"]
    rec.update(
        films=len(info["films"]),
        share=plan["share"],
        outside_mm2=plan["outside_mm2"],
        surface_mm2=sum(f["surface_mm2"] for f in info["films"]),
        largest_outside=plan["regions"][0] if plan["regions"] else None,
        regions=len(plan["regions"]) + plan["regions_not_listed"],
        seams_mm=info["seams"]["length_mm"],
    )
    return rec


def table(recs: list[dict], cmd: str) -> str:
    lines = [
        '# films = "auto" on scanned parts',
        "",
        f"`{cmd}`",
        "",
        f'Each scan {SIZE_MM:g} mm (its longest side), three views, `surface = "seen"`, `max_stretch = '
        f"{MAX_STRETCH}`; the share within [0.8, {MAX_STRETCH}] as design.json's `within_material` says it.",
        "",
        "| scan | faces | within_share asked | films | within the band | outside (mm²) | largest region outside "
        "| seams (mm) | seconds |",
        "|---|---:|---:|---:|---:|---:|---|---:|---:|",
    ]
    for r in recs:
        if "error" in r:
            lines.append(f"| {r['scan']} ({r['what']}) | {r.get('faces', '')} | {r['within_share']} | refused: "
                         f"{r['error']} | | | | | {r.get('seconds', '')} |")  # fmt: skip
            continue
        big = r["largest_outside"]
        where = (
            f"{big['area_mm2']:.1f} mm² on {big['film']} at ({', '.join(f'{v:.0f}' for v in big['centre_mm'])}) mm, "
            f"stretch {big['stretch']:.2f}"
            if big
            else "none"
        )
        lines.append(
            f"| {r['scan']} ({r['what']}) | {r['faces']:,} | {r['within_share']} | {r['films']} | "
            f"{100 * r['share']:.2f} % | {r['outside_mm2']:.1f} | {where} | {r['seams_mm']:.0f} | {r['seconds']} |"
        )
    n_ok = [r for r in recs if "error" not in r]
    lines += [
        "",
        f"Designed without refusal: {len(n_ok)} of {len(recs)}; in at most {TARGET_FILMS} films: "
        f"{sum(r['films'] <= TARGET_FILMS for r in n_ok)} of {len(recs)}.",
        "",
        "Sources: " + "; ".join(f"{r['scan']}: {r['file']}, {r['source']}" for r in recs) + ".",
    ]
    return "\n".join(lines) + "\n"


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--meshes", type=Path, required=True, help="folder holding the scans' source files")
    ap.add_argument("--out", type=Path, default=Path("films-on-scans"))
    ap.add_argument("--within-share", type=float, nargs="+", default=[0.99])
    ap.add_argument("--only", default="", help="comma-separated scan names")
    args = ap.parse_args(argv)
    only = set(filter(None, args.only.split(",")))
    recs = []
    for share in args.within_share:
        for scan in SCANS:
            if only and scan[0] not in only:
                continue
            rec = run(scan, args.meshes, args.out / f"{share:g}", share)
            print(json.dumps({k: v for k, v in rec.items() if k not in ("source",)}), flush=True)
            recs.append(rec)
    cmd = "python benchmarks/films_on_scans.py " + " ".join(sys.argv[1:] if argv is None else argv)
    args.out.mkdir(parents=True, exist_ok=True)
    (args.out / "films_on_scans.json").write_text(json.dumps(recs, indent=1) + "\n")
    (args.out / "films_on_scans.md").write_text(table(recs, cmd))
    print(table(recs, cmd))
    return 0


if __name__ == "__main__":
    sys.exit(main())
