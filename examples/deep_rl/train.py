"""Deep RL with a proven reward automaton and a safety shield (issue 21):
``python examples/deep_rl/train.py [--timesteps N] [--seed S] [--out DIR]``.

Two agents learn to drive through a set of built highway scenes and are evaluated on held-out ones:

  shield + automaton   sb3-contrib's MaskablePPO, its actions masked by the runtime shield
                       (rac.engine.lookahead), rewarded by driving.ra's automaton (safety > progress >
                       comfort, P1 and P2 proved by ``rac check``), scaled so a sample's reward lies in
                       [-1, 1]
  no shield + Eq. 9    stable-baselines3's PPO, every action allowed, rewarded by the paper's weighted
                       reward function (Eq. 9: ``10*!isClose + (5 + 100*goal())*prog + comf``), scaled
                       the same way

It prints, for each, the env steps to the first safe goal (the first training episode at the goal
without a collision), the collisions during training and the success (goal without a collision)
over the evaluation episodes on the held-out scenes. ``benchmarks/deep_rl.py`` runs this over
several seeds and writes the table. The scenes are written by the script into ``--out`` (default
``examples/deep_rl/out/``), never read from elsewhere. Needs the ``rl`` extra: ``pip install
torch==2.13.0`` (the CPU build), then ``pip install '.[rl]'``.
"""

from __future__ import annotations

import argparse
import re
import sys
import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import gymnasium
import numpy as np

HERE = Path(__file__).resolve().parent
MODEL = HERE / "driving.ra"
DEFAULT_OUT = HERE / "out"

try:  # the installed rac; in a checkout without it, the checkout's src/
    import rac  # noqa: F401
except ImportError:
    sys.path.insert(0, str(HERE.parents[1] / "src"))

#: The paper's weighted reward function (Eq. 9), over driving.ra's inputs and the model's goal().
EQ9 = "10*!isClose + (5 + 100*goal())*prog + comf"
#: The two configurations compared: (masked by the shield, reward).
CONFIGS: dict[str, tuple[bool, str]] = {"shield + automaton": (True, "automaton"), "no shield + Eq. 9": (False, EQ9)}
#: The scenes trained on and held out (until seeded scene variants exist: distinct built scenes).
TRAIN_SCENES = ("highway", "tutorial")
HELD_OUT_SCENES = ("overtaking",)


def build_scenes(folder: Path) -> tuple[list[Path], list[Path]]:
    """Write the training and held-out scenes into ``folder/scenes``; their paths (train, held out)."""
    from rac.model.scenes import write_scene

    scenes = folder / "scenes"
    scenes.mkdir(parents=True, exist_ok=True)
    return ([write_scene(name, scenes / f"{name}.xml") for name in TRAIN_SCENES],
            [write_scene(name, scenes / f"{name}.xml") for name in HELD_OUT_SCENES])


def write_models(folder: Path, scenes: Sequence[Path]) -> list[Path]:
    """driving.ra once per scene in ``folder`` (its ``scenario`` line pointing at the scene): the
    ``.ra`` files the environments load."""
    text = MODEL.read_text(encoding="utf-8")
    models = []
    for scene in scenes:
        path = folder / f"driving_{scene.stem}.ra"
        path.write_text(re.sub(r'scenario "[^"]*"', f'scenario "{scene.resolve().as_posix()}"', text, count=1),
                        encoding="utf-8")
        models.append(path)
    return models


def reward_scale(reward: str) -> float:
    """What a sample's reward is divided by so that it lies in [-1, 1]: the largest change of the
    objective in one sample (the penalty of 100 in ``sa``, weighted 10, and the collision's 100 on
    top) for the automaton, Eq. 9's largest value otherwise.

    A stand-in for the proven scale (``ScenarioEnv(scale="proven")``), written out by hand from
    driving.ra until rac derives it."""
    return 10 * 200.0 + 5 + 1 if reward == "automaton" else 10 + 105 + 1


class Scaled(gymnasium.RewardWrapper):
    """The environment's reward divided by ``scale`` (``action_masks`` passes through)."""

    def __init__(self, env: gymnasium.Env, scale: float) -> None:
        super().__init__(env)
        self.scale = scale

    def reward(self, reward: Any) -> float:
        return float(reward) / self.scale

    def action_masks(self) -> np.ndarray:
        """The wrapped environment's mask (MaskablePPO asks every environment of the vector env)."""
        return self.env.unwrapped.action_masks()  # type: ignore[attr-defined, no-any-return]


def make_env(model: Path, config: str, depth: int, seconds: float) -> gymnasium.Env:
    """The environment of ``config`` on the scene of ``model``."""
    from rac.engine.lookahead import LookaheadSettings
    from rac.learning.gym import ScenarioEnv

    shielded, reward = CONFIGS[config]
    lookahead = LookaheadSettings(depth=depth, seconds=seconds) if shielded else None
    return Scaled(ScenarioEnv(model, lookahead=lookahead, reward=reward), reward_scale(reward))


@dataclass
class Tally:
    """What one training run met (from each step's ``info``)."""

    steps: int = 0
    episodes: int = 0
    collision_steps: int = 0
    collided_episodes: int = 0
    goal_episodes: int = 0
    safe_goal_episodes: int = 0
    #: Env steps (over all environments) up to the end of the first episode at the goal without a collision.
    first_safe_goal: int | None = None
    _collided: list[bool] = field(default_factory=list)

    def add(self, env: int, info: dict[str, Any], done: bool) -> None:
        """One step of environment ``env``."""
        while len(self._collided) <= env:
            self._collided.append(False)
        self.steps += 1
        self.collision_steps += bool(info["collided"])
        self._collided[env] |= bool(info["collided"])
        if done:
            self.episodes += 1
            self.collided_episodes += self._collided[env]
            goal = bool(info["goal"])
            self.goal_episodes += goal
            if goal and not self._collided[env]:
                self.safe_goal_episodes += 1
                if self.first_safe_goal is None:
                    self.first_safe_goal = self.steps
            self._collided[env] = False


@dataclass
class Result:
    """One configuration trained from one seed and evaluated."""

    config: str
    seed: int
    tally: Tally
    eval_episodes: int
    eval_success: int
    eval_collided: int
    cpu_seconds: float
    wall_seconds: float


def train_and_evaluate(config: str, seed: int, *, timesteps: int, eval_episodes: int, out: Path,
                       depth: int = 4, seconds: float = 0.05, quick: bool = False) -> Result:
    """Train ``config`` from ``seed`` for ``timesteps`` env steps on the training scenes, then run
    its greedy policy (masked, for the shielded one) for ``eval_episodes`` episodes on the held-out
    scenes, round-robin."""
    import torch
    from sb3_contrib import MaskablePPO
    from stable_baselines3 import PPO
    from stable_baselines3.common.callbacks import BaseCallback
    from stable_baselines3.common.vec_env import DummyVecEnv

    torch.set_num_threads(1)  # the machine's cores are shared: one thread per process
    cpu, wall = time.process_time(), time.perf_counter()
    train_scenes, held_out = build_scenes(out)
    train_models, eval_models = write_models(out, train_scenes), write_models(out, held_out)
    shielded = CONFIGS[config][0]
    vec = DummyVecEnv([lambda model=model: make_env(model, config, depth, seconds) for model in train_models])
    tally = Tally()

    class Record(BaseCallback):
        def _on_step(self) -> bool:
            for env, (info, done) in enumerate(zip(self.locals["infos"], self.locals["dones"])):
                tally.add(env, info, bool(done))
            return True

    hyper: dict[str, Any] = dict(n_steps=32, batch_size=32, n_epochs=2) if quick else \
        dict(n_steps=256, batch_size=128, n_epochs=5)
    algorithm = MaskablePPO if shielded else PPO
    agent = algorithm("MlpPolicy", vec, seed=seed, verbose=0, gamma=0.99, ent_coef=0.01,
                      policy_kwargs=dict(net_arch=[64, 64]), device="cpu", **hyper)
    agent.learn(total_timesteps=timesteps, callback=Record())
    vec.close()
    success = collided = 0
    envs = [make_env(model, config, depth, seconds) for model in eval_models]
    for episode in range(eval_episodes):
        env = envs[episode % len(envs)]
        obs, _ = env.reset(seed=seed + episode)
        done, crashed = False, False
        while not done:
            if shielded:
                action, _ = agent.predict(obs, action_masks=env.action_masks(), deterministic=True)  # type: ignore[attr-defined]
            else:
                action, _ = agent.predict(obs, deterministic=True)
            obs, _, terminated, truncated, info = env.step(int(action))
            crashed |= bool(info["collided"])
            done = terminated or truncated
        collided += crashed
        success += bool(info["goal"]) and not crashed
    return Result(config, seed, tally, eval_episodes, success, collided, time.process_time() - cpu,
                  time.perf_counter() - wall)


def describe(result: Result) -> str:
    """One line of text for ``result``."""
    tally = result.tally
    first = f"{tally.first_safe_goal:,}" if tally.first_safe_goal is not None else "never"
    return (f"{result.config} (seed {result.seed}): first safe goal after {first} env steps; "
            f"{tally.collision_steps:,} collision steps in {tally.collided_episodes:,} of {tally.episodes:,} "
            f"training episodes; held-out success {result.eval_success}/{result.eval_episodes} "
            f"({result.eval_collided} with a collision); {result.cpu_seconds:.0f} s CPU, "
            f"{result.wall_seconds:.0f} s wall")


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--timesteps", type=int, default=20_000, help="training env steps per agent")
    parser.add_argument("--eval-episodes", type=int, default=100)
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--out", type=Path, default=DEFAULT_OUT, help="where the scenes and models are written")
    args = parser.parse_args(argv)
    for config in CONFIGS:
        print(describe(train_and_evaluate(config, args.seed, timesteps=args.timesteps,
                                          eval_episodes=args.eval_episodes, out=args.out)), flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
