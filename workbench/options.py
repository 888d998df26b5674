"""One validated parser for every number given on the command line.

Every numeric option, and every number of an option that takes several (``--orbit
AZ,EL,DIST``, ``--corners A,B,C,D``, ``--squares NXxNY``), is read here: a finite number
(an integer where one is meant, any number of digits) inside the range the command can
honour, else one line naming the option and the value, exit status 2. The ranges are
what the commands can honour, not what is sensible: plausibility (a dpi that prints
nothing legible) is the commands' warnings.
"""

from __future__ import annotations

import argparse
import math

from workbench.errors import UsageError


def _fmt(x: float) -> str:
    """A bound as typed: whole numbers in full (2147483647, not 2.14748e+09)."""
    return str(int(x)) if float(x).is_integer() and abs(x) < 1e16 else f"{x:g}"


def _range_text(lo: float, hi: float, lo_open: bool, hi_open: bool, unit: str) -> str:
    u = f" {unit}" if unit else ""
    if math.isinf(hi):
        return f"more than {_fmt(lo)}{u}" if lo_open else f"at least {_fmt(lo)}{u}"
    if lo_open and lo == 0 and not hi_open:
        return f"positive, at most {_fmt(hi)}{u}"
    if lo_open and hi_open:
        return f"between {_fmt(lo)} and {_fmt(hi)}{u}, both excluded"
    if lo_open or hi_open:
        low = f"{'more than' if lo_open else 'at least'} {_fmt(lo)}"
        return f"{low} and {'less than' if hi_open else 'at most'} {_fmt(hi)}{u}"
    return f"between {_fmt(lo)} and {_fmt(hi)}{u}"


def parse_number(
    text: str,
    what: str,
    lo: float = -math.inf,
    hi: float = math.inf,
    *,
    integer: bool = False,
    lo_open: bool = False,
    hi_open: bool = False,
    unit: str = "",
) -> float | int:
    """``text`` as a finite number in ``[lo, hi]`` (ends open where asked), else a :class:`UsageError`.

    Parameters
    ----------
    text : str
        The value as typed.
    what : str
        The option, as the error names it (``--dpi``).
    lo, hi : float
        The range.
    integer : bool
        A whole number (``int``; ``3.0`` and ``1e3`` are refused).
    lo_open, hi_open : bool
        The end itself excluded.
    unit : str
        Named in the error after the range (``mm``).

    Returns
    -------
    float or int
    """
    s = str(text).strip()
    span = _range_text(lo, hi, lo_open, hi_open, unit)
    try:
        value = int(s) if integer else float(s)
    except ValueError:
        kind = "a whole number" if integer else "a number"
        raise UsageError(f"{what} {text!r}: not {kind} (must be {span})") from None
    if not integer and not math.isfinite(value):
        raise UsageError(f"{what} {text}: must be a finite number")
    below = value <= lo if lo_open else value < lo
    above = value >= hi if hi_open else value > hi
    if below or above:
        raise UsageError(f"{what} {text}: must be {span}")
    return value


def parse_numbers(text: str, n: int, what: str, sep: str = ",", **limits) -> tuple:
    """``n`` numbers separated by ``sep``, each through :func:`parse_number` with ``limits``."""
    parts = str(text).split(sep)
    if len(parts) != n or not all(p.strip() for p in parts):
        raise UsageError(f"{what} {text!r}: give {n} {'comma-separated' if sep == ',' else sep + '-separated'} numbers")
    return tuple(parse_number(p, what, **limits) for p in parts)


def parse_part_offset(text: str | None) -> tuple | None:
    """``--part-offset-mm X,Y`` or ``X,Y,Z`` (mm; Z 0 when not given), as render and validate take it."""
    if text is None:
        return None
    n = 3 if len(str(text).split(",")) == 3 else 2
    vals = parse_numbers(text, n, "--part-offset-mm", lo=-1000, hi=1000, unit="mm")
    return tuple(vals) + (0.0,) * (3 - n)


def parse_part_rotation(text: str | None) -> tuple | None:
    """``--part-rotation-deg RX,RY,RZ`` (degrees), as render and validate take it."""
    if text is None:
        return None
    return parse_numbers(text, 3, "--part-rotation-deg", lo=-360, hi=360, unit="degrees")


class Number(argparse.Action):
    """``add_argument(..., action=Number, lo=, hi=, integer=, lo_open=, hi_open=, unit=)``: a checked number."""

    def __init__(self, option_strings, dest, *, lo=-math.inf, hi=math.inf, integer=False, lo_open=False,
                 hi_open=False, unit="", **kwargs):  # fmt: skip
        super().__init__(option_strings, dest, **kwargs)
        self.limits = {"lo": lo, "hi": hi, "integer": integer, "lo_open": lo_open, "hi_open": hi_open, "unit": unit}

    def __call__(self, parser, namespace, values, option_string=None):
        setattr(namespace, self.dest, parse_number(values, option_string or self.dest, **self.limits))
