"""``rac sweep``'s benchmark: ``python benchmarks/sweep.py [--quick] [--output FILE]``.

The scenario set: the four scenes rac builds with commonroad-io (``rac.model.scenes``: left_turn,
t_junction, highway, overtaking) and, when ``../shared/scenarios`` lies beside the checkout, its real
CommonRoad files. The template: ``benchmarks/sweep_template.ra`` (Qb, Qc, Qd over a 2 s horizon).
The grid: ``exponent=1,2`` and ``decide_period=0.5,1`` (``--quick``: ``exponent=1`` on the four built
scenes only, a smoke run).

Rows:
  sweep, N workers   the whole sweep on a local cluster of N worker processes (cluster start and
                     stop included), every task run (``force``): seconds, tasks per minute;
  scaling            tasks per minute with 2 workers / with 1;
  rac verify         the same tasks, each instantiated file run by ``python -m rac verify`` in a
                     process of its own, one after the other;
  overhead per task  (the 1-worker sweep's seconds - rac verify's) / tasks: what Dask, the store and
                     the task's child process add to each task.

Prints one table and writes it as markdown to ``benchmarks/results/sweep.md`` (or ``--output``).
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time
from collections.abc import Sequence
from pathlib import Path

HERE = Path(__file__).resolve().parent
REPOSITORY = HERE.parent
TEMPLATE = HERE / "sweep_template.ra"
SHARED = REPOSITORY.parent / "shared" / "scenarios"
DEFAULT_OUTPUT = HERE / "results" / "sweep.md"

try:  # benchmark the installed rac; in a checkout without it, the checkout's src/
    import rac  # noqa: F401
except ImportError:
    sys.path.insert(0, str(REPOSITORY / "src"))

from rac.model.scenes import write_scene  # noqa: E402
from rac.sweep import plan, sweep  # noqa: E402
from rac.sweep.template import instantiate  # noqa: E402


def scenario_folder(folder: Path, shared: bool = True) -> Path:
    """The benchmark's scenarios, written into ``folder`` (``shared``: also ../shared's, when beside)."""
    for name in ("left_turn", "t_junction", "highway", "overtaking"):
        write_scene(name, folder / f"{name}.xml")
    if shared and SHARED.is_dir():
        for path in sorted(SHARED.glob("*.xml")):
            (folder / path.name).write_bytes(path.read_bytes())
    return folder


def timed_sweep(scenarios: Path, sets: list[str], workers: int, out: Path) -> tuple[float, int]:
    started = time.perf_counter()
    rows = sweep(TEMPLATE, [scenarios], sets=sets, workers=workers, out=out, force=True, quiet=True)
    return time.perf_counter() - started, len(rows)


def timed_direct(scenarios: Path, sets: list[str], folder: Path) -> tuple[float, int]:
    """Every task's file, instantiated as the sweep does, through ``python -m rac verify``."""
    tasks = plan(TEMPLATE, [scenarios], sets=sets, out=folder / "unused").specs
    text = TEMPLATE.read_text(encoding="utf-8")
    paths = [str(REPOSITORY / "src"), *filter(None, os.environ.get("PYTHONPATH", "").split(os.pathsep))]
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(paths)}  # no empty entry: that would add the cwd
    started = time.perf_counter()
    for index, spec in enumerate(tasks):
        path = folder / f"task{index}.ra"
        path.write_text(instantiate(text, TEMPLATE, spec.scenario, spec.settings), encoding="utf-8")
        subprocess.run([sys.executable, "-m", "rac", "verify", str(path), "-q", "-o", str(folder / "out")],
                       env=env, capture_output=True, check=False)
    return time.perf_counter() - started, len(tasks)


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--quick", action="store_true", help="the built scenes at exponent 1 only (a smoke run)")
    parser.add_argument("--output", type=Path, default=DEFAULT_OUTPUT, help="markdown file to write")
    args = parser.parse_args(argv)
    sets = ["exponent=1"] if args.quick else ["exponent=1,2", "decide_period=0.5,1"]
    rows: list[tuple[str, str, str]] = []
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        (folder / "scenarios").mkdir()
        scenarios = scenario_folder(folder / "scenarios", shared=not args.quick)
        rates: dict[int, float] = {}
        seconds_by_workers: dict[int, float] = {}
        for workers in (1, 2):
            seconds, tasks = timed_sweep(scenarios, sets, workers, folder / f"out{workers}")
            rates[workers] = tasks / seconds * 60
            rows.append((f"sweep, {workers} worker{'s' * (workers > 1)}", f"{tasks} tasks in {seconds:.1f} s",
                         f"{rates[workers]:.1f} tasks/min"))
            seconds_by_workers[workers] = seconds
        rows.append(("scaling (2 workers / 1)", f"{rates[2] / rates[1]:.2f}", f"on {os.cpu_count()} cores"))
        direct, tasks = timed_direct(scenarios, sets, folder)
        rows.append(("rac verify, one process per file", f"{tasks} files in {direct:.1f} s",
                     f"{direct / tasks:.2f} s per file"))
        overhead = (seconds_by_workers[1] - direct) / tasks
        rows.append(("overhead per task (1-worker sweep - rac verify)", f"{overhead:+.2f} s",
                     "cluster start and stop included"))
    scenario_names = "4 built scenes" + (f" + {len(list(SHARED.glob('*.xml')))} shared"
                                         if SHARED.is_dir() and not args.quick else "")
    header = f"template {TEMPLATE.name}, scenarios: {scenario_names}, grid: {' × '.join(sets)}"
    widths = [max(len(r[i]) for r in rows) for i in range(3)]
    print(header)
    for row in rows:
        print("  ".join(cell.ljust(width) for cell, width in zip(row, widths)).rstrip())
    args.output.parent.mkdir(parents=True, exist_ok=True)
    args.output.write_text("\n".join([f"# rac sweep benchmark\n\n{header}\n", "| row | value | rate |", "|---|---|---|",
                                      *(f"| {a} | {b} | {c} |" for a, b, c in rows)]) + "\n", encoding="utf-8")
    print(f"\nwrote {args.output}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
