"""Every benchmark, one after another, into one dated folder (issue 24): ``python benchmarks/all.py
[--quick] [--only NAME ...] [--output DIR] [--timeout SECONDS]``.

Runs each benchmark script of ``benchmarks/`` (a file with an ``if __name__ == "__main__":`` guard,
as tests/benchmarks/test_benchmarks_quick.py finds them) with the arguments docs/benchmarks.md prints
beside its table (:data:`ARGUMENTS`), each in a process of its own, and ``python -X importtime -m rac
--version`` (the start-up's imports). Each one's output goes verbatim to ``DIR/NAME.md`` under a
header (the command, its exit status, wall and CPU time, the load average before and after), and
``DIR/README.md`` holds the run's header (date and time, machine, CPU count, Python and numpy
versions, git commit) and one summary row per script. ``DIR`` defaults to
``benchmarks/results/<UTC date and time>/`` (git-ignored). Progress (which script, elapsed) goes to
stdout as it runs.

``--quick`` passes ``--quick`` to every script (a smoke run: its figures are not to be quoted);
``--only NAME`` (repeatable; ``engine`` or ``engine.py``) runs only those. Scripts needing the
``rl`` extra (sb3-contrib) are skipped with a message when it is missing. A script that fails or
outlives ``--timeout`` is recorded as such and the run goes on; the exit status is 1 if any did.
"""

from __future__ import annotations

import argparse
import ast
import datetime
import importlib.util
import os
import platform
import resource
import subprocess
import sys
import time
from dataclasses import dataclass
from pathlib import Path

HERE = Path(__file__).resolve().parent
REPOSITORY = HERE.parent
RESULTS = HERE / "results"

#: The arguments docs/benchmarks.md prints beside each script's table (none: the script's defaults).
ARGUMENTS: dict[str, list[str]] = {"check": ["--timeout", "90"]}
#: The order of the run: the quick and central ones first, the long learning runs last; a script
#: not named here runs after these, in alphabetical order.
ORDER = ("startup", "importtime", "run", "check", "engine", "queries", "scenario_load", "sweep", "synthesis",
         "learning", "simulation", "vector_env", "experiment_scenes", "deep_rl", "masked_ppo")
#: Not a script: the modules ``rac --version`` imports, and how long each took (stderr).
IMPORTTIME = "importtime"
#: How often a running script's elapsed time is printed, in seconds.
HEARTBEAT = 60.0


def is_script(path: Path) -> bool:
    """Whether ``path`` runs as a script: a module-level ``if __name__ == "__main__":``."""
    tree = ast.parse(path.read_text(encoding="utf-8"))
    return any(isinstance(node, ast.If) and isinstance(node.test, ast.Compare)
               and isinstance(node.test.left, ast.Name) and node.test.left.id == "__name__"
               for node in tree.body)


def scripts() -> list[str]:
    """Every benchmark script's name (without ``.py``) but this one's, plus ``importtime``, in run order."""
    found = {path.stem for path in HERE.glob("*.py") if path.name != Path(__file__).name and is_script(path)}
    found.add(IMPORTTIME)
    rank = {name: i for i, name in enumerate(ORDER)}
    return sorted(found, key=lambda name: (rank.get(name, len(ORDER)), name))


def needs_rl(name: str) -> bool:
    """Whether the script imports sb3-contrib (the ``rl`` extra)."""
    return name != IMPORTTIME and "sb3_contrib" in (HERE / f"{name}.py").read_text(encoding="utf-8")


def command(name: str, quick: bool, folder: Path) -> list[str]:
    """The command run for ``name`` (``--output`` into ``folder`` for the scripts that take one)."""
    if name == IMPORTTIME:
        return [sys.executable, "-X", "importtime", "-m", "rac", "--version"]
    script = HERE / f"{name}.py"
    arguments = [sys.executable, str(script), *ARGUMENTS.get(name, [])]
    if quick:
        arguments.append("--quick")
    if '"--output"' in script.read_text(encoding="utf-8"):
        arguments += ["--output", str(folder / f"{name}.table.md")]
    return arguments


def shown(arguments: list[str]) -> str:
    """The command as docs/benchmarks.md prints it: ``python benchmarks/NAME.py ARGS``, no ``--output``."""
    words = ["python", *(os.path.relpath(a, REPOSITORY) if a.endswith(".py") else a for a in arguments[1:])]
    if "--output" in words:
        del words[words.index("--output"):words.index("--output") + 2]
    return " ".join(words)


def git(*arguments: str) -> str:
    done = subprocess.run(["git", *arguments], cwd=REPOSITORY, capture_output=True, text=True, check=False)
    return done.stdout.strip() if done.returncode == 0 else "unknown"


def cpu_model() -> str:
    try:
        for line in Path("/proc/cpuinfo").read_text(encoding="utf-8").splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or "unknown"


def load() -> str:
    return " ".join(f"{x:.2f}" for x in os.getloadavg())


def now() -> datetime.datetime:
    return datetime.datetime.now(datetime.UTC)


def children_cpu() -> float:
    """User + system CPU seconds of the waited-for child processes (and theirs) so far."""
    usage = resource.getrusage(resource.RUSAGE_CHILDREN)
    return usage.ru_utime + usage.ru_stime


@dataclass
class Outcome:
    name: str
    shown: str
    status: str
    wall: float = 0.0
    cpu: float = 0.0
    load_before: str = ""
    load_after: str = ""


def run_one(name: str, arguments: list[str], folder: Path, timeout: float | None) -> Outcome:
    """Run one script, its stdout (and stderr, when any) verbatim into ``folder/NAME.md``."""
    out_path, err_path = folder / f"{name}.stdout.txt", folder / f"{name}.stderr.txt"
    before, cpu0, start = load(), children_cpu(), time.perf_counter()
    started = now()
    with out_path.open("w", encoding="utf-8") as out, err_path.open("w", encoding="utf-8") as err:
        process = subprocess.Popen(arguments, cwd=REPOSITORY, stdout=out, stderr=err, text=True)
        status = ""
        while True:
            try:
                code = process.wait(timeout=HEARTBEAT)
                status = "ok" if code == 0 else f"exit {code}"
                break
            except subprocess.TimeoutExpired:
                elapsed = time.perf_counter() - start
                if timeout is not None and elapsed > timeout:
                    process.kill()
                    process.wait()
                    status = f"killed after {elapsed:.0f} s (--timeout {timeout:.0f})"
                    break
                print(f"    ... {name}: {elapsed / 60:.0f} min, load {load()}", flush=True)
    outcome = Outcome(name, shown(arguments), status, time.perf_counter() - start, children_cpu() - cpu0,
                      before, load())
    stdout = out_path.read_text(encoding="utf-8")
    stderr = err_path.read_text(encoding="utf-8")
    out_path.unlink()
    err_path.unlink()
    lines = [f"# {name}", "", f"- command: `{outcome.shown}`", f"- started: {started:%Y-%m-%d %H:%M:%S} UTC",
             f"- status: {outcome.status}", f"- wall time: {outcome.wall:.1f} s; CPU time (user + system, "
             f"with its child processes): {outcome.cpu:.1f} s",
             f"- load average (1, 5, 15 min) before: {outcome.load_before}; after: {outcome.load_after}", "",
             "## stdout", "", "````text", stdout.rstrip("\n"), "````", ""]
    if stderr.strip():
        lines += ["## stderr", "", "````text", stderr.rstrip("\n"), "````", ""]
    (folder / f"{name}.md").write_text("\n".join(lines), encoding="utf-8")
    return outcome


def header(started: datetime.datetime, quick: bool) -> list[str]:
    """The run's own facts: when, where, with what (taken before the first script runs)."""
    try:
        import numpy  # the benchmarked code's numpy; imported here only to name its version
        numpy_version = numpy.__version__
    except ImportError:
        numpy_version = "not installed"
    dirty = " (with uncommitted changes)" if git("status", "--porcelain", "--untracked-files=no") else ""
    return [f"# `python benchmarks/all.py{' --quick' if quick else ''}`, {started:%Y-%m-%d %H:%M} UTC", "",
            f"- started: {started:%Y-%m-%d %H:%M:%S} UTC",
            f"- git commit: {git('rev-parse', 'HEAD')}{dirty} (branch {git('rev-parse', '--abbrev-ref', 'HEAD')})",
            f"- machine: {platform.node()}, {platform.platform()}, {cpu_model()}",
            f"- CPUs: {os.cpu_count()}",
            f"- Python {platform.python_version()} ({sys.executable}), numpy {numpy_version}",
            f"- load average (1, 5, 15 min) at the start: {load()}",
            "- note: the machine is shared; the load averages before and after each script say how busy it was"]


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--quick", action="store_true", help="pass --quick to every script (a smoke run)")
    parser.add_argument("--only", action="append", metavar="NAME", help="run only this script (repeatable)")
    parser.add_argument("--output", type=Path, help="the results folder (default benchmarks/results/<date>/)")
    parser.add_argument("--timeout", type=float, help="seconds before a script is killed (default: none)")
    args = parser.parse_args()
    names = scripts()
    if args.only:
        wanted = [name.removesuffix(".py") for name in args.only]
        unknown = sorted(set(wanted) - set(names))
        if unknown:
            parser.error(f"no such benchmark: {', '.join(unknown)} (known: {', '.join(names)})")
        names = [name for name in names if name in wanted]
    started = now()
    folder = args.output or RESULTS / f"{started:%Y-%m-%d_%H%M}{'-quick' if args.quick else ''}"
    folder.mkdir(parents=True, exist_ok=True)
    rl = importlib.util.find_spec("sb3_contrib") is not None
    facts = header(started, args.quick)  # at the start: the commit and the tree the scripts import
    print(f"benchmarks/all.py: {len(names)} benchmarks into {folder}", flush=True)
    outcomes: list[Outcome] = []
    clock = time.perf_counter()
    for i, name in enumerate(names, 1):
        arguments = command(name, args.quick, folder)
        if needs_rl(name) and not rl:
            print(f"[{i}/{len(names)}] {name}: skipped (needs the rl extra: pip install '.[rl]')", flush=True)
            outcomes.append(Outcome(name, shown(arguments), "skipped: needs the rl extra (sb3-contrib)"))
            continue
        print(f"[{i}/{len(names)}] {name}: {shown(arguments)} (run so far {time.perf_counter() - clock:.0f} s, "
              f"load {load()})", flush=True)
        outcome = run_one(name, arguments, folder, args.timeout)
        outcomes.append(outcome)
        print(f"[{i}/{len(names)}] {name}: {outcome.status}, {outcome.wall:.1f} s wall, {outcome.cpu:.1f} s CPU",
              flush=True)
    total = time.perf_counter() - clock
    finished = f"- finished: {now():%Y-%m-%d %H:%M:%S} UTC, {total / 60:.1f} min; load average at the end: {load()}"
    lines = [*facts, finished, "", "| script | command | status | wall (s) | CPU (s) | load before | load after |",
              "| --- | --- | --- | ---: | ---: | --- | --- |"]
    lines += [f"| [{o.name}]({o.name}.md) | `{o.shown}` | {o.status} | {o.wall:.1f} | {o.cpu:.1f} | {o.load_before} "
              f"| {o.load_after} |" for o in outcomes]
    (folder / "README.md").write_text("\n".join(lines) + "\n", encoding="utf-8")
    print("\n".join(lines[-len(outcomes) - 2:]))
    print(f"benchmarks/all.py: done in {total / 60:.1f} min; results in {folder}", flush=True)
    return 1 if any(o.status not in {"ok"} and not o.status.startswith("skipped") for o in outcomes) else 0


if __name__ == "__main__":
    sys.exit(main())
