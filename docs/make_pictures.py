"""Regenerate the pictures of the README and the docs (docs/img/) from the bundled default job (run after `make demo`).

.venv/bin/python docs/make_pictures.py
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import cv2
import numpy as np

ROOT = Path(__file__).resolve().parents[1]
IMG = ROOT / "docs" / "img"


def fit(img: np.ndarray, height: int) -> np.ndarray:
    s = height / img.shape[0]
    return cv2.resize(img, (int(round(img.shape[1] * s)), height), interpolation=cv2.INTER_AREA)


def label(img: np.ndarray, text: str) -> np.ndarray:
    out = cv2.copyMakeBorder(img, 34, 6, 6, 6, cv2.BORDER_CONSTANT, value=(255, 255, 255))
    cv2.putText(out, text, (8, 24), cv2.FONT_HERSHEY_SIMPLEX, 0.6, (20, 20, 20), 1, cv2.LINE_AA)
    return out


def main() -> None:
    IMG.mkdir(parents=True, exist_ok=True)
    out = ROOT / "out" / "pictures"
    wb = str(ROOT / ".venv" / "bin" / "workbench")
    for cmd, src, dst in (
        ("flatten", "fixtures/default/part.obj", "flatten"),
        ("design", "fixtures/default/job.toml", "design"),
    ):
        subprocess.run([wb, cmd, src, "--out", str(out / dst), "-q"], check=True, cwd=ROOT)
    (IMG / "flatten-default.png").write_bytes((out / "flatten" / "flatten.png").read_bytes())
    (IMG / "design-views.png").write_bytes((out / "design" / "views.png").read_bytes())
    (IMG / "design-stretch.png").write_bytes((out / "design" / "stretch.png").read_bytes())
    pdf = out / "default.pdf"
    subprocess.run([wb, "pdf", str(out / "design"), "-o", str(pdf), "--paper", "A4", "-q"], check=True, cwd=ROOT)
    fixture = out / "fixture.pdf"
    subprocess.run(
        [wb, "board", "fixture", "fixtures/default/job.toml", "-o", str(fixture), "-q"], check=True, cwd=ROOT
    )
    prev = out / "previews"
    subprocess.run([wb, "render", str(out / "design"), "--previews", "-o", str(prev), "-q"], check=True, cwd=ROOT)
    (IMG / "render-previews.png").write_bytes((prev / "contact_sheet.png").read_bytes())
    import pypdfium2 as pdfium

    for src, name in ((pdf, "pdf-default.png"), (fixture, "board-fixture-default.png")):
        page = pdfium.PdfDocument(str(src))[0].render(scale=110 / 72).to_pil()
        page.save(IMG / name, optimize=True)
    # validate: a photo with the film 0.8 mm off, its heat map
    photo = out / "photo_offset.jpg"
    subprocess.run(
        [
            wb,
            "render",
            str(out / "design"),
            "--orbit",
            "10,55,330",
            "--size",
            "2000x1500",
            "--realistic",
            "--film-offset-mm",
            "0.8,0",
            "-o",
            str(photo),
            "-q",
        ],
        check=True,
        cwd=ROOT,
    )
    subprocess.run(
        [
            wb,
            "validate",
            str(out / "design"),
            str(photo),
            "--camera",
            str(photo.with_suffix(".json")),
            "--out",
            str(out / "validation"),
            "-q",
        ],
        check=True,
        cwd=ROOT,
    )
    heat = cv2.imread(str(out / "validation" / "photo_offset_heatmap_front.png"))
    shot = fit(cv2.imread(str(photo)), heat.shape[0] - 40)
    cv2.imwrite(
        str(IMG / "validate-default.png"),
        np.hstack([label(shot, "photo: film 0.8 mm off"), cv2.resize(heat, (heat.shape[1], shot.shape[0] + 40))]),
    )
    # calibrate: residuals of a camera calibration on 15 synthetic views
    sys.path.insert(0, str(ROOT / "tests"))
    from test_calibrate import board_definition, calibration_photos

    cal = out / "calib"
    cal.mkdir(exist_ok=True)
    board, board_path = board_definition(cal)
    views = calibration_photos(cal, board)
    subprocess.run(
        [wb, "calibrate", "camera", *map(str, views), "--board", str(board_path), "-o", str(cal / "camera.json"), "-q"],
        check=True,
        cwd=ROOT,
    )
    (IMG / "calibrate-residuals.png").write_bytes((cal / "camera.png").read_bytes())
    logo = cv2.imread(str(ROOT / "fixtures/default/logo.png"))
    front = cv2.imread(str(ROOT / "fixtures/default/front.png"))
    printed = cv2.imread(str(out / "design" / "print.png"))
    h = 300
    inputs = np.vstack(
        [label(fit(logo, h // 2 - 20), "view 1 'logo' (from above)"), label(fit(front, h // 2 - 20), "view 2 'front'")]
    )
    right = label(fit(printed, inputs.shape[0] - 40), "print.png: one print, exact from both views")
    right = cv2.copyMakeBorder(right, 0, inputs.shape[0] - right.shape[0], 0, 0, cv2.BORDER_CONSTANT, value=(255,) * 3)
    arrow = np.full((inputs.shape[0], 60, 3), 255, np.uint8)
    cv2.arrowedLine(arrow, (8, inputs.shape[0] // 2), (52, inputs.shape[0] // 2), (40, 40, 40), 3, tipLength=0.35)
    cv2.imwrite(str(IMG / "design-default.png"), np.hstack([inputs, arrow, right]))
    print(f"wrote {IMG}", file=sys.stderr)


def real_mesh_picture(name: str = "arm-1-needles") -> None:
    """A corpus disc that needs Ptolemy flips: the input, and its common subdivision in the print."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.collections import PolyCollection

    from workbench.conformal.flatten import flatten
    from workbench.conformal.layout import signed_areas

    d = np.load(ROOT / "tests" / "data" / "corpus" / f"{name}.npz")
    V, F = d["V"].astype(np.float64), d["F"].astype(np.int64)
    V *= 150.0 / np.linalg.norm(V.max(0) - V.min(0))
    r = flatten(V, F)
    cut = np.bincount(r.parent, minlength=len(F)) > 1  # input triangles the flips cut
    P = V - V.mean(0)
    Q = P @ np.linalg.svd(P, full_matrices=False)[2][:2].T
    fig, ax = plt.subplots(1, 2, figsize=(12, 5.4), dpi=100)
    colours = np.where(cut, "#f4a261", "#d9d9d9")
    ax[0].add_collection(PolyCollection(Q[F], facecolors=colours, edgecolors="#555555", linewidths=0.15))
    ax[0].set_title(f"{name}: {len(F)} input triangles; orange: cut by flipped edges", fontsize=10)
    sub = np.where(cut[r.parent], "#f4a261", "#d9d9d9")
    ax[1].add_collection(PolyCollection(r.uv[r.F], facecolors=sub, edgecolors="#555555", linewidths=0.15))
    ax[1].set_title(
        f"print, {r.width_mm:.0f} x {r.height_mm:.0f} mm: {r.intrinsic_flips} Ptolemy flips, {len(r.F)} triangles, "
        f"{int((signed_areas(r.uv, r.F) <= 0).sum())} flipped",
        fontsize=10,
    )
    for a in ax:
        a.autoscale()
        a.set_aspect("equal")
        a.axis("off")
    fig.tight_layout()
    fig.savefig(IMG / "flatten-real.png")
    print(f"wrote {IMG / 'flatten-real.png'}", file=sys.stderr)


def face_mask_pictures() -> None:
    """views.png and stretch.png of the bundled face mask (free outline)."""
    wb = str(ROOT / ".venv" / "bin" / "workbench")
    out = ROOT / "out" / "pictures" / "face-mask"
    subprocess.run([wb, "design", "fixtures/face-mask/job.toml", "--out", str(out), "-q"], check=True, cwd=ROOT)
    (IMG / "face-mask-views.png").write_bytes((out / "views.png").read_bytes())
    (IMG / "face-mask-stretch.png").write_bytes((out / "stretch.png").read_bytes())
    print(f"wrote {IMG / 'face-mask-views.png'}, face-mask-stretch.png", file=sys.stderr)


def films_picture() -> None:
    """views.png of the default lid with one film per view."""
    import tempfile

    wb = str(ROOT / ".venv" / "bin" / "workbench")
    with tempfile.TemporaryDirectory() as tmp:
        job = Path(tmp) / "lid-two-films.toml"
        text = (ROOT / "fixtures/default/job.toml").read_text()
        for name in ("part.obj", "logo.png", "front.png"):
            text = text.replace(f'"{name}"', f'"{ROOT / "fixtures/default" / name}"')
        films = '\n[[films]]\nname = "logo"\nviews = ["logo"]\noutline = "free"\n'
        films += '\n[[films]]\nname = "front"\nviews = ["front"]\noutline = "free"\n'
        job.write_text(text + films)
        out = Path(tmp) / "out"
        subprocess.run([wb, "design", str(job), "--out", str(out), "-q"], check=True, cwd=ROOT)
        (IMG / "films-views.png").write_bytes((out / "views.png").read_bytes())
    print(f"wrote {IMG / 'films-views.png'}", file=sys.stderr)


if __name__ == "__main__":
    main()
    real_mesh_picture()
    face_mask_pictures()
    films_picture()
