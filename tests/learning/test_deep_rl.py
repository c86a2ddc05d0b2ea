"""The deep-RL example (examples/deep_rl/, issue 21): its automaton checks with P1 and P2 proved on a
built scene, and ``python benchmarks/deep_rl.py --quick`` trains MaskablePPO under the shield and
plain PPO (with ``--quick``, one seed) and writes a sane table. The benchmark needs the ``rl`` extra; its test
is skipped without it (CI installs the test extra only)."""

from __future__ import annotations

import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest
from conftest import rac_env

from rac.compiler import compile_file
from rac.model.scenes import scene_set

REPO = Path(__file__).resolve().parents[2]
EXAMPLE = REPO / "examples" / "deep_rl"
BENCHMARK = REPO / "benchmarks" / "deep_rl.py"
CONFIGS = ("shield + automaton", "no shield + Eq. 9")


def test_the_example_automaton_checks_with_its_priorities_proved() -> None:
    result = compile_file(EXAMPLE / "driving.ra")
    assert result.ok, [d.message for d in result.diagnostics]
    facts = "\n".join(str(fact) for fact in result.facts)
    assert "P1 holds" in facts and "P2 holds" in facts


def test_the_benchmark_runs_and_writes_a_sane_table(tmp_path: Path) -> None:
    pytest.importorskip("sb3_contrib", reason="benchmarks/deep_rl.py needs sb3-contrib and torch (the rl extra: "
                        "pip install torch==2.13.0, then pip install '.[rl]'), which are not installed")
    output = tmp_path / "deep_rl.md"
    done = subprocess.run([sys.executable, str(BENCHMARK), "--quick", "--output", str(output)], env=rac_env(),
                          capture_output=True, text=True, timeout=900, check=False)
    assert done.returncode == 0, done.stdout + done.stderr
    text = output.read_text(encoding="utf-8")
    rows = [[cell.strip() for cell in row.split("|")[1:-1]] for row in text.splitlines()
            if row.startswith("| ") and not row.startswith("| configuration ")]
    runs = [row for row in rows if row[1]]
    means = [row for row in rows if not row[1]]
    assert sorted((row[0], row[1]) for row in runs) == sorted((c, "1") for c in CONFIGS)  # --quick: seed 1
    assert [row[0] for row in means] == [f"**{c}**, mean" for c in CONFIGS]
    collisions = dict.fromkeys(CONFIGS, 0)
    for config, _, first, training, episodes, success, crashed, cpu, wall in runs:
        assert first == "never" or int(first.replace(",", "")) > 0
        steps, with_collision = (int(n.replace(",", "")) for n in training.split(" / "))
        assert 0 <= with_collision <= steps and with_collision <= int(episodes.replace(",", ""))
        won, of = map(int, success.split("/"))
        assert of == 5 and 0 <= won <= of and 0 <= int(crashed) <= of - won
        assert re.fullmatch(r"\d+ s", cpu) and re.fullmatch(r"\d+ s", wall)
        collisions[config] += steps
    # the shield keeps the learner out of collisions the unshielded one runs into
    assert collisions["shield + automaton"] <= collisions["no shield + Eq. 9"]


def test_the_quickstart_trains_through_make_vec_env_and_logs_the_objectives(tmp_path: Path) -> None:
    """examples/deep_rl/quickstart.py (docs/python.md, "Training with SB3"): SB3's make_vec_env on the
    registered id, MaskablePPO on the runtime shield's masks, RacCallback's keys in SB3's log."""
    pytest.importorskip("sb3_contrib", reason="the quickstart needs sb3-contrib and torch (the rl extra: "
                        "pip install torch==2.13.0, then pip install '.[rl]'), which are not installed")
    shutil.copy(EXAMPLE / "quickstart.py", tmp_path / "quickstart.py")
    shutil.copy(EXAMPLE / "driving.ra", tmp_path / "driving.ra")
    done = subprocess.run([sys.executable, str(tmp_path / "quickstart.py")], env=rac_env(), cwd=tmp_path,
                          capture_output=True, text=True, timeout=600, check=False)
    assert done.returncode == 0, done.stdout + done.stderr
    logged = dict(match.groups() for line in done.stdout.splitlines()  # SB3's table: | key | value |
                  if (match := re.fullmatch(r"\|\s+([\w/ ]+?)\s+\|\s+([^|\s]+)\s+\|", line)))
    for key in ("reward/sa", "reward/pr", "reward/co", "location/Normal", "collisions", "total_timesteps"):
        assert key in logged, (key, done.stdout)
    assert int(logged["total_timesteps"]) >= 256
    shares = [float(v) for k, v in logged.items() if k.startswith("location/")]
    assert sum(shares) == pytest.approx(1.0, abs=0.01)
    assert any(k.startswith("shield/lookahead") for k in logged)  # every mask came from the runtime shield
    # the masks reach predict() the way docs/python.md says (its former env.action_masks() is no VecEnv's method)
    assert "greedy steps outside the masks: 0" in done.stdout.splitlines(), done.stdout


def test_the_template_scene_is_the_first_highway_variant(tmp_path: Path) -> None:
    """examples/deep_rl/highway.xml is what rac.model.scenes writes for highway variant 0 (regenerate it
    with ``scene_set("highway", 1, 0, folder)`` when the variants change)."""
    (written,) = scene_set("highway", 1, 0, tmp_path)
    assert written.read_bytes() == (EXAMPLE / "highway.xml").read_bytes()
