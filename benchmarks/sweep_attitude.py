"""Sweep: the attitude states of mode full (docs/dynamic-method.md section 3b) against the
simulator's truth, and the margins against the independent reference limit
(tests/tightness_reference.py), over seeds.

Trips: the simulator's ``hills`` variant with GNSS position + velocity only (no compass,
no attitude stream), at 1 Hz and at 10 Hz, with the IMU preset given (MTx-grade by
default). Per trip: the share of the true roll and pitch inside the states (at the
epochs and at every truth sample over the links), their median half-width, whether the
run is guaranteed (and its failed checks), and per channel the median half-width /
reference limit at tau >= 10 s (accel_x, accel_y, gyro_z) and the verdicts of all six.

Usage: ``python benchmarks/sweep_attitude.py [--seeds N] [--preset mtx] [--rates 1,10]
[--duration S] [--fault CH=VALUE]`` (``--fault``: a bias step on channel CH at
mid-trip). The last line: ``trips <n> enclosed_all <n> false_withdrawals <n>
roll_median_deg <x> pitch_median_deg <x> heading_median_deg <x> worst_ratio <x> exceeds
{channel: trips}``.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))


def one(seed: int, preset: str, rate: float, duration: float,
        fault: tuple[str, float] | None = None) -> dict[str, Any]:
    from tests.tightness_reference import (
        accel_x_ratios,
        accel_y_ratios,
        gyro_z_ratios,
        tilt_floor,
    )

    from imubounds.dynamic.estimator.full import run_full
    from imubounds.dynamic.estimator.result import full_summary
    from imubounds.dynamic.scenario import Fault, make_trip

    faults = (Fault(fault[0], "bias", fault[1], 0.5 * duration),) if fault else ()
    res = make_trip("hills", seed=seed, aiding=("gnss", "gnss-vel"), imu_preset=preset,
                    gps_rate_hz=rate, duration_s=duration, distance_m=duration * 11.87,
                    hill_amplitude_m=15.0 * duration / 792.0, truth_rate_hz=100.0,
                    faults=faults)
    run = run_full(res.drive)
    d = full_summary(run, res.drive)
    st = run.ctx.attitude
    t_true = res.truth["t"] - run.ctx.imu.t0
    out: dict[str, Any] = {"seed": seed, "rate_hz": rate, "clean": bool(res.clean),
                           "guaranteed": bool(d["guaranteed"]),
                           "violations": [v["test"] for v in d["violations"]]}
    for ax in ("roll", "pitch"):
        a = st.angle(ax, "full")
        x = np.interp(st.te, t_true, res.truth[ax])
        out[f"{ax}_nodes_inside"] = float(np.mean((a.nodes.lo <= x) & (x <= a.nodes.hi)))
        k = np.searchsorted(st.te, t_true, side="right") - 1
        ok = (k >= 0) & (k < st.te.size - 1)
        kk = k[ok]
        y = res.truth[ax][ok]
        out[f"{ax}_pieces_inside"] = float(np.mean((a.pieces.lo[kk] <= y) & (y <= a.pieces.hi[kk])))
        out[f"{ax}_median_deg"] = float(np.degrees(np.median(0.5 * (a.nodes.hi - a.nodes.lo))))
    # heading: the smoother's model heading (ENU, from east counter-clockwise) against the
    # truth's yaw (the same convention), modulo 2 pi; a node without an interval is a miss
    sm = run.smoother
    assert sm is not None
    psi_lo, psi_hi = sm.X[:, 4, 0], sm.X[:, 4, 1]  # smoother.PSI
    yaw = np.interp(sm.te, t_true, np.unwrap(res.truth["yaw"]))
    mid = 0.5 * (psi_lo + psi_hi)
    fin = np.isfinite(mid)
    yy = yaw + 2 * np.pi * np.round((np.where(fin, mid, yaw) - yaw) / (2 * np.pi))
    out["heading_finite"] = float(np.mean(fin))
    out["heading_nodes_inside"] = float(np.mean(fin & (psi_lo <= yy) & (yy <= psi_hi)))
    hw = 0.5 * (psi_hi - psi_lo)
    out["heading_median_deg"] = float(np.degrees(np.median(np.where(fin, hw, np.inf))))
    # the vehicle's jerk bound minus the truth's (the floor's adversary uses the rest)
    acc = np.asarray(res.truth["acc_enu"], float)
    jerk = np.linalg.norm(np.diff(acc, axis=0), axis=1) / np.diff(res.truth["t"])
    slack = run.ctx.vehicle.max_jerk - float(np.max(jerk))
    out["jerk_slack"] = slack
    for ax, ch in (("pitch", "accel_x"), ("roll", "accel_y")):
        fl = tilt_floor(run.ctx, ch, jerk_slack=slack)
        out[f"{ax}_floor_deg"] = {k: round(float(np.degrees(v)), 3) for k, v in fl.items()}
    out["margins_10s"] = {}
    for ch, m in run.margins.items():
        lv = [lr for lr in m.levels if lr.tau_s >= 10.0]
        if lv:
            lr = lv[0]
            e = 0.5 * (np.asarray(lr.x_hi) - np.asarray(lr.x_lo))
            out["margins_10s"][ch] = [round(float(lr.tau_s), 3), float(np.median(e))]
    ratios = {}
    for ch, fn in (("accel_x", accel_x_ratios), ("accel_y", accel_y_ratios)):
        rows = fn(run.ctx, run.margins[ch], min_tau_s=10.0)
        ratios[ch] = {f"{r.tau_s:.3g}": round(r.ratio, 3) for r in rows}
    rows = [r for r in gyro_z_ratios(run.ctx, run.margins["gyro_z"]) if r.tau_s >= 10.0]
    ratios["gyro_z"] = {f"{r.tau_s:.3g}": round(r.ratio, 3) for r in rows}
    out["ratios"] = ratios
    out["verdicts"] = d["verdict"]
    out["windows_inside"] = {ch: m["enclosed_fraction"]
                             for ch, m in d.get("margins_truth", {}).items()}
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=50)
    ap.add_argument("--first", type=int, default=0)
    ap.add_argument("--preset", default="mtx")
    ap.add_argument("--rates", default="1,10")
    ap.add_argument("--duration", type=float, default=792.0)
    ap.add_argument("--json", default=None, help="write every trip's row to this file")
    ap.add_argument("--fault", default=None, metavar="CH=VALUE",
                    help="a bias step of VALUE (m/s^2 or rad/s) on channel CH at mid-trip")
    args = ap.parse_args()
    fault = None
    if args.fault:
        ch, val = args.fault.split("=")
        fault = (ch.strip(), float(val))
    rows = []
    for rate in (float(x) for x in args.rates.split(",")):
        for seed in range(args.first, args.first + args.seeds):
            t0 = time.perf_counter()
            r = one(seed, args.preset, rate, args.duration, fault)
            r["seconds"] = round(time.perf_counter() - t0, 1)
            rows.append(r)
            print(json.dumps(r), flush=True)
    if args.json:
        Path(args.json).write_text(json.dumps(rows, indent=1))
    enc = [all(r[k] == 1.0 for k in r if k.endswith("_inside") and k != "windows_inside"
               and not (k == "heading_nodes_inside" and not r["guaranteed"]))
           and all(v in (None, 1.0) for v in r["windows_inside"].values()) for r in rows]
    false_w = sum(1 for r in rows if r["clean"] and not r["guaranteed"])
    exc = {ch: sum(1 for r in rows if r["verdicts"].get(ch) == "exceeds")
           for ch in rows[0]["verdicts"]} if rows else {}
    worst = max((v for r in rows for ch in r["ratios"].values() for v in ch.values()),
                default=float("nan"))
    print(f"trips {len(rows)} enclosed_all {sum(enc)} false_withdrawals {false_w} "
          f"roll_median_deg {np.median([r['roll_median_deg'] for r in rows]):.3g} "
          f"pitch_median_deg {np.median([r['pitch_median_deg'] for r in rows]):.3g} "
          f"heading_median_deg {np.median([r['heading_median_deg'] for r in rows]):.3g} "
          f"worst_ratio {worst:.3g} exceeds {json.dumps(exc)}")


if __name__ == "__main__":
    main()
