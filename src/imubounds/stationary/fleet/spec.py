"""Datasheet limits for a fleet and the pass/fail table against them.

Spec format (YAML)::

    name: ADIS16405 datasheet          # optional
    criterion: value                   # or ci_upper (compare the CI's upper end)
    gyro:                              # per sensor kind: gyro and/or accel
      N: 2.0 deg/sqrt(h)               # max angle random walk
      B: 25 deg/h                      # max bias instability
      K: 10 deg/h/sqrt(h)              # max rate random walk (optional)
    accel:
      N: 0.2 m/s/sqrt(h)
      B: 0.5 mg
      K: 0.05 m/s/h/sqrt(h)

Quantities are parsed with :func:`imubounds.stationary.noise_sim.parse_quantity` (a bare
number is SI). Margin = ``1 - value/limit`` (fraction of the limit unused;
negative when failing).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from imubounds.errors import OptionError
from imubounds.stationary.fleet.settings import TERMS

__all__ = ["FleetSpec", "check_spec", "load_spec", "parse_spec"]


@dataclass(frozen=True)
class FleetSpec:
    """Datasheet limits: ``limits[kind][term]`` in SI; ``criterion`` value|ci_upper."""

    limits: dict[str, dict[str, float]]
    criterion: str = "value"
    name: str = "spec"


def parse_spec(data: Mapping[str, Any], where: str = "spec") -> FleetSpec:
    """A :class:`FleetSpec` from the YAML mapping (see the module docstring)."""
    from imubounds.stationary.noise_sim import parse_quantity

    if not isinstance(data, Mapping):
        raise OptionError(f"{where}: expected a mapping with 'gyro' and/or 'accel' limits")
    unknown = [k for k in data if k not in ("name", "criterion", "gyro", "accel")]
    if unknown:
        raise OptionError(
            f"{where}: unknown key(s) {', '.join(map(repr, unknown))}; use name, criterion, "
            "gyro, accel"
        )
    criterion = str(data.get("criterion", "value"))
    if criterion not in ("value", "ci_upper"):
        raise OptionError(f"{where}: criterion must be 'value' or 'ci_upper', got {criterion!r}")
    limits: dict[str, dict[str, float]] = {}
    for kind in ("gyro", "accel"):
        block = data.get(kind)
        if block is None:
            continue
        if not isinstance(block, Mapping):
            raise OptionError(f"{where}: {kind} must map terms (N, B, K, ...) to limits")
        limits[kind] = {}
        for term, value in block.items():
            if term not in TERMS:
                raise OptionError(
                    f"{where}: {kind}.{term} is not a noise term; use {', '.join(TERMS)}"
                )
            lim = parse_quantity(value, kind, term, where=f"{where}: {kind}.")
            if not lim > 0:
                raise OptionError(f"{where}: {kind}.{term} must be > 0, got {value!r}")
            limits[kind][term] = lim
    if not limits:
        raise OptionError(f"{where}: no limits; give a 'gyro' and/or 'accel' block")
    return FleetSpec(limits, criterion, str(data.get("name", Path(where).stem)))


def load_spec(path: str | Path) -> FleetSpec:
    """Read a datasheet spec YAML file."""
    import yaml

    p = Path(path)
    try:
        data = yaml.safe_load(p.read_text(encoding="utf-8"))
    except OSError as err:
        raise OptionError(f"cannot read spec {p}: {err.strerror}") from err
    except yaml.YAMLError as err:
        raise OptionError(f"{p}: not valid YAML ({str(err).splitlines()[0]})") from err
    return parse_spec(data, where=str(p))


def check_spec(df: Any, spec: FleetSpec) -> Any:
    """Pass/fail table: one row per (unit, channel, term) with a limit.

    A resolved term is compared by its value (criterion ``value``) or the upper
    end of its confidence interval (``ci_upper``): ``pass`` or ``fail``. A term
    the log did not resolve has no value, only an upper bound (``{term}_ub``, the
    curve's bound from its 99 % intervals as ``imubounds static`` uses it): it
    passes when that bound is within the limit, else it is ``undetermined``
    (never ``pass`` on a fit's 0, never ``fail`` on a bound).

    Columns: unit, channel, kind, term, value (the quantity compared, SI), basis
    (``value``, ``ci_upper`` or ``upper_bound``), term_status, limit (SI),
    margin (``1 - value/limit``), value_ieee, limit_ieee, unit_ieee, status
    (``pass``/``fail``/``undetermined``).
    """
    import pandas as pd

    from imubounds.units import to_ieee

    def num(x: Any) -> float:
        try:
            return float(x)
        except (TypeError, ValueError):
            return math.nan

    rows = []
    ok = df[df["status"] == "ok"]
    for rec in ok.to_dict("records"):
        kind = rec["kind"]
        for term, lim in spec.limits.get(kind, {}).items():
            # tables without per-term status (older runs): a positive value counts
            tstat = str(rec.get(f"{term}_status") or
                        ("resolved" if num(rec[term]) > 0 else "upper_bound"))  # fmt: skip
            hi = num(rec.get(f"{term}_hi"))
            if tstat == "resolved":
                basis = "ci_upper" if spec.criterion == "ci_upper" else "value"
                v = hi if basis == "ci_upper" else num(rec[term])
                ok_v = math.isfinite(v)
                status = ("pass" if v <= lim else "fail") if ok_v else "undetermined"
            else:  # the selection's bound: the curve's 99 % one (older tables: the CI's end)
                ub = num(rec.get(f"{term}_ub"))
                basis, v = "upper_bound", ub if math.isfinite(ub) else hi
                status = "pass" if math.isfinite(v) and v <= lim else "undetermined"
            margin = 1.0 - v / lim if math.isfinite(v) else math.nan
            iv, iu = to_ieee(kind, term, v)  # type: ignore[arg-type]
            rows.append({
                "unit": rec["unit"], "channel": rec["channel"], "kind": kind, "term": term,
                "value": v, "basis": basis, "term_status": tstat, "limit": lim,
                "margin": margin, "value_ieee": iv,
                "limit_ieee": to_ieee(kind, term, lim)[0], "unit_ieee": iu,  # type: ignore[arg-type]
                "status": status,
            })  # fmt: skip
    cols = ["unit", "channel", "kind", "term", "value", "basis", "term_status", "limit",
            "margin", "value_ieee", "limit_ieee", "unit_ieee", "status"]  # fmt: skip
    return pd.DataFrame(rows, columns=cols)
