"""The loader's messages for CommonRoad files edited by hand into shapes commonroad-io fails on.

Each file is a tiny straight road (tests/support/tiny_scenarios.py, written with commonroad-io) with
one edit to its XML text (or to its 2018b variant, whose obstacles are ``<obstacle>`` elements with a
``<role>``). commonroad-io's own failure said what went wrong in numpy's or Python's
words ("operands could not be broadcast together with shapes (2,2) (3,2)", "an element it needs is
missing or empty", "attributes must be instances of <class 'commonroad.common.util.Interval'> only");
rac's message names the element and what it lacks.
"""

from __future__ import annotations

import dataclasses
import re
from pathlib import Path

import pytest
from tiny_scenarios import Block, GoalBox, StraightRoad

from rac.model.commonroad import EgoStart, ScenarioError, load_scenario


def road_xml() -> str:
    """A 100 m lane with a car driving ahead of the ego (a trajectory of 40 states) and a parked one."""
    road = StraightRoad(100.0, EgoStart(10.0, 1.75, 0.0, 5.0), GoalBox(40.0, 50.0),
                        obstacles=(Block(11, 30.0, 1.75, velocity=3.0), Block(12, 60.0, 1.75)))
    return road.xml("messages").decode("utf-8")


def road_2018b() -> str:
    """:func:`road_xml` in the 2018b format (commonroad-io writes 2020a only): the tags an attribute,
    no location, each obstacle an ``<obstacle>`` with its ``<role>``."""
    text = road_xml().replace('commonRoadVersion="2020a"', 'commonRoadVersion="2018b" tags="single_lane"')
    text = edit(text, r"\s*<location>.*?</location>\s*<scenarioTags>.*?</scenarioTags>", "")
    text = re.sub(r'<(dynamic|static)Obstacle (id="\d+")>', r"<obstacle \2><role>\1</role>", text)
    return re.sub(r"</(dynamic|static)Obstacle>", "</obstacle>", text)


def edit(text: str, pattern: str, replacement: str) -> str:
    """``text`` with the first match of ``pattern`` (DOTALL) replaced; the pattern must match."""
    edited, made = re.subn(pattern, replacement, text, count=1, flags=re.S)
    assert made, pattern
    return edited


POINT = r"<point>\s*<x>[^<]*</x>\s*<y>[^<]*</y>\s*</point>\s*"
#: The end of the file's last lanelet, where traffic signs and lights follow.
LAST_LANELET = r"(</lanelet>)(?!.*</lanelet>)"
TRAFFIC_SIGN = ("<trafficSign id=\"800\"><trafficSignElement><trafficSignID>274</trafficSignID><additionalValue>120"
                "</additionalValue></trafficSignElement><position><point><x>50.0</x><y>-1.0</y></point></position>"
                "</trafficSign>")


def traffic_light(*colours: str) -> str:
    """A traffic light (id 900) cycling through ``colours``, 20 time steps each."""
    cycle = "".join(f"<cycleElement><duration>20</duration><color>{colour}</color></cycleElement>"
                    for colour in colours)
    return (f"<trafficLight id=\"900\"><cycle>{cycle}</cycle><position><point><x>50.0</x><y>-1.0</y></point>"
            "</position><active>true</active></trafficLight>")


@pytest.mark.parametrize(("name", "pattern", "replacement", "message"), [
    ("uneven_bounds", r"(<rightBound>\s*" + POINT + ")", r"\1<point><x>50.0</x><y>0.0</y></point>",
     "lanelet 1 has 2 points in its <leftBound> and 3 in its <rightBound>: CommonRoad pairs them, one left and one "
     "right point per cross-section"),
    ("one_point_bound", r"(<leftBound>\s*" + POINT + ")" + POINT, r"\1",
     "lanelet 1 has 1 point in its <leftBound>: a bound is a polyline of at least 2 points"),
    ("goal_without_time", r"<goalState>\s*<time>.*?</time>", "<goalState>",
     "goal of planning problem 100 has no <time> in its <goalState>: CommonRoad's goal states give the time "
     "interval in which to reach the goal"),
    ("exact_goal_time", r"(<goalState>\s*<time>).*?(</time>)", r"\1<exact>20</exact>\2",
     "goal of planning problem 100 has a <time> without <intervalStart> and <intervalEnd> in its <goalState>: a "
     "goal's time is an interval (for one time step N, write N as both ends)"),
    ("empty_trajectory", r"<trajectory>.*?</trajectory>", "<trajectory></trajectory>",
     "dynamic obstacle 11 has an empty <trajectory>: a trajectory has at least one <state>"),
    ("negative_problem_id", r'<planningProblem id="100"', '<planningProblem id="-5"',
     "planning problem -5 has a negative id: CommonRoad ids are positive whole numbers"),
    ("negative_lanelet_id", r'<lanelet id="1"', '<lanelet id="-1"',
     "lanelet -1 has a negative id: CommonRoad ids are positive whole numbers"),
    # the 2020a schema allows it; commonroad-io read it as no shape: "an element it needs is missing or empty"
    ("shape_group", r'(<staticObstacle id="12">.*?<shape>)(.*?)(</shape>)',
     r"\1<shapeGroup><shape>\2</shape></shapeGroup>\3",
     "static obstacle 12 has a <shapeGroup> as its shape, which commonroad-io does not read: give the obstacle one "
     "rectangle, circle, polygon, truck or semi-trailer truck (rac bounds any shape by a rectangle, so the group's "
     "bounding rectangle loses nothing)"),
    # commonroad-io passed over it without a word: the model lacked the car
    ("misspelt_obstacle", r'<dynamicObstacle id="11">(.*?)</dynamicObstacle>',
     r'<dynamicObstacles id="11">\1</dynamicObstacles>',
     "<dynamicObstacles> is not a CommonRoad element (is it <dynamicObstacle>?): commonroad-io passes over it, so "
     "the model would lack it"),
    # the message went on "rac supports ... groups of these": it read as if a <shapeGroup> were supported
    ("goal_shape_group", r"(<goalState>.*?<position>)(.*?)(</position>)", r"\1<shapeGroup>\2</shapeGroup>\3",
     "goal of planning problem 100 has an unsupported shape (<shapeGroup>); rac supports rectangles, polygons, "
     "circles and lanelets, several of them side by side in the <position> (each a goal region)"),
    # commonroad-io failed with "lanelet network cannot be read: 'off' is not a valid TrafficLightState"
    ("light_colour", LAST_LANELET, r"\1" + traffic_light("off"),
     "traffic light 900 has the colour `off`, which commonroad-io does not read (it reads red, yellow, redYellow, "
     "green, inactive): rac does not use traffic lights, but commonroad-io refuses the file; write one of those "
     "colours"),
    # commonroad-io failed with an assert: "<CommonRoadFileReader/TrafficSignFactory...>: CommonRoad file is invalid!"
    ("unreferenced_sign", LAST_LANELET, r"\1" + TRAFFIC_SIGN,
     "traffic sign 800 is referenced by no lanelet's <trafficSignRef>: rac does not use traffic signs, but "
     "commonroad-io refuses the file; reference it from the lanelet it applies to, or remove it"),
])
def test_a_hand_edited_file_is_refused_in_its_own_words(tmp_path: Path, name: str, pattern: str, replacement: str,
                                                        message: str) -> None:
    path = tmp_path / f"{name}.xml"
    path.write_text(edit(road_xml(), pattern, replacement), encoding="utf-8")
    with pytest.raises(ScenarioError) as failure:
        load_scenario(path)
    assert str(failure.value) == f"{path}: {message}"


@pytest.mark.parametrize(("tag", "label"), [("lanelet", "lanelet"), ("staticObstacle", "static obstacle"),
                                          ("dynamicObstacle", "dynamic obstacle"),
                                          ("planningProblem", "planning problem")])
def test_an_element_without_an_id_is_named_with_its_line(tmp_path: Path, tag: str, label: str) -> None:
    """An element without its `id` attribute failed in commonroad-io with Python's own words: "static
    obstacle (without id) cannot be read: int() argument must be a string, a bytes-like object or a
    real number, not 'NoneType'". The message now says the attribute is missing, and where."""
    text = edit(road_xml(), rf'<{tag} id="\d+">', f"<{tag}>")
    line = text[:text.index(f"<{tag}>")].count("\n") + 1
    path = tmp_path / "without_id.xml"
    path.write_text(text, encoding="utf-8")
    with pytest.raises(ScenarioError) as failure:
        load_scenario(path)
    assert str(failure.value) == (f"{path}: {label} (without id) has no `id` attribute (line {line}): every "
                                  "CommonRoad lanelet, obstacle and planning problem has a unique positive "
                                  "whole-number id")


def test_traffic_lights_of_every_colour_and_referenced_signs_read(tmp_path: Path) -> None:
    """The refusals above are commonroad-io's alone: CommonRoad's five colours read, and so does a
    referenced sign."""
    path = tmp_path / "lights.xml"
    text = edit(road_xml(), LAST_LANELET, r"\1" + TRAFFIC_SIGN + traffic_light("red", "redYellow", "green", "yellow",
                                                                                   "inactive"))
    path.write_text(edit(text, r"(</lanelet>)", r'<trafficSignRef ref="800"/>\1'), encoding="utf-8")
    assert [o.id for o in load_scenario(path).obstacles] == [11, 12]


def test_a_dynamic_obstacle_without_an_initial_velocity_takes_it_from_its_motion(tmp_path: Path) -> None:
    """The schema leaves an obstacle's initial <velocity> out at will, and commonroad-io reads 0 then:
    rac refused the file ("has no <velocity> in its <initialState>"). The speed now comes from the move
    to the next state, as for a trajectory state without one (car 11: 3 m/s); an initial state without
    <orientation>, which the schema requires, is still refused."""
    path = tmp_path / "no_speed.xml"
    path.write_text(edit(road_xml(), r'(<dynamicObstacle id="11">.*?<initialState>.*?)<velocity>.*?</velocity>', r"\1"),
                    encoding="utf-8")
    (car,) = [o for o in load_scenario(path).obstacles if o.id == 11]
    assert car.waypoints[0].velocity == pytest.approx(3.0) and car.waypoints[0].heading == 0.0
    assert car.waypoints[1].velocity == 3.0
    path.write_text(edit(road_xml(), r'(<dynamicObstacle id="11">.*?<initialState>.*?)<orientation>.*?</orientation>',
                         r"\1"), encoding="utf-8")
    with pytest.raises(ScenarioError, match="dynamic obstacle 11 has no <orientation> in its <initialState>"):
        load_scenario(path)


def test_lanelet_points_with_an_elevation_read_as_the_planar_road(tmp_path: Path) -> None:
    """The schema gives a <point> an optional <z> (maps with elevation; commonroad-io reads lanelet
    bounds of three columns): rac's loader unpacked two and ended `rac check` in an internal error
    ("too many values to unpack"). The model is planar: the same road as without the <z>."""
    def raised(match: re.Match[str]) -> str:
        return re.sub(r"(<point>\s*<x>[^<]*</x>\s*<y>[^<]*</y>)", r"\1<z>1.5</z>", match.group(0))

    flat = tmp_path / "flat.xml"
    flat.write_text(road_xml(), encoding="utf-8")
    hilly = tmp_path / "hilly.xml"
    hilly.write_text(re.sub(r"<lanelet .*?</lanelet>", raised, road_xml(), flags=re.S), encoding="utf-8")
    assert "<z>1.5</z>" in hilly.read_text(encoding="utf-8")
    assert load_scenario(hilly) == dataclasses.replace(load_scenario(flat), path=str(hilly))


@pytest.mark.parametrize(("time_of_day", "weather"), [("day", "sunny"), ("night", "light_rain")])
def test_an_environment_commonroad_io_does_not_know_is_passed_over(tmp_path: Path, time_of_day: str,
                                                                   weather: str) -> None:
    """The 2020a schema's <environment> of a <location> allows the time of day `day` and the weather
    `sunny`, which commonroad-io's enums lack: it refused the whole file ("location cannot be read:
    'sunny' is not a valid Weather") for metadata rac never reads. The file now reads as without it."""
    environment = (f"<environment><time>08:30:00</time><timeOfDay>{time_of_day}</timeOfDay><weather>{weather}"
                   "</weather><underground>clean</underground></environment>")
    flat = tmp_path / "flat.xml"
    flat.write_text(road_xml(), encoding="utf-8")
    path = tmp_path / "environment.xml"
    path.write_text(edit(road_xml(), r"(</location>)", environment + r"\1"), encoding="utf-8")
    assert load_scenario(path) == dataclasses.replace(load_scenario(flat), path=str(path))


def test_a_planning_problem_may_share_an_obstacles_id(tmp_path: Path) -> None:
    """commonroad-io keeps planning problems apart from the scenario's elements, and CommonRoad's own
    converters give a planning problem its vehicle's obstacle id (OSC_Overtake-1_1_T-1: planning problem
    and dynamic obstacle 256): rac refused such files ("planning problem 100 has the id of dynamic obstacle
    100: ids must be unique in a file"). Two planning problems, or two obstacles, of one id still are."""
    path = tmp_path / "shared_id.xml"
    path.write_text(road_xml().replace('<dynamicObstacle id="11">', '<dynamicObstacle id="100">'), encoding="utf-8")
    scenario = load_scenario(path)
    assert [o.id for o in scenario.obstacles] == [12, 100] and scenario.planning_problem_id == 100
    assert scenario.recorded_ego is None  # car 100 starts 20 m ahead of the ego: another road user
    path.write_text(road_xml().replace('<dynamicObstacle id="11">', '<dynamicObstacle id="12">'), encoding="utf-8")
    with pytest.raises(ScenarioError, match="dynamic obstacle 12 has the id of static obstacle 12"):
        load_scenario(path)


def test_the_ego_recorded_as_an_obstacle_is_left_out(tmp_path: Path) -> None:
    """Files converted from OpenSCENARIO (and CommonRoad-CriMe's) hold the ego's own recorded run as a
    dynamic obstacle starting at the planning problem's time, position and heading: rac kept it, and
    `collide()` held from the start (W0724), every safety query false. It is left out now, and said."""
    road = StraightRoad(100.0, EgoStart(10.0, 1.75, 0.0, 5.0), GoalBox(40.0, 50.0),
                        obstacles=(Block(11, 10.0, 1.75, velocity=5.0), Block(12, 60.0, 1.75)))
    path = tmp_path / "recorded.xml"
    path.write_bytes(road.xml("recorded"))
    scenario = load_scenario(path)
    assert [o.id for o in scenario.obstacles] == [12] and scenario.recorded_ego == 11
    moved = StraightRoad(100.0, EgoStart(10.0, 1.75, 0.0, 5.0), GoalBox(40.0, 50.0),
                         obstacles=(Block(11, 10.0, 1.75, velocity=5.0, heading=0.1), Block(12, 60.0, 1.75)))
    path.write_bytes(moved.xml("recorded"))  # another heading: a road user in a collision, kept (W0724 says so)
    assert [o.id for o in load_scenario(path).obstacles] == [11, 12] and load_scenario(path).recorded_ego is None


def test_the_2018b_road_reads(tmp_path: Path) -> None:
    """The 2018b variant the tests below edit reads as the 2020a file does."""
    path = tmp_path / "old.xml"
    path.write_text(road_2018b(), encoding="utf-8")
    scenario = load_scenario(path)
    assert [(o.id, o.static, len(o.waypoints)) for o in scenario.obstacles] == [(11, False, 41), (12, True, 1)]


@pytest.mark.parametrize(("name", "pattern", "replacement", "message"), [
    ("no_role", r"<role>dynamic</role>", "", "obstacle 11 has no <role>"),
    ("unknown_role", r"<role>dynamic</role>", "<role>parked</role>",
     "obstacle 11 has the <role> `parked`: a 2018b obstacle's role is `static` or `dynamic`"),
    ("no_shape", r'(<obstacle id="12">.*?)<shape>.*?</shape>', r"\1", "obstacle 12 has no <shape>"),
    ("no_initial_state", r'(<obstacle id="11">.*?)<initialState>.*?</initialState>', r"\1",
     "obstacle 11 has no <initialState>"),
    ("empty_trajectory", r"<trajectory>.*?</trajectory>", "<trajectory></trajectory>",
     "obstacle 11 has an empty <trajectory>: a trajectory has at least one <state>"),
    ("bad_length", r'(<obstacle id="12">.*?<length>)[^<]*', r"\1long",
     "obstacle 12 cannot be read: `long` is not a number"),
])
def test_a_2018b_obstacle_is_named(tmp_path: Path, name: str, pattern: str, replacement: str, message: str) -> None:
    """A 2018b ``<obstacle>`` without its role, shape or initial state was "cannot be read by commonroad-io
    ('NoneType' object is not iterable)" or "... an element it needs is missing or empty", without the obstacle."""
    path = tmp_path / f"{name}.xml"
    path.write_text(edit(road_2018b(), pattern, replacement), encoding="utf-8")
    with pytest.raises(ScenarioError) as failure:
        load_scenario(path)
    assert str(failure.value).startswith(f"{path}: {message}")


#: The second state of the car's trajectory (time step 2).
SECOND_STATE = r"(<trajectory>\s*<state>.*?</state>\s*<state>)(.*?)(</state>)"


@pytest.mark.parametrize(("name", "pattern", "replacement", "message"), [
    ("point_without_y", r"(<trajectory>.*?<point>\s*<x>[^<]*</x>)\s*<y>[^<]*</y>", r"\1",
     "dynamic obstacle 11 has a <point> without <y>"),
    ("empty_velocity", r"(<trajectory>.*?<velocity>\s*<exact>)[^<]*", r"\1",
     "dynamic obstacle 11 has an empty <exact> in its <velocity>"),
    ("velocity_without_exact", r"(<trajectory>.*?<velocity>)\s*<exact>[^<]*</exact>", r"\1",
     "dynamic obstacle 11 has a <velocity> without <exact> (or <intervalStart> and <intervalEnd>) in its <state>"),
    ("state_without_velocity", SECOND_STATE, lambda m: m[1] + re.sub(r"(?s)<velocity>.*?</velocity>", "", m[2]) + m[3],
     "dynamic obstacle 11 has a <trajectory> whose state at time step 2 has no <velocity>, unlike its first state"),
    ("state_without_time", SECOND_STATE, lambda m: m[1] + re.sub(r"(?s)<time>.*?</time>", "", m[2]) + m[3],
     "dynamic obstacle 11 has a <state> without <time> in its <trajectory>"),
    ("empty_position", r"(<trajectory>.*?<position>).*?(</position>)", r"\1\2",
     "dynamic obstacle 11 has an empty <position>"),
    ("rectangle_without_width", r'(<staticObstacle id="12">.*?)<width>[^<]*</width>', r"\1",
     "static obstacle 12 has a <rectangle> without <width>"),
    ("goal_without_length", r"(<goalState>.*?)<length>.*?</length>", r"\1",
     "planning problem 100 has a <rectangle> without <length>"),
    # the schema allows a <z> in every <point>; commonroad-io failed on a state's: "too many values to unpack"
    ("state_elevation", r'(<dynamicObstacle id="11">.*?<initialState>.*?<y>[^<]*</y>)', r"\1<z>1.5</z>",
     "dynamic obstacle 11 has a <z> in the <point> of its <initialState>"),
])
def test_a_malformed_element_is_named_with_its_line(tmp_path: Path, name: str, pattern: str, replacement,
                                                     message: str) -> None:
    """commonroad-io fails on each with words that name neither the part nor the line: "an element it
    needs is missing or empty", "float() argument must be a string or a real number, not 'NoneType'",
    "a value is neither <exact> nor ...", "all states must have the same attributes"."""
    text = edit(road_xml(), pattern, replacement) if isinstance(replacement, str) else \
        re.sub(pattern, replacement, road_xml(), count=1, flags=re.S)
    path = tmp_path / f"{name}.xml"
    path.write_text(text, encoding="utf-8")
    with pytest.raises(ScenarioError) as failure:
        load_scenario(path)
    found = re.fullmatch(rf"{re.escape(f'{path}: {message}')} \(line (\d+)\)(: .*)?", str(failure.value))
    assert found, str(failure.value)
    assert 1 < int(found[1]) <= len(text.splitlines())


def test_the_line_is_the_malformed_parts(tmp_path: Path) -> None:
    text = edit(road_xml(), r"(<trajectory>.*?<point>\s*<x>[^<]*</x>)\s*<y>[^<]*</y>", r"\1")
    path = tmp_path / "point.xml"
    path.write_text(text, encoding="utf-8")
    with pytest.raises(ScenarioError) as failure:
        load_scenario(path)
    trajectory = text.index("<trajectory>")
    line = text[:text.index("<point>", trajectory)].count("\n") + 1
    assert str(failure.value) == f"{path}: dynamic obstacle 11 has a <point> without <y> (line {line})"


def test_commonroad_io_says_nothing_of_what_it_makes_of_a_file(tmp_path: Path, capfd: pytest.CaptureFixture[str],
                                                               caplog: pytest.LogCaptureFixture) -> None:
    """commonroad-io logs a warning for every intersection of a 2020a file ("successorStraight 1 is of
    deprecated format ...") and for a traffic sign id it does not know; Python's last-resort handler printed
    them to standard error among rac's diagnostics, on every command that read the file."""
    import logging

    extra = ('<trafficSign id="500"><trafficSignElement><trafficSignID>99999</trafficSignID></trafficSignElement>'
             "<position><point><x>10</x><y>-1</y></point></position></trafficSign>\n"
             '  <intersection id="900"><incoming id="901"><incomingLanelet ref="1"/><successorsStraight ref="1"/>'
             "</incoming></intersection>\n  <planningProblem")
    path = tmp_path / "intersection.xml"
    text = edit(road_xml(), r'(<lanelet id="1">.*?)(</lanelet>)', r'\1<trafficSignRef ref="500"/>\2')
    path.write_text(text.replace("<planningProblem", extra, 1), encoding="utf-8")
    logger = logging.getLogger("commonroad")
    before = logger.level
    with caplog.at_level(logging.WARNING):  # (pytest's handler takes the records the last-resort one printed)
        scenario = load_scenario(path)
    assert [o.id for o in scenario.obstacles] == [11, 12]
    assert [record.getMessage() for record in caplog.records] == []
    assert capfd.readouterr() == ("", "")
    assert logger.level == before  # the user's own setting is back


def test_an_obstacle_of_the_other_format_is_refused(tmp_path: Path) -> None:
    """commonroad-io reads a 2020a file's obstacles from <staticObstacle>, <dynamicObstacle>, ... and a 2018b
    file's from <obstacle>, passing over the other format's: the model had no obstacle, every safety query held."""
    old_in_new = road_2018b().replace('commonRoadVersion="2018b" tags="single_lane"', 'commonRoadVersion="2020a"')
    header = re.search(r"<location>.*?</location>\s*<scenarioTags>.*?</scenarioTags>", road_xml(), re.S)
    assert header is not None
    old_in_new = old_in_new.replace("<lanelet ", header.group(0) + "\n  <lanelet ", 1)
    new_in_old = road_xml().replace('commonRoadVersion="2020a"', 'commonRoadVersion="2018b" tags="single_lane"')
    new_in_old = edit(new_in_old, r"\s*<location>.*?</location>\s*<scenarioTags>.*?</scenarioTags>", "")
    for name, text, message in (
            ("old_in_new", old_in_new,
             'obstacle 12 is written as <obstacle>, the 2018b format\'s obstacle element, in a file labelled '
             'commonRoadVersion="2020a": commonroad-io reads a 2020a file\'s obstacles from <staticObstacle>, '
             "<dynamicObstacle>, <environmentObstacle>, <phantomObstacle> only and passes over it, so the model "
             'would lack this obstacle; write it in the 2020a format, or label the file commonRoadVersion="2018b" '
             "if it is one"),
            ("new_in_old", new_in_old,
             'static obstacle 12 is written as <staticObstacle>, the 2020a format\'s obstacle element, in a file '
             'labelled commonRoadVersion="2018b": commonroad-io reads a 2018b file\'s obstacles from <obstacle> '
             "only and passes over it, so the model would lack this obstacle; write it in the 2018b format, or "
             'label the file commonRoadVersion="2020a" if it is one')):
        path = tmp_path / f"{name}.xml"
        path.write_text(text, encoding="utf-8")
        with pytest.raises(ScenarioError) as failure:
            load_scenario(path)
        assert str(failure.value) == f"{path}: {message}"


def test_an_element_of_an_extension_is_left_alone(tmp_path: Path) -> None:
    """Only a misspelt CommonRoad element is refused (test_a_hand_edited_file_is_refused_in_its_own_words): an
    element of no likeness to one (a tool's own annotation) is passed over, as commonroad-io does."""
    path = tmp_path / "annotated.xml"
    path.write_text(road_xml().replace("<planningProblem", "<toolAnnotation>ok</toolAnnotation>\n  <planningProblem",
                                       1), encoding="utf-8")
    assert [o.id for o in load_scenario(path).obstacles] == [11, 12]
