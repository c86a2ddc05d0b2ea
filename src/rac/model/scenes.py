"""Small scenes of the kinds rac is judged on, built in code with commonroad-io.

Four scenes, each a CommonRoad 2020a file written like a user's (:mod:`rac.model.scenario_xml`),
with the ego's planning problem 100 and 0.1 s time steps:

- ``left_turn``: the paper's left-turn intersection (:mod:`rac.model.intersection`);
- ``t_junction``: the same junction without its north arm, the ego turning left across the main
  road's traffic (:func:`rac.model.intersection.build_t_junction`); going straight on leaves the
  road where the north arm is missing;
- ``highway``: three lanes towards +x, the ego at 20 m/s in the middle one behind a truck at
  15 m/s, a faster car coming up in the left lane and a slower one ahead in the right lane
  (:func:`build_highway`);
- ``overtaking``: a two-lane country road, one lane per direction, the ego at 12 m/s behind a
  tractor at 5 m/s, a car coming the other way in the oncoming lane (:func:`build_overtaking`).

``python -m rac.model.scenes NAME OUT.xml`` writes one; ``write_scene(name, path)`` from Python.
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
from commonroad.geometry.occupancy.rect_occupancy import RectOccupancy
from commonroad.planning.goal import GoalRegion
from commonroad.planning.planning_problem import PlanningProblem, PlanningProblemSet
from commonroad.scenario.lanelet import Lanelet
from commonroad.scenario.obstacle import ObstacleType
from commonroad.scenario.scenario import Scenario, Tag
from commonroad.scenario.state import CustomState, InitialState

from rac.model.intersection import left_turn_bytes, t_junction_bytes
from rac.model.scenario_xml import DT, clean, scenario_bytes, straight_car

__all__ = ["LANE_WIDTH", "PLANNING_PROBLEM_ID", "SCENES", "build_highway", "build_overtaking", "scene_bytes",
           "write_scene"]

LANE_WIDTH = 3.5  #: m
PLANNING_PROBLEM_ID = 100
ROAD_LENGTH = 300.0  #: m, from x = 0
STEPS = 120  #: time steps of the obstacles' trajectories and of the goal's time interval (12 s)


def _lane(lanelet_id: int, y_right: float, *, towards_x: bool, left: int | None, left_same: bool | None,
          right: int | None, kind: LaneletType) -> Lanelet:
    """A straight lane from x = 0 to :data:`ROAD_LENGTH` between ``y_right`` and ``y_right + LANE_WIDTH``;
    ``towards_x`` False: it drives towards -x (its vertices run backwards, its left is lower y)."""
    xs = np.linspace(0.0, ROAD_LENGTH, 7)
    low, high = y_right, y_right + LANE_WIDTH

    def line(y: float) -> np.ndarray:
        points = np.column_stack([xs, np.full(xs.size, y)])
        return clean(points if towards_x else points[::-1])

    left_y, right_y = (high, low) if towards_x else (low, high)
    return Lanelet(line(left_y), line((low + high) / 2), line(right_y), lanelet_id,
                   adjacent_left=left, adjacent_left_same_direction=left_same,
                   adjacent_right=right, adjacent_right_same_direction=True if right is not None else None,
                   line_marking_left_vertices=LineMarking.DASHED if left is not None else LineMarking.SOLID,
                   line_marking_right_vertices=LineMarking.DASHED if right is not None else LineMarking.SOLID,
                   lanelet_type={kind})


def _problem(x: float, y: float, velocity: float, goal_x: tuple[float, float], road_width: float) -> PlanningProblemSet:
    initial = InitialState(time_step=0, position=clean(np.array([x, y])), orientation=0.0,
                           velocity=float(clean(velocity)), acceleration=0.0, yaw_rate=0.0, slip_angle=0.0)
    area = RectOccupancy(rect_center=shapely.Point(float(clean((goal_x[0] + goal_x[1]) / 2)), road_width / 2),
                         length=float(clean(goal_x[1] - goal_x[0])), width=road_width, orientation=0.0)
    goal = GoalRegion([CustomState(time_step=Interval(0, STEPS), position=area)])
    return PlanningProblemSet([PlanningProblem(PLANNING_PROBLEM_ID, initial, goal)])


def build_highway() -> tuple[Scenario, PlanningProblemSet]:
    """Three 3.5 m lanes towards +x (lanelets 1, 2, 3 from the right). The ego starts at x = 30 in
    the middle lane at 20 m/s; truck 61 (12 m × 2.5 m) drives ahead of it at 15 m/s from x = 70; car
    62 comes up the left lane at 25 m/s from x = 10; car 63 drives in the right lane at 17 m/s from
    x = 95. The goal spans the road from x = 170 to 230 within 12 s: keeping 20 m/s runs into the
    truck after about 6 s, so the ego brakes behind it or changes lanes between the other two."""
    scenario = Scenario(DT, ScenarioID(country_id="ZAM", map_name="Highway", map_id=1, obstacle_behavior="T",
                                       prediction_id=1))
    for i in range(3):
        scenario.add_objects(_lane(i + 1, i * LANE_WIDTH, towards_x=True, left=i + 2 if i < 2 else None,
                                   left_same=True if i < 2 else None, right=i if i > 0 else None,
                                   kind=LaneletType.HIGHWAY))
    middle = [LANE_WIDTH * (i + 0.5) for i in range(3)]
    scenario.add_objects(straight_car(61, 70.0, middle[1], 0.0, 15.0, STEPS, length=12.0, width=2.5,
                                      kind=ObstacleType.TRUCK))
    scenario.add_objects(straight_car(62, 10.0, middle[2], 0.0, 25.0, STEPS))
    scenario.add_objects(straight_car(63, 95.0, middle[0], 0.0, 17.0, STEPS))
    return scenario, _problem(30.0, middle[1], 20.0, (170.0, 230.0), 3 * LANE_WIDTH)


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
    "t_junction": t_junction_bytes,
    "left_turn": left_turn_bytes,
}


def scene_bytes(name: str) -> bytes:
    """The scene ``name`` (:data:`SCENES`) as CommonRoad XML."""
    if name not in SCENES:
        raise ValueError(f"unknown scene {name!r}; the scenes are {', '.join(SCENES)}")
    return SCENES[name]()


def write_scene(name: str, path: str | Path) -> Path:
    """Write the scene ``name`` to ``path`` and return the path."""
    path = Path(path)
    path.write_bytes(scene_bytes(name))
    return path


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m rac.model.scenes",
                                     description="Write one of rac's generated scenes as CommonRoad XML.")
    parser.add_argument("name", choices=list(SCENES))
    parser.add_argument("out", help="the .xml file to write")
    args = parser.parse_args(argv)
    print(f"wrote {write_scene(args.name, args.out)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
