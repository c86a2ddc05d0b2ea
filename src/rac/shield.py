"""Safety shields saved to a file and used from a training loop.

``rac.shield.save(shield, path)`` writes the most permissive safe strategy computed by
:func:`rac.engine.storm.safety_shield` (``strategy safe = control: A[] ...``);
``rac.shield.load(path)`` reads it back as a :class:`ShieldTable`::

    table = rac.shield.load("safe.shield.npz")
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

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from rac.engine.storm import Shield

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

    def __post_init__(self) -> None:
        if self.unseen not in UNSEEN_POLICIES:
            raise ValueError(f"unseen must be one of {UNSEEN_POLICIES}, not {self.unseen!r}")
        index = {row.tobytes(): i for i, row in enumerate(np.ascontiguousarray(self.states, dtype=np.int32))}
        object.__setattr__(self, "_index", index)

    @property
    def n_actions(self) -> int:
        return int(self.masks.shape[1])

    def _row(self, state: object) -> int | None:
        key = np.ascontiguousarray(np.asarray(state, dtype=np.int32)).tobytes()
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


def save(shield: Shield, path: str | Path, *, n_actions: int | None = None) -> Path:
    """Write a shield's decision states and their allowed actions to ``path`` (compressed .npz)."""
    graph = shield.graph
    actions = graph.choice_action
    decision = actions >= 0
    n_actions = n_actions if n_actions is not None else (int(actions.max()) + 1 if decision.any() else 0)
    owner = np.repeat(np.arange(graph.n_states), np.diff(graph.choice_offsets))
    states_with_decisions = np.unique(owner[decision])
    row_of = np.full(graph.n_states, -1, dtype=np.int64)
    row_of[states_with_decisions] = np.arange(states_with_decisions.size)
    masks = np.zeros((states_with_decisions.size, n_actions), dtype=bool)
    picked = decision & shield.allowed_choices
    masks[row_of[owner[picked]], actions[picked]] = True
    path = Path(path)
    with path.open("wb") as handle:
        np.savez_compressed(handle, format=np.array(FORMAT), columns=np.array(graph.columns),
                            states=graph.states[states_with_decisions].astype(np.int32), masks=masks)
    return path


def load(path: str | Path, *, unseen: str = "none") -> ShieldTable:
    """Read a shield written by :func:`save`; ``unseen`` says what unknown states get."""
    path = Path(path)
    try:
        with np.load(path, allow_pickle=False) as data:
            if str(data["format"]) != FORMAT:
                raise ValueError(f"{path}: not a rac shield (format {str(data['format'])!r})")
            return ShieldTable(tuple(str(c) for c in data["columns"]), data["states"].astype(np.int32),
                               data["masks"].astype(bool), unseen)
    except (OSError, KeyError, ValueError) as exc:
        if isinstance(exc, FileNotFoundError):
            raise
        raise ValueError(f"{path}: cannot read the shield: {exc}") from None
