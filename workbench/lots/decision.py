"""The decision on a lot: its recorded parts against the sampling plan."""

from __future__ import annotations

from dataclasses import dataclass

from workbench.lots.plan import SamplingPlan

CONCLUSIVE = ("PASS", "FAIL")


@dataclass(frozen=True)
class LotPart:
    """One part of the lot as the store has it: its deciding record (see :func:`lot_parts`)."""

    part_id: str
    verdict: str
    reason: str
    recorded_at: str
    out_dir: str
    record_id: int


@dataclass(frozen=True)
class LotDecision:
    """The plan, the parts counted and the decision (``accept``, ``reject`` or ``incomplete (...)``)."""

    plan: SamplingPlan
    inspected: int
    nonconforming: int
    not_inspected: int
    beyond_sample: int
    decision: str


def lot_parts(records: list[dict]) -> list[LotPart]:
    """Each part once, in recording order, from the lot's records (any order of ``records``).

    A part's first conclusive record (PASS or FAIL) decides it: a sampled item is inspected
    once, and a FAIL validated again into a PASS would hide a nonconformity. A part with no
    conclusive record (only INVALID or INCOMPLETE ones) keeps its latest, and is not inspected.
    The parts are in the order of their deciding records.
    """
    by_part: dict[str, dict] = {}
    for r in sorted(records, key=lambda r: r["id"]):
        seen = by_part.get(r["part_id"])
        if seen is None or (seen["verdict"] not in CONCLUSIVE):
            by_part[r["part_id"]] = r
    chosen = sorted(by_part.values(), key=lambda r: r["id"])
    return [
        LotPart(r["part_id"], r["verdict"], r.get("reason") or "", r["recorded_at"], r["out_dir"], r["id"])
        for r in chosen
    ]


def lot_decision(plan: SamplingPlan, parts: list[LotPart]) -> LotDecision:
    """Accept, reject, or how many more parts to inspect.

    The sample is the first ``plan.sample_size`` parts with a conclusive verdict, in recording
    order (later ones are ``beyond_sample``); INVALID and INCOMPLETE parts are not inspected,
    never conforming. Reject as soon as the nonconforming parts (FAIL) reach the rejection
    number (no further part can undo it); accept once the sample is complete with at most the
    acceptance number; else incomplete.
    """
    conclusive = [p for p in parts if p.verdict in CONCLUSIVE]
    sample = conclusive[: plan.sample_size]
    nonconforming = sum(p.verdict == "FAIL" for p in sample)
    if nonconforming >= plan.reject:
        decision = "reject"
    elif len(sample) >= plan.sample_size:
        decision = "accept"
    else:
        decision = f"incomplete ({plan.sample_size - len(sample)} more parts to inspect)"
    return LotDecision(
        plan=plan,
        inspected=len(sample),
        nonconforming=nonconforming,
        not_inspected=len(parts) - len(conclusive),
        beyond_sample=len(conclusive) - len(sample),
        decision=decision,
    )


def decision_dict(lot: str, d: LotDecision, switching=None) -> dict:
    """What ``workbench lot --json`` prints: the plan and the decision.

    ``switching``: the :class:`~workbench.lots.switching.Switching` the lot was inspected under
    (``inspection`` is its inspection, ``switching`` its rule and lots); None: normal, no series.
    """
    from workbench.lots.switching import START, switching_dict

    p = d.plan
    switching = START if switching is None else switching
    return {
        "lot": lot,
        "lot_size": p.lot_size,
        "level": p.level,
        "aql": p.aql,
        "inspection": switching.inspection,
        "switching": switching_dict(switching),
        "code_letter": p.code_letter,
        "plan_letter": p.plan_letter,
        "sample_size": p.sample_size,
        "hundred_percent": p.hundred_percent,
        "accept": p.accept,
        "reject": p.reject,
        "inspected": d.inspected,
        "nonconforming": d.nonconforming,
        "not_inspected": d.not_inspected,
        "beyond_sample": d.beyond_sample,
        "decision": d.decision,
    }
