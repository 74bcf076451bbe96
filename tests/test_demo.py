"""``imubounds demo`` (what ``make demo`` runs) end to end, from a relative output folder
as a user types it: every step runs and the report holds both pipelines."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from imubounds.cli import main


@pytest.mark.slow  # the whole pipeline on the bundled data: about a minute
def test_demo_with_a_relative_output_folder(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    monkeypatch.chdir(tmp_path)
    code = main(["demo", "-o", "out", "-q"])
    err = capsys.readouterr().err
    assert code == 0, err
    out = Path("out")
    for f in ("static/noise.json", "sim/drive.yaml", "dynamic/dynamic.json",
              "dynamic_vn100/dynamic.json", "report.html", "run.json"):  # fmt: skip
        assert (out / f).is_file(), f
    dyn = json.loads((out / "dynamic" / "dynamic.json").read_text())
    assert set(dyn["modes"]) == {"full", "paper"}
    assert dyn["modes"]["full"]["guaranteed"] is True
    assert dyn["modes"]["paper"]["guaranteed"] is False
    html = (out / "report.html").read_text()
    assert "Stationary characterisation" in html and "Dynamic error margins" in html
