"""Run a checked reward automaton in process: one at a time, or thousands at once with numpy.

:class:`RewardAutomaton` interprets an :class:`rac.ir.Automaton` sample by sample;
:class:`rac.runtime.batch.BatchRewardAutomaton` (``RewardAutomaton.batch(n)``) steps ``n`` independent copies
at once. Both follow the runtime semantics below to the bit, and so does the standalone
module of :mod:`rac.targets.python`; the agreement tests hold all three to it.

One ``step(inputs)`` (one sample):

1. the inputs are validated: every declared input present, nothing else; booleans via
   ``True``/``False`` or 0/1 (:func:`rac.runtime.semantics.boolean_input`); numbers are real numbers
   (not strings, complex numbers or sequences), read via ``float(v)``, finite and within their
   bounds (compared with the bounds as floats); ``int`` inputs integral. Then every ``assume`` must hold on them.
   A violation raises :class:`ValueError` and leaves the automaton untouched; for an ``assume``, the
   message names the first clause violated, in source order (:class:`rac.runtime.semantics.AssumeCheck`).
2. every reward grows by its rate in the current location times the period
   (``rate.scaled(period)`` rounded to floats), evaluated on the inputs held from the previous
   sample (the current ones at the first sample after a reset);
3. the first edge of the current location whose guard holds on the new inputs is taken: its
   updates are applied left to right, then the location changes. No enabled edge: stay;
4. with ``episode ends when COND``: if COND holds on the new inputs, the run ends here: every end
   clause whose guard holds on those inputs is applied, in order, and :attr:`~RewardAutomaton.terminated`
   becomes true (:attr:`rac.ir.Automaton.ending`);
5. the sample counter advances and the reward handed out is ``objective - previous objective``
   (the end clauses' increase included).

A linear form ``c0 + c1*v1 + ... + ck*vk`` is always evaluated as
``((float(c0) + float(c1)*v1) + ...) + float(ck)*vk``; guard atoms compare the input with
``float(threshold)``, exactly for the number the float stands for (:func:`rac.runtime.semantics.float_atoms`).
``end(inputs)`` validates, checks ``assume``, applies every end clause
whose guard holds (in order), ends the run and returns the objective's increase; ``step`` and
``end`` then raise :class:`RuntimeError` until :meth:`~RewardAutomaton.reset`. After a run that
its condition ended (``terminated``), ``step`` raises the same, while ``end`` returns 0.0 and
changes nothing (the end clauses were applied at that sample; nothing is read).
"""
from __future__ import annotations

import math
import operator
from collections.abc import Callable, Mapping, Sequence
from fractions import Fraction
from typing import TYPE_CHECKING, Any

from rac import ir
from rac.runtime.batch import BatchRewardAutomaton
from rac.runtime.semantics import (
    ENDED_MESSAGE,
    AutomatonDescription,
    FloatAtom,
    FloatLinear,
    assume_checks,
    boolean_input,
    check_automaton,
    check_mapping,
    clip_inputs,
    float_atoms,
    float_linear,
    input_specs,
    key_error,
    number_input,
    range_error,
)

if TYPE_CHECKING:
    from rac.runtime.batch import BatchRewardAutomaton

__all__ = ["RewardAutomaton"]

_OPS: dict[str, Callable[[Any, Any], Any]] = {
    "<": operator.lt,
    "<=": operator.le,
    ">": operator.gt,
    ">=": operator.ge,
    "==": operator.eq,
    "!=": operator.ne,
}


#: What a run changes (pickled with the IR; everything else is compiled from the IR).
_RUN_STATE = ("_loc", "_r", "_held", "_samples", "_ended", "_terminated", "_objective", "clipped")
# what RewardAutomaton.__init__ builds from the IR (closures pickle cannot carry): rebuilt on load, not pickled;
# any other attribute is a subclass's own and travels with the pickle
_BUILT = ("_ir", "_specs", "_names", "_period", "_rates", "_edges", "_end_clauses", "_episode_ends", "_assume",
          "_objective_fn", "_initial_objective")

_Values = dict[str, Any]
_LinearFn = Callable[[list[float], _Values], float]
_GuardFn = Callable[[_Values], bool]


def _compile_linear(form: FloatLinear, reward_index: Mapping[str, int]) -> _LinearFn:
    const, terms = form
    compiled = tuple((coef, reward_index.get(name, -1), name) for coef, name in terms)

    def evaluate(r: list[float], x: _Values) -> float:
        acc = const
        for coef, index, name in compiled:
            acc = acc + coef * (r[index] if index >= 0 else x[name])
        return acc

    return evaluate


def _guard_const(value: bool) -> _GuardFn:
    value = bool(value)
    return lambda x: value


def _guard_input(leaf: ir.BInput) -> _GuardFn:
    name = leaf.name
    return lambda x: x[name]


def _guard_atom(compared: FloatAtom, name: str) -> _GuardFn:
    if isinstance(compared, bool):  # `x == 1/3`: no float stands for 1/3 unless it is a number of x
        return _guard_const(compared)
    op, threshold = _OPS[compared[0]], compared[1]
    return lambda x: op(x[name], threshold)


def _guard_not(inner: _GuardFn) -> _GuardFn:
    return lambda x: not inner(x)


def _guard_and(parts: tuple[_GuardFn, ...]) -> _GuardFn:
    if len(parts) == 2:  # the common case without a generator: a step evaluates guards often
        a, b = parts
        return lambda x: a(x) and b(x)
    return lambda x: all(p(x) for p in parts)


def _guard_or(parts: tuple[_GuardFn, ...]) -> _GuardFn:
    if len(parts) == 2:
        a, b = parts
        return lambda x: a(x) or b(x)
    return lambda x: any(p(x) for p in parts)


def _guard_compiler(automaton: ir.Automaton) -> ir.GuardFold[_GuardFn]:
    """Compiles a guard of ``automaton`` into one closure over the inputs (Python's ``and``/``or``: the first
    deciding operand); an atom compares as :func:`rac.runtime.semantics.float_atoms` says."""
    atoms = float_atoms(automaton)
    return ir.GuardFold(const=_guard_const, boolean=_guard_input,
                        atom=lambda leaf: _guard_atom(atoms(leaf), leaf.input),
                        negate=_guard_not, conjoin=_guard_and, disjoin=_guard_or)


class RewardAutomaton(AutomatonDescription):
    """The in-process interpreter of one reward automaton.

    Example::

        from rac.compiler import compile_file
        from rac.runtime.interpreter import RewardAutomaton

        ra = RewardAutomaton(compile_file("stdlib/driving.ra").raise_for_errors())
        r = ra.step({"isClose": False, "prog": True, "comf": True, "collide": False, "dgoal": 40.0})
        r += ra.end({"isClose": False, "prog": True, "comf": True, "collide": False, "dgoal": 1.0})
        assert ra.ended and ra.location == "Normal"
    """

    def __init__(self, automaton: ir.Automaton) -> None:
        check_automaton(automaton)
        self._ir = automaton
        self._specs = input_specs(automaton)
        self._names = tuple(s.name for s in self._specs)
        self._period = Fraction(automaton.period)
        index = {name: i for i, name in enumerate(automaton.rewards)}

        def updates(items: Sequence[ir.Assignment], where: str) -> tuple[tuple[int, _LinearFn], ...]:
            return tuple((index[a.reward], _compile_linear(float_linear(a.value, where), index))
                         for a in items)

        self._rates = tuple(
            tuple((i, _compile_linear(float_linear(rate.scaled(self._period), "rate"), {}))
                  for i, rate in enumerate(location.rates))
            for location in automaton.locations
        )
        _compile_guard = _guard_compiler(automaton)
        self._edges = tuple(
            tuple((_compile_guard(e.guard), updates(e.updates, "update"), e.target) for e in group)
            for group in automaton.edges
        )
        self._end_clauses = tuple((_compile_guard(c.guard), updates(c.updates, "end update"))
                                  for c in automaton.end_clauses)
        ends = automaton.ending
        self._episode_ends: _GuardFn | None = None if ends is None else _compile_guard(ends)
        self._assume = tuple((_compile_guard(check.guard), check) for check in assume_checks(automaton))
        self._objective_fn = _compile_linear(float_linear(automaton.objective, "objective"), index)
        self._initial_objective = self._objective_fn([0.0] * len(automaton.rewards), {})
        #: Per numeric input, how many values the last ``step``/``end`` with ``clip=True`` clipped.
        self.clipped: dict[str, int] = {}
        self.reset()

    # -------------------------------------------------------- description
    @property
    def locations(self) -> tuple[str, ...]:
        """Location names, in declaration order."""
        return self._ir.location_names

    # -------------------------------------------------------- state
    @property
    def location(self) -> str:
        """The current location's name."""
        return self._ir.locations[self._loc].name

    @property
    def rewards(self) -> dict[str, float]:
        """A copy of the reward values."""
        return dict(zip(self._ir.rewards, self._r))

    @property
    def objective(self) -> float:
        """The objective's current value."""
        return self._objective

    @property
    def samples(self) -> int:
        """Samples taken since the last reset."""
        return self._samples

    @property
    def time(self) -> float:
        """``samples * period`` in seconds (correctly rounded)."""
        return self._samples * self._period.numerator / self._period.denominator

    @property
    def ended(self) -> bool:
        """Whether the run has ended since the last reset: ``end`` was called, or :attr:`terminated`."""
        return self._ended

    @property
    def terminated(self) -> bool:
        """Whether ``episode ends when COND`` ended the run: COND held on the last sample's inputs
        (its end clauses are applied and counted in that ``step``'s reward). False after :meth:`reset`
        and when the run ended by :meth:`end`; always False without the declaration."""
        return self._terminated

    # -------------------------------------------------------- running
    def reset(self) -> None:
        """Start a new run: initial location, rewards 0, no held inputs."""
        self._loc = self._ir.initial
        self._r = [0.0] * len(self._ir.rewards)
        self._held: _Values | None = None
        self._samples = 0
        self._ended = False
        self._terminated = False
        self._objective = self._initial_objective

    def batch(self, n: int) -> BatchRewardAutomaton:
        """``n`` independent copies of this automaton, stepped together with numpy, each at the start of a
        run (this automaton's run state is not copied)."""

        return BatchRewardAutomaton(self._ir, n)

    def _read(self, inputs: Mapping[str, object]) -> _Values:
        # A dict, True/False and a float are taken by identity tests: the abstract-class checks of
        # check_mapping, boolean_input and number_input cost more than the rest of a sample.
        if type(inputs) is not dict:  # a dict subclass too: a defaultdict must not invent a missing input
            check_mapping(inputs, self._names)
        values: _Values = {}
        try:
            if len(inputs) != len(self._specs):
                raise KeyError
            for spec in self._specs:
                raw = inputs[spec.name]
                if spec.kind == "bool":
                    values[spec.name] = raw if raw is True or raw is False else boolean_input(spec.name, raw)
                    continue
                value = raw if type(raw) is float else number_input(spec.name, raw, spec.low, spec.high)
                if not spec.low <= value <= spec.high or not math.isfinite(value) or (
                        spec.kind == "int" and not value.is_integer()):
                    raise range_error(spec, value)
                values[spec.name] = value
        except KeyError:
            raise key_error(inputs, self._names) from None
        for holds, check in self._assume:
            if not holds(values):
                raise check.error(values)
        return values

    def _increase(self, x: _Values) -> float:
        objective = self._objective_fn(self._r, x)
        reward = objective - self._objective
        self._objective = objective
        return reward

    def _clip(self, inputs: Mapping[str, object], clip: bool) -> tuple[Mapping[str, object], dict[str, int] | None]:
        """The inputs clipped (with ``clip``) and the counts, which the caller keeps in :attr:`clipped`
        once the inputs are read: a call that raises leaves the automaton untouched, its counts too."""
        if not clip:
            return inputs, None
        # an array (but a 0-d one, its one value) is refused as given, not clipped; what is no mapping is refused too
        return clip_inputs(self._specs, inputs, scalars=True)

    def step(self, inputs: Mapping[str, object], *, clip: bool = False) -> float:
        """Take one sample with ``inputs``; return the objective's increase.

        ``clip``: numeric values outside their declared range are clipped to it first
        (:func:`rac.runtime.semantics.clip_inputs`; NaN is refused), and :attr:`clipped` counts them.
        """
        if self._ended:
            raise RuntimeError(ENDED_MESSAGE)
        inputs, counts = self._clip(inputs, clip)
        x = self._read(inputs)
        if counts is not None:
            self.clipped = counts
        held = x if self._held is None else self._held
        r = self._r
        for i, rate in self._rates[self._loc]:
            r[i] = r[i] + rate(r, held)
        for guard, updates, target in self._edges[self._loc]:
            if guard(x):
                for i, value in updates:
                    r[i] = value(r, x)
                self._loc = target
                break
        if self._episode_ends is not None and self._episode_ends(x):
            self._apply_end(x)
            self._terminated = True
        self._held = x
        self._samples += 1
        return self._increase(x)

    def _apply_end(self, x: _Values) -> None:
        """Every end clause whose guard holds on ``x``, in order; the run has ended."""
        r = self._r
        for guard, updates in self._end_clauses:
            if guard(x):
                for i, value in updates:
                    r[i] = value(r, x)
        self._ended = True

    def end(self, inputs: Mapping[str, object], *, clip: bool = False) -> float:
        """End the run with the final ``inputs`` (applies ``at end`` clauses); return the increase.

        ``clip`` as in :meth:`step`. After a run its condition ended (:attr:`terminated`): 0.0, and
        nothing is read or changed (the end clauses were applied at that sample)."""
        if self._terminated:
            return 0.0
        if self._ended:
            raise RuntimeError(ENDED_MESSAGE)
        inputs, counts = self._clip(inputs, clip)
        x = self._read(inputs)
        if counts is not None:
            self.clipped = counts
        self._apply_end(x)
        return self._increase(x)

    # -------------------------------------------------------- copies and pickles
    def __copy__(self) -> RewardAutomaton:
        """A copy with a run state of its own (rewards, held inputs, clip counts) at the same point.

        The compiled guards and forms are shared: they are pure functions of the frozen IR.
        """
        twin = object.__new__(type(self))
        twin.__dict__.update(self.__dict__)
        twin._r = list(self._r)
        twin._held = None if self._held is None else dict(self._held)
        twin.clipped = dict(self.clipped)
        return twin

    def __deepcopy__(self, memo: dict[int, object]) -> RewardAutomaton:
        """As :meth:`__copy__`: the run state holds only floats and bools, the IR is immutable."""
        return self.__copy__()

    def __getstate__(self) -> dict[str, object]:
        """For pickle: the IR and the run state; the compiled closures are rebuilt from the IR on load
        (they are local functions, which pickle cannot carry, and this lets SubprocVecEnv or Dask ship
        an automaton to a worker)."""
        own = {key: value for key, value in self.__dict__.items() if key not in _BUILT and key not in _RUN_STATE}
        return {"ir": self._ir, **{key: getattr(self, key) for key in _RUN_STATE}, "own": own}

    def __setstate__(self, state: dict[str, Any]) -> None:
        RewardAutomaton.__init__(self, state["ir"])
        for key in _RUN_STATE:
            # a pickle from before `episode ends when` has no `_terminated`: such a run never ended itself
            setattr(self, key, state.get(key, False) if key == "_terminated" else state[key])
        # a subclass's own attributes (a pickle from before they were kept has none): SubprocVecEnv and Dask
        # ship the automaton by pickle, and a worker's copy lost them (AttributeError at its next use)
        self.__dict__.update(state.get("own", {}))

    def __repr__(self) -> str:
        ending = ", terminated" if self._terminated else ", ended" if self._ended else ""
        return (f"<{type(self).__name__} {self.name} at {self.location}, samples={self._samples}, "
                f"objective={self._objective!r}{ending}>")
