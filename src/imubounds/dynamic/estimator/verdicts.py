"""Margins and verdicts (docs/dynamic-method.md, section 4).

``[E_W] = [y_W] - [x_W]`` per window. Verdict per channel: ``exceeds`` if some window's
``[E_W]`` (or some change ``[E_W2] - [E_W1]``) lies entirely outside its band;
``consistent`` if there is a decidable window (``[x_W]`` not wider than the band) and
none exceeds; ``undecided`` otherwise. A verdict that another band within
:data:`FRAGILE_SHARE` of the computed one would change is *fragile* (:func:`fragility`).
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from imubounds.dynamic.estimator.aided.forms import label_counts

#: the verdict of a channel whose noise figures (N, B) were given nowhere: its band would
#: be a default preset's, so the margins are given but not judged
NO_REFERENCE = "no reference"
HOW_TO_REFERENCE = (
    "give the IMU's stationary noise: --static noise.json (from 'imubounds static' on a "
    "static log of this IMU), --imu-spec PRESET or accel_nd=..,accel_bs=..,gyro_nd=..,"
    "gyro_bs=.., or imu: accel_nd/accel_bs/gyro_nd/gyro_bs (or preset:) in drive.yaml"
)


#: A verdict resting on a margin within this share of its band is fragile: the verdict
#: against the band scaled by 1 -+ FRAGILE_SHARE differs (docs/dynamic-method.md, section 4).
FRAGILE_SHARE = 0.05


def _is_default(src: str) -> bool:
    return src == "default" or src.endswith("(default)")


def band_reference(cn: Any) -> str | None:
    """Where the stationary band of a channel comes from (the sources of its white noise N
    and bias instability B), None when either is only a default."""
    srcs = getattr(cn, "sources", {}) or {}
    n, b = str(srcs.get("N", "default")), str(srcs.get("B", "default"))
    if _is_default(n) or _is_default(b):
        return None
    return n if n == b else f"N: {n}, B: {b}"


@dataclass
class LevelResult:
    """Windows of one tau level evaluated (arrays over windows)."""

    tau_s: float
    kind: str
    t_start: np.ndarray
    tau: np.ndarray
    x_lo: np.ndarray
    x_hi: np.ndarray
    y_lo: np.ndarray
    y_hi: np.ndarray
    band: np.ndarray
    band_nto: np.ndarray
    k: float
    #: change test: adjacent pairs (window indices), the stationary band of the change
    #: of the window means (turn-on bias cancels), its k
    p1: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))
    p2: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))
    c_band: np.ndarray = field(default_factory=lambda: np.zeros(0))
    c_k: float = 0.0
    #: ``[x_W2 - x_W1]`` over the pairs computed jointly (the tilt change from the gyros,
    #: docs/dynamic-method.md section 3b, (3b.9)); empty: the difference of the windows'
    dx_lo: np.ndarray = field(default_factory=lambda: np.zeros(0))
    dx_hi: np.ndarray = field(default_factory=lambda: np.zeros(0))
    #: per window, the bound forms giving its two ends (``name`` or ``lo_name|hi_name``;
    #: docs/dynamic-method.md, section 3, "Bound forms and their shares")
    bound_by: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=object))

    @property
    def d_lo(self) -> np.ndarray:
        """Lower end of ``[E_W2] - [E_W1]`` over the adjacent pairs (met with the joint
        change where there is one)."""
        lo = np.nextafter(self.e_lo[self.p2] - self.e_hi[self.p1], -np.inf)
        if self.dx_hi.size == lo.size and lo.size:
            alt = np.nextafter(self.y_lo[self.p2] - self.y_hi[self.p1] - self.dx_hi, -np.inf)
            lo = np.maximum(lo, np.where(self._joint_ok, alt, -np.inf))
        return lo

    @property
    def d_hi(self) -> np.ndarray:
        hi = np.nextafter(self.e_hi[self.p2] - self.e_lo[self.p1], np.inf)
        if self.dx_lo.size == hi.size and hi.size:
            alt = np.nextafter(self.y_hi[self.p2] - self.y_lo[self.p1] - self.dx_lo, np.inf)
            hi = np.minimum(hi, np.where(self._joint_ok, alt, np.inf))
        return hi

    @property
    def _joint_ok(self) -> np.ndarray:
        """Pairs whose joint change meets the windows' difference (where it does not, the
        windows' difference is kept: both enclose the same change unless an input bound
        fails, which the window checks report)."""
        lo = self.e_lo[self.p2] - self.e_hi[self.p1]
        hi = self.e_hi[self.p2] - self.e_lo[self.p1]
        alo = self.y_lo[self.p2] - self.y_hi[self.p1] - self.dx_hi
        ahi = self.y_hi[self.p2] - self.y_lo[self.p1] - self.dx_lo
        return np.asarray((np.maximum(lo, alo) <= np.minimum(hi, ahi)), dtype=bool)

    @property
    def c_exceeds(self) -> np.ndarray:
        return (self.d_lo > self.c_band) | (self.d_hi < -self.c_band)

    @property
    def c_decidable(self) -> np.ndarray:
        xw = 0.5 * (self.x_hi - self.x_lo)
        w = xw[self.p1] + xw[self.p2]
        if self.dx_lo.size == w.size and w.size:
            w = np.minimum(w, np.where(self._joint_ok, 0.5 * (self.dx_hi - self.dx_lo), np.inf))
        return w <= self.c_band

    @property
    def e_lo(self) -> np.ndarray:
        return np.nextafter(self.y_lo - self.x_hi, -np.inf)

    @property
    def e_hi(self) -> np.ndarray:
        return np.nextafter(self.y_hi - self.x_lo, np.inf)

    @property
    def halfwidth(self) -> np.ndarray:
        return 0.5 * (self.e_hi - self.e_lo)

    @property
    def decidable(self) -> np.ndarray:
        return 0.5 * (self.x_hi - self.x_lo) <= self.band

    @property
    def exceeds(self) -> np.ndarray:
        return (self.e_lo > self.band) | (self.e_hi < -self.band)

    @property
    def fragile(self) -> np.ndarray:
        """Windows whose test turns with the band scaled by 1 -+ :data:`FRAGILE_SHARE`:
        decidable or not, inside or outside, by a margin within that share of the band."""
        lo, hi = self.band * (1.0 - FRAGILE_SHARE), self.band * (1.0 + FRAGILE_SHARE)
        xw = 0.5 * (self.x_hi - self.x_lo)
        gap = np.maximum(self.e_lo, -self.e_hi)  # outside the band exactly when gap > band
        with np.errstate(invalid="ignore"):
            return ((xw > lo) & (xw <= hi)) | ((gap > lo) & (gap <= hi))

    def scaled(self, factor: float) -> LevelResult:
        """The same windows against the band (and the change band) times ``factor``."""
        return replace(self, band=self.band * factor, c_band=self.c_band * factor)

    def summary(self) -> dict[str, Any]:
        hw = self.halfwidth
        fin = np.isfinite(hw)
        return {
            "tau_s": self.tau_s,
            "halfwidth_max": float(np.max(hw[fin])) if fin.any() else None,
            "halfwidth_median": float(np.median(hw[fin])) if fin.any() else None,
            "stationary": float(np.median(self.band)) if self.band.size else None,
            "stationary_max": float(np.max(self.band)) if self.band.size else None,
            "exceeds_fraction": float(np.mean(self.exceeds)) if self.band.size else 0.0,
            "decidable_fraction": float(np.mean(self.decidable)) if self.band.size else 0.0,
            "fragile_fraction": float(np.mean(self.fragile)) if self.band.size else 0.0,
            "n_windows": int(self.band.size),
            "k": self.k,
            "aided_from": "vehicle bounds" if self.kind == "vehicle" else "aiding",
            "bound_by": label_counts(self.bound_by),
            "bound_by_max": self._bound_by_max(hw, fin),
            **self._change_summary(),
        }

    def _bound_by_max(self, hw: np.ndarray, fin: np.ndarray) -> str:
        """The forms giving the bound of the window of ``halfwidth_max``."""
        if not fin.any() or self.bound_by.size != hw.size:
            return ""
        return str(self.bound_by[int(np.argmax(np.where(fin, hw, -np.inf)))])

    def _change_summary(self) -> dict[str, Any]:
        if self.p1.size == 0:
            return {"n_changes": 0}
        hw = 0.5 * (self.d_hi - self.d_lo)
        fin = np.isfinite(hw)
        return {
            "n_changes": int(self.p1.size),
            "change_halfwidth_median": float(np.median(hw[fin])) if fin.any() else None,
            "change_stationary": float(np.median(self.c_band)),
            "change_exceeds_fraction": float(np.mean(self.c_exceeds)),
            "change_k": self.c_k,
        }


@dataclass
class ChannelMargins:
    channel: str
    unit: str
    source: str
    levels: list[LevelResult]
    verdict: str
    reason: str
    exceeding: list[dict[str, Any]]
    n_exceeding: int
    notes: list[str] = field(default_factory=list)
    #: the verdict against the band as computed (the same as ``verdict`` unless that is
    #: ``no reference``: then the verdict against the default preset's band, not a finding)
    raw_verdict: str = ""
    #: the verdicts against the band scaled by 1 -+ FRAGILE_SHARE that differ from
    #: ``verdict`` ({"0.95": "undecided"}): empty when the verdict is not fragile
    fragile: dict[str, str] = field(default_factory=dict)

    def table(self) -> list[dict[str, Any]]:
        return [lv.summary() for lv in self.levels]

    def to_dict(self) -> dict[str, Any]:
        return {
            "unit": self.unit,
            "aided_from": self.source,
            "verdict": self.verdict,
            "reason": self.reason,
            "exceeding_windows": self.exceeding,
            "n_exceeding_windows": self.n_exceeding,
            "notes": self.notes,
            "fragile": bool(self.fragile),
            **({"fragile_detail": fragile_text(self.verdict, self.fragile),
                "verdict_if_band_scaled": dict(self.fragile)} if self.fragile else {}),
            **(
                {"verdict_against_default_band": self.raw_verdict}
                if self.verdict == NO_REFERENCE
                else {}
            ),
        }


def verdict_of(levels: list[LevelResult], max_list: int = 50) -> tuple[str, str, list[Any], int]:
    """The channel verdict from its evaluated levels."""
    exc: list[dict[str, Any]] = []
    n_exc = 0
    any_dec = False
    n_lev = n_chg = 0
    for lv in levels:
        ex = lv.exceeds
        any_dec |= bool(np.any(lv.decidable))
        for w in np.flatnonzero(ex):
            n_lev += 1
            if len(exc) < max_list:
                exc.append(
                    {
                        "test": "level",
                        "t_start_s": float(lv.t_start[w]),
                        "tau_s": float(lv.tau[w]),
                        "interval": [float(lv.e_lo[w]), float(lv.e_hi[w])],
                        "stationary": float(lv.band[w]),
                        "bound_by": str(lv.bound_by[w]) if lv.bound_by.size else "",
                    }
                )
    for lv in levels:
        if lv.p1.size == 0:
            continue
        any_dec |= bool(np.any(lv.c_decidable))
        cex = lv.c_exceeds
        d_lo, d_hi = lv.d_lo, lv.d_hi
        for q in np.flatnonzero(cex):
            n_chg += 1
            if len(exc) < max_list:
                w1, w2 = int(lv.p1[q]), int(lv.p2[q])
                exc.append(
                    {
                        "test": "change",
                        "t_start_s": float(lv.t_start[w1]),
                        "t_change_s": float(lv.t_start[w2]),
                        "tau_s": float(lv.tau[w1]),
                        "interval": [float(d_lo[q]), float(d_hi[q])],
                        "stationary": float(lv.c_band[q]),
                    }
                )
    n_exc = n_lev + n_chg
    if n_exc:
        parts = []
        if n_lev:
            f = next(e for e in exc if e["test"] == "level") if any(
                e["test"] == "level" for e in exc
            ) else None
            parts.append(
                f"{n_lev} window(s) lie entirely outside the stationary band"
                + (f" (first at t = {f['t_start_s']:.1f} s, tau = {f['tau_s']:.3g} s)" if f else "")
            )
        if n_chg:
            f = next((e for e in exc if e["test"] == "change"), None)
            parts.append(
                f"{n_chg} change(s) between adjacent windows lie entirely outside the "
                "stationary band of changes"
                + (f" (first at t = {f['t_change_s']:.1f} s, tau = {f['tau_s']:.3g} s)"
                   if f else "")
            )
        return "exceeds", "; ".join(parts), exc, n_exc
    if any_dec:
        return (
            "consistent",
            "every decidable window, and every change between adjacent windows, lies "
            "within its stationary band",
            exc,
            0,
        )
    return (
        "undecided",
        "the aided interval is wider than the stationary band at every tau",
        exc,
        0,
    )


def attribute_exceeds(margins: dict[str, ChannelMargins],
                      rests_on: dict[str, tuple[str, ...]]) -> list[str]:
    """Name the channel a fault is in (docs/dynamic-method.md section 4, "Which channel").

    A channel whose margins rest on another channel's budget (``rests_on``: gyro_x,
    gyro_y judged from an accelerometer's window pairs; accel_z with the roll and pitch
    of the full attitude states, built from accel_x's and accel_y's windows) cannot tell
    its own fault from that channel's: when a channel it rests on ``exceeds`` by its own
    test, its ``exceeds`` becomes ``undecided`` (the reason names the channel; the
    windows outside the band stay listed). The channels rested on are never changed
    here, so the order does not matter. Returns the notes (one per changed channel)."""
    notes = []
    for ch, srcs in rests_on.items():
        m = margins.get(ch)
        if m is None or m.verdict != "exceeds":
            continue
        hit = [s for s in srcs if s != ch and s not in rests_on
               and getattr(margins.get(s), "verdict", None) == "exceeds"]
        if not hit:
            continue
        who = " and ".join(hit)
        m.verdict = "undecided"
        m.fragile = {}  # computed against `exceeds`; undecided is no decided verdict
        m.reason = (
            f"{m.reason}; but {ch}'s windows rest on {who}'s budget and {who} exceeds its "
            f"own stationary band: the excess is {who}'s or {ch}'s, not decided"
        )
        notes.append(f"{ch}: `exceeds` attributed to {who} (its windows rest on {who}'s "
                     "budget, which fails by its own test)")
        m.notes.append(notes[-1])
    return notes


def fragility(levels: list[LevelResult], verdict: str) -> dict[str, str]:
    """The verdicts against the band scaled by ``1 - FRAGILE_SHARE`` and ``1 +
    FRAGILE_SHARE`` that differ from ``verdict`` (keys ``"0.95"``, ``"1.05"``): a verdict
    that rests on a margin within 5 % of the band is fragile, not decided."""
    out: dict[str, str] = {}
    for factor in (1.0 - FRAGILE_SHARE, 1.0 + FRAGILE_SHARE):
        other = verdict_of([lv.scaled(factor) for lv in levels])[0]
        if other != verdict:
            out[f"{factor:.2f}"] = other
    return out


def fragile_text(verdict: str, flips: dict[str, str]) -> str:
    """One line saying why a verdict is fragile."""
    parts = []
    for key, other in sorted(flips.items()):
        how = "narrower" if float(key) < 1 else "wider"
        parts.append(f"{other} with the band {round(100 * FRAGILE_SHARE)} % {how}")
    return (f"FRAGILE: '{verdict}' rests on a margin within {round(100 * FRAGILE_SHARE)} % of "
            f"the stationary band ({'; '.join(parts)}): not decided")
