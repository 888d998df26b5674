"""The results store: workbench validate --store records a validation, whole or not at all; export."""

from __future__ import annotations

import csv
import hashlib
import io
import json
import signal
import socket
import subprocess
import sys
import time

import pytest
from conftest import ROOT
from sqlalchemy import select, text

from workbench.cli import main
from workbench.errors import WorkbenchError
from workbench.store.database import store_url
from workbench.store.record import Recorder, record_validation, validation_rows
from workbench.store.schema import LATEST, files, photos, schema_version, validations


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


@pytest.fixture(scope="module")
def recorded(part, module_store, tmp_path_factory):
    """One real validation recorded through the command line, and a second of the same part in another lot.

    On both backends: a SQLite file, and a database of a real PostgreSQL server.
    """
    d = tmp_path_factory.mktemp("recorded")
    mp = pytest.MonkeyPatch()
    mp.setenv("SOURCE_DATE_EPOCH", "1700000000")
    try:
        store = ["--store", module_store.text, "--station", "bench-1", "--operator", "ana"]
        assert validate(part, d / "out", *store, "--part-id", "P-001", "--lot", "L-7") == 0
        # the environment variable, a URL, and the host and login names by default
        mp.setenv("WORKBENCH_STORE", str(module_store.url.render_as_string(hide_password=False)))
        assert validate(part, d / "out2", "--part-id", "P-002") == 0
    finally:
        mp.undo()
    return d, module_store


def test_a_validation_is_recorded_with_its_figures_and_files(recorded):
    recorded, store = recorded
    engine = store.engine()
    with engine.connect() as conn:
        rows = [dict(r._mapping) for r in conn.execute(select(validations).order_by(validations.c.id))]
        query = select(files).where(files.c.validation_id == rows[0]["id"]).order_by(files.c.id)
        written = [dict(r._mapping) for r in conn.execute(query)]
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
    recorded, store = recorded
    db = store.text
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
    _, store = recorded
    db = store.text
    before = store.count(validations)
    # a camera profile that does not exist: the validation fails before any work, nothing written
    design, photo = part
    status = main(["validate", str(design), str(photo), "--camera", str(tmp_path / "none.json"),
                   "--out", str(tmp_path / "out"), "-q", "--store", str(db), "--part-id", "P-003"])  # fmt: skip
    assert status == 1 and "none.json" in capsys.readouterr().err
    assert store.count(validations) == before and not (tmp_path / "out").exists()
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


def test_a_record_is_whole_or_nothing(store, tmp_path):
    url = store_url(store.text)
    record_validation(fake_rows(url, "ok", tmp_path), url)
    broken = fake_rows(url, "broken", tmp_path)
    broken["files"] = [{"path": None, "sha256": "x", "bytes": 1}]  # NOT NULL: fails after the validation's row
    with pytest.raises(WorkbenchError, match="(?i)not.null"):
        record_validation(broken, url)
    assert store.column(validations.c.part_id) == ["ok"]


# one recording station: waits for the go (a file), then records its parts one by one, each with a
# photo and a file, each in its own transaction
RECORDER = """
import json, sys, time
from pathlib import Path
sys.path.insert(0, {root!r})
from workbench.store.database import store_url
from workbench.store.record import Recorder, record_validation, validation_rows
url, name, n, go = store_url(sys.argv[1]), sys.argv[2], int(sys.argv[3]), Path(sys.argv[4])
photo = {{"photo": "p.jpg", "verdict": "PASS", "misregistration_mm": {{"p95": 0.1}}}}
part = {{"verdict": "PASS"}}
report = json.dumps({{"software": {{"version": "t"}}, "design": {{}}, "part": part, "photos": [photo]}})
while not go.exists():
    time.sleep(0.01)
for k in range(n):
    rec = Recorder(url=url, part_id=f"{{name}}-{{k}}", lot="C", station=name, operator="o")
    record_validation(validation_rows(report, go.parent, [go], rec, "2023-11-14T22:13:20Z"), url)
"""


def test_ten_processes_recording_at_once_lose_nothing(store, tmp_path):
    """Ten stations start together on a new store (so they also race to create its schema)."""
    go = tmp_path / "go"
    script = RECORDER.format(root=str(ROOT))
    n = 20
    names = [f"s{k}" for k in range(10)]
    procs = [
        subprocess.Popen([sys.executable, "-c", script, store.text, name, str(n), str(go)], stderr=subprocess.PIPE)
        for name in names
    ]
    go.write_text("go")
    for p in procs:
        _, err = p.communicate(timeout=300)
        assert p.returncode == 0, err.decode()
    expected = sorted(f"{w}-{k}" for w in names for k in range(n))
    assert sorted(store.column(validations.c.part_id)) == expected  # every record, none twice
    assert store.count(photos) == store.count(files) == len(expected)
    # each record's children point at it
    assert sorted(store.column(photos.c.validation_id)) == sorted(store.column(validations.c.id))
    assert store.column(schema_version.c.version) == list(range(1, LATEST + 1))  # the schema made once


def test_a_validation_killed_mid_run_records_nothing(part, store, tmp_path):
    """A real ``validate --store`` killed (SIGKILL, then SIGTERM) while it works: the store keeps what it had."""
    url = store_url(store.text)
    record_validation(fake_rows(url, "before", tmp_path), url)
    design, photo = part
    photos_given = [str(photo)] * 6  # (six photos: a run that lasts beyond the kill on any machine)
    for signum in (signal.SIGKILL, signal.SIGTERM):
        out = tmp_path / f"out-{signum}"
        args = ["validate", str(design), *photos_given, "--camera", str(photo.with_suffix(".json")),
                "--out", str(out), "-q", "--jobs", "1", "--store", store.text, "--part-id", "killed"]  # fmt: skip
        p = subprocess.Popen([sys.executable, "-m", "workbench", *args], cwd=ROOT, stderr=subprocess.PIPE)
        time.sleep(4.0)
        assert p.poll() is None, "the validation ended before it could be killed"
        p.send_signal(signum)
        p.communicate(timeout=120)
        assert p.returncode != 0
        assert store.column(validations.c.part_id) == ["before"] and store.count(photos) == 0, signum
        assert not out.exists()


def test_a_store_of_a_newer_schema_is_refused(store, part, tmp_path, capsys):
    url = store_url(store.text)
    record_validation(fake_rows(url, "p", tmp_path), url)
    store.execute("insert into schema_version (version, description) values (99, 'future')")
    says = "a store of schema version 99, newer than this workbench's"
    assert main(["store", "export", store.text]) == 1
    err = capsys.readouterr().err
    assert says in err and len(err.strip().splitlines()) == 1
    assert main(["lot", "C", "--aql", "1.0", "--store", store.text]) == 1
    err = capsys.readouterr().err
    assert says in err and len(err.strip().splitlines()) == 1
    # validate refuses before its work: no output folder, no record
    assert validate(part, tmp_path / "out", "--store", store.text, "--part-id", "q") == 1
    err = capsys.readouterr().err
    assert says in err and len(err.strip().splitlines()) == 1
    assert not (tmp_path / "out").exists() and store.column(validations.c.part_id) == ["p"]


def test_a_store_that_does_not_exist_is_not_made(tmp_path, capsys):
    assert main(["store", "export", str(tmp_path / "none.db")]) == 1
    assert "no store at" in capsys.readouterr().err and not (tmp_path / "none.db").exists()


def refused_port() -> int:
    """A port of 127.0.0.1 nothing listens on (bound, then closed: a connection to it is refused)."""
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


@pytest.mark.parametrize("command", ["validate", "lot", "export"])
def test_an_unreachable_store_is_one_line_and_writes_nothing(part, tmp_path, capsys, command):
    given = f"postgresql://workbench@127.0.0.1:{refused_port()}/store"
    if command == "validate":
        status = validate(part, tmp_path / "out", "--store", given, "--part-id", "p")
    elif command == "lot":
        status = main(["lot", "L", "--aql", "1.0", "--store", given, "--report", str(tmp_path / "r.html")])
    else:
        status = main(["store", "export", given, "-o", str(tmp_path / "e.json")])
    err = capsys.readouterr().err
    assert status == 1 and len(err.strip().splitlines()) == 1, err
    assert "Connection refused" in err and "postgresql+psycopg://workbench@127.0.0.1" in err, err
    assert list(tmp_path.iterdir()) == []


def test_postgresql_urls_take_psycopg():
    assert store_url("postgresql://u@h/db").drivername == "postgresql+psycopg"
    assert store_url("postgres://u:secret@h:5433/db").render_as_string(hide_password=False) == (
        "postgresql+psycopg://u:secret@h:5433/db"
    )
    assert store_url("postgresql+psycopg://u@h/db").drivername == "postgresql+psycopg"


def test_a_postgresql_database_that_does_not_exist_is_one_line(tmp_path, capsys):
    from postgres import server_url

    given = server_url().set(database="no_such_store").render_as_string(hide_password=False)
    assert main(["lot", "L", "--aql", "1.0", "--store", given, "--report", str(tmp_path / "r.pdf")]) == 1
    err = capsys.readouterr().err
    assert 'database "no_such_store" does not exist' in err and len(err.strip().splitlines()) == 1, err
    assert list(tmp_path.iterdir()) == []
