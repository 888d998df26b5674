"""Local defects found by workbench validate, against the truth the renderer wrote: printed figures.

    .venv/bin/python benchmarks/bench_defects.py [--size 4000x3000] [--renderer workbench|mitsuba|both]

Designs the default job and renders, through the issue's conditions (glossy film with the
lamp's highlight, --realistic, lens distortion k1 = -0.10 known to the camera profile), one
photo per defect and a perfect one; validates each at a 0.2 mm tolerance and prints, per
defect, the verdict, the location error (mm on the print), the area error (%), the kind, and
the share of each view's own region that is measured, and the detection limit validate states
for the photo. With ``--renderer mitsuba`` (or ``both``, the default) the same photos come from
Mitsuba 3's path tracer (8 samples a pixel, its own gloss and lamp, JPEG 90).
"""

from __future__ import annotations

import argparse
import json
import subprocess
import tempfile
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
WB = str(ROOT / ".venv" / "bin" / "workbench")
LOOKS = {
    "workbench": ["--orbit=10,55,330", "--realistic", "--gloss", "0.5", "--distortion=-0.1,0,0,0,0"],
    "mitsuba": [
        "--orbit=10,55,330",
        "--renderer",
        "mitsuba",
        "--spp",
        "8",
        "--gloss",
        "0.5",
        "--distortion=-0.1,0,0,0,0",
        "--jpeg-quality",
        "90",
    ],
}
CASES = {
    "perfect": [],
    "bubble 1 mm, 12 mm across": ["--defect", "bubble:45,30,6,1"],
    "bubble 0.5 mm, 6 mm across": ["--defect", "bubble:75,50,3,0.5"],
    "dropout 10 mm²": ["--defect", "dropout:60,25,1.784"],
    "scratch 20 mm x 0.5 mm": ["--defect", "scratch:38,42,58,42,0.5"],
}


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--size", default="4000x3000")
    ap.add_argument("--renderer", choices=["workbench", "mitsuba", "both"], default="both")
    args = ap.parse_args()
    renderers = ["workbench", "mitsuba"] if args.renderer == "both" else [args.renderer]
    with tempfile.TemporaryDirectory(prefix="bench_defects_") as tmp:
        tmp = Path(tmp)
        design = tmp / "design"
        subprocess.run([WB, "design", str(ROOT / "fixtures/default/job.toml"), "--out", str(design), "-q"], check=True)
        for renderer in renderers:
            table(tmp, design, args.size, renderer)


def table(tmp: Path, design: Path, size: str, renderer: str) -> None:
    """One photo per case from one renderer, validated; a line per case."""
    print(f"workbench validate on {size} {renderer} renders: gloss 0.5, k1 = -0.10; tolerance 0.2 mm")
    print(f"{'case':<28} {'verdict':<7} {'found':>5} {'kind':<8} {'error mm':>8} {'area mm²':>9} {'truth':>7}")
    for name, extra in CASES.items():
        p = tmp / "p.jpg"
        cmd = [WB, "render", str(design), "--size", size, *LOOKS[renderer], *extra, "-o", str(p), "-q"]
        subprocess.run(cmd, check=True)
        out = tmp / "v"
        cmd = [WB, "validate", str(design), str(p), "--camera", str(p.with_suffix(".json"))]
        subprocess.run([*cmd, "--tolerance-mm", "0.2", "--out", str(out), "-q", "--jobs", "1"], check=True)
        e = json.loads((out / "validation.json").read_text())["photos"][0]
        truth = json.loads(p.with_suffix(".json").read_text())["defects"]
        cov = ", ".join(f"{k} {100 * v['measured']:.1f} %" for k, v in e["dense"]["coverage"].items())
        if not truth:
            lim = e["dense"]["detection_limit"]
            print(
                f"{name:<28} {e['verdict']:<7} {len(e['defects']):>5}   measured: {cov}; detection limit "
                f"{lim['min_area_mm2']:.1f} mm², {lim['min_shift_mm']:.3f} mm; {e['seconds']:.2f} s"
            )
            continue
        t = truth[0]
        c = np.asarray(t["centre_mm"])
        f = min(e["defects"], key=lambda d: np.linalg.norm(np.asarray(d["centre_mm"]) - c))
        err = float(np.linalg.norm(np.asarray(f["centre_mm"]) - c))
        print(
            f"{name:<28} {e['verdict']:<7} {len(e['defects']):>5} {f['kind']:<8} {err:>8.2f} "
            f"{f['area_mm2']:>9.2f} {t['area_mm2']:>7.2f} ({100 * (f['area_mm2'] / t['area_mm2'] - 1):+.1f} %)"
        )


if __name__ == "__main__":
    main()
