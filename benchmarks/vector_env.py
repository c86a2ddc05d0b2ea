"""The vector environment's benchmark (issue 21): ``python benchmarks/vector_env.py [--quick] [--output FILE]``.

Automaton samples per CPU-second of :class:`rac.learning.scenario_env.ScenarioEnv` alone (one
Python step per episode, what a SyncVectorEnv of ScenarioEnvs costs per episode) against
:class:`rac.learning.vector.ScenarioVectorEnv` (``gymnasium.make_vec("rac/Scenario-v0", ...)``) with
1, 16, 64 and 256 episodes stepped as one batch. The scene is the tutorial scene of
benchmarks/masked_ppo.py (:func:`rac.model.scenes.build_tutorial`, 45 actions every 0.2 s, 4 s
episodes: 40 samples, 20 steps), random actions, no shield (the shield's cost is its own,
benchmarks/masked_ppo.py), the default observation. A *sample* is one sense period of one episode:
a step of either environment takes ``decide_every`` of them. Goal: 64 episodes at least 20 times
the samples per CPU-second of one ScenarioEnv. Each row runs for a fixed CPU time (``--quick``: shorter).
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np

HERE = Path(__file__).resolve().parent
REPOSITORY = HERE.parent
DEFAULT_OUTPUT = HERE / "results" / "vector_env.md"
SIZES = (1, 16, 64, 256)
GOAL = 20.0  # 64 episodes against one ScenarioEnv

try:  # benchmark the installed rac; in a checkout without it, the checkout's src/
    import rac  # noqa: F401
except ImportError:
    sys.path.insert(0, str(REPOSITORY / "src"))

from masked_ppo import write_model  # noqa: E402  (the same scene and automaton)


def single(model: Any, seconds: float) -> tuple[int, int, float]:
    """(steps, samples, CPU seconds) of one ScenarioEnv with random actions for about ``seconds``."""
    from rac.learning.scenario_env import ScenarioEnv

    env = ScenarioEnv(model)
    env.reset(seed=0)
    steps = samples = 0
    start = time.process_time()
    while time.process_time() - start < seconds:
        before = int(env.episodes.k[0])
        _, _, terminated, truncated, _ = env.step(int(env.np_random.integers(env.action_space.n)))
        steps += 1
        samples += int(env.episodes.k[0]) - before
        if terminated or truncated:
            env.reset()
    return steps, samples, time.process_time() - start


def vector(model: Any, n: int, seconds: float) -> tuple[int, int, float]:
    """(steps, samples, CPU seconds) of a ScenarioVectorEnv of ``n`` episodes, random actions."""
    import gymnasium

    import rac.gym

    envs = gymnasium.make_vec(rac.gym.SCENARIO, num_envs=n, model=model)
    envs.reset(seed=0)
    episodes = envs.unwrapped.episodes  # type: ignore[attr-defined]
    actions = envs.single_action_space.n  # type: ignore[attr-defined]
    rng = np.random.default_rng(0)
    pending = np.zeros(n, dtype=bool)
    steps = samples = 0
    start = time.process_time()
    while time.process_time() - start < seconds:
        before = episodes.k.copy()
        _, _, terminated, truncated, _ = envs.step(rng.integers(actions, size=n))
        steps += 1
        samples += int((episodes.k - before)[~pending].sum())  # restarted episodes took no sample
        pending = terminated | truncated
    return steps, samples, time.process_time() - start


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python benchmarks/vector_env.py", description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="a shorter CPU time per row")
    parser.add_argument("--seconds", type=float, default=None, help="CPU seconds per row (default 3; --quick 0.5)")
    parser.add_argument("--output", type=Path, default=DEFAULT_OUTPUT)
    args = parser.parse_args(argv)
    seconds = args.seconds if args.seconds is not None else (0.5 if args.quick else 3.0)
    from rac.compiler import compile_file

    with tempfile.TemporaryDirectory() as folder:
        model = compile_file(write_model(Path(folder)))  # compiled once: the rows time stepping only
        assert model.ok, [d.message for d in model.diagnostics]
        rows = [("ScenarioEnv", 1, *single(model, seconds))]
        rows += [("ScenarioVectorEnv", n, *vector(model, n, seconds)) for n in SIZES]
    base = rows[0][3] / rows[0][4]
    lines = ["| environment | episodes at once | steps | samples | CPU s | samples per CPU-s | x one ScenarioEnv |",
             "| --- | --- | --- | --- | --- | --- | --- |"]
    ratio = {}
    for name, n, steps, samples, cpu in rows:
        rate = samples / cpu
        if name != "ScenarioEnv":
            ratio[n] = rate / base
        lines.append(f"| {name} | {n} | {steps:,} | {samples:,} | {cpu:.2f} | {rate:,.0f} | {rate / base:.1f} |")
    met = ratio[64] >= GOAL
    lines.append("")
    lines.append(f"64 episodes: {ratio[64]:.1f} x one ScenarioEnv's samples per CPU-second (goal >= {GOAL:g} x): "
                 f"{'met' if met else 'not met'}")
    text = "\n".join(lines)
    print(text)
    args.output.parent.mkdir(parents=True, exist_ok=True)
    args.output.write_text("# python benchmarks/vector_env.py" + (" --quick" if args.quick else "") + "\n\n"
                           + text + "\n", encoding="utf-8")
    print(f"\nwritten to {args.output}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
