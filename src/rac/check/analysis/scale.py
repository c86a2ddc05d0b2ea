"""How much the objective can change within one sample: the proven scale of a learner's reward.

A learner trains best on rewards in [-1, 1]; dividing every reward by a positive factor keeps the
priority proofs (they compare signs and orders of the objective, which a positive factor keeps).
:func:`sample_change_bound` proves the factor from the automaton alone, in exact arithmetic:

- ``per_sample``: the largest ``|objective after - objective before|`` over one sample taken in any
  location a run can reach (the horizon aside: an environment may run longer than it), the held
  inputs (which the accrual reads) and the new inputs (which the edge reads) each ranging over every
  valuation ``assume`` allows: the accrual ``period * rate`` plus the change made by the edge that
  fires (its guard and the edges before it decide which inputs reach it);
- ``at_end``: the largest ``|change|`` made by the ``at end`` clauses, over every end valuation.

A translation (``r = r + c + d*x``) changes the objective by an amount that depends on the inputs
only, so its bound is exact. An update that scales or resets a reward (``r = 0``) changes it by an
amount that depends on the rewards' current values: those are bounded by the reward ranges the
worst-run search proves (the int32 range check's question,
:func:`rac.check.analysis.priority.range_target`), so the bound is sound for runs within the
horizon, which those ranges cover, but may not be attained. When that search cannot finish,
:class:`ScaleUnproven` says why.
"""

from __future__ import annotations

from dataclasses import dataclass
from fractions import Fraction

from rac import ir
from rac.check.analysis.affine import Affine, Moves, moves, sup_linear
from rac.check.analysis.behaviour import input_space
from rac.check.analysis.priority import range_target
from rac.check.analysis.worst import Unfinished, maximise
from rac.core.diagnostics import RacError
from rac.ir.inputs import Piece

__all__ = ["SampleChange", "ScaleUnproven", "sample_change_bound"]

ZERO = Fraction(0)
_Box = tuple[tuple[str, Piece], ...]


class ScaleUnproven(RacError, ValueError):
    """No bound on the objective's change per sample could be proved; the message says why."""


@dataclass(frozen=True)
class SampleChange:
    """Proven bounds on ``|objective increase|``: over one sample, and by the ``at end`` clauses."""

    per_sample: Fraction
    at_end: Fraction

    def step_bound(self, samples: int = 1) -> Fraction:
        """The largest ``|reward|`` of a step of ``samples`` samples that may end the run:
        ``samples * per_sample + at_end`` (e.g. ScenarioEnv's step of ``decide_every`` samples)."""
        if samples < 1:
            raise ValueError(f"a step takes at least one sample, not {samples}")
        return samples * self.per_sample + self.at_end


def _range(form: dict[str, Fraction], box: _Box) -> tuple[Fraction, Fraction]:
    """(inf, sup) of ``Σ form[x]·x`` over a box's closure (inputs the box leaves out must not appear)."""
    names = {name for name, _ in box}
    missing = [name for name, coefficient in form.items() if coefficient and name not in names]
    assert not missing, missing  # arithmetic_inputs() covers every input a rate or update reads
    high, _ = sup_linear(form, box)
    low, _ = sup_linear({name: -c for name, c in form.items()}, box)
    return -low, high


def _weighted(offsets: tuple[ir.Linear, ...], weights: tuple[Fraction, ...]) -> tuple[Fraction, dict[str, Fraction]]:
    """``Σ w_k·offset_k`` as (constant, {input: coefficient})."""
    const = ZERO
    form: dict[str, Fraction] = {}
    for w, offset in zip(weights, offsets):
        if not w:
            continue
        const += w * offset.const
        for name, coefficient in offset.terms:
            form[name] = form.get(name, ZERO) + w * coefficient
    return const, form


class _Ranges:
    """The proven range of every reward over every instant of every run, searched on first need."""

    def __init__(self, automaton: ir.Automaton, outs: Moves) -> None:
        self._automaton, self._outs = automaton, outs
        self._found: list[tuple[Fraction, Fraction]] | None = None

    def get(self) -> list[tuple[Fraction, Fraction]]:
        if self._found is None:
            found = []
            for k, reward in enumerate(self._automaton.rewards):
                ends = []
                for sign in (1, -1):
                    try:
                        # the values a map starts from: instants of the semantics, none inside an update sequence
                        worst = maximise(self._automaton, self._outs,
                                         range_target(self._automaton, k, sign, intermediates=False), run=False)
                    except Unfinished as stop:
                        raise ScaleUnproven(f"an update scales or resets reward `{reward}`, so its change depends on "
                                            f"the reward's value, and its range could not be proved: {stop.reason}"
                                            ) from None
                    ends.append(ZERO if worst is None else sign * worst.value)
                found.append((ends[1], ends[0]))
            self._found = found
        return self._found


def _map_change(affine: Affine, weights: tuple[Fraction, ...], box: _Box,
                ranges: _Ranges) -> tuple[Fraction, Fraction]:
    """(inf, sup) of ``w·affine(r, x) - w·r``: exact over the box for a translation; else with ``r``
    over the proven reward ranges (sound, not always attained)."""
    const, form = _weighted(affine.offset, weights)
    low, high = _range(form, box)
    low, high = low + const, high + const
    if affine.matrix is not None:
        size = len(weights)
        # w·M r - w·r = Σ_j (Σ_k w_k M_kj - w_j) r_j, each r_j within its proven range
        for j, (r_low, r_high) in enumerate(ranges.get()):
            g = sum((weights[k] * affine.matrix[k][j] for k in range(size)), ZERO) - weights[j]
            low += g * (r_low if g > 0 else r_high)
            high += g * (r_high if g > 0 else r_low)
    return low, high


def _reached(automaton: ir.Automaton, outs: Moves) -> list[int]:
    """Locations some run reaches, the horizon aside (an environment may run longer), following the
    edges that actually fire (an edge always shadowed by an earlier one leads nowhere)."""
    seen = {automaton.initial}
    todo = [automaton.initial]
    while todo:
        for outcome in outs.samples[todo.pop()]:
            if outcome.target not in seen:
                seen.add(outcome.target)
                todo.append(outcome.target)
    return sorted(seen)


def sample_change_bound(automaton: ir.Automaton) -> SampleChange:
    """Prove the largest change of the objective within one sample and by the ``at end`` clauses.

    Raises :class:`ScaleUnproven` when the input space is too large for the exact analyses, or when
    an update's change depends on a reward whose range cannot be proved (see the module docstring).
    """
    space, problems = input_space(automaton)
    if space is None:
        raise ScaleUnproven(problems[0].message if problems else "the input space could not be built")
    outs = moves(automaton, space)
    ranges = _Ranges(automaton, outs)
    weights = tuple(automaton.objective.coefficient(r) for r in automaton.rewards)
    # The held inputs are an earlier sample's (any valuation assume allows: the end outcomes' boxes
    # cover every allowed class, and the accrual reads the same inputs as any update).
    held_boxes = [end.box for end in outs.ends]
    per_sample = ZERO
    for index in _reached(automaton, outs):
        location = automaton.locations[index]
        const, form = _weighted(tuple(rate.scaled(automaton.period) for rate in location.rates), weights)
        accrued = [_range(form, box) for box in held_boxes]
        if not accrued:
            break  # assume allows no valuation: no sample is ever taken
        accrual_low = const + min(low for low, _ in accrued)
        accrual_high = const + max(high for _, high in accrued)
        for outcome in outs.samples[index]:
            low, high = _map_change(outcome.edge_map, weights, outcome.box, ranges)
            per_sample = max(per_sample, accrual_high + high, -(accrual_low + low))
    at_end = ZERO
    for end in outs.ends:
        low, high = _map_change(end.end_map, weights, end.box, ranges)
        at_end = max(at_end, high, -low)
    return SampleChange(per_sample, at_end)
