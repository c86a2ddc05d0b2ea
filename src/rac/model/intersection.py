"""The left-turn intersection of the paper's experiment, built in code with commonroad-io.

A four-way intersection of two two-lane roads (one 3.5 m lane per direction, right-hand traffic),
centred on the origin: x grows to the east, y to the north. Each of the four arms has an
incoming and an outgoing lanelet from ``HALF_BOX`` (8 m) to ``ARM_END`` (70 m) from the centre;
inside the 16 m × 16 m box every incoming lanelet continues by a left-turn, a straight and a
right-turn connector lanelet (quarter circles and straight lines), so the road (the union of the
lanelets) is the two crossing roads plus the rounded corners of the turns.

- The ego starts on the south arm at (1.75, -18) heading north at 6 m/s; its route is the
  left-turn connector (lanelet 11) into the westbound lane of the west arm (lanelet 8).
- The goal is an 8 m × 3.5 m rectangle centred at (-22, 1.75) on that lane, at any time of the
  horizon (time steps 0..100, i.e. 0..10 s).
- Three cars (4.5 m × 1.8 m) drive at constant velocity for 100 steps of dt = 0.1 s:
  51 from the west going east (crosses the ego's path), 52 from the north going south (oncoming
  traffic the left turn must yield to), 53 from the east going west (passes the intersection
  first and drives ahead of the ego through the goal area). An ego that keeps its speed hits
  car 51; one that accelerates cannot pass first; one that yields to 51 and 52 reaches the goal
  after about 8 to 10 s.

Lanelet ids: the incoming lanelets are 1 (south), 3 (east), 5 (north), 7 (west); the outgoing
lanelets are 2, 4, 6, 8 on the same arms; the connectors leaving the incoming lanelet of
approach k (south 1, east 2, north 3, west 4) are 10k+1 (left), 10k+2 (straight), 10k+3 (right).

``build_left_turn(seed)``: seed 0 is the committed example (examples/left_turn/left_turn.xml);
another seed moves each car up to 4 m along its lane and changes its speed by up to 1 m/s,
reproducibly. ``python -m rac.model.intersection OUT.xml [--seed N] [--png OUT.png]``
writes the CommonRoad XML (and optionally a picture).
"""

from __future__ import annotations

import argparse
import math
import sys
import warnings
from collections.abc import Sequence
from dataclasses import dataclass
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
from commonroad.prediction.prediction import TrajectoryPrediction
from commonroad.scenario.lanelet import Lanelet
from commonroad.scenario.obstacle import DynamicObstacle, ObstacleType
from commonroad.scenario.scenario import Scenario, Tag
from commonroad.scenario.state import CustomState, ExtendedPMState, InitialState
from commonroad.scenario.trajectory import Trajectory

from rac.core.files import atomic_write
from rac.model.scenario_xml import DECIMALS, DT, clean, scenario_bytes

__all__ = [
    "ARM_END", "DT", "EGO_START", "GOAL_CENTER", "GOAL_SIZE", "HALF_BOX", "LANE_WIDTH", "OBSTACLES",
    "PLANNING_PROBLEM_ID", "STEPS", "T_ARMS", "build_left_turn", "build_t_junction", "render_left_turn",
    "left_turn_bytes", "t_junction_bytes", "write_left_turn",
]

LANE_WIDTH = 3.5  #: m, one lane per direction
HALF_BOX = 8.0  #: m, from the centre to where the arms begin (the intersection box is 16 m wide)
ARM_END = 70.0  #: m, from the centre to the far end of each arm
STEPS = 100  #: time steps of the obstacles' trajectories and of the goal's time interval (10 s)
ARC_SEGMENTS = 16  #: segments of each quarter-circle boundary of a turning connector
STRAIGHT_SPACING = 5.0  #: m, at most between two boundary points of a straight lanelet
PLANNING_PROBLEM_ID = 100

#: Approaches in counter-clockwise order: name, rotation (multiples of 90°) of the south approach.
APPROACHES = ("south", "east", "north", "west")
_ROTATIONS = ((1.0, 0.0), (0.0, 1.0), (-1.0, 0.0), (0.0, -1.0))  # exact cos, sin of k * 90°

#: Ego start: x, y, heading (north, to the file's decimals), velocity (the south arm's northbound lane).
EGO_START = (LANE_WIDTH / 2, -18.0, round(math.pi / 2, DECIMALS), 6.0)
GOAL_CENTER = (-22.0, LANE_WIDTH / 2)  #: on the westbound lane of the west arm (lanelet 8)
GOAL_SIZE = (8.0, LANE_WIDTH)  #: length (along x), width


@dataclass(frozen=True)
class CarSpec:
    """A car driving straight through on its approach's incoming lane at constant velocity."""

    id: int
    approach: int  # index into APPROACHES: where it comes from
    start_distance: float  # m before the centre of the intersection, along its lane
    velocity: float  # m/s
    length: float = 4.5
    width: float = 1.8


OBSTACLES = (
    CarSpec(51, approach=3, start_distance=30.0, velocity=8.0),  # from the west, going east
    CarSpec(52, approach=2, start_distance=30.0, velocity=7.0),  # from the north, going south
    CarSpec(53, approach=1, start_distance=16.0, velocity=8.0),  # from the east, going west
)


def incoming_id(approach: int) -> int:
    return 1 + 2 * approach


def outgoing_id(approach: int) -> int:
    return 2 + 2 * approach


def connector_id(approach: int, turn: str) -> int:
    return 10 * (approach + 1) + {"left": 1, "straight": 2, "right": 3}[turn]


def _rotate(points: np.ndarray, approach: int) -> np.ndarray:
    c, s = _ROTATIONS[approach]
    x, y = points[:, 0], points[:, 1]
    return np.column_stack((c * x - s * y, s * x + c * y))


def _straight(x: float, y0: float, y1: float) -> np.ndarray:
    n = max(2, math.ceil(abs(y1 - y0) / STRAIGHT_SPACING) + 1)
    return np.column_stack((np.full(n, x), np.linspace(y0, y1, n)))


def _arc(cx: float, cy: float, r: float, a0: float, a1: float) -> np.ndarray:
    angles = np.linspace(a0, a1, ARC_SEGMENTS + 1)
    return np.column_stack((cx + r * np.cos(angles), cy + r * np.sin(angles)))


def _south_polylines() -> dict[str, tuple[np.ndarray, np.ndarray, np.ndarray]]:
    """Left, centre and right boundaries of the south approach's lanelets (the others are rotations)."""
    w, h, far = LANE_WIDTH, HALF_BOX, ARM_END
    quarter = math.pi / 2
    return {
        # northbound towards the box, then southbound away from it
        "incoming": (_straight(0.0, -far, -h), _straight(w / 2, -far, -h), _straight(w, -far, -h)),
        "outgoing": (_straight(0.0, -h, -far), _straight(-w / 2, -h, -far), _straight(-w, -h, -far)),
        "straight": (_straight(0.0, -h, h), _straight(w / 2, -h, h), _straight(w, -h, h)),
        # quarter circles around the box's south-west corner: (w/2, -h) heading north -> (-h, w/2) heading west
        "left": (_arc(-h, -h, h, 0.0, quarter), _arc(-h, -h, h + w / 2, 0.0, quarter),
                 _arc(-h, -h, h + w, 0.0, quarter)),
        # around the south-east corner: (w/2, -h) heading north -> (h, -w/2) heading east
        "right": (_arc(h, -h, h, math.pi, quarter), _arc(h, -h, h - w / 2, math.pi, quarter),
                  _arc(h, -h, h - w, math.pi, quarter)),
    }


def _lanelets(arms: Sequence[int] = (0, 1, 2, 3)) -> list[Lanelet]:
    """The lanelets of the junction's ``arms`` (approach indices) and of the connectors between them."""
    south = _south_polylines()
    lanelets = []
    every = {"left": 3, "straight": 2, "right": 1}  # outgoing approach = (approach + offset) % 4
    for k in arms:
        targets = {turn: offset for turn, offset in every.items() if (k + offset) % 4 in arms}
        sources = {turn: offset for turn, offset in every.items() if (k - offset) % 4 in arms}
        def bounds(kind: str, k: int = k) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
            left, centre, right = south[kind]
            return clean(_rotate(left, k)), clean(_rotate(centre, k)), clean(_rotate(right, k))

        left, centre, right = bounds("incoming")
        lanelets.append(Lanelet(
            left, centre, right, incoming_id(k),
            successor=[connector_id(k, turn) for turn in targets],
            adjacent_left=outgoing_id(k), adjacent_left_same_direction=False,
            line_marking_left_vertices=LineMarking.DASHED, line_marking_right_vertices=LineMarking.SOLID,
            lanelet_type={LaneletType.URBAN}))
        left, centre, right = bounds("outgoing")
        lanelets.append(Lanelet(
            left, centre, right, outgoing_id(k),
            predecessor=[connector_id((k - offset) % 4, turn) for turn, offset in sources.items()],
            adjacent_left=incoming_id(k), adjacent_left_same_direction=False,
            line_marking_left_vertices=LineMarking.DASHED, line_marking_right_vertices=LineMarking.SOLID,
            lanelet_type={LaneletType.URBAN}))
        for turn, offset in targets.items():
            left, centre, right = bounds(turn)
            lanelets.append(Lanelet(
                left, centre, right, connector_id(k, turn),
                predecessor=[incoming_id(k)], successor=[outgoing_id((k + offset) % 4)],
                lanelet_type={LaneletType.URBAN, LaneletType.INTERSECTION}))
    return sorted(lanelets, key=lambda lanelet: lanelet.lanelet_id)


def _heading(approach: int) -> float:
    """Heading of traffic on an approach's incoming lane, in (-pi, pi]."""
    return float(clean(math.remainder(math.pi / 2 * (1 + approach), 2 * math.pi)))


def _car(spec: CarSpec, shift: float, dv: float, steps: int = STEPS) -> DynamicObstacle:
    (x0, y0), = _rotate(np.array([[LANE_WIDTH / 2, -(spec.start_distance + shift)]]), spec.approach)
    heading = _heading(spec.approach)
    c, s = _ROTATIONS[(spec.approach + 1) % 4]  # unit vector of the heading, exactly
    v = float(clean(spec.velocity + dv))

    def position(k: int) -> np.ndarray:
        return clean(np.array([[x0 + c * v * k * DT, y0 + s * v * k * DT]]))[0]

    initial = InitialState(time_step=0, position=position(0), orientation=heading, velocity=v,
                           acceleration=0.0, yaw_rate=0.0, slip_angle=0.0)
    states = [ExtendedPMState(time_step=k, position=position(k), velocity=v, orientation=heading, acceleration=0.0)
              for k in range(1, steps + 1)]
    shape = RectObstacleShape(width=spec.width, length=spec.length)
    return DynamicObstacle(spec.id, ObstacleType.CAR, shape, initial,
                           TrajectoryPrediction(Trajectory(1, states), shape))


def build_left_turn(seed: int = 0, steps: int = STEPS) -> tuple[Scenario, PlanningProblemSet]:
    """The commonroad-io scenario and planning problem set of the left turn (see the module docstring).

    Seed 0 is the committed example; another seed moves each car up to 4 m along its lane and
    changes its speed by up to 1 m/s (numpy's default generator, so the same seed gives the same
    scenario). The road and the planning problem do not depend on the seed. ``steps`` time steps
    of 0.1 s are the cars' trajectories and the goal's time window (default 100: 10 s).
    """
    if seed < 0:
        raise ValueError(f"seed must be >= 0, got {seed}")
    if steps < 1:
        raise ValueError(f"steps must be >= 1, got {steps}")
    rng = np.random.default_rng(seed) if seed else None
    scenario = Scenario(DT, ScenarioID(country_id="ZAM", map_name="LeftTurn", map_id=1, configuration_id=seed + 1,
                                       obstacle_behavior="T", prediction_id=1))
    for lanelet in _lanelets():
        scenario.add_objects(lanelet)
    for spec in OBSTACLES:
        shift, dv = (rng.uniform(-4.0, 4.0), rng.uniform(-1.0, 1.0)) if rng is not None else (0.0, 0.0)
        scenario.add_objects(_car(spec, shift, dv, steps))

    return scenario, _problems(steps)


def _problems(steps: int) -> PlanningProblemSet:
    """The ego's start on the south arm and the goal on the west arm, within ``steps`` time steps."""
    x, y, heading, velocity = EGO_START
    initial = InitialState(time_step=0, position=np.array([x, y]), orientation=heading, velocity=velocity,
                           acceleration=0.0, yaw_rate=0.0, slip_angle=0.0)
    goal_area = RectOccupancy(rect_center=shapely.Point(*GOAL_CENTER), length=GOAL_SIZE[0], width=GOAL_SIZE[1],
                              orientation=0.0)
    goal = GoalRegion([CustomState(time_step=Interval(0, steps), position=goal_area)])
    return PlanningProblemSet([PlanningProblem(PLANNING_PROBLEM_ID, initial, goal)])


#: The T-junction's arms: the intersection without its north arm.
T_ARMS = (0, 1, 3)


def build_t_junction(steps: int = STEPS) -> tuple[Scenario, PlanningProblemSet]:
    """A T-junction: the intersection without its north arm (:data:`T_ARMS`), the same ego turning
    left from the south arm into the west arm's westbound lane and the same goal, across two cars
    driving straight through on the main road: 51 from the west going east (it crosses the ego's
    path) and 53 from the east going west (it drives ahead of the ego through the goal area)."""
    if steps < 1:
        raise ValueError(f"steps must be >= 1, got {steps}")
    scenario = Scenario(DT, ScenarioID(country_id="ZAM", map_name="TJunction", map_id=1, obstacle_behavior="T",
                                       prediction_id=1))
    for lanelet in _lanelets(T_ARMS):
        scenario.add_objects(lanelet)
    for spec in OBSTACLES:
        if spec.approach in T_ARMS:
            scenario.add_objects(_car(spec, 0.0, 0.0, steps))
    return scenario, _problems(steps)


def t_junction_bytes(steps: int = STEPS) -> bytes:
    """:func:`build_t_junction` as canonical CommonRoad XML."""
    scenario, problems = build_t_junction(steps)
    return scenario_bytes(scenario, problems, tags={Tag.URBAN, Tag.INTERSECTION, Tag.TURN_LEFT, Tag.TWO_LANE},
                          source="generated by rac.model.intersection (T-junction)")


def left_turn_bytes(seed: int = 0, steps: int = STEPS) -> bytes:
    """:func:`build_left_turn` as canonical CommonRoad XML."""
    scenario, problems = build_left_turn(seed, steps)
    return scenario_bytes(scenario, problems,
                          tags={Tag.URBAN, Tag.INTERSECTION, Tag.TURN_LEFT, Tag.ONCOMING_TRAFFIC, Tag.TWO_LANE},
                          source=(f"generated by rac.model.intersection (seed {seed})"
                                  + (f" ({steps} steps)" if steps != STEPS else "")))


def write_left_turn(path: str | Path, seed: int = 0, steps: int = STEPS) -> Path:
    """Write the left-turn scenario as a CommonRoad 2020a XML file (schema-checked) and return its path."""
    data = left_turn_bytes(seed, steps)
    # atomically, as rac.model.scenes writes: an interrupted write left a truncated scenario there
    return atomic_write(path, lambda file: file.write(data))


def render_left_turn(xml_path: str | Path, png_path: str | Path) -> Path:
    """Draw the scenario in ``xml_path`` (with commonroad's MPRenderer, headless) into ``png_path``:
    the lanelets, the cars at time step 0 with their trajectories, the ego's start and the goal,
    plus the ego's route along the lanelets' centre lines (dashed) and labels."""
    import matplotlib  # matplotlib: only when a plot is written

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt  # matplotlib: only when a plot is written

    # commonroad: only when this runs; importing rac.model.intersection stays light
    from commonroad.common.file_reader import CommonRoadFileReader

    # commonroad: only when this runs; importing rac.model.intersection stays light
    from commonroad.visualization.mp_renderer import MPRenderer

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        scenario, problems = CommonRoadFileReader(str(xml_path)).open()
        fig, ax = plt.subplots(figsize=(10, 7.6))
        # the arms are cut where nothing happens: the cars' and the ego's paths stay inside
        renderer = MPRenderer(ax=ax, plot_limits=[-66.0, 52.0, -42.0, 40.0])
        renderer.draw_params.time_begin = 0
        renderer.draw_params.dynamic_obstacle.draw_icon = False
        renderer.draw_params.dynamic_obstacle.show_label = False
        scenario.draw(renderer)
        problems.draw(renderer)
        renderer.render()

        network = scenario.lanelet_network
        route = np.concatenate([network.find_lanelet_by_id(i).center_vertices
                                for i in (incoming_id(0), connector_id(0, "left"), outgoing_id(3))])
        ax.plot(route[:, 0], route[:, 1], linestyle="--", color="#2e7d32", linewidth=1.6, zorder=40,
                label="ego's route (lanelets 1, 11, 8)")
        x, y, heading, _ = EGO_START
        ax.annotate("ego start", (x, y), xytext=(x + 6, y - 6), zorder=41, fontsize=10,
                    arrowprops={"arrowstyle": "->", "color": "#2e7d32"}, color="#2e7d32")
        ax.annotate("goal", GOAL_CENTER, xytext=(GOAL_CENTER[0] - 4, GOAL_CENTER[1] + 8), zorder=41, fontsize=10,
                    arrowprops={"arrowstyle": "->", "color": "#b71c1c"}, color="#b71c1c")
        for obstacle in scenario.dynamic_obstacles:
            first = obstacle.initial_state
            last = obstacle.prediction.trajectory.state_list[-1]
            (x0, y0), (x1, y1) = first.position, last.position
            ax.annotate("", (x1, y1), xytext=(x0, y0), zorder=39,
                        arrowprops={"arrowstyle": "->", "color": "#1d4f91", "linewidth": 1.0, "alpha": 0.7})
            # label on the car's right, i.e. outside the road for right-hand traffic
            ax.text(x0 + 7.0 * math.sin(first.orientation), y0 - 7.0 * math.cos(first.orientation),
                    f"car {obstacle.obstacle_id}\n{first.velocity:g} m/s", fontsize=9, zorder=41, color="#1d4f91",
                    ha="center", va="center")
        # the file's own trajectories (--steps): the title said the default's 10 s whatever they were
        last = max((o.prediction.trajectory.final_state.time_step for o in scenario.dynamic_obstacles), default=0)
        ax.set_title(f"{scenario.scenario_id}: left turn, t = 0 s (trajectories to {last * scenario.dt:g} s)")
        ax.legend(loc="upper right")
        ax.set_aspect("equal")
        # MPRenderer leaves the axes unlabelled: say the coordinates are metres, as rac render does
        ax.set_xlabel("x (m)")
        ax.set_ylabel("y (m)")
        fig.tight_layout()
        # a temporary file, renamed: a full disk halfway leaves the old picture, not half of a new one
        atomic_write(png_path, lambda file: fig.savefig(file, format="png", dpi=110))
        plt.close(fig)
    return Path(png_path)


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m rac.model.intersection",
                                     description="Write the left-turn intersection scenario as CommonRoad XML.")
    parser.add_argument("out", help="the .xml file to write")
    parser.add_argument("--seed", type=int, default=0, help="0 (default) is the committed example")
    parser.add_argument("--steps", type=int, default=STEPS,
                        help=f"0.1 s time steps of the cars' trajectories and the goal window (default {STEPS})")
    parser.add_argument("--png", help="also draw the scenario into this .png file")
    args = parser.parse_args(argv)
    if args.seed < 0:
        parser.error("--seed must be >= 0")
    if args.steps < 1:
        parser.error("--steps must be >= 1")
    try:  # a missing folder, a folder where the file goes: said, no traceback (as python -m rac.model.scenes)
        path = write_left_turn(args.out, args.seed, args.steps)
        print(f"wrote {path}")
        if args.png:
            print(f"wrote {render_left_turn(path, args.png)}")
    except OSError as exc:
        parser.error(str(exc))
    return 0


if __name__ == "__main__":
    sys.exit(main())
