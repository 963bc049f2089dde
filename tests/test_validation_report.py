"""shellform validate: report and JSON for the fast cases."""

import json

from shellform.cli import main
from shellform.validation import CASES


def test_validate_writes_report_and_json(tmp_path):
    assert main(["validate", "catenary", "von_mises", "--out", str(tmp_path), "--quiet"]) == 0
    data = json.loads((tmp_path / "validation.json").read_text())
    assert data["passed"] is True
    assert [c["name"] for c in data["cases"]] == ["catenary", "von_mises"]
    report = (tmp_path / "report.md").read_text()
    assert "| first limit load [N] |" in report
    assert (tmp_path / "von_mises.png").exists()


def test_unknown_case_is_named(tmp_path, capsys):
    assert main(["validate", "nonsense", "--out", str(tmp_path)]) == 2
    assert "nonsense" in capsys.readouterr().err


def test_every_case_is_registered_with_a_title():
    assert all(case.title for case in CASES.values())
