"""A small highway-like environment for the wrapper tests: follow a lead car, keep a gap, do not crash."""

from __future__ import annotations

from typing import Any

import gymnasium
import numpy as np

from rac import ir
from rac.compiler import compile_text

FOLLOW = """automaton Follow {
    input headway : real in [0, 10]   // the gap to the lead car, in metres
    input collide : bool
    assume collide imply headway < 2
    reward sa, pr
    priority sa > pr
    objective 10 * sa + pr
    sample every 0.1
    horizon 3
    initial location Safe { sa' == 1;  pr' == 1 }
    location Unsafe       { sa' == -1; pr' == 0 }
    edge Safe -> Unsafe   when headway < 2 do sa = sa - 10
    edge Unsafe -> Safe   when headway >= 2
    edge Unsafe -> Unsafe when collide do sa = sa - 20
    at end when headway >= 5 do pr = pr + 5
}
"""


#: An automaton whose update scales a reward (`sa = sa * 2 - 10`): the discounted P2 check covers
#: translations only, so it is not made there (W0405).
SCALING = """automaton Doubling {
    input hit : bool
    reward sa, pr
    priority sa > pr
    objective 10 * sa + pr
    sample every 1
    horizon 5
    initial location Fine { sa' == 0; pr' == 1 }
    location Hit { sa' == -1; pr' == 0 }
    edge Fine -> Hit when hit do sa = sa * 2 - 10
}
"""


def follow() -> ir.Automaton:
    return compile_text(FOLLOW, "follow.ra").raise_for_errors()


class HighwayLike(gymnasium.Env):
    """Observation [gap to the lead car, own speed]; actions 0 slower, 1 keep, 2 faster; ``dt`` 0.1 s."""

    metadata: dict[str, Any] = {"render_modes": []}

    def __init__(self, dt: float = 0.1) -> None:
        self.dt = dt
        self.observation_space = gymnasium.spaces.Box(np.array([-100.0, 0.0], dtype=np.float32),
                                                      np.array([100.0, 40.0], dtype=np.float32))
        self.action_space = gymnasium.spaces.Discrete(3)
        self.gap, self.speed = 10.0, 10.0
        self.road = "the road"  # highway-env keeps the scene here (env.unwrapped.road)

    def _obs(self) -> np.ndarray:
        return np.array([self.gap, self.speed], dtype=np.float32)

    def reset(self, *, seed: int | None = None,
              options: dict[str, Any] | None = None) -> tuple[np.ndarray, dict[str, Any]]:
        super().reset(seed=seed)
        self.gap = float(self.np_random.uniform(3.0, 15.0))
        self.speed = float(self.np_random.uniform(8.0, 12.0))
        return self._obs(), {"collision": False}

    def step(self, action: int) -> tuple[np.ndarray, float, bool, bool, dict[str, Any]]:
        self.speed = float(np.clip(self.speed + (int(action) - 1) * 2.0, 0.0, 40.0))
        self.gap = float(np.clip(self.gap + (10.0 - self.speed) * self.dt * 5, -100.0, 100.0))
        collision = self.gap <= 0.0
        return self._obs(), 1.0, collision, False, {"collision": collision}


def inputs(obs: np.ndarray, info: dict[str, Any]) -> dict[str, object]:
    return {"headway": float(obs[0]), "collide": bool(info["collision"]) and float(obs[0]) < 2}


def vector_inputs(obs: np.ndarray, infos: dict[str, Any]) -> dict[str, object]:
    return {"headway": obs[:, 0].astype(np.float64), "collide": infos["collision"] & (obs[:, 0] < 2)}
