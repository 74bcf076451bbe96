"""Mode full: the error budget, the window margins, the smoother (compiled vs reference),
every link and state against the truth on short trips, the change test, real drives
(the 200-trip soundness test, and issue 11's informative and detection criteria, run
on the product's simulator: test_dynamic_soundness.py, test_dynamic_simulated.py)."""

from __future__ import annotations

import math
from fractions import Fraction
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from imubounds.dynamic.estimator import dynamic_margins
from imubounds.dynamic.estimator import full as F
from imubounds.dynamic.estimator import smoother as SM
from imubounds.dynamic.estimator.budget import (
    ChannelNoise,
    box_sum_variance,
    centered_ms_bound,
    kernel_variance,
    read_noise_json,
)
from imubounds.dynamic.estimator.inputs import PiecewiseSignal
from imubounds.errors import InputError, OptionError
from imubounds.units import DEG
from tests.smoother_reference import (
    preintegrate_reference,
    sweep_reference,
)
from tests.trips import make_trip, record

SHORT = {"duration_s": 240.0, "distance_m": 2600.0, "corner_m": 80.0}
QUANTITIES = ("position", "heading", "u", "v", "speed")


def enclosed_everywhere(d: dict) -> list[str]:
    """Names of the quantities (states, biases, window means) whose truth left the
    intervals at some step."""
    bad = [k for k, v in d["enclosure"].items() if isinstance(v, float) and v < 1.0]
    bad += [
        f"window {ch}" for ch, m in d.get("margins_truth", {}).items()
        if m["enclosed_fraction"] is not None and m["enclosed_fraction"] < 1.0
    ]
    return bad


# ------------------------------------------------------------------------- budget


def test_read_noise_json_prefers_selected_then_stationary_then_fit(tmp_path: Path) -> None:
    doc = {
        "channels": {
            "accel_x": {
                "noise": {
                    "selected": {"N": {"value": 0.003, "status": "ok"}, "B": {"value": 0.01}},
                    "fit": {"N": {"value": 9.0}, "K": {"value": 1e-5}},
                },
                "stationary": {"N": 7.0, "B": 7.0},
            },
            "gyro_z": {
                "stationary": {"N": 1e-4, "B": 2e-5},
                "noise": {"slope": {"Q": {"value": 1e-6}}},
            },
        }
    }
    got = read_noise_json(doc)
    assert got["accel_x"] == {"N": 0.003, "B": 0.01, "K": 1e-5}
    assert got["gyro_z"] == {"N": 1e-4, "B": 2e-5, "Q": 1e-6}
    p = tmp_path / "noise.json"
    p.write_text("{")
    with pytest.raises(InputError, match="cannot read noise.json"):
        read_noise_json(p)
    with pytest.raises(InputError, match="no 'channels'"):
        read_noise_json({"x": 1})


def _brute_box_variance(cn: ChannelNoise, m: int, dt: float) -> float:
    idx = np.arange(m)
    C = np.eye(m) * cn.N**2 / dt
    for s, b in cn.gm_terms():
        C += s * s * np.exp(-b * dt * np.abs(idx[:, None] - idx[None, :]))
    return float(np.sum(C)) * dt * dt


@pytest.mark.parametrize("m", [1, 2, 7, 100, 1500])
def test_box_sum_variance_equals_covariance_sum(m: int) -> None:
    cn = ChannelNoise("gyro_z", N=0.05 * DEG, B=1.0 * DEG)
    exact = _brute_box_variance(cn, m, 0.01)
    got = box_sum_variance(cn, m, 0.01)
    assert got == pytest.approx(exact, rel=1e-8), f"{got} vs {exact}"
    assert got >= exact  # rounded up
    c = np.full(m, 1.0 / m)
    assert kernel_variance(cn, c, 0.01, False) == pytest.approx(got / (m * 0.01) ** 2, rel=1e-8)


def test_centered_ms_bound_covers_simulated_flicker() -> None:
    """The deviation bound of the transport term holds for the noise simulator's own flicker
    process (300 draws, per-window level 1e-3: no draw may exceed it)."""
    from imubounds.stationary.noise_sim import AxisNoise, simulate_axis

    cn = ChannelNoise("gyro_z", N=0.05 * DEG, B=1.0 * DEG)
    for m in (100, 2000):
        b = centered_ms_bound(cn, m, 0.01, 1e-3)
        worst = 0.0
        for s in range(300):
            y = simulate_axis(AxisNoise(N=cn.N, B=cn.B), m, 100.0, seed=s)
            worst = max(worst, float(np.mean((y - y.mean()) ** 2)))
        assert worst < b, f"m={m}: worst mean square {worst:.3g} above the bound {b:.3g}"


@settings(max_examples=40, deadline=None)
@given(
    st.lists(st.floats(-50, 50), min_size=3, max_size=40),
    st.floats(0.0, 1.0),
    st.floats(0.0, 1.0),
)
def test_piecewise_integral_encloses_exact(vals: list[float], fa: float, fb: float) -> None:
    """int_a^b y and the mean of Y over [a, b] contain the exact rational values."""
    n = len(vals)
    bnd = np.arange(n + 1) * 0.01 + 100.0
    y = np.array(vals)
    sig = PiecewiseSignal(bnd, y)
    a, b = sorted((bnd[0] + fa * n * 0.01, bnd[0] + fb * n * 0.01))
    lo, hi = sig.integral(np.array([a]), np.array([b]))

    def exact_int(t0: float, t1: float) -> Fraction:
        acc = Fraction(0)
        for k in range(n):
            s0, s1 = max(Fraction(bnd[k]), Fraction(t0)), min(Fraction(bnd[k + 1]), Fraction(t1))
            if s1 > s0:
                acc += Fraction(y[k]) * (s1 - s0)
        return acc

    ex = exact_int(a, b)
    assert Fraction(lo[0]) <= ex <= Fraction(hi[0])
    km = sig.kernel_mean(np.array([a]), np.array([a]), np.array([b]), np.array([b]),
                         np.array([b - a]) if b > a else np.array([1.0]))
    if b > a:
        assert Fraction(km.lo[0]) <= ex / (Fraction(b) - Fraction(a)) <= Fraction(km.hi[0])


# ---------------------------------------------------------------- compiled vs reference


def _links_and_states(variant: str = "paper", **kw: object) -> tuple:
    drive, _ = make_trip(variant, 4, duration_s=40.0, distance_m=300.0, corner_m=40.0,
                         ramp_s=10.0, **kw)
    ctx = F.build_context(drive, None, {})
    beta0 = np.array([[-0.05, 0.05], [-0.05, 0.06], [-0.02, 0.01]])
    prior, meas, has = F._smoother_inputs(ctx)
    return ctx, beta0, prior, meas, has


def test_preintegrate_compiled_equals_reference() -> None:
    ctx, beta0, *_ = _links_and_states("hills")
    imu, ag, veh = ctx.imu, ctx.aiding, ctx.vehicle
    te = ctx.te[:12]
    rl, rh, pl, ph = ag.tilt_range(imu.bnd[:-1], imu.bnd[1:], veh)
    args = []
    for ch in ("accel_x", "accel_y", "accel_z", "gyro_z"):
        s = imu.sig[ch]
        args.append(np.ascontiguousarray(np.stack([s.y, s.y], -1)))
    n = te.size - 1
    out = [np.empty((n, 2)), np.empty((n, 2, 2)), np.empty((n, 2, 2)), np.empty((n, 2))]
    SM.preintegrate(te, imu.bnd, *args, rl, rh, pl, ph, 0.001, *out)
    ref = preintegrate_reference(te, imu.bnd, *args, rl, rh, pl, ph, 0.001)
    for a, b in zip(out, ref, strict=True):
        np.testing.assert_array_equal(a, b)


def test_sweep_compiled_equals_reference() -> None:
    ctx, beta0, prior, meas, has = _links_and_states("paper")
    links = F._link_errors(ctx, beta0)
    n = 30
    X = np.maximum(prior[:n], meas[:n])
    X[..., 1] = np.minimum(prior[:n, :, 1], meas[:n, :, 1])
    X1, X2 = X.copy(), X.copy()
    b1, b2 = beta0.copy(), beta0.copy()
    link = np.ones(n - 1, dtype=np.bool_)
    args = (links["YR"][: n - 1], links["FH"][: n - 1], links["QH"][: n - 1])
    dt = np.diff(ctx.te[:n])
    st_ = SM.sweep(X1, link, *args, dt, b1, 0.3, True, 1e-3)
    ok = sweep_reference(X2, link, *args, dt, b2, 0.3, True)
    assert st_[0] == 0 and ok
    np.testing.assert_array_equal(X1, X2)
    np.testing.assert_array_equal(b1, b2)
    # and it contracts something
    assert np.sum(X1[..., 1] - X1[..., 0] < X[..., 1] - X[..., 0]) > 0


# ------------------------------------------------------------------------- soundness


@pytest.mark.parametrize("variant", ["hills", "sharp", "dvl"])
def test_every_link_constraint_holds_for_the_truth(variant: str) -> None:
    """Each link of the smoother (heading increment, heading-frame velocity and position
    increments) contains the true increment when the bias states take their true values."""
    from tests.trips import _truth, variant_config

    kw = {**SHORT, "imu_hz": 50.0}
    drive, errs = make_trip(variant, 12, **kw)
    ctx = F.build_context(drive, None, {})
    beta0 = np.array([[-0.1, 0.1], [-0.1, 0.1], [-0.1, 0.1]])
    links = F._link_errors(ctx, beta0)
    te = ctx.te + ctx.imu.t0
    tr = _truth(variant_config(variant, **kw), te)
    vh = tr["u"] * np.cos(tr["pitch"])
    ve, vn, psi = vh * np.cos(tr["psi"]), vh * np.sin(tr["psi"]), tr["psi"]
    b = [errs.turn_on["accel_x"], errs.turn_on["accel_y"], errs.turn_on["gyro_z"]]
    D = np.diff(te)
    c, s = np.cos(psi[:-1]), np.sin(psi[:-1])
    checks = {
        "heading": (np.diff(psi), links["YR"], D * b[2]),
    }
    dve, dvn = np.diff(ve), np.diff(vn)
    de = np.diff(tr["east"]) - ve[:-1] * D
    dn = np.diff(tr["north"]) - vn[:-1] * D
    for a, (f_true, q_true) in enumerate(
        ((c * dve + s * dvn, c * de + s * dn), (-s * dve + c * dvn, -s * de + c * dn))
    ):
        checks[f"velocity {a}"] = (f_true, links["FH"][:, a], D * b[a])
        checks[f"position {a}"] = (q_true, links["QH"][:, a], D * D / 2 * b[a])
    for name, (x, box, shift) in checks.items():
        lo, hi = box[:, 0] - shift, box[:, 1] - shift
        bad = np.flatnonzero((x < lo) | (x > hi))
        assert bad.size == 0, f"{variant} {name}: {bad.size} links miss the truth (first {bad[:5]})"



@pytest.mark.parametrize(
    "variant", ["paper", "hills", "sharp", "gnss10", "pos_only", "dvl", "outliers"]
)
def test_truth_inside_every_interval_short_trips(variant: str) -> None:
    """Realistic noise (biased, Gaussian, flicker, outliers): every state, bias and window
    mean of a short trip of each variant is enclosed at every step."""
    drive, errs = make_trip(variant, 11, imu_hz=50.0, **SHORT)
    r = dynamic_margins(drive)
    d = r.to_dict()
    bad = enclosed_everywhere(d)
    rec = record(r, errs)
    clean = all(v == 0 for k, v in rec.items() if k not in ("gnss_outliers", "gnss_position"))
    assert clean, rec
    misses = d["enclosure"]["first_miss_t_s"]
    assert not bad, f"{variant}: truth outside {bad}; first misses {misses}"
    if variant == "outliers":
        # every outlier the record lists is dropped, located and attributed
        times = {round(x["t_s"], 3) for x in d["empty_intersections"]["dropped"]}
        assert errs.gnss_outlier is not None
        t_out = {round(float(t), 3) for t in drive.gnss.t[errs.gnss_outlier]}  # type: ignore[union-attr]
        assert t_out <= times, f"outliers at {sorted(t_out)} not all dropped ({sorted(times)})"


def test_assumptions_and_budget_are_stated() -> None:
    drive, _ = make_trip("paper", 3, imu_hz=50.0, **SHORT)
    d = dynamic_margins(drive).to_dict()
    assert d["guaranteed"] is True and "probability at least 0.99" in d["statement"]
    assert any("non-holonomic" in a for a in d["assumptions"])
    for ch in ("accel_x", "accel_y", "accel_z", "gyro_x", "gyro_y", "gyro_z"):
        terms = {row["term"]: row for row in d["budget"][ch]}
        assert terms["turn-on bias bound"]["source"] == "drive.yaml"
        assert terms["white noise density N"]["source"].startswith("preset")
        for row in d["budget"][ch]:
            assert set(row) == {"term", "value", "unit", "source", "assumption"}
    fams = d["alpha"]["families"]
    assert sum(f["alpha"] for f in fams.values()) == pytest.approx(0.01)
    for rows in d["margins"].values():
        for row in rows:
            assert {"tau_s", "halfwidth_max", "halfwidth_median", "stationary",
                    "exceeds_fraction"} <= set(row)


# ------------------------------------------------------------------------ informative


def _margin_at(d: dict, ch: str, tau: float) -> float:
    rows = d["margins"][ch]
    row = min(rows, key=lambda r: abs(math.log(r["tau_s"] / tau)))
    return float(row["halfwidth_median"])


def test_heading_from_the_gnss_course_without_a_heading_sensor() -> None:
    """GNSS position + velocity only (no compass, no attitude): the heading comes from the
    course (lateral bound, no reversing), the truth stays inside, the gyro gets margins
    and the accelerometer margins stay informative; --reverses turns the course off."""
    drive, errs = make_trip("pos_vel", 23, imu_hz=50.0, compass=False, attitude=False, **SHORT)
    r = dynamic_margins(drive, max_tilt_deg=0.2)  # a flat trip
    d = r.to_dict()
    assert not enclosed_everywhere(d), d["enclosure"]
    assert r.full.margins["gyro_z"].source == "heading (GNSS course)"
    assert d["verdict"]["gyro_z"] == "consistent"
    assert _margin_at(d, "accel_x", 10.0) <= 0.5
    assert any("GNSS course" in a for a in d["assumptions"] + d.get("notes", []))
    d2 = dynamic_margins(drive, reverses=True, max_tilt_deg=0.2).to_dict()
    assert d2["verdict"]["gyro_z"] == "undecided"
    assert _margin_at(d2, "accel_x", 10.0) > 2 * _margin_at(d, "accel_x", 10.0)


def test_change_test_detects_a_step_inside_the_level_band() -> None:
    """With a stated drift bound (as the simulator states it) the level band of an MTx
    accelerometer is ~0.25 m/s^2; a 0.2 m/s^2 step at mid-trip stays inside it but the
    change between adjacent windows (turn-on cancels, the flicker changes by its Allan
    deviation) exceeds its band; the clean trip has no change outside."""
    kw = dict(state_drift=True, dvl_bound=0.05)
    drive, _ = make_trip("dvl", 32, **kw)
    d = dynamic_margins(drive).to_dict()
    assert "exceeds" not in d["verdict"].values(), d["verdict"]
    drive, _ = make_trip("dvl", 32, faults=[("accel_x", 0.2, 396.0)], **kw)
    r = dynamic_margins(drive)
    d = r.to_dict()
    assert d["verdict"]["accel_x"] == "exceeds" and d["verdict"]["gyro_z"] != "exceeds"
    tests = {e["test"] for e in r.full.margins["accel_x"].exceeding}
    assert "change" in tests
    rows = {round(m["tau_s"]): m for m in d["margins"]["accel_x"]}
    row = min(rows.values(), key=lambda m: abs(math.log(m["tau_s"] / 10.0)))
    assert row["change_stationary"] < 0.6 * row["stationary"]


def test_gyro_fault_does_not_make_the_accelerometers_exceed() -> None:
    """The gyro enters the accelerometers' aided intervals only as a magnitude bound in the
    transport terms: a 30 deg/s gyro fault from the start leaves them consistent."""
    drive, _ = make_trip("paper", 31, faults=[("gyro_z", 30 * DEG, 0.0)])
    d = dynamic_margins(drive).to_dict()
    assert d["verdict"]["gyro_z"] == "exceeds"
    assert d["verdict"]["accel_x"] != "exceeds" and d["verdict"]["accel_y"] != "exceeds"


# -------------------------------------------------------------------------- real data


def test_comma2k19_encloses_truth(shared_data: Path) -> None:
    from imubounds.cli.dynamic import load_drive

    drive = load_drive([str(shared_data / "dynamic" / "comma2k19_example1")])
    d = dynamic_margins(drive).to_dict()
    enc = d["enclosure"]
    for q in ("position", "heading", "speed", "u", "v"):
        assert enc[q] == 1.0, f"{q}: {enc[q]} (first miss {enc['first_miss_t_s']})"
    assert enc["epochs"] > 500
    rows = d["margins"]["gyro_z"]
    assert len(rows) >= 8 and rows[-1]["tau_s"] >= 8.0


def test_vn100_runs_and_every_drop_is_located(shared_data: Path) -> None:
    from imubounds.cli.dynamic import load_drive

    drive = load_drive([str(shared_data / "dynamic" / "vn100_bu353_circle")])
    d = dynamic_margins(drive).to_dict()
    ei = d["empty_intersections"]
    assert ei["count"] == len(ei["dropped"]) == sum(ei["by_sensor"].values())
    for x in ei["dropped"]:
        assert x["sensor"] and math.isfinite(x["t_s"]) and x["reason"]
    assert any("AHRS" in n for n in d["notes"])  # the yaw comes from the VN-100 itself


# ---------------------------------------------------------------------------- options


def test_bad_options_refused() -> None:
    drive, _ = make_trip("paper", 0, imu_hz=20.0, **SHORT)
    with pytest.raises(OptionError, match="alpha"):
        dynamic_margins(drive, alpha=1.5)
    with pytest.raises(OptionError, match="unknown option"):
        dynamic_margins(drive, nonsense=1)
    with pytest.raises(OptionError, match="mode"):
        dynamic_margins(drive, mode="both")


def test_result_frame_and_plot() -> None:
    drive, _ = make_trip("paper", 1, imu_hz=20.0, **SHORT)
    r = dynamic_margins(drive)
    df = r.to_frame()
    assert {"channel", "tau_s", "halfwidth_median", "stationary"} <= set(df.columns)
    assert set(df["channel"]) >= {"accel_x", "accel_y", "gyro_z"}
    fig = r.plot()
    assert len(fig.axes) == 2
    from matplotlib.figure import Figure

    ax = Figure().add_subplot(1, 1, 1)
    assert r.plot(ax=ax) is ax.figure


@pytest.mark.slow
@pytest.mark.parametrize("ch", ["accel_x", "gyro_z"])
def test_sensitivity_smallest_detected_bias(ch: str) -> None:
    """The smallest bias step injected at mid-trip that gives ``exceeds`` on its channel
    (and on no other), as a multiple of the channel's bias bound (turn-on bound + stated
    drift bound, as the simulator states them), by bisection on the DVL + compass trip:
    below one bias bound for both channels (the change test: turn-on cancels)."""
    kw = dict(state_drift=True, imu_hz=50.0)

    def detected(val: float) -> tuple[bool, object]:
        drive, _ = make_trip("dvl", 33, faults=[(ch, val, 396.0)] if val else [], **kw)
        r = dynamic_margins(drive)
        v = r.to_dict()["verdict"]
        assert all(x != "exceeds" for c, x in v.items() if c != ch), v
        return v[ch] == "exceeds", r

    clean, r0 = detected(0.0)
    assert not clean
    ctx = r0.full.ctx  # type: ignore[attr-defined]
    cn = ctx.noise[ch]
    bound = cn.turn_on_bound(ctx.alpha.k("imu_turn_on")) + float(cn.drift_bound or 0.0)
    lo, hi = 0.0, 1.5 * bound
    assert detected(hi)[0], f"{ch}: 1.5 bias bounds not detected"
    for _ in range(5):
        mid = 0.5 * (lo + hi)
        if detected(mid)[0]:
            hi = mid
        else:
            lo = mid
    multiple = hi / bound
    print(f"{ch}: smallest detected step {hi:.4g} (bias bound {bound:.4g}) = {multiple:.2f} x")
    assert multiple <= 1.0, f"{ch}: smallest detected = {multiple:.2f} bias bounds"
