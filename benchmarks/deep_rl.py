"""Deep RL on built scenes, with and without the safety shield and the reward automaton (issue 21):
``python benchmarks/deep_rl.py [--quick] [--seeds 1 2 3] [--timesteps N] [--jobs 2] [--output FILE]``.

Runs ``examples/deep_rl/train.py``'s two configurations — MaskablePPO under the runtime shield on
driving.ra's automaton (scaled to [-1, 1] per sample) and plain PPO without a shield on the paper's
weighted reward (Eq. 9) — from each seed, each in a process of its own (``--jobs`` at a time, one
torch thread each), and writes one row per configuration and seed: the env steps to the first safe
goal (the first training episode at the goal without a collision), the collisions during training
(steps, and episodes with one), the success (goal without a collision) of the greedy policy over
``--eval-episodes`` episodes on the held-out scenes, and the CPU and wall time. Needs the ``rl``
extra: ``pip install torch==2.13.0`` (the CPU build on this machine's disk), then ``pip install '.[rl]'``.
"""

from __future__ import annotations

import argparse
import dataclasses
import datetime
import sys
import tempfile
import time
from collections.abc import Sequence
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path
from statistics import mean
from typing import TYPE_CHECKING

HERE = Path(__file__).resolve().parent
REPOSITORY = HERE.parent
EXAMPLE = REPOSITORY / "examples" / "deep_rl"
DEFAULT_OUTPUT = HERE / "results" / "deep_rl.md"

try:  # benchmark the installed rac; in a checkout without it, the checkout's src/
    import rac
except ImportError:
    sys.path.insert(0, str(REPOSITORY / "src"))
    import rac
sys.path.insert(0, str(EXAMPLE))  # the example's train.py owns the configurations and the training
import train  # noqa: E402

if TYPE_CHECKING:
    from train import Result


def run_one(config: str, seed: int, settings: train.Settings) -> Result:
    """One configuration from one seed, in a folder of its own (the worker processes' entry point)."""
    with tempfile.TemporaryDirectory(prefix="rac-deep-rl-") as folder:
        return train.train_and_evaluate(config, seed, settings, Path(folder))


def row(result: Result) -> str:
    """The table row of ``result``."""
    tally = result.tally
    first = f"{tally.first_safe_goal:,}" if tally.first_safe_goal is not None else "never"
    return (f"| {result.config} | {result.seed} | {first} | {tally.collision_steps:,} / {tally.collided_episodes:,} "
            f"| {tally.episodes:,} | {result.eval_success}/{result.eval_episodes} | {result.eval_collided} "
            f"| {result.cpu_seconds:.0f} s | {result.wall_seconds:.0f} s |")


def mean_row(config: str, results: Sequence[Result]) -> str:
    """The row of ``config``'s means over its seeds (steps to the first safe goal over the seeds that had one)."""
    firsts = [r.tally.first_safe_goal for r in results if r.tally.first_safe_goal is not None]
    first = "never"
    if firsts:
        missing = len(firsts) < len(results)
        first = f"{mean(firsts):,.0f}" + (f" ({len(firsts)} of {len(results)} seeds)" if missing else "")
    success = mean(100 * r.eval_success / r.eval_episodes for r in results)
    return (f"| **{config}**, mean | | {first} | {mean(r.tally.collision_steps for r in results):,.0f} / "
            f"{mean(r.tally.collided_episodes for r in results):,.0f} | {mean(r.tally.episodes for r in results):,.0f} "
            f"| {success:.0f} % | {mean(r.eval_collided for r in results):.1f} "
            f"| {mean(r.cpu_seconds for r in results):.0f} s | {mean(r.wall_seconds for r in results):.0f} s |")


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--quick", action="store_true",
                        help="a smoke run: 400 steps per run, 5 evaluation episodes, seed 1 only")
    parser.add_argument("--seeds", type=int, nargs="+", default=None, help="default 1 2 3 (--quick: 1)")
    parser.add_argument("--timesteps", type=int, default=None, help="training env steps per run (default 6000)")
    parser.add_argument("--eval-episodes", type=int, default=None, help="evaluation episodes per run (default 100)")
    parser.add_argument("--jobs", type=int, default=2, help="runs at a time, each a process with one torch thread")
    parser.add_argument("--output", type=Path, default=DEFAULT_OUTPUT)
    args = parser.parse_args(argv)
    if args.seeds is None:
        args.seeds = [1] if args.quick else [1, 2, 3]
    try:
        import sb3_contrib  # noqa: F401
    except ImportError:
        print("benchmarks/deep_rl.py needs sb3-contrib and torch: pip install torch==2.13.0, then "
              "pip install '.[rl]'", file=sys.stderr)
        return 2
    settings = train.QUICK if args.quick else train.Settings()
    if args.timesteps is not None:
        settings = dataclasses.replace(settings, timesteps=args.timesteps)
    if args.eval_episodes is not None:
        settings = dataclasses.replace(settings, eval_episodes=args.eval_episodes)
    timesteps, eval_episodes = settings.timesteps, settings.eval_episodes
    runs = [(config, seed) for seed in args.seeds for config in train.CONFIGS]
    cpu, wall = time.process_time(), time.perf_counter()
    header = [f"rac {rac.__version__}, {datetime.date.today().isoformat()}; {timesteps:,} training env steps per run, "
              f"{eval_episodes} greedy evaluation episodes on the held-out scenes, seeds "
              f"{', '.join(map(str, args.seeds))}, {args.jobs} runs at a time (one torch thread each)",
              f"scenes (rac.model.scenes.scene_set, {' and '.join(train.KINDS)} variants): {settings.train_scenes} to "
              f"train on (variants 0 on), {settings.held_out_scenes} held out (variants {train.HELD_OUT_SEED} on); "
              f"runtime shield: depth {settings.depth} decisions, {settings.nodes} search nodes per decision; PPO: "
              f"{settings.n_envs} envs x {settings.n_steps} steps per rollout, batch {settings.batch_size}, "
              f"{settings.n_epochs} epochs, net 64x64"]
    rows = ["| configuration | seed | env steps to the first safe goal | collisions in training (steps / episodes) "
            "| training episodes | held-out success | held-out episodes with a collision | CPU time | wall time |",
            "|---|---:|---:|---:|---:|---:|---:|---:|---:|"]
    print("\n".join(header + [""] + rows), flush=True)
    with ProcessPoolExecutor(max_workers=args.jobs) as pool:
        futures = [pool.submit(run_one, config, seed, settings) for config, seed in runs]
        results = []
        for future in futures:
            results.append(future.result())
            rows.append(row(results[-1]))
            print(rows[-1], flush=True)
    rows.extend(mean_row(config, [r for r in results if r.config == config]) for config in train.CONFIGS)
    print("\n".join(rows[-len(train.CONFIGS):]))
    # the children's CPU time is in the rows; the parent's own is small
    total = (f"total: {sum(r.cpu_seconds for r in results) + time.process_time() - cpu:.0f} s CPU, "
             f"{time.perf_counter() - wall:.0f} s wall")
    print(total)
    args.output.parent.mkdir(parents=True, exist_ok=True)
    command = "python benchmarks/deep_rl.py" + (" --quick" if args.quick else "")
    args.output.write_text(f"# {command}\n\n" + "\n".join(f"- {line}" for line in [*header, total]) + "\n\n"
                           + "\n".join(rows) + "\n", encoding="utf-8")
    print(f"\nwritten to {args.output}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
