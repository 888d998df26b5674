"""workbench trend: control charts of the recorded parts and calibration checks, the Nelson rules, drift."""

from __future__ import annotations

import json

import numpy as np
import pytest
from conftest import ROOT
from scipy.stats import poisson
from sqlalchemy import create_engine, inspect, select, text
from trend_run import DESIGN_SHA, TOLERANCE_MM, part_id, production_run, record_run, report_text

from workbench.cli import main
from workbench.store.database import store_url
from workbench.store.figures import part_figures
from workbench.store.schema import LATEST, MIGRATIONS, calibrations, schema_version, validations
from workbench.trend import nelson
from workbench.trend.charts import D2, D4, Tolerance, imr_limits, parts_to_tolerance, rolling_trend, u_limits

# --- the rules, each on the pattern it names and on the nearest pattern it must not fire on


def fires_at(rule: int, z) -> list[int]:
    return np.flatnonzero(nelson.RULES[rule](np.asarray(z, dtype=float))).tolist()


def test_rule_1_beyond_three_sigma():
    assert fires_at(1, [0, 3.01, -2.99, -3.5, 3.0]) == [1, 3]


def test_rule_2_nine_on_one_side():
    assert fires_at(2, [0.1] * 9) == [8]
    assert fires_at(2, [0.1] * 8 + [-0.1]) == [] and fires_at(2, [-0.2] * 10) == [8, 9]
    assert fires_at(2, [0.1] * 4 + [np.nan] + [0.1] * 4) == []  # a part without the figure breaks the run


def test_rule_3_six_steadily_increasing_or_decreasing():
    assert fires_at(3, [0, 0.1, 0.2, 0.3, 0.4, 0.5]) == [5]
    assert fires_at(3, [0, 0.1, 0.2, 0.2, 0.4, 0.5]) == []  # a tie is no step
    assert fires_at(3, [5, 4, 3, 2, 1, 0, -1]) == [5, 6]


def test_rule_4_fourteen_alternating():
    alternating = [(-1) ** k * 0.5 for k in range(14)]
    assert fires_at(4, alternating) == [13] and fires_at(4, alternating[:13]) == []
    broken = alternating.copy()
    broken[7] = broken[6]  # one step flat
    assert fires_at(4, broken) == []


def test_rule_5_two_of_three_beyond_two_sigma_on_one_side():
    assert fires_at(5, [2.1, 0, 2.1]) == [2] and fires_at(5, [2.1, 0, -2.1]) == []
    assert fires_at(5, [2.1, 0, 0, 2.1]) == []


def test_rule_6_four_of_five_beyond_one_sigma_on_one_side():
    assert fires_at(6, [1.1, 1.1, 0, 1.1, 1.1]) == [4] and fires_at(6, [1.1, 1.1, 0, 1.1, -1.1]) == []


def test_rule_7_fifteen_within_one_sigma():
    assert fires_at(7, [0.5, -0.5] * 7 + [0.9]) == [14] and fires_at(7, [0.5] * 14 + [1.2]) == []


def test_rule_8_eight_beyond_one_sigma_on_both_sides():
    assert fires_at(8, [1.5, -1.5] * 4) == [7]
    assert fires_at(8, [1.5] * 8) == []  # one side only: rule 6's, not a mixture
    assert fires_at(8, [1.5, -1.5, 1.5, 0.5, -1.5, 1.5, -1.5, 1.5]) == []


# --- limits and the drift's projection against analytic values


def test_imr_limits_from_the_baseline():
    lim = imr_limits(np.array([1.0, 2.0, 4.0, 3.0]))
    mr_bar = (1 + 2 + 1) / 3
    assert lim.centre == 2.5 and lim.mr_centre == pytest.approx(mr_bar)
    assert lim.sigma == pytest.approx(mr_bar / 1.128) and D2 == 1.128
    assert lim.ucl == pytest.approx(2.5 + 3 * mr_bar / 1.128) and lim.lcl == pytest.approx(2.5 - 3 * mr_bar / 1.128)
    assert lim.mr_ucl == pytest.approx(3.267 * mr_bar) and D4 == 3.267


def test_u_chart_limit_is_the_poisson_probability_limit():
    counts = np.array([0, 1, 0, 0, 1, 0, 0, 0, 0, 0, 0, 0, 0, 0, 1])  # u = 0.2 defects per part
    lim = u_limits(counts)
    assert lim.centre == pytest.approx(0.2)
    # P(X >= 3) = 0.00115 <= 0.00135 < P(X >= 2) = 0.0175: three defects are beyond, two are not
    assert poisson.sf(2, 0.2) <= 0.00135 < poisson.sf(1, 0.2) and lim.ucl == 2.0
    assert u_limits(np.zeros(15)).centre == pytest.approx(0.5 / 15)


def test_trend_and_parts_to_tolerance_on_an_exact_line():
    x = 0.1 + 0.025 * np.arange(12)
    slope, now, t = rolling_trend(x, 8)
    assert np.isnan(slope[6]) and slope[7:] == pytest.approx(0.025) and now[11] == pytest.approx(x[11])
    assert t[11] > 1e6  # on the line: no scatter (but rounding)
    ptt = parts_to_tolerance(slope, now, Tolerance(-0.5, 0.5))
    assert ptt[11] == pytest.approx((0.5 - x[11]) / 0.025)
    assert parts_to_tolerance(-slope, -now, Tolerance(-0.5, 0.5))[11] == pytest.approx((0.5 - x[11]) / 0.025)
    assert parts_to_tolerance(-slope, now, Tolerance(None, 0.5))[11] == np.inf  # heading away
    assert parts_to_tolerance(slope, now + 1, Tolerance(None, 0.5))[11] == 0.0  # beyond already


def test_a_slope_is_as_significant_as_the_larger_scatter_allows():
    from workbench.trend.analysis import slope_significance

    slope = np.array([0.025, 0.025, -0.025])
    t_window = np.array([9.0, 2.0, 9.0])
    by_baseline = 0.025 * np.sqrt(42.0) / 0.03  # sum of (t - mean)^2 over 8 parts: 42
    assert slope_significance(slope, t_window, 8, 0.03) == pytest.approx([by_baseline, 2.0, by_baseline])


# --- the done-when: a simulated production run recorded in a real SQLite store


def run_trend(capsys, *args) -> dict:
    assert main(["trend", *args, "--json"]) == 0, capsys.readouterr().err
    return json.loads(capsys.readouterr().out)


# seed 0, the first: over seeds 0-99 the drift is caught 15 parts or more before the first FAIL in
# 50 % of runs (median 14.5 parts ahead), and 12 % of 200-part runs without it raise a false alarm
# (benchmarks/trend_false_alarms.py): the done-when asks for both in every run, which no rule on
# these figures gives (see the report); seed 0 was not chosen, it is the first
SEED = 0


def test_a_drift_raises_an_alarm_fifteen_parts_before_the_first_fail(tmp_path, capsys):
    run = production_run(seed=SEED, parts=60, drift_mm=0.025)
    db = tmp_path / "s.db"
    record_run(run, store_url(str(db)), tmp_path)
    first_fail = int(np.flatnonzero(run.fails())[0])
    d = run_trend(capsys, "--store", str(db))
    alarm = d["alarms"][0]  # (in recording order)
    first = int(alarm["first"][1:]) - 1
    assert first_fail - first >= 15, (first_fail, alarm)
    assert alarm["rule_name"] == nelson.NAMES[alarm["rule"]] and alarm["figure"] in ("film_offset_x_mm", "worst_p95_mm")
    # every part of the run of firings it stands for, from the first whose pattern completed
    ids = alarm["part_ids"]
    assert alarm["first"] in ids and ids == sorted(ids) and ids[0] <= alarm["first"]
    assert alarm["parts_to_tolerance"] < 25 and alarm["trend_per_part"] > 0
    assert all(a["design"] == DESIGN_SHA for a in d["alarms"])
    # the limits: from the first 15 parts, as recorded
    x = next(c for c in d["charts"] if c["figure"] == "film_offset_x_mm")
    lim = imr_limits(run.x[:15])
    assert x["centre"] == pytest.approx(lim.centre, abs=1e-6) and x["ucl"] == pytest.approx(lim.ucl, abs=1e-6)
    assert x["tolerance"] == {"lo": -TOLERANCE_MM, "hi": TOLERANCE_MM} and x["points"] == 60
    assert main(["trend", "--store", str(db)]) == 0
    out = capsys.readouterr().out
    assert f"ALARM {alarm['figure']}" in out and f"rule {alarm['rule']}" in out


def test_the_same_run_without_drift_raises_no_alarm_over_200_parts(tmp_path, capsys):
    run = production_run(seed=SEED, parts=200)
    assert not run.fails().any()
    db = tmp_path / "s.db"
    record_run(run, store_url(str(db)), tmp_path)
    d = run_trend(capsys, "--store", str(db), "--design", "sim")
    assert d["alarms"] == [] and len(d["charts"]) == 6 and d["not_charted"] == []
    # the rules fire by chance all the same, and are counted: signals, no tolerance at stake
    assert sum(s["count"] for s in d["signals"]) > 0 and all(s["rule_name"] for s in d["signals"])
    # the classical chart, every firing an alarm: the same firings, now alarms
    classical = run_trend(capsys, "--store", str(db), "--every-signal")
    individuals = sum(s["count"] for s in d["signals"] if s["chart"] == "individuals")
    assert len(classical["alarms"]) == individuals > 0
    u = next(c for c in d["charts"] if c["figure"] == "defects")
    assert u["chart"] == "u" and u["centre"] == pytest.approx(max(run.defects[:15].mean(), 0.5 / 15), abs=1e-6)


@pytest.fixture(scope="module")
def store60(tmp_path_factory):
    d = tmp_path_factory.mktemp("trend")
    run = production_run(seed=7, parts=40, drift_mm=0.025)
    record_run(run, store_url(str(d / "s.db")), d)
    record_run(production_run(seed=8, parts=20), store_url(str(d / "s.db")), d, station="line-2")
    return d / "s.db"


def test_station_and_since_choose_the_parts_charted(store60, capsys):
    d = run_trend(capsys, "--store", str(store60), "--station", "line-2")
    assert {c["points"] for c in d["charts"]} == {20}
    # part 1's time + 20 min: line-1's parts 21-40 (line-2's 20 parts were recorded before)
    d = run_trend(capsys, "--store", str(store60), "--since", "2023-11-14T22:33:20Z")
    assert {c["points"] for c in d["charts"]} == {20}
    assert all(int(p[1:]) >= 21 for a in d["alarms"] for p in a["part_ids"])


def test_pictures_and_report_are_the_same_bytes_each_time(store60, tmp_path, capsys, monkeypatch):
    monkeypatch.setenv("SOURCE_DATE_EPOCH", "1700000000")
    for k in (1, 2):
        assert main(["trend", "--store", str(store60), "--out", str(tmp_path / f"r{k}")]) == 0
    capsys.readouterr()
    names = sorted(p.name for p in (tmp_path / "r1").iterdir())
    assert "trend.html" in names and sum(n.endswith(".png") for n in names) == 6
    for n in names:
        assert (tmp_path / "r1" / n).read_bytes() == (tmp_path / "r2" / n).read_bytes(), n
    png = (tmp_path / "r1" / f"{DESIGN_SHA[:40]}-film_offset_x_mm.png").read_bytes()
    assert png.startswith(b"\x89PNG") and b"Software" not in png and b"tIME" not in png
    html = (tmp_path / "r1" / "trend.html").read_text()
    assert html.count("data:image/png;base64,") == 6 and "http" not in html and "2023-11-14T22:13:20Z" in html


# --- the schema: version 1 stores are brought to version 2, their figures filled from validation.json


def test_a_version_1_store_is_migrated(tmp_path, capsys):
    db = tmp_path / "v1.db"
    engine = create_engine(f"sqlite:///{db}")
    run = production_run(seed=3, parts=16)
    with engine.begin() as conn:
        schema_version.create(conn)
        MIGRATIONS[0][2](conn)  # version 1's step, as released
        conn.execute(schema_version.insert().values(version=1, description=MIGRATIONS[0][1]))
        v1_columns = {c["name"] for c in inspect(conn).get_columns("validations")}
        assert "film_offset_x_mm" not in v1_columns and not inspect(conn).has_table("calibrations")
        row = {c.name: None for c in validations.columns if c.name in v1_columns and c.name != "id"}
        for i in range(16):
            values = {"part_id": part_id(i), "station": "s", "operator": "o", "recorded_at": "2026-01-01T00:00:00Z"}
            values.update(software_version="v1", verdict="PASS", photos=1, photos_pass=1, photos_fail=0)
            values.update(photos_invalid=0, defects=0, out_dir="/x", validation_json=report_text(run, i))
            values.update(design_json_sha256=DESIGN_SHA, tolerance_mm=0.5, worst_p95_mm=float(run.p95[i]))
            conn.execute(validations.insert().values(**{**row, **values}))
    engine.dispose()
    d = run_trend(capsys, "--store", str(db))  # any command brings the store up to date
    assert len(d["charts"]) == 6
    with engine.connect() as conn:
        versions = conn.execute(select(schema_version.c.version).order_by(schema_version.c.version)).scalars().all()
        got = conn.execute(select(validations.c.film_offset_x_mm, validations.c.delta_e00_mean)).all()
        incomplete = conn.execute(select(validations.c.photos_incomplete)).scalars().all()
        indexes = {i["name"] for i in inspect(conn).get_indexes("validations")}
        assert inspect(conn).has_table("calibrations")
    engine.dispose()
    assert versions == [1, 2, 3] == list(range(1, LATEST + 1))
    assert incomplete == [0] * 16  # (filled from each record's validation.json: its photos' verdicts)
    assert [g[0] for g in got] == pytest.approx(run.x.tolist()) and [g[1] for g in got] == pytest.approx(run.delta_e)
    assert {"ix_validations_design", "ix_validations_job"} <= indexes


def test_part_figures_from_a_validation_report():
    report = {
        "photos": [
            {"verdict": "PASS", "film_offset_mm": [0.1, -0.2], "film_rotation_deg": 0.5},
            {"verdict": "FAIL", "film_offset_mm": [0.3, 0.0], "film_rotation_deg": 0.1},
            {"verdict": "INVALID", "film_offset_mm": [9.0, 9.0], "film_rotation_deg": 9.0},
        ],
        "part": {"colour": {"worst_delta_e00": {"mean": 2.5}}},
    }
    f = part_figures(report)
    assert f["film_offset_x_mm"] == pytest.approx(0.2) and f["film_offset_y_mm"] == pytest.approx(-0.1)
    assert f["film_rotation_deg"] == pytest.approx(0.3) and f["delta_e00_mean"] == 2.5
    report["part"]["colour"]["delta_e00"] = {"mean": 1.25}  # the fused colour's, when there is one
    assert part_figures(report)["delta_e00_mean"] == 1.25
    assert part_figures({"photos": [], "part": {}}) == dict.fromkeys(f)


# --- calibration history


def test_calibrate_check_records_and_trend_charts_the_printer_scale(tmp_path, capsys, monkeypatch):
    prof = ROOT / "calib" / "printers" / "reference-laser.json"
    scan = ROOT / "calib" / "regression" / "printer-target-scan-300dpi.png"
    db = tmp_path / "s.db"
    monkeypatch.setenv("SOURCE_DATE_EPOCH", "1700000000")
    assert main(["calibrate", "check", str(prof), str(scan), "--store", str(db), "-q"]) == 0
    monkeypatch.setenv("WORKBENCH_STORE", str(db))
    assert main(["calibrate", "check", str(prof), str(scan), "-q"]) == 0
    engine = create_engine(f"sqlite:///{db}")
    with engine.connect() as conn:
        rows = conn.execute(select(calibrations).order_by(calibrations.c.id)).all()
    engine.dispose()
    profile = json.loads(prof.read_text())
    assert len(rows) == 2 and rows[0].camera == "reference-laser" and rows[0].verdict == "OK"
    assert rows[0].kind == "printer-profile" and rows[0].recorded_at == "2023-11-14T22:13:20Z"
    assert abs(rows[0].scale_x - profile["scale_x"]) * 100 <= 0.05 and rows[0].profile_scale_x == profile["scale_x"]
    d = run_trend(capsys, "--calibration", "--camera", "reference-laser", "--baseline-parts", "2")
    assert [c["figure"] for c in d["charts"]] == ["scale_x", "scale_y"] and d["alarms"] == []
    assert d["charts"][0]["tolerance"]["hi"] == pytest.approx(profile["scale_x"] + 0.0005)


def test_calibrate_check_records_a_camera_check(tmp_path, capsys):
    prof = ROOT / "calib" / "cameras" / "opencv-left.json"
    photos = [ROOT / "calib" / "regression" / "opencv-chessboard" / f"left{k:02d}.jpg" for k in (9, 11, 12, 13, 14)]
    db = tmp_path / "s.db"
    assert main(["calibrate", "check", str(prof), *map(str, photos), "--store", str(db), "-q"]) == 0
    engine = create_engine(f"sqlite:///{db}")
    with engine.connect() as conn:
        row = conn.execute(select(calibrations)).one()
    engine.dispose()
    K = json.loads(prof.read_text())["K"]
    assert row.kind == "camera-profile" and row.verdict == "OK" and row.profile_fx == K[0][0]
    assert abs(row.fx - K[0][0]) / K[0][0] < 0.01 and row.focal_tolerance_pct == 1.0 and row.pp_tolerance_px == 8.0
    assert json.loads(row.check_json)["fx"] == row.fx


# --- bad input: one line, exit 1 or 2, nothing written


def test_bad_input(store60, tmp_path, capsys):
    out = tmp_path / "out"
    cases = [
        (["--store", str(store60), "--design", "no-such-job"], "--design no-such-job: no part of it is recorded"),
        (["--store", str(store60), "--design", "x'); drop table validations; --"], "no part of it is recorded"),
        (["--store", str(store60), "--baseline-parts", "61"], "--baseline-parts 61: design"),
        (["--store", str(tmp_path / "none.db")], "no store at"),
        (["--store", str(store60), "--calibration"], "no calibration check recorded"),
        (["--store", str(store60), "--calibration", "--camera", "x"], "--camera x: no calibration check of it"),
        (["--store", str(store60), "--rules", "1,9"], "--rules 1,9: give Nelson rule numbers 1 to 8"),
        (["--store", str(store60), "--since", "yesterday"], "--since yesterday: not a date"),
        (["--store", str(store60), "--station", "line-9"], "no part recorded matches them"),
        (["--store", str(store60), "--baseline-parts", "1"], "--baseline-parts"),
    ]
    for args, says in cases:
        status = main(["trend", *args, "--out", str(out)])
        err = capsys.readouterr().err
        assert status in (1, 2) and says in err and len(err.strip().splitlines()) == 1, (args, err)
        assert not out.exists() and not (tmp_path / "none.db").exists()
    empty = tmp_path / "empty.db"
    engine = create_engine(f"sqlite:///{empty}")
    with engine.begin() as conn:
        for step in MIGRATIONS:
            step[2](conn) if step[0] == 1 else None
        schema_version.create(conn)
        conn.execute(text("insert into schema_version (version, description) values (99, 'future')"))
    engine.dispose()
    assert main(["trend", "--store", str(empty)]) == 1
    assert "a store of schema version 99, newer than this workbench's" in capsys.readouterr().err


def test_a_store_with_no_record(tmp_path, capsys):
    db = tmp_path / "s.db"
    engine = create_engine(f"sqlite:///{db}")
    from workbench.store.schema import migrate

    with engine.begin() as conn:
        migrate(conn)
    engine.dispose()
    before = db.read_bytes()
    assert main(["trend", "--store", str(db), "--out", str(tmp_path / "o")]) == 1
    err = capsys.readouterr().err
    assert "no part recorded" in err and len(err.strip().splitlines()) == 1
    assert db.read_bytes() == before and not (tmp_path / "o").exists()
