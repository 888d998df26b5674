"""workbench lot: ISO 2859-1 plans, and the decision on a lot from the parts the store has."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from workbench.cli import main
from workbench.lots.decision import LotPart, lot_decision, lot_parts
from workbench.lots.plan import code_letter, sampling_plan
from workbench.lots.tables import AQLS, NORMAL
from workbench.store.database import store_url
from workbench.store.record import Recorder, record_validation, validation_rows


@pytest.mark.parametrize(
    ("lot_size", "level", "aql", "letter", "n", "ac", "re"),
    [
        (1000, "II", "1.0", "J", 80, 2, 3),  # the example
        (1200, "II", "1.0", "J", 80, 2, 3),
        (1201, "II", "1.0", "K", 125, 3, 4),
        (8, "II", "6.5", "A", 2, 0, 1),
        (8, "II", "10", "A", 2, 0, 1),  # A's up arrow has no plan above: A's 0/1
        (8, "II", "15", "A", 3, 1, 2),  # down arrow: B
        (12, "II", "10", "B", 5, 1, 2),  # down arrow: C
        (50, "II", "2.5", "D", 5, 0, 1),  # up arrow: C
        (50, "II", "4.0", "D", 13, 1, 2),  # down arrow: E
        (90, "II", "0.010", "E", 90, 0, 1),  # the long down arrow: Q, n 1250 > the lot: 100 %
        (150001, "II", "0.010", "P", 1250, 0, 1),  # P 0.010 down: Q
        # ISO 2859-1:1999's plans for lots of 35,001 to 500,000 (figshare 22583454)
        (100000, "S-4", "0.65", "J", 80, 1, 2),
        (100000, "S-3", "0.65", "G", 20, 0, 1),  # G 0.65 is an up arrow: F
        (100000, "S-4", "0.40", "J", 125, 1, 2),  # J 0.40 is a down arrow: K
        (100000, "S-3", "0.40", "G", 32, 0, 1),
        (100000, "S-4", "0.25", "J", 50, 0, 1),  # J 0.25 up: H
        (100000, "S-4", "0.15", "J", 80, 0, 1),
        (3000, "II", "15", "K", 80, 21, 22),  # K 15 up: J
        (600000, "III", "0.010", "R", 1250, 0, 1),  # R 0.010 up: Q
        (600000, "III", "0.025", "R", 2000, 1, 2),
        (10, "II", "1000", "B", 3, 44, 45),
        (30, "II", "1000", "D", 3, 44, 45),  # D and C at 1000 up: B
        (30, "II", "400", "D", 8, 44, 45),
    ],
)
def test_plans_are_the_standards(lot_size, level, aql, letter, n, ac, re):
    p = sampling_plan(lot_size, level, aql)
    assert (p.code_letter, p.sample_size, p.accept, p.reject) == (letter, n, ac, re)


# a second, independent source: MIL-STD-105E's Table II-A at level II, AQL 0.65 to 15, as the
# rejection numbers of www.nibs.org/FMOC/DPW_AC/AC-TABLE.ASC (Table 1-A), row by code letter;
# "v"/"^": the arrows, whose plans are the first below/above
LEVEL_II_REJECT = {
    "A": "v v v v v 1 ^ v",
    "B": "v v v v 1 ^ v 2",
    "C": "v v v 1 ^ v 2 3",
    "D": "v v 1 ^ v 2 3 4",
    "E": "v 1 ^ v 2 3 4 6",
    "F": "1 ^ v 2 3 4 6 8",
    "G": "^ v 2 3 4 6 8 11",
    "H": "v 2 3 4 6 8 11 15",
    "J": "2 3 4 6 8 11 15 22",
    "K": "3 4 6 8 11 15 22 ^",
    "L": "4 6 8 11 15 22 ^ ^",
    "M": "6 8 11 15 22 ^ ^ ^",
    "N": "8 11 15 22 ^ ^ ^ ^",
    "P": "11 15 22 ^ ^ ^ ^ ^",
    "Q": "15 22 ^ ^ ^ ^ ^ ^",
}


def test_table_2a_agrees_with_a_second_source():
    first = AQLS.index("0.65")
    for letter, row in LEVEL_II_REJECT.items():
        cells = NORMAL[letter].split(" | ")[first : first + 8]
        ours = [c if c in "v^" else c.split()[1] for c in cells]
        assert ours == row.split(), letter


def test_table_2a_has_the_standards_shape():
    pairs = ["0 1", "1 2", "2 3", "3 4", "5 6", "7 8", "10 11", "14 15", "21 22", "30 31", "44 45"]
    for letter, row in NORMAL.items():
        cells = row.split(" | ")
        assert len(cells) == len(AQLS)
        plans = [c for c in cells if c not in "v^"]
        assert plans == pairs[pairs.index(plans[0]) : pairs.index(plans[0]) + len(plans)], letter
        assert all(c == "v" for c in cells[: cells.index(plans[0])]) or letter == "R"
    # the diagonal: one row down is one AQL column to the left
    letters = list(NORMAL)
    for a, b in zip(letters[:4], letters[1:5], strict=True):
        assert NORMAL[b].split(" | ")[:-1] == NORMAL[a].split(" | ")[1:]


def test_code_letters():
    assert [code_letter(n, "II") for n in (2, 8, 9, 500, 501, 1200, 1201, 500000, 500001)] == list("AABHJJKPQ")
    assert [code_letter(1000, lv) for lv in ("S-1", "S-2", "S-3", "S-4", "I", "II", "III")] == list("CCEFGJK")
    assert [code_letter(10**7, lv) for lv in ("S-1", "S-2", "S-3", "S-4", "I", "II", "III")] == list("DEHKNQR")


def part(pid, verdict, k):
    return LotPart(pid, verdict, "", "2023-11-14T22:13:20Z", f"/v/{pid}", k)


def test_invalid_and_incomplete_parts_are_not_conforming():
    plan = sampling_plan(1000, "II", "1.0")  # n 80, Ac 2, Re 3
    parts = [part(f"p{k}", "PASS", k) for k in range(78)] + [part("x", "INVALID", 90), part("y", "INCOMPLETE", 91)]
    d = lot_decision(plan, parts)
    assert (d.inspected, d.nonconforming, d.not_inspected) == (78, 0, 2)
    assert d.decision == "incomplete (2 more parts to inspect)"
    d = lot_decision(plan, [*parts, part("z1", "PASS", 92), part("z2", "FAIL", 93)])
    assert (d.inspected, d.nonconforming, d.decision) == (80, 1, "accept")
    fails = [part(f"f{k}", "FAIL", 100 + k) for k in range(3)]
    assert lot_decision(plan, fails).decision == "reject"  # Re reached: no further part can undo it


def test_a_part_counts_once_by_its_first_conclusive_record():
    records = [
        {"id": 1, "part_id": "a", "verdict": "INVALID", "recorded_at": "", "out_dir": "/1"},
        {"id": 2, "part_id": "a", "verdict": "FAIL", "recorded_at": "", "out_dir": "/2"},
        {"id": 3, "part_id": "a", "verdict": "PASS", "recorded_at": "", "out_dir": "/3"},
        {"id": 4, "part_id": "b", "verdict": "PASS", "recorded_at": "", "out_dir": "/4"},
        {"id": 5, "part_id": "b", "verdict": "INVALID", "recorded_at": "", "out_dir": "/5"},
    ]
    parts = lot_parts(records)
    assert [(p.part_id, p.verdict, p.record_id) for p in parts] == [("a", "FAIL", 2), ("b", "PASS", 4)]


def fake_record(url, part_id, lot, verdict, job=None):
    """One part's record: a validation.json reduced to its verdict (and the design's job, if given)."""
    report = {"software": {"version": "t"}, "design": {"job": job}, "part": {"verdict": verdict}, "photos": []}
    rec = Recorder(url=url, part_id=part_id, lot=lot, station="s", operator="o")
    rows = validation_rows(json.dumps(report), Path("/parts") / part_id, [], rec, "2023-11-14T22:13:20Z")
    return record_validation(rows, url)


def test_lot_command(store, tmp_path, capsys):
    url = store_url(store.text)
    for k in range(4):
        fake_record(url, f"p{k}", "L", "PASS")
    fake_record(url, "bad", "L", "FAIL")
    fake_record(url, "dark", "L", "INVALID")
    fake_record(url, "other", "M", "FAIL")
    report = tmp_path / "lot.html"
    args = ["lot", "L", "--aql", "6.5", "--lot-size", "20", "--store", store.text, "--json"]
    assert main([*args, "--report", str(report)]) == 0
    d = json.loads(capsys.readouterr().out)
    # 20 items at level II: C, n 5; C at 6.5 is a down arrow: D, n 8, Ac 1, Re 2
    assert {k: d[k] for k in ("code_letter", "sample_size", "accept", "reject", "inspected", "nonconforming")} == {
        "code_letter": "C",
        "sample_size": 8,
        "accept": 1,
        "reject": 2,
        "inspected": 5,
        "nonconforming": 1,
    }
    assert d["decision"] == "incomplete (3 more parts to inspect)" and d["not_inspected"] == 1
    html = report.read_text()
    assert html.count("<tr class=") == 6 and "INVALID" in html and "other" not in html
    fake_record(url, "bad2", "L", "FAIL")
    assert main(args) == 0
    assert json.loads(capsys.readouterr().out)["decision"] == "reject"


@pytest.mark.parametrize(
    ("extra", "says", "status"),
    [
        (["--aql", "0.5"], "--aql 0.5: not an AQL of ISO 2859-1", 2),
        (["--aql", "1.0", "--lot-size", "1"], "--lot-size", 2),
        (["--aql", "1.0", "--level", "IV"], "--level", 2),
        (["--aql", "1.0", "--store", "nosuch://x"], "--store nosuch://x: no database driver", 2),
        (["--aql", "1.0", "--store", "{tmp}/none.db"], "no store at", 1),
        (["--aql", "1.0", "--store", "{tmp}/s.db", "--lot-size", "2"], "the store has", 1),
    ],
)
def test_bad_input_is_one_line_and_writes_nothing(tmp_path, capsys, extra, says, status):
    url = store_url(str(tmp_path / "s.db"))
    for k in range(3):
        fake_record(url, f"p{k}", "L", "PASS")
    extra = [e.replace("{tmp}", str(tmp_path)) for e in extra]
    before = sorted(tmp_path.iterdir())
    store = [] if "--store" in extra else ["--store", str(tmp_path / "s.db")]
    assert main(["lot", "L", *store, *extra, "--report", str(tmp_path / "r.html")]) == status
    err = capsys.readouterr().err
    assert says in err and len(err.strip().splitlines()) == 1, err
    assert sorted(tmp_path.iterdir()) == before


def test_an_unknown_lot_is_one_line(store, tmp_path, capsys):
    url = store_url(store.text)
    fake_record(url, "p", "L", "PASS")
    report = tmp_path / "r.html"
    assert main(["lot", "NOPE", "--aql", "1.0", "--store", store.text, "--report", str(report)]) == 1
    err = capsys.readouterr().err
    assert "lot NOPE: no part of it is recorded" in err and len(err.strip().splitlines()) == 1
    assert not report.exists()


def test_an_aql_the_standard_does_not_list_is_one_line(store, tmp_path, capsys):
    url = store_url(store.text)
    fake_record(url, "p", "L", "PASS")
    report = tmp_path / "r.html"
    assert main(["lot", "L", "--aql", "0.5", "--store", store.text, "--report", str(report)]) == 2
    err = capsys.readouterr().err
    assert "--aql 0.5: not an AQL of ISO 2859-1" in err and len(err.strip().splitlines()) == 1
    assert not report.exists()


def test_lot_report_pdf_lists_every_part_with_its_evidence(tmp_path, capsys):
    from pypdf import PdfReader

    url = store_url(str(tmp_path / "s.db"))
    ids = [f"part-{k:03d}" for k in range(90)]
    for k, pid in enumerate(ids):
        fake_record(url, pid, "L", "FAIL" if k == 7 else "INVALID" if k == 8 else "PASS")
    args = ["lot", "L", "--aql", "1.0", "--lot-size", "1200", "--store", str(tmp_path / "s.db")]
    reports = ["--report", str(tmp_path / "lot.pdf"), "--report", str(tmp_path / "lot.html")]
    assert main([*args, *reports]) == 0
    first = (tmp_path / "lot.pdf").read_bytes()
    pdf = PdfReader(tmp_path / "lot.pdf")
    assert len(pdf.pages) >= 2  # 90 parts do not fit one A4 page
    text = "\n".join(page.extract_text() for page in pdf.pages)
    assert "Lot L: accept" in text and "normal inspection" in text and "sample size: 80" in text
    cells = text.splitlines()  # (one cell a line, as pypdf reads the table back)
    for k, pid in enumerate(ids):
        at = cells.index(pid)
        verdict = "FAIL" if k == 7 else "INVALID" if k == 8 else "PASS"
        row = [str(k + 1), pid, verdict, "2023-11-14T22:13:20Z", f"/parts/{pid}/validation.json"]
        assert cells[at - 1 : at + 4] == row, cells[at - 1 : at + 4]
    assert (tmp_path / "lot.html").read_text().count("<tr class=") == 90
    # the same records, the same bytes
    assert main([*args, "--report", str(tmp_path / "again.pdf")]) == 0
    assert (tmp_path / "again.pdf").read_bytes() == first
    capsys.readouterr()
    assert main([*args, "--report", str(tmp_path / "lot.txt")]) == 2
    assert "--report" in capsys.readouterr().err and not (tmp_path / "lot.txt").exists()
