"""The learning benchmark (issues 5, 11 and 23): ``python benchmarks/learning.py [--quick]``.

Four tables:

1. **Samples per second against batch size** (issues 11 and 23): :class:`rac.learning.episodes.EpisodeBatch`
   on examples/paper/model.ra (the experiment's model: 140 samples an episode, 3 obstacles, 20
   Euler sub-steps a sample), random actions, 1 to 1024 episodes stepped together, with the
   bindings, reward and goal walked by the evaluator (``compiled=False``, before issue 23) and
   compiled (:mod:`rac.engine.compiled`, the default), both without the memo of steps taken (every
   sample calls the model). A *sample* is one sense period of every
   episode of the batch; episode-samples per second is what learning gets done.
2. **Learning episodes per minute** (issue 5; target at least 1,000 for 30-step episodes):

     episodes, random actions   EpisodeBatch on the left turn (examples/left_turn/model.ra), 64 at once
     Q-learning                 rac.learning.qlearning.learn (episodes, Q-table updates and the greedy
                                evaluation after every batch), 32 episodes per batch
     Q-learning under a shield  the same on examples/paper/model.ra (14 s episodes) under its shield
                                (rac.engine.shield.synthesise)
     ScenarioEnv                rac.learning.gym.ScenarioEnv, one episode at a time (a gymnasium agent's view)

3. **Commands** (issue 11): ``rac experiment examples/paper/model.ra --episodes 2000 --bins
   4,4,2,0.4`` as docs/learning.md runs it (goal: under 60 s; ``--quick``: 50 episodes, seed 1), and the
   replay of a learned run on the paper's model (``StrategyRun.samples``, what every ``A[] p under
   S`` query on a learned ``S`` does).
4. **The memo of steps taken** (issue 23): the CPU time of ``rac experiment``'s learning with its
   defaults (``run_experiment``, in this process) without and with
   ``EpisodeBatch(memo=...)``, checked to give the same results (``--quick``: seed 1, 50 episodes).

Each row is the best of ``--repeat`` runs (default 3; the experiment runs once). ``--quick``: one
run per row, fewer episodes (tests/benchmarks/test_benchmarks_quick.py runs it so).
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
REPOSITORY = HERE.parent
LEFT_TURN = REPOSITORY / "examples" / "left_turn" / "model.ra"
PAPER = REPOSITORY / "examples" / "paper" / "model.ra"
TARGET = 1000.0  # episodes per minute
EXPERIMENT_GOAL = 60.0  # seconds
BATCH_SIZES = (1, 4, 16, 64, 256, 1024)

try:  # benchmark the installed rac; in a checkout without it, the checkout's src/
    import rac  # noqa: F401
except ImportError:
    sys.path.insert(0, str(REPOSITORY / "src"))


def _best(run: Callable[[], int], repeat: int) -> tuple[int, float]:
    """(count, seconds) of the fastest of ``repeat`` runs."""
    results = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        count = run()
        results.append((count, time.perf_counter() - t0))
    return max(results, key=lambda r: r[0] / r[1])


def samples_by_batch_size(repeat: int, quick: bool) -> list[tuple[int, dict[bool, tuple[int, float]]]]:
    """Per batch size: (samples, seconds) of random episodes of the paper's model, walked
    (``compiled=False``) and compiled, each after one warm-up episode (the model keeps cos/sin and
    sub-step trajectories it has computed). The same actions for both."""
    from rac.compiler import compile_file
    from rac.learning.episodes import EpisodeBatch

    result = compile_file(PAPER)
    # without the memo of steps taken: every run repeats the same actions, which it would recall
    batches = {compiled: EpisodeBatch(result, compiled=compiled, memo=False) for compiled in (False, True)}

    def episodes(batch: EpisodeBatch, n: int, count: int) -> int:
        rng = np.random.default_rng(1)
        samples = 0
        for _ in range(count):
            batch.reset(n)
            while not batch.done.all():
                before = int(batch.k.max())
                batch.step(rng.integers(0, batch.n_actions, batch.n))
                samples += int(batch.k.max()) - before
        return samples

    rows = []
    for n in BATCH_SIZES:
        count = 1 if quick or n >= 256 else 2
        timed = {}
        for compiled, batch in batches.items():
            episodes(batch, n, 1)
            timed[compiled] = _best(lambda batch=batch, n=n, count=count: episodes(batch, n, count), repeat)
        rows.append((n, timed))
    return rows


def learning_spec(result) -> tuple[list[str], list[str]]:  # type: ignore[no-untyped-def]
    """The observation lists (as text) of the file's first learning query, or the paper's defaults
    (as rac experiment chooses them)."""
    from rac.ir import query as iq

    automaton = result.automaton
    for decl in automaton.queries:
        if isinstance(decl.query, iq.LearnStrategy):
            count = len(decl.query.discrete)
            return list(decl.query.labels[:count]), list(decl.query.labels[count:])
    return [f"{automaton.name}.location"], ["x", "y", "v", "head"]


def paper_shield(paper):  # type: ignore[no-untyped-def]
    """The paper model's safety shield table (:func:`rac.engine.shield.synthesise`, as rac experiment)."""
    from rac.engine.shield import synthesise

    return synthesise(paper.model_data, paper.automaton.steps, max_states=5_000_000)[1]


def episodes_per_minute(repeat: int, scale: int) -> list[tuple[str, int, float]]:
    """The issue-5 rows: (case, episodes, seconds)."""
    from rac.compiler import compile_file
    from rac.learning.episodes import EpisodeBatch
    from rac.learning.gym import ScenarioEnv
    from rac.learning.qlearning import learn
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
    discrete, continuous = learning_spec(left)

    def q_learning() -> int:
        return learn(EpisodeBatch(left, horizon_samples=30), discrete=discrete, continuous=continuous,
                     episodes=128 * scale, parallel=32, seed=1, stop_after=10**6).episodes

    rows.append(("Q-learning (32 per batch), left turn, 30 steps", *_best(q_learning, repeat)))
    table = paper_shield(paper)
    paper_discrete, paper_continuous = learning_spec(paper)

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
    return rows


def replay_seconds(repeat: int) -> float:
    """The replay of a learned strategy's run on the paper's model (140 samples, the ground truth
    in 100 RK4 steps a sample): the fastest of ``repeat``."""
    from rac.compiler import compile_file
    from rac.learning.episodes import EpisodeBatch
    from rac.learning.qlearning import learn, run_strategy

    paper = compile_file(PAPER)
    assert paper.model_data is not None and paper.automaton is not None
    table = paper_shield(paper)
    discrete, continuous = learning_spec(paper)
    outcome = learn(EpisodeBatch(paper), discrete=discrete, continuous=continuous, shield=table, episodes=64,
                    parallel=16, seed=1, bins=[4, 4, 2, 0.4])
    run = run_strategy(EpisodeBatch(paper, goal=None), outcome.strategy, shield=table)
    best = float("inf")
    for _ in range(repeat):
        t0 = time.perf_counter()
        run.samples(paper.model_data)
        best = min(best, time.perf_counter() - t0)
    return best


def experiment_cpu(quick: bool) -> dict[bool, float]:
    """CPU seconds of ``rac experiment examples/paper/model.ra``'s learning (its defaults: seeds 1-5,
    500 episodes; ``quick``: seed 1, 50 episodes) without and with the memo of steps taken
    (``run_experiment(..., memo=...)``), in this process: the same results, the time it saves."""
    from rac.compiler import compile_file
    from rac.studies.experiment import run_experiment

    paper = compile_file(PAPER)
    options: dict = {"seeds": (1,), "episodes": 50, "evaluation_runs": 10} if quick else {}
    seconds, tables = {}, {}
    for memo in (False, True):
        t0 = time.process_time()
        report = run_experiment(paper, memo=memo, **options)
        seconds[memo] = time.process_time() - t0
        tables[memo] = [(r.combination, r.seed, r.first_success_episode, r.greedy_return, r.returns.tolist())
                        for r in report["records"]]
    if tables[False] != tables[True]:
        raise AssertionError("the memo changed the experiment's results")
    return seconds


def experiment_seconds(episodes: int, more: tuple[str, ...] = ()) -> float:
    """``rac experiment examples/paper/model.ra --episodes N --bins 4,4,2,0.4 [more]``, in a fresh process."""
    with tempfile.TemporaryDirectory() as out:
        command = [sys.executable, "-m", "rac", "experiment", str(PAPER), "--episodes", str(episodes),
                   "--bins", "4,4,2,0.4", *more, "--out", out, "-q"]
        t0 = time.perf_counter()
        subprocess.run(command, check=True, stdout=subprocess.DEVNULL, env=dict(os.environ))
        return time.perf_counter() - t0


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python benchmarks/learning.py", description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="fewer episodes, one run per row")
    parser.add_argument("--repeat", type=int, default=3)
    args = parser.parse_args(argv)
    repeat = 1 if args.quick else args.repeat
    scale = 1 if args.quick else 4

    print("Samples per second against batch size: random episodes of examples/paper/model.ra, the bindings "
          "walked by the evaluator (before issue 23) and compiled (rac.engine.compiled)\n")
    print("| episodes in the batch | samples | ms per sample, walked | ms per sample, compiled | samples/s, walked | "
          "samples/s, compiled | episode-samples/s, compiled | speed-up |")
    print("| --- | --- | --- | --- | --- | --- | --- | --- |")
    for n, timed in samples_by_batch_size(repeat, args.quick):
        (walked, walked_s), (samples, seconds) = timed[False], timed[True]
        before, after = walked / walked_s, samples / seconds
        print(f"| {n:,} | {samples:,} | {1e3 / before:.3f} | {1e3 / after:.3f} | {before:,.0f} | {after:,.0f} | "
              f"{n * after:,.0f} | {after / before:.2f}x |")

    print(f"\nLearning episodes per minute (target >= {TARGET:,.0f} for 30-step episodes)\n")
    print("| case | episodes | seconds | episodes/min | target met |")
    print("| --- | --- | --- | --- | --- |")
    for name, episodes, seconds in episodes_per_minute(repeat, scale):
        rate = episodes / seconds * 60
        print(f"| {name} | {episodes:,} | {seconds:.2f} | {rate:,.0f} | {'yes' if rate >= TARGET else 'no'} |")

    episodes = 50 if args.quick else 2000
    more = ("--seeds", "1", "--runs", "10") if args.quick else ()  # a smoke run: one seed, 10 evaluation runs
    replay = replay_seconds(repeat)
    experiment = experiment_seconds(episodes, more)
    print(f"\nCommands on examples/paper/model.ra (goal: the experiment under {EXPERIMENT_GOAL:g} s)\n")
    print("| command | seconds | goal met |")
    print("| --- | --- | --- |")
    print(f"| rac experiment examples/paper/model.ra --episodes {episodes} --bins 4,4,2,0.4{' '.join(('',) + more)} | "
          f"{experiment:.1f} | "
          f"{'yes' if experiment < EXPERIMENT_GOAL else 'no'} |")
    print(f"| replay of a learned run (StrategyRun.samples, 140 samples) | {replay:.3f} | |")

    cpu = experiment_cpu(args.quick)
    what = "seed 1, 50 episodes" if args.quick else "its defaults: seeds 1-5, 500 episodes"
    print(f"\nThe memo of steps taken (EpisodeBatch(memo=...)): run_experiment on examples/paper/model.ra ({what}), "
          "CPU seconds in this process, the same results\n")
    print("| memo | CPU seconds | saved |")
    print("| --- | --- | --- |")
    print(f"| off | {cpu[False]:.2f} | |")
    print(f"| on | {cpu[True]:.2f} | {100 * (1 - cpu[True] / cpu[False]):.0f} % |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
