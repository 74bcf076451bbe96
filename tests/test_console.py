"""The answer first on a terminal (a pseudo-terminal, as a user's shell gives): the first
15 lines of ``imubounds static`` on the bundled log hold the N/B/K table and the filter
parameters; ``imubounds dynamic`` on a 1 h trip shows its progress within 2 s, and the
progress line is gone when the command is not on a terminal."""

from __future__ import annotations

import fcntl
import os
import pty
import re
import select
import struct
import subprocess
import sys
import termios
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

import imubounds as ib

ANSI = re.compile(rb"\x1b\[[0-9;?]*[A-Za-z]")


def on_terminal(argv: list[str], stop: Callable[[bytes], bool] | None = None,
                timeout: float = 300.0) -> tuple[list[tuple[float, bytes]], int | None]:
    """Run ``imubounds ARGV`` on a pseudo-terminal (160 columns); its output as (seconds
    since the start, bytes) chunks, until it ends or ``stop(output so far)`` (then the
    process, our own child, is killed)."""
    master, slave = pty.openpty()
    fcntl.ioctl(slave, termios.TIOCSWINSZ, struct.pack("HHHH", 50, 160, 0, 0))
    t0 = time.monotonic()
    proc = subprocess.Popen([sys.executable, "-m", "imubounds", *argv], stdin=slave,
                            stdout=slave, stderr=slave, close_fds=True)  # fmt: skip
    os.close(slave)
    chunks: list[tuple[float, bytes]] = []
    try:
        while time.monotonic() - t0 < timeout:
            ready, _, _ = select.select([master], [], [], 0.1)
            if ready:
                try:
                    data = os.read(master, 65536)
                except OSError:  # the terminal closed: the command ended
                    break
                if not data:
                    break
                chunks.append((time.monotonic() - t0, data))
                if stop is not None and stop(b"".join(c for _, c in chunks)):
                    break
            elif proc.poll() is not None:
                break
    finally:
        if proc.poll() is None:
            proc.kill()
        proc.wait()
        os.close(master)
    return chunks, proc.returncode


def screen(raw: bytes) -> list[str]:
    """The lines a terminal keeps: each line's text after its last carriage return (what
    a progress line rewrote), escape sequences left out."""
    out = []
    for seg in ANSI.sub(b"", raw).split(b"\n"):
        out.append(seg.rstrip(b"\r").split(b"\r")[-1].decode("utf-8", "replace").rstrip())
    return out


def test_static_on_a_terminal_answers_in_its_first_15_lines(tmp_path: Path) -> None:
    chunks, code = on_terminal(["static", str(ib.bundled_static_log()), "-o",
                                str(tmp_path / "st"), "--no-plot", "--no-report"])  # fmt: skip
    raw = b"".join(c for _, c in chunks)
    assert code == 0, raw[-2000:]
    assert b"imubounds static: " in raw  # the progress line was there
    lines = screen(raw)
    first = "\n".join(lines[:15])
    for ch in ("gyro_x", "gyro_y", "gyro_z", "accel_x", "accel_y", "accel_z"):
        assert any(ln.startswith(ch) for ln in lines[:15]), first
    assert "N [deg/s/sqrt(Hz)]" in first and "N [rad/s^0.5]" in first  # datasheet and SI
    assert "B [mg]" in first and "K [m/s^3/sqrt(Hz)]" in first
    for key in ("gyroscope_noise_density", "gyroscope_random_walk",
                "accelerometer_noise_density", "accelerometer_random_walk", "update_rate"):
        assert key in first, key
    assert "imubounds static:" not in "\n".join(lines)  # the progress line is gone
    # the notes are counted and pointed to, not printed; the warnings are printed
    notes = next(ln for ln in lines if "note(s) on the analysis" in ln)
    assert "noise.json" in notes and "--verbose" in notes
    assert not any(ln.startswith("gyro_x: Q: dominates nowhere") for ln in lines)
    assert any(ln.startswith("imubounds: warning: accel_y") for ln in lines)


def _hour_trip(d: Path) -> Path:
    """A 1 h drive layout (IMU at 100 Hz, GNSS and compass at 1 Hz; a parked car)."""
    d.mkdir()
    rng = np.random.default_rng(0)
    n = 360_000
    imu = pd.DataFrame({"time_s": np.arange(n) / 100.0})
    for a in "xyz":
        imu[f"gyro_{a}_dps"] = rng.normal(0.0, 0.05, n)
    for a, g in zip("xyz", (0.0, 0.0, 1.0), strict=True):
        imu[f"accel_{a}_g"] = g + rng.normal(0.0, 0.002, n)
    imu.to_parquet(d / "imu.parquet", index=False)
    tg = np.arange(0.0, 3600.0, 1.0)
    pd.DataFrame({"time_s": tg, "lat_deg": 45.0 + rng.normal(0, 1e-5, tg.size),
                  "lon_deg": 7.0 + rng.normal(0, 1e-5, tg.size)}).to_parquet(
        d / "gnss.parquet", index=False)  # fmt: skip
    pd.DataFrame({"time_s": tg, "heading_deg": 30.0 + rng.normal(0, 1.0, tg.size)}).to_parquet(
        d / "heading.parquet", index=False)
    (d / "drive.yaml").write_text("gnss: {cep_m: 2.5}\nimu: {preset: vn100}\n")
    return d


def test_dynamic_on_a_one_hour_trip_shows_progress_first(tmp_path: Path) -> None:
    trip = _hour_trip(tmp_path / "trip")

    def into_mode_full(out: bytes) -> bool:
        return b"mode full" in out

    chunks, _ = on_terminal(["dynamic", str(trip), "-o", str(tmp_path / "out")],
                            stop=into_mode_full, timeout=120.0)  # fmt: skip
    progress = [(t, c) for t, c in chunks if b"imubounds dynamic: " in c]
    assert progress, b"".join(c for _, c in chunks)[-2000:]
    # the progress line is the first thing on the terminal and is there before the drive
    # has been read (no wall-clock threshold: a loaded CI machine takes seconds to import;
    # on an idle machine the first line comes within about 1 s)
    assert chunks[0][1].strip().startswith(b"imubounds dynamic: "), chunks[0]
    t_full = next(t for t, c in chunks if b"2/6 mode full" in c)
    assert progress[0][0] < t_full, (progress[0], t_full)
    # it moves: the steps (reading, then mode full) and its clock, twice a second
    raw = b"".join(c for _, c in chunks)
    assert b"1/6 reading the drive" in raw and b"2/6 mode full" in raw
    assert len(progress) >= 3


def _small_log(path: Path) -> Path:
    rng = np.random.default_rng(1)
    pd.DataFrame({"time_s": np.arange(6000) / 100.0,
                  "gyro_z_rads": rng.normal(0, 1e-3, 6000)}).to_csv(path, index=False)
    return path


def test_no_progress_line_when_not_on_a_terminal(tmp_path: Path) -> None:
    proc = subprocess.run(
        [sys.executable, "-m", "imubounds", "static", str(_small_log(tmp_path / "log.csv")),
         "-o", str(tmp_path / "st"), "--no-plot", "--no-report", "--models", "none"],
        capture_output=True, check=False,
    )  # fmt: skip
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert b"imubounds static:" not in proc.stderr and b"\r" not in proc.stderr
    assert proc.stdout.splitlines()[0].startswith(b"gyro ")  # the answer first on stdout


@pytest.mark.parametrize("verbose", [False, True])
def test_verbose_prints_the_notes(tmp_path: Path, verbose: bool,
                                  capsys: pytest.CaptureFixture[str]) -> None:  # fmt: skip
    from imubounds.cli import main

    argv = ["static", str(_small_log(tmp_path / "log.csv")), "-o", str(tmp_path / "o"),
            "--no-plot", "--no-report", "--models", "none",
            *(["--verbose"] if verbose else [])]  # fmt: skip
    assert main(argv) == 0
    err = capsys.readouterr().err
    assert ("gyro_z: Q:" in err) is verbose
    assert ("--verbose prints them" in err) is not verbose
