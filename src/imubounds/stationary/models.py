"""Stochastic error models of a static sensor signal (METHOD.md 1.3).

Two models are fitted to a rate signal (gyro rad/s or accelerometer m/s², SI):

* **First-order Gauss–Markov (GM)**, optionally on top of white noise
  (white + GM is an ARMA(1,1) process).  The exact discrete form used for
  simulation is ``x[k+1] = exp(-β δt)·x[k] + σ·sqrt(1 - exp(-2β δt))·w[k]``,
  β = 1/correlation time, σ the stationary standard deviation.  β and σ come
  from a least-squares fit of ``A·exp(-β|τ|)`` to the sample autocovariance
  at lags ≥ 1 (lag 0 holds the white noise, so it is skipped), so a white
  floor does not ruin the correlation time; the white variance is what lag 0
  has in excess of the GM.  The paper's 1/e read-off of the normalised
  autocorrelation is offered as ``method="paper"``.
* **AR(p) by Burg's method** with order selection (AIC, BIC, HQIC, FPE or a
  fixed order).  Convention (METHOD.md):
  ``y[n] = -Σ_{k=1..p} a_k·y[n-k] + e[n]``, ``var(e) = noise_variance``.
  ``coefficients`` are these ``a_k``.  Statsmodels' ``burg`` returns
  ``rho = -a`` (``y[n] = Σ rho_k·y[n-k] + e[n]``).

Long logs are decimated by **block averaging** before fitting (default
``decimate_to_hz="auto"``: down to about 1 Hz while keeping at least 20 000
samples), so the models describe the long-term behaviour and fitting a
10⁶-sample log takes well under a second per channel.  Block averaging keeps
the Allan variance: the Allan variance of the averaged series at cluster
``m`` equals that of the raw series at cluster ``m·D``; the GM fit corrects
its amplitude for the averaging exactly.  Every fitted model can simulate
noise and give its theoretical Allan deviation, so a measured curve can be
compared with each model.

The code: :mod:`~imubounds.stationary.model_base` (signal checks, block
averaging, the Allan variance of a sequence from its autocovariance),
:mod:`~imubounds.stationary.gauss_markov`, :mod:`~imubounds.stationary.ar_model`
and, here, the choice of the model that follows a measured curve.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any, Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray

from imubounds.errors import OptionError
from imubounds.stationary.ar_model import (
    CRITERIA,
    ArModel,
    ar_from_pacf,
    burg_path,
    fit_ar_burg,
    information_criteria,
)
from imubounds.stationary.gauss_markov import (
    GaussMarkovModel,
    fit_gauss_markov,
)
from imubounds.stationary.model_base import (
    ModelNotSupportedError,
    _as_signal,
    block_average,
    decimation_factor,
)

__all__ = [
    "ArModel",
    "GaussMarkovModel",
    "ModelNotSupportedError",
    "ModelsResult",
    "adequacy",
    "candidate_factors",
    "fit_models",
    "parse_kinds",
]


# ----------------------------------------------------------------------------
# adequacy: does the model's curve follow the measured one?

#: A model fits when its curve lies inside the measured 95 % interval (from each
#: point's EDF) widened by this relative tolerance at no fewer than
#: ADEQUACY_FRACTION of the points where it is valid, and is off by no more than
#: ADEQUACY_MAX_RATIO at any of those points with EDF >= ADEQUACY_EDF_MIN.
ADEQUACY_TOLERANCE = 0.10
ADEQUACY_FRACTION = 0.9
ADEQUACY_MAX_RATIO = 1.5
ADEQUACY_EDF_MIN = 10.0
#: Fit rates (Hz) tried besides the automatic one when a curve is given: a
#: lower rate lets a low-order model follow the long-term part of the curve.
CANDIDATE_RATES_HZ: tuple[float, ...] = (10.0, 1.0, 0.5, 0.2, 0.1)
#: Fewest samples a candidate fit rate must leave.
CANDIDATE_MIN_SAMPLES = 500
#: AR orders tried above the criterion's choice (up to the maximum order).
AR_ORDER_LADDER: tuple[int, ...] = (1, 2, 3, 4, 5, 6, 8, 10, 12, 15, 20, 25, 30, 40, 50, 60, 80)


def adequacy(model: GaussMarkovModel | ArModel, curve: Any) -> dict[str, Any]:
    """How well ``model`` follows a measured Allan-family ``curve`` where it is valid.

    ``curve`` is an :class:`~imubounds.stationary.allan.AllanResult` (its
    estimator is used for the model's curve). Over the points with
    τ ≥ ``model.valid_from_tau_s``: z = ln(model/measured) over the spread of
    ln σ² for the point's EDF (ψ₁(edf/2), halved for the deviation) combined
    with :data:`ADEQUACY_TOLERANCE`; the fraction with |z| ≤ 2 (a 95 %
    interval), the worst ratio model/measured at points with enough EDF and
    its τ, and ``chi2_dof`` (mean z²). ``adequate`` applies
    :data:`ADEQUACY_FRACTION` and :data:`ADEQUACY_MAX_RATIO`.
    """
    from scipy import special

    tau = np.asarray(curve.tau, dtype=np.float64)
    dev = np.asarray(curve.dev, dtype=np.float64)
    edf = np.asarray(curve.edf, dtype=np.float64)
    estimator = str(getattr(curve, "estimator", "overlapping"))
    rate = getattr(curve, "rate_hz", None)
    valid = (tau >= model.valid_from_tau_s * (1 - 1e-9)) & (dev > 0)
    out: dict[str, Any] = {
        "estimator": estimator,
        "valid_from_tau_s": model.valid_from_tau_s,
        "criterion": (
            f"inside the curve's 95 % interval widened by {ADEQUACY_TOLERANCE:.0%} at >= "
            f"{ADEQUACY_FRACTION:.0%} of the points with tau >= valid_from_tau_s, and off by "
            f"no more than x{ADEQUACY_MAX_RATIO:g} where the EDF is >= {ADEQUACY_EDF_MIN:g}"
        ),
    }
    if np.count_nonzero(valid) < 3:
        out.update(points=int(np.count_nonzero(valid)), adequate=False,
                   reason="fewer than 3 points of the curve where the model is valid")  # fmt: skip
        return out
    pred = np.sqrt(model.variance(tau[valid], estimator, rate_hz=rate))
    t, d, e = tau[valid], dev[valid], np.maximum(edf[valid], 0.5)
    lr = np.log(pred / d)
    sd = np.sqrt(special.polygamma(1, e / 2.0) / 4.0 + math.log(1.0 + ADEQUACY_TOLERANCE) ** 2)
    zz = lr / sd
    inside = np.abs(zz) <= 2.0
    strong = e >= ADEQUACY_EDF_MIN
    pool = np.flatnonzero(strong) if np.any(strong) else np.arange(t.size)
    worst = int(pool[np.argmax(np.abs(lr[pool]))])
    frac = float(np.mean(inside))
    ratio = float(np.exp(lr[worst]))
    out.update(
        tau_range_s=[float(t[0]), float(t[-1])],
        points=int(t.size),
        inside_fraction=frac,
        worst_ratio=ratio,
        worst_tau_s=float(t[worst]),
        chi2_dof=float(np.mean(zz**2)),
        adequate=bool(
            frac >= ADEQUACY_FRACTION and abs(math.log(ratio)) <= math.log(ADEQUACY_MAX_RATIO)
        ),
    )
    return out


def _score(adq: dict[str, Any]) -> tuple[int, float]:
    return (0 if adq.get("adequate") else 1, float(adq.get("chi2_dof", math.inf)))


def candidate_factors(
    n: int, rate_hz: float, decimate_to_hz: float | Literal["auto"] | None
) -> list[int]:
    """Block-averaging factors to try: the asked one first, then those of
    :data:`CANDIDATE_RATES_HZ` that leave at least :data:`CANDIDATE_MIN_SAMPLES`."""
    first = decimation_factor(n, rate_hz, decimate_to_hz)
    out = [first]
    for target in CANDIDATE_RATES_HZ:
        d = decimation_factor(n, rate_hz, target)
        if d not in out and n // d >= CANDIDATE_MIN_SAMPLES:
            out.append(d)
    return out


def _describe_misfit(kind: str, adq: dict[str, Any], tried: str) -> str:
    if "worst_ratio" not in adq:
        return f"no {kind} model could be checked against the curve ({adq.get('reason', '')})"
    return (
        f"no {kind} model fits the curve within its intervals (tried {tried}); the best "
        f"follows {adq['inside_fraction']:.0%} of the points from tau = "
        f"{adq['valid_from_tau_s']:.3g} s and is off by x{adq['worst_ratio']:.3g} at tau = "
        f"{adq['worst_tau_s']:.3g} s: do not use it to predict the curve there"
    )


def _best_gm(
    arr: NDArray[np.float64],
    rate_hz: float,
    factors: list[int],
    curve: Any,
    notes: list[str],
    **kw: Any,
) -> tuple[GaussMarkovModel | None, dict[str, Any] | None]:
    best: tuple[tuple[int, float], GaussMarkovModel, dict[str, Any], list[str]] | None = None
    errors: list[str] = []
    # an adequate model at the smallest factor (highest rate) wins: try those first
    for d in sorted(factors):
        if best is not None and best[0][0] == 0:
            break
        local: list[str] = []
        try:
            gm = fit_gauss_markov(arr, rate_hz, decimate_to_hz=rate_hz / d, notes=local, **kw)
        except ModelNotSupportedError as err:
            errors.append(str(err))
            continue
        adq = adequacy(gm, curve)
        key = (_score(adq)[0], d if adq.get("adequate") else _score(adq)[1])
        if best is None or key < best[0]:
            best = (key, gm, adq, local)
    if best is None:
        notes.append("Gauss-Markov model not fitted: " + (errors[0] if errors else "no rate"))
        return None, None
    _, gm, adq, local = best
    notes.extend(local)
    tried = ", ".join(f"{rate_hz / d:g} Hz" for d in factors)
    if not adq.get("adequate"):
        notes.append(_describe_misfit("Gauss-Markov (+ white)", adq, tried))
    return gm, adq


def _best_ar(
    arr: NDArray[np.float64],
    rate_hz: float,
    factors: list[int],
    curve: Any,
    order_max: int,
    criterion: str,
    notes: list[str],
    unit: str | None,
) -> tuple[ArModel | None, dict[str, Any] | None]:
    best: tuple[tuple[int, float], ArModel, dict[str, Any]] | None = None
    for d in sorted(factors):  # as in _best_gm: the first adequate model wins
        if best is not None and best[0][0] == 0:
            break
        x = block_average(arr, d)
        n = x.size
        pmax = min(int(order_max), n // 10 - 1)
        if pmax < 1:
            continue
        pacf, s2 = burg_path(x, pmax)
        crit = information_criteria(s2, n)
        p0 = max(int(np.argmin(crit[criterion])), 1)
        orders = [p0] + [p for p in (*AR_ORDER_LADDER, pmax) if p0 < p <= pmax]
        local_best: tuple[tuple[int, float], ArModel, dict[str, Any]] | None = None
        for p in sorted(set(orders)):
            model = _ar_model(pacf, s2, p, rate_hz / d, d, criterion, pmax, crit, x, unit)
            adq = adequacy(model, curve)
            key = _score(adq)
            if local_best is None or key < local_best[0]:
                local_best = (key, model, adq)
            if adq.get("adequate"):
                break
        if local_best is None:
            continue
        key = (local_best[0][0], d if local_best[2].get("adequate") else local_best[0][1])
        if best is None or key < best[0]:
            best = (key, local_best[1], local_best[2])
    if best is None:
        notes.append("AR model not fitted: too few samples at every fit rate tried")
        return None, None
    _, model, adq = best
    tried = ", ".join(f"{rate_hz / d:g} Hz" for d in factors) + f", orders up to {order_max}"
    if not adq.get("adequate"):
        notes.append(_describe_misfit("AR", adq, tried))
    elif model.order == order_max:
        notes.append(f"the AR model needs the largest order tried ({order_max}); a larger"
                     " --ar-max-order may give a simpler fit elsewhere")  # fmt: skip
    return model, adq


def _ar_model(
    pacf: NDArray[np.float64],
    s2: NDArray[np.float64],
    p: int,
    rate: float,
    d: int,
    criterion: str,
    pmax: int,
    crit: dict[str, NDArray[np.float64]],
    x: NDArray[np.float64],
    unit: str | None,
) -> ArModel:
    a = ar_from_pacf(pacf[: p + 1])
    return ArModel(
        coefficients=tuple(float(v) for v in a),
        noise_variance=float(s2[p]),
        rate_hz=rate,
        decimation=d,
        criterion=criterion,
        orders=tuple(range(pmax + 1)),
        criteria={k: [float(v) for v in vals] for k, vals in crit.items()},
        mean=float(x.mean()),
        unit=unit,
    )


@dataclass
class ModelsResult:
    """The models fitted to one channel (either may be ``None``: see ``notes``)."""

    gauss_markov: GaussMarkovModel | None
    ar: ArModel | None
    rate_hz: float
    decimation: int
    n_samples: int
    unit: str | None = None
    notes: list[str] = field(default_factory=list)
    adequacy: dict[str, dict[str, Any]] = field(default_factory=dict)

    @property
    def effective_rate_hz(self) -> float:
        return self.rate_hz / self.decimation

    @property
    def models(self) -> dict[str, GaussMarkovModel | ArModel]:
        """The fitted models by name (``"gauss_markov"``, ``"ar"``)."""
        out: dict[str, GaussMarkovModel | ArModel] = {}
        if self.gauss_markov is not None:
            out["gauss_markov"] = self.gauss_markov
        if self.ar is not None:
            out["ar"] = self.ar
        return out

    def adev(self, tau: ArrayLike) -> dict[str, NDArray[np.float64]]:
        """Each model's theoretical Allan deviation at τ (s), for plotting."""
        return {k: m.adev(tau) for k, m in self.models.items()}

    def to_dict(self) -> dict[str, Any]:
        return {
            "input_rate_hz": self.rate_hz,
            "n_samples": self.n_samples,
            "decimation": self.decimation,
            "effective_rate_hz": self.effective_rate_hz,
            "decimation_method": "block average",
            "gauss_markov": _with_adequacy(self.gauss_markov, self.adequacy.get("gauss_markov")),
            "ar": _with_adequacy(self.ar, self.adequacy.get("ar")),
            "notes": list(self.notes),
        }


def _with_adequacy(
    model: GaussMarkovModel | ArModel | None, adq: dict[str, Any] | None
) -> dict[str, Any] | None:
    if model is None:
        return None
    d = model.to_dict()
    if adq is not None:
        d["adequacy"] = adq
    return d


def parse_kinds(kinds: str | Sequence[str]) -> tuple[str, ...]:
    """``"gm,ar"`` or a sequence → validated tuple of model kinds."""
    items = kinds.split(",") if isinstance(kinds, str) else list(kinds)
    alias = {"gauss_markov": "gm", "gm": "gm", "ar": "ar", "burg": "ar"}
    out: list[str] = []
    for k in items:
        key = alias.get(str(k).strip().lower())
        if key is None:
            raise OptionError(f"unknown model {k!r}; choose from gm, ar")
        if key not in out:
            out.append(key)
    return tuple(out)


def fit_models(
    y: ArrayLike,
    rate_hz: float,
    kinds: str | Sequence[str] = ("gm", "ar"),
    *,
    ar_order_max: int = 20,
    criterion: str = "bic",
    ar_order: int | None = None,
    decimate_to_hz: float | Literal["auto"] | None = "auto",
    max_lag_s: float | None = None,
    gm_method: Literal["acf_ls", "paper"] = "acf_ls",
    name: str = "signal",
    unit: str | None = None,
    curve: Any = None,
) -> ModelsResult:
    """Fit the asked stochastic models to one channel.

    Both fits share one block-averaged series (``decimate_to_hz``; default
    ``"auto"``: ~1 Hz, ≥ 20 000 samples kept).  Invalid input (NaN, constant,
    too short) raises; a model the data do not support (e.g. no positive
    autocorrelation for GM) is left ``None`` and explained in ``notes``.

    With ``curve`` (the channel's measured Allan-family curve) every model is
    checked against it (:func:`adequacy`): the fit is repeated at the fit rates
    of :func:`candidate_factors` and, for AR, at increasing orders from the
    criterion's choice up to ``ar_order_max``, and the first adequate model
    (widest valid range, lowest order) is kept; when none is adequate the
    closest one is kept and a note says plainly that no model of that family
    fits. ``adequacy`` of the result holds the check of each kept model.

    Other parameters are those of :func:`fit_gauss_markov` and :func:`fit_ar_burg`.
    """
    ks = parse_kinds(kinds)
    arr = _as_signal(y, rate_hz, name)
    d = decimation_factor(arr.size, rate_hz, decimate_to_hz)
    notes: list[str] = []
    if d > 1:
        dropped = arr.size % d
        notes.append(
            f"decimated by block averaging from {rate_hz:g} Hz to {rate_hz / d:g} Hz "
            f"(factor {d}) before the model fits"
            + (f"; last {dropped} samples dropped" if dropped else "")
        )
    fixed = float(rate_hz / d) if d > 1 else None
    gm: GaussMarkovModel | None = None
    ar: ArModel | None = None
    if curve is not None and ar_order is None:
        if criterion not in CRITERIA:
            raise OptionError(
                f"AR order criterion must be one of {', '.join(CRITERIA)}; got {criterion!r}"
            )
        if int(ar_order_max) < 1:
            raise OptionError(f"AR order must be >= 1, got {ar_order_max}")
        factors = candidate_factors(arr.size, rate_hz, decimate_to_hz)
        adq: dict[str, dict[str, Any]] = {}
        if "gm" in ks:
            gm, a_gm = _best_gm(arr, rate_hz, factors, curve, notes, max_lag_s=max_lag_s,
                                method=gm_method, name=name, unit=unit)  # fmt: skip
            if a_gm is not None:
                adq["gauss_markov"] = a_gm
        if "ar" in ks:
            ar, a_ar = _best_ar(arr, rate_hz, factors, curve, ar_order_max, criterion, notes, unit)
            if a_ar is not None:
                adq["ar"] = a_ar
    else:
        gm, ar = _fit_plain(arr, rate_hz, ks, fixed, notes, max_lag_s=max_lag_s,
                            gm_method=gm_method, ar_order_max=ar_order_max, criterion=criterion,
                            ar_order=ar_order, name=name, unit=unit)  # fmt: skip
        adq = {}
    return ModelsResult(
        gauss_markov=gm,
        ar=ar,
        rate_hz=float(rate_hz),
        decimation=d,
        n_samples=int(arr.size),
        unit=unit,
        notes=notes,
        adequacy=adq,
    )


def _fit_plain(
    arr: NDArray[np.float64],
    rate_hz: float,
    ks: tuple[str, ...],
    fixed: float | None,
    notes: list[str],
    *,
    max_lag_s: float | None,
    gm_method: Literal["acf_ls", "paper"],
    ar_order_max: int,
    criterion: str,
    ar_order: int | None,
    name: str,
    unit: str | None,
) -> tuple[GaussMarkovModel | None, ArModel | None]:
    """The models at one fit rate, without checking them against a curve."""
    gm: GaussMarkovModel | None = None
    ar: ArModel | None = None
    if "gm" in ks:
        try:
            gm = fit_gauss_markov(
                arr,
                rate_hz,
                decimate_to_hz=fixed,
                max_lag_s=max_lag_s,
                method=gm_method,
                name=name,
                unit=unit,
                notes=notes,
            )
        except ModelNotSupportedError as err:
            notes.append(f"Gauss-Markov model not fitted: {err}")
    if "ar" in ks:
        ar = fit_ar_burg(
            arr,
            rate_hz,
            order_max=ar_order_max,
            criterion=criterion,
            order=ar_order,
            decimate_to_hz=fixed,
            name=name,
            unit=unit,
            notes=notes,
        )
    return gm, ar
