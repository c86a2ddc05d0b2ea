"""Run a checked reward automaton in process: one at a time, or thousands at once with numpy.

:class:`RewardAutomaton` interprets an :class:`rac.ir.Automaton` sample by sample;
:class:`BatchRewardAutomaton` (``RewardAutomaton.batch(n)``) steps ``n`` independent copies
at once. Both follow the runtime semantics below to the bit, and so does the standalone
module of :mod:`rac.targets.python`; the agreement tests hold all three to it.

One ``step(inputs)`` (one sample):

1. the inputs are validated: every declared input present, nothing else; booleans via
   ``bool(v)``; numbers via ``float(v)``, finite and within their bounds (compared with the
   bounds as floats); ``int`` inputs integral. Then the ``assume`` guard must hold on them.
   A violation raises :class:`ValueError` and leaves the automaton untouched.
2. every reward grows by its rate in the current location times the period
   (``rate.scaled(period)`` rounded to floats), evaluated on the inputs held from the previous
   sample (the current ones at the first sample after a reset);
3. the first edge of the current location whose guard holds on the new inputs is taken: its
   updates are applied left to right, then the location changes. No enabled edge: stay;
4. the sample counter advances and the reward handed out is ``objective - previous objective``.

A linear form ``c0 + c1*v1 + ... + ck*vk`` is always evaluated as
``((float(c0) + float(c1)*v1) + ...) + float(ck)*vk``; guard atoms compare the input with
``float(threshold)``. ``end(inputs)`` validates, checks ``assume``, applies every end clause
whose guard holds (in order), ends the run and returns the objective's increase; ``step`` and
``end`` then raise :class:`RuntimeError` until :meth:`~RewardAutomaton.reset`.
"""

from __future__ import annotations

import math
import operator
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from fractions import Fraction
from typing import Any

import numpy as np

from rac import ir

__all__ = [
    "BatchRewardAutomaton",
    "FloatLinear",
    "InputSpec",
    "RewardAutomaton",
    "check_automaton",
    "float_linear",
    "input_specs",
    "to_float",
]

_OPS: dict[str, Callable[[Any, Any], Any]] = {
    "<": operator.lt,
    "<=": operator.le,
    ">": operator.gt,
    ">=": operator.ge,
    "==": operator.eq,
    "!=": operator.ne,
}

#: ``(float(const), ((float(coefficient), name), ...))`` — a Linear as every target evaluates it.
FloatLinear = tuple[float, tuple[tuple[float, str], ...]]


# ---------------------------------------------------------------- shared preparation
def to_float(value: Fraction | int, what: str) -> float:
    """``float(value)``, refusing values a float cannot carry (overflow, or a non-zero that rounds to 0).

    Refusing underflow keeps ``-0.0`` out of every constant, which the targets rely on.
    """
    try:
        result = float(value)
    except OverflowError:
        raise ValueError(f"{what}: {value} is too large for a float") from None
    if result == 0.0 and value != 0:
        raise ValueError(f"{what}: {value} is too small for a float (it would round to 0)")
    return result


def float_linear(linear: ir.Linear, what: str) -> FloatLinear:
    """The float form of ``linear``: constant and coefficients rounded, term order kept."""
    return (to_float(linear.const, what),
            tuple((to_float(c, f"{what} (coefficient of {n})"), n) for n, c in linear.terms))


@dataclass(frozen=True)
class InputSpec:
    """One declared input as the runtimes validate it (bounds as floats, ±inf when absent)."""

    name: str
    kind: str
    low: float
    high: float

    @property
    def is_bool(self) -> bool:
        return self.kind == "bool"

    @property
    def bounded(self) -> bool:
        return math.isfinite(self.low) and math.isfinite(self.high)


def input_specs(automaton: ir.Automaton) -> tuple[InputSpec, ...]:
    """The validation data of every input, in declaration order."""
    specs = []
    for item in automaton.inputs:
        low = -math.inf if item.low is None else to_float(item.low, f"lower bound of {item.name}")
        high = math.inf if item.high is None else to_float(item.high, f"upper bound of {item.name}")
        specs.append(InputSpec(item.name, item.kind, low, high))
    return tuple(specs)


def _guard_names(guard: ir.Guard, out: list[ir.Guard]) -> None:
    if isinstance(guard, (ir.BInput, ir.BAtom)):
        out.append(guard)
    elif isinstance(guard, ir.BNot):
        _guard_names(guard.operand, out)
    elif isinstance(guard, (ir.BAnd, ir.BOr)):
        for operand in guard.operands:
            _guard_names(operand, out)
    elif not isinstance(guard, ir.BConst):
        raise TypeError(f"not a guard: {guard!r}")


def check_automaton(automaton: ir.Automaton) -> None:
    """Check what the runtimes rely on (the compiler guarantees it; hand-built IR may not).

    Names resolve with the right kinds, rates read numeric inputs only, updates read rewards
    and numeric inputs, the objective reads rewards only, and every number fits a float.
    Raises :class:`ValueError` naming the first problem.
    """
    rewards = set(automaton.rewards)
    kinds = {i.name: i.kind for i in automaton.inputs}
    if len(rewards) != len(automaton.rewards) or len(kinds) != len(automaton.inputs):
        raise ValueError("duplicate reward or input names")
    if rewards & kinds.keys():
        raise ValueError(f"names used both as rewards and inputs: {sorted(rewards & kinds.keys())}")
    numeric = {name for name, kind in kinds.items() if kind != "bool"}
    n_loc = len(automaton.locations)
    if not automaton.locations or not 0 <= automaton.initial < n_loc:
        raise ValueError("the automaton needs locations and an initial location among them")
    if len(automaton.edges) != n_loc:
        raise ValueError("edges must be grouped by source location (one group per location)")
    if automaton.period <= 0:
        raise ValueError("the sample period must be positive")
    input_specs(automaton)

    def check_guard(guard: ir.Guard, where: str) -> None:
        atoms: list[ir.Guard] = []
        _guard_names(guard, atoms)
        for atom in atoms:
            if isinstance(atom, ir.BInput):
                if kinds.get(atom.name) != "bool":
                    raise ValueError(f"{where}: {atom.name!r} is not a boolean input")
            else:
                assert isinstance(atom, ir.BAtom)
                if atom.input not in numeric:
                    raise ValueError(f"{where}: {atom.input!r} is not a numeric input")
                if atom.op not in _OPS:
                    raise ValueError(f"{where}: unknown comparison {atom.op!r}")
                to_float(atom.threshold, f"{where}: threshold of {atom.input}")

    def check_linear(linear: ir.Linear, allowed: set[str], where: str) -> None:
        for name, _ in linear.terms:
            if name not in allowed:
                raise ValueError(f"{where}: {name!r} cannot appear here")
        float_linear(linear, where)

    def check_updates(updates: Sequence[ir.Assignment], where: str) -> None:
        for update in updates:
            if update.reward not in rewards:
                raise ValueError(f"{where}: {update.reward!r} is not a reward")
            check_linear(update.value, rewards | numeric, f"{where}: value of {update.reward}")

    for location in automaton.locations:
        if len(location.rates) != len(automaton.rewards):
            raise ValueError(f"location {location.name}: one rate per reward expected")
        for reward, rate in zip(automaton.rewards, location.rates):
            check_linear(rate.scaled(automaton.period), numeric, f"rate of {reward} in {location.name}")
    for index, group in enumerate(automaton.edges):
        for edge in group:
            where = f"edge {automaton.locations[index].name} -> {edge.target}"
            if edge.source != index or not 0 <= edge.target < n_loc:
                raise ValueError(f"{where}: source or target out of place")
            check_guard(edge.guard, where)
            check_updates(edge.updates, where)
    for clause in automaton.end_clauses:
        check_guard(clause.guard, "at end")
        check_updates(clause.updates, "at end")
    check_guard(automaton.assume, "assume")
    check_linear(automaton.objective, rewards, "objective")


def _key_error(inputs: Mapping[str, object], names: Sequence[str]) -> ValueError:
    missing = [name for name in names if name not in inputs]
    known = set(names)
    unknown = sorted(repr(key) for key in inputs if key not in known)
    parts = []
    if missing:
        parts.append("missing input(s): " + ", ".join(missing))
    if unknown:
        parts.append("unknown input(s): " + ", ".join(unknown))
    return ValueError("; ".join(parts) or "the inputs do not match the declared inputs")


def _range_error(spec: InputSpec, value: object, where: str = "") -> ValueError:
    in_range = isinstance(value, float) and math.isfinite(value) and spec.low <= value <= spec.high
    if spec.kind == "int" and in_range:
        return ValueError(f"input {spec.name!r}{where} = {value!r} is not an integer")
    return ValueError(f"input {spec.name!r}{where} = {value!r} is outside [{spec.low!r}, {spec.high!r}]")


_ASSUME_MESSAGE = "inputs violate `assume`"
_ENDED_MESSAGE = "the run has ended; call reset() first"


# ---------------------------------------------------------------- scalar interpreter
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


def _compile_guard(guard: ir.Guard) -> _GuardFn:
    if isinstance(guard, ir.BConst):
        value = bool(guard.value)
        return lambda x: value
    if isinstance(guard, ir.BInput):
        name = guard.name
        return lambda x: x[name]
    if isinstance(guard, ir.BAtom):
        op, name, threshold = _OPS[guard.op], guard.input, to_float(guard.threshold, "threshold")
        return lambda x: op(x[name], threshold)
    if isinstance(guard, ir.BNot):
        inner = _compile_guard(guard.operand)
        return lambda x: not inner(x)
    parts = tuple(_compile_guard(g) for g in guard.operands)
    if isinstance(guard, ir.BAnd):
        if len(parts) == 2:
            a, b = parts
            return lambda x: a(x) and b(x)
        return lambda x: all(p(x) for p in parts)
    if len(parts) == 2:
        a, b = parts
        return lambda x: a(x) or b(x)
    return lambda x: any(p(x) for p in parts)


class RewardAutomaton:
    """The in-process interpreter of one reward automaton.

    Example::

        from rac.compiler import compile_file
        from rac.runtime import RewardAutomaton

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
        self._edges = tuple(
            tuple((_compile_guard(e.guard), updates(e.updates, "update"), e.target) for e in group)
            for group in automaton.edges
        )
        self._end_clauses = tuple((_compile_guard(c.guard), updates(c.updates, "end update"))
                                  for c in automaton.end_clauses)
        self._assume = _compile_guard(automaton.assume)
        self._objective_fn = _compile_linear(float_linear(automaton.objective, "objective"), index)
        self._initial_objective = self._objective_fn([0.0] * len(automaton.rewards), {})
        self.reset()

    # -------------------------------------------------------- description
    @property
    def ir(self) -> ir.Automaton:
        """The automaton this interpreter runs."""
        return self._ir

    @property
    def name(self) -> str:
        """The automaton's name."""
        return self._ir.name

    @property
    def inputs(self) -> tuple[str, ...]:
        """Input names, in declaration order."""
        return self._names

    @property
    def reward_names(self) -> tuple[str, ...]:
        """Reward names, in declaration order."""
        return self._ir.rewards

    @property
    def locations(self) -> tuple[str, ...]:
        """Location names, in declaration order."""
        return self._ir.location_names

    @property
    def period(self) -> float:
        """Seconds per sample."""
        return float(self._period)

    @property
    def steps(self) -> int:
        """Samples in a run of the full horizon (not enforced here: the caller ends runs)."""
        return self._ir.steps

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
        """Whether ``end`` was called since the last reset."""
        return self._ended

    # -------------------------------------------------------- running
    def reset(self) -> None:
        """Start a new run: initial location, rewards 0, no held inputs."""
        self._loc = self._ir.initial
        self._r = [0.0] * len(self._ir.rewards)
        self._held: _Values | None = None
        self._samples = 0
        self._ended = False
        self._objective = self._initial_objective

    def batch(self, n: int) -> BatchRewardAutomaton:
        """``n`` independent copies of this automaton, stepped together with numpy."""
        return BatchRewardAutomaton(self._ir, n)

    def _read(self, inputs: Mapping[str, object]) -> _Values:
        values: _Values = {}
        try:
            if len(inputs) != len(self._specs):
                raise KeyError
            for spec in self._specs:
                raw = inputs[spec.name]
                if spec.kind == "bool":
                    values[spec.name] = bool(raw)
                    continue
                value = float(raw)  # type: ignore[arg-type]
                if not spec.low <= value <= spec.high or not math.isfinite(value) or (
                        spec.kind == "int" and not value.is_integer()):
                    raise _range_error(spec, value)
                values[spec.name] = value
        except KeyError:
            raise _key_error(inputs, self._names) from None
        if not self._assume(values):
            raise ValueError(_ASSUME_MESSAGE)
        return values

    def _increase(self, x: _Values) -> float:
        objective = self._objective_fn(self._r, x)
        reward = objective - self._objective
        self._objective = objective
        return reward

    def step(self, inputs: Mapping[str, object]) -> float:
        """Take one sample with ``inputs``; return the objective's increase."""
        if self._ended:
            raise RuntimeError(_ENDED_MESSAGE)
        x = self._read(inputs)
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
        self._held = x
        self._samples += 1
        return self._increase(x)

    def end(self, inputs: Mapping[str, object]) -> float:
        """End the run with the final ``inputs`` (applies ``at end`` clauses); return the increase."""
        if self._ended:
            raise RuntimeError(_ENDED_MESSAGE)
        x = self._read(inputs)
        r = self._r
        for guard, updates in self._end_clauses:
            if guard(x):
                for i, value in updates:
                    r[i] = value(r, x)
        self._ended = True
        return self._increase(x)

    def __repr__(self) -> str:
        return (f"<RewardAutomaton {self.name} at {self.location}, samples={self._samples}, "
                f"objective={self._objective!r}{', ended' if self._ended else ''}>")


# ---------------------------------------------------------------- batch
_NP_OPS: dict[str, Callable[[np.ndarray, float], np.ndarray]] = {
    "<": np.less,
    "<=": np.less_equal,
    ">": np.greater,
    ">=": np.greater_equal,
    "==": np.equal,
    "!=": np.not_equal,
}

#: Table mode: locations × 2**atoms entries at most.
_TABLE_LIMIT = 1 << 16


def _eval_np_linear(form: FloatLinear, values: Callable[[str], np.ndarray], n: int) -> np.ndarray:
    const, terms = form
    if not terms:
        return np.full(n, const)
    acc: Any = const
    for coef, name in terms:
        acc = acc + coef * values(name)
    return acc


class _Guards:
    """Every distinct guard sub-expression of an automaton, evaluated once per call over all n."""

    def __init__(self, n: int) -> None:
        self._n = n
        self._ids: dict[ir.Guard, int] = {}
        self.program: list[tuple[str, Any]] = []

    def add(self, guard: ir.Guard) -> int:
        found = self._ids.get(guard)
        if found is not None:
            return found
        if isinstance(guard, ir.BConst):
            node: tuple[str, Any] = ("const", np.full(self._n, bool(guard.value)))
        elif isinstance(guard, ir.BInput):
            node = ("input", guard.name)
        elif isinstance(guard, ir.BAtom):
            node = ("atom", (guard.input, _NP_OPS[guard.op], to_float(guard.threshold, "threshold")))
        elif isinstance(guard, ir.BNot):
            node = ("not", self.add(guard.operand))
        else:
            node = ("and" if isinstance(guard, ir.BAnd) else "or", tuple(self.add(g) for g in guard.operands))
        self.program.append(node)
        self._ids[guard] = len(self.program) - 1
        return len(self.program) - 1

    def evaluate(self, x: Mapping[str, np.ndarray]) -> list[np.ndarray]:
        out: list[np.ndarray] = []
        for kind, arg in self.program:
            if kind == "input":
                out.append(x[arg])
            elif kind == "atom":
                name, op, threshold = arg
                out.append(op(x[name], threshold))
            elif kind == "not":
                out.append(~out[arg])
            elif kind == "const":
                out.append(arg)
            else:
                value = out[arg[0]]
                combine = np.logical_and if kind == "and" else np.logical_or
                for other in arg[1:]:
                    value = combine(value, out[other])
                out.append(value)
        return out


def _atoms(guard: ir.Guard, out: dict[ir.Guard, int]) -> None:
    found: list[ir.Guard] = []
    _guard_names(guard, found)
    for atom in found:
        out.setdefault(atom, len(out))


def _eval_atoms(guard: ir.Guard, bits: Mapping[ir.Guard, bool]) -> bool:
    if isinstance(guard, ir.BConst):
        return bool(guard.value)
    if isinstance(guard, (ir.BInput, ir.BAtom)):
        return bits[guard]
    if isinstance(guard, ir.BNot):
        return not _eval_atoms(guard.operand, bits)
    if isinstance(guard, ir.BAnd):
        return all(_eval_atoms(g, bits) for g in guard.operands)
    return any(_eval_atoms(g, bits) for g in guard.operands)


class BatchRewardAutomaton:
    """``n`` independent copies of one reward automaton, stepped together with numpy.

    Each column follows exactly the semantics of :class:`RewardAutomaton` (the same float
    operations in the same order, elementwise), so the results are bit-identical to ``n``
    scalar interpreters. Inputs are arrays of shape ``(n,)`` (scalars broadcast).

    Edge selection is a table lookup over (location, truth values of the guard atoms) when
    that table is small (``strategy="table"``), else every distinct guard sub-expression is
    evaluated once per call over all ``n`` (``strategy="direct"``); ``"auto"`` picks.

    Example (a vectorised environment that ends and resets finished runs)::

        ra = RewardAutomaton(automaton).batch(4096)
        rewards = ra.step_batch(inputs)          # inputs: name -> array of shape (4096,)
        if done.any():
            rewards += ra.end_batch(inputs, mask=done)
            ra.reset(mask=done)
    """

    def __init__(self, automaton: ir.Automaton, n: int, *, strategy: str = "auto") -> None:
        check_automaton(automaton)
        if n < 1:
            raise ValueError("a batch holds at least one automaton")
        if strategy not in ("auto", "table", "direct"):
            raise ValueError(f"unknown strategy {strategy!r}")
        self._ir = automaton
        self._n = int(n)
        self._specs = input_specs(automaton)
        self._names = tuple(s.name for s in self._specs)
        self._period = Fraction(automaton.period)
        self._index = {name: i for i, name in enumerate(automaton.rewards)}
        k, n_loc = len(automaton.rewards), len(automaton.locations)
        self._guards = _Guards(self._n)

        # ---- rates: constant tables, plus per-slot coefficient tables for input-dependent rates
        forms = [[float_linear(loc.rates[i].scaled(self._period), "rate") for loc in automaton.locations]
                 for i in range(k)]
        constants = [[f[0] for f in row] for row in forms]
        self._rate_table = np.array(constants, dtype=np.float64).reshape(k, n_loc)
        self._all_constant = all(not f[1] for row in forms for f in row)
        # Per reward: None (constant rates) or [(coefficient table over locations, input name)].
        # A location without that term has coefficient 0.0 there, which adds exactly nothing
        # (inputs are finite and a partial sum is never -0.0, since no constant is -0.0).
        self._rate_terms: list[list[tuple[np.ndarray, str]] | None] = []
        held: set[str] = set()
        for row in forms:
            width = max(len(f[1]) for f in row)
            if width == 0:
                self._rate_terms.append(None)
                continue
            slots: list[tuple[np.ndarray, str]] = []
            for slot in range(width):
                names = dict.fromkeys(f[1][slot][1] for f in row if len(f[1]) > slot)
                for name in names:
                    table = np.array([f[1][slot][0] if len(f[1]) > slot and f[1][slot][1] == name else 0.0
                                      for f in row])
                    slots.append((table, name))
                    held.add(name)
            self._rate_terms.append(slots)
        self._held_names = tuple(name for name in self._names if name in held)

        # ---- updates, grouped in classes of identical update lists (class 0: no updates)
        classes: dict[tuple[ir.Assignment, ...], int] = {(): 0}
        for edge in automaton.all_edges():
            classes.setdefault(edge.updates, len(classes))
        self._classes = [self._compile_updates(updates) for updates in classes]

        # ---- edge selection
        atoms: dict[ir.Guard, int] = {}
        for edge in automaton.all_edges():
            _atoms(edge.guard, atoms)
        _atoms(automaton.assume, atoms)
        table_size = n_loc << len(atoms)
        if strategy == "auto":
            strategy = "table" if len(atoms) <= 16 and table_size <= _TABLE_LIMIT else "direct"
        self.strategy = strategy
        if strategy == "table":
            self._build_tables(atoms, classes)
        else:
            self._direct = []
            for loc, group in enumerate(automaton.edges):
                if group:
                    self._direct.append((loc, [(self._guards.add(e.guard), e.target, classes[e.updates])
                                               for e in group]))
            self._assume_id = (None if automaton.assume == ir.TRUE else self._guards.add(automaton.assume))
        self._end = [(self._guards.add(c.guard), self._compile_updates(c.updates))
                     for c in automaton.end_clauses]
        self._end_assume = self._guards.add(automaton.assume)

        self._objective_form = float_linear(automaton.objective, "objective")
        zeros = np.zeros((k, 1))
        initial = _eval_np_linear(self._objective_form, lambda r: zeros[self._index[r]], 1)
        self._initial_objective = float(initial[0])

        n = self._n
        self._loc = np.full(n, automaton.initial, dtype=np.intp)
        self._R = np.zeros((k, n), dtype=np.float64)
        self._samples = np.zeros(n, dtype=np.int64)
        self._ended = np.zeros(n, dtype=bool)
        self._n_ended = 0
        self._obj = np.full(n, self._initial_objective)
        self._held: dict[str, np.ndarray] = {name: np.zeros(n) for name in self._held_names}
        self._first = np.ones(n, dtype=bool)
        self._any_first = True

    def _compile_updates(self, updates: Sequence[ir.Assignment]) -> list[tuple[int, FloatLinear]]:
        return [(self._index[a.reward], float_linear(a.value, "update")) for a in updates]

    def _build_tables(self, atoms: dict[ir.Guard, int],
                      classes: dict[tuple[ir.Assignment, ...], int]) -> None:
        a = len(atoms)
        self._atom_list = [(atom.name, None, 0.0) if isinstance(atom, ir.BInput)
                           else (atom.input, _NP_OPS[atom.op], to_float(atom.threshold, "threshold"))
                           for atom in atoms]  # type: ignore[union-attr]
        self._atom_bits = a
        self._code_dtype = np.uint8 if a <= 8 else np.uint16
        combos = [{atom: bool(code >> bit & 1) for atom, bit in atoms.items()} for code in range(1 << a)]
        assume = self._ir.assume
        self._assume_table = (None if assume == ir.TRUE
                              else np.array([_eval_atoms(assume, bits) for bits in combos], dtype=bool))
        n_loc = len(self._ir.locations)
        nxt = np.empty(n_loc << a, dtype=np.intp)
        cls = np.zeros(n_loc << a, dtype=np.intp)
        for loc, group in enumerate(self._ir.edges):
            for code, bits in enumerate(combos):
                nxt[loc << a | code] = loc
                for edge in group:
                    if _eval_atoms(edge.guard, bits):
                        nxt[loc << a | code] = edge.target
                        cls[loc << a | code] = classes[edge.updates]
                        break
        self._next_table = nxt
        self._class_table = cls

    # -------------------------------------------------------- description
    @property
    def ir(self) -> ir.Automaton:
        """The automaton these copies run."""
        return self._ir

    @property
    def n(self) -> int:
        """Number of automata in the batch."""
        return self._n

    def __len__(self) -> int:
        return self._n

    @property
    def name(self) -> str:
        """The automaton's name."""
        return self._ir.name

    @property
    def inputs(self) -> tuple[str, ...]:
        """Input names, in declaration order."""
        return self._names

    @property
    def reward_names(self) -> tuple[str, ...]:
        """Reward names, in declaration order."""
        return self._ir.rewards

    @property
    def period(self) -> float:
        """Seconds per sample."""
        return float(self._period)

    # -------------------------------------------------------- state (copies)
    @property
    def locations(self) -> np.ndarray:
        """Current location index of each automaton (into ``ir.location_names``)."""
        return self._loc.copy()

    def location_names(self) -> list[str]:
        """Current location name of each automaton."""
        names = self._ir.location_names
        return [names[i] for i in self._loc.tolist()]

    @property
    def rewards(self) -> dict[str, np.ndarray]:
        """Reward name -> copy of its values across the batch."""
        return {name: self._R[i].copy() for i, name in enumerate(self._ir.rewards)}

    @property
    def objective(self) -> np.ndarray:
        """The objective's current value per automaton (a copy)."""
        return self._obj.copy()

    @property
    def samples(self) -> np.ndarray:
        """Samples since each automaton's last reset (a copy)."""
        return self._samples.copy()

    @property
    def time(self) -> np.ndarray:
        """``samples * period`` per automaton, in seconds (correctly rounded)."""
        return self._samples * self._period.numerator / self._period.denominator

    @property
    def ended(self) -> np.ndarray:
        """Which automata have ended their run (a copy)."""
        return self._ended.copy()

    # -------------------------------------------------------- running
    def _mask(self, mask: object) -> np.ndarray:
        m = np.asarray(mask, dtype=bool)
        if m.shape != (self._n,):
            raise ValueError(f"mask must have shape ({self._n},), not {m.shape}")
        return m

    def reset(self, mask: np.ndarray | Sequence[bool] | None = None) -> None:
        """Reset every automaton, or those where ``mask`` is true."""
        if mask is None:
            self._loc = np.full(self._n, self._ir.initial, dtype=np.intp)
            self._R[:] = 0.0
            self._samples[:] = 0
            self._ended[:] = False
            self._obj[:] = self._initial_objective
            self._first[:] = True
        else:
            m = self._mask(mask)
            self._loc = self._loc.copy()
            self._loc[m] = self._ir.initial
            self._R[:, m] = 0.0
            self._samples[m] = 0
            self._ended[m] = False
            self._obj[m] = self._initial_objective
            self._first[m] = True
        self._n_ended = int(self._ended.sum())
        self._any_first = bool(self._first.any())

    def _read(self, inputs: Mapping[str, object], rows: np.ndarray | None) -> dict[str, np.ndarray]:
        """Validated inputs as arrays (bool / float64); only ``rows`` are checked when given."""
        n = self._n
        if len(inputs) != len(self._names) or any(name not in inputs for name in self._names):
            raise _key_error(inputs, self._names)
        out: dict[str, np.ndarray] = {}
        for spec in self._specs:
            raw = np.asarray(inputs[spec.name])
            if raw.shape != (n,):
                if raw.ndim != 0:
                    raise ValueError(f"input {spec.name!r} must have shape ({n},), not {raw.shape}")
                raw = np.broadcast_to(raw, (n,))
            if spec.is_bool:
                out[spec.name] = raw.astype(bool, copy=False)
                continue
            value = raw.astype(np.float64, copy=False)
            if spec.bounded:
                ok = (value >= spec.low) & (value <= spec.high)
            else:
                ok = np.isfinite(value) & (value >= spec.low) & (value <= spec.high)
            if spec.kind == "int":
                ok &= np.floor(value) == value
            if rows is not None:
                ok |= ~rows
            if not ok.all():
                bad = int(np.flatnonzero(~ok)[0])
                raise _range_error(spec, float(value[bad]), f"[{bad}]")
            out[spec.name] = value
        return out

    def _assume_failed(self, ok: np.ndarray) -> ValueError:
        bad = np.flatnonzero(~ok)
        return ValueError(f"{_ASSUME_MESSAGE} (automata {bad[:10].tolist()}{'...' if len(bad) > 10 else ''})")

    def _apply(self, updates: list[tuple[int, FloatLinear]], where: np.ndarray,
               x: Mapping[str, np.ndarray]) -> None:
        R, index = self._R, self._index

        def value(name: str) -> np.ndarray:
            i = index.get(name)
            return R[i] if i is not None else x[name]

        for i, form in updates:
            np.copyto(R[i], _eval_np_linear(form, value, self._n), where=where)

    def _objective_now(self) -> np.ndarray:
        R, index = self._R, self._index
        return _eval_np_linear(self._objective_form, lambda name: R[index[name]], self._n)

    def step_batch(self, inputs: Mapping[str, object]) -> np.ndarray:
        """One sample for every automaton; returns each one's objective increase (float64, (n,))."""
        if self._n_ended:
            ended = np.flatnonzero(self._ended)[:10].tolist()
            raise RuntimeError(f"{_ENDED_MESSAGE} (automata {ended} have ended)")
        x = self._read(inputs, None)
        loc = self._loc
        with np.errstate(all="ignore"):
            # ---- choose edges (before anything changes: an assume violation leaves the state alone)
            fired: list[tuple[int, np.ndarray]] = []
            if self.strategy == "table":
                code: Any = None
                for bit, (name, op, threshold) in enumerate(self._atom_list):
                    truth = x[name] if op is None else op(x[name], threshold)
                    term = truth.astype(self._code_dtype)
                    if bit:
                        term <<= bit
                        code |= term
                    else:
                        code = term
                if code is None:
                    code = np.zeros(self._n, dtype=self._code_dtype)
                if self._assume_table is not None:
                    ok = self._assume_table[code]
                    if not ok.all():
                        raise self._assume_failed(ok)
                idx = (loc << self._atom_bits) | code
                nxt = self._next_table[idx]
                if len(self._classes) > 1:
                    cls = self._class_table[idx]
                    for c in range(1, len(self._classes)):
                        m = cls == c
                        if m.any():
                            fired.append((c, m))
            else:
                g = self._guards.evaluate(x)
                if self._assume_id is not None and not g[self._assume_id].all():
                    raise self._assume_failed(g[self._assume_id])
                nxt = loc.copy()
                masks: dict[int, np.ndarray] = {}
                for source, edges in self._direct:
                    rest = loc == source
                    last = len(edges) - 1
                    for j, (gid, target, c) in enumerate(edges):
                        f = rest & g[gid]
                        if j < last:
                            rest &= ~g[gid]
                        if target != source:
                            np.copyto(nxt, target, where=f)
                        if c:
                            masks[c] = masks[c] | f if c in masks else f
                fired = [(c, m) for c, m in sorted(masks.items()) if m.any()]

            # ---- accrual with the held inputs
            if self._held_names:
                held = self._held
                if self._any_first:
                    for name in self._held_names:
                        held[name] = np.where(self._first, x[name], held[name])
                    self._first[:] = False
                    self._any_first = False
            if self._all_constant:
                self._R += self._rate_table[:, loc]
            else:
                for i, terms in enumerate(self._rate_terms):
                    rate = self._rate_table[i][loc]
                    if terms is not None:
                        for table, name in terms:
                            rate = rate + table[loc] * held[name]
                    self._R[i] += rate
            for name in self._held_names:
                held[name] = np.array(x[name], dtype=np.float64)

            # ---- edges
            for c, m in fired:
                self._apply(self._classes[c], m, x)
            self._loc = nxt
            self._samples += 1
            objective = self._objective_now()
            reward = objective - self._obj
        self._obj = objective
        return reward

    def end_batch(self, inputs: Mapping[str, object],
                  mask: np.ndarray | Sequence[bool] | None = None) -> np.ndarray:
        """End the runs where ``mask`` is true (all when ``None``); returns their objective increase.

        Inputs are validated on the masked automata only; unmasked ones get reward 0.0.
        """
        m = np.ones(self._n, dtype=bool) if mask is None else self._mask(mask)
        if (self._ended & m).any():
            raise RuntimeError(f"{_ENDED_MESSAGE} (automata {np.flatnonzero(self._ended & m)[:10].tolist()})")
        x = self._read(inputs, m)
        with np.errstate(all="ignore"):
            g = self._guards.evaluate(x)
            ok = g[self._end_assume] | ~m
            if not ok.all():
                raise self._assume_failed(ok)
            for gid, updates in self._end:
                f = m & g[gid]
                if f.any():
                    self._apply(updates, f, x)
            objective = self._objective_now()
            reward = np.where(m, objective - self._obj, 0.0)
        np.copyto(self._obj, objective, where=m)
        self._ended |= m
        self._n_ended = int(self._ended.sum())
        return reward

    def __repr__(self) -> str:
        return f"<BatchRewardAutomaton {self.name} n={self._n} strategy={self.strategy}>"
