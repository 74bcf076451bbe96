"""``imubounds dynamic DIR -o OUT``: dynamic error margins of an IMU from a drive.

Runs mode ``full`` (guaranteed window-mean margins per averaging time, verdicts, the
whole-trip interval smoother) and mode ``paper`` (the paper's per-step estimator, not
guaranteed) unless ``--mode`` selects one; writes OUT/dynamic.json (schema in
docs/dynamic-method.md), margins.csv, states.csv, steps.csv and the figures.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path
from typing import TYPE_CHECKING, Any

from imubounds.cli._common import (
    add_force_option,
    compass_calibration,
    declination,
    imu_spec,
    noise_json,
    nonneg_float,
    positive_float,
    positive_int,
    probability,
    setting_value,
)
from imubounds.errors import InputError

if TYPE_CHECKING:
    from imubounds.dynamic.estimator.options import FullOptions


def register(sub: Any) -> None:
    p = sub.add_parser(
        "dynamic",
        help="guaranteed dynamic error margins of the IMU from a drive (IMU + aiding sensors)",
        description="For each IMU channel and each averaging time tau (octaves from one "
        "sample to a quarter of the trip): the guaranteed interval of the tau-averaged IMU "
        "error, built from the aiding sensors only, against the stationary band of the "
        "noise budget, and a verdict (consistent, exceeds, undecided; 'no reference' when "
        "no noise figures are given); a whole-trip interval smoother encloses position, "
        "heading, body velocity and each channel's bias (mode full, the default). Mode "
        "paper reproduces the paper's per-step method (not guaranteed). DIR: a drive-layout "
        "directory (imu.csv, gnss.csv, velocity.csv, heading.csv, attitude.csv, truth.csv, "
        "drive.yaml), an 'imubounds simulate' "
        "directory, a VN-100 directory (or its two CSV files), a comma2k19 segment, a ROS "
        "bag/MCAP, a PX4 ULog, or an NMEA file with an IMU log. A drive.yaml in the "
        "log's directory (any of these layouts) gives its settings.",
    )
    p.add_argument("log", nargs="+", help="drive directory or files")
    p.add_argument("-o", "--out", default="out", metavar="DIR", help="output directory")
    add_force_option(p)
    p.add_argument(
        "--mode",
        choices=("full", "paper"),
        help="run only this mode (default: both; full is the primary)",
    )
    src = p.add_mutually_exclusive_group()
    src.add_argument(
        "--static", type=noise_json, metavar="NOISE_JSON",
        help="IMU noise terms from 'imubounds static'"
    )
    src.add_argument(
        "--imu-spec",
        type=imu_spec,
        metavar="SPEC",
        help="a preset (mtx, vn100) or 'accel_nd=..,accel_bs=..,gyro_nd=..,gyro_bs=..' "
        "(m/s^2/sqrt(Hz), m/s^2, deg/s/sqrt(Hz), deg/s); default drive.yaml, else mtx",
    )
    f = p.add_argument_group("mode full (every figure defaults to drive.yaml, then a default)")
    f.add_argument(
        "--alpha",
        type=probability,
        help="whole-trip probability that some stated probabilistic bound fails (0.01)",
    )
    f.add_argument("--turn-on-accel", type=nonneg_float, metavar="M/S2",
                   help="turn-on bias bound of the accelerometers")
    f.add_argument("--turn-on-gyro", type=nonneg_float, metavar="DEG/S",
                   help="turn-on bias bound of the gyros")
    f.add_argument("--scale", type=setting_value("imu.scale_factor", ""), metavar="FRACTION",
                   help="scale-factor error bound (0.005 = 0.5 %%)")
    f.add_argument("--misalignment", type=setting_value("imu.misalignment_deg", "deg"),
                   metavar="DEG",
                   help="axis misalignment bound")
    f.add_argument("--imu-stamp", choices=("end", "start", "centre"),
                   help="where in its period an IMU sample is time-stamped (end)")
    f.add_argument("--max-tilt", type=setting_value("vehicle.max_tilt_deg", "deg"),
                   metavar="DEG",
                   help="roll/pitch bound when there is no attitude stream (vehicle.max_tilt_deg)")
    f.add_argument("--lateral-speed-bound", type=nonneg_float, metavar="M/S",
                   help="non-holonomic |lateral velocity| bound of a wheeled vehicle "
                        "(vehicle.lateral_speed_bound_mps)")
    f.add_argument("--vertical-speed-bound", type=nonneg_float, metavar="M/S",
                   help="|vertical body velocity| bound: suspension heave plus speed x "
                        "pitch against the path (vehicle.vertical_speed_bound_mps; ground "
                        "default 0.5)")
    f.add_argument("--reverses", action="store_true", default=None,
                   help="the vehicle may drive backwards: no heading from the GNSS course")
    f.add_argument("--max-speed", type=positive_float, metavar="M/S")
    f.add_argument("--max-accel", type=positive_float, metavar="M/S2",
                   help="horizontal acceleration bound (centripetal included)")
    f.add_argument("--max-jerk", type=positive_float, metavar="M/S3")
    f.add_argument("--max-rate", type=positive_float, metavar="DEG/S",
                   help="angular-rate bound (vehicle.max_yaw_rate_dps)")
    f.add_argument("--max-ang-accel", type=positive_float, metavar="DEG/S2",
                   help="angular-acceleration bound (360)")
    f.add_argument("--gnss-cep", type=positive_float, metavar="M", help="CEP at HDOP 1")
    f.add_argument("--gnss-vel-sigma", type=setting_value("gnss.vel_sigma_mps", "m/s"),
                   metavar="M/S",
                   help="1-sigma GNSS velocity error per component")
    f.add_argument("--velocity-bound", type=nonneg_float, metavar="M/S",
                   help="body-velocity sensor error bound")
    f.add_argument("--attitude-bound", type=setting_value("attitude.bound_deg", "deg"),
                   metavar="DEG",
                   help="roll/pitch error bound of the attitude stream")
    f.add_argument("--heading-noise", type=setting_value("heading.noise_deg", "deg"),
                   metavar="DEG",
                   help="1-sigma compass noise")
    f.add_argument("--heading-deviation", type=setting_value("heading.deviation_deg", "deg"),
                   metavar="DEG",
                   help="compass deviation bound after correction")
    f.add_argument("--declination", type=declination, metavar="DEG",
                   help="magnetic declination, east positive")
    f.add_argument("--compass-cal", type=compass_calibration, metavar="FILE",
                   help="swing calibration CSV (measured_deg,reference_deg) for the compass "
                   "deviation (default: drive.yaml heading.calibration)")
    f.add_argument("--compass-fit", choices=("auto", "ellipse", "swing", "gnss-course", "none"),
                   help="how the compass is calibrated (default: drive.yaml heading.fit, "
                   "auto); gnss-course makes the heading depend on the GNSS")
    f.add_argument("--max-windows", type=positive_int, metavar="N",
                   help="windows per averaging time, at most (2048)")
    f.add_argument("--tol", type=positive_float, help="fixpoint tolerance (1e-3 of a width)")
    g = p.add_argument_group("mode paper (the paper's per-step estimator, not guaranteed)")
    g.add_argument("--kinematics", choices=("paper", "full"),
                   help="the paper's printed model or the full transport terms (paper)")
    g.add_argument("--k-sigma", type=positive_float, help="factor k of k*sigma_c (3)")
    g.add_argument("--bias-margin", type=nonneg_float, metavar="M",
                   help="widen the IMU bound by M x B (0)")
    g.add_argument("--avg-time", type=positive_float, metavar="S",
                   help="averaging time t of sigma_c (the drive length)")
    g.add_argument("--gps-box", metavar="mean|p=P", help="GPS box: mean (the paper) or p=P")
    g.add_argument("--step", type=positive_float, metavar="S", help="time step (1 s)")
    g.add_argument("--passes", type=positive_int, help="Waltz sweeps over a window (1)")
    g.add_argument("--window", type=positive_int, help="window in steps (10)")
    g.add_argument("--on-empty", choices=("keep", "reset", "qrelax"),
                   help="rule for an empty intersection (reset)")
    g.add_argument("--initial-speed", type=nonneg_float, metavar="M/S",
                   help="bound on |u|, |v| at the start")
    p.add_argument(
        "--mount",
        choices=("auto", "forward", "backward"),
        default="auto",
        help="VN-100 mounting (auto: detect a backwards unit from yaw vs course)",
    )
    p.add_argument("--no-plot", action="store_true", help="skip the figures")
    p.add_argument("--no-report", action="store_true", help="skip DIR/report.html")
    p.add_argument("--json", action="store_true", help="print dynamic.json on stdout")
    p.add_argument("-q", "--quiet", action="store_true", help="print no summary")
    p.set_defaults(func=run)


# ------------------------------------------------------------------------- input


def load_drive(paths: list[str], mount: str = "auto") -> Any:
    """A :class:`~imubounds.io.drive.Drive` from any supported input, through the one
    reader registry :func:`imubounds.io.read_drive`."""
    from imubounds.io import read_drive
    from imubounds.io.validate import is_url

    for p in paths:
        if not Path(p).exists():
            if is_url(p):
                raise InputError(f"{p}: a URL; imubounds dynamic reads local files and "
                                 "folders: download it first")  # fmt: skip
            raise InputError(f"{p}: no such file or directory")
    drive = read_drive(paths, mount=mount)
    drive.check()
    from imubounds.io.drive.validate_imu import CORRUPT_SAMPLES

    corrupt = drive.meta.get(CORRUPT_SAMPLES) or []
    if corrupt:
        more = f" (and {len(corrupt) - 1} more channel(s))" if len(corrupt) > 1 else ""
        raise InputError(
            f"{corrupt[0]}{more}: corrupt samples, which no error bound holds over; repair "
            "or remove these rows (imubounds convert keeps them, with a warning)"
        )
    from imubounds.dynamic.imu_mount import mount_warning

    if (w := mount_warning(drive)) is not None:
        drive.warnings.append(w)
    return drive


# --------------------------------------------------------------------------- run


def _full_options(args: argparse.Namespace, settings: Any) -> FullOptions:
    """The options of mode full from the arguments, checked (:class:`OptionError`), an
    ``--imu-stamp`` not given taken from drive.yaml (``settings``)."""
    from imubounds.dynamic.estimator.options import check_options
    from imubounds.units import DEG as deg

    o = {
        "alpha": args.alpha,
        "imu_spec": args.imu_spec,
        "accel_turn_on": args.turn_on_accel,
        "gyro_turn_on": None if args.turn_on_gyro is None else args.turn_on_gyro * deg,
        "scale": args.scale,
        "misalignment_deg": args.misalignment,
        "imu_stamp": args.imu_stamp,
        "max_tilt_deg": args.max_tilt,
        "lateral_speed_bound_mps": args.lateral_speed_bound,
        "vertical_speed_bound_mps": args.vertical_speed_bound,
        "max_speed": args.max_speed,
        "max_accel": args.max_accel,
        "max_jerk": args.max_jerk,
        "max_rate_dps": args.max_rate,
        "max_ang_accel_dps2": args.max_ang_accel,
        "gnss_cep_m": args.gnss_cep,
        "gnss_vel_sigma": args.gnss_vel_sigma,
        "velocity_bound": args.velocity_bound,
        "attitude_bound_deg": args.attitude_bound,
        "heading_noise_deg": args.heading_noise,
        "heading_deviation_deg": args.heading_deviation,
        "declination_deg": args.declination,
        "compass_cal": args.compass_cal,
        "compass_fit": args.compass_fit,
        "max_windows": args.max_windows,
        "tol": args.tol,
        "reverses": args.reverses,
    }
    return check_options({k: v for k, v in o.items() if v is not None}, settings)


def _paper_options(args: argparse.Namespace) -> dict[str, Any]:
    o = {
        "imu_spec": args.imu_spec,
        "kinematics": args.kinematics,
        "k_sigma": args.k_sigma,
        "bias_margin": args.bias_margin,
        "t_avg_s": args.avg_time,
        "gps_box": args.gps_box,
        "step_s": args.step,
        "passes": args.passes,
        "window": args.window,
        "fallback": args.on_empty,
        "initial_speed_bound": args.initial_speed,
        "gps_cep_m": args.gnss_cep,
        "declination_rad": None if args.declination is None else math.radians(args.declination),
    }
    return {k: v for k, v in o.items() if v is not None}


def run(args: argparse.Namespace) -> int:
    from imubounds.io.outputs import OutputSet

    inputs = [*args.log, *(x for x in (args.static,) if x)]
    with OutputSet(args.out, force=args.force, inputs=inputs, command="dynamic",
                   source=args.log) as outset:
        outset.check(["dynamic.json", "motion.json", "margins.csv", "states.csv", "steps.csv",
                      "report.html"])
        messages = _run(args, outset)
    for m in messages:
        # the summary on stdout (as static's); notes and warnings on stderr, the warnings
        # about the input even with --quiet
        warning = m.startswith("imubounds: warning:")
        if args.quiet and not warning:
            continue
        note = warning or m.startswith("imubounds: note:")
        print(m, file=sys.stderr if note or args.json else sys.stdout)
    return 0


def _step_names(args: argparse.Namespace) -> list[str]:
    modes = [args.mode] if args.mode else ["full", "paper"]
    names = ["reading the drive", *(f"mode {m}" for m in modes), "writing the tables"]
    if not args.no_plot:
        names.append("drawing the figures")
    if not args.no_report:
        names.append("writing the report")
    return names


def _run(args: argparse.Namespace, outset: Any) -> list[str]:
    from imubounds.cli._common import Reporter

    with Reporter(args.quiet).steps("imubounds dynamic", len(_step_names(args))) as steps:
        return _analyse(args, outset, steps)


def _analyse(args: argparse.Namespace, outset: Any, steps: Any) -> list[str]:
    steps.step("reading the drive")
    from imubounds.dynamic.estimator import SCHEMA_VERSION, dynamic_margins
    from imubounds.io.outputs import to_jsonable, write_json, write_with

    messages: list[str] = []
    say = messages.append
    drive = load_drive(list(args.log), mount=args.mount)
    modes = [args.mode] if args.mode else ["full", "paper"]
    results: dict[str, Any] = {}
    skipped: list[str] = []
    for mode in modes:
        steps.step(f"mode {mode}")
        if mode == "full":
            results[mode] = dynamic_margins(drive, noise=args.static, mode=mode,
                                            options=_full_options(args, drive.settings),
                                            progress=steps.sub)  # fmt: skip
            continue
        opts = _paper_options(args)
        if drive.gnss is None:
            skipped.append("imubounds: note: mode paper skipped: it needs GNSS fixes")
            continue
        results[mode] = dynamic_margins(drive, noise=args.static, mode=mode, **opts)
    primary = "full" if "full" in results else next(iter(results))
    full = results.get("full")
    doc: dict[str, Any] = {
        "format": SCHEMA_VERSION,
        "schema_version": SCHEMA_VERSION,
        "input": {
            "paths": list(args.log),
            "layout": drive.layout,
            "source": drive.source,
            "streams": drive.streams(),
            "imu_rate_hz": drive.imu.rate_hz if drive.imu is not None else None,
            "warnings": list(drive.warnings),
            "settings_assumed": list(drive.settings.assumed),
            "frames": "ENU at the first GNSS fix (x east, y north); body FLU; heading CCW "
            "from east inside, compass clockwise from north in the inputs",
        },
        "primary_mode": primary,
        "modes": {m: r.to_dict() for m, r in results.items()},
    }
    if full is not None and full.full.ctx.aiding.origin is not None:
        doc["input"]["origin_lat_lon_alt"] = list(full.full.ctx.aiding.origin)
    steps.step("writing the tables")
    out = outset.staging
    write_json(out / "dynamic.json", doc)
    motion: dict[str, Any] | None = None
    if full is not None and getattr(full, "full", None) is not None:
        from imubounds.motion import motion_figures

        motion = motion_figures(full, noise=args.static)
        write_json(out / "motion.json", motion)
    if full is not None:
        df = full.to_frame()
        write_with(out / "margins.csv", lambda p: df.to_csv(p, index=False, float_format="%.9g"))
        st = full.states_frame()
        write_with(out / "states.csv", lambda p: st.to_csv(p, index=False, float_format="%.9g"))
    if "paper" in results:
        steps_df = _steps_table(results["paper"].paper)
        write_with(out / "steps.csv",
                   lambda p: steps_df.to_csv(p, index=False, float_format="%.9g"))
    if not args.no_plot:
        steps.step("drawing the figures")
        _figures(args, drive, results, out)
    outset.record(getattr(args, "argv", None), command_name="dynamic")
    if not args.no_report:
        steps.step("writing the report")
        from imubounds.report.html import write_report

        write_report(out)
    if args.json:
        print(json.dumps(to_jsonable(doc), indent=2))
    _summary(results, motion, say)
    for w in drive.warnings:
        say(f"imubounds: warning: {w}")
    messages += skipped
    files = ["dynamic.json", *(["motion.json", "margins.csv", "states.csv"] if full else []),
             *(["steps.csv"] if "paper" in results else [])]
    say(f"wrote {', '.join(files)}{'' if args.no_plot else ', figures'}"
        f"{'' if args.no_report else ', report.html'} to {args.out}")
    return messages


def _figures(args: argparse.Namespace, drive: Any, results: dict[str, Any], out: Path) -> None:
    from imubounds.report import dynamic_plots as P

    title = f"{Path(str(drive.source)).name} ({drive.layout})"
    full = results.get("full")
    if full is not None:
        P.save(P.plot_margins(full.summary, title=title), out, "margins")
        P.save(P.plot_windows(full, title=title), out, "windows")
        P.save(P.plot_trajectory(full, drive, title=title), out, "trajectory")
        from imubounds.motion import plot_motion, read_motion

        noise_doc = None
        if args.static:
            noise_doc = json.loads(Path(args.static).read_text(encoding="utf-8"))
        P.save(plot_motion(read_motion(out), noise_doc), out, "motion")
    if "paper" in results:
        P.save(P.plot_intervals(results["paper"].paper, title=title), out, "intervals")


def _tightest(mode: str, ch: str, s: dict[str, Any]) -> tuple[str, list[str]]:
    """The tightest decidable margin of a channel (or why none is decidable) and notes."""
    rows = s.get("margins", {}).get(ch) or []
    best = [x for x in rows if x.get("halfwidth_median") is not None]
    if mode != "full" or not best:
        return "", []
    f, unit = (180 / math.pi, "deg/s") if ch.startswith("gyro") else (1.0, "m/s^2")
    dec = [x for x in best if x.get("decidable_fraction", 0) > 0]
    if dec:
        x = min(dec, key=lambda x: x["halfwidth_median"])
        return (f"+-{x['halfwidth_median'] * f:.3g} {unit} at tau {x['tau_s']:.3g} s "
                f"(band {x['stationary'] * f:.3g})"), []
    # nothing decidable: the narrowest margin against its band, and why
    x = min(best, key=lambda x: x["halfwidth_median"] / max(x["stationary"], 1e-99))
    notes = list((s.get("verdict_detail", {}).get(ch) or {}).get("notes") or [])
    return (f"wider than the band at every tau (closest at tau {x['tau_s']:.3g} s: "
            f"+-{x['halfwidth_median'] * f:.3g} {unit}, band {x['stationary'] * f:.3g})"),\
        notes[:1]


def _factor_text(mc: dict[str, Any] | None) -> str:
    if not mc:
        return "-"
    F = mc.get("F")
    taus = mc.get("resolved_taus") or []
    if F is None:
        return "not resolved"
    return f"{F:.3g} (tau {min(taus):.3g}-{max(taus):.3g} s)" if taus else f"{F:.3g}"


def _summary(results: dict[str, Any], motion: dict[str, Any] | None, say: Any) -> None:
    """The answer first: per mode whether it is guaranteed (the failed checks when not),
    the verdict of every channel the result holds (fragile ones marked), the in-motion
    factor F (motion.json) and the tightest margin; then the corrections applied, the
    truth inside and the dropped measurements."""
    from imubounds.dynamic.estimator.result import applied_corrections

    mchans = (motion or {}).get("channels") or {}
    for mode, r in results.items():
        s = r.summary
        verdicts = s.get("verdict") or {}
        if mode != "full":
            say(f"mode {mode} ({'guaranteed' if s.get('guaranteed') else 'NOT guaranteed'}): "
                + ", ".join(f"{ch} {v}" for ch, v in verdicts.items()))
        else:
            _full_answer(s, mchans, say)
        for line in applied_corrections(s):
            say(f"  {line}")
        if "no reference" in verdicts.values():
            from imubounds.dynamic.estimator.verdicts import HOW_TO_REFERENCE

            say(f"  no reference to judge against: {HOW_TO_REFERENCE}")
        enc = s.get("enclosure")
        if enc:
            keys = [k for k in ("position", "heading", "u", "v") if enc.get(k) is not None]
            say("  truth inside: " + ", ".join(f"{k} {100 * enc[k]:.1f}%" for k in keys))
        ei = s.get("empty_intersections")
        if ei and ei.get("count"):
            say(f"  empty intersections: {ei['count']} (see dynamic.json)")


def _full_answer(s: dict[str, Any], mchans: dict[str, Any], say: Any) -> None:
    """Mode full's guarantee, then a table: channel, verdict, in-motion F, tightest margin
    (each row followed by why it is fragile or undecided)."""
    viol = s.get("violations") or []
    alpha = (s.get("alpha") or {}).get("alpha")
    if s.get("guaranteed"):
        tag = "guaranteed" + (f" with probability >= {1 - alpha:.4g} over the trip"
                              if alpha else "")
    else:
        tag = f"NOT guaranteed: {len(viol)} assumption check(s) failed"
    say(f"mode full ({tag}): the IMU's error in motion against its stationary band")
    if viol:
        say(f"  NOT GUARANTEED: {len(viol)} assumption check(s) failed (violations in "
            "dynamic.json, column guaranteed of states.csv):")
        for v in viol[:5]:
            say(f"    {v['stream']}: {v['test']}: {v['detail']}")
        if len(viol) > 5:
            say(f"    ... and {len(viol) - 5} more")
    details = s.get("verdict_detail", {}) or {}
    rows: list[tuple[list[str], list[str]]] = []
    for ch, v in (s.get("verdict") or {}).items():
        det = details.get(ch) or {}
        tight, notes = _tightest("full", ch, s)
        sub = ([str(det.get("fragile_detail"))] if det.get("fragile") else []) + notes
        rows.append(([ch, f"{v}, FRAGILE" if det.get("fragile") else str(v),
                      _factor_text(mchans.get(ch)), tight], sub))
    if not rows:
        return
    head = ["channel", "verdict", "in-motion F", "tightest margin (median window)"]
    widths = [max(len(h), *(len(r[i]) for r, _ in rows)) for i, h in enumerate(head)]
    for cells, sub in [(head, []), *rows]:
        say("    " + "  ".join(c.ljust(w) for c, w in zip(cells, widths, strict=True)).rstrip())
        for line in sub:
            say(f"             {line}")


def _steps_table(res: Any) -> Any:
    import numpy as np
    import pandas as pd

    from imubounds.dynamic.estimator.paper import CHANNELS

    st = res.steps
    df = pd.DataFrame({"t": st.t, "t_rel": st.t - st.t[0], "flags": res.flags})
    for i, nm in enumerate(["x", "y", "u", "v", "psi"]):
        df[f"{nm}_lo"], df[f"{nm}_hi"] = res.S[:, 2 * i], res.S[:, 2 * i + 1]
    df["gps_x_lo"], df["gps_x_hi"], df["gps_y_lo"], df["gps_y_hi"] = st.gps.T
    df["heading_centre"], df["heading_half"] = st.heading.T
    for c, ch in enumerate(CHANNELS):
        m = st.meas[:, c]
        df[f"{ch}_meas"] = m
        df[f"{ch}_aided_lo"], df[f"{ch}_aided_hi"] = res.A[:, 2 * c], res.A[:, 2 * c + 1]
        df[f"{ch}_err_lo"], df[f"{ch}_err_hi"] = res.A[:, 2 * c] - m, res.A[:, 2 * c + 1] - m
    if st.truth is not None:
        for k, v in st.truth.items():
            df[f"truth_{k}"] = v
    cols = [c for c in df.columns if "_aided_" in c or "_err_" in c]
    df.loc[df.index[0], cols] = np.nan
    df["t"] = df["t"].map("{:.6f}".format)
    return df
