"""Queries and bindings in UPPAAL syntax, printed from the checked IR (:mod:`rac.ir.expr`, :mod:`rac.ir.query`).

One printer serves both UPPAAL targets and three dialects, which differ only in how a few names
and operators are written (the tables below):

- ``SYMBOLIC`` (``A[]``, ``E<>``, ``E[]``, ``A<>``, ``-->``, ``control:``, discrete observations):
  UPPAAL's symbolic engine reads no double in a query, so rewards are their integer mirrors,
  numbers their significands and ``time`` the sample counter ``count`` (``count * C1`` seconds: the
  engine's time, which stands still between samples and after the run, where UPPAAL's clock
  ``time`` flows on). A comparison whose sides are linear in such integers is printed as one exact
  comparison of integers (``v > 30`` is ``v > 300000``). Any
  other condition — one that computes with doubles, like ``mindist() < 3 * collision_distance`` —
  becomes a function of the declarations that returns a ``bool`` (:attr:`UppaalPrinter.conditions`):
  the query calls it, as it calls ``collide()``, passing ``Process.location`` when the condition reads
  the location index (a function of the declarations cannot name a process's location);
- ``STATISTICAL`` (``Pr``, ``E``, ``simulate``, learning): doubles are allowed; rewards are their
  hybrid clocks, the true state the ``Dynamics`` process's clocks;
- ``FUNCTION`` (the body of such a condition, and the bindings, which the emitted model evaluates in
  functions): the subset of expressions valid in UPPAAL's functions and in C, so that the tests
  compile it with the system C compiler and compare it with the engine. ``a imply b`` is ``!a || b``
  there.

The printer extends :class:`rac.targets.uppaal.expr.UppaalSyntax`, whose operator table puts the
parentheses. Numbers are printed the way the engine computes them: a double expression is printed as
its tree (no reordering), constants as double literals, a significand as ``i2d(s)``
(``s / SCALE_D``); an exact comparison as integers. :class:`QueryError` says why a query cannot be written over the
emitted model (e.g. a symbolic query that reads the true state).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from fractions import Fraction

from rac.core.diagnostics import short_number
from rac.core.numbers import INT32_LOW, INT32_MAX, INT32_MIN
from rac.core.printing import Level, Printed, number, signed_sum
from rac.ir import compare
from rac.ir import expr as ie
from rac.ir import query as iq
from rac.ir.significands import common_denominator
from rac.ir.vocabulary import ACTIONS, Holding
from rac.targets.uppaal.expr import NotRepresentable, QueryError, UppaalSyntax, double_literal, int_literal, terms_text

__all__ = ["FUNCTION", "STATISTICAL", "SYMBOLIC", "Condition", "ModelNames", "UppaalPrinter", "Vocabulary",
           "time_bound"]

SYMBOLIC, STATISTICAL, FUNCTION = "symbolic", "statistical", "function"

_FLIP = {"<": ">", "<=": ">=", ">": "<", ">=": "<=", "==": "==", "!=": "!="}


@dataclass(frozen=True)
class ModelNames:
    """How the whole model names the scenario model's vocabulary (absent in the automaton-alone model)."""

    #: The process holding the true state's hybrid clocks (``Dynamics``).
    dynamics: str
    #: The constant holding the horizon in time units (``MAXT``).
    maxt: str
    #: The Timer process and its location between samples: waiting there at a decision sample, after
    #: ``decide!``, ``jerk`` and ``turn`` already hold the newly chosen action beside the decision
    #: sample's state (rac's engine shows it from the next sample on, and has no such state).
    timer: str
    wait: str
    #: The constant holding the samples between two decisions (C2 / C1; declared by
    #: :mod:`rac.targets.uppaal.declarations`).
    decide_every: str
    #: The location of :attr:`dynamics` once its start edge has set the true state: before it, in the
    #: model's initial state, the true state's hybrid clocks are 0 (rac's engine has no such state).
    running: str


@dataclass(frozen=True)
class Vocabulary:
    """The UPPAAL names of everything a query or a binding reads in one emitted model.

    ``mirrors`` and ``hybrids`` map each reward to its integer mirror and its hybrid clock;
    ``significands`` each numeric input to its ``int32_t`` global; ``bools`` each boolean input;
    ``locations`` each location to its UPPAAL name inside ``process``. ``count`` is the sample
    counter, which every dialect reads as ``time`` (``count * C1`` seconds); ``unit`` the time unit of
    the time bounds (``Pr[<=T]``) in seconds; ``settled`` a global that is false exactly while the
    inputs are newer than the location. ``model`` is None in the automaton-alone model.
    """

    automaton: str
    process: str
    locations: Mapping[str, str]
    bools: Mapping[str, str]
    significands: Mapping[str, str]
    mirrors: Mapping[str, str]
    hybrids: Mapping[str, str]
    strategies: Mapping[str, str]
    scale: int
    unit: Fraction
    count: str
    settled: str
    horizon: Fraction
    #: The sample period C1 in seconds, and the constant holding it in time units (``PERIOD``).
    period: Fraction = Fraction(1)
    period_name: str = "PERIOD"
    #: The constant holding the samples of a run (``STEPS``): ``time`` at the horizon is ``count == STEPS``.
    steps_name: str = "STEPS"
    model: ModelNames | None = None
    #: Why the scenario model's names are missing (the message of :class:`QueryError`).
    no_model: str = "the automaton-alone UPPAAL model has no scenario-model names"
    #: The parameter through which a condition of a symbolic query receives ``process.location`` (a
    #: fresh name, so that it hides none of the globals the condition reads).
    location_parameter: str = "loc"


@dataclass(frozen=True)
class Condition:
    """A condition of a symbolic query that computes with doubles, declared as
    ``bool name(int32_t parameter) { return body; }`` (no parameter: ``name()``) and called by the
    query as ``name(argument)``: the argument is ``process.location`` where the body reads the location
    index, which only a query (not a function of the declarations) can name."""

    name: str
    body: str
    parameter: str | None = None
    argument: str = ""

    @property
    def call(self) -> str:
        """The call in the query."""
        return f"{self.name}({self.argument})"

    @property
    def signature(self) -> str:
        """The function's parameter list (empty, or ``int32_t loc``)."""
        return "" if self.parameter is None else f"int32_t {self.parameter}"


@dataclass
class UppaalPrinter(UppaalSyntax):
    """Print checked queries and bindings over one emitted model.

    ``fresh(base)`` names a new function of the declarations; :attr:`conditions` collects the
    conditions of symbolic queries that compute with doubles, by body, each to be declared as a
    function returning ``bool`` (:class:`Condition`; identical bodies share one function).
    """

    v: Vocabulary
    fresh: Callable[[str], str] = str
    conditions: dict[str, Condition] = field(default_factory=dict)  # by body
    #: In the bindings' function: the local variable holding each ``prev(e)``'s value, by ``e``.
    prevs: dict[ie.Expr, str] = field(default_factory=dict)
    #: Write ``a imply b`` as ``!a || b`` in every dialect (C has no ``imply``; the tests compile
    #: query expressions printed so against the engine's values).
    c_syntax: bool = False
    #: While a condition of a symbolic query is printed: the parameter holding the location index.
    located: str | None = None

    # ------------------------------------------------------------ whole queries
    def formula(self, query: iq.Query) -> str:
        """The query as one line of UPPAAL property syntax (:class:`QueryError` when it cannot be written)."""
        if not (isinstance(query, iq.PathQuery) and query.quantifier in ("A[]", "E<>")) and any(
                r.kind is ie.RefKind.DEADLOCK for e in iq.query_exprs(query) for r in ie.refs(e)):
            # UTAP's PropertyBuilder: `$Cannot_handle_this_deadlock_predicate` in any other query
            raise QueryError("UPPAAL reads `deadlock` only in `A[] p` and `E<> p` queries")
        if isinstance(query, iq.PathQuery):
            text = f"{query.quantifier} {self.state(query.expr, SYMBOLIC, query.quantifier in ('A[]', 'E[]')).text}"
        elif isinstance(query, iq.LeadsToQuery):
            left, right = self.state(query.left, SYMBOLIC, False), self.state(query.right, SYMBOLIC, False)
            text = f"{left.text} --> {right.text}"
        elif isinstance(query, iq.ControlStrategy):
            body = self.state(query.expr, SYMBOLIC, query.goal == "A[]").text
            # UPPAAL 5 states a reachability objective as `control: A<> p` (the strategy forces p)
            goal = "A<>" if query.goal == "E<>" else query.goal
            text = f"strategy {self._strategy(query.name)} = control: {goal} {body}"
        elif isinstance(query, iq.ProbabilityQuery):
            body = self.state(query.expr, STATISTICAL, query.path == "[]").text
            if query.compare is not None and query.runs is not None:
                raise QueryError("UPPAAL tests a probability against a threshold sequentially, choosing the "
                                 "number of runs itself: drop `;N` from the bound")
            text = f"Pr[{self._bound(query.bound, query.runs)}]({query.path} {body})"
            if query.compare is not None:
                op, threshold = query.compare
                if op not in (">=", "<="):
                    raise QueryError(f"UPPAAL compares a probability with `>=` or `<=` only, not `{op}`")
                text += f" {op} {double_literal(threshold)}"
        elif isinstance(query, iq.ExpectationQuery):
            text = (f"E[{self._bound(query.bound, query.runs)}]"
                    f"({query.aggregate}: {self.extreme(query.expr, query.aggregate).text})")
        elif isinstance(query, iq.SimulateQuery):
            exprs = ", ".join(self.any(e) for e in query.exprs)
            text = f"simulate[{self._bound(query.bound, query.runs)}]{{{exprs}}}"
        elif isinstance(query, iq.LearnStrategy):
            if query.path != "<>":
                raise QueryError("UPPAAL learns reachability goals only (`: <> p`)")
            discrete = ", ".join(self.discrete(e) for e in query.discrete)
            continuous = ", ".join(self.any(e) for e in query.continuous)
            body = self.state(query.expr, STATISTICAL, query.path == "[]").text
            text = (f"strategy {self._strategy(query.name)} = {query.optimise}("
                    f"{self.number(query.objective, STATISTICAL).text})[{self._bound(query.bound, None)}]"
                    f"{{{discrete}}}->{{{continuous}}}: {query.path} {body}")
        else:
            raise TypeError(f"not a query: {query!r}")
        under = getattr(query, "under", None)
        if under is not None:
            text += f" under {self._strategy(under)}"
        return text

    def _strategy(self, name: str) -> str:
        return self.v.strategies.get(name, name)

    def _bound(self, bound: iq.Bound, runs: int | None) -> str:
        if bound.kind == "time":
            units = bound.limit / self.v.unit
            # the model's time unit divides every bound it can (automaton.py), all but one whose unit would
            # put a duration of the model beyond int32 (UPPAAL's lexer: `$Overflow`)
            if units.denominator != 1:
                raise QueryError(f"the time bound {short_number(bound.limit, 12)} s needs a time unit so fine that "
                                 f"the model's durations in it leave the 32-bit integer range (the model's unit is "
                                 f"{_short(self.v.unit)} s)")
            if units > INT32_MAX:
                raise QueryError(f"the time bound {short_number(bound.limit, 12)} s is {short_number(units)} time "
                                 f"units of {_short(self.v.unit)} s, beyond the 32-bit integer range")
            text = "<=" + (self.v.model.maxt if self.v.model is not None and bound.limit == self.v.horizon
                           else int_literal(units))
        else:
            text = "#<=" + int_literal(bound.limit)
        return text if runs is None else f"{text};{int_literal(runs)}"

    # ------------------------------------------------------------ conditions
    def state(self, expr: ie.Expr, dialect: str, box: bool) -> Printed:
        """A state formula, over the states rac's engine has too. When it reads an input, states where
        the inputs are newer than the location (``settled`` false) are left out; when it reads ``jerk``
        or ``turn``, the period after a decision, where they already hold the new choice
        (:attr:`ModelNames.wait`). ``g imply p`` under ``[]``, else ``g && p``."""
        text = self.condition(expr, dialect)
        reads_inputs = any(r.kind is ie.RefKind.INPUT for r in ie.refs(expr))
        settled = [Printed(self.v.settled, Level.ATOM)] if reads_inputs else []
        guard = self._all_of([*settled, *self._model_guards(expr)])
        if guard is None:
            return text
        if box and self.c_syntax:
            return self.infix("||", self.prefix("!", guard), text)
        if box:
            return self.infix("imply", guard, text)
        return self.infix("&&", guard, text)

    def _model_guards(self, expr: ie.Expr) -> list[Printed]:
        """The whole model's states that ``expr`` is not read in, as conditions to hold: not the period
        after a decision (:meth:`_not_after_decision`), not before the true state is set (:meth:`_truth_started`)."""
        return [g for g in (self._not_after_decision(expr), self._truth_started(expr)) if g is not None]

    def _all_of(self, guards: list[Printed]) -> Printed | None:
        """``guards`` joined by ``&&`` (None for none)."""
        if not guards:
            return None
        guard = guards[0]
        for more in guards[1:]:
            guard = self.infix("&&", guard, more)
        return guard

    def _not_after_decision(self, expr: ie.Expr) -> Printed | None:
        """``!(Timer.Wait && count % DECIDE_EVERY == 0)`` when ``expr`` reads ``jerk`` or ``turn`` in the
        whole model: false in the period after a decision, where they already hold the new choice
        beside the decision sample's state (rac's engine shows it from the next sample on); else None."""
        if self.v.model is None or not any(r.is_model and r.model.kind == "ego" and r.name in ACTIONS
                                           for r in ie.refs(expr)):
            return None
        model = self.v.model
        chosen = f"({model.timer}.{model.wait} && {self.v.count} % {model.decide_every} == 0)"
        return self.prefix("!", Printed(chosen, Level.ATOM))

    def _truth_started(self, expr: ie.Expr) -> Printed | None:
        """``Dynamics.Running`` when ``expr`` reads the true state in the whole model: false only in the
        model's initial state, where the true state's hybrid clocks are still 0 (``Dynamics`` sets them
        to the ego's start on its first, committed edge, at time 0). rac's engine starts the truth at the
        ego's start, so without the guard `Pr[<=T](<> fabs(true_x - x) >= sensor_error)` held in every run
        of the emitted model, at its first state; else None."""
        if self.v.model is None or not ie.reads_truth(expr):
            return None
        return Printed(f"{self.v.model.dynamics}.{self.v.model.running}", Level.ATOM)

    def extreme(self, expr: ie.Expr, aggregate: str) -> Printed:
        """The expression of ``E[..](max: e)`` (``aggregate`` ``max`` or ``min``), a double. Where ``e``
        reads ``jerk`` or ``turn``, the period after a decision counts as ``-DBL_MAX`` (``DBL_MAX`` for
        ``min``): a decision at the bound's last sample would otherwise bring a choice into the run's
        extreme that rac's engine, which shows a choice from the next sample on, never reaches. The
        action the decision replaced is still counted: the states before ``decide!`` hold it, at the
        same instant."""
        value = self.number(expr, STATISTICAL)
        guard = self._all_of(self._model_guards(expr))
        if guard is None:
            return value
        neutral = "-DBL_MAX" if aggregate == "max" else "DBL_MAX"
        return Printed(f"({guard.text} ? {value.text} : {neutral})", Level.ATOM)

    def condition(self, expr: ie.Expr, dialect: str) -> Printed:
        """A boolean expression."""
        if isinstance(expr, ie.Const):
            return self.literal(bool(expr.value))
        if isinstance(expr, ie.Ref):
            return Printed(self._name(expr, dialect), Level.ATOM)
        if isinstance(expr, ie.Unary):
            return self.prefix("!", self.condition(expr.operand, dialect))
        if isinstance(expr, ie.Binary):
            left, right = self.condition(expr.left, dialect), self.condition(expr.right, dialect)
            if expr.op == "imply" and (dialect == FUNCTION or self.c_syntax):
                return self.infix("||", self.prefix("!", left), right)
            return self.infix(expr.op, left, right)
        if isinstance(expr, ie.Call):
            return Printed(self._call(expr, dialect), Level.ATOM)
        if isinstance(expr, ie.Prev):
            return Printed(self._prev(expr, dialect), Level.ATOM)
        assert isinstance(expr, ie.Compare)
        if expr.left.type == ie.BOOL:
            return self.infix(expr.op, self.condition(expr.left, dialect), self.condition(expr.right, dialect))
        exact = self._exact(expr, dialect)
        if exact is not None:
            return exact
        if dialect == SYMBOLIC:
            return Printed(self._hoisted(expr), Level.ATOM)
        return self.infix(expr.op, self.number(expr.left, dialect), self.number(expr.right, dialect))

    def _hoisted(self, expr: ie.Compare) -> str:
        """A condition of a symbolic query that computes with doubles, as a call of a function. A function
        of the declarations cannot name a process's location, so one that reads the location index gets
        it as a parameter, and the query passes ``process.location`` (as rac's engine reads it: the
        integer of the current location)."""
        reads_location = any(r.kind is ie.RefKind.LOCATION_INDEX for r in ie.refs(expr))
        self.located = self.v.location_parameter if reads_location else None
        try:
            body = self.condition(expr, FUNCTION).text
        except QueryError as exc:
            raise QueryError(f"a symbolic query cannot compute this comparison: {exc}") from None
        finally:
            self.located = None
        if body not in self.conditions:
            parameter = self.v.location_parameter if reads_location else None
            argument = f"{self.v.process}.location" if reads_location else ""
            self.conditions[body] = Condition(self.fresh("cond"), body, parameter, argument)
        return self.conditions[body].call

    def _exact(self, expr: ie.Compare, dialect: str) -> Printed | None:
        """``left op right`` as an exact comparison of integers, when both sides are linear in values
        held as integers in this dialect; None otherwise."""
        form = expr.linear
        if form is None:
            return None
        if form.is_constant:
            return self.literal(compare(form.const, expr.op, 0))
        terms = []
        for ref, coefficient in form.terms:
            held = self._integer(ref, dialect)
            if held is None:
                return None
            name, unit = held
            terms.append((name, coefficient * unit))
        multiplier = math.lcm(*(c.denominator for _, c in terms))
        coefficients = [(int(c * multiplier), name) for name, c in terms]
        bound = -form.const * multiplier
        op = expr.op
        if coefficients[0][0] < 0:
            coefficients = [(-c, n) for c, n in coefficients]
            bound, op = -bound, _FLIP[op]
        if len(coefficients) == 1 and coefficients[0][0] != 1:
            # one integer times c > 0: compare the integer itself with bound / c, exactly (on the
            # integers it keeps its truth), rather than a product that may leave int32 or 2**53
            # (`2147483647 * d > 1` is `d > 0`)
            bound, coefficients = bound / coefficients[0][0], [(1, coefficients[0][1])]
        result = ie.integer_bound(op, bound)
        if isinstance(result, bool):
            return self.literal(result)
        op, whole = result
        if coefficients == [(1, self.v.count)] and whole * self.v.period == self.v.horizon:
            return Printed(f"{self.v.count} {op} {self.v.steps_name}", Level.COMPARE)
        truth = self._beyond(coefficients, op, whole) if abs(whole) > INT32_MAX else None
        if truth is not None:  # no int32 literal holds the threshold, and no value of the sum reaches it
            return self.literal(truth)
        largest = sum(abs(c) * self._largest(name) for c, name in coefficients)
        if largest <= INT32_MAX:
            if whole == INT32_MIN:  # one mirror, which may hold it, but no literal writes it: its neighbour
                least: dict[str, bool | tuple[str, int]] = {
                    "<": False, ">=": True, ">": (">=", INT32_LOW), "<=": ("<", INT32_LOW), "==": ("<", INT32_LOW),
                    "!=": (">=", INT32_LOW)}  # the mirror is never below it
                rewritten = least[op]
                if isinstance(rewritten, bool):
                    return self.literal(rewritten)
                op, whole = rewritten
            return Printed(f"{terms_text(coefficients)} {op} {int_literal(whole)}", Level.COMPARE)
        # a sum of int32 values may leave int32 (10*iSa with iSa = -3e8): compute it in doubles, exact
        # for integers below 2**53, in a condition of the declarations when the query is symbolic
        if largest + abs(whole) >= 2**53:
            raise NotRepresentable(f"the comparison's coefficients are too large to be computed exactly "
                                   f"({short_number(Fraction(largest + abs(whole)))} >= 2**53)")
        if dialect == SYMBOLIC:
            return Printed(self._hoisted(expr), Level.ATOM)
        (first, name), *rest = coefficients  # the first coefficient is positive (flipped above)
        parts = [(False, f"{double_literal(first)} * {name}")]
        parts += [(c < 0, name if abs(c) == 1 else f"{double_literal(abs(c))} * {name}") for c, name in rest]
        text = signed_sum(parts)
        return Printed(f"{text} {op} {double_literal(whole)}", Level.COMPARE)

    def _beyond(self, coefficients: list[tuple[int, str]], op: str, whole: int) -> bool | None:
        """``Σ c*name op whole`` where ``whole`` lies beyond every value the sum takes (each name within
        the range its integer holds: ``x > 1000000`` is ``x > 10000000000`` on an int32, never true),
        or None when some value reaches it. The engine compares exactly and gives the same truth."""
        low = high = 0
        for c, name in coefficients:
            ends = [c * end for end in self._range(name)]
            low, high = low + min(ends), high + max(ends)
        if whole > high:
            return op in ("<", "<=", "!=")
        if whole < low:
            return op in (">", ">=", "!=")
        return None

    def _is_location(self, name: str) -> bool:
        """Whether the integer ``name`` is the location index (in a query, or a condition's parameter)."""
        return name == f"{self.v.process}.location" or (self.located is not None and name == self.located)

    def _range(self, name: str) -> tuple[int, int]:
        """The least and greatest value the integer ``name`` holds: a location index, the sample counter,
        or any int32 (a mirror may hold ``INT32_MIN``)."""
        if self._is_location(name):
            return 0, max(0, len(self.v.locations) - 1)
        if name == self.v.count:
            return 0, math.ceil(self.v.horizon / self.v.period)
        return INT32_MIN, INT32_MAX

    def _largest(self, name: str) -> int:
        """The largest magnitude the integer ``name`` holds: a location index, the sample counter, or any int32."""
        if self._is_location(name):
            return max(1, len(self.v.locations))
        if name == self.v.count:
            return math.ceil(self.v.horizon / self.v.period)
        return INT32_MAX

    def _integer(self, ref: ie.Ref, dialect: str) -> tuple[str, Fraction] | None:
        """The integer that holds ``ref`` in this dialect and the value of one of its units, or None."""
        v = self.v
        if ref.kind is ie.RefKind.INPUT:
            return v.significands[ref.name], Fraction(1, v.scale)
        if ref.kind is ie.RefKind.REWARD:
            return (v.mirrors[ref.name], Fraction(1, v.scale)) if dialect != STATISTICAL else None
        if ref.kind is ie.RefKind.LOCATION_INDEX:
            if dialect == FUNCTION:  # only a condition of a symbolic query receives it (a parameter)
                return (self.located, Fraction(1)) if self.located is not None else None
            return f"{v.process}.location", Fraction(1)
        entry = ref.model
        if entry.holding is Holding.SIGNIFICAND and entry.kind == "ego":
            self._model(ref.name)
            return entry.uppaal, Fraction(1, v.scale)
        if entry.holding is Holding.TIME:  # the engine's k * C1 at sample k, in every dialect
            return v.count, v.period
        return None

    # ------------------------------------------------------------ numbers (doubles)
    def number(self, expr: ie.Expr, dialect: str) -> Printed:
        """A numeric expression as a double, printed as its tree (the engine computes the same)."""
        if expr.type == ie.BOOL:  # a condition counting 0 or 1 (reward expressions), always in parentheses
            return Printed(f"({self.condition(expr, dialect).text})", Level.ATOM)
        if isinstance(expr, ie.Const):
            return number(double_literal(expr.value))
        if isinstance(expr, ie.Ref):
            return self._number_name(expr, dialect)
        if isinstance(expr, ie.Call):
            return Printed(self._call(expr, dialect), Level.ATOM)
        if isinstance(expr, ie.Prev):
            return Printed(self._prev(expr, dialect), Level.ATOM)
        if isinstance(expr, ie.Unary):
            return self.prefix("-", self.number(expr.operand, dialect))
        assert isinstance(expr, ie.Binary)
        return self.infix(expr.op, self.number(expr.left, dialect), self.number(expr.right, dialect))

    def _number_name(self, ref: ie.Ref, dialect: str) -> Printed:
        v = self.v
        scale = double_literal(v.scale)
        if ref.kind is ie.RefKind.INPUT:
            return Printed(f"{v.significands[ref.name]} / {scale}", Level.MUL)
        if ref.kind is ie.RefKind.REWARD:
            if dialect == STATISTICAL:
                return Printed(v.hybrids[ref.name], Level.ATOM)
            return Printed(f"{v.mirrors[ref.name]} / {scale}", Level.MUL)
        if ref.kind is ie.RefKind.LOCATION_INDEX:
            if dialect == FUNCTION and self.located is None:
                raise QueryError("a location cannot be read in a condition computed with doubles")
            # a double, as the engine reads it: UPPAAL's integer `-P.location` is 0 where the engine's
            # -(0.0) is -0.0, so `1 / -P.location` would be inf in one and -inf in the other
            held = self.located if dialect == FUNCTION else f"{v.process}.location"
            return Printed(f"{held} * 1.0", Level.MUL)
        if ref.kind is not ie.RefKind.MODEL:
            raise QueryError(f"`{ref.name}` is not a number")
        entry = ref.model
        model = self._model(ref.name) if entry.holding is not Holding.TIME else None
        if entry.holding is Holding.SIGNIFICAND:
            return Printed(f"i2d({entry.uppaal})", Level.ATOM)
        if entry.holding is Holding.EXACT:
            assert ref.value is not None
            return Printed(entry.uppaal, Level.ATOM) if entry.uppaal else number(double_literal(ref.value))
        if entry.holding is Holding.TIME:  # k * C1 at sample k, the double the engine computes
            return Printed(f"{v.count} * {double_literal(v.period)}", Level.MUL)
        if dialect != STATISTICAL:
            raise QueryError(f"`{ref.name}` is the ground truth, which only statistical queries (Pr, E, simulate) "
                             "follow")
        assert model is not None
        return Printed(f"{model.dynamics}.{entry.uppaal}", Level.ATOM)

    def _model(self, name: str = "") -> ModelNames:
        if self.v.model is None:
            raise QueryError(f"`{name}` is not a name of the automaton `{self.v.automaton}` ({self.v.no_model})"
                             if name else self.v.no_model)
        return self.v.model

    def _prev(self, expr: ie.Prev, dialect: str) -> str:
        if dialect == FUNCTION and expr.operand in self.prevs:
            return self.prevs[expr.operand]
        raise QueryError(_PREV)

    # ------------------------------------------------------------ names and calls
    def _name(self, ref: ie.Ref, dialect: str) -> str:
        v = self.v
        if ref.kind is ie.RefKind.INPUT:
            return v.bools[ref.name]
        if ref.kind is ie.RefKind.LOCATION:
            if dialect == FUNCTION:
                raise QueryError("a location cannot be read in a condition computed with doubles")
            return f"{v.process}.{v.locations[ref.name]}"
        if ref.kind is ie.RefKind.DEADLOCK:
            if dialect == FUNCTION:
                raise QueryError("`deadlock` cannot be read in a condition computed with doubles")
            return "deadlock"
        raise QueryError(f"`{ref.name}` is not a condition")

    def _call(self, call: ie.Call, dialect: str) -> str:
        function = call.function
        if function.kind == "model":
            if self.v.model is None:
                raise QueryError(f"`{function.name}()` is a function of the scenario model, which the "
                                 f"automaton-alone UPPAAL model does not contain")
            return f"{function.uppaal}()"
        args = ", ".join(self.number(a, dialect).text for a in call.args)
        return f"{function.uppaal}({args})"

    # ------------------------------------------------------------ observations
    def any(self, expr: ie.Expr) -> str:
        """A simulated or continuously observed expression: a condition or a (double) number."""
        if expr.type == ie.BOOL:
            return self.condition(expr, STATISTICAL).text
        return self.number(expr, STATISTICAL).text

    def discrete(self, expr: ie.Expr) -> str:
        """A discrete observation of a learning query: an integer expression (mirrors, significands)."""
        if expr.type == ie.BOOL:
            return self.condition(expr, SYMBOLIC).text
        form = ie.linear_form(expr)
        terms = []
        for ref, coefficient in form.terms if form is not None else ():
            held = self._integer(ref, SYMBOLIC)
            if held is None:
                form = None
                break
            terms.append((held[0], coefficient * held[1]))
        if form is None:
            raise QueryError("a discrete observation must be linear in rewards, inputs, the ego state, `time` "
                             "and `Automaton.location` (it is observed as integers: mirrors and significands)")
        # observed as the smallest whole multiple: `x` is the significand, `sa + pr` the mirrors' sum
        _, constant, whole = common_denominator(form.const, [(c, name) for name, c in terms])
        if not whole:
            return int_literal(constant)
        text = terms_text(whole)
        return signed_sum([(False, text), (constant < 0, int_literal(abs(constant)))]) if constant else text

    # ------------------------------------------------------------ bindings
    def binding(self, expr: ie.Expr) -> str:
        """A binding's expression in the function dialect (numbers as doubles, conditions as bools)."""
        if expr.type == ie.BOOL:
            return self.condition(expr, FUNCTION).text
        return self.number(expr, FUNCTION).text


_PREV = ("`prev(...)` cannot be read by a query over the emitted model: the model keeps the previous sample "
         "only while it reads the inputs")


def _short(value: Fraction) -> str:
    if value.denominator == 1:
        return str(value.numerator)
    text = f"{float(value):.6g}"
    return text if Fraction(text) == value else f"{value.numerator}/{value.denominator}"


def time_bound(query: iq.Query) -> Fraction | None:
    """The time bound of a query in seconds (``Pr[<=30]`` needs 30 s as whole time units), or None.

    Comparisons of ``time`` need no time unit: they read the sample counter."""
    bound = getattr(query, "bound", None)
    return bound.limit if bound is not None and bound.kind == "time" else None
