"""Priority soundness (P1 rate dominance, P2 no compensation) and the int32 range check."""

from __future__ import annotations

import dataclasses
import itertools
import math
from collections import deque
from collections.abc import Callable, Collection, Iterable, Mapping, Sequence
from fractions import Fraction

from rac import ir
from rac.check.analysis.affine import Affine, Moves, Outcome, accrual, end_assignments, from_assignments, moves
from rac.check.analysis.behaviour import allowed_boxes, input_space
from rac.check.analysis.worst import (
    AFTER_END,
    BEFORE_EDGE,
    BEFORE_NEXT,
    CONTINUE,
    MAX_SAMPLES,
    MID_EDGE,
    MID_END,
    Target,
    Unfinished,
    Worst,
    maximise,
    within_limit,
)
from rac.core.diagnostics import UNFINISHED, Diagnostic, Fact, Note, error, short_number, warning
from rac.core.numbers import INT32_MAX, INT32_MIN, exact_decimal
from rac.ir.inputs import InputSpace, guard_inputs
from rac.ir.significands import observation_diagnostics, update_diagnostics
from rac.ir.vocabulary import DEFAULT_BASE, DEFAULT_EXPONENT

ZERO = Fraction(0)
#: Default number representation (model.md): significand = trunc(v · base^exponent).


def _bounds(item: ir.Input) -> tuple[Fraction, Fraction]:
    """A numeric input's declared bounds (the resolver rejects a numeric input without them)."""
    assert item.low is not None and item.high is not None, item.name
    return item.low, item.high


def _declared_box(automaton: ir.Automaton, names: Iterable[str]) -> dict[str, tuple[Fraction, Fraction]]:
    """The declared bounds of the numeric inputs ``names``, as a box for :func:`_range_in`."""
    return {name: _bounds(automaton.input(name)) for name in names}


#: Integer inputs in a rate pair are enumerated up to this many joint values; beyond, all but the
#: widest are (and the widest is searched exactly), else they are relaxed to reals.
MAX_INT_POINTS = 4096


def _exists_neg_pos(f: ir.Linear, g: ir.Linear, automaton: ir.Automaton) -> bool:
    """Is there an input point ``assume`` allows with f < 0 and g > 0?

    Within each box of allowed inputs (:func:`~rac.check.analysis.behaviour.allowed_boxes`; the
    declared bounds when the classes are too many to list) by :func:`exists_neg_pos_in`.
    """
    names = tuple(sorted(set(f.variables()) | set(g.variables())))
    boxes = allowed_boxes(automaton, names)
    if boxes is None:
        boxes = [_declared_box(automaton, names)]
    return any(exists_neg_pos_in(f, g, automaton, box) for box in boxes)


def exists_neg_pos_in(f: ir.Linear, g: ir.Linear, automaton: ir.Automaton,
                      box: dict[str, tuple[Fraction, Fraction]]) -> bool:
    """Is there a point of ``box`` (closed bounds per input) with f < 0 and g > 0?

    ``min_x max(f, -g) < 0`` (:class:`_MinMax`). The minimax theorem behind it needs convex ranges:
    ``int`` inputs take whole values, so they are enumerated, when few. When their joint values are
    too many, every one but the widest is enumerated and the widest searched exactly (the minimum
    over the real inputs is convex in it); only when even those are too many are the ``int`` inputs
    relaxed to reals (which may report a point that no whole values reach).
    """
    names = sorted(set(f.variables()) | set(g.variables()))
    ints = [n for n in names if automaton.input(n).kind == "int"]
    ranges = [range(int(box[n][0]), int(box[n][1]) + 1) for n in ints]
    if not ints or math.prod(len(r) for r in ranges) <= MAX_INT_POINTS:
        least = _MinMax(f, g, ints, box)
        return any(least(combo) < 0 for combo in itertools.product(*ranges))
    widest = max(range(len(ints)), key=lambda i: len(ranges[i]))
    others = ranges[:widest] + ranges[widest + 1:]
    if math.prod(len(r) for r in others) > MAX_INT_POINTS:
        return _MinMax(f, g, [], box)(()) < 0  # relaxed to reals
    least = _MinMax(f, g, ints, box)
    for combo in itertools.product(*others):
        def at(v: int, combo: tuple[int, ...] = combo) -> Fraction:
            return least((*combo[:widest], v, *combo[widest:]))

        # convex in the widest input's value: its differences grow; a binary search on their sign
        low, high = ranges[widest][0], ranges[widest][-1]
        while low < high:
            middle = (low + high) // 2
            if at(middle + 1) < at(middle):
                low = middle + 1
            else:
                high = middle
        if at(low) < 0:
            return True
    return False


class _MinMax:
    """``min`` over the real inputs of ``box`` of ``max(f, -g)``, as a function of the whole values of
    the inputs ``ints`` (in that order; ``[]``: every input real). By the minimax theorem it is the
    max over λ ∈ [0, 1] of a separable minimum, piecewise linear in λ: its breakpoints decide, each
    an affine function of the ``int`` values (a max of affine functions: convex in them)."""

    def __init__(self, f: ir.Linear, g: ir.Linear, ints: Sequence[str],
                 box: dict[str, tuple[Fraction, Fraction]]) -> None:
        reals = sorted((set(f.variables()) | set(g.variables())) - set(ints))
        lambdas = {Fraction(0), Fraction(1)}
        for name in reals:
            a, b = f.coefficient(name), -g.coefficient(name)
            if a != b and 0 <= -b / (a - b) <= 1:
                lambdas.add(-b / (a - b))
        self.rows: list[tuple[Fraction, tuple[Fraction, ...]]] = []
        for lam in lambdas:
            mix = f.scaled(lam) + g.scaled(-(1 - lam))
            real_part = ir.Linear(mix.const, tuple((n, c) for n, c in mix.terms if n not in ints))
            self.rows.append((_range_in(real_part, box)[0], tuple(mix.coefficient(n) for n in ints)))

    def __call__(self, values: Sequence[int]) -> Fraction:
        return max(const + sum((c * v for c, v in zip(coefficients, values)), ZERO)
                   for const, coefficients in self.rows)


def _range_in(linear: ir.Linear, box: dict[str, tuple[Fraction, Fraction]]) -> tuple[Fraction, Fraction]:
    """[min, max] of a linear form over a box of closed bounds."""
    low = high = linear.const
    for name, coefficient in linear.terms:
        a, b = coefficient * box[name][0], coefficient * box[name][1]
        low += min(a, b)
        high += max(a, b)
    return low, high


def _can_be_negative(linear: ir.Linear, automaton: ir.Automaton, guard: ir.Guard | None = None) -> bool:
    """Whether ``linear`` is below 0 for some input ``assume`` allows (where ``guard`` holds)."""
    names = tuple(sorted(set(linear.variables())))
    boxes = allowed_boxes(automaton, names, guard)
    if boxes is None:
        boxes = [_declared_box(automaton, names)]
    return any(_range_in(linear, box)[0] < 0 for box in boxes)


def check_rate_dominance(automaton: ir.Automaton) -> list[Diagnostic]:
    """P1: wherever a reward decreases, no lower-priority reward has a positive weighted rate."""
    result = []
    index = {r: i for i, r in enumerate(automaton.rewards)}
    order = automaton.priority
    for location in automaton.locations:
        for a, high in enumerate(order):
            rate_high = location.rates[index[high]]
            for low in order[a + 1:]:
                weight = automaton.objective.coefficient(low)
                rate_low = location.rates[index[low]].scaled(weight)
                if _exists_neg_pos(rate_high, rate_low, automaton):
                    result.append(error(
                        "E0401",
                        f"P1 rate dominance fails in `{location.name}`: `{high}` decreases while "
                        f"lower-priority `{low}` increases",
                        location.span,
                        notes=[f"priority {' > '.join(order)}; in `{location.name}` `{high}'` = "
                               f"{_linear_text(rate_high)} and the weighted rate of `{low}` is "
                               f"{_linear_text(rate_low)}"],
                        hints=[f"give `{low}` a rate <= 0 in `{location.name}`, or reorder the priorities"],
                        data={"location": location.name, "decreasing": high, "increasing": low}))
    return result


def rate_conflicts(automaton: ir.Automaton, location: ir.Location, high: str, low: str) -> tuple[bool, bool]:
    """Whether, in ``location``, ``high`` can decrease while ``low`` increases, and while ``low``
    decreases: P1 fails for a positive weight of ``low`` with the first, for a negative one with the second."""
    index = {r: i for i, r in enumerate(automaton.rewards)}
    rate_high, rate_low = location.rates[index[high]], location.rates[index[low]]
    return (_exists_neg_pos(rate_high, rate_low, automaton),
            _exists_neg_pos(rate_high, rate_low.scaled(Fraction(-1)), automaton))


def _penalised(automaton: ir.Automaton, reward: str) -> tuple[bool, ...]:
    """Locations that penalise a reward: a rate there that some input ``assume`` allows makes
    negative, or an edge into it that lowers it for some allowed input its guard lets through.

    What an edge does is its whole sequence of updates (``p += 5, p -= 1`` raises p by 4, and lowers
    it nowhere); a change that depends on the rewards (``p = 0``, ``p = p / 2``) may lower it."""
    k = automaton.rewards.index(reward)
    marks = [_can_be_negative(loc.rates[k], automaton) for loc in automaton.locations]
    for edge in automaton.all_edges():
        if marks[edge.target] or all(update.reward != reward for update in edge.updates):
            continue
        whole = from_assignments(edge.updates, automaton.rewards)
        row = None if whole.matrix is None else whole.matrix[k]
        if row is not None and any(c != (1 if j == k else 0) for j, c in enumerate(row)):
            marks[edge.target] = True
        elif _can_be_negative(whole.offset[k], automaton, edge.guard):
            marks[edge.target] = True
    return tuple(marks)


def p2_levels(automaton: ir.Automaton) -> range:
    """The priority levels P2 checks: the highest only, or every level under ``priority strict``."""
    if not automaton.priority:
        return range(0)
    return range(len(automaton.priority)) if automaton.strict else range(1)


def p2_target(automaton: ir.Automaton, level: int) -> Target:
    """What P2 maximises at ``level``: the weighted sum from that level down, over the instants spent
    where the level's reward is penalised; P2 holds when the maximum is <= 0."""
    ranked = set(automaton.priority[level:])
    weights = tuple(automaton.objective.coefficient(r) if r in ranked else ZERO for r in automaton.rewards)
    constant = automaton.objective.const if level == 0 else ZERO
    return Target(weights, constant, _penalised(automaton, automaton.priority[level]))


def range_target(automaton: ir.Automaton, k: int, sign: int, intermediates: bool = True) -> Target:
    """What the int32 range check maximises for reward ``k``: ``sign``·r_k over every instant, and
    (``intermediates``) inside every sequence of updates: UPPAAL stores the value after each
    assignment of an edge's (and the ``at end`` clauses') updates in the reward's 32-bit mirror."""
    size = len(automaton.rewards)
    weights = tuple(Fraction(sign) if j == k else ZERO for j in range(size))
    return Target(weights, ZERO, tuple(True for _ in automaton.locations), intermediates)


def range_limit(sign: int) -> int:
    """The significand a reward must stay below (``sign`` 1) or whose negation it must stay below (-1)."""
    return INT32_MAX + 1 if sign > 0 else -INT32_MIN + 1


def _prepared(automaton: ir.Automaton, prepared: tuple[InputSpace, Moves] | None
              ) -> tuple[InputSpace | None, Moves | None, list[Diagnostic]]:
    """The input space and the moves: the caller's (``prepared``), or built here."""
    if prepared is not None:
        return prepared[0], prepared[1], []
    space, problems = input_space(automaton)
    return space, (moves(automaton, space) if space is not None else None), problems


def check_priorities(automaton: ir.Automaton, facts: list[Fact] | None = None,
                     prepared: tuple[InputSpace, Moves] | None = None) -> list[Diagnostic]:
    """P1 and P2 (every level when ``priority strict``); proofs are appended to ``facts``.

    ``prepared`` is the automaton's input space and moves when the caller has built them.
    """
    facts = facts if facts is not None else []
    if not automaton.priority:
        facts.append(Fact("priority", "no `priority` declared: P1 and P2 not checked"))
        return []
    diagnostics = check_rate_dominance(automaton)
    if not diagnostics:
        facts.append(Fact("P1", "P1 holds: wherever a reward decreases, no lower-priority reward grows"))
    space, outs, problems = _prepared(automaton, prepared)
    if space is None or outs is None:
        return diagnostics + problems
    for level in p2_levels(automaton):
        reward = automaton.priority[level]
        target = p2_target(automaton, level)
        weights, constant, watched = target.weights, target.constant, target.watched
        if not any(watched):
            facts.append(Fact("P2", f"P2 holds trivially for `{reward}`: no location penalises it", {"reward": reward}))
            continue
        def violates(value: Fraction) -> bool:
            return value > 0

        prefix = False
        try:
            worst = maximise(automaton, outs, target, run=violates)
        except Unfinished as stop:
            worst = _refuted_within_limit(automaton, outs, target, violates)
            if worst is None:
                diagnostics.append(_unfinished(automaton, f"P2 for `{reward}`", stop))
                continue
            prefix = True
        if worst is None or worst.value <= 0:
            places = ", ".join(f"`{n}`" for n, w in zip(automaton.location_names, watched) if w)
            what = "the objective" if level == 0 else f"the weighted sum from `{reward}` down"
            if worst is None:
                facts.append(Fact("P2", f"P2 holds for `{reward}`: no run of {show_number(automaton.horizon)} s "
                                  f"reaches a location that penalises it ({places})", {"reward": reward}))
            else:
                facts.append(Fact("P2", f"P2 holds for `{reward}` (penalised in {places}): {what} stays "
                                  f"<= {show_number(worst.value)} over every run of {show_number(automaton.horizon)} s",
                                  {"reward": reward, "bound": str(worst.value), "level": level}))
            continue
        found = _p2_error(automaton, space, outs, worst, level, weights, constant)
        diagnostics.append(_cut_short(found, automaton) if prefix else found)
    return diagnostics


def _refuted_within_limit(automaton: ir.Automaton, outs: Moves, target: Target,
                          violates: Callable[[Fraction], bool]) -> Worst | None:
    """After the worst-run search stopped at :data:`MAX_SAMPLES`: the worst run over the horizon's first
    :data:`MAX_SAMPLES` samples when it already violates (a run of the horizon too, so a refutation),
    else None (the check stays unfinished, W0405)."""
    try:
        worst = maximise(within_limit(automaton), outs, target, run=violates)
    except Unfinished:
        return None
    return worst if worst is not None and violates(worst.value) else None


def _cut_short(found: Diagnostic, automaton: ir.Automaton) -> Diagnostic:
    """``found`` (a violation :func:`_refuted_within_limit` found) with a note that says where it was searched."""
    return dataclasses.replace(found, notes=(*found.notes, Note(
        f"found among the runs of the horizon's first {within_limit(automaton).steps:,} samples (of "
        f"{automaton.steps:,}), where the worst-run search stops: every such run is a run of the horizon, "
        "so the check fails; over the whole horizon the value can be larger still")))


def _unfinished(automaton: ir.Automaton, what: str, stop: Unfinished) -> Diagnostic:
    """W0405: an analysis stopped at its limit, neither proved nor refuted."""
    return warning(
        UNFINISHED, f"{what} not checked: {stop.reason}",
        automaton.spans.get("decl:horizon") or automaton.spans.get("decl:sample"),
        notes=[f"the horizon has {automaton.steps:,} samples (horizon / sample period); the worst-run search "
               f"stops at {MAX_SAMPLES:,} unless the worst values settle before"],
        hints=["shorten the horizon or sample less often to have it checked"],
        data={"limit": MAX_SAMPLES, "samples": automaton.steps})


def _p2_error(automaton: ir.Automaton, space: InputSpace, outs, worst: Worst, level: int,
              weights: tuple[Fraction, ...], constant: Fraction) -> Diagnostic:
    reward = automaton.priority[level]
    values, where = replay(automaton, space, worst)
    ranked = automaton.priority[level:]
    scope = "the objective" if level == 0 else "the weighted sum of " + ", ".join(f"`{r}`" for r in ranked)
    weight = automaton.objective.coefficient(reward)
    span = automaton.spans.get("decl:priority")
    run = describe_run(automaton, space, worst)
    listing = ", ".join(f"{r} = {show_number(v)}" for r, v in zip(automaton.rewards, values))
    total = sum((w * v for w, v in zip(weights, values)), constant)
    notes = [Note("counterexample (" + f"sample every {show_number(automaton.period)} s, horizon "
                  f"{show_number(automaton.horizon)} s):\n" + "\n".join(run)),
             Note(f"at the violating instant ({where}): {listing}; {scope} = {show_number(total)} > 0")]
    hints = []
    if weight > 0:
        hints.append(f"penalise `{reward}` by at least {show_number(worst.value / weight)} more "
                     f"({show_number(worst.value)} / weight {show_number(weight)}), or shrink what lower objectives "
                     "can gain")
    else:  # a larger penalty cannot help: the objective does not weigh the reward up (a sign slip, a lost term)
        how = f"weighs `{reward}` by {show_number(weight)}" if weight < 0 else f"leaves `{reward}` out (weight 0)"
        hints.append(f"the objective {how}, so a penalty on `{reward}` {'raises' if weight < 0 else 'does not lower'} "
                     f"it: give `{reward}` a positive weight in `objective`")
    strict = "strict " if automaton.strict else ""
    return error(
        "E0402",
        f"P2 no compensation fails: while `{reward}` is penalised, {scope} {_reaches(space, worst)} "
        f"{show_number(worst.value)}",
        span,
        notes=notes,
        hints=hints,
        data={"property": "P2", "level": level, "reward": reward, "value": str(worst.value),
              "priority": f"{strict}{' > '.join(automaton.priority)}",
              **replayable_json(automaton, space, worst, lambda near: sum(
                  (w * v for w, v in zip(weights, replay(automaton, space, near)[0])), constant) > 0),
              "values": {r: str(v) for r, v in zip(automaton.rewards, values)}})


class _When:
    """An instant of a run, formatted only when shown (a replay goes through every sample)."""

    __slots__ = ("time", "what")

    def __init__(self, time: Fraction, what: str) -> None:
        self.time, self.what = time, what

    def __str__(self) -> str:
        return f"t = {show_number(self.time)} s, {self.what}"


def trace(automaton: ir.Automaton, space: InputSpace, worst: Worst, inside: bool = False):
    """Exact reward values along the worst run: yields (the instant, whose str() is a phrase naming it, values).

    ``inside``: also the values in between each sequence of updates, after each assignment (those
    UPPAAL stores: :attr:`~rac.check.analysis.worst.Target.intermediates`); a run whose value is
    taken in between (MID_EDGE, MID_END) ends there either way."""
    r = [ZERO] * len(automaton.rewards)
    yield _When(ZERO, "before any sample"), r
    l0 = automaton.initial
    names = automaton.location_names
    name = names[l0]
    time = ZERO
    period = automaton.period
    accruals = [accrual(loc, period) for loc in automaton.locations]
    inputs: dict[tuple[int, int], dict[str, Fraction]] = {}  # a run repeats its samples: build each once
    offsets: dict[tuple[int, int], list[Fraction]] = {}
    # per sequence of updates (kept alive: its id is the key): the map after its first i assignments
    prefixes: dict[int, tuple[tuple[ir.Assignment, ...], list[Affine]]] = {}

    def between(updates: tuple[ir.Assignment, ...], stop: int | None, r: list[Fraction], x: dict[str, Fraction],
                place: str):
        """The values in between ``updates`` (up to after ``stop`` of them, else all but the last)."""
        known = prefixes.get(id(updates))
        if known is None:
            known = prefixes[id(updates)] = (updates, [from_assignments(updates[:i], automaton.rewards)
                                                       for i in range(len(updates))])
        maps = known[1]
        last = stop if stop is not None else len(updates) - 1
        for applied in range(1 if inside else last, last + 1):
            yield _When(time, f"{place}, {_inside(updates, applied)}: an intermediate value, which UPPAAL "
                              "stores too"), _apply(maps[applied], r, x)

    def apply(affine: Affine, r: list[Fraction], x: dict[str, Fraction]) -> list[Fraction]:
        if affine.matrix is not None:
            return _apply(affine, r, x)
        offset = offsets.get((id(affine), id(x)))
        if offset is None:
            offset = offsets[id(affine), id(x)] = [term.evaluate(x) for term in affine.offset]
        return [a + b for a, b in zip(r, offset)]

    for step in worst.steps:
        o = step.outcome
        x = inputs.get((o.cls, id(step.inputs)))
        if x is None:
            x = inputs[o.cls, id(step.inputs)] = _inputs(space, step)
        time = step.sample * period
        if step.sample == 1:
            r = apply(accruals[l0], r, x)
            yield _When(time, f"in `{name}` before the sample's edge"), r
            if step.instant == BEFORE_EDGE:
                return
        stop = worst.applied if step.instant == MID_EDGE else None
        if o.edge is not None and (inside or stop is not None):
            yield from between(o.edge.updates, stop, r, x, f"during the edge `{name}` -> `{names[o.target]}`")
            if stop is not None:
                return
        r = apply(o.edge_map, r, x)
        name = names[o.target]
        # a sample that ends the episode applies its `at end` updates next, in the same step of the runtimes
        after = "right after the sample's edge, before the `at end` updates of the episode's end" \
            if o.ends_episode else "right after the sample"
        yield _When(time, f"in `{name}` {after}"), r
        if step.instant not in (CONTINUE, BEFORE_NEXT):
            break
        r = apply(accruals[o.target], r, x)
        yield _When(time + period, f"in `{name}` just before the next sample"), r
        if step.instant != CONTINUE:
            return
    if worst.instant in (AFTER_END, MID_END) and worst.end is not None:
        x = {n: v for n, v in space.valuation(worst.end.cls).items() if not isinstance(v, bool)}
        x.update(worst.end_inputs)
        stop = worst.applied if worst.instant == MID_END else None
        if inside or stop is not None:
            yield from between(end_assignments(automaton, worst.end.ends), stop, r, x,
                               f"in `{name}` during the `at end` updates")
            if stop is not None:
                return
        yield _When(time, f"in `{name}` after the `at end` updates"), _apply(worst.end.end_map, r, x)


def _inside(updates: tuple[ir.Assignment, ...], applied: int) -> str:
    """Where inside a sequence of updates a MID_EDGE or MID_END instant is: after which assignment."""
    line = updates[applied - 1].span
    where = f" (line {line.line})" if line is not None else ""
    return f"right after its update {applied} of {len(updates)}{where}"


def offending_update(automaton: ir.Automaton, worst: Worst) -> ir.Assignment | None:
    """At a MID_EDGE or MID_END instant: the assignment of the sequence the worst run's value is
    taken after (what the UPPAAL model stores there); None at any other instant."""
    if worst.applied is None:
        return None
    if worst.instant == MID_EDGE:
        edge = worst.steps[-1].outcome.edge
        assert edge is not None
        return edge.updates[worst.applied - 1]
    assert worst.instant == MID_END and worst.end is not None
    return end_assignments(automaton, worst.end.ends)[worst.applied - 1]


def replay(automaton: ir.Automaton, space: InputSpace, worst: Worst) -> tuple[list[Fraction], str]:
    """Exact reward values at the instant the worst run ends, and a phrase naming that instant."""
    (where, values), = deque(trace(automaton, space, worst), maxlen=1)  # the last instant (the start, at least)
    return values, str(where)


def _apply(affine: Affine, r: list[Fraction], x: dict[str, Fraction]) -> list[Fraction]:
    """``affine`` applied to the rewards ``r`` with the inputs ``x``."""
    size = len(r)
    if affine.matrix is None:
        base = list(r)
    else:
        base = [sum((affine.matrix[k][j] * r[j] for j in range(size)), ZERO) for k in range(size)]
    return [base[k] + affine.offset[k].evaluate(x) for k in range(size)]


def _inputs(space: InputSpace, step) -> dict[str, Fraction]:
    values = {n: v for n, v in space.valuation(step.outcome.cls).items() if not isinstance(v, bool)}
    values.update(step.inputs)
    return values


def _inputs_text(label: str) -> str:
    """``inputs isClose=true`` for a run's line, or that no input is read there (a location without edges)."""
    return f"inputs {label}" if label else "no input is read"


def _outcome_inputs(automaton: ir.Automaton, o: Outcome) -> set[str]:
    """The inputs worth showing for a sample: those the location's guards read, and those `episode ends
    when` reads (they decide whether the run goes on: a replay must give them the run's values)."""
    names: set[str] = set()
    for edge in automaton.edges[o.source]:
        names |= guard_inputs(edge.guard)
    if automaton.ending is not None:
        names |= guard_inputs(automaton.ending)
    return names


def describe_run(automaton: ir.Automaton, space: InputSpace, worst: Worst, *, shown: Collection[str] = (),
                 ending: str | None = None) -> list[str]:
    """The worst run as readable lines: (location, samples spent), inputs, edges, end.

    Each sample shows the inputs its location's guards read, and those named in ``shown``;
    ``ending`` starts the line of an end with ``at end`` (why the run ends there; by default, that
    ``episode ends when`` held at the last sample, or only that the run ends)."""
    if ending is None:
        ended = bool(worst.steps) and worst.steps[-1].outcome.ends_episode
        ending = "the episode ends (`episode ends when` holds)" if ended else "run ends"
    names = automaton.location_names
    period = automaton.period
    lines: list[str] = []
    if not worst.steps and worst.instant != AFTER_END:
        return [f"  t = 0 s: in `{names[automaton.initial]}` before any sample"]
    groups: list[list] = []
    labels: dict[tuple[int, int], str] = {}
    for step in worst.steps:
        o = step.outcome
        label = labels.get((id(o), id(step.inputs)))
        if label is None:
            # The values the run's arithmetic reads (rates, updates) too: the run reaches its value with them.
            label = labels[id(o), id(step.inputs)] = _inputs_text(space.describe(
                o.cls, _outcome_inputs(automaton, o) | set(shown), step.inputs, none=""))
        key = (o.source, id(o.edge), label)
        if groups and groups[-1][0] == key and groups[-1][1][-1].instant == CONTINUE:
            groups[-1][1].append(step)
        else:
            groups.append([key, [step]])
    if len(groups) > 12:
        # Long alternating runs: the beginning and the end tell the story.
        hidden = len(groups) - 10
        groups = groups[:5] + [[None, hidden]] + groups[-5:]
    for key, steps in groups:
        if key is None:
            lines.append(f"  ... {steps} more segments ...")
            continue
        source, _, label = key
        no_edge = steps[-1].outcome.edge is None
        first, last = steps[0].sample, steps[-1].sample
        when = (f"samples {first}-{last} (t = {show_number(first * period)}..{show_number(last * period)} s)"
                if first != last else f"sample {first} (t = {show_number(first * period)} s)")
        o = steps[-1].outcome
        if no_edge:
            what = f"stays in `{names[source]}`"
        else:
            line = o.edge.span.line if o.edge and o.edge.span else "?"
            what = f"`{names[source]}` -> `{names[o.target]}` (edge at line {line})"
        count = f", {len(steps)} samples" if len(steps) > 1 else ""
        lines.append(f"  {when}: {what}{count}; {label}")
    if worst.instant == MID_EDGE and worst.applied is not None and worst.steps:
        edge = worst.steps[-1].outcome.edge
        assert edge is not None
        lines.append(f"  stops during that edge's updates, {_inside(edge.updates, worst.applied)}")
    if worst.instant in (AFTER_END, MID_END) and worst.end is not None:
        end = worst.end
        spans = [(i, automaton.end_clauses[i].span) for i in end.ends]
        clauses = ", ".join(f"line {span.line}" if span else str(i) for i, span in spans)
        read: set[str] = set()
        for clause in automaton.end_clauses:
            read |= guard_inputs(clause.guard)
        when = show_number(worst.steps[-1].sample * period) if worst.steps else "0"
        lines.append(f"  {ending} at t = {when} s: `at end` ({clauses or 'no clause enabled'}); "
                     f"{_inputs_text(space.describe(end.cls, read, worst.end_inputs, none=''))}")
        if worst.instant == MID_END and worst.applied is not None:
            lines.append(f"  stops during the `at end` updates, "
                         f"{_inside(end_assignments(automaton, end.ends), worst.applied)}")
    return lines


def run_json(automaton: ir.Automaton, space: InputSpace, worst: Worst) -> list[dict[str, object]]:
    """The run's samples for ``--format json``: one entry per stretch of consecutive samples that take
    the same edge on the same inputs at the same instant, from ``sample`` to ``last_sample`` (equal
    for a single sample). A run of the full horizon mostly repeats one sample: at 90,000 samples, one
    entry per sample made a check's JSON 170 MB."""
    result: list[dict[str, object]] = []
    # a run repeats its samples: build each once
    shown: dict[tuple[int, int], tuple[dict[str, object], dict[str, str]]] = {}
    previous: tuple[object, ...] | None = None
    for step in worst.steps:
        o = step.outcome
        known = shown.get((o.cls, id(step.inputs)))
        if known is None:
            known = shown[o.cls, id(step.inputs)] = _json_inputs(space, o.cls, step.inputs)
        inputs, approached = known
        edge_line = o.edge.span.line if o.edge and o.edge.span else None
        alike = (o.source, o.target, edge_line, step.instant, inputs)  # what the entry shows
        if alike == previous and result[-1]["last_sample"] == step.sample - 1:
            result[-1]["last_sample"] = step.sample
            continue
        previous = alike
        result.append({
            "sample": step.sample,
            "last_sample": step.sample,
            "time": str(step.sample * automaton.period),
            "from": automaton.location_names[o.source],
            "to": automaton.location_names[o.target],
            "edge_line": edge_line,
            "inputs": dict(inputs),
            "approached": dict(approached),
            "instant": step.instant,
        })
    return result


def _reaches(space: InputSpace, worst: Worst) -> str:
    """``can reach`` when the worst run takes every input value its value needs; else ``comes arbitrarily
    close to`` (a guard cuts at a value it needs: the worst value is a supremum, approached by runs, and
    a violation all the same, since runs close enough to it violate too)."""
    # a run of the horizon mostly repeats one sample: each distinct one is looked at once
    distinct = {(step.outcome.cls, id(step.inputs)): step for step in worst.steps}.values()
    attained = all(space.attains(step.outcome.cls, name, value)
                   for step in distinct for name, value in step.inputs.items())
    if worst.end is not None:
        attained = attained and all(space.attains(worst.end.cls, name, value)
                                    for name, value in worst.end_inputs.items())
    return "can reach" if attained else "comes arbitrarily close to"


def _json_inputs(space: InputSpace, cls: int, values: Mapping[str, Fraction]
                 ) -> tuple[dict[str, object], dict[str, str]]:
    """A sample's inputs for JSON, each a value the run takes there (replayed, they drive the same
    run), and the values the worst run only approaches (``approached``: a guard cuts at the value
    its arithmetic needs, so the run's value is a supremum; the input is then the class's own
    representative)."""
    chosen = space.valuation(cls)
    approached: dict[str, str] = {}
    for name, value in values.items():
        if space.attains(cls, name, value):
            chosen[name] = value
        else:
            approached[name] = str(value)
    return {k: (v if isinstance(v, bool) else str(v)) for k, v in chosen.items()}, approached


def replayable_json(automaton: ir.Automaton, space: InputSpace, worst: Worst,
                    violates: Callable[[Worst], bool]) -> dict[str, object]:
    """``run`` (:func:`run_json`) and ``end`` (:func:`end_json`) of a violating ``worst`` run for a
    diagnostic's data, its inputs a run a user can replay: where the run only approaches an input's value
    (a supremum: a guard cuts there), that input's value is moved from its class's representative to
    as near the limit as the run needs to violate (``violates``, on the run replayed exactly): runs
    close enough to a supremum above the bound violate too, but the representative's need not
    (docs/checks.md). ``approached`` still names the limits."""
    (found,) = replayable_runs_json(automaton, space, [worst], lambda near: violates(near[0]))
    return found


def replayable_runs_json(automaton: ir.Automaton, space: InputSpace, worsts: Sequence[Worst],
                         holds: Callable[[list[Worst]], bool]) -> list[dict[str, object]]:
    """:func:`replayable_json` of runs a diagnostic compares (an incentive check's pair: the run that
    ends early and the best continuation, ...): ``run`` and ``end`` of each, their approached values
    moved alike (by the same fraction, so that a prefix the runs share stays shared) until ``holds``,
    on the runs replayed exactly, says the diagnostic's claim is true of them."""
    nears = _near_limits(space, worsts, holds)
    return [_moved_json(automaton, space, worst, near) for worst, near in zip(worsts, nears)]


def _moved_json(automaton: ir.Automaton, space: InputSpace, worst: Worst, near: Worst) -> dict[str, object]:
    """``run`` and ``end`` of ``near`` (``worst`` with its approached values moved), ``approached``
    naming the limits ``worst`` approaches."""
    run, end = run_json(automaton, space, worst), end_json(automaton, space, worst)
    if near is worst:
        return {"run": run, "end": end}
    limits = {k: entry["approached"] for entry in run
              for k in range(int(entry["sample"]), int(entry["last_sample"]) + 1)}  # type: ignore[call-overload]
    moved = run_json(automaton, space, near)
    for entry in moved:
        entry["approached"] = limits.get(int(entry["sample"]), {})  # type: ignore[call-overload]
    moved_end = end_json(automaton, space, near)
    if moved_end is not None and end is not None:
        moved_end["approached"] = end["approached"]
    return {"run": moved, "end": moved_end}


#: How near (a fraction 2**-k of the way from the representative) :func:`_near_limits` tries at most:
#: so at most this many exact replays of each run (a loophole's pair: 2 * 64), none where no value is
#: only approached.
NEAREST = 64


def _near_limits(space: InputSpace, worsts: Sequence[Worst], holds: Callable[[list[Worst]], bool]) -> list[Worst]:
    """``worsts`` with each input value they only approach moved into its class, a fraction 2**-k of
    the way from the value to the class's representative, for the first k (from 1) at which the runs
    still satisfy ``holds``; ``worsts`` themselves where they approach nothing (or no k up to
    :data:`NEAREST` does)."""
    def approaches(cls: int, values: Mapping[str, Fraction]) -> bool:
        return any(not space.attains(cls, name, value) for name, value in values.items())

    def ends(worst: Worst) -> bool:
        return worst.end is not None and worst.instant in (AFTER_END, MID_END)

    if not any(approaches(step.outcome.cls, step.inputs) for worst in worsts for step in worst.steps) and not any(
            ends(worst) and approaches(worst.end.cls, worst.end_inputs) for worst in worsts):  # type: ignore[union-attr]
        return list(worsts)

    def moved(cls: int, values: dict[str, Fraction], fraction: Fraction,
              shared: dict[tuple[int, int], dict[str, Fraction]]) -> dict[str, Fraction]:
        key = (cls, id(values))  # runs repeat their samples' inputs (and share a prefix's): move each once
        if key not in shared:
            inside = space.valuation(cls)
            shared[key] = {name: value if space.attains(cls, name, value) else
                           value + fraction * (inside[name] - value)  # type: ignore[operator]
                           for name, value in values.items()}
        return shared[key]

    for k in range(1, NEAREST + 1):
        fraction = Fraction(1, 2 ** k)
        shared: dict[tuple[int, int], dict[str, Fraction]] = {}
        nears = []
        for worst in worsts:
            steps = [dataclasses.replace(step, inputs=moved(step.outcome.cls, step.inputs, fraction, shared))
                     for step in worst.steps]
            end_inputs = (moved(worst.end.cls, worst.end_inputs, fraction, shared)  # type: ignore[union-attr]
                          if ends(worst) else worst.end_inputs)
            nears.append(dataclasses.replace(worst, steps=steps, end_inputs=end_inputs))
        if holds(nears):
            return nears
    return list(worsts)


def end_json(automaton: ir.Automaton, space: InputSpace, worst: Worst) -> dict[str, object] | None:
    """How the worst run ends (``at end`` clauses and the end's inputs), or None."""
    if worst.instant not in (AFTER_END, MID_END) or worst.end is None:
        return None
    inputs, approached = _json_inputs(space, worst.end.cls, worst.end_inputs)
    return {
        "time": str(worst.steps[-1].sample * automaton.period if worst.steps else 0),
        "clause_lines": [span.line if span else None
                         for span in (automaton.end_clauses[i].span for i in worst.end.ends)],
        "inputs": inputs,
        "approached": approached,
    }


def check_ranges(automaton: ir.Automaton, base: int = DEFAULT_BASE, exponent: int = DEFAULT_EXPONENT,
                 facts: list[Fact] | None = None, prepared: tuple[InputSpace, Moves] | None = None
                 ) -> list[Diagnostic]:
    """Every reward's significand trunc(v·base^exponent) stays within int32 over the horizon."""
    facts = facts if facts is not None else []
    extremes = []
    space, outs, problems = _prepared(automaton, prepared)
    if space is None or outs is None:
        return problems
    factor = Fraction(base) ** exponent
    unfinished: Unfinished | None = None  # a search stopped at its limit: no proof, unless another refutes
    # each reward's least and greatest value over every instant, in between updates too
    bounds: dict[str, list[Fraction]] = {reward: [ZERO, ZERO] for reward in automaton.rewards}
    for k, reward in enumerate(automaton.rewards):
        for sign in (1, -1):
            limit = range_limit(sign)

            def overflows(value: Fraction, limit: int = limit) -> bool:
                return value * factor >= limit

            prefix = False
            try:
                worst = maximise(automaton, outs, range_target(automaton, k, sign), run=overflows)
            except Unfinished as stop:
                worst = _refuted_within_limit(automaton, outs, range_target(automaton, k, sign), overflows)
                if worst is None:
                    unfinished = unfinished or stop
                    continue
                prefix = True
            if worst is None or worst.value * factor < limit:
                if worst is not None:
                    extremes.append(sign * worst.value)
                    bounds[reward][0 if sign < 0 else 1] = sign * worst.value
                continue
            bound = Fraction(limit - 1) / factor
            first = _first_overflow(automaton, space, worst, k, sign, bound)
            word = "at most" if sign > 0 else "at least"
            declared = automaton.spans.get(reward) or (automaton.source.name.span if automaton.source else None)
            notes: list[Note | str] = [
                f"its significand trunc({reward}·{base}^{exponent}) must stay {word} "
                f"{sign * (limit - 1)}, i.e. {reward} within [{show_number(Fraction(INT32_MIN) / factor)}, "
                f"{show_number(Fraction(INT32_MAX) / factor)}]",
                f"first overflow on the worst run: {first}",
                "run:\n" + "\n".join(describe_run(automaton, space, worst))]
            hints = ["lower the exponent of the number representation, shorten the horizon, "
                     "or bound the reward's growth"]
            data: dict[str, object] = {"reward": reward, "value": str(sign * worst.value), "base": base,
                                       "exponent": exponent}
            span = declared
            model = automaton.model
            if model is not None and (model.base, model.exponent) == (base, exponent):
                # The model block chose the representation: point at the setting to change.
                setting = automaton.spans.get("model:exponent") or automaton.spans.get("model:base")
                if setting is not None:
                    span = setting
                try:
                    hints = [_exponent_hint(_largest_magnitude(automaton, outs), base, exponent)]
                except Unfinished:
                    pass  # the general hint stays
            where = ""
            update = offending_update(automaton, worst)
            if update is not None and update.span is not None:
                # Not an instant of the semantics but a value inside a sequence of updates, which UPPAAL
                # stores: point at the assignment that leaves it.
                span = update.span
                sequence = "an edge's updates" if worst.instant == MID_EDGE else "the `at end` updates"
                where = f" in between {sequence}"
                notes.insert(0, Note(
                    f"an intermediate value, right after this update (update {worst.applied} of its sequence): "
                    f"UPPAAL runs a sequence of updates left to right and stores each assignment in `{reward}`'s "
                    "32-bit integer, so every value in between must fit, not only the sequence's result"))
                hints.insert(0, "reorder or merge the updates so that no value in between leaves the range "
                             "(e.g. `r += a - b` instead of `r += a, r -= b`)")
                data["update_line"] = update.span.line
                data["applied"] = worst.applied
            if span is not declared:
                notes.insert(1 if where else 0, Note(f"`{reward}` is declared here", declared))
            found = error(
                "E0501",
                f"reward `{reward}` overflows int32 at base {base}, exponent {exponent}{where}: "
                f"it {_reaches(space, worst)} {show_number(sign * worst.value)}",
                span,
                notes=notes,
                hints=hints,
                data=data)
            return [_cut_short(found, automaton) if prefix else found]
    if unfinished is not None:
        return [_unfinished(automaton, f"the int32 range at base {base}, exponent {exponent}", unfinished)]
    # Every value fits: so must what the UPPAAL model computes on the way to an update's value.
    ranges = {reward: (low, high) for reward, (low, high) in bounds.items()}
    inside = update_diagnostics(automaton, ranges) + observation_diagnostics(automaton, ranges)
    if inside:
        return inside
    if extremes:
        facts.append(Fact("range", f"int32 range holds at base {base}, exponent {exponent}: rewards stay within "
                               f"[{show_number(min(extremes))}, {show_number(max(extremes))}]",
                          {"base": base, "exponent": exponent, "low": str(min(extremes)), "high": str(max(extremes))}))
    return []


def _largest_magnitude(automaton: ir.Automaton, outs) -> Fraction:
    """The largest |value| any reward reaches over every run (both directions of every reward), in
    between an edge's updates too (what the range check bounds)."""
    largest = ZERO
    for k in range(len(automaton.rewards)):
        for sign in (1, -1):
            worst = maximise(automaton, outs, range_target(automaton, k, sign), run=False)
            if worst is not None:
                largest = max(largest, worst.value)
    return largest


def _exponent_hint(magnitude: Fraction, base: int, exponent: int) -> str:
    """Which exponent of the model block keeps every reward (at most ``magnitude`` away from 0) within int32."""
    # The positive side is the tighter one: trunc(v · scale) <= INT32_MAX.
    fits = [e for e in range(exponent - 1, 0, -1) if magnitude * Fraction(base) ** e < INT32_MAX + 1]
    if fits:
        return (f"set `exponent {fits[0]}` in the `model` block (the largest that fits), shorten the horizon, "
                "or bound the reward's growth")
    return f"even `exponent 1` overflows at base {base}: shorten the horizon, or bound the reward's growth"


def _first_overflow(automaton: ir.Automaton, space: InputSpace, worst: Worst, k: int, sign: int,
                    bound: Fraction) -> str:
    """The first instant of the worst run at which the reward leaves the int32 range."""
    for where, values in trace(automaton, space, worst, inside=True):
        if sign * values[k] > bound:
            return f"{where} ({automaton.rewards[k]} = {show_number(values[k])})"
    return f"at the end of the run ({automaton.rewards[k]} = {show_number(sign * worst.value)})"


def _linear_text(linear: ir.Linear) -> str:
    parts = [show_number(linear.const)] if linear.const or not linear.terms else []
    for name, coefficient in linear.terms:
        parts.append(f"{show_number(coefficient)}*{name}")
    return " + ".join(parts)


def show_number(value: Fraction) -> str:
    """A value as a check's message shows it: exact where that is short, else rounded (marked ``…``)."""
    # exact up to 30 digits (a proved bound is read as written); beyond, 3e302… (`…` marks the
    # rounding) rather than 303 digits nobody reads
    if value.denominator == 1 and abs(value.numerator) < 10**30:
        return str(value.numerator)
    if value.denominator == 1 or not Fraction(1, 10**300) < abs(value) < 10**300:
        return short_number(value)
    text = f"{float(value):.10g}"
    if Fraction(text) == value:
        return text
    # a long decimal (-10000099.998 after 100,000 samples of 1 ms), not -5000049999/500
    return exact_decimal(value, max_places=12) or f"{value.numerator}/{value.denominator}"
