"""IMU noise simulator: multi-axis sensor noise from noise terms, datasheets or fitted models.

Each channel's noise is the sum of independent components, all in SI:

=========  ==========================================  ==============================
term       process (rate samples y_k, period δt)        Allan variance
=========  ==========================================  ==============================
Q          (e_{k+1} - e_k)/δt, e_k ~ N(0, Q²)            3Q²/τ²  (exact for τ = mδt)
N          N/√δt · w_k                                  N²/τ    (exact)
B          sum of first-order Gauss–Markov processes     (2 ln2/π)·B² over the τ range
           approximating flicker noise over a τ range    ``bias_tau_range_s``
K          random walk b_{k+1} = b_k + K√δt·w_k          K²τ/3 + K²δt²/(6τ)
R          deterministic ramp R·t                        R²τ²/2
GM         exact discrete Gauss–Markov (any number)      closed form (models.py)
AR         an AR(p) model fitted by Burg (its own rate)  from its autocovariance
bias       constant, plus an optional turn-on bias drawn from N(0, bias_sigma²)
=========  ==========================================  ==============================

The flicker approximation is :func:`imubounds.stationary.flicker.flicker_gm_terms`
(shared with the dynamic error budget).

Generation is seeded and reproducible: every channel, and every component
within a channel, draws from its own stream spawned from one
:class:`numpy.random.SeedSequence`, so adding a component or a channel does
not change the others.  Output is an :class:`~imubounds.io.log.ImuLog`, written by
:func:`write_csv` in the layout the readers take
(``time_s, gyro_x_rads, ..., accel_z_mps2``).
"""

from __future__ import annotations

import json
import math
import re
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any, Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray

from imubounds import presets as _presets
from imubounds.errors import InputError, OptionError
from imubounds.io.log import IMU_CHANNELS, ImuLog
from imubounds.stationary.ar_model import ArModel
from imubounds.stationary.flicker import DEFAULT_BIAS_TAU_RANGE, flicker_gm_terms
from imubounds.stationary.gauss_markov import GaussMarkovModel
from imubounds.units import DEG, G0, SI_UNITS, sensor_kind, si_unit_of_signal

TERMS: tuple[str, ...] = ("Q", "N", "B", "K", "R")
#: CSV column of each channel in the layout the readers recognise.
CSV_COLUMNS: dict[str, str] = {
    "gyro_x": "gyro_x_rads",
    "gyro_y": "gyro_y_rads",
    "gyro_z": "gyro_z_rads",
    "accel_x": "accel_x_mps2",
    "accel_y": "accel_y_mps2",
    "accel_z": "accel_z_mps2",
}
# component order: fixes which spawned stream each component uses
_COMPONENTS = ("Q", "N", "B", "K", "bias", "gm", "ar")


# ----------------------------------------------------------------------------
# units of datasheet figures

# name -> (factor to SI, (angle, length, time) exponents)
_UNIT_ATOMS: dict[str, tuple[float, tuple[float, float, float]]] = {
    "rad": (1.0, (1, 0, 0)),
    "mrad": (1e-3, (1, 0, 0)),
    "urad": (1e-6, (1, 0, 0)),
    "µrad": (1e-6, (1, 0, 0)),
    "deg": (DEG, (1, 0, 0)),
    "°": (DEG, (1, 0, 0)),
    "mdeg": (1e-3 * DEG, (1, 0, 0)),
    "arcsec": (DEG / 3600.0, (1, 0, 0)),
    "dps": (DEG, (1, 0, -1)),
    "mdps": (1e-3 * DEG, (1, 0, -1)),
    "m": (1.0, (0, 1, 0)),
    "mm": (1e-3, (0, 1, 0)),
    "g": (G0, (0, 1, -2)),
    "mg": (1e-3 * G0, (0, 1, -2)),
    "ug": (1e-6 * G0, (0, 1, -2)),
    "µg": (1e-6 * G0, (0, 1, -2)),
    "s": (1.0, (0, 0, 1)),
    "sec": (1.0, (0, 0, 1)),
    "ms": (1e-3, (0, 0, 1)),
    "min": (60.0, (0, 0, 1)),
    "h": (3600.0, (0, 0, 1)),
    "hr": (3600.0, (0, 0, 1)),
    "hour": (3600.0, (0, 0, 1)),
    "hz": (1.0, (0, 0, -1)),
    "rthz": (1.0, (0, 0, -0.5)),
    "rth": (60.0, (0, 0, 0.5)),
    "rts": (1.0, (0, 0, 0.5)),
    "1": (1.0, (0, 0, 0)),
}
_TOKEN = re.compile(r"\s*(sqrt\(|√|\(|\)|\^|/|\*|·|[-+]?\d+(?:\.\d*)?|[A-Za-zµ°]+)")

Dims = tuple[float, float, float]


def _tokens(text: str) -> list[str]:
    pos, out = 0, []
    s = text.strip()
    while pos < len(s):
        m = _TOKEN.match(s, pos)
        if not m or m.end() == pos:
            raise OptionError(f"cannot read unit {text!r} at {s[pos:]!r}")
        out.append(m.group(1))
        pos = m.end()
    return out


class _UnitParser:
    def __init__(self, text: str) -> None:
        self.text = text
        self.toks = _tokens(text)
        self.i = 0

    def peek(self) -> str | None:
        return self.toks[self.i] if self.i < len(self.toks) else None

    def take(self) -> str:
        tok = self.peek()
        if tok is None:
            raise OptionError(f"unit {self.text!r} ends too early")
        self.i += 1
        return tok

    def parse(self) -> tuple[float, Dims]:
        f, d = self.expr()
        if self.peek() is not None:
            raise OptionError(f"unexpected {self.peek()!r} in unit {self.text!r}")
        return f, d

    def expr(self) -> tuple[float, Dims]:
        f, d = self.factor()
        while self.peek() in ("/", "*", "·"):
            op = self.take()
            f2, d2 = self.factor()
            sgn = -1.0 if op == "/" else 1.0
            f *= f2**sgn
            d = (d[0] + sgn * d2[0], d[1] + sgn * d2[1], d[2] + sgn * d2[2])
        return f, d

    def factor(self) -> tuple[float, Dims]:
        tok = self.take()
        if tok in ("sqrt(", "("):
            f, d = self.expr()
            if self.take() != ")":
                raise OptionError(f"missing ')' in unit {self.text!r}")
            if tok == "sqrt(":
                f, d = math.sqrt(f), (d[0] / 2, d[1] / 2, d[2] / 2)
        elif tok == "√":
            f, d = self.factor()
            f, d = math.sqrt(f), (d[0] / 2, d[1] / 2, d[2] / 2)
        else:
            f, d = self.atom(tok)
        nxt = self.peek()
        if nxt is not None and re.fullmatch(r"\d", nxt):  # m/s2: digit right after a name
            p = float(self.take())
            f, d = f**p, (d[0] * p, d[1] * p, d[2] * p)
        elif nxt == "^":
            self.take()
            try:
                p = float(self.take())
            except ValueError as err:
                raise OptionError(f"bad exponent in unit {self.text!r}") from err
            f, d = f**p, (d[0] * p, d[1] * p, d[2] * p)
        return f, d

    def atom(self, tok: str) -> tuple[float, Dims]:
        key = tok.lower() if tok.lower() in _UNIT_ATOMS else tok
        if key in _UNIT_ATOMS:
            return _UNIT_ATOMS[key][0], _UNIT_ATOMS[key][1]
        if tok == "1":
            return 1.0, (0.0, 0.0, 0.0)
        raise OptionError(
            f"unknown unit {tok!r} in {self.text!r}; known: {', '.join(sorted(_UNIT_ATOMS))}"
        )


def parse_unit(text: str) -> tuple[float, Dims]:
    """Parse a unit like ``deg/s/sqrt(Hz)``, ``deg/h^0.5``, ``m/s/rtHz``, ``ug``.

    Returns (factor to SI, (angle, length, time) exponents).
    """
    return _UnitParser(text).parse()


def _dims_of(kind: str, what: str) -> Dims:
    """SI dimensions of a term (or ``signal``/``time``) for a sensor kind."""
    if what == "time":
        return (0.0, 0.0, 1.0)
    sig: Dims = (1.0, 0.0, -1.0) if kind == "gyro" else (0.0, 1.0, -2.0)
    extra = {"Q": 1.0, "N": 0.5, "B": 0.0, "K": -0.5, "R": -1.0, "signal": 0.0}[what]
    return (sig[0], sig[1], sig[2] + extra)


def _unit_hint(kind: str, what: str) -> str:
    if what == "time":
        return "s"
    if what == "signal":
        return si_unit_of_signal(kind)  # type: ignore[arg-type]
    return SI_UNITS[kind][what]  # type: ignore[index]


def parse_quantity(value: Any, kind: str, what: str, where: str = "") -> float:
    """A datasheet figure → SI float.

    ``value`` is a number (already SI), a string ``"0.05 deg/s/sqrt(Hz)"`` or a
    mapping ``{"value": 0.05, "unit": "deg/s/sqrt(Hz)"}``.  ``what`` is a term
    (Q, N, B, K, R), ``"signal"`` or ``"time"``; the unit's dimensions are
    checked against it.
    """
    label = f"{where}{what}" if where else what
    if isinstance(value, Mapping):
        if "value" not in value:
            raise OptionError(f"{label}: a mapping needs 'value' (and optionally 'unit')")
        number, unit = value["value"], value.get("unit")
    elif isinstance(value, str):
        m = re.fullmatch(r"\s*([-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?)\s*(.*?)\s*", value)
        if not m:
            raise OptionError(f"{label}: cannot read {value!r}; write e.g. '0.05 deg/s/sqrt(Hz)'")
        number, unit = m.group(1), (m.group(2) or None)
    else:
        number, unit = value, None
    try:
        x = float(number)
    except (TypeError, ValueError) as err:
        raise OptionError(f"{label}: {number!r} is not a number") from err
    if not math.isfinite(x):
        raise OptionError(f"{label}: {x} is not finite")
    if unit is None or str(unit).strip() == "":
        return x
    try:
        factor, dims = parse_unit(str(unit))
    except OptionError as err:  # name the file and key the unit came from
        raise OptionError(f"{label}: {err}") from None
    want = _dims_of(kind, what)
    if any(abs(a - b) > 1e-9 for a, b in zip(dims, want, strict=True)):
        raise OptionError(
            f"{label}: unit {unit!r} does not fit a {kind} {what} "
            f"(expected something like {_unit_hint(kind, what)})"
        )
    return x * factor


# ----------------------------------------------------------------------------
# spec


@dataclass(frozen=True)
class AxisNoise:
    """Noise of one channel, SI units.

    Attributes
    ----------
    Q, N, B, K, R:
        IEEE 952 coefficients (rad, rad/s^0.5, rad/s, rad/s^1.5, rad/s² for a
        gyro; m/s, m/s^1.5, m/s², m/s^2.5, m/s³ for an accelerometer).
    bias:
        Constant bias, signal units.
    bias_sigma:
        Std of a turn-on bias drawn once per run, signal units.
    gauss_markov:
        Extra Gauss–Markov processes (their white parts included).
    ar:
        An AR model; it can only be simulated at its own rate.
    bias_tau_range_s:
        τ range (s) over which B is flicker noise.
    """

    Q: float = 0.0
    N: float = 0.0
    B: float = 0.0
    K: float = 0.0
    R: float = 0.0
    bias: float = 0.0
    bias_sigma: float = 0.0
    gauss_markov: tuple[GaussMarkovModel, ...] = ()
    ar: ArModel | None = None
    bias_tau_range_s: tuple[float, float] = DEFAULT_BIAS_TAU_RANGE

    def __post_init__(self) -> None:
        for t in (*TERMS, "bias_sigma"):
            v = getattr(self, t)
            if not (math.isfinite(v) and v >= 0):
                raise OptionError(f"noise term {t} must be finite and >= 0, got {v}")
        if not math.isfinite(self.bias):
            raise OptionError(f"bias must be finite, got {self.bias}")

    def flicker(self) -> tuple[GaussMarkovModel, ...]:
        return flicker_gm_terms(self.B, self.bias_tau_range_s)

    def avar(self, tau: ArrayLike, rate_hz: float | None = None) -> NDArray[np.float64]:
        """Theoretical Allan variance at τ (s) of what :func:`simulate_axis` generates.

        ``rate_hz=None`` uses the continuous-time forms; with a rate the
        discrete corrections (random walk K²δt²/(6τ), point-sampled GM) are
        included.  B uses the actual flicker approximation, not a flat line.
        """
        t = np.asarray(tau, dtype=np.float64)
        out = 3 * self.Q**2 / t**2 + self.N**2 / t + self.K**2 * t / 3 + self.R**2 * t**2 / 2
        if rate_hz is not None:
            out = out + self.K**2 / rate_hz**2 / (6 * t)
        for gm in (*self.flicker(), *self.gauss_markov):
            out = out + gm.avar(t, rate_hz)
        if self.ar is not None:
            out = out + self.ar.avar(t)
        return np.asarray(out, dtype=np.float64)

    def adev(self, tau: ArrayLike, rate_hz: float | None = None) -> NDArray[np.float64]:
        """Theoretical Allan deviation at τ (s), signal units."""
        return np.sqrt(self.avar(tau, rate_hz))

    def to_dict(self) -> dict[str, Any]:
        d: dict[str, Any] = {t: getattr(self, t) for t in TERMS}
        d.update(
            bias=self.bias, bias_sigma=self.bias_sigma, bias_tau_range_s=list(self.bias_tau_range_s)
        )
        if self.gauss_markov:
            d["gauss_markov"] = [g.to_dict() for g in self.gauss_markov]
        if self.ar is not None:
            d["ar"] = self.ar.to_dict()
        return d


def simulate_axis(
    noise: AxisNoise,
    n: int,
    rate_hz: float,
    seed: int | np.random.SeedSequence | None = None,
) -> NDArray[np.float64]:
    """``n`` noise samples of one channel at ``rate_hz`` (signal units, SI)."""
    if n < 1:
        raise OptionError(f"number of samples must be >= 1, got {n}")
    if not (math.isfinite(rate_hz) and rate_hz > 0):
        raise OptionError(f"rate must be a positive number of Hz, got {rate_hz}")
    ss = seed if isinstance(seed, np.random.SeedSequence) else np.random.SeedSequence(seed)
    streams = dict(zip(_COMPONENTS, ss.spawn(len(_COMPONENTS)), strict=True))
    dt = 1.0 / rate_hz
    y = np.zeros(n)
    if noise.Q > 0:
        g = np.random.default_rng(streams["Q"])
        y += np.diff(g.standard_normal(n + 1)) * (noise.Q / dt)
    if noise.N > 0:
        g = np.random.default_rng(streams["N"])
        y += g.standard_normal(n) * (noise.N / math.sqrt(dt))
    if noise.B > 0:
        subs = streams["B"].spawn(64)
        for gm, s in zip(noise.flicker(), subs, strict=False):
            y += gm.simulate(n, rate_hz, np.random.default_rng(s))
    if noise.K > 0:
        g = np.random.default_rng(streams["K"])
        steps = g.standard_normal(n) * (noise.K * math.sqrt(dt))
        steps[0] = 0.0
        y += np.cumsum(steps)
    if noise.R > 0:
        y += noise.R * dt * np.arange(n)
    if noise.bias or noise.bias_sigma:
        g = np.random.default_rng(streams["bias"])
        y += noise.bias + noise.bias_sigma * g.standard_normal()
    if noise.gauss_markov:
        subs = streams["gm"].spawn(len(noise.gauss_markov))
        for gm, s in zip(noise.gauss_markov, subs, strict=True):
            y += gm.simulate(n, rate_hz, np.random.default_rng(s))
    if noise.ar is not None:
        y += noise.ar.simulate(n, rate_hz, np.random.default_rng(streams["ar"]))
    return y


@dataclass(frozen=True)
class NoiseSpec:
    """Noise of every channel to simulate.

    ``channels`` maps canonical names (``gyro_x`` ...) to :class:`AxisNoise`;
    ``rate_hz`` is a default rate (e.g. from a noise.json); ``name`` says
    where the figures came from; ``notes`` records choices made while building it.
    """

    channels: dict[str, AxisNoise]
    name: str = "custom"
    rate_hz: float | None = None
    notes: tuple[str, ...] = ()

    @classmethod
    def from_datasheet(
        cls,
        gyro: AxisNoise | None = None,
        accel: AxisNoise | None = None,
        name: str = "datasheet",
    ) -> NoiseSpec:
        """The same noise on the three axes of each sensor."""
        ch: dict[str, AxisNoise] = {}
        for kind, ax in (("gyro", gyro), ("accel", accel)):
            if ax is not None:
                for c in ("x", "y", "z"):
                    ch[f"{kind}_{c}"] = ax
        if not ch:
            raise OptionError("a datasheet spec needs gyro and/or accelerometer figures")
        return cls(channels=ch, name=name)

    def with_overrides(
        self, kind: str, values: Mapping[str, Any], *, add_missing: bool = True
    ) -> NoiseSpec:
        """Replace fields (SI) on every axis of ``kind`` (added if missing, unless
        ``add_missing`` is false: then only the axes the spec has)."""
        ch = dict(self.channels)
        for c in ("x", "y", "z"):
            key = f"{kind}_{c}"
            if key not in ch and not add_missing:
                continue
            ch[key] = replace(ch.get(key, AxisNoise()), **values)
        return replace(self, channels=ch)

    def adev(self, tau: ArrayLike, rate_hz: float | None = None) -> dict[str, NDArray[np.float64]]:
        """Theoretical Allan deviation of each channel at τ (s)."""
        return {k: v.adev(tau, rate_hz) for k, v in self.channels.items()}

    def to_dict(self) -> dict[str, Any]:
        return {
            "format": "imubounds.noisespec/1",
            "name": self.name,
            "rate_hz": self.rate_hz,
            "units": "SI",
            "channels": {k: v.to_dict() for k, v in self.channels.items()},
            "notes": list(self.notes),
        }

    @classmethod
    def from_mapping(cls, data: Mapping[str, Any], source: str = "spec") -> NoiseSpec:
        """Build from a spec mapping (YAML/JSON), figures with units allowed.

        Keys: ``gyro``/``accel`` (applied to the three axes), then per-axis
        ``gyro_x`` ... (merged over the sensor's); each holds Q, N, B, K, R,
        bias, bias_sigma (values: SI numbers, ``"0.05 deg/s/sqrt(Hz)"`` strings
        or ``{value, unit}``), ``bias_tau_range_s: [lo, hi]``,
        ``gauss_markov: [{sigma, correlation_time_s | beta}]``.  Optional
        ``name`` and ``rate_hz``.  :meth:`to_dict` output is accepted too.
        """
        if not isinstance(data, Mapping):
            raise InputError(f"{source}: a noise spec must be a mapping")
        if data.get("format") == "imubounds.stationary.terms/1":
            return cls.from_noise_json(data, source=source)
        body: Mapping[str, Any] = data.get("channels", data)  # to_dict output nests
        known = {"gyro", "accel", *IMU_CHANNELS}
        unknown = [
            k
            for k in body
            if k not in known and k not in ("name", "rate_hz", "format", "units", "notes")
        ]
        if unknown:
            raise InputError(
                f"{source}: unknown key(s) {', '.join(map(str, unknown))}; "
                "use gyro, accel or gyro_x..accel_z"
            )
        chans: dict[str, AxisNoise] = {}
        for kind in ("gyro", "accel"):
            base = body.get(kind)
            for c in ("x", "y", "z"):
                key = f"{kind}_{c}"
                merged: dict[str, Any] = {}
                if isinstance(base, Mapping):
                    merged.update(base)
                if isinstance(body.get(key), Mapping):
                    merged.update(body[key])
                if base is None and key not in body:
                    continue
                chans[key] = _axis_from_mapping(merged, kind, f"{source}: {key}.")
        if not chans:
            raise InputError(f"{source}: no gyro or accel noise given")
        rate = data.get("rate_hz")
        return cls(
            channels=chans,
            name=str(data.get("name", source)),
            rate_hz=float(rate) if rate else None,
        )

    @classmethod
    def from_noise_json(
        cls,
        data: Mapping[str, Any] | str | Path,
        *,
        terms: str = "fit",
        models: Sequence[str] = (),
        bias_tau_range_s: tuple[float, float] = DEFAULT_BIAS_TAU_RANGE,
        source: str | None = None,
    ) -> NoiseSpec:
        """Build from a ``noise.json`` written by ``imubounds static``.

        ``terms``: ``"fit"`` (default), ``"slope"``, ``"selected"`` (the terms
        used for bounds: upper bounds where the log did not resolve a term) or
        ``"none"``: which estimate of Q, N, B, K, R to use (a missing, null,
        NaN or zero term is omitted).  ``models``: any of ``"gm"``, ``"ar"``: also add the fitted
        Gauss–Markov / AR models (they overlap with the terms: usually use
        ``terms="none"`` with models).
        """
        if isinstance(data, str | Path):
            path = Path(data)
            source = source or str(path)
            try:
                data = json.loads(path.read_text())
            except OSError as err:
                raise InputError(f"{path}: cannot read ({err.strerror})") from err
            except json.JSONDecodeError as err:
                raise InputError(f"{path}: not valid JSON ({err.msg}, line {err.lineno})") from err
        source = source or "noise.json"
        if not isinstance(data, Mapping) or data.get("format") != "imubounds.stationary.terms/1":
            raise InputError(
                f"{source}: not a noise.json from 'imubounds static' "
                "(format imubounds.stationary.terms/1 missing)"
            )
        if terms not in ("fit", "slope", "selected", "none"):
            raise OptionError(f"terms must be fit, slope, selected or none, got {terms!r}")
        models = tuple(models)
        for m in models:
            if m not in ("gm", "ar"):
                raise OptionError(f"unknown model {m!r}; choose from gm, ar")
        chans: dict[str, AxisNoise] = {}
        notes: list[str] = []
        for name, entry in (data.get("channels") or {}).items():
            if name not in IMU_CHANNELS:
                continue
            values: dict[str, float] = {}
            if terms != "none":
                block = ((entry.get("noise") or {}).get(terms)) or {}
                for t in TERMS:
                    v = (block.get(t) or {}).get("value")
                    if v is not None and math.isfinite(float(v)) and float(v) > 0:
                        values[t] = float(v)
            gms: tuple[GaussMarkovModel, ...] = ()
            ar: ArModel | None = None
            mblock = entry.get("models") or {}
            if "gm" in models:
                if mblock.get("gauss_markov"):
                    gms = (GaussMarkovModel.from_dict(mblock["gauss_markov"]),)
                else:
                    notes.append(f"{name}: no Gauss-Markov model in {source}")
            if "ar" in models:
                if mblock.get("ar"):
                    ar = ArModel.from_dict(mblock["ar"])
                else:
                    notes.append(f"{name}: no AR model in {source}")
            chans[name] = AxisNoise(
                **values, gauss_markov=gms, ar=ar, bias_tau_range_s=bias_tau_range_s
            )
        if not chans:
            raise InputError(f"{source}: no gyro/accel channel in 'channels'")
        rate = (data.get("input") or {}).get("sample_rate_hz")
        return cls(
            channels=chans,
            name=f"{source} ({terms} terms" + (f", models {','.join(models)})" if models else ")"),
            rate_hz=float(rate) if rate else None,
            notes=tuple(notes),
        )


def _axis_from_mapping(m: Mapping[str, Any], kind: str, where: str) -> AxisNoise:
    kw: dict[str, Any] = {}
    for key, val in m.items():
        if key in TERMS:
            kw[key] = parse_quantity(val, kind, key, where)
        elif key in ("bias", "bias_sigma"):
            kw[key] = parse_quantity(val, kind, "signal", where + key + ":")
        elif key == "bias_tau_range_s":
            try:
                lo, hi = (float(v) for v in val)
            except (TypeError, ValueError) as err:
                raise InputError(f"{where}bias_tau_range_s must be [lo, hi] in s") from err
            kw[key] = (lo, hi)
        elif key == "gauss_markov":
            items = val if isinstance(val, list) else [val]
            gms = []
            for g in items:
                if not isinstance(g, Mapping):
                    raise InputError(f"{where}gauss_markov entries must be mappings")
                if "correlation_time_s" in g:
                    tc = parse_quantity(g["correlation_time_s"], kind, "time", where)
                elif "beta" in g:
                    tc = 1.0 / float(g["beta"])
                else:
                    raise InputError(f"{where}gauss_markov needs correlation_time_s or beta")
                sigma = parse_quantity(g.get("sigma", 0.0), kind, "signal", where + "sigma:")
                wd = parse_quantity(g.get("white_density", 0.0), kind, "N", where)
                if not (tc > 0 and sigma >= 0):
                    raise InputError(f"{where}gauss_markov needs correlation time > 0, sigma >= 0")
                gms.append(GaussMarkovModel(beta=1.0 / tc, sigma=sigma, white_density=wd))
            kw[key] = tuple(gms)
        elif key == "ar":
            kw[key] = ArModel.from_dict(val)
        elif key in ("model", "unit", "notes"):
            continue
        else:
            raise InputError(
                f"{where}{key}: unknown field; use Q, N, B, K, R, bias, bias_sigma, "
                "bias_tau_range_s, gauss_markov, ar"
            )
    return AxisNoise(**kw)


#: Datasheet presets by name, as noise-simulator mappings (from :mod:`imubounds.presets`).
PRESETS: dict[str, dict[str, Any]] = {k: p.noise_mapping() for k, p in _presets.PRESETS.items()}


def preset(name: str, bias_tau_range_s: tuple[float, float] | None = None) -> NoiseSpec:
    """A datasheet preset by name (see :data:`PRESETS`)."""
    p = _presets.get_preset(name)
    key = p.key
    data: dict[str, Any] = p.noise_mapping()
    if bias_tau_range_s is not None:
        for kind in ("gyro", "accel"):
            data[kind]["bias_tau_range_s"] = list(bias_tau_range_s)
    return NoiseSpec.from_mapping(data, source=key)


def load_spec(path: str | Path) -> NoiseSpec:
    """Read a spec from YAML or JSON (a ``noise.json`` from ``imubounds static`` too)."""
    p = Path(path)
    try:
        text = p.read_text()
    except OSError as err:
        raise InputError(f"{p}: cannot read ({err.strerror})") from err
    if p.suffix.lower() == ".json":
        try:
            data = json.loads(text)
        except json.JSONDecodeError as err:
            raise InputError(f"{p}: not valid JSON ({err.msg}, line {err.lineno})") from err
    else:
        import yaml

        try:
            data = yaml.safe_load(text)
        except yaml.YAMLError as err:
            raise InputError(f"{p}: not valid YAML ({str(err).splitlines()[0]})") from err
    return NoiseSpec.from_mapping(data, source=str(p))


def parse_term_list(text: str, kind: str) -> dict[str, Any]:
    """``"N=0.05 deg/s/sqrt(Hz), B=1 deg/s"`` → {field: SI value}.

    The result feeds :meth:`NoiseSpec.with_overrides`.
    """
    out: dict[str, Any] = {}
    for item in (s for s in text.split(",") if s.strip()):
        if "=" not in item:
            raise OptionError(f"--{kind} {text!r}: write TERM=VALUE[ UNIT], e.g. N=0.05deg/s/rtHz")
        key, val = (s.strip() for s in item.split("=", 1))
        if key in TERMS:
            out[key] = parse_quantity(val, kind, key, f"--{kind} ")
        elif key in ("bias", "bias_sigma"):
            out[key] = parse_quantity(val, kind, "signal", f"--{kind} {key}:")
        else:
            raise OptionError(
                f"--{kind}: unknown term {key!r}; use Q, N, B, K, R, bias, bias_sigma"
            )
    return out


# ----------------------------------------------------------------------------
# simulate & write


def simulate(
    spec: NoiseSpec,
    rate_hz: float | None = None,
    duration_s: float | None = None,
    *,
    n_samples: int | None = None,
    seed: int | None = 0,
    channels: Sequence[str] | None = None,
    t0: float = 0.0,
) -> ImuLog:
    """Simulate every channel of ``spec``.

    Parameters
    ----------
    spec:
        The noise of each channel.
    rate_hz:
        Sample rate, Hz (default: ``spec.rate_hz``).
    duration_s, n_samples:
        Length: ``n = round(duration_s·rate_hz)`` or ``n_samples``.
    seed:
        Seed; the same seed gives the same output.  Channel ``c`` uses the
        stream spawned at its index in :data:`~imubounds.io.log.IMU_CHANNELS`.
    channels:
        Only these channels (default: all in the spec).
    t0:
        First time stamp, s.

    Returns
    -------
    ImuLog in SI units.
    """
    rate = rate_hz if rate_hz is not None else spec.rate_hz
    if rate is None or not (math.isfinite(rate) and rate > 0):
        raise OptionError("give a positive sample rate (rate_hz / --rate)")
    if n_samples is None:
        if duration_s is None or not (math.isfinite(duration_s) and duration_s > 0):
            raise OptionError("give a positive duration (duration_s / --duration) or n_samples")
        n = int(round(duration_s * rate))
    else:
        n = int(n_samples)
    if n < 2:
        raise OptionError(f"the run would have {n} samples; give a longer duration")
    names = list(channels) if channels else [c for c in IMU_CHANNELS if c in spec.channels]
    missing = [c for c in names if c not in spec.channels]
    if missing:
        raise OptionError(
            f"channel(s) {', '.join(missing)} not in the noise spec; "
            f"available: {', '.join(spec.channels)}"
        )
    root = np.random.SeedSequence(seed)
    streams = root.spawn(len(IMU_CHANNELS))
    out: dict[str, np.ndarray] = {}
    for name in names:
        idx = IMU_CHANNELS.index(name)
        out[name] = simulate_axis(spec.channels[name], n, rate, streams[idx])
    t = t0 + np.arange(n) / rate
    return ImuLog(
        channels=out,
        rate_hz=float(rate),
        t=t,
        source=f"simulated: {spec.name}, seed {seed}",
        input_units={c: si_unit_of_signal(sensor_kind(c)) for c in out},
        frame="unknown",
        warnings=list(spec.notes),
    )


def write_csv(log: ImuLog, path: str | Path, *, precision: int = 10) -> Path:
    """Write ``time_s, gyro_x_rads, ..., accel_z_mps2`` (the channels present),
    gzip-compressed when the name ends in ``.gz``."""
    import pandas as pd

    p = Path(path)
    cols: dict[str, np.ndarray] = {"time_s": log.t}
    for name in IMU_CHANNELS:
        if name in log.channels:
            cols[CSV_COLUMNS[name]] = log.channels[name]
    from imubounds.io.outputs import atomic_path

    if not p.parent.is_dir():
        raise OptionError(f"cannot write {p}: folder {p.parent} does not exist")
    compression: Literal["gzip"] | None = "gzip" if p.name.lower().endswith(".gz") else None
    try:
        with atomic_path(p) as tmp:
            pd.DataFrame(cols).to_csv(
                tmp, index=False, float_format=f"%.{precision}g", compression=compression
            )
    except OSError as err:
        raise OptionError(f"cannot write {p}: {err.strerror}") from err
    return p


def parse_duration(text: str) -> float:
    """``"7200"``, ``"7200s"``, ``"2h"``, ``"90min"``, ``"1.5 h"`` → seconds."""
    m = re.fullmatch(r"\s*(\d+(?:\.\d*)?|\.\d+)(?:[eE]([-+]?\d+))?\s*([a-z]*)\s*", text.lower())
    if not m:
        raise OptionError(f"--duration {text!r}: write e.g. 7200, 7200s, 90min or 2h")
    x = float(m.group(1)) * (10.0 ** int(m.group(2)) if m.group(2) else 1.0)
    unit = m.group(3) or "s"
    factors = {
        "s": 1.0,
        "sec": 1.0,
        "min": 60.0,
        "m": 60.0,
        "h": 3600.0,
        "hr": 3600.0,
        "d": 86400.0,
    }
    if unit not in factors:
        raise OptionError(f"--duration {text!r}: unit must be s, min, h or d")
    return x * factors[unit]


__all__ = [
    "AxisNoise",
    "NoiseSpec",
    "PRESETS",
    "CSV_COLUMNS",
    "flicker_gm_terms",
    "load_spec",
    "parse_duration",
    "parse_quantity",
    "parse_term_list",
    "parse_unit",
    "preset",
    "simulate",
    "simulate_axis",
    "write_csv",
]
