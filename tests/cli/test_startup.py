"""Lazy start (issue 24): ``rac --version``, ``--help``, ``fmt``, a usage error and a syntax error
import neither numpy nor the checker's analyses; the parser names every command and each command's
module exists (benchmarks/startup.py measures the times)."""

from __future__ import annotations

import importlib
import subprocess
import sys
from pathlib import Path

import pytest
from conftest import rac_env

from rac.cli.arguments import COMMANDS, build_parser

ROOT = Path(__file__).resolve().parents[2]
HEAVY = ("numpy", "sympy", "rac.check.analysis")


def imported(arguments: list[str], cwd: Path) -> set[str]:
    """The modules ``python -m rac ARGUMENTS`` imported (``-X importtime`` lists each)."""
    done = subprocess.run([sys.executable, "-X", "importtime", "-m", "rac", *arguments], capture_output=True,
                          text=True, env=rac_env(), cwd=cwd, timeout=120)
    return {line.rsplit("|", 1)[-1].strip() for line in done.stderr.splitlines() if line.startswith("import time:")}


@pytest.mark.parametrize("arguments", [["--version"], ["--help"], ["check"], ["fmt", "--check", "ok.ra"],
                                       ["check", "broken.ra"]],
                         ids=["version", "help", "usage-error", "fmt", "syntax-error"])
def test_light_commands_load_no_numpy_and_no_analysis(arguments: list[str], tmp_path: Path) -> None:
    (tmp_path / "ok.ra").write_text((ROOT / "stdlib" / "driving.ra").read_text(encoding="utf-8"), encoding="utf-8")
    (tmp_path / "broken.ra").write_text("automaton A {\n    reward r\n    initial location L { r' == 1\n}\n",
                                        encoding="utf-8")
    modules = imported(arguments, tmp_path)
    assert "rac.cli.main" in modules  # the listing works: rac did start
    loaded = sorted(m for m in modules if any(m == heavy or m.startswith(heavy + ".") for heavy in HEAVY))
    assert not loaded, f"rac {' '.join(arguments)} imported {loaded}"


def test_a_full_check_does_load_the_analyses(tmp_path: Path) -> None:
    # the other side of the test above: the probe sees numpy when it is imported
    assert "numpy" in imported(["check", str(ROOT / "stdlib" / "driving.ra")], tmp_path)


def test_every_command_of_the_parser_has_its_runner() -> None:
    parser = build_parser()
    choices = next(action.choices for action in parser._actions if action.dest == "command")
    assert set(choices) == set(COMMANDS)
    for module, function in COMMANDS.values():
        assert callable(getattr(importlib.import_module(module), function))


@pytest.mark.parametrize("arguments", [["--version"], ["--help"]], ids=["version", "help"])
def test_the_parser_alone_loads_no_language(arguments: list[str], tmp_path: Path) -> None:
    # Building the parser reads the sweep's task list (rac.sweep.kinds); importing that submodule
    # once pulled in rac.sweep's API and with it the grammar and the IR: 0.12 s of rac --version.
    modules = imported(arguments, tmp_path)
    assert "rac.cli.main" in modules
    loaded = sorted(m for m in modules if m in ("lark", "rac.lang", "rac.ir", "rac.sweep.api", "rac.sweep.grid"))
    assert not loaded, f"rac {' '.join(arguments)} imported {loaded}"
