"""Penalties that no action avoids: the decision states of the product of model and automaton
(:func:`rac.engine.product.explore_product`) where every choice the model allows leads the automaton
into a location that penalises an objective (issue 25).

A reward teaches nothing where it cannot be avoided: when traffic spawns inside the unsafe distance,
every action at the first decision is followed by the unsafe location, so the penalty says nothing
about the action. Which locations penalise which objective is the caller's to say (``rac verify``
passes P2's notion, :func:`rac.check.analysis.priority.p2_target`'s ``watched``: a location whose
rate of the objective can be negative, or that an edge enters lowering it); the engine reads the
automaton's location after each sample.

**What a choice incurs.** A choice at a decision sample ``k`` holds until the next decision, at
``k + decide_every`` (or the horizon). It *incurs a penalty of* ``o`` when the automaton is in a
location that penalises ``o`` after one of the samples ``k + 1 ... k + decide_every``: after the
edge (phase ``sampled``) of each. The objective's increase over the step is not used: a sample's
accrual is the rate of the location the automaton was in *before* the action took effect, with the
inputs held from the sample before (:mod:`rac.engine.product`, step 1), which no choice at ``k``
changes. That increase would flag a state already in a penalising location although some action
leads out of it, and miss the spawn, whose first step still accrues in the initial location; the
location after the step is what the action decides.

A decision state is one with choices of actions (``action >= 0``); a state where ``allow when``
leaves none is no decision (``rac verify`` reports those apart). Example::

    graph = explore_product(data, automaton, horizon_samples=4)
    found = unavoidable(graph, {"sa": (False, True)})   # `sa` penalised in the second location
    found["sa"].states                                  # the decision states, earliest first
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from rac.engine.product import SAMPLED, ProductGraph

__all__ = ["Unavoidable", "choice_penalties", "decision_states", "unavoidable"]


@dataclass(frozen=True)
class Unavoidable:
    """The decision states where every allowed choice incurs a penalty of ``objective``.

    ``states`` are indices into the graph's states, earliest sample first (then by index);
    ``decisions`` is how many decision states were judged."""

    objective: str
    states: np.ndarray
    decisions: int

    @property
    def first(self) -> int | None:
        """The earliest such state (None: there is none)."""
        return int(self.states[0]) if self.states.size else None


def decision_states(graph: ProductGraph) -> np.ndarray:
    """(n,) bool: the states whose choices are actions (a decision sample with an allowed action)."""
    counts = np.diff(graph.choice_offsets)
    has = counts > 0
    first_action = np.full(graph.n_states, -1, dtype=np.int64)
    first_action[has] = graph.choice_action[graph.choice_offsets[:-1][has]]
    return has & (first_action >= 0)


def choice_penalties(graph: ProductGraph, penalising: Sequence[bool]) -> np.ndarray:
    """(m,) int64 per choice of the graph: the first location that penalises (``penalising[loc]``)
    which the automaton is in after a sample before the choice's successor next decides, or -1.

    Between decisions a state has one choice (action -1); the chain from a choice's target is followed
    through it (``accrued``, ``read``, ``sampled``, ``ended`` phases) up to and including the next
    decision state, whose location is the last the choice decides."""
    mask = np.asarray(penalising, dtype=bool)
    location = graph.location.astype(np.int64)
    k = graph.k.astype(np.int64)
    sampled = (graph.phase == SAMPLED) & (k > 0)
    here = np.where(sampled & mask[location], location, -1)
    counts = np.diff(graph.choice_offsets)
    follow = (counts == 1) & ~decision_states(graph)
    onward = np.zeros(graph.n_states, dtype=np.int64)
    onward[follow] = graph.choice_target[graph.choice_offsets[:-1][follow]]
    # the product is layered: a chain is a few phases per sample up to the next decision, so the
    # fixed point is reached after that many rounds
    first = here
    while True:
        step = np.where(here >= 0, here, np.where(follow, first[onward], -1))
        if np.array_equal(step, first):
            break
        first = step
    return first[graph.choice_target]


def unavoidable(graph: ProductGraph, penalised: Mapping[str, Sequence[bool]], *,
                before: int | None = None) -> dict[str, Unavoidable]:
    """Per objective (``penalised[o][loc]``: whether location ``loc`` penalises ``o``), the decision
    states at samples before ``before`` (default: all) where every allowed choice incurs a penalty
    of ``o`` (:func:`choice_penalties`).

    ``graph`` must be the complete product (not pruned, not a beam's); ``before`` leaves out the
    decisions whose chains reach beyond an exploration cut short of the horizon."""
    if not graph.complete:
        raise ValueError("penalties no action avoids are decided on the complete product only")
    decides = decision_states(graph)
    k = graph.k.astype(np.int64)
    if before is not None:
        decides &= k < before
    owner = np.repeat(np.arange(graph.n_states, dtype=np.int64), np.diff(graph.choice_offsets))
    counts = np.diff(graph.choice_offsets)
    found = {}
    for objective, mask in penalised.items():
        incurs = choice_penalties(graph, mask) >= 0
        hits = np.bincount(owner[incurs], minlength=graph.n_states)
        states = np.flatnonzero(decides & (hits == counts))
        states = states[np.lexsort((states, k[states]))]
        found[objective] = Unavoidable(objective, states, int(decides.sum()))
    return found
