"""Counterfactual transitions for a deep learner's replay buffer, from rac's wrappers' infos.

One vector step of ``n`` environments, each a :class:`~rac.learning.wrappers.RewardAutomatonWrapper`
under :class:`~rac.learning.location_observation.LocationObservation` (``"concat"`` layout), as an
off-policy algorithm stores it (stable-baselines3's ``ReplayBuffer.add``: observations ``(n, D)``,
one info dict per environment): :class:`CounterfactualRows` gives the ``L - 1`` other batches of
``n`` transitions, one per location the automaton was not in — the same environment transitions,
with the observation's location, the reward and the next location the automaton would have had
(:mod:`rac.learning.counterfactual`). :class:`rac.learning.sb3.CounterfactualReplayBuffer` stores
them beside the real ones.

Exact when the observation shows the automaton only through its location, as for
:mod:`rac.learning.counterfactual`: the episode's end does not depend on the automaton's location
(``episode ends when`` reads the inputs only, so it ends the episode from every location alike, its
``at end`` clauses in the step).
"""

from __future__ import annotations

import os
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from rac import ir
from rac.learning.counterfactual import Replayer, counterfactual_transitions
from rac.learning.location_observation import one_hot_index, replace_one_hot
from rac.learning.wrappers import AutomatonLike, automaton_ir

__all__ = ["CounterfactualRows", "CounterfactualStep"]

#: The keys of ``info["rac"]`` a counterfactual replay reads (RewardAutomatonWrapper's step info).
NEEDED = ("inputs", "held", "rewards", "reward_steps", "scale", "location")


@dataclass(frozen=True, eq=False)
class CounterfactualStep:
    """``n`` counterfactual transitions (one per environment) from locations the automaton was not in:
    ``obs`` and ``next_obs`` (``(n, D)``, the location columns replaced), the ``reward`` (``(n,)``,
    scaled as the wrapper scales) and the ``location`` and ``next_location`` indices."""

    obs: np.ndarray
    next_obs: np.ndarray
    reward: np.ndarray
    location: np.ndarray
    next_location: np.ndarray


def _column(racs: Sequence[Mapping[str, Any]], key: str) -> dict[str, np.ndarray]:
    """The per-environment values of the mapping ``info["rac"][key]`` as one array per name."""
    return {name: np.array([rac[key][name] for rac in racs]) for name in racs[0][key]}


class CounterfactualRows:
    """Builds the counterfactual transitions of vector steps (see the module docstring).

    Args:
        automaton: the automaton the wrappers run (a ``.ra`` path, an :class:`rac.ir.Automaton`, or a
            runtime from :func:`rac.load`); its location order is the one-hot vector's.
    """

    def __init__(self, automaton: str | os.PathLike[str] | ir.Automaton | AutomatonLike) -> None:
        program = automaton_ir(automaton)
        if program is None:  # a generated class's instance: no IR to replay
            raise TypeError(f"automaton must be a .ra path, an ir.Automaton or a RewardAutomaton, not {automaton!r}")
        self._replayer = Replayer(program)
        #: The location names, index ``i`` the one-hot column ``i``.
        self.locations: tuple[str, ...] = program.location_names
        self._index = {name: i for i, name in enumerate(self.locations)}

    def _infos(self, infos: Sequence[Mapping[str, Any]], n: int) -> list[Mapping[str, Any]]:
        if isinstance(infos, Mapping):  # its length is its number of keys: "not 4 dicts" said nothing useful
            raise ValueError("infos is one dict (a gymnasium vector environment's, e.g. RewardAutomatonVectorWrapper's "
                             "arrays): counterfactual transitions take one info dict per environment, as "
                             "stable-baselines3's VecEnv gives them, each environment a RewardAutomatonWrapper")
        if len(infos) != n:
            raise ValueError(f"infos must hold one dict per environment ({n}), not {len(infos)}")
        found: list[Mapping[str, Any]] = []
        for i, info in enumerate(infos):
            rac = info.get("rac") if isinstance(info, Mapping) else None
            if rac is None and isinstance(info, Mapping) and "location" in info:
                raise ValueError(f"infos[{i}] carries the automaton's location at its top level, as rac's scenario "
                                 "environments (ScenarioEnv, ScenarioVectorEnv) do: their step is several samples of "
                                 "the automaton, which counterfactual transitions from one info do not replay (rac."
                                 "learning.episodes.EpisodeBatch.counterfactual replays them); these need each "
                                 "environment wrapped in rac.learning.wrappers.RewardAutomatonWrapper")
            missing = [key for key in NEEDED if not isinstance(rac, Mapping) or key not in rac]
            if missing or not isinstance(rac, Mapping):
                raise ValueError(f"infos[{i}] has no info['rac'][{missing[0]!r}]: counterfactual transitions need "
                                 "the step info of rac.learning.wrappers.RewardAutomatonWrapper (inputs, held, "
                                 "rewards, reward_steps, scale, location), around each environment")
            found.append(rac)
        return found

    def step(self, obs: np.ndarray, next_obs: np.ndarray, done: np.ndarray,
             infos: Sequence[Mapping[str, Any]]) -> list[CounterfactualStep]:
        """The ``L - 1`` batches of counterfactual transitions of one vector step: ``obs`` before and
        ``next_obs`` after it (``(n, D)``, the location's one-hot vector in the last ``L`` columns),
        ``done`` where the episode ended (the ``at end`` clauses apply), ``infos`` the wrappers' step
        infos. Batch ``k`` starts each environment ``k`` locations after the one it was in."""
        obs, next_obs = np.asarray(obs), np.asarray(next_obs)
        if obs.ndim != 2 or next_obs.shape != obs.shape:  # one environment's (D,) was read as D environments
            raise ValueError(f"obs and next_obs must be batches (n environments, D columns) of the same shape, not "
                             f"{obs.shape} and {next_obs.shape}: one environment's observation is obs[None, :]")
        count = len(self.locations)
        n = int(obs.shape[0])
        racs = self._infos(infos, n)
        real = one_hot_index(obs, count)
        unknown = sorted({str(rac["location"]) for rac in racs} - set(self._index))
        if unknown:  # the wrappers run another automaton than the one given here
            raise ValueError(f"info['rac']['location'] is {unknown[0]!r}, which this automaton does not have (its "
                             f"locations: {', '.join(self.locations)}): pass the automaton the wrappers run")
        after = np.array([self._index[str(rac["location"])] for rac in racs], dtype=np.int64)
        try:
            shown = one_hot_index(next_obs, count)
        except ValueError as exc:  # obs was one-hot: only an episode's last next_obs went through a normaliser
            raise ValueError(f"{exc}: in next_obs, while obs's are; where an episode ended, stable-baselines3 "
                             "stores the terminal observation VecNormalize normalised, unnormalised again (inexactly, "
                             "and clipped): use VecNormalize(norm_obs=False)") from None
        if not np.array_equal(shown, after):
            raise ValueError("next_obs's location columns differ from info['rac']['location']: the observation's "
                             "one-hot vector is not this automaton's (another automaton, or another location order)")
        inputs = _column(racs, "inputs")
        prior = {name: np.array([float(rac["rewards"][name]) - float(rac["reward_steps"][name]) for rac in racs])
                 for name in racs[0]["rewards"]}
        scale = np.array([float(rac["scale"]) for rac in racs])
        held = _column(racs, "held")
        cf = counterfactual_transitions(self._replayer, inputs, rewards=prior, held=held,
                                        ended=np.asarray(done, dtype=bool).reshape(n))
        rows = np.arange(n)
        batches = []
        for k in range(1, count):
            location = (real + k) % count
            pick = rows * count + location
            next_location = cf.next_location[pick]
            batches.append(CounterfactualStep(replace_one_hot(obs, location, count),
                                              replace_one_hot(next_obs, next_location, count),
                                              cf.reward[pick] / scale, location, next_location))
        return batches
