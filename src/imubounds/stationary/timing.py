"""What assuming a constant sample rate costs the Allan curve (docs/static-method.md,
section 1.2, irregular sampling).

The Allan family takes samples at a constant step δt. With jittered stamps the
true cluster of m samples lasts ``m·δt·(1 + ε)``, ε of standard deviation
``δ/√m`` for independent step errors of relative size δ (robust: the IQR of the
steps / 1.349 / the median step); on a curve of local slope μ that moves σ by
``|μ|·δ/√m``, and weighting the samples by their actual steps instead of equally
changes a cluster mean's variance by at most ``δ²`` (σ by ``δ²/2``). So the
relative error of σ(τ) from assuming the constant rate is at most

    b(τ) = |μ(τ)|·δ/√m + δ²/2          (one standard deviation of ε),

reported per τ beside the curve's own relative CI half-width. If the stamps only
carry noise of the clock that stamped them (the samples themselves regular),
the curve is exact and b is a bound only.

Gaps (steps above the gap threshold of :func:`imubounds.io.validate.gap_threshold`,
left in with ``--on-gap ignore``): a cluster pair of 2m samples straddles one of
g gaps with probability about ``min(1, g·2m/n)``; the τ where this passes
:data:`GAP_FRACTION_MAX` are named as unreliable.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from imubounds.io.validate import find_gaps, gap_threshold
from imubounds.stationary.term_curve import local_slopes

#: Fraction of cluster pairs across a gap above which a point is called unreliable.
GAP_FRACTION_MAX = 0.1
#: Bound (relative, on σ) above which the console warns.
WARN_BOUND = 0.01


def stamp_stats(t: Any) -> dict[str, Any]:
    """Median step (s), robust relative jitter, gaps and missing time of the stamps
    (shared by the channels of a log)."""
    steps = np.diff(np.asarray(t, dtype=np.float64))
    if steps.size < 2:
        return {"n": steps.size + 1}
    med, factor = gap_threshold(steps)
    gaps = find_gaps(steps, med, factor)
    regular = steps[(steps > 0) & (steps <= factor * med)]
    q25, q75 = np.percentile(regular, [25, 75]) if regular.size else (med, med)
    return {
        "n": steps.size + 1,
        "median_step_s": float(med),
        "jitter_rel": float((q75 - q25) / 1.349 / med) if med > 0 else 0.0,
        "gaps": int(np.size(gaps)),
        "gap_threshold_s": float(factor * med),
        "missing_s": float(np.sum(steps[gaps] - med)) if np.size(gaps) else 0.0,
    }


def timing_check(
    t: Any, tau: Any, dev: Any, ci_lower: Any, ci_upper: Any, stamps: dict[str, Any] | None = None
) -> dict[str, Any]:
    """The ``timing`` block of a channel: jitter, gaps and the bound b(τ) (module doc);
    ``stamps`` from :func:`stamp_stats` of ``t`` when already computed."""
    st = stamps if stamps is not None else stamp_stats(t)
    tau_a = np.asarray(tau, dtype=np.float64)
    dev_a = np.asarray(dev, dtype=np.float64)
    out: dict[str, Any] = {"checked": "median_step_s" in st}
    if not out["checked"]:
        out["reason"] = "fewer than three time stamps"
        return out
    med, jitter, g = st["median_step_s"], st["jitter_rel"], st["gaps"]
    m = np.maximum(np.rint(tau_a / med), 1.0) if med > 0 else np.ones_like(tau_a)
    mu = np.abs(local_slopes(tau_a, dev_a)) if tau_a.size >= 2 else np.ones_like(tau_a)
    bound = mu * jitter / np.sqrt(m) + jitter**2 / 2.0
    half = np.asarray(ci_upper, dtype=np.float64) - np.asarray(ci_lower, dtype=np.float64)
    half = half / 2.0 / np.where(dev_a > 0, dev_a, 1.0)
    frac = np.minimum(1.0, g * 2.0 * m / max(int(st["n"]), 1))
    out.update(
        median_step_s=float(med),
        jitter_rel=jitter,
        gaps=g,
        gap_threshold_s=st["gap_threshold_s"],
        missing_s=st["missing_s"],
        tau_s=[float(v) for v in tau_a],
        bound_rel=[float(v) for v in bound],
        ci_half_width_rel=[float(v) for v in half],
        bound_rel_max=float(np.max(bound)) if bound.size else 0.0,
        gap_fraction=[float(v) for v in frac],
        unreliable_tau_s=[
            float(v) for v, f in zip(tau_a, frac, strict=True) if f > GAP_FRACTION_MAX
        ],
        assumption="constant sample rate (the median step)",
        bound_formula="|slope|*jitter/sqrt(m) + jitter^2/2 (relative, on the deviation)",
    )
    return out


def timing_messages(block: dict[str, Any]) -> list[str]:
    """Warnings when assuming the constant rate may move the curve noticeably."""
    if not block.get("checked"):
        return []
    out = []
    b = float(block["bound_rel_max"])
    if b > WARN_BOUND:
        worst = int(np.argmax(block["bound_rel"]))
        out.append(
            f"the time stamps jitter by {block['jitter_rel']:.2%} of the step: assuming a "
            f"constant rate may move the Allan deviation by up to {b:.2%} (at tau = "
            f"{block['tau_s'][worst]:.3g} s; its CI half-width there "
            f"{block['ci_half_width_rel'][worst]:.1%})"
        )
    if block["gaps"]:
        bad = block["unreliable_tau_s"]
        where = (
            f"; from tau = {min(bad):.3g} s more than {GAP_FRACTION_MAX:.0%} of the cluster "
            "pairs straddle a gap: those points are unreliable"
            if bad
            else ""
        )
        out.append(
            f"{block['gaps']} gap(s) ({block['missing_s']:.4g} s missing) were left in and "
            f"the samples analysed as if contiguous{where}"
        )
    return out
