"""Warm-up, drift and false flags of the stationarity checks on simulated static logs.

One command::

    .venv/bin/python benchmarks/bench_drift.py            # 100 Hz, 2 h, 6 channels
    .venv/bin/python benchmarks/bench_drift.py --rate 10  # the same at 10 Hz (faster)

The logs come from ``tests/drift_sim.py`` (numpy only, no code shared with
``imubounds.stationary.noise_sim``): white + flicker + rate random walk per channel
(gyro N = 3e-4 rad/s/√Hz, B = 5e-5 rad/s, K = 1e-6 rad/s/√s; accelerometer 1e-3,
1e-4, 2e-6 in m/s²), and

* ``--warm`` logs with a warm-up 10·B·exp(−t/180 s) (``--warm-amp`` for another
  amplitude): how many channels are flagged, how many of the flagged have T and the
  end within 20 % of the truth, how many T intervals hold the truth, the cut per
  channel, and the information limit: the Cramér–Rao bound of T under the true noise;
* ``--clean`` logs without anything: logs with a false warm-up flag, and logs with
  a channel called not stationary;
* ramps of 20·B and 100·B over the log and thermal settlings 20·B·(1 − exp(−t/1 h))
  and 100·B (``--drift`` logs each): channels called not stationary, channels left
  stationary with a warning that the resolved R or K may be the trend, and channels
  left stationary with R or K resolved and no word (the drift absorbed silently);
* the same clean logs with a Gauss–Markov component (σ = B, τc = 300 s).

Prints the counts; exits 0. Runs ``stationarity()`` of each channel, the check the
pipeline runs before the Allan analysis (a few minutes at 100 Hz on a loaded host).
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from tests.drift_sim import CHANNELS, Disturbance, axis, static_log  # noqa: E402

from imubounds.stationary.allan import allan  # noqa: E402
from imubounds.stationary.stationarity import stationarity  # noqa: E402
from imubounds.stationary.terms import analyse_curve  # noqa: E402

T_TRUE = 180.0
END_TRUE = T_TRUE * math.log(20.0)


def channels(seed: int, rate: float, **kw: object) -> list[tuple[str, object]]:
    log = static_log(seed, rate_hz=rate, **kw)  # type: ignore[arg-type]
    return [(c, stationarity(log[c], rate)) for c in CHANNELS]


def with_terms(seed: int, rate: float, **kw: object) -> list[tuple[Any, list[str], bool]]:
    """What ``imubounds static`` runs per channel: the Allan curve, the stationarity
    checks with it, the terms. Per channel: the checks, the resolved R and K, and
    whether a warning names a trend those terms may describe."""
    log = static_log(seed, rate_hz=rate, **kw)  # type: ignore[arg-type]
    out = []
    for c in CHANNELS:
        curve = allan(log[c], rate, "octave")
        try:
            st = stationarity(log[c], rate, curve=curve)
        except TypeError:  # an older stationarity() without the curve
            st = stationarity(log[c], rate)
        sel = analyse_curve(curve)[2]
        resolved = [t for t in ("R", "K") if sel.status(t) == "resolved"]
        named = hasattr(st, "trend_message") and st.trend_message(resolved) is not None
        out.append((st, resolved, bool(named)))
    return out


def information_limit(rate: float, amp: float) -> str:
    """The Cramér–Rao bound of T (1 σ, relative) for each channel kind: the Fisher
    information of (A, T) in the block means under the true noise (its covariance
    from imubounds.stationary.drift, checked against the Allan responses in
    tests/test_drift.py), and the chance an efficient estimate lands within 20 %."""
    try:
        from imubounds.stationary import drift
    except ImportError:  # an older imubounds
        return "n/a (no imubounds.stationary.drift)"
    n = int(round(2.0 * 3600.0 * rate))
    bl = drift.block_means(np.zeros(n), rate)
    units = drift.unit_covariances(bl)
    out = []
    for kind in ("gyro_x", "accel_x"):
        a = axis(kind)
        model = drift.NoiseModel({"Q": 0.0, "N": a.N, "B": a.B, "K": a.K, "R": 0.0},
                                 (1.0, 1.0), "truth")  # fmt: skip
        gls = drift.Gls(bl, model, units)
        h = 1e-4 * T_TRUE
        d_t = amp * a.B * (bl.average("exp", T_TRUE + h) - bl.average("exp", T_TRUE - h)) / (2 * h)
        jac = gls.whiten(np.column_stack([bl.average("exp", T_TRUE), d_t]))
        sd = math.sqrt(float(np.linalg.inv(jac.T @ jac)[1, 1])) / T_TRUE
        out.append(f"{kind[:-2]} {sd:.0%} (P within 20 % {math.erf(0.2 / sd / math.sqrt(2)):.2f})")
    return "; ".join(out)


def warm(args: argparse.Namespace) -> None:
    flagged = t_ok = end_ok = covered = 0
    ts, cuts, cut_other = [], [], 0
    for s in range(args.warm):
        res = channels(1000 + s, args.rate, disturbance=Disturbance(args.warm_amp, T_TRUE))
        ends = [st.warmup.end_s for _, st in res if st.warmup is not None]  # type: ignore[attr-defined]
        for _, st in res:
            w = st.warmup  # type: ignore[attr-defined]
            if w is None:
                # the cut --cut-warmup gives a channel without a warm-up of its own: none
                # (per channel), or the log's latest end (one cut for every channel)
                per_channel = any(hasattr(x.warmup, "cut_s") for _, x in res if x.warmup)  # type: ignore[attr-defined]
                cut_other += bool(ends) and not per_channel
                continue
            flagged += 1
            ts.append(w.time_constant_s)
            t_ok += abs(w.time_constant_s / T_TRUE - 1.0) <= 0.2
            end_ok += abs(w.end_s / END_TRUE - 1.0) <= 0.2
            ci = getattr(w, "time_constant_ci_s", (math.nan, math.nan))
            covered += ci[0] <= T_TRUE <= ci[1]
            cuts.append(getattr(w, "cut_s", max(ends)))
    n = 6 * args.warm
    print(f"warm-up (T = {T_TRUE:g} s, amplitude {args.warm_amp:g} B), {args.warm} logs, "
          f"{n} channels:")  # fmt: skip
    print(f"  flagged {flagged}/{n}; of them T within 20 %: {t_ok}, end within 20 %: {end_ok}, "
          f"T's 68 % interval holds the truth: {covered}")  # fmt: skip
    print(f"  information limit (Cramer-Rao, true noise): sd(T)/T = "
          f"{information_limit(args.rate, args.warm_amp)}")  # fmt: skip
    if ts:
        print(f"  T from {min(ts):.0f} to {max(ts):.0f} s (median {np.median(ts):.0f} s); "
              f"--cut-warmup: flagged channels cut from {min(cuts):.0f} to {max(cuts):.0f} s "
              f"(median {np.median(cuts):.0f} s; true end {END_TRUE:.0f} s); channels "
              f"without a warm-up cut: {cut_other}")  # fmt: skip


def clean(args: argparse.Namespace, label: str, **kw: object) -> None:
    warm_logs, nonstat_logs, nonstat_ch, drift_ch, named = [], 0, 0, 0, 0
    zs = []
    for s in range(args.clean):
        terms = with_terms(2000 + s, args.rate, **kw)
        named += sum(t for _, _, t in terms)
        res = [(c, st) for c, (st, _, _) in zip(CHANNELS, terms, strict=True)]
        zs += [abs(st.trend.z) for _, st in res if getattr(st, "trend", None) is not None]
        ends = [round(st.warmup.end_s) for _, st in res if st.warmup is not None]
        if ends:
            warm_logs.append(ends)
        bad = sum(not st.stationary for _, st in res)
        drift_ch += sum(getattr(st, "drift", None) is not None for _, st in res)
        nonstat_ch += bad
        nonstat_logs += bad > 0
    print(f"{label}, {args.clean} logs: false warm-up flag on {len(warm_logs)} logs "
          f"(ends {warm_logs}); not stationary on {nonstat_logs} logs "
          f"({nonstat_ch} of {6 * args.clean} channels: {drift_ch} by a drift, the others "
          f"by the windows' test); a trend named on {named} channels"
          + (f"; the slope's |z| at most {max(zs):.2f}" if zs else ""))  # fmt: skip


def drifts(args: argparse.Namespace) -> None:
    cases = {
        "ramp 20 B": Disturbance(ramp_total=20.0),
        "ramp 100 B": Disturbance(ramp_total=100.0),
        "thermal 20 B, tau 1 h": Disturbance(thermal_amp=20.0),
        "thermal 100 B, tau 1 h": Disturbance(thermal_amp=100.0),
    }
    for label, dist in cases.items():
        nonstat = drifted = named = silent = 0
        for s in range(args.drift):
            res = with_terms(3000 + s, args.rate, disturbance=dist, k_scale=args.k_scale)
            for st, resolved, trend in res:
                nonstat += not st.stationary
                drifted += getattr(st, "drift", None) is not None
                named += trend
                silent += bool(st.stationary and resolved and not trend)
        print(f"{label}: not stationary on {nonstat}/{6 * args.drift} channels "
              f"(drift named on {drifted}); stationary with a warning that the resolved R "
              f"or K may be the trend: {named}; stationary with R or K resolved and no "
              f"word (absorbed silently): {silent}")  # fmt: skip


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rate", type=float, default=100.0, help="sample rate, Hz (default 100)")
    ap.add_argument("--warm", type=int, default=10, help="logs with a warm-up (default 10)")
    ap.add_argument("--warm-amp", type=float, default=10.0,
                    help="the warm-up's amplitude in units of B (default 10)")  # fmt: skip
    ap.add_argument("--clean", type=int, default=50, help="clean logs (default 50)")
    ap.add_argument("--drift", type=int, default=7, help="logs per drift case (default 7)")
    ap.add_argument("--no-gm", action="store_true", help="skip the Gauss-Markov clean logs")
    ap.add_argument("--k-scale", type=float, default=1.0,
                    help="K of the drift logs times this (default 1)")  # fmt: skip
    ap.add_argument("--only", choices=("warm", "clean", "drift"), help="run one part")
    args = ap.parse_args()
    t0 = time.perf_counter()
    print(f"{args.rate:g} Hz, 2 h, channels {', '.join(CHANNELS)}")
    if args.only in (None, "warm"):
        warm(args)
    if args.only in (None, "clean"):
        clean(args, "clean")
    if args.only in (None, "drift"):
        drifts(args)
    if not args.no_gm and args.only in (None, "clean"):
        clean(args, "clean + Gauss-Markov (sigma = B, 300 s)", gm_sigma_over_b=1.0)
    print(f"({time.perf_counter() - t0:.0f} s)")


if __name__ == "__main__":
    main()
