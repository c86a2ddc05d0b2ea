"""Start-up time of the ``rac`` command (issue 24): ``python benchmarks/startup.py [--quick] [--output FILE]``.

Each row is a command run in a fresh Python process, the best wall time of ``--repeat`` runs
(default 10; ``--quick`` 3), beside ``python -c pass`` and ``python -c "import lark"`` (the goal:
``rac --version`` under 3 x ``import lark``), and whether the process imported numpy (``python -X
importtime``): ``--version``, ``--help``, ``fmt`` and a syntax error must not.

The table goes to ``benchmarks/results/startup.md`` (or ``--output``); docs/benchmarks.md quotes it.
"""

from __future__ import annotations

import argparse
import subprocess
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
REPOSITORY = HERE.parent
DEFAULT_OUTPUT = HERE / "results" / "startup.md"
DRIVING = REPOSITORY / "stdlib" / "driving.ra"
#: A file whose first error is a syntax error (an unclosed location).
BROKEN = "automaton A {\n    reward r\n    initial location L { r' == 1\n}\n"
#: ``rac --version`` must start within this many times ``import lark``.
GOAL_FACTOR = 3.0


def best_of(command: list[str], repeat: int) -> float:
    """The best wall time of ``repeat`` runs of ``command``, in seconds."""
    best = float("inf")
    for _ in range(repeat):
        start = time.perf_counter()
        subprocess.run(command, capture_output=True, check=False)
        best = min(best, time.perf_counter() - start)
    return best


def imports_numpy(arguments: list[str]) -> bool:
    """Whether ``python -m rac ARGUMENTS`` imports numpy (``-X importtime`` names every module)."""
    done = subprocess.run([sys.executable, "-X", "importtime", "-m", "rac", *arguments], capture_output=True,
                          text=True, check=False)
    return any(line.rsplit("|", 1)[-1].strip() == "numpy" for line in done.stderr.splitlines())


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--quick", action="store_true", help="3 runs per row instead of 10")
    parser.add_argument("--repeat", type=int, default=None, help="runs per row (default 10, --quick 3)")
    parser.add_argument("--output", type=Path, default=DEFAULT_OUTPUT, help="where the markdown table goes")
    args = parser.parse_args()
    repeat = args.repeat or (3 if args.quick else 10)
    with tempfile.TemporaryDirectory(prefix="rac-startup-") as scratch:
        broken = Path(scratch) / "broken.ra"
        broken.write_text(BROKEN, encoding="utf-8")
        formatted = Path(scratch) / "driving.ra"
        formatted.write_text(DRIVING.read_text(encoding="utf-8"), encoding="utf-8")
        python = [sys.executable]
        rows: list[tuple[str, list[str] | None, list[str]]] = [
            ("python -c pass", None, ["-c", "pass"]),
            ('python -c "import lark"', None, ["-c", "import lark"]),
            ("rac --version", ["--version"], []),
            ("rac --help", ["--help"], []),
            ("rac fmt --check stdlib/driving.ra", ["fmt", "--check", str(formatted)], []),
            ("rac check (a syntax error)", ["check", str(broken)], []),
            ("rac check stdlib/driving.ra", ["check", str(DRIVING)], []),
        ]
        table = []
        lark = version = None
        for label, rac_args, plain in rows:
            command = python + (["-m", "rac", *rac_args] if rac_args is not None else plain)
            seconds = best_of(command, repeat)
            numpy = "—" if rac_args is None else ("yes" if imports_numpy(rac_args) else "no")
            if label.startswith('python -c "import lark"'):
                lark = seconds
            if label == "rac --version":
                version = seconds
            table.append(f"| {label} | {seconds * 1000:.0f} | {numpy} |")
    assert lark is not None and version is not None
    verdict = "met" if version < GOAL_FACTOR * lark else "NOT met"
    text = (f"`python benchmarks/startup.py{' --quick' if args.quick else ''}` ({time.strftime('%Y-%m-%d')}; "
            f"best of {repeat} runs each)\n\n"
            "| command | ms | imports numpy |\n| --- | --- | --- |\n" + "\n".join(table) + "\n\n"
            f"`rac --version` takes {version / lark:.2f} x `import lark` (goal: under {GOAL_FACTOR:g} x): {verdict}.\n")
    args.output.parent.mkdir(parents=True, exist_ok=True)
    args.output.write_text(text, encoding="utf-8")
    print(text)


if __name__ == "__main__":
    main()
