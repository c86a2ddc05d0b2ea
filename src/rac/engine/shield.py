"""Safety shields saved to a file and used from a training loop.

``rac.engine.shield.save(shield, path)`` writes the most permissive safe strategy computed by
:func:`rac.engine.storm.safety_shield` (``strategy safe = control: A[] ...``);
``rac.engine.shield.load(path)`` reads it back as a :class:`ShieldTable`::

    table = rac.engine.shield.load("safe.shield.npz")
    mask = table.mask(state)          # (n_actions,) bool: the actions allowed in `state`
    ok = table.allowed(state)         # the allowed action indices

A state is the integer vector of the explored model (``table.columns``, e.g.
``k, x, y, v, acc, head, jerk, turn``). Only decision states are stored.

**States the shield has never seen.** The shield was computed on the states the model can
reach; a state outside them (a different start, a sensor reading the model cannot produce)
is *unseen*. What to do then is the caller's choice, made once when loading:

- ``unseen="none"`` (default): nothing is known to be safe, so no action is allowed (an empty
  mask). A masked learner must then fall back to a safe manoeuvre of its own;
- ``unseen="all"``: every action is allowed (the shield does not restrict unseen states);
- ``unseen="error"``: raise :class:`UnseenState`.
"""

from __future__ import annotations

import os
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from rac.engine.storm import Shield

if TYPE_CHECKING:
    from rac.model.data import ModelData

FORMAT = "rac-shield-1"
UNSEEN_POLICIES = ("none", "all", "error")


class UnseenState(KeyError):
    """The shield has no entry for this state (``unseen="error"``)."""


@dataclass(frozen=True)
class ShieldTable:
    """A loaded shield: per decision state, a mask over the action indices."""

    columns: tuple[str, ...]
    states: np.ndarray  # (s, d) int32, decision states
    masks: np.ndarray  # (s, n_actions) bool
    unseen: str = "none"
    #: > 0: the shield was computed with ``explore(..., forget_actions=True)``, so a state at a sample
    #: ``k`` with ``k % forget_every == 0`` is looked up with its ``jerk`` and ``turn`` as 0 (the action
    #: that led to it, which no later step reads); 0: states are looked up as they are.
    forget_every: int = 0

    def __post_init__(self) -> None:
        if self.unseen not in UNSEEN_POLICIES:
            raise ValueError(f"unseen must be one of {UNSEEN_POLICIES}, not {self.unseen!r}")
        index = {row.tobytes(): i for i, row in enumerate(np.ascontiguousarray(self.states, dtype=np.int32))}
        object.__setattr__(self, "_index", index)

    @property
    def n_actions(self) -> int:
        return int(self.masks.shape[1])

    def _keys(self, rows: np.ndarray) -> np.ndarray:
        """``rows`` ``(n, d)`` as the table keys them (see :attr:`forget_every`)."""
        rows = np.array(rows, dtype=np.int32, ndmin=2)
        if self.forget_every > 0 and "k" in self.columns:
            forgotten = rows[:, self.columns.index("k")] % self.forget_every == 0
            for name in ("jerk", "turn"):
                if name in self.columns:
                    rows[forgotten, self.columns.index(name)] = 0
        return np.ascontiguousarray(rows)

    def _row(self, state: object) -> int | None:
        key = self._keys(np.asarray(state))[0].tobytes()
        return self._index.get(key)  # type: ignore[attr-defined]

    def mask(self, state: object) -> np.ndarray:
        """``(n_actions,)`` bool: the actions allowed in ``state`` (the MaskablePPO convention)."""
        row = self._row(state)
        if row is not None:
            return self.masks[row].copy()
        if self.unseen == "error":
            raise UnseenState(f"the shield has no entry for state {list(np.asarray(state).tolist())}")
        return np.full(self.n_actions, self.unseen == "all")

    def allowed(self, state: object) -> np.ndarray:
        """The allowed action indices in ``state`` (see the module docstring for unseen states)."""
        return np.flatnonzero(self.mask(state))

    def knows(self, state: object) -> bool:
        """Whether ``state`` is one of the shield's decision states."""
        return self._row(state) is not None

    def masks_at(self, k: int, states: np.ndarray) -> np.ndarray:
        """:meth:`masks_for` of the ego rows ``states`` ``(n, 7)`` at sample ``k``: the
        ``policy(k, states)`` that :func:`rac.engine.simulate.simulate` takes."""
        states = np.asarray(states, dtype=np.int32)
        return self.masks_for(np.column_stack([np.full(states.shape[0], k, dtype=np.int32), states]))

    def masks_for(self, states: np.ndarray) -> np.ndarray:
        """``(n, n_actions)`` bool: :meth:`mask` of every row of ``states`` (``(n, d)``), in one call.

        Unseen rows follow the table's ``unseen`` policy (``"error"`` raises for the first one)."""
        rows = self._keys(np.asarray(states))
        found = np.array([self._index.get(row.tobytes(), -1) for row in rows], dtype=np.int64)  # type: ignore[attr-defined]
        out = np.empty((rows.shape[0], self.n_actions), dtype=bool)
        seen = found >= 0
        out[seen] = self.masks[found[seen]]
        if not seen.all():
            if self.unseen == "error":
                raise UnseenState(f"the shield has no entry for state {rows[~seen][0].tolist()}")
            out[~seen] = self.unseen == "all"
        return out


class SafeOnward:
    """Whether a run can stay safe from a state to the horizon: the state is winning in the safety
    game of ``shield`` (``control: A[] !collide() && !offroad()`` up to ``horizon_samples``), read off
    its graph. Called with ``(m, 8)`` state keys ``k, x, y, v, acc, head, jerk, turn``; a state the
    graph does not hold (none a safe run reaches) is not. ``forget_every``: the graph was explored
    with ``forget_actions`` (:func:`rac.engine.explore.forgets_actions`), so such keys are looked up
    with jerk and turn at 0 where it holds them so. Used by ``rac experiment`` to judge a run that
    reaches the goal: "safe at the goal" means it can also stay safe to the horizon."""

    def __init__(self, shield: Shield, horizon_samples: int, forget_every: int = 0) -> None:
        graph = shield.graph
        self.horizon = horizon_samples
        self.forget_every = forget_every
        k = graph.states[:, 0]
        order = np.argsort(k, kind="stable")
        bounds = np.searchsorted(k[order], np.arange(horizon_samples + 2))
        self._layers = {layer: order[bounds[layer]:bounds[layer + 1]] for layer in range(horizon_samples + 1)}
        self._graph = graph
        # collision sticky: only states no collision has reached, keyed without the flag
        self._columns = [i for i, name in enumerate(graph.columns) if name != "crashed"]
        self._clean = (graph.states[:, graph.columns.index("crashed")] == 0 if "crashed" in graph.columns
                       else np.ones(graph.n_states, dtype=bool))
        self._winning = shield.winning
        self._sets: dict[int, set[bytes]] = {}

    def _winning_at(self, k: int) -> set[bytes]:
        found = self._sets.get(k)
        if found is None:
            rows = self._layers.get(k, np.zeros(0, dtype=np.int64))
            rows = rows[self._winning[rows] & self._clean[rows]]
            states = np.ascontiguousarray(self._graph.states[rows][:, self._columns], dtype=np.int32)
            found = self._sets[k] = {row.tobytes() for row in states}
        return found

    def __call__(self, keys: np.ndarray) -> np.ndarray:
        from rac.engine.explore import forgets_actions

        rows = np.array(keys, dtype=np.int32, ndmin=2)
        if self.forget_every > 0:
            rows[forgets_actions(rows[:, 0], self.forget_every, self.horizon), 6:8] = 0
        rows = np.ascontiguousarray(rows)
        return np.array([row.tobytes() in self._winning_at(int(row[0])) for row in rows], dtype=bool)


def synthesise(data: ModelData, horizon_samples: int, *, max_states: int | None = None,
               max_bytes: int | None = None,
               progress: Callable[[int, int, int], None] | None = None) -> tuple[Shield, ShieldTable]:
    """The safety shield of ``control: A[] !collide() && !offroad()`` up to the horizon: the model
    explored with unsafe states not expanded, the most permissive strategy
    (:func:`rac.engine.storm.safety_shield`), and its table over the model's whole action grid.
    :class:`~rac.engine.budget.BudgetExceeded` (a ``MemoryError``) beyond ``max_states`` or ``max_bytes``
    (from the exploration)."""
    from rac.engine.explore import action_pairs, explore
    from rac.engine.storm import safety_shield

    # The shield reads labels and choices only: states differing in the action that led to them merge.
    graph = explore(data, horizon_samples=horizon_samples, prune_unsafe=True, max_states=max_states,
                    max_bytes=max_bytes, progress=progress, forget_actions=True)
    computed = safety_shield(graph, "safe")
    return computed, table(computed, n_actions=len(action_pairs(data)), forget_every=data.decide_every)


def table(shield: Shield, *, n_actions: int | None = None, unseen: str = "none", forget_every: int = 0) -> ShieldTable:
    """The :class:`ShieldTable` of a computed shield (what :func:`save` writes and :func:`load` reads);
    ``forget_every``: the model's ``decide_every`` when the graph was explored with ``forget_actions``."""
    graph = shield.graph
    actions = graph.choice_action
    decision = actions >= 0
    n_actions = n_actions if n_actions is not None else (int(actions.max()) + 1 if decision.any() else 0)
    owner = np.repeat(np.arange(graph.n_states), np.diff(graph.choice_offsets))
    states_with_decisions = np.unique(owner[decision])
    columns = tuple(graph.columns)
    kept = list(range(len(columns)))
    if "crashed" in columns:  # collision sticky: the table holds the states no collision has reached yet,
        crashed = columns.index("crashed")  # keyed without the flag, as a training loop observes them
        states_with_decisions = states_with_decisions[graph.states[states_with_decisions, crashed] == 0]
        kept.remove(crashed)
        columns = tuple(columns[i] for i in kept)
    row_of = np.full(graph.n_states, -1, dtype=np.int64)
    row_of[states_with_decisions] = np.arange(states_with_decisions.size)
    masks = np.zeros((states_with_decisions.size, n_actions), dtype=bool)
    picked = decision & shield.allowed_choices
    masks[row_of[owner[picked]], actions[picked]] = True
    states = graph.states[states_with_decisions][:, kept].astype(np.int32)
    return ShieldTable(columns, states, masks, unseen, forget_every)


def save(shield: Shield | ShieldTable, path: str | Path, *, n_actions: int | None = None) -> Path:
    """Write a shield's decision states and their allowed actions to ``path`` (compressed .npz).

    The file is written to a temporary name beside ``path`` and renamed, so an interrupted
    write never leaves a half shield behind."""
    shield_table = shield if isinstance(shield, ShieldTable) else table(shield, n_actions=n_actions)
    path = Path(path)
    partial = path.with_name(path.name + ".partial")
    try:
        with partial.open("wb") as handle:
            np.savez_compressed(handle, format=np.array(FORMAT), columns=np.array(shield_table.columns),
                                states=shield_table.states.astype(np.int32), masks=shield_table.masks,
                                forget_every=np.array(shield_table.forget_every))
        os.replace(partial, path)
    finally:
        partial.unlink(missing_ok=True)
    return path


def load(path: str | Path, *, unseen: str = "none") -> ShieldTable:
    """Read a shield written by :func:`save`; ``unseen`` says what unknown states get."""
    path = Path(path)
    try:
        with np.load(path, allow_pickle=False) as data:
            if str(data["format"]) != FORMAT:
                raise ValueError(f"{path}: not a rac shield (format {str(data['format'])!r})")
            forget_every = int(data["forget_every"]) if "forget_every" in data.files else 0
            return ShieldTable(tuple(str(c) for c in data["columns"]), data["states"].astype(np.int32),
                               data["masks"].astype(bool), unseen, forget_every)
    except (OSError, KeyError, ValueError) as exc:
        if isinstance(exc, FileNotFoundError):
            raise
        raise ValueError(f"{path}: cannot read the shield: {exc}") from None
