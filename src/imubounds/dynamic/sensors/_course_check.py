"""The compass against the GNSS course (docs/dynamic-method.md, section 5b).

``d = heading - course`` at the GNSS epochs fast enough for the sideslip to be small is
the compass error ``e(psi)`` + the sideslip + the noise of both. Two uses, one least
squares (:func:`harmonic_fit`):

* :func:`estimate_heading_model`: the compass error model ``e(psi) = c0 + a1 cos psi +
  b1 sin psi + a2 cos 2psi + b2 sin 2psi`` (``psi`` the compass reading) with an interval
  per coefficient; the coefficients the data detect (interval excluding 0), and the
  constant when its interval is narrower than the stated alignment allowance, are taken
  off the headings (:func:`apply_heading_model`) and their half-widths replace the
  allowance in the heading's bound: a mount offset, a declination or a two-cycle
  deviation become unknowns of the trip, bounded from the GNSS course.
* :func:`check_against_course`: compare (never fit) the corrected heading with the GNSS
  course, signed; a failed test withdraws the guarantee.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

from imubounds.dynamic.sensors.gnss import cep_to_sigma
from imubounds.frames import TWO_PI, wrap_pi
from imubounds.geodesy import geodetic_to_enu

if TYPE_CHECKING:
    from imubounds.dynamic.sensors._compass import CompassHeading

#: the stated bound (s) on an undeclared clock offset of the heading stream against the
#: IMU (drive.yaml heading.time_offset_s / time_offset_bound_s replace it); a larger
#: offset is what the check against the GNSS course in the turns tests (re-exported by
#: :mod:`imubounds.dynamic.sensors._timing`)
DEFAULT_HEADING_CLOCK_BOUND_S = 0.1
#: the most families mode full's alpha plan has (estimator/full.py: imu_samples,
#: imu_windows, imu_changes, imu_intervals, imu_turn_on, imu_drift, gnss_position,
#: gnss_velocity, heading): the heading family's share is at least alpha / this, and the
#: coefficients of :func:`estimate_heading_model` are counted in that family
ALPHA_FAMILIES_MAX = 9
#: room for the heading clock estimate's events the heading family also counts (the
#: estimate and its references' parts, sensors/_timing.py)
HEADING_FAMILY_EXTRA = 4


def _velocity_course(
    g: Any, ok: np.ndarray, min_speed: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
    """(t, course rad clockwise from true north, speed m/s) from the receiver's velocity
    where usable and faster than ``min_speed``; None without velocity or with fewer than
    three such fixes."""
    ne = g.velocity_ne()
    if ne is None:
        return None
    vn, ve = ne
    sp = np.hypot(vn, ve)
    keep = ok & np.isfinite(sp) & (sp >= min_speed)
    if keep.sum() < 3:
        return None
    return g.t[keep], np.mod(np.arctan2(ve[keep], vn[keep]), TWO_PI), sp[keep]


def _interp_heading(t: np.ndarray, tq: np.ndarray, h: np.ndarray) -> np.ndarray:
    return np.mod(np.interp(tq, t, np.unwrap(h)), TWO_PI)


#: heading bins of the check against the GNSS course (the deviation's shape)
COURSE_CHECK_BINS = 12
#: the check against the GNSS course uses epochs at least this fast (m/s) and this many
#: times the lateral speed bound (the sideslip bound asin(lateral / speed) stays small)
COURSE_CHECK_MIN_SPEED = 5.0
#: share of the trip's alpha given to the check against the GNSS course (the residual
#: checks get another quarter; dynamic-method.md 5b)
COURSE_CHECK_SHARE = 0.25
#: turns for the signed test of the check against the GNSS course: |yaw rate| at least
#: this (deg/s) and half the trip's 99th percentile
TURN_MIN_DPS = 2.0
#: fixes spanned by one chord of the course from positions (no receiver velocity)
COURSE_CHORD = 5
#: harmonics of the deviation tested by the check against the GNSS course (cycles 1 and 2:
#: the cos and sin coefficient of each, one test each)
COURSE_CHECK_HARMONICS = 2
#: tests of the check against the GNSS course: the mean, the turns, the heading bins and
#: the 2 x COURSE_CHECK_HARMONICS coefficients (Bonferroni within COURSE_CHECK_SHARE)
COURSE_CHECK_TESTS = 2 + COURSE_CHECK_BINS + 2 * COURSE_CHECK_HARMONICS
#: share of the heading clock allowance the check's means budget (offset x yaw rate): a
#: compass within half its allowance never trips them under the stated bounds; one
#: between half and the whole may (a conservative withdrawal); the power to see a 0.2 s
#: lag, which the heading intervals (the whole allowance at each epoch's own rate, the
#: test the mean rate of the turns) no longer hold at the fastest turns, stays
CLOCK_TEST_SHARE = 0.5


def course_noise(
    drive: Any, min_speed: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray] | None:
    """(t, course rad clockwise from north, 1-sigma of the course rad, a lower bound of
    the speed m/s at 3 sigma) of the GNSS while faster than ``min_speed``: from the
    receiver's velocity (sigma = vel sigma / speed) or from chords of
    :data:`COURSE_CHORD` fixes (sigma = sqrt(2) x position sigma per axis / length),
    the GNSS errors being isotropic Gaussian (drive.yaml gnss: cep_m, vel_sigma_mps)."""
    g = drive.gnss
    if g is None:
        return None
    st = drive.settings.gnss
    ok = g.usable()
    vel = _velocity_course(g, ok, min_speed)
    if vel is not None:
        sv = float(st.vel_sigma_mps)
        return vel[0], vel[1], sv / vel[2], vel[2] - 3.0 * sv
    if ok.sum() < 3:
        return None
    e, n, _ = geodetic_to_enu(g.lat_deg[ok], g.lon_deg[ok])
    t = g.t[ok]
    hd = g.hdop[ok].astype(float) if g.hdop is not None else np.full(e.size, np.nan)
    hd = np.where(np.isfinite(hd) & (hd > 0), hd, float(st.default_hdop))
    s_ax = cep_to_sigma(hd * float(st.cep_m))
    # chords of COURSE_CHORD fixes (not overlapping): the chord of an arc points along
    # its tangent at the middle, and its noise is COURSE_CHORD times smaller
    c = COURSE_CHORD
    i0 = np.arange(0, e.size - c, c)
    i1 = i0 + c
    de, dn = e[i1] - e[i0], n[i1] - n[i0]
    dt = t[i1] - t[i0]
    dist = np.hypot(de, dn)
    med = float(np.median(np.diff(t))) if t.size > 1 else 1.0
    with np.errstate(divide="ignore", invalid="ignore"):
        speed = dist / dt
    keep = np.isfinite(speed) & (speed >= min_speed) & (dt <= 1.5 * c * med)
    if keep.sum() < 3:
        return None
    s_d = np.hypot(s_ax[i0], s_ax[i1])[keep]
    return (
        0.5 * (t[i0] + t[i1])[keep],
        np.arctan2(de, dn)[keep] % TWO_PI,
        s_d / dist[keep],
        speed[keep] - 3.0 * s_d / dt[keep],
    )


def harmonic_fit(
    psi: np.ndarray,
    d: np.ndarray,
    sig2: np.ndarray,
    bound: np.ndarray,
    k: float,
    rate: np.ndarray | None = None,
    psi_var: float = 0.0,
) -> list[dict[str, Any]]:
    """The compass error's constant and harmonics in ``d = heading - course`` (rad), with a
    bound per coefficient.

    ``c = W d`` the weighted least-squares coefficients (weights ``1/sig2``) of the basis
    ``1, cos psi, sin psi, ..., cos(H psi), sin(H psi)`` (H = :data:`COURSE_CHECK_HARMONICS`,
    :func:`harmonic_basis`) and, when ``rate`` is given, the yaw rate (a clock offset
    between the two streams shows as offset x rate: its column takes it out of the other
    coefficients, to first order). With ``d_i = sum_j c_j basis_j(psi_i) + e_i + n_i``,
    ``|e_i| <= bound_i`` (what the basis does not model + the sideslip bound, any sign)
    and ``n_i`` independent Gaussian of variance ``sig2_i``, ``W`` reproduces the basis
    (``W A = I``), so every coefficient's estimate obeys ``|c^_j - c_j| <= sum_i |W_ji|
    bound_i + k sqrt(sum_i W_ji^2 sig2_i)`` but with the probability of a Gaussian beyond
    k sigma. The weights are taken at the measured ``psi``, whose noise (variance
    ``psi_var``, rad^2) is part of ``d``'s: to second order it biases ``c_j`` by ``psi_var
    sum_i dW_ji/dpsi_i``, whose absolute values are added to the bound. Returns, per
    coefficient (the constant first), ``{index, cycle, term, coef, limit, det, sd}`` (rad;
    ``cycle`` 0 the constant; with ``rate`` last the yaw rate's, term ``"rate"``, cycle
    None, in s: minus the heading's clock offset against the course, to first order);
    empty when the design is singular (headings not spread)."""
    lsq = _harmonic_lsq(psi, sig2, rate)
    if lsq is None:
        return []
    a, da, w, nrm, wm = lsq
    coef = wm @ d
    # dW_:,i/dpsi_i = M^-1 a'_i w_i (1 - h_i) - W_:,i w_i a'_i.M^-1 a_i (M = A'wA, h_i the
    # leverage w_i a_i.M^-1 a_i): the derivative of the column W_:,i = M^-1 a_i w_i
    dm = np.linalg.solve(nrm, (da * w[:, None]).T)
    lev = np.einsum("ij,ji->i", a, wm)
    cross = np.einsum("ij,ji->i", da, wm)
    dwm = dm * (1.0 - lev) - wm * cross
    out: list[dict[str, Any]] = []
    n_basis = 1 + 2 * COURSE_CHECK_HARMONICS
    for j in range(a.shape[1]):
        det = float(np.abs(wm[j]) @ bound) + psi_var * float(np.sum(np.abs(dwm[j])))
        sd = math.sqrt(float(wm[j] ** 2 @ sig2))
        out.append({"index": j, "cycle": (j + 1) // 2 if j < n_basis else None,
                    "term": ("const" if j == 0 else "cos" if j % 2 else "sin")
                    if j < n_basis else "rate",
                    "coef": float(coef[j]), "limit": det + k * sd, "det": det, "sd": sd})
    return out


def _harmonic_lsq(
    psi: np.ndarray, sig2: np.ndarray, rate: np.ndarray | None
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray] | None:
    """(A, dA/dpsi, weights, A'wA, W) of :func:`harmonic_fit`'s weighted least squares;
    None when the design is singular."""
    cols, dcols = [np.ones_like(psi)], [np.zeros_like(psi)]
    for m in range(1, COURSE_CHECK_HARMONICS + 1):
        cols += [np.cos(m * psi), np.sin(m * psi)]
        dcols += [-m * np.sin(m * psi), m * np.cos(m * psi)]
    if rate is not None:
        cols.append(rate)
        dcols.append(np.zeros_like(psi))
    a, da = np.column_stack(cols), np.column_stack(dcols)
    w = 1.0 / sig2
    nrm = a.T @ (a * w[:, None])
    if a.shape[0] <= a.shape[1] or np.linalg.cond(nrm) > 1e8:
        return None
    wm = np.linalg.solve(nrm, (a * w[:, None]).T)  # rows: the coefficients' weights
    return a, da, w, nrm, wm


def model_adequacy(
    psi: np.ndarray,
    d: np.ndarray,
    sig2: np.ndarray,
    bound: np.ndarray,
    k: float,
    rate: np.ndarray | None = None,
) -> list[dict[str, Any]] | None:
    """Whether the compass error model describes ``d``: the mean, over each of
    :data:`COURSE_CHECK_BINS` heading bins (3 epochs or more), of the residual of
    :func:`harmonic_fit`'s least squares ``e = (I - A W) d``. The projection takes every
    coefficient of the model (and the clock offset's yaw-rate column) out exactly, so
    with ``d = A c + e_d + n`` (``|e_d| <= bound``) the bin's mean ``u_B . d`` (``u_B =
    1_B / n_B - mean_B(A) W``) lies within ``sum_i |u_Bi| bound_i + k sqrt(sum_i u_Bi^2
    sig2_i)``; a larger one is a shape the model does not have (three cycles or more,
    a deviation beyond the unmodelled bound). Returns the failed bins
    ``{heading_from_deg, mean_deg, limit_deg}`` (empty: adequate); None when the design is
    singular."""
    lsq = _harmonic_lsq(psi, sig2, rate)
    if lsq is None:
        return None
    a, wm = lsq[0], lsq[4]
    bins = np.floor(np.mod(psi, TWO_PI) / (TWO_PI / COURSE_CHECK_BINS)).astype(int)
    failed: list[dict[str, Any]] = []
    for bn in range(COURSE_CHECK_BINS):
        sel = bins == bn
        nb = int(sel.sum())
        if nb < 3:
            continue
        u = -(a[sel].mean(axis=0) @ wm)
        u[sel] += 1.0 / nb
        stat = float(u @ d)
        lim = float(np.abs(u) @ bound) + k * math.sqrt(float(u**2 @ sig2))
        if abs(stat) > lim:
            failed.append({"heading_from_deg": bn * 360.0 / COURSE_CHECK_BINS,
                           "mean_deg": math.degrees(stat), "limit_deg": math.degrees(lim)})
    return failed


def harmonic_basis(j: int, psi: np.ndarray) -> np.ndarray:
    """Basis function ``j`` of :func:`harmonic_fit` at ``psi`` (rad): 1, cos psi, sin psi,
    cos 2psi, sin 2psi, ..."""
    if j == 0:
        return np.ones_like(psi)
    m = (j + 1) // 2
    return np.cos(m * psi) if j % 2 else np.sin(m * psi)


@dataclass
class CourseData:
    """The compass heading against the GNSS course at the course's epochs (rad)."""

    t: np.ndarray
    #: the compass heading (clockwise from north) and d = heading - course
    h: np.ndarray
    d: np.ndarray
    #: variance of d's noise (course + heading)
    sig2: np.ndarray
    #: sideslip bound asin(lateral bound / speed lower bound); None: no lateral bound
    slip: np.ndarray | None
    #: the IMU's yaw rate (rad/s); None without a gyro z
    rate: np.ndarray | None
    vmin: float


def course_data(drive: Any, ch: CompassHeading, min_speed: float) -> CourseData | None:
    """The corrected heading ``ch`` against the GNSS course (:func:`course_noise`) at the
    epochs faster than :data:`COURSE_CHECK_MIN_SPEED`, ``min_speed`` and 5 x the lateral
    speed bound, inside the heading's span; None with fewer than 10 such epochs."""
    lat = drive.settings.vehicle.lateral_speed_bound_mps
    vmin = max(min_speed, COURSE_CHECK_MIN_SPEED, 5.0 * (lat or 0.0))
    gc = course_noise(drive, vmin)
    if gc is None or not ch.t.size:
        return None
    tc, course, sig_c, v_lo = gc
    inside = (tc >= ch.t[0]) & (tc <= ch.t[-1])
    if inside.sum() < 10:
        return None
    tc, course, sig_c, v_lo = tc[inside], course[inside], sig_c[inside], v_lo[inside]
    h = _interp_heading(ch.t, tc, ch.heading_rad)
    d = np.asarray(wrap_pi(h - course), dtype=float)
    slip = (None if lat is None
            else np.arcsin(np.minimum(1.0, lat / np.maximum(v_lo, 1e-9))))
    imu = drive.imu
    rate = None
    if imu is not None and imu.t.size > 1 and np.isfinite(imu.gyro[:, 2]).all():
        rate = np.interp(tc, imu.t, imu.gyro[:, 2])
    return CourseData(tc, h, d, sig_c**2 + ch.noise_sigma_rad**2, slip, rate, vmin)


def heading_clock_allowance_s(drive: Any) -> float:
    """The heading clock offset the check against the GNSS course allows (s): the stated
    ``heading.time_offset_s`` + ``time_offset_bound_s`` (the check sees the stamps before
    the stated offset is taken off), else :data:`DEFAULT_HEADING_CLOCK_BOUND_S`."""
    hs = drive.settings.heading
    if hs.time_offset_bound_s is not None:
        return abs(float(hs.time_offset_s)) + float(hs.time_offset_bound_s)
    return DEFAULT_HEADING_CLOCK_BOUND_S + abs(float(hs.time_offset_s))


# ------------------------------------------------------------------ the error model
@dataclass
class HeadingModel:
    """The compass error model estimated against the GNSS course
    (:func:`estimate_heading_model`); angles in rad, the compass frame (clockwise)."""

    #: per coefficient: index, cycle, term, coef, limit (the half-width), det, sd, applied
    terms: list[dict[str, Any]]
    #: the heading's deviation bound before (the stated one) and after the correction
    stated_rad: float
    remainder_rad: float
    #: the bound of what the model does not take (the stated bound minus the alignment)
    unmodelled_rad: float
    k: float
    n: int
    #: factor on the heading noise (the correction evaluated at the noisy reading)
    noise_gain: float = 1.0
    notes: list[str] = field(default_factory=list)
    #: the heading bins where the fit's residual is beyond its bound (model_adequacy)
    adequacy_failed: list[dict[str, Any]] = field(default_factory=list)

    @property
    def applied(self) -> bool:
        return any(c["applied"] for c in self.terms)

    def to_dict(self) -> dict[str, Any]:
        deg = math.degrees
        return {
            "applied": self.applied,
            "coefficients": [
                {"cycle": c["cycle"], "term": c["term"], "estimate_deg": deg(c["coef"]),
                 "interval_deg": [deg(c["coef"] - c["limit"]), deg(c["coef"] + c["limit"])],
                 "half_width_deg": deg(c["limit"]), "bound_part_deg": deg(c["det"]),
                 "sd_deg": deg(c["sd"]), "applied": c["applied"]}
                for c in self.terms
            ],
            "stated_bound_deg": deg(self.stated_rad),
            "remainder_bound_deg": deg(self.remainder_rad),
            "unmodelled_bound_deg": deg(self.unmodelled_rad),
            "noise_gain": self.noise_gain,
            "adequate": not self.adequacy_failed,
            "adequacy_bins_failed": list(self.adequacy_failed),
            "k": self.k,
            "epochs": self.n,
            "method": (
                "weighted least squares of heading - GNSS course on 1, cos psi, sin psi, "
                "cos 2psi, sin 2psi (psi the compass reading) and the yaw rate; interval "
                "coef +- (sum|W| (unmodelled bound + sideslip bound) + the heading noise's "
                "bias + k sd), k at the heading family's share "
                "(course_check.estimate_heading_model)"
            ),
            "notes": list(self.notes),
        }


def estimate_heading_model(
    drive: Any, ch: CompassHeading, alpha: float, min_speed: float, alignment_rad: float
) -> HeadingModel | None:
    """The compass error model ``e(psi) = c0 + sum_m (a_m cos m psi + b_m sin m psi)``
    (m = 1 .. :data:`COURSE_CHECK_HARMONICS`) from ``d = heading - course``
    (:func:`harmonic_fit`), every coefficient with an interval: the compass error beyond
    the model bounded by the stated deviation bound minus the alignment allowance
    ``alignment_rad`` (the constant is free), + the sideslip bound; k two-sided at
    ``alpha`` / :data:`ALPHA_FAMILIES_MAX` Bonferroni over the heading epochs, the
    coefficients and :data:`HEADING_FAMILY_EXTRA` (the heading family of mode full counts
    the coefficients, its k is then at most this one). A coefficient is applied
    when its interval excludes 0 (the data contradict the stated bound) or, the constant,
    when its half-width is narrower than the alignment allowance. None without a GNSS
    course, a lateral speed bound or headings spread enough."""
    from scipy.stats import norm

    data = course_data(drive, ch, min_speed)
    if data is None or data.slip is None:
        return None
    n_terms = 1 + 2 * COURSE_CHECK_HARMONICS
    n_events = ch.t.size + n_terms + HEADING_FAMILY_EXTRA
    k = float(norm.isf(alpha / ALPHA_FAMILIES_MAX / (2.0 * n_events)))
    unmodelled = max(0.0, ch.deviation_bound_rad - alignment_rad)
    fit = [c for c in harmonic_fit(data.h, data.d, data.sig2, unmodelled + data.slip, k,
                                   data.rate, ch.noise_sigma_rad**2) if c["term"] != "rate"]
    if not fit:
        return None
    # the model's adequacy, tested at the check's k: a shape it does not have leaves it
    # unapplied (the check of the stated bound decides)
    k_check = float(norm.isf(alpha * COURSE_CHECK_SHARE / (2.0 * COURSE_CHECK_TESTS)))
    bad = model_adequacy(data.h, data.d, data.sig2, unmodelled + data.slip, k_check,
                         data.rate) or []
    for c in fit:
        detected = abs(c["coef"]) > c["limit"]
        c["applied"] = bool(not bad and (
            detected or (c["cycle"] == 0 and c["limit"] < alignment_rad)))
    const = fit[0]["applied"]
    rem = (unmodelled if const else ch.deviation_bound_rad) + sum(
        c["limit"] for c in fit if c["applied"])
    gain = 1.0 + sum(c["cycle"] * abs(c["coef"]) for c in fit if c["applied"])
    model = HeadingModel(fit, ch.deviation_bound_rad, rem, unmodelled, k,
                         int(data.d.size), gain, adequacy_failed=bad)
    if bad:
        worst = max(bad, key=lambda b: abs(b["mean_deg"]) - b["limit_deg"])
        model.notes.append(
            f"compass error model not applied: in {len(bad)} heading bin(s) the residual of "
            f"its fit to the GNSS course is beyond its bound (worst {worst['mean_deg']:+.2f} "
            f"deg against {worst['limit_deg']:.2f} from {worst['heading_from_deg']:g} deg): "
            "a deviation shape it does not have; the stated bound stays, checked"
        )
    return model


def apply_heading_model(ch: CompassHeading, model: HeadingModel) -> None:
    """Take the applied coefficients off ``ch``'s headings (at each reading) and replace
    its deviation bound by the model's remainder: the unmodelled bound (+ the alignment
    allowance when the constant is not applied) + the half-widths of the applied
    coefficients (``sum_j h_j |basis_j(psi)| <= sum_j h_j``). The heading is then no
    longer independent of the GNSS (its correction uses the course)."""
    if not model.applied:
        return
    psi = ch.heading_rad
    corr = np.zeros_like(psi)
    for c in model.terms:
        if c["applied"]:
            corr += c["coef"] * harmonic_basis(int(c["index"]), psi)
    ch.heading_rad = np.mod(psi - corr, TWO_PI)
    ch.deviation_bound_rad = float(model.remainder_rad)
    if model.terms[0]["applied"]:
        ch.constant_bound_rad = float(model.terms[0]["limit"])
    ch.independent_of_gnss = False
    names = ", ".join(
        ("constant" if c["cycle"] == 0 else f"{c['term']} {c['cycle']}psi")
        + f" {math.degrees(c['coef']):+.2f} +- {math.degrees(c['limit']):.2f} deg"
        for c in model.terms if c["applied"])
    model.notes.append(
        f"compass error estimated against the GNSS course and taken off the headings "
        f"({names}); the heading's deviation bound is now "
        f"{math.degrees(model.remainder_rad):.2f} deg (was "
        f"{math.degrees(model.stated_rad):.2f}); the heading is no longer independent of "
        "the GNSS, and the check against the course cannot test the terms it estimated"
    )
    ch.notes.extend(model.notes)


def against_course(
    drive: Any, ch: CompassHeading, alpha: float, min_speed: float, alignment_rad: float,
    estimate: bool = True,
) -> None:
    """The compass error model estimated and applied (``estimate``:
    :func:`estimate_heading_model`, :func:`apply_heading_model`, its report in
    ``ch.detail['heading_model']``), then the check of the corrected heading
    (:func:`check_against_course`)."""
    if estimate:
        model = estimate_heading_model(drive, ch, alpha, min_speed, alignment_rad)
        if model is not None:
            apply_heading_model(ch, model)
            ch.detail["heading_model"] = model.to_dict()
    check_against_course(drive, ch, alpha, min_speed)


# ------------------------------------------------------------------ the check
def check_against_course(drive: Any, ch: CompassHeading, alpha: float, min_speed: float) -> None:
    """Compare (never fit) the corrected heading with the GNSS course, signed.

    ``d = heading - course`` at the GNSS epochs of :func:`course_data`. With the stated
    assumptions (a compass error within its deviation bound plus white Gaussian noise, the
    sideslip within asin(lateral bound / speed) at the speed's 3-sigma lower bound,
    isotropic Gaussian GNSS errors, the heading clock within ``b`` =
    :data:`CLOCK_TEST_SHARE` x :func:`heading_clock_allowance_s` of the GNSS's), the mean
    of ``d`` over all the
    epochs and over each of :data:`COURSE_CHECK_BINS` heading bins, and of ``d`` x
    sign(yaw rate) over the turns (a clock offset between the streams), lies within the
    deviation bound + the mean sideslip bound + ``b`` x |the mean yaw rate| (signed by
    the turn in the turns) + k sigma_mean; and each cos / sin coefficient of the
    deviation's harmonics 1 to :data:`COURSE_CHECK_HARMONICS` (:func:`harmonic_fit`
    without the constant, with the yaw rate: the clock offset leaves them) lies within
    ``sum_i |W_ji| (deviation bound - its constant part + sideslip bound_i) + k sd_j`` (a constant
    leaves the harmonics); k two-sided at level ``alpha`` x :data:`COURSE_CHECK_SHARE`
    split over the :data:`COURSE_CHECK_TESTS` tests. A larger signed mean is a constant
    offset (mount, declination), a deviation shape the bound does not cover or a clock
    offset: ``detail['gnss_course_check']['passed']`` is False and the check says which.
    """
    data = course_data(drive, ch, min_speed)
    if data is None:
        return
    d, h, sig2, slip, r = data.d, data.h, data.sig2, data.slip, data.rate
    if slip is None:
        ch.detail["gnss_course_check"] = {
            "n": int(d.size),
            "mean_diff_deg": math.degrees(float(np.mean(d))),
            "passed": None,
            "rule": "not tested: no lateral speed bound (the sideslip is not bounded)",
        }
        return
    from scipy.stats import norm

    level = alpha * COURSE_CHECK_SHARE
    k = float(norm.isf(level / (2.0 * COURSE_CHECK_TESTS)))
    dev = ch.deviation_bound_rad
    b = CLOCK_TEST_SHARE * heading_clock_allowance_s(drive)
    rr = r if r is not None else np.zeros_like(d)
    absr = np.abs(rr)

    def test(sel: np.ndarray, sign: np.ndarray | None = None) -> tuple[float, float]:
        x = d[sel] if sign is None else d[sel] * sign[sel]
        xr = rr[sel] if sign is None else rr[sel] * sign[sel]
        m = float(np.mean(x))
        noise = k * math.sqrt(float(np.sum(sig2[sel]))) / int(sel.sum())
        # a clock offset L shows as L x rate: its mean within b x |mean rate|
        lim = dev + float(np.mean(slip[sel])) + b * abs(float(np.mean(xr))) + noise
        return m, lim

    m_all, lim_all = test(np.ones(d.size, dtype=bool))
    # in the turns, signed by the turn: a clock offset between the two streams shows
    # as offset x yaw rate (the yaw rate from the IMU's gyro, independent of d's noise)
    turn: dict[str, float] | None = None
    if r is not None:
        thr = max(math.radians(TURN_MIN_DPS), 0.5 * float(np.percentile(absr, 99)))
        sel_t = absr >= thr
        if sel_t.sum() >= 5:
            m_t, lim_t = test(sel_t, np.sign(rr))
            rate_t = float(np.mean(absr[sel_t]))
            turn = {"mean_diff_deg": math.degrees(m_t), "limit_deg": math.degrees(lim_t),
                    "clock_allowance_deg": math.degrees(b * rate_t),
                    "n": int(sel_t.sum()), "mean_rate_dps": math.degrees(rate_t)}
    worst: list[tuple[float, float, float]] = []
    bins = np.floor(np.mod(h, TWO_PI) / (TWO_PI / COURSE_CHECK_BINS)).astype(int)
    for bn in range(COURSE_CHECK_BINS):
        sel = bins == bn
        if sel.sum() >= 3:
            m, lim = test(sel)
            if abs(m) > lim:
                worst.append((bn * 360.0 / COURSE_CHECK_BINS, m, lim))
    turn_failed = turn is not None and abs(turn["mean_diff_deg"]) > turn["limit_deg"]
    # the deviation's harmonics, least squares over every epoch (the bins' power pooled)
    # a constant part of the bound (the alignment allowance, the estimated offset's
    # half-width) leaves the harmonics (W_j 1 = 0 for j >= 1: the basis has a constant)
    fit = harmonic_fit(h, d, sig2, dev - ch.constant_bound_rad + slip, k, r,
                       ch.noise_sigma_rad**2)
    harm = [c for c in fit if c["cycle"]]
    harm_failed = [c for c in harm if abs(c["coef"]) > c["limit"]]
    passed = abs(m_all) <= lim_all and not worst and not turn_failed and not harm_failed
    ch.detail["gnss_course_check"] = {
        "n": int(d.size),
        "mean_diff_deg": math.degrees(m_all),
        "limit_deg": math.degrees(lim_all),
        "bins_failed": [
            {"heading_from_deg": a, "mean_diff_deg": math.degrees(m), "limit_deg": math.degrees(li)}
            for a, m, li in worst
        ],
        "turns": turn,
        "harmonics": [
            {"cycle": c["cycle"], "term": c["term"], "coef_deg": math.degrees(c["coef"]),
             "limit_deg": math.degrees(c["limit"]), "bound_part_deg": math.degrees(c["det"]),
             "sd_deg": math.degrees(c["sd"])}
            for c in harm
        ],
        "clock_allowance_s": b,
        "deviation_bound_deg": math.degrees(dev),
        "passed": passed,
        "rule": (
            f"signed mean of heading - GNSS course (speed >= {data.vmin:g} m/s) within "
            f"deviation bound + sideslip bound + {b:g} s (half the heading clock allowance) x "
            f"the mean yaw rate + k sigma of the mean, k = {k:.3g} (two-sided, level "
            f"{level:g} over 1 + {COURSE_CHECK_BINS} heading bins + the turns signed by the "
            f"yaw rate + the cos and sin coefficients of the deviation's harmonics 1 to "
            f"{COURSE_CHECK_HARMONICS} (least squares with the yaw rate, limit sum|W| x "
            "(deviation + sideslip bound) + k sd))"
        ),
    }
    note = _failure_note(m_all, lim_all, turn if turn_failed else None, worst, harm_failed)
    if note:
        ch.notes.append(note)


def _failure_note(
    m_all: float,
    lim_all: float,
    turn: dict[str, float] | None,
    worst: list[tuple[float, float, float]],
    harm_failed: list[dict[str, Any]],
) -> str:
    """What a failed check against the GNSS course says (the first failed test)."""
    if abs(m_all) > lim_all:
        return (
            f"check failed: the corrected heading differs from the GNSS course by a mean "
            f"{math.degrees(m_all):+.2f} deg, beyond the {math.degrees(lim_all):.2f} deg its "
            "bounds allow: a constant heading offset (declination, mount, "
            "heading.alignment_deg)"
        )
    if turn is not None:
        lag = turn["mean_diff_deg"] / max(turn["mean_rate_dps"], 1e-9)
        return (
            f"check failed: in the turns the corrected heading differs from the GNSS course "
            f"by a mean {turn['mean_diff_deg']:+.2f} deg signed by the turn, beyond the "
            f"{turn['limit_deg']:.2f} deg its bounds allow: a clock offset between the "
            f"heading and the GNSS (about {lag:+.2f} s at the mean turn rate "
            f"{turn['mean_rate_dps']:.1f} deg/s), or a deviation the bound does not cover"
        )
    if worst:
        return (
            f"check failed: in {len(worst)} heading bin(s) the corrected heading differs "
            f"from the GNSS course by more than its bounds allow (worst mean "
            f"{math.degrees(max(abs(w[1]) for w in worst)):.2f} deg): the compass deviation "
            "is larger than heading.deviation_deg or has more cycles than the calibration"
        )
    if harm_failed:
        c = max(harm_failed, key=lambda c: abs(c["coef"]) - c["limit"])
        return (
            f"check failed: the {c['term']} coefficient of the heading's {c['cycle']}-cycle "
            f"deviation against the GNSS course is {math.degrees(c['coef']):+.2f} deg, beyond "
            f"the {math.degrees(c['limit']):.2f} deg its bounds allow: the compass deviation "
            "is larger than heading.deviation_deg or has more cycles than the calibration"
        )
    return ""
