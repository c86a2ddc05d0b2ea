"""The runtime shield: an action is allowed when a safe continuation exists for the next ``depth``
decisions (issue 20, "a shield for every step of training").

The exhaustive shield (:func:`rac.engine.shield.synthesise`) answers for every state the model can
reach up to its horizon, and beyond a few decisions of a fine action grid it cannot be computed at
all. :class:`Lookahead` answers for one state at a time, at run time: from a decision state it
searches the next ``depth`` decisions against the recorded obstacles and stops searching below an
action as soon as one continuation of it has survived them all (first the few fixed continuations
that most actions survive, then exhaustively, layer by layer).

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

**The budget.** ``nodes`` and ``seconds`` bound the search per decision (:class:`LookaheadSettings`), and
``max_bytes`` its memory: a layer's successors are estimated (:data:`SUCCESSOR_BYTES`, :data:`LAYER_BYTES`)
before each chunk of them is computed, so a search stops before it would hold more (:attr:`LookaheadMask.memory`).
By default the budget is :data:`NODE_BUDGET` search nodes, which gives the same masks on every machine
(so a training run at a seed is the same anywhere), with a time guard of :data:`GUARD_SECONDS` far
above what they take.
The first decision period of every action is always computed (one vectorised call); when the
budget runs out below it, the search stops where it is: every depth found so far is a proved one,
so the mask stays sound — each allowed action has a safe continuation of :attr:`LookaheadMask.depth`
decisions — but it may allow fewer actions than a complete search, or reach less deep.
:attr:`LookaheadMask.complete` is then False, and every consumer reports it (ScenarioEnv's
``info["shield_timeout"]``), never silently. The node budget gives the same answer on every machine;
where the time budget stopped the search, :attr:`LookaheadMask.clock` says the answer depended on the
machine's speed.

The search (all of it numpy over :class:`rac.model.batch.BatchModel`, the functions the exploration
uses) goes layer by layer, all open actions at once: a layer holds the states that have survived
so many decisions, each tagged with the first action it continues. A few fixed continuations (hold
the state's action, brake, coast or accelerate straight on) are tried from every state of a layer
in one vectorised pass, and an action one of them carries to the end is done: most actions are
proved so within a few calls. The states of the actions left open are expanded exhaustively, one
decision period under every action in one call per chunk, and their safe successors (merged where
equal) form the next layer; an action whose states all die out has the depth of its last layer.

Example::

    shield = Lookahead(data, horizon_samples=40, settings=LookaheadSettings(depth=5, nodes=200))
    result = shield.decide(np.array([k, *ego]))       # k a decision sample, ego the 7 significands
    result.mask, result.depth, result.complete
"""

from __future__ import annotations

import numbers
import time
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from rac.core.diagnostics import RacError
from rac.engine.allow import ActionGuard, action_pairs
from rac.model.batch import BatchModel, batch_model
from rac.model.data import ModelData
from rac.model.sample import ACTION, Ego, collides

__all__ = ["DEFAULT_DEPTH", "DEFAULT_SECONDS", "GUARD_SECONDS", "LAYER_BYTES", "NODE_BUDGET", "SUCCESSOR_BYTES",
           "Lookahead", "LookaheadMask", "LookaheadSettings"]

#: The default number of decisions a continuation must survive.
DEFAULT_DEPTH = 5
#: The default node budget per decision (:class:`LookaheadSettings`), so that answers do not depend on
#: the machine (ScenarioEnv's masks, the on-demand shield's per state, ``rac simulate --shield``'s
#: runtime shield): the searches the fixed continuations leave to it take up to ~0.2 s on the paper's
#: model with 45 actions, a few ms mostly.
NODE_BUDGET = 64
#: The time guard beside :data:`NODE_BUDGET`, in seconds: a safety net far above what the nodes take;
#: where it fires the answer says so (:attr:`LookaheadMask.clock`).
GUARD_SECONDS = 2.0
#: The default time limit per decision, in seconds: the guard :data:`GUARD_SECONDS` (until the node
#: budget became the default it was a budget of 0.1 s, which made the masks depend on the machine's load).
DEFAULT_SECONDS = GUARD_SECONDS
#: How many successor rows one call computes (states of a layer times actions).
CHUNK_ROWS = 1 << 12
#: The peak bytes one safe successor of an expanded layer costs until the next layer is merged: its row
#: (owner and 7 int32 columns) in the chunks, in their concatenation, in the merged copy, and the next
#: layer's owners (int64) and states split from it. An upper bound: tracemalloc saw 81 B a successor at the start
#: search's worst (3.5 M successors of a layer, 45 actions), the peak RSS a little more.
SUCCESSOR_BYTES = 96
#: The bytes a layer's state costs while it is searched: its owner (int64) and 7 int32 columns, a copy of
#: both where the carried states leave it, and the per-state results of the fixed continuations.
LAYER_BYTES = 96
#: A merged row's columns (owner, then the state's 7) as fields: sorted in place field by field, the
#: order of ``np.unique(rows, axis=0)``, without its copies.
_ROW_FIELDS = np.dtype([(f"f{i}", np.int32) for i in range(8)])


@dataclass(frozen=True)
class LookaheadSettings:
    """How far and how long the runtime shield searches at one decision.

    ``depth``: the decisions a safe continuation must cover (>= 1); ``nodes``: a budget of expanded
    search nodes per decision (>= 1, default :data:`NODE_BUDGET`; None: unbounded) — the same on every
    machine, for reproducible runs and tests; ``seconds``: a time limit per decision (> 0, default
    :data:`GUARD_SECONDS`, a guard far above what the default nodes take; None: unbounded). Where the
    time limit stops a search, the answer depends on the machine's speed and load, and says so
    (:attr:`LookaheadMask.clock`); ``nodes=None`` with a small ``seconds`` makes that the rule.

    The first decision period of every action is always searched (one node), whatever the budget:
    a budget of 0 nodes or 0 seconds could not be kept (and reads like "no limit", which is None), so
    it is refused; ``nodes=1`` asks for that first period alone."""

    depth: int = DEFAULT_DEPTH
    seconds: float | None = DEFAULT_SECONDS
    nodes: int | None = NODE_BUDGET
    #: The most bytes the search may hold (None: no limit): a search that would need more stops, what it
    #: proved standing (:attr:`LookaheadMask.memory`). The default node budget needs a few MB.
    max_bytes: int | None = None

    def __post_init__(self) -> None:
        # numpy's integers are whole numbers too (a depth or budget from a sweep's array): kept as int
        if not _whole(self.depth) or self.depth < 1:
            raise ValueError(f"depth must be a whole number of decisions >= 1, not {self.depth!r}")
        object.__setattr__(self, "depth", int(self.depth))
        # 0 is refused: the first decision period (one node) is searched whatever the budget, and 0
        # reads like "no limit" (None), where it gave every state a mask one decision deep
        if self.seconds is not None and (not isinstance(self.seconds, numbers.Real) or isinstance(self.seconds, bool)
                                         or not self.seconds > 0):
            raise ValueError(f"seconds must be a time > 0 (a limit per decision) or None (no limit), "
                             f"not {self.seconds!r}")
        if self.nodes is not None:
            if not _whole(self.nodes) or self.nodes < 1:
                raise ValueError(f"nodes must be a whole number >= 1 (the first decision period of every action "
                                 f"is one node, always searched) or None (no budget), not {self.nodes!r}")
            object.__setattr__(self, "nodes", int(self.nodes))
        if self.max_bytes is not None:
            if not _whole(self.max_bytes) or self.max_bytes < 1:
                raise ValueError(f"max_bytes must be a whole number of bytes >= 1 or None (no limit), "
                                 f"not {self.max_bytes!r}")
            object.__setattr__(self, "max_bytes", int(self.max_bytes))


def _whole(value: object) -> bool:
    """Whether ``value`` is an integer (numpy's too), not a bool."""
    return isinstance(value, numbers.Integral) and not isinstance(value, (bool, np.bool_))


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
    #: The *time* budget stopped the search (not the node budget, nor its end): then the answer depends
    #: on the machine's speed and load, and consumers that promise reproducible answers say so.
    clock: bool = False
    #: The memory limit (:attr:`LookaheadSettings.max_bytes`) stopped the search before its other budgets.
    memory: bool = False

    @property
    def timed_out(self) -> bool:
        """The budget ran out: the mask is sound for :attr:`depth` but may allow fewer actions."""
        return not self.complete


class _OutOfBudget(RacError):
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
        self._progress: Callable[[int], None] | None = None

    # ------------------------------------------------------------ the model over decision periods
    def _fallback_actions(self) -> list[int]:
        """The fixed continuations tried before a layer is expanded (besides holding the state's
        action): brake hard, coast, accelerate — each with the turning rate nearest 0."""
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
        current[:, ACTION] = self.pairs[actions]
        safe = np.ones(current.shape[0], dtype=bool) if crashed is None else ~np.asarray(crashed, dtype=bool)
        clearance = np.full(current.shape[0], np.inf)
        end = self.period_end(k)
        for sample in range(k + 1, end + 1):
            current = model.sense(current)
            if sample == k + 1 and self.guard.restricts:
                safe &= self.guard.successors_allowed(current, sample)
            distance = model.mindist(current, sample)
            np.minimum(clearance, distance, out=clearance)
            safe &= ~collides(distance, model.native.td_d)
            safe &= ~model.offroad(current, sample)
        return current, safe, clearance

    def _stopped(self, states: np.ndarray, k: int) -> np.ndarray:
        """``(n,)``: decision states where ``allow when`` leaves no action (a run stops there)."""
        if not self.guard.restricts or states.shape[0] == 0:
            return np.zeros(states.shape[0], dtype=bool)
        return np.asarray(~self.guard.masks(states, k).any(axis=1), dtype=bool)

    # ------------------------------------------------------------ the search
    def decide(self, state: np.ndarray, crashed: bool = False,
               progress: Callable[[int], None] | None = None) -> LookaheadMask:
        """The mask at ``state``: ``(8,)`` ``k, x, y, v, acc, head, jerk, turn`` (the shield's state row,
        :meth:`rac.learning.episodes.EpisodeBatch.state_keys`), ``k`` a decision sample before the
        horizon. ``crashed``: under ``collision sticky``, a collision happened on the way here
        (then nothing that follows is safe). ``progress(nodes)``: called with the search nodes spent so far
        as they are spent (a long search's bar)."""
        started = time.perf_counter()
        self._progress = progress
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
        self._clock = False
        self._memory = False
        depths = np.zeros(self.n_actions, dtype=np.int64)
        complete = True
        if not (self.sticky and crashed):
            actions = np.arange(self.n_actions)
            ends, safe, _ = self.periods(np.repeat(ego, self.n_actions, axis=0), k, actions)
            self._nodes = 1
            depths[safe] = 1
            end = self.period_end(k)
            try:
                if target > 1:
                    self._deepen(ends, safe, actions, end, target - 1, depths)
            except _OutOfBudget:
                complete = False
        best = int(depths.max())
        mask = depths == best if best > 0 else np.zeros(self.n_actions, dtype=bool)
        return LookaheadMask(mask=mask, depths=depths, depth=best, target=target, until=self.sample_after(k, best),
                             complete=complete, nodes=self._nodes, seconds=time.perf_counter() - started,
                             clock=self._clock and not complete,  # a complete search is exact, whatever the clock
                             memory=self._memory and not complete)

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

    def _spend(self, nodes: int = 1, needed_bytes: int = 0) -> None:
        """Count ``nodes`` expanded states; :class:`_OutOfBudget` when that would exceed the node budget,
        the search would then hold more than ``max_bytes`` (``needed_bytes``: its estimate), or the time is up."""
        settings = self.settings
        if settings.nodes is not None and self._nodes + nodes > settings.nodes:
            raise _OutOfBudget
        if settings.max_bytes is not None and needed_bytes > settings.max_bytes:
            self._memory = True
            raise _OutOfBudget
        if self._deadline is not None and time.perf_counter() >= self._deadline:
            self._clock = True
            raise _OutOfBudget
        self._nodes += nodes
        if self._progress is not None:
            self._progress(self._nodes)

    def _deepen(self, ends: np.ndarray, safe: np.ndarray, actions: np.ndarray, k: int, remaining: int,
                depths: np.ndarray) -> None:
        """Raise ``depths[a]`` (1 where the root's child ``a`` is ``safe``) to ``1 +`` the deepest safe
        continuation of ``remaining`` decisions from its state ``ends[a]`` at sample ``k``.

        Layer by layer over all open actions at once: a layer holds the states (each tagged with the
        root action it continues) that have survived so many decisions. Before a layer is expanded,
        the fixed continuations (:meth:`_fixed`) are tried from all of its states; an action one of
        them carries to the end is done, and its states leave the layer. The rest are expanded —
        every action, one decision period, in one call per chunk — and the safe successors (merged
        where equal) are the next layer. An action whose states all die out has the depth of its
        last layer: the search below it was exhaustive."""
        owners = np.flatnonzero(safe)
        layer = ends[owners]
        survived = 1  # decisions behind the states of `layer`
        sample = k
        while owners.size:
            left = remaining - (survived - 1)  # decisions still to survive from `layer`
            # complete already: at the horizon, or where `allow when` leaves no action (the run stops)
            done = (self._stopped(layer, sample) if sample < self.horizon else np.ones(owners.size, dtype=bool))
            if left == 0:
                done[:] = True
            finished = np.unique(owners[done])
            depths[finished] = 1 + remaining
            keep = ~np.isin(owners, finished)
            owners, layer = owners[keep], layer[keep]
            if owners.size == 0:
                return
            reached = np.zeros(owners.size, dtype=np.int64)
            chunk = max(1, CHUNK_ROWS // (1 + len(self._fallbacks)))
            for start in range(0, owners.size, chunk):  # the budget checked before each chunk
                self._spend(needed_bytes=owners.size * LAYER_BYTES)
                part = slice(start, start + chunk)
                reached[part] = self._fixed(layer[part], sample, self._action_of(layer[part]), left)
                np.maximum.at(depths, owners[part], survived + reached[part])
            carried = np.unique(owners[reached >= left])
            keep = ~np.isin(owners, carried)
            owners, layer = owners[keep], layer[keep]
            if owners.size == 0:
                return
            owners, layer = self._expand(owners, layer, sample)
            survived += 1
            np.maximum.at(depths, owners, survived)
            sample = self.period_end(sample)

    def _action_of(self, states: np.ndarray) -> np.ndarray:
        """``(n,)``: the action index of each state's own jerk and turn (the action that led to it;
        jerk-major over the grids, as :func:`rac.engine.allow.action_pairs`)."""
        jerks, turns = np.unique(self.pairs[:, 0]), np.unique(self.pairs[:, 1])
        j = np.clip(np.searchsorted(jerks, states[:, Ego.JERK]), 0, jerks.size - 1)
        t = np.clip(np.searchsorted(turns, states[:, Ego.TURN]), 0, turns.size - 1)
        return (j * turns.size + t).astype(np.int64)

    def _expand(self, owners: np.ndarray, layer: np.ndarray, sample: int) -> tuple[np.ndarray, np.ndarray]:
        """The next layer: every safe successor, one decision period from sample ``sample`` under each
        action, of every state of ``layer``, tagged with its state's owner; equal (owner, state) rows
        merged. Computed in chunks, the budget (nodes, memory, time) checked before each: the memory as the
        layer held and the successors so far and of the chunk (:data:`LAYER_BYTES`, :data:`SUCCESSOR_BYTES`),
        so a search stops before it allocates past ``max_bytes``."""
        per = self.n_actions
        chunk = max(1, CHUNK_ROWS // per)
        held = owners.size * LAYER_BYTES
        parts: list[np.ndarray] = []
        found = 0
        for start in range(0, owners.size, chunk):
            rows = layer[start:start + chunk]
            self._spend(rows.shape[0], held + (found + rows.shape[0] * per) * SUCCESSOR_BYTES)
            actions = np.tile(np.arange(per), rows.shape[0])
            ends, safe, _ = self.periods(np.repeat(rows, per, axis=0), sample, actions)
            # owner and state in one int32 row (owners are action indices): half the bytes of int64 rows
            part = np.empty((int(safe.sum()), 8), dtype=np.int32)
            part[:, 0] = np.repeat(owners[start:start + chunk], per)[safe]
            part[:, 1:] = ends[safe]
            parts.append(part)
            found += part.shape[0]
        merged = _distinct_rows(parts)
        return merged[:, 0].astype(np.int64), np.ascontiguousarray(merged[:, 1:])

    def _fixed(self, states: np.ndarray, k: int, held: np.ndarray, remaining: int) -> np.ndarray:
        """``(n,)``: per row, the most decisions (up to ``remaining``) one of the fixed continuations —
        the row's own action held, or one of :meth:`_fallback_actions` held — survives from ``states``
        at sample ``k``. Every number returned is proved (a continuation of that many decisions is safe).
        ``held`` only picks which continuations are tried: any choice is sound."""
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
            if self._deadline is not None and time.perf_counter() >= self._deadline:
                self._clock = True  # the answer is cut by the clock, whichever budget then stops the search
                break  # what is proved so far stands; the search's next _spend stops it (a long horizon held)
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


def _distinct_rows(parts: list[np.ndarray]) -> np.ndarray:
    """The distinct rows of the ``(n, 8)`` int32 arrays ``parts`` (emptied), sorted as ``np.unique(rows,
    axis=0)`` sorts them: concatenated once and sorted in place, where ``np.unique`` held two more copies
    (a layer of millions of rows cost about 1 GB at the start search's budget)."""
    rows = np.concatenate(parts) if parts else np.empty((0, 8), dtype=np.int32)
    parts.clear()
    if rows.shape[0] < 2:
        return rows
    keys = rows.view(_ROW_FIELDS).reshape(-1)  # the rows themselves, sorted in place
    keys.sort()
    distinct = np.empty(keys.size, dtype=bool)
    distinct[0] = True
    distinct[1:] = keys[1:] != keys[:-1]
    return rows[distinct]
