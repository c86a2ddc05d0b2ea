"""The model block's bindings, read as the emitted model's ``read_inputs()`` reads them.

Both the product of model and automaton (:mod:`rac.engine.product`) and the training-side
episodes (:mod:`rac.learning.episodes`) compute every input from its binding on a frame: a
condition as a ``bool``, a number as its significand ``d2i(e) = trunc(e * SCALE_D)`` (a value
beyond int32 is :class:`rac.model.data.ModelRangeError`: the emitted model's ``d2i()`` has no int32 for
it, so no verdict can rest on it; ``rac check`` refuses the bindings that leave int32 wherever no obstacle
exists, E0801).

The bindings are compiled once into one function of a frame (:mod:`rac.engine.compiled`, issue 23):
a sample reads every input without walking the expressions' trees. ``compiled=False`` reads them
with the evaluator's walk instead, the reference (the same values; benchmarks/learning.py compares
the speed).
"""

from __future__ import annotations

import math

import numpy as np

from rac import ir
from rac.core.diagnostics import RacValueError
from rac.core.numbers import INT32_BOUND, INT32_MAX
from rac.engine.compiled import compile_expressions
from rac.engine.evaluate import Evaluator, Frame
from rac.ir import expr as ie
from rac.model.data import ModelRangeError

__all__ = ["Bindings"]


class Bindings:
    """Every input of ``automaton`` from its binding (``reader`` names who reads them in the error
    for an input without one, e.g. ``"the product"``), and the bindings' ``prev(e)`` operands."""

    def __init__(self, evaluator: Evaluator, automaton: ir.Automaton, reader: str, *, compiled: bool = True) -> None:
        self.evaluator = evaluator
        spec = automaton.model
        bound = {b.input: b.expr for b in spec.bindings} if spec is not None else {}
        missing = [item.name for item in automaton.inputs if item.name not in bound]
        if missing:
            names = ", ".join(f"`{name}`" for name in missing)
            raise RacValueError(f"input {names} has no binding: {reader} reads every input from the model, "
                                f"as the emitted model does (add `bind {missing[0]} = ...` to the `model` block)")
        #: (input, is a condition, its binding), in the automaton's input order.
        self.items: list[tuple[str, bool, ie.Expr]] = [(item.name, item.is_bool, bound[item.name])
                                                       for item in automaton.inputs]
        self.prev_args: list[ie.Expr] = ie.prev_operands([expr for _, _, expr in self.items])
        #: Whether the bindings are read by compiled code (else by the evaluator's walk).
        self.compiled = compiled
        # one function for all bindings (a subexpression they share is computed once), one for the prevs
        self._bindings = compile_expressions(evaluator, [expr for _, _, expr in self.items]) if compiled else None
        self._prevs = compile_expressions(evaluator, self.prev_args) if compiled else None

    def column(self, index: int, frame: Frame) -> np.ndarray:
        """Input ``index`` on every state of ``frame``: bool, or int64 significands."""
        return self._held(index, self.evaluator.evaluate(self.items[index][2], frame))

    def columns(self, frame: Frame, *, saturate: bool = False) -> list[np.ndarray]:
        """Every input on every state of ``frame`` (:meth:`column` of each, in the input order).
        ``saturate``: a number beyond int32 is held as the nearest int32 instead of refused, for a reading
        no model makes (the learning episodes' inputs shown at sample 0, before the first reading)."""
        if self._bindings is None:
            values = [self.evaluator.evaluate(expr, frame) for _, _, expr in self.items]
        else:
            values = self._bindings(frame)
        return [self._held(index, value, saturate) for index, value in enumerate(values)]

    def _held(self, index: int, value: np.ndarray, saturate: bool = False) -> np.ndarray:
        """A binding's value as the model holds the input: bool, or int64 significands."""
        name, is_bool, _ = self.items[index]
        if is_bool:
            return np.asarray(value if value.dtype == bool else value != 0, dtype=bool)
        value = np.asarray(value, dtype=np.float64)
        scaled = value * self.evaluator.scale_d
        if saturate:  # NaN still has no significand
            scaled = np.clip(scaled, -INT32_MAX, INT32_MAX)
        bad = ~((scaled > -INT32_BOUND) & (scaled < INT32_BOUND))  # also NaN
        if bad.any():
            row = int(np.flatnonzero(bad)[0])
            significand = int(scaled[row]) if math.isfinite(scaled[row]) else None
            raise ModelRangeError(f"the binding of `{name}`", float(value[row]), significand,
                                  self.evaluator.data.scale, binding=name)
        return scaled.astype(np.int64)  # truncation towards zero, like fint()

    def read(self, frame: Frame) -> np.ndarray:
        """``(n, inputs)`` int64: booleans 0/1, numbers as significands."""
        out = np.zeros((frame.n, len(self.items)), dtype=np.int64)
        for index, column in enumerate(self.columns(frame)):
            out[:, index] = column
        return out

    def prevs(self, frame: Frame) -> np.ndarray:
        """``(n, prevs)`` float64: the value of every ``prev(e)``'s ``e`` (booleans as 0/1)."""
        out = np.zeros((frame.n, len(self.prev_args)), dtype=np.float64)
        values = (self._prevs(frame) if self._prevs is not None
                  else [self.evaluator.evaluate(expr, frame) for expr in self.prev_args])
        for column, value in enumerate(values):
            out[:, column] = value
        return out
