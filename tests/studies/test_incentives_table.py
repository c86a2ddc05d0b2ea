"""rac.studies.incentives: the table docs/stdlib.md shows (p* and the loophole verdicts per file, as
declared and as a gymnasium environment ending episodes at a collision or the goal would run it)."""

from __future__ import annotations

from pathlib import Path

import pytest

from rac.compiler import compile_file
from rac.studies.incentives import COLUMNS, gym_ending, main, rows

ROOT = Path(__file__).resolve().parents[2]


def cells(path: str) -> list[dict[str, str]]:
    result = compile_file(ROOT / path)
    assert result.automaton is not None and result.ok
    return [dict(zip(COLUMNS, row)) for row in rows(path, result.automaton)]


def test_driving_as_declared_and_ending_at_the_goal() -> None:
    declared, ending = cells("stdlib/driving.ra")
    returns = (declared["R_goal"], declared["R_stall"], declared["R_crash"], declared["p*"])
    assert returns == ("980", "480", "-20", "0.5")
    assert declared["episodes end"] == "at the horizon"
    assert declared["ending early never pays"] == "—"  # runs last the horizon: nothing ends early
    assert declared["goal earlier never pays less"] == "holds"
    # ending at the goal forfeits the rest of the horizon's accrual: arriving at the last sample pays most
    assert ending["episodes end"] == "when collide || dgoal < 2, else at the horizon"
    assert ending["goal earlier never pays less"] == "**fails** by 478.4 (samples 1 and 300)"
    assert ending["ending early never pays"] == "holds"


def test_a_file_with_its_own_ending_has_one_row() -> None:
    (row,) = cells("examples/weighted/naive.ra")
    assert row["ending early never pays"] == "**fails** by 289 (sample 1)"
    assert row["p*"] == "— (no `goal when`)"
    result = compile_file(ROOT / "examples" / "weighted" / "naive.ra")
    assert result.automaton is not None and gym_ending(result.automaton) is None


def test_the_table_escapes_the_pipes_of_a_condition(capsys: pytest.CaptureFixture[str]) -> None:
    assert main([str(ROOT / "stdlib" / "driving.ra"), str(ROOT / "stdlib" / "speed_limit.ra")]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert lines[0] == "| " + " | ".join(COLUMNS) + " |"
    assert len(lines) == 2 + 3  # header, rule, driving twice, speed_limit once (no goal or collision)
    assert all(line.count(" | ") == len(COLUMNS) - 1 for line in lines[2:])
    assert "collide \\|\\| dgoal < 2" in lines[3]


def test_a_file_that_does_not_check_is_named(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    broken = tmp_path / "broken.ra"
    broken.write_text("automaton A {\n", encoding="utf-8")
    assert main([str(broken), str(tmp_path / "missing.ra")]) == 1
    err = capsys.readouterr().err
    assert f"{broken}: does not check" in err
    assert f"{tmp_path / 'missing.ra'}: cannot be read: No such file or directory" in err
