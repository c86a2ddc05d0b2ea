"""benchmarks/engine.py's table of the shield against the exploration (issue 20): its rows and goal note,
and `--quick --shield-only` on ZAM_Ramp when the shared scenario is beside the checkout."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest
from conftest import rac_env

REPOSITORY = Path(__file__).resolve().parents[2]
BENCHMARKS = REPOSITORY / "benchmarks"
RAMP = REPOSITORY.parent / "shared" / "scenarios" / "ZAM_Ramp-1_1-T-1.xml"


@pytest.fixture(scope="module")
def engine():  # benchmarks/engine.py as a module (its folder on sys.path, as when it runs as a script)
    sys.path.insert(0, str(BENCHMARKS))
    try:
        import engine as module
    finally:
        sys.path.remove(str(BENCHMARKS))
    return module


def measured(explore: float, shield: float, explore_peak: float, shield_peak: float, **more: object) -> dict:
    return {"states": 1000, "choices": 2000, "explore": explore, "shield": shield, "explore_peak": explore_peak,
            "shield_peak": shield_peak, "graph": explore_peak / 2, **more}


def test_a_row_gives_both_ratios(engine) -> None:
    row = engine.shield_row("ZAM", 60, measured(4.0, 0.05, 400.0, 10.0, storm=2.0, same=True))
    assert dict(zip(engine.SHIELD_COLUMNS, row)) == {
        "case": "ZAM", "horizon": "60", "states": "1,000", "choices": "2,000", "explore CPU": "4.00 s",
        "shield CPU": "50 ms", "shield / explore": "0.013", "explore peak": "400 MB", "shield peak": "10.0 MB",
        "shield / explore (memory)": "0.025", "Storm's shield CPU": "2.00 s", "same as Storm's": "yes"}
    assert engine.shield_row("ZAM", 200, {"error": "timed out"})[2] == "timed out"


def test_the_goal_note_names_the_highest_ratios(engine) -> None:
    fine = {("a", 10): measured(1.0, 0.1, 100.0, 5.0), ("a", 20): measured(2.0, 0.1, 200.0, 40.0)}
    note = engine.shield_notes(fine)[0]
    assert ": ok (" in note and "time 0.100 at a, horizon 10" in note and "memory 0.200 at a, horizon 20" in note
    slow = {("b", 30): measured(1.0, 0.3, 100.0, 1.0, storm=1.0, same=False)}
    notes = engine.shield_notes(slow)
    assert ": MISS (" in notes[0] and notes[1] == "the shield differs from Storm's: b, horizon 30"


@pytest.mark.skipif(not RAMP.is_file(), reason="the shared ZAM_Ramp scenario is not beside this checkout")
def test_quick_shield_table_on_zam_ramp(tmp_path: Path) -> None:
    output = tmp_path / "engine.md"
    done = subprocess.run([sys.executable, str(BENCHMARKS / "engine.py"), "--quick", "--shield-only", "--ramp",
                           str(RAMP), "--output", str(output)], env=rac_env(), capture_output=True, text=True,
                          timeout=600, check=False)
    assert done.returncode == 0, done.stdout + done.stderr
    rows = [line for line in output.read_text(encoding="utf-8").splitlines() if line.startswith("| ZAM_Ramp")]
    assert len(rows) == 4 and all(row.endswith("| yes |") for row in rows)  # the same as Storm's
    assert "the shield at most 0.25 of the exploration in CPU time and in peak memory at every horizon: ok" in (
        done.stdout)
