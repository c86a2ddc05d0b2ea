"""examples/highway_env/train.py (issue 21): a rac reward on highway-env's highway-fast-v0 with SB3's PPO —
inputs read from the environment itself, clipped, scaled by the proven factor, logged by RacCallback.
Needs highway-env and the rl extra, which CI does not install: skipped without them, saying why."""

from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

import pytest
from conftest import rac_env

from rac.compiler import compile_file

EXAMPLE = Path(__file__).resolve().parents[2] / "examples" / "highway_env"


def test_the_automaton_checks() -> None:
    result = compile_file(EXAMPLE / "follow.ra")
    assert result.ok, [d.message for d in result.diagnostics]
    assert result.automaton is not None and float(result.automaton.period) == 1.0  # highway-fast-v0's step


def test_ppo_trains_on_highway_fast_through_the_wrapper() -> None:
    pytest.importorskip("highway_env", reason="highway-env is not installed (pip install highway-env)")
    pytest.importorskip("stable_baselines3", reason="the rl extra is not installed (pip install torch==2.13.0, "
                        "then pip install '.[rl]')")
    done = subprocess.run([sys.executable, str(EXAMPLE / "train.py"), "--timesteps", "256", "--episodes", "1"],
                          env=rac_env(), capture_output=True, text=True, timeout=600, check=False)
    assert done.returncode == 0, done.stdout + done.stderr
    assert "reward scale: 1010 (proved from follow.ra)" in done.stdout
    assert re.search(r"\|\s+reward/sa\s+\|", done.stdout) and re.search(r"\|\s+location/\w+\s+\|", done.stdout)
    assert re.search(r"greedy policy, 1 episodes: \d+ steps \(.*\); [01] crashed", done.stdout), done.stdout
    assert "UserWarning" not in done.stderr  # the env's 1 s steps and 30 s episodes are the automaton's
