"""The Q-table of :func:`rac.learning.qlearning.learn` and one batch of its episodes.

:class:`QTable` maps observation keys to rows of Q-values (in the maximised sense). :class:`Learner`
steps one batch of ``parallel`` learning episodes (epsilon-greedy choices, Watkins' updates after
each step, the backward replay at the end, then the best episode seen replayed) and, next to them
in the same batch, the greedy episode that evaluates the table as it was before the batch (issue
11): that episode chooses from a :class:`Frozen` copy of the table, is not learned from and draws
no random numbers, so it is the run a separate greedy episode would have had — every episode of a
batch is stepped row by row — while the batch's cost per sample is shared. Its run is recorded as
:func:`rac.learning.strategy.rollout` records one (:class:`rac.learning.runs.RunRecorder`). A batch
is a generator of steps (:mod:`rac.learning.runs`): it requests its episodes and each step, so that
it can share a batch with others (:mod:`rac.learning.lockstep`).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from functools import cached_property
from itertools import repeat
from typing import NamedTuple

import numpy as np

from rac.core.diagnostics import RacValueError
from rac.engine.shield import ShieldTable
from rac.ir import expr as ie
from rac.learning.runs import Ahead, Reset, RunRecorder, Steps, StrategyRun, rollout_steps
from rac.learning.strategy import (
    Episodes,
    StepOutcome,
    allowed_actions,
    greedy_actions,
    key_bytes,
    observation_keys,
    uniform_allowed,
)

__all__ = ["STEERED", "UNTRIED", "BatchLog", "Frozen", "Learner", "Prepared", "QTable", "Transition", "apply",
           "check_finite", "prepare", "update"]

#: The pessimistic initial value (:func:`rac.learning.qlearning.learning`'s ``pessimistic``): below
#: any return a run can have (learning refuses episodes whose return comes within a factor 10 of it),
#: so an untried action is never preferred to a tried one, and a tried action whose future is not
#: known yet (its next state has nothing tried: ``reward + UNTRIED``) ranks below every known one.
UNTRIED = -1e9
#: The share of the exploring choices that :attr:`Learner.steer` steers (the others stay uniform): half, so
#: that every allowed action stays likely to be tried (heading for the goal alone reached it less often
#: on examples/paper: the way there first waits for the crossing traffic).
STEERED = 0.5


@dataclass(frozen=True, eq=False)
class Frozen:
    """The first ``size`` rows of a :class:`QTable`'s values as they were (a copy)."""

    size: int
    values: np.ndarray


class QTable:
    """The growing table of learning: observation key -> row of Q-values, in the *maximised* sense
    (``sign * value``: for ``minE`` the negated costs). ``initial`` is the value of an entry not yet
    learned: 0, an optimistic value above any return, or :data:`UNTRIED` (pessimistic)."""

    def __init__(self, width: int, n_actions: int, initial: float = 0.0) -> None:
        #: The value of every entry not yet learned (optimistic initial values when above any return,
        #: pessimistic ones at UNTRIED).
        self.initial = initial
        self.index: dict[bytes, int] = {}
        self.keys = np.zeros((64, width), dtype=np.float64)
        self.values = np.zeros((64, n_actions), dtype=np.float64)
        self.size = 0

    def rows(self, keys: np.ndarray, *, create: bool) -> np.ndarray:
        """Each key's row; a new key gets a row of zeros (``create``) or -1."""
        raws = key_bytes(keys)
        index = self.index
        if not create:
            return np.array(list(map(index.get, raws, repeat(-1, len(raws)))), dtype=np.int64)
        out = list(map(index.get, raws))  # map: no Python frame per key
        if None in out:  # new keys get rows in the order they come (a key twice: one row)
            for i, row in enumerate(out):
                if row is None:
                    raw = raws[i]
                    found = index.get(raw)
                    out[i] = found if found is not None else self._add(keys[i], raw)
        return np.array(out, dtype=np.int64)

    def _add(self, key: np.ndarray, raw: bytes) -> int:
        if self.size == self.keys.shape[0]:  # amortised doubling
            self.keys = np.concatenate([self.keys, np.zeros_like(self.keys)])
            self.values = np.concatenate([self.values, np.zeros_like(self.values)])
        self.keys[self.size] = key
        self.values[self.size] = self.initial
        self.index[raw] = self.size
        self.size += 1
        return self.size - 1

    def utilities(self, rows: np.ndarray) -> np.ndarray:
        """``(n, P)``: the rows' values, :attr:`initial` for unseen rows (-1)."""
        out = self.values[np.maximum(rows, 0)]
        out[rows < 0] = self.initial
        return out

    def freeze(self) -> Frozen:
        """The table's values now, to choose from later (:meth:`frozen_utilities`)."""
        return Frozen(self.size, self.values[:self.size].copy())

    def frozen_utilities(self, frozen: Frozen, keys: np.ndarray) -> np.ndarray:
        """:meth:`utilities` of ``keys`` in the table as it was when ``frozen``: a key added since is unseen."""
        out = np.empty((keys.shape[0], self.values.shape[1]))
        # one key per step (the greedy episode): row by row costs less than numpy's masks
        for i, row in enumerate(map(self.index.get, key_bytes(keys))):
            out[i] = frozen.values[row] if row is not None and row < frozen.size else self.initial
        return out


class Transition(NamedTuple):
    """One step of a batch: the ``active`` episodes' indices, then per episode (``(n,)`` or
    ``(n, P)``) the table row before, the action, the reward in the maximised sense, the row and
    allowed actions after, and whether the episode ``ends``."""

    active: np.ndarray
    rows: np.ndarray
    actions: np.ndarray
    reward: np.ndarray
    next_rows: np.ndarray
    next_masks: np.ndarray
    ends: np.ndarray


def check_finite(rewards: np.ndarray) -> None:
    """RacValueError when a step's reward is not a finite number (the reward divides by zero or overflows
    on the episodes' samples): the user's reward, said in the user's words, not a table or a backward
    pass computed on NaN."""
    bad = rewards[~np.isfinite(rewards)]
    if bad.size:
        raise RacValueError(f"a step's reward is {bad[0]:g}, not a finite number: the reward divides by "
                            "zero or overflows on the episodes' samples")


def update(values: np.ndarray, step: Transition, alpha: float, gamma: float, untried: float | None = None) -> None:
    """Watkins' update of every active episode's transition, in episode order (a later row sees an
    earlier one's update). An ending episode does not bootstrap; the maximum runs over the actions
    allowed in the next state. With ``untried`` (:data:`UNTRIED`, pessimistic initial values), an
    entry still at that value takes its target as it is: its first update sets it.

    Batched, with the same results to the last bit: when no continuing episode's next row is a row
    this step updates (with the decision time observed, never), every target can be computed first
    (the maxima over the next rows at once); the entries are then updated in episode order, an entry
    that comes again seeing its earlier updates. A step updated again (the backward replay) is
    worked out once (:func:`prepare`) and applied each time (:func:`apply`)."""
    if step.active.size == 1:  # one episode (the best episode's replay, a batch of one): no array work
        _update_in_order(values, step, alpha, gamma, untried)
        return
    apply(values, prepare(step, values.shape[1]), alpha, gamma, untried)


class Prepared(NamedTuple):
    """What :func:`update` of one :class:`Transition` works out before reading the table, for a
    table of ``n_actions`` columns: the ``step``; whether it is updated one episode at a time
    (``in_order``: one episode, or a continuing episode's next row is a row the step updates); per
    active episode, in episode order, its ``reward``, its place among the continuing episodes
    (``nexts``; -1: it ends) and its entry by its place in ``unique`` (``slots``); the continuing
    episodes' ``next_rows`` and ``allowed`` actions there; the distinct entries the step updates
    (``unique``: flat indices ``row * n_actions + action``, in the order they come)."""

    step: Transition
    n_actions: int
    in_order: bool
    reward: list[float]
    nexts: list[int]
    slots: Sequence[int]
    next_rows: np.ndarray
    allowed: np.ndarray
    unique: np.ndarray


def prepare(step: Transition, n_actions: int) -> Prepared:
    """``step``'s update for a table of ``n_actions`` columns, worked out once (:class:`Prepared`)."""
    active = step.active
    if active.size <= 1:  # no array work for one episode (nothing at all for none)
        nothing = np.zeros(0, dtype=np.int64)
        return Prepared(step, n_actions, active.size == 1, [], [], [], nothing, np.zeros((0, n_actions), dtype=bool),
                        nothing)
    rows = step.rows[active]
    ends = step.ends[active].tolist()
    continuing = active
    nexts: list[int] = list(range(len(ends)))
    if True in ends:
        continuing = active[~step.ends[active]]
        going = 0
        for i, end in enumerate(ends):
            nexts[i] = -1 if end else going
            going += not end
    next_rows = step.next_rows[continuing]
    # a few dozen rows: sets decide it faster than np.isin's sorting
    in_order = bool(next_rows.size) and not set(rows.tolist()).isdisjoint(next_rows.tolist())
    unique = rows * n_actions + step.actions[active]
    entries = unique.tolist()
    slots: Sequence[int] = range(len(entries))
    if len(set(entries)) < len(entries):  # an entry more than once: each occurrence is an update of one slot
        place: dict[int, int] = {}
        slots = [place.setdefault(entry, len(place)) for entry in entries]
        unique = np.array(list(place), dtype=unique.dtype)
    return Prepared(step, n_actions, in_order, np.asarray(step.reward[active], dtype=np.float64).tolist(), nexts,
                    slots, next_rows, np.asarray(step.next_masks[continuing], dtype=bool), unique)


def apply(values: np.ndarray, prepared: Prepared, alpha: float, gamma: float, untried: float | None = None) -> None:
    """:func:`update` of ``prepared``'s step on ``values`` (a table of its ``n_actions`` columns).

    The few dozen targets and entries of a step are computed on Python floats (IEEE doubles, each
    operation rounded as numpy rounds it), which costs less than numpy's calls on arrays this small;
    only the maxima over the next rows are numpy's, and the entries are read and written once."""
    if prepared.in_order or not values.flags.c_contiguous or values.shape[1] != prepared.n_actions:
        _update_in_order(values, prepared.step, alpha, gamma, untried)
        return
    if not prepared.reward:
        return
    # the step's next rows are none it updates (not in_order): their maxima first
    best = np.maximum.reduce(np.where(prepared.allowed, values[prepared.next_rows], -np.inf), axis=1).tolist() \
        if prepared.next_rows.size else []
    entries = values.reshape(-1)  # a view: the table is C-contiguous
    unique = prepared.unique
    current = entries[unique].tolist()
    # in episode order: an entry that comes again sees its earlier updates
    for slot, reward, going in zip(prepared.slots, prepared.reward, prepared.nexts):
        target = reward if going < 0 else reward + gamma * best[going]
        old = current[slot]
        current[slot] = target if old == untried else old + alpha * (target - old)
    entries[unique] = current


def _update_in_order(values: np.ndarray, step: Transition, alpha: float, gamma: float,
                     untried: float | None) -> None:
    """:func:`update` one transition at a time (a next row is a row this step updates)."""
    rows, actions = step.rows, step.actions
    for i in step.active:
        target = step.reward[i]
        if not step.ends[i]:
            target += gamma * np.maximum.reduce(np.where(step.next_masks[i], values[step.next_rows[i]], -np.inf))
        old = values[rows[i], actions[i]]
        values[rows[i], actions[i]] = target if old == untried else old + alpha * (target - old)


@dataclass(frozen=True, eq=False)
class BatchLog:
    """Per learning episode of a batch: the undiscounted ``returns``, whether it ``reached`` the goal,
    ``collided``, went ``offroad`` (at any sample), was ``stranded`` at the goal (no safe run to the
    horizon from there, where judged), and its ``fallbacks`` (empty shield masks)."""

    returns: np.ndarray
    reached: np.ndarray
    collided: np.ndarray
    offroad: np.ndarray
    stranded: np.ndarray
    fallbacks: np.ndarray


@dataclass
class Learner:
    """Batches of Q-learning on one :class:`QTable` (see the module docstring). ``exprs`` are the
    checked observations (the first ``n_discrete`` as they are, the others binned by ``widths``),
    ``sign`` 1 to maximise the rewards and -1 to minimise them."""

    table: QTable
    exprs: Sequence[ie.Expr]
    n_discrete: int
    widths: tuple[float, ...]
    shield: ShieldTable | None
    rng: np.random.Generator
    sign: float
    alpha: float
    gamma: float
    replay: int
    #: The observation's column holding the automaton's location, for counterfactual experiences
    #: (:mod:`rac.learning.counterfactual`): every transition also updates the observation in every
    #: other location. None: off.
    location_column: int | None = None
    #: Learning episodes break greedy ties at random (among the allowed actions of equal value), so a
    #: state where no allowed action was tried continues with a uniformly random one; False: the
    #: lowest index, as the greedy strategy (deterministic either way).
    random_ties: bool = False
    #: After every batch, the best learning episode seen so far (a safe goal first, then the
    #: return) is replayed backwards too, so the greedy strategy keeps following it where later
    #: episodes through the same (binned) observation keys overwrote its values.
    replay_best: bool = False
    #: Exploration steered by the model (``rac experiment --explore goal``): half the exploring choices
    #: (by a draw of their own) take the allowed action whose value of this expression one decision
    #: later is least — ``dist_goal()``, the goal's distance — read by looking ahead in the model
    #: (:meth:`rac.learning.episodes.EpisodeBatch.ahead`), ties at random; the other half stay uniform
    #: among the allowed actions. None: every exploring choice is uniform.
    steer: ie.Expr | None = None
    #: The best learning episode seen: its (safe goal, return in the maximised sense) and transitions.
    best: tuple[tuple[bool, float], list[Transition]] | None = field(default=None, repr=False)

    @property
    def untried(self) -> float | None:
        """:data:`UNTRIED` when the table's initial values are the pessimistic ones, else None."""
        return UNTRIED if self.table.initial == UNTRIED else None

    def observe(self, batch: Episodes) -> np.ndarray:
        """Every episode's observed values now."""
        return batch.observe(self.exprs) if self.exprs else np.zeros((batch.n, 0))

    def keys(self, observed: np.ndarray) -> np.ndarray:
        return observation_keys(observed, self.n_discrete, self.bin_widths)

    @cached_property
    def bin_widths(self) -> np.ndarray:
        """:attr:`widths` as an array (converted once, not at every observation)."""
        return np.asarray(self.widths, dtype=np.float64)

    def counterfactual(self, batch: Episodes, step: Transition, keys: np.ndarray, next_keys: np.ndarray) -> Transition:
        """The counterfactual transitions of ``step`` (the batch's last step, whose learning episodes
        had the observation ``keys`` before it and ``next_keys`` after): the same step of the model
        from every *other* location of the automaton, its reward and next location from the
        automaton (``batch.counterfactual()``, :meth:`rac.learning.episodes.EpisodeBatch.counterfactual`)."""
        column = self.location_column
        assert column is not None
        replay = getattr(batch, "counterfactual", None)
        if replay is None:
            raise RacValueError("these episodes cannot replay a step from other locations (no counterfactual())")
        cf = replay()
        sources = step.active
        actual = keys[sources, column].astype(np.int64)
        which, location = np.nonzero(np.arange(cf.n_locations)[None, :] != actual[:, None])
        source = sources[which]
        before = keys[source]  # a copy (indexed by an array)
        before[:, column] = location
        after = next_keys[source]
        after[:, column] = cf.next_location[source, location]
        return Transition(np.arange(source.size), self.table.rows(before, create=True), step.actions[source],
                          self.sign * cf.reward[source, location], self.table.rows(after, create=True),
                          step.next_masks[source], step.ends[source])

    def exploit(self, utilities: np.ndarray, masks: np.ndarray) -> np.ndarray:
        """The learning episodes' greedy choices: the best allowed action per row, ties to the lowest
        index or (:attr:`random_ties`) uniformly among the tied ones."""
        if not self.random_ties:
            return greedy_actions(utilities, masks)
        return self._at_best(np.where(masks, utilities, -np.inf), masks)

    def toward(self, values: np.ndarray, masks: np.ndarray) -> np.ndarray:
        """Per row (``masks``: its allowed actions; ``values``: :attr:`steer` one decision later under each
        action, :class:`rac.learning.runs.Ahead`'s answer), the allowed action whose value is least, ties at
        random (uniformly among the allowed ones where none is a number: a done episode)."""
        return self._at_best(np.where(masks & ~np.isnan(values), -values, -np.inf), masks)

    def _at_best(self, scores: np.ndarray, masks: np.ndarray) -> np.ndarray:
        """Per row, an allowed action of the highest ``scores`` (``-inf`` where not allowed), uniformly at
        random among those tied (among all allowed ones where every score is ``-inf``)."""
        return uniform_allowed(self.rng, masks & (scores == np.maximum.reduce(scores, axis=1, keepdims=True)))

    def _replay_best(self, own: Sequence[Transition], returns: np.ndarray, good: np.ndarray) -> None:
        """Keep the best of the batch's episodes if it beats the best seen, then replay that one backwards."""
        for i in range(returns.size):
            score = (bool(good[i]), float(returns[i]))
            if self.best is None or score > self.best[0]:
                path = [Transition(np.array([0]), step.rows[i:i + 1], step.actions[i:i + 1], step.reward[i:i + 1],
                                   step.next_rows[i:i + 1], step.next_masks[i:i + 1], step.ends[i:i + 1])
                        for step in own if i in step.active]
                self.best = (score, path)
        if self.best is not None:
            for step in reversed(self.best[1]):
                update(self.table.values, step, self.alpha, self.gamma, self.untried)

    def greedy_run(self) -> Steps[StrategyRun]:
        """The greedy strategy of the table now, by its one run alone (a batch of one episode)."""
        table = self.table

        def choose(observed: np.ndarray, masks: np.ndarray) -> np.ndarray:
            return greedy_actions(table.utilities(table.rows(self.keys(observed), create=False)), masks)

        return rollout_steps(self.exprs, 1, self.shield, choose)

    def run(self, n: int, eps: np.ndarray, frozen: Frozen | None) -> Steps[tuple[BatchLog, StrategyRun | None]]:
        """One batch of ``n`` learning episodes (exploring with the probabilities ``eps``), then the
        backward replay; with ``frozen``, also the greedy episode of that table, in the batch's last
        row, and its run. A generator of steps (:mod:`rac.learning.runs`)."""
        table, rng, shield = self.table, self.rng, self.shield
        alpha, gamma, untried, sign = self.alpha, self.gamma, self.untried, self.sign
        n_actions = table.values.shape[1]
        width = n + (frozen is not None)
        batch: Episodes = yield Reset(width)
        recorder = RunRecorder(batch, slice(n, width), 1, len(self.exprs)) if frozen is not None else None
        observed = self.observe(batch)
        observed_keys = self.keys(observed)  # every row's key at once: the learning episodes' and the greedy one's
        keys = observed_keys[:n]
        rows = table.rows(keys, create=True)
        # the state keys, read once per state: the shield's masks and the greedy episode's record both need them
        states = batch.state_keys() if shield is not None else None
        masks, empty = allowed_actions(batch, shield, states)
        fallbacks = empty[:n].astype(np.int64)
        returns = np.zeros(n)
        reached, collided, offroad, stranded = (np.zeros(n, dtype=bool) for _ in range(4))
        steps: list[Prepared] = []  # this batch's transitions, for the backward replay
        own: list[Transition] = []  # the learning episodes' own (not the counterfactual ones)
        recording = recorder is not None
        for _ in range(batch.max_steps):
            active = ~np.asarray(batch.done, dtype=bool)
            if recorder is not None and recording:
                recorder.before(observed, states)
                recording = bool(active[n])
            if not active.any():
                break
            learning = active[:n]
            anyone = bool(learning.any())
            actions = np.zeros(width, dtype=np.int64)
            if anyone:  # the random numbers are the learning episodes' only
                explore = rng.random(n) < eps
                random_actions = uniform_allowed(rng, masks[:n])
                if self.steer is not None:  # a share of the exploring choices, steered by a lookahead
                    steered = np.flatnonzero((rng.random(n) < STEERED) & explore & learning)
                    if steered.size:
                        values = yield Ahead((self.steer,), steered, masks[steered])  # the allowed actions only
                        random_actions[steered] = self.toward(values[:, :, 0], masks[steered])
                # every learning row has a row of the table (created when observed): its values as they are
                chosen = np.where(explore, random_actions, self.exploit(table.values[rows], masks[:n]))
                actions[:n] = np.where(learning, chosen, 0)
            greedy_row = frozen is not None and bool(active[n])
            if greedy_row:
                assert frozen is not None
                greedy = table.frozen_utilities(frozen, observed_keys[n:])
                actions[n] = greedy_actions(greedy, masks[n:])[0]
            outcome: StepOutcome = yield actions
            if recorder is not None and greedy_row:
                recorder.after(active, empty, actions, outcome)
            observed = self.observe(batch)
            observed_keys = self.keys(observed)
            states = batch.state_keys() if shield is not None else None
            next_masks, next_empty = allowed_actions(batch, shield, states)
            if anyone:
                reward = np.asarray(outcome.reward, dtype=np.float64)[:n]
                check_finite(reward[learning])  # a NaN would poison the table silently
                terminated = np.asarray(outcome.terminated, dtype=bool)[:n]
                ends = terminated | np.asarray(outcome.truncated, dtype=bool)[:n] | np.asarray(outcome.ended,
                                                                                              dtype=bool)[:n]
                next_keys = observed_keys[:n]
                next_rows = table.rows(next_keys, create=True)
                step = Transition(learning.nonzero()[0], rows, actions[:n], sign * reward, next_rows,
                                  next_masks[:n], ends)
                prepared = prepare(step, n_actions)
                apply(table.values, prepared, alpha, gamma, untried)
                steps.append(prepared)
                own.append(step)
                if self.location_column is not None:
                    prepared = prepare(self.counterfactual(batch, step, keys, next_keys), n_actions)
                    apply(table.values, prepared, alpha, gamma, untried)
                    steps.append(prepared)
                keys = next_keys
                returns[learning] += reward[learning]
                reached |= terminated & learning
                collided |= np.asarray(outcome.collided, dtype=bool)[:n] & learning
                offroad |= np.asarray(outcome.offroad, dtype=bool)[:n] & learning
                stranded |= np.asarray(outcome.stranded, dtype=bool)[:n] & learning
                fallbacks += next_empty[:n] & learning & ~ends  # only a continuing episode decides there
                rows = next_rows
            masks, empty = next_masks, next_empty
        else:
            if recorder is not None and recording:
                recorder.before(observed, states)  # the state after the last decision
        # Backward replay: the batch's transitions again, last step first, so a reward at the end
        # of an episode reaches its first decision in one sweep instead of one step per visit.
        for _ in range(self.replay):
            for prepared in reversed(steps):
                apply(table.values, prepared, alpha, gamma, untried)
        if self.replay_best:
            self._replay_best(own, sign * returns, reached & ~collided & ~offroad & ~stranded)
        if untried is not None and (sign * returns <= UNTRIED / 10).any():
            raise RacValueError(f"a return of {returns.min():g} is too large for the pessimistic initial value "
                                f"{UNTRIED:g}")
        log = BatchLog(returns, reached, collided, offroad, stranded, fallbacks)
        return log, recorder.finish() if recorder is not None else None
