"""The loophole checks as functions of one parameter (issue 25: `rac tune` under `require`).

:mod:`~rac.check.analysis.incentives` decides "ending early never pays", "reaching the goal earlier
never pays less" and "stalling never beats reaching the goal" at one value of the automaton's
numbers, by max-plus dynamic programmes over (sample, location) whose values are the best returns
of sets of runs. Here the same programmes run with a parameter ``P in [lo, hi]`` left open: under the
conditions :func:`rac.check.analysis.synthesis.unsupported` checks, the runs (their edges, input
classes and flags) do not depend on ``P`` and a sample's gain is affine in it, so every value of the
programme is the best of finitely many affine functions of ``P``: a convex piecewise-affine function,
kept as its upper envelope of lines. Adding a gain shifts the lines, taking the best of several
values merges envelopes, and each check becomes a finite set of comparisons between two such
functions (``E(P) <= S(P)``: the best early end against the best safe continuation at a reachable
point; ``G_k2(P) <= G_k1(P)`` for consecutive samples at which a safe run can first reach the goal;
``R_stall(P) <= G_k(P)``), each holding on a finite union of intervals computed exactly
(:meth:`~rac.check.analysis.piecewise.Piecewise.where`). The checks hold on the intersection.

Everything is exact: the lines are integers over one common denominator, the envelopes' breakpoints
rationals. That a gain is affine is verified, not assumed: each move's gain at the midpoint must lie
on the line through its values at ``lo`` and ``hi`` (a gain is convex in ``P``, so it is affine on the
interval exactly when it meets that chord inside); where it does not (``P`` an objective weight
multiplying a numeric input), the search stops with :class:`~rac.check.analysis.worst.Unfinished`.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable
from fractions import Fraction

from rac import ir
from rac.check.analysis.affine import moves
from rac.check.analysis.behaviour import input_space
from rac.check.analysis.incentives import Move, Runs, split_guards, unchecked
from rac.check.analysis.piecewise import Interval, Piecewise, intersect
from rac.check.analysis.synthesis import Unresolved
from rac.check.analysis.worst import Unfinished

__all__ = ["LOOPHOLES", "Envelope", "loophole_values", "upper"]

#: The loophole checks this module decides, by their `require` names.
LOOPHOLES = ("ending_early_never_pays", "goal_earlier_never_pays_less", "stalling_never_pays")

#: A line ``(slope, intercept)`` over the common denominator: its value at ``P`` is ``(slope * P +
#: intercept) / scale``. An envelope is the tuple of lines on the upper envelope, by increasing slope.
Line = tuple[int, int]
Envelope = tuple[Line, ...]

#: The automaton resolved with the parameter at a value (None when it does not resolve).
Resolve = Callable[[Fraction], "ir.Automaton | None"]


def _cross(a: Line, b: Line) -> Fraction:
    """Where line ``b`` (the steeper) meets line ``a``: ``b`` is higher to the right of it."""
    return Fraction(a[1] - b[1], b[0] - a[0])


def upper(lines: Iterable[Line], low: Fraction, high: Fraction) -> Envelope:
    """The lines of ``lines`` that are the maximum somewhere in ``[low, high]``, by increasing slope
    (the convex-hull trick, exact in integers and rationals)."""
    ordered = sorted(set(lines))
    hull: list[Line] = []
    for line in ordered:
        if hull and hull[-1][0] == line[0]:  # same slope: the higher intercept (sorted last) wins
            hull.pop()
        while len(hull) >= 2:
            a, b = hull[-2], hull[-1]
            # b is never above both a and `line` when `line` overtakes a no later than b does
            if (a[1] - line[1]) * (b[0] - a[0]) <= (a[1] - b[1]) * (line[0] - a[0]):
                hull.pop()
            else:
                break
        hull.append(line)
    start = 0
    while len(hull) - start >= 2 and _cross(hull[start], hull[start + 1]) <= low:
        start += 1
    end = len(hull)
    while end - start >= 2 and _cross(hull[end - 2], hull[end - 1]) >= high:
        end -= 1
    return tuple(hull[start:end])


def _plus(a: Envelope, b: Envelope, low: Fraction, high: Fraction) -> Envelope:
    if len(b) == 1:
        (s, c), = b
        return tuple((x + s, y + c) for x, y in a)
    return upper(((x + s, y + c) for x, y in a for s, c in b), low, high)


class _Parametric:
    """The programmes of :class:`~rac.check.analysis.incentives.Runs` with envelopes for values."""

    def __init__(self, resolve: Resolve, parameter: ir.Parameter) -> None:
        self.low, self.high = low, high = parameter.low, parameter.high
        middle = (low + high) / 2
        runs: list[Runs] = []
        for value in (low, middle, high):
            automaton = resolve(value)
            if automaton is None:  # the bounds resolved; the midpoint need not (E0011 of a tiny coefficient)
                raise Unresolved(value)
            space, _ = input_space(automaton)
            if space is None:
                raise Unfinished("the inputs have too many classes")
            outs = moves(automaton, space, split_guards(automaton))
            stop = unchecked(automaton, outs)
            if stop is not None:
                raise Unfinished(stop.reason)
            runs.append(Runs(automaton, space, outs, prune=False))
        first = runs[0]
        self.steps, self.l0 = first.steps, first.l0
        self.moves: list[list[Move]] = first.moves
        shapes = [[[(m.outcome.target, m.ends, m.goal, m.collision) for m in ms] for ms in r.moves] for r in runs]
        if shapes[1] != shapes[0] or shapes[2] != shapes[0]:
            raise Unfinished("the runs differ between the parameter's values")

        def line(values: tuple[Fraction, Fraction, Fraction]) -> tuple[Fraction, Fraction]:
            at_low, at_middle, at_high = values
            slope = (at_high - at_low) / (high - low) if high > low else Fraction(0)
            if at_middle != at_low + slope * (middle - low):
                raise Unfinished("a sample's gain is not affine in the parameter (it weighs a numeric input "
                                 "whose best value changes with it)")
            return slope, at_low - slope * low

        start = line((runs[0].c0, runs[1].c0, runs[2].c0))
        exact: list[list[tuple[tuple[Fraction, Fraction], ...]]] = []
        for here, ms in enumerate(self.moves):
            found = []
            for i in range(len(ms)):
                gains = [(*r.moves[here][i].going, *r.moves[here][i].stopping) for r in runs]
                found.append(tuple(line((gains[0][j][0], gains[1][j][0], gains[2][j][0])) for j in range(4)))
            exact.append(found)
        numbers = [*start] + [x for ls in exact for gs in ls for g in gs for x in g]
        self.scale = math.lcm(*(x.denominator for x in numbers))

        def scaled(pair: tuple[Fraction, Fraction]) -> Line:
            return int(pair[0] * self.scale), int(pair[1] * self.scale)

        self.start: Envelope = (scaled(start),)
        #: gains[l][i]: the lines of move i of location l, as Runs.gains orders them.
        self.gains = [[tuple(scaled(g) for g in gs) for gs in ls] for ls in exact]

    def gain(self, here: int, i: int, k: int, stop: bool) -> Envelope:
        return (self.gains[here][i][(2 if stop else 0) + (0 if k == 1 else 1)],)

    def stops(self, m: Move, k: int) -> bool:
        return m.ends or k == self.steps

    def best(self, lines: Iterable[Line]) -> Envelope:
        return upper(lines, self.low, self.high)

    def function(self, envelope: Envelope) -> Piecewise:
        """The envelope as a piecewise-affine function on ``[low, high]``."""
        points = [self.low]
        for a, b in zip(envelope, envelope[1:]):
            points.append(_cross(a, b))
        points.append(self.high)
        return Piecewise(tuple(points), tuple(Fraction(s, self.scale) for s, _ in envelope),
                         tuple(Fraction(c, self.scale) for _, c in envelope))

    def holds(self, lower: Envelope, higher: Envelope) -> list[Interval]:
        """Where ``lower <= higher``."""
        if self.low == self.high:
            below = self.function(lower)(self.low) <= self.function(higher)(self.low)
            return [Interval(self.low, self.high)] if below else []
        return self.function(lower).combine(self.function(higher), Fraction(1), Fraction(-1)).where(False)

    # ------------------------------------------------------------ the programmes
    def forward(self, allowed: Callable[[Move], bool]) -> list[dict[int, Envelope]]:
        """layers[k][l]: the best value after k samples in l of a run not ended yet, its moves allowed."""
        layers: list[dict[int, Envelope]] = [{self.l0: self.start}]
        for k in range(1, self.steps):
            found: dict[int, list[Line]] = {}
            for here, value in layers[-1].items():
                for i, m in enumerate(self.moves[here]):
                    if m.ends or not allowed(m):
                        continue
                    s, c = self.gains[here][i][0 if k == 1 else 1]
                    found.setdefault(m.outcome.target, []).extend((x + s, y + c) for x, y in value)
            layers.append({target: self.best(lines) for target, lines in found.items()})
        return layers

    def safe_rests(self) -> list[dict[int, Envelope]]:
        """rests[k][l]: the best the rest of a safe run earns after k samples in l."""
        rests: list[dict[int, Envelope]] = [{} for _ in range(self.steps + 1)]
        for k in range(self.steps - 1, -1, -1):
            for here, ms in enumerate(self.moves):
                lines: list[Line] = []
                for i, m in enumerate(ms):
                    if not m.collision:
                        lines.extend(self.rest(here, i, k + 1, rests))
                if lines:
                    rests[k][here] = self.best(lines)
        return rests

    def rest(self, here: int, i: int, k: int, rests: list[dict[int, Envelope]]) -> Envelope:
        """What a run taking move i of ``here`` at sample ``k`` earns from there on, its rest safe
        (empty: no such rest)."""
        m = self.moves[here][i]
        if self.stops(m, k):
            return self.gain(here, i, k, True)
        after = rests[k].get(m.outcome.target)
        return () if after is None else _plus(after, self.gain(here, i, k, False), self.low, self.high)


def loophole_values(resolve: Resolve, parameter: ir.Parameter, checks: Iterable[str]) -> dict[str, list[Interval]]:
    """For each loophole check of ``checks`` (names of :data:`LOOPHOLES`), the values of ``parameter``
    in its bounds where it holds, exactly, as :func:`~rac.check.analysis.incentives.analyse` decides it at
    one value (see the module). Raises :class:`~rac.check.analysis.worst.Unfinished` where the method
    does not apply, and :class:`~rac.check.analysis.synthesis.Unresolved` where the file does not check at the
    midpoint of the bounds, which it reads (the caller's E0407)."""
    wanted = [c for c in LOOPHOLES if c in set(checks)]
    runs = _Parametric(resolve, parameter)
    whole = [Interval(runs.low, runs.high)]
    found: dict[str, list[Interval]] = {}
    rests = runs.safe_rests()
    if "ending_early_never_pays" in wanted:
        found["ending_early_never_pays"] = _ending_early(runs, rests, whole)
    if "goal_earlier_never_pays_less" in wanted or "stalling_never_pays" in wanted:
        quiet = runs.forward(lambda m: not (m.goal or m.collision))
        goal_by_sample, stall = _goals(runs, rests, quiet)
        order = sorted(goal_by_sample)
        if "goal_earlier_never_pays_less" in wanted:
            holding = whole
            for earlier, later in zip(order, order[1:]):
                holding = intersect(holding, runs.holds(goal_by_sample[later], goal_by_sample[earlier]))
            found["goal_earlier_never_pays_less"] = holding
        if "stalling_never_pays" in wanted:
            holding = whole
            if stall is not None:
                for k in order:
                    holding = intersect(holding, runs.holds(stall, goal_by_sample[k]))
            found["stalling_never_pays"] = holding
    return found


def _ending_early(runs: _Parametric, rests: list[dict[int, Envelope]], whole: list[Interval]) -> list[Interval]:
    """Where, at every point a run can reach, ending early (without the goal) earns no more than the
    best safe continuation."""
    holding = whole
    reach = {runs.l0}
    for k in range(1, runs.steps + 1):
        following: set[int] = set()
        for here in sorted(reach):
            ms = runs.moves[here]
            early: list[Line] = []
            safe: list[Line] = []
            for i, m in enumerate(ms):
                if not m.ends:
                    following.add(m.outcome.target)
                if m.ends and not m.goal:
                    early.extend(runs.gain(here, i, k, True))
                elif not m.collision:
                    safe.extend(runs.rest(here, i, k, rests))
            if early and safe:
                holding = intersect(holding, runs.holds(runs.best(early), runs.best(safe)))
                if not holding:
                    return []
        reach = following
    return holding


def _goals(runs: _Parametric, rests: list[dict[int, Envelope]], quiet: list[dict[int, Envelope]]
           ) -> tuple[dict[int, Envelope], Envelope | None]:
    """G_k (the best return of a safe run first reaching the goal at sample k, for each k where one
    does) and R_stall (None: no safe run stalls), as envelopes."""
    goal_by_sample: dict[int, Envelope] = {}
    stall: list[Line] = []
    for k in range(1, runs.steps + 1):
        lines: list[Line] = []
        for here, value in quiet[k - 1].items():
            for i, m in enumerate(runs.moves[here]):
                if m.collision:
                    continue
                if m.goal:
                    rest = runs.rest(here, i, k, rests)
                    if rest:
                        lines.extend(_plus(value, rest, runs.low, runs.high))
                elif runs.stops(m, k):
                    stall.extend(_plus(value, runs.gain(here, i, k, True), runs.low, runs.high))
        if lines:
            goal_by_sample[k] = runs.best(lines)
    return goal_by_sample, (runs.best(stall) if stall else None)
