"""benchmarks/simulation.py --quick: the measured peak memory of simulating runs stays below the estimate
that sizes the statistical queries' chunks (``rac.engine.budget.SIMULATION_PEAK_FACTOR``, issue 22)."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest
from conftest import rac_env

from rac.engine.budget import SIMULATION_PEAK_FACTOR

SIMULATION = Path(__file__).resolve().parents[2] / "benchmarks" / "simulation.py"


@pytest.mark.skipif(not SIMULATION.exists(), reason="benchmarks/ is not in this tree")
def test_simulation_benchmark_quick(tmp_path: Path) -> None:
    output = tmp_path / "simulation.md"
    done = subprocess.run([sys.executable, str(SIMULATION), "--quick", "--output", str(output)], env=rac_env(),
                          capture_output=True, text=True, timeout=300, check=False)
    assert done.returncode == 0, done.stdout + done.stderr
    table = output.read_text(encoding="utf-8")
    assert "| runs | samples | expressions | estimated arrays | peak RSS growth | growth / arrays | time |" in table
    rows = [line.split(" | ") for line in table.splitlines() if line.startswith(("| 2,000", "| 4,000"))]
    assert len(rows) == 2, table
    assert all(0 < float(row[5]) <= SIMULATION_PEAK_FACTOR for row in rows), table  # measured under the estimate
    assert f"SIMULATION_PEAK_FACTOR = {SIMULATION_PEAK_FACTOR}: ok" in table
