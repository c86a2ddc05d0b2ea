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

BENCHMARKS = Path(__file__).resolve().parents[2] / "benchmarks"
#: A markdown table's separator row: ``| --- |``, ``|---:|``.
TABLE = re.compile(r"^\|\s*:?-{3,}", re.MULTILINE)


def is_script(path: Path) -> bool:
    """Whether ``path`` runs as a script: a module-level ``if __name__ == "__main__":``."""
    tree = ast.parse(path.read_text(encoding="utf-8"))
    return any(isinstance(node, ast.If) and isinstance(node.test, ast.Compare)
               and isinstance(node.test.left, ast.Name) and node.test.left.id == "__name__"
               for node in tree.body)


#: Scripts whose own test already runs them with ``--quick`` and checks their numbers (not only a
#: table): running them here too would double the suite's time for nothing.
DEDICATED: dict[str, str] = {
    "all.py": "test_benchmarks_quick.py", "deep_rl.py": "test_deep_rl.py",
    "engine.py": "test_bench_engine.py", "masked_ppo.py": "test_masked_ppo.py",
    "queries.py": "test_benchmark_queries.py", "run.py": "test_cli.py", "scenario_load.py": "test_scenario_load.py",
    "simulation.py": "test_bench_simulation.py", "synthesis.py": "test_weights.py",
    "vector_env.py": "test_vector_env.py",
}
TESTS = Path(__file__).resolve().parents[1]

SCRIPTS = sorted(path for path in BENCHMARKS.glob("*.py") if is_script(path)) if BENCHMARKS.exists() else []


def test_scripts_and_helpers_are_told_apart() -> None:
    if not BENCHMARKS.exists():
        pytest.skip("benchmarks/ is not in this tree")
    helpers = {path.name for path in BENCHMARKS.glob("*.py")} - {path.name for path in SCRIPTS}
    assert {"learning.py", "run.py", "engine.py"} <= {path.name for path in SCRIPTS}
    assert helpers >= {"children.py", "handwritten_driving.py"}
    for path in SCRIPTS:
        assert '"--quick"' in path.read_text(encoding="utf-8"), f"{path.name} does not accept --quick"


def test_every_dedicated_test_runs_its_script_quick() -> None:
    """A script left to its own test is run there with ``--quick`` (else it would rot unseen)."""
    for script, test in DEDICATED.items():
        text = next(TESTS.rglob(test)).read_text(encoding="utf-8")  # tests/<package>/test_*.py
        assert script.removesuffix(".py") in text and '"--quick"' in text, f"{test} does not run {script} --quick"
        assert (BENCHMARKS / script).exists(), f"{script} is gone: drop it from DEDICATED"


GENERIC = [path for path in SCRIPTS if path.name not in DEDICATED]


@pytest.mark.parametrize("script", GENERIC, ids=[path.stem for path in GENERIC])
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


def test_all_runs_the_scripts_it_is_asked_for_into_one_folder(tmp_path: Path) -> None:
    """``all.py --quick --only`` (a cheap script and the import times, not every benchmark again): each
    one's output verbatim under its header, and the run's header and summary in README.md."""
    if not BENCHMARKS.exists():
        pytest.skip("benchmarks/ is not in this tree")
    folder = tmp_path / "run"
    done = subprocess.run([sys.executable, str(BENCHMARKS / "all.py"), "--quick", "--only", "startup",
                           "--only", "importtime", "--output", str(folder)], env=rac_env(), cwd=tmp_path,
                          capture_output=True, text=True, timeout=600, check=False)
    assert done.returncode == 0, done.stdout[-4000:] + done.stderr[-4000:]
    assert "[1/2] startup" in done.stdout and "[2/2] importtime" in done.stdout
    readme = (folder / "README.md").read_text(encoding="utf-8")
    for fact in ("git commit:", "CPUs:", "numpy", "load average"):
        assert fact in readme
    assert TABLE.search(readme) and "`python benchmarks/startup.py --quick` | ok" in readme
    startup = (folder / "startup.md").read_text(encoding="utf-8")
    assert "- command: `python benchmarks/startup.py --quick`" in startup and "wall time:" in startup
    assert TABLE.search(startup) and "rac --version" in startup
    importtime = (folder / "importtime.md").read_text(encoding="utf-8")
    assert "## stdout" in importtime and "rac.cli.arguments" in importtime  # -X importtime's lines, verbatim
    assert "numpy" not in importtime.split("## stderr", 1)[1]  # rac --version imports no numpy
    refused = subprocess.run([sys.executable, str(BENCHMARKS / "all.py"), "--only", "nonesuch"], env=rac_env(),
                             cwd=tmp_path, capture_output=True, text=True, timeout=60, check=False)
    assert refused.returncode != 0 and "no such benchmark: nonesuch" in refused.stderr
    known = refused.stderr.split("(known: ", 1)[1].split(")", 1)[0].split(", ")
    assert set(known) == {path.stem for path in SCRIPTS} - {"all"} | {"importtime"}  # every script, not itself
