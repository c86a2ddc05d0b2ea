"""P2 for the discounted return: what a learner with a discount ``gamma < 1`` maximises.

``rac check`` proves P2 (no compensation) of the objective's value, the rewards' plain sum. A learner
such as stable-baselines3's maximises the *discounted* return instead: the reward of its ``j``-th
step counts ``gamma**(j-1)``, so gains early can outweigh a penalty late, and the priority order the
proof covers may not hold for what it learns. This module checks P2 of the discounted value: on
every run within the horizon, at every instant the automaton is in a location that penalises the
highest-priority objective (every level under ``priority strict``), ``constant + sum over the
learner's steps of gamma**(j-1) * (the step's change of the weighted rewards) <= 0``.

A learner's step may span several samples (:class:`Discount`'s ``samples_per_step``: a
:class:`~rac.learning.scenario_env.ScenarioEnv` step is a decision period); the reward of a step is
the objective's change from the end of the step before to the end of its last sample, so the
accrual between two samples counts with the later sample's step. The instants watched are P2's (just
after a sample's edge, after the ``at end`` updates of a run that ends there, just before the next
sample), so with ``gamma = 1`` the check is P2 itself, to the last digit (the tests compare them).

The search is :func:`rac.check.analysis.worst.maximise_translations`' backward max-plus recurrence
with each sample's offsets weighted by its step's discount, exact (integers scaled by the powers of
gamma's denominator); automata whose updates scale a reward (``sa = sa * 2``) are not covered (the
discounted value is then no function of the rewards alone), and horizons beyond
:data:`MAX_DISCOUNTED_SAMPLES` samples or gammas whose powers would carry more than
:data:`MAX_DISCOUNT_DIGITS` digits are not searched: each is reported as a check not made (W0405), never
as a proof.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence
from dataclasses import dataclass
from decimal import ROUND_CEILING, Context, Decimal
from fractions import Fraction

from rac import ir
from rac.check.analysis.affine import Affine, EndOutcome, Moves, Outcome, accrual, moves, sup_weighted
from rac.check.analysis.behaviour import input_space
from rac.check.analysis.priority import (
    describe_run,
    p2_levels,
    p2_target,
    replay,
    replayable_json,
    show_number,
    trace,
)
from rac.check.analysis.worst import (
    AFTER_EDGE,
    AFTER_END,
    BEFORE_EDGE,
    BEFORE_NEXT,
    CONTINUE,
    Step,
    Target,
    Unfinished,
    Worst,
)
from rac.core.diagnostics import UNFINISHED, Diagnostic, Fact, Note, error, short_number, warning
from rac.core.numbers import exact_decimal
from rac.ir.inputs import InputSpace

__all__ = ["DISCOUNTED_P2", "Discount", "MAX_DISCOUNTED_SAMPLES", "MAX_DISCOUNT_DIGITS", "check_discounted",
           "discounted_value", "discounted_worst", "exact_text", "gamma_text", "upper_text"]

#: The diagnostic of a discounted return that compensates a penalty (P2 fails for it).
DISCOUNTED_P2 = "E0410"

#: The most samples the discounted search goes through: its values are exact rationals whose
#: denominators grow with ``gamma``'s powers (0.99 over 10,000 samples: 20,000 digits), and, unlike
#: the undiscounted search, it cannot stop early when the values settle (each sample weighs less).
MAX_DISCOUNTED_SAMPLES = 20_000

#: The most digits gamma's powers may carry over the horizon's steps (the denominator's digits times the
#: steps): each sample's arithmetic is on numbers that long (20,000 samples of 0.99: 40,000 digits, 1.3 s;
#: of 0.9966666666666667, a float's 1 - 1/300: 320,000 digits, 19 s).
MAX_DISCOUNT_DIGITS = 200_000

#: The discounts the hint of E0410 tries, nearest first (the first above the one asked that holds is
#: named), on horizons of at most MAX_HINTED_SAMPLES samples.
HINTED = (Fraction(99, 100), Fraction(995, 1000), Fraction(999, 1000), Fraction(9999, 10000))
MAX_HINTED_SAMPLES = 5_000

ZERO = Fraction(0)
ONE = Fraction(1)


@dataclass(frozen=True)
class Discount:
    """A learner's discount: ``gamma`` per step, a step being ``samples_per_step`` samples."""

    gamma: Fraction
    samples_per_step: int = 1

    def __post_init__(self) -> None:
        if not ZERO < self.gamma <= ONE:
            raise ValueError(f"a discount lies in (0, 1], not {self.gamma}")
        if self.samples_per_step < 1:
            raise ValueError(f"a step spans at least one sample, not {self.samples_per_step}")

    def weight(self, sample: int) -> Fraction:
        """What the objective's change at ``sample`` (1-based) counts in the discounted return."""
        return self.gamma ** ((sample - 1) // self.samples_per_step)

    def ratio(self, sample: int) -> Fraction:
        """``weight(sample + 1) / weight(sample)``: gamma where the next sample begins a step, else 1."""
        return self.gamma if sample % self.samples_per_step == 0 else ONE

    def describe(self) -> str:
        """``gamma = 0.99 per step of 1 sample``: how the messages name it."""
        samples = "1 sample" if self.samples_per_step == 1 else f"{self.samples_per_step} samples"
        return f"gamma = {gamma_text(self.gamma)} per step of {samples}"


def upper_text(value: Fraction) -> str:
    """A proved upper bound as a fact writes it: exact where short, else rounded *up* to 6 digits and
    marked ``…`` (rounded to nearest, -184.9466 would read -184.947, below the value it bounds)."""
    text = short_number(value)
    if not text.endswith("…"):
        return text
    up = Context(prec=6, rounding=ROUND_CEILING).divide(Decimal(value.numerator), Decimal(value.denominator))
    return str(up.normalize()).replace("E+", "e").replace("E", "e") + "…"


def gamma_text(gamma: Fraction) -> str:
    """A discount as a message writes it: exactly where it is a decimal of up to 20 places (0.9, and a
    float's 0.9966666666666667), else rounded and marked (1/3: 0.333333333333…)."""
    return exact_decimal(gamma, max_places=20) or short_number(gamma, 12)


def exact_text(value: Fraction) -> str:
    """``value`` for ``--format json``: exact (``numerator/denominator``) where Python writes it out, else
    rounded to 40 digits and marked ``…`` (gamma's powers make denominators of thousands of digits,
    beyond what Python converts to text)."""
    try:
        return str(value)
    except ValueError:  # more than sys.get_int_max_str_digits() digits
        return short_number(value, 40)


def _sup(w: tuple[Fraction, ...], parts: Sequence[tuple[Fraction, Affine]],
         box: tuple) -> tuple[Fraction, dict[str, Fraction]]:
    """:func:`~rac.check.analysis.affine.sup_weighted` of ``parts``' maps, each weighed by its factor."""
    return sup_weighted(w, [affine for _, affine in parts], box, [factor for factor, _ in parts])


@dataclass
class _Row:
    """One outcome's values relative to its sample's weight, for the ratio ``rho`` of the next sample's."""

    stop: Fraction | None  # the best watched instant of the sample (None: its target is not watched)
    instant: str  # which instant attains ``stop``
    stop_point: dict[str, Fraction]
    next: Fraction  # the sample's offsets and the accrual after it (what a continuing run adds)
    next_point: dict[str, Fraction]


class _Rows:
    """Per outcome and ratio ``rho`` (and for the first sample, whose accrual before the edge reads its
    inputs): the values the recurrence weighs by the sample's discount."""

    def __init__(self, automaton: ir.Automaton, target: Target,
                 end: tuple[Fraction, EndOutcome, dict[str, Fraction]] | None) -> None:
        self.automaton, self.target, self.end = automaton, target, end
        self.accruals = [accrual(loc, automaton.period) for loc in automaton.locations]
        self.cache: dict[tuple[int, Fraction, bool, bool], _Row] = {}

    def row(self, o: Outcome, rho: Fraction, first: bool, last: bool) -> _Row:
        key = (id(o), rho, first, last)
        found = self.cache.get(key)
        if found is None:
            found = self.cache[key] = self._row(o, rho, first, last)
        return found

    def _row(self, o: Outcome, rho: Fraction, first: bool, last: bool) -> _Row:
        w = self.target.weights
        before = ((ONE, self.accruals[self.automaton.initial]),) if first else ()
        nxt, next_point = _sup(w, (*before, (ONE, o.edge_map), (rho, self.accruals[o.target])), o.box)
        options: list[tuple[Fraction, str, dict[str, Fraction]]] = []
        if self.target.watched[o.target]:
            edge, edge_point = _sup(w, (*before, (ONE, o.edge_map)), o.box)
            options.append((edge, AFTER_EDGE, edge_point))
            if o.ends_episode:  # the run ends here, with this sample's own end clauses and nothing after
                if o.ending is not None and o.ending.ends:
                    value, point = _sup(w, (*before, (ONE, o.edge_map), (ONE, o.ending.end_map)), o.box)
                    options.append((value, AFTER_END, point))
            else:
                if self.end is not None and self.end[0] > 0:  # the run ends here, on inputs of its own
                    options.append((edge + self.end[0], AFTER_END, edge_point))
                if not last:
                    options.append((nxt, BEFORE_NEXT, next_point))
        if not options:
            return _Row(None, CONTINUE, {}, nxt, next_point)
        value, instant, point = max(options, key=lambda item: item[0])  # the first of equals: P2's order
        return _Row(value, instant, point, nxt, next_point)


def discounted_worst(automaton: ir.Automaton, moves: Moves, target: Target, discount: Discount) -> Worst | None:
    """The largest discounted value of ``target`` over the instants it watches, and a run reaching it
    (None when no watched instant is reachable); raises :class:`Unfinished` where the search does not go
    (updates that scale a reward, a horizon beyond :data:`MAX_DISCOUNTED_SAMPLES`)."""
    if not moves.translations_only:
        raise Unfinished("an update scales a reward (as `sa = sa * 2`), and the discounted check covers "
                         "translations (`sa = sa - 100`) only")
    steps = automaton.steps
    if steps > MAX_DISCOUNTED_SAMPLES:
        raise Unfinished(f"the horizon has {steps:,} samples, more than the {MAX_DISCOUNTED_SAMPLES:,} the "
                         "discounted search goes through")
    last_step = (steps - 1) // discount.samples_per_step
    digits = int(last_step * math.log10(discount.gamma.denominator)) if last_step else 0
    if digits > MAX_DISCOUNT_DIGITS:
        raise Unfinished(f"gamma = {gamma_text(discount.gamma)} is a fraction whose denominator has "
                         f"{len(str(discount.gamma.denominator))} digits: its powers over the {last_step:,} steps "
                         f"would carry {digits:,} digits, more than the {MAX_DISCOUNT_DIGITS:,} the exact search "
                         "works with (a gamma of fewer digits, as 0.997 for 0.9966666666666667, is checked)")
    w, w0, l0 = target.weights, target.constant, automaton.initial
    outs = moves.samples
    ends = [(_sup(w, ((ONE, e.end_map),), e.box), e) for e in moves.ends]
    end = None
    if ends:
        (k_end, end_point), best_end = max(ends, key=lambda item: item[0][0])
        end = (k_end, best_end, end_point)
    rows = _Rows(automaton, target, end)
    start: Worst | None = None
    if target.watched[l0]:  # t = 0, before any sample: the constant, or the end there
        start = Worst(w0)
        if end is not None and w0 + end[0] > w0:
            start = Worst(w0 + end[0], [], AFTER_END, end[1], end[2])
    # Exact and fast: every value times S = L * q**J (gamma = p/q, J the last step's index, L the
    # common denominator of the rows) is an integer, and sample k's weight gamma**j times S is
    # L * p**j * q**(J-j); Fractions of gamma's powers cost a gcd per operation (3,000 samples: 34 s).
    p, q = discount.gamma.numerator, discount.gamma.denominator
    ratios = {ONE, discount.gamma}
    table = {(id(o), rho, first, last): rows.row(o, rho, first, last)
             for here, os in enumerate(outs) for o in os for rho in ratios
             for first in ((False, True) if here == l0 else (False,)) for last in (False, True)}
    before = [_sup(w, ((ONE, rows.accruals[l0]),), o.box)[0] for o in outs[l0]]
    fractions = [w0, *before] + [v for row in table.values() for v in (row.stop, row.next) if v is not None]
    scale = math.lcm(*(v.denominator for v in fractions))
    scaled = {key: (None if row.stop is None else int(row.stop * scale), int(row.next * scale))
              for key, row in table.items()}
    # value[l]: the most a run adds from just before sample k's edge in l (None: no watched instant ahead)
    value: list[int | None] = [None] * len(automaton.locations)
    choice: dict[int, list[tuple[int, bool]]] = {}
    step, weight = last_step, p ** last_step  # L * p**j * q**(J-j) / L, for the step j of sample k
    for k in range(steps, 1, -1):
        j = (k - 1) // discount.samples_per_step
        while step > j:  # one step back: a factor p less, a factor q more (exact: p**step divides it)
            step, weight = step - 1, weight // p * q
        rho = discount.ratio(k)
        new: list[int | None] = []
        picks: list[tuple[int, bool]] = []
        for os in outs:
            best: int | None = None
            pick = (-1, False)
            for oi, o in enumerate(os):
                stop_value, next_value = scaled[id(o), rho, False, k == steps]
                if stop_value is not None and (best is None or weight * stop_value > best):
                    best, pick = weight * stop_value, (oi, True)
                ahead = value[o.target]
                if k < steps and not o.ends_episode and ahead is not None:
                    cont = weight * next_value + ahead
                    if best is None or cont > best:
                        best, pick = cont, (oi, False)
            new.append(best)
            picks.append(pick)
        value = new
        choice[k] = picks
    # Sample 1, from the initial location only (weight 1, q**J scaled): the accrual before its edge reads
    # its inputs.
    while step > 0:
        step, weight = step - 1, weight // p * q
    rho = discount.ratio(1)
    base = int(w0 * scale) * weight
    best_scaled: int | None = None
    first: tuple[int, str] | None = None
    for oi, o in enumerate(outs[l0]):
        stop_value, next_value = scaled[id(o), rho, True, steps == 1]
        options: list[tuple[int, str]] = []
        if stop_value is not None:
            options.append((base + weight * stop_value, "stop"))
        if target.watched[l0]:
            options.append((base + weight * int(before[oi] * scale), BEFORE_EDGE))
        ahead = value[o.target]
        if steps > 1 and not o.ends_episode and ahead is not None:
            options.append((base + weight * next_value + ahead, CONTINUE))
        for v, instant in options:
            if best_scaled is None or v > best_scaled:
                best_scaled, first = v, (oi, instant)
    if best_scaled is None or first is None:
        return start
    best_value = Fraction(best_scaled, scale * weight)
    if start is not None and start.value >= best_value:
        return start
    result = Worst(best_value)
    oi, instant = first
    here, k = l0, 1
    while True:
        o = outs[here][oi]
        row = rows.row(o, discount.ratio(k), k == 1, k == steps)
        if instant == BEFORE_EDGE:
            point = _sup(w, ((ONE, rows.accruals[l0]),), o.box)[1]
        elif instant == "stop":
            instant, point = row.instant, row.stop_point
        else:
            point = row.next_point
        if instant == AFTER_END:
            if o.ends_episode:
                result.end, result.end_inputs = o.ending, point
            else:
                assert end is not None
                result.end, result.end_inputs = end[1], end[2]  # type: ignore[assignment]
        result.steps.append(Step(k, o, point, instant))
        if instant != CONTINUE:
            result.instant = instant
            return result
        here, k = o.target, k + 1
        oi, stopped = choice[k][here]
        instant = "stop" if stopped else CONTINUE


def discounted_value(automaton: ir.Automaton, space: InputSpace, worst: Worst, target: Target,
                     discount: Discount) -> Fraction:
    """The discounted value of ``target`` at the instant ``worst`` ends, by replaying its run exactly
    (the search's answer, recomputed the long way: the tests compare the two)."""
    total, previous = target.constant, [ZERO] * len(automaton.rewards)
    weights = target.weights
    step, weight = 0, ONE  # the step of the instant's sample, and its discount (the instants come in time order)
    for when, values in trace(automaton, space, worst):
        # an instant at time t belongs to the sample at or after t: the accrual before a sample is its step's
        sample = max(1, math.ceil(when.time / automaton.period))  # type: ignore[attr-defined]
        while step < (sample - 1) // discount.samples_per_step:
            step, weight = step + 1, weight * discount.gamma
        change = sum((wk * (v - p) for wk, v, p in zip(weights, values, previous)), ZERO)
        total += weight * change
        previous = list(values)
    return total


def check_discounted(automaton: ir.Automaton, discount: Discount, facts: list[Fact] | None = None,
                     prepared: tuple[InputSpace, Moves] | None = None) -> list[Diagnostic]:
    """P2 of the discounted return at every level P2 checks (:func:`~rac.check.analysis.priority.p2_levels`):
    E0410 with a counterexample where it fails, W0405 where the search does not go, else a fact."""
    facts = facts if facts is not None else []
    if not automaton.priority:
        return []
    if prepared is None:
        space, problems = input_space(automaton)
        if space is None:
            return problems
        prepared = (space, moves(automaton, space))
    space, outs = prepared
    found: list[Diagnostic] = []
    for level in p2_levels(automaton):
        reward = automaton.priority[level]
        target = p2_target(automaton, level)
        if not any(target.watched):
            continue
        try:
            worst = discounted_worst(automaton, outs, target, discount)
        except Unfinished as stop:
            found.append(warning(
                UNFINISHED, f"P2 for `{reward}` under the discount ({discount.describe()}) not checked: {stop.reason}",
                automaton.spans.get("decl:priority"),
                notes=["rac check proves P2 of the undiscounted return; what a learner with this discount "
                       "maximises is not covered"],
                # named as E0410's and the fact's: "P2" alone is E0402's, the undiscounted check
                data={"property": "P2-discounted", "reward": reward, "gamma": exact_text(discount.gamma),
                      "samples_per_step": discount.samples_per_step}))
            continue
        if worst is None or worst.value <= 0:
            bound = "" if worst is None else f": the discounted value stays <= {upper_text(worst.value)}"
            facts.append(Fact("P2-discounted", f"P2 holds for `{reward}` under the discount "
                              f"({discount.describe()}){bound} over every run of {show_number(automaton.horizon)} s",
                              {"reward": reward, "gamma": exact_text(discount.gamma),
                               "samples_per_step": discount.samples_per_step,
                               "bound": None if worst is None else exact_text(worst.value)}))
            continue
        found.append(_error(automaton, prepared, worst, level, target, discount))
    return found


def _error(automaton: ir.Automaton, prepared: tuple[InputSpace, Moves], worst: Worst, level: int, target: Target,
           discount: Discount) -> Diagnostic:
    space, outs = prepared
    reward = automaton.priority[level]
    values, where = replay(automaton, space, worst)
    plain = sum((wk * v for wk, v in zip(target.weights, values)), target.constant)
    scope = "the objective" if level == 0 else "the weighted sum from `" + reward + "` down"
    last = worst.steps[-1].sample if worst.steps else 0
    # just before the next sample, the accrual since the last is the next sample's step's reward
    at = last + 1 if worst.instant == BEFORE_NEXT else last
    step = (at - 1) // discount.samples_per_step + 1 if at else 0
    notes = [
        Note(f"counterexample (sample every {show_number(automaton.period)} s, horizon "
             f"{show_number(automaton.horizon)} s):\n" + "\n".join(describe_run(automaton, space, worst))),
        Note(f"at the violating instant ({where}), in the learner's step {step}: {scope} is "
             f"{show_number(plain)} undiscounted, {short_number(worst.value)} discounted"),
        Note("a learner maximising the discounted return (stable-baselines3's `gamma`, 0.99 by default) "
             f"counts the reward of its step j by gamma**(j-1) (here {short_number(discount.weight(at or 1))} "
             "at that step): gains early outweigh the penalty late, which the priority order rules out for the "
             "plain return only"),
    ]
    # the nearest usual gamma above that would do, where a search costs little (5,000 samples: about 0.5 s)
    candidates = HINTED if automaton.steps <= MAX_HINTED_SAMPLES else ()
    better = next((g for g in candidates
                   if g > discount.gamma and _holds(automaton, outs, dataclasses.replace(discount, gamma=g))),
                  None)
    hints = []
    if better is not None:
        # the command checks what this error is about: the same steps (per sample, it may fail again)
        option = f" --samples-per-step {discount.samples_per_step}" if discount.samples_per_step > 1 else ""
        hints.append(f"with gamma = {gamma_text(better)} it holds (rac check --discount "
                     f"{gamma_text(better)}{option}); or penalise `{reward}` more, or earlier")
    else:
        hints.append(f"train with a gamma nearer 1, or penalise `{reward}` more, or earlier (a penalty at the "
                     "end counts gamma**steps of one at the start)")
    return error(
        DISCOUNTED_P2,
        f"P2 no compensation fails for the discounted return ({discount.describe()}): while `{reward}` is "
        f"penalised, {scope}, discounted, can reach {short_number(worst.value)}",
        automaton.spans.get("decl:priority"),
        notes=notes,
        hints=hints,
        data={"property": "P2-discounted", "level": level, "reward": reward, "value": exact_text(worst.value),
              "undiscounted": exact_text(plain), "gamma": exact_text(discount.gamma),
              "samples_per_step": discount.samples_per_step,
              **replayable_json(automaton, space, worst,
                                lambda near: discounted_value(automaton, space, near, target, discount) > 0)})


def _holds(automaton: ir.Automaton, outs: Moves, discount: Discount) -> bool:
    """Whether P2 holds under ``discount`` at every level it checks (False where the search does not go):
    a hint's gamma must not fail another level (under ``priority strict``; the check is not monotone in
    gamma)."""
    for level in p2_levels(automaton):
        target = p2_target(automaton, level)
        if not any(target.watched):
            continue
        try:
            worst = discounted_worst(automaton, outs, target, discount)
        except Unfinished:
            return False
        if worst is not None and worst.value > 0:
            return False
    return True
