"""One sample's state, named once: the columns of every state array and the labels of a state.

Columns. An *ego row* is the controller's state as significands, :data:`rac.ir.vocabulary.EGO_STATE`
in order (:class:`Ego`); under ``collision sticky`` it carries one more column, :data:`CRASHED`
(``collide()`` held at this sample or an earlier one, 0/1). The explored graph's rows
(:func:`rac.engine.explore.explore`) put the sample index first (:class:`GraphColumn`); the product's
rows (:func:`rac.engine.product.explore_product`) put the sample index and the phase first, the
automaton's location, inputs and reward mirrors after the ego (:class:`ProductColumn`). Code that
indexes a state array by column names the column here; tests/project/test_layout.py fails on a bare integer.

Labels. :data:`LABELS` are the model's predicates every explored state carries; :func:`collides`,
:func:`safe` and :func:`labels` are their one definition (``collide()`` is ``mindist() < TD``), which
the scalar and batch model, exploration, the product, simulation and episodes all call.
"""

from __future__ import annotations

from enum import IntEnum
from typing import TYPE_CHECKING, overload

from rac.ir.vocabulary import EGO_STATE

if TYPE_CHECKING:  # numpy only for the annotations: importing the model's native functions stays light
    import numpy as np

__all__ = ["ACTION", "CRASHED", "EGO", "GRAPH_ACTION", "GRAPH_EGO", "GRAPH_LAYER_ROW", "LABELS", "MOTION", "POSITION",
           "PRODUCT_EGO", "Ego", "GraphColumn", "ProductColumn", "collides", "labels", "safe"]


class Ego(IntEnum):
    """The columns of an ego row (:data:`rac.ir.vocabulary.EGO_STATE` in order)."""

    X = 0
    Y = 1
    V = 2
    ACC = 3
    HEAD = 4
    JERK = 5
    TURN = 6


assert tuple(column.name.lower() for column in Ego) == EGO_STATE, "Ego must follow EGO_STATE"

#: The column after the ego under ``collision sticky``: ``collide()`` so far (0/1).
CRASHED = len(Ego)
#: The ego columns of a row that may carry :data:`CRASHED` after them.
EGO = slice(Ego.X, Ego.TURN + 1)
#: The position ``x, y``.
POSITION = slice(Ego.X, Ego.Y + 1)
#: What the dynamics integrate, ``x, y, v, acc, head`` (:meth:`rac.model.native.NativeModel.sense`'s output).
MOTION = slice(Ego.X, Ego.HEAD + 1)
#: The action held until the next decision, ``jerk, turn``.
ACTION = slice(Ego.JERK, Ego.TURN + 1)


class GraphColumn(IntEnum):
    """The columns of :attr:`rac.engine.graph.ExploredGraph.states` from exploration: ``k``, the ego, then
    (``collision sticky``) ``crashed`` (:data:`rac.engine.explore.COLUMNS`)."""

    K = 0
    CRASHED = 1 + len(Ego)


#: The ego columns of an explored graph's rows.
GRAPH_EGO = slice(1, 1 + len(Ego))
#: An explored graph's row without ``k``: a layer's row as exploration holds it (the ego, ``crashed``).
GRAPH_LAYER_ROW = slice(1, None)
#: The action ``jerk, turn`` of an explored graph's rows.
GRAPH_ACTION = slice(1 + Ego.JERK, 1 + Ego.TURN + 1)


class ProductColumn(IntEnum):
    """The columns of the product's states (:meth:`rac.engine.product.ProductGraph.columns_of`): ``k``,
    ``phase``, the ego, ``location``, then one per input (from :attr:`INPUTS`), one mirror per reward and
    (``collision sticky``) ``crashed``."""

    K = 0
    PHASE = 1
    LOCATION = 2 + len(Ego)
    INPUTS = 3 + len(Ego)


#: The ego columns of the product's rows.
PRODUCT_EGO = slice(2, 2 + len(Ego))

#: The state labels every explored graph carries (the model's predicates a query may name).
LABELS: tuple[str, ...] = ("collide", "offroad", "goal", "safe")


@overload
def collides(mindist: float, td: float) -> bool: ...
@overload
def collides(mindist: np.ndarray, td: float, crashed: np.ndarray | None = None) -> np.ndarray: ...
def collides(mindist: float | np.ndarray, td: float, crashed: np.ndarray | None = None) -> bool | np.ndarray:
    """``collide()``: ``mindist() < TD`` (``td``, a double); with ``crashed`` (``collision sticky``: it held
    at an earlier sample), or that."""
    now = mindist < td
    return now if crashed is None else now | crashed


def safe(collide: np.ndarray, offroad: np.ndarray) -> np.ndarray:
    """The label ``safe``: ``!collide() && !offroad()``."""
    return ~collide & ~offroad


def labels(collide: np.ndarray, offroad: np.ndarray, goal: np.ndarray) -> dict[str, np.ndarray]:
    """The :data:`LABELS` of states, from their ``collide()``, ``offroad()`` and ``goal()`` (bool arrays)."""
    return {"collide": collide, "offroad": offroad, "goal": goal, "safe": safe(collide, offroad)}
