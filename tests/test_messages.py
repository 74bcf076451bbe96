"""Messages go where they belong: summaries on stdout, progress bars only on a terminal."""

from __future__ import annotations

import io
import sys
from typing import Any

import pytest

from imubounds.cli._common import Reporter


class _Tty(io.StringIO):
    def isatty(self) -> bool:
        return True


def _bars(monkeypatch: pytest.MonkeyPatch, stream: Any) -> str:
    monkeypatch.setattr(sys, "stderr", stream)
    rep = Reporter(quiet=False)
    with rep.session() as progress:
        for i in range(5):
            progress("allan", i + 1, 5)
    return str(stream.getvalue())


def test_progress_bars_only_on_a_terminal(monkeypatch: pytest.MonkeyPatch) -> None:
    assert _bars(monkeypatch, io.StringIO()) == ""  # a log file, a pipe: no bar
    assert "allan" in _bars(monkeypatch, _Tty())  # a terminal: the bar


def test_simulate_summary_on_stdout(tmp_path: Any, capsys: pytest.CaptureFixture[str]) -> None:
    from imubounds.cli import main

    assert main(["simulate", "-o", str(tmp_path / "s"), "--duration", "200",
                 "--distance", "2400"]) == 0  # fmt: skip
    captured = capsys.readouterr()
    assert "simulated paper (seed 0)" in captured.out and "record:" in captured.out
    assert "simulated" not in captured.err
