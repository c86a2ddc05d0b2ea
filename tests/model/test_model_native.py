"""The native model functions (rac.model.native) on hand-made scenarios with known answers.

The scenario builders here are shared with tests/targets/test_model_c.py (the differential test against C).
"""

from __future__ import annotations

import math
from dataclasses import replace
from fractions import Fraction as F
from pathlib import Path

import numpy as np
import pytest

from rac.ir import Action, ModelSpec
from rac.model import (
    NO_OBSTACLE,
    ModelData,
    ModelRangeError,
    NativeModel,
    State,
    build_model_data,
    check_significands,
    max_significand,
)
from rac.model.commonroad import EgoStart, Goal, Obstacle, Polygon, Scenario, Waypoint


# ---------------------------------------------------------------- builders (shared with test_model_c)
def rectangle(x0: float, y0: float, x1: float, y1: float) -> Polygon:
    return Polygon(((x0, y0), (x1, y0), (x1, y1), (x0, y1)))


def make_spec(exponent: int = 3, *, granularity: F = F(1, 10), sense: F = F(1, 10), decide: F = F(1, 2),
              min_speed: F = F(0), max_speed: F = F(20)) -> ModelSpec:
    return ModelSpec(
        scenario="hand-made.xml", scenario_path="hand-made.xml", base=10, exponent=exponent,
        sense_period=sense, decide_period=decide, granularity=granularity,
        actions=(Action("jerk", F(-2), F(2), F(1, 2)), Action("turn", F(-2, 5), F(2, 5), F(1, 10))),
        length=F(9, 2), width=F(9, 5), max_acceleration=F(3), max_turn=F(2, 5),
        min_speed=min_speed, max_speed=max_speed, collision_distance=F(1, 2),
        comfort_acceleration=F(1, 2), comfort_turn=F(1, 2), bindings=())


def straight_scenario() -> Scenario:
    """Two lanes along x (0..200, y -3.5..3.5, sharing y = 0); an obstacle ahead in the left lane
    from t = 1 s to t = 6 s whose speed changes at its waypoints; a goal far ahead at 5..8 s."""
    waypoints = tuple(Waypoint(1.0 + 0.5 * i, 30.0 + sum(8.0 + 0.5 * j for j in range(i)) * 0.5, 1.75, 0.0,
                               8.0 + 0.5 * i) for i in range(11))
    return Scenario(
        name="straight", path="straight.xml", dt=0.1,
        road=(rectangle(0.0, -3.5, 200.0, 0.0), rectangle(0.0, 0.0, 200.0, 3.5)),
        obstacles=(Obstacle(10, 4.8, 2.0, waypoints),),
        ego=EgoStart(10.0, -1.75, 0.0, 10.0),
        goal=Goal((rectangle(150.0, -3.5, 170.0, 0.0),), 5.0, 8.0),
    )


def crossing_scenario() -> Scenario:
    """Two crossing roads; a car driving north through the crossing, a parked car, and a car that
    turns at its waypoints; the goal is a pentagon up the north road."""
    north = tuple(Waypoint(0.1 * i, 1.75, -60.0 + 0.7 * i, math.pi / 2, 7.0) for i in range(0, 121, 10))
    turning = tuple(Waypoint(2.0 + 0.5 * i, -40.0 + 3.0 * i, -1.75 + 0.2 * i * i, 0.1 * i, 6.0 - 0.3 * i)
                    for i in range(8))
    return Scenario(
        name="crossing", path="crossing.xml", dt=0.1,
        road=(rectangle(-100.0, -3.5, 100.0, 3.5), rectangle(-3.5, -100.0, 3.5, 100.0)),
        obstacles=(
            Obstacle(21, 4.5, 1.9, north),
            Obstacle(22, 4.2, 1.8, (Waypoint(0.0, 30.0, 2.5, 0.1, 0.0),), static=True),
            Obstacle(23, 5.0, 2.1, turning),
        ),
        ego=EgoStart(-50.0, -1.75, 0.0, 8.0, 0.5),
        goal=Goal((Polygon(((-3.5, 60.0), (0.0, 55.0), (3.5, 60.0), (3.5, 80.0), (-3.5, 80.0))),), 4.0, 12.0),
    )


def goal_scenario() -> Scenario:
    """An L-shaped (non-convex) road, no obstacles, a rectangular goal at the corner."""
    road = Polygon(((0.0, 0.0), (60.0, 0.0), (60.0, 40.0), (53.0, 40.0), (53.0, 7.0), (0.0, 7.0)))
    return Scenario(
        name="goal", path="goal.xml", dt=0.1, road=(road,), obstacles=(),
        ego=EgoStart(5.0, 3.5, 0.0, 6.0),
        goal=Goal((rectangle(53.0, 20.0, 60.0, 30.0), rectangle(40.0, 0.0, 45.0, 7.0)), 2.0, 4.5),
    )


#: How a divider's two copies differ in :func:`divided_scenario`.
DIVIDERS = ("noise", "sampled")
#: DEU_Muc-3_1_T-1's lanelets 1172 and 1178 (left bound, right bound), opposite lanes by the ego's start
#: whose shared divider the file gives twice, sampled about 1 cm apart along it.
MUC_1172 = ([(-10.2455, 1.2657), (-0.40761, -1.4423), (9.6058, -4.1986), (19.6192, -6.9548), (29.6327, -9.7111),
             (39.6461, -12.4673), (49.6645, -15.2249)],
            [(-11.0451, -1.6233), (-1.2031, -4.3324), (8.8103, -7.0886), (18.8237, -9.8449), (28.8372, -12.6012),
             (38.8506, -15.3574), (48.8641, -18.1136)])
MUC_1178 = ([(49.6645, -15.2249), (39.656, -12.47), (29.6425, -9.7138), (19.6291, -6.9575), (9.6157, -4.2013),
             (-0.39775, -1.445), (-10.2455, 1.2657)],
            [(50.4649, -12.3361), (40.4515, -9.5799), (30.438, -6.8237), (20.4246, -4.0675), (10.4112, -1.3112),
             (0.39775, 1.445), (-9.4446, 4.1542)])


def divided_scenario(folder: Path, divider: str) -> Scenario:
    """Two lanelets, 1 and 2 on its left, sharing a divider that the map gives twice, built with
    commonroad-io as a CommonRoad file and loaded as rac loads one. ``noise``: 3.5 m lanes along x
    with the divider at y = 3.5, written 3.4999999999 in lanelet 1 and 3.5000000001 in lanelet 2 (float
    noise; commonroad-io writes 6 decimals, so the file's text is edited). ``sampled``: DEU_Muc-3_1_T-1's
    lanelets 1172 and 1178 (:data:`MUC_1172`), opposite lanes whose two copies of the divider are sampled
    about 1 cm apart along it, each point written to 4 decimals."""
    import re

    import numpy as np
    from commonroad.scenario.lanelet import Lanelet
    from commonroad.scenario.scenario import Tag

    from rac.model.commonroad import load_scenario
    from rac.model.scenario_xml import scenario_bytes
    from rac.model.scenes import build_highway

    scenario, problems = build_highway()
    for lanelet in list(scenario.lanelet_network.lanelets):
        scenario.remove_lanelet(lanelet)
    if divider == "noise":
        xs = np.linspace(0.0, 300.0, 7)[:, None]
        one = (np.hstack([xs, np.full_like(xs, 3.5)]), np.hstack([xs, np.zeros_like(xs)]))
        two = (np.hstack([xs, np.full_like(xs, 7.0)]), np.hstack([xs, np.full_like(xs, 3.5)]))
        same = True
    else:
        one, two = (tuple(np.array(bound) for bound in lanelet) for lanelet in (MUC_1172, MUC_1178))
        same = False
    scenario.add_objects([
        Lanelet(one[0], (one[0] + one[1]) / 2, one[1], 1, adjacent_left=2, adjacent_left_same_direction=same),
        Lanelet(two[0], (two[0] + two[1]) / 2, two[1], 2, adjacent_right=1 if same else None,
                adjacent_right_same_direction=True if same else None, adjacent_left=None if same else 1,
                adjacent_left_same_direction=None if same else False)])
    text = scenario_bytes(scenario, problems, tags={Tag.HIGHWAY}, source="divided").decode()
    if divider == "noise":  # y = 3.5 is lanelet 1's left bound and lanelet 2's right bound, nothing else
        first, second = text.index('<lanelet id="1">'), text.index('<lanelet id="2">')
        text = (text[:first] + text[first:second].replace("<y>3.5</y>", "<y>3.4999999999</y>")
                + text[second:].replace("<y>3.5</y>", "<y>3.5000000001</y>"))
        assert len(re.findall(r"<y>3\.4999999999</y>", text)) == len(re.findall(r"<y>3\.5000000001</y>", text)) == 7
    path = folder / f"divided-{divider}.xml"
    path.write_text(text, encoding="utf-8")
    return load_scenario(path)


def across_the_divider(scenario: Scenario, data: ModelData) -> list[State]:
    """Ego states at a thousand points along :func:`divided_scenario`'s divider whose corners all lie inside its
    road, at least 20 cm from its edges and ends; many have a corner close to the divider (changing
    lanes across it; the centre jitters across by up to 30 cm, differently at each step)."""
    start, end = scenario.lanes[0].left[0], scenario.lanes[0].left[-1]
    length = math.dist(start, end)
    width = math.dist(start, scenario.lanes[0].right[0])  # of each lane
    ux, uy = (end[0] - start[0]) / length, (end[1] - start[1]) / length
    heading = math.atan2(uy, ux)
    model = NativeModel(data)
    states = []
    for step in range(1, 1000):
        jitter = ((step * 0.618034) % 1 - 0.5) * 0.6
        for offset in (-1.4, -0.9, 0.0, 0.9, 1.4):  # the ego's centre across the divider (m, left +)
            for turn in (-0.1, 0.0, 0.1):
                across = offset + jitter
                x = start[0] + length * step / 1000 * ux - across * uy
                y = start[1] + length * step / 1000 * uy + across * ux
                state = State(int(x * data.scale), int(y * data.scale), 10 * data.scale, 0,
                              int((heading + turn) * data.scale), 0, 0)
                corners = [((cx - start[0]) * ux + (cy - start[1]) * uy, (cy - start[1]) * ux - (cx - start[0]) * uy)
                           for cx, cy in model.corner_points(state)]
                if all(0.2 < a < length - 0.2 and abs(b) < width - 0.2 for a, b in corners):
                    states.append(state)
    return states


@pytest.mark.parametrize("divider", DIVIDERS)
def test_a_divider_given_twice_is_no_gap_in_the_road(tmp_path: Path, divider: str) -> None:
    """DEU_Muc-3_1_T-1 gives each lane divider twice, once per lanelet, sampled 5 mm apart along it and
    rounded to 4 decimals; truncated to significands the two copies parted, and at exponent 2 the road
    had nine hairline gaps along its dividers (up to 1 cm wide, 13 to 27 m long, one at the ego's start):
    a lane change with a corner in one was off the road. Float noise (3.4999999999 for 3.5) truncates
    apart as well. The model's road now carries both copies' vertices along the divider, one value each."""
    from rac.model.batch import BatchModel

    scenario = divided_scenario(tmp_path, divider)
    for exponent in (1, 2, 3):  # the old road failed at each (at 2: 198 and 22 states off it)
        data = build_model_data(scenario, make_spec(exponent))
        states = across_the_divider(scenario, data)
        assert len(states) > 500
        native = NativeModel(data)
        off = [state for state in states if native.offroad(state)]
        assert not off, f"exponent {exponent}: {len(off)} of {len(states)} states inside the road are off it"
        assert not BatchModel(data).offroad(np.array(states, dtype=np.int64)).any()


# ---------------------------------------------------------------- data
def test_significands_truncate_decimals_exactly():
    data = build_model_data(straight_scenario(), make_spec(2))
    assert data.scale == 100
    assert data.ego_x == 1000 and data.ego_y == -175 and data.ego_v == 1000
    assert data.length == 450 and data.width == 180 and data.td == 50
    jerk = data.action("jerk")
    assert (jerk.low, jerk.high, jerk.step, jerk.count) == (-200, 200, 50, 9)
    assert data.action("turn").values == (-40, -30, -20, -10, 0, 10, 20, 30, 40)
    # 0.57 * 100 is 56.99999999999999 in floating point; the decimal 0.57 is 57 hundredths
    odd = replace(straight_scenario(), ego=EgoStart(0.57, -0.57, 0.0, 0.0))
    data = build_model_data(odd, make_spec(2))
    assert (data.ego_x, data.ego_y) == (57, -57)
    assert build_model_data(odd, make_spec(1)).ego_y == -5  # toward zero


def test_times_in_sense_periods():
    data = build_model_data(straight_scenario(), make_spec())
    assert data.wp_time[:3] == (10, 15, 20)
    assert (data.obs_from, data.obs_until) == ((10,), (60,))
    assert (data.goal_low, data.goal_high) == (50, 80)
    assert (data.decide_every, data.substeps, data.unit, data.period) == (5, 10, 0.01, 0.1)
    crossing = build_model_data(crossing_scenario(), make_spec())
    assert crossing.obs_from[1] == 0 and crossing.obs_until[1] == 2**31 - 1  # the parked car
    assert crossing.wp_vel[crossing.wp_start[1]] == 0


def test_times_count_from_the_ego_start():
    late = replace(straight_scenario(), ego=EgoStart(10.0, -1.75, 0.0, 10.0, time=2.0))
    data = build_model_data(late, make_spec())
    assert data.wp_time[:3] == (-10, -5, 0) and (data.obs_from, data.obs_until) == ((-10,), (40,))
    assert (data.goal_low, data.goal_high) == (30, 60)
    model = NativeModel(data)
    assert model.obstacle_position(0, 0) == NativeModel(build_model_data(straight_scenario(), make_spec())) \
        .obstacle_position(0, 20)


def test_polygons_are_flattened():
    data = build_model_data(goal_scenario(), make_spec(1))
    assert data.road_start == (0, 6) and data.road_x[:3] == (0, 600, 600)
    assert data.goal_start == (0, 4, 8) and data.goal_count == 2
    assert (data.goal_cx, data.goal_cy) == (565, 250)
    assert data.obstacle_count == 0 and data.wp_start == (0,)


def test_overflow_names_the_value():
    far = replace(straight_scenario(), ego=EgoStart(3000.0, 0.0, 0.0, 0.0))
    assert check_significands(far, make_spec(5)) is None
    with pytest.raises(ModelRangeError) as error:
        build_model_data(far, make_spec(6))
    assert error.value.what == "ego start x" and error.value.significand == 3_000_000_000
    assert "ego start x = 3000.0" in str(error.value) and "int32" in str(error.value)
    found = check_significands(far, make_spec(6))
    assert found is not None and found.what == "ego start x"
    assert max_significand(far, make_spec(6)) == ("ego start x", 3_000_000_000)
    assert max_significand(straight_scenario(), make_spec(3)) == ("road polygon 0 vertex 1 x", 200_000)
    nan = replace(straight_scenario(), ego=EgoStart(math.nan, 0.0, 0.0, 0.0))
    assert check_significands(nan, make_spec()).significand is None


# ---------------------------------------------------------------- sense
def test_sense_with_zero_actions_drives_straight():
    model = NativeModel(build_model_data(straight_scenario(), make_spec(3)))
    start = model.initial_state()
    after = model.sense(start)
    # 10 m/s for 0.1 s along x: ten sub-steps of 0.1 m sum to 10.999999999999996 in doubles, and
    # Eq. (1) truncates toward zero, so the sensed x is 10.999, not 11.000 (docs/model.md)
    assert after == State(10999, -1750, 10000, 0, 0, 0, 0)
    heading = math.atan2(3.0, 4.0)
    diagonal = State(0, 0, 5000, 0, int(heading * 1000), 0, 0)
    after = model.sense(diagonal)
    h = diagonal.head / 1000
    assert after.x == int(0.5 * math.cos(h) * 1000) and after.y == int(0.5 * math.sin(h) * 1000)
    assert after.v == 5000 and after.head == diagonal.head


def test_sense_integrates_jerk_and_turn():
    model = NativeModel(build_model_data(straight_scenario(), make_spec(4, granularity=F(1, 100))))
    after = model.sense(State(0, 0, 100000, 0, 0, 20000, 4000))  # jerk 2, turn 0.4 for 0.1 s
    assert after.acc == 2000  # 2 * 0.1
    assert after.head == 399  # 0.4 * 0.1 summed in 100 sub-steps is just below 0.04, truncated
    # v = 10 + jerk t^2 / 2 = 10.01; x ~ 1.0; y ~ 10 * 0.4 t^2 / 2 = 0.02 (Euler: slightly more)
    assert 100095 <= after.v <= 100105 and 9995 <= after.x <= 10005 and 195 <= after.y <= 205
    assert (after.jerk, after.turn) == (20000, 4000)


def test_sense_clamps_acceleration_and_speed():
    model = NativeModel(build_model_data(straight_scenario(), make_spec(3)))
    assert model.sense(State(0, 0, 10000, 2990, 0, 2000, 0)).acc == 3000
    assert model.sense(State(0, 0, 10000, -2990, 0, -2000, 0)).acc == -3000
    top = model.sense(State(0, 0, 19990, 3000, 0, 0, 0))
    assert top.v == 20000
    stop = model.sense(State(0, 0, 10, -3000, 0, 0, 0))
    assert stop.v == 0 and stop.x == 0  # min speed 0: it stops, it does not reverse


def test_sense_overflow_raises():
    model = NativeModel(build_model_data(straight_scenario(), make_spec(6)))
    with pytest.raises(ModelRangeError, match="sense"):
        model.sense(State(2147000000, 0, 20000000, 0, 0, 0, 0))


# ---------------------------------------------------------------- obstacles and distances
def test_obstacle_positions_follow_waypoints():
    model = NativeModel(build_model_data(straight_scenario(), make_spec(3)))
    assert model.obstacle_position(0, 9) is None and model.obstacle_position(0, 61) is None
    assert model.obstacle_position(0, 10) == (30.0, 1.75, 0.0)
    x, y, h = model.obstacle_position(0, 13)  # 0.3 s at 8 m/s after the first waypoint
    assert x == pytest.approx(32.4) and y == 1.75 and h == 0.0
    assert model.obstacle_position(0, 15)[0] == 34.0  # the next waypoint (t = 1.5 s)
    crossing = NativeModel(build_model_data(crossing_scenario(), make_spec(3)))
    assert crossing.obstacle_position(1, 0) == crossing.obstacle_position(1, 10**6) == (30.0, 2.5, 0.1)
    x, y, h = crossing.obstacle_position(0, 25)  # north at 7 m/s since t = 2.0 s (y = -46)
    assert h == 1.570 and x == pytest.approx(1.75 + 7 * math.cos(1.57) * 0.5) and y == pytest.approx(-42.5, abs=1e-3)


def test_mindist_straight_ahead():
    scenario = straight_scenario()
    model = NativeModel(build_model_data(scenario, make_spec(3)))
    # the obstacle is at (30, 1.75) at sample 10; put the ego 20 m behind it on the same line
    ego = State(10000, 1750, 10000, 0, 0, 0, 0)
    ego_radius = math.sqrt((4.5 / 6) ** 2 + 0.9**2)
    obstacle_radius = math.sqrt((4.8 / 6) ** 2 + 1.0**2)
    gap = (30.0 - 4.8 / 3) - (10.0 + 4.5 / 3)  # front disc of the ego to the rear disc of the obstacle
    assert model.mindist(ego, 10) == pytest.approx(gap - ego_radius - obstacle_radius)
    assert not model.collide(ego, 10)
    assert model.mindist(ego, 5) == NO_OBSTACLE  # the obstacle does not exist yet
    touching = ego._replace(x=int((30.0 - 4.8 / 3 - 4.5 / 3 - ego_radius - obstacle_radius) * 1000) - 300)
    assert 0 < model.mindist(touching, 10) < 0.5 and model.collide(touching, 10)
    assert model.mindist(ego._replace(x=30000), 10) < 0  # overlapping
    empty = NativeModel(build_model_data(goal_scenario(), make_spec(3)))
    assert empty.mindist(ego, 10) == NO_OBSTACLE and not empty.collide(ego, 10)


def test_offroad():
    model = NativeModel(build_model_data(straight_scenario(), make_spec(3)))
    on = State(50000, -1750, 10000, 0, 0, 0, 0)
    assert not model.offroad(on)
    assert not model.offroad(on._replace(y=0))  # across the shared edge of the two lanes
    assert model.offroad(on._replace(y=-3000))  # right corners below y = -3.5
    assert model.offroad(on._replace(x=-1000))  # rear corners behind x = 0
    assert model.offroad(on._replace(head=1571))  # across: 4.5 m long from y = -1.75 reaches below -3.5
    assert model.offroad(on._replace(x=250000))
    road = NativeModel(build_model_data(goal_scenario(), make_spec(3)))
    assert not road.offroad(State(56500, 30000, 0, 0, 1571, 0, 0))  # up the vertical arm
    assert road.offroad(State(40000, 20000, 0, 0, 0, 0, 0))  # in the notch of the L


def test_goal_and_dist_goal():
    model = NativeModel(build_model_data(goal_scenario(), make_spec(2)))
    inside = State(5650, 2500, 500, 0, 157, 0, 0)
    assert model.goal(inside, 20) and model.goal(inside, 45)
    assert not model.goal(inside, 19) and not model.goal(inside, 46)
    assert model.goal(State(4250, 350, 0, 0, 0, 0, 0), 30)  # the second region
    assert not model.goal(State(5000, 350, 0, 0, 0, 0, 0), 30)
    assert model.dist_goal(inside) == 0.0
    assert model.dist_goal(State(5650, -1500, 0, 0, 0, 0, 0)) == 40.0
    assert model.dist_goal(State(5650 + 300, 2500 + 400, 0, 0, 0, 0, 0)) == 5.0


def test_one_pass_builds_the_data_and_finds_the_largest_significand():
    """`rac check` builds the model's data once (issue 22: twice doubled a large scenario's check)."""
    from rac.model.data import build_model_data_and_largest

    for scenario, spec in ((straight_scenario(), make_spec(3)),
                           (replace(straight_scenario(), ego=EgoStart(3000.0, 0.0, 0.0, 0.0)), make_spec(5))):
        data, largest = build_model_data_and_largest(scenario, spec)
        assert data == build_model_data(scenario, spec)
        assert largest == max_significand(scenario, spec)
