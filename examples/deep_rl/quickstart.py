"""rac with stable-baselines3 in a dozen lines: ``python examples/deep_rl/quickstart.py``.

sb3-contrib's MaskablePPO on the registered ``rac/Scenario-v0`` through SB3's own ``make_vec_env``:
driving.ra's automaton as the reward (``scale="proven"``: every step's reward in [-1, 1]), the
runtime shield's action masks, a set of four built highway scenes (one drawn per episode), and
:class:`rac.learning.sb3.RacCallback` logging each objective, the automaton's locations, the
shield's guarantees and the collisions beside SB3's own numbers; then the greedy policy drives, given the
masks (``predict(obs, action_masks=get_action_masks(envs))``). Needs the ``rl`` extra
(``pip install torch==2.13.0``, then ``pip install '.[rl]'``); ``tests/learning/test_deep_rl.py`` runs it.
"""

from pathlib import Path

import torch
from sb3_contrib import MaskablePPO
from sb3_contrib.common.maskable.utils import get_action_masks
from stable_baselines3.common.env_util import make_vec_env
from stable_baselines3.common.logger import configure

import rac.gym  # noqa: F401  (registers rac/Scenario-v0)
from rac.engine.lookahead import LookaheadSettings
from rac.learning.sb3 import RacCallback
from rac.model.scenes import scene_set

HERE = Path(__file__).resolve().parent
torch.set_num_threads(1)

scenes = scene_set("highway", 4, 0, HERE / "out" / "quickstart")  # written by rac.model.scenes, seeded
shield = LookaheadSettings(depth=6, seconds=None, nodes=1000)  # a node budget: the same masks on any machine
envs = make_vec_env("rac/Scenario-v0", n_envs=2, seed=1,
                    env_kwargs={"model": HERE / "driving.ra", "scenarios": scenes, "lookahead": shield,
                                "scale": "proven"})
agent = MaskablePPO("MlpPolicy", envs, n_steps=128, batch_size=64, n_epochs=2, seed=1, device="cpu")
agent.set_logger(configure(None, ["stdout"]))  # or ["stdout", "csv", "tensorboard"] with a folder
agent.learn(total_timesteps=256, callback=RacCallback())

obs = envs.reset()  # the greedy policy drives an episode's worth of steps, choosing from the shield's masks
for _ in range(24):
    actions, _ = agent.predict(obs, action_masks=get_action_masks(envs), deterministic=True)
    obs, rewards, dones, infos = envs.step(actions)
print("greedy steps outside the masks:", sum(envs.get_attr("outside_mask_steps")))
