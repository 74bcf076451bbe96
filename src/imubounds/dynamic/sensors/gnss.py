"""The GNSS as a sensor (METHOD.md 2.2; docs/dynamic-method.md, section 3): its error
model, its position and velocity boxes, and its check (the outlier screen).

Error model (Rayleigh, one place): CEP (m, 50 % circle) -> DRMS = CEP/sqrt(ln 2) -> per fix
DRMS(i) = HDOP(i)·DRMS(HDOP=1). Two box half-widths are offered to mode paper:

* ``mean`` (the paper): the mean radial error mu_e = (sqrt(pi)/2)·DRMS(i);
  with CEP 3 m and HDOP 1 this is 3.19 m. Under the same Rayleigh model such a
  box holds the true position only about 54 % of the time.
* ``p=P`` (default ``p=0.999``): the radius D_p = DRMS(i)·sqrt(-ln(1-P)) that
  contains the true position with probability P.

The screen (:func:`gnss_outliers`): fixes that contradict their GNSS neighbours, tested
on the GNSS alone; every rejected fix is a violation of mode full.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from imubounds.constants import ROUND_REL
from imubounds.dynamic.estimator.budget import Term, setting_source
from imubounds.errors import OptionError
from imubounds.geodesy import geodetic_to_enu
from imubounds.interval.rounding import up as _up
from imubounds.io.drive import DEFAULT_CEP_M, DEFAULT_HDOP  # the GNSS defaults, defined once

if TYPE_CHECKING:
    from imubounds.dynamic.estimator.budget import AlphaPlan
    from imubounds.dynamic.estimator.inputs import Aiding, Vehicle
    from imubounds.dynamic.estimator.options import FullOptions

#: Default probability level of the position box.
DEFAULT_BOX = "p=0.999"


# ------------------------------------------------------------------ the error model
#
# The horizontal error of a fix is Gaussian, independent and of equal deviation sigma on
# each axis; its radius is Rayleigh: P(radius > r) = exp(-r^2 / DRMS^2), DRMS = sqrt(2)
# sigma, CEP (the median radius) = DRMS sqrt(ln 2). Every radius of the package is
# rayleigh_factor() x DRMS (or x sigma), every conversion one of the functions below.


def cep_to_drms(cep_m: float) -> float:
    """DRMS in m from CEP in m under the Rayleigh model: ``CEP/sqrt(ln 2)`` (= 1.201·CEP)."""
    if not (math.isfinite(cep_m) and cep_m > 0):
        raise OptionError(f"--gps-cep must be a positive number of metres, got {cep_m!r}")
    return cep_m / math.sqrt(math.log(2.0))


def cep_to_sigma(cep_m: Any) -> Any:
    """The 1-sigma error per horizontal axis (m) of a CEP (m, float or array, not checked):
    ``CEP/sqrt(2 ln 2)`` (= 0.849·CEP)."""
    return cep_m / math.sqrt(2.0 * math.log(2.0))


def drms_to_sigma(drms_m: Any) -> Any:
    """The 1-sigma error per horizontal axis (m) of a DRMS (m): ``DRMS/sqrt(2)``."""
    return drms_m / math.sqrt(2.0)


def sigma_to_drms(sigma_m: Any) -> Any:
    """DRMS (m) of a 1-sigma error per horizontal axis (m, e.g. a receiver's ``h_acc_m``):
    ``sqrt(2) sigma``."""
    return math.sqrt(2.0) * sigma_m


def rayleigh_factor(
    *,
    outside: float | None = None,
    inside: float | None = None,
    one_in: float | None = None,
    per: str = "drms",
) -> float:
    """The Rayleigh radius exceeded with probability ``P`` over DRMS (``per="drms"``):
    ``sqrt(-ln P)``; over the per-axis sigma (``per="sigma"``): ``sqrt(-2 ln P)``.

    ``P`` is given as ``outside`` (a small share of alpha), as ``inside = 1 - P`` (a box
    level such as 0.999: ``log1p`` keeps its digits) or as ``one_in = 1/P`` (a count over
    alpha), each evaluated in the form exact for it; exactly one of the three."""
    given = [x is not None for x in (outside, inside, one_in)]
    if sum(given) != 1 or per not in ("drms", "sigma"):
        raise ValueError("rayleigh_factor: give one of outside, inside, one_in; per drms|sigma")
    if outside is not None:
        if per == "sigma":
            return math.sqrt(-2.0 * math.log(outside))
        return math.sqrt(-math.log(outside))
    if inside is not None:
        ln_p = math.log1p(-inside)
        return math.sqrt(-2.0 * ln_p) if per == "sigma" else math.sqrt(-ln_p)
    assert one_in is not None
    return math.sqrt(2.0 * math.log(one_in)) if per == "sigma" else math.sqrt(math.log(one_in))


def mean_error(drms_m: float | np.ndarray) -> float | np.ndarray:
    """Mean radial error in m, ``(sqrt(pi)/2)·DRMS`` (the paper's mu_e)."""
    return 0.5 * math.sqrt(math.pi) * drms_m


def radius_at_probability(drms_m: float | np.ndarray, p: float) -> float | np.ndarray:
    """Radius in m holding the true position with probability ``p``: ``DRMS·sqrt(-ln(1-p))``."""
    if not (0.0 < p < 1.0):
        raise OptionError(f"GPS box probability must lie in (0, 1), got {p!r}")
    return drms_m * rayleigh_factor(inside=p)


@dataclass(frozen=True)
class GpsBoxSpec:
    """How GPS boxes are built: ``kind`` is ``"mean"`` or ``"p"``; ``p`` the level."""

    kind: str
    p: float | None = None

    def factor(self) -> float:
        """Half-width of the box divided by DRMS(i) (dimensionless)."""
        if self.kind == "mean":
            return 0.5 * math.sqrt(math.pi)
        assert self.p is not None
        return rayleigh_factor(inside=self.p)

    def label(self) -> str:
        return "mean" if self.kind == "mean" else f"p={self.p:g}"

    def containment(self) -> float:
        """Probability that the box's circle holds the true position (Rayleigh model)."""
        f = self.factor()
        return 1.0 - math.exp(-f * f)


def parse_gps_box(text: str) -> GpsBoxSpec:
    """Parse ``--gps-box``: ``mean`` or ``p=0.999``."""
    s = text.strip().lower()
    if s == "mean":
        return GpsBoxSpec("mean")
    if s.startswith("p="):
        try:
            p = float(s[2:])
        except ValueError:
            p = float("nan")
        if 0.0 < p < 1.0:
            return GpsBoxSpec("p", p)
    raise OptionError(f"--gps-box must be 'mean' or 'p=P' with 0<P<1 (e.g. p=0.999), got {text!r}")


def gps_box_halfwidths(
    hdop: np.ndarray,
    cep_m: float = DEFAULT_CEP_M,
    box: GpsBoxSpec | str = DEFAULT_BOX,
    default_hdop: float = DEFAULT_HDOP,
) -> tuple[np.ndarray, int]:
    """Half-width in m of each fix's square position box ``[x ± h] × [y ± h]``.

    Parameters
    ----------
    hdop:
        HDOP per fix (dimensionless); NaN or non-positive means "not reported"
        and is replaced by ``default_hdop``.
    cep_m:
        Receiver CEP in m at HDOP 1.
    box:
        ``"mean"`` (paper) or ``"p=P"``.

    Returns
    -------
    (halfwidths, n_defaulted):
        Half-widths in m, and how many fixes used the default HDOP.
    """
    spec = parse_gps_box(box) if isinstance(box, str) else box
    if not (math.isfinite(default_hdop) and default_hdop > 0):
        raise OptionError(f"default HDOP must be positive, got {default_hdop!r}")
    h = np.asarray(hdop, dtype=float).copy()
    missing = ~np.isfinite(h) | (h <= 0)
    h[missing] = default_hdop
    return h * cep_to_drms(cep_m) * spec.factor(), int(missing.sum())


# --------------------------------------------------------------------- the screen

#: (Rayleigh: a good fix is rejected with probability exp(-16) ~ 1e-7; a rejected fix is
#: a failed check of the GNSS error model, reported as a violation by mode full)
REJECT_K = 4.0


def gnss_outliers(
    t: np.ndarray, e: np.ndarray, n: np.ndarray, drms: np.ndarray, a_max: float
) -> np.ndarray:
    """Fixes that contradict most predictions from their kept GNSS neighbours (pairs of
    the three nearest kept fixes on each side): the residual from a pair's linear
    interpolation, less the acceleration-bounded departure from the chord, exceeds
    ``REJECT_K`` times its DRMS (``drms_i sqrt(1 + w_a^2 + w_b^2)`` for independent fix
    errors) for more than half of the pairs. The worst offenders (local maxima of the
    median excess) are rejected first and the test repeated with them removed, so that
    two outliers in a row do not vouch for each other. A test on the GNSS alone (no
    IMU); every rejected fix is a failed check (a violation in mode full)."""
    m = t.size
    kept = np.ones(m, dtype=bool)
    if m < 3:
        return ~kept
    for _ in range(m):
        idx = np.flatnonzero(kept)
        if idx.size < 3:
            break
        ratio, any_valid = _worst_ratio(t[idx], e[idx], n[idx], drms[idx], a_max)
        bad = any_valid & (ratio > 1.0)
        if not np.any(bad):
            break
        # reject the local maxima of the excess among the offenders (within 2 kept fixes)
        r = np.where(bad, ratio, -np.inf)
        pad = np.concatenate([[-np.inf, -np.inf], r, [-np.inf, -np.inf]])
        neigh = np.max(np.stack([pad[k:k + r.size] for k in (0, 1, 3, 4)]), axis=0)
        top = bad & (r >= neigh)
        kept[idx[top]] = False
    return ~kept


def _worst_ratio(
    t: np.ndarray, e: np.ndarray, n: np.ndarray, drms: np.ndarray, a_max: float
) -> tuple[np.ndarray, np.ndarray]:
    """Per fix: the median over the pairs of its neighbours (up to three on each side) of
    (residual - departure) / (REJECT_K DRMS) -- a fix next to an outlier still agrees
    with most pairs --, and whether any pair was valid."""
    ratios = []
    any_valid = np.zeros(t.size, dtype=bool)
    for da in (1, 2, 3):
        for db in (1, 2, 3):
            ce, cn, dev, res, valid = _pair_residual(t, e, n, drms, a_max, da, db)
            d = (np.hypot(e - ce, n - cn) - dev) / (REJECT_K * res)
            ratios.append(np.where(valid, d, np.nan))
            any_valid |= valid
    with np.errstate(all="ignore"):
        import warnings

        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)
            med = np.nanmedian(np.stack(ratios), axis=0)
    return np.where(any_valid, med, 0.0), any_valid


def _pair_residual(
    t: np.ndarray, e: np.ndarray, n: np.ndarray, drms: np.ndarray, a_max: float, da: int,
    db: int,
) -> tuple[np.ndarray, ...]:
    """Interpolation of each fix from fixes i - da and i + db: centre, the chord's
    departure bound ``a_max (t - t_a)(t_b - t)/2``, the residual's DRMS, validity."""
    m = t.size
    idx = np.arange(m)
    ia, ib = idx - da, idx + db
    valid = (ia >= 0) & (ib < m)
    ia, ib = np.clip(ia, 0, m - 1), np.clip(ib, 0, m - 1)
    span = np.where(valid, t[ib] - t[ia], 1.0)
    w = np.where(valid, (t - t[ia]) / span, 0.0)
    ce = e[ia] + (e[ib] - e[ia]) * w
    cn = n[ia] + (n[ib] - n[ia]) * w
    dev = a_max * (t - t[ia]) * (t[ib] - t) / 2
    res = np.sqrt(drms**2 + ((1 - w) * drms[ia]) ** 2 + (w * drms[ib]) ** 2)
    return ce, cn, dev, res, valid


def miss_of(
    t: np.ndarray, e: np.ndarray, n: np.ndarray, drms: np.ndarray, out: np.ndarray,
    a_max: float,
) -> np.ndarray:
    """By how much each rejected fix (``out``, of fixes at ``t`` with east/north ``e, n``)
    exceeds the test's threshold of its nearest pair (m)."""
    best = np.full(t.size, np.inf)
    for da, db in ((1, 1), (2, 1), (1, 2), (2, 2)):
        ce, cn, dev, res, valid = _pair_residual(t, e, n, drms, a_max, da, db)
        d = np.hypot(e - ce, n - cn) - dev - REJECT_K * res
        best = np.minimum(best, np.where(valid, d, np.inf))
    return best[out]


# ---------------------------------------------------------------------- the boxes


def gnss_position_boxes(
    ag: Aiding, g: Any, ok: np.ndarray, st: Any, vehicle: Vehicle, alpha: AlphaPlan,
    opts: FullOptions, t0: float,
) -> tuple[np.ndarray, float]:
    """GNSS position boxes (Rayleigh radius of each usable fix, plus the lever arm) and
    the GNSS outlier screen; returns the fixes kept and the horizontal lever arm (m)."""
    lat, lon = g.lat_deg[ok], g.lon_deg[ok]
    alt = g.alt_m[ok] if g.alt_m is not None else None
    e, n, origin = geodetic_to_enu(lat, lon, alt, method=opts.geodesy)
    ag.origin = origin
    ag.gnss_t = np.asarray(g.t[ok], dtype=float) - t0
    ag.gnss_e, ag.gnss_n = e, n
    ag.gnss_alt = np.asarray(alt, float) if alt is not None else np.full(e.size, np.nan)
    va = getattr(g, "v_acc_m", None)
    ag.gnss_vacc = np.asarray(va[ok], float) if va is not None else np.full(e.size, np.nan)
    cep = float(opts.gnss_cep_m or st.gnss.cep_m)
    dflt = float(opts.default_hdop or st.gnss.default_hdop)
    hd = g.hdop[ok].astype(float) if g.hdop is not None else np.full(e.size, np.nan)
    hd = np.where(np.isfinite(hd) & (hd > 0), hd, dflt)
    drms = hd * cep_to_drms(cep)
    if g.h_acc_m is not None:
        # h_acc_m is the 1-sigma of each horizontal axis: DRMS = sqrt(2) h_acc
        ha = g.h_acc_m[ok].astype(float)
        drms = np.where(np.isfinite(ha) & (ha > 0), sigma_to_drms(ha), drms)
    p = alpha.p_radial("gnss_position")
    fac = rayleigh_factor(outside=p)
    lever = getattr(st, "lever_arm_m", None)
    lev = float(np.hypot(lever[0], lever[1])) if lever is not None else 0.0
    ag.gnss_h = _up(drms * fac * (1 + ROUND_REL) + lev)
    ag.gnss_sig = drms_to_sigma(drms)
    ag.gnss_det = lev
    src_cep = setting_source(st, "gnss.cep_m", bool(opts.gnss_cep_m))
    ag.budget["gnss_position"] = [
        Term("CEP at HDOP 1", cep, "m", src_cep, "circular error probable of the fix"),
        Term(
            "box half-width factor",
            fac,
            "x DRMS",
            "alpha plan",
            f"Rayleigh radial error, P(outside) = {p:.3g} per fix (whole trip "
            f"{alpha.share():.3g} over {ok.sum()} fixes); DRMS = sqrt(2) h_acc_m "
            "(1-sigma per axis) where given, else HDOP x CEP / sqrt(ln 2)",
        ),
        Term(
            "lever arm",
            lev,
            "m",
            "drive.yaml" if lever is not None else "default",
            "horizontal antenna offset from the IMU, added to the position radius "
            "and (x the yaw-rate bound) to the velocity radius",
        ),
        Term(
            "median box half-width",
            float(np.median(ag.gnss_h)),
            "m",
            "computed",
            "square box around the circle of that radius",
        ),
    ]
    out = gnss_outliers(ag.gnss_t, ag.gnss_e, ag.gnss_n, drms, vehicle.max_accel)
    if np.any(out):
        misses = miss_of(ag.gnss_t, ag.gnss_e, ag.gnss_n, drms, out, vehicle.max_accel)
        ag.gnss_rejected = [
            (float(ag.gnss_t[i] + t0), float(miss))
            for i, miss in zip(np.flatnonzero(out), misses, strict=True)
        ]
        keep = ~out
        for name in ("gnss_t", "gnss_e", "gnss_n", "gnss_h", "gnss_sig", "gnss_alt",
                     "gnss_vacc"):
            setattr(ag, name, getattr(ag, name)[keep])
        ok_idx = np.flatnonzero(ok)[keep]
        ok = np.zeros_like(ok)
        ok[ok_idx] = True
    return ok, lev


def gnss_velocity_boxes(
    ag: Aiding, g: Any, ok: np.ndarray, lev: float, st: Any, vehicle: Vehicle,
    alpha: AlphaPlan, opts: FullOptions,
) -> None:
    """GNSS velocity radii of the kept fixes (Rayleigh, plus omega x lever)."""
    vel = g.velocity_ne()
    if vel is not None and opts.use_gnss_velocity:
        vn, ve = vel[0][ok], vel[1][ok]
        good = np.isfinite(vn) & np.isfinite(ve)
        if np.any(good):
            sig = float(opts.gnss_vel_sigma or st.gnss.vel_sigma_mps)
            # radial (Rayleigh) bound of the 2-D velocity error: it bounds each
            # component, the speed (|S - |Vm|| <= R) and the course (asin(R/|Vm|))
            p_v = alpha.p_radial("gnss_velocity")
            k = rayleigh_factor(outside=p_v, per="sigma")
            ag.gvel_ok = good
            ag.gvel_e = np.where(good, ve, np.nan)
            ag.gvel_n = np.where(good, vn, np.nan)
            sig_i = np.full(good.size, sig)
            va = getattr(g, "vel_acc_mps", None)
            if va is not None and not opts.gnss_vel_sigma:
                va = np.asarray(va, dtype=float)[ok]
                sig_i = np.where(np.isfinite(va) & (va > 0), va, sig)
            # a lever arm adds omega x lever to the antenna velocity
            lv_v = lev * vehicle.max_rate
            ag.gvel_h = float(_up(np.float64(k * sig * (1 + ROUND_REL) + lv_v)))
            ag.gvel_hi = _up(k * sig_i * (1 + ROUND_REL) + lv_v)
            ag.gvel_sig = sig_i
            ag.gvel_det = lv_v
            # where each number came from: the receiver's per-fix accuracies where it gave
            # them, else the option, drive.yaml or the default (drive.yaml silent)
            src = setting_source(st, "gnss.vel_sigma_mps", bool(opts.gnss_vel_sigma))
            n_rx = int(np.sum(good & (sig_i != sig))) if va is not None else 0
            sig_shown = sig
            if n_rx:
                src = (f"receiver's vel_acc_mps at {n_rx} of {int(good.sum())} fixes (median)"
                       + (f"; {src} {sig:g} m/s at the others" if n_rx < good.sum() else ""))
                sig_shown = float(np.median(sig_i[good]))
            ag.budget["gnss_velocity"] = [
                Term(
                    "velocity sigma per component",
                    sig_shown,
                    "m/s",
                    src,
                    "Gaussian error of north and east velocity",
                ),
                Term(
                    "radius factor",
                    k,
                    "x sigma",
                    "alpha plan",
                    f"Rayleigh radial error, P(outside) = {p_v:.3g} per fix "
                    f"({int(good.sum())} fixes)",
                ),
                Term(
                    "radius",
                    float(np.median(ag.gvel_hi[good])) if n_rx else ag.gvel_h,
                    "m/s",
                    "computed" + (" (median over the fixes)" if n_rx else ""),
                    "bounds the 2-D velocity error, hence each component, the speed "
                    "and (asin(radius / speed)) the course",
                ),
            ]
