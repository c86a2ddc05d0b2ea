"""benchmarks/queries.py --quick (the left turn only): its table says how each query was decided."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest
from conftest import rac_env

QUERIES = Path(__file__).resolve().parents[2] / "benchmarks" / "queries.py"


@pytest.mark.skipif(not QUERIES.exists(), reason="benchmarks/ is not in this tree")
def test_queries_benchmark_quick(tmp_path: Path) -> None:
    output = tmp_path / "queries.md"
    done = subprocess.run([sys.executable, str(QUERIES), "--quick", "--output", str(output)], env=rac_env(),
                          capture_output=True, text=True, timeout=600, check=False)
    assert done.returncode == 0, done.stdout + done.stderr
    table = output.read_text(encoding="utf-8")
    assert "| scene | query | verdict | decided | states | time | peak RSS (file) |" in table
    rows = [line for line in table.splitlines() if line.startswith("| left turn") or line.startswith("|  |")]
    assert len(rows) == 11, table  # the standard queries and the file's four
    assert "UNKNOWN" not in table
    assert "| exhaustive |" in table  # Qb-Qd on the complete graph
