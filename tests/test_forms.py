"""The registry of bound forms (aided/forms.py, aided/form_tables.py): the probability
accounting of :data:`SHARES` and :func:`allot`, :func:`combine`'s intersection, and the
tables' equation numbers against docs/dynamic-method.md."""

from __future__ import annotations

import re
from itertools import combinations
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from imubounds.dynamic.estimator.aided.form_tables import TABLES
from imubounds.dynamic.estimator.aided.forms import (
    REST,
    SHARES,
    BoundForm,
    FormRecord,
    allot,
    check_shares,
    combine,
    form_probability,
    label_counts,
    share,
    side_labels,
)
from imubounds.interval import IntervalArray as IA

DOC = Path(__file__).resolve().parents[1] / "docs" / "dynamic-method.md"


def test_every_row_of_the_shares_sums_to_at_most_one() -> None:
    check_shares()
    for row in SHARES.values():
        assert sum(v for v in row.values() if not isinstance(v, str)) <= 1.0 + 1e-12


def test_a_row_over_one_is_refused(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setitem(SHARES, "bad", {"a": 0.7, "b": 0.4})
    with pytest.raises(ValueError, match="bad"):
        check_shares()
    with pytest.raises(ValueError, match="allot"):
        share("accel_y.transport", "mean_abs_r")  # the REST part has no number


@pytest.mark.parametrize("event", sorted(SHARES))
def test_allot_spends_at_most_p_and_rest_takes_what_is_left(event: str) -> None:
    """Every subset of a row's parts applying: the parts' probabilities sum to at most p
    (to p where the row has a REST part), parts that do not apply get 0 (Bonferroni over
    the forms: all hold at once with probability >= 1 - p)."""
    row = SHARES[event]
    numbered = [k for k, v in row.items() if not isinstance(v, str)]
    p = 1e-4
    for n in range(len(numbered) + 1):
        for applying in combinations(numbered, n):
            out = allot(p, event, list(applying))
            assert set(out) == set(row)
            assert sum(out.values()) <= p * (1 + 1e-12)
            for k in numbered:
                assert out[k] == (share(event, k) * p if k in applying else 0.0)
            if REST in row.values():
                assert sum(out.values()) == pytest.approx(p, rel=1e-12)


def test_every_share_path_of_the_tables_names_a_share() -> None:
    for (ch, term), table in TABLES.items():
        assert table, (ch, term)
        names = [f.name for f in table]
        assert len(set(names)) == len(names), (ch, term)
        for f in table:
            for ev, part in f.share:
                assert part in SHARES[ev], (ch, term, f.name)
            assert form_probability(f, 1.0) <= 1.0


def test_a_family_splits_its_share_equally() -> None:
    f = BoundForm("x", "3.1", (("mean_abs", "heading_blocks"),), lambda x: True,
                  lambda x, p: p, family="heading_blocks")
    assert form_probability(f, 1.0, 4) == pytest.approx(share("mean_abs", "heading_blocks") / 4)
    g = BoundForm("y", "3.1", (), lambda x: True, lambda x, p: p)
    assert form_probability(g, 1.0) == 0.0  # no event of its own


def _enc(lo: list[float], hi: list[float]) -> object:
    return lambda x, p: IA(np.array(lo), np.array(hi))


def test_combine_intersects_and_records_both_ends() -> None:
    table = (
        BoundForm("a", "3.1", (), lambda x: True, _enc([-1.0, -3.0, 0.0], [2.0, 3.0, 1.0])),
        BoundForm("b", "3.1", (), lambda x: True, _enc([-2.0, -1.0, 2.0], [1.0, 4.0, 3.0])),
        BoundForm("never", "3.1", (), lambda x: False, _enc([9.0] * 3, [9.0] * 3)),
    )
    rec = FormRecord()
    out = combine("t", table, None, 1e-3, rec)
    # window 0: [-1, 1] (lo from a, hi from b); window 1: [-1, 3]; window 2 disjoint:
    # the narrowest (a), whole
    assert out.lo.tolist() == [-1.0, -1.0, 0.0]
    assert out.hi.tolist() == [1.0, 3.0, 1.0]
    lo, hi = rec.sides("t")
    assert lo.tolist() == ["a", "b", "a"] and hi.tolist() == ["b", "a", "a"]
    labels = side_labels(lo, hi)
    assert labels.tolist() == ["a|b", "b|a", "a"]
    assert label_counts(labels) == "a 1, a|b 1, b|a 1"


def test_combine_upper_takes_the_smallest_finite_bound() -> None:
    table = (
        BoundForm("m", "3.7", (), lambda x: True, lambda x, p: np.array([1.0, 5.0, 2.0])),
        BoundForm("c", "3.8", (("mean_abs", "centred_window"),), lambda x: True,
                  lambda x, p: np.array([np.inf, 3.0, np.nan])),
    )
    rec = FormRecord()
    out = combine("u", table, None, 1e-3, rec, kind="upper")
    assert out.tolist() == [1.0, 3.0, 2.0]
    assert rec.sides("u")[0].tolist() == ["m", "c", "m"]


def test_each_form_gets_its_share_of_the_event() -> None:
    seen: dict[str, float] = {}

    def note(name: str) -> object:
        def f(x: object, p: float) -> np.ndarray:
            seen[name] = p
            return np.ones(1)
        return f

    fam = tuple(BoundForm(f"b{k}", "3.9", (("mean_abs", "heading_blocks"),), lambda x: True,
                          note(f"b{k}"), family="heading_blocks") for k in range(5))
    table = (BoundForm("c", "3.8", (("mean_abs", "centred_window"),), lambda x: True,
                       note("c")), *fam)
    combine("v", table, None, 1.0, kind="upper")
    assert seen["c"] == pytest.approx(0.5)
    assert all(seen[f"b{k}"] == pytest.approx(0.1) for k in range(5))
    assert sum(seen.values()) <= 1.0 + 1e-12


@settings(max_examples=60, deadline=None)
@given(st.lists(st.tuples(st.floats(0, 10), st.floats(0, 10)), min_size=1, max_size=6),
       st.floats(-5, 5))
def test_the_intersection_holds_the_truth_each_form_holds(
    radii: list[tuple[float, float]], truth: float
) -> None:
    """Enclosures that all contain the truth: so does their intersection (and it is no
    wider than the narrowest)."""
    table = tuple(
        BoundForm(f"f{i}", "3.1", (), lambda x: True,
                  _enc([truth - a], [truth + b])) for i, (a, b) in enumerate(radii)
    )
    out = combine("h", table, None, 1e-3)
    assert out.lo[0] <= truth <= out.hi[0]
    assert out.hi[0] - out.lo[0] <= min(a + b for a, b in radii) * (1 + 1e-12) + 1e-12


def test_every_eq_of_the_tables_is_a_numbered_equation_of_the_method() -> None:
    """The registry's ``eq`` fields cite equations docs/dynamic-method.md numbers."""
    numbered = set(re.findall(r"\((\d+\.\d+)\)\s*$", DOC.read_text(), flags=re.M))
    for (ch, term), table in TABLES.items():
        for f in table:
            assert f.eq in numbered, f"{ch} {term} {f.name}: eq {f.eq} not in the method"
