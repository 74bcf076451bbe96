"""Issue 16 item 5: interval results whatever the FPU rounding mode of the process.

The estimator's kernels (numba, on the scalar rules) and the vectorised rules rely on
round-to-nearest; ``dynamic_margins`` sets it around its work and restores the caller's
mode. Two ways a process gets another mode: ``import codac`` (round-upward, checked in a
subprocess so that the rest of the test run keeps its mode) and ``fesetround`` via ctypes.
"""

from __future__ import annotations

import json
import platform
import subprocess
import sys
from pathlib import Path

import pytest

from imubounds.dynamic.estimator import dynamic_margins
from imubounds.interval import IntervalArray
from imubounds.interval.rounding import FE_TONEAREST, rounding, rounding_mode

REPO = Path(__file__).resolve().parents[2]
#: FE_UPWARD of glibc on x86-64 and on aarch64
FE_UPWARD = 0x400000 if platform.machine() in ("aarch64", "arm64") else 0x800
TRIP = {"duration_s": 60.0, "distance_m": 500.0, "corner_m": 40.0, "ramp_s": 10.0,
        "imu_hz": 20.0}

SCRIPT = """
import json, sys
sys.path.insert(0, {repo!r})
try:
    import h5py  # noqa: F401  (must precede codac in this environment)
except ImportError:
    pass
from imubounds.dynamic.estimator import dynamic_margins
from tests.trips import make_trip
drive, _ = make_trip("paper", 3, **{trip!r})  # the same data as in the parent process
import codac  # switches the process to round-upward
from imubounds.interval.rounding import rounding_mode
mode_before = rounding_mode()
d = dynamic_margins(drive).to_dict()
print(json.dumps({{"before": mode_before, "after": rounding_mode(), "margins": d["margins"],
                  "bias": d["bias"], "enclosure": d["enclosure"]}}))
"""


def _drive() -> object:
    from tests.trips import make_trip

    return make_trip("paper", 3, **TRIP)[0]


def _summary(drive: object = None) -> dict:
    d = dynamic_margins(drive if drive is not None else _drive()).to_dict()
    return {"margins": d["margins"], "bias": d["bias"], "enclosure": d["enclosure"]}


def test_dynamic_margins_identical_in_round_upward_mode() -> None:
    """A caller in round-upward (set with fesetround) gets the same intervals, bit for bit,
    and keeps its own mode afterwards."""
    assert rounding_mode() == FE_TONEAREST
    drive = _drive()
    ref = _summary(drive)
    with rounding(FE_UPWARD):
        assert rounding_mode() == FE_UPWARD
        got = _summary(drive)
        assert rounding_mode() == FE_UPWARD  # the caller's mode is restored
    assert rounding_mode() == FE_TONEAREST
    assert json.dumps(got, sort_keys=True) == json.dumps(ref, sort_keys=True)


def test_vectorised_rules_refuse_another_mode() -> None:
    with rounding(FE_UPWARD):
        with pytest.raises(ValueError, match="round-to-nearest"):
            IntervalArray([0.1, 0.2]) + IntervalArray([0.3, 0.4])


def _differences(a: object, b: object, rel: float = 1e-9, path: str = "") -> list[str]:
    """Paths where two JSON documents differ by more than ``rel`` (numbers) or at all."""
    if isinstance(a, dict) and isinstance(b, dict):
        if a.keys() != b.keys():
            return [f"{path}: keys {sorted(set(a) ^ set(b))}"]
        return [d for k in a for d in _differences(a[k], b[k], rel, f"{path}/{k}")]
    if isinstance(a, list) and isinstance(b, list):
        if len(a) != len(b):
            return [f"{path}: lengths {len(a)} and {len(b)}"]
        return [d for i, (x, y) in enumerate(zip(a, b, strict=True))
                for d in _differences(x, y, rel, f"{path}[{i}]")]
    if isinstance(a, int | float) and isinstance(b, int | float):
        if a == b or abs(a - b) <= rel * max(abs(a), abs(b)):
            return []
    elif a == b:
        return []
    return [f"{path}: {a!r} and {b!r}"]


def test_after_import_codac() -> None:
    """In a process that imported codac (round-upward), dynamic_margins gives the same
    results as here (to 1e-9 relative: the NNLS fit of the flicker model runs in BLAS
    worker threads, which keep codac's mode; the interval kernels run in the calling
    thread under round-to-nearest) and leaves the process in codac's mode."""
    import importlib.util

    # find it without importing it: importing codac here would switch THIS process
    if importlib.util.find_spec("codac") is None:
        pytest.skip("codac is a test-only dependency (pip install codac)")
    code = SCRIPT.format(repo=str(REPO), trip=TRIP)
    res = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         timeout=900, cwd=REPO)
    assert res.returncode == 0, res.stderr[-2000:]
    out = json.loads(res.stdout.strip().splitlines()[-1])
    assert out["before"] != FE_TONEAREST, "importing codac did not change the rounding mode"
    assert out["after"] == out["before"]
    ref = json.loads(json.dumps(_summary()))
    for key in ("margins", "bias", "enclosure"):
        diff = _differences(out[key], ref[key])
        assert not diff, diff[:5]
    assert out["enclosure"] == ref["enclosure"]
