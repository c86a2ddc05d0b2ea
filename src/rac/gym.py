"""rac's gymnasium ids: importing this module registers them (and does nothing else, so it stays
light: gymnasium only, the environments are imported when one is made).

- ``rac/Scenario-v0``: :class:`rac.learning.scenario_env.ScenarioEnv`, the scenario model of a
  ``.ra`` file's ``model`` block (``gymnasium.make("rac/Scenario-v0", model="file.ra", ...)``, the
  keywords are ScenarioEnv's). Its vector entry point is :func:`rac.learning.vector.make_vector_env`:
  ``gymnasium.make_vec("rac/Scenario-v0", num_envs=N, model=...)`` steps N episodes as one numpy batch.

Without importing it first: ``gymnasium.make("rac.gym:rac/Scenario-v0", model=...)``. No
``max_episode_steps``: the environment truncates its episodes at its own horizon (the ``horizon``
keyword, default the automaton's), which a TimeLimit would duplicate, and contradict when the horizon
is changed; ``max_episode_steps=N`` given to ``make`` truncates outside the environment, where its
``at end`` clauses cannot apply (the first episode it cuts warns): use ``horizon=``. Registering again (a
reload) keeps the first registration.
"""

from __future__ import annotations

import gymnasium

__all__ = ["SCENARIO", "register"]

#: The id of the scenario model's environment.
SCENARIO = "rac/Scenario-v0"


def register() -> None:
    """Register rac's ids with gymnasium, unless they are registered already."""
    if SCENARIO not in gymnasium.registry:
        gymnasium.register(id=SCENARIO, entry_point="rac.learning.scenario_env:ScenarioEnv",
                           vector_entry_point="rac.learning.vector:make_vector_env")


register()
