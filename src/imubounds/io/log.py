"""The in-memory log model shared by every reader and every analysis.

Readers convert whatever they read into an :class:`ImuLog`: SI units,
canonical channel names (``gyro_x`` ... ``accel_z``), a time vector in seconds
and a nominal sample rate. Frames are recorded so that later conversions are
explicit (``"FLU"`` body axes unless a reader knows better).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

IMU_CHANNELS: tuple[str, ...] = (
    "gyro_x",
    "gyro_y",
    "gyro_z",
    "accel_x",
    "accel_y",
    "accel_z",
)

#: Column-name suffix of each sensor's SI unit in :meth:`ImuLog.to_frame` (the
#: readers recognise these names, so a frame written to CSV reads back unchanged).
SI_SUFFIX: dict[str, str] = {"gyro": "rads", "accel": "mps2"}


@dataclass
class ImuLog:
    """An IMU log in SI units.

    Attributes
    ----------
    channels:
        Channel name -> float64 samples in SI (rad/s for gyros, m/s^2 for
        accelerometers). Only channels present in the input appear.
    rate_hz:
        Nominal sample rate in Hz (from the time stamps or ``--rate``).
    t:
        Time stamps in s, same length as every channel.
    source:
        Where the log came from (a path or a description).
    input_units:
        Channel name -> unit the input was in, before conversion to SI.
    frame:
        Body frame convention of the axes (``"FLU"``, ``"FRD"`` or ``"unknown"``).
    warnings:
        Things the reader noticed and a user should see (gaps, fallbacks).
    """

    channels: dict[str, np.ndarray]
    rate_hz: float
    t: np.ndarray
    source: str = "<memory>"
    input_units: dict[str, str] = field(default_factory=dict)
    frame: str = "unknown"
    warnings: list[str] = field(default_factory=list)

    def __repr__(self) -> str:
        return (
            f"ImuLog(source={self.source!r}, channels={self.channel_names()}, "
            f"rate_hz={self.rate_hz:g}, n_samples={self.n_samples}, "
            f"duration_s={self.duration_s:g}, warnings={len(self.warnings)})"
        )

    @property
    def n_samples(self) -> int:
        """Number of samples."""
        return int(self.t.shape[0])

    @property
    def duration_s(self) -> float:
        """Duration in s: number of samples divided by the rate."""
        return self.n_samples / self.rate_hz

    @property
    def dt(self) -> float:
        """Nominal sample period in s."""
        return 1.0 / self.rate_hz

    def channel_names(self) -> list[str]:
        """Channels present, in canonical order first, then any others."""
        known = [c for c in IMU_CHANNELS if c in self.channels]
        return known + [c for c in self.channels if c not in IMU_CHANNELS]

    def si_unit(self, channel: str) -> str:
        """SI unit of a channel's samples: ``"rad/s"`` (gyro) or ``"m/s^2"`` (accel)."""
        return "rad/s" if channel.startswith("gyro") else "m/s^2"

    def to_frame(self) -> Any:
        """The samples as a :class:`pandas.DataFrame` in SI with the unit in each name:
        ``time_s``, ``gyro_x_rads`` ... ``accel_z_mps2`` (names every reader recognises,
        so ``read_log`` of the frame written to CSV gives the same log)."""
        import pandas as pd

        cols: dict[str, np.ndarray] = {"time_s": np.asarray(self.t, dtype=np.float64)}
        for name in self.channel_names():
            kind = name.split("_")[0]
            suffix = SI_SUFFIX.get(kind)
            cols[f"{name}_{suffix}" if suffix else name] = np.asarray(self.channels[name])
        return pd.DataFrame(cols)

    def to_dict(self) -> dict[str, Any]:
        """A JSON-able description of the log (not the samples): source, rate, duration,
        channels with their SI unit and input unit, frame and warnings (the ``input``
        block of noise.json, plus the channels)."""
        return {
            "path": self.source,
            "sample_rate_hz": float(self.rate_hz),
            "duration_s": float(self.duration_s),
            "n_samples": self.n_samples,
            "channels": {
                c: {"unit": self.si_unit(c), "input_unit": self.input_units.get(c)}
                for c in self.channel_names()
            },
            "input_units": dict(self.input_units),
            "frame": self.frame,
            "warnings": list(self.warnings),
        }
