"""Roll and pitch as interval states of mode full, from the accelerometers against the
aiding and the gyros between (docs/dynamic-method.md, section 3b).

* :mod:`.gravity` -- vector matching over each accelerometer window (3b.1)-(3b.2);
* :mod:`.gyro_terms` -- the gyros' increments and their error bounds (3b.4);
* :mod:`.kernels` -- the compiled window sums and node chain (3b.3)-(3b.6);
* :mod:`.solve` -- one angle over the trip: window nodes, chain, pieces (3b.5)-(3b.7);
* :mod:`.states` -- both angles, twice, per independence variant;
* :mod:`.consumers` -- the tilt functions, the smoother's spans and the window ends
  that read them;
* :mod:`.rates` -- gyro_x and gyro_y from the accelerometers' window pairs (3b.8);
* :mod:`.changes` -- the accelerometers' change test with the tilt change from the
  gyros (3b.9);
* :mod:`.mount` -- the IMU's pitch against its path (mount) from the states and GNSS
  altitude;
* :mod:`.report` -- the summary, the checks and the truth comparison.
"""

from __future__ import annotations

from typing import Any

#: the events (``imu_intervals`` family) per window and angle: the white noise of the
#: main gyro and of gyro_z from the node to each side by the reflection principle (2
#: each), and the deviation of the magnitude sums on each side (1 each)
EVENTS_PER_WINDOW = 10
#: per link: the white noise of gyro_x, gyro_y and gyro_z over the link (reflection
#: principle, 2 each) and the magnitudes' deviation of each angle (1 each)
EVENTS_PER_LINK = 8


def applicable(opts: Any, available: dict[str, bool]) -> bool:
    """Whether the attitude states run, from the settings alone (before the alpha plan,
    so that their events are counted whatever the data): every gyro and accel_x,
    accel_y available, and not turned off (``attitude_states=False``)."""
    if not getattr(opts, "attitude_states", True):
        return False
    return all(available.get(ch, False)
               for ch in ("accel_x", "accel_y", "gyro_x", "gyro_y", "gyro_z"))


def interval_events(n_epochs: int) -> int:
    """An upper bound of the events the states add to ``imu_intervals``: the windows of
    accel_x's and accel_y's plans of at least ``gravity.MIN_PERIODS`` aiding periods
    (windows every half their length over octave levels: at most ``n_epochs`` per
    angle), every link between the epochs and the change pairs of :mod:`.changes`."""
    n = max(int(n_epochs), 1)
    # + the change pairs of accel_x and accel_y (attitude/changes.py: at most one per epoch
    # and channel over the levels, plus one per level)
    pairs = 2 * (n + 64)
    return EVENTS_PER_WINDOW * (2 * n + pairs) + EVENTS_PER_LINK * (n - 1)


def rests_on(ctx: Any) -> dict[str, tuple[str, ...]]:
    """The channels whose margins rest on another channel's budget through the states
    (docs/dynamic-method.md section 3b, design decision (b)): gyro_x and gyro_y judged
    from an accelerometer's window pairs (3b.8) rest on that accelerometer; accel_z reads
    the full variant's roll and pitch, built from accel_x's and accel_y's windows.
    Empty without the states."""
    if getattr(ctx, "attitude", None) is None:
        return {}
    out: dict[str, tuple[str, ...]] = {"accel_z": ("accel_x", "accel_y")}
    for ch in ("gyro_x", "gyro_y"):
        acc = getattr(ctx.plans.get(ch), "accel", "") if ch in ctx.plans else ""
        if acc:
            out[ch] = (str(acc),)
    return out
