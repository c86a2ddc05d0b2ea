"""A rac reward on someone else's environment: highway-env's ``highway-fast-v0`` with
stable-baselines3's PPO (issue 21): ``python examples/highway_env/train.py [--timesteps N] [--episodes N]``.

follow.ra (safety over speed, P2 proved by ``rac check``) replaces highway-env's own reward through
:class:`rac.learning.wrappers.RewardAutomatonWrapper`:

- ``inputs(obs, info, env)`` reads the time gap to the car ahead from ``env.unwrapped.road`` (the
  observation does not hold it) and the crash and speed from ``info``;
- ``clip=True``: a gap beyond follow.ra's declared 10 s (an empty lane) is clipped to 10 and
  counted (``info["rac"]["clipped"]``) instead of ending training with a ValueError;
- ``scale="proven"``: every reward divided by the largest change of the objective in one sample that
  rac proves, so rewards lie in [-1, 1] and the priority order still holds;
- :class:`rac.learning.sb3.RacCallback` logs each objective, the locations' shares and the crashes
  into SB3's logger (``--log DIR`` also writes them as CSV and TensorBoard files).

After training, the greedy policy drives ``--episodes`` episodes; the script prints the share of
steps in each location, the crashes and the mean return. Needs highway-env (``pip install
highway-env``) and the ``rl`` extra (``pip install torch==2.13.0``, then ``pip install '.[rl]'``).
"""

from __future__ import annotations

import argparse
import sys
from collections import Counter
from collections.abc import Sequence
from pathlib import Path
from typing import Any

HERE = Path(__file__).resolve().parent

try:  # the installed rac; in a checkout without it, the checkout's src/
    import rac  # noqa: F401
except ImportError:
    sys.path.insert(0, str(HERE.parents[1] / "src"))


def inputs(obs: Any, info: dict[str, Any], env: Any) -> dict[str, object]:
    """follow.ra's inputs after one step of highway-env (``env``: the wrapped environment)."""
    road, ego = env.unwrapped.road, env.unwrapped.vehicle
    ahead, _ = road.neighbour_vehicles(ego)  # the vehicle ahead in the ego's lane, if any
    gap = ego.lane_distance_to(ahead) if ahead is not None else float("inf")
    headway = max(gap, 0.0) / max(float(ego.speed), 1.0)  # inf with no car ahead: clipped to 10 s
    return {"headway": headway, "collide": bool(info["crashed"]), "fast": float(info["speed"]) >= 25.0}


def make_env() -> Any:
    """highway-fast-v0 with follow.ra's reward, inputs clipped, rewards scaled by the proven factor."""
    import gymnasium
    import highway_env  # noqa: F401  (registers highway-fast-v0)

    from rac.learning.wrappers import RewardAutomatonWrapper

    return RewardAutomatonWrapper(gymnasium.make("highway-fast-v0"), HERE / "follow.ra", inputs,
                                  clip=True, scale="proven")


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--timesteps", type=int, default=4000, help="PPO's training env steps (default 4000)")
    parser.add_argument("--episodes", type=int, default=10, help="greedy evaluation episodes (default 10)")
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--log", type=Path, default=None, help="also write SB3's log (CSV, TensorBoard) here")
    args = parser.parse_args(argv)

    import torch
    from stable_baselines3 import PPO
    from stable_baselines3.common.logger import configure

    from rac.learning.sb3 import RacCallback

    torch.set_num_threads(1)
    env = make_env()
    print(f"reward scale: {env.scale:g} (proved from follow.ra); one step = one sample of "
          f"{env.automaton.period:g} s", flush=True)
    agent = PPO("MlpPolicy", env, n_steps=256, batch_size=64, n_epochs=5, seed=args.seed, device="cpu", verbose=0)
    formats = ["stdout"] + (["csv", "tensorboard"] if args.log is not None else [])
    agent.set_logger(configure(str(args.log) if args.log is not None else None, formats))
    agent.learn(args.timesteps, callback=RacCallback())

    locations: Counter[str] = Counter()
    crashes, returns, clipped = 0, 0.0, 0
    for episode in range(args.episodes):
        obs, info = env.reset(seed=10_000 + episode)
        done = False
        while not done:
            action, _ = agent.predict(obs, deterministic=True)
            obs, reward, terminated, truncated, info = env.step(action)
            locations[info["rac"]["location"]] += 1
            clipped += sum(info["rac"]["clipped"].values())
            returns += float(reward)
            done = terminated or truncated
        crashes += bool(info["crashed"])
    steps = sum(locations.values())
    shares = ", ".join(f"{name} {count / steps:.0%}" for name, count in sorted(locations.items()))
    print(f"greedy policy, {args.episodes} episodes: {steps} steps ({shares}); {crashes} crashed; "
          f"mean return {returns / args.episodes:.3f} (scaled); {clipped} headways clipped to 10 s")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
