"""Continuous piecewise-affine functions of one parameter, exact (issue 25: synthesis under `require`).

A best return ``R(p) = max over runs r of J_r(p)`` is convex and piecewise affine in a parameter ``p``
whenever the runs do not depend on ``p`` and each ``J_r`` is affine in it (the conditions
:func:`rac.check.analysis.synthesis.unsupported` checks). :func:`convex` recovers such a function
exactly from an oracle that gives, at a point, the value and the slope of a run attaining it (a
supporting line): the two lines at the ends of an interval meet at one point; if the function's value
there is on them, the function is their maximum on the interval; otherwise the new line splits it.
Each split finds a line not seen before, so the search ends after at most twice as many oracle calls
as the function has pieces. Differences of such functions (the requirement ``p* <= b`` compares
three of them) are piecewise affine too; :meth:`Piecewise.where` gives the exact set where one is
``<= 0`` or ``> 0``, as a list of :class:`Interval`.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from fractions import Fraction

#: ``oracle(p) = (value, slope)``: the function's value at ``p`` and the slope of a line through that
#: point that lies below the function everywhere (the line of a run attaining the maximum).
Oracle = Callable[[Fraction], tuple[Fraction, Fraction]]


@dataclass(frozen=True)
class Interval:
    """A set of parameter values ``low .. high``, each end included unless ``*_open``."""

    low: Fraction
    high: Fraction
    low_open: bool = False
    high_open: bool = False

    def __contains__(self, value: Fraction) -> bool:
        above = value > self.low if self.low_open else value >= self.low
        below = value < self.high if self.high_open else value <= self.high
        return above and below

    @property
    def empty(self) -> bool:
        return self.low > self.high or (self.low == self.high and (self.low_open or self.high_open))


@dataclass(frozen=True)
class Piecewise:
    """A continuous function on ``[points[0], points[-1]]``, affine between consecutive ``points``:
    ``slopes[i] * p + intercepts[i]`` on ``[points[i], points[i + 1]]``."""

    points: tuple[Fraction, ...]
    slopes: tuple[Fraction, ...]
    intercepts: tuple[Fraction, ...]

    @staticmethod
    def affine(low: Fraction, high: Fraction, slope: Fraction, intercept: Fraction) -> Piecewise:
        return Piecewise((low, high), (slope,), (intercept,))

    def __call__(self, p: Fraction) -> Fraction:
        if not self.points[0] <= p <= self.points[-1]:
            raise ValueError(f"{p} is outside [{self.points[0]}, {self.points[-1]}]")
        for i in range(len(self.slopes)):
            if p <= self.points[i + 1]:
                return self.slopes[i] * p + self.intercepts[i]
        raise AssertionError("unreachable: p is within the last piece")

    def combine(self, other: Piecewise, a: Fraction, b: Fraction) -> Piecewise:
        """``a * self + b * other`` on the common domain (the two must share their ends)."""
        if (self.points[0], self.points[-1]) != (other.points[0], other.points[-1]):
            raise ValueError("piecewise functions over different intervals")
        points = sorted(set(self.points) | set(other.points))
        if len(points) == 1:
            # a domain of one value (`param P in [5, 5]`) is one piece there: without it the sum had no
            # piece, held nowhere, and `require risk` was refused at a value where it holds
            points = [points[0], points[0]]
        slopes, intercepts = [], []
        for left, right in zip(points, points[1:]):
            middle = (left + right) / 2
            s1, c1 = self.piece_at(middle)
            s2, c2 = other.piece_at(middle)
            slopes.append(a * s1 + b * s2)
            intercepts.append(a * c1 + b * c2)
        return Piecewise(tuple(points), tuple(slopes), tuple(intercepts)).simplified()

    def piece_at(self, p: Fraction) -> tuple[Fraction, Fraction]:
        """(slope, intercept) of the piece holding ``p`` (the left one at a breakpoint)."""
        for i in range(len(self.slopes)):
            if p <= self.points[i + 1]:
                return self.slopes[i], self.intercepts[i]
        return self.slopes[-1], self.intercepts[-1]

    def simplified(self) -> Piecewise:
        """The same function with neighbouring pieces on one line merged."""
        points = [self.points[0]]
        slopes: list[Fraction] = []
        intercepts: list[Fraction] = []
        for i, (s, c) in enumerate(zip(self.slopes, self.intercepts)):
            if slopes and (slopes[-1], intercepts[-1]) == (s, c):
                points[-1] = self.points[i + 1]
                continue
            slopes.append(s)
            intercepts.append(c)
            points.append(self.points[i + 1])
        return Piecewise(tuple(points), tuple(slopes), tuple(intercepts))

    def where(self, positive: bool) -> list[Interval]:
        """Where the function is ``> 0`` (``positive``) or ``<= 0``, as disjoint intervals in order."""
        found: list[Interval] = []
        for i, (s, c) in enumerate(zip(self.slopes, self.intercepts)):
            left, right = self.points[i], self.points[i + 1]
            part = _affine_part(s, c, left, right, positive)
            if part is None:
                continue
            if found and found[-1].high == part.low and not (found[-1].high_open and part.low_open):
                last = found.pop()
                part = Interval(last.low, part.high, last.low_open, part.high_open)
            found.append(part)
        return found


def _affine_part(slope: Fraction, intercept: Fraction, left: Fraction, right: Fraction,
                 positive: bool) -> Interval | None:
    """Where ``slope * p + intercept`` is ``> 0`` (or ``<= 0``) within ``[left, right]``."""
    if slope == 0:
        return Interval(left, right) if (intercept > 0) == positive else None
    root = -intercept / slope
    if positive and slope > 0:  # above zero right of the root
        part = Interval(max(root, left), right, low_open=root >= left)
    elif positive:  # falling: above zero left of the root
        part = Interval(left, min(root, right), high_open=root <= right)
    elif slope > 0:  # at most zero up to the root
        part = Interval(left, min(root, right))
    else:
        part = Interval(max(root, left), right)
    return None if part.empty else part


def convex(oracle: Oracle, low: Fraction, high: Fraction, *, limit: int = 10_000) -> Piecewise:
    """The convex piecewise-affine function on ``[low, high]`` that ``oracle`` describes (see the
    module's docstring). ``limit`` bounds the oracle calls (a function with that many pieces is refused
    with ``ValueError``: the runs then depend on the parameter in a way the method does not cover)."""
    if low > high:
        raise ValueError(f"empty interval [{low}, {high}]")
    calls = 0

    def line(p: Fraction) -> tuple[Fraction, Fraction]:
        nonlocal calls
        calls += 1
        if calls > limit:
            raise ValueError(f"more than {limit} oracle calls: the function is not piecewise affine with "
                             "few pieces")
        value, slope = oracle(p)
        return slope, value - slope * p

    lines = [line(low)]
    if high == low:
        return Piecewise.affine(low, high, *lines[0])
    # Lines found in order of slope; between two consecutive ones, either their crossing is on the
    # function (the maximum of the two is it there) or a new line in between is found.
    stack = [(low, lines[0], high, line(high))]
    points: dict[Fraction, tuple[Fraction, Fraction]] = {}
    while stack:
        a, left, b, right = stack.pop()
        if left == right:
            points[a] = left
            continue
        (s1, c1), (s2, c2) = left, right
        if s1 == s2:  # parallel supporting lines at both ends: the higher one would contain both points
            raise ValueError("the oracle's lines are not supporting lines of one convex function")
        cross = (c2 - c1) / (s1 - s2)
        cross = min(max(cross, a), b)
        middle = line(cross)
        if middle[0] * cross + middle[1] == s1 * cross + c1:  # the function's value at the crossing
            points[a] = left
            points[cross] = right
            continue
        stack.append((cross, middle, b, right))
        stack.append((a, left, cross, middle))
    ordered = sorted(points)
    breakpoints = [p for p in ordered if p < high] + [high]
    slopes = tuple(points[p][0] for p in ordered if p < high)
    intercepts = tuple(points[p][1] for p in ordered if p < high)
    return Piecewise(tuple(breakpoints), slopes, intercepts).simplified()


def intersect(first: list[Interval], second: list[Interval]) -> list[Interval]:
    """The intersection of two sets given as disjoint intervals in order."""
    found: list[Interval] = []
    for a in first:
        for b in second:
            low, low_open = max((a.low, a.low_open), (b.low, b.low_open))
            high, high_open = min((b.high, not b.high_open), (a.high, not a.high_open))
            part = Interval(low, high, low_open, not high_open)
            if not part.empty:
                found.append(part)
    return sorted(found, key=lambda i: (i.low, i.low_open))
