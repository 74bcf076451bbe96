"""``imubounds simulate``: the paper's drive as a simulator directory for ``dynamic``."""

from __future__ import annotations

import argparse
import sys
from typing import Any

from imubounds.cli._common import add_force_option


def register(sub: Any) -> None:
    p = sub.add_parser(
        "simulate",
        help="simulate a drive (IMU, GPS, compass, truth) for 'imubounds dynamic'",
        description="Simulate the paper's experiment (closed 9.4 km / 792 s trip, MTx-grade IMU, "
        "GPS CEP 3 m at HDOP ~0.8, compass with hard-iron deviation) or a variant, and write a "
        "directory that 'imubounds dynamic DIR' reads: imu.csv, gps.csv, compass.csv, "
        "compass_cal.csv, truth.csv, scenario.json.",
    )
    p.add_argument("--scenario", choices=("paper",), default="paper", help="base scenario")
    p.add_argument("-o", "--out", required=True, metavar="DIR", help="output directory")
    add_force_option(p)
    p.add_argument("--seed", type=int, default=0, help="random seed (0)")
    p.add_argument("--rate", type=float, default=1.0, metavar="HZ", help="IMU rate (1 Hz)")
    p.add_argument("--gps-rate", type=float, metavar="HZ", help="GPS rate (1 Hz)")
    p.add_argument("--compass-rate", type=float, metavar="HZ", help="compass rate (1 Hz)")
    p.add_argument("--duration", type=float, default=792.0, metavar="S", help="trip length, s")
    p.add_argument("--distance", type=float, default=9400.0, metavar="M", help="trip length, m")
    p.add_argument("--laps", type=int, default=1, help="laps of the loop (more turns)")
    p.add_argument(
        "--corner-length",
        type=float,
        default=150.0,
        metavar="M",
        help="arc length of each 90-degree corner (shorter = sharper turns)",
    )
    p.add_argument("--noise-scale", type=float, default=1.0, help="multiply the IMU noise")
    p.add_argument("--gps-cep", type=float, default=3.0, metavar="M", help="GPS CEP (3 m)")
    p.add_argument("--hdop", type=float, default=0.8, help="mean HDOP (0.8)")
    p.add_argument(
        "--gps-outliers",
        type=float,
        default=0.0,
        metavar="FRACTION",
        help="share of GPS fixes with an outlier jump",
    )
    p.add_argument(
        "--outlier-size",
        type=float,
        default=40.0,
        metavar="M",
        help="size of an outlier jump (40 m)",
    )
    p.add_argument(
        "--compass-noise",
        type=float,
        default=0.3,
        metavar="DEG",
        help="compass noise standard deviation (0.3 deg)",
    )
    p.add_argument(
        "--truth-model",
        choices=("continuous", "paper", "full"),
        default="continuous",
        help="continuous trajectory, or truth following the estimator's discrete "
        "model of that mode exactly",
    )
    p.add_argument(
        "--bounded",
        action="store_true",
        help="draw every noise sample inside the bounds handed to the estimator",
    )
    p.add_argument("-q", "--quiet", action="store_true", help="no messages on stderr")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from imubounds.dynamic.scenario import ScenarioConfig, closure_error, simulate, write_scenario

    cfg = ScenarioConfig(
        scenario=args.scenario,
        seed=args.seed,
        duration_s=args.duration,
        distance_m=args.distance,
        rate_hz=args.rate,
        gps_rate_hz=args.gps_rate
        if args.gps_rate
        else args.rate
        if args.truth_model != "continuous"
        else 1.0,
        compass_rate_hz=args.compass_rate
        if args.compass_rate
        else args.rate
        if args.truth_model != "continuous"
        else 1.0,
        laps=args.laps,
        corner_length_m=args.corner_length,
        noise_scale=args.noise_scale,
        gps_cep_m=args.gps_cep,
        hdop_mean=args.hdop,
        gps_outlier_fraction=args.gps_outliers,
        gps_outlier_m=args.outlier_size,
        compass_noise_deg=args.compass_noise,
        truth_model=args.truth_model,
        bounded=args.bounded,
    )
    from imubounds.io.outputs import OutputSet

    with OutputSet(args.out, force=args.force) as outset:
        outset.check(["imu.csv", "gps.csv", "compass.csv", "truth.csv", "scenario.json"])
        sc = simulate(cfg)
        write_scenario(sc, outset.staging)
        outset.record(getattr(args, "argv", None), command_name="simulate")
    out = args.out
    if not args.quiet:
        tr = sc.truth
        print(
            f"simulated {cfg.scenario}: {sc.t.size} IMU samples at {cfg.rate_hz:g} Hz, "
            f"{sc.gps_t.size} GPS fixes, closure {closure_error(sc):.2e} m, max speed "
            f"{tr['u'].max():.1f} m/s -> {out}",
            file=sys.stderr,
        )
    return 0
