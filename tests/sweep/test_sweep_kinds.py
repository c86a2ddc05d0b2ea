"""rac.sweep.kinds: the tasks ``rac sweep --task`` offers are the ones the task module runs."""

from __future__ import annotations

import subprocess
import sys

from conftest import rac_env

from rac.sweep.kinds import TASKS


def test_the_task_names() -> None:
    assert TASKS == ("check", "verify", "preanalyse", "experiment")


def test_the_cli_parser_offers_exactly_these_tasks() -> None:
    """``rac sweep --task`` refuses another word and lists the tasks in its message."""
    done = subprocess.run([sys.executable, "-m", "rac", "sweep", "--task", "no_such_task", "x.ra", "y.xml"],
                          env=rac_env(), capture_output=True, text=True, timeout=60, check=False)
    assert done.returncode == 2
    assert "{" + ",".join(TASKS) + "}" in done.stderr
    assert "(choose from " + ", ".join(f"'{task}'" for task in TASKS) + ")" in done.stderr
