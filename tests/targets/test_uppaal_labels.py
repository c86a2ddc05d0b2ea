"""rac.targets.uppaal.labels: the reward automaton's labels as UPPAAL text."""

from __future__ import annotations

from fractions import Fraction

from test_uppaal_significands import generator

from rac import ir
from rac.targets.uppaal.labels import Labels


def test_rates_become_the_odes_of_the_hybrid_clocks() -> None:
    g = generator()
    labels: Labels = g.labels
    go, slow = g.a.locations
    assert labels.ode(go, Fraction(1)) == "sa' == 1 && pr' == 2"
    assert labels.ode(slow, Fraction(1)) == "sa' == -1 && pr' == 0"
    # per time unit: with a unit of 0.5 s a rate of 2 per second is 1 per unit
    assert labels.ode(go, Fraction(1, 2)) == "sa' == 0.5 && pr' == 1"


def test_accrual_adds_to_the_mirrors() -> None:
    g = generator()
    inputs = g.numbers.inputs(g.n, g.array, g.select)
    go_row, slow_row = g.numbers.accruals(inputs, g.n)
    assert g.labels.accrual(go_row) == ["iSa = iSa + 5000", "iPr = iPr + 10000"]
    assert g.labels.accrual(slow_row) == ["iSa = iSa - 5000"]  # pr gains nothing: no assignment


def test_guards_compare_significands() -> None:
    g = generator()
    guards = [g.labels.guard(edge.guard) for edges in g.a.edges for edge in edges]
    assert "near || d < 25000" in guards
    assert "!near && d >= 25000" in guards


def test_an_update_changes_the_clock_and_its_mirror() -> None:
    g = generator()
    update = next(edge for edges in g.a.edges for edge in edges if edge.updates)
    assert g.labels.updates(update.updates, None) == "sa = sa - 3, iSa = iSa - 30000"
    assert g.labels.end_updates() == ("", "")  # no `at end` clause
    assert isinstance(update.updates[0], ir.Assignment)
