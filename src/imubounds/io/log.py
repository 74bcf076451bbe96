"""The in-memory log model shared by every reader and every analysis.

Readers convert whatever they read into an :class:`ImuLog`: SI units,
canonical channel names (``gyro_x`` ... ``accel_z``), a time vector in seconds
and a nominal sample rate. Frames are recorded so that later conversions are
explicit (``"FLU"`` body axes unless a reader knows better).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

IMU_CHANNELS: tuple[str, ...] = (
    "gyro_x",
    "gyro_y",
    "gyro_z",
    "accel_x",
    "accel_y",
    "accel_z",
)


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

    @property
    def n_samples(self) -> int:
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
