"""The planning problem's goal and start as the model reads them (the sweep of new scenes, "sweepB").

Each scene is built with commonroad-io (tests/support/tiny_scenarios.py):

- a goal window [0, 0.7] s sampled every 0.2 s holds the samples 0 to 3 (0.6 s), not 4 (0.8 s):
  the window is the samples inside it, in the model's data, ``goal()`` and the UPPAAL declarations;
  a window between two samples holds none (W0722), and so does one that closes before the ego starts or
  opens after the horizon;
- a goal that also asks for a velocity and an orientation: W0723 (the model reads neither), and two
  goal states of which only one asks for a velocity are accepted with it;
- a curved lanelet goal (half a ring): its centre, which ``dist_goal()`` measures to, lies on the
  lanelet, not in the ring's hole; a region whose vertex mean lies outside it gets a point inside;
- a goal of time alone (no position): ``dist_goal()`` reads 0, so a binding reading it warns (W0727);
- traffic lights, signs and stop lines, which the model does not read: W0730;
- a goal region without area (a polygon on one line, a rectangle 0 m long): refused (E0712);
- an ego that starts inside a parked car: W0724;
- the loader's messages for a file without a version, a 2020a file labelled 2018b, and a time step
  of 0 or below (E0718, with the position, like any step outside [1 µs, 10^6 s]).
"""

from __future__ import annotations

import re
from fractions import Fraction
from pathlib import Path

import numpy as np
import pytest
import shapely
from commonroad.common.common_lanelet import LaneletType
from commonroad.common.util import Interval
from commonroad.geometry.occupancy.polygon_occupancy import PolygonOccupancy
from commonroad.geometry.occupancy.rect_occupancy import RectOccupancy
from commonroad.planning.goal import GoalRegion
from commonroad.planning.planning_problem import PlanningProblem, PlanningProblemSet
from commonroad.scenario.lanelet import Lanelet
from commonroad.scenario.scenario import Tag
from commonroad.scenario.state import CustomState
from engine_files import TEMPLATE
from tiny_scenarios import (
    PLANNING_PROBLEM_ID,
    RING_RADIUS,
    Block,
    GoalBox,
    StraightRoad,
    TinySettings,
    blocked_start,
    commonroad_xml,
    curved_lane_goal,
    goal_anywhere,
    goal_with_direction,
    late_start,
    ramp,
    traffic_rules,
)

from rac.compiler import compile_file
from rac.model.batch import batch_model
from rac.model.commonroad import (
    EgoStart,
    Goal,
    InconsistentScenarioError,
    Polygon,
    ScenarioError,
    inside_point,
    load_scenario,
)
from rac.model.data import build_model_data
from rac.model.native import NativeModel
from rac.targets.uppaal.declarations import emit_declarations

MODEL = """\
    model {{
        scenario "{scenario}"
{items}        bind near = mindist() < 3 * collision_distance
    }}"""


def write(folder: Path, scenario: str, xml: bytes, period: str = "0.1", items: str = "") -> Path:
    """``folder/drive.ra`` (sampling every ``period`` s) over ``folder/<scenario>``, written from ``xml``."""
    (folder / scenario).write_bytes(xml)
    text = TEMPLATE.format(period=period, horizon="2", model=MODEL.format(scenario=scenario, items=items),
                           queries="")
    path = folder / "drive.ra"
    path.write_text(text, encoding="utf-8")
    return path


def warnings_of(path: Path, code: str) -> list:
    result = compile_file(path)
    assert result.ok, [d.message for d in result.diagnostics]
    return [d for d in result.diagnostics if d.code == code]


def window(time_low: float, time_high: float) -> bytes:
    return StraightRoad(100.0, EgoStart(10.0, 1.75, 0.0, 10.0), GoalBox(17.9, 25.0, time_low, time_high)).xml("window")


# ---------------------------------------------------------------- the goal's time window
def test_the_goal_window_is_the_samples_inside_it(tmp_path: Path) -> None:
    """[0, 0.7] s every 0.2 s: samples 0..3; rounding both ends to the nearest (ties to even) gave 0..4,
    and `goal()` held at 0.8 s, after the window had closed."""
    path = tmp_path / "window.xml"
    path.write_bytes(window(0.0, 0.7))
    settings = TinySettings(sense_period=Fraction(1, 5), decide_period=Fraction(1, 5))
    data = build_model_data(load_scenario(path), settings.model_spec(path))
    assert (data.goal_low, data.goal_high) == (0, 3)
    declarations = emit_declarations(data)  # the UPPAAL model reads the same numbers
    assert re.search(r"\bGOAL_LOW = 0;", declarations) and re.search(r"\bGOAL_HIGH = 3;", declarations)
    model = NativeModel(data)
    inside = model.initial_state()._replace(x=21 * data.scale)
    assert model.goal(inside, 3) and not model.goal(inside, 4)

    path.write_bytes(window(0.3, 0.7))  # [0.3, 0.7]: samples 2 (0.4 s) and 3, not 1 (0.2 s)
    data = build_model_data(load_scenario(path), settings.model_spec(path))
    assert (data.goal_low, data.goal_high) == (2, 3)


def test_a_goal_window_without_a_sample_is_a_warning(tmp_path: Path) -> None:
    items = "        sense_period 0.2\n        decide_period 0.2\n"
    (warning,) = warnings_of(write(tmp_path, "window.xml", window(0.3, 0.3), "0.2", items), "W0722")
    assert warning.message == ("the goal's time window [0.3, 0.3] s holds no sample of the model (every 0.2 s from "
                               "the ego's start at 0 s): `goal()` never holds")
    assert not warnings_of(write(tmp_path, "window.xml", window(0.2, 0.3), "0.2", items), "W0722")


def test_a_goal_window_closed_before_the_start_is_a_warning(tmp_path: Path) -> None:
    path = write(tmp_path, "late.xml", late_start())
    (warning,) = warnings_of(path, "W0722")
    assert warning.message == ("the goal's time window [0, 6] s closes before the ego starts (at 7 s of the "
                               "scenario): `goal()` never holds")
    fact = compile_file(path).proved[-1]
    assert "goal at scenario time t in [0, 6] s (the model's time counts from the ego's start at 7 s)" in fact


def test_a_goal_window_after_the_horizon_is_a_warning(tmp_path: Path) -> None:
    """Runs of 2 s end before the window [3, 5] s opens: `goal()` holds at no sample of any run, so every goal
    query is "no" for that reason alone, and `rac check` said nothing of it. A window that opens at the
    horizon's last sample holds that sample."""
    (warning,) = warnings_of(write(tmp_path, "window.xml", window(3.0, 5.0)), "W0722")
    assert warning.message == ("the goal's time window [3, 5] s opens after the horizon ends (scenario time t = 2 s): "
                               "`goal()` never holds")
    assert warning.hints[0].startswith("lengthen the horizon to at least 3 s (`horizon`)")
    assert not warnings_of(write(tmp_path, "window.xml", window(2.0, 5.0)), "W0722")


# ---------------------------------------------------------------- what the goal asks beyond position and time
def test_goal_velocity_and_orientation_are_a_warning(tmp_path: Path) -> None:
    (warning,) = warnings_of(write(tmp_path, "direction.xml", goal_with_direction()), "W0723")
    assert warning.message == ("the goal of `direction.xml` also asks for velocity in [0, 1] m/s and orientation in "
                               "[2.5, 3.5] rad, which the model does not read: `goal()` holds at any speed and heading "
                               "inside the goal region")
    assert not warnings_of(write(tmp_path, "ramp.xml", ramp(start_x=5.0)), "W0723")


def test_goal_states_that_differ_only_in_velocity_are_accepted(tmp_path: Path) -> None:
    path = tmp_path / "mixed.xml"
    path.write_bytes(goal_with_direction(mixed=True))
    goal = load_scenario(path).goal
    assert len(goal.regions) == 2 and goal.velocity == (0.0, 1.0) and goal.orientation is None
    (warning,) = warnings_of(write(tmp_path, "mixed.xml", goal_with_direction(mixed=True)), "W0723")
    assert "velocity in [0, 1] m/s, which" in warning.message


# ---------------------------------------------------------------- a goal of time alone
def time_goal(*states: CustomState) -> bytes:
    """:func:`window`'s road whose planning problem's goal is ``states`` (default: the time steps 20
    to 30 alone, a velocity in [0, 15] m/s and no position: CommonRoad's "be anywhere in [2, 3] s")."""
    scenario, problems = StraightRoad(100.0, EgoStart(10.0, 1.75, 0.0, 10.0), GoalBox(40.0, 50.0)).build("timed")
    (problem,) = problems.planning_problem_dict.values()
    goal = GoalRegion(list(states) or [CustomState(time_step=Interval(20, 30), velocity=Interval(0.0, 15.0))])
    problems = PlanningProblemSet([PlanningProblem(PLANNING_PROBLEM_ID, problem.initial_state, goal)])
    return commonroad_xml(scenario, problems, "timed", Tag.SINGLE_LANE)


def test_a_goal_without_a_position_holds_anywhere_in_its_window(tmp_path: Path) -> None:
    """A goal state of time alone (common in real files: "survive until T") was refused (E0712, "has no
    position"). CommonRoad reaches such a goal at any position inside the window: `goal()` reads the
    window alone and `dist_goal()` is 0, in the model's data, the native and batch models and the
    UPPAAL declarations."""
    path = tmp_path / "timed.xml"
    path.write_bytes(time_goal())
    goal = load_scenario(path).goal
    assert goal.anywhere and goal.regions == () and (goal.time_low, goal.time_high) == (2.0, 3.0)
    assert goal.velocity == (0.0, 15.0)
    data = build_model_data(load_scenario(path), TinySettings().model_spec(path))
    assert data.goal_anywhere and data.goal_count == 0 and (data.goal_low, data.goal_high) == (4, 6)
    assert re.search(r"\bGOAL_ANYWHERE = true;", emit_declarations(data))
    model = NativeModel(data)
    far = model.initial_state()._replace(x=-500 * data.scale, y=300 * data.scale)  # off the road, far away
    assert [model.goal(far, k) for k in (3, 4, 6, 7)] == [False, True, True, False]
    assert model.dist_goal(far) == 0.0
    rows = np.array([far, model.initial_state()], dtype=np.int64)
    batch = batch_model(data)
    assert batch.goal(rows, 5).tolist() == [True, True] and batch.goal(rows, 7).tolist() == [False, False]
    assert batch.goal(rows, np.array([3, 4])).tolist() == [False, True]
    assert batch.dist_goal(rows).tolist() == [0.0, 0.0]

    source = write(tmp_path, "timed.xml", time_goal())
    result = compile_file(source)
    assert result.ok, [d.message for d in result.diagnostics]
    assert ("goal at any position (the file's goal has no position; `dist_goal()` reads 0) at scenario time t in "
            "[2, 3] s") in result.proved[-1]
    (warning,) = [d for d in result.diagnostics if d.code == "W0723"]
    assert warning.message.endswith("`goal()` holds at any speed and heading in the window")


#: The progress automaton of stdlib/driving.ra, cut down: its progress reads `dist_goal()`, and so does `d`.
PROGRESS = """\
automaton Progress {
    input near : bool
    input prog : bool
    input d    : real in [0, 500]
    reward sa
    objective sa
    sample every 0.1
    horizon 2
    initial location Normal { sa' == 1 }
    location Stalled        { sa' == -1 }
    edge Normal -> Stalled when !prog || near || d > 100
    edge Stalled -> Normal when prog && !near && d <= 100
    model {
        scenario "%s"
        bind near = mindist() < 3 * collision_distance
        bind prog = dist_goal() < prev(dist_goal())
        bind d    = fmin(dist_goal(), 500)
    }
}
"""


def test_a_binding_that_reads_dist_goal_of_a_goal_anywhere_warns(tmp_path: Path) -> None:
    """A goal of time alone makes `dist_goal()` 0 everywhere, so stdlib/driving.ra's progress `prog =
    dist_goal() < prev(dist_goal())` never held, and only the `proved:` line said `dist_goal()` reads 0:
    W0727 at each binding that reads it, none at the one that does not, none when the goal has a position."""
    (tmp_path / "survive.xml").write_bytes(goal_anywhere())
    (tmp_path / "ramp.xml").write_bytes(ramp(10.0))
    source = tmp_path / "progress.ra"
    source.write_text(PROGRESS % "survive.xml", encoding="utf-8")
    found = warnings_of(source, "W0727")
    text = PROGRESS % "survive.xml"
    assert [d.span.line for d in found] == [i for i, line in enumerate(text.splitlines(), 1)
                                            if line.startswith(("        bind prog", "        bind d "))]
    assert found[0].message == ("binding `prog = dist_goal() < prev(dist_goal())` reads `dist_goal()`, which is 0 "
                                "everywhere: the goal of `survive.xml` has no position")
    assert "anywhere at scenario time t in [0, 8] s" in found[0].notes[0].message
    assert "`x > prev(x)`" in found[0].hints[0]
    source.write_text(PROGRESS % "ramp.xml", encoding="utf-8")
    assert warnings_of(source, "W0727") == []


def test_a_goal_state_without_a_position_makes_the_whole_goal_anywhere(tmp_path: Path) -> None:
    """CommonRoad's goal is reached when one of its states is: one of them of time alone holds anywhere,
    whatever region the others name."""
    box = RectOccupancy(rect_center=shapely.Point(45.0, 1.75), length=10.0, width=3.5, orientation=0.0)
    path = tmp_path / "mixed.xml"
    path.write_bytes(time_goal(CustomState(time_step=Interval(20, 30), position=box),
                               CustomState(time_step=Interval(20, 30))))
    goal = load_scenario(path).goal
    assert goal.anywhere and goal.regions == ()
    path.write_bytes(time_goal(CustomState(time_step=Interval(20, 30), position=box)))
    assert not load_scenario(path).goal.anywhere


# ---------------------------------------------------------------- the goal's centre
def test_the_centre_of_a_curved_lanelet_goal_lies_on_the_lanelet(tmp_path: Path) -> None:
    path = tmp_path / "ring.xml"
    path.write_bytes(curved_lane_goal())
    scenario = load_scenario(path)
    x, y = scenario.goal.center
    assert (x, y) == pytest.approx((0.0, -RING_RADIUS), abs=1e-9)  # the centre line's midpoint
    settings = TinySettings()
    data = build_model_data(scenario, settings.model_spec(path))
    assert (data.goal_cx, data.goal_cy) == (0, -round(RING_RADIUS * data.scale))
    declarations = emit_declarations(data)
    assert re.search(rf"\bGOAL_CY = {data.goal_cy};", declarations)


def test_a_region_whose_vertex_mean_lies_outside_gets_a_point_inside() -> None:
    ell = Polygon(((0.0, 0.0), (10.0, 0.0), (10.0, 1.0), (1.0, 1.0), (1.0, 10.0), (0.0, 10.0)))
    point = inside_point(ell)
    assert 0 < point[0] < 10 and 0 < point[1] < 10 and (point[0] < 1 or point[1] < 1)
    square = Polygon(((0.0, 0.0), (2.0, 0.0), (2.0, 2.0), (0.0, 2.0)))
    assert inside_point(square) == (1.0, 1.0)  # a convex region: its vertex mean, as before
    assert Goal((ell,), 0.0, 1.0).center == point


def flat_goal(shape) -> bytes:
    """:func:`window`'s road with the goal region ``shape`` (a commonroad-io occupancy)."""
    scenario, problems = StraightRoad(100.0, EgoStart(10.0, 1.75, 0.0, 10.0), GoalBox(40.0, 50.0)).build("flat")
    (problem,) = problems.planning_problem_dict.values()
    goal = GoalRegion([CustomState(time_step=Interval(0, 40), position=shape)])
    problems = PlanningProblemSet([PlanningProblem(PLANNING_PROBLEM_ID, problem.initial_state, goal)])
    return commonroad_xml(scenario, problems, "flat", Tag.SINGLE_LANE)


def test_a_goal_region_without_area_is_refused(tmp_path: Path) -> None:
    """A polygon on one line (valid CommonRoad) was taken silently, and `goal()` never held; a rectangle
    of length 0 (commonroad-io reads it) ended ``rac check`` in an internal error (shapely, finding a
    point inside it). Both are E0712 now, naming the shape."""
    line = flat_goal(PolygonOccupancy(shapely.Polygon([(40.0, 1.0), (50.0, 1.0), (45.0, 1.0)])))
    path = write(tmp_path, "line.xml", line)
    (error,) = [d for d in compile_file(path).diagnostics if d.is_error]
    assert error.code == "E0712"
    assert error.message == (f"cannot load the scenario: {tmp_path / 'line.xml'}: goal of planning problem 100 has a "
                             "goal region without area (a polygon whose vertices lie on one line): `goal()` could "
                             "never hold in it")
    flat = window(0.0, 4.0).decode("utf-8")
    flat, changed = re.subn(r"(<goalState>.*?<length>)[^<]*", r"\g<1>0", flat, count=1, flags=re.S)
    assert changed
    path = write(tmp_path, "flat.xml", flat.encode("utf-8"))
    (error,) = [d for d in compile_file(path).diagnostics if d.is_error]
    assert error.code == "E0712" and "has a goal region without area (a 0 m × 3.5 m rectangle)" in error.message
    # a bowtie's signed area is 0, but its two triangles hold the goal: accepted
    bowtie = flat_goal(PolygonOccupancy(shapely.Polygon([(40.0, 0.0), (50.0, 3.5), (50.0, 0.0), (40.0, 3.5)])))
    assert compile_file(write(tmp_path, "bowtie.xml", bowtie)).ok


def test_a_goal_lanelet_without_area_is_refused(tmp_path: Path) -> None:
    """A goal lanelet 0 m long (both bounds a single point twice over, as map converters write stubs)
    was taken as a goal region without a word although `goal()` could never hold in it, while the same
    region given as a rectangle or polygon is refused: it is E0712 now, naming the lanelet."""
    scenario, problems = StraightRoad(100.0, EgoStart(10.0, 1.75, 0.0, 10.0), GoalBox(40.0, 50.0)).build("stub")
    stub = np.array([[100.0, 0.0], [100.0, 0.0]]), np.array([[100.0, 3.5], [100.0, 3.5]])
    scenario.add_objects(Lanelet(stub[1], (stub[0] + stub[1]) / 2, stub[0], 7, lanelet_type={LaneletType.URBAN}))
    (problem,) = problems.planning_problem_dict.values()
    goal = GoalRegion([CustomState(time_step=Interval(0, 40), position=RectOccupancy(
        rect_center=shapely.Point(100.0, 1.75), length=1.0, width=1.0, orientation=0.0))],
        lanelets_of_goal_position={0: [7]})
    problems = PlanningProblemSet([PlanningProblem(PLANNING_PROBLEM_ID, problem.initial_state, goal)])
    path = write(tmp_path, "stub.xml", commonroad_xml(scenario, problems, "stub", Tag.SINGLE_LANE))
    (error,) = [d for d in compile_file(path).diagnostics if d.is_error]
    assert error.code == "E0712"
    assert error.message == (f"cannot load the scenario: {tmp_path / 'stub.xml'}: goal of planning problem 100 has a "
                             "goal region without area (lanelet 7, whose bounds enclose no area): `goal()` could "
                             "never hold in it")


# ---------------------------------------------------------------- the start
def test_a_start_inside_an_obstacle_is_a_warning(tmp_path: Path) -> None:
    (warning,) = warnings_of(write(tmp_path, "blocked.xml", blocked_start()), "W0724")
    assert warning.message == ("the ego starts in a collision: `collide()` holds at the start (the nearest obstacle is "
                               "static obstacle 31 (parkedVehicle) at (13.5, 1.75))")
    assert not warnings_of(write(tmp_path, "ramp.xml", ramp(start_x=5.0)), "W0724")


def test_the_ego_recorded_as_an_obstacle_is_said_and_not_a_collision(tmp_path: Path) -> None:
    """The ego's own recorded run (an obstacle starting at the planning problem's time, position and
    heading) is left out: no W0724 (`collide()` at the start), and the `proved:` line names it."""
    road = StraightRoad(100.0, EgoStart(10.0, 1.75, 0.0, 5.0), GoalBox(40.0, 50.0),
                        obstacles=(Block(11, 10.0, 1.75, velocity=5.0), Block(12, 60.0, 1.75)))
    path = write(tmp_path, "recorded.xml", road.xml("recorded"))
    assert not warnings_of(path, "W0724")
    assert ("1 obstacle (obstacle 11 left out: the planning problem's own vehicle, recorded from its start)"
            in compile_file(path).proved[-1])


# ---------------------------------------------------------------- the loader's messages
def test_version_and_time_step_messages(tmp_path: Path) -> None:
    text = ramp(start_x=5.0).decode("utf-8")
    path = tmp_path / "scene.xml"
    path.write_text(text.replace(' commonRoadVersion="2020a"', ""), encoding="utf-8")
    with pytest.raises(ScenarioError) as caught:
        load_scenario(path)
    assert str(caught.value) == (f"{path}: has no commonRoadVersion attribute on its <commonRoad> element; "
                                 "commonroad-io reads the XML formats 2018b and 2020a")

    path.write_text(text.replace('commonRoadVersion="2020a"', 'commonRoadVersion="2018b"'), encoding="utf-8")
    with pytest.raises(ScenarioError) as caught:
        load_scenario(path)
    assert "is labelled commonRoadVersion=\"2018b\" but has no `tags` attribute" in str(caught.value)
    assert "is it a 2020a file labelled 2018b?" in str(caught.value)

    for step in ("0", "-0.1"):
        path.write_text(text.replace('timeStepSize="0.1"', f'timeStepSize="{step}"'), encoding="utf-8")
        with pytest.raises(InconsistentScenarioError) as inconsistent:
            load_scenario(path)
        assert inconsistent.value.code == "E0718" and inconsistent.value.line == 2
        assert f'has timeStepSize="{step}" s, not positive' in str(inconsistent.value)


def test_traffic_rules_the_model_does_not_read_are_w0730(tmp_path: Path) -> None:
    """Regression: a traffic light, a stop sign and their stop line (an urban scene's) were read by commonroad-io
    and ignored without a word, so a shield or a proof said nothing of running the red light. W0730 counts them;
    signs that are all speed limits are said so, with `max_speed` as the hint; a file without any has none."""
    (tmp_path / "lights.xml").write_bytes(traffic_rules())
    (tmp_path / "limits.xml").write_bytes(traffic_rules("limits"))
    (tmp_path / "ramp.xml").write_bytes(ramp(10.0))
    source = tmp_path / "rules.ra"
    source.write_text(PROGRESS % "lights.xml", encoding="utf-8")
    (found,) = warnings_of(source, "W0730")
    assert found.message == ("`lights.xml` has 1 traffic light, 1 traffic sign and 1 stop line, which the model "
                             "does not read: runs ignore them")
    assert "`bind pastStop" in found.hints[0] and "max_speed" not in found.hints[0]
    source.write_text(PROGRESS % "limits.xml", encoding="utf-8")
    (limits,) = warnings_of(source, "W0730")
    assert limits.message.startswith("`limits.xml` has 2 speed-limit signs, which the model does not read")
    assert limits.hints[0].startswith("set the model's `max_speed` to the limit")
    source.write_text(PROGRESS % "ramp.xml", encoding="utf-8")
    assert warnings_of(source, "W0730") == []
