"""The scenario a model is built from: road, obstacles, ego start and goal, in plain numbers.

:func:`load_scenario` (with commonroad-io) turns a CommonRoad XML file into these frozen
values; everything downstream (the native model, the UPPAAL target) reads only them.
Units: metres, seconds, radians, m/s.
"""

from __future__ import annotations

import difflib
import logging
import math
import os
import re
import threading
import warnings
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from xml.etree import ElementTree
from xml.parsers import expat
from xml.parsers.expat import ExpatError

from rac.core.diagnostics import RacError


@dataclass(frozen=True)
class Polygon:
    """A simple polygon, counter-clockwise or clockwise, not closed (first point not repeated)."""

    points: tuple[tuple[float, float], ...]


@dataclass(frozen=True)
class Lane:
    """A lanelet's centre line and bounds, each point in the driving direction (index ``i`` of the
    three is one cross-section). The model reads only the road's polygons; a learner's observation
    (:mod:`rac.learning.observation`) measures the ego against the lanes."""

    id: int
    centre: tuple[tuple[float, float], ...]
    left: tuple[tuple[float, float], ...]
    right: tuple[tuple[float, float], ...]


@dataclass(frozen=True)
class Waypoint:
    """An obstacle's state at one time: it moves in a straight line at ``velocity`` along
    ``heading`` until the next waypoint (velocity and heading change only at waypoints)."""

    time: float
    x: float
    y: float
    heading: float
    velocity: float


@dataclass(frozen=True)
class Obstacle:
    """A static or dynamic obstacle, a ``length`` × ``width`` rectangle centred on its position."""

    id: int
    length: float
    width: float
    waypoints: tuple[Waypoint, ...]  # one waypoint for a static obstacle
    static: bool = False
    kind: str = ""  # the CommonRoad obstacle type, e.g. "car", "truck", "parkedVehicle"


@dataclass(frozen=True)
class EgoStart:
    x: float
    y: float
    heading: float
    velocity: float
    acceleration: float = 0.0
    time: float = 0.0  # the planning problem's initial time step, in seconds


@dataclass(frozen=True)
class Goal:
    """The planning problem's goal: the ego's position inside one of ``regions`` while
    ``time_low <= time <= time_high`` (seconds); with ``anywhere``, the time alone (a goal state
    without a position: "be there, on any spot, in the window")."""

    regions: tuple[Polygon, ...]
    time_low: float
    time_high: float
    #: What the planning problem also asks of the ego in the goal, as closed intervals (m/s,
    #: radians), None when it asks nothing; several goal states asking different ones give the
    #: hull of theirs. ``goal()`` (model.md) reads only regions and time: ``rac check`` warns (W0723).
    velocity: tuple[float, float] | None = None
    orientation: tuple[float, float] | None = None
    #: The loader's point for :attr:`center` when the first region is a lanelet: the midpoint of its
    #: centre line by arc length (a curved lanelet's vertex mean may lie off the lanelet).
    lane_point: tuple[float, float] | None = None
    #: A goal state has no position (CommonRoad's goal of time alone, "survive until T"): the goal
    #: holds at every position inside the time window, ``regions`` is empty and ``goal()`` reads
    #: the time only; ``dist_goal()`` is 0 (model.md).
    anywhere: bool = False

    @property
    def center(self) -> tuple[float, float]:
        """A point inside the first region, which ``dist_goal()`` measures to: ``lane_point`` for a
        lanelet goal, else the mean of the region's vertices when it lies inside the region (a convex
        region's always does), else :func:`inside_point`. A goal without regions (``anywhere``, or
        one built without any) has none: an ``IndexError``."""
        if self.lane_point is not None:
            return self.lane_point
        return inside_point(self.regions[0])


def inside_point(polygon: Polygon) -> tuple[float, float]:
    """The mean of ``polygon``'s vertices when it lies inside the polygon, else a point inside it
    (shapely's ``representative_point``): the vertex mean of a ring or an L lies in its hole."""
    import shapely  # shapely (commonroad-io's, loaded with the scenario): importing this module stays light

    points = polygon.points
    mean = (sum(p[0] for p in points) / len(points), sum(p[1] for p in points) / len(points))
    shape = shapely.Polygon(points)
    if shape.contains(shapely.Point(mean)):
        return mean
    point = shape.representative_point()
    return (float(point.x), float(point.y))


def _midpoint(line: tuple[tuple[float, float], ...]) -> tuple[float, float]:
    """The point halfway along ``line`` (a polyline) by arc length."""
    lengths = [math.hypot(x1 - x0, y1 - y0) for (x0, y0), (x1, y1) in zip(line, line[1:])]
    remaining = sum(lengths) / 2
    for ((x0, y0), (x1, y1)), length in zip(zip(line, line[1:]), lengths):
        if remaining <= length and length > 0:
            share = remaining / length
            return (x0 + share * (x1 - x0), y0 + share * (y1 - y0))
        remaining -= length
    return line[-1]


@dataclass(frozen=True)
class TrafficRules:
    """A scenario's traffic lights, traffic signs and stop lines, counted: CommonRoad's rules, which the model
    does not read (W0730). ``speed_limits``: every sign is a speed limit (``max_speed`` can keep one)."""

    lights: int = 0
    signs: int = 0
    stop_lines: int = 0
    speed_limits: bool = False

    def counted(self) -> tuple[str, ...]:
        """``("1 traffic light", "2 speed-limit signs")``: each kind the scenario has, counted."""
        kinds = ((self.lights, "traffic light"), (self.signs, "speed-limit sign" if self.speed_limits else
                                                               "traffic sign"), (self.stop_lines, "stop line"))
        return tuple(f"{count} {what}{'s' * (count != 1)}" for count, what in kinds if count)


@dataclass(frozen=True)
class Scenario:
    name: str
    path: str
    dt: float  # the CommonRoad time step (s)
    road: tuple[Polygon, ...]  # the lanelets' polygons; the road is their union
    obstacles: tuple[Obstacle, ...]
    ego: EgoStart
    goal: Goal
    planning_problem_id: int | None = None  # the CommonRoad planning problem ego and goal come from
    planning_problem_ids: tuple[int, ...] = ()  # every planning problem of the file, in id order
    lanes: tuple[Lane, ...] = ()  # the lanelets as lanes, in lanelet id order (like ``road``)
    #: The dynamic obstacle left out as the planning problem's own recorded vehicle (it starts at the
    #: planning problem's time, position and orientation), or None.
    recorded_ego: int | None = None
    #: What the file regulates that the model does not read (W0730).
    traffic_rules: TrafficRules = TrafficRules()

    @property
    def traffic_ends(self) -> float | None:
        """The scenario time (s) after which no moving obstacle is recorded (CommonRoad, and the model, take an
        obstacle as gone after its last time step): the last waypoint of the last moving obstacle; None
        without moving obstacles. A horizon past it covers a road without the traffic (W0728)."""
        ends = [obstacle.waypoints[-1].time for obstacle in self.obstacles if not obstacle.static]
        return max(ends) if ends else None

    def outruns_traffic(self, horizon: float) -> bool:
        """Whether runs of ``horizon`` s from the ego's start go on after :attr:`traffic_ends` (W0728)."""
        ends = self.traffic_ends
        return ends is not None and ends < self.ego.time + horizon - 1e-9


# ---------------------------------------------------------------- reading CommonRoad files
class ScenarioError(RacError):
    """A CommonRoad file rac cannot turn into a :class:`Scenario`.

    ``str(error)`` is ``"<path>: <element> <problem>"``, e.g. ``"left_turn.xml: dynamic obstacle 42
    has no trajectory prediction"``. ``path`` is the file as given, ``element`` names the part of
    the file at fault (``"dynamic obstacle 42"``, ``"goal of planning problem 7"``, ...) or is None
    when the problem is the file as a whole (missing, not XML, not CommonRoad, no planning problem).
    """

    def __init__(self, path: str | os.PathLike[str], element: str | None, problem: str) -> None:
        self.path = os.fspath(path)
        self.element = element
        self.problem = problem
        super().__init__(f"{self.path}: {element} {problem}" if element else f"{self.path}: {problem}")


class InconsistentScenarioError(ScenarioError):
    """A CommonRoad file that reads, but whose parts contradict each other or the model: its own
    diagnostic ``code`` (E0718-E0721, E0729, docs/diagnostics.md), the ``attribute`` at fault, the position
    ``line``:``column`` (1-based) of the element in the file when known, and a ``hint`` for the fix.

    ``str(error)`` is ``"<path>:<line>:<column>: <element> <problem>"`` (without the position when
    unknown)."""

    def __init__(self, path: str | os.PathLike[str], code: str, element: str | None, attribute: str, problem: str,
                 hint: str, position: tuple[int, int] | None = None) -> None:
        super().__init__(path, element, problem)
        self.code = code
        self.attribute = attribute
        self.hint = hint
        self.line: int | None = position[0] if position is not None else None
        self.column: int | None = position[1] if position is not None else None
        where = f"{self.path}:{self.line}:{self.column}" if position is not None else self.path
        self.args = (f"{where}: {element} {problem}" if element else f"{where}: {problem}",)


#: E0718: the shortest and longest CommonRoad time step rac accepts (s). Times are held to 1e-9 s
#: (:func:`_seconds`), so a shorter step loses its digits and its time steps collapse; a longer one
#: puts an obstacle's second state beyond any horizon the model's int32 periods reach.
MIN_TIME_STEP = 1e-6
MAX_TIME_STEP = 1e6
#: The lanelet elements that name another lanelet by its ``ref`` (E0720).
LANELET_REFERENCES = ("predecessor", "successor", "adjacentLeft", "adjacentRight")
#: The largest ``|orientation|`` (rad) rac hands to commonroad-io. Its reader brings a state's
#: orientation into [-2π, 2π] by adding or subtracting 2π one turn at a time (``make_valid_orientation``
#: for an obstacle's initial state, ``make_valid_orientation_interval`` for any ``AngleInterval``): at
#: 1e300 or inf a step no longer changes the number and the read never ends; at 1e6 it takes 160,000
#: steps (14 ms for one value, seconds for a file of such obstacles) and ends 1e-6 rad off. Up to 1e4
#: (1,600 turns, which no vehicle makes in a scenario; CommonRoad's files stay within ±2π) it takes at
#: most 1,600 steps (50 µs) and ends within 1e-10 rad.
MAX_ORIENTATION = 1e4
#: The children of an ``<orientation>`` that hold its numbers (an orientation of a shape holds its own text).
ORIENTATION_VALUES = ("exact", "intervalStart", "intervalEnd")


class PlanningProblemError(ScenarioError):
    """The planning problem to use is not clear: ``chosen`` is not among the file's ``ids``, or
    (``chosen`` None, with ``require_choice``) the file has several."""

    def __init__(self, path: str | os.PathLike[str], chosen: int | None, ids: tuple[int, ...]) -> None:
        self.chosen = chosen
        self.ids = ids
        listed = ", ".join(map(str, ids))
        if chosen is None:
            super().__init__(path, None, f"has {len(ids)} planning problems ({listed}) and none was chosen")
        else:
            super().__init__(path, f"planning problem {chosen}", f"does not exist (the file has {listed})")


#: The goal positions rac reads, as its messages say (a ``<shapeGroup>`` is not one: the goal's
#: ``<position>`` lists its shapes side by side, and "groups of these" read as if it were).
GOAL_SHAPES = ("rac supports rectangles, polygons, circles and lanelets, several of them side by side in the "
               "<position> (each a goal region)")
#: Vertices of the regular polygon that stands for a circular goal region.
CIRCLE_VERTICES = 16


def load_scenario(path: str | os.PathLike[str], planning_problem_id: int | None = None, *,
                  require_choice: bool = False) -> Scenario:
    """Read a CommonRoad XML file (format 2018b or 2020a) with commonroad-io's CommonRoadFileReader.

    - ``road``: one polygon per lanelet (its right bound, then its left bound reversed), in lanelet
      id order; the road is their union.
    - ``obstacles``: static and dynamic obstacles in id order. Each is a ``length`` × ``width``
      rectangle: a rectangle shape as it is (an ``originXShift`` or a ``<center>`` moves the waypoints
      to the rectangle's centre; a rectangle turned by its own ``<orientation>`` becomes its bounding
      rectangle in the obstacle's frame); a circle becomes its bounding square (moved by its
      ``<center>``); a polygon, truck or semi-trailer truck becomes its bounding rectangle in the
      obstacle's own frame (a semi-trailer at hitch angle 0). A static obstacle has one waypoint
      (velocity 0). A dynamic obstacle needs a trajectory prediction: its waypoints are the initial
      state followed by every trajectory state, ``time = time_step * dt`` (rounded to 1e-9 s); a
      state without orientation or velocity takes them from the move to the next state (a
      point-mass state from its velocity components). CommonRoad regards the obstacle as gone after
      its last time step. Environment and phantom obstacles are ignored.
    - ``ego``: the planning problem's initial state (position, orientation, velocity,
      acceleration, time).
    - ``goal``: the planning problem's goal position as polygons — a rectangle (its 4 corners), a
      polygon, a circle (approximated by the inscribed regular 16-gon, whose vertices lie on the
      circle), a group of these (one region each) or lanelets (each lanelet's polygon) — and its
      time-step interval in seconds; velocity and orientation intervals, if any, are kept in
      ``Goal.velocity`` / ``Goal.orientation`` (the hull of the goal states'; the model does not
      read them). Several goal states are merged (their regions concatenated) when they ask for the
      same time interval. ``Goal.center`` is a point inside the first region (for a lanelet, the
      midpoint of its centre line by arc length). A goal state without a position makes the goal
      ``anywhere`` (no regions: the time window alone).

    ``planning_problem_id`` picks the planning problem; None picks the one with the smallest id, or,
    with ``require_choice``, raises :class:`PlanningProblemError` when the file has several (before
    reading any of them). An id the file lacks is a :class:`PlanningProblemError` as well.
    ``planning_problem_ids`` lists every planning problem of the file.
    All polygons come counter-clockwise, without the first point repeated. Anything rac cannot
    represent raises :class:`ScenarioError` naming the file and the element; so do a missing file,
    a file that is not XML or not CommonRoad, and a file commonroad-io fails on.
    """
    data = _read_bytes(path)
    root = _parse_root(path, data)
    positions = _positions(root, data)
    _check_time_step(path, root, positions)
    _check_structure(path, root, positions)
    _check_references(path, root, positions)
    _check_orientations(path, root, positions)  # before commonroad-io: it loops forever on a huge one
    data = _without_environment(root, data)

    # commonroad: only when this runs; importing rac.model.commonroad stays light
    from commonroad.common.file_reader import CommonRoadFileReader

    with quiet_reader():
        try:
            with linear_ids():
                cr_scenario, problems = CommonRoadFileReader(data).open()
        except Exception as error:  # commonroad-io raises a bare Exception too: reader_failure sorts
            if not reader_failure(error):
                raise
            diagnosis: ScenarioError | None = _diagnose(path, root, error, positions)
        else:
            diagnosis = None
        if diagnosis is not None:
            raise diagnosis
        return _convert(path, root, cr_scenario, problems, planning_problem_id, require_choice, positions)


#: The values of a ``<location>``'s ``<environment>`` commonroad-io reads, by element (its enums' names).
_ENVIRONMENT = {"timeOfDay": "TimeOfDay", "weather": "Weather", "underground": "Underground"}


def _without_environment(root, data: bytes) -> bytes:
    """``data`` without its ``<location>``'s ``<environment>`` when that holds a value commonroad-io does
    not know: the 2020a schema's ``day`` and ``sunny`` are not in commonroad-io's enums, and it refused the
    whole file ("location cannot be read: 'sunny' is not a valid Weather") for metadata rac never reads.
    The element's lines stay as empty lines, so every later line keeps its number."""
    environment = root.find("location/environment")
    if environment is None:
        return data
    # commonroad: only when this runs; importing rac.model.commonroad stays light
    from commonroad.common import common_scenario

    known = {tag: {str(e.value) for e in getattr(common_scenario, name)} for tag, name in _ENVIRONMENT.items()}
    if all(child.text in known[child.tag] for child in environment if child.tag in known):
        return data
    match = re.search(rb"<environment\b.*?</environment>", data, flags=re.S)
    if match is None:  # written as <environment/>: nothing in it to refuse
        return data
    return data[:match.start()] + b"\n" * data.count(b"\n", match.start(), match.end()) + data[match.end():]


def reader_failure(error: BaseException) -> bool:
    """Whether ``error`` is what commonroad-io (and the lxml and shapely it calls) raise on a file it
    cannot read: its own asserts and bare ``Exception()`` (``file_reader_xml``), lookups and
    conversions of the XML's text, the XML parsers' (ElementTree's, expat's, lxml's) and shapely's
    errors. Anything else (a subclass of ``Exception`` of no such kind) is a bug, rac's or
    commonroad-io's, and propagates."""

    from lxml import etree  # lxml: only when this runs; importing rac.model.commonroad stays light
    from shapely.errors import ShapelyError  # shapely: only when this runs; importing rac.model.commonroad stays light

    return type(error) is Exception or isinstance(error, (
        AssertionError, ArithmeticError, AttributeError, LookupError, TypeError, ValueError, NotImplementedError,
        SyntaxError, ExpatError, etree.Error, ShapelyError))  # ElementTree's ParseError is a SyntaxError


#: Serialises :func:`quiet_reader`'s count of the blocks running and its change of commonroad-io's log level.
_QUIET_LOCK = threading.Lock()
_quiet = {"blocks": 0, "level": logging.NOTSET}


@contextmanager
def quiet_reader() -> Iterator[None]:
    """While the block runs, commonroad-io's warnings and its log records below ERROR are dropped.

    Why: its reader reports what it makes of a file on the warnings module (benchmark ids it finds
    irregular) and on its loggers (every intersection of a 2020a file, "successorStraight 3 is of
    deprecated format, thus mapped to outgoingStraight"; a traffic sign id it does not know). Python's
    last-resort handler printed the log records to standard error, among rac's diagnostics, once per
    read of the file, for parts rac does not use. The logger's own level is back when the last block ends."""
    logger = logging.getLogger("commonroad")
    with _QUIET_LOCK:
        if _quiet["blocks"] == 0:
            _quiet["level"] = logger.level
            logger.setLevel(logging.ERROR)
        _quiet["blocks"] += 1
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            yield
    finally:
        with _QUIET_LOCK:
            _quiet["blocks"] -= 1
            if _quiet["blocks"] == 0:
                logger.setLevel(_quiet["level"])


#: Serialises :func:`linear_ids`: it swaps a name of commonroad-io's reader module while a file is read.
_READER_LOCK = threading.Lock()


@contextmanager
def linear_ids() -> Iterator[None]:
    """While the block runs, commonroad-io's XML reader builds its scenario as a subclass whose
    ``generate_object_id`` takes constant time instead of time linear in the ids used so far.

    Why: reading a CommonRoad 2020a file, commonroad-io (2026.1 and earlier) gives every lanelet's
    two bounds an id of their own (``ScenarioFactory.create_from_xml_node``), each from
    ``Scenario.generate_object_id``, which scans the whole id set (``max(self._id_set)``): 2 n scans of
    about n ids for n lanelets, O(n²). Measured on a generated grid of lanes: 2,000 lanelets 0.4 s of
    the load, 5,000 2.2 s, 10,000 8.6 s, 25,000 about 55 s (docs/history.md, "Loading a
    large scenario (issue 22)"). The subclass keeps the largest id as ids are marked used (the one place commonroad-io
    adds to the set) and scans again only when the set changed otherwise (an id removed), so its ids
    are those commonroad-io's method gives. The reader's module is left as it was when the block
    ends; when commonroad-io's reader or its ``Scenario`` do not look as expected (another version),
    nothing is swapped and the reader runs as it is."""
    # commonroad: only when this runs; importing rac.model.commonroad stays light
    from commonroad.common.reader import file_reader_xml

    # commonroad: only when this runs; importing rac.model.commonroad stays light
    from commonroad.scenario.scenario import Scenario as CommonRoadScenario

    expected = (getattr(file_reader_xml, "Scenario", None) is CommonRoadScenario
                and callable(getattr(CommonRoadScenario, "generate_object_id", None))
                and callable(getattr(CommonRoadScenario, "_mark_object_id_as_used", None)))
    if not expected:
        yield
        return

    class LinearIdScenario(CommonRoadScenario):  # type: ignore[misc]
        """commonroad-io's ``Scenario`` with the largest id used kept up to date."""

        _rac_count = 0  # the ids in the set when _rac_largest was last known (-1: not known)
        _rac_largest: int | None = None

        def _mark_object_id_as_used(self, object_id: int) -> None:
            in_step = self._rac_count == len(self._id_set)
            super()._mark_object_id_as_used(object_id)
            if in_step:
                largest = self._rac_largest
                self._rac_largest = object_id if largest is None or object_id > largest else largest
                self._rac_count = len(self._id_set)
            else:
                self._rac_count = -1

        def generate_object_id(self) -> int:
            ids = self._id_set
            if self._rac_count != len(ids):  # changed behind our back (an id removed): scan once
                self._rac_largest, self._rac_count = max(ids, default=None), len(ids)
            counter: int = getattr(self, "_id_counter", None) or 0  # commonroad-io's: None before the first id
            if self._rac_largest is not None:
                counter = max(counter, self._rac_largest)
            self._id_counter = counter + 1
            return counter + 1

    with _READER_LOCK:
        file_reader_xml.Scenario = LinearIdScenario
        try:
            yield
        finally:
            file_reader_xml.Scenario = CommonRoadScenario


def _positions(root, data: bytes) -> dict[int, tuple[int, int]]:
    """The (line, column), 1-based, of every element of ``root`` by ``id(element)``: expat reports the
    start tags in document order, the order of ``root.iter()`` (ElementTree keeps no positions)."""

    parser = expat.ParserCreate()
    starts: list[tuple[int, int]] = []
    parser.StartElementHandler = lambda name, attributes: starts.append(
        (parser.CurrentLineNumber, parser.CurrentColumnNumber + 1))
    try:
        parser.Parse(data, True)
    except expat.ExpatError:  # ElementTree read it: only the positions are lost
        return {}
    return {id(node): where for node, where in zip(root.iter(), starts)}


def _check_time_step(path: str | os.PathLike[str], root, positions: dict[int, tuple[int, int]]) -> None:
    """E0718: a ``timeStepSize`` outside [MIN_TIME_STEP, MAX_TIME_STEP] (zero, negative and infinite ones too)."""
    dt = float(root.get("timeStepSize"))
    if MIN_TIME_STEP <= dt <= MAX_TIME_STEP:
        return
    if dt <= 0:
        why = "not positive: the scenario's time would not advance"
    elif dt < MIN_TIME_STEP:
        why = "shorter than 1 µs: rac holds times to 1 ns, so its time steps would collapse into each other"
    else:
        why = "longer than 10^6 s: an obstacle's next state would lie beyond any horizon"
    raise InconsistentScenarioError(
        path, "E0718", None, "timeStepSize", f"has timeStepSize=\"{root.get('timeStepSize')}\" s, {why}",
        "write the time step the trajectories were recorded at (CommonRoad's scenarios use 0.1 s); rac accepts "
        "steps from 1 µs to 10^6 s", positions.get(id(root)))


def _check_references(path: str | os.PathLike[str], root, positions: dict[int, tuple[int, int]]) -> None:
    """E0720: a lanelet's predecessor, successor or adjacent lanelet that the file does not define
    (commonroad-io keeps the dangling id, and the road graph would lead nowhere)."""
    defined = {node.get("id") for node in root.iter("lanelet")}
    for lanelet in root.iter("lanelet"):
        for kind in LANELET_REFERENCES:
            for reference in lanelet.iterfind(kind):
                target = reference.get("ref")
                if target is not None and target not in defined:
                    raise InconsistentScenarioError(
                        path, "E0720", f"lanelet {lanelet.get('id')}", kind,
                        f"has <{kind} ref=\"{target}\">, but the file defines no lanelet {target}",
                        f"add lanelet {target}, correct the `ref`, or remove the <{kind}>",
                        positions.get(id(reference)))


def _check_orientations(path: str | os.PathLike[str], root, positions: dict[int, tuple[int, int]]) -> None:
    """Refuse an ``<orientation>`` number (``exact``, ``intervalStart``, ``intervalEnd``, or a shape's own
    text) that is not finite or beyond ±:data:`MAX_ORIENTATION` before commonroad-io reads the file:
    its reader normalises such a value in a loop that never ends (or runs for seconds), so the loader's
    checks after the read would never run. The only angles commonroad-io normalises are orientations
    (``yawRate``, ``slipAngle``, ``steeringAngle``, ``hitchAngle`` are read as they are). One pass over
    the ``<orientation>`` elements, under 1 % of the load: 0.3 ms of 60 ms for examples/paper/left_turn_15s.xml
    (250 kB), 34 ms of 4 s for a generated grid of 10.8 MB (``scenes.grid_bytes(200, 200)``)."""
    for node in root:
        for orientation in node.iter("orientation"):
            holders = [child for child in orientation if child.tag in ORIENTATION_VALUES] if len(orientation) \
                else [orientation]
            for holder in holders:
                value = _number_text(holder.text)  # not a number: commonroad-io's reader reports it
                if value is not None and not (math.isfinite(value) and abs(value) <= MAX_ORIENTATION):
                    raise _orientation_error(path, node, orientation, (holder.text or "").strip(), value,
                                             positions.get(id(orientation)))


def _orientation_error(path: str | os.PathLike[str], node, orientation, text: str, value: float,
                       position: tuple[int, int] | None) -> ScenarioError:
    """The :class:`ScenarioError` of :func:`_check_orientations`: the element in the loader's words (a
    goal's ``"goal of planning problem 7"``), the state or shape holding the orientation, its line."""
    parents = {child: parent for parent in node.iter() for child in parent}  # only on failure: no cost otherwise
    holder = parents.get(orientation, node)
    ancestors = []
    at = orientation
    while at in parents:
        at = parents[at]
        ancestors.append(at.tag)
    label = f"{_LABELS[node.tag]} {node.get('id', '(without id)')}" if node.tag in _LABELS else f"<{node.tag}>"
    element = f"goal of {label}" if node.tag == "planningProblem" and "goalState" in ancestors else label
    if holder.tag == "initialState":
        what = "its initial state"
    elif holder.tag == "goalState":
        what = "its goal state"
    elif holder.tag == "state":
        step = (holder.findtext("time/exact") or holder.findtext("time/intervalStart") or "?").strip()
        what = f"the state at time step {step}"
    else:
        what = f"its <{holder.tag}>"
    where = f" (line {position[0]})" if position is not None else ""
    if not math.isfinite(value):
        return ScenarioError(path, element, f"has an orientation that is not finite ({text}) in {what}{where}")
    return ScenarioError(path, element, f"has an orientation of {text} rad in {what}{where}, beyond the "
                                        f"±{MAX_ORIENTATION:g} rad rac accepts (CommonRoad's are within ±2π)")


def with_planning_problem(name: str, planning_problem: int | None) -> str:
    """A scene as messages name it: ``name`` (its file, its label), and the planning problem when one was
    chosen for it (a scene set's ``(path, id)``, a sweep's task per planning problem)."""
    return name if planning_problem is None else f"{name} (planning problem {planning_problem})"


def planning_problem_ids(data: bytes) -> tuple[int, ...]:
    """The ids of the planning problems of the CommonRoad file ``data`` (its bytes) in id order, read from its
    XML alone (no commonroad-io: a sweep plans a task per planning problem of each file before any loads it);
    ``()`` for bytes that do not parse, or ids that are not whole numbers (:func:`load_scenario` says what is
    wrong)."""
    try:
        root = ElementTree.fromstring(data)
        return tuple(sorted(int(element.attrib["id"]) for element in root.iter("planningProblem")))
    except (ElementTree.ParseError, KeyError, ValueError):
        return ()


def _read_bytes(path: str | os.PathLike[str]) -> bytes:
    try:
        if Path(path).exists() and not Path(path).is_dir() and not Path(path).is_file():
            # a FIFO or a device would block the read (or never end): refuse it
            raise ScenarioError(path, None, "is not a regular file (a pipe or a device?), not a CommonRoad XML file")
        return Path(path).read_bytes()
    except FileNotFoundError:
        if Path(path).is_symlink():  # the link is there, its target is not: "does not exist" sent users looking for it
            target = os.readlink(path)
            raise ScenarioError(path, None, f"is a symbolic link to {target}, which does not exist") from None
        raise ScenarioError(path, None, "does not exist") from None
    except IsADirectoryError:
        raise ScenarioError(path, None, "is a directory, not a CommonRoad XML file") from None
    except OSError as error:
        raise ScenarioError(path, None, f"cannot be read ({error.strerror or error})") from None


#: expat's errors for input that ends too soon (:func:`_parse_root`).
_CUT_SHORT = frozenset(expat.errors.codes[name] for name in (
    expat.errors.XML_ERROR_NO_ELEMENTS, expat.errors.XML_ERROR_UNCLOSED_TOKEN, expat.errors.XML_ERROR_PARTIAL_CHAR))


def _parse_root(path: str | os.PathLike[str], data: bytes):
    # commonroad: only when this runs; importing rac.model.commonroad stays light
    from commonroad import SUPPORTED_COMMONROAD_VERSIONS

    try:
        root = ElementTree.fromstring(data)
    except ElementTree.ParseError as error:
        # CommonRoad's scenarios are downloaded as zip archives: the parser's "not well-formed (invalid
        # token)" at line 1 did not say that the file is one, or what to do
        for magic, what, fix in ((b"PK\x03\x04", "a zip archive", "unpack it"),
                                 (b"\x1f\x8b", "gzip-compressed", "decompress it (gunzip)")):
            if data.startswith(magic):
                raise ScenarioError(path, None, f"is {what}, not a CommonRoad XML file: {fix} and name the "
                                                ".xml file") from None
        line, column = error.position
        if error.code in _CUT_SHORT:
            # expat's "no element found", "unclosed token" are its words for a file that ends too soon: an
            # empty one, or one whose download or copy was cut short, which the message did not say
            if re.search(rb"<[A-Za-z_]", data) is None:
                raise ScenarioError(path, None, "is empty: it holds no XML element, not a CommonRoad scenario") \
                    from None
            last = data.count(b"\n") + 1
            raise ScenarioError(path, None, f"ends at line {last} before its elements are closed: is it truncated "
                                            "(a download or copy cut short)?") from None
        raise ScenarioError(path, None, f"is not XML (line {line}, column {column + 1}: "
                                        f"{str(error).split(':')[0]})") from None
    if root.tag != "commonRoad":
        raise ScenarioError(path, None, f"is not a CommonRoad file (its root element is <{root.tag}>, "
                                        "not <commonRoad>)")
    version = root.get("commonRoadVersion")
    if version not in SUPPORTED_COMMONROAD_VERSIONS:
        supported = " and ".join(sorted(SUPPORTED_COMMONROAD_VERSIONS))
        found = f"has CommonRoad version {version!r}" if version is not None else \
            "has no commonRoadVersion attribute on its <commonRoad> element"
        raise ScenarioError(path, None, f"{found}; commonroad-io reads the XML formats {supported}")
    try:
        dt = float(root.get("timeStepSize", "nan"))
    except ValueError:
        dt = math.nan
    if math.isnan(dt):  # a number outside the range is E0718 (_check_time_step), with its position
        raise ScenarioError(path, None, f"has no valid timeStepSize (got {root.get('timeStepSize')!r})")
    return root


def _number_text(text: str | None) -> float | None:
    """A number of the XML (an interval's bound), or None when it is not one (commonroad-io reports it)."""
    try:
        return float(text or "")
    except ValueError:
        return None


#: Python's words for a text that is no number (commonroad-io converts element texts with float()/int()).
_NOT_A_NUMBER = re.compile(r"(could not convert string to float|invalid literal for int\(\) with base 10): '(.*)'$")


def _line_of(path: str | os.PathLike[str] | None, text: str) -> str:
    """" (line N)" of the first element whose text is ``text`` in the file at ``path`` ("" if none)."""
    if path is None:
        return ""
    try:
        lines = Path(path).read_bytes().decode("utf-8", errors="replace").splitlines()
    except OSError:
        return ""
    wanted = f">{text}<"
    return next((f" (line {number})" for number, line in enumerate(lines, 1) if wanted in line), "")


def _describe(error: BaseException, path: str | os.PathLike[str] | None = None) -> str:
    text = str(error).strip()
    found = _NOT_A_NUMBER.search(text) if isinstance(error, ValueError) else None
    if found:  # a value commonroad-io read with float() or int(): say which, and where
        kind = "a whole number" if found.group(1).startswith("invalid literal for int") else "a number"
        return f"`{found.group(2)}` is not {kind}{_line_of(path, found.group(2))}"
    if isinstance(error, AttributeError) and "NoneType" in text or isinstance(error, IndexError):
        return "an element it needs is missing or empty"
    if type(error) is Exception and not text:  # what commonroad-io raises for a value it cannot make out
        return "a value is neither <exact> nor <intervalStart>/<intervalEnd>, or a position neither a point nor a shape"
    if isinstance(error, (ValueError, TypeError)) and text:
        return text
    return f"{type(error).__name__}: {text}" if text else f"unexpected content ({type(error).__name__})"


#: What each top-level element needs: commonroad-io fails without it or, worse, fills in zeros.
_STATE = ("initialState", "initialState/position", "initialState/orientation", "initialState/time")
_REQUIRED = {
    "lanelet": ("leftBound", "rightBound"),
    "staticObstacle": ("type", "shape", *_STATE),
    # a dynamic obstacle's initial <velocity> may be absent (the schema's choice): rac takes it from the
    # motion (:func:`_obstacle`), as for a trajectory state, not commonroad-io's 0
    "dynamicObstacle": ("type", "shape", *_STATE),
    "planningProblem": (*_STATE, "initialState/velocity", "goalState"),
    "obstacle": ("role", "type", "shape", "initialState"),  # the 2018b format's, static or dynamic by its <role>
}
#: The elements a ``<commonRoad>`` holds, in either format (2018b's obstacles are ``<obstacle>``).
_TOP_LEVEL = ("location", "scenarioTags", "lanelet", "trafficSign", "trafficLight", "intersection", "staticObstacle",
              "dynamicObstacle", "phantomObstacle", "environmentObstacle", "obstacle", "planningProblem")
#: The elements whose ``<shape>`` commonroad-io reads as one obstacle shape (:func:`_check_structure`).
_SHAPED = ("staticObstacle", "dynamicObstacle", "obstacle")
#: The roles of a 2018b ``<obstacle>`` (commonroad-io fails on another without naming it).
_ROLES_2018B = ("static", "dynamic")
_LABELS = {
    "lanelet": "lanelet",
    "staticObstacle": "static obstacle",
    "dynamicObstacle": "dynamic obstacle",
    "environmentObstacle": "environment obstacle",
    "phantomObstacle": "phantom obstacle",
    "obstacle": "obstacle",
    "planningProblem": "planning problem",
}


def _check_structure(path: str | os.PathLike[str], root, positions: dict[int, tuple[int, int]]) -> None:
    # CommonRoad ids are unique within a file (commonroad-io keeps the last): each id's element and its line
    seen: dict[str, tuple[str, int | None]] = {}
    for node in root:
        if node.tag in _LABELS and node.get("id") is None:
            # commonroad-io fails on it with Python's own int(None) message, which named no attribute
            where = f" (line {positions[id(node)][0]})" if id(node) in positions else ""
            raise ScenarioError(path, f"{_LABELS[node.tag]} (without id)",
                                f"has no `id` attribute{where}: every CommonRoad lanelet, obstacle and planning "
                                "problem has a unique positive whole-number id")
        # a misspelt element (<dynamicObstacles>, <staticobstacle>) is one commonroad-io passes over without a
        # word: the model lacked that obstacle or lanelet; another unknown element is left alone (an extension)
        close = difflib.get_close_matches(node.tag, _TOP_LEVEL, n=1, cutoff=0.8) if node.tag not in _TOP_LEVEL \
            else []
        if close:
            raise ScenarioError(path, f"<{node.tag}>", f"is not a CommonRoad element (is it <{close[0]}>?): "
                                                        "commonroad-io passes over it, so the model would lack it")
        ident = node.get("id")
        if node.tag in _LABELS and ident is not None:
            here = f"{_LABELS[node.tag]} {ident}"
            # a planning problem's id has a namespace of its own: commonroad-io keeps planning problems
            # apart from the scenario's elements (nothing is lost), and CommonRoad's own converters give
            # a planning problem the id of its vehicle's recorded obstacle (OpenSCENARIO's, say)
            key = f"planningProblem {ident}" if node.tag == "planningProblem" else ident
            if key in seen:
                # both lines: in a file of hundreds of obstacles (two files merged, say) the id alone
                # did not say where the two elements are
                first, line = seen[key][1], positions.get(id(node), (None,))[0]
                lines = f" (lines {first} and {line})" if first is not None and line is not None else ""
                if seen[key][0] == here:
                    # two of one kind: "lanelet 3 has the id of lanelet 3" read as a riddle
                    raise ScenarioError(path, f"two {_LABELS[node.tag]}s",
                                        f"have the id {ident}{lines}: ids must be unique in a file")
                raise ScenarioError(path, here, f"has the id of {seen[key][0]}{lines}: ids must be unique in a file")
            seen[key] = (here, positions.get(id(node), (None,))[0])
    for node in root:
        for child in _REQUIRED.get(node.tag, ()):
            if node.find(child) is None:
                parent, _, name = child.rpartition("/")
                where = f" in its <{parent}>" if parent else ""
                raise ScenarioError(path, f"{_LABELS[node.tag]} {node.get('id', '(without id)')}",
                                    f"has no <{name}>{where}")
        if node.tag in _SHAPED and node.find("shape/shapeGroup") is not None:
            # valid in the 2020a schema, but commonroad-io (2026.1) reads it as no shape at all and fails
            # on that with "an element it needs is missing", which sent users looking for a missing element
            raise ScenarioError(path, f"{_LABELS[node.tag]} {node.get('id', '(without id)')}",
                                "has a <shapeGroup> as its shape, which commonroad-io does not read: give the "
                                "obstacle one rectangle, circle, polygon, truck or semi-trailer truck (rac bounds "
                                "any shape by a rectangle, so the group's bounding rectangle loses nothing)")
        if node.tag == "obstacle" and (role := (node.findtext("role") or "").strip()) not in _ROLES_2018B:
            raise ScenarioError(path, f"obstacle {node.get('id', '(without id)')}",
                                f"has the <role> `{role}`: a 2018b obstacle's role is `static` or `dynamic`")
        if node.tag in ("dynamicObstacle", "obstacle") and (trajectory := node.find("trajectory")) is not None \
                and trajectory.find("state") is None:
            raise ScenarioError(path, f"{_LABELS[node.tag]} {node.get('id', '(without id)')}",
                                "has an empty <trajectory>: a trajectory has at least one <state>")
        for goal in node.iterfind("goalState") if node.tag == "planningProblem" else ():
            # commonroad-io fails on either with "an element it needs is missing" or its own GoalRegion assert
            element = f"goal of planning problem {node.get('id', '(without id)')}"
            time = goal.find("time")
            if time is None:
                raise ScenarioError(path, element, "has no <time> in its <goalState>: CommonRoad's goal states "
                                                   "give the time interval in which to reach the goal")
            if time.find("intervalStart") is None or time.find("intervalEnd") is None:
                raise ScenarioError(path, element, "has a <time> without <intervalStart> and <intervalEnd> in its "
                                                   "<goalState>: a goal's time is an interval (for one time step "
                                                   "N, write N as both ends)")


def _diagnose(path: str | os.PathLike[str], root, error: BaseException,
              positions: dict[int, tuple[int, int]] | None = None) -> ScenarioError:
    """Find the element commonroad-io failed on by reading the elements one at a time; ``positions``
    (:func:`_positions`) give the line of a malformed part of it (:func:`_malformed`)."""
    positions = positions or {}

    # commonroad: only when this runs; importing rac.model.commonroad stays light
    from commonroad.common.reader import file_reader_xml as factories

    # commonroad: only when this runs; importing rac.model.commonroad stays light
    from commonroad.scenario.lanelet import LaneletNetwork

    def label(node) -> str:
        return f"{_LABELS[node.tag]} {node.get('id', '(without id)')}"

    if root.get("commonRoadVersion") == "2018b" and root.get("tags") is None:
        # commonroad-io reads a 2018b file's tags from this attribute (2020a has <scenarioTags> instead)
        newer = [f"<{tag}>" for tag in ("location", "scenarioTags") if root.find(tag) is not None]
        guess = (f"; its {' and '.join(newer)} belong to the 2020a format: is it a 2020a file labelled 2018b? "
                 "Then write commonRoadVersion=\"2020a\"") if newer else ""
        return ScenarioError(path, "<commonRoad>", "is labelled commonRoadVersion=\"2018b\" but has no `tags` "
                                                   f"attribute, which commonroad-io reads in a 2018b file{guess}")
    header = [("scenario tags", lambda: factories.TagsFactory.create_from_xml_node(root)),
              ("location", lambda: factories.LocationFactory.create_from_xml_node(root))]
    for element, read in header if root.get("commonRoadVersion") != "2018b" else ():
        try:
            read()
        except Exception as failure:  # commonroad-io's failures only (reader_failure)
            if not reader_failure(failure):
                raise
            return ScenarioError(path, element, f"cannot be read: {_describe(failure, path)}")
    for node in root:  # commonroad-io asserts on a negative id, in words that do not say so
        ident = _number_text(node.get("id")) if node.tag in _LABELS else None
        if ident is not None and ident < 0:
            return ScenarioError(path, label(node), "has a negative id: CommonRoad ids are positive whole numbers")
    lanelet_ids = {node.get("id") for node in root.iter("lanelet")}
    for lanelet in root.iter("lanelet"):  # commonroad-io's shapely fails on a NaN with a GEOS message
        for bound in ("leftBound", "rightBound"):
            pairs = ((_number_text(point.findtext("x")), _number_text(point.findtext("y")))
                     for point in lanelet.iterfind(f"{bound}/point"))
            unfinite = _unfinite_point(path, f"lanelet {lanelet.get('id')}",
                                       ((x, y) for x, y in pairs if x is not None and y is not None), f"its <{bound}>")
            if unfinite is not None:
                return unfinite
    for lanelet in root.iterfind("lanelet"):  # the road's (a goal's <lanelet ref=...> has no bounds)
        bounds = _bound_points(path, lanelet)
        if bounds is not None:
            return bounds
    for node in root.iter():
        low, high = node.find("intervalStart"), node.find("intervalEnd")
        if low is None or high is None:
            continue
        start, end = _number_text(low.text), _number_text(high.text)
        if start is None or end is None:
            continue
        finite = math.isfinite(start) and math.isfinite(end)  # NaN fails commonroad-io's start <= end assert
        if not finite or start > end:
            owner = next((f"{label(n)}'s" for n in root if n.tag in _LABELS and node in n.iter()), "an")
            why = "which ends before it starts" if finite else "whose bounds are not both finite"
            return ScenarioError(path, f"{owner} <{node.tag}>", f"has the interval [{low.text}, {high.text}], {why}")
    for problem in root.iter("planningProblem"):
        for position in problem.iterfind("goalState/position"):
            shapes = [child.tag for child in position]
            unsupported = [tag for tag in shapes if tag not in ("rectangle", "circle", "polygon", "lanelet")]
            if unsupported or not shapes:
                found = f"<{unsupported[0]}>" if unsupported else "an empty <position>"
                return ScenarioError(path, f"goal of {label(problem)}", f"has an unsupported shape ({found}); "
                                     f"{GOAL_SHAPES}")
        for ref in problem.iterfind("goalState/position/lanelet"):
            if ref.get("ref") not in lanelet_ids:
                return ScenarioError(path, f"goal of {label(problem)}",
                                     f"refers to lanelet {ref.get('ref')}, which the file does not define")
    unread = _traffic_rules(path, root)
    if unread is not None:
        return unread
    network = LaneletNetwork()
    readers = {
        "lanelet": lambda node: factories.LaneletFactory.create_from_xml_node(node),
        "staticObstacle": lambda node: factories.StaticObstacleFactory.create_from_xml_node(node, network, False),
        "dynamicObstacle": lambda node: factories.DynamicObstacleFactory.create_from_xml_node(node, network, False),
        "obstacle": lambda node: (factories.StaticObstacleFactory if node.findtext("role").strip() == "static" else
                                  factories.DynamicObstacleFactory).create_from_xml_node(node, network, False),
        "environmentObstacle": lambda node: factories.EnvironmentObstacleFactory.create_from_xml_node(node),
        "phantomObstacle": lambda node: factories.PhantomObstacleFactory.create_from_xml_node(node),
    }
    for node in root:
        if node.tag in readers:
            try:
                readers[node.tag](node)
            except Exception as failure:  # commonroad-io's failures only (reader_failure)
                if not reader_failure(failure):
                    raise
                return _malformed(path, label(node), node, positions) or \
                    ScenarioError(path, label(node), f"cannot be read: {_describe(failure, path)}")
    try:
        network = factories.LaneletNetworkFactory.create_from_xml_node(ElementTree.ElementTree(root))
    except Exception as failure:  # commonroad-io's failures only (reader_failure)
        if not reader_failure(failure):
            raise
        return ScenarioError(path, "lanelet network", f"cannot be read: {_describe(failure, path)}")
    for node in root.iter("planningProblem"):
        try:
            factories.PlanningProblemFactory.create_from_xml_node(node, network)
        except Exception as failure:  # commonroad-io's failures only (reader_failure)
            if not reader_failure(failure):
                raise
            return _malformed(path, label(node), node, positions) or \
                ScenarioError(path, label(node), f"cannot be read: {_describe(failure, path)}")
    return ScenarioError(path, None, f"cannot be read by commonroad-io ({_describe(error, path)})")


def _traffic_rules(path: str | os.PathLike[str], root) -> ScenarioError | None:
    """A traffic light or sign commonroad-io refuses the whole file for, though rac reads neither: a
    light's colour it does not know (it failed with "'off' is not a valid TrafficLightState", blaming
    the lanelet network), a sign no lanelet references (an assert in its own words)."""
    # commonroad: only when this runs; importing rac.model.commonroad stays light
    from commonroad.scenario.traffic_light import TrafficLightState

    colours = [state.value for state in TrafficLightState]
    for light in root.iterfind("trafficLight"):
        for colour in light.iterfind("cycle/cycleElement/color"):
            if colour.text not in colours:
                return ScenarioError(path, f"traffic light {light.get('id', '(without id)')}",
                                     f"has the colour `{colour.text}`, which commonroad-io does not read (it reads "
                                     f"{', '.join(colours)}): rac does not use traffic lights, but commonroad-io "
                                     "refuses the file; write one of those colours")
    referenced = {ref.get("ref") for ref in root.iter("trafficSignRef")}
    for sign in root.iterfind("trafficSign"):
        if sign.get("id") not in referenced:
            return ScenarioError(path, f"traffic sign {sign.get('id', '(without id)')}",
                                 "is referenced by no lanelet's <trafficSignRef>: rac does not use traffic signs, "
                                 "but commonroad-io refuses the file; reference it from the lanelet it applies to, "
                                 "or remove it")
    return None


#: What a part of an element needs (commonroad-io fails without it, in words that do not name it).
_NEEDS = {"point": ("x", "y"), "center": ("x", "y"), "rectangle": ("length", "width"), "circle": ("radius",)}
#: The elements that hold one number (commonroad-io fails on an empty one with "float() argument must be ...").
_NUMBERS = ("x", "y", "exact", "intervalStart", "intervalEnd", "length", "width", "radius", "orientation",
            "originXShift")
#: The elements that hold a state's values (each an ``<exact>`` or an ``<intervalStart>``/``<intervalEnd>``
#: pair, its ``<position>`` a point or shapes).
_STATES = ("initialState", "state", "goalState")


def _malformed(path: str | os.PathLike[str], element: str, node,
               positions: dict[int, tuple[int, int]]) -> ScenarioError | None:
    """What is malformed in ``node`` (a top-level element commonroad-io failed on), in the file's words,
    where commonroad-io's own failure does not say: a part without what it needs (:data:`_NEEDS`: a
    ``<point>`` without ``<y>``, say), an empty ``<position>``, ``<shape>`` or number, a state's value
    without ``<exact>`` (or an interval), a trajectory state without ``<time>`` or ``<position>``, or one
    whose values differ from the first state's (commonroad-io: "an element it needs is missing or empty",
    "all states must have the same attributes", "a value is neither <exact> nor ..."). None if none of these."""
    def line(part) -> str:
        where = positions.get(id(part))
        return f" (line {where[0]})" if where else ""

    parents = {child: parent for parent in node.iter() for child in parent}
    for part in node.iter():
        for child in _NEEDS.get(part.tag, ()):  # (a shape's <center> is optional: the origin)
            if part.find(child) is None:
                return ScenarioError(path, element, f"has a <{part.tag}> without <{child}>{line(part)}")
        if part.tag in ("position", "shape") and len(part) == 0:  # a point or shapes / one kind of shape
            return ScenarioError(path, element, f"has an empty <{part.tag}>{line(part)}")
        if part.tag in _NUMBERS and len(part) == 0 and not (part.text or "").strip():
            where = f" in its <{parents[part].tag}>" if part in parents else ""
            return ScenarioError(path, element, f"has an empty <{part.tag}>{where}{line(part)}")
    for state in (part for part in node.iter() if part.tag in _STATES):
        for value in state:
            if value.tag == "position" or value.find("exact") is not None or \
                    (value.find("intervalStart") is not None and value.find("intervalEnd") is not None):
                continue
            return ScenarioError(path, element, f"has a <{value.tag}> without <exact> (or <intervalStart> and "
                                                f"<intervalEnd>) in its <{state.tag}>{line(value)}")
    for state in (part for part in node.iter() if part.tag in _STATES):
        point = state.find("position/point")
        if point is not None and point.find("z") is not None:  # commonroad-io: "too many values to unpack"
            return ScenarioError(path, element, f"has a <z> in the <point> of its <{state.tag}>{line(point)}: "
                                                "commonroad-io reads a state's position in the plane only (a "
                                                "lanelet's points may have one); remove the <z>")
    for trajectory in node.iterfind("trajectory"):
        states = trajectory.findall("state")
        first = {child.tag for child in states[0]} if states else set()
        for state in states:
            for needed in ("time", "position"):
                if state.find(needed) is None:
                    return ScenarioError(path, element, f"has a <state> without <{needed}> in its "
                                                        f"<trajectory>{line(state)}")
            if state.find("time/exact") is None:
                return ScenarioError(path, element, f"has a <state> whose <time> is an interval in its <trajectory>"
                                                    f"{line(state)}: a trajectory's states are at exact time steps")
            tags = {child.tag for child in state}
            if tags != first:
                step = (state.findtext("time/exact") or "?").strip()
                differ = [f"no <{tag}>" for tag in sorted(first - tags)] + \
                    [f"a <{tag}>" for tag in sorted(tags - first)]
                return ScenarioError(path, element, f"has a <trajectory> whose state at time step {step} has "
                                                    f"{' and '.join(differ)}, unlike its first state{line(state)}: "
                                                    "commonroad-io needs the same values in every state")
    return None


def _bound_points(path: str | os.PathLike[str], lanelet) -> ScenarioError | None:
    """A lanelet whose bounds commonroad-io cannot pair (it fails with numpy's "operands could not be
    broadcast" or a bare assert): fewer than 2 points in a bound, or not as many on the left as on the right."""
    counts = {bound: len(lanelet.findall(f"{bound}/point")) for bound in ("leftBound", "rightBound")}
    element = f"lanelet {lanelet.get('id', '(without id)')}"
    for bound, count in counts.items():
        if count < 2:
            return ScenarioError(path, element, f"has {count} point{'' if count == 1 else 's'} in its <{bound}>: a "
                                                 "bound is a polyline of at least 2 points")
    if counts["leftBound"] != counts["rightBound"]:
        return ScenarioError(path, element, f"has {counts['leftBound']} points in its <leftBound> and "
                                            f"{counts['rightBound']} in its <rightBound>: CommonRoad pairs them, one "
                                            "left and one right point per cross-section")
    return None


def _convert(path, root, cr_scenario, problems, planning_problem_id: int | None,
             require_choice: bool = False, positions: dict[int, tuple[int, int]] | None = None) -> Scenario:
    positions = positions or {}
    _check_obstacle_format(path, root)
    nodes = {(node.tag, node.get("id")): node for node in root}

    def where(tag: str, ident: int) -> tuple[int, int] | None:
        node = nodes.get((tag, str(ident)))
        return None if node is None else positions.get(id(node))

    dt = float(cr_scenario.dt)
    lanelets = sorted(cr_scenario.lanelet_network.lanelets, key=lambda lanelet: lanelet.lanelet_id)
    if not lanelets:
        raise ScenarioError(path, None, "has no lanelets (rac needs the road network)")
    for lanelet in lanelets:
        _check_finite_bounds(path, lanelet)
        _check_width(path, lanelet, where("lanelet", lanelet.lanelet_id))
        _check_direction(path, lanelet, where("lanelet", lanelet.lanelet_id))
    road = tuple(_polygon(lanelet.polygon.vertices) for lanelet in lanelets)
    lanes = tuple(Lane(lanelet.lanelet_id, _points(lanelet.center_vertices), _points(lanelet.left_vertices),
                       _points(lanelet.right_vertices)) for lanelet in lanelets)

    # commonroad: only when this runs; importing rac.model.commonroad stays light
    from commonroad.scenario.obstacle import StaticObstacle

    ids = tuple(sorted(problems.planning_problem_dict))
    if not ids:
        raise ScenarioError(path, None, "has no planning problem (rac needs one for the ego's start and goal)")
    if planning_problem_id is None and require_choice and len(ids) > 1:
        raise PlanningProblemError(path, None, ids)
    if planning_problem_id is None:
        planning_problem_id = ids[0]
    elif planning_problem_id not in problems.planning_problem_dict:
        raise PlanningProblemError(path, planning_problem_id, ids)
    problem = problems.planning_problem_dict[planning_problem_id]

    obstacles = []
    # the ego's own recorded run, not another road user: the one with the planning problem's id first
    recorded = sorted((o for o in cr_scenario.dynamic_obstacles if _recorded_ego(o, problem)),
                      key=lambda o: (o.obstacle_id != problem.planning_problem_id, o.obstacle_id))
    recorded_ego = int(recorded[0].obstacle_id) if recorded else None
    for obstacle in sorted([*cr_scenario.static_obstacles, *cr_scenario.dynamic_obstacles],
                           key=lambda obstacle: obstacle.obstacle_id):
        if obstacle.obstacle_id == recorded_ego:
            continue
        static = isinstance(obstacle, StaticObstacle)
        name = f"{'static' if static else 'dynamic'} obstacle {obstacle.obstacle_id}"
        tag = "staticObstacle" if static else "dynamicObstacle"
        node = nodes.get((tag, str(obstacle.obstacle_id))) or nodes.get(("obstacle", str(obstacle.obstacle_id)))
        placement = shape_placement(path, name, node)
        given = node is None or static or node.find("initialState/velocity") is not None
        obstacles.append(_obstacle(path, name, obstacle, static, dt, where(tag, obstacle.obstacle_id), placement,
                                   initial_velocity=given))

    ego = _ego(path, f"planning problem {planning_problem_id}", problem.initial_state, dt)
    goal = _goal(path, f"goal of planning problem {planning_problem_id}", problem.goal, cr_scenario.lanelet_network, dt)
    name = root.get("benchmarkID") or Path(path).stem
    return Scenario(name=name, path=os.fspath(path), dt=dt, road=road, obstacles=tuple(obstacles), ego=ego,
                    goal=goal, planning_problem_id=planning_problem_id, planning_problem_ids=ids,
                    lanes=lanes, recorded_ego=recorded_ego, traffic_rules=_rules_counted(cr_scenario.lanelet_network))


def _rules_counted(network) -> TrafficRules:
    """The traffic lights, traffic signs and stop lines of ``network`` (:attr:`Scenario.traffic_rules`)."""
    signs = network.traffic_signs
    return TrafficRules(lights=len(network.traffic_lights), signs=len(signs),
                        stop_lines=sum(lanelet.stop_line is not None for lanelet in network.lanelets),
                        speed_limits=bool(signs) and all(element.traffic_sign_element_id.name == "MAX_SPEED"
                                                         for sign in signs for element in sign.traffic_sign_elements))


def _recorded_ego(obstacle, problem) -> bool:
    """Whether the dynamic ``obstacle`` is the planning problem's own vehicle as recorded: its initial
    time step, position and orientation are exactly the planning problem's (CommonRoad's OpenSCENARIO
    converter writes the ego so, under the planning problem's id; CommonRoad-CriMe's scenarios under
    another). Two road users cannot start on one spot with one heading; as an obstacle it would sit
    on the ego, and ``collide()`` hold from the start."""
    import numpy as np  # numpy: only when this runs; importing rac.model.commonroad stays light

    start, own = problem.initial_state, obstacle.initial_state
    for attribute in ("time_step", "orientation"):
        mine, theirs = getattr(start, attribute, None), getattr(own, attribute, None)
        if not isinstance(mine, (int, float)) or not isinstance(theirs, (int, float)) or mine != theirs:
            return False
    here, there = getattr(start, "position", None), getattr(own, "position", None)
    if not isinstance(here, np.ndarray) or not isinstance(there, np.ndarray) or here.shape != there.shape:
        return False  # an uncertain position (a shape) is not a recorded run
    return bool(np.array_equal(here, there))


#: The obstacle elements commonroad-io reads in each format; it passes over the other format's without a word.
_OBSTACLES_OF_FORMAT = {"2018b": ("obstacle",),
                        "2020a": ("staticObstacle", "dynamicObstacle", "environmentObstacle", "phantomObstacle")}


def _check_obstacle_format(path, root) -> None:
    """Refuse an obstacle element of the other format than the file's ``commonRoadVersion`` (a 2018b
    ``<obstacle>`` in a 2020a file, a ``<dynamicObstacle>`` in a 2018b one): commonroad-io reads the
    file without it, and the model had no such obstacle, so that every safety query held, silently."""
    version = root.get("commonRoadVersion")
    read = _OBSTACLES_OF_FORMAT.get(version, ())
    for node in root:
        other = next((v for v, tags in _OBSTACLES_OF_FORMAT.items() if v != version and node.tag in tags), None)
        if other is None or node.tag in read:
            continue
        raise ScenarioError(
            path, f"{_LABELS[node.tag]} {node.get('id', '(without id)')}",
            f"is written as <{node.tag}>, the {other} format's obstacle element, in a file labelled "
            f"commonRoadVersion=\"{version}\": commonroad-io reads a {version} file's obstacles from "
            f"{', '.join(f'<{tag}>' for tag in read)} only and passes over it, so the model would lack this "
            f"obstacle; write it in the {version} format, or label the file commonRoadVersion=\"{other}\" if it is one")


def _check_width(path, lanelet, position: tuple[int, int] | None) -> None:
    """E0721: a lanelet whose left and right bounds coincide at every point: no area, so nothing can
    be on it (a lane may narrow to a point where it merges, but not everywhere)."""
    left, right = _points(lanelet.left_vertices), _points(lanelet.right_vertices)
    if len(left) == len(right) and all(math.hypot(lx - rx, ly - ry) <= 1e-9 for (lx, ly), (rx, ry) in zip(left, right)):
        raise InconsistentScenarioError(
            path, "E0721", f"lanelet {lanelet.lanelet_id}", "leftBound",
            "has no width: its <leftBound> and <rightBound> coincide at every point",
            "give the lanelet its two bounds (a lane's width apart, e.g. 3.5 m), or remove it", position)


def _check_direction(path, lanelet, position: tuple[int, int] | None) -> None:
    """E0729: a lanelet whose left and right bounds run in opposite directions (one written from the lane's
    end to its start, as a converter or a hand edit leaves it). Its polygon, the right bound then the left one
    reversed, crosses itself: most of the lane lies outside it, so ``offroad()`` held across the lane and
    ``rac check`` blamed the ego's start (W0716), or said nothing where the ego only drove onto it later.
    The bounds run opposite when pairing each one's start with the other's end brings them closer than
    pairing start with start and end with end (for bounds that run alike, those pairs are the diagonals of
    the lane's outline, longer than its two ends)."""
    left, right = _points(lanelet.left_vertices), _points(lanelet.right_vertices)
    if len(left) < 2 or len(right) < 2:
        return
    along = math.dist(left[0], right[0]) + math.dist(left[-1], right[-1])
    across = math.dist(left[0], right[-1]) + math.dist(left[-1], right[0])
    if across < along:
        raise InconsistentScenarioError(
            path, "E0729", f"lanelet {lanelet.lanelet_id}", "leftBound",
            f"has its <leftBound> and <rightBound> running in opposite directions: the left one from "
            f"({_short(left[0])}) to ({_short(left[-1])}), the right one from ({_short(right[0])}) to "
            f"({_short(right[-1])}), so the lanelet's outline crosses itself and most of the lane would be off "
            "the road", "write both bounds in the driving direction (reverse the points of the one that runs "
            "backwards)", position)


def _short(point: tuple[float, float]) -> str:
    """A bound's point as a message writes it: ``12.5, -3``."""
    return ", ".join(f"{value:.6g}" for value in point)


def _check_finite_bounds(path, lanelet) -> None:
    """A lanelet bound's point that is not finite: the road's polygons (and ``offroad()``) need finite ones."""
    import numpy as np  # numpy: only when this runs; importing rac.model.commonroad stays light

    for bound, vertices in (("leftBound", lanelet.left_vertices), ("rightBound", lanelet.right_vertices)):
        points = np.asarray(vertices, dtype=float)
        if not np.isfinite(points).all():  # one vectorised test per bound: a large road stays fast
            unfinite = _unfinite_point(path, f"lanelet {lanelet.lanelet_id}", _points(points), f"its <{bound}>")
            assert unfinite is not None  # a point is not finite: the test above
            raise unfinite


def _unfinite_point(path, element: str, points, where: str) -> ScenarioError | None:
    """The :class:`ScenarioError` of the first of ``points`` ((x, y) numbers) that is not finite, in
    ``where`` of ``element``; None when all are."""
    bad = next(((x, y) for x, y in points if not (math.isfinite(x) and math.isfinite(y))), None)
    return None if bad is None else ScenarioError(path, element, f"has a point that is not finite "
                                                                 f"({bad[0]}, {bad[1]}) in {where}")


def _finite(path, element: str, quantity: str, value, what: str) -> float:
    """``value`` as a float; a :class:`ScenarioError` when it is NaN or infinite: the model's numbers
    and geometry need finite ones (and commonroad-io's derived values, e.g. a sine of inf, fail)."""
    number = float(value)
    if not math.isfinite(number):
        article = "an" if quantity[:1] in ("a", "e", "i", "o", "u") else "a"
        raise ScenarioError(path, element, f"has {article} {quantity} that is not finite ({number}) in {what}")
    return number


def _seconds(step: float, dt: float) -> float:
    """``step * dt`` without the float noise of the product (3 * 0.1 is 0.3, not 0.30000000000000004)."""
    return round(step * dt, 9)


def _points(vertices) -> tuple[tuple[float, float], ...]:
    """``(x, y)`` of each vertex; a ``<z>`` (the schema allows an elevation) is left out: the model is planar."""
    return tuple((float(point[0]), float(point[1])) for point in vertices)


def _polygon(points) -> Polygon:
    """A counter-clockwise polygon without repeated points from CommonRoad vertices."""
    result: list[tuple[float, float]] = []
    for x, y, *_ in points:  # a <z> (elevation) left out: the model is planar
        point = (float(x), float(y))
        if not result or point != result[-1]:
            result.append(point)
    if len(result) > 1 and result[0] == result[-1]:
        result.pop()
    area2 = sum(x0 * y1 - x1 * y0 for (x0, y0), (x1, y1) in zip(result, result[1:] + result[:1]))
    if area2 < 0:
        result.reverse()
    return Polygon(tuple(result))


def _exact_position(path, element: str, state, what: str) -> tuple[float, float]:
    import numpy as np  # numpy: only when this runs; importing rac.model.commonroad stays light

    position = getattr(state, "position", None)
    if position is None:
        raise ScenarioError(path, element, f"has no position in {what}")
    array = np.asarray(position) if isinstance(position, (np.ndarray, list, tuple)) else None
    if array is None or array.shape != (2,):
        raise ScenarioError(path, element, f"has an uncertain position (a {type(position).__name__}) in {what}; "
                                           "rac needs exact states")
    x, y = float(array[0]), float(array[1])
    if not (math.isfinite(x) and math.isfinite(y)):
        raise ScenarioError(path, element, f"has a position that is not finite ({x}, {y}) in {what}")
    return x, y


def _exact_number(path, element: str, state, attribute: str, what: str) -> float | None:
    value = getattr(state, attribute, None)
    if value is None:
        return None
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise ScenarioError(path, element, f"has an uncertain {attribute} (an interval) in {what}; "
                                           "rac needs exact states")
    return _finite(path, element, attribute, value, what)


def _time_step(path, element: str, state, what: str) -> int:
    step = getattr(state, "time_step", None)
    if isinstance(step, bool) or not isinstance(step, int):
        raise ScenarioError(path, element, f"has no exact time step in {what}")
    return step


def shape_placement(path, element: str, node) -> tuple[float, float, float]:
    """The ``<center>`` (x forward, y left) and ``<orientation>`` of the rectangle or circle that is the
    obstacle ``node``'s shape, in the obstacle's own frame; (0, 0, 0) when the file gives none.

    Why from the XML: commonroad-io (2026.1) reads an obstacle's rectangle as its length, width and
    ``originXShift`` only, and a circle as its radius, so a shape the file places off the obstacle's
    position (CommonRoad 2020a allows both) would stand at the position, turned with the obstacle.
    ``element`` names the obstacle in a :class:`ScenarioError` for a number that is not one."""
    shape = node.find("shape") if node is not None else None
    part = next(iter(shape), None) if shape is not None else None
    if part is None or part.tag not in ("rectangle", "circle"):
        return 0.0, 0.0, 0.0
    values = []
    for child, quantity in (("center/x", "centre x"), ("center/y", "centre y"), ("orientation", "orientation")):
        text = part.findtext(child)
        if text is None or child == "orientation" and part.tag == "circle":
            values.append(0.0)
            continue
        number = _number_text(text)
        if number is None:
            raise ScenarioError(path, element, f"has `{text.strip()}` as its shape's <{child.replace('/', '> <')}>, "
                                               "not a number")
        values.append(_finite(path, element, quantity, number, "its shape"))
    return values[0], values[1], values[2]


def placed_outline(shape, placement: tuple[float, float, float]) -> tuple[tuple[float, float], ...] | None:
    """The outline, in the obstacle's own frame, of commonroad-io's rectangle or circle ``shape`` placed by
    ``placement`` (:func:`shape_placement`): the turned rectangle's 4 corners, the circle's inscribed
    :data:`CIRCLE_VERTICES`-gon; None when the placement moves nothing or the shape is of another kind.
    What :func:`rac.output.render.render_trajectory` draws, so that the picture shows the obstacle where
    the model has it (commonroad-io's own drawing stands it at its position)."""
    # commonroad: only when this runs; importing rac.model.commonroad stays light
    from commonroad.geometry.obstacle_shapes.circle_obstacle_shape import CircleObstacleShape

    # commonroad: only when this runs; importing rac.model.commonroad stays light
    from commonroad.geometry.obstacle_shapes.rect_obstacle_shape import RectObstacleShape

    ahead, aside, turned = placement
    if placement == (0.0, 0.0, 0.0):
        return None
    if isinstance(shape, RectObstacleShape):
        cos, sin = math.cos(turned), math.sin(turned)
        centre = (ahead - shape.origin_x_shift, aside)
        return tuple((centre[0] + a * shape.length / 2 * cos - b * shape.width / 2 * sin,
                      centre[1] + a * shape.length / 2 * sin + b * shape.width / 2 * cos)
                     for a, b in ((1, 1), (-1, 1), (-1, -1), (1, -1)))
    if isinstance(shape, CircleObstacleShape):
        return tuple((ahead + shape.radius * math.cos(2 * math.pi * i / CIRCLE_VERTICES),
                      aside + shape.radius * math.sin(2 * math.pi * i / CIRCLE_VERTICES))
                     for i in range(CIRCLE_VERTICES))
    return None


def _box(path, element: str, shape, placement: tuple[float, float, float] = (0.0, 0.0, 0.0)
         ) -> tuple[float, float, float, float]:
    """length, width and the offset (forward, left) of the box centre from the obstacle's position;
    ``placement`` is the shape's centre and orientation in the obstacle's frame (:func:`_shape_placement`):
    a turned rectangle becomes its bounding rectangle in that frame."""
    ahead, aside, turned = placement
    # commonroad: only when this runs; importing rac.model.commonroad stays light
    from commonroad.geometry.obstacle_shapes.circle_obstacle_shape import CircleObstacleShape

    # commonroad: only when this runs; importing rac.model.commonroad stays light
    from commonroad.geometry.obstacle_shapes.rect_obstacle_shape import RectObstacleShape

    if isinstance(shape, RectObstacleShape):
        length = _finite(path, element, "length", shape.length, "its shape")
        width = _finite(path, element, "width", shape.width, "its shape")
        shift = _finite(path, element, "originXShift", shape.origin_x_shift, "its shape")
        if turned:
            cos, sin = abs(math.cos(turned)), abs(math.sin(turned))
            length, width = length * cos + width * sin, length * sin + width * cos
        return length, width, ahead - shift, aside
    if isinstance(shape, CircleObstacleShape):  # (its occupancy's shapely polygon has half the radius)
        radius = _finite(path, element, "radius", shape.radius, "its shape")
        return 2.0 * radius, 2.0 * radius, ahead, aside
    import numpy as np  # numpy: only when this runs; importing rac.model.commonroad stays light

    # commonroad: only when this runs; importing rac.model.commonroad stays light
    from commonroad.scenario.state import InitialState

    try:
        occupancy = shape.compute_occupancy_for_state(InitialState(time_step=0, position=np.zeros(2), orientation=0.0))
        min_x, min_y, max_x, max_y = (float(v) for v in occupancy.shapely_object.bounds)
    except Exception as failure:  # commonroad-io's and shapely's failures only (reader_failure)
        if not reader_failure(failure):
            raise
        raise ScenarioError(path, element, f"has a shape rac cannot bound by a rectangle "
                                           f"({type(shape).__name__})") from None
    if not all(map(math.isfinite, (min_x, min_y, max_x, max_y))):
        raise ScenarioError(path, element, f"has an empty shape ({type(shape).__name__})")
    return max_x - min_x, max_y - min_y, (min_x + max_x) / 2, (min_y + max_y) / 2


def _obstacle(path, element: str, obstacle, static: bool, dt: float, position: tuple[int, int] | None = None,
              placement: tuple[float, float, float] = (0.0, 0.0, 0.0), initial_velocity: bool = True) -> Obstacle:
    """``initial_velocity`` False: the file's initial state has no ``<velocity>`` (commonroad-io reads 0
    then); it comes from the move to the next state, like a trajectory state's."""
    # commonroad: only when this runs; importing rac.model.commonroad stays light
    from commonroad.prediction.prediction import SetBasedPrediction, TrajectoryPrediction

    length, width, forward, left = _box(path, element, obstacle.obstacle_shape, placement)
    if not (length > 0 and width > 0):  # a point or a line: mindist() would treat it as nothing there
        raise ScenarioError(path, element, f"has a {length:g} m × {width:g} m shape: an obstacle needs a positive "
                                           "length and width")
    kind = getattr(obstacle.obstacle_type, "value", "") or ""
    if static:
        states = [obstacle.initial_state]
    else:
        prediction = obstacle.prediction
        if prediction is None:
            raise ScenarioError(path, element, "has no trajectory prediction")
        if isinstance(prediction, SetBasedPrediction) or not isinstance(prediction, TrajectoryPrediction):
            raise ScenarioError(path, element, "has a set-based prediction (occupancy sets), not a trajectory; "
                                               "rac needs a trajectory")
        states = [obstacle.initial_state, *prediction.trajectory.state_list]

    steps: list[int] = []
    points: list[tuple[float, float]] = []
    headings: list[float | None] = []  # None: not given, derived from the motion below
    speeds: list[float | None] = []
    for index, state in enumerate(states):
        what = f"the state at time step {getattr(state, 'time_step', '?')}"
        step = _time_step(path, element, state, what)
        if index == 1 and step == steps[-1]:
            continue  # a trajectory that repeats the initial state
        if steps and step != steps[-1] + 1:
            _trajectory_times(path, element, steps[-1], step, position)
        steps.append(step)
        points.append(_exact_position(path, element, state, what))
        heading = _exact_number(path, element, state, "orientation", what)
        speed = _exact_number(path, element, state, "velocity", what) if index or initial_velocity else None
        lateral = _exact_number(path, element, state, "velocity_y", what)
        if heading is None and speed is not None and lateral is not None:  # point mass: velocity components
            heading, speed = math.atan2(lateral, speed), math.hypot(speed, lateral)
        headings.append(heading)
        speeds.append(0.0 if static else speed)

    waypoints = []
    for i, (step, (x, y)) in enumerate(zip(steps, points)):
        heading, speed = headings[i], speeds[i]
        if heading is None or speed is None:  # from the move to the next state (the last: from the previous)
            j, k = (i, i + 1) if i + 1 < len(steps) else (i - 1, i)
            if j < 0:
                moved_heading, moved_speed = 0.0, 0.0
            else:
                (x0, y0), (x1, y1) = points[j], points[k]
                moved_speed = math.hypot(x1 - x0, y1 - y0) / ((steps[k] - steps[j]) * dt)
                moved_heading = math.atan2(y1 - y0, x1 - x0) if moved_speed > 0 else (headings[j] or 0.0)
            heading = moved_heading if heading is None else heading
            speed = moved_speed if speed is None else speed
        cos, sin = math.cos(heading), math.sin(heading)
        waypoints.append(Waypoint(time=_seconds(step, dt), x=x + forward * cos - left * sin,
                                  y=y + forward * sin + left * cos, heading=heading, velocity=speed))
    return Obstacle(id=int(obstacle.obstacle_id), length=length, width=width, waypoints=tuple(waypoints),
                    static=static, kind=kind)


def _trajectory_times(path, element: str, previous: int, step: int, position: tuple[int, int] | None) -> None:
    """E0719: a trajectory's time step that repeats, goes back, or skips steps: CommonRoad gives a
    dynamic obstacle one state per time step, and the model's obstacle would jump or stand still."""
    if step == previous:
        problem = f"has two states at time step {step}"
    elif step < previous:
        problem = f"has time steps out of order ({previous} then {step})"
    else:
        missing = f"step {previous + 1}" if step == previous + 2 else f"steps {previous + 1} to {step - 1}"
        problem = f"skips time {missing} (its trajectory goes from step {previous} to {step})"
    raise InconsistentScenarioError(
        path, "E0719", element, "time", f"{problem}: a trajectory has one state per time step",
        "give the trajectory one state at each time step, in order (interpolate the missing ones, drop the "
        "repeated ones)", position)


def _ego(path, element: str, state, dt: float) -> EgoStart:
    what = "its initial state"
    x, y = _exact_position(path, element, state, what)
    values = {}
    for attribute in ("orientation", "velocity", "acceleration"):
        value = _exact_number(path, element, state, attribute, what)
        if value is None and attribute != "acceleration":
            raise ScenarioError(path, element, f"has no {attribute} in {what}")
        values[attribute] = value or 0.0
    step = _time_step(path, element, state, what)
    if step < 0:
        raise ScenarioError(path, element, f"starts at time step {step}: a scenario's time begins at step 0")
    return EgoStart(x=x, y=y, heading=values["orientation"], velocity=values["velocity"],
                    acceleration=values["acceleration"], time=_seconds(step, dt))


def _interval(path, element: str, value, attribute: str) -> tuple[float, float] | None:
    # commonroad: only when this runs; importing rac.model.commonroad stays light
    from commonroad.common.util import Interval

    if value is None:
        return None
    if isinstance(value, Interval):
        low, high = float(value.start), float(value.end)
    elif isinstance(value, (int, float)) and not isinstance(value, bool):
        low = high = float(value)
    else:
        raise ScenarioError(path, element, f"has an unsupported {attribute} ({type(value).__name__})")
    if not (math.isfinite(low) and math.isfinite(high)):
        raise ScenarioError(path, element, f"has a {attribute} interval that is not finite ([{low}, {high}])")
    return low, high


def _goal(path, element: str, goal, network, dt: float) -> Goal:
    states = list(goal.state_list)
    if not states:
        raise ScenarioError(path, element, "has no goal state")
    by_lanelets = goal.lanelets_of_goal_position or {}
    regions: list[Polygon] = []
    lane_point: tuple[float, float] | None = None
    times = set()
    velocities: list[tuple[float, float]] = []
    orientations: list[tuple[float, float]] = []
    anywhere = False
    for index, state in enumerate(states):
        if index in by_lanelets:
            for lanelet_id in by_lanelets[index]:
                lanelet = network.find_lanelet_by_id(lanelet_id)
                if lanelet is None:
                    raise ScenarioError(path, element,
                                        f"refers to lanelet {lanelet_id}, which the file does not define")
                if not regions:  # the first region's point for dist_goal(): on the lanelet
                    lane_point = _midpoint(_points(lanelet.center_vertices))
                # a lanelet 0 m long (converters write such stubs) encloses nothing: goal() could never hold
                regions.append(_region(path, element, _polygon(lanelet.polygon.vertices),
                                       f"lanelet {lanelet_id}, whose bounds enclose no area"))
        elif getattr(state, "position", None) is None:
            anywhere = True  # CommonRoad: this goal state holds at any position (a goal of time alone)
        else:
            regions.extend(_regions(path, element, state.position))
        time = _interval(path, element, getattr(state, "time_step", None), "time")
        if time is None:
            raise ScenarioError(path, element, "has no time interval")
        times.add(time)
        for found, attribute in ((velocities, "velocity"), (orientations, "orientation")):
            interval = _interval(path, element, getattr(state, attribute, None), attribute)
            if interval is not None:
                found.append(interval)
    if len(times) > 1:  # the model has one goal window (velocity and orientation it does not model)
        raise ScenarioError(path, element, f"has {len(states)} goal states with different time intervals; rac "
                                           "supports one goal time interval")
    low, high = times.pop()
    if anywhere:  # one goal state reached anywhere: the others' regions add nothing (one time window)
        regions, lane_point = [], None
    return Goal(regions=tuple(regions), time_low=_seconds(low, dt), time_high=_seconds(high, dt),
                velocity=_hull(velocities), orientation=_hull(orientations), lane_point=lane_point,
                anywhere=anywhere)


def _hull(intervals: list[tuple[float, float]]) -> tuple[float, float] | None:
    """The smallest interval holding every one of ``intervals`` (None for none)."""
    return (min(i[0] for i in intervals), max(i[1] for i in intervals)) if intervals else None


def _region(path, element: str, polygon: Polygon, shape: str) -> Polygon:
    """``polygon``, a goal region; a :class:`ScenarioError` naming ``shape`` when it has no area: ``goal()``
    could never hold in it (and a point inside it, :attr:`Goal.center`, does not exist)."""
    points = polygon.points
    (x0, y0), rest = (points[0], points[1:]) if points else ((0.0, 0.0), ())
    # all on one line (a bowtie's signed area may be 0, yet its two triangles hold the goal)
    if not any((x1 - x0) * (y2 - y0) != (x2 - x0) * (y1 - y0) for (x1, y1), (x2, y2) in zip(rest, rest[1:])):
        raise ScenarioError(path, element, f"has a goal region without area ({shape}): `goal()` could never hold "
                                           "in it")
    return polygon


def _regions(path, element: str, position) -> list[Polygon]:
    import numpy as np  # numpy: only when this runs; importing rac.model.commonroad stays light

    # commonroad: only when this runs; importing rac.model.commonroad stays light
    from commonroad.geometry.occupancy.circle_occupancy import CircleOccupancy

    # commonroad: only when this runs; importing rac.model.commonroad stays light
    from commonroad.geometry.occupancy.occupancy_group import OccupancyGroup

    # commonroad: only when this runs; importing rac.model.commonroad stays light
    from commonroad.geometry.occupancy.polygon_occupancy import PolygonOccupancy

    # commonroad: only when this runs; importing rac.model.commonroad stays light
    from commonroad.geometry.occupancy.rect_occupancy import RectOccupancy

    if isinstance(position, OccupancyGroup):
        return [region for part in position.occupancies for region in _regions(path, element, part)]
    # each number checked before commonroad-io's shapely geometry is built from it: a NaN fails there
    if isinstance(position, RectOccupancy):
        for quantity, value in (("length", position.length), ("width", position.width),
                                ("orientation", position.orientation), ("centre x", position.rect_center.x),
                                ("centre y", position.rect_center.y)):
            _finite(path, element, quantity, value, "its rectangle")
        return [_region(path, element, _polygon(position.vertices),
                        f"a {position.length:g} m × {position.width:g} m rectangle")]
    if isinstance(position, PolygonOccupancy):
        points = _points(position.vertices)
        unfinite = _unfinite_point(path, element, points, "its polygon")
        if unfinite is not None:
            raise unfinite
        return [_region(path, element, _polygon(points), "a polygon whose vertices lie on one line")]
    if isinstance(position, CircleOccupancy):
        x, y, r = (_finite(path, element, quantity, value, "its circle") for quantity, value in (
            ("centre x", position.circle_center.x), ("centre y", position.circle_center.y),
            ("radius", position.radius)))
        return [_region(path, element, _polygon([(x + r * math.cos(2 * math.pi * i / CIRCLE_VERTICES),
                                                  y + r * math.sin(2 * math.pi * i / CIRCLE_VERTICES))
                                                 for i in range(CIRCLE_VERTICES)]), f"a circle of radius {r:g} m")]
    kind = "a point" if isinstance(position, (np.ndarray, list, tuple)) else type(position).__name__
    raise ScenarioError(path, element, f"has an unsupported shape ({kind}); {GOAL_SHAPES}")
