"""A stable-baselines3 callback logging the reward automaton (:class:`RacCallback`).

stable-baselines3 is an optional dependency (``pip install 'rac[rl]'``); this module needs it,
:mod:`rac.learning.training_log` (what is recorded) does not.
"""

from __future__ import annotations

try:
    from stable_baselines3.common.callbacks import BaseCallback
    from stable_baselines3.common.off_policy_algorithm import OffPolicyAlgorithm
except ImportError as exc:  # pragma: no cover - depends on the environment
    raise ImportError("rac.learning.sb3 needs stable-baselines3: pip install 'rac[rl]'") from exc

from rac.learning.training_log import TrainingLog

__all__ = ["RacCallback"]


class RacCallback(BaseCallback):
    """Records :class:`~rac.learning.training_log.TrainingLog`'s values with ``self.logger.record``
    (``rac/reward/<name>``, ``rac/location/<name>``, ``rac/shield/...``, ``rac/collisions``) over
    the steps since SB3's logger last wrote its table: the values so far are recorded at every
    rollout's end for an on-policy algorithm (PPO, A2C, MaskablePPO: its table follows a rollout,
    every ``log_interval`` rollouts), at every step for an off-policy one (DQN, SAC, ...: its table
    is written at an episode's end, within a rollout of a few steps). Needs stable-baselines3 (an
    optional dependency: ``pip install 'rac[rl]'``).

    Example::

        model = PPO("MlpPolicy", RewardAutomatonWrapper(env, "follow.ra", inputs, scale="proven"))
        model.learn(10_000, callback=RacCallback())
    """

    def __init__(self, verbose: int = 0) -> None:
        super().__init__(verbose)
        self.log = TrainingLog()
        self._per_step = False  # an off-policy algorithm: record the values at every step
        self._logged: dict[str, float] = {}  # what the logger was last given, until it writes them out

    def _init_callback(self) -> None:
        self._per_step = isinstance(self.model, OffPolicyAlgorithm)

    def _on_step(self) -> bool:
        # The logger's table is written when the algorithm says (A2C: every 100 rollouts; DQN: at an
        # episode's end, within a rollout): recording each rollout alone, the table showed the last few
        # steps (the collisions before them lost). The window runs until a dump has written it out (a
        # dump clears the logger's values).
        if any(self.logger.name_to_value.get(key) != value for key, value in self._logged.items()):
            self.log.record()  # written out: what follows is the next window's
            self._logged = {}
        self.log.add(self.locals.get("infos", ()))
        if self._per_step:
            self._write()
        return True

    def _on_rollout_end(self) -> None:
        if not self._per_step:  # an on-policy table follows a rollout (an evaluation's may come within one)
            self._write()

    def _write(self) -> None:
        self._logged = self.log.values()
        for key, value in self._logged.items():
            self.logger.record(key, value)
