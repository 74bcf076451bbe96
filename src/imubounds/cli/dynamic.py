"""``imubounds dynamic LOG...``: dynamic error margins from a drive log (METHOD.md 3)."""

from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path
from typing import Any

from imubounds.cli._common import add_force_option
from imubounds.errors import InputError, OptionError


def register(sub: Any) -> None:
    p = sub.add_parser(
        "dynamic",
        help="interval INS/GPS/compass estimator: dynamic error margins of the IMU",
        description="Estimate guaranteed intervals of the forward/lateral acceleration and turn "
        "rate from IMU + GPS + compass (forward-backward interval contractor), the dynamic "
        "error margins of the IMU, and compare them with the stationary 95 %% level. Runs both "
        "kinematic modes (paper, full); writes dynamic.json, steps.csv and figures into -o DIR. "
        "LOG is a 'imubounds simulate' directory, a VN-100 directory (or its *_imu.csv and "
        "*_gps.csv), or a comma2k19 segment directory.",
    )
    p.add_argument("log", nargs="+", help="drive log directory or the two VN-100 CSV files")
    p.add_argument("-o", "--out", default="out", metavar="DIR", help="output directory")
    add_force_option(p)
    src = p.add_mutually_exclusive_group()
    src.add_argument(
        "--static",
        metavar="NOISE_JSON",
        help="take N and B per channel from 'imubounds static' noise.json",
    )
    src.add_argument(
        "--imu-spec",
        metavar="SPEC",
        help="datasheet figures: 'mtx' (default) or 'accel_nd=0.002,accel_bs=0.02,"
        "gyro_nd=0.05,gyro_bs=1' (m/s^2/sqrt(Hz), m/s^2, deg/s/sqrt(Hz), deg/s)",
    )
    p.add_argument("--k-sigma", type=float, help="factor k of the IMU bound k*sigma_c (3)")
    p.add_argument(
        "--bias-margin",
        type=float,
        metavar="M",
        help="widen the IMU bound by M x the bias-instability B (0, the paper; 1 keeps a "
        "sensor whose bias wanders by its bias stability inside its bounds)",
    )
    p.add_argument(
        "--avg-time",
        type=float,
        metavar="S",
        help="averaging time t of sigma_c (default: the drive length)",
    )
    g = p.add_argument_group("GPS")
    g.add_argument("--gps-cep", type=float, metavar="M", help="CEP at HDOP 1 in m (3)")
    g.add_argument(
        "--gps-box",
        metavar="mean|p=P",
        help="box half-width: 'mean' (paper, mu_e) or a probability level (default p=0.999)",
    )
    g.add_argument("--default-hdop", type=float, help="HDOP for fixes without one (1.0)")
    g.add_argument("--geodesy", choices=("wgs84", "haversine"), help="geodetic -> ENU (wgs84)")
    c = p.add_argument_group("compass")
    c.add_argument(
        "--compass-cal",
        metavar="FILE",
        help="CSV measured_deg,reference_deg for the deviation fit (default: GPS "
        "course over ground, with a warning)",
    )
    c.add_argument(
        "--compass-mode",
        choices=("paper", "corrected"),
        help="heading interval: paper |psi_err| or corrected + residual (corrected)",
    )
    c.add_argument(
        "--compass-floor",
        type=float,
        metavar="DEG",
        help="minimum heading half-width in degrees (0.5)",
    )
    c.add_argument(
        "--declination",
        type=float,
        metavar="DEG",
        help="magnetic declination, east positive, for magnetometer headings (0)",
    )
    c.add_argument(
        "--mount",
        choices=("auto", "forward", "backward"),
        default="auto",
        help="VN-100 mounting (auto: detect a backwards unit from yaw vs course)",
    )
    e = p.add_argument_group("estimator")
    e.add_argument(
        "--mode",
        choices=("paper", "full"),
        default="full",
        help="kinematic mode of the figures and steps.csv (both are reported)",
    )
    e.add_argument("--step", type=float, metavar="S", help="time step in s (1.0, the paper)")
    e.add_argument(
        "--passes",
        type=int,
        help="1: single forward-backward pass (paper); >1: "
        "Waltz sweeps over a sliding window, at most this many",
    )
    e.add_argument("--window", type=int, help="window length in steps for --passes > 1 (10)")
    e.add_argument(
        "--velocity-difference",
        choices=("contracted", "ins"),
        help="subtract the contracted box (default) or the INS box (paper) at t",
    )
    e.add_argument(
        "--on-empty",
        choices=("keep", "reset", "qrelax"),
        help="rule for an empty intersection: keep the prediction, reset to the "
        "aiding interval (default), or the q-relaxed intersection of the prediction "
        "and the aiding intervals of the last --window steps",
    )
    e.add_argument(
        "--q",
        type=int,
        dest="q_outliers",
        metavar="Q",
        help="outliers tolerated by --on-empty qrelax (1)",
    )
    e.add_argument(
        "--initial-speed",
        type=float,
        metavar="M/S",
        help="bound on |u|, |v| at the start (default: --max-speed; 0 for sims)",
    )
    e.add_argument("--max-speed", type=float, metavar="M/S", help="speed bound (70)")
    e.add_argument(
        "--nav-accel-bound",
        type=float,
        metavar="M/S2",
        help="model-error bound: position residual 1/2*A*dt^2 per step (0)",
    )
    e.add_argument(
        "--jerk-bound",
        type=float,
        metavar="M/S3",
        help="model-error bound: velocity residual J*dt^2 per step (0)",
    )
    e.add_argument(
        "--model-error",
        action="store_true",
        help="use the model-error bounds recorded by the simulator (sim dirs)",
    )
    p.add_argument("--no-plot", action="store_true", help="skip the figures")
    p.add_argument("--no-report", action="store_true", help="skip DIR/report.html")
    p.add_argument("--json", action="store_true", help="print dynamic.json on stdout")
    p.add_argument("-q", "--quiet", action="store_true", help="no messages on stderr")
    p.set_defaults(func=run)


def parse_imu_spec(text: str | None) -> Any:
    from imubounds.dynamic.estimator import ImuSpec
    from imubounds.presets import get_preset, preset_names
    from imubounds.units import DEG

    if text is None or text.strip().lower() in preset_names():
        p = get_preset(text or "mtx")
        return ImuSpec(
            accel={k: p.accel[k] for k in ("N", "B")},
            gyro={k: p.gyro[k] for k in ("N", "B")},
            source=f"{p.key} datasheet",
        )
    vals: dict[str, float] = {}
    for part in text.split(","):
        if "=" not in part:
            raise OptionError(
                f"--imu-spec {text!r}: use 'mtx' or key=value pairs "
                "accel_nd, accel_bs, gyro_nd, gyro_bs"
            )
        k, v = part.split("=", 1)
        try:
            vals[k.strip()] = float(v)
        except ValueError as err:
            raise OptionError(f"--imu-spec: {k.strip()}={v!r} is not a number") from err
    need = {"accel_nd", "accel_bs", "gyro_nd", "gyro_bs"}
    if set(vals) != need or any(not (x >= 0 and math.isfinite(x)) for x in vals.values()):
        raise OptionError(f"--imu-spec needs exactly {', '.join(sorted(need))} (non-negative)")
    return ImuSpec(
        accel={"N": vals["accel_nd"], "B": vals["accel_bs"]},
        gyro={"N": vals["gyro_nd"] * DEG, "B": vals["gyro_bs"] * DEG},
        source="--imu-spec",
    )


def read_static(path: str) -> Any:
    """N and B per channel from a noise.json written by ``imubounds static``."""
    from imubounds.dynamic.estimator import ImuSpec

    try:
        js = json.loads(Path(path).read_text())
    except (OSError, ValueError) as err:
        raise InputError(f"{path}: cannot read noise.json ({err})") from err
    chans = js.get("channels", {}) if isinstance(js, dict) else {}
    per: dict[str, dict[str, float]] = {}
    for ch in ("accel_x", "accel_y", "gyro_z"):
        c = chans.get(ch)
        if not isinstance(c, dict):
            raise InputError(
                f"{path}: no channel {ch} (the dynamic analysis needs accel_x, "
                "accel_y and gyro_z from the static log)"
            )
        stat = c.get("stationary", {})
        if "N" in stat and "B" in stat:
            N, B = stat["N"], stat["B"]
        else:
            terms = c.get("noise", {}).get("fit") or c.get("noise", {}).get("slope") or {}
            N = terms.get("N", {}).get("value")
            B = terms.get("B", {}).get("value")
        if N is None or not math.isfinite(float(N)):
            raise InputError(f"{path}: channel {ch} has no random-walk coefficient N")
        per[ch] = {"N": float(N), "B": float(B) if B is not None else 0.0}
    acc, gyr = per["accel_x"], per["gyro_z"]
    return ImuSpec(accel=acc, gyro=gyr, per_channel=per, source=str(path))


def _steps_table(res: Any) -> Any:
    import numpy as np
    import pandas as pd

    from imubounds.dynamic.estimator import CHANNELS

    st = res.steps
    df = pd.DataFrame({"t": st.t, "t_rel": st.t - st.t[0], "flags": res.flags})
    names = ["x", "y", "u", "v", "psi"]
    for i, nm in enumerate(names):
        df[f"{nm}_lo"], df[f"{nm}_hi"] = res.S[:, 2 * i], res.S[:, 2 * i + 1]
    for i, nm in enumerate(["x", "y"]):
        df[f"{nm}_ins_lo"], df[f"{nm}_ins_hi"] = res.P[:, 2 * i], res.P[:, 2 * i + 1]
    df["gps_x_lo"], df["gps_x_hi"], df["gps_y_lo"], df["gps_y_hi"] = st.gps.T
    df["heading_centre"], df["heading_half"] = st.heading.T
    for c, ch in enumerate(CHANNELS):
        m = st.meas[:, c]
        df[f"{ch}_meas"] = m
        df[f"{ch}_meas_lo"], df[f"{ch}_meas_hi"] = res.M[:, 2 * c], res.M[:, 2 * c + 1]
        df[f"{ch}_aided_lo"], df[f"{ch}_aided_hi"] = res.A[:, 2 * c], res.A[:, 2 * c + 1]
        df[f"{ch}_est_lo"], df[f"{ch}_est_hi"] = res.D[:, 2 * c], res.D[:, 2 * c + 1]
        df[f"{ch}_err_lo"], df[f"{ch}_err_hi"] = res.A[:, 2 * c] - m, res.A[:, 2 * c + 1] - m
    if st.truth is not None:
        for k, v in st.truth.items():
            df[f"truth_{k}"] = v
    df.iloc[
        0,
        df.columns.get_indexer(
            [c for c in df.columns if c.endswith(("_aided_lo", "_aided_hi", "_err_lo", "_err_hi"))]
        ),
    ] = np.nan
    df["t"] = df["t"].map("{:.6f}".format)  # keep Unix-time resolution in the CSV
    return df


def run(args: argparse.Namespace) -> int:
    from imubounds.io.outputs import OutputSet

    inputs = [*args.log, *(x for x in (args.static, getattr(args, "compass_cal", None)) if x)]
    with OutputSet(args.out, force=args.force, inputs=inputs) as outset:
        outset.check(["dynamic.json", "steps.csv", "report.html"])
        messages = _run(args, outset)
    if not args.quiet:
        for m in messages:
            print(m, file=sys.stderr)
    return 0


def _run(args: argparse.Namespace, outset: Any) -> list[str]:
    from imubounds.dynamic.aiding.compass import read_calibration
    from imubounds.dynamic.estimator import config_dict, config_for_log, scenario_model_error
    from imubounds.dynamic.estimator import run as run_est
    from imubounds.io.drive_legacy import read_drive_log as read_drive
    from imubounds.io.outputs import write_json, write_with

    messages: list[str] = []
    say = messages.append

    log = read_drive(list(args.log), mount=args.mount)
    imu = (
        read_static(args.static)
        if args.static
        else (parse_imu_spec(args.imu_spec) if args.imu_spec or log.layout != "sim" else None)
    )
    me = scenario_model_error(log) if args.model_error else {}
    if args.model_error and log.layout != "sim":
        raise OptionError(
            "--model-error takes the bounds of a simulator directory; "
            "give --nav-accel-bound/--jerk-bound for other logs"
        )
    overrides: dict[str, Any] = dict(
        k_sigma=args.k_sigma,
        bias_margin=args.bias_margin,
        t_avg_s=args.avg_time,
        gps_cep_m=args.gps_cep,
        gps_box=args.gps_box,
        default_hdop=args.default_hdop,
        geodesy=args.geodesy,
        compass_mode=args.compass_mode,
        compass_floor_rad=math.radians(args.compass_floor)
        if args.compass_floor is not None
        else None,
        declination_rad=math.radians(args.declination) if args.declination is not None else None,
        step_s=args.step,
        passes=args.passes,
        window=args.window,
        veldiff=args.velocity_difference,
        fallback=args.on_empty,
        q_outliers=args.q_outliers,
        initial_speed_bound=args.initial_speed,
        max_speed=args.max_speed,
        nav_accel_bound=args.nav_accel_bound
        if args.nav_accel_bound is not None
        else me.get("nav_accel_bound"),
        jerk_bound=args.jerk_bound if args.jerk_bound is not None else me.get("jerk_bound"),
    )
    if args.compass_cal:
        overrides["deviation"] = read_calibration(args.compass_cal)
    summaries: dict[str, Any] = {}
    results: dict[str, Any] = {}
    for mode in ("paper", "full"):
        cfg = config_for_log(log, imu=imu, mode=mode, **overrides)
        results[mode] = run_est(log, cfg)
        summaries[mode] = results[mode].summary
    primary = results[args.mode]
    st = primary.steps
    doc: dict[str, Any] = {
        "format": "imubounds-dynamic/1",
        "input": {
            "paths": list(args.log),
            "layout": log.layout,
            "source": log.source,
            "imu_rate_hz": log.imu_rate_hz,
            "gps_rate_hz": log.gps_rate_hz,
            "origin_lat_lon_alt": list(st.origin),
            "warnings": st.warnings,
            "frames": "ENU at the first fix (x east, y north); body FLU; heading CCW "
            "from east in the model, compass clockwise from north",
        },
        "settings": config_dict(primary.config),
        "imu_bounds": {
            "source": primary.config.imu.source,
            "halfwidth_per_step": dict(
                zip(("accel_x", "accel_y", "gyro_z"), st.half.tolist(), strict=True)
            ),
            "unit": {"accel_x": "m/s^2", "accel_y": "m/s^2", "gyro_z": "rad/s"},
        },
        "compass_deviation": st.deviation.to_dict(),
        "primary_mode": args.mode,
        "modes": summaries,
        "definitions": {
            "aided": "interval of the quantity from the contracted states through the "
            "kinematic constraint, without its own measurement",
            "estimate": "measured interval intersected with the aided interval",
            "dynamic_error": "[aided] - measured value (mean of lower ends, mean of upper ends)",
            "stationary_level_95": "1.96 * N[per sqrt(h)] * sqrt(T[h]) over the drive length",
            "enclosure": "share of steps whose true value lies inside the interval",
        },
    }
    if (
        log.truth is not None
        and log.layout == "sim"
        and not args.model_error
        and any(v > 0 for v in scenario_model_error(log).values())
    ):
        me2 = scenario_model_error(log)
        cfg2 = config_for_log(log, imu=imu, mode=args.mode, **{**overrides, **me2})
        doc["with_model_error"] = {"bounds": me2, "summary": run_est(log, cfg2).summary}
    out = outset.staging
    write_json(out / "dynamic.json", doc)
    df = _steps_table(primary)
    write_with(out / "steps.csv", lambda p: df.to_csv(p, index=False, float_format="%.9g"))
    if not args.no_plot:
        from imubounds.report import dynamic_plots as pd_

        title = f"{Path(log.source).name} ({log.layout}, mode {args.mode})"
        pd_.plot_intervals(primary, out, title=title)
        pd_.plot_trajectory(primary, out, title=title)
        pd_.plot_comparison(summaries, out)
    outset.record(getattr(args, "argv", None), command_name="dynamic")
    if not args.no_report:
        from imubounds.report.html import write_report

        write_report(out)
    if args.json:
        from imubounds.io.outputs import to_jsonable

        print(json.dumps(to_jsonable(doc), indent=2))
    for w in st.warnings:
        say(f"imubounds: note: {w}")
    s = summaries[args.mode]
    say(f"dynamic ({args.mode} mode, {s['n_steps']} steps of {s['step_s']:g} s) -> {args.out}")
    for ch, c in s["channels"].items():
        lo, hi = c["dynamic_error_mean_interval"]
        f, unit = (180 / math.pi, "deg/s") if ch == "gyro_z" else (1.0, "m/s^2")
        inside = 100 * c["measurement_inside_aided"]
        say(
            f"  {ch:8s} error [{lo * f:+.4f}, {hi * f:+.4f}] {unit}; stationary 95% "
            f"{c['stationary_level_95'] * f:.4f}; meas inside {inside:.1f}%; {c['verdict']}"
        )
    if "enclosure" in s:
        say(f"  truth inside position boxes: {100 * s['enclosure']['position_box']:.1f}% of steps")
    n_empty = sum(v["count"] for k, v in s["flags"].items() if "empty" in k)
    if n_empty:
        say(f"  empty intersections: {n_empty} (rule: {s['empty_rule']}); see dynamic.json flags")
    return messages
