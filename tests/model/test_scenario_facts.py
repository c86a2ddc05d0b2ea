"""Facts of the scenario that `rac check` no longer takes silently (issue 11, "scenario facts").

One test per finding, each on a scene built with commonroad-io (tests/support/tiny_scenarios.py,
rac.model.intersection):

- a highway whose ego starts faster than `max_speed`, slower than `min_speed` or accelerating
  harder than `max_acceleration`: E0714, naming the setting to change (the model would clamp the
  start at the first sample);
- the left-turn junction with a second planning problem: E0715 lists the ids until the block
  chooses one with `planning_problem ID`, which the model data, the engine and the UPPAAL target
  then share; an id the file lacks is E0715 too;
- an urban road without obstacles: "no obstacle" in the facts, the pre-analysis table and JSON,
  the plots (no 1e9 axis) and `rac simulate`'s note, where `mindist()` reads 1e9;
- a ramp whose ego starts half before the road (as CommonUppRoad's ZAM_Ramp does): W0716.
"""

from __future__ import annotations

import json
import math
from fractions import Fraction
from pathlib import Path

import numpy as np
import pytest
from engine_files import TEMPLATE, write_engine_file
from tiny_scenarios import SECOND_PROBLEM_ID, GoalBox, StraightRoad, highway, junction_with_two_problems, ramp

from rac.cli.main import main
from rac.compiler import compile_file
from rac.model.commonroad import EgoStart
from rac.model.native import NO_OBSTACLE

#: The engine tests' automaton (one input from `mindist()`, one reward) over a `model` block.
MODEL = """\
    model {{
        scenario "{scenario}"
{items}        bind near = mindist() < 3 * collision_distance
    }}"""


def write(folder: Path, scenario: str, xml: bytes, items: str = "") -> tuple[Path, str]:
    """``folder/drive.ra`` over ``folder/<scenario>`` (written from ``xml``): the path and the text."""
    (folder / scenario).write_bytes(xml)
    text = TEMPLATE.format(period="0.1", horizon="10", model=MODEL.format(scenario=scenario, items=items), queries="")
    path = folder / "drive.ra"
    path.write_text(text, encoding="utf-8")
    return path, text


def line_of(text: str, needle: str) -> int:
    return next(i for i, line in enumerate(text.splitlines(), 1) if needle in line)


def errors(result) -> list:
    return [d for d in result.diagnostics if d.is_error]


# ---------------------------------------------------------------- the ego's start and the model's limits
def test_an_ego_faster_than_max_speed_is_an_error(tmp_path: Path) -> None:
    """33 m/s against the default `max_speed 20`: the model would clamp it to 20 at the first sample."""
    path, text = write(tmp_path, "highway.xml", highway(33.0))
    result = compile_file(path)
    (diagnostic,) = errors(result)
    assert diagnostic.code == "E0714"
    assert diagnostic.message == "the ego starts at 33 m/s, faster than `max_speed` (20 m/s)"
    assert diagnostic.span is not None and diagnostic.span.line == line_of(text, 'scenario "highway.xml"')
    assert any("`max_speed` defaults to 20 m/s" in note.message for note in diagnostic.notes)
    assert list(diagnostic.hints) == ["set `max_speed 33` (or more) in the `model` block"]
    # a written setting is where the error points
    path, text = write(tmp_path, "highway.xml", highway(33.0), "        max_speed 30\n")
    (diagnostic,) = errors(compile_file(path))
    assert diagnostic.code == "E0714" and diagnostic.span is not None
    assert diagnostic.span.line == line_of(text, "max_speed 30")
    # the hint's setting fixes it
    path, _ = write(tmp_path, "highway.xml", highway(33.0), "        max_speed 33\n")
    fixed = compile_file(path)
    assert fixed.ok, [d.message for d in fixed.diagnostics]
    assert fixed.model_data is not None and fixed.model_data.ego_v == fixed.model_data.max_speed == 330_000


@pytest.mark.parametrize(("speed", "acceleration", "items", "message", "hint"), [
    (8.0, 0.0, "        min_speed 10\n", "the ego starts at 8 m/s, slower than `min_speed` (10 m/s)",
     "set `min_speed 8` (or less) in the `model` block"),
    (25.0, -4.5, "        max_speed 30\n",
     "the ego starts with the acceleration -4.5 m/s², beyond `max_acceleration` (3 m/s²)",
     "set `max_acceleration 4.5` (or more) in the `model` block"),
])
def test_an_ego_outside_the_other_limits_is_an_error(tmp_path: Path, speed: float, acceleration: float, items: str,
                                                     message: str, hint: str) -> None:
    path, _ = write(tmp_path, "highway.xml", highway(speed, acceleration), items)
    (diagnostic,) = errors(compile_file(path))
    assert (diagnostic.code, diagnostic.message, list(diagnostic.hints)) == ("E0714", message, [hint])


# ---------------------------------------------------------------- several planning problems
def test_several_planning_problems_need_a_choice(tmp_path: Path) -> None:
    path, text = write(tmp_path, "junction.xml", junction_with_two_problems())
    result = compile_file(path)
    (diagnostic,) = errors(result)
    assert diagnostic.code == "E0715"
    assert diagnostic.message == "the scenario has 2 planning problems (100, 101) and the `model` block chooses none"
    assert diagnostic.span is not None and diagnostic.span.line == line_of(text, 'scenario "junction.xml"')
    assert list(diagnostic.hints) == ["choose one with `planning_problem 100` or `planning_problem 101` in the `model` "
                                "block"]

    chosen_item = f"        planning_problem {SECOND_PROBLEM_ID}\n"
    path, _ = write(tmp_path, "junction.xml", junction_with_two_problems(), chosen_item)
    chosen = compile_file(path)
    assert chosen.ok, [d.message for d in chosen.diagnostics]
    assert chosen.automaton is not None and chosen.automaton.model is not None
    assert chosen.automaton.model.planning_problem == SECOND_PROBLEM_ID
    assert chosen.scenario is not None and chosen.scenario.planning_problem_id == SECOND_PROBLEM_ID
    data = chosen.model_data
    assert data is not None and (data.ego_x, data.ego_y, data.ego_v) == (-17_500, 180_000, 50_000)
    assert "planning problem 101 (of 100, 101)" in chosen.proved[-1]
    # the UPPAAL target, loading the scenario itself, takes the same planning problem
    from rac.targets.uppaal.model import generate_uppaal_model

    assert generate_uppaal_model(chosen.automaton).xml == generate_uppaal_model(chosen.automaton, data=data).xml

    path, text = write(tmp_path, "junction.xml", junction_with_two_problems(), "        planning_problem 7\n")
    (diagnostic,) = errors(compile_file(path))
    assert diagnostic.code == "E0715"
    assert diagnostic.message == "the scenario has no planning problem 7"
    assert diagnostic.span is not None and diagnostic.span.line == line_of(text, "planning_problem 7")
    assert any("its planning problems are 100, 101" in note.message for note in diagnostic.notes)


def test_a_planning_problem_the_setting_cannot_name_is_not_offered(tmp_path: Path) -> None:
    """commonroad-io reads a planning problem with id 0 (CommonRoad's schema wants positive ids); E0715
    offered `planning_problem 0`, which E0702 then refused."""
    xml = junction_with_two_problems().replace(b'<planningProblem id="100"', b'<planningProblem id="0"', 1)
    assert xml != junction_with_two_problems()
    path, _ = write(tmp_path, "junction.xml", xml)
    (diagnostic,) = errors(compile_file(path))
    assert diagnostic.message == "the scenario has 2 planning problems (0, 101) and the `model` block chooses none"
    assert list(diagnostic.hints) == ["choose one with `planning_problem 101` in the `model` block"]
    assert "planning problem 0 cannot be chosen: `planning_problem` is a whole number >= 1" in \
        diagnostic.notes[-1].message
    path, _ = write(tmp_path, "junction.xml", xml, "        planning_problem 101\n")
    assert compile_file(path).ok


def test_planning_problem_is_a_setting(tmp_path: Path) -> None:
    from rac.ir.vocabulary import SETTINGS

    setting = SETTINGS["planning_problem"]
    assert setting.whole and setting.minimum == Fraction(1) and setting.default is None
    for value in ("0", "1.5"):
        path, text = write(tmp_path, "junction.xml", b"", f"        planning_problem {value}\n")
        (diagnostic,) = errors(compile_file(path))
        assert diagnostic.code == "E0702"
        assert diagnostic.message == f"`planning_problem` must be a whole number >= 1 (found {value})"
        assert diagnostic.span is not None and diagnostic.span.line == line_of(text, "planning_problem")
    # a file with one planning problem needs none, and may name it
    path, _ = write(tmp_path, "highway.xml", highway(15.0), "        planning_problem 100\n")
    result = compile_file(path)
    assert result.ok and result.scenario is not None and result.scenario.planning_problem_id == 100


# ---------------------------------------------------------------- no obstacle
def test_no_obstacle_is_reported_as_such(tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                         capsys: pytest.CaptureFixture[str]) -> None:
    """An urban road without obstacles (tiny goal_ahead): `mindist()` reads 1e9 there."""
    from rac.studies.preanalysis import render_table, sweep

    path = write_engine_file(tmp_path, "goal_ahead", {})
    result = compile_file(path)
    assert result.ok and result.proved[-1].startswith("scenario goal_ahead.xml: 1 lanelet, no obstacle (")
    # the pre-analysis: no 1e9 minimum in the table, nulls in the JSON
    rows = sweep(result, runs=5, seed=1, out_dir=tmp_path / "pre")
    table = render_table(rows)
    assert "1000000000" not in table and "no obstacle" in table
    (row,) = [r for r in rows if "exponent" in r]
    assert row["true_min"] == [None] * 5 and row["sensed_min"] == [None] * 5
    json.dumps(rows, allow_nan=False)  # valid JSON
    # `rac simulate` says why no run comes close
    assert main(["simulate", str(path), "--runs", "2", "--seed", "1", "--horizon", "1"]) == 0
    err = capsys.readouterr().err
    assert "no obstacle" in err and "mindist()" in err


def test_plots_draw_no_obstacle_as_no_value(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    import rac.output.plots as plots

    figures = []
    monkeypatch.setattr(plots, "save_figure", lambda figure, path, **options: figures.append(figure) or Path(path))
    times = np.arange(5) * 0.5
    plots.plot_runs(times, np.full((3, 5), NO_OBSTACLE), tmp_path / "none.png", threshold=1.5, threshold_label="3·TD")
    axes = figures[-1].axes[0]
    assert axes.get_ylim()[1] < 10 and "no obstacle" in axes.get_title()
    some = np.array([[NO_OBSTACLE, NO_OBSTACLE, 4.0, 3.0, 2.0]] * 2)  # an obstacle appears at 1 s
    plots.plot_runs(times, some, tmp_path / "some.png", threshold=1.5)
    axes = figures[-1].axes[0]
    assert axes.get_ylim()[1] < 10
    assert any("no obstacle" in text.get_text() for text in axes.get_legend().get_texts())
    plots.plot_sweep([{"exponent": 2, "sense": 0.5, "decide": 1.0, "min_distances": [math.nan] * 3,
                       "threshold": 0.5}], tmp_path / "sweep.png")
    assert any("no obstacle" in text.get_text() for text in figures[-1].axes[0].texts)


# ---------------------------------------------------------------- off the road at the start
def test_a_start_off_the_road_is_a_warning(tmp_path: Path, capsys: pytest.CaptureFixture[str],
                                           monkeypatch: pytest.MonkeyPatch) -> None:
    path, text = write(tmp_path, "ramp.xml", ramp())
    result = compile_file(path)
    assert result.ok and result.model_data is not None
    (warning,) = [d for d in result.diagnostics if d.code == "W0716"]
    assert warning.severity.value == "warning"
    assert warning.message == "the ego starts off the road: its rear-right and rear-left corners lie outside " \
                              "every lanelet"
    assert warning.span is not None and warning.span.line == line_of(text, 'scenario "ramp.xml"')
    assert warning.hints
    monkeypatch.chdir(tmp_path)
    assert main(["check", "drive.ra"]) == 0
    out = capsys.readouterr().out
    assert "warning[W0716]" in out and "drive.ra: ok, 1 warning" in out
    # one corner off the road: named alone (it read "its  and front-left corner lies")
    tilted = StraightRoad(100.0, EgoStart(10.0, 2.5, 0.05, 5.0), GoalBox(40.0, 50.0)).xml("tilted")
    path, _ = write(tmp_path, "tilted.xml", tilted)
    (warning,) = [d for d in compile_file(path).diagnostics if d.code == "W0716"]
    assert warning.message == "the ego starts off the road: its front-left corner lies outside every lanelet"
    # on the road: no warning
    path, _ = write(tmp_path, "ramp.xml", ramp(start_x=5.0))
    assert not compile_file(path).diagnostics
