"""``python benchmarks/masked_ppo.py --quick``: MaskablePPO (sb3-contrib) on the 45-action tutorial scene
with the runtime shield, the exhaustive table alone and no shield (issue 20). Needs the ``rl`` extra;
skipped without it (CI installs the test extra only)."""

from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

import pytest
from conftest import rac_env

pytest.importorskip("sb3_contrib", reason="benchmarks/masked_ppo.py needs sb3-contrib and torch (the rl extra: "
                    "pip install torch==2.13.0, then pip install '.[rl]'), which are not installed")

BENCHMARK = Path(__file__).resolve().parents[2] / "benchmarks" / "masked_ppo.py"


def test_the_benchmark_runs_and_the_runtime_shield_covers_the_steps(tmp_path: Path) -> None:
    output = tmp_path / "masked_ppo.md"
    done = subprocess.run([sys.executable, str(BENCHMARK), "--quick", "--output", str(output)], env=rac_env(),
                          capture_output=True, text=True, timeout=600, check=False)
    assert done.returncode == 0, done.stdout + done.stderr
    text = output.read_text(encoding="utf-8")
    rows = {row.split("|")[1].strip(): [cell.strip() for cell in row.split("|")[2:-1]]
            for row in text.splitlines() if row.startswith("| ") and not row.startswith("| run ")}
    assert set(rows) == {"runtime shield", "table only", "no shield"}

    def percent(run: str, column: int) -> float:
        match = re.fullmatch(r"([\d.]+) %", rows[run][column])
        assert match, rows[run]
        return float(match.group(1))

    exhaustive, lookahead, none = 2, 3, 5  # the columns after run: steps, episodes, exhaustive, lookahead, short, none
    for run in rows:  # every step's mask carried one of the three guarantees
        assert percent(run, exhaustive) + percent(run, lookahead) + percent(run, none) == pytest.approx(100, abs=0.2)
    assert percent("runtime shield", lookahead) > 50 and percent("runtime shield", none) < 10
    assert percent("table only", exhaustive) > 0 and percent("table only", lookahead) == 0
    assert percent("no shield", none) == 100
    assert "exhaustive shield over the whole episode" in text  # it could not be had
