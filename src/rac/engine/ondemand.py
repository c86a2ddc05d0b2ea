"""The safety shield up to the horizon, state by state, where the model is too large to explore.

``strategy safe = control: A[] !collide() && !offroad()`` needs the whole (pruned) model for its
table (:func:`rac.engine.shield.synthesise`); on a fine action grid or a long horizon that graph
cannot be built. :class:`OnDemandShield` answers the same question for one state at a time, when a
run reaches it: an action is allowed when the runtime shield (:class:`rac.engine.lookahead.Lookahead`)
proves a safe continuation from it **up to the horizon** (every remaining decision). That is the
exhaustive shield's own condition, so every allowed action is one the table would allow.

The search per state has a budget of search nodes (:attr:`OnDemandShield.nodes`, the runtime shield's
:attr:`~rac.engine.lookahead.LookaheadSettings.nodes`): the same on every machine, so the same inputs
give the same masks anywhere. When it runs out before an action is proved, that action is not
allowed: the mask stays sound (nothing unsafe is allowed) but may allow fewer actions than the
table would. A time guard per state (:attr:`OnDemandShield.seconds`) is only a safety net against a
search far slower than its nodes suggest; a mask it cut depends on the machine's speed and load.
:attr:`OnDemandShield.stats` counts the states whose budget ran out, those of them the time guard
cut, and the states where no action was proved (a mask of all False, the table's answer for a
losing state), so that every consumer can say how far the guarantee reached and whether it was
reproducible.

It is a :class:`~rac.engine.shield.ShieldTable` without rows: :meth:`masks_for` computes a row
when it is asked for (and keeps it), so simulations and learning use it as they use a table.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import ClassVar

import numpy as np

from rac.engine.allow import action_pairs
from rac.engine.lookahead import GUARD_SECONDS, NODE_BUDGET, Lookahead, LookaheadSettings
from rac.engine.shield import ShieldTable
from rac.model.data import ModelData
from rac.model.sample import GRAPH_EGO, GraphColumn

__all__ = ["OnDemandShield", "OnDemandStats", "on_demand"]

#: The default node budget per state (simulations and learning ask for thousands): the same masks on
#: every machine.
DEFAULT_NODES = NODE_BUDGET
#: The default time guard per state, in seconds, reported where it fires (:attr:`OnDemandStats.clock`).
DEFAULT_SECONDS = GUARD_SECONDS
#: The (state, action) pairs whose fixed continuations are tried at once (their arrays, ~100 bytes a
#: pair and continuation, two continuations a pair, stay near 50 MB however many states are asked
#: about together).
FIXED_PAIRS = 1 << 18
#: The columns of the shield's state rows (as :meth:`rac.learning.episodes.EpisodeBatch.state_keys`).
COLUMNS = ("k", "x", "y", "v", "acc", "head", "jerk", "turn")


@dataclass
class OnDemandStats:
    """What the on-demand shield has answered so far."""

    states: int = 0  # distinct states asked about
    timed_out: int = 0  # of them, where the budget ran out (the mask may allow fewer actions)
    clock: int = 0  # of those, where the time guard cut the search (the mask depends on the machine)
    empty: int = 0  # of the states, where no action was proved safe to the horizon
    clocked_answers: int = 0  # masks handed out (a state asked again counts again) that the time guard cut


@dataclass(frozen=True)
class OnDemandShield(ShieldTable):
    """A :class:`ShieldTable` whose rows are the runtime shield's answers up to the horizon, computed
    when asked for (see the module docstring). Build it with :func:`on_demand`."""

    lookahead: Lookahead | None = field(default=None, compare=False, repr=False)
    #: The time guard per state (None: none).
    seconds: float | None = DEFAULT_SECONDS
    #: The node budget per state (None: none; with no time guard either, every row is searched exactly).
    nodes: int | None = DEFAULT_NODES
    stats: OnDemandStats = field(default_factory=OnDemandStats, compare=False)
    #: Called before each search of a state and each chunk of fixed continuations (None: nothing): a time
    #: limit's check, which may raise. One sample of thousands of runs may ask for thousands of searches.
    check: Callable[[], None] | None = field(default=None, compare=False, repr=False)
    savable: ClassVar[bool] = False  # its rows are computed when asked: a saved file would hold none

    def __post_init__(self) -> None:
        super().__post_init__()
        object.__setattr__(self, "_memo", {})
        # per state whose row is empty: the actions the search proved safe the longest (fewer decisions
        # than the horizon), for consumers that must choose there anyway (:meth:`fallback_for`)
        object.__setattr__(self, "_longest", {})
        # the states whose search the time guard cut: every answer from them is counted (stats.clocked_answers)
        object.__setattr__(self, "_clocked", set())

    def masks_for(self, states: np.ndarray) -> np.ndarray:
        """``(n, n_actions)`` bool: per state row, the actions proved to have a safe continuation up
        to the horizon (all False: none proved; at or after the horizon: every action).

        With a budget per state (nodes or time), the rows asked for together at one sample are first tried at once:
        every action of every row, followed by two fixed continuations to the horizon (holding the
        action; braking straight on), in one vectorised pass. A row where that proves some action
        keeps the actions it proved (sound; it may allow fewer than a full search); the others are
        searched one by one. Without a budget every row is searched exactly."""
        assert self.lookahead is not None
        rows = np.array(states, dtype=np.int64, ndmin=2)
        memo: dict[bytes, np.ndarray] = self._memo  # type: ignore[attr-defined]
        keys = [row[:GraphColumn.CRASHED].tobytes() for row in rows]
        todo = [i for i, key in enumerate(keys) if key not in memo]
        if todo and (self.seconds is not None or self.nodes is not None):
            for k in np.unique(rows[todo, GraphColumn.K]).tolist():
                group = [i for i in todo if rows[i, GraphColumn.K] == k and keys[i] not in memo]
                if k >= self.lookahead.horizon or not group:
                    continue
                # in chunks: the fixed continuations hold several int32 copies of every (row, action)
                # pair, 6.7 GB for the million states of one layer of the tutorial's 45 actions
                step = max(1, FIXED_PAIRS // self.n_actions)  # rows of n_actions pairs each
                egos = rows[group, GRAPH_EGO]
                proved = np.concatenate([self._fixed_proofs(egos[start:start + step], int(k))
                                         for start in range(0, len(group), step)])  # _fixed_proofs checks
                for i, mask in zip(group, proved):
                    if mask.any() and keys[i] not in memo:  # a state asked twice at once is one state
                        memo[keys[i]] = mask
                        self.stats.states += 1
        for i, key in enumerate(keys):
            if key not in memo:
                if self.check is not None:
                    self.check()
                memo[key] = self._searched(rows[i])
        clocked: set[bytes] = self._clocked  # type: ignore[attr-defined]
        if clocked:
            self.stats.clocked_answers += sum(key in clocked for key in keys)
        return np.array([memo[key] for key in keys], dtype=bool).reshape(rows.shape[0], self.n_actions)

    def _searched(self, row: np.ndarray) -> np.ndarray:
        """One row's mask by the runtime shield's own search up to the horizon."""
        assert self.lookahead is not None
        if int(row[0]) >= self.lookahead.horizon:
            return np.ones(self.n_actions, dtype=bool)
        found = self.lookahead.decide(row[:GraphColumn.CRASHED])
        full = found.depth >= found.target and found.depth > 0
        mask = found.mask.copy() if full else np.zeros(self.n_actions, dtype=bool)
        if not full and found.depth > 0 and found.mask.any():
            self._longest[row[:GraphColumn.CRASHED].tobytes()] = found.mask.copy()  # type: ignore[attr-defined]
        self.stats.states += 1
        self.stats.timed_out += int(not found.complete)
        self.stats.clock += int(found.clock)
        if found.clock:
            self._clocked.add(row[:GraphColumn.CRASHED].tobytes())  # type: ignore[attr-defined]
        self.stats.empty += int(not mask.any())
        return mask

    def fallback_for(self, states: np.ndarray) -> np.ndarray:
        """Where a row allows nothing (no action proved safe to the horizon within the budget): the
        actions the search proved safe for the most decisions, if it proved any (all False else).
        :meth:`masks_for` must have been asked about the rows first."""
        rows = np.array(states, dtype=np.int64, ndmin=2)
        longest: dict[bytes, np.ndarray] = self._longest  # type: ignore[attr-defined]
        empty = np.zeros(self.n_actions, dtype=bool)
        return np.array([longest.get(row[:GraphColumn.CRASHED].tobytes(), empty) for row in rows],
                        dtype=bool).reshape(rows.shape[0], self.n_actions)

    def _fixed_proofs(self, egos: np.ndarray, k: int) -> np.ndarray:
        """``(n, P)``: the actions at sample ``k`` of the ego rows ``egos`` ``(n, 7)`` that a fixed
        continuation (hold the action, or brake straight on) keeps safe up to the horizon."""
        shield = self.lookahead
        assert shield is not None
        if self.check is not None:
            self.check()
        n, count = egos.shape[0], self.n_actions
        actions = np.tile(np.arange(count), n)
        ends, safe, _ = shield.periods(np.repeat(egos.astype(np.int32), count, axis=0), k, actions)
        pairs = shield.pairs
        brake = int(np.lexsort((np.abs(pairs[:, 1]), pairs[:, 0]))[0])  # the hardest braking, straight on
        # both continuations in one batch (each row is computed alone, so stacking changes no value):
        # the model's calls cost mostly their overhead on the few rows a learning step asks about
        chosen = np.concatenate([actions, np.full(actions.size, brake)])
        alive = np.concatenate([safe, safe])
        current = np.concatenate([ends, ends])
        sample = shield.period_end(k)
        while sample < shield.horizon and alive.any():
            live = np.flatnonzero(alive)
            current[live], ok, _ = shield.periods(current[live], sample, chosen[live])
            alive[live] = ok
            sample = shield.period_end(sample)
        proved = alive[:actions.size] | alive[actions.size:]
        return proved.reshape(n, count)

    def mask(self, state: object) -> np.ndarray:
        return self.masks_for(np.asarray(state))[0].copy()

    def knows(self, state: object) -> bool:
        return True


def on_demand(data: ModelData, horizon_samples: int, seconds: float | None = DEFAULT_SECONDS,
              nodes: int | None = DEFAULT_NODES, check: Callable[[], None] | None = None) -> OnDemandShield:
    """The on-demand safety shield of ``data`` up to ``horizon_samples``: ``nodes`` search nodes per
    state (reproducible), ``seconds`` per state as a time guard (None: none; both None: exact); ``check``
    before each state's search (:attr:`OnDemandShield.check`)."""
    n_actions = len(action_pairs(data))
    settings = LookaheadSettings(depth=horizon_samples + 1, seconds=seconds, nodes=nodes)
    lookahead = Lookahead(data, horizon_samples, settings)
    return OnDemandShield(COLUMNS, np.zeros((0, len(COLUMNS)), dtype=np.int32), np.zeros((0, n_actions), dtype=bool),
                          horizon=horizon_samples, model=data.digest, lookahead=lookahead, seconds=settings.seconds,
                          nodes=settings.nodes, check=check)
