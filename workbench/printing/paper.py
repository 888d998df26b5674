"""Paper sizes and the choice of a sheet that holds a layout."""

from __future__ import annotations

import re

from workbench.errors import UsageError, WorkbenchError
from workbench.options import parse_number

# portrait width x height, mm
PAPERS = {
    "A5": (148.0, 210.0),
    "A4": (210.0, 297.0),
    "letter": (215.9, 279.4),
    "legal": (215.9, 355.6),
    "A3": (297.0, 420.0),
    "tabloid": (279.4, 431.8),
    "A2": (420.0, 594.0),
    "A1": (594.0, 841.0),
    "A0": (841.0, 1189.0),
}
AUTO_ORDER = ("A4", "letter", "A3", "A2", "A1", "A0")


# No printer or plotter takes a sheet longer than this (mm): a larger one is a typo.
MAX_SHEET_MM = 5000.0


def parse_paper(text: str) -> str | tuple[float, float]:
    """``A4``, ``letter``, ``auto`` or ``WxH`` (mm) → a paper name or (w, h) in mm."""
    if text == "auto" or text in PAPERS:
        return text
    for name in PAPERS:
        if text.lower() == name.lower():
            return name
    m = re.fullmatch(r"\s*([0-9.eE+-]+)\s*[xX]\s*([0-9.eE+-]+)\s*(mm)?\s*", text)
    if m:
        w, h = (
            parse_number(v, f"--paper {text!r}: each side", 0, MAX_SHEET_MM, lo_open=True, unit="mm")
            for v in m.group(1, 2)
        )
        return (w, h)
    raise UsageError(f"--paper {text!r}: use {', '.join(PAPERS)}, auto, or WxH in mm (e.g. 300x400)")


def choose_sheet(paper: str | tuple[float, float], need_w: float, need_h: float) -> tuple[str, float, float]:
    """A sheet, in the orientation that holds ``need_w`` x ``need_h`` mm.

    Parameters
    ----------
    paper : str or (w, h)
        A name from PAPERS, ``'auto'`` (the first of A4, letter, A3, ... that holds
        it) or a custom size in mm.
    need_w, need_h : float
        Size of the content including its margins, mm.

    Returns
    -------
    name, width_mm, height_mm
        The sheet as the page will be (portrait or landscape).

    Raises
    ------
    WorkbenchError
        The content does not fit; names the smallest standard sheet that would.
    """
    candidates = AUTO_ORDER if paper == "auto" else [paper]
    for p in candidates:
        w, h = PAPERS[p] if isinstance(p, str) else p
        name = p if isinstance(p, str) else f"{w:g}x{h:g} mm"
        for pw, ph, orient in ((w, h, "portrait"), (h, w, "landscape")):
            if need_w <= pw + 1e-9 and need_h <= ph + 1e-9:
                return f"{name} {orient}", pw, ph
    fits = next((p for p in AUTO_ORDER if _holds(PAPERS[p], need_w, need_h)), None)
    hint = (
        f"use --paper {fits} (or auto)" if fits else f"use --paper {need_w:.0f}x{need_h:.0f} on a wide-format printer"
    )
    name = paper if isinstance(paper, str) else f"{paper[0]:g}x{paper[1]:g} mm"
    raise WorkbenchError(f"the print with its marks needs {need_w:.1f} x {need_h:.1f} mm; {name} is too small: {hint}")


def _holds(size: tuple[float, float], w: float, h: float) -> bool:
    return (w <= size[0] and h <= size[1]) or (w <= size[1] and h <= size[0])
