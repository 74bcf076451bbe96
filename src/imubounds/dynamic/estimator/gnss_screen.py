"""GNSS outlier screen of mode full: fixes that contradict their GNSS neighbours, tested on
the GNSS alone (docs/dynamic-method.md, section 3; every rejected fix is a violation)."""

from __future__ import annotations

import numpy as np

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
