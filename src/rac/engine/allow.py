"""The model block's ``allow when e``: which actions a state may choose (docs/language.md).

An action is allowed in a state when ``e`` holds in the state it leads to one sense period later
(``sense()`` of the state with the action's jerk and turn, at the next sample) — CommonUppRoad's
``canTurn()``: the next heading within bounds and the ego on the road one step ahead. Every
consumer of the model reads the rule from here: exploration keeps only allowed choices (a state
with none has no successor, as the emitted model deadlocks there), simulation and learning choose
among allowed actions only, and the UPPAAL target prints the same condition into
``allow_actions()``.

Example::

    guard = ActionGuard(data)
    masks = guard.masks(states, k)        # (n, P) bool over rac.engine.explore.action_pairs(data)
"""

from __future__ import annotations

import numpy as np

from rac.engine.evaluate import Evaluator, Frame
from rac.model.batch import batch_model
from rac.model.data import ModelData
from rac.model.sample import ACTION

__all__ = ["ActionGuard", "action_pairs"]


def action_pairs(data: ModelData) -> np.ndarray:
    """``(P, 2)`` int32: every (jerk, turn) pair; row ``a`` is action index ``a`` of the graph,
    ``a = jerk_index * turn_count + turn_index`` over :attr:`ActionData.values`."""
    jerk = np.asarray(data.action("jerk").values, dtype=np.int32)
    turn = np.asarray(data.action("turn").values, dtype=np.int32)
    return np.stack([np.repeat(jerk, len(turn)), np.tile(turn, len(jerk))], axis=1)


class ActionGuard:
    """The ``allow when`` condition of ``data`` (:attr:`ModelData.allow`) over successor states."""

    def __init__(self, data: ModelData) -> None:
        self.data = data
        self.evaluator = Evaluator(data) if data.allow is not None else None

    @property
    def restricts(self) -> bool:
        """Whether the model has an ``allow when`` condition at all."""
        return self.evaluator is not None

    def successors_allowed(self, successors: np.ndarray, k: int | np.ndarray) -> np.ndarray:
        """``(n,)`` bool: whether each successor state (ego columns, reached at sample ``k``) meets the
        condition — whether the choice that led to it is allowed."""
        samples = np.broadcast_to(np.asarray(k, dtype=np.int64), (successors.shape[0],))
        return self.allowed_in(Frame(k=samples, ego=successors))

    def allowed_in(self, frame: Frame) -> np.ndarray:
        """``(n,)`` bool: whether each successor state of ``frame`` meets the condition, read on that frame
        (so its model calls are shared with whatever else reads the frame)."""
        if self.evaluator is None or self.data.allow is None:
            return np.ones(frame.n, dtype=bool)
        return np.asarray(self.evaluator.evaluate_bool(self.data.allow, frame), dtype=bool)

    def masks(self, states: np.ndarray, k: int | np.ndarray) -> np.ndarray:
        """``(n, P)`` bool: the actions (:func:`action_pairs`) allowed in each state (ego columns) at
        sample ``k``: all of them without a condition."""
        pairs = action_pairs(self.data)
        n = states.shape[0]
        if self.evaluator is None or n == 0:
            return np.ones((n, len(pairs)), dtype=bool)
        chosen = np.repeat(np.asarray(states, dtype=np.int32), len(pairs), axis=0)
        chosen[:, ACTION] = np.tile(pairs, (n, 1))
        samples = np.repeat(np.broadcast_to(np.asarray(k, dtype=np.int64), (n,)), len(pairs))
        successors = batch_model(self.data).sense(chosen)
        return self.successors_allowed(successors, samples + 1).reshape(n, len(pairs))
