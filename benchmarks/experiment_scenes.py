"""The paper's experiment on the built scenes (issue 23): ``python benchmarks/experiment_scenes.py [--quick]``.

``rac experiment`` (shield + reward automaton, shield + reward function, automaton alone, reward
function alone; seeds 1-5, 500 episodes) on the highway, T-junction and overtaking scenes of
:mod:`rac.model.scenes`, each written as CommonRoad XML and given examples/paper/model.ra's
automaton with the scene's ``model`` block as ``benchmarks/queries.py`` writes it (a decision
every 2 s, 3 x 3 actions, a 10 s horizon; the overtaking's horizon is its goal window's end,
12 s). One row per scene: the episodes until the first safe goal per combination (mean over the
seeds that got there, and how many never did), how many SS&RA seeds came within 5 % of the exact
optimum, whether the paper's ordering holds (RF needs at least 10x SS&RA's episodes or never gets
there), and the command's user CPU.

The table goes to ``benchmarks/results/experiment_scenes.md`` (or ``--output``); docs/learning.md
quotes it. ``--explore goal``: the experiment's model-steered exploration (give it its own ``--output``,
not to overwrite the uniform table), with a column of what such exploring can expect. ``--quick``: the
highway alone, seed 1, 40 episodes (tests/benchmarks/test_benchmarks_quick.py runs it so).
"""

from __future__ import annotations

import argparse
import json
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from statistics import mean, pstdev

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
import queries  # noqa: E402 - the scenes' files as the query benchmark writes them

from rac.studies.experiment import EXPLORE  # noqa: E402 - the choices of rac experiment --explore

DEFAULT_OUTPUT = HERE / "results" / "experiment_scenes.md"
SCENES = ("highway", "t_junction", "overtaking")
#: The overtaking's goal window ends at 12 s (rac.model.scenes.build_overtaking): a longer horizon
#: could not reach the goal either, a shorter one cuts the window.
HORIZONS = {"overtaking": 12}
COMBINATIONS = ("SS&RA", "SS&RF", "RA", "RF")


def children_cpu() -> float:
    """User CPU seconds of the finished children so far."""
    return resource.getrusage(resource.RUSAGE_CHILDREN).ru_utime


def first_goal(runs: list[dict], combination: str) -> str:
    """``mean ± sd`` of the episodes until the first safe goal, and the seeds that never got there."""
    mine = [run for run in runs if run["combination"] == combination]
    got = [int(run["first_success_episode"]) for run in mine if run["first_success_episode"] is not None]
    never = len(mine) - len(got)
    if not got:
        return f"never ({never} of {len(mine)})"
    text = f"{mean(got):.3g} ± {pstdev(got):.2g}"
    return text + (f" ({never} of {len(mine)} never)" if never else "")


def ordering(runs: list[dict]) -> str:
    """Whether RF needs at least 10x SS&RA's mean episodes (a seed that never got there counts as
    its budget plus one), said plainly."""
    def episodes(combination: str) -> list[int]:
        return [int(run["first_success_episode"]) if run["first_success_episode"] is not None
                else int(run["episodes"]) + 1 for run in runs if run["combination"] == combination]

    if all(run["first_success_episode"] is None for run in runs if run["combination"] == "SS&RA"):
        return "cannot show: SS&RA never reached the goal"
    ratio = mean(episodes("RF")) / mean(episodes("SS&RA"))
    return f"{'holds' if ratio >= 10 else 'does not hold'} (RF / SS&RA {ratio:.3g}x)"


def within(runs: list[dict], optimum: dict | None) -> str:
    """How many SS&RA seeds came within 5 % of the exact optimum, and the optimum."""
    mine = [run for run in runs if run["combination"] == "SS&RA"]
    close = [run for run in mine if run.get("shortfall") is not None and float(run["shortfall"]) <= 0.05]
    if optimum is None:
        return f"{len(close)} of {len(mine)}"
    reaches = "" if optimum.get("reaches_goal_safely") else ", a run that does not reach the goal"
    return f"{len(close)} of {len(mine)} (optimum {optimum['value']:.4g}{reaches})"


def uniform(optimum: dict | None, key: str = "uniform_success") -> str:
    """The episodes a uniformly random explorer under the shield needs on average until its first safe
    goal (exact, from the optimum's graph): what SS&RA's first safe goal compares with; with ``key``
    ``steered_success``, an explorer steered as ``--explore goal`` steers."""
    if optimum is None or optimum.get(key) is None:
        return "—"
    chance = float(optimum[key])
    return f"{1 / chance:.3g} ({100 * chance:.3g} % of episodes)" if chance > 0 else "never"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--quick", action="store_true", help="the highway alone, seed 1, 40 episodes")
    parser.add_argument("--output", type=Path, default=DEFAULT_OUTPUT, help="where the markdown table goes")
    parser.add_argument("--explore", choices=tuple(EXPLORE), default="uniform",
                        help="rac experiment's --explore (default uniform)")
    args = parser.parse_args()
    scenes = ("highway",) if args.quick else SCENES
    extra = ["--seeds", "1", "--episodes", "40", "--runs", "10"] if args.quick else []
    extra += ["--explore", args.explore]
    rows = []
    queries.HORIZONS.update(HORIZONS)
    with tempfile.TemporaryDirectory(prefix="rac-experiment-scenes-") as scratch:
        folder = Path(scratch)
        for scene in scenes:
            xml = folder / f"{scene}.xml"
            subprocess.run([sys.executable, "-m", "rac.model.scenes", scene, str(xml)], check=True,
                           capture_output=True)
            source = folder / f"{scene}.ra"
            source.write_text(queries.scene_source(scene), encoding="utf-8")
            out = folder / f"{scene}.out"
            before, start = children_cpu(), time.perf_counter()
            done = subprocess.run([sys.executable, "-m", "rac", "experiment", str(source), "-o", str(out), "-q",
                                   *extra], capture_output=True, text=True)
            cpu, wall = children_cpu() - before, time.perf_counter() - start
            # exit 1 with the files written: no run the shield allows reaches the goal (the overtaking); the
            # table shows it as a row, as rac experiment does
            if done.returncode not in (0, 1) or not (out / "results.json").exists():
                raise SystemExit(f"rac experiment on {scene} failed (exit {done.returncode}):\n{done.stderr}")
            report = json.loads((out / "results.json").read_text(encoding="utf-8"))
            runs = report["runs"]
            optimum = (report.get("optima") or {}).get("SS&RA")
            steered = [uniform(optimum, "steered_success")] if args.explore != "uniform" else []
            rows.append([queries.NAMES[scene], *(first_goal(runs, c) for c in COMBINATIONS), uniform(optimum), *steered,
                         within(runs, optimum), ordering(runs), f"{cpu:.1f}", f"{wall:.1f}"])
            print(f"{scene}: {wall:.1f} s", file=sys.stderr)
    header = ["scene", *(f"{c}: first safe goal" for c in COMBINATIONS),
              "uniform exploration under the shield: first safe goal (exact mean)",
              *([f"--explore {args.explore} under the shield: first safe goal (exact mean)"]
                if args.explore != "uniform" else []),
              "SS&RA within 5 % of the optimum",
              "ordering (RF >= 10x SS&RA)", "user CPU (s)", "wall (s)"]
    lines = ["| " + " | ".join(header) + " |", "| " + " | ".join("---" for _ in header) + " |",
             *("| " + " | ".join(row) + " |" for row in rows)]
    mode = "--quick: highway, seed 1, 40 episodes" if args.quick else "seeds 1-5, 500 episodes"
    flags = (" --quick" if args.quick else "") + (f" --explore {args.explore}" if args.explore != "uniform" else "")
    text = (f"`python benchmarks/experiment_scenes.py{flags}` "
            f"({time.strftime('%Y-%m-%d')}; {mode})\n\n" + "\n".join(lines) + "\n")
    args.output.parent.mkdir(parents=True, exist_ok=True)
    args.output.write_text(text, encoding="utf-8")
    print(text)


if __name__ == "__main__":
    main()
