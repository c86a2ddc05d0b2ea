"""The checked automaton as the targets see it: names resolved, arithmetic exact.

Targets (the in-process interpreter, generated Python, UPPAAL) and the static
analyses read this representation only. All numbers are ``Fraction``; each
target decides how to round them (see :meth:`Linear.scaled`).

May import: core, lang.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from fractions import Fraction
from typing import Generic, TypeVar, Union

from rac.core.source import Span
from rac.ir.expr import Expr
from rac.ir.query import QueryDecl
from rac.lang import ast


@dataclass(frozen=True)
class Linear:
    """``const + Σ coefficient·variable`` over rewards and numeric inputs."""

    const: Fraction = Fraction(0)
    terms: tuple[tuple[str, Fraction], ...] = ()

    @staticmethod
    def constant(value: Fraction | int) -> Linear:
        return Linear(Fraction(value))

    @staticmethod
    def variable(name: str) -> Linear:
        return Linear(Fraction(0), ((name, Fraction(1)),))

    @property
    def is_constant(self) -> bool:
        return not self.terms

    def coefficient(self, name: str) -> Fraction:
        return dict(self.terms).get(name, Fraction(0))

    def variables(self) -> tuple[str, ...]:
        return tuple(name for name, _ in self.terms)

    def _combine(self, other: Linear, sign: int) -> Linear:
        coefficients = dict(self.terms)
        for name, value in other.terms:
            coefficients[name] = coefficients.get(name, Fraction(0)) + sign * value
        return Linear(self.const + sign * other.const,
                      tuple((n, c) for n, c in coefficients.items() if c != 0))

    def __add__(self, other: Linear) -> Linear:
        return self._combine(other, 1)

    def __sub__(self, other: Linear) -> Linear:
        return self._combine(other, -1)

    def scaled(self, factor: Fraction | int) -> Linear:
        factor = Fraction(factor)
        if factor == 0:
            return Linear()
        return Linear(self.const * factor, tuple((n, c * factor) for n, c in self.terms))

    def evaluate(self, values: dict[str, Fraction]) -> Fraction:
        return self.const + sum((c * values[n] for n, c in self.terms), Fraction(0))

    def ordered(self, order: tuple[str, ...]) -> Linear:
        """The same form with terms in a fixed variable order (targets rely on it)."""
        rank = {name: i for i, name in enumerate(order)}
        return Linear(self.const, tuple(sorted(self.terms, key=lambda t: rank.get(t[0], len(rank)))))


# ---------------------------------------------------------------- guards
@dataclass(frozen=True)
class BConst:
    value: bool


@dataclass(frozen=True)
class BInput:
    """A boolean input's current value."""

    name: str


@dataclass(frozen=True)
class BAtom:
    """``input op threshold`` for a numeric input (every numeric comparison is normalised to this)."""

    input: str
    op: str  # < <= > >= == !=
    threshold: Fraction


@dataclass(frozen=True)
class BNot:
    operand: Guard


@dataclass(frozen=True)
class BAnd:
    operands: tuple[Guard, ...]


@dataclass(frozen=True)
class BOr:
    operands: tuple[Guard, ...]


Guard = Union[BConst, BInput, BAtom, BNot, BAnd, BOr]

TRUE = BConst(True)

T = TypeVar("T")


@dataclass(frozen=True)
class GuardFold(Generic[T]):
    """The one walk over the six guard nodes: what a guard means to one evaluator is a value per leaf
    (``const``, ``boolean`` for a :class:`BInput`, ``atom`` for a :class:`BAtom`) and a combination per
    connective (``negate``, ``conjoin``, ``disjoin`` of the operands' values, in order). Calling it folds a
    guard bottom-up, the operands before their node; with ``memo``, each distinct sub-guard once (the
    memo keeps the values). The interpreter folds into closures, the batch runtime into a program of
    numpy steps, the product into arrays over its states, :func:`evaluate_guard` into exact truth."""

    const: Callable[[bool], T]
    boolean: Callable[[BInput], T]
    atom: Callable[[BAtom], T]
    negate: Callable[[T], T]
    conjoin: Callable[[tuple[T, ...]], T]
    disjoin: Callable[[tuple[T, ...]], T]

    def __call__(self, guard: Guard, memo: dict[Guard, T] | None = None) -> T:
        if memo is not None and guard in memo:
            return memo[guard]
        value: T
        if isinstance(guard, BConst):
            value = self.const(guard.value)
        elif isinstance(guard, BInput):
            value = self.boolean(guard)
        elif isinstance(guard, BAtom):
            value = self.atom(guard)
        elif isinstance(guard, BNot):
            value = self.negate(self(guard.operand, memo))
        elif isinstance(guard, BAnd):
            value = self.conjoin(tuple(self(g, memo) for g in guard.operands))
        elif isinstance(guard, BOr):
            value = self.disjoin(tuple(self(g, memo) for g in guard.operands))
        else:
            raise TypeError(f"not a guard: {guard!r}")
        if memo is not None:
            memo[guard] = value
        return value


# ---------------------------------------------------------------- scenario model (model block)
@dataclass(frozen=True)
class Action:
    """A controller action: values ``low, low+step, ..., high`` (UPPAAL ``select`` over significands)."""

    name: str  # "jerk" or "turn"
    low: Fraction
    high: Fraction
    step: Fraction

    @property
    def count(self) -> int:
        """How many values the action offers, counted exactly without listing them (the checker
        compares it with :data:`rac.ir.vocabulary.MAX_ACTION_VALUES` before anything lists them)."""
        return int((self.high - self.low) / self.step) + 1

    @property
    def values(self) -> tuple[Fraction, ...]:
        return tuple(self.low + i * self.step for i in range(self.count))


@dataclass(frozen=True)
class Binding:
    """``bind input = expr``: how the scenario model drives one automaton input.

    ``expr`` is a resolved expression (:mod:`rac.ir.expr`) over the model's vocabulary
    (:mod:`rac.ir.vocabulary`): ``collide()``, ``offroad()``, ``goal()``, ``mindist()``,
    ``dist_goal()``, ``prev(e)``, ``fabs(e)``, the ego state ``x, y, v, acc, head, jerk, turn``,
    ``time`` and the model's settings, the automaton's constants inlined.
    """

    input: str
    expr: Expr
    span: Span | None = field(default=None, compare=False)


@dataclass(frozen=True)
class ModelSpec:
    """The ``model`` block: the scenario and every parameter of the vehicle model (model.md)."""

    scenario: str  # as written in the file
    scenario_path: str  # resolved against the .ra file's folder
    base: int
    exponent: int
    sense_period: Fraction  # C1, equal to the automaton's `sample every`
    decide_period: Fraction  # C2, a multiple of C1
    granularity: Fraction  # G: sense() integrates in 1/G Euler sub-steps of C1*G
    actions: tuple[Action, ...]  # jerk, turn
    length: Fraction
    width: Fraction
    max_acceleration: Fraction  # MA
    max_turn: Fraction  # MT
    min_speed: Fraction
    max_speed: Fraction
    collision_distance: Fraction  # TD
    comfort_acceleration: Fraction  # p1
    comfort_turn: Fraction  # p2
    bindings: tuple[Binding, ...]
    sensor_error: Fraction = Fraction(1, 2)  # THD: the threshold of the sensor-error query Qa (m)
    #: The id of the CommonRoad planning problem the ego's start and goal come from; 0 (CommonRoad
    #: ids are positive): none chosen, the file must have exactly one (E0715 otherwise).
    planning_problem: int = 0
    #: How ``sense()`` moves the ego (:data:`rac.ir.vocabulary.WORD_SETTINGS`): ``"integrated"``
    #: (Algorithm 1 on doubles, truncated at the end) or ``"increments"`` (each sub-step adds truncated
    #: increments to the integer state, as CommonUppRoad's model does).
    dynamics: str = "integrated"
    #: ``"instant"``: ``collide()`` tests the current sample; ``"sticky"``: once it held, it holds for
    #: the rest of the run (``collision`` setting).
    collision: str = "instant"
    #: The ego's start, each None: the planning problem's (``start_*`` settings).
    start_x: Fraction | None = None
    start_y: Fraction | None = None
    start_heading: Fraction | None = None
    start_speed: Fraction | None = None
    #: ``offroad()`` is false at samples before this one (1: the start is not checked).
    offroad_from: int = 0
    #: ``allow when e``: an action is allowed only where ``e`` (a condition over the model's
    #: vocabulary, without ``prev``) holds in the state it leads to one sense period later; None: all.
    allow: Expr | None = None
    span: Span | None = field(default=None, compare=False)

    @property
    def scale(self) -> int:
        """base ** exponent: a real v is held as the significand trunc(v * scale)."""
        return self.base ** self.exponent

    @property
    def substeps(self) -> int:
        return int(1 / self.granularity)

    def action(self, name: str) -> Action:
        return next(a for a in self.actions if a.name == name)


# ---------------------------------------------------------------- automaton
@dataclass(frozen=True)
class Input:
    name: str
    kind: str  # "bool", "real" or "int"
    low: Fraction | None = None
    high: Fraction | None = None
    span: Span | None = field(default=None, compare=False)

    @property
    def is_bool(self) -> bool:
        return self.kind == "bool"


@dataclass(frozen=True)
class Assignment:
    """``reward = value`` with ``value`` linear in rewards and numeric inputs."""

    reward: str
    value: Linear
    span: Span | None = field(default=None, compare=False)


@dataclass(frozen=True)
class Location:
    name: str
    #: One rate per reward (same order as ``Automaton.rewards``), linear in numeric inputs.
    rates: tuple[Linear, ...]
    span: Span | None = field(default=None, compare=False)


@dataclass(frozen=True)
class Edge:
    source: int
    target: int
    guard: Guard
    updates: tuple[Assignment, ...]
    span: Span | None = field(default=None, compare=False)


@dataclass(frozen=True)
class EndClause:
    guard: Guard
    updates: tuple[Assignment, ...]
    span: Span | None = field(default=None, compare=False)


@dataclass(frozen=True)
class Assumption:
    """One ``assume`` declaration: its guard, its condition as written and its place (the runtimes
    quote both when inputs violate it; neither takes part in equality)."""

    guard: Guard
    text: str = field(compare=False)
    span: Span | None = field(default=None, compare=False)


@dataclass(frozen=True)
class Parameter:
    """``param NAME in [low, high]``: the automaton was resolved with ``value`` in its place."""

    name: str
    low: Fraction
    high: Fraction
    value: Fraction
    span: Span | None = field(default=None, compare=False)


#: The checks a ``require`` can make errors of (issue 25): ``risk`` takes a bound (the largest
#: indifference point p* allowed); the others take none.
REQUIREMENT_CHECKS = ("risk", "ending_early_never_pays", "goal_earlier_never_pays_less",
                      "stalling_never_pays")


@dataclass(frozen=True)
class Requirement:
    """``require CHECK`` or ``require risk <= BOUND``: the check's failure is an error, not a warning."""

    check: str  # one of REQUIREMENT_CHECKS
    bound: Fraction | None = None  # for ``risk``: the largest p* allowed
    span: Span | None = field(default=None, compare=False)


@dataclass(frozen=True)
class Automaton:
    """A checked reward automaton."""

    name: str
    inputs: tuple[Input, ...]
    rewards: tuple[str, ...]
    locations: tuple[Location, ...]
    initial: int
    #: Edges grouped by source location, in source order (``*`` already expanded).
    edges: tuple[tuple[Edge, ...], ...]
    end_clauses: tuple[EndClause, ...]
    #: The ``assume`` declarations, in source order.
    assumptions: tuple[Assumption, ...]
    objective: Linear
    priority: tuple[str, ...]
    strict: bool
    period: Fraction
    horizon: Fraction
    constants: tuple[tuple[str, Fraction | bool], ...] = ()
    #: The ``param`` declarations (each resolved as a constant of the value it records).
    parameters: tuple[Parameter, ...] = ()
    #: ``episode ends when COND``: after a sample's edge, the run ends when COND holds on that
    #: sample's inputs (its ``at end`` clauses read the same inputs). None: runs last the horizon.
    episode_ends: Guard | None = None
    #: ``goal when COND``: a run reaches the goal at a sample where COND holds on its inputs.
    goal: Guard | None = None
    #: ``collision when COND``: a run collides (is unsafe) at a sample where COND holds.
    collision: Guard | None = None
    #: The ``require`` declarations, in source order.
    requirements: tuple[Requirement, ...] = ()
    #: The scenario model from the `model` block, if the file has one.
    model: ModelSpec | None = None
    #: The file's queries, checked (:mod:`rac.ir.query`).
    queries: tuple[QueryDecl, ...] = field(default=(), compare=False)
    #: With a `model` block: the paper's standard queries over it (Qa-Qd, Fig. 7's simulations,
    #: the learning queries), checked like the file's (:mod:`rac.check.standard`).
    standard_queries: tuple[QueryDecl, ...] = field(default=(), compare=False)
    source: ast.Automaton | None = field(default=None, compare=False, repr=False)
    spans: dict[str, Span] = field(default_factory=dict, compare=False, repr=False)

    @property
    def assume(self) -> Guard:
        """What every input valuation satisfies: the assumptions together (``true`` without any)."""
        if not self.assumptions:
            return TRUE
        guards = tuple(a.guard for a in self.assumptions)
        return guards[0] if len(guards) == 1 else BAnd(guards)

    @property
    def ending(self) -> Guard | None:
        """The condition that ends a run at a sample (``episode ends when COND``), or None when no
        sample ends it (no declaration, or a condition that is constantly false): the one rule every
        runtime, target, engine and static analysis follows.

        At a sample, after the accrual and the edge: if COND holds on the inputs just read, every end
        clause whose guard holds on those same inputs is applied, in order, the sample's objective
        increase includes theirs, and the run ends there (no further sample, no later ``end``)."""
        ends = self.episode_ends
        return None if ends is None or ends == BConst(False) else ends

    @property
    def steps(self) -> int:
        """Samples in a run of the full horizon."""
        return int(self.horizon / self.period)

    @property
    def rates_read_inputs(self) -> bool:
        """Whether some rate reads an input (then the first sample's rewards accrue with its inputs)."""
        return any(rate.terms for location in self.locations for rate in location.rates)

    @property
    def location_names(self) -> tuple[str, ...]:
        return tuple(loc.name for loc in self.locations)

    def input(self, name: str) -> Input:
        for item in self.inputs:
            if item.name == name:
                return item
        raise KeyError(name)

    @property
    def numeric_inputs(self) -> tuple[Input, ...]:
        return tuple(i for i in self.inputs if not i.is_bool)

    @property
    def bool_inputs(self) -> tuple[Input, ...]:
        return tuple(i for i in self.inputs if i.is_bool)

    def all_edges(self) -> tuple[Edge, ...]:
        return tuple(e for group in self.edges for e in group)

    def first_non_translation(self) -> tuple[str, str] | None:
        """The first update that is not a translation ``r = r + c`` (``c`` free of rewards: ``sa = sa * 2``,
        ``sa = 0``, ``pr = sa`` are not), as its reward and where it is (``"the edge A -> B"``, ``"an `at end`
        clause"``); None when every update is one, so that a reward's change never depends on the values."""
        names = self.location_names
        places = [(f"the edge {names[edge.source]} -> {names[edge.target]}", edge.updates) for edge in self.all_edges()]
        places += [("an `at end` clause", clause.updates) for clause in self.end_clauses]
        for where, updates in places:
            for update in updates:
                read = [name for name in update.value.variables() if name in self.rewards]
                if update.value.coefficient(update.reward) != 1 or any(name != update.reward for name in read):
                    return update.reward, where
        return None


def guard_leaves(guard: Guard) -> list[BInput | BAtom]:
    """The input reads of a guard (boolean inputs and numeric atoms), first occurrence order."""
    found: dict[BInput | BAtom, None] = {}

    def walk(node: Guard) -> None:
        if isinstance(node, (BInput, BAtom)):
            found.setdefault(node, None)
        elif isinstance(node, BNot):
            walk(node.operand)
        elif isinstance(node, (BAnd, BOr)):
            for operand in node.operands:
                walk(operand)
        elif not isinstance(node, BConst):
            raise TypeError(f"not a guard: {node!r}")

    walk(guard)
    return list(found)


def evaluate_guard(guard: Guard, values: dict[str, object]) -> bool:
    """Exact evaluation of a guard on one input valuation (bools and Fractions/floats). ``and``/``or``
    stop at their first deciding operand (the fold builds thunks), so an input read only past it
    may be missing from ``values``."""
    lazy: GuardFold[Callable[[], bool]] = GuardFold(
        const=lambda value: lambda: value,
        boolean=lambda leaf: lambda: bool(values[leaf.name]),
        atom=lambda leaf: lambda: compare(values[leaf.input], leaf.op, leaf.threshold),
        negate=lambda inner: lambda: not inner(),
        conjoin=lambda parts: lambda: all(part() for part in parts),
        disjoin=lambda parts: lambda: any(part() for part in parts))
    return lazy(guard)()


def compare(left, op: str, right) -> bool:
    if op == "<":
        return left < right
    if op == "<=":
        return left <= right
    if op == ">":
        return left > right
    if op == ">=":
        return left >= right
    if op == "==":
        return left == right
    return left != right
