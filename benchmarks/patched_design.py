"""A perfect photo against a design that is not what was printed: the verdict must never be PASS.

    .venv/bin/python benchmarks/patched_design.py [--patches 20] [--renderer workbench|mitsuba|both]
        [--size 4000x3000] [--seed 0] [--finish glossy|matte] [--out DIR]

Designs the default job, renders a perfect photo of it (the workbench renderer with --realistic
and, on a glossy film, the lamp's gloss; or Mitsuba 3's path tracer), then validates that photo against copies of the
design whose print carries one square patch each: 25 to 100 mm², a colour drawn uniformly from the
RGB cube, its centre drawn uniformly over the film where the print is not background. That is the
part without the patch, judged against a design with it ("a patch of the design that is not on
the part"); the reverse (a patch on the part and not in the design) is a defect and is measured by
``random_defects.py``. Prints, per patch, its place, size and colour, the verdict, and the listed
defect nearest to the patch; then the counts. A PASS is a wrong answer.
"""

from __future__ import annotations

import argparse
import json
import shutil
import subprocess
import tempfile
from pathlib import Path

import cv2
import numpy as np

ROOT = Path(__file__).resolve().parents[1]
WB = str(ROOT / ".venv" / "bin" / "workbench")
LOOKS = {
    "workbench": ["--orbit=10,55,330", "--realistic"],
    "mitsuba": ["--orbit=10,55,330", "--renderer", "mitsuba", "--spp", "8", "--jpeg-quality", "90"],
}
GLOSS = {"glossy": "0.5", "matte": "0"}  # the film's --gloss for each --finish


def patch_print(design: Path, out: Path, rng: np.random.Generator) -> dict:
    """A copy of ``design`` whose print carries one random square patch; the patch's truth."""
    shutil.copytree(design, out)
    info = json.loads((design / "design.json").read_text())
    ppm = info["print"]["dpi"] / 25.4
    img = cv2.imread(str(out / "print.png"), cv2.IMREAD_UNCHANGED)
    background = np.array([int(info.get("print", {}).get("background", "#ffffff")[i : i + 2], 16) for i in (1, 3, 5)]
                          if isinstance(info["print"].get("background"), str) else [255, 255, 255])  # fmt: skip
    area = float(rng.uniform(25.0, 100.0))
    side_px = int(round(np.sqrt(area) * ppm))
    rows, cols = img.shape[:2]
    rgb = img[..., 2::-1] if img.shape[2] >= 3 else img
    # where the print is ink, not background, with the whole square inside the print
    ink = (np.abs(rgb.astype(int) - background).max(axis=2) > 8)[: rows - side_px, : cols - side_px]
    r, c = np.argwhere(ink)[rng.integers(int(ink.sum()))]
    colour = rng.integers(0, 256, 3)
    img[r : r + side_px, c : c + side_px, :3] = colour[::-1]  # BGR
    cv2.imwrite(str(out / "print.png"), img)
    centre = ((c + side_px / 2) / ppm, (r + side_px / 2) / ppm)
    return {"centre_mm": centre, "area_mm2": (side_px / ppm) ** 2, "rgb": colour.tolist()}


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--patches", type=int, default=20)
    ap.add_argument("--renderer", choices=["workbench", "mitsuba", "both"], default="workbench")
    ap.add_argument("--size", default="4000x3000")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--finish", choices=sorted(GLOSS), default="glossy", help="the film rendered and validated")
    ap.add_argument("--out", type=Path, default=None, help="keep the folders here (default: a temporary one)")
    args = ap.parse_args()
    renderers = ["workbench", "mitsuba"] if args.renderer == "both" else [args.renderer]
    with tempfile.TemporaryDirectory(prefix="patched_design_") as tmp:
        root = args.out or Path(tmp)
        root.mkdir(parents=True, exist_ok=True)
        design = root / "design"
        if not design.exists():
            subprocess.run(
                [WB, "design", str(ROOT / "fixtures/default/job.toml"), "--out", str(design), "-q"], check=True
            )
        photos = {}
        for renderer in renderers:
            photo = root / f"perfect-{renderer}-{args.finish}.jpg"
            if not photo.exists():
                look = [*LOOKS[renderer], "--gloss", GLOSS[args.finish]]
                cmd = [WB, "render", str(design), *look, "--size", args.size, "-o", str(photo), "-q"]
                subprocess.run(cmd, check=True)
            photos[renderer] = photo
        rng = np.random.default_rng(args.seed)
        counts: dict = {}
        print("| # | renderer | patch centre (mm) | mm² | RGB | verdict | nearest defect |")
        print("|---|---|---|---:|---|---|---|")
        for k in range(args.patches):
            patched = root / f"patched-{k}"
            shutil.rmtree(patched, ignore_errors=True)
            truth = patch_print(design, patched, rng)
            for renderer, photo in photos.items():
                out = root / f"v-{k}-{renderer}"
                shutil.rmtree(out, ignore_errors=True)
                cmd = [WB, "validate", str(patched), str(photo), "--camera", str(photo.with_suffix(".json"))]
                subprocess.run([*cmd, "--finish", args.finish, "--out", str(out), "-q"], check=False)
                rep = json.loads((out / "validation.json").read_text())
                verdict = rep["part"]["verdict"] if "part" in rep else rep["photos"][0]["verdict"]
                counts[verdict] = counts.get(verdict, 0) + 1
                defects = [d for p in rep["photos"] for d in (p.get("defects") or [])]
                near = "none listed"
                if defects:
                    dist = [np.hypot(*np.subtract(d["centre_mm"], truth["centre_mm"])) for d in defects]
                    j = int(np.argmin(dist))
                    near = f"{defects[j]['kind']} {defects[j]['area_mm2']:.1f} mm² at {dist[j]:.1f} mm"
                x, y = truth["centre_mm"]
                where = f"({x:.1f}, {y:.1f}) | {truth['area_mm2']:.0f} | {truth['rgb']}"
                print(f"| {k} | {renderer} | {where} | {verdict} | {near} |")
        print()
        print("verdicts:", ", ".join(f"{v} {n}" for v, n in sorted(counts.items())), "(a PASS is a wrong answer)")


if __name__ == "__main__":
    main()
