"""The single sampling plan ISO 2859-1 gives for a lot size, an inspection level and an AQL."""

from __future__ import annotations

from dataclasses import dataclass

from workbench.errors import UsageError
from workbench.lots.tables import (
    AQLS,
    CODE_LETTERS,
    LEVELS,
    NORMAL,
    REDUCED,
    REDUCED_SAMPLE_SIZES,
    SAMPLE_SIZES,
    TIGHTENED,
    TIGHTENED_SAMPLE_SIZES,
)

LETTERS = tuple(SAMPLE_SIZES)
# each inspection's master table (Tables 2-A, 2-B, 2-C) and its sample size per code letter
INSPECTIONS = ("normal", "tightened", "reduced")
MASTER_TABLES = {
    "normal": (NORMAL, SAMPLE_SIZES),
    "tightened": (TIGHTENED, TIGHTENED_SAMPLE_SIZES),
    "reduced": (REDUCED, REDUCED_SAMPLE_SIZES),
}


@dataclass(frozen=True)
class SamplingPlan:
    """A single sampling plan under ``inspection`` (normal, tightened or reduced).

    ``code_letter`` is Table 1's letter for the lot; ``plan_letter`` the row of the inspection's
    master table (2-A, 2-B or 2-C) the arrows lead to, whose sample size the plan takes.
    ``sample_size`` is at most the lot size (a sample as large as the lot is 100 % inspection,
    ``hundred_percent``).
    """

    lot_size: int
    level: str
    aql: str
    code_letter: str
    plan_letter: str
    sample_size: int
    accept: int
    reject: int
    hundred_percent: bool
    inspection: str = "normal"


def aql_text(value: str) -> str:
    """The AQL as Table 2-A prints it (``"1"`` and ``"1.00"`` are ``"1.0"``), else a :class:`UsageError`."""
    try:
        x = float(value)
    except ValueError:
        x = None
    for a in AQLS:
        if x is not None and abs(float(a) - x) <= 1e-9 * float(a):
            return a
    raise UsageError(f"--aql {value}: not an AQL of ISO 2859-1 (one of {', '.join(AQLS)})")


def code_letter(lot_size: int, level: str) -> str:
    """Table 1's sample size code letter for a lot of ``lot_size`` items at inspection ``level``."""
    if level not in LEVELS:
        raise UsageError(f"--level {level}: not an inspection level of ISO 2859-1 (one of {', '.join(LEVELS)})")
    if lot_size < 2:
        raise UsageError(f"--lot-size {lot_size}: a lot has at least 2 items")
    for largest, letters in CODE_LETTERS:
        if largest is None or lot_size <= largest:
            return letters.split()[LEVELS.index(level)]
    raise AssertionError("Table 1's last row has no bound")


def sampling_plan(lot_size: int, level: str, aql: str, inspection: str = "normal") -> SamplingPlan:
    """The single sampling plan (ISO 2859-1, Table 1 and Table 2-A, 2-B or 2-C).

    Parameters
    ----------
    lot_size : int
        Items in the lot (2 or more).
    level : str
        Inspection level: S-1 to S-4, I, II or III.
    aql : str
        An AQL of Table 2-A (see :func:`aql_text`).
    inspection : str
        ``normal``, ``tightened`` or ``reduced`` (see :mod:`workbench.lots.switching`).

    Returns
    -------
    SamplingPlan
        The arrows of the master table followed to the first plan below (``v``) or above (``^``);
        the one up arrow with no plan above it (code letter A, AQL 10, normal) is read as A's 0/1.
    """
    aql = aql_text(aql)
    letter = code_letter(lot_size, level)
    table, sizes = MASTER_TABLES[inspection]
    letters = tuple(table)
    column = AQLS.index(aql)
    row = letters.index(letter)
    cell = table[letter].split(" | ")[column]
    while cell in ("v", "^"):
        if cell == "^" and row == 0:
            # the first row's up arrow (A at AQL 10) has no plan above it: our reading takes the
            # nearest plan of the row (A's 0/1 under 6.5, n = 2), the stricter of its neighbours
            column -= 1
        else:
            row += 1 if cell == "v" else -1
        cell = table[letters[row]].split(" | ")[column]
    if cell == "-":
        raise AssertionError(f"{inspection} {letter} {aql}: an arrow to a cell without a plan")
    accept, reject = map(int, cell.split())
    n = sizes[letters[row]]
    return SamplingPlan(
        lot_size=lot_size,
        level=level,
        aql=aql,
        code_letter=letter,
        plan_letter=letters[row],
        sample_size=min(n, lot_size),
        accept=accept,
        reject=reject,
        hundred_percent=n >= lot_size,
        inspection=inspection,
    )
