"""Where each bound form of the registry wins, and by how much (run by hand): the data
behind retiring forms (docs/dynamic-method.md, section 3, "Bound forms and their shares").

Installs :data:`imubounds.dynamic.estimator.aided.forms.OBSERVER` and runs one of the
workloads below; per term and form it counts the windows where the form narrows its
term and the largest gain: for an intersected term (accel_y's transport), the width of
the intersection of the OTHER forms over the width of all (``(w_without - w) /
w_without``); for an upper bound (mean |r|, mean |q|), ``(min of the others - min) /
min of the others``. A form never ahead by more than 3 % anywhere can be removed and
widen its term by at most 3 % (its margin less).

Usage::

    python benchmarks/form_wins.py OUT.json sweep [CASES] [SEEDS]   # benchmarks/sweep_faults.py
    python benchmarks/form_wins.py OUT.json clean-sweep N
    python benchmarks/form_wins.py OUT.json drive PATH [OPTIONS_JSON]
    python benchmarks/form_wins.py OUT.json sim VARIANT SEED AIDING [KEY=VALUE ...]
    python benchmarks/form_wins.py OUT.json cli dynamic PATH [CLI OPTIONS ...]   # the CLI
    python benchmarks/form_wins.py --merge OUT.json IN.json ...     # add up runs

AIDING like ``gnss+compass``. The JSON holds, per ``term/form``: ``windows`` (seen),
``ahead`` (windows where it narrows the term), ``ahead_3pct``, ``max_gain`` and
``where`` (the run and window count of the largest). With ``FORM_WINS_RETIRE=a,b,..``
(form names) also, per term, ``term/retired``: the same gains for removing all the named
forms of the term at once (what retiring them together costs; their shares going to
the forms left only narrows those further).
"""

from __future__ import annotations

import json
import os
import sys
from pathlib import Path
from typing import Any

import numpy as np

REPO = Path(__file__).resolve().parents[1]
STATS: dict[str, dict[str, Any]] = {}
RUN = {"name": ""}


def _gains(names: tuple[str, ...], cands: list[Any], kind: str) -> np.ndarray:
    """Per form (rows) and window (columns): how much the term narrows with the form."""
    if kind == "upper":
        v = np.stack([np.where(np.isfinite(c), c, np.inf) for c in cands])
        best = np.min(v, axis=0)
        out = np.zeros(v.shape)
        for i in range(len(names)):
            others = np.min(np.delete(v, i, axis=0), axis=0) if len(names) > 1 else np.inf
            with np.errstate(invalid="ignore", divide="ignore"):
                g = (others - best) / others
            out[i] = np.where(np.isfinite(others) & (others > 0), g, np.where(
                np.isfinite(best) & ~np.isfinite(others), 1.0, 0.0))
        return out
    lo = np.stack([c.lo for c in cands])
    hi = np.stack([c.hi for c in cands])
    width = np.min(hi, axis=0) - np.max(lo, axis=0)
    out = np.zeros(lo.shape)
    for i in range(len(names)):
        if len(names) == 1:
            out[i] = np.where(np.isfinite(width), 1.0, 0.0)
            continue
        w_wo = np.min(np.delete(hi, i, axis=0), axis=0) - np.max(np.delete(lo, i, axis=0), axis=0)
        with np.errstate(invalid="ignore", divide="ignore"):
            g = (w_wo - width) / w_wo
        out[i] = np.where(np.isfinite(w_wo) & (w_wo > 0) & (width >= 0), g,
                          np.where(np.isfinite(width) & ~np.isfinite(w_wo), 1.0, 0.0))
    return out


RETIRE = {x for x in os.environ.get("FORM_WINS_RETIRE", "").split(",") if x}


def _joint_gain(names: tuple[str, ...], cands: list[Any], kind: str) -> np.ndarray | None:
    """Per window, how much wider the term is without all the forms named in RETIRE."""
    gone = [i for i, nm in enumerate(names) if nm in RETIRE]
    if not gone:
        return None
    keep = [i for i in range(len(names)) if i not in gone]
    merged = ("retired",) + tuple(names[i] for i in keep)
    if kind == "upper":
        v = np.stack([np.where(np.isfinite(cands[i]), cands[i], np.inf) for i in gone])
        cands2 = [np.min(v, axis=0), *(cands[i] for i in keep)]
    else:
        lo = np.max(np.stack([cands[i].lo for i in gone]), axis=0)
        hi = np.min(np.stack([cands[i].hi for i in gone]), axis=0)
        cands2 = [_Pair(lo, hi), *(cands[i] for i in keep)]
    return _gains(merged, cands2, kind)[0]


class _Pair:
    def __init__(self, lo: np.ndarray, hi: np.ndarray) -> None:
        self.lo, self.hi = lo, hi


def _add(key: str, gi: np.ndarray) -> None:
    st = STATS.setdefault(key, {"windows": 0, "ahead": 0, "ahead_3pct": 0,
                                "max_gain": 0.0, "where": ""})
    gi = np.nan_to_num(gi, nan=0.0)
    st["windows"] += int(gi.size)
    st["ahead"] += int(np.sum(gi > 0))
    st["ahead_3pct"] += int(np.sum(gi > 0.03))
    m = float(np.max(gi)) if gi.size else 0.0
    if m > st["max_gain"]:
        st["max_gain"] = m
        st["where"] = f"{RUN['name']} ({int(np.sum(gi > 0.03))} windows > 3 % here)"


def observe(term: str, names: tuple[str, ...], cands: list[Any], kind: str) -> None:
    if not cands or np.size(cands[0] if kind == "upper" else cands[0].lo) == 0:
        return
    g = _gains(names, cands, kind)
    joint = _joint_gain(names, cands, kind) if RETIRE else None
    if joint is not None:
        _add(f"{term}/retired", joint)
    for i, nm in enumerate(names):
        _add(f"{term}/{nm}", g[i])


def _sim(variant: str, seed: int, aiding: str, rest: list[str]) -> Any:
    from imubounds.dynamic.scenario import make_trip

    kw: dict[str, Any] = {}
    for kv in rest:
        k, v = kv.split("=", 1)
        kw[k] = float(v)
    return make_trip(variant, seed=seed, aiding=tuple(aiding.split("+")), **kw).drive


def main() -> None:
    if sys.argv[1] == "--merge":
        tot: dict[str, dict[str, Any]] = {}
        for p in sys.argv[3:]:
            for k, st in json.loads(Path(p).read_text()).items():
                t = tot.setdefault(k, {"windows": 0, "ahead": 0, "ahead_3pct": 0,
                                       "max_gain": 0.0, "where": ""})
                for f in ("windows", "ahead", "ahead_3pct"):
                    t[f] += st[f]
                if st["max_gain"] > t["max_gain"]:
                    t["max_gain"], t["where"] = st["max_gain"], st["where"]
        Path(sys.argv[2]).write_text(json.dumps(tot, indent=1, sort_keys=True))
        return
    import imubounds.dynamic.estimator.aided.forms as F
    from imubounds.dynamic.estimator import dynamic_margins

    F.OBSERVER = observe
    out, what, args = sys.argv[1], sys.argv[2], sys.argv[3:]
    RUN["name"] = " ".join([what, *args])
    if what in ("sweep", "clean-sweep"):
        sys.path.insert(0, str(REPO / "benchmarks"))
        import sweep_faults

        sys.argv = ["sweep_faults.py", *( ["clean-sweep"] if what == "clean-sweep" else []),
                    *args]
        sweep_faults.main()
    elif what == "drive":
        from imubounds.io import read_drive

        drive = read_drive([args[0]])
        drive.check()
        opts = json.loads(args[1]) if len(args) > 1 else {}
        dynamic_margins(drive, **opts)
    elif what == "sim":
        dynamic_margins(_sim(args[0], int(args[1]), args[2], args[3:]))
    elif what == "cli":
        from imubounds.cli import main as cli_main

        cli_main(args)
    else:
        raise SystemExit(f"unknown workload {what!r}")
    Path(out).write_text(json.dumps(STATS, indent=1, sort_keys=True))


if __name__ == "__main__":
    main()
