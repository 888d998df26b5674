"""The results store: workbench validate --store records a validation, whole or not at all; export."""

from __future__ import annotations

import csv
import hashlib
import io
import json
import subprocess
import sys

import pytest
from conftest import ROOT
from sqlalchemy import create_engine, func, select, text

from workbench.cli import main
from workbench.store.database import store_url
from workbench.store.record import Recorder, record_validation, validation_rows
from workbench.store.schema import LATEST, files, validations


@pytest.fixture(scope="module")
def part(tmp_path_factory):
    """A design and one small rendered photo of it, with the photo's exact camera profile."""
    d = tmp_path_factory.mktemp("store")
    assert main(["design", str(ROOT / "fixtures" / "default" / "job.toml"), "--out", str(d / "design"), "-q"]) == 0
    photo = d / "small.jpg"
    render = ["render", str(d / "design"), "--orbit=10,55,330", "--size", "640x480", "-o", str(photo), "-q"]
    assert main([*render, "--realistic"]) == 0
    return d / "design", photo


def validate(part, out, *extra):
    design, photo = part
    return main(["validate", str(design), str(photo), "--camera", str(photo.with_suffix(".json")), "--out", str(out),
                 "-q", "--jobs", "1", *extra])  # fmt: skip


def count(db, table=validations):
    engine = create_engine(f"sqlite:///{db}")
    with engine.connect() as conn:
        n = conn.execute(select(func.count()).select_from(table)).scalar()
    engine.dispose()
    return n


@pytest.fixture(scope="module")
def recorded(part, tmp_path_factory):
    """One real validation recorded through the command line, and a second of the same part in another lot."""
    d = tmp_path_factory.mktemp("recorded")
    mp = pytest.MonkeyPatch()
    mp.setenv("SOURCE_DATE_EPOCH", "1700000000")
    try:
        store = ["--store", str(d / "results.db"), "--station", "bench-1", "--operator", "ana"]
        assert validate(part, d / "out", *store, "--part-id", "P-001", "--lot", "L-7") == 0
        # the environment variable, a URL, and the host and login names by default
        mp.setenv("WORKBENCH_STORE", f"sqlite:///{d / 'results.db'}")
        assert validate(part, d / "out2", "--part-id", "P-002") == 0
    finally:
        mp.undo()
    return d


def test_a_validation_is_recorded_with_its_figures_and_files(recorded):
    db = recorded / "results.db"
    engine = create_engine(f"sqlite:///{db}")
    with engine.connect() as conn:
        rows = [dict(r._mapping) for r in conn.execute(select(validations).order_by(validations.c.id))]
        written = [dict(r._mapping) for r in conn.execute(select(files).where(files.c.validation_id == rows[0]["id"]))]
        version = conn.execute(text("select max(version) from schema_version")).scalar()
    engine.dispose()
    assert version == LATEST and len(rows) == 2
    v = rows[0]
    report_text = (recorded / "out" / "validation.json").read_text()
    report = json.loads(report_text)
    assert (v["part_id"], v["lot"], v["station"], v["operator"]) == ("P-001", "L-7", "bench-1", "ana")
    assert v["recorded_at"] == "2023-11-14T22:13:20Z"  # SOURCE_DATE_EPOCH
    assert v["validation_json"] == report_text  # as written
    assert v["verdict"] == report["part"]["verdict"] and v["photos"] == 1
    assert v["photos_pass"] == (report["photos"][0]["verdict"] == "PASS")
    assert v["worst_p95_mm"] == report["photos"][0]["misregistration_mm"]["p95"]
    assert v["design_json_sha256"] == report["design"]["design_json_sha256"] and v["job"] == "default"
    on_disk = sorted(p for p in (recorded / "out").iterdir() if not p.name.startswith("."))
    assert [w["path"] for w in written] == [str(p) for p in on_disk]
    for w, p in zip(written, on_disk, strict=True):
        assert w["sha256"] == hashlib.sha256(p.read_bytes()).hexdigest() and w["bytes"] == p.stat().st_size
    second = rows[1]
    assert second["part_id"] == "P-002" and second["lot"] is None and second["station"] and second["operator"]


def test_export_round_trips(recorded, capsys):
    db = str(recorded / "results.db")
    assert main(["store", "export", db, "--format", "json"]) == 0
    records = json.loads(capsys.readouterr().out)
    assert [r["part_id"] for r in records] == ["P-001", "P-002"]
    assert records[0]["validation"] == json.loads((recorded / "out" / "validation.json").read_text())
    assert records[0]["photos"][0]["verdict"] == records[0]["validation"]["photos"][0]["verdict"]
    assert main(["store", "export", db, "--format", "csv", "--lot", "L-7"]) == 0
    rows = list(csv.DictReader(io.StringIO(capsys.readouterr().out)))
    assert len(rows) == 1 and rows[0]["part_id"] == "P-001" and rows[0]["verdict"] == records[0]["verdict"]
    assert float(rows[0]["worst_p95_mm"]) == records[0]["worst_p95_mm"]
    out = recorded / "export.json"
    assert main(["store", "export", db, "-o", str(out)]) == 0
    assert json.loads(out.read_text()) == records


def test_a_failed_validation_records_nothing(part, recorded, tmp_path, capsys):
    db = recorded / "results.db"
    before = count(db)
    # a camera profile that does not exist: the validation fails before any work, nothing written
    design, photo = part
    status = main(["validate", str(design), str(photo), "--camera", str(tmp_path / "none.json"),
                   "--out", str(tmp_path / "out"), "-q", "--store", str(db), "--part-id", "P-003"])  # fmt: skip
    assert status == 1 and "none.json" in capsys.readouterr().err
    assert count(db) == before and not (tmp_path / "out").exists()
    # a new store is not even created
    new = ["--store", str(tmp_path / "new.db"), "--part-id", "P"]
    status = main(["validate", str(design), str(photo), "--camera", str(tmp_path / "none.json"),
                   "--out", str(tmp_path / "out"), "-q", *new])  # fmt: skip
    assert status == 1 and not (tmp_path / "new.db").exists()


@pytest.mark.parametrize(
    ("extra", "says"),
    [
        (["--part-id", "P"], "--part-id: records in a store; give --store URL"),
        (["--store", "{tmp}/s.db"], "--part-id: required to record in a store"),
        (["--store", "nosuch://x", "--part-id", "P"], "--store nosuch://x: no database driver"),
        (["--store", "{tmp}/no/folder/s.db", "--part-id", "P"], "no folder"),
        (["--store", "sqlite://", "--part-id", "P"], "an in-memory SQLite store keeps nothing"),
    ],
)
def test_bad_store_options_are_one_line_and_write_nothing(part, tmp_path, capsys, extra, says):
    extra = [e.replace("{tmp}", str(tmp_path)) for e in extra]
    assert validate(part, tmp_path / "out", *extra) != 0
    err = capsys.readouterr().err
    assert says in err and len(err.strip().splitlines()) == 1, err
    assert list(tmp_path.iterdir()) == []


def fake_rows(url, part_id, folder):
    report = {"software": {"version": "t"}, "design": {"job": None}, "part": {"verdict": "PASS"}, "photos": []}
    rec = Recorder(url=url, part_id=part_id, lot="C", station="s", operator="o")
    return validation_rows(json.dumps(report), folder, [], rec, "2023-11-14T22:13:20Z")


def test_a_record_is_whole_or_nothing(tmp_path):
    url = store_url(str(tmp_path / "s.db"))
    record_validation(fake_rows(url, "ok", tmp_path), url)
    broken = fake_rows(url, "broken", tmp_path)
    broken["files"] = [{"path": None, "sha256": "x", "bytes": 1}]  # NOT NULL: fails after the validation's row
    with pytest.raises(Exception, match="NOT NULL"):
        record_validation(broken, url)
    assert count(tmp_path / "s.db") == 1


RECORDER = """
import json, sys
from pathlib import Path
sys.path.insert(0, {root!r})
from workbench.store.database import store_url
from workbench.store.record import Recorder, record_validation, validation_rows
url = store_url(sys.argv[1])
report = json.dumps({{"software": {{"version": "t"}}, "design": {{}}, "part": {{"verdict": "PASS"}}, "photos": []}})
for k in range(int(sys.argv[3])):
    rec = Recorder(url=url, part_id=f"{{sys.argv[2]}}-{{k}}", lot="C", station="s", operator="o")
    record_validation(validation_rows(report, Path(sys.argv[1]).parent, [], rec, "2023-11-14T22:13:20Z"), url)
"""


def test_two_processes_recording_at_once_lose_nothing(tmp_path):
    db = tmp_path / "s.db"  # a new store: both also race to create its schema
    script = RECORDER.format(root=str(ROOT))
    n = 200
    procs = [
        subprocess.Popen([sys.executable, "-c", script, str(db), name, str(n)], stderr=subprocess.PIPE)
        for name in ("a", "b")
    ]
    for p in procs:
        _, err = p.communicate(timeout=300)
        assert p.returncode == 0, err.decode()
    engine = create_engine(f"sqlite:///{db}")
    with engine.connect() as conn:
        ids = sorted(r[0] for r in conn.execute(select(validations.c.part_id)))
        versions = conn.execute(text("select count(*) from schema_version")).scalar()
    engine.dispose()
    assert ids == sorted(f"{w}-{k}" for w in "ab" for k in range(n)) and versions == LATEST


def test_a_store_of_a_newer_schema_is_refused(tmp_path, capsys):
    url = store_url(str(tmp_path / "s.db"))
    record_validation(fake_rows(url, "p", tmp_path), url)
    engine = create_engine(f"sqlite:///{tmp_path / 's.db'}")
    with engine.begin() as conn:
        conn.execute(text("insert into schema_version (version, description) values (99, 'future')"))
    engine.dispose()
    assert main(["store", "export", str(tmp_path / "s.db")]) == 1
    err = capsys.readouterr().err
    assert "a store of schema version 99, newer than this workbench's" in err and len(err.strip().splitlines()) == 1
    assert main(["store", "export", str(tmp_path / "none.db")]) == 1
    assert "no store at" in capsys.readouterr().err and not (tmp_path / "none.db").exists()
