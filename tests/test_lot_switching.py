"""ISO 2859-1's tightened and reduced inspection: Tables 2-B and 2-C, and the switching rules between them."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from workbench.cli import main
from workbench.lots.plan import sampling_plan
from workbench.lots.switching import START, LotOutcome, after, tighter_acceptance
from workbench.lots.tables import AQLS, CODE_LETTERS, LEVELS, NORMAL, REDUCED, TIGHTENED
from workbench.store.database import store_url
from workbench.store.record import Recorder, record_validation, validation_rows


@pytest.mark.parametrize(
    ("lot_size", "aql", "inspection", "letter", "n", "ac", "re"),
    [
        # the lot: 1,200 parts, level II, AQL 1.0
        (1200, "1.0", "normal", "J", 80, 2, 3),
        (1200, "1.0", "tightened", "J", 80, 1, 2),
        (1200, "1.0", "reduced", "J", 32, 1, 2),  # the 1999 edition's Re = Ac + 1
        (2000, "0.65", "normal", "K", 125, 2, 3),
        (2000, "0.65", "tightened", "K", 125, 1, 2),
        (2000, "0.65", "reduced", "K", 50, 1, 2),
        (1200, "0.65", "tightened", "J", 125, 1, 2),  # J 0.65 tightened: a down arrow to K
        (1200, "0.25", "tightened", "J", 80, 0, 1),
        (1200, "0.40", "reduced", "J", 32, 0, 1),
        (1200, "0.10", "reduced", "J", 125, 0, 1),  # down arrows to M (125 under reduced)
        (20, "6.5", "tightened", "C", 13, 1, 2),  # C and D tightened at 6.5: down arrows to E
        (20, "6.5", "reduced", "C", 2, 0, 1),
        (10, "1000", "tightened", "B", 3, 41, 42),
        (600000, "0.015", "tightened", "R", 1250, 0, 1),  # R 0.015 tightened: up to Q's 0/1
        (600000, "0.025", "tightened", "R", 3150, 1, 2),  # R 0.025 tightened: down to S's 1/2
    ],
)
def test_tightened_and_reduced_plans(lot_size, aql, inspection, letter, n, ac, re):
    level = "III" if lot_size == 600000 else "II"
    p = sampling_plan(lot_size, level, aql, inspection)
    assert (p.code_letter, p.sample_size, p.accept, p.reject, p.inspection) == (letter, n, ac, re, inspection)


def test_p_at_0015_tightened_is_qs_0_1():
    p = sampling_plan(200000, "II", "0.015", "tightened")
    assert (p.code_letter, p.sample_size, p.accept, p.reject) == ("P", 1250, 0, 1)


# MIL-STD-105E's Table II-B at level II, AQL 0.65 to 15, as the rejection numbers of
# www.nibs.org/FMOC/DPW_AC/AC-TABLE.ASC (its Table 1-B), rows B to L (its row A is garbled there)
TIGHTENED_LEVEL_II_REJECT = {
    "B": "v v v v v 1 v v",
    "C": "v v v v 1 v v 2",
    "D": "v v v 1 v v 2 3",
    "E": "v v 1 v v 2 3 4",
    "F": "v 1 v v 2 3 4 6",
    "G": "1 v v 2 3 4 6 9",
    "H": "v v 2 3 4 6 9 13",
    "J": "v 2 3 4 6 9 13 19",
    "K": "2 3 4 6 9 13 19 ^",
    "L": "3 4 6 9 13 19 ^ ^",
}


def test_table_2b_agrees_with_a_second_source():
    first = AQLS.index("0.65")
    for letter, row in TIGHTENED_LEVEL_II_REJECT.items():
        cells = TIGHTENED[letter].split(" | ")[first : first + 8]
        ours = [c if c in "v^" else c.split()[1] for c in cells]
        assert ours == row.split(), letter


@pytest.mark.parametrize("table", ["normal", "tightened", "reduced"])
def test_master_tables_have_the_standards_diagonals(table):
    rows = {"normal": NORMAL, "tightened": TIGHTENED, "reduced": REDUCED}[table]
    # the largest acceptance number of a sample of 20 or more (the five smallest samples go on)
    cap = 18 if table == "tightened" else 21

    def capped(letter):
        return [c if c in "v^" or int(c.split()[0]) <= cap else "^" for c in rows[letter].split(" | ")]

    letters = [x for x in rows if x != "S"]
    # one row down is one AQL column to the left, wherever both rows have their own sample
    # (reduced: from D, whose samples all differ; up to Q: R's arrows at the smallest AQLs, with no
    # plan below them, point back to Q in Tables 2-A and 2-B, and R's 0.010 is a plan in 2-C)
    pairs = {"normal": letters[:-1], "tightened": letters[:-1], "reduced": letters[3:-1]}[table]
    for a, b in zip(pairs[:-1], pairs[1:], strict=True):
        assert capped(b)[:-1] == capped(a)[1:], (table, a, b)
    # and each row's plans are the table's sequence, without a gap
    sequence = {
        "normal": ["0 1", "1 2", "2 3", "3 4", "5 6", "7 8", "10 11", "14 15", "21 22", "30 31", "44 45"],
        "tightened": ["0 1", "1 2", "2 3", "3 4", "5 6", "8 9", "12 13", "18 19", "27 28", "41 42"],
        "reduced": ["0 1", "0 1", "1 2", "1 2", "2 3", "3 4", "5 6", "7 8", "10 11", "14 15", "21 22", "30 31"]
        + ["44 45"],
    }[table]
    for letter in letters:
        plans = [c for c in rows[letter].split(" | ") if c not in "v^"]
        assert plans == sequence[: len(plans)] or letter == "R", (table, letter)


def acceptance(plan, p):
    """The plan's probability of accepting a lot of fraction nonconforming ``p`` (Poisson)."""
    from scipy.stats import poisson

    return poisson.cdf(plan.accept, plan.sample_size * p)


def test_every_plan_is_reached_and_tightened_is_stricter():
    """Every lot size, level, AQL and inspection ends on a plan; at the AQL, tightened accepts less often."""
    for largest, _ in CODE_LETTERS:
        for level in LEVELS:
            for aql in AQLS:
                normal = sampling_plan(largest or 10**7, level, aql)
                tightened = sampling_plan(largest or 10**7, level, aql, "tightened")
                sampling_plan(largest or 10**7, level, aql, "reduced")
                if float(aql) <= 10:  # (percent nonconforming: a probability)
                    p = float(aql) / 100
                    assert acceptance(tightened, p) <= acceptance(normal, p) + 1e-9, (largest, level, aql)


def outcome(lot, accepted, nonconforming=0, plan=None):
    plan = plan or sampling_plan(1200, "II", "1.0")  # J: n 80, Ac 2, Re 3
    return LotOutcome(lot, plan, nonconforming if accepted else max(nonconforming, plan.reject), accepted)


def run(outcomes, allow_reduced=False, state=START):
    states = [state]
    for o in outcomes:
        states.append(after(states[-1], o, allow_reduced))
    return states


def test_two_rejected_of_five_consecutive_lots_switch_to_tightened():
    states = run([outcome("L1", True), outcome("L2", False), outcome("L3", True), outcome("L4", True)])
    assert [s.inspection for s in states] == ["normal"] * 5
    s = after(states[-1], outcome("L5", False))  # L2 and L5: 2 of the 4 consecutive lots L2..L5
    assert s.inspection == "tightened" and s.lots == ("L2", "L3", "L4", "L5") and "9.3.1" in s.rule
    # 2 rejected 5 lots apart (6 lots from first to second): normal stays
    names = [f"M{k}" for k in range(7)]
    states = run([outcome(m, ok) for m, ok in zip(names, [False, True, True, True, True, False, True], strict=True)])
    assert [s.inspection for s in states][-1] == "normal"


def test_tightened_returns_to_normal_after_five_accepted():
    tightened = run([outcome("a", False), outcome("b", False)])[-1]
    assert tightened.inspection == "tightened"
    states = run([outcome(f"t{k}", k != 1) for k in range(6)], state=tightened)
    # t1 not accepted: the five after it (t2..t6) are needed; after t5 four only
    assert [s.inspection for s in states] == ["tightened"] * 7
    s = after(states[-1], outcome("t6", True))
    assert s.inspection == "normal" and s.lots == ("t2", "t3", "t4", "t5", "t6") and "9.3.2" in s.rule


def test_five_lots_not_accepted_on_tightened_discontinue():
    tightened = run([outcome("a", False), outcome("b", False)])[-1]
    oks = [False, True, False, False, True, False, False]  # the 5th lot not accepted: t6
    states = run([outcome(f"t{k}", ok) for k, ok in enumerate(oks)], state=tightened)
    assert [s.inspection for s in states] == ["tightened"] * 7 + ["discontinued"]
    assert states[-1].lots == ("t0", "t2", "t3", "t5", "t6") and "9.4" in states[-1].rule
    assert after(states[-1], outcome("x", True)).inspection == "discontinued"


def test_the_switching_score_leads_to_reduced_with_approval():
    # J, AQL 1.0: Ac 2; one step tighter (0.65, the same sample of 80) accepts 1
    assert tighter_acceptance(sampling_plan(1200, "II", "1.0")) == 1
    good = [outcome(f"g{k}", True, nonconforming=1) for k in range(10)]  # accepted at 0.65 too: +3 each
    states = run(good)
    assert [s.switching_score for s in states] == list(range(0, 31, 3)) and states[-1].inspection == "normal"
    approved = run(good, allow_reduced=True)
    assert approved[-1].inspection == "reduced" and approved[-2].inspection == "normal"
    assert approved[-1].lots == tuple(f"g{k}" for k in range(10)) and "9.3.3" in approved[-1].rule
    # 2 nonconforming: accepted at 1.0, not at 0.65: the score resets
    s = run([*good[:9], outcome("h", True, nonconforming=2)], allow_reduced=True)[-1]
    assert (s.inspection, s.switching_score) == ("normal", 0)
    # a plan accepting 0 or 1 adds 2 per accepted lot: 15 lots
    small = sampling_plan(1200, "II", "0.65")  # J 0.65: n 80, Ac 1
    states = run([outcome(f"s{k}", True, plan=small) for k in range(15)], allow_reduced=True)
    assert [s.inspection for s in states[-2:]] == ["normal", "reduced"] and states[-2].switching_score == 28
    # reduced to normal at the first lot not accepted
    s = after(states[-1], outcome("bad", False, plan=small))
    assert (s.inspection, s.lots) == ("normal", ("bad",)) and "9.3.4" in s.rule


def record(url, part_id, lot, verdict, design="d1"):
    report = {"software": {"version": "t"}, "design": {"design_json_sha256": design}, "part": {"verdict": verdict},
              "photos": []}  # fmt: skip
    rec = Recorder(url=url, part_id=part_id, lot=lot, station="s", operator="o")
    rows = validation_rows(json.dumps(report), Path("/parts") / part_id, [], rec, "2023-11-14T22:13:20Z")
    record_validation(rows, url)


def test_lot_switches_to_tightened_from_the_stored_lots(store, tmp_path, capsys):
    """Lots of 20 at AQL 6.5 (normal: n 8, Ac 1, Re 2): L2 and L5 rejected, so L6 is inspected tightened."""
    url = store_url(store.text)
    for lot, fails in (("L1", 0), ("L2", 2), ("L3", 1), ("L4", 0), ("L5", 2)):
        for k in range(8 - fails if fails < 2 else 6):
            record(url, f"{lot}-{k}", lot, "PASS")
        for k in range(fails):
            record(url, f"{lot}-f{k}", lot, "FAIL")
    record(url, "X-1", "X", "FAIL", design="other")  # another design's lot: not in the series
    record(url, "X-2", "X", "FAIL", design="other")
    record(url, "L6-0", "L6", "PASS")
    args = ["lot", "L6", "--aql", "6.5", "--lot-size", "20", "--store", store.text, "--json"]
    assert main(args) == 0
    d = json.loads(capsys.readouterr().out)
    assert d["inspection"] == "tightened" and d["switching"]["lots"] == ["L2", "L3", "L4", "L5"]
    assert (d["code_letter"], d["sample_size"], d["accept"], d["reject"]) == ("C", 13, 1, 2)
    assert d["decision"] == "incomplete (12 more parts to inspect)"
    # the lots before it were inspected normally
    assert main(["lot", "L5", "--aql", "6.5", "--lot-size", "20", "--store", store.text, "--json"]) == 0
    d = json.loads(capsys.readouterr().out)
    assert (d["inspection"], d["sample_size"], d["decision"]) == ("normal", 8, "reject")
    assert main(["lot", "X", "--aql", "6.5", "--lot-size", "20", "--store", store.text]) == 0
    assert "reject: normal inspection (start" in capsys.readouterr().out
