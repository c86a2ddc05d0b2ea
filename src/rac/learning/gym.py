"""Gymnasium integration, one import away: :class:`RewardAutomatonWrapper` (a reward automaton's
reward on any environment, :mod:`rac.learning.wrappers`), :class:`RewardAutomatonVectorWrapper` (the
same on a gymnasium vector environment), :class:`ScenarioEnv` (the scenario
model of a ``.ra`` file's ``model`` block as an environment, :mod:`rac.learning.scenario_env`) and
:class:`LocationObservation` / :class:`LocationVectorObservation` (the automaton's location in the
observation, :mod:`rac.learning.location_observation`).

The registered ids (``gymnasium.make("rac/Scenario-v0", model=...)``) come with ``import rac.gym``.
"""

from __future__ import annotations

from rac.learning.location_observation import LocationObservation, LocationVectorObservation
from rac.learning.scenario_env import ScenarioEnv
from rac.learning.wrappers import AutomatonLike, RewardAutomatonVectorWrapper, RewardAutomatonWrapper

__all__ = ["AutomatonLike", "LocationObservation", "LocationVectorObservation", "RewardAutomatonVectorWrapper",
           "RewardAutomatonWrapper", "ScenarioEnv"]
