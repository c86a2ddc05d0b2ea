"""Tiny hand-made CommonRoad scenarios whose verdicts are known by construction (issue 4).

Each scenario is a straight road along x (one or more lanes of ``lane_width``, from x = 0 to
``length``, the first lane's right edge on y = 0), built with commonroad-io objects (lanelets,
static and dynamic obstacles, a planning problem with a rectangular goal region) and written with
commonroad-io's writer, so that it reaches rac through :func:`rac.model.commonroad.load_scenario` exactly
like a user's file. Each comes with the model settings it is meant for (:class:`TinySettings`: a
coarse action grid, a short horizon, a coarse number representation, so that exploring it takes
well under a second) and with the answers known by construction (:class:`TinyScenario`).

The named scenarios (:data:`TINY_SCENARIOS`), with the default settings — jerk in {-2, 0, 2} m/s³,
turn in {-0.2, 0, 0.2} rad/s, C1 = 0.5 s, C2 = 1 s, horizon 4 s, speed in [0, 10] m/s, ego
4.5 m × 1.8 m. Qb is ``E[] !collide() && !offroad()``, Qc ``E<> !collide() && !offroad() && goal()``
(on the graph explored with unsafe states pruned: reaching the goal without being unsafe first).

| scenario | Qb | Qc | the shield at the start allows |
| --- | --- | --- | --- |
| :func:`narrow_road`: a road 1 m wide, narrower than the ego | false | false | nothing (no shield) |
| :func:`avoidable_obstacle`: a van parked in the only lane, 15 m ahead | true | false | (jerk -2, turn 0) |
| :func:`goal_behind_wall`: a wall across the road before the goal | true | false | (jerk -2, turn 0) |
| :func:`goal_ahead`: the same road without the wall | true | true | jerk -2, 0 and 2 with turn 0 |

Each builder's docstring derives its answers; the tests (tests/engine/test_known_answers.py) check them.

Example::

    from tiny_scenarios import avoidable_obstacle
    from rac.engine.explore import explore

    tiny = avoidable_obstacle()
    data = tiny.model_data("/tmp")      # writes /tmp/avoidable_obstacle.xml and loads it with load_scenario
    graph = explore(data, horizon_samples=tiny.settings.horizon_samples, prune_unsafe=True)
    tiny.stays_safe, tiny.reaches_goal, tiny.start_actions   # the known answers

``python -m tiny_scenarios OUT_DIR`` writes every tiny scenario as ``OUT_DIR/<name>.xml``.

This module imports commonroad-io when it is imported; :mod:`rac.model.commonroad` does not.
"""

from __future__ import annotations

import argparse
import functools
import math
import re
import sys
import tempfile
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from fractions import Fraction
from pathlib import Path

import numpy as np
import shapely
from commonroad.common.common_lanelet import LaneletType, LineMarking
from commonroad.common.common_scenario import ScenarioID
from commonroad.common.file_writer import CommonRoadFileWriter
from commonroad.common.util import AngleInterval, FileFormat, Interval
from commonroad.common.writer.file_writer_interface import OverwriteExistingFile
from commonroad.geometry.obstacle_shapes.rect_obstacle_shape import RectObstacleShape
from commonroad.geometry.occupancy.rect_occupancy import RectOccupancy
from commonroad.planning.goal import GoalRegion
from commonroad.planning.planning_problem import PlanningProblem, PlanningProblemSet
from commonroad.prediction.prediction import TrajectoryPrediction
from commonroad.scenario.lanelet import Lanelet, StopLine
from commonroad.scenario.obstacle import DynamicObstacle, ObstacleType, StaticObstacle
from commonroad.scenario.scenario import Scenario as CRScenario
from commonroad.scenario.scenario import Tag
from commonroad.scenario.state import CustomState, ExtendedPMState, InitialState
from commonroad.scenario.traffic_light import (
    TrafficLight,
    TrafficLightCycle,
    TrafficLightCycleElement,
    TrafficLightState,
)
from commonroad.scenario.traffic_sign import TrafficSign, TrafficSignElement, TrafficSignIDGermany
from commonroad.scenario.trajectory import Trajectory
from lxml import etree

from rac.ir import Action, ModelSpec
from rac.model.commonroad import EgoStart, load_scenario
from rac.model.data import ModelData, build_model_data

__all__ = [
    "AVOIDABLE_LANE",
    "AVOIDABLE_VAN",
    "DT",
    "LANE_WIDTH",
    "PLANNING_PROBLEM_ID",
    "SECOND_PROBLEM_ID",
    "SECOND_START",
    "TINY_SCENARIOS",
    "WALL",
    "WALL_EGO",
    "WALL_GOAL",
    "Block",
    "GoalBox",
    "Pair",
    "TinyScenario",
    "TinySettings",
    "avoidable_obstacle",
    "commonroad_xml",
    "goal_ahead",
    "goal_behind_wall",
    "highway",
    "junction_with_two_problems",
    "narrow_road",
    "blocked_start",
    "curved_lane_goal",
    "goal_with_direction",
    "late_start",
    "ramp",
    "StraightRoad",
    "straight_road",
]

DT = 0.1  #: s, the CommonRoad time step of every tiny scenario
LANE_WIDTH = 3.5  #: m, the default lane width
PLANNING_PROBLEM_ID = 100  #: (CommonRoad ids are unique across lanelets, obstacles and problems)
#: Decimals written to the file; every number is rounded to them first, so that the built and the
#: re-read scenario hold the same values (commonroad-io's writer truncates to its precision).
DECIMALS = 6
#: The ``date`` written into the file header, so that writing a scenario again gives the same bytes.
FILE_DATE = "2026-01-01"


# ---------------------------------------------------------------- settings
@dataclass(frozen=True)
class TinySettings:
    """The ``model`` block settings a tiny scenario is meant for (model.md), plus the horizon.

    Defaults: a coarse grid (jerk in {-2, 0, 2} m/s³, turn in {-0.2, 0, 0.2} rad/s), C1 = 0.5 s,
    C2 = 1 s, 1/G = 4 Euler sub-steps, exponent 2 (centimetres), speed in [0, 10] m/s, a 4 s
    horizon: at most 9**4 states per sample, explored in well under a second.
    """

    exponent: int = 2
    base: int = 10
    sense_period: Fraction = Fraction(1, 2)  # C1, s
    decide_period: Fraction = Fraction(1)  # C2, s, a multiple of C1
    granularity: Fraction = Fraction(1, 4)  # G
    jerk: tuple[Fraction, Fraction, Fraction] = (Fraction(-2), Fraction(2), Fraction(2))  # low, high, step
    turn: tuple[Fraction, Fraction, Fraction] = (Fraction(-1, 5), Fraction(1, 5), Fraction(1, 5))
    length: Fraction = Fraction(9, 2)
    width: Fraction = Fraction(9, 5)
    max_acceleration: Fraction = Fraction(3)
    max_turn: Fraction = Fraction(2, 5)
    min_speed: Fraction = Fraction(0)
    max_speed: Fraction = Fraction(10)
    collision_distance: Fraction = Fraction(1, 2)
    comfort_acceleration: Fraction = Fraction(4, 5)
    comfort_turn: Fraction = Fraction(4, 5)
    horizon: Fraction = Fraction(4)  # s, a multiple of C1

    @property
    def horizon_samples(self) -> int:
        """The horizon in sense periods (the ``horizon_samples`` of :func:`rac.engine.explore.explore`)."""
        return int(self.horizon / self.sense_period)

    @property
    def decide_every(self) -> int:
        """C2 / C1: a decision every so many samples."""
        return int(self.decide_period / self.sense_period)

    def model_spec(self, scenario_path: str | Path) -> ModelSpec:
        """The :class:`rac.ir.ModelSpec` of these settings for the scenario file ``scenario_path``."""
        path = str(scenario_path)
        return ModelSpec(
            scenario=Path(path).name, scenario_path=path, base=self.base, exponent=self.exponent,
            sense_period=self.sense_period, decide_period=self.decide_period, granularity=self.granularity,
            actions=(Action("jerk", *self.jerk), Action("turn", *self.turn)),
            length=self.length, width=self.width, max_acceleration=self.max_acceleration, max_turn=self.max_turn,
            min_speed=self.min_speed, max_speed=self.max_speed, collision_distance=self.collision_distance,
            comfort_acceleration=self.comfort_acceleration, comfort_turn=self.comfort_turn, bindings=())

    def model_block(self, scenario_file: str, bindings: Sequence[str] = ()) -> str:
        """These settings as the text of a ``.ra`` ``model`` block (docs/language.md), e.g. for an
        example; ``bindings`` are ``bind`` lines' contents such as ``"collide = collide()"``.
        The automaton's ``sample every`` must equal ``sense_period``."""
        lines = [f'scenario "{scenario_file}"', f"base {self.base}", f"exponent {self.exponent}"]
        for name in ("sense_period", "decide_period", "granularity"):
            lines.append(f"{name} {_decimal(getattr(self, name))}")
        for name in ("jerk", "turn"):
            low, high, step = getattr(self, name)
            lines.append(f"action {name} in [{_decimal(low)}, {_decimal(high)}] step {_decimal(step)}")
        for name in ("length", "width", "max_acceleration", "max_turn", "min_speed", "max_speed",
                     "collision_distance", "comfort_acceleration", "comfort_turn"):
            lines.append(f"{name} {_decimal(getattr(self, name))}")
        lines.extend(f"bind {binding}" for binding in bindings)
        return "model {\n" + "".join(f"    {line}\n" for line in lines) + "}\n"


def _decimal(value: Fraction) -> str:
    """The exact decimal of a fraction whose denominator has only the factors 2 and 5."""
    value = Fraction(value)
    if value.denominator == 1:
        return str(value.numerator)
    digits = 0
    while (value * 10**digits).denominator != 1:
        digits += 1
        if digits > 30:
            raise ValueError(f"{value} has no finite decimal")
    text = f"{abs(value.numerator) * 10**digits // value.denominator:0{digits + 1}d}"
    return ("-" if value < 0 else "") + text[:-digits] + "." + text[-digits:]


# ---------------------------------------------------------------- the straight road
@dataclass(frozen=True)
class Block:
    """A rectangular obstacle on the straight road: ``length`` along its heading, centred at
    ``(x, y)`` at time 0. With ``velocity == 0`` a CommonRoad static obstacle; otherwise a dynamic
    obstacle driving at constant ``velocity`` along ``heading`` for the scenario's ``steps``
    CommonRoad time steps (rac's model drops it after its last step)."""

    id: int
    x: float
    y: float
    length: float = 4.5
    width: float = 1.8
    velocity: float = 0.0
    heading: float = 0.0
    kind: ObstacleType | None = None  # default: a parked vehicle when static, a car when moving


@dataclass(frozen=True)
class GoalBox:
    """The goal region: the road's whole width between ``x_low`` and ``x_high``, during
    ``time_low <= t <= time_high`` seconds (whole CommonRoad time steps)."""

    x_low: float
    x_high: float
    time_low: float = 0.0
    time_high: float = 4.0


def _clean(values: float | np.ndarray) -> np.ndarray:
    """Rounded to the file's ``DECIMALS`` (the built and the re-read scenario agree), without -0.0."""
    return np.round(np.asarray(values, dtype=float), DECIMALS) + 0.0


def _steps(seconds: float) -> int:
    steps = round(seconds / DT)
    if not math.isclose(steps * DT, seconds, abs_tol=1e-9):
        raise ValueError(f"{seconds} s is not a whole number of CommonRoad time steps ({DT} s)")
    return steps


def _lanelets(length: float, lanes: int, lane_width: float) -> list[Lanelet]:
    result = []
    for i in range(lanes):
        right, left = i * lane_width, (i + 1) * lane_width

        def bound(y: float) -> np.ndarray:
            return _clean(np.array([[0.0, y], [length, y]]))

        has_left, has_right = i + 1 < lanes, i > 0
        result.append(Lanelet(
            bound(left), bound((left + right) / 2), bound(right), i + 1,
            adjacent_left=i + 2 if has_left else None, adjacent_left_same_direction=True if has_left else None,
            adjacent_right=i if has_right else None, adjacent_right_same_direction=True if has_right else None,
            line_marking_left_vertices=LineMarking.DASHED if has_left else LineMarking.SOLID,
            line_marking_right_vertices=LineMarking.DASHED if has_right else LineMarking.SOLID,
            lanelet_type={LaneletType.URBAN}))
    return result


def _obstacle(block: Block, steps: int) -> StaticObstacle | DynamicObstacle:
    shape = RectObstacleShape(width=block.width, length=block.length)
    heading = float(_clean(block.heading))
    initial = InitialState(time_step=0, position=_clean([block.x, block.y]), orientation=heading,
                           velocity=float(_clean(block.velocity)), acceleration=0.0, yaw_rate=0.0, slip_angle=0.0)
    if block.velocity == 0:
        return StaticObstacle(block.id, block.kind or ObstacleType.PARKED_VEHICLE, shape, initial)
    c, s = math.cos(block.heading), math.sin(block.heading)
    states = [ExtendedPMState(time_step=k, position=_clean([block.x + c * block.velocity * k * DT,
                                                            block.y + s * block.velocity * k * DT]),
                              velocity=float(_clean(block.velocity)), orientation=heading, acceleration=0.0)
              for k in range(1, steps + 1)]
    prediction = TrajectoryPrediction(Trajectory(1, states), shape)
    return DynamicObstacle(block.id, block.kind or ObstacleType.CAR, shape, initial, prediction)


@dataclass(frozen=True)
class StraightRoad:
    """A straight road along x and what is on it: ``lanes`` lanelets (ids 1, 2, ...) of
    ``lane_width`` side by side, all driving towards +x from x = 0 to ``length``, lanelet 1's right
    edge on y = 0; ``ego`` is the planning problem's initial state, ``goal`` its goal box across
    the whole road; dynamic obstacles drive for ``steps`` CommonRoad time steps (default: to the
    goal's last time step). Obstacle ids must differ from the lanelet ids and from
    :data:`PLANNING_PROBLEM_ID` (CommonRoad ids are unique within a file)."""

    length: float
    ego: EgoStart
    goal: GoalBox
    lanes: int = 1
    lane_width: float = LANE_WIDTH
    obstacles: tuple[Block, ...] = ()
    steps: int | None = None

    def __post_init__(self) -> None:
        if self.lanes < 1 or self.length <= 0 or self.lane_width <= 0:
            raise ValueError("a straight road needs at least one lane and a positive length and lane width")
        ids = [*range(1, self.lanes + 1), *(block.id for block in self.obstacles), PLANNING_PROBLEM_ID]
        if len(set(ids)) != len(ids):
            raise ValueError(f"CommonRoad ids must be unique: lanelets 1..{self.lanes}, obstacles "
                             f"{[block.id for block in self.obstacles]}, planning problem {PLANNING_PROBLEM_ID}")

    def build(self, name: str) -> tuple[CRScenario, PlanningProblemSet]:
        """The commonroad-io scenario and planning problem set; ``name`` becomes the benchmark id's
        map name (``narrow_road`` -> ``ZAM_NarrowRoad-1_1_T-1``, rac's ``Scenario.name``)."""
        goal, ego = self.goal, self.ego
        steps = _steps(goal.time_high) if self.steps is None else self.steps
        map_name = "".join(part.capitalize() for part in name.split("_")) or "Tiny"
        scenario = CRScenario(DT, ScenarioID(country_id="ZAM", map_name=map_name, map_id=1, obstacle_behavior="T",
                                             prediction_id=1))
        for lanelet in _lanelets(self.length, self.lanes, self.lane_width):
            scenario.add_objects(lanelet)
        for block in sorted(self.obstacles, key=lambda b: b.id):
            scenario.add_objects(_obstacle(block, steps))
        initial = InitialState(time_step=_steps(ego.time), position=_clean([ego.x, ego.y]),
                               orientation=float(_clean(ego.heading)), velocity=float(_clean(ego.velocity)),
                               acceleration=float(_clean(ego.acceleration)), yaw_rate=0.0, slip_angle=0.0)
        width = self.lanes * self.lane_width
        area = RectOccupancy(rect_center=shapely.Point(*_clean([(goal.x_low + goal.x_high) / 2, width / 2])),
                             length=float(_clean(goal.x_high - goal.x_low)), width=float(_clean(width)),
                             orientation=0.0)
        region = GoalRegion([CustomState(time_step=Interval(_steps(goal.time_low), _steps(goal.time_high)),
                                         position=area)])
        return scenario, PlanningProblemSet([PlanningProblem(PLANNING_PROBLEM_ID, initial, region)])

    def xml(self, name: str) -> bytes:
        """:meth:`build` written with commonroad-io's writer as CommonRoad 2020a XML (schema-checked,
        with a fixed date, so that the same road gives the same bytes)."""
        tag = Tag.SINGLE_LANE if self.lanes == 1 else Tag.MULTI_LANE  # one tag: no set order to pin
        return commonroad_xml(*self.build(name), name, tag)


def commonroad_xml(scenario: CRScenario, problems: PlanningProblemSet, name: str, tag: Tag) -> bytes:
    """A commonroad-io scenario and its planning problems written with commonroad-io's writer as
    CommonRoad 2020a XML, schema-checked, with a fixed date (the same objects give the same bytes);
    ``tag`` is the scenario's one tag (one: no set order to pin). E.g. the left-turn junction of
    :func:`rac.model.intersection.build_left_turn` with a second planning problem added."""
    writer = CommonRoadFileWriter(scenario, problems, author="rac", affiliation="rac (reward-automata compiler)",
                                  source=f"tiny_scenarios: {name}", tags={tag},
                                  decimal_precision=DECIMALS, file_format=FileFormat.XML)
    with tempfile.TemporaryDirectory(prefix="rac-tiny-") as folder:
        target = Path(folder) / f"{name}.xml"
        writer.write_to_file(str(target), OverwriteExistingFile.ALWAYS)
        data = target.read_bytes()
    root = etree.fromstring(data, etree.XMLParser(remove_blank_text=True))
    root.set("date", FILE_DATE)
    text = etree.tostring(root.getroottree(), pretty_print=True, xml_declaration=True, encoding="UTF-8")
    _check_schema(text)
    return text


@functools.cache
def _schema() -> etree.XMLSchema:
    import commonroad

    xsd = Path(commonroad.__file__).parent / "common" / "xml_definition_files" / "XML_commonRoad_XSD.xsd"
    return etree.XMLSchema(etree.parse(str(xsd)))


def _check_schema(data: bytes) -> None:
    """Validate against commonroad-io's 2020a XSD (the writer's own check ignores the result)."""
    schema = _schema()
    if not schema.validate(etree.fromstring(data)):
        raise RuntimeError(f"the generated scenario does not match commonroad-io's XSD: {schema.error_log.last_error}")


# ---------------------------------------------------------------- named scenarios
#: An action pair (jerk m/s³, turn rad/s).
Pair = tuple[Fraction, Fraction]


@dataclass(frozen=True)
class TinyScenario:
    """A tiny scenario: its CommonRoad XML, the settings it is meant for and its known answers.

    Under ``settings`` and within ``settings.horizon``:

    - ``stays_safe``: the answer of Qb ``E[] !collide() && !offroad()`` (equivalently: the safety
      shield exists); ``reaches_goal``: the answer of Qc ``E<> !collide() && !offroad() && goal()``
      on the explored graph with unsafe states pruned, i.e. reaching the goal without being
      unsafe on the way; None when not known by construction (random scenarios);
    - ``start_actions``: the (jerk, turn) pairs the most permissive safety shield allows at the
      start, None when not stated;
    - ``safe_plan`` / ``goal_plan``: one (jerk, turn) pair per decision, a run that stays safe to
      the horizon / reaches the goal safely, when there is one (empty otherwise);
    - ``facts``: why, in a sentence (the builder's docstring has the arithmetic).
    """

    name: str
    xml: bytes = field(repr=False)
    settings: TinySettings
    stays_safe: bool | None = None
    reaches_goal: bool | None = None
    start_actions: frozenset[Pair] | None = None
    safe_plan: tuple[Pair, ...] = ()
    goal_plan: tuple[Pair, ...] = ()
    facts: str = ""

    def write(self, path: str | Path) -> Path:
        """Write the XML to ``path`` (a file, or an existing folder that gets ``<name>.xml``); return the file."""
        path = Path(path)
        if path.is_dir():
            path = path / f"{self.name}.xml"
        path.write_bytes(self.xml)
        return path

    def model_spec(self, scenario_path: str | Path | None = None) -> ModelSpec:
        """:meth:`TinySettings.model_spec` for the file (default ``<name>.xml``)."""
        return self.settings.model_spec(scenario_path if scenario_path is not None else f"{self.name}.xml")

    def model_data(self, folder: str | Path) -> ModelData:
        """Write the scenario into ``folder``, read it back with :func:`rac.model.commonroad.load_scenario`
        (as a user's file would be) and build its :class:`rac.model.ModelData`."""
        path = self.write(Path(folder) / f"{self.name}.xml")
        return build_model_data(load_scenario(path), self.model_spec(path))


def straight_road(name: str, road: StraightRoad, *, settings: TinySettings | None = None,
                  stays_safe: bool | None = None, reaches_goal: bool | None = None,
                  start_actions: frozenset[Pair] | None = None, safe_plan: Sequence[Pair] = (),
                  goal_plan: Sequence[Pair] = (), facts: str = "") -> TinyScenario:
    """A :class:`TinyScenario` of ``road`` (written as ``road.xml(name)``); the answers default to
    unknown (None), the settings to :class:`TinySettings`'s defaults."""
    return TinyScenario(name, road.xml(name), settings or TinySettings(), stays_safe, reaches_goal, start_actions,
                        tuple(safe_plan), tuple(goal_plan), facts)


_BRAKE: Pair = (Fraction(-2), Fraction(0))
_KEEP: Pair = (Fraction(0), Fraction(0))
_SPEED_UP: Pair = (Fraction(2), Fraction(0))
_DECISIONS = TinySettings().horizon_samples // TinySettings().decide_every  # 4 with the default settings


def narrow_road() -> TinyScenario:
    """A road 1 m wide (one lanelet along y in [0, 1], 60 m long), narrower than the 1.8 m wide
    ego, which starts on its middle line (x = 10, y = 0.5, 5 m/s); no obstacle.

    Known by construction: the ego rectangle is convex and at least 1.8 m across in every
    direction, so its four corners never all lie in a strip 1 m wide: ``offroad()`` holds in
    every state, Qb and Qc are false, and there is no safety shield (no action is allowed)."""
    return straight_road(
        "narrow_road", StraightRoad(60.0, EgoStart(10.0, 0.5, 0.0, 5.0), GoalBox(30.0, 40.0), lane_width=1.0),
        stays_safe=False, reaches_goal=False, start_actions=frozenset(),
        facts="the road (1 m) is narrower than the ego (1.8 m): every state is off the road")


AVOIDABLE_LANE = 3.0  #: m, the lane width of :func:`avoidable_obstacle`
#: The parked van of :func:`avoidable_obstacle` (6 m × 2.4 m, centred in the lane at x = 25).
AVOIDABLE_VAN = Block(11, x=25.0, y=AVOIDABLE_LANE / 2, length=6.0, width=2.4)


def avoidable_obstacle() -> TinyScenario:
    """One lane 3 m wide (y in [0, 3], 100 m long); the ego at x = 10 on the lane's middle line,
    heading +x at 5 m/s; a parked van (6 m × 2.4 m, static) in the lane, centred 15 m ahead at
    x = 25; the goal region x in [40, 50] beyond it.

    Known by construction (default settings; disc radii: ego sqrt(0.75² + 0.9²) = 1.17, van
    sqrt(1² + 1.2²) = 1.56, so two discs collide below 1.17 + 1.56 + TD 0.5 = 3.23 m):

    - The van cannot be passed: on the road the ego's centre has |y - 1.5| < 1.5, so its centre
      disc collides with the van's middle disc whenever |x - 25| < sqrt(3.23² - 1.5²) = 2.86;
      in one sense period the ego moves at most max_speed · C1 = 5 m < 5.72 m, so a run from
      x = 10 to the goal has a sample in that band. Qc is false.
    - Heading +x in the lane's middle, the ego's front disc collides with the van's rear disc when
      x > 25 - 2 - 1.5 - 3.23 = 18.27. Braking from the start (jerk -2 at every decision, turn 0)
      stops the ego at x = 16.96 (2.4 s, Euler-integrated), and a stopped ego stays stopped
      (speed clamps at 0): Qb holds and the shield exists.
    - The first action is held for C2 = 1 s. Jerk 0 first leaves the ego at x = 15 still at
      5 m/s, and braking from there stops it only at x = 21.96 > 18.27; jerk +2 first is worse.
      A turn rate of ±0.2 rad/s held for that second turns the ego by 0.2 rad and moves it about
      0.47 m sideways even while braking, so a front corner lies 0.47 + 2.25 sin 0.2 +
      0.9 cos 0.2 = 1.80 m from the middle line, beyond the lane's 1.5 m half-width, at sample 2.
      So the shield allows exactly (jerk -2, turn 0) at the start.
    """
    road = StraightRoad(100.0, EgoStart(10.0, AVOIDABLE_LANE / 2, 0.0, 5.0), GoalBox(40.0, 50.0),
                        lane_width=AVOIDABLE_LANE, obstacles=(AVOIDABLE_VAN,))
    return straight_road(
        "avoidable_obstacle", road,
        stays_safe=True, reaches_goal=False, start_actions=frozenset({_BRAKE}), safe_plan=(_BRAKE,) * _DECISIONS,
        facts="a parked van blocks the lane 15 m ahead; only braking at once, straight on, stops the ego in time")


#: The wall of :func:`goal_behind_wall`: a static construction zone 6 m long across the whole road.
WALL = Block(11, x=36.0, y=LANE_WIDTH / 2, length=6.0, width=LANE_WIDTH + 1.0, kind=ObstacleType.CONSTRUCTION_ZONE)
#: The goal of :func:`goal_behind_wall` and :func:`goal_ahead`: x in [44, 54], at any time of the horizon.
WALL_GOAL = GoalBox(44.0, 54.0, 0.0, 4.0)
#: The ego of :func:`goal_behind_wall` and :func:`goal_ahead`: x = 10 on the lane's middle line, 8 m/s along +x.
WALL_EGO = EgoStart(10.0, LANE_WIDTH / 2, 0.0, 8.0)


def goal_behind_wall() -> TinyScenario:
    """One lane 3.5 m wide (y in [0, 3.5], 80 m long); the ego at x = 10 on the middle line,
    heading +x at 8 m/s; a wall (6 m × 4.5 m, static, wider than the road) centred at x = 36;
    the goal region x in [44, 54] behind it, at any time of the 4 s horizon.

    Known by construction (disc radii: ego 1.17, wall sqrt(1² + 2.25²) = 2.46; collision below
    1.17 + 2.46 + 0.5 = 4.13 m):

    - Qc is false: on the road the ego's centre has |y - 1.75| < 1.75, so its centre disc collides
      with the wall's middle disc whenever |x - 36| < sqrt(4.13² - 1.75²) = 3.74; in one sense
      period the ego moves at most max_speed · C1 = 5 m < 7.48 m, so a run from x = 10 to the goal
      has a sample in that band, where it collides (or is off the road).
    - Qb holds: braking from the start (jerk -2, turn 0) stops the ego at x = 25.31, while its front
      disc reaches the wall's rear disc only beyond x = 36 - 2 - 1.5 - 4.13 = 28.37.
    - At the start the shield allows exactly (jerk -2, turn 0): keeping the speed for the first
      second leaves the ego at x = 18, at 8 m/s, which no braking stops before 28.37 (it stops
      at 33.31); a turn held for that second puts a corner 0.81 + 1.33 = 2.14 m from the middle
      line, beyond the 1.75 m half-width.

    :func:`goal_ahead` is the same road without the wall, where the goal is reached.
    """
    return straight_road(
        "goal_behind_wall", StraightRoad(80.0, WALL_EGO, WALL_GOAL, obstacles=(WALL,)),
        stays_safe=True, reaches_goal=False, start_actions=frozenset({_BRAKE}), safe_plan=(_BRAKE,) * _DECISIONS,
        facts="a wall across the road stands between the ego and the goal; braking at once stops before it")


def goal_ahead() -> TinyScenario:
    """:func:`goal_behind_wall` without the wall: an empty straight road.

    Known by construction: speeding up (jerk +2 at every decision, turn 0; the speed clamps at
    10 m/s) reaches x = 48.33 at 4 s, inside the goal region, on the road (80 m long) and with
    nothing to collide with: Qc holds, with a witness; keeping the speed would reach only x = 42.
    Qb holds; at the start the shield allows every jerk straight on (no run leaves the road
    before 4 s: x + 2.25 <= 10 + 40 + 2.25 < 80) and no turn (a corner off the road at sample 2,
    as in :func:`goal_behind_wall`)."""
    return straight_road(
        "goal_ahead", StraightRoad(80.0, WALL_EGO, WALL_GOAL),
        stays_safe=True, reaches_goal=True, start_actions=frozenset({_BRAKE, _KEEP, _SPEED_UP}),
        safe_plan=(_KEEP,) * _DECISIONS, goal_plan=(_SPEED_UP,) * _DECISIONS,
        facts="the goal lies ahead on an empty road; speeding up reaches it within the horizon")


# ---------------------------------------------------------------- scenes whose start `rac check` questions
def highway(speed: float = 33.0, acceleration: float = 0.0) -> bytes:
    """Three lanes of 3.5 m, 400 m long; the ego on the middle lane at x = 20 at ``speed`` m/s (with
    ``acceleration``), a truck (12 m × 2.5 m) ahead on the right lane at 22 m/s; the goal 300 m to
    390 m within 12 s. At the default 33 m/s the ego is faster than the default `max_speed` 20 (E0714)."""
    road = StraightRoad(400.0, EgoStart(20.0, 5.25, 0.0, speed, acceleration), GoalBox(300.0, 390.0, 0.0, 12.0),
                        lanes=3, obstacles=(Block(11, x=80.0, y=1.75, length=12.0, width=2.5, velocity=22.0,
                                                  kind=ObstacleType.TRUCK),))
    return road.xml("highway")


#: The second planning problem of :func:`junction_with_two_problems` and its start (x, y, heading, velocity).
SECOND_PROBLEM_ID = 101
SECOND_START = (-1.75, 18.0, round(-math.pi / 2, DECIMALS), 5.0)


def junction_with_two_problems() -> bytes:
    """The left-turn junction (:func:`rac.model.intersection.build_left_turn`, planning problem 100)
    with a second planning problem, :data:`SECOND_PROBLEM_ID`: an ego on the north arm's southbound
    lane at (-1.75, 18), 5 m/s, going straight on to the south arm (E0715 until one is chosen)."""
    from rac.model.intersection import build_left_turn

    scenario, problems = build_left_turn()
    x, y, heading, velocity = SECOND_START
    initial = InitialState(time_step=0, position=np.array([x, y]), orientation=heading, velocity=velocity,
                           acceleration=0.0, yaw_rate=0.0, slip_angle=0.0)
    area = RectOccupancy(rect_center=shapely.Point(-1.75, -22.0), length=3.5, width=8.0, orientation=0.0)
    problems.add_planning_problem(PlanningProblem(
        SECOND_PROBLEM_ID, initial, GoalRegion([CustomState(time_step=Interval(0, 100), position=area)])))
    return commonroad_xml(scenario, problems, "junction", Tag.INTERSECTION)


def ramp(start_x: float = 0.0) -> bytes:
    """One lane 3.5 m wide, 200 m long; the ego starts at x = ``start_x`` on the lane's middle line
    at 10 m/s; no obstacle; the goal 100 m to 150 m within 8 s. At the default x = 0 half of the
    ego lies before the road's start, as in CommonUppRoad's ZAM_Ramp (W0716)."""
    return StraightRoad(200.0, EgoStart(start_x, 1.75, 0.0, 10.0), GoalBox(100.0, 150.0, 0.0, 8.0)).xml("ramp")


def blocked_start() -> bytes:
    """:func:`ramp` with the ego at x = 10 and a parked car (static obstacle 31) at x = 13.5 on the same
    line: the two rectangles overlap at the start (W0724)."""
    return StraightRoad(200.0, EgoStart(10.0, 1.75, 0.0, 10.0), GoalBox(100.0, 150.0, 0.0, 8.0),
                        obstacles=(Block(31, x=13.5, y=1.75),)).xml("blocked")


def late_start() -> bytes:
    """:func:`ramp` with the ego starting at 7 s (time step 70) and the goal's window [0, 6] s: the
    window has closed before the ego starts (W0722). CommonRoad's schema wants a planning problem to
    start at step 0, so the step is written into the schema-checked file afterwards."""
    text = StraightRoad(200.0, EgoStart(10.0, 1.75, 0.0, 10.0), GoalBox(100.0, 150.0, 0.0, 6.0),
                        steps=90).xml("late").decode("utf-8")
    text, made = re.subn(r"(<planningProblem .*?<initialState>.*?<time>\s*<exact>)0(</exact>)", r"\g<1>70\2", text,
                         count=1, flags=re.S)
    assert made == 1, "late_start: no initial time step to move"
    return text.encode("utf-8")


def goal_with_direction(mixed: bool = False) -> bytes:
    """:func:`ramp` whose goal also asks for a velocity in [0, 1] m/s and an orientation in [2.5, 3.5] rad
    (W0723). With ``mixed``, two goal states with the same time interval: the first as before without
    the orientation, the second a box at x in [160, 170] without either."""
    scenario, problems = StraightRoad(200.0, EgoStart(10.0, 1.75, 0.0, 10.0),
                                      GoalBox(100.0, 150.0, 0.0, 8.0)).build("goal_direction")
    (problem,) = problems.planning_problem_dict.values()
    (state,) = problem.goal.state_list
    state.velocity = Interval(0.0, 1.0)
    states = [state]
    if mixed:
        states.append(CustomState(time_step=state.time_step, position=RectOccupancy(
            rect_center=shapely.Point(165.0, LANE_WIDTH / 2), length=10.0, width=LANE_WIDTH, orientation=0.0)))
    else:
        state.orientation = AngleInterval(2.5, 3.5)
    goal = GoalRegion(states)
    problems = PlanningProblemSet([PlanningProblem(PLANNING_PROBLEM_ID, problem.initial_state, goal)])
    return commonroad_xml(scenario, problems, "goal_direction", Tag.SINGLE_LANE)


def goal_anywhere() -> bytes:
    """:func:`ramp` whose goal has no position, only the time window [0, 8] s (time steps 0 to 80): a goal
    of time alone, reached anywhere ("survive until 8 s"), so ``dist_goal()`` reads 0 everywhere (W0727)."""
    scenario, problems = StraightRoad(200.0, EgoStart(10.0, 1.75, 0.0, 10.0),
                                      GoalBox(100.0, 150.0, 0.0, 8.0)).build("survive")
    (problem,) = problems.planning_problem_dict.values()
    goal = GoalRegion([CustomState(time_step=Interval(0, 80))])
    problems = PlanningProblemSet([PlanningProblem(PLANNING_PROBLEM_ID, problem.initial_state, goal)])
    return commonroad_xml(scenario, problems, "survive", Tag.SINGLE_LANE)


def short_traffic() -> bytes:
    """One lane 200 m long, the ego at x = 10 at 10 m/s, a car ahead at x = 40 driving at 8 m/s whose recorded
    trajectory ends at 8 s (time step 80), the goal x in [150, 190] within [0, 30] s: under a 30 s horizon the
    road holds no moving obstacle for the last 22 s (W0728)."""
    road = StraightRoad(200.0, EgoStart(10.0, 1.75, 0.0, 10.0), GoalBox(150.0, 190.0, 0.0, 30.0),
                        obstacles=(Block(11, x=40.0, y=1.75, velocity=8.0),), steps=80)
    return road.xml("short_traffic")


def traffic_rules(signs: str = "stop") -> bytes:
    """:func:`ramp`'s lane with a traffic light at x = 60 (red for the first 5 s, then green) and its stop line
    (W0730). ``signs="limits"``: two 50 km/h speed-limit signs instead; ``"stop"`` adds a stop sign to the light."""
    scenario, problems = StraightRoad(200.0, EgoStart(10.0, 1.75, 0.0, 10.0),
                                      GoalBox(100.0, 150.0, 0.0, 8.0)).build("lights")
    network = scenario.lanelet_network
    (lanelet,) = network.lanelets
    if signs == "limits":
        for ident, x in ((801, 20.0), (802, 120.0)):
            network.add_traffic_sign(TrafficSign(ident, [TrafficSignElement(TrafficSignIDGermany.MAX_SPEED, ["13.89"])],
                                                 {lanelet.lanelet_id}, np.array([x, 4.0])), {lanelet.lanelet_id})
        return commonroad_xml(scenario, problems, "limits", Tag.SINGLE_LANE)
    cycle = TrafficLightCycle([TrafficLightCycleElement(TrafficLightState.RED, 50),
                               TrafficLightCycleElement(TrafficLightState.GREEN, 100)])
    network.add_traffic_light(TrafficLight(900, np.array([60.0, 4.0]), cycle), {lanelet.lanelet_id})
    network.add_traffic_sign(TrafficSign(800, [TrafficSignElement(TrafficSignIDGermany.STOP, [])],
                                         {lanelet.lanelet_id}, np.array([60.0, 4.5])), {lanelet.lanelet_id})
    lanelet.stop_line = StopLine(np.array([60.0, 0.0]), np.array([60.0, LANE_WIDTH]), LineMarking.SOLID,
                                 traffic_light_ref={900}, traffic_sign_ref={800})
    return commonroad_xml(scenario, problems, "lights", Tag.URBAN)


#: The ring of :func:`curved_lane_goal`: its centre line's radius (m) and the lane width.
RING_RADIUS = 20.0


def curved_lane_goal() -> bytes:
    """A ring road of two lanelets (each half a circle of radius :data:`RING_RADIUS` on its centre line,
    :data:`LANE_WIDTH` wide, centred at the origin, counter-clockwise): lanelet 1 the upper half,
    lanelet 2 the lower half. The ego starts on lanelet 1 at (20, 0) heading north; the goal is
    lanelet 2, whose vertices' mean lies in the ring's hole."""
    def arc(radius: float, start: float) -> np.ndarray:
        angles = np.linspace(start, start + math.pi, 17)
        return _clean(np.column_stack([radius * np.cos(angles), radius * np.sin(angles)]))

    inner, outer = RING_RADIUS - LANE_WIDTH / 2, RING_RADIUS + LANE_WIDTH / 2
    scenario = CRScenario(DT, ScenarioID(country_id="ZAM", map_name="Ring", map_id=1, obstacle_behavior="T",
                                         prediction_id=1))
    for ident, start in ((1, 0.0), (2, math.pi)):
        scenario.add_objects(Lanelet(arc(inner, start), arc(RING_RADIUS, start), arc(outer, start), ident,
                                     predecessor=[3 - ident], successor=[3 - ident],
                                     line_marking_left_vertices=LineMarking.SOLID,
                                     line_marking_right_vertices=LineMarking.SOLID,
                                     lanelet_type={LaneletType.URBAN}))
    initial = InitialState(time_step=0, position=np.array([RING_RADIUS, 0.0]), orientation=float(_clean(math.pi / 2)),
                           velocity=5.0, acceleration=0.0, yaw_rate=0.0, slip_angle=0.0)
    goal = GoalRegion([CustomState(time_step=Interval(0, 80), position=RectOccupancy(
        rect_center=shapely.Point(0.0, -RING_RADIUS), length=1.0, width=1.0, orientation=0.0))],
        lanelets_of_goal_position={0: [2]})
    problems = PlanningProblemSet([PlanningProblem(PLANNING_PROBLEM_ID, initial, goal)])
    return commonroad_xml(scenario, problems, "ring", Tag.URBAN)


#: The named tiny scenarios, by name.
TINY_SCENARIOS: dict[str, Callable[[], TinyScenario]] = {
    "narrow_road": narrow_road,
    "avoidable_obstacle": avoidable_obstacle,
    "goal_behind_wall": goal_behind_wall,
    "goal_ahead": goal_ahead,
}


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m tiny_scenarios",
                                     description="Write the tiny scenarios with known answers as CommonRoad XML.")
    parser.add_argument("out", help="the folder to write <name>.xml into")
    args = parser.parse_args(argv)
    folder = Path(args.out)
    folder.mkdir(parents=True, exist_ok=True)
    for build in TINY_SCENARIOS.values():
        tiny = build()
        path = tiny.write(folder / f"{tiny.name}.xml")
        print(f"wrote {path}: Qb {tiny.stays_safe}, Qc {tiny.reaches_goal} ({tiny.facts})")
    return 0


if __name__ == "__main__":
    sys.exit(main())
