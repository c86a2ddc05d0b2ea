"""The learning benchmark (issue 5): ``python benchmarks/learning.py [--quick]``.

Simulated learning episodes per minute on the left-turn intersection (examples/left_turn/model.ra,
the paper's driving automaton as the reward), for an episode of 30 time steps (3 s). Target: at
least 1,000 episodes per minute. Rows:

  episodes, random actions   rac.learning.episodes.EpisodeBatch, 64 episodes stepped together
  Q-learning                 rac.learning.qlearning.learn (episodes, Q-table updates and the greedy
                             evaluation after every batch), 32 episodes per batch
  Q-learning under a shield  the same on examples/paper/model.ra (14 s episodes) under its shield
  ScenarioEnv                rac.learning.gym.ScenarioEnv, one episode at a time (a gymnasium agent's view)

Each row is the best of ``--repeat`` runs (default 3).
"""

from __future__ import annotations

import argparse
import sys
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
REPOSITORY = HERE.parent
LEFT_TURN = REPOSITORY / "examples" / "left_turn" / "model.ra"
PAPER = REPOSITORY / "examples" / "paper" / "model.ra"
TARGET = 1000.0  # episodes per minute

try:  # benchmark the installed rac; in a checkout without it, the checkout's src/
    import rac  # noqa: F401
except ImportError:
    sys.path.insert(0, str(REPOSITORY / "src"))


def _best(run: Callable[[], int], repeat: int) -> tuple[int, float]:
    """(episodes, seconds) of the fastest of ``repeat`` runs."""
    results = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        episodes = run()
        results.append((episodes, time.perf_counter() - t0))
    return max(results, key=lambda r: r[0] / r[1])


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python benchmarks/learning.py", description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="fewer episodes, one run per row")
    parser.add_argument("--repeat", type=int, default=3)
    args = parser.parse_args(argv)
    repeat = 1 if args.quick else args.repeat
    scale = 1 if args.quick else 4

    from rac.compiler import compile_file
    from rac.learning.episodes import EpisodeBatch
    from rac.learning.gym import ScenarioEnv
    from rac.learning.qlearning import learn
    from rac.studies.experiment import _learning_spec, _shield

    left = compile_file(LEFT_TURN)
    paper = compile_file(PAPER)
    rows: list[tuple[str, int, float]] = []

    rng = np.random.default_rng(1)
    batch = EpisodeBatch(left, horizon_samples=30)

    def random_episodes() -> int:
        total = 0
        for _ in range(4 * scale):
            batch.reset(64)
            while not batch.done.all():
                batch.step(rng.integers(0, batch.n_actions, batch.n))
            total += 64
        return total

    rows.append(("episodes, random actions (64 at once), left turn, 30 steps", *_best(random_episodes, repeat)))

    discrete, continuous = _learning_spec(left)

    def q_learning() -> int:
        return learn(EpisodeBatch(left, horizon_samples=30), discrete=discrete, continuous=continuous,
                     episodes=128 * scale, parallel=32, seed=1, stop_after=10**6).episodes

    rows.append(("Q-learning (32 per batch), left turn, 30 steps", *_best(q_learning, repeat)))

    table, _, _ = _shield(paper, paper.automaton.steps, 5_000_000)  # type: ignore[union-attr]
    paper_discrete, paper_continuous = _learning_spec(paper)

    def shielded() -> int:
        return learn(EpisodeBatch(paper), discrete=paper_discrete, continuous=paper_continuous, shield=table,
                     episodes=64 * scale, parallel=32, seed=1, stop_after=10**6).episodes

    rows.append(("Q-learning under the shield, examples/paper (14 s, 140 steps)", *_best(shielded, repeat)))

    env = ScenarioEnv(LEFT_TURN, horizon=3)

    def gym_episodes() -> int:
        for _ in range(8 * scale):
            env.reset(seed=1)
            done = False
            while not done:
                _, _, terminated, truncated, _ = env.step(int(rng.integers(env.action_space.n)))
                done = terminated or truncated
        return 8 * scale

    rows.append(("ScenarioEnv, one episode at a time, left turn, 30 steps", *_best(gym_episodes, repeat)))

    print(f"Learning episodes per minute (target >= {TARGET:,.0f} for 30-step episodes)\n")
    print("| case | episodes | seconds | episodes/min | target met |")
    print("| --- | --- | --- | --- | --- |")
    for name, episodes, seconds in rows:
        rate = episodes / seconds * 60
        print(f"| {name} | {episodes:,} | {seconds:.2f} | {rate:,.0f} | {'yes' if rate >= TARGET else 'no'} |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
