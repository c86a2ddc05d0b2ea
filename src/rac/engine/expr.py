"""Query and binding expressions over arrays of model states (issue 4).

The engine evaluates a ``.ra`` expression (an :mod:`rac.ast` node that the checker has already
typed) for ``n`` states at once: one :class:`Frame` holds what the expression may read at one
sample — the sample index, the sensed ego significands, optionally the ground truth, the
automaton's location, rewards and inputs, and the frame of the previous sample for ``prev(e)``.

Numbers follow the emitted UPPAAL/C code (:mod:`rac.targets.uppaal_model`), so a binding
evaluated here gives the double the UPPAAL Controller computes: an ego name is
``significand / SCALE_D``, ``time`` is ``k * C1``, a setting with a name in the paper (``TD``,
``MA``, ...) is its significand over ``SCALE_D``, any other setting or literal is the nearest
double. Booleans are numpy ``bool`` arrays, numbers ``float64`` arrays.

Example::

    evaluator = Evaluator(data, automaton)
    frame = Frame(k=np.full(n, 3), ego=states)
    unsafe = evaluator.evaluate(parse_expr("mindist() < 3 * collision_distance"), frame)
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from fractions import Fraction

import numpy as np

from rac import ast, ir
from rac.engine.explore import EGO_COLUMNS, BatchModel
from rac.model.data import ModelData
from rac.model_block import SETTINGS, TRUE_STATE
from rac.source import Span

__all__ = ["EvaluationError", "Evaluator", "Frame", "reads"]

#: Settings that the model holds as significands (``i2d(TD)`` in UPPAAL), by ModelData field.
_SIGNIFICAND_SETTINGS = {"collision_distance": "td", "max_acceleration": "max_acc", "max_turn": "max_turn",
                         "comfort_acceleration": "p1", "comfort_turn": "p2", "length": "length", "width": "width",
                         "min_speed": "min_speed", "max_speed": "max_speed"}
_MATH_1 = {"abs": np.abs, "fabs": np.abs, "sqrt": np.sqrt, "floor": np.floor, "ceil": np.ceil,
           "trunc": np.trunc}


class EvaluationError(ValueError):
    """An expression reads something the frame does not hold (e.g. ``true_x`` in an exhaustive query)."""

    def __init__(self, message: str, span: Span | None = None) -> None:
        super().__init__(message)
        self.span = span


@dataclass(frozen=True)
class Frame:
    """What an expression reads at one sample, for ``n`` states.

    ``k`` (n,) sample indices; ``ego`` (n, 7) sensed significands (:data:`EGO_COLUMNS`);
    ``truth`` (n, 5) true ``x, y, v, acc, head`` (metres, seconds) or None; ``location`` (n,)
    automaton location indices; ``rewards`` name -> (n,) float64 values; ``inputs`` name -> (n,)
    values (bool, or float64 reals); ``prev`` the frame of the previous sample (``prev(e)`` at
    the first sample is ``e`` itself, as the emitted model's ``init_prevs()``).
    """

    k: np.ndarray
    ego: np.ndarray
    truth: np.ndarray | None = None
    location: np.ndarray | None = None
    rewards: Mapping[str, np.ndarray] | None = None
    inputs: Mapping[str, np.ndarray] | None = None
    prev: Frame | None = None
    _cache: dict = field(default_factory=dict, compare=False, repr=False)

    @property
    def n(self) -> int:
        return int(self.ego.shape[0])


class Evaluator:
    """Evaluates typed expressions of one automaton (and its model) over :class:`Frame` s."""

    def __init__(self, data: ModelData, automaton: ir.Automaton | None = None) -> None:
        self.data = data
        self.automaton = automaton
        self.model = BatchModel(data)
        self.scale_d = float(data.scale)
        self.period_d = float(data.period)
        self.constants: dict[str, Fraction | bool] = dict(automaton.constants) if automaton else {}
        self.locations = automaton.location_names if automaton else ()
        self.rewards = automaton.rewards if automaton else ()
        self.input_names = tuple(i.name for i in automaton.inputs) if automaton else ()

    # ------------------------------------------------------------ public
    def evaluate(self, expr: ast.Expr, frame: Frame) -> np.ndarray:
        """The value of ``expr`` in every state of ``frame``: a ``(n,)`` bool or float64 array."""
        value = self._eval(expr, frame)
        return np.broadcast_to(value, (frame.n,)) if np.ndim(value) == 0 else value

    def evaluate_bool(self, expr: ast.Expr, frame: Frame) -> np.ndarray:
        """:meth:`evaluate` for a boolean expression (numbers compare with 0, as in C)."""
        value = self.evaluate(expr, frame)
        return value if value.dtype == bool else value != 0

    # ------------------------------------------------------------ the walk
    def _eval(self, expr: ast.Expr, frame: Frame):
        if isinstance(expr, ast.Number):
            return np.float64(float(expr.value))
        if isinstance(expr, ast.BoolLit):
            return np.bool_(expr.value)
        if isinstance(expr, ast.Name):
            return self._name(expr, frame)
        if isinstance(expr, ast.Qualified):
            return self._qualified(expr, frame)
        if isinstance(expr, ast.Call):
            return self._call(expr, frame)
        if isinstance(expr, ast.Unary):
            operand = self._eval(expr.operand, frame)
            return np.logical_not(operand) if expr.op == "!" else -operand
        assert isinstance(expr, ast.Binary)
        return self._binary(expr, frame)

    def _name(self, expr: ast.Name, frame: Frame):
        name = expr.id
        if name in self.input_names:
            if frame.inputs is None or name not in frame.inputs:
                raise EvaluationError(f"the input `{name}` is not known here: it needs the product of the model "
                                      "and the automaton", expr.span)
            return frame.inputs[name]
        if name in self.rewards:
            if frame.rewards is None:
                raise EvaluationError(f"the reward `{name}` is not known here: it needs the product of the model "
                                      "and the automaton", expr.span)
            return frame.rewards[name]
        if name in self.locations:
            if frame.location is None:
                raise EvaluationError(f"the location `{name}` is not known here: it needs the product of the "
                                      "model and the automaton", expr.span)
            return frame.location == self.locations.index(name)
        if name in self.constants:
            value = self.constants[name]
            return np.bool_(value) if isinstance(value, bool) else np.float64(float(value))
        if name in EGO_COLUMNS:
            return frame.ego[:, EGO_COLUMNS.index(name)] / self.scale_d
        if name == "time":
            return frame.k * self.period_d
        if name == "deadlock":
            return np.bool_(False)  # the model never deadlocks: every state has a choice until the horizon
        if name in TRUE_STATE:
            if frame.truth is None:
                raise EvaluationError(f"`{name}` is the ground truth, which only statistical queries "
                                      "(Pr, E, simulate) follow", expr.span)
            return frame.truth[:, TRUE_STATE.index(name)]
        if name in _SIGNIFICAND_SETTINGS:
            return np.float64(getattr(self.data, _SIGNIFICAND_SETTINGS[name]) / self.scale_d)
        if name == "sensor_error" and self.automaton is not None and self.automaton.model is not None:
            return np.float64(float(self.automaton.model.sensor_error))
        if name in SETTINGS and self.automaton is not None and self.automaton.model is not None:
            return np.float64(float(Fraction(getattr(self.automaton.model, name))))
        raise EvaluationError(f"`{name}` cannot be evaluated by the engine", expr.span)

    def _qualified(self, expr: ast.Qualified, frame: Frame):
        if frame.location is None:
            raise EvaluationError(f"`{expr.scope}.{expr.id}` needs the product of the model and the automaton",
                                  expr.span)
        if expr.id == "location":
            return frame.location.astype(np.float64)
        return frame.location == self.locations.index(expr.id)

    def _call(self, expr: ast.Call, frame: Frame):
        func = expr.func
        if func == "prev":
            return self._eval(expr.args[0], frame.prev if frame.prev is not None else frame)
        if func in ("collide", "offroad", "goal", "mindist", "dist_goal"):
            key = func
            if key not in frame._cache:  # one model call per frame, however often a query reads it
                model = self.model
                frame._cache[key] = {
                    "collide": lambda: model.collide(frame.ego, frame.k),
                    "offroad": lambda: model.offroad(frame.ego),
                    "goal": lambda: model.goal(frame.ego, frame.k),
                    "mindist": lambda: model.mindist(frame.ego, frame.k),
                    "dist_goal": lambda: model.dist_goal(frame.ego),
                }[func]()
            return frame._cache[key]
        args = [np.asarray(self._eval(a, frame), dtype=np.float64) for a in expr.args]
        if func in _MATH_1:
            with np.errstate(invalid="ignore"):
                return _MATH_1[func](args[0])
        if func == "round":  # C's round: half away from zero (numpy rounds half to even)
            return np.sign(args[0]) * np.floor(np.abs(args[0]) + 0.5)
        if func == "fmin":
            return np.fmin(args[0], args[1])
        if func == "fmax":
            return np.fmax(args[0], args[1])
        raise EvaluationError(f"`{func}()` cannot be evaluated by the engine", expr.span)

    def _binary(self, expr: ast.Binary, frame: Frame):
        op = expr.op
        left = self._eval(expr.left, frame)
        right = self._eval(expr.right, frame)
        if op == "&&":
            return np.logical_and(left, right)
        if op == "||":
            return np.logical_or(left, right)
        if op == "imply":
            return np.logical_or(np.logical_not(left), right)
        if op in ast.COMPARISON_OPS:
            return {"<": np.less, "<=": np.less_equal, ">": np.greater, ">=": np.greater_equal,
                    "==": np.equal, "!=": np.not_equal}[op](left, right)
        with np.errstate(divide="ignore", invalid="ignore"):
            if op == "+":
                return np.add(left, right, dtype=np.float64)
            if op == "-":
                return np.subtract(left, right, dtype=np.float64)
            if op == "*":
                return np.multiply(left, right, dtype=np.float64)
            return np.divide(left, right, dtype=np.float64)


def reads(expr: ast.Expr) -> set[str]:
    """The names an expression reads, and its calls as ``"name()"`` (``"prev()"`` when it uses
    ``prev``), so the model's ``collide()`` is not mistaken for an input named ``collide``.

    The engine uses it to choose how to answer a query: one that reads ``true_*`` needs the
    ground truth (statistical), one that reads inputs, rewards or locations needs the product.
    """
    found: set[str] = set()

    def walk(node: ast.Expr) -> None:
        if isinstance(node, ast.Name):
            found.add(node.id)
        elif isinstance(node, ast.Qualified):
            found.add("location")
        elif isinstance(node, ast.Call):
            found.add(f"{node.func}()")
            for arg in node.args:
                walk(arg)
        elif isinstance(node, ast.Unary):
            walk(node.operand)
        elif isinstance(node, ast.Binary):
            walk(node.left)
            walk(node.right)

    walk(expr)
    return found
