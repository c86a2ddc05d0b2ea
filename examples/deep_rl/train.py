"""Deep RL with a proven reward automaton and a safety shield (issue 21):
``python examples/deep_rl/train.py [--timesteps N] [--seed S] [--out DIR]``.

Two agents learn to drive through a set of built highway scenes and are evaluated on held-out ones:

  shield + automaton   sb3-contrib's MaskablePPO, its actions masked by the runtime shield
                       (rac.engine.lookahead), rewarded by driving.ra's automaton (safety > progress >
                       comfort, P1 and P2 proved by ``rac check``), ``scale="proven"``: every step's
                       reward in [-1, 1]
  no shield + Eq. 9    stable-baselines3's PPO, every action allowed, rewarded by the paper's weighted
                       reward function (Eq. 9: ``10*!isClose + (5 + 100*goal())*prog + comf``), scaled
                       the same way

It prints, for each, the env steps to the first safe goal (the first training episode at the goal
without a collision), the collisions during training and the success (goal without a collision)
over the evaluation episodes on the held-out scenes. ``benchmarks/deep_rl.py`` runs this over
several seeds and writes the table. The scenes are written by the script into ``--out`` (default
``examples/deep_rl/out/``), never read from elsewhere. Needs the ``rl`` extra: ``pip install
torch==2.13.0 --index-url https://download.pytorch.org/whl/cpu`` (the CPU build), then ``pip install
'.[rl]'``.
"""

from __future__ import annotations

import argparse
import dataclasses
import sys
import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import gymnasium

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
#: The kinds of scene (rac.model.scenes.scene_set), half of each set from each.
KINDS = ("highway", "tutorial")
#: The first variant seed of the held-out scenes: far from the training scenes' (0 on).
HELD_OUT_SEED = 1000


def build_scenes(folder: Path, train: int, held_out: int) -> tuple[list[Path], list[Path]]:
    """Write ``train`` training scenes into ``folder/train`` and ``held_out`` others into
    ``folder/held_out`` (seeded variants of each kind: the same files on every run);
    their paths (train, held out)."""
    from rac.model.scenes import scene_set

    def write(count: int, seed: int, where: Path) -> list[Path]:
        paths = []
        for i, kind in enumerate(KINDS):  # the count split evenly, the first kinds taking the rest
            share = count // len(KINDS) + (i < count % len(KINDS))
            paths += scene_set(kind, share, seed, where) if share else []
        return paths

    return write(train, 0, folder / "train"), write(held_out, HELD_OUT_SEED, folder / "held_out")


#: Eq. 9's largest value over one step (5 samples of at most 10 + 105 + 1): its rewards are divided by it,
#: so they lie in [-1, 1] like the automaton's under ``scale="proven"`` (which rac proves; Eq. 9 has no proof).
EQ9_SCALE = 5 * (10 + 105 + 1)


def make_env(scenes: Sequence[Path], config: str, depth: int, nodes: int) -> gymnasium.Env:
    """The environment of ``config`` on the set ``scenes`` (one drawn per reset), with the
    scene-independent ``"relative"`` observation."""
    from rac.engine.lookahead import LookaheadSettings
    from rac.learning.gym import ScenarioEnv

    shielded, reward = CONFIGS[config]
    # a budget of search nodes, not seconds: the same masks however loaded the machine is
    lookahead = LookaheadSettings(depth=depth, seconds=None, nodes=nodes) if shielded else None
    # the automaton's rewards divided by the largest change of its objective over one step that
    # rac check proves: every reward in [-1, 1], and the priority proofs still hold (a positive factor)
    scale: float | str = "proven" if reward == "automaton" else EQ9_SCALE
    return ScenarioEnv(MODEL, scenarios=scenes, lookahead=lookahead, reward=reward, observation="relative",
                       scale=scale)


@dataclass
class Tally:
    """What one training run met (from each step's ``info``)."""

    steps: int = 0
    episodes: int = 0
    collision_steps: int = 0
    collided_episodes: int = 0
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
            if info["goal"] and not self._collided[env] and self.first_safe_goal is None:
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


@dataclass(frozen=True)
class Settings:
    """How a run trains and is evaluated (the defaults: the benchmark's full run)."""

    timesteps: int = 6_000
    train_scenes: int = 16
    held_out_scenes: int = 100
    eval_episodes: int = 100
    #: The runtime shield: a safe continuation for the next ``depth`` decisions (3 s), found within
    #: ``nodes`` search nodes per decision.
    depth: int = 6
    nodes: int = 1000
    #: Environments stepped together (sb3's DummyVecEnv), and PPO's rollout and update.
    n_envs: int = 2
    n_steps: int = 256
    batch_size: int = 128
    n_epochs: int = 5


#: A smoke run's settings (``--quick``).
QUICK = Settings(timesteps=400, train_scenes=2, held_out_scenes=5, eval_episodes=5, n_steps=64, batch_size=64,
                 n_epochs=2)


def train_and_evaluate(config: str, seed: int, settings: Settings, out: Path) -> Result:
    """Train ``config`` from ``seed`` for ``settings.timesteps`` env steps on the training scenes,
    then run its greedy policy (masked, for the shielded one) for ``settings.eval_episodes``
    episodes on the held-out scenes, one scene after the other."""
    import torch
    from sb3_contrib import MaskablePPO
    from stable_baselines3 import PPO
    from stable_baselines3.common.base_class import BaseAlgorithm
    from stable_baselines3.common.callbacks import BaseCallback
    from stable_baselines3.common.vec_env import DummyVecEnv

    torch.set_num_threads(1)  # the machine's cores are shared: one thread per process
    cpu, wall = time.process_time(), time.perf_counter()
    train_scenes, held_out = build_scenes(out, settings.train_scenes, settings.held_out_scenes)
    shielded = CONFIGS[config][0]
    vec = DummyVecEnv([lambda: make_env(train_scenes, config, settings.depth, settings.nodes)] * settings.n_envs)
    tally = Tally()

    class Record(BaseCallback):
        def _on_step(self) -> bool:
            for env, (info, done) in enumerate(zip(self.locals["infos"], self.locals["dones"])):
                tally.add(env, info, bool(done))
            return True

    algorithm: type[BaseAlgorithm] = MaskablePPO if shielded else PPO
    agent = algorithm("MlpPolicy", vec, seed=seed, verbose=0, gamma=0.99, ent_coef=0.01, n_steps=settings.n_steps,
                      batch_size=settings.batch_size, n_epochs=settings.n_epochs,
                      policy_kwargs=dict(net_arch=[64, 64]), device="cpu")
    agent.learn(total_timesteps=settings.timesteps, callback=Record())
    vec.close()
    success = collided = 0
    env = make_env(held_out, config, settings.depth, settings.nodes)
    for episode in range(settings.eval_episodes):
        obs, _ = env.reset(seed=seed, options={"scenario": episode % len(held_out)})
        done, crashed = False, False
        while not done:
            masks = env.action_masks() if shielded else None  # type: ignore[attr-defined]
            action, _ = agent.predict(obs, deterministic=True, **({"action_masks": masks} if shielded else {}))
            obs, _, terminated, truncated, info = env.step(int(action))
            crashed |= bool(info["collided"])
            done = terminated or truncated
        collided += crashed
        success += bool(info["goal"]) and not crashed
    return Result(config, seed, tally, settings.eval_episodes, success, collided, time.process_time() - cpu,
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
    parser.add_argument("--quick", action="store_true", help="a smoke run: 400 steps, 5 evaluation episodes")
    parser.add_argument("--timesteps", type=int, default=None, help="training env steps per agent (default 6000)")
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--out", type=Path, default=DEFAULT_OUT, help="where the scenes are written")
    args = parser.parse_args(argv)
    settings = QUICK if args.quick else Settings()
    if args.timesteps is not None:
        settings = dataclasses.replace(settings, timesteps=args.timesteps)
    for config in CONFIGS:
        print(describe(train_and_evaluate(config, args.seed, settings, args.out)), flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
