"""rac.model.sample: the column enums and slices match the state layouts the engine writes, and the
labels are their one definition."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from rac.compiler import compile_file
from rac.engine.explore import COLUMNS, STICKY_COLUMNS
from rac.engine.product import ProductGraph
from rac.ir.vocabulary import EGO_STATE
from rac.model.sample import (
    ACTION,
    CRASHED,
    EGO,
    GRAPH_ACTION,
    GRAPH_EGO,
    GRAPH_LAYER_ROW,
    LABELS,
    MOTION,
    POSITION,
    PRODUCT_EGO,
    Ego,
    GraphColumn,
    ProductColumn,
    collides,
    labels,
    safe,
)

STDLIB = Path(__file__).resolve().parents[2] / "stdlib"


def take(columns: tuple[str, ...], where: slice | int) -> tuple[str, ...] | str:
    return columns[where]


def test_ego_row() -> None:
    ego_row = (*EGO_STATE, "crashed")
    assert tuple(c.name.lower() for c in Ego) == EGO_STATE
    assert take(ego_row, EGO) == EGO_STATE
    assert take(ego_row, POSITION) == ("x", "y")
    assert take(ego_row, MOTION) == ("x", "y", "v", "acc", "head")
    assert take(ego_row, ACTION) == ("jerk", "turn")
    assert ego_row[CRASHED] == "crashed"


def test_explored_graph_columns() -> None:
    assert COLUMNS[GraphColumn.K] == "k"
    assert take(COLUMNS, GRAPH_EGO) == EGO_STATE
    assert take(COLUMNS, GRAPH_ACTION) == ("jerk", "turn")
    assert STICKY_COLUMNS[GraphColumn.CRASHED] == "crashed"
    assert take(STICKY_COLUMNS, GRAPH_LAYER_ROW) == (*EGO_STATE, "crashed")


def test_product_columns() -> None:
    result = compile_file(STDLIB / "driving.ra")
    assert result.automaton is not None
    columns = ProductGraph.columns_of(result.automaton)
    assert (columns[ProductColumn.K], columns[ProductColumn.PHASE]) == ("k", "phase")
    assert take(columns, PRODUCT_EGO) == EGO_STATE
    assert columns[ProductColumn.LOCATION] == "location"
    assert columns[ProductColumn.INPUTS] == result.automaton.inputs[0].name


def test_labels_are_the_documented_predicates() -> None:
    mindist = np.array([0.1, 0.5, 2.0, 0.49])
    now = collides(mindist, 0.5)
    assert now.tolist() == [True, False, False, True]
    assert collides(0.5, 0.5) is False and collides(0.4, 0.5) is True
    crashed = np.array([False, True, False, False])
    assert collides(mindist, 0.5, crashed).tolist() == [True, True, False, True]
    offroad = np.array([False, False, True, False])
    goal = np.array([False, False, False, True])
    assert safe(now, offroad).tolist() == [False, True, False, False]
    got = labels(now, offroad, goal)
    assert tuple(got) == LABELS
    assert got["safe"].tolist() == [False, True, False, False]
    assert got["goal"] is goal
