"""The paper's pre-analysis finding on the left-turn example (issue 4, item 8; docs/verify.md).

Under the safety shield, a coarse number representation or a long sensing period lets the *true*
distance to a car drop below the collision distance; exponent 4 with a 0.1 s period does not.
"""

from __future__ import annotations

from pathlib import Path

import pytest
from engine_files import write_engine_file
from tiny_scenarios import GoalBox, StraightRoad

from rac.compiler import compile_file
from rac.model.commonroad import EgoStart
from rac.studies.preanalysis import render_table, sweep

EXAMPLE = Path(__file__).resolve().parents[2] / "examples" / "left_turn" / "preanalysis.ra"


@pytest.fixture(scope="module")
def rows() -> list[dict[str, object]]:
    result = compile_file(EXAMPLE)
    assert result.ok, result.diagnostics
    return sweep(result, exponents="1,4", senses="0.1,0.5", runs=100, seed=1)


def row(rows: list[dict[str, object]], exponent: int, sense: float) -> dict[str, object]:
    return next(r for r in rows if r.get("exponent") == exponent and r.get("sense") == sense)


def test_the_fine_setting_keeps_every_run_clear_of_the_cars(rows: list[dict[str, object]]) -> None:
    fine = row(rows, 4, 0.1)
    assert fine["qb"] is True and fine["qd"] is True
    assert fine["below"] == 0
    assert min(fine["true_min"]) >= 0.5  # type: ignore[type-var, arg-type]
    assert fine["qa"][1] < 0.05  # type: ignore[index]  # the sensed x stays within THD of the truth


def test_a_coarse_representation_collides_under_the_shield(rows: list[dict[str, object]]) -> None:
    coarse = row(rows, 1, 0.1)
    assert coarse["qd"] is True  # the shield exists on the coarse model ...
    assert coarse["below"] >= 20  # type: ignore[operator]  # ... yet many runs truly collide
    assert coarse["qa"][0] > 0.9  # type: ignore[index]  # the sensed x drifts from the truth


def test_a_long_sensing_period_misses_close_encounters(rows: list[dict[str, object]]) -> None:
    slow = row(rows, 4, 0.5)
    assert slow["qd"] is True
    assert slow["below"] >= 3  # type: ignore[operator]
    # the sensed distance, all the shield sees, never drops below the collision distance
    assert min(slow["sensed_min"]) >= 0.5  # type: ignore[type-var, arg-type]


def test_the_table_has_a_row_per_setting(rows: list[dict[str, object]]) -> None:
    table = render_table(rows)
    assert table.count("\n| 1 |") + table.count("\n| 4 |") == 4
    assert "0 of 100" in table


def test_a_sensing_period_that_does_not_divide_the_files_horizon_is_a_row_that_says_so(tmp_path: Path) -> None:
    # its runs were cut to the whole periods within the horizon and the row did not say so
    path = write_engine_file(tmp_path, "goal_ahead", {})  # horizon 4 s, sensing period 0.5 s
    [short, whole] = sweep(compile_file(path), senses="0.3,0.5", decides="1.5", runs=2, seed=1)
    assert short == {"exponent": 2, "sense": 0.3, "decide": 1.5,
                     "error": "the horizon, 4 s, is not a whole number of sensing periods (its runs would stop "
                              "short of it)"}
    assert "error" not in whole and whole["samples"] == 8


def test_a_scenario_too_large_for_the_ground_truth_says_so(tmp_path: Path) -> None:
    """A road 300 km long fits int32 at the file's exponent 2 but not at exponent 4, where the ground
    truth is measured: each row said "does not fit int32 at this exponent" (exponent 1 or 2) and
    quoted a significand at scale 10000."""
    path = write_engine_file(tmp_path, "goal_ahead", {})  # exponent 2
    road = StraightRoad(300_100.0, EgoStart(10.0, 1.75, 0.0, 5.0), GoalBox(40.0, 50.0))
    (tmp_path / "goal_ahead.xml").write_bytes(road.xml("long_road"))
    result = compile_file(path)
    assert result.ok, result.diagnostics
    [row] = sweep(result, exponents="2", runs=2, seed=1)
    assert row["error"].startswith(  # type: ignore[union-attr]
        "the scenario does not fit int32 at exponent 4, where the pre-analysis measures the ground truth of Qa and "
        "Qd: road polygon 0 vertex 0 x = 300100.0 needs the significand 3001000000 at scale 10000")
