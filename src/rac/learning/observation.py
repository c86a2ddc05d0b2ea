"""What a learner observes of an episode of the scenario model: one owner for the observation's
meaning, shared by :class:`rac.learning.scenario_env.ScenarioEnv` and the vector environment
(:mod:`rac.learning.vector`), so the two cannot drift apart.

An :class:`Observation` reads a whole :class:`rac.learning.episodes.EpisodeBatch` at once (one row
per episode, float32) and has one :class:`gymnasium.spaces.Box` for one episode, with finite bounds
that do not depend on the scene (a policy trained on a set of scenes sees one space).

Kinds (:data:`KINDS`, :func:`make_observation`):

- ``"ego"``: the sensed ``x, y, v, acc, head, jerk, turn`` (metres, seconds, radians:
  significand / scale) and the time in seconds — the scene's own coordinates; a policy can only
  memorise one scene with it.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Protocol

import gymnasium
import numpy as np

from rac.core.numbers import INT32_MAX

if TYPE_CHECKING:
    from rac.learning.episodes import EpisodeBatch

__all__ = ["KINDS", "EgoObservation", "Observation", "make_observation"]


class Observation(Protocol):
    """An observation of every episode of a batch."""

    #: The kind's name (one of :data:`KINDS`).
    kind: str
    #: The space of one episode's observation (float32, finite bounds).
    space: gymnasium.spaces.Box

    def observe(self, episodes: EpisodeBatch) -> np.ndarray:
        """``(episodes.n, dim)`` float32: each episode's observation now (after ``reset`` or ``step``)."""
        ...


class EgoObservation:
    """``"ego"``: the sensed ego state and the time (8 values; see the module docstring)."""

    kind = "ego"

    def __init__(self, episodes: EpisodeBatch) -> None:
        data = episodes.data
        self._scale = float(data.scale)
        self._period = float(data.period)
        bound = np.float32(INT32_MAX / self._scale)  # every sensed value is an int32 significand
        end = np.float32(episodes.horizon_samples * self._period)
        self.space = gymnasium.spaces.Box(
            low=np.array([-bound] * 7 + [0.0], dtype=np.float32),
            high=np.array([bound] * 7 + [end], dtype=np.float32), dtype=np.float32)

    def observe(self, episodes: EpisodeBatch) -> np.ndarray:
        out = np.empty((episodes.n, 8), dtype=np.float32)
        out[:, :7] = episodes.ego / self._scale
        out[:, 7] = episodes.k * self._period
        return out


#: The kinds of observation, by name.
KINDS: dict[str, type] = {"ego": EgoObservation}


def make_observation(kind: str, episodes: EpisodeBatch) -> Observation:
    """The observation ``kind`` (one of :data:`KINDS`) of ``episodes``' model; :class:`ValueError` names
    the kinds for any other."""
    if kind not in KINDS:
        raise ValueError(f"observation must be one of {sorted(KINDS)}, not {kind!r}")
    observation: Observation = KINDS[kind](episodes)
    return observation
