"""The demo's closing summary: one screen, what to do per part, and the files to open first."""

from __future__ import annotations

import json

from fixtures.demo_summary import main


def test_the_summary_names_the_reports_to_open_and_the_html_only_when_there(tmp_path, capsys):
    part = tmp_path / "validation" / "film"
    part.mkdir(parents=True)
    place = {"verdict": "FAIL", "move_mm": [-0.8, 0.0], "turn_deg": 0.0, "offset_mm": [0.8, 0.0], "rotation_deg": 0.0}
    report = {
        "max_defect_mm2": 4.0,
        "max_delta_e": 3.0,
        "photos": [{"photo": "../../p.jpg", "verdict": "FAIL", "reason": "", "placement": place}],
        "part": {"verdict": "FAIL", "defects": [], "colour": {"verdict": "not measured", "reasons": ["no chart"]}},
    }
    (part / "validation.json").write_text(json.dumps(report))
    (part / "qa_report.pdf").write_bytes(b"%PDF")
    main(tmp_path)
    out = capsys.readouterr().out
    assert "film: FAIL  (p.jpg)" in out and "Move the film by (-0.80, +0.00) mm" in out
    assert str(part / "qa_report.pdf") in out and "qa_report.html" not in out
    # one screen: a few lines, each within 100 characters but for the files' own paths
    assert len(out.splitlines()) <= 24 and max(len(x) for x in out.splitlines() if str(tmp_path) not in x) <= 100
    (part / "qa_report.html").write_text("<html></html>")
    main(tmp_path)
    assert str(part / "qa_report.html") in capsys.readouterr().out
