"""Query and binding expressions over arrays of model states (issue 4), read from the checked IR.

The engine evaluates a checked expression (:mod:`rac.ir.expr`: every name already resolved and
typed by the checker) for ``n`` states at once: one :class:`Frame` holds what the expression may
read at one sample — the sample index, the sensed ego significands, optionally the ground truth,
the automaton's location, rewards and inputs, and the frame of the previous sample for ``prev(e)``.

Numbers follow the emitted UPPAAL/C code (:mod:`rac.targets.uppaal.query` prints the same tree),
so a binding evaluated here gives the double the emitted ``read_inputs()`` computes: every name is
read as :mod:`rac.ir.vocabulary` says the model holds it — an ego name is ``significand / SCALE_D``,
``time`` is ``k * C1``, a setting the model holds as a significand (``collision_distance``,
``length``, ...) is that significand over ``SCALE_D``, any other setting or literal the nearest
double. A comparison whose sides are linear in values held as integers here (ego significands,
``time``, the location index, and — when the frame holds them — input significands and reward
mirrors) is decided exactly on those integers, as the emitted model compares them. Booleans are
numpy ``bool`` arrays, numbers ``float64`` arrays.

Example::

    evaluator = Evaluator(data, automaton)
    frame = Frame(k=np.full(n, 3), ego=states)
    unsafe = evaluator.evaluate(lower_expression(automaton, "mindist() < 3 * collision_distance"), frame)
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from fractions import Fraction

import numpy as np

from rac import ir
from rac.core.diagnostics import RacError
from rac.core.numbers import INT32_BOUND
from rac.core.source import Span
from rac.ir import expr as ie
from rac.ir.vocabulary import Holding
from rac.model.batch import batch_model
from rac.model.data import ModelData
from rac.model.sample import collides

__all__ = ["EvaluationError", "Evaluator", "Frame", "c_round", "int_sum"]

_MATH_1 = {"abs": np.abs, "fabs": np.abs, "sqrt": np.sqrt, "floor": np.floor, "ceil": np.ceil, "trunc": np.trunc}
_COMPARE = {"<": np.less, "<=": np.less_equal, ">": np.greater, ">=": np.greater_equal, "==": np.equal,
            "!=": np.not_equal}
_SAFE_INT64 = 2**62


class EvaluationError(RacError, ValueError):
    """An expression reads something the frame does not hold (e.g. ``true_x`` in an exhaustive query)."""

    def __init__(self, message: str, span: Span | None = None) -> None:
        super().__init__(message)
        self.span = span


@dataclass(frozen=True)
class Frame:
    """What an expression reads at one sample, for ``n`` states.

    ``k`` (n,) sample indices; ``ego`` (n, 7) sensed significands (:data:`rac.ir.vocabulary.EGO_STATE`
    order); ``truth`` (n, 5) true ``x, y, v, acc, head`` (metres, seconds) or None; ``location`` (n,)
    automaton location indices; ``rewards`` name -> (n,) float64 values; ``inputs`` name -> (n,)
    values (bool, or float64 reals); ``prev`` the frame of the previous sample (``prev(e)`` at the
    first sample is ``e`` itself, as in the emitted model). ``mirrors`` (reward -> int mirrors) and
    ``significands`` (numeric input -> int significands), when given, are what comparisons over
    rewards and inputs are decided on, exactly (the product of model and automaton holds them).
    """

    k: np.ndarray
    ego: np.ndarray
    truth: np.ndarray | None = None
    location: np.ndarray | None = None
    rewards: Mapping[str, np.ndarray] | None = None
    inputs: Mapping[str, np.ndarray] | None = None
    prev: Frame | None = None
    mirrors: Mapping[str, np.ndarray] | None = None
    significands: Mapping[str, np.ndarray] | None = None
    #: (n,) bool: under ``collision sticky``, whether ``collide()`` held at an earlier sample of the run
    #: (or at this one): ``collide()`` is that or this sample's test. Needed then, ignored otherwise.
    crashed: np.ndarray | None = None
    #: The model's functions of position (``offroad``, ``mindist``, ``goal``, ``dist_goal``) of these
    #: states, when the caller has them: ``functions(name)`` is ``(n,)`` (e.g. computed once per distinct
    #: position that many states share, :class:`rac.engine.explore.Geometry`). None: the model is called.
    functions: Callable[[str], np.ndarray] | None = None
    _cache: dict = field(default_factory=dict, compare=False, repr=False)

    @property
    def n(self) -> int:
        return int(self.ego.shape[0])

    def known(self) -> dict[str, np.ndarray]:
        """The model functions computed on this frame so far (name -> ``(n,)``, :meth:`Evaluator.function`)."""
        return dict(self._cache)

    def reading(self, inputs: Mapping[str, np.ndarray], location: np.ndarray | None = None,
                rewards: Mapping[str, np.ndarray] | None = None) -> Frame:
        """This frame with the automaton's ``inputs`` (and ``location``, ``rewards``) on its states:
        ``dataclasses.replace`` of those fields (the model functions computed so far shared, as it
        shares them), without its per-call look at the fields (a sample of a few episodes asks it twice)."""
        return Frame(self.k, self.ego, self.truth, self.location if location is None else location,
                     self.rewards if rewards is None else rewards, inputs, self.prev, self.mirrors,
                     self.significands, self.crashed, self.functions, self._cache)

    def keep(self, name: str, values: np.ndarray) -> None:
        """Hand the frame model function ``name``'s values on its states, computed elsewhere (e.g. on
        the same states at the previous sample), so that :meth:`Evaluator.function` does not call the model."""
        self._cache[name] = values


def int_sum(const: int, terms: Sequence[tuple[int, np.ndarray]], n: int) -> np.ndarray:
    """``const + Σ c * column`` exactly: int64 when no intermediate can overflow it, else Python ints."""
    exact = abs(const) + sum(abs(c) for c, _ in terms) * INT32_BOUND < _SAFE_INT64
    dtype = np.int64 if exact else object
    total = np.full(n, const, dtype=dtype)
    for c, column in terms:
        total = total + c * column.astype(dtype)
    return total


def c_round(x: np.ndarray) -> np.ndarray:
    """C's ``round()`` (the emitted model's): half away from zero, the sign of zero kept, exact.

    numpy rounds half to even; ``sign(x) * floor(|x| + 0.5)`` is not C's either: ``|x| + 0.5`` rounds
    0.49999999999999994 up to 1 and 2**52 + 1 to an even number, and ``sign(-0.0)`` loses the minus.
    ``x - trunc(x)`` is exact, so the comparison with 0.5 decides the half exactly."""
    whole = np.trunc(x)
    with np.errstate(invalid="ignore"):  # inf - inf: no fraction, the whole value stays
        away = np.abs(x - whole) >= 0.5
    return np.where(away, whole + np.copysign(1.0, x), whole)


class Evaluator:
    """Evaluates checked expressions of one automaton (and its model) over :class:`Frame` s."""

    def __init__(self, data: ModelData, automaton: ir.Automaton | None = None) -> None:
        self.data = data
        self.automaton = automaton
        self.model = batch_model(data)  # shared: its kept cos/sin and trajectories too
        self.scale_d = float(data.scale)
        self.period_d = float(data.period)
        self.period = Fraction(automaton.period) if automaton is not None else Fraction(data.sense_period, data.scale)

    # ------------------------------------------------------------ public
    def evaluate(self, expr: ie.Expr, frame: Frame) -> np.ndarray:
        """The value of ``expr`` in every state of ``frame``: a ``(n,)`` bool or float64 array."""
        value = self._eval(expr, frame)
        return np.broadcast_to(value, (frame.n,)) if np.ndim(value) == 0 else value

    def evaluate_bool(self, expr: ie.Expr, frame: Frame) -> np.ndarray:
        """:meth:`evaluate` for a boolean expression (numbers compare with 0, as in C)."""
        value = self.evaluate(expr, frame)
        return value if value.dtype == bool else value != 0

    def _collide(self, frame: Frame) -> np.ndarray:
        """``collide()``: ``mindist() < TD`` at the frame's sample, or before it under ``collision sticky``."""
        now = collides(self.function("mindist", frame), self.model.native.td_d)
        if not self.data.sticky:
            return now
        if frame.crashed is None:
            raise EvaluationError("`collide()` under `collision sticky` reads the run's history, which this "
                                  "evaluation does not have")
        return np.asarray(frame.crashed, dtype=bool) | now

    # ------------------------------------------------------------ the walk
    def _eval(self, expr: ie.Expr, frame: Frame):
        if isinstance(expr, ie.Const):
            return np.bool_(expr.value) if isinstance(expr.value, bool) else np.float64(float(expr.value))
        if isinstance(expr, ie.Ref):
            return self._ref(expr, frame)
        if isinstance(expr, ie.Call):
            return self._call(expr, frame)
        if isinstance(expr, ie.Prev):
            return self._eval(expr.operand, frame.prev if frame.prev is not None else frame)
        if isinstance(expr, ie.Unary):
            operand = self._eval(expr.operand, frame)
            return np.logical_not(operand) if expr.op == "!" else -operand
        if isinstance(expr, ie.Compare):
            exact = self._exact(expr, frame)
            if exact is not None:
                return exact
            return _COMPARE[expr.op](self._eval(expr.left, frame), self._eval(expr.right, frame))
        return self._binary(expr, frame)

    def _ref(self, ref: ie.Ref, frame: Frame):
        kind = ref.kind
        if kind is ie.RefKind.INPUT:
            if frame.inputs is None or ref.name not in frame.inputs:
                raise EvaluationError(f"the input `{ref.name}` is not known here: it needs the product of the "
                                      "model and the automaton", ref.span)
            return frame.inputs[ref.name]
        if kind is ie.RefKind.REWARD:
            if frame.rewards is None:
                raise EvaluationError(f"the reward `{ref.name}` is not known here: it needs the product of the "
                                      "model and the automaton", ref.span)
            return frame.rewards[ref.name]
        if kind in (ie.RefKind.LOCATION, ie.RefKind.LOCATION_INDEX):
            if frame.location is None:
                what = f"the location `{ref.name}`" if kind is ie.RefKind.LOCATION else "`location`"
                raise EvaluationError(f"{what} is not known here: it needs the product of the model and the "
                                      "automaton", ref.span)
            if kind is ie.RefKind.LOCATION_INDEX:
                return frame.location.astype(np.float64)
            return frame.location == ref.index
        if kind is ie.RefKind.DEADLOCK:
            if self.data.allow is not None:  # the emitted model deadlocks where `allow when` leaves no action
                raise EvaluationError("`deadlock` is not answered for a model with `allow when` yet: where "
                                      "`allow when` leaves no action the emitted model deadlocks, and rac's "
                                      "engines stop the run there without telling it apart", ref.span)
            return np.bool_(False)  # the model never deadlocks: every state has a choice until the horizon
        entry = ref.model
        if entry.kind == "ego":
            return frame.ego[:, ref.index] / self.scale_d
        if entry.holding is Holding.TIME:
            return frame.k * self.period_d
        if entry.holding is Holding.TRUTH:
            if frame.truth is None:
                raise EvaluationError(f"`{ref.name}` is the ground truth, which only statistical queries "
                                      "(Pr, E, simulate) follow", ref.span)
            return frame.truth[:, ref.index]
        assert ref.value is not None, ref
        return np.float64(float(ref.value))  # a setting, as the model holds it

    def function(self, name: str, frame: Frame) -> np.ndarray:
        """The model function ``name`` (``collide``, ``offroad``, ``goal``, ``mindist``, ``dist_goal``)
        on every state of ``frame``: computed once per frame and kept on it, so that the bindings,
        the labels, the ``allow when`` rule and any query reading the frame share one model call
        (``collide()`` is ``mindist() < TD``: one ``mindist`` for both)."""
        cache = frame._cache
        if name not in cache and name != "collide" and frame.functions is not None:
            cache[name] = np.asarray(frame.functions(name))
        if name not in cache:
            model = self.model
            if name == "collide":
                cache[name] = self._collide(frame)
            elif name == "offroad":
                cache[name] = model.offroad(frame.ego, frame.k)
            elif name == "goal":
                cache[name] = model.goal(frame.ego, frame.k)
            elif name == "mindist":
                cache[name] = model.mindist(frame.ego, frame.k)
            elif name == "dist_goal":
                cache[name] = model.dist_goal(frame.ego)
            else:
                raise KeyError(name)
        return cache[name]

    def value(self, expr: ie.Expr, frame: Frame):
        """The value of ``expr`` on ``frame`` as the walk computes it: a ``(n,)`` array, or a numpy
        scalar for a constant (what :meth:`evaluate` broadcasts); the reference of
        :mod:`rac.engine.compiled`, which calls it for what it does not compile."""
        return self._eval(expr, frame)

    def _call(self, call: ie.Call, frame: Frame):
        name = call.name
        if call.function.kind == "model":
            return self.function(name, frame)
        args = [np.asarray(self._eval(a, frame), dtype=np.float64) for a in call.args]
        if name in _MATH_1:
            with np.errstate(invalid="ignore"):
                return _MATH_1[name](args[0])
        if name == "round":  # C's round (numpy rounds half to even)
            return c_round(args[0])
        if name == "fmin":
            return np.fmin(args[0], args[1])
        if name == "fmax":
            return np.fmax(args[0], args[1])
        raise EvaluationError(f"`{name}()` cannot be evaluated by the engine", call.span)

    def _binary(self, expr: ie.Binary, frame: Frame):
        op = expr.op
        left = self._eval(expr.left, frame)
        right = self._eval(expr.right, frame)
        if op == "&&":
            return np.logical_and(left, right)
        if op == "||":
            return np.logical_or(left, right)
        if op == "imply":
            return np.logical_or(np.logical_not(left), right)
        with np.errstate(divide="ignore", invalid="ignore"):
            if op == "+":
                return np.add(left, right, dtype=np.float64)
            if op == "-":
                return np.subtract(left, right, dtype=np.float64)
            if op == "*":
                return np.multiply(left, right, dtype=np.float64)
            return np.divide(left, right, dtype=np.float64)

    # ------------------------------------------------------------ exact comparisons
    def _exact(self, expr: ie.Compare, frame: Frame) -> np.ndarray | None:
        """``left op right`` decided on integers, when its linear form's terms are all held as integers
        in this frame (ego significands, ``k``, the location, and mirrors and input significands when
        the frame holds them); None otherwise."""
        form = expr.linear
        if form is None:
            return None
        columns: list[tuple[Fraction, np.ndarray]] = []
        for ref, coefficient in form.terms:
            held = self._integer(ref, frame)
            if held is None:
                return None
            column, unit = held
            columns.append((coefficient * unit, column))
        multiple = math.lcm(form.const.denominator, *(c.denominator for c, _ in columns))
        total = int_sum(int(form.const * multiple), [(int(c * multiple), col.astype(np.int64)) for c, col in columns],
                        frame.n)
        return np.asarray(_COMPARE[expr.op](total, 0), dtype=bool)

    def _integer(self, ref: ie.Ref, frame: Frame) -> tuple[np.ndarray, Fraction] | None:
        """The integers holding ``ref`` in ``frame`` and the value of one unit, or None."""
        if ref.kind is ie.RefKind.INPUT:
            if frame.significands is None or ref.name not in frame.significands:
                return None
            return frame.significands[ref.name], Fraction(1, self.data.scale)
        if ref.kind is ie.RefKind.REWARD:
            if frame.mirrors is None:
                return None
            return frame.mirrors[ref.name], Fraction(1, self.data.scale)
        if ref.kind is ie.RefKind.LOCATION_INDEX:
            return (frame.location, Fraction(1)) if frame.location is not None else None
        entry = ref.model
        if entry.kind == "ego":
            return frame.ego[:, ref.index], Fraction(1, self.data.scale)
        if entry.holding is Holding.TIME:
            return frame.k, self.period
        return None
