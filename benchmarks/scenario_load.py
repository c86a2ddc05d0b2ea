"""How a large scenario loads: ``python benchmarks/scenario_load.py [--quick] [--output FILE]``.

Issue 22: a 50 MB scenario (~25,000 lanelets) took 891 s and 1.47 GB before ``rac check`` said ok,
growing faster than linearly, without a word. This benchmark measures what ``rac check`` does with a
`model` block's scenario — :func:`rac.model.checks.check_scenario`: the load
(:func:`rac.model.commonroad.load_scenario`) and the model's data
(:func:`rac.model.data.build_model_data_and_largest`) — on generated scenes
(:func:`rac.model.scenes.build_grid`) of growing numbers of lanelets and of obstacles, each in a child
process of its own (``benchmarks/children.py``) so that its peak memory is its own.

Per scene the table gives the file's size, the lanelets and obstacles, the time of the check, its
peak memory beyond what the process held before (``ru_maxrss`` after against the resident size
before: the automaton checked, rac, numpy and commonroad-io imported), the ratio of that peak to
the file's size, and rac's estimate (:func:`rac.core.resources.estimate_load`), which must be at
least the peak. The notes give the
fitted factors: the largest peak per file byte (what ``LOAD_BYTES_PER_FILE_BYTE`` must hold), the
slowest rate in bytes per second (``LOAD_BYTES_PER_SECOND``), and the time per lanelet at the
largest size against the smallest (1 when the load is linear).

``--quick`` (a smoke run, under 30 s): 250-1,000 lanelets and 30-120 obstacles. Without it: 2,000,
5,000 and 10,000 lanelets, and 500, 1,500 and 3,000 obstacles of 40 time steps (several minutes).
The table is written to ``benchmarks/results/scenario_load.md`` as well (``--output``).
"""

from __future__ import annotations

import argparse
import datetime
import json
import os
import platform
import re
import resource
import sys
import tempfile
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

HERE = Path(__file__).resolve().parent
REPOSITORY = HERE.parent
DEFAULT_OUTPUT = HERE / "results" / "scenario_load.md"
LEFT_TURN = REPOSITORY / "examples" / "left_turn" / "model.ra"

try:  # benchmark the installed rac; in a checkout without it, the checkout's src/
    import rac
except ImportError:
    sys.path.insert(0, str(REPOSITORY / "src"))
    import rac

import children  # noqa: E402 - benchmarks/, on sys.path as the script's folder
from children import seconds  # noqa: E402

RAC_PATH = Path(rac.__file__).resolve().parent.parent
MB = 2**20
CHILD_TIMEOUT = 1800  # seconds
#: (lanelets, obstacles, time steps of the obstacles' trajectories)
CASES = ((2_000, 0, 40), (5_000, 0, 40), (10_000, 0, 40), (4, 500, 40), (4, 1_500, 40), (4, 3_000, 40))
QUICK_CASES = ((250, 0, 40), (500, 0, 40), (1_000, 0, 40), (4, 30, 40), (4, 120, 40))
COLUMNS = ["lanelets", "obstacles", "file", "check", "peak", "peak / file", "estimate", "estimate holds"]


def model_text(scenario: Path) -> str:
    """examples/left_turn/model.ra with ``scenario`` (an absolute path) in its `model` block."""
    text = LEFT_TURN.read_text(encoding="utf-8")
    return re.sub(r'scenario "[^"]+"', lambda _: f'scenario "{scenario.as_posix()}"', text, count=1)


def rss_bytes() -> int:
    """This process's resident set size now (Linux: /proc/self/statm; elsewhere its peak so far)."""
    try:
        pages = int(Path("/proc/self/statm").read_text().split()[1])
        return pages * os.sysconf("SC_PAGE_SIZE")
    except (OSError, ValueError, IndexError):
        return peak_bytes()


def peak_bytes() -> int:
    """This process's peak resident set size (``ru_maxrss``: KiB on Linux, bytes on macOS)."""
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * (1 if sys.platform == "darwin" else 1024)


def measure(model: str) -> dict[str, Any]:
    """The child's work: what ``rac check`` does with the `model` block of ``model`` (a .ra file) —
    :func:`rac.model.checks.check_scenario`, the load and the model's data — its time and its peak
    memory beyond what the process held before (the automaton checked, commonroad-io imported)."""
    import commonroad.common.file_reader  # noqa: F401 - imported before, like rac's other imports

    from rac.compiler import compile_file
    from rac.model.checks import check_scenario

    automaton = compile_file(model, analyse=False).raise_for_errors()
    before = rss_bytes()
    start = time.perf_counter()
    checked = check_scenario(automaton)
    elapsed = time.perf_counter() - start
    errors = [d.code for d in checked.diagnostics if d.is_error]
    scenario = checked.scenario
    return {"seconds": elapsed, "peak": max(peak_bytes() - before, 0), "errors": errors,
            "lanelets": len(scenario.road) if scenario else 0, "obstacles": len(scenario.obstacles) if scenario else 0}


def run_case(folder: Path, lanelets: int, obstacles: int, steps: int) -> dict[str, Any]:
    """Write the scene and its .ra file into ``folder``, check it in a child; the child's measurements
    with the file's size."""
    from rac.model.scenes import grid_bytes

    scene = folder / f"grid_{lanelets}_{obstacles}.xml"
    scene.write_bytes(grid_bytes(lanelets, obstacles, steps))
    model = folder / f"grid_{lanelets}_{obstacles}.ra"
    model.write_text(model_text(scene.resolve()), encoding="utf-8")
    measured = children.run_child(Path(__file__).resolve(), {"model": str(model)}, CHILD_TIMEOUT, RAC_PATH)
    measured["file"] = scene.stat().st_size
    scene.unlink()
    return measured


def row(lanelets: int, obstacles: int, measured: dict[str, Any]) -> list[str]:
    """One line of the table."""
    from rac.core.resources import estimate_load

    size = measured["file"]
    if "error" in measured:
        return [f"{lanelets:,}", f"{obstacles:,}", f"{size / MB:.1f} MB", measured["error"], "", "", "", ""]
    estimate = estimate_load(size).peak_bytes
    return [f"{lanelets:,}", f"{obstacles:,}", f"{size / MB:.1f} MB", seconds(measured["seconds"]),
            f"{measured['peak'] / MB:.0f} MB", f"{measured['peak'] / size:.1f}", f"{estimate / MB:.0f} MB",
            "yes" if estimate >= measured["peak"] else "NO"]


def notes(results: list[tuple[int, int, dict[str, Any]]]) -> list[str]:
    """The fitted factors, and whether rac's constants hold them."""
    from rac.core.resources import LOAD_BASE_BYTES, LOAD_BYTES_PER_FILE_BYTE, LOAD_BYTES_PER_SECOND

    good = [(n, m, r) for n, m, r in results if "error" not in r and not r["errors"]]
    if not good:
        return ["no case was measured"]
    said = []
    for family, cases in (("lanelets", [r for _, m, r in good if m == 0]),
                          ("obstacles", [r for _, m, r in good if m > 0])):
        if len(cases) >= 2:  # least squares: peak = base + factor * file
            xs, ys = [r["file"] for r in cases], [r["peak"] for r in cases]
            mx, my = sum(xs) / len(xs), sum(ys) / len(ys)
            factor = sum((x - mx) * (y - my) for x, y in zip(xs, ys)) / sum((x - mx) ** 2 for x in xs)
            said.append(f"fitted on {family}: peak = {(my - factor * mx) / MB:.0f} MB + {factor:.1f} x file bytes")
    upper = max((r["peak"] - LOAD_BASE_BYTES) / r["file"] for _, _, r in good)
    rate = min(r["file"] / r["seconds"] for _, _, r in good)
    said += [f"upper factor: {upper:.1f} bytes per file byte beyond LOAD_BASE_BYTES = {LOAD_BASE_BYTES / MB:.0f} MB "
             f"(the largest over the cases; rac's LOAD_BYTES_PER_FILE_BYTE = {LOAD_BYTES_PER_FILE_BYTE}: "
             f"{'holds' if LOAD_BYTES_PER_FILE_BYTE >= upper else 'TOO LOW'})",
             f"slowest rate: {rate / MB:.2f} MB/s (rac's LOAD_BYTES_PER_SECOND = {LOAD_BYTES_PER_SECOND / MB:.2f} "
             "MB/s announces the time)"]
    lanes = [(n, r) for n, m, r in good if m == 0]
    if len(lanes) >= 2:
        (n0, r0), (n1, r1) = lanes[0], lanes[-1]
        growth = (r1["seconds"] / n1) / (r0["seconds"] / n0)
        said.append(f"time per lanelet at {n1:,} lanelets / at {n0:,}: {growth:.2f} (1 when the load is linear)")
    failed = [f"{n} lanelets, {m} obstacles: {r.get('error') or r['errors']}" for n, m, r in results
              if "error" in r or r["errors"]]
    said += [f"FAILED {item}" for item in failed]
    return said


def main(argv: Sequence[str] | None = None) -> int:
    """Measure every case, print the table and the notes, write them to ``--output``; 1 if a case
    failed or the estimate fell below a measured peak."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--quick", action="store_true", help="small scenes only (a smoke run, under 30 s)")
    parser.add_argument("--output", type=Path, default=DEFAULT_OUTPUT,
                        help=f"markdown file to write (default: {DEFAULT_OUTPUT.relative_to(REPOSITORY)})")
    parser.add_argument("--child", help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    if args.child:
        print(json.dumps(measure(json.loads(args.child)["model"])))
        return 0
    cases = QUICK_CASES if args.quick else CASES
    results = []
    with tempfile.TemporaryDirectory(prefix="rac-scenario-load-") as folder:
        for lanelets, obstacles, steps in cases:
            measured = run_case(Path(folder), lanelets, obstacles, steps)
            results.append((lanelets, obstacles, measured))
            print(" | ".join(row(lanelets, obstacles, measured)), file=sys.stderr, flush=True)
    lines = ["| " + " | ".join(COLUMNS) + " |", "|" + "---|" * len(COLUMNS)]
    lines += ["| " + " | ".join(row(n, m, r)) + " |" for n, m, r in results]
    command = "python benchmarks/scenario_load.py" + (" --quick" if args.quick else "")
    header = [f"command: `{command}`", f"date: {datetime.date.today().isoformat()}",
              f"machine: {platform.machine()}, {os.cpu_count()} CPUs, Python {platform.python_version()}",
              "the check of examples/left_turn/model.ra on each generated grid (rac.model.scenes.build_grid), "
              "in a child process; peak: ru_maxrss beyond the resident size before the load"]
    said = notes(results)
    children.report("Loading a large scenario", header, "\n".join(lines), said, args.output)
    failed = any("error" in r or r["errors"] for _, _, r in results) or any(
        cell == "NO" for n, m, r in results for cell in row(n, m, r))
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
