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
  updates the Q-value of the transition's observation in every location.
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
from rac.runtime.batch import BatchRewardAutomaton

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
    one batch of automata per size, so that replaying costs one automaton step per sample."""

    def __init__(self, automaton: ir.Automaton) -> None:
        self.automaton = automaton
        self.n_locations = len(automaton.locations)
        self._batches: dict[int, BatchRewardAutomaton] = {}

    def replay(self, samples: Sequence[Sample], n: int, rewards: Mapping[str, np.ndarray] | None = None,
               held: Mapping[str, np.ndarray] | None = None) -> Counterfactuals:
        """The :class:`Counterfactuals` of ``n`` transitions made of ``samples`` (in order), each
        starting with the reward values ``rewards`` (name -> ``(n,)``; default 0) in every location
        and the inputs ``held`` from the sample before (name -> ``(n,)``, which input-dependent rates
        read at the first sample; default none, as at a run's first sample)."""
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
