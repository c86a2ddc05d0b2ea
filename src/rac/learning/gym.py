"""Gymnasium integration, one import away: :class:`RewardAutomatonWrapper` (a reward automaton's
reward on any environment, :mod:`rac.learning.wrappers`), :class:`RewardAutomatonVectorWrapper` (the
same on a gymnasium vector environment) and :class:`ScenarioEnv` (the scenario
model of a ``.ra`` file's ``model`` block as an environment, :mod:`rac.learning.scenario_env`).

The registered ids (``gymnasium.make("rac/Scenario-v0", model=...)``) come with ``import rac.gym``.
"""

from __future__ import annotations

from rac.learning.scenario_env import ScenarioEnv
from rac.learning.wrappers import AutomatonLike, RewardAutomatonVectorWrapper, RewardAutomatonWrapper

__all__ = ["AutomatonLike", "RewardAutomatonVectorWrapper", "RewardAutomatonWrapper", "ScenarioEnv"]
