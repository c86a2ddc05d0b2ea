"""The explored state graph: what exploration produces and what Storm decides on.

Transitions are deterministic given a choice (obstacles are functions of time and the
ego follows the chosen action), so a choice is a single successor. States whose sample is
not a decision sample have exactly one choice (action -1).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from rac.model.sample import LABELS

__all__ = ["LABELS", "ExploredGraph"]


@dataclass(frozen=True)
class ExploredGraph:
    """A finite MDP with deterministic choices, as numpy arrays.

    ``states[i]`` is state i's integer vector (column meaning in ``columns``); the choices of
    state i are ``choice_offsets[i] : choice_offsets[i + 1]`` in ``choice_action`` (the
    action index, -1 when no decision is taken) and ``choice_target`` (the successor's index).
    A state with no choices is terminal (the horizon is reached).

    ``complete`` is False for a graph whose exploration stopped at a witness before the horizon or
    kept only some states of a layer (:func:`rac.engine.explore.explore`'s ``stop_at`` and ``beam``):
    its states and paths are the model's, but its terminal states need not be, so it proves that a
    run exists, never that none does.
    """

    states: np.ndarray  # (n, d) int32 (significands and the sample index)
    columns: tuple[str, ...]
    choice_offsets: np.ndarray  # (n + 1,) int64
    choice_action: np.ndarray  # (m,) int64
    choice_target: np.ndarray  # (m,) int64
    initial: int = 0
    labels: dict[str, np.ndarray] = field(default_factory=dict)  # name -> (n,) bool
    complete: bool = True
    #: > 0: explored with ``forget_actions`` (:func:`rac.engine.explore.explore`) for a decision every
    #: ``forget_every`` samples, so its states hold jerk and turn as 0 where
    #: :func:`rac.engine.explore.forgets_actions` says; a lookup by a run's state must do the same.
    forget_every: int = 0
    #: :attr:`rac.model.data.ModelData.digest` of the model explored (None: a graph built otherwise): the
    #: model a shield table made from this graph records (:func:`rac.engine.shield.table`).
    model: str | None = None

    @property
    def nbytes(self) -> int:
        """The bytes its arrays hold (states, choices, labels): what keeping it for later queries costs."""
        arrays = (self.states, self.choice_offsets, self.choice_action, self.choice_target, *self.labels.values())
        return sum(int(array.nbytes) for array in arrays)

    @property
    def n_states(self) -> int:
        return int(self.states.shape[0])

    @property
    def n_choices(self) -> int:
        return int(self.choice_target.shape[0])

    def choices(self, state: int) -> range:
        return range(int(self.choice_offsets[state]), int(self.choice_offsets[state + 1]))

    def terminal(self) -> np.ndarray:
        """(n,) bool: states without choices."""
        return np.diff(self.choice_offsets) == 0

    def stopped(self, horizon_samples: int) -> np.ndarray:
        """(n,) bool: safe states before the horizon without choices — where the model's ``allow when``
        leaves no action (an explored graph ends a run early nowhere else), so runs stop there, as
        the emitted model deadlocks. Needs the ``k`` column and the ``safe`` label."""
        k = self.states[:, self.columns.index("k")]
        return self.terminal() & (k < horizon_samples) & self.labels["safe"]

    def path_to(self, state: int) -> list[int]:
        """A path of states from the initial state to ``state`` through the graph's choices (a graph
        explored layer by layer has no cycles; ``ValueError`` when ``state`` is not reached)."""
        owner = np.repeat(np.arange(self.n_states, dtype=np.int64), np.diff(self.choice_offsets))
        parent = np.full(self.n_states, -1, dtype=np.int64)
        parent[self.choice_target[::-1]] = owner[::-1]  # the first choice leading to each state
        path = [int(state)]
        while path[-1] != self.initial:
            before = int(parent[path[-1]])
            if before < 0 or len(path) > self.n_states:
                raise ValueError(f"state {state} is not reached from the initial state")
            path.append(before)
        return path[::-1]

    def reachable(self) -> np.ndarray:
        """The states reachable from the initial one through the graph's choices (a restricted graph
        keeps every explored state, also those its choices no longer reach)."""
        seen = np.zeros(self.n_states, dtype=bool)
        frontier = np.array([self.initial], dtype=np.int64)
        seen[frontier] = True
        while frontier.size:
            starts, ends = self.choice_offsets[frontier], self.choice_offsets[frontier + 1]
            counts = ends - starts
            index = np.repeat(starts - np.concatenate([[0], np.cumsum(counts)[:-1]]), counts) + np.arange(counts.sum())
            targets = np.unique(self.choice_target[index])
            frontier = targets[~seen[targets]]
            seen[frontier] = True
        return seen

    def validate(self) -> None:
        """Raise ValueError when the arrays do not describe a graph (cheap; call in tests)."""
        n = self.n_states
        if self.choice_offsets.shape != (n + 1,) or self.choice_offsets[0] != 0:
            raise ValueError("choice_offsets must have n + 1 entries starting at 0")
        if np.any(np.diff(self.choice_offsets) < 0) or self.choice_offsets[-1] != self.n_choices:
            raise ValueError("choice_offsets must be non-decreasing and end at the number of choices")
        if self.choice_action.shape != self.choice_target.shape:
            raise ValueError("choice_action and choice_target differ in length")
        if self.n_choices and (self.choice_target.min() < 0 or self.choice_target.max() >= n):
            raise ValueError("a choice targets a state that does not exist")
        for name, mask in self.labels.items():
            if mask.shape != (n,) or mask.dtype != bool:
                raise ValueError(f"label {name!r} must be a bool array of shape (n,)")
