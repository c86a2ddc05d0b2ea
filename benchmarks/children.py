"""What the engine benchmarks share: a measurement in a child process of its own (so that its peak
memory is its own), the child's peak RSS, and durations as the tables print them.
``benchmarks/engine.py`` and ``benchmarks/queries.py`` import it (run as scripts, their folder is on
``sys.path``)."""

from __future__ import annotations

import json
import os
import resource
import subprocess
import sys
from pathlib import Path
from typing import Any

__all__ = ["peak_rss_mb", "report", "run_child", "seconds"]


def peak_rss_mb() -> float:
    """This process's peak resident set size in MB (``ru_maxrss``: KiB on Linux, bytes on macOS)."""
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    return peak / 2**20 if sys.platform == "darwin" else peak / 2**10


def run_child(script: Path, spec: dict[str, Any], timeout: int, rac_path: Path) -> dict[str, Any]:
    """``python SCRIPT --child JSON(spec)`` with ``rac_path`` (the benchmarked rac's parent folder)
    first on ``PYTHONPATH`` and no progress lines; the JSON object on the child's last line of output,
    or ``{"error": ...}`` when it times out or fails."""
    env = dict(os.environ, RAC_PROGRESS_INTERVAL="3600",
               PYTHONPATH=os.pathsep.join([str(rac_path), *filter(None, [os.environ.get("PYTHONPATH")])]))
    try:
        done = subprocess.run([sys.executable, str(script), "--child", json.dumps(spec)], env=env,
                              capture_output=True, text=True, timeout=timeout, check=False)
    except subprocess.TimeoutExpired:
        return {"error": f"timed out after {timeout} s"}
    if done.returncode != 0:
        tail = (done.stderr.strip().splitlines() or ["(no message)"])[-1]
        return {"error": f"child exited with {done.returncode}: {tail}"}
    return json.loads(done.stdout.strip().splitlines()[-1])


def seconds(value: float) -> str:
    """A duration with three significant digits or so: ``290.2 s``, ``1.21 s``, ``465 ms``, ``5.3 ms``."""
    if value >= 10:
        return f"{value:.1f} s"
    if value >= 1:
        return f"{value:.2f} s"
    return f"{value * 1e3:.0f} ms" if value >= 0.01 else f"{value * 1e3:.1f} ms"


def report(title: str, header: list[str], table: str, notes: list[str], output: Path) -> None:
    """Print the header lines, the table and the notes, and write them as markdown to ``output``."""
    print("\n".join(header))
    print()
    print(table)
    print()
    for note in notes:
        print(f"note: {note}")
    output.parent.mkdir(parents=True, exist_ok=True)
    output.write_text(f"# {title}\n\n" + "\n".join(f"- {item}" for item in header) + "\n\n" + table
                      + "\n\n" + "\n".join(f"- {note}" for note in notes) + "\n", encoding="utf-8")
    print(f"\nwrote {output}")

