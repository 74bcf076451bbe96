"""The tutorial (docs/tutorial.md) runs, and its numbers are the command line's.

Every ```python cell of the page is executed in order in one namespace (as a notebook
would); then ``static.to_dict()`` must equal the noise.json of ``imubounds static`` and
``dyn.to_dict()`` the ``modes.full`` block of the dynamic.json of ``imubounds dynamic``
on the same bundled data, every number to 1e-9 relative.
"""

from __future__ import annotations

import json
import math
import os
import re
from pathlib import Path
from typing import Any

import pytest

from imubounds.cli import main

REPO = Path(__file__).resolve().parents[1]
TUTORIAL = REPO / "docs" / "tutorial.md"
CELL = re.compile(r"^```python\n(.*?)^```", re.S | re.M)
REL = 1e-9


def cells(path: Path) -> list[str]:
    return CELL.findall(path.read_text(encoding="utf-8"))


def differences(a: Any, b: Any, where: str = "") -> list[str]:
    """Paths where two JSON documents differ (numbers compared to REL relative)."""
    if isinstance(a, dict) and isinstance(b, dict):
        out = [f"{where}.{k}: only in one" for k in set(a) ^ set(b)]
        for k in set(a) & set(b):
            out += differences(a[k], b[k], f"{where}.{k}")
        return out
    if isinstance(a, list) and isinstance(b, list):
        if len(a) != len(b):
            return [f"{where}: length {len(a)} vs {len(b)}"]
        out = []
        for i, (x, y) in enumerate(zip(a, b, strict=True)):
            out += differences(x, y, f"{where}[{i}]")
        return out
    num = (int, float)
    if isinstance(a, num) and isinstance(b, num) and not isinstance(a, bool | str):
        if math.isclose(a, b, rel_tol=REL, abs_tol=0.0) or a == b:
            return []
        return [f"{where}: {a!r} vs {b!r}"]
    return [] if a == b else [f"{where}: {a!r} vs {b!r}"]


def test_differences_sees_a_change_beyond_the_tolerance() -> None:
    doc = {"a": [1.0, {"b": 2.0}], "c": "x"}
    assert differences(doc, json.loads(json.dumps(doc))) == []
    moved = {"a": [1.0, {"b": 2.0 * (1 + 1e-8)}], "c": "x"}
    assert differences(doc, moved) == [".a[1].b: 2.0 vs 2.00000002"]
    assert differences(doc, {"a": [1.0], "c": "x"}) == [".a: length 2 vs 1"]


def test_tutorial_has_static_then_dynamic_cells() -> None:
    code = cells(TUTORIAL)
    assert len(code) >= 6
    first_static = next(i for i, c in enumerate(code) if "characterize(" in c)
    first_dynamic = next(i for i, c in enumerate(code) if "dynamic_margins(" in c)
    assert first_static < first_dynamic


@pytest.mark.slow
def test_tutorial_runs_and_gives_the_cli_numbers(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    import imubounds as ib

    work = tmp_path / "notebook"
    work.mkdir()
    monkeypatch.chdir(work)
    ns: dict[str, Any] = {"__name__": "__tutorial__"}
    for i, code in enumerate(cells(TUTORIAL)):
        try:
            exec(compile(code, f"{TUTORIAL.name} cell {i + 1}", "exec"), ns)
        except Exception as err:  # pragma: no cover - the message says which cell
            raise AssertionError(f"tutorial cell {i + 1} failed: {err!r}\n{code}") from err
    assert os.listdir(work) == [], "the tutorial wrote files"

    static_out, dyn_out = tmp_path / "static", tmp_path / "dyn"
    # a plain 'imubounds static' (its defaults) is the tutorial's plain characterize(log)
    assert main(["static", str(ib.bundled_static_log()), "-o", str(static_out),
                 "--no-plot", "--no-report", "--quiet"]) == 0  # fmt: skip
    assert main(["dynamic", str(ib.bundled_drive_log()), "-o", str(dyn_out), "--mode", "full",
                 "--imu-spec", "vn100", "--no-plot", "--no-report", "--quiet"]) == 0  # fmt: skip

    noise = json.loads((static_out / "noise.json").read_text())
    got = ns["static"].to_dict()
    diff = differences(got, noise)
    assert not diff, "tutorial vs noise.json:\n" + "\n".join(sorted(diff)[:20])

    dyn = json.loads((dyn_out / "dynamic.json").read_text())
    got = ns["dyn"].to_dict()
    diff = differences(got, dyn["modes"]["full"])
    assert not diff, "tutorial vs dynamic.json:\n" + "\n".join(sorted(diff)[:20])
    assert ns["dyn"].verdicts == dyn["modes"]["full"]["verdict"]
    # the tables of the tutorial are the CSV files of the command line
    margins = ns["margins"]
    assert len(margins) == sum(len(v) for v in dyn["modes"]["full"]["margins"].values())
