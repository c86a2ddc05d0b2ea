"""The runtime shield: an action is allowed when a safe continuation exists for the next ``depth``
decisions (issue 20, "a shield for every step of training").

The exhaustive shield (:func:`rac.engine.shield.synthesise`) answers for every state the model can
reach up to its horizon, and beyond a few decisions of a fine action grid it cannot be computed at
all. :class:`Lookahead` answers for one state at a time, at run time: from a decision state it
searches the next ``depth`` decisions against the recorded obstacles, depth first, and stops
searching below an action as soon as one continuation has survived them all.

**What "safe" means** is what it means to the exhaustive shield (``control: A[] !collide() &&
!offroad()``, :data:`rac.engine.graph.LABELS`): every sample of the continuation is safe (no
collision, on the road; under ``collision sticky`` no collision since the start either), and a
continuation only chooses actions the model's ``allow when`` allows (:class:`rac.engine.allow.ActionGuard`).
A continuation is complete after ``depth`` decisions, at the horizon, or at a decision state where
``allow when`` leaves no action (the run stops there, as the exhaustive shield's graph ends it). The
goal does not end a continuation (the model's runs go on, as for the exhaustive shield). The state
the decision is made in is not judged: the mask is about what follows, so a run that has already
left the road is still steered back onto it where that can be done.

**The mask.** Every action gets the *depth* of its deepest safe continuation found (0: its first
decision period is unsafe already, or ``allow when`` refuses it). The mask allows the actions of
the greatest depth ``d`` found, and :attr:`LookaheadMask.depth` says which ``d`` that is: ``depth`` (or
fewer decisions up to the horizon, :attr:`LookaheadMask.target`) when some action survives them all,
fewer when none does (then the mask allows the actions that stay safe longest, and says how long),
0 when every action is unsafe within one decision period (the mask is all False: no action is
known to be safe).

**The budget.** ``seconds`` and ``nodes`` bound the search per decision (:class:`LookaheadSettings`).
The first decision period of every action is always computed (one vectorised call); when the
budget runs out below it, the search stops where it is: every depth found so far is a proved one,
so the mask stays sound — each allowed action has a safe continuation of :attr:`LookaheadMask.depth`
decisions — but it may allow fewer actions than a complete search, or reach less deep.
:attr:`LookaheadMask.complete` is then False, and every consumer reports it (ScenarioEnv's
``info["shield_timeout"]``), never silently.

The search (all of it numpy over :class:`rac.model.batch.BatchModel`, the functions the exploration
uses): a node's children — one per action, over one decision period — are computed in one call;
before recursing, a few fixed continuations (hold the action, brake straight on, coast straight on,
brake holding the turn) are tried for every child at once, so that most actions are proved with a
handful of vectorised calls; only children none of them carries are searched exactly, in order of
their clearance to the obstacles.

Example::

    shield = Lookahead(data, horizon_samples=40, settings=LookaheadSettings(depth=5, seconds=0.05))
    result = shield.decide(np.array([k, *ego]))       # k a decision sample, ego the 7 significands
    result.mask, result.depth, result.complete
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from rac.engine.allow import ActionGuard, action_pairs
from rac.model.batch import BatchModel, batch_model
from rac.model.data import ModelData

__all__ = ["DEFAULT_DEPTH", "DEFAULT_SECONDS", "Lookahead", "LookaheadMask", "LookaheadSettings"]

#: The default number of decisions a continuation must survive.
DEFAULT_DEPTH = 5
#: The default time budget per decision, in seconds.
DEFAULT_SECONDS = 0.25


@dataclass(frozen=True)
class LookaheadSettings:
    """How far and how long the runtime shield searches at one decision.

    ``depth``: the decisions a safe continuation must cover (>= 1); ``seconds``: the time budget per
    decision (None: unbounded); ``nodes``: a budget of expanded search nodes per decision (None:
    unbounded) — the same on every machine, for reproducible runs and tests."""

    depth: int = DEFAULT_DEPTH
    seconds: float | None = DEFAULT_SECONDS
    nodes: int | None = None

    def __post_init__(self) -> None:
        if isinstance(self.depth, bool) or not isinstance(self.depth, int) or self.depth < 1:
            raise ValueError(f"depth must be a whole number of decisions >= 1, not {self.depth!r}")
        if self.seconds is not None and not self.seconds >= 0:
            raise ValueError(f"seconds must be >= 0 or None, not {self.seconds!r}")
        if self.nodes is not None and (isinstance(self.nodes, bool) or self.nodes < 0):
            raise ValueError(f"nodes must be >= 0 or None, not {self.nodes!r}")


@dataclass(frozen=True)
class LookaheadMask:
    """The runtime shield's answer at one decision state (see the module docstring)."""

    #: ``(P,)`` bool over :func:`rac.engine.allow.action_pairs`: the allowed actions.
    mask: np.ndarray
    #: ``(P,)`` int: per action, the deepest safe continuation found (decisions; 0: none).
    depths: np.ndarray
    #: The decisions every allowed action is proved to survive (0: the mask is empty).
    depth: int
    #: The decisions asked for at this state: the setting's depth, or fewer up to the horizon.
    target: int
    #: The sample up to which every allowed action has a safe continuation (the state's own sample
    #: when none has).
    until: int
    #: The search ended within its budget (every depth is exact up to ``target``).
    complete: bool
    #: Search nodes expanded (the root's children count as one).
    nodes: int
    seconds: float

    @property
    def timed_out(self) -> bool:
        """The budget ran out: the mask is sound for :attr:`depth` but may allow fewer actions."""
        return not self.complete


class _OutOfBudget(Exception):
    """The search's budget is spent (caught inside :meth:`Lookahead.decide`)."""


class Lookahead:
    """The runtime shield over ``data`` for runs ending at ``horizon_samples`` (see the module docstring)."""

    def __init__(self, data: ModelData, horizon_samples: int, settings: LookaheadSettings | None = None) -> None:
        if horizon_samples < 0:
            raise ValueError(f"horizon_samples must be >= 0, not {horizon_samples}")
        self.data = data
        self.horizon = int(horizon_samples)
        self.settings = settings if settings is not None else LookaheadSettings()
        self.every = int(data.decide_every)
        self.model: BatchModel = batch_model(data)
        self.guard = ActionGuard(data)
        self.pairs = action_pairs(data)
        self.n_actions = int(self.pairs.shape[0])
        self.sticky = bool(data.sticky)
        self._fallbacks = self._fallback_actions()

    # ------------------------------------------------------------ the model over decision periods
    def _fallback_actions(self) -> list[int]:
        """Fixed continuations tried before the exact search (besides holding the action): brake
        hard, coast, accelerate — each with the turning rate nearest 0."""
        jerks = np.unique(self.pairs[:, 0])
        turns = self.pairs[:, 1]
        straight = turns[np.argmin(np.abs(turns))]
        wanted = [jerks.min(), jerks[np.argmin(np.abs(jerks))], jerks.max()]
        out: list[int] = []
        for jerk in wanted:
            index = int(np.flatnonzero((self.pairs[:, 0] == jerk) & (turns == straight))[0])
            if index not in out:
                out.append(index)
        return out

    def period_end(self, k: int) -> int:
        """The sample where the decision period starting at sample ``k`` ends (the next decision
        sample, or the horizon)."""
        return min((k // self.every + 1) * self.every, self.horizon)

    def periods(self, states: np.ndarray, k: int, actions: np.ndarray,
                crashed: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """One decision period from sample ``k`` for every row: ``states`` ``(n, 7)`` ego rows, each with
        the action ``actions[i]`` held. Returns the states at the period's end ``(n, 7)``, whether every
        sample of the period is safe ``(n,)`` (and the action allowed: ``allow when`` on its first
        successor), and the smallest ``mindist()`` over the period ``(n,)`` (for ordering)."""
        model = self.model
        current = np.array(states, dtype=np.int32, copy=True)
        current[:, 5:7] = self.pairs[actions]
        safe = np.ones(current.shape[0], dtype=bool) if crashed is None else ~np.asarray(crashed, dtype=bool)
        clearance = np.full(current.shape[0], np.inf)
        end = self.period_end(k)
        for sample in range(k + 1, end + 1):
            current = model.sense(current)
            if sample == k + 1 and self.guard.restricts:
                safe &= self.guard.successors_allowed(current, sample)
            distance = model.mindist(current, sample)
            np.minimum(clearance, distance, out=clearance)
            safe &= ~(distance < model.native.td_d)
            safe &= ~model.offroad(current, sample)
        return current, safe, clearance

    def _stopped(self, states: np.ndarray, k: int) -> np.ndarray:
        """``(n,)``: decision states where ``allow when`` leaves no action (a run stops there)."""
        if not self.guard.restricts or states.shape[0] == 0:
            return np.zeros(states.shape[0], dtype=bool)
        return np.asarray(~self.guard.masks(states, k).any(axis=1), dtype=bool)

    # ------------------------------------------------------------ the search
    def decide(self, state: np.ndarray, crashed: bool = False) -> LookaheadMask:
        """The mask at ``state``: ``(8,)`` ``k, x, y, v, acc, head, jerk, turn`` (the shield's state row,
        :meth:`rac.learning.episodes.EpisodeBatch.state_keys`), ``k`` a decision sample before the
        horizon. ``crashed``: under ``collision sticky``, a collision happened on the way here
        (then nothing that follows is safe)."""
        started = time.perf_counter()
        row = np.asarray(state, dtype=np.int64).reshape(-1)
        if row.size != 8:
            raise ValueError(f"state must be the 8 values k, x, y, v, acc, head, jerk, turn, not {row.size}")
        k = int(row[0])
        if not 0 <= k < self.horizon:
            raise ValueError(f"the runtime shield decides at samples 0 .. {self.horizon - 1}, not at {k}")
        ego = row[1:].astype(np.int32)[None, :]
        target = self.decisions_left(k)
        self._deadline = None if self.settings.seconds is None else started + self.settings.seconds
        self._nodes = 0
        depths = np.zeros(self.n_actions, dtype=np.int64)
        complete = True
        if not (self.sticky and crashed):
            actions = np.arange(self.n_actions)
            ends, safe, clearance = self.periods(np.repeat(ego, self.n_actions, axis=0), k, actions)
            self._nodes = 1
            depths[safe] = 1
            end = self.period_end(k)
            try:
                if target > 1:
                    self._deepen(ends, safe, clearance, actions, end, target - 1, depths)
            except _OutOfBudget:
                complete = False
        best = int(depths.max())
        mask = depths == best if best > 0 else np.zeros(self.n_actions, dtype=bool)
        return LookaheadMask(mask=mask, depths=depths, depth=best, target=target, until=self.sample_after(k, best),
                             complete=complete, nodes=self._nodes, seconds=time.perf_counter() - started)

    def decisions_left(self, k: int) -> int:
        """The decisions asked for from sample ``k``: the setting's depth, or fewer up to the horizon."""
        count, sample = 0, k
        while sample < self.horizon and count < self.settings.depth:
            sample = self.period_end(sample)
            count += 1
        return count

    def sample_after(self, k: int, decisions: int) -> int:
        """The sample ``decisions`` decision periods after sample ``k`` (at most the horizon)."""
        sample = k
        for _ in range(decisions):
            sample = self.period_end(sample)
        return sample

    def reach(self, k: int) -> int:
        """The sample a complete answer at sample ``k`` guarantees safety up to."""
        return self.sample_after(k, self.decisions_left(k))

    def _spend(self) -> None:
        """Count one expanded node; :class:`_OutOfBudget` once the budget is spent."""
        settings = self.settings
        if settings.nodes is not None and self._nodes >= settings.nodes:
            raise _OutOfBudget
        if self._deadline is not None and time.perf_counter() >= self._deadline:
            raise _OutOfBudget
        self._nodes += 1

    def _deepen(self, ends: np.ndarray, safe: np.ndarray, clearance: np.ndarray, actions: np.ndarray, k: int,
                remaining: int, depths: np.ndarray) -> None:
        """Raise ``depths[actions[i]]`` (already 1 where ``safe``) to ``1 +`` the deepest continuation of
        ``remaining`` decisions from ``ends[i]`` at sample ``k`` — the root's children, all at once where
        the fixed continuations carry them, else one by one, the clearest first."""
        open_ = np.flatnonzero(safe)
        if open_.size == 0:
            return
        # complete already: at the horizon, or where `allow when` leaves no action (the run stops)
        done = self._stopped(ends[open_], k) if k < self.horizon else np.ones(open_.size, dtype=bool)
        depths[actions[open_[done]]] = 1 + remaining
        open_ = open_[~done]
        if open_.size == 0:
            return
        reached = self._fixed(ends[open_], k, actions[open_], remaining)
        depths[actions[open_]] = np.maximum(depths[actions[open_]], 1 + reached)
        rest = open_[reached < remaining]
        for i in rest[np.argsort(-clearance[rest], kind="stable")]:
            action = int(actions[i])

            def found(d: int, action: int = action) -> None:
                depths[action] = max(int(depths[action]), 1 + d)

            self._search(ends[i], k, action, remaining, found)

    def _fixed(self, states: np.ndarray, k: int, held: np.ndarray, remaining: int) -> np.ndarray:
        """``(n,)``: per row, the most decisions (up to ``remaining``) one of the fixed continuations —
        the row's own action held, or one of :meth:`_fallback_actions` held — survives from ``states``
        at sample ``k``. Every number returned is proved (a continuation of that many decisions is safe)."""
        self._spend()
        n = states.shape[0]
        candidates = [held] + [np.full(n, action) for action in self._fallbacks]
        count = len(candidates)
        rows = np.tile(states, (count, 1))
        actions = np.concatenate(candidates)
        alive = np.ones(rows.shape[0], dtype=bool)
        reached = np.zeros(rows.shape[0], dtype=np.int64)
        sample = k
        for decision in range(remaining):
            if sample >= self.horizon:
                reached[alive] = remaining
                break
            live = np.flatnonzero(alive)
            if live.size == 0:
                break
            stopped = self._stopped(rows[live], sample)
            reached[live[stopped]] = remaining
            alive[live[stopped]] = False
            live = live[~stopped]
            moved, ok, _ = self.periods(rows[live], sample, actions[live])
            rows[live] = moved
            alive[live[~ok]] = False
            reached[live[ok]] = decision + 1
            sample = self.period_end(sample)
        return reached.reshape(count, n).max(axis=0)

    def _search(self, state: np.ndarray, k: int, parent: int, remaining: int, found: Callable[[int], None]) -> int:
        """The deepest safe continuation (up to ``remaining`` decisions) from the decision state
        ``state`` at sample ``k``, depth first with early exit; ``found(d)`` is called with every deeper
        ``d`` proved on the way (so that a search cut short by the budget keeps what it proved)."""
        if remaining == 0 or k >= self.horizon:
            found(remaining)
            return remaining
        self._spend()
        ego = state[None, :]
        if self._stopped(ego, k)[0]:
            found(remaining)
            return remaining
        actions = np.arange(self.n_actions)
        ends, safe, clearance = self.periods(np.repeat(ego, self.n_actions, axis=0), k, actions)
        open_ = np.flatnonzero(safe)
        if open_.size == 0:
            return 0
        best = 1
        found(1)
        if remaining == 1:
            return 1
        end = self.period_end(k)
        if end >= self.horizon:
            found(remaining)
            return remaining
        reached = self._fixed(ends[open_], end, actions[open_], remaining - 1)
        top = int(reached.max())
        if top >= 1:
            best = max(best, 1 + top)
            found(best)
            if best == remaining:
                return best
        # the parent's action first (continuity), then the clearest
        order = open_[np.lexsort((-clearance[open_], actions[open_] != parent))]
        for i in order:
            if reached[np.searchsorted(open_, i)] >= remaining - 1:
                continue
            def deeper(d: int) -> None:
                found(1 + d)

            depth = 1 + self._search(ends[i], end, int(actions[i]), remaining - 1, deeper)
            if depth > best:
                best = depth
                if best == remaining:
                    return best
        return best

