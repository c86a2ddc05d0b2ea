"""rac.model.commonroad.load_scenario and the left-turn example (rac.model.intersection).

- the example is built in a temporary folder, read back and compared with the numbers it was built
  from; the committed examples/left_turn/left_turn.xml is the same file;
- every way a file can be unusable gives a ScenarioError that names the file and the element
  (broken files are made by editing the example's XML text);
- the shared CommonRoad scenarios (../shared/scenarios, next to the repository) load quickly; those
  tests skip when the folder is absent.
"""

from __future__ import annotations

import contextlib
import dataclasses
import math
import re
import subprocess
import sys
from pathlib import Path

import pytest

pytest.importorskip("commonroad")

from conftest import REPOSITORY, rac_env  # noqa: E402

from rac.model import intersection  # noqa: E402
from rac.model.commonroad import CIRCLE_VERTICES, Polygon, Scenario, ScenarioError, load_scenario  # noqa: E402
from rac.model.intersection import (  # noqa: E402
    DT,
    EGO_START,
    GOAL_CENTER,
    GOAL_SIZE,
    OBSTACLES,
    STEPS,
    build_left_turn,
    write_left_turn,
)

COMMITTED = REPOSITORY / "examples" / "left_turn" / "left_turn.xml"
SHARED = Path(__file__).resolve().parents[3] / "shared" / "scenarios"


@pytest.fixture(scope="module")
def example_xml(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return write_left_turn(tmp_path_factory.mktemp("left_turn") / "left_turn.xml")


@pytest.fixture(scope="module")
def example(example_xml: Path) -> Scenario:
    return load_scenario(example_xml)


def edited(tmp_path: Path, example_xml: Path, name: str, pattern: str, replacement: str, count: int = 1) -> Path:
    """A copy of the example with ``pattern`` (a regular expression, DOTALL) replaced ``count`` times (0: all)."""
    text, made = re.subn(pattern, replacement, example_xml.read_text(encoding="utf-8"), count=count, flags=re.S)
    assert made, f"the pattern {pattern!r} is not in the example"
    path = tmp_path / name
    path.write_text(text, encoding="utf-8")
    return path


def error_of(path: Path, **kwargs) -> ScenarioError:
    with pytest.raises(ScenarioError) as caught:
        load_scenario(path, **kwargs)
    error = caught.value
    assert error.path == str(path)
    assert str(error).startswith(f"{path}: "), str(error)
    assert path.name in str(error)
    return error


def signed_area(polygon: Polygon) -> float:
    points = polygon.points
    return sum(x0 * y1 - x1 * y0 for (x0, y0), (x1, y1) in zip(points, points[1:] + points[:1])) / 2


GOAL_POSITION = r"(<goalState>.*?)<position>.*?</position>"


# ---------------------------------------------------------------- the left-turn example
def test_the_example_reads_back_as_it_was_built(example: Scenario, example_xml: Path) -> None:
    assert example.name == "ZAM_LeftTurn-1_1_T-1"
    assert example.path == str(example_xml)
    assert example.dt == DT
    assert example.planning_problem_id == intersection.PLANNING_PROBLEM_ID

    x, y, heading, velocity = EGO_START
    assert (example.ego.x, example.ego.y, example.ego.heading, example.ego.velocity) == (x, y, heading, velocity)
    assert example.ego.acceleration == 0.0 and example.ego.time == 0.0
    assert heading == pytest.approx(math.pi / 2, abs=1e-6)

    (region,) = example.goal.regions
    (gx, gy), (length, width) = GOAL_CENTER, GOAL_SIZE
    assert sorted(region.points) == sorted([(gx - length / 2, gy - width / 2), (gx - length / 2, gy + width / 2),
                                            (gx + length / 2, gy - width / 2), (gx + length / 2, gy + width / 2)])
    assert example.goal.center == pytest.approx(GOAL_CENTER)
    assert (example.goal.time_low, example.goal.time_high) == (0.0, STEPS * DT)
    assert example.goal.velocity is None and example.goal.orientation is None

    assert [obstacle.id for obstacle in example.obstacles] == [spec.id for spec in OBSTACLES]
    for obstacle, spec in zip(example.obstacles, OBSTACLES):
        assert not obstacle.static and obstacle.kind == "car"
        assert (obstacle.length, obstacle.width) == (spec.length, spec.width)
        assert len(obstacle.waypoints) == STEPS + 1  # the initial state, then every trajectory state
        assert [w.time for w in obstacle.waypoints] == [round(k * DT, 9) for k in range(STEPS + 1)]
        assert {w.velocity for w in obstacle.waypoints} == {spec.velocity}
        first, last = obstacle.waypoints[0], obstacle.waypoints[-1]
        assert math.hypot(first.x, first.y) == pytest.approx(math.hypot(spec.start_distance, 1.75))
        # constant velocity along the heading: the last waypoint is where the first one leads (the file holds
        # headings to 6 decimals, so over the ~60 m of a trajectory the exact line is up to 2e-5 m away)
        travelled = spec.velocity * STEPS * DT
        assert last.x == pytest.approx(first.x + travelled * math.cos(first.heading), abs=1e-4)
        assert last.y == pytest.approx(first.y + travelled * math.sin(first.heading), abs=1e-4)


def test_the_example_has_a_sensible_road(example: Scenario) -> None:
    shapely = pytest.importorskip("shapely")
    assert len(example.road) == 20  # 8 arm lanelets and 12 connectors
    assert all(signed_area(polygon) > 0 for polygon in example.road)  # counter-clockwise
    assert all(polygon.points[0] != polygon.points[-1] for polygon in example.road)
    road = shapely.union_all([shapely.Polygon(polygon.points) for polygon in example.road])
    assert road.geom_type == "Polygon" and not road.interiors  # one piece, no holes
    assert road.covers(shapely.Polygon(example.goal.regions[0].points))
    assert road.contains(shapely.Point(example.ego.x, example.ego.y))
    for obstacle in example.obstacles:
        assert road.covers(shapely.MultiPoint([(w.x, w.y) for w in obstacle.waypoints]))
    # the left-turn connector (lanelet 11) joins the ego's lane to the goal's lane
    network = build_left_turn()[0].lanelet_network
    left_turn = network.find_lanelet_by_id(11)
    assert left_turn.predecessor == [1] and left_turn.successor == [8]
    start, end = left_turn.center_vertices[0], left_turn.center_vertices[-1]
    assert tuple(start) == pytest.approx((1.75, -8.0)) and tuple(end) == pytest.approx((-8.0, 1.75))


def test_the_scenario_picture_labels_its_axes_in_metres(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """The left-turn picture's axes had numbers but no labels: a reader could not tell they are metres."""
    from matplotlib.figure import Figure

    from rac.model.intersection import render_left_turn

    drawn: list[Figure] = []
    savefig = Figure.savefig

    def keep(figure: Figure, *args: object, **options: object) -> None:
        drawn.append(figure)
        savefig(figure, *args, **options)  # type: ignore[arg-type]

    monkeypatch.setattr(Figure, "savefig", keep)
    render_left_turn(write_left_turn(tmp_path / "x.xml"), tmp_path / "x.png")
    (ax,) = drawn[0].axes
    assert (ax.get_xlabel(), ax.get_ylabel()) == ("x (m)", "y (m)")
    assert ax.get_aspect() == 1.0


def test_the_committed_example_is_a_fresh_build(example_xml: Path) -> None:
    def stable(data: bytes) -> bytes:  # the date is pinned already; ignore it anyway
        return re.sub(rb'\sdate="[^"]*"', b"", data, count=1)

    assert COMMITTED.exists(), "run: python -m rac.model.intersection examples/left_turn/left_turn.xml"
    assert stable(COMMITTED.read_bytes()) == stable(example_xml.read_bytes()), (
        "examples/left_turn/left_turn.xml is stale: python -m rac.model.intersection "
        "examples/left_turn/left_turn.xml --png examples/left_turn/left_turn.png")
    assert load_scenario(COMMITTED) == dataclasses.replace(load_scenario(example_xml), path=str(COMMITTED))


def test_builds_are_reproducible_and_seeds_move_the_cars(tmp_path: Path, example: Scenario) -> None:
    again = write_left_turn(tmp_path / "again.xml")
    assert again.read_bytes() == write_left_turn(tmp_path / "again2.xml").read_bytes()
    seeded = load_scenario(write_left_turn(tmp_path / "seed7.xml", seed=7))
    assert seeded.name == "ZAM_LeftTurn-1_8_T-1"
    assert seeded.road == example.road and seeded.goal == example.goal and seeded.ego == example.ego
    assert seeded.obstacles != example.obstacles
    for moved, original in zip(seeded.obstacles, example.obstacles):
        assert moved.waypoints[0].heading == original.waypoints[0].heading
        start_shift = math.hypot(moved.waypoints[0].x - original.waypoints[0].x,
                                 moved.waypoints[0].y - original.waypoints[0].y)
        assert start_shift <= 4.0 + 1e-6
        assert abs(moved.waypoints[0].velocity - original.waypoints[0].velocity) <= 1.0 + 1e-6
    assert load_scenario(write_left_turn(tmp_path / "seed7b.xml", seed=7)).obstacles == seeded.obstacles
    with pytest.raises(ValueError):
        build_left_turn(-1)


def test_the_command_writes_the_example_and_a_picture(tmp_path: Path, example_xml: Path) -> None:
    out, png = tmp_path / "out.xml", tmp_path / "out.png"
    result = subprocess.run([sys.executable, "-m", "rac.model.intersection", str(out), "--png", str(png)],
                            env=rac_env(), capture_output=True, text=True, timeout=120, check=False)
    assert result.returncode == 0, result.stdout + result.stderr
    assert f"wrote {out}" in result.stdout and f"wrote {png}" in result.stdout
    assert out.read_bytes() == example_xml.read_bytes()
    assert png.read_bytes().startswith(b"\x89PNG") and png.stat().st_size > 10_000


def test_the_command_says_what_it_cannot_write_and_titles_the_files_trajectories(
        tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch) -> None:
    """A folder or a missing one where the file goes ended in a traceback; the picture's title said the
    default's "trajectories to 10 s" whatever --steps wrote."""
    from matplotlib.figure import Figure

    from rac.model.intersection import main

    for out, said in ((tmp_path, "Is a directory"), (tmp_path / "missing" / "x.xml", "No such file or directory")):
        with pytest.raises(SystemExit) as stop:
            main([str(out)])
        assert stop.value.code == 2
        error = capsys.readouterr().err
        assert said in error and str(out) in error and "Traceback" not in error, error
    titles: list[str] = []
    monkeypatch.setattr(Figure, "savefig", lambda figure, *args, **options: titles.append(figure.axes[0].get_title()))
    assert main([str(tmp_path / "short.xml"), "--steps", "50", "--png", str(tmp_path / "short.png")]) == 0
    assert titles == ["ZAM_LeftTurn-1_1_T-1: left turn, t = 0 s (trajectories to 5 s)"]


# ---------------------------------------------------------------- what the loader accepts
def test_goal_shapes_circle_group_polygon_and_lanelets(tmp_path: Path, example_xml: Path) -> None:
    circle = "<position><circle><radius>2.0</radius><center><x>-22.0</x><y>1.75</y></center></circle></position>"
    (region,) = load_scenario(edited(tmp_path, example_xml, "circle.xml", GOAL_POSITION, rf"\1{circle}")).goal.regions
    assert len(region.points) == CIRCLE_VERTICES
    assert all(math.hypot(x + 22.0, y - 1.75) == pytest.approx(2.0) for x, y in region.points)
    assert signed_area(region) > 0

    group = ("<position><rectangle><length>2</length><width>1</width><center><x>-30</x><y>1.75</y></center>"
             "</rectangle><polygon><point><x>-20</x><y>0</y></point><point><x>-18</x><y>0</y></point>"
             "<point><x>-19</x><y>3</y></point></polygon></position>")
    goal = load_scenario(edited(tmp_path, example_xml, "group.xml", GOAL_POSITION, rf"\1{group}")).goal
    assert [len(region.points) for region in goal.regions] == [4, 3]
    assert goal.center == pytest.approx((-30.0, 1.75))  # the first region's
    assert sorted(goal.regions[1].points) == [(-20.0, 0.0), (-19.0, 3.0), (-18.0, 0.0)]

    lanelets = '<position><lanelet ref="8"/><lanelet ref="4"/></position>'
    scenario = load_scenario(edited(tmp_path, example_xml, "lanelets.xml", GOAL_POSITION, rf"\1{lanelets}"))
    by_id = dict(zip(sorted([1, 2, 3, 4, 5, 6, 7, 8] + [10 * k + t for k in (1, 2, 3, 4) for t in (1, 2, 3)]),
                     scenario.road))
    assert scenario.goal.regions == (by_id[8], by_id[4])


def test_goal_time_velocity_and_orientation(tmp_path: Path, example_xml: Path) -> None:
    path = edited(tmp_path, example_xml, "constrained.xml", r"(<goalState>.*?</time>)",
                  r"\1<orientation><intervalStart>3.0</intervalStart><intervalEnd>3.2</intervalEnd></orientation>"
                  r"<velocity><intervalStart>0.0</intervalStart><intervalEnd>5.0</intervalEnd></velocity>")
    text = path.read_text(encoding="utf-8")
    text = re.sub(r"(<goalState>.*?<time>).*?(</time>)",
                  r"\1<intervalStart>20</intervalStart><intervalEnd>70</intervalEnd>\2", text, count=1, flags=re.S)
    path.write_text(text, encoding="utf-8")
    goal = load_scenario(path).goal
    assert (goal.time_low, goal.time_high) == (2.0, 7.0)
    assert goal.velocity == (0.0, 5.0)
    assert goal.orientation == pytest.approx((3.0, 3.2))


def test_several_planning_problems(tmp_path: Path, example_xml: Path) -> None:
    second = (r'\g<0>\n  <planningProblem id="70"><initialState><position><point><x>-1.75</x><y>20.0</y></point>'
              r"</position><orientation><exact>-1.5</exact></orientation><time><exact>3</exact></time>"
              r"<velocity><exact>4.0</exact></velocity><yawRate><exact>0.0</exact></yawRate>"
              r"<slipAngle><exact>0.0</exact></slipAngle></initialState><goalState><position><rectangle>"
              r"<length>4</length><width>3</width><center><x>-1.75</x><y>-30</y></center></rectangle></position>"
              r"<time><intervalStart>50</intervalStart><intervalEnd>50</intervalEnd></time></goalState></planningProblem>")
    path = edited(tmp_path, example_xml, "two.xml", r"</planningProblem>", second)
    first = load_scenario(path)  # the smallest id
    assert first.planning_problem_id == 70 and (first.ego.x, first.ego.y, first.ego.time) == (-1.75, 20.0, 0.3)
    assert (first.goal.time_low, first.goal.time_high) == (5.0, 5.0)
    chosen = load_scenario(path, planning_problem_id=100)
    assert chosen.planning_problem_id == 100 and chosen.ego.y == -18.0
    error = error_of(path, planning_problem_id=3)
    assert error.element == "planning problem 3" and "does not exist (the file has 70, 100)" in str(error)


def test_obstacle_shapes_become_rectangles(tmp_path: Path, example_xml: Path) -> None:
    shape = r'(<dynamicObstacle id="51">.*?<shape>).*?(</shape>)'
    circle = load_scenario(edited(tmp_path, example_xml, "circle.xml", shape,
                                  r"\1<circle><radius>1.5</radius></circle>\2"))
    assert (circle.obstacles[0].length, circle.obstacles[0].width) == (3.0, 3.0)

    polygon = (r"\1<polygon><point><x>-1</x><y>-1</y></point><point><x>3</x><y>-1</y></point>"
               r"<point><x>3</x><y>1.5</y></point><point><x>-1</x><y>1.5</y></point></polygon>\2")
    moved = load_scenario(edited(tmp_path, example_xml, "polygon.xml", shape, polygon)).obstacles[0]
    assert (moved.length, moved.width) == (4.0, 2.5)
    # the bounding box's centre is 1 m ahead and 0.25 m left of the position: the car heads east
    assert (moved.waypoints[0].x, moved.waypoints[0].y) == pytest.approx((-29.0, -1.5))

    shifted = (r"\1<rectangle><length>4.5</length><width>1.8</width><originXShift>-1.0</originXShift>"
               r"</rectangle>\2")
    car = load_scenario(edited(tmp_path, example_xml, "shifted.xml", shape, shifted)).obstacles[0]
    assert (car.length, car.width, car.waypoints[0].x, car.waypoints[0].y) == (4.5, 1.8, -29.0, -1.75)


def test_a_shape_placed_off_the_obstacle_position_stays_there(tmp_path: Path, example_xml: Path) -> None:
    """A CommonRoad 2020a rectangle or circle may carry its own <center> and <orientation> in the obstacle's
    frame. commonroad-io reads past both: the obstacle stood at its position, unturned, silently."""
    shape = r'(<dynamicObstacle id="51">.*?<shape>).*?(</shape>)'  # heading east from (-30, -1.75)
    turned = (r"\1<rectangle><length>4</length><width>2</width><orientation>1.5707963267948966</orientation>"
              r"<center><x>3</x><y>1</y></center></rectangle>\2")
    car = load_scenario(edited(tmp_path, example_xml, "turned.xml", shape, turned)).obstacles[0]
    assert (car.length, car.width) == pytest.approx((2.0, 4.0))
    assert (car.waypoints[0].x, car.waypoints[0].y) == pytest.approx((-27.0, -0.75))
    circle = r"\1<circle><radius>1</radius><center><x>-2</x><y>0</y></center></circle>\2"
    ball = load_scenario(edited(tmp_path, example_xml, "circle.xml", shape, circle)).obstacles[0]
    assert (ball.length, ball.width, ball.waypoints[0].x, ball.waypoints[0].y) == (2.0, 2.0, -32.0, -1.75)
    at_origin = r"\1<rectangle><length>4</length><width>2</width><orientation>0</orientation>" \
                r"<center><x>0</x><y>0</y></center></rectangle>\2"  # CommonRoad's files write these zeros
    plain = load_scenario(edited(tmp_path, example_xml, "plain.xml", shape, at_origin)).obstacles[0]
    assert (plain.length, plain.width, plain.waypoints[0].x, plain.waypoints[0].y) == (4.0, 2.0, -30.0, -1.75)
    broken = r"\1<rectangle><length>4</length><width>2</width><center><x>far</x><y>0</y></center></rectangle>\2"
    error = error_of(edited(tmp_path, example_xml, "broken.xml", shape, broken))
    assert error.element == "dynamic obstacle 51" and "`far` as its shape's <center> <x>, not a number" in str(error)


def test_missing_velocity_and_orientation_come_from_the_motion(tmp_path: Path, example_xml: Path) -> None:
    def strip(match: re.Match[str]) -> str:
        body = re.sub(r"<trajectory>.*</trajectory>", lambda m: re.sub(
            r"<(velocity|orientation|acceleration)>.*?</\1>", "", m.group(0), flags=re.S), match.group(0), flags=re.S)
        return body

    text = re.sub(r'<dynamicObstacle id="52">.*?</dynamicObstacle>', strip,
                  example_xml.read_text(encoding="utf-8"), count=1, flags=re.S)
    path = tmp_path / "bare.xml"
    path.write_text(text, encoding="utf-8")
    car = load_scenario(path).obstacles[1]
    assert car.id == 52 and len(car.waypoints) == STEPS + 1
    assert all(w.velocity == pytest.approx(7.0) for w in car.waypoints)
    assert all(w.heading == pytest.approx(-math.pi / 2, abs=1e-6) for w in car.waypoints)


def test_static_obstacles(tmp_path: Path, example_xml: Path) -> None:
    parked = (r'<staticObstacle id="60"><type>parkedVehicle</type><shape><rectangle><length>4</length>'
              r"<width>2</width></rectangle></shape><initialState><position><point><x>-40</x><y>5</y></point>"
              r"</position><orientation><exact>0.1</exact></orientation><time><exact>0</exact></time>"
              r"<velocity><exact>0.0</exact></velocity><yawRate><exact>0.0</exact></yawRate>"
              r"<slipAngle><exact>0.0</exact></slipAngle></initialState></staticObstacle>\n  \g<0>")
    scenario = load_scenario(edited(tmp_path, example_xml, "parked.xml", r'<dynamicObstacle id="51">', parked))
    obstacle = scenario.obstacles[-1]
    assert (obstacle.id, obstacle.static, obstacle.kind, obstacle.length, obstacle.width) == (
        60, True, "parkedVehicle", 4.0, 2.0)
    (waypoint,) = obstacle.waypoints
    assert (waypoint.time, waypoint.x, waypoint.y, waypoint.heading, waypoint.velocity) == (0.0, -40.0, 5.0, 0.1, 0.0)


# ---------------------------------------------------------------- what it rejects, and how it says so
def test_missing_file(tmp_path: Path) -> None:
    error = error_of(tmp_path / "nowhere.xml")
    assert error.element is None and str(error).endswith("nowhere.xml: does not exist")
    assert "is a directory" in str(error_of(tmp_path))
    # a dangling link is there: its target is what is missing
    (tmp_path / "link.xml").symlink_to(tmp_path / "moved.xml")
    error = error_of(tmp_path / "link.xml")
    assert error.element is None and str(error).endswith(f"link.xml: is a symbolic link to {tmp_path / 'moved.xml'}, "
                                                         "which does not exist")


def test_not_xml(tmp_path: Path) -> None:
    path = tmp_path / "notes.xml"
    path.write_text("this is not XML at all\n", encoding="utf-8")
    error = error_of(path)
    assert error.element is None and "notes.xml: is not XML (line 1" in str(error)
    path.write_bytes(b"")
    assert str(error_of(path)) == f"{path}: is empty: it holds no XML element, not a CommonRoad scenario"


def test_a_compressed_scenario_says_so(tmp_path: Path) -> None:
    """CommonRoad's scenarios are downloaded as zip archives: a zip or a gzip-compressed file was "not XML
    (line 1, column 1: not well-formed (invalid token))", which did not say what the file is or what to do."""
    import gzip
    import zipfile

    xml = intersection.left_turn_bytes()
    archive = tmp_path / "scenario.zip"
    with zipfile.ZipFile(archive, "w") as bundle:
        bundle.writestr("left_turn.xml", xml)
    assert str(error_of(archive)) == (f"{archive}: is a zip archive, not a CommonRoad XML file: unpack it and name "
                                      "the .xml file")
    packed = tmp_path / "left_turn.xml.gz"
    packed.write_bytes(gzip.compress(xml))
    assert str(error_of(packed)) == (f"{packed}: is gzip-compressed, not a CommonRoad XML file: decompress it "
                                     "(gunzip) and name the .xml file")


def test_not_commonroad(tmp_path: Path, example_xml: Path) -> None:
    path = tmp_path / "other.xml"
    path.write_text("<?xml version='1.0'?><osm version='0.6'/>", encoding="utf-8")
    assert "other.xml: is not a CommonRoad file (its root element is <osm>" in str(error_of(path))
    newer = edited(tmp_path, example_xml, "newer.xml", 'commonRoadVersion="2020a"', 'commonRoadVersion="2024a"')
    assert "newer.xml: has CommonRoad version '2024a'; commonroad-io reads the XML formats 2018b and 2020a" in str(
        error_of(newer))
    no_dt = edited(tmp_path, example_xml, "no_dt.xml", 'timeStepSize="0.1"', 'timeStepSize="fast"')
    assert "no_dt.xml: has no valid timeStepSize" in str(error_of(no_dt))


def test_no_planning_problem(tmp_path: Path, example_xml: Path) -> None:
    path = edited(tmp_path, example_xml, "no_problem.xml", r"<planningProblem .*?</planningProblem>\s*", "")
    error = error_of(path)
    assert error.element is None
    assert str(error) == f"{path}: has no planning problem (rac needs one for the ego's start and goal)"


def test_obstacle_without_trajectory(tmp_path: Path, example_xml: Path) -> None:
    path = edited(tmp_path, example_xml, "no_trajectory.xml",
                  r'(<dynamicObstacle id="52">.*?)<trajectory>.*?</trajectory>', r"\1")
    error = error_of(path)
    assert error.element == "dynamic obstacle 52"
    assert str(error) == f"{path}: dynamic obstacle 52 has no trajectory prediction"

    occupancy_set = (r"\1<occupancySet><occupancy><shape><rectangle><length>4</length><width>2</width>"
                     r"<center><x>0</x><y>0</y></center></rectangle></shape><time><exact>1</exact></time>"
                     r"</occupancy></occupancySet>")
    path = edited(tmp_path, example_xml, "set_based.xml",
                  r'(<dynamicObstacle id="53">.*?)<trajectory>.*?</trajectory>', occupancy_set)
    error = error_of(path)
    assert error.element == "dynamic obstacle 53" and "has a set-based prediction" in str(error)


def test_unsupported_goal_shape(tmp_path: Path, example_xml: Path) -> None:
    point = r"\1<position><point><x>-22.0</x><y>1.75</y></point></position>"
    path = edited(tmp_path, example_xml, "point_goal.xml", GOAL_POSITION, point)
    error = error_of(path)
    assert error.element == "goal of planning problem 100"
    assert str(error).startswith(f"{path}: goal of planning problem 100 has an unsupported shape (<point>)")

    path = edited(tmp_path, example_xml, "no_goal_position.xml", GOAL_POSITION, r"\1")
    assert load_scenario(path).goal.anywhere  # a goal of time alone (tests/model/test_scenario_goal.py)

    path = edited(tmp_path, example_xml, "unknown_lanelet.xml", GOAL_POSITION,
                  r'\1<position><lanelet ref="99"/></position>')
    error = error_of(path)
    assert str(error) == f"{path}: goal of planning problem 100 refers to lanelet 99, which the file does not define"

    two = (r'\g<0><goalState><position><rectangle><length>2</length><width>2</width><center><x>0</x><y>0</y>'
           r"</center></rectangle></position><time><intervalStart>0</intervalStart><intervalEnd>10</intervalEnd>"
           r"</time></goalState>")
    path = edited(tmp_path, example_xml, "two_goals.xml", r"</goalState>", two)
    assert "has 2 goal states with different time" in str(error_of(path))


def test_broken_elements_are_named(tmp_path: Path, example_xml: Path) -> None:
    path = edited(tmp_path, example_xml, "no_shape.xml", r'(<dynamicObstacle id="52">.*?)<shape>.*?</shape>', r"\1")
    error = error_of(path)
    assert error.element == "dynamic obstacle 52" and str(error).endswith("dynamic obstacle 52 has no <shape>")

    path = edited(tmp_path, example_xml, "bad_number.xml", r'(<dynamicObstacle id="53">.*?<length>)4.5', r"\1long")
    error = error_of(path)
    # said in its own words, with the line the value is on (it was Python's: could not convert string to float)
    line = next(n for n, text in enumerate(path.read_text(encoding="utf-8").splitlines(), 1) if ">long<" in text)
    assert error.element == "dynamic obstacle 53"
    assert str(error).endswith(f"dynamic obstacle 53 cannot be read: `long` is not a number (line {line})")
    path = edited(tmp_path, example_xml, "bad_step.xml", r"(<dynamicObstacle id=\"53\">.*?<time>\s*<exact>)(\d+)",
                  r"\g<1>3s")
    assert "`3s` is not a whole number (line " in str(error_of(path))

    path = edited(tmp_path, example_xml, "no_start.xml",
                  r"(<planningProblem [^>]*>\s*)<initialState>.*?</initialState>", r"\1")
    error = error_of(path)
    assert error.element == "planning problem 100" and str(error).endswith("has no <initialState>")

    path = edited(tmp_path, example_xml, "no_road.xml", r"<lanelet id=.*?</lanelet>\s*", "", count=0)
    assert str(error_of(path)) == f"{path}: has no lanelets (rac needs the road network)"


def test_no_commonroad_exception_escapes(tmp_path: Path, example_xml: Path) -> None:
    """Damage the example at many places; whatever happens, it is a result or a ScenarioError."""
    text = example_xml.read_text(encoding="utf-8")
    tags = sorted(set(re.findall(r"<([a-zA-Z]+)>", text)))
    for i, tag in enumerate(tags):
        damaged = re.sub(rf"<{tag}>.*?</{tag}>", f"<{tag}>?</{tag}>", text, count=1, flags=re.S)
        path = tmp_path / f"damaged_{i}.xml"
        path.write_text(damaged, encoding="utf-8")
        try:
            load_scenario(path)
        except ScenarioError as error:
            assert str(error).startswith(f"{path}: "), (tag, str(error))


# ---------------------------------------------------------------- the shared CommonRoad scenarios
@pytest.mark.parametrize("name", ["DEU_Muc-3_1_T-1.xml", "ZAM_Ramp-1_1-T-1.xml", "ZAM_Tutorial-1_2_T-1.xml"])
def test_shared_scenarios_load(name: str) -> None:
    """What they hold; how fast they load is a row of ``python benchmarks/run.py``."""
    path = SHARED / name
    if not path.exists():
        pytest.skip(f"{SHARED} is absent")
    scenario = load_scenario(path)
    assert scenario.dt == pytest.approx(0.1) and scenario.road and scenario.goal.regions
    assert scenario.goal.time_low <= scenario.goal.time_high
    dynamic = [obstacle for obstacle in scenario.obstacles if not obstacle.static]
    assert dynamic and all(len(obstacle.waypoints) > 1 for obstacle in dynamic)
    for obstacle in dynamic:
        times = [waypoint.time for waypoint in obstacle.waypoints]
        assert times == sorted(set(times))
    assert all(signed_area(polygon) > 0 for polygon in scenario.road + scenario.goal.regions)


def test_the_paper_example_is_the_left_turn_with_15_s_of_traffic(tmp_path: Path, example: Scenario) -> None:
    """examples/paper/left_turn_15s.xml: the same road, cars and ego; trajectories and goal window 15 s."""
    committed = Path(__file__).resolve().parents[2] / "examples" / "paper" / "left_turn_15s.xml"
    fresh = write_left_turn(tmp_path / "left_turn_15s.xml", steps=150)
    assert committed.read_bytes() == fresh.read_bytes(), (
        "examples/paper/left_turn_15s.xml is stale: python -m rac.model.intersection "
        "examples/paper/left_turn_15s.xml --steps 150")
    longer = load_scenario(fresh)
    assert longer.road == example.road and longer.ego == example.ego
    assert longer.goal.time_high == 15.0 and example.goal.time_high == 10.0
    for moved, original in zip(longer.obstacles, example.obstacles):
        assert moved.waypoints[0] == original.waypoints[0]
        assert moved.waypoints[-1].time == 15.0
    with pytest.raises(ValueError, match="steps"):
        write_left_turn(tmp_path / "none.xml", steps=0)


# ---------------------------------------------------------------- files rac refuses plainly (issue 12)
def _committed_line(marker: str) -> int:
    """The line of ``marker``'s first occurrence in the committed example intersection."""
    text = COMMITTED.read_text(encoding="utf-8")
    return text[:text.index(marker)].count("\n") + 1


def _variant(tmp_path: Path, name: str, change) -> Path:
    """The example intersection with one change to its XML text."""
    text = change(COMMITTED.read_text(encoding="utf-8"))
    path = tmp_path / f"{name}.xml"
    path.write_text(text, encoding="utf-8")
    return path


@pytest.mark.parametrize(("name", "change", "message"), [
    ("reversed_goal_time", lambda t: re.sub(r"<intervalStart>0</intervalStart>\s*<intervalEnd>100</intervalEnd>",
                                            "<intervalStart>100</intervalStart><intervalEnd>0</intervalEnd>", t,
                                            count=1),
     "planning problem 100's <time> has the interval [100, 0], which ends before it starts"),
    # with both lines: in a file of hundreds of elements the id alone did not say where they are
    ("duplicate_id", lambda t: t.replace('<lanelet id="2">', '<lanelet id="1">', 1),
     "two lanelets have the id 1 (lines {} and {}): ids must be unique in a file".format(
         _committed_line('<lanelet id="1">'), _committed_line('<lanelet id="2">'))),
    ("zero_length", lambda t: re.sub(r"<length>4.5</length>", "<length>0.0</length>", t, count=1),
     "dynamic obstacle 51 has a 0 m × 1.8 m shape: an obstacle needs a positive length and width"),
    ("negative_start", lambda t: re.sub(r"(<planningProblem id=\"100\">\s*<initialState>.*?<exact>)0(</exact>)",
                                        r"\g<1>-3\2", t, count=1, flags=re.S),
     "planning problem 100 starts at time step -3: a scenario's time begins at step 0"),
])
def test_a_scenario_rac_cannot_use_is_refused_in_its_own_words(tmp_path: Path, name: str, change,
                                                                message: str) -> None:
    """A reversed goal interval leaked commonroad-io's AssertionError text; duplicate ids, a
    zero-length obstacle and a negative start time were accepted silently."""
    path = _variant(tmp_path, name, change)
    assert path.read_text(encoding="utf-8") != COMMITTED.read_text(encoding="utf-8")
    with pytest.raises(ScenarioError) as failure:
        load_scenario(path)
    assert message in str(failure.value) and str(path) in str(failure.value)
    assert "Assertion" not in str(failure.value)


def test_a_picture_that_fails_halfway_leaves_the_old_one(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """The picture was drawn straight onto its path: a full disk halfway left a truncated PNG in place of the
    good one (every other picture rac draws goes through rac.core.files.atomic_write)."""
    import errno

    from matplotlib.figure import Figure

    from rac.model.intersection import render_left_turn

    xml, png = write_left_turn(tmp_path / "x.xml"), tmp_path / "x.png"
    png.write_bytes(b"\x89PNG the good picture")

    def full_disk(figure: object, target: object, **options: object) -> None:
        with (open(target, "wb") if isinstance(target, (str, Path)) else contextlib.nullcontext(target)) as out:
            out.write(b"\x89PNG half")  # type: ignore[union-attr]
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(Figure, "savefig", full_disk)
    with pytest.raises(OSError, match="No space left"):
        render_left_turn(xml, png)
    assert png.read_bytes() == b"\x89PNG the good picture"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["x.png", "x.xml"]
