"""The curated Python API: numpy arrays, pandas tables and files in, result objects out.

Every function here is re-exported by :mod:`imubounds` (``imubounds.allan``, ...),
which is the place to import them from. Arrays are in SI (rad/s for gyros, m/s^2
for accelerometers, s for times, Hz for rates) and every result says its units;
results convert with ``.to_dict()`` (what the command line writes to JSON),
``.to_frame()`` (a :class:`pandas.DataFrame` with the units in the column names or
a ``unit`` column) and ``.plot(ax=None)`` (a :class:`matplotlib.figure.Figure`,
made without pyplot). Bad input raises the errors of :mod:`imubounds.errors`
(subclasses of :class:`ValueError`) with a one-line message; nothing prints.

Stationary (a static log)::

    log = read_log(path)                       # ImuLog (SI)
    curve = allan(log.channels["gyro_z"], log.rate_hz, unit="rad/s")
    terms = noise_terms(curve)                 # Selection: Q, N, B, K, R with status
    result = characterize(log)                 # StaticResult == noise.json

Dynamic (a drive with aiding sensors)::

    drive = read_drive(path)                   # Drive (SI, body frame FLU)
    margins = dynamic_margins(drive, noise=result)   # DynamicResult == dynamic.json

A filter's IMU noise file (Kalibr, OpenVINS, VINS, GTSAM, ROS)::

    text = export_noise(result, "kalibr")      # imu.yaml text (units in comments)
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Mapping, Sequence
from os import PathLike
from pathlib import Path
from typing import TYPE_CHECKING, Any, Literal

from imubounds.errors import InputError, OptionError

if TYPE_CHECKING:
    import numpy as np
    import pandas as pd
    from numpy.typing import ArrayLike

    from imubounds.dynamic.scenario import SimResult
    from imubounds.io.log import ImuLog
    from imubounds.stationary.allan import AllanResult
    from imubounds.stationary.pipeline import StaticResult
    from imubounds.stationary.terms import Selection

__all__ = [
    "SI_SIGNAL_UNITS",
    "allan",
    "characterize",
    "export_noise",
    "noise_terms",
    "read_log",
    "simulate_trip",
]

#: The unit of each sensor's samples inside imubounds, and the unit an Allan
#: curve of its signal is in.
SI_SIGNAL_UNITS: dict[str, str] = {"gyro": "rad/s", "accel": "m/s^2"}

OnGap = Literal["refuse", "split", "ignore"]
PathType = str | PathLike[str]


def read_log(
    path: PathType,
    *,
    rate_hz: float | None = None,
    columns: Mapping[str, str] | None = None,
    gyro_unit: str | None = None,
    accel_unit: str | None = None,
    time_unit: str | None = None,
    on_gap: OnGap = "refuse",
    gap_tolerance: float | None = None,
    channels: Iterable[str] | None = None,
    topic: str | None = None,
    dataset: str | None = None,
    unusual_rate: bool = False,
) -> ImuLog:
    """Read a static IMU log file into an :class:`~imubounds.io.log.ImuLog` in SI.

    The reader of ``imubounds static`` (:func:`imubounds.io.read_imu`): CSV (plain
    or ``.gz``), Parquet, HDF5, ROS 1/2 bags and MCAP, PX4 ULog, NMEA ``$VNYMR``.
    Columns are recognised by name (``time_s``, ``gyro_x_dps``, ``accel_z_g``, ...;
    see the file-formats page) and converted to rad/s and m/s^2.

    Parameters
    ----------
    path : str or os.PathLike
        The log file (or a ROS 2 bag directory).
    rate_hz : float, optional
        Sample rate in Hz; required when the file has no time column.
    columns : mapping, optional
        ``{canonical: source_column}`` for unrecognised names, e.g.
        ``{"gyro_x": "wx", "time": "stamp"}``.
    gyro_unit, accel_unit, time_unit : str, optional
        Unit overrides (``"deg/s"``, ``"g"``, ``"ms"``, ...) for names without one.
    on_gap : {"refuse", "split", "ignore"}
        A gap in the time stamps raises (default), keeps the longest segment, or is
        kept with a warning.
    gap_tolerance : float, optional
        A step longer than this multiple of the period is a gap (default automatic).
    channels : iterable of str, optional
        Only these canonical channels (``gyro_x`` ... ``accel_z``).
    topic : str, optional
        ROS bag or ULog topic.
    dataset : str, optional
        HDF5 path of the IMU table.
    unusual_rate : bool
        Accept a sample rate outside 0.5 Hz..100 kHz (a time column in ms or us
        labelled s is refused without it; ``--allow-unusual-rate``).

    Returns
    -------
    ImuLog
        Samples in SI, time in s, nominal rate in Hz; what the reader noticed is in
        ``ImuLog.warnings``.

    Raises
    ------
    InputError
        The file cannot be used as given (the message names the file, row and column).
    OptionError
        An invalid option.
    """
    from imubounds.io.registry import read_imu

    if not isinstance(path, str | PathLike):
        raise InputError(f"read_log takes a file path (str or Path), got {type(path).__name__}")
    fmt = {k: v for k, v in (("topic", topic), ("dataset", dataset)) if v is not None}
    return read_imu(
        Path(path),
        rate_hz=rate_hz,
        columns=columns,
        gyro_unit=gyro_unit,
        accel_unit=accel_unit,
        time_unit=time_unit,
        gap_tolerance=gap_tolerance,
        on_gap=on_gap,
        channels=channels,
        format_options=fmt,
        unusual_rate=unusual_rate,
    )


def _rate(rate_hz: float | None, rate: float | None) -> float:
    """The one sample rate given (checked by the estimator)."""
    if rate_hz is not None and rate is not None and rate_hz != rate:
        raise OptionError(f"give the sample rate once: rate_hz={rate_hz!r} and rate={rate!r}")
    value = rate_hz if rate_hz is not None else rate
    if value is None:
        raise OptionError("the sample rate is needed: pass rate_hz= (Hz)")
    return value


def allan(
    x: ArrayLike | pd.Series,
    rate_hz: float | None = None,
    *,
    rate: float | None = None,
    estimator: str = "overlapping",
    taus: str | int | Sequence[float] | np.ndarray = "points:40",
    confidence: float = 0.683,
    noise: str | int = "auto",
    robust: bool = False,
    unit: str | None = None,
    name: str | None = None,
) -> AllanResult:
    """Allan-family deviation of one rate signal, with chi-squared confidence intervals.

    Parameters
    ----------
    x : array_like or pandas.Series, shape (N,)
        Rate samples in SI (gyro rad/s, accelerometer m/s^2), finite, evenly spaced.
    rate_hz : float
        Sample rate in Hz (``rate=`` is accepted as another name).
    estimator : str
        ``"overlapping"`` (default), ``"non-overlapping"``, ``"modified"``,
        ``"hadamard"``, ``"non-overlapping-hadamard"`` or ``"total"``.
    taus : str, int or sequence of float
        ``"points:40"`` (default: 40 log-spaced points, the grid of :func:`characterize`
        and ``imubounds static``), ``"octave"``, ``"decade"``, ``"all"``, ``"points:K"``
        or a number K of log-spaced points, or averaging times in s.
    confidence : float
        Two-sided level of the intervals, in (0, 1); 0.683 = 1 sigma.
    noise : "auto", int or str
        Power-law exponent alpha behind the degrees of freedom: identified per τ
        (``"auto"``) or forced (``0`` or ``"white_fm"``, ...).
    robust : bool
        Outlier-resistant curve (spikes interpolated, clipped mean of the squares).
    unit : {"rad/s", "m/s^2"}, optional
        Unit of ``x``, recorded in the result (and so in the units of
        :func:`noise_terms`).
    name : str, optional
        Name of the signal in error messages (default: the Series name).

    Returns
    -------
    AllanResult
        ``tau`` (s), ``dev``, ``ci_lower``, ``ci_upper`` (unit of ``x``), ``edf``,
        ``alpha`` per τ; ``.to_frame()``, ``.to_dict()``, ``.plot()``.

    Raises
    ------
    InputError
        ``x`` is not a 1-D array of finite numbers, or is too short.
    OptionError
        An unknown estimator, a bad τ grid, rate or confidence.
    """
    import dataclasses

    import pandas as pd

    from imubounds.stationary.allan import allan as _allan

    if unit is not None and unit not in SI_SIGNAL_UNITS.values():
        raise OptionError(
            f"unit {unit!r}: imubounds works in SI, 'rad/s' for a gyro or 'm/s^2' for an "
            "accelerometer; convert the samples first"
        )
    if isinstance(x, pd.DataFrame):
        raise InputError(
            "allan takes one signal (an array or a Series); for a table of channels use "
            "imubounds.characterize or pass one column"
        )
    label = name or (str(x.name) if isinstance(x, pd.Series) and x.name is not None else "signal")
    values = x.to_numpy() if isinstance(x, pd.Series) else x
    res = _allan(
        values,  # type: ignore[arg-type]  # checked (1-D, finite numbers) by the estimator
        _rate(rate_hz, rate),
        taus,
        estimator,
        confidence,
        noise,
        name=label,
        robust=robust,
    )
    return dataclasses.replace(res, unit=unit) if unit is not None else res


def noise_terms(
    curve: AllanResult,
    *,
    sensor: Literal["gyro", "accel"] | None = None,
    prefer: Literal["fit", "slope"] = "fit",
) -> Selection:
    """The noise terms Q, N, B, K, R of an Allan curve, as ``imubounds static`` selects them.

    A robust weighted fit of the five terms and the IEEE 952 slope read-off are
    made; each term is taken from the ``prefer`` estimate where it is resolved,
    else from the other, else it is an upper bound from the curve's confidence
    intervals (never 0). The same numbers as ``noise.selected`` in noise.json.

    Parameters
    ----------
    curve : AllanResult
        From :func:`allan` (or ``StaticResult.channels[name].allan``).
    sensor : {"gyro", "accel"}, optional
        Which sensor the curve is of (gives the units); default from ``curve.unit``.
    prefer : {"fit", "slope"}
        The estimate preferred where both resolve a term.

    Returns
    -------
    Selection
        ``terms["N"].value`` (SI), ``.status`` (``resolved``, ``upper_bound``,
        ``not_observed``), ``.ci``; ``sigma_min``; ``fit`` and ``slope`` (the two
        estimates); ``.to_frame()``, ``.to_dict()``, ``.plot()``.

    Raises
    ------
    OptionError
        The sensor is unknown or contradicts ``curve.unit``; ``prefer`` is invalid.
    AnalysisError
        The curve has too few points to fit.
    """
    import dataclasses

    from imubounds.stationary.allan import AllanResult as _AllanResult
    from imubounds.stationary.terms import analyse_curve

    if not isinstance(curve, _AllanResult):
        raise InputError(
            f"noise_terms takes an AllanResult (from imubounds.allan), got {type(curve).__name__}"
        )
    if sensor is not None and sensor not in SI_SIGNAL_UNITS:
        raise OptionError(f"sensor must be 'gyro' or 'accel', got {sensor!r}")
    from_unit = next((k for k, u in SI_SIGNAL_UNITS.items() if u == curve.unit), None)
    if sensor is None:
        if from_unit is None:
            raise OptionError(
                "which sensor is this curve of? pass sensor='gyro' or 'accel' (or "
                "unit='rad/s' / 'm/s^2' to imubounds.allan); the units of the terms depend "
                "on it"
            )
        sensor = from_unit  # type: ignore[assignment]
    elif from_unit is not None and from_unit != sensor:
        raise OptionError(
            f"sensor={sensor!r} but the curve is in {curve.unit}, the unit of a {from_unit}"
        )
    if prefer not in ("fit", "slope"):
        raise OptionError(f"prefer must be 'fit' or 'slope', got {prefer!r}")
    fit, slope, sel = analyse_curve(curve, prefer=prefer, confidence=curve.confidence)
    return dataclasses.replace(
        sel,
        kind=sensor,
        fit=dataclasses.replace(fit, kind=sensor),
        slope=dataclasses.replace(slope, kind=sensor),
    )


def _named_array(data: Any, channels: Sequence[str] | None) -> dict[str, Any]:
    """A numpy array in SI as named columns: 1-D is one channel, 2-D one per column."""
    import numpy as np

    from imubounds.io.log import IMU_CHANNELS, SI_SUFFIX

    arr = np.asarray(data)
    if arr.ndim == 1:
        arr = arr[:, None]
    if arr.ndim != 2:
        raise InputError(f"expected a 1-D or 2-D array of samples, got shape {arr.shape}")
    if channels is None:
        if arr.shape[1] != len(IMU_CHANNELS):
            raise InputError(
                "name the channels of an array: characterize(x, rate_hz=..., channels=["
                f"'gyro_z', ...]) (one name per column, from {', '.join(IMU_CHANNELS)}); "
                f"this one has {arr.shape[1]} column(s)"
            )
        channels = IMU_CHANNELS
    names = list(channels)
    bad = [c for c in names if c not in IMU_CHANNELS]
    if bad or len(set(names)) != len(names):
        raise OptionError(
            f"channels {names!r}: give distinct names from {', '.join(IMU_CHANNELS)}"
        )
    if len(names) != arr.shape[1]:
        raise InputError(
            f"{len(names)} channel name(s) for an array of {arr.shape[1]} column(s)"
        )
    return {f"{c}_{SI_SUFFIX[c.split('_')[0]]}": arr[:, i] for i, c in enumerate(names)}


def characterize(
    data: ImuLog | pd.DataFrame | Mapping[str, ArrayLike] | np.ndarray | PathType,
    rate_hz: float | None = None,
    *,
    taus: str | int | Sequence[float] = "points:40",
    estimator: str = "overlapping",
    confidence: float = 0.683,
    k_sigma: float = 3.0,
    averaging_time_s: float | None = None,
    run_hours: float | None = None,
    terms_from: Literal["fit", "slope"] = "fit",
    models: Sequence[str] = ("gm", "ar"),
    robust: bool = False,
    spike_threshold: float = 8.0,
    ar_max_order: int = 20,
    channels: Sequence[str] | None = None,
    gyro_unit: str | None = None,
    accel_unit: str | None = None,
    progress: Callable[[str, int, int], None] | None = None,
) -> StaticResult:
    """The whole stationary characterisation of ``imubounds static``, in memory.

    Spike check, Allan curve per channel, noise terms (fit, read-off, selection),
    Gauss-Markov and AR models checked against the curve, the per-sample bound
    ``k·σ_c`` and the 95 % random-walk growth. The defaults are those of the
    command line, so ``characterize(read_log(p)).to_dict()`` is the noise.json of
    ``imubounds static p`` (up to the version and nothing else).

    Parameters
    ----------
    data : ImuLog, pandas.DataFrame, dict of arrays, numpy array, or a path
        A log from :func:`read_log`; a table read by :func:`read_frame` (columns
        named ``gyro_x_rads``, ``accel_z_g``, ... plus ``time_s`` or ``rate_hz``);
        a numpy array in SI (rad/s, m/s^2) with ``rate_hz``, its columns named by
        ``channels`` (six columns default to ``gyro_x`` ... ``accel_z``); or a file
        path read by :func:`read_log`.
    rate_hz : float, optional
        Sample rate of a table without a time column (or of a file without one).
    taus, estimator, confidence
        The Allan curve (see :func:`allan`); the τ grid defaults to 40 log-spaced points
        (``"points:40"``, as ``imubounds static`` and :func:`allan`).
    k_sigma : float
        The k of the per-sample bound ``k·σ_c``.
    averaging_time_s : float, optional
        The t of σ_c in s (default: the log length).
    run_hours : float, optional
        The T of the random-walk growth in hours (default: the log length).
    terms_from : {"fit", "slope"}
        The estimate preferred for the selected terms.
    models : sequence of {"gm", "ar"}
        Stochastic models to fit (``()`` for none).
    robust : bool
        Outlier-resistant Allan curves (the plain ones are kept beside them).
    spike_threshold : float
        Robust z above which a sample is a spike.
    ar_max_order : int
        Largest AR order tried.
    channels : sequence of str, optional
        Only these channels; for a numpy array, the channel of each column.
    gyro_unit, accel_unit : str, optional
        Units of a table's columns whose names do not say (``"deg/s"``, ``"g"``).
    progress : callable(stage, done, total), optional
        Called as the work advances (the library never prints).

    Returns
    -------
    StaticResult
        ``.channels[name]`` per channel; ``.to_dict()`` (= noise.json),
        ``.to_frame()`` (selected terms), ``.plot()`` (the Allan figure),
        ``.kalibr_yaml()`` (= imu.yaml).

    Raises
    ------
    InputError
        Data that cannot be used (see :func:`read_frame`), a bare array without
        channel names.
    OptionError
        Invalid settings.
    AnalysisError
        No gyro or accelerometer channel, or a log too short for the analysis.
    """
    import pandas as pd

    from imubounds.io.log import ImuLog as _ImuLog
    from imubounds.stationary.pipeline import StaticSettings, analyse_static

    known = ("gm", "ar")
    bad = [m for m in models if m not in known]
    if isinstance(models, str) or bad:
        raise OptionError(f"models: give a sequence of {', '.join(known)}, got {models!r}")
    from imubounds.io.table import read_frame

    if isinstance(data, _ImuLog):
        if gyro_unit is not None or accel_unit is not None:
            raise OptionError("an ImuLog is already in SI: gyro_unit/accel_unit do not apply")
        log = data
    elif isinstance(data, pd.DataFrame | Mapping):
        log = read_frame(data, rate_hz=rate_hz, gyro_unit=gyro_unit, accel_unit=accel_unit)
    elif isinstance(data, str | PathLike):
        log = read_log(data, rate_hz=rate_hz, gyro_unit=gyro_unit, accel_unit=accel_unit)
    elif type(data).__module__ == "numpy" and hasattr(data, "ndim"):
        if gyro_unit is not None or accel_unit is not None:
            raise OptionError("an array is taken in SI (rad/s, m/s^2): convert it first")
        log = read_frame(_named_array(data, channels), rate_hz=rate_hz, source="<array>")
        channels = None
    else:
        raise InputError(
            f"characterize takes an ImuLog, a DataFrame, a dict of named columns, a numpy "
            f"array or a path, got {type(data).__name__}"
        )
    if isinstance(data, _ImuLog) and rate_hz is not None and rate_hz != log.rate_hz:
        raise OptionError(f"rate_hz={rate_hz!r} contradicts the log's {log.rate_hz:g} Hz")
    settings = StaticSettings(
        taus=taus,
        estimator=estimator,
        confidence=confidence,
        k_sigma=k_sigma,
        averaging_time_s=averaging_time_s,
        run_hours=run_hours,
        terms_from=terms_from,
        models=tuple(models),
        robust=robust,
        spike_threshold=spike_threshold,
        ar_max_order=ar_max_order,
    )
    return analyse_static(log, settings, channels=channels, progress=progress)


def simulate_trip(
    variant: str = "paper",
    seed: int = 0,
    *,
    imu_noise: PathType | None = None,
    **overrides: Any,
) -> SimResult:
    """Simulate a drive with ground truth (the trips of ``imubounds simulate``).

    Parameters
    ----------
    variant : str
        A named scenario of :data:`imubounds.dynamic.scenario.VARIANTS` (``"paper"``:
        the paper's 9.4 km / 792 s trip with an MTx-grade IMU, GPS and compass).
    seed : int
        Random seed (the same seed gives the same trip).
    imu_noise : path, optional
        A noise.json of :func:`characterize` / ``imubounds static``: the trip's IMU gets
        that noise per axis (N, B as flicker, K, and Q/R where the fit resolved them), as
        ``imubounds simulate --imu-noise``; the drive's settings name the file, so that
        :func:`imubounds.dynamic_margins` bounds with it. Default: the ``imu_preset``.
    **overrides
        Any field of :class:`imubounds.dynamic.scenario.ScenarioConfig`.

    Returns
    -------
    SimResult
        ``.drive`` (a :class:`~imubounds.io.drive.Drive` with ``truth``) for
        :func:`imubounds.dynamic_margins`, and ``.record`` (inputs outside their bounds).
    """
    import numpy as np

    from imubounds.dynamic.scenario import make_trip

    if not isinstance(variant, str):
        raise OptionError(f"variant must be a scenario name (text), got {variant!r}")
    if isinstance(seed, bool) or not isinstance(seed, int | np.integer) or seed < 0:
        raise OptionError(f"seed must be a whole number >= 0, got {seed!r}")
    if imu_noise is not None:
        overrides["imu_noise"] = str(imu_noise)
    return make_trip(variant, seed=int(seed), **overrides)


def export_noise(
    results: StaticResult | Mapping[str, Any] | PathType,
    format: Literal["kalibr", "openvins", "vins", "gtsam", "ros"] = "kalibr",
    *,
    motion: Mapping[str, Any] | PathType | None = None,
) -> str:
    """The text of a filter's IMU noise file from the noise terms (``imubounds export``).

    Parameters
    ----------
    results : StaticResult, mapping or path
        A result of :func:`characterize`, a loaded noise.json, its path, or an
        ``imubounds static`` output folder.
    format : {"kalibr", "openvins", "vins", "gtsam", "ros"}
        ``kalibr``: imu.yaml (continuous-time densities, the worst axis);
        ``openvins``: kalibr_imu_chain.yaml; ``vins``: ``acc_n``, ``gyr_n`` (per-sample
        sigma = N*sqrt(rate)) and ``acc_w``, ``gyr_w`` (K*sqrt(rate)); ``gtsam``:
        PreintegrationCombinedParams covariances (N^2, K^2 per axis); ``ros``:
        sensor_msgs/Imu covariances (N^2 * rate per axis).
    motion : mapping or path, optional
        ``motion.json`` or an ``imubounds dynamic`` output folder (mode full): N and K
        multiplied by each channel's in-motion factor F.

    Returns
    -------
    str
        YAML text; each number's unit and conversion is in a comment beside it.

    Raises
    ------
    OptionError
        An unknown format.
    InputError
        The results cannot give the format's numbers (the message names the key).
    """
    from imubounds.export import export_noise as _export

    return _export(results, format, motion=motion)
