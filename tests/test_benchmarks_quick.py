"""Every benchmark script runs with ``--quick`` and prints a table (issue 23: none can rot unnoticed).

A *script* is a ``benchmarks/*.py`` file with an ``if __name__ == "__main__":`` guard, found by
globbing (a new script is included without touching this test); a file without the guard is a
helper module the scripts import (``children.py``, ``handwritten_driving.py``), as
docs/benchmarks.md says. Each script runs in a child process with ``--quick`` (and, when it accepts
``--output``, a file in a temporary folder, so that the committed results are not overwritten); it
must exit 0 and print (or write) a markdown table. Scripts that need the optional ``rl`` extra
(``sb3_contrib``) are skipped without it.
"""

from __future__ import annotations

import ast
import importlib.util
import re
import subprocess
import sys
from pathlib import Path

import pytest
from conftest import rac_env

BENCHMARKS = Path(__file__).resolve().parents[1] / "benchmarks"
#: A markdown table's separator row: ``| --- |``, ``|---:|``.
TABLE = re.compile(r"^\|\s*:?-{3,}", re.MULTILINE)


def is_script(path: Path) -> bool:
    """Whether ``path`` runs as a script: a module-level ``if __name__ == "__main__":``."""
    tree = ast.parse(path.read_text(encoding="utf-8"))
    return any(isinstance(node, ast.If) and isinstance(node.test, ast.Compare)
               and isinstance(node.test.left, ast.Name) and node.test.left.id == "__name__"
               for node in tree.body)


SCRIPTS = sorted(path for path in BENCHMARKS.glob("*.py") if is_script(path)) if BENCHMARKS.exists() else []


def test_scripts_and_helpers_are_told_apart() -> None:
    if not BENCHMARKS.exists():
        pytest.skip("benchmarks/ is not in this tree")
    helpers = {path.name for path in BENCHMARKS.glob("*.py")} - {path.name for path in SCRIPTS}
    assert {"learning.py", "run.py", "engine.py"} <= {path.name for path in SCRIPTS}
    assert helpers >= {"children.py", "handwritten_driving.py"}
    for path in SCRIPTS:
        assert '"--quick"' in path.read_text(encoding="utf-8"), f"{path.name} does not accept --quick"


@pytest.mark.parametrize("script", SCRIPTS, ids=[path.stem for path in SCRIPTS])
def test_every_benchmark_runs_quick_and_prints_a_table(script: Path, tmp_path: Path) -> None:
    text = script.read_text(encoding="utf-8")
    if "sb3_contrib" in text and importlib.util.find_spec("sb3_contrib") is None:
        pytest.skip(f"{script.name} needs the rl extra (sb3-contrib)")
    command = [sys.executable, str(script), "--quick"]
    output = tmp_path / f"{script.stem}.md"
    if '"--output"' in text:
        command += ["--output", str(output)]
    done = subprocess.run(command, env=rac_env(), cwd=tmp_path, capture_output=True, text=True, timeout=600,
                          check=False)
    assert done.returncode == 0, done.stdout[-4000:] + done.stderr[-4000:]
    written = output.read_text(encoding="utf-8") if output.exists() else ""
    assert TABLE.search(done.stdout) or TABLE.search(written), done.stdout[-4000:]
