"""rac.check.analysis.piecewise: convex functions recovered exactly from a supporting-line oracle,
combined, and the sets where they are positive, against brute force over lines and points."""

from __future__ import annotations

from fractions import Fraction

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from rac.check.analysis.piecewise import Interval, Piecewise, convex, intersect

F = Fraction
lines = st.lists(st.tuples(st.integers(-20, 20), st.integers(-200, 200)), min_size=1, max_size=8)


def oracle_of(found: list[tuple[int, int]]):
    def oracle(p: Fraction) -> tuple[Fraction, Fraction]:
        value, slope = max((s * p + c, s) for s, c in found)
        return F(value), F(slope)
    return oracle


def grid(low: Fraction, high: Fraction, n: int = 40) -> list[Fraction]:
    return [low + (high - low) * F(i, n) for i in range(n + 1)]


@settings(max_examples=200, deadline=None)
@given(lines, st.integers(-30, 0), st.integers(1, 30))
def test_convex_is_the_maximum_of_the_lines(found, low, high):
    calls = []
    oracle = oracle_of(found)

    def counted(p):
        calls.append(p)
        return oracle(p)

    f = convex(counted, F(low), F(high))
    for p in grid(F(low), F(high)) + list(f.points):
        assert f(p) == oracle(p)[0]
    assert len(f.slopes) <= len(found)
    assert len(calls) <= 2 * len(found) + 1
    assert list(f.slopes) == sorted(f.slopes)  # convex


@settings(max_examples=200, deadline=None)
@given(lines, lines, st.integers(-3, 3), st.integers(-3, 3))
def test_where_matches_the_sign_at_every_point(first, second, a, b):
    low, high = F(-10), F(10)
    f = convex(oracle_of(first), low, high).combine(convex(oracle_of(second), low, high), F(a), F(b))
    positive, nonpositive = f.where(True), f.where(False)
    points = grid(low, high, 80) + list(f.points)
    for interval in positive + nonpositive:
        points += [interval.low, interval.high]
    for p in points:
        value = a * oracle_of(first)(p)[0] + b * oracle_of(second)(p)[0]
        assert f(p) == value
        assert any(p in i for i in positive) == (value > 0)
        assert any(p in i for i in nonpositive) == (value <= 0)


@settings(max_examples=100, deadline=None)
@given(lines, lines, st.integers(-3, 3), st.integers(-3, 3), st.integers(-10, 10))
def test_a_domain_of_one_value_keeps_its_sign(first, second, a, b, at):
    """`param P in [5, 5]`: the two functions on the one value combined had no piece, so the sum was
    positive nowhere and at most 0 nowhere (`require risk` refused where it holds)."""
    p = F(at)
    f = convex(oracle_of(first), p, p).combine(convex(oracle_of(second), p, p), F(a), F(b))
    value = a * oracle_of(first)(p)[0] + b * oracle_of(second)(p)[0]
    assert f(p) == value
    assert f.where(value > 0) == [Interval(p, p)]
    assert f.where(value <= 0) == []


def test_a_crossing_is_an_open_end_of_the_positive_set():
    f = Piecewise.affine(F(0), F(10), F(1), F(-4))  # p - 4
    assert f.where(True) == [Interval(F(4), F(10), low_open=True)]
    assert f.where(False) == [Interval(F(0), F(4))]


def test_lines_that_are_not_supporting_are_refused():
    with pytest.raises(ValueError):
        convex(lambda p: (F(0), F(1) if p < 5 else F(1)), F(0), F(10))


@settings(max_examples=200, deadline=None)
@given(st.lists(st.tuples(st.integers(-10, 10), st.integers(0, 6), st.booleans(), st.booleans()), max_size=3),
       st.lists(st.tuples(st.integers(-10, 10), st.integers(0, 6), st.booleans(), st.booleans()), max_size=3))
def test_intersect_is_membership_in_both(raw_a, raw_b):
    def disjoint(raw):
        found, start = [], F(-30)
        for gap, width, lo, hi in raw:
            low = start + abs(gap) + 1
            found.append(Interval(low, low + width, lo and width > 0, hi and width > 0))
            start = low + width + 1
        return found

    a, b = disjoint(raw_a), disjoint(raw_b)
    both = intersect(a, b)
    for k in range(-60 * 4, 60 * 4):
        p = F(k, 4)
        assert any(p in i for i in both) == (any(p in i for i in a) and any(p in i for i in b))
