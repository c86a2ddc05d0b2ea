"""MaskablePPO on the 45-action tutorial scene, with and without the runtime shield (issue 20):
``python benchmarks/masked_ppo.py [--quick] [--timesteps N] [--output FILE]``.

The scene is :func:`rac.model.scenes.build_tutorial` (two lanes, a slower car ahead, a faster one
coming up the left lane, a parked van) with :data:`rac.model.scenes.TUTORIAL_45`: 45 actions (9
jerks x 5 turning rates) every 0.2 s, 4 s episodes (20 decisions). Its exhaustive shield cannot be
had for a whole episode (the exploration grows ~37x per decision); the benchmark computes it for the
first decisions it can (``--table-horizon``) and trains sb3-contrib's MaskablePPO from the same
seed, over whole episodes, on :class:`rac.learning.gym.ScenarioEnv` three ways:

  runtime shield   the table where it applies, the runtime shield (rac.engine.lookahead) elsewhere
  table only       the table, then nothing (lookahead=None): past its horizon every action is
                   allowed (info["shield"] == "none", flagged no_safe_action) — before issue 20 the
                   mask was all False there, and MaskablePPO sampled uniformly from it
  no shield        every action allowed

For each: the fraction of training steps per guarantee their mask carried (``info["shield"]``),
the steps whose runtime shield ran out of its budget, the collisions during training (steps, and
episodes with one), episodes off the road and at the goal, and the greedy (deterministic, masked)
run after training. Needs the ``rl`` extra: torch's CPU build (``pip install torch==2.13.0 --index-url
https://download.pytorch.org/whl/cpu``), then ``pip install '.[rl]'``.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from collections import Counter
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

HERE = Path(__file__).resolve().parent
REPOSITORY = HERE.parent
DEFAULT_OUTPUT = HERE / "results" / "masked_ppo.md"

try:  # benchmark the installed rac; in a checkout without it, the checkout's src/
    import rac
except ImportError:
    sys.path.insert(0, str(REPOSITORY / "src"))
    import rac

#: The automaton trained on the scene: safety over progress (examples/paper/model.ra's shape).
AUTOMATON = """\
// The tutorial scene with 45 actions every 0.2 s: benchmarks/masked_ppo.py (issue 20).
automaton Tutorial {{
    input isClose : bool  // an obstacle is nearer than 3 * collision_distance
    input prog    : bool  // the distance to the goal shrank since the last sample
    input collide : bool
    input atGoal  : bool
    assume collide imply isClose

    reward sa, pr
    priority sa > pr
    objective 10 * sa + pr

    sample every 0.1
    horizon {horizon}

    initial location Normal {{ sa' == 1;  pr' == 1 }}
    location Stalled        {{ sa' == 1;  pr' == -1 }}
    location Unsafe         {{ sa' == -1; pr' == 0 }}

    edge * -> Unsafe  when isClose          do sa = sa - 100
    edge * -> Stalled when !isClose && !prog
    edge * -> Normal  when !isClose && prog
    edge Unsafe -> Unsafe when collide      do sa = sa - 100

    at end when atGoal do pr = pr + 100

    model {{
{model}
    }}
}}
"""
BINDINGS = ("bind isClose = mindist() < 3 * collision_distance", "bind prog = dist_goal() < prev(dist_goal())",
            "bind collide = collide()", "bind atGoal = goal()")
HORIZON = 4  # s: 40 samples, 20 decisions
RUNS = ("runtime shield", "table only", "no shield")


def write_model(folder: Path, horizon: float = HORIZON) -> Path:
    """The tutorial scene and the automaton over it in ``folder``; the ``.ra`` file's path."""
    from rac.model.scenes import TUTORIAL_45, write_scene

    write_scene("tutorial", folder / "tutorial.xml")
    items = ['scenario "tutorial.xml"', *TUTORIAL_45, *BINDINGS]
    path = folder / "tutorial.ra"
    path.write_text(AUTOMATON.format(horizon=f"{horizon:g}", model="\n".join(f"        {item}" for item in items)),
                    encoding="utf-8")
    return path


@dataclass
class Tally:
    """What one training run met, step by step (from each step's ``info``)."""

    steps: int = 0
    episodes: int = 0
    guarantees: Counter[str] = field(default_factory=Counter)
    timeouts: int = 0
    collision_steps: int = 0
    collided_episodes: int = 0
    offroad_episodes: int = 0
    goal_episodes: int = 0
    _collided: bool = False
    _offroad: bool = False

    def add(self, info: dict[str, Any], done: bool) -> None:
        self.steps += 1
        kind = info["shield"]
        self.guarantees["lookahead" if kind.startswith("lookahead") else kind] += 1
        if info["shield_short"]:
            self.guarantees["lookahead, short"] += 1
        self.timeouts += bool(info["shield_timeout"])
        self.collision_steps += bool(info["collided"])
        self._collided |= bool(info["collided"])
        self._offroad |= bool(info["offroad"])
        if done:
            self.episodes += 1
            self.collided_episodes += self._collided
            self.offroad_episodes += self._offroad
            self.goal_episodes += bool(info["goal"])
            self._collided = self._offroad = False


def share(count: int, total: int) -> str:
    return f"{100 * count / total:.1f} %" if total else "-"


def train(model: Path, run: str, table: Any, timesteps: int, depth: int, seconds: float, seed: int,
          quick: bool) -> dict[str, Any]:
    """One MaskablePPO run of ``timesteps`` steps (rounded up to whole rollouts); its tally, time and
    greedy run."""
    import torch
    from sb3_contrib import MaskablePPO
    from stable_baselines3.common.callbacks import BaseCallback

    from rac.engine.lookahead import LookaheadSettings
    from rac.learning.gym import ScenarioEnv

    torch.set_num_threads(1)
    # a wall-clock budget, as docs/verify.md reports this benchmark (not the default node budget)
    settings = LookaheadSettings(depth=depth, seconds=seconds, nodes=None)
    shield, lookahead = {"runtime shield": (table, settings), "table only": (table, None),
                         "no shield": (None, None)}[run]
    env = ScenarioEnv(model, shield=shield, lookahead=lookahead)
    tally = Tally()

    class Record(BaseCallback):
        def _on_step(self) -> bool:
            for info, done in zip(self.locals["infos"], self.locals["dones"]):
                tally.add(info, bool(done))
            return True

    hyper = dict(n_steps=64, batch_size=32, n_epochs=2) if quick else dict(n_steps=1000, batch_size=100, n_epochs=5)
    agent = MaskablePPO("MlpPolicy", env, seed=seed, verbose=0, gamma=0.99, **hyper)
    start = time.perf_counter()
    agent.learn(total_timesteps=timesteps, callback=Record())
    elapsed = time.perf_counter() - start
    # the greedy run after training, under the same masks
    obs, _ = env.reset(seed=seed)
    greedy = {"collided": False, "offroad": False, "goal": False}
    done = False
    while not done:
        action, _ = agent.predict(obs, action_masks=env.action_masks(), deterministic=True)
        obs, _, terminated, truncated, info = env.step(int(action))
        for key in greedy:
            greedy[key] |= bool(info[key])
        done = terminated or truncated
        last_time = info["time"]
    return {"run": run, "tally": tally, "seconds": elapsed, "greedy": greedy, "greedy_time": last_time}


def greedy_text(result: dict[str, Any]) -> str:
    greedy = result["greedy"]
    if greedy["collided"] or greedy["offroad"]:
        what = " and ".join(word for word, key in (("collides", "collided"), ("leaves the road", "offroad"))
                            if greedy[key])
        return f"{what} (ends at {result['greedy_time']:.1f} s)"
    return "safe, at the goal" if greedy["goal"] else "safe to the horizon"


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--quick", action="store_true", help="a smoke run: 128 steps per run, a small table")
    parser.add_argument("--timesteps", type=int, default=None, help="training steps per run (default 10000)")
    parser.add_argument("--depth", type=int, default=10, help="the runtime shield's depth (decisions)")
    parser.add_argument("--seconds", type=float, default=0.1, help="the runtime shield's budget per decision")
    parser.add_argument("--table-horizon", type=int, default=None,
                        help="the exhaustive shield's horizon in samples (default 8; --quick 4)")
    parser.add_argument("--max-states", type=int, default=6_000_000,
                        help="the state budget of the exhaustive shield over the whole episode")
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--output", type=Path, default=DEFAULT_OUTPUT)
    args = parser.parse_args(argv)
    try:
        import sb3_contrib  # noqa: F401
    except ImportError:
        print("benchmarks/masked_ppo.py needs sb3-contrib and torch: pip install torch==2.13.0, then "
              "pip install '.[rl]'", file=sys.stderr)
        return 2
    from rac.compiler import compile_file
    from rac.engine.budget import BudgetExceeded
    from rac.engine.shield import synthesise

    timesteps = args.timesteps if args.timesteps is not None else (128 if args.quick else 10_000)
    table_horizon = args.table_horizon if args.table_horizon is not None else (4 if args.quick else 8)
    with tempfile.TemporaryDirectory(prefix="rac-masked-ppo-") as folder:
        model = write_model(Path(folder))
        result = compile_file(model)
        if not result.ok or result.model_data is None or result.automaton is None:
            print("\n".join(d.message for d in result.diagnostics), file=sys.stderr)
            return 1
        data = result.model_data
        samples = result.automaton.steps
        notes = []
        # the exhaustive shield over the whole episode: out of reach
        start = time.perf_counter()
        whole_budget = 100_000 if args.quick else args.max_states
        try:
            synthesise(data, samples, max_states=whole_budget)
            notes.append(f"the exhaustive shield over the whole {samples}-sample episode was computed")
        except BudgetExceeded as exc:
            notes.append(f"exhaustive shield over the whole episode ({samples} samples): {exc} "
                         f"({time.perf_counter() - start:.1f} s)")
        start = time.perf_counter()
        shield, table = synthesise(data, table_horizon, max_states=args.max_states)
        notes.append(f"exhaustive shield up to sample {table_horizon} ({table_horizon * float(data.period):g} s): "
                     f"{shield.graph.n_states:,} states, {table.states.shape[0]:,} decision states, "
                     f"{time.perf_counter() - start:.1f} s")
        header = [f"rac {rac.__version__}, sb3-contrib MaskablePPO, seed {args.seed}, {timesteps:,} training steps "
                  f"per run (whole episodes of {samples} samples, 45 actions every 0.2 s)",
                  f"runtime shield: depth {args.depth} decisions ({args.depth * 0.2:g} s), budget "
                  f"{args.seconds:g} s per decision"]
        rows = ["| run | steps | episodes | exhaustive | lookahead | of it short of the depth asked | none | "
                "budget ran out | collisions (steps) | episodes with a collision | episodes off the road | "
                "episodes at the goal | training time | greedy run after training |",
                "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---|"]
        print("\n".join(header + [""] + rows), flush=True)
        for run in RUNS:
            out = train(model, run, table, timesteps, args.depth, args.seconds, args.seed, args.quick)
            tally: Tally = out["tally"]
            n, g = tally.steps, tally.guarantees
            row = (f"| {run} | {n:,} | {tally.episodes:,} | {share(g['exhaustive'], n)} | {share(g['lookahead'], n)} "
                   f"| {share(g['lookahead, short'], n)} | {share(g['none'], n)} | {share(tally.timeouts, n)} "
                   f"| {tally.collision_steps:,} | {tally.collided_episodes:,} | {tally.offroad_episodes:,} "
                   f"| {tally.goal_episodes:,} | {out['seconds']:.0f} s | {greedy_text(out)} |")
            rows.append(row)
            print(row, flush=True)
    print()
    for note in notes:
        print(f"note: {note}")
    args.output.parent.mkdir(parents=True, exist_ok=True)
    args.output.write_text("# python benchmarks/masked_ppo.py" + (" --quick" if args.quick else "") + "\n\n"
                           + "\n".join(f"- {line}" for line in header + notes) + "\n\n" + "\n".join(rows) + "\n",
                           encoding="utf-8")
    print(f"\nwritten to {args.output}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
