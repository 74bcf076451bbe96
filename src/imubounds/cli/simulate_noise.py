"""``imubounds simulate-noise``: generate IMU sensor noise as a CSV log the readers take."""

from __future__ import annotations

import argparse
import math
import sys
from typing import Any

from imubounds.cli._common import (
    add_force_option,
    finite_float,
    nonneg_int,
    positive_float,
    positive_int,
)
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
    p.add_argument(
        "-o", "--out", type=csv_name, metavar="CSV",
        help="output CSV (.csv or .csv.gz); required unless --list-presets",
    )
    add_force_option(p)
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
        type=bias_range_text,
        metavar="LO,HI",
        help="tau range (s) where B is flicker noise (default 1,1000)",
    )
    run_g = p.add_argument_group("the run")
    run_g.add_argument(
        "--rate",
        type=positive_float,
        metavar="HZ",
        help="sample rate (default: the noise.json's or the spec's)",
    )
    run_g.add_argument(
        "--duration", type=duration_text, metavar="T", help="length: 7200, 7200s, 90min, 2h"
    )
    run_g.add_argument(
        "--samples", type=at_least_two, metavar="N", help="length in samples (at least 2)"
    )
    run_g.add_argument("--seed", type=nonneg_int, default=0, help="random seed (default 0)")
    run_g.add_argument(
        "--t0", type=finite_float, default=0.0, metavar="S", help="first time stamp"
    )
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
    if not (math.isfinite(hi) and 0 < lo < hi):
        raise OptionError(f"--bias-tau-range {text!r}: need 0 < LO < HI, both finite")
    return lo, hi


def _parse_type(check: Any) -> Any:
    """An argparse type that runs ``check(text)`` and passes the text on."""

    def parse(text: str) -> str:
        try:
            check(text)
        except OptionError as err:
            raise argparse.ArgumentTypeError(str(err).split(": ", 1)[-1]) from None
        except OverflowError:
            raise argparse.ArgumentTypeError(f"{text!r} is too large; must be finite") from None
        return text

    parse.__name__ = getattr(check, "__name__", "value")
    return parse


def _duration_check(text: str) -> None:
    from imubounds.stationary.noise_sim import parse_duration

    d = parse_duration(text)
    if not (math.isfinite(d) and d > 0):
        raise OptionError(f"--duration {text!r}: must be a positive, finite length")


bias_range_text = _parse_type(_bias_range)
duration_text = _parse_type(_duration_check)

#: Endings of the CSV written by -o (the readers choose the format by the ending).
CSV_ENDINGS = (".csv", ".csv.gz", ".txt", ".txt.gz", ".dat", ".dat.gz")


def csv_name(text: str) -> str:
    """An output name ending like a CSV (``.csv``, ``.csv.gz``, ``.txt`` ...)."""
    if not text.lower().endswith(CSV_ENDINGS):
        raise argparse.ArgumentTypeError(
            f"{text!r} does not end in .csv or .csv.gz (the log is written as CSV text; "
            "a name ending otherwise would be read back as another format)"
        )
    return text


def at_least_two(text: str) -> int:
    """A whole number >= 2 (a log needs two samples for its rate)."""
    n = positive_int(text)
    if n < 2:
        raise argparse.ArgumentTypeError(f"must be at least 2, got {text}")
    return n


def _check_sources(args: argparse.Namespace) -> list[str]:
    """The one source of figures (--preset, --from-noise, --spec), checked for consistency."""
    sources = [s for s in (args.preset, args.from_noise, args.spec) if s]
    if len(sources) > 1:
        raise OptionError("give only one of --preset, --from-noise, --spec")
    if not sources and not (args.gyro or args.accel):
        raise OptionError(
            "nothing to simulate: give --preset, --from-noise, --spec or --gyro/--accel figures"
        )
    if (args.models or args.terms != "fit") and not args.from_noise:
        raise OptionError("--terms and --models apply only with --from-noise")
    return sources


def build_spec(args: argparse.Namespace) -> Any:
    """The :class:`~imubounds.stationary.noise_sim.NoiseSpec` the options describe."""
    from dataclasses import replace

    from imubounds.stationary import noise_sim as sim

    sources = _check_sources(args)
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
        if getattr(args, kind):
            spec = spec.with_overrides(kind, values)
        elif tau_range is not None:  # the flicker band only: the axes the spec has
            spec = spec.with_overrides(kind, values, add_missing=False)
    if sources and (args.gyro or args.accel):
        spec = replace(spec, name=f"{spec.name} + command-line figures")
    return spec


def _check_text(path: str, option: str) -> None:
    """A spec or noise.json must be UTF-8 text: a binary file is an error naming it."""
    from imubounds.errors import InputError

    try:
        with open(path, "rb") as fh:
            head = fh.read(1 << 20)
        head.decode("utf-8")
        ok = b"\0" not in head
    except UnicodeDecodeError as err:
        ok = err.start >= len(head) - 4  # a character cut by the 1 MiB read is fine
    except OSError as err:
        raise InputError(f"{path} ({option}): cannot read ({err.strerror or err})") from err
    if not ok:
        raise InputError(
            f"{path} ({option}): not a text file (binary, or not UTF-8); give the noise.json "
            "of 'imubounds static' or a YAML/JSON noise spec"
        )


def _check_figures(spec: Any) -> None:
    """Every channel of the spec must have a noise figure: an empty block (``gyro: {}``)
    would simulate exact zeros."""
    empty = [c for c, ax in spec.channels.items()
             if not any(getattr(ax, k, 0) for k in ("Q", "N", "B", "K", "R", "bias_sigma",
                                                    "gauss_markov", "ar"))]
    if empty:
        kinds = sorted({c.split("_")[0] for c in empty})
        raise OptionError(
            f"{spec.name}: {', '.join(empty)} ha{'s' if len(empty) == 1 else 've'} no noise "
            f"figure (the {' and '.join(kinds)} block is empty or all zero): give at least one "
            "of Q, N, B, K, R, or leave the block out"
        )


def run(args: argparse.Namespace) -> int:
    from imubounds.cli._common import Reporter
    from imubounds.io.outputs import check_output_file, output_file, write_json
    from imubounds.io.validate import check_input_path
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
    if args.out is None:
        raise OptionError("give the output CSV with -o/--out (.csv or .csv.gz)")
    # Inputs are checked before they are read (a named pipe would block), outputs
    # before the simulation (nothing is computed for a file that may not be written).
    _check_sources(args)
    inputs = []
    for option, path, what in (
        ("--from-noise", args.from_noise, "noise.json"),
        ("--spec", args.spec, "noise spec"),
    ):
        if path is not None:
            inputs.append(check_input_path(path, what=what, option=option))
    check_output_file(args.out, force=args.force, inputs=inputs, option="-o")
    if args.save_spec:
        check_output_file(
            args.save_spec, force=args.force, inputs=inputs, option="--save-spec",
            others=[args.out],
        )
    for option, path in (("--from-noise", args.from_noise), ("--spec", args.spec)):
        if path is not None:
            _check_text(path, option)
    spec = build_spec(args)
    _check_figures(spec)
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
    with output_file(args.out, force=args.force, inputs=inputs, option="-o") as tmp:
        sim.write_csv(log, tmp)
    if args.save_spec:
        with output_file(
            args.save_spec, force=args.force, inputs=inputs, option="--save-spec"
        ) as tmp:
            write_json(tmp, spec.to_dict())
    rep.info(
        f"wrote {log.n_samples} samples x {len(log.channels)} channels at {log.rate_hz:g} Hz "
        f"({log.duration_s:g} s) to {args.out} [{spec.name}; seed {args.seed}]"
    )
    if not args.quiet:
        print(str(args.out), file=sys.stdout)
    return 0
