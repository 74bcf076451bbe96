"""imubounds.runtime: process settings the CLI and the fleet's workers apply."""

from __future__ import annotations

import os
import platform
import subprocess
import sys

import pytest

from imubounds.runtime import MALLOC_SETTINGS, malloc_environment


def test_a_value_the_user_set_wins(monkeypatch: pytest.MonkeyPatch) -> None:
    for k in MALLOC_SETTINGS:
        monkeypatch.delenv(k, raising=False)
    assert malloc_environment() == {k: str(v) for k, v in MALLOC_SETTINGS.items()}
    monkeypatch.setenv("MALLOC_TRIM_THRESHOLD_", "1234")
    assert malloc_environment()["MALLOC_TRIM_THRESHOLD_"] == "1234"


def test_tuning_keeps_freed_arrays_for_reuse() -> None:
    """In a fresh process: applied on glibc Linux, and a loop of log-length arrays then
    faults far fewer pages than with glibc's defaults (the point of it)."""
    code = (
        "import resource, sys, numpy as np\n"
        "from imubounds.runtime import tune_malloc\n"
        "ok = tune_malloc() if sys.argv[1] == '1' else None\n"
        "x = np.ones(500_000)\n"
        "f0 = resource.getrusage(resource.RUSAGE_SELF).ru_minflt\n"
        "for _ in range(40):\n"
        "    y = x * 2.0; z = np.cumsum(y); del y, z\n"
        "print(ok, resource.getrusage(resource.RUSAGE_SELF).ru_minflt - f0)\n"
    )
    env = {k: v for k, v in os.environ.items() if not k.startswith("MALLOC_")}

    def run(tuned: str) -> tuple[str, int]:
        out = subprocess.run([sys.executable, "-c", code, tuned], env=env, check=True,
                             capture_output=True, text=True).stdout.split()  # fmt: skip
        return out[0], int(out[1])

    ok, tuned = run("1")
    _, plain = run("0")
    if sys.platform.startswith("linux") and platform.libc_ver()[0] == "glibc":
        assert ok == "True"
        assert tuned * 4 < plain, (tuned, plain)
