"""``imubounds simulate-noise``: generate IMU sensor noise as a CSV log the readers take."""

from __future__ import annotations

import argparse
import json
import sys
from typing import Any

from imubounds.errors import OptionError

EPILOG = """\
figures with units (dimensions are checked):
  gyro  N: deg/sqrt(h), deg/s/sqrt(Hz), rad/s^0.5   B: deg/h, deg/s, rad/s
        K: deg/h/sqrt(h), rad/s^1.5   Q: deg, rad   R: deg/h^2, rad/s^2
  accel N: m/s/sqrt(h), m/s^2/sqrt(Hz), ug/sqrt(Hz)   B: ug, mg, m/s^2
        K: m/s^2/sqrt(s), m/s^2.5   Q: m/s   R: m/s^3
  a bare number is SI.

examples:
  imubounds simulate-noise --preset xsens-mtx --rate 100 --duration 2h -o mtx.csv
  imubounds simulate-noise --gyro 'N=0.3 deg/sqrt(h),B=5 deg/h' \\
      --accel 'N=60 ug/sqrt(Hz),B=20 ug' --rate 200 --duration 30min -o imu.csv.gz
  imubounds simulate-noise --from-noise out/noise.json --duration 1h -o again.csv
"""


def register(sub: Any) -> None:
    p = sub.add_parser(
        "simulate-noise",
        help="generate multi-axis IMU noise from a datasheet, noise terms or fitted models",
        description="Generate seeded, reproducible IMU noise (quantization Q, white N, bias "
        "instability B as a sum of Gauss-Markov processes, rate random walk K, rate ramp R, "
        "constant/turn-on bias, Gauss-Markov and AR models) and write it as a CSV log "
        "(time_s, gyro_x_rads ... accel_z_mps2) that 'imubounds static' reads.",
        epilog=EPILOG,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument("-o", "--out", required=True, metavar="CSV", help="output CSV (.csv or .csv.gz)")
    src = p.add_argument_group("where the noise figures come from (one of, then overrides)")
    src.add_argument("--preset", metavar="NAME", help="datasheet preset, e.g. xsens-mtx")
    src.add_argument("--from-noise", metavar="JSON", help="noise.json from 'imubounds static'")
    src.add_argument("--spec", metavar="FILE", help="noise spec in YAML or JSON")
    src.add_argument(
        "--terms",
        choices=("fit", "slope", "selected", "none"),
        default="fit",
        help="with --from-noise: which term estimate to use: fit (default), slope, or the "
        "selected terms (upper bounds where the log did not resolve a term)",
    )
    src.add_argument(
        "--models",
        default="",
        help="with --from-noise: also simulate the fitted models gm,ar (usually with --terms none)",
    )
    src.add_argument(
        "--gyro",
        action="append",
        default=[],
        metavar="TERMS",
        help="gyro figures on all 3 axes, e.g. 'N=0.3 deg/sqrt(h),B=5 deg/h'",
    )
    src.add_argument(
        "--accel",
        action="append",
        default=[],
        metavar="TERMS",
        help="accelerometer figures, e.g. 'N=60 ug/sqrt(Hz),B=20 ug'",
    )
    src.add_argument(
        "--bias-tau-range",
        metavar="LO,HI",
        help="tau range (s) where B is flicker noise (default 1,1000)",
    )
    run_g = p.add_argument_group("the run")
    run_g.add_argument(
        "--rate",
        type=float,
        metavar="HZ",
        help="sample rate (default: the noise.json's or the spec's)",
    )
    run_g.add_argument("--duration", metavar="T", help="length: 7200, 7200s, 90min, 2h")
    run_g.add_argument("--samples", type=int, metavar="N", help="length in samples")
    run_g.add_argument("--seed", type=int, default=0, help="random seed (default 0)")
    run_g.add_argument("--t0", type=float, default=0.0, metavar="S", help="first time stamp")
    run_g.add_argument("--channels", help="only these channels, e.g. gyro_z,accel_x")
    p.add_argument("--save-spec", metavar="JSON", help="also write the resolved spec (SI) here")
    p.add_argument("--list-presets", action="store_true", help="list presets and exit")
    p.add_argument("-q", "--quiet", action="store_true", help="no messages on stderr")
    p.set_defaults(func=run)


def _bias_range(text: str | None) -> tuple[float, float] | None:
    if text is None:
        return None
    try:
        lo, hi = (float(v) for v in text.split(","))
    except ValueError as err:
        raise OptionError(
            f"--bias-tau-range {text!r}: write LO,HI in seconds, e.g. 1,1000"
        ) from err
    if not 0 < lo < hi:
        raise OptionError(f"--bias-tau-range {text!r}: need 0 < LO < HI")
    return lo, hi


def build_spec(args: argparse.Namespace) -> Any:
    """The :class:`~imubounds.stationary.noise_sim.NoiseSpec` the options describe."""
    from dataclasses import replace

    from imubounds.stationary import noise_sim as sim

    sources = [s for s in (args.preset, args.from_noise, args.spec) if s]
    if len(sources) > 1:
        raise OptionError("give only one of --preset, --from-noise, --spec")
    if not sources and not (args.gyro or args.accel):
        raise OptionError(
            "nothing to simulate: give --preset, --from-noise, --spec or --gyro/--accel figures"
        )
    if (args.models or args.terms != "fit") and not args.from_noise:
        raise OptionError("--terms and --models apply only with --from-noise")
    tau_range = _bias_range(args.bias_tau_range)
    if args.preset:
        spec = sim.preset(args.preset, tau_range)
    elif args.from_noise:
        models = tuple(m.strip() for m in args.models.split(",") if m.strip())
        spec = sim.NoiseSpec.from_noise_json(
            args.from_noise,
            terms=args.terms,
            models=models,
            bias_tau_range_s=tau_range or sim.DEFAULT_BIAS_TAU_RANGE,
        )
    elif args.spec:
        spec = sim.load_spec(args.spec)
    else:
        spec = sim.NoiseSpec(channels={}, name="command-line figures")
    for kind in ("gyro", "accel"):
        values: dict[str, Any] = {}
        for text in getattr(args, kind):
            values.update(sim.parse_term_list(text, kind))
        if tau_range is not None:
            values["bias_tau_range_s"] = tau_range
        if getattr(args, kind) or (
            tau_range is not None and any(c.startswith(kind) for c in spec.channels)
        ):
            spec = spec.with_overrides(kind, values)
    if sources and (args.gyro or args.accel):
        spec = replace(spec, name=f"{spec.name} + command-line figures")
    return spec


def run(args: argparse.Namespace) -> int:
    from imubounds.cli._common import Reporter
    from imubounds.stationary import noise_sim as sim

    rep = Reporter(args.quiet)
    if args.list_presets:
        for name, data in sim.PRESETS.items():
            print(f"{name}: {data.get('name', '')}")
            for kind in ("gyro", "accel"):
                if kind in data:
                    figs = ", ".join(f"{k}={v}" for k, v in data[kind].items())
                    print(f"  {kind}: {figs}")
        return 0
    spec = build_spec(args)
    if args.duration is not None and args.samples is not None:
        raise OptionError("give --duration or --samples, not both")
    duration = sim.parse_duration(args.duration) if args.duration is not None else None
    if duration is None and args.samples is None:
        raise OptionError("give the length of the run: --duration (e.g. 2h) or --samples")
    channels = [c.strip() for c in args.channels.split(",")] if args.channels else None
    log = sim.simulate(
        spec,
        args.rate,
        duration,
        n_samples=args.samples,
        seed=args.seed,
        channels=channels,
        t0=args.t0,
    )
    for note in spec.notes:
        rep.warn(note)
    path = sim.write_csv(log, args.out)
    if args.save_spec:
        from pathlib import Path

        Path(args.save_spec).write_text(json.dumps(spec.to_dict(), indent=2, default=float) + "\n")
    rep.info(
        f"wrote {log.n_samples} samples x {len(log.channels)} channels at {log.rate_hz:g} Hz "
        f"({log.duration_s:g} s) to {path} [{spec.name}; seed {args.seed}]"
    )
    if not args.quiet:
        print(str(path), file=sys.stdout)
    return 0
