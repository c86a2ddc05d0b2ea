"""The paper's pre-analysis finding on the left-turn example (issue 4, item 8; docs/verify.md).

Under the safety shield, a coarse number representation or a long sensing period lets the *true*
distance to a car drop below the collision distance; exponent 4 with a 0.1 s period does not.
"""

from __future__ import annotations

import re
from pathlib import Path

import pytest
from engine_files import write_engine_file
from tiny_scenarios import Block, GoalBox, StraightRoad

from rac.compiler import compile_file
from rac.engine.budget import TimeExceeded, TimeLimit
from rac.model.commonroad import EgoStart
from rac.output.progress import Heartbeat
from rac.studies.preanalysis import render_table, sweep

EXAMPLE = Path(__file__).resolve().parents[2] / "examples" / "left_turn" / "preanalysis.ra"


class Recorder(Heartbeat):
    """A heartbeat that prints nothing and keeps the phases and counts it hears."""

    def __init__(self) -> None:
        super().__init__("rac preanalyse", enabled=False)
        self.phases: list[str] = []
        self.counts: list[tuple[int, str]] = []

    def phase(self, text: str) -> None:
        self.phases.append(text)
        super().phase(text)

    def count(self, n: int, unit: str, what: str = "") -> None:
        self.counts.append((n, unit))
        super().count(n, unit, what)


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


def stop_at(kind: str, n: int = 0) -> type[TimeLimit]:
    """A time limit that passes at a chosen check: in the exploration (``exploring``, at its first layer: an
    exploration's progress has three numbers), in a simulation (``simulating``, at its ``n``-th sample of Qa's
    runs or, past them, of Fig. 7's: a simulation's has two), or at the ``n``-th check between the setting's
    steps (``between``)."""

    class StopAt(TimeLimit):
        steps = 0

        def check(self, *progress: int) -> None:
            if not progress:
                self.steps += 1
            if (kind == "exploring" and len(progress) == 3) \
                    or (kind == "between" and not progress and self.steps == n) \
                    or (kind == "simulating" and len(progress) == 2 and progress[0] == n):
                raise TimeExceeded(what=self.what, limit=1.0, seconds=1.5)

    return StopAt


# simulating: a setting's simulations did not check the limit, so a long horizon's runs went on past it (with
# --max-seconds 5, 20 runs of 50,000 samples for five minutes, until `timeout` killed the command)
@pytest.mark.parametrize(("kind", "n", "answered"), [("exploring", 0, ["qa"]),
                                                     ("between", 3, ["qa", "qb", "qc", "qd", "states"]),
                                                     ("simulating", 1, [])])
def test_a_setting_past_its_time_limit_keeps_its_answers_and_says_so(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch, kind: str, n: int, answered: list[str]) -> None:
    """rac preanalyse had a memory limit but no time limit: a setting whose exploration took hours could
    only be killed, losing every row. Past --max-seconds a setting is given up between its steps or
    between two layers of its exploration; its row keeps the answers found and says why the rest is
    missing (the table too)."""
    path = write_engine_file(tmp_path, "goal_ahead", {})
    monkeypatch.setattr("rac.studies.preanalysis.TimeLimit", stop_at(kind, n))
    [row] = sweep(compile_file(path), runs=2, seed=1, max_seconds=1.0)
    assert row["error"] == "this setting: given up after 1.5 s, past the time limit of 1 s (--max-seconds)"
    assert row["time_limit"] == 1.0
    assert [key for key in ("qa", "qb", "qc", "qd", "states", "below") if key in row] == answered
    if "qb" in row:  # the table shows the answers, and why the rest is missing
        line = render_table([row]).splitlines()[2]
        assert "| true | true (safe to the horizon) | true |" in line and line.endswith(f"| {row['error']} |")


def test_a_scenario_too_large_for_the_ground_truth_is_measured_coarser(tmp_path: Path) -> None:
    """A road 300 km long (like a real map's UTM coordinates, x ≈ 5e5 m) fits int32 at the file's
    exponent 2 but not at exponent 4, where the true distances are measured: every row was refused,
    Qa-Qd included, which do not need them, so `rac preanalyse` answered nothing on such a map. The
    true distances are now measured at the finest exponent that fits, and the row says which."""
    path = write_engine_file(tmp_path, "goal_ahead", {})  # exponent 2
    car = (Block(31, 30.0, 1.75, velocity=5.0),)  # ahead at the ego's speed: a distance to measure
    road = StraightRoad(300_100.0, EgoStart(10.0, 1.75, 0.0, 5.0), GoalBox(40.0, 50.0), obstacles=car)
    (tmp_path / "goal_ahead.xml").write_bytes(road.xml("long_road"))
    result = compile_file(path)
    assert result.ok, result.diagnostics
    [row] = sweep(result, exponents="2", runs=2, seed=1)
    assert "error" not in row, row.get("error")
    assert row["truth_exponent"] == 3 and row["qb"] is True and row["qd"] is True and len(row["true_min"]) == 2
    assert render_table([row]).splitlines()[2].endswith(
        "(measured at exponent 3: the scenario overflows int32 at exponent 4) |")
    path.write_text(path.read_text(encoding="utf-8").replace("goal_ahead.xml", "short.xml"), encoding="utf-8")
    (tmp_path / "short.xml").write_bytes(StraightRoad(100.0, EgoStart(10.0, 1.75, 0.0, 5.0), GoalBox(40.0, 50.0),
                                                      obstacles=car).xml("short_road"))
    [row] = sweep(compile_file(path), exponents="2", runs=2, seed=1)
    assert row["truth_exponent"] == 4 and "measured at exponent" not in render_table([row])


def test_a_short_time_step_is_refused_up_front_when_its_true_distances_exceed_the_memory_budget(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """The true distances are measured at every CommonRoad time step: a timeStepSize of 1 µs makes
    500,000 of them per sensing period of 0.5 s, and the row ran for many minutes with no word. Their
    memory is estimated before the setting's work: beyond --max-memory the row says so, and nothing
    of the ground truth is integrated."""
    import rac.studies.preanalysis as preanalysis

    path = write_engine_file(tmp_path, "goal_ahead", {})  # horizon 4 s, sensing period 0.5 s
    scenario = tmp_path / "goal_ahead.xml"
    text = scenario.read_text(encoding="utf-8")
    step = re.search(r'timeStepSize="([^"]+)"', text)
    assert step is not None
    scenario.write_text(text.replace(step.group(0), 'timeStepSize="1e-06"'), encoding="utf-8")
    result = compile_file(path)
    assert result.ok, result.diagnostics

    def integrated(*args: object, **kwargs: object) -> None:
        raise AssertionError("the ground truth was integrated, not refused up front")

    monkeypatch.setattr(preanalysis, "integrate_truth", integrated)
    [row] = sweep(result, runs=2, seed=1, max_bytes=64 * 2**20)
    assert row["error"] == (  # 2 copies of 2 runs x (8 samples x 500,000 steps + 1) float64
        "measuring the true distances of 2 runs at every CommonRoad time step (4,000,000 steps per run: 500,000 "
        "per sensing period, the scenario's timeStepSize being 1e-06 s) would need about 122 MB, more than the "
        "memory budget of 64 MB (--max-memory): use fewer --runs, a shorter --horizon, or a scenario whose "
        "timeStepSize is not that short, or raise --max-memory if the machine has that much memory free")
    assert "qb" not in row
    assert row["error"] in render_table([row])  # the table shows why the row has no answers


def test_the_true_distances_count_their_time_steps_off_a_terminal(tmp_path: Path) -> None:
    """A long measurement of the true distances is seen: off a terminal the progress lines name the
    setting, then the time steps to integrate (their number up front) and count them."""
    path = write_engine_file(tmp_path, "goal_ahead", {})  # horizon 4 s, C1 0.5 s over CommonRoad steps of 0.1 s
    with Recorder() as beat:
        [row] = sweep(compile_file(path), runs=2, seed=1)
    assert "qb" in row and "true_min" in row
    assert beat.phases == ["setting 1 of 1 (exponent 2, C1 0.5 s, C2 1 s)", "true distances, 40 steps of 2 runs"]
    steps = [n for n, unit in beat.counts if unit == "steps"]
    assert steps == list(range(1, 41))  # 8 samples of 5 time steps each
    # the simulations count their samples too (Qa's runs, then Fig. 7's): a long horizon's take minutes
    assert [n for n, unit in beat.counts if unit == "samples"] == [*range(1, 9), *range(1, 9)]
    # and the exploration of Qb-Qd its states, up to the shield's graph (it counted nothing)
    states = [n for n, unit in beat.counts if unit == "states"]
    assert states and states == sorted(states) and states[-1] == row["states"]


def test_a_time_step_that_does_not_divide_the_sensing_period_still_measures_at_least_as_often(
        tmp_path: Path) -> None:
    """A 0.5 s period over CommonRoad steps of 0.2 s: the true distances were measured at the samples
    only (one step per period: 0.5 / 0.2 is not whole), so a long period hid a close encounter, the
    very thing Fig. 7 measures. Now ceil(0.5 / 0.2) = 3 steps per period."""
    path = write_engine_file(tmp_path, "goal_ahead", {})  # horizon 4 s, C1 0.5 s
    scenario = tmp_path / "goal_ahead.xml"
    text = scenario.read_text(encoding="utf-8")
    step = re.search(r'timeStepSize="([^"]+)"', text)
    assert step is not None and float(step.group(1)) == 0.1
    scenario.write_text(text.replace(step.group(0), 'timeStepSize="0.2"'), encoding="utf-8")
    result = compile_file(path)
    assert result.ok, result.diagnostics
    with Recorder() as beat:
        [row] = sweep(result, runs=2, seed=1)
    assert "true_min" in row
    assert "true distances, 24 steps of 2 runs" in beat.phases  # 8 samples of 3 steps each


@pytest.mark.parametrize(("old", "new", "error"), [
    ("collision_distance 0.5", "collision_distance 0.05",
     "at base 10, exponent 1, `collision_distance` 0.05 truncates to 0: the model would use 0, not the file's value "
     "(rac check: E0702 at this exponent)"),
    ("action turn in [-0.2, 0.2] step 0.2", "action turn in [-0.25, 0.25] step 0.25",
     "at base 10, exponent 1, action `turn` in [-0.25, 0.25] step 0.25 does not fall on whole significands (rac "
     "check: E0706 at this exponent)"),
])
def test_an_exponent_of_the_grid_at_which_the_model_is_not_the_files_is_a_row_that_says_so(
        tmp_path: Path, old: str, new: str, error: str) -> None:
    """`--exponent` rebuilt the model at each exponent without the `model` block's checks: at exponent 1
    a collision distance of 0.05 m was 0 (the row compared the true distances with 0 m) and a turn step
    of 0.25 rad/s was truncated, answering for another model than the file's, silently."""
    path = write_engine_file(tmp_path, "goal_ahead", {})  # exponent 2
    text = path.read_text(encoding="utf-8")
    assert old in text
    path.write_text(text.replace(old, new), encoding="utf-8")
    result = compile_file(path)
    assert result.ok, result.diagnostics  # at the file's own exponent, every check holds
    coarse, own = sweep(result, exponents="1,2", runs=2, seed=1)
    assert coarse == {"exponent": 1, "sense": 0.5, "decide": 1.0, "error": error, "seed": 1}
    assert "error" not in own and own["qd"] is True


def test_a_fig7_plot_of_many_time_steps_draws_each_runs_lowest_points_only(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """CommonRoad steps of 1 ms give 4,001 true distances per run over 4 s: the plot drew every one
    (millions for a shorter step, which matplotlib drew for over ten minutes after the bar was done).
    It now draws at most PLOT_POINTS per run, each the smallest of its stretch: the lowest stays."""
    import rac.output.plots as plots
    from rac.studies.preanalysis import PLOT_POINTS

    path = write_engine_file(tmp_path, "avoidable_obstacle", {})  # horizon 4 s, C1 0.5 s, a van ahead
    scenario = tmp_path / "avoidable_obstacle.xml"
    text = scenario.read_text(encoding="utf-8")
    step = re.search(r'timeStepSize="([^"]+)"', text)
    assert step is not None
    scenario.write_text(text.replace(step.group(0), 'timeStepSize="0.001"'), encoding="utf-8")
    drawn: list[tuple[object, object]] = []
    monkeypatch.setattr(plots, "plot_runs", lambda times, values, path, **kw: drawn.append((times, values)) or path)
    [row, _] = sweep(compile_file(path), runs=2, seed=1, out_dir=tmp_path / "plots")
    ((times, values),) = drawn
    assert values.shape[0] == 2 and 1000 < values.shape[1] <= PLOT_POINTS  # type: ignore[attr-defined]
    assert times.shape == (values.shape[1],)  # type: ignore[attr-defined]
    assert row["true_min"] is not None and None not in row["true_min"]  # type: ignore[operator]
    assert list(values.min(axis=1)) == pytest.approx(row["true_min"], abs=1e-4)  # type: ignore[attr-defined]
