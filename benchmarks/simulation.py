"""The peak memory of simulating runs (issue 22): ``python benchmarks/simulation.py [--quick] [--output FILE]``.

``rac verify``'s statistical queries (``simulate``, ``Pr``, ``E``) simulate runs
(:func:`rac.engine.simulate.simulate`) and evaluate expressions on every sample of them
(:meth:`rac.verify.context.Context.values`); they size their chunks of runs by
:func:`rac.engine.budget.simulation_bytes`: the runs' arrays and the values
(:data:`~rac.engine.budget.RUN_BYTES_PER_SAMPLE`, :data:`~rac.engine.budget.VALUE_BYTES` per
expression) times :data:`~rac.engine.budget.SIMULATION_PEAK_FACTOR`. This benchmark measures that
factor: for a few numbers of runs, samples and expressions, in a child process of its own each
(``benchmarks/children.py``), it simulates the runs of examples/left_turn/model.ra and evaluates
the expressions as ``rac verify`` does, and reports the child's peak RSS growth over its peak
before the simulation, over the estimated arrays (``simulation_bytes / SIMULATION_PEAK_FACTOR``).
The largest such ratio must stay below the constant. The table goes to
``benchmarks/results/simulation.md`` (or ``--output``); ``--quick`` measures smaller cases
(under 30 s).
"""

from __future__ import annotations

import argparse
import datetime
import gc
import json
import platform
import sys
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

HERE = Path(__file__).resolve().parent
REPOSITORY = HERE.parent
DEFAULT_OUTPUT = HERE / "results" / "simulation.md"
LEFT_TURN = REPOSITORY / "examples" / "left_turn" / "model.ra"

try:  # benchmark the installed rac; in a checkout without it, the checkout's src/
    import rac
except ImportError:
    sys.path.insert(0, str(REPOSITORY / "src"))
    import rac

import children  # noqa: E402 - benchmarks/, on sys.path as the script's folder
from children import peak_rss_mb, seconds  # noqa: E402

RAC_PATH = Path(rac.__file__).resolve().parent.parent
#: The expressions evaluated, the first ``columns`` of them.
EXPRESSIONS = ("mindist()", "v", "x + y")
#: (runs, samples, expressions): the full run's cases, and --quick's.
CASES = ((2_000, 100, 1), (8_000, 100, 1), (8_000, 100, 3), (16_000, 100, 3))
QUICK_CASES = ((2_000, 80, 1), (4_000, 80, 3))
CHILD_TIMEOUT = 600  # seconds
COLUMNS = ("runs", "samples", "expressions", "estimated arrays", "peak RSS growth", "growth / arrays", "time")
MB = 2**20


def measure(model: str, runs: int, samples: int, columns: int) -> dict[str, Any]:
    """Simulate ``runs`` runs of ``samples`` samples of ``model`` and evaluate the first ``columns`` of
    :data:`EXPRESSIONS` on them, as ``rac verify``'s statistical queries do; the peak RSS before and after."""
    from rac.check.queries import lower_expression
    from rac.compiler import compile_file
    from rac.engine.budget import SIMULATION_PEAK_FACTOR, simulation_bytes
    from rac.engine.simulate import simulate
    from rac.verify.context import Context, VerifyOptions

    result = compile_file(model)
    automaton = result.raise_for_errors()
    context = Context(result, VerifyOptions(max_bytes=None, plots=False))
    exprs = tuple(lower_expression(automaton, text, bool_numbers=True) for text in EXPRESSIONS[:columns])
    context.values(simulate(context.data, runs=1, horizon_samples=samples, seed=0), exprs)  # imports, one-off tables
    gc.collect()
    before = peak_rss_mb()
    start = time.perf_counter()
    values = context.values(simulate(context.data, runs=runs, horizon_samples=samples, seed=1), exprs)
    elapsed = time.perf_counter() - start
    assert len(values) == columns and values[0].shape == (runs, samples + 1)
    return {"arrays": simulation_bytes(runs, samples, columns) / SIMULATION_PEAK_FACTOR,
            "growth": (peak_rss_mb() - before) * MB, "seconds": elapsed, "factor": SIMULATION_PEAK_FACTOR}


def child_main(spec: str) -> int:
    """The child's side of :func:`run_child`: one JSON line with :func:`measure`'s result."""
    args = json.loads(spec)
    print(json.dumps(measure(args["model"], args["runs"], args["samples"], args["columns"])))
    return 0


def run_child(runs: int, samples: int, columns: int) -> dict[str, Any]:
    """:func:`measure` in a fresh Python process (the same rac), so that its peak RSS is this case's."""
    spec = {"model": str(LEFT_TURN), "runs": runs, "samples": samples, "columns": columns}
    return children.run_child(Path(__file__).resolve(), spec, CHILD_TIMEOUT, RAC_PATH)


def row(case: tuple[int, int, int], m: dict[str, Any]) -> list[str]:
    """One line of the table (an error in the estimate's column)."""
    runs, samples, columns = case
    if "error" in m:
        return [f"{runs:,}", str(samples), str(columns), m["error"], "", "", ""]
    return [f"{runs:,}", str(samples), str(columns), f"{m['arrays'] / MB:.1f} MB", f"{m['growth'] / MB:.1f} MB",
            f"{m['growth'] / m['arrays']:.2f}", seconds(m["seconds"])]


def markdown(rows: list[list[str]]) -> str:
    """The rows as a markdown table under :data:`COLUMNS`."""
    lines = ["| " + " | ".join(COLUMNS) + " |", "|" + " --- |" * len(COLUMNS)]
    return "\n".join([*lines, *("| " + " | ".join(r) + " |" for r in rows)])


def verdict(results: Sequence[dict[str, Any]]) -> str:
    """Whether the largest measured ratio stays below ``SIMULATION_PEAK_FACTOR``."""
    ratios = [m["growth"] / m["arrays"] for m in results if "error" not in m]
    if not ratios:
        return "no case measured"
    factor = next(m["factor"] for m in results if "error" not in m)
    ok = "ok" if max(ratios) <= factor else "MISS"
    return f"largest growth / arrays {max(ratios):.2f}, SIMULATION_PEAK_FACTOR = {factor}: {ok}"


def main(argv: Sequence[str] | None = None) -> int:
    """Measure every case in a child process, print and write the table."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--quick", action="store_true", help="smaller cases (under 30 s)")
    parser.add_argument("--output", type=Path, default=DEFAULT_OUTPUT, help="where the markdown table goes")
    parser.add_argument("--child", help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    if args.child is not None:
        return child_main(args.child)
    cases = QUICK_CASES if args.quick else CASES
    results = [run_child(*case) for case in cases]
    header = [f"date: {datetime.datetime.now().astimezone().isoformat(timespec='seconds')}",
              f"mode: {'--quick' if args.quick else 'full'}; each case in a child process",
              f"python {platform.python_version()}, rac {rac.__version__} from {RAC_PATH / 'rac'}",
              f"model: {LEFT_TURN.relative_to(REPOSITORY)}; expressions: {', '.join(EXPRESSIONS)} (the first N)",
              "peak RSS growth: the child's ru_maxrss after the simulation and evaluation minus before "
              "(after one run that loads the model's tables)"]
    notes = [verdict(results)]
    children.report("Simulation memory", header, markdown([row(c, m) for c, m in zip(cases, results)]), notes,
                    args.output)
    return 1 if any("error" in m for m in results) else 0


if __name__ == "__main__":
    sys.exit(main())
