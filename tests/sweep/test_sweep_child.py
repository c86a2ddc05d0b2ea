"""rac.sweep.child: ``python -m rac.sweep.child`` reads a TaskSpec as JSON on standard input and writes
the task's part of the row, and only that, as JSON on standard output."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest
from conftest import rac_env
from engine_files import engine_source
from tiny_scenarios import TINY_SCENARIOS

from rac.sweep import child
from rac.sweep.task import TaskSpec

QUERIES = {"Stays": "E[] !collide() && !offroad()"}


@pytest.fixture(scope="module")
def folder(tmp_path_factory: pytest.TempPathFactory) -> Path:
    root = tmp_path_factory.mktemp("child")
    (root / "sweep.ra").write_text(engine_source(TINY_SCENARIOS["goal_ahead"](), QUERIES,
                                                 scenario_file="placeholder.xml"), encoding="utf-8")
    TINY_SCENARIOS["goal_ahead"]().write(root / "goal_ahead.xml")
    (root / "broken.xml").write_text("<commonRoad><lanelet id='1'>", encoding="utf-8")
    return root


def run_child(spec: TaskSpec, *args: str) -> tuple[dict, str]:
    done = subprocess.run([sys.executable, "-m", child.__name__, *args], input=json.dumps(spec.to_json()),
                          env=rac_env(), capture_output=True, text=True, timeout=300, check=False)
    assert done.returncode == 0, done.stderr
    return json.loads(done.stdout), done.stderr  # json.loads fails if anything else reached stdout


def spec(folder: Path, scenario: str, task: str) -> TaskSpec:
    template = folder / "sweep.ra"
    return TaskSpec(str(template), template.read_text(encoding="utf-8"), str(folder / scenario), (), task)


def test_a_check_task_writes_its_row(folder: Path) -> None:
    row, _ = run_child(spec(folder, "goal_ahead.xml", "check"), str(os.getpid()))
    assert row["status"] == "ok" and row["error"] is None, row
    assert row["peak_memory"] > 0 and row["seconds"] >= 0


def test_a_verify_task_reports_its_verdicts(folder: Path) -> None:
    row, _ = run_child(spec(folder, "goal_ahead.xml", "verify"))
    assert row["status"] == "ok", row
    assert row["verdicts"] == {"Stays": "satisfied"}


def test_a_broken_scenario_is_an_error_row_not_a_crash(folder: Path) -> None:
    row, _ = run_child(spec(folder, "broken.xml", "check"))
    assert row["status"] == "error" and "cannot load the scenario" in str(row["error"]), row
