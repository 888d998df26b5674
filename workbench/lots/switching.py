"""ISO 2859-1's switching rules: a lot's inspection (normal, tightened, reduced) from the lots before it.

The rules of ISO 2859-1:1999, clause 9, over a series of lots in the order they were inspected:

- normal to tightened (9.3.1): 2 lots not accepted on original inspection out of 5 or fewer
  consecutive lots;
- tightened to normal (9.3.2): 5 consecutive lots accepted on original inspection;
- normal to reduced (9.3.3): the switching score reaches 30, production is steady and the
  responsible authority approves reduced inspection. The score starts at 0 with normal inspection;
  a lot whose plan accepts 2 or more adds 3 if it would have been accepted with the AQL one step
  tighter, else resets it; a lot whose plan accepts 0 or 1 adds 2 when accepted; a lot not accepted
  resets it. Steadiness and approval are not in the records: the caller says (``allow_reduced``);
- reduced to normal (9.3.4): a lot not accepted;
- discontinuation (9.4): the lots not accepted in one run of tightened inspection reach 5; the
  acceptance procedure stops there (every later lot is ``discontinued``).
"""

from __future__ import annotations

from dataclasses import dataclass, replace

from workbench.lots.plan import SamplingPlan
from workbench.lots.tables import AQLS, NORMAL

SCORE_FOR_REDUCED = 30
WINDOW = 5  # "2 out of 5 or fewer consecutive lots"
ACCEPTED_TO_NORMAL = 5
NOT_ACCEPTED_TO_DISCONTINUE = 5


@dataclass(frozen=True)
class LotOutcome:
    """One earlier lot as the rules see it: its name, plan and decision (``accept`` or ``reject``)."""

    lot: str
    plan: SamplingPlan
    nonconforming: int
    accepted: bool


@dataclass(frozen=True)
class Switching:
    """The inspection for the next lot and why.

    ``rule``: the rule that set it (with its clause); ``lots``: the lots that triggered that rule;
    ``switching_score``: the score of 9.3.3 (normal inspection only; 0 otherwise). ``run`` and
    ``score_lots`` are the rules' memory: the outcomes (lot, accepted) since the current
    inspection began, and the lots that built the score.
    """

    inspection: str
    rule: str
    lots: tuple[str, ...]
    switching_score: int = 0
    run: tuple[tuple[str, bool], ...] = ()
    score_lots: tuple[str, ...] = ()


START = Switching("normal", "start: normal inspection at the start of the series (ISO 2859-1 9.2)", ())


def tighter_acceptance(plan: SamplingPlan) -> int | None:
    """The acceptance number of the same sample one AQL step tighter (Table 2-A, the cell to the left).

    None where that cell is an arrow (only for plans that accept 0 or 1, which 9.3.3.2 scores
    without it).
    """
    column = AQLS.index(plan.aql)
    if column == 0:
        return None
    cell = NORMAL[plan.plan_letter].split(" | ")[column - 1]
    return None if cell in ("v", "^") else int(cell.split()[0])


def _normal_after(state: Switching, o: LotOutcome, allow_reduced: bool) -> Switching:
    run = (*state.run, (o.lot, o.accepted))
    if not o.accepted:
        window = run[-WINDOW:]
        rejected = [k for k, (_, ok) in enumerate(window) if not ok]
        if len(rejected) >= 2:
            lots = tuple(name for name, _ in window[rejected[-2] :])
            return Switching(
                "tightened",
                "normal to tightened: 2 lots not accepted out of 5 or fewer consecutive lots (ISO 2859-1 9.3.1)",
                lots,
            )
        return replace(state, run=run, switching_score=0, score_lots=())
    if o.plan.accept >= 2:
        tighter = tighter_acceptance(o.plan)
        scores = tighter is not None and o.nonconforming <= tighter
        score, score_lots = (state.switching_score + 3, (*state.score_lots, o.lot)) if scores else (0, ())
    else:
        score, score_lots = state.switching_score + 2, (*state.score_lots, o.lot)
    if score >= SCORE_FOR_REDUCED and allow_reduced:
        return Switching(
            "reduced",
            f"normal to reduced: switching score {score} (30 or more, ISO 2859-1 9.3.3), production steady and "
            "reduced inspection approved (--allow-reduced)",
            score_lots,
        )
    return replace(state, run=run, switching_score=score, score_lots=score_lots)


def _tightened_after(state: Switching, o: LotOutcome) -> Switching:
    run = (*state.run, (o.lot, o.accepted))
    not_accepted = tuple(name for name, ok in run if not ok)
    if len(not_accepted) >= NOT_ACCEPTED_TO_DISCONTINUE:
        return Switching(
            "discontinued",
            "discontinued: 5 lots not accepted on tightened inspection (ISO 2859-1 9.4); the acceptance procedure "
            "stops until the supplier's quality is improved",
            not_accepted,
        )
    last = run[-ACCEPTED_TO_NORMAL:]
    if len(last) == ACCEPTED_TO_NORMAL and all(ok for _, ok in last):
        return Switching(
            "normal",
            "tightened to normal: 5 consecutive lots accepted on tightened inspection (ISO 2859-1 9.3.2)",
            tuple(name for name, _ in last),
        )
    return replace(state, run=run)


def after(state: Switching, outcome: LotOutcome, allow_reduced: bool = False) -> Switching:
    """The inspection for the lot after ``outcome``'s (decided under ``state.inspection``).

    Parameters
    ----------
    state : Switching
        The inspection the lot was inspected under, and the rules' memory.
    outcome : LotOutcome
        The lot's plan, nonconforming items and whether it was accepted.
    allow_reduced : bool
        Production is steady and the responsible authority approves reduced inspection: without
        it a switching score of 30 keeps normal inspection.
    """
    if state.inspection == "normal":
        return _normal_after(state, outcome, allow_reduced)
    if state.inspection == "tightened":
        return _tightened_after(state, outcome)
    if state.inspection == "reduced" and not outcome.accepted:
        return Switching(
            "normal", "reduced to normal: a lot not accepted on reduced inspection (ISO 2859-1 9.3.4)", (outcome.lot,)
        )
    return state  # reduced and accepted; discontinued stays so


def switching_dict(state: Switching) -> dict:
    """What ``workbench lot --json`` says of the switching: the rule, its lots and the switching score."""
    return {"rule": state.rule, "lots": list(state.lots), "switching_score": state.switching_score}


def series_inspection(earlier: list[tuple[str, list]], plan_for, allow_reduced: bool = False) -> Switching:
    """The inspection for the next lot of a series, from the earlier lots' parts, in their order.

    Parameters
    ----------
    earlier : list of (str, list of LotPart)
        The earlier lots of the series (the same design), each with its parts (:func:`lot_parts`).
    plan_for : callable
        ``plan_for(parts, inspection)``: the lot's :class:`SamplingPlan` under that inspection.
    allow_reduced : bool
        See :func:`after`.

    Each lot is decided under the inspection the lots before it set; a lot not decided yet (its
    sample incomplete) is not in the series: no rule counts it, accepted or not.
    """
    from workbench.lots.decision import lot_decision

    state = START
    for lot, parts in earlier:
        if state.inspection == "discontinued":
            break
        d = lot_decision(plan_for(parts, state.inspection), parts)
        if d.decision in ("accept", "reject"):
            state = after(state, LotOutcome(lot, d.plan, d.nonconforming, d.decision == "accept"), allow_reduced)
    return state
