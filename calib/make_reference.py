"""Regenerate the reference data of the printer calibration regression (needs the test extras).

    .venv/bin/python calib/make_reference.py

A5 printer target -> simulated print with +0.40 % x and -0.25 % y scale error -> flat scan at
300 dpi -> the reference profile. `workbench calibrate check calib/printers/reference-laser.json
calib/regression/printer-target-scan-300dpi.png` is the weekly check.
"""

from __future__ import annotations

import subprocess
from pathlib import Path

import cv2
import numpy as np

from workbench.export import png_bytes

HERE = Path(__file__).resolve().parent
WB = str(HERE.parent / ".venv" / "bin" / "workbench")


def main() -> None:
    import pypdfium2 as pdfium

    board = HERE / "boards" / "printer-target-A5.pdf"
    subprocess.run(
        [WB, "board", "printer-target", "--paper", "A5", "-o", str(board), "-q"],
        check=True,
        env={"SOURCE_DATE_EPOCH": "1795392000", "PATH": ""},
    )
    hi = np.asarray(pdfium.PdfDocument(str(board))[0].render(scale=600 / 72, grayscale=True).to_pil().convert("L"))
    h, w = hi.shape
    sx, sy = 1.004, 0.9975
    # exact affine resampling (see tests/test_calibrate.py: stretch_and_scan)
    blurred = cv2.GaussianBlur(hi.astype(np.float32), (0, 0), 1.2)
    M = np.array([[2 / sx, 0, 1 / sx - 0.5], [0, 2 / sy, 1 / sy - 0.5]])
    scan = cv2.warpAffine(
        blurred, M, (int(w * sx / 2), int(h * sy / 2)), flags=cv2.INTER_LINEAR | cv2.WARP_INVERSE_MAP, borderValue=255
    )
    scan = np.clip(scan + np.random.default_rng(11).normal(0, 1.5, scan.shape), 0, 255).astype(np.uint8)
    out = HERE / "regression" / "printer-target-scan-300dpi.png"
    out.write_bytes(png_bytes(scan, 300, compression=9))
    subprocess.run(
        [
            WB,
            "calibrate",
            "printer",
            str(out),
            "--board",
            str(board.with_suffix(".json")),
            "--dpi",
            "300",
            "--name",
            "reference laser (simulated)",
            "-o",
            str(HERE / "printers" / "reference-laser.json"),
        ],
        check=True,
    )


if __name__ == "__main__":
    main()
