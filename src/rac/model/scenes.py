"""Small scenes of the kinds rac is judged on, built in code with commonroad-io.

The scenes, each a CommonRoad 2020a file written like a user's (:mod:`rac.model.scenario_xml`),
with the ego's planning problem 100 and 0.1 s time steps:

- ``left_turn``: the paper's left-turn intersection (:mod:`rac.model.intersection`);
- ``t_junction``: the same junction without its north arm, the ego turning left across the main
  road's traffic (:func:`rac.model.intersection.build_t_junction`); going straight on leaves the
  road where the north arm is missing;
- ``highway``: three lanes towards +x, the ego at 20 m/s in the middle one behind a truck at
  15 m/s, a faster car coming up in the left lane and a slower one ahead in the right lane
  (:func:`build_highway`);
- ``overtaking``: a two-lane country road, one lane per direction, the ego at 12 m/s behind a
  tractor at 5 m/s, a car coming the other way in the oncoming lane (:func:`build_overtaking`);
- ``tutorial``: a short two-lane road like CommonRoad's tutorial scenario, the ego at 10 m/s behind
  a slower car, a faster one coming up the left lane and a parked van further on
  (:func:`build_tutorial`); with :data:`TUTORIAL_45` (45 actions every 0.2 s) it is the scene on
  which an exhaustive shield cannot be computed for a whole episode (issue 20);
- ``urban``: an urban boulevard, three lanes per direction, no other road users, a goal 105-135 m
  ahead within 14 s (:func:`build_urban`): every run on the road is safe, so runs are many;
- ``urban_head_on``: an urban street, two lanes per direction, a car overtaking towards the ego in
  the ego's lane until 12 s, a goal window at 19.4-20.4 s (:func:`build_urban_head_on`).

Seeded variants, for training on a set of scenes (:class:`rac.learning.scenario_env.ScenarioEnv`):
:func:`highway_variant` and :func:`tutorial_variant` draw the other road users' starts and speeds
from a seed (on a 0.5 grid, within ranges that keep the hazard of the scene) and keep the ego's
start, the road and the goal; :func:`scene_set` writes ``count`` of them (``variant_bytes`` one).
The same seed gives the same file, byte for byte.

A scene as large as asked, for measuring how a large scenario loads (issue 22): :func:`build_grid`
(``grid_bytes(lanelets, obstacles)``), parallel roads of four lanes with cars on the first.

``python -m rac.model.scenes NAME OUT.xml`` writes one; ``write_scene(name, path)`` from Python;
``python -m rac.model.scenes highway OUT_FOLDER --count 8 --seed 0`` writes a set.
The benchmark of every query on each kind (``benchmarks/queries.py``) and the tests use them.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Callable, Sequence
from pathlib import Path

import numpy as np
import shapely
from commonroad.common.common_lanelet import LaneletType, LineMarking
from commonroad.common.common_scenario import ScenarioID
from commonroad.common.util import Interval
from commonroad.geometry.obstacle_shapes.rect_obstacle_shape import RectObstacleShape
from commonroad.geometry.occupancy.rect_occupancy import RectOccupancy
from commonroad.planning.goal import GoalRegion
from commonroad.planning.planning_problem import PlanningProblem, PlanningProblemSet
from commonroad.scenario.lanelet import Lanelet, LaneletNetwork
from commonroad.scenario.obstacle import ObstacleType, StaticObstacle
from commonroad.scenario.scenario import Scenario, Tag
from commonroad.scenario.state import CustomState, InitialState

from rac.core.files import atomic_write, head
from rac.model.intersection import left_turn_bytes, t_junction_bytes
from rac.model.scenario_xml import DT, clean, recorded_car, scenario_bytes, straight_car

__all__ = ["GRID_FIRST_ID", "GRID_LANES", "GRID_SEGMENTS", "HEAD_ON_STEPS", "LANE_WIDTH", "PLANNING_PROBLEM_ID",
           "SCENES", "TUTORIAL_45", "URBAN_STEPS", "VARIANTS", "build_grid", "build_highway", "build_overtaking",
           "build_tutorial", "build_urban", "build_urban_head_on", "grid_bytes", "head_on_track", "highway_variant",
           "scene_bytes", "scene_set", "tutorial_variant", "variant_bytes", "write_scene"]

LANE_WIDTH = 3.5  #: m
PLANNING_PROBLEM_ID = 100
ROAD_LENGTH = 300.0  #: m, from x = 0
STEPS = 120  #: time steps of the obstacles' trajectories and of the goal's time interval (12 s)
URBAN_STEPS = 140  #: the urban street's time steps (14 s)
HEAD_ON_STEPS = 210  #: the head-on scene's time steps (21 s)
#: Mixed into every variant's seed, so a scene set's draws are rac's own (not another numpy stream's).
SET_SEED = 21


def _lane(lanelet_id: int, y_right: float, *, towards_x: bool, left: int | None, left_same: bool | None,
          right: int | None, kind: LaneletType, x0: float = 0.0, predecessor: int | None = None,
          successor: int | None = None) -> Lanelet:
    """A straight lane from x = ``x0`` to ``x0`` + :data:`ROAD_LENGTH` between ``y_right`` and ``y_right +
    LANE_WIDTH``; ``towards_x`` False: it drives towards -x (its vertices run backwards, its left is lower y)."""
    xs = np.linspace(x0, x0 + ROAD_LENGTH, 7)
    low, high = y_right, y_right + LANE_WIDTH

    def line(y: float) -> np.ndarray:
        points = np.column_stack([xs, np.full(xs.size, y)])
        return clean(points if towards_x else points[::-1])

    left_y, right_y = (high, low) if towards_x else (low, high)
    return Lanelet(line(left_y), line((low + high) / 2), line(right_y), lanelet_id,
                   predecessor=None if predecessor is None else [predecessor],
                   successor=None if successor is None else [successor], adjacent_left=left,
                   adjacent_left_same_direction=left_same,
                   adjacent_right=right, adjacent_right_same_direction=True if right is not None else None,
                   line_marking_left_vertices=LineMarking.DASHED if left is not None else LineMarking.SOLID,
                   line_marking_right_vertices=LineMarking.DASHED if right is not None else LineMarking.SOLID,
                   lanelet_type={kind})


def _problem(x: float, y: float, velocity: float, goal_x: tuple[float, float], road_width: float,
             steps: tuple[int, int] = (0, STEPS)) -> PlanningProblemSet:
    """The ego's planning problem: its start, and a goal spanning the road from ``goal_x[0]`` to
    ``goal_x[1]`` within the time steps ``steps``."""
    initial = InitialState(time_step=0, position=clean(np.array([x, y])), orientation=0.0,
                           velocity=float(clean(velocity)), acceleration=0.0, yaw_rate=0.0, slip_angle=0.0)
    area = RectOccupancy(rect_center=shapely.Point(float(clean((goal_x[0] + goal_x[1]) / 2)), road_width / 2),
                         length=float(clean(goal_x[1] - goal_x[0])), width=road_width, orientation=0.0)
    goal = GoalRegion([CustomState(time_step=Interval(*steps), position=area)])
    return PlanningProblemSet([PlanningProblem(PLANNING_PROBLEM_ID, initial, goal)])


def build_highway(truck: tuple[float, float] = (70.0, 15.0), left: tuple[float, float] = (10.0, 25.0),
                  right: tuple[float, float] = (95.0, 17.0), name: str = "Highway",
                  map_id: int = 1) -> tuple[Scenario, PlanningProblemSet]:
    """Three 3.5 m lanes towards +x (lanelets 1, 2, 3 from the right). The ego starts at x = 30 in
    the middle lane at 20 m/s; truck 61 (12 m × 2.5 m) drives ahead of it at 15 m/s from x = 70; car
    62 comes up the left lane at 25 m/s from x = 10; car 63 drives in the right lane at 17 m/s from
    x = 95. The goal spans the road from x = 170 to 230 within 12 s: keeping 20 m/s runs into the
    truck after about 6 s, so the ego brakes behind it or changes lanes between the other two.
    ``truck``, ``left``, ``right``: the three vehicles' (start x, speed) (:func:`highway_variant`)."""
    scenario = Scenario(DT, ScenarioID(country_id="ZAM", map_name=name, map_id=map_id, obstacle_behavior="T",
                                       prediction_id=1))
    for i in range(3):
        scenario.add_objects(_lane(i + 1, i * LANE_WIDTH, towards_x=True, left=i + 2 if i < 2 else None,
                                   left_same=True if i < 2 else None, right=i if i > 0 else None,
                                   kind=LaneletType.HIGHWAY))
    middle = [LANE_WIDTH * (i + 0.5) for i in range(3)]
    scenario.add_objects(straight_car(61, truck[0], middle[1], 0.0, truck[1], STEPS, length=12.0, width=2.5,
                                      kind=ObstacleType.TRUCK))
    scenario.add_objects(straight_car(62, left[0], middle[2], 0.0, left[1], STEPS))
    scenario.add_objects(straight_car(63, right[0], middle[0], 0.0, right[1], STEPS))
    return scenario, _problem(30.0, middle[1], 20.0, (170.0, 230.0), 3 * LANE_WIDTH)


def _draw(rng: np.random.Generator, low: float, high: float) -> float:
    """A number in ``[low, high]`` on a 0.5 grid (short decimals, exact in the XML)."""
    return float(rng.integers(round(2 * low), round(2 * high) + 1)) / 2


def highway_variant(seed: int) -> tuple[Scenario, PlanningProblemSet]:
    """:func:`build_highway` with the three vehicles' start and speed drawn from ``seed`` (the same
    seed, the same scene): truck 61 from x 55-85 at 12-18 m/s, car 62 from x -10-20 at 22-28 m/s,
    car 63 from x 80-120 at 14-20 m/s; the ego's start and the goal are the highway's."""
    rng = np.random.default_rng([SET_SEED, 1, seed])
    return build_highway(truck=(_draw(rng, 55, 85), _draw(rng, 12, 18)), left=(_draw(rng, -10, 20), _draw(rng, 22, 28)),
                         right=(_draw(rng, 80, 120), _draw(rng, 14, 20)), name="HighwayVariant",
                         map_id=seed + 1)


def build_overtaking() -> tuple[Scenario, PlanningProblemSet]:
    """A two-lane road, lanelet 1 towards +x (y 0 to 3.5) and lanelet 2 towards -x (y 3.5 to 7). The
    ego starts at x = 20 in lanelet 1 at 12 m/s; tractor 71 (6 m × 2.5 m) drives ahead at 5 m/s from
    x = 45; car 72 comes the other way in lanelet 2 at 15 m/s from x = 160. The goal spans the road
    from x = 100 to 150 within 12 s: behind the tractor the ego gets there too late, so it overtakes
    in the oncoming lane once car 72 has passed."""
    scenario = Scenario(DT, ScenarioID(country_id="ZAM", map_name="Overtaking", map_id=1, obstacle_behavior="T",
                                       prediction_id=1))
    scenario.add_objects(_lane(1, 0.0, towards_x=True, left=2, left_same=False, right=None, kind=LaneletType.COUNTRY))
    scenario.add_objects(_lane(2, LANE_WIDTH, towards_x=False, left=1, left_same=False, right=None,
                               kind=LaneletType.COUNTRY))
    scenario.add_objects(straight_car(71, 45.0, LANE_WIDTH / 2, 0.0, 5.0, STEPS, length=6.0, width=2.5,
                                      kind=ObstacleType.TRUCK))
    scenario.add_objects(straight_car(72, 160.0, 1.5 * LANE_WIDTH, float(clean(np.pi)), 15.0, STEPS))
    return scenario, _problem(20.0, LANE_WIDTH / 2, 12.0, (100.0, 150.0), 2 * LANE_WIDTH)


def _street(name: str, lanes: int) -> Scenario:
    """An urban street of ``lanes`` 3.5 m lanes per direction: lanelets 1 .. ``lanes`` towards +x from
    y = 0 up, the next ``lanes`` towards -x above them."""
    scenario = Scenario(DT, ScenarioID(country_id="ZAM", map_name=name, map_id=1, obstacle_behavior="T",
                                       prediction_id=1))
    for i in range(2 * lanes):
        if i < lanes:  # towards +x: its left is the next lane up (the first oncoming one after the last)
            scenario.add_objects(_lane(i + 1, i * LANE_WIDTH, towards_x=True, left=i + 2, left_same=i + 1 < lanes,
                                       right=i if i > 0 else None, kind=LaneletType.URBAN))
        else:  # towards -x: its left is the lane below
            scenario.add_objects(_lane(i + 1, i * LANE_WIDTH, towards_x=False, left=i, left_same=i > lanes,
                                       right=i + 2 if i + 1 < 2 * lanes else None, kind=LaneletType.URBAN))
    return scenario


def build_urban() -> tuple[Scenario, PlanningProblemSet]:
    """An urban boulevard without other road users: three lanes per direction (:func:`_street`). The
    ego starts at x = 10 in lanelet 1 at 8 m/s; the goal spans the road from x = 115 to 145 within
    14 s (keeping its speed the ego gets there after about 13.2 s; accelerating, from 7 s on). Every
    run is safe as long as it stays on the road, so the runs are many (each decision's actions
    multiply them: examples/paper/model.ra's settings give more than 5 million states) and those that
    reach the goal early few."""
    scenario = _street("Urban", 3)
    return scenario, _problem(10.0, LANE_WIDTH / 2, 8.0, (115.0, 145.0), 6 * LANE_WIDTH, (0, URBAN_STEPS))


#: Car 91 of :func:`build_urban_head_on`: from x = 200 at 10 m/s towards -x in the ego's lane
#: (lanelet 2), back to its own side (lanelet 3) between 10 and 12 s (a smooth lane change of 3.5 m).
HEAD_ON_START, HEAD_ON_SPEED, HEAD_ON_BACK = 200.0, 10.0, (10.0, 12.0)


def head_on_track(t: float) -> tuple[float, float, float, float]:
    """Car 91's position, heading and speed at time ``t`` (:data:`rac.model.scenario_xml.Track`)."""
    start, end = HEAD_ON_BACK
    u = min(max((t - start) / (end - start), 0.0), 1.0)
    y = 1.5 * LANE_WIDTH + LANE_WIDTH * (3 * u * u - 2 * u * u * u)
    vy = LANE_WIDTH * 6 * u * (1 - u) / (end - start) if 0.0 < u < 1.0 else 0.0
    vx = -HEAD_ON_SPEED
    return HEAD_ON_START + vx * t, y, float(np.arctan2(vy, vx)), float(np.hypot(vx, vy))


def build_urban_head_on() -> tuple[Scenario, PlanningProblemSet]:
    """An urban street of two lanes per direction (:func:`_street`) over 21 s with car 91
    (:func:`head_on_track`) coming towards the ego in the ego's lane (lanelet 2, the inner one),
    overtaking, until it returns to its own side between 10 and 12 s. The ego starts at x = 10 in
    lanelet 2 at 8 m/s: keeping its speed and heading it runs into car 91 at 10.3 s. The goal spans the
    road from x = 140 to 180 between 19.4 and 20.4 s (samples 194 to 204): the ego gives way — slows
    down or changes lanes — and drives on to arrive in that window."""
    scenario = _street("UrbanHeadOn", 2)
    scenario.add_objects(recorded_car(91, head_on_track, HEAD_ON_STEPS))
    return scenario, _problem(10.0, 1.5 * LANE_WIDTH, 8.0, (140.0, 180.0), 4 * LANE_WIDTH, (194, 204))


#: The ``model`` block settings (besides ``scenario`` and the bindings) of the tutorial scene with 45
#: actions every 0.2 s: 9 jerks (the default -2 .. 2 m/s³ in steps of 0.5) x 5 turning rates (-0.4 ..
#: 0.4 rad/s in steps of 0.2), a decision every second sample of 0.1 s. An exhaustive exploration
#: meets 45 successors per decision, which hardly merge: it ends after a few decisions, far short of
#: a 4 s episode (docs/verify.md, "A shield for every step").
TUTORIAL_45: tuple[str, ...] = ("exponent 2", "decide_period 0.2", "granularity 0.25", "max_speed 20",
                                "action jerk in [-2, 2] step 0.5", "action turn in [-0.4, 0.4] step 0.2")


def build_tutorial(ahead: tuple[float, float] = (30.0, 6.0), left: tuple[float, float] = (-5.0, 14.0),
                   parked: float = 95.0, name: str = "Tutorial",
                   map_id: int = 45) -> tuple[Scenario, PlanningProblemSet]:
    """Two 3.5 m lanes towards +x (lanelets 1, right, and 2, left), like the road of CommonRoad's
    tutorial scenario. The ego starts at x = 10 in the right lane at 10 m/s; car 81 drives
    ahead of it at 6 m/s from x = 30; car 82 comes up the left lane at 14 m/s from x = -5; van 83
    (6 m × 2.2 m) is parked in the right lane at x = 95. The goal spans the road from x = 45 to 80
    within 12 s: keeping 10 m/s runs into car 81 after about 4 s, so the ego brakes behind it or
    changes lanes after car 82 has passed. ``ahead``, ``left``: cars 81 and 82's (start x, speed);
    ``parked``: van 83's x (:func:`tutorial_variant`)."""
    scenario = Scenario(DT, ScenarioID(country_id="ZAM", map_name=name, map_id=map_id, obstacle_behavior="T",
                                       prediction_id=1))
    scenario.add_objects(_lane(1, 0.0, towards_x=True, left=2, left_same=True, right=None, kind=LaneletType.URBAN))
    scenario.add_objects(_lane(2, LANE_WIDTH, towards_x=True, left=None, left_same=None, right=1,
                               kind=LaneletType.URBAN))
    right, left_y = LANE_WIDTH / 2, 1.5 * LANE_WIDTH
    scenario.add_objects(straight_car(81, ahead[0], right, 0.0, ahead[1], STEPS))
    scenario.add_objects(straight_car(82, left[0], left_y, 0.0, left[1], STEPS))
    standing = InitialState(time_step=0, position=clean(np.array([parked, right])), orientation=0.0, velocity=0.0,
                          acceleration=0.0, yaw_rate=0.0, slip_angle=0.0)
    scenario.add_objects(StaticObstacle(83, ObstacleType.PARKED_VEHICLE, RectObstacleShape(length=6.0, width=2.2),
                                        standing))
    return scenario, _problem(10.0, right, 10.0, (45.0, 80.0), 2 * LANE_WIDTH)


def tutorial_variant(seed: int) -> tuple[Scenario, PlanningProblemSet]:
    """:func:`build_tutorial` with the other road users drawn from ``seed`` (the same seed, the same
    scene): car 81 from x 25-40 at 4-8 m/s, car 82 from x -15-5 at 12-16 m/s, van 83 parked at x
    85-110; the ego's start and the goal are the tutorial's."""
    rng = np.random.default_rng([SET_SEED, 2, seed])
    return build_tutorial(ahead=(_draw(rng, 25, 40), _draw(rng, 4, 8)), left=(_draw(rng, -15, 5), _draw(rng, 12, 16)),
                          parked=_draw(rng, 85, 110), name="TutorialVariant", map_id=seed + 1)


#: :func:`build_grid`: the lanes of one road, its segments along x, and the first lanelet's id (above the
#: planning problem's 100: CommonRoad ids are unique across a file).
GRID_LANES, GRID_SEGMENTS, GRID_FIRST_ID = 4, 10, 1000


def build_grid(lanelets: int, obstacles: int = 0, steps: int = STEPS) -> tuple[Scenario, PlanningProblemSet]:
    """A scene as large as asked: ``lanelets`` lanelets and ``obstacles`` cars, for measuring the load
    of a large scenario (``benchmarks/scenario_load.py``, issue 22). Roads of :data:`GRID_LANES` lanes
    towards +x, each of :data:`GRID_SEGMENTS` straight segments of :data:`ROAD_LENGTH` m (a segment's
    successor the next), are stacked along y until there are ``lanelets`` lanelets (the last road may
    be narrower or shorter). The cars drive straight on at 10 m/s for ``steps`` time steps, one per
    lane of the first segments in turn, 20 m apart. The ego starts at x = 30 in the first lane at 10
    m/s; the goal spans the first road from x = 170 to 230 within ``steps`` time steps."""
    if lanelets < 1 or obstacles < 0:
        raise ValueError(f"a grid needs at least one lanelet and no negative count of obstacles, not "
                         f"{lanelets} and {obstacles}")

    per_road = GRID_LANES * GRID_SEGMENTS
    built = []
    for index in range(lanelets):
        road, rest = divmod(index, per_road)
        segment, lane = divmod(rest, GRID_LANES)
        ident = GRID_FIRST_ID + index
        left = ident + 1 if lane + 1 < GRID_LANES and index + 1 < lanelets else None
        ahead = ident + GRID_LANES if segment + 1 < GRID_SEGMENTS and index + GRID_LANES < lanelets else None
        built.append(_lane(ident, (road * GRID_LANES + lane) * LANE_WIDTH, towards_x=True, left=left,
                           left_same=True if left is not None else None, right=ident - 1 if lane > 0 else None,
                           kind=LaneletType.HIGHWAY, x0=segment * ROAD_LENGTH,
                           predecessor=ident - GRID_LANES if segment > 0 else None, successor=ahead))
    scenario = Scenario(DT, ScenarioID(country_id="ZAM", map_name="Grid", map_id=1, obstacle_behavior="T",
                                       prediction_id=1))
    # one network at once: adding lanelets one by one rebuilds commonroad-io's spatial index each time
    scenario.add_objects(LaneletNetwork.create_from_lanelet_list(built, cleanup_ids=False))
    lanes = min(lanelets, GRID_LANES)
    for k in range(obstacles):
        lane, row = k % lanes, k // lanes
        scenario.add_objects(straight_car(GRID_FIRST_ID + lanelets + k, 60.0 + 20.0 * row,
                                          LANE_WIDTH * (lane + 0.5), 0.0, 10.0, steps))
    return scenario, _problem(30.0, LANE_WIDTH / 2, 10.0, (170.0, 230.0), lanes * LANE_WIDTH, (0, steps))


def grid_bytes(lanelets: int, obstacles: int = 0, steps: int = STEPS) -> bytes:
    """:func:`build_grid` as CommonRoad XML (byte-stable)."""
    scenario, problems = build_grid(lanelets, obstacles, steps)
    return scenario_bytes(scenario, problems, tags={Tag.HIGHWAY, Tag.MULTI_LANE},
                          source=f"generated by rac.model.scenes (grid of {lanelets} lanelets, {obstacles} cars)")


def _straight_bytes(build: Callable[[], tuple[Scenario, PlanningProblemSet]], name: str,
                    tags: set[Tag]) -> Callable[[], bytes]:
    def make() -> bytes:
        scenario, problems = build()
        return scenario_bytes(scenario, problems, tags=tags, source=f"generated by rac.model.scenes ({name})")
    return make


#: The scenes by name: each gives its canonical CommonRoad XML.
SCENES: dict[str, Callable[[], bytes]] = {
    "highway": _straight_bytes(build_highway, "highway", {Tag.HIGHWAY, Tag.MULTI_LANE, Tag.LANE_CHANGE}),
    "overtaking": _straight_bytes(build_overtaking, "overtaking",
                                  {Tag.RURAL, Tag.TWO_LANE, Tag.ONCOMING_TRAFFIC, Tag.EMERGENCY_BRAKING}),
    "tutorial": _straight_bytes(build_tutorial, "tutorial", {Tag.URBAN, Tag.MULTI_LANE, Tag.LANE_CHANGE}),
    "t_junction": t_junction_bytes,
    "left_turn": left_turn_bytes,
    "urban": _straight_bytes(build_urban, "urban", {Tag.URBAN, Tag.TWO_LANE, Tag.NO_ONCOMING_TRAFFIC}),
    "urban_head_on": _straight_bytes(build_urban_head_on, "urban_head_on",
                                     {Tag.URBAN, Tag.TWO_LANE, Tag.ONCOMING_TRAFFIC, Tag.CRITICAL}),
}


#: The scene kinds with seeded variants (:func:`scene_set`): the variant builder and the scene's tags.
VARIANTS: dict[str, tuple[Callable[[int], tuple[Scenario, PlanningProblemSet]], set[Tag]]] = {
    "highway": (highway_variant, {Tag.HIGHWAY, Tag.MULTI_LANE, Tag.LANE_CHANGE}),
    "tutorial": (tutorial_variant, {Tag.URBAN, Tag.MULTI_LANE, Tag.LANE_CHANGE}),
}


def variant_bytes(kind: str, seed: int) -> bytes:
    """The variant ``seed`` of the scene ``kind`` (:data:`VARIANTS`) as CommonRoad XML (byte-stable)."""
    if kind not in VARIANTS:
        raise ValueError(f"no variants of scene {kind!r}; the kinds with variants are {', '.join(VARIANTS)}")
    if seed < 0:  # numpy's own refusal, "expected non-negative integer", named no seed
        raise ValueError(f"a variant's seed is a whole number from 0 on, not {seed}")
    build, tags = VARIANTS[kind]
    scenario, problems = build(seed)
    return scenario_bytes(scenario, problems, tags=tags, source=_variant_source(kind, seed))


def _variant_source(kind: str, seed: int) -> str:
    """The ``source`` a variant's file names: rac's mark (:data:`rac.core.files.GENERATED_MARK`), the kind and
    the seed, which tell a scene set's own files from any other."""
    return f"generated by rac.model.scenes ({kind} variant {seed})"


def scene_set(kind: str, count: int, seed: int, folder: str | Path) -> list[Path]:
    """Write ``count`` variants of the scene ``kind`` (:data:`VARIANTS`) into ``folder`` (created if
    missing) as ``{kind}_{seed + i}.xml``, variant ``seed + i`` for ``i < count``; return their paths
    in that order. The same arguments give the same files, byte for byte; each is written atomically
    (:func:`rac.core.files.atomic_write`), so an interrupted run never leaves a truncated scene. The files
    of ``kind`` an earlier set wrote there and this one does not (a larger count, another seed) are removed,
    so that the folder, read as a set (:class:`rac.learning.scenario_env.ScenarioEnv`), is this set: only
    variants rac wrote (their ``source`` says so), never another file, nor another kind's set."""
    if count < 1:
        raise ValueError(f"a scene set needs at least one scene, not {count}")
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    paths = [_write(folder / f"{kind}_{seed + i}.xml", variant_bytes(kind, seed + i)) for i in range(count)]
    for stale in sorted(set(folder.glob(f"{kind}_*.xml")) - set(paths)):
        try:
            number = int(stale.stem.removeprefix(f"{kind}_"))
        except ValueError:  # no variant's name: not the set's
            continue
        # a link is the user's (to a variant kept elsewhere), even when what it leads to is rac's
        if not stale.is_symlink() and f'source="{_variant_source(kind, number)}"'.encode() in head(stale):
            stale.unlink(missing_ok=True)
    return paths


def scene_bytes(name: str) -> bytes:
    """The scene ``name`` (:data:`SCENES`) as CommonRoad XML."""
    if name not in SCENES:
        raise ValueError(f"unknown scene {name!r}; the scenes are {', '.join(SCENES)}")
    return SCENES[name]()


def write_scene(name: str, path: str | Path) -> Path:
    """Write the scene ``name`` to ``path`` (atomically, :func:`rac.core.files.atomic_write`) and return the path."""
    return _write(Path(path), scene_bytes(name))


def _write(path: Path, data: bytes) -> Path:
    """``data`` into ``path`` atomically: an interrupted write left a truncated scene there, which the next
    run read."""
    return atomic_write(path, lambda file: file.write(data))


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m rac.model.scenes",
                                     description="Write one of rac's generated scenes as CommonRoad XML.")
    parser.add_argument("name", choices=list(SCENES))
    parser.add_argument("out", help="the .xml file to write (with --count: the folder of the set)")
    parser.add_argument("--count", type=int, help="write a set of this many seeded variants instead")
    parser.add_argument("--seed", type=int, default=0, help="the set's first variant (default 0)")
    args = parser.parse_args(argv)
    if args.count is not None and args.name not in VARIANTS:
        parser.error(f"{args.name} has no variants; --count works with {', '.join(VARIANTS)}")
    try:
        if args.count is None:
            print(f"wrote {write_scene(args.name, args.out)}")
            return 0
        paths = scene_set(args.name, args.count, args.seed, args.out)
    except (OSError, ValueError) as exc:  # a folder that is a file, a missing one, --count 0: said, no traceback
        parser.error(str(exc))
    print(f"wrote {len(paths)} scenes to {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
