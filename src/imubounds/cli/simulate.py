"""``imubounds simulate``: a trip with ground truth, written in the generic drive layout."""

from __future__ import annotations

import argparse
from typing import Any

from imubounds.cli._common import (
    add_force_option,
    noise_json,
    nonneg_float,
    nonneg_int,
    positive_float,
    positive_int,
    probability,
)


def _fraction(text: str) -> float:
    """A number in [0, 1)."""
    x = nonneg_float(text)
    if not x < 1:
        raise argparse.ArgumentTypeError(f"must lie in [0, 1), got {text}")
    return x


def _fault(text: str) -> Any:
    from imubounds.dynamic.scenario import parse_fault
    from imubounds.errors import OptionError

    try:
        return parse_fault(text)
    except OptionError as err:
        raise argparse.ArgumentTypeError(str(err).replace(f"--fault {text!r}: ", "")) from None


def _aiding(text: str) -> tuple[str, ...]:
    from imubounds.dynamic.scenario import AIDING_STREAMS

    names = tuple(s.strip().lower() for s in text.split(",") if s.strip())
    if not names:
        raise argparse.ArgumentTypeError("give at least one stream, e.g. gnss,compass")
    for s in names:
        if s not in AIDING_STREAMS:
            raise argparse.ArgumentTypeError(
                f"unknown stream {s!r}; use any of {', '.join(AIDING_STREAMS)}"
            )
    return names


def register(sub: Any) -> None:
    from imubounds.dynamic.scenario import AIDING_STREAMS, DEFAULT_AIDING, VARIANTS

    variants = "; ".join(f"{k}: {v[1]}" for k, v in VARIANTS.items())
    p = sub.add_parser(
        "simulate",
        help="simulate a trip with ground truth (IMU, GNSS, compass, ...) in the drive layout",
        description="Simulate the paper's experiment (closed 9.4 km / 792 s trip, Xsens MTx-grade "
        "IMU at 100 Hz with turn-on bias, bias drift and white noise, GNSS CEP 3 m at HDOP ~0.8, "
        "compass with a one-cycle deviation) or a variant, with 3-D rigid-body truth, and write "
        "it in the generic drive layout: imu.csv, gnss.csv, velocity.csv, heading.csv, "
        "attitude.csv, truth.csv, drive.yaml (every bound the data were drawn against), "
        "compass_cal.csv and scenario.json (settings, seed, every true error term, and the "
        "record of inputs that fell outside their stated bounds). Variants: " + variants + ".",
    )
    p.add_argument("--scenario", choices=("paper",), default="paper", help="base scenario")
    p.add_argument(
        "--variant", choices=tuple(VARIANTS), default="paper", help="variant (default paper)"
    )
    p.add_argument("-o", "--out", required=True, metavar="DIR", help="output directory")
    add_force_option(p)
    p.add_argument("--seed", type=nonneg_int, default=0, help="random seed (0)")
    g = p.add_argument_group("trip")
    g.add_argument("--duration", type=positive_float, metavar="S", help="trip length, s (792)")
    g.add_argument(
        "--distance", type=positive_float, metavar="M", help="horizontal path length, m (9400)"
    )
    g.add_argument("--laps", type=positive_int, help="laps of the loop (1; more turns)")
    g.add_argument(
        "--corner-length",
        type=positive_float,
        metavar="M",
        help="arc length of each right-angle corner (150 m; shorter = sharper, the vehicle slows)",
    )
    g.add_argument(
        "--hill-amplitude", type=nonneg_float, metavar="M", help="hills: altitude amplitude (0)"
    )
    g = p.add_argument_group("sensors")
    g.add_argument(
        "--aiding",
        type=_aiding,
        metavar="LIST",
        help=f"aiding streams, comma-separated from {','.join(AIDING_STREAMS)} "
        f"(default {','.join(DEFAULT_AIDING)}, or the variant's)",
    )
    g.add_argument("--rate", type=positive_float, metavar="HZ", help="IMU rate (100 Hz)")
    g.add_argument("--gps-rate", type=positive_float, metavar="HZ", help="GNSS rate (1 Hz)")
    g.add_argument(
        "--compass-rate", type=positive_float, metavar="HZ", help="compass/magnetometer rate (1 Hz)"
    )
    g.add_argument(
        "--velocity-rate", type=positive_float, metavar="HZ", help="DVL/wheel rate (10 Hz)"
    )
    g.add_argument("--attitude-rate", type=positive_float, metavar="HZ", help="attitude (10 Hz)")
    g.add_argument(
        "--truth-rate", type=positive_float, metavar="HZ", help="rows of truth.csv (10 Hz)"
    )
    g.add_argument("--imu-preset", metavar="NAME", help="IMU datasheet preset (mtx)")
    g.add_argument(
        "--imu-noise",
        type=noise_json,
        metavar="NOISE_JSON",
        help="the IMU's noise per axis from a noise.json of 'imubounds static' (N, B as "
        "flicker, K, and Q/R where the fit resolved them; as simulate-noise --from-noise) "
        "instead of a preset; drive.yaml names it (copied beside as imu_noise.json)",
    )
    g.add_argument(
        "--noise-scale",
        type=nonneg_float,
        help="multiply the IMU noise and biases (1; 0: noiseless IMU)",
    )
    g.add_argument(
        "--no-bias",
        action="store_true",
        help="IMU without turn-on bias and bias drift (white noise only)",
    )
    g.add_argument(
        "--scale-error",
        type=nonneg_float,
        metavar="FRACTION",
        help="1-sigma scale-factor error per IMU channel (0)",
    )
    g.add_argument(
        "--misalignment", type=nonneg_float, metavar="DEG", help="1-sigma misalignment (0)"
    )
    g.add_argument(
        "--fault",
        type=_fault,
        action="append",
        metavar="CH:KIND=VALUE[@T0]",
        help="inject an IMU fault from T0 s: CHANNEL:bias=VALUE (m/s^2 or rad/s) or "
        "CHANNEL:scale=VALUE (fraction); repeatable, e.g. accel_x:bias=0.3@396",
    )
    g.add_argument("--gps-cep", type=positive_float, metavar="M", help="GNSS CEP (3 m)")
    g.add_argument("--hdop", type=positive_float, help="mean HDOP (0.8)")
    g.add_argument(
        "--gps-vel-sigma",
        type=nonneg_float,
        metavar="MPS",
        help="GNSS velocity 1-sigma per component (0.1 m/s)",
    )
    g.add_argument(
        "--gps-outliers",
        type=_fraction,
        metavar="FRACTION",
        help="share of GNSS fixes with a gross outlier, in [0, 1) (0)",
    )
    g.add_argument(
        "--outlier-size", type=positive_float, metavar="M", help="size of an outlier jump (40 m)"
    )
    g.add_argument(
        "--compass-noise",
        type=nonneg_float,
        metavar="DEG",
        help="compass noise standard deviation (0.3 deg)",
    )
    g.add_argument(
        "--attitude-sigma",
        type=nonneg_float,
        metavar="DEG",
        help="roll/pitch (AHRS) error standard deviation (0.1 deg)",
    )
    g.add_argument(
        "--dvl-sigma",
        type=nonneg_float,
        metavar="MPS",
        help="DVL velocity error standard deviation per axis (0.02 m/s)",
    )
    g.add_argument(
        "--wheel-sigma",
        type=nonneg_float,
        metavar="MPS",
        help="wheel-speed error standard deviation (0.05 m/s)",
    )
    g.add_argument(
        "--alpha",
        type=probability,
        help="whole-trip risk of every stated bound, per stream (0.01)",
    )
    g.add_argument(
        "--bounded",
        action="store_true",
        help="draw every error inside its stated bound (the record is then clean "
        "unless there are outliers or faults)",
    )
    g.add_argument(
        "--attitude-yaw",
        type=nonneg_float,
        metavar="DEG",
        help="the attitude stream carries an AHRS yaw with this error sigma (0: none)",
    )
    g.add_argument(
        "--velocity-lag",
        type=nonneg_float,
        metavar="S",
        help="the wheel/DVL stamps are this late, not stated in drive.yaml (0 s)",
    )
    g.add_argument(
        "--imu-axes",
        type=_axes,
        metavar="AX,AX,AX",
        help="the IMU's mount, as drive.yaml imu_axes (the sensor axis along body x, y, z, "
        "e.g. x,-z,y: on its side); imu.csv is written in the sensor's axes (x,y,z)",
    )
    g.add_argument(
        "--vehicle-kind",
        choices=("ground", "air", "marine"),
        help="vehicle.kind in drive.yaml (ground)",
    )
    p.add_argument("-q", "--quiet", action="store_true", help="print no summary")
    p.set_defaults(func=run)


def _axes(text: str) -> tuple[str, ...]:
    parts = tuple(x.strip() for x in text.split(",") if x.strip())
    if len(parts) != 3:
        raise argparse.ArgumentTypeError(f"{text!r}: give three axes, e.g. x,-z,y")
    return parts


_OPTIONS = {
    "duration": "duration_s",
    "distance": "distance_m",
    "laps": "laps",
    "corner_length": "corner_length_m",
    "hill_amplitude": "hill_amplitude_m",
    "aiding": "aiding",
    "rate": "rate_hz",
    "gps_rate": "gps_rate_hz",
    "compass_rate": "compass_rate_hz",
    "velocity_rate": "velocity_rate_hz",
    "attitude_rate": "attitude_rate_hz",
    "truth_rate": "truth_rate_hz",
    "imu_preset": "imu_preset",
    "imu_noise": "imu_noise",
    "noise_scale": "noise_scale",
    "scale_error": "scale_error",
    "misalignment": "misalignment_deg",
    "gps_cep": "gps_cep_m",
    "hdop": "hdop_mean",
    "gps_vel_sigma": "gps_vel_sigma_mps",
    "gps_outliers": "gps_outlier_fraction",
    "outlier_size": "gps_outlier_m",
    "compass_noise": "compass_noise_deg",
    "attitude_sigma": "attitude_sigma_deg",
    "dvl_sigma": "dvl_sigma_mps",
    "wheel_sigma": "wheel_sigma_mps",
    "velocity_lag": "velocity_lag_s",
    "attitude_yaw": "attitude_yaw_sigma_deg",
    "imu_axes": "imu_axes",
    "vehicle_kind": "vehicle_kind",
    "alpha": "alpha",
}


def config_from_args(args: argparse.Namespace) -> Any:
    """The :class:`ScenarioConfig` the options describe (variant first, then each option)."""
    from imubounds.dynamic.scenario import ScenarioConfig

    kw: dict[str, Any] = {
        field: getattr(args, opt)
        for opt, field in _OPTIONS.items()
        if getattr(args, opt, None) is not None
    }
    if args.imu_noise and args.imu_preset:
        from imubounds.errors import OptionError

        raise OptionError("give --imu-preset or --imu-noise, not both")
    if args.no_bias:
        kw["imu_bias"] = False
    if args.bounded:
        kw["bounded"] = True
    if args.fault:
        kw["faults"] = tuple(args.fault)
    kw["scenario"] = args.scenario
    kw["seed"] = args.seed
    return ScenarioConfig.for_variant(args.variant, **kw)


def run(args: argparse.Namespace) -> int:
    from imubounds.cli._common import Reporter
    from imubounds.dynamic.scenario import OUTPUT_FILES, simulate, write_scenario
    from imubounds.io.outputs import OutputSet

    cfg = config_from_args(args)
    cfg.check()
    inputs = [x for x in (args.imu_noise,) if x]
    with OutputSet(args.out, force=args.force, command="simulate", inputs=inputs) as outset, \
            Reporter(args.quiet).steps("imubounds simulate", 2) as steps:  # fmt: skip
        outset.check(OUTPUT_FILES)
        steps.step(f"simulating the {cfg.variant} trip")
        res = simulate(cfg)
        steps.step("writing the drive")
        write_scenario(res, outset.staging)
        _check_written_settings(outset.staging)
        outset.record(getattr(args, "argv", None), command_name="simulate")
    if not args.quiet:
        d = res.drive
        assert d.imu is not None
        print(
            f"simulated {cfg.variant} (seed {cfg.seed}): {d.imu.t.size} IMU samples at "
            f"{cfg.rate_hz:g} Hz, streams {', '.join(d.streams())}; closure "
            f"{res.closure_error_m():.2e} m, max speed {res.truth['speed'].max():.1f} m/s -> "
            f"{args.out}"
        )
        fig = res.imu_errors.figures
        if cfg.imu_noise is not None:
            print(
                f"IMU noise: {fig.source}; {len(fig.notes)} note(s) on what was simulated "
                "(terms given only as upper bounds) in scenario.json: "
                "true_values.imu.figures.noise_notes"
            )
        print(res.record.summary())
    return 0


#: drive.yaml settings the simulator writes from an option (a bound from its sigma)
_SETTING_OPTIONS = {
    "imu.misalignment_deg": "--misalignment",
    "imu.scale_factor": "--scale-error",
    "heading.noise_deg": "--compass-noise",
    "attitude.bound_deg": "--attitude-sigma",
}


def _check_written_settings(staging: Any) -> None:
    """The drive.yaml the simulator wrote must be one its reader takes: a setting out of
    its range (a bound made of ``--misalignment 100``'s sigma) is an :class:`OptionError`
    naming the option, and nothing is written."""
    from imubounds.errors import InputError, OptionError
    from imubounds.io.drive.settings import read_settings

    try:
        read_settings(staging)
    except InputError as err:
        text = str(err)
        opt = next((o for k, o in _SETTING_OPTIONS.items() if k in text), None)
        what = text.split(": ", 1)[-1]
        raise OptionError(
            f"{opt + ': ' if opt else ''}the drive.yaml it makes would be refused by "
            f"every reader ({what}); give a smaller value"
        ) from None
