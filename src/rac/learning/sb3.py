"""A stable-baselines3 callback logging the reward automaton (:class:`RacCallback`).

stable-baselines3 is an optional dependency (``pip install 'rac[rl]'``); this module needs it,
:mod:`rac.learning.training_log` (what is recorded) does not.
"""

from __future__ import annotations

try:
    from stable_baselines3.common.callbacks import BaseCallback
except ImportError as exc:  # pragma: no cover - depends on the environment
    raise ImportError("rac.learning.sb3 needs stable-baselines3: pip install 'rac[rl]'") from exc

from rac.learning.training_log import TrainingLog

__all__ = ["RacCallback"]


class RacCallback(BaseCallback):
    """Records :class:`~rac.learning.training_log.TrainingLog`'s values with ``self.logger.record``
    at the end of every rollout (``rac/reward/<name>``, ``rac/location/<name>``, ``rac/shield/...``,
    ``rac/collisions``). Needs stable-baselines3 (an optional dependency: ``pip install 'rac[rl]'``).

    Example::

        model = PPO("MlpPolicy", RewardAutomatonWrapper(env, "follow.ra", inputs, scale="proven"))
        model.learn(10_000, callback=RacCallback())
    """

    def __init__(self, verbose: int = 0) -> None:
        super().__init__(verbose)
        self.log = TrainingLog()

    def _on_step(self) -> bool:
        self.log.add(self.locals.get("infos", ()))
        return True

    def _on_rollout_end(self) -> None:
        for key, value in self.log.record().items():
            self.logger.record(key, value)
