"""Counterfactual experiences: one transition, replayed from every location of the reward automaton (issue 23).

A reward automaton's inputs are read from the environment (the model's bindings), never from the
automaton: the inputs a transition produced would have been the same in whichever location the
automaton was. Since rac knows the automaton, it knows what the automaton would have done from every
other location — the next location and the reward — so one transition of the environment yields one
experience per location. This is Toro Icarte et al.'s *counterfactual reasoning* for reward machines
(CRM; "Reward Machines: Exploiting Reward Function Structure in Reinforcement Learning", JAIR 2022),
which PyCRM implements for Python environments.

- :class:`Replayer` replays a transition's samples (each sample's inputs, which episodes take it,
  which end at it) from every location, on one :class:`rac.runtime.batch.BatchRewardAutomaton` of
  ``B * L`` copies, each starting with the episode's own reward values: the reward (the objective's
  increase, ``at end`` bonus included) and the next location per transition and location.
  :meth:`rac.learning.episodes.EpisodeBatch.counterfactual` uses it for the step just taken (a step is
  a decision period of several samples); tabular Q-learning (:mod:`rac.learning.tabular`) then
  updates the Q-value of the transition's observation in every location. With a memo (the episodes'
  ``memo``), a transition replayed before is recalled by all its replay reads, bit for bit the same.
- :func:`counterfactual_transitions` is the same for a deep learner's replay buffer, where one
  environment step is one sample (:class:`rac.learning.wrappers.RewardAutomatonWrapper`): for a
  batch of ``B`` transitions, ``B * L`` counterfactual ones — which transition each comes from, its
  location before and after, and its reward — to be stored next to (or instead of) the real ones,
  the observation's location part replaced.

Exact when the observation sees the automaton only through its location and the episode's end does
not depend on the automaton (the default goal, ``goal()``, reads the model only): then the
counterfactual transitions are transitions the environment could really have produced.

Example (a deep learner's replay buffer; ``inputs`` the automaton's inputs of each transition, ``held``
those of the step before it, which input-dependent rates read: required for such an automaton)::

    cf = counterfactual_transitions(automaton, inputs, rewards=rewards_before, ended=terminated | truncated,
                                    held=held)
    obs_cf = np.concatenate([obs[cf.source], one_hot(cf.location)], axis=1)
    next_cf = np.concatenate([next_obs[cf.source], one_hot(cf.next_location)], axis=1)
    buffer.add(obs_cf, actions[cf.source], cf.reward, next_cf, ended[cf.source])
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from rac import ir
from rac.engine.budget import REPLAY_MEMOS
from rac.runtime.batch import BatchRewardAutomaton
from rac.runtime.semantics import input_specs

__all__ = ["CounterfactualBatch", "Counterfactuals", "Replayer", "Sample", "counterfactual_transitions"]


@dataclass(frozen=True)
class Sample:
    """One sample of a transition for ``B`` episodes: the automaton's ``inputs`` (name -> ``(B,)``),
    which episodes are ``active`` (take the sample) and which are ``ending`` at it (the ``at end``
    clauses apply after it, with the same inputs)."""

    inputs: Mapping[str, np.ndarray]
    active: np.ndarray
    ending: np.ndarray


@dataclass(frozen=True, eq=False)
class Counterfactuals:
    """Per transition ``b`` and location ``l`` (``(B, L)`` arrays): the ``reward`` (the objective's
    increase, the ``at end`` bonus included) had the automaton been in location ``l`` when the
    transition began, the ``next_location``, and the reward values after it (``rewards``, name ->
    ``(B, L)``)."""

    reward: np.ndarray
    next_location: np.ndarray
    rewards: Mapping[str, np.ndarray]

    @property
    def n_locations(self) -> int:
        return int(self.reward.shape[1])


class Replayer:
    """Replays transitions of ``automaton`` from every location (see the module docstring); keeps
    one batch of automata per size, so that replaying costs one automaton step per sample.

    With ``memo``, a transition's replay is kept by everything it reads (:class:`_Replays`): a
    transition replayed again (the episodes of a deterministic model repeat most of their steps) is
    recalled, the same values to the last bit. :attr:`rows_computed` and :attr:`rows_recalled`
    count the transitions replayed and recalled."""

    def __init__(self, automaton: ir.Automaton, *, memo: bool = False) -> None:
        self.automaton = automaton
        self.n_locations = len(automaton.locations)
        self._batches: dict[int, BatchRewardAutomaton] = {}
        specs = input_specs(automaton)
        self._inputs = {spec.name for spec in specs}
        self._bools = [spec.name for spec in specs if spec.is_bool]
        self._numbers = [spec.name for spec in specs if not spec.is_bool]
        #: the inputs the rates read, held from the sample before a transition
        self._held = sorted({name for location in automaton.locations for rate in location.rates
                             for name in rate.variables()})
        self._memo = _Replays(self.n_locations * (2 + len(automaton.rewards))) if memo else None
        self.rows_computed = 0
        self.rows_recalled = 0

    def replay(self, samples: Sequence[Sample], n: int, rewards: Mapping[str, np.ndarray] | None = None,
               held: Mapping[str, np.ndarray] | None = None) -> Counterfactuals:
        """The :class:`Counterfactuals` of ``n`` transitions made of ``samples`` (in order), each
        starting with the reward values ``rewards`` (name -> ``(n,)``; default 0) in every location
        and the inputs ``held`` from the sample before (name -> ``(n,)``, which input-dependent rates
        read at the first sample; default none, as at a run's first sample)."""
        memo = self._memo
        keys = None if memo is None else self._keys(samples, n, rewards, held)
        if memo is None or keys is None:
            self.rows_computed += n
            return self._compute(samples, n, rewards, held)
        slots = memo.find(keys)
        found = slots >= 0
        table = np.empty((n, memo.width))
        table[found] = memo.store[slots[found]]
        missing = np.flatnonzero(~found)
        self.rows_recalled += n - missing.size
        if missing.size:  # each distinct transition replayed once
            first: dict[bytes, int] = {}  # key -> its first row
            inverse = np.fromiter((first.setdefault(keys[row], row) for row in missing.tolist()), dtype=np.int64,
                                  count=missing.size)
            rows = np.fromiter(first.values(), dtype=np.int64, count=len(first))  # ascending, as missing
            self.rows_computed += rows.size
            # padded to a power of two with rows that take no sample (they change nothing), so that a few
            # batch sizes serve every count of rows missing
            size = max(16, 1 << (rows.size - 1).bit_length())
            take = np.concatenate([rows, np.repeat(rows[:1], size - rows.size)])
            padded = [Sample({name: column[take] for name, column in sample.inputs.items()},
                             _padded(sample.active, take, rows.size), _padded(sample.ending, take, rows.size))
                      for sample in samples]
            cf = self._compute(padded, size,
                               None if rewards is None else {name: np.asarray(column, dtype=np.float64)[take]
                                                             for name, column in rewards.items()},
                               None if held is None else {name: np.asarray(held[name])[take] for name in self._held})
            computed = np.concatenate([cf.reward, cf.next_location.astype(np.float64),
                                       *(cf.rewards[name] for name in self.automaton.rewards)], axis=1)[:rows.size]
            table[missing] = computed[np.searchsorted(rows, inverse)]
            memo.add(list(first), computed)
        width = self.n_locations
        return Counterfactuals(table[:, :width].copy(), table[:, width:2 * width].astype(np.int64),
                               {name: table[:, (2 + i) * width:(3 + i) * width].copy()
                                for i, name in enumerate(self.automaton.rewards)})

    def _compute(self, samples: Sequence[Sample], n: int, rewards: Mapping[str, np.ndarray] | None,
                 held: Mapping[str, np.ndarray] | None) -> Counterfactuals:
        """:meth:`replay` on the batch of automata of that size."""
        size = n * self.n_locations
        batch = self._batches.get(size)
        if batch is None:
            batch = self._batches[size] = BatchRewardAutomaton(self.automaton, size)
        spread = {name: np.repeat(np.asarray(values, dtype=np.float64), self.n_locations)
                  for name, values in (rewards or {}).items()}
        kept = None if held is None else {name: np.repeat(np.asarray(values, dtype=np.float64), self.n_locations)
                                          for name, values in held.items() if np.asarray(values).dtype != bool}
        batch.resume(np.tile(np.arange(self.n_locations), n), spread, kept)
        total = batch.run_samples([(sample.inputs, sample.active, sample.ending) for sample in samples],
                                  repeat=self.n_locations)
        shape = (n, self.n_locations)
        return Counterfactuals(total.reshape(shape), batch.locations.astype(np.int64).reshape(shape),
                               {name: values.reshape(shape) for name, values in batch.rewards.items()})

    def _keys(self, samples: Sequence[Sample], n: int, rewards: Mapping[str, np.ndarray] | None,
              held: Mapping[str, np.ndarray] | None) -> list[bytes] | None:
        """Each transition's key in the memo: the bytes of everything its replay reads — the number of
        samples, the reward values before it, the held inputs the rates read, and per sample whether it
        takes it and ends at it and, where it does either, the inputs (a sample it neither takes nor ends
        at reads none). None (replayed, not kept) for what is not plainly that: other dtypes or shapes
        (replaying validates them), a reward of -0.0 or not finite (see :class:`_Replays`)."""
        rewards = rewards or {}
        if n < 1 or any(name not in self.automaton.rewards for name in rewards):
            return None
        floats: list[np.ndarray] = []
        for name in self.automaton.rewards:
            value = np.asarray(rewards[name], dtype=np.float64) if name in rewards else np.zeros(n)
            if value.shape != (n,) or not np.isfinite(value).all() or (np.signbit(value) & (value == 0)).any():
                return None
            floats.append(value)
        held_flag = 0
        if self._held and held is not None:
            held_flag = 1
            for name in self._held:
                if name not in held:
                    return None
                column = np.asarray(held[name])
                if column.dtype != np.float64 or column.shape != (n,):
                    return None
                floats.append(column)
        bools: list[np.ndarray] = []  # per sample: whether it is taken, ended at, and the boolean inputs
        numbers: list[np.ndarray] = []
        for sample in samples:
            if sample.inputs.keys() != self._inputs:
                return None
            bools += [sample.active, sample.ending, *(sample.inputs[name] for name in self._bools)]
            numbers += [sample.inputs[name] for name in self._numbers]
        if any(not isinstance(c, np.ndarray) or c.dtype != bool or c.shape != (n,) for c in bools) \
                or any(not isinstance(c, np.ndarray) or c.dtype != np.float64 or c.shape != (n,) for c in numbers):
            return None
        count = len(samples)
        flags = np.stack(bools).reshape(count, 2 + len(self._bools), n) if count else np.zeros((0, 2, n), bool)
        reads = flags[:, 0] | flags[:, 1]
        flags[:, 2:] &= reads[:, None]
        if numbers:
            floats += list(np.where(np.repeat(reads, len(self._numbers), axis=0),
                                    np.stack(numbers), 0.0))
        header = np.array([count, held_flag], dtype=np.int64).view(np.uint8)
        parts = [np.broadcast_to(header, (n, header.size))]
        if floats:
            parts.append(np.column_stack(floats).view(np.uint8))
        if count:
            parts.append(np.packbits(flags.reshape(-1, n).T, axis=1))
        raw = np.ascontiguousarray(np.concatenate(parts, axis=1)).tobytes()
        width = len(raw) // n
        return [raw[start:start + width] for start in range(0, len(raw), width)]


def _padded(flags: np.ndarray, take: np.ndarray, rows: int) -> np.ndarray:
    """``flags[take]`` with the rows from ``rows`` on false (padding: they take no sample)."""
    out = np.asarray(flags)[take]
    out[rows:] = False
    return out


class _Replays:
    """The replays a :class:`Replayer` computed, by their transition's key (:meth:`Replayer._keys`): per
    transition one row of ``width`` doubles — the reward, the next location and each reward's value
    after, each per location. A transition's replay reads its key alone, not its neighbours in the
    batch: the automata are stepped elementwise, and an automaton a sample leaves out (``active``
    false) is left as it is, but that its rewards gain a zero (the rate times false) when others take
    the sample. A zero added changes no value but -0.0, and no reward is -0.0: a replay kept starts from
    rewards that are not (:meth:`Replayer._keys`), and a reward after a sample is a sum whose first
    operand is not -0.0 (the reward before, or an update's constant: a rational), which in
    round-to-nearest is -0.0 only when both operands are. So a recalled replay is the replay, bit for
    bit (tests/learning/test_counterfactual.py compares them).

    All memos of the process keep at most :data:`rac.engine.budget.REPLAY_MEMO_BYTES` together, as
    :class:`rac.learning.episodes.EpisodeBatch`'s memo of steps shares its budget; a memo that would
    exceed it starts afresh (only the time changes), and hands its bytes back when it is collected."""

    #: The bytes of one key in the index beside its own (the bytes object and the dictionary's entry).
    INDEX_BYTES = 150

    def __init__(self, width: int) -> None:
        self.width = width
        self.index: dict[bytes, int] = {}
        self.store = np.zeros((0, width))
        #: this memo's bytes within :data:`rac.engine.budget.REPLAY_MEMOS`, handed back when it is collected
        self.share = REPLAY_MEMOS.share(self)

    def find(self, keys: list[bytes]) -> np.ndarray:
        """Each key's row in :attr:`store`, -1 for a transition not kept."""
        index = self.index
        return np.fromiter((index.get(key, -1) for key in keys), dtype=np.int64, count=len(keys))

    def add(self, keys: list[bytes], rows: np.ndarray) -> None:
        """Keep the distinct ``keys`` (none kept yet) with their ``rows``, as far as the budget allows."""
        if not keys:
            return
        size, capacity = len(self.index), self.store.shape[0]
        row_bytes = self.width * 8
        per_key = self.INDEX_BYTES + len(keys[0])
        wanted = capacity if size + len(keys) <= capacity else max(2 * capacity, size + len(keys), 64)
        cost = (wanted - capacity) * row_bytes + len(keys) * per_key
        if cost > REPLAY_MEMOS.left():  # start afresh, with these
            self.share.release()
            self.index, self.store = {}, np.zeros((0, self.width))
            size = capacity = 0
            wanted = max(len(keys), 64)
            cost = wanted * row_bytes + len(keys) * per_key
            if cost > REPLAY_MEMOS.left():
                return
        if wanted > capacity:
            grown = np.zeros((wanted, self.width))
            grown[:size] = self.store[:size]
            self.store = grown
        self.store[size:size + len(keys)] = rows
        self.index.update(zip(keys, range(size, size + len(keys))))
        self.share.charge(cost)


@dataclass(frozen=True, eq=False)
class CounterfactualBatch:
    """``B * L`` counterfactual transitions of ``B`` real ones (``(B * L,)`` arrays, transition-major):
    the real transition each comes from (``source``, an index into the batch), the automaton's
    ``location`` before and ``next_location`` after, the ``reward`` (the objective's increase, plus
    the ``at end`` bonus where the transition ended its episode) and whether it ``ended``."""

    source: np.ndarray
    location: np.ndarray
    next_location: np.ndarray
    reward: np.ndarray
    ended: np.ndarray


def counterfactual_transitions(automaton: ir.Automaton | Replayer, inputs: Mapping[str, np.ndarray], *,
                               rewards: Mapping[str, np.ndarray] | None = None,
                               ended: np.ndarray | None = None,
                               held: Mapping[str, np.ndarray] | None = None) -> CounterfactualBatch:
    """The counterfactual transitions of a batch of ``B`` one-sample transitions (one environment
    step = one sample, as :class:`rac.learning.wrappers.RewardAutomatonWrapper` steps the automaton):
    ``inputs`` the automaton's inputs each transition produced (name -> ``(B,)``), ``rewards`` the
    reward values before it (name -> ``(B,)``; default 0, exact for automata whose updates add
    constants or inputs; required — a ``ValueError`` without it — where an update reads a reward's
    value, as ``sa = sa * 2``), ``ended`` which transitions ended their episode (the ``at end`` clauses apply),
    ``held`` the inputs of the step before each transition (name -> ``(B,)``; the rates of the
    transition's sample read them: :class:`~rac.learning.wrappers.RewardAutomatonWrapper`'s
    ``info["rac"]["held"]``; required when a rate reads an input — at an episode's first step they are
    the step's own inputs — and a ``ValueError`` without it: replayed as a first sample, every later
    transition's rewards would be wrong, silently; not needed for automata whose rates read no inputs).
    Pass a :class:`Replayer` instead of the automaton to reuse its batches across calls."""
    replayer = automaton if isinstance(automaton, Replayer) else Replayer(automaton)
    program = replayer.automaton
    if held is None and program.rates_read_inputs:
        read = sorted({name for location in program.locations for rate in location.rates
                       for name in rate.variables()})
        raise ValueError(f"the rates of `{program.name}` read the input(s) {', '.join(read)} held from the step "
                         "before each transition: pass held= (RewardAutomatonWrapper's info['rac']['held']; at an "
                         "episode's first step, the step's own inputs)")
    reading = program.first_non_translation()
    if rewards is None and reading is not None:
        raise ValueError(f"in `{program.name}`, the update of `{reading[0]}` on {reading[1]} reads the rewards' "
                         "values, so a transition's reward depends on them: pass rewards= (each reward's value before "
                         "the transition: RewardAutomatonWrapper's info['rac']['rewards'] minus "
                         "info['rac']['reward_steps'])")
    columns = {name: np.asarray(values) for name, values in inputs.items()}
    if not columns and ended is None:  # an automaton without inputs: only `ended` says how many transitions
        raise ValueError("inputs name no input: pass ended= (one flag per transition) to give their number")
    n = int(next(iter(columns.values())).shape[0]) if columns else int(np.asarray(ended).reshape(-1).shape[0])
    done = np.zeros(n, dtype=bool) if ended is None else np.asarray(ended, dtype=bool)
    if done.shape != (n,):
        raise ValueError(f"ended must have shape ({n},), not {done.shape}")
    cf = replayer.replay([Sample(columns, np.ones(n, dtype=bool), done)], n, rewards, held)
    size = replayer.n_locations
    return CounterfactualBatch(np.repeat(np.arange(n), size), np.tile(np.arange(size), n),
                               cf.next_location.reshape(-1), cf.reward.reshape(-1), np.repeat(done, size))
