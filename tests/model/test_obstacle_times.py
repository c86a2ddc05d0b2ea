"""Dynamic obstacles on the sample grid (docs/model.md, *Times* and *Dynamic obstacles*).

``build_model_data`` resamples each dynamic obstacle's trajectory at the sample times
``t0 + k*C1``. As a result, the model's projection from a waypoint is exact even when the
CommonRoad time step ``dt`` is shorter than ``C1``. Waypoint times used to be rounded to
samples, which left an obstacle up to ``v*C1/2`` off, even at the start.

Positions are compared bit for bit: ``float.hex`` tells ``-0.0`` from ``0.0``, which ``==`` does not.
"""

from __future__ import annotations

import math
from dataclasses import replace
from fractions import Fraction as F
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from test_model_native import make_spec, rectangle
from tiny_scenarios import Block, GoalBox, StraightRoad, straight_road

from rac.model import NativeModel, build_model_data
from rac.model.commonroad import EgoStart, Goal, Obstacle, Scenario, Waypoint
from rac.model.data import exact

#: The CommonRoad time step of the hand-built trajectories (s).
DT = 0.1


def bits(position: tuple[float, ...] | None) -> tuple[str, ...] | None:
    """A position as the hex of its doubles, so that equality is bit for bit."""
    return None if position is None else tuple(float.hex(value) for value in position)


def road_with(obstacle: Obstacle, ego_time: float = 0.0) -> Scenario:
    """A straight two-lane road along x carrying ``obstacle``; the ego starts at ``ego_time``."""
    return Scenario(
        name="times", path="times.xml", dt=DT,
        road=(rectangle(-50.0, -3.5, 250.0, 0.0), rectangle(-50.0, 0.0, 250.0, 3.5)),
        obstacles=(obstacle,), ego=EgoStart(0.0, -1.75, 0.0, 5.0, time=ego_time),
        goal=Goal((rectangle(150.0, -3.5, 170.0, 0.0),), 5.0, 8.0),
    )


def spec(c1: F, exponent: int = 3):
    """:func:`make_spec` with the sense (and decision) period ``c1``."""
    return make_spec(exponent, sense=c1, decide=c1)


def trajectory(steps: int, first_step: int = 0) -> tuple[Waypoint, ...]:
    """A car that speeds up, then slows down, while it weaves: its velocity and heading change at
    every CommonRoad time step. It moves in a straight line between states, as
    :class:`rac.model.commonroad.Waypoint` defines. Times are ``round(step*dt, 9)`` and coordinates have 6
    decimals, as load_scenario reads them from a file."""
    points = []
    x, y = 20.0, 1.75
    for i in range(steps + 1):
        velocity = round(6.0 + 2.5 * math.sin(i / 9), 6)
        heading = round(0.3 * math.sin(i / 6), 6)
        points.append(Waypoint(round((first_step + i) * DT, 9), x, y, heading, velocity))
        x = round(x + velocity * math.cos(heading) * DT, 6)
        y = round(y + velocity * math.sin(heading) * DT, 6)
    return tuple(points)


def state_at(waypoints: tuple[Waypoint, ...], time: F, scale: int) -> tuple[str, str, str]:
    """The obstacle's exact state at ``time``, in the model's doubles: the last waypoint at or before
    ``time``, moved straight on, exactly but for the double cos and sin, then truncated to
    significands and divided by the scale, as ``obstacle_position`` does at a waypoint."""
    point = [w for w in waypoints if exact(round(w.time, 9)) <= time][-1]
    elapsed = time - exact(point.time)
    speed, heading = exact(point.velocity), point.heading
    x = exact(point.x) + speed * F(math.cos(heading)) * elapsed
    y = exact(point.y) + speed * F(math.sin(heading)) * elapsed
    return bits(tuple(math.trunc(value * scale) / float(scale) for value in (x, y, exact(heading))))


# ---------------------------------------------------------------- the reported example
def test_car_at_30_going_4_is_at_30_then_32():
    """The bug report: x = 30 at 4 m/s, dt = 0.1 s, C1 = 0.5 s. The model used to put the car at
    30.8 and 32.8, because waypoint times were rounded to samples (ties to even) and then projected."""
    car = Obstacle(5, 4.5, 1.8, tuple(Waypoint(round(i * DT, 9), round(30.0 + 4.0 * i * DT, 6), 1.75, 0.0, 4.0)
                                      for i in range(31)))
    data = build_model_data(road_with(car), spec(F(1, 2)))
    model = NativeModel(data)
    assert bits(model.obstacle_position(0, 0)) == bits((30.0, 1.75, 0.0))
    assert bits(model.obstacle_position(0, 1)) == bits((32.0, 1.75, 0.0))
    assert [model.obstacle_position(0, k)[0] for k in range(7)] == [30.0, 32.0, 34.0, 36.0, 38.0, 40.0, 42.0]
    # one waypoint per sample, every fifth CommonRoad state, each exactly on its sample
    assert data.wp_time == (0, 1, 2, 3, 4, 5, 6) and (data.obs_from, data.obs_until) == ((0,), (6,))
    assert data.wp_x == (30000, 32000, 34000, 36000, 38000, 40000, 42000)


def test_car_at_30_going_4_from_a_commonroad_file(tmp_path: Path):
    """The same through a CommonRoad file written by commonroad-io and read by load_scenario; the
    tiny scenarios have exactly these times (dt = 0.1 s, C1 = 0.5 s)."""
    road = StraightRoad(100.0, EgoStart(5.0, 1.75, 0.0, 4.0), GoalBox(60.0, 70.0), lanes=2,
                        obstacles=(Block(11, 30.0, 5.25, velocity=4.0),))
    tiny = straight_road("car_at_30", road)
    assert tiny.settings.sense_period == F(1, 2)
    model = NativeModel(tiny.model_data(tmp_path))
    assert bits(model.obstacle_position(0, 0)) == bits((30.0, 5.25, 0.0))
    assert bits(model.obstacle_position(0, 1)) == bits((32.0, 5.25, 0.0))
    assert model.obstacle_position(0, 8)[0] == 46.0 and model.obstacle_position(0, 9) is None  # gone after 4 s


# ---------------------------------------------------------------- changing speed and heading
@pytest.mark.parametrize("c1", [F(1, 10), F(1, 5), F(1, 2), F(1, 4), F(3, 10), F(7, 10)])
@pytest.mark.parametrize("ego_time", [0.0, 0.3, 1.2])
def test_resampled_states_match_the_trajectory(c1: F, ego_time: float):
    """At every sample, obstacle_position is the trajectory's state at ``t0 + k*C1``, bit for bit:
    it is the state at that time when ``C1`` is a multiple of ``dt``, and the state before it moved on
    when ``C1`` is not (``C1 = 0.25`` s or ``0.7`` s). An ego that starts late puts the obstacle's first
    samples before 0."""
    waypoints = trajectory(40)
    data = build_model_data(road_with(Obstacle(7, 4.5, 1.8, waypoints), ego_time), spec(c1))
    model = NativeModel(data)
    t0, last = exact(ego_time), exact(waypoints[-1].time)
    samples = [k for k in range(-40, 60) if 0 <= t0 + k * c1 <= last]
    assert (data.obs_from, data.obs_until) == ((samples[0],), (samples[-1],))
    assert data.wp_time == tuple(samples)  # C1 >= dt: a new state comes into force at every sample
    for k in samples:
        assert bits(model.obstacle_position(0, k)) == state_at(waypoints, t0 + k * c1, data.scale), k
    assert model.obstacle_position(0, samples[0] - 1) is None and model.obstacle_position(0, samples[-1] + 1) is None


@pytest.mark.parametrize("c1", [F(1, 20), F(1, 30), F(3, 40)])
def test_sense_period_shorter_than_the_time_step(c1: F):
    """With ``C1 < dt`` each state gets one waypoint, at the first sample at or after it, moved on
    to that sample. The exception is a last state that lies after the lifetime's last sample
    (2.0 s is sample 26.7 at ``C1 = 0.075`` s). The samples between are the model's projection
    from the waypoint: the trajectory's state, up to the truncation of the waypoint's significands."""
    waypoints = trajectory(20)
    data = build_model_data(road_with(Obstacle(7, 4.5, 1.8, waypoints)), spec(c1))
    model = NativeModel(data)
    assert data.obs_until[0] == math.floor(2 / c1)
    assert data.wp_time == tuple(k for k in (math.ceil(exact(w.time) / c1) for w in waypoints)
                                 if k <= data.obs_until[0])
    for k in range(data.obs_from[0], data.obs_until[0] + 1):
        expected = [float.fromhex(h) for h in state_at(waypoints, k * c1, data.scale)]
        if k in data.wp_time:
            assert model.obstacle_position(0, k) == tuple(expected)
        else:
            assert model.obstacle_position(0, k) == pytest.approx(expected, abs=3 / data.scale)


def test_lifetime_is_the_samples_within_the_trajectory():
    """The obstacle exists at the samples within its first and last state's times, as in
    CommonRoad. Rounding would have kept it one sample past its last state at 2.3 s."""
    data = build_model_data(road_with(Obstacle(7, 4.5, 1.8, trajectory(23))), spec(F(1, 2)))
    assert (data.obs_from, data.obs_until) == ((0,), (4,))  # 0 .. 2.0 s; 2.5 s is past 2.3 s
    late = build_model_data(road_with(Obstacle(7, 4.5, 1.8, trajectory(20, first_step=3))), spec(F(1, 2)))
    assert (late.obs_from, late.obs_until) == ((1,), (4,))  # 0.3 .. 2.3 s
    assert late.wp_time == (1, 2, 3, 4)


def test_an_obstacle_between_two_samples_is_never_present():
    """An obstacle that lives from 1.1 s to 1.3 s, with samples at 1.0 s and 1.5 s: absent at every
    sample, with one (unused) waypoint so that the arrays keep their shape."""
    data = build_model_data(road_with(Obstacle(7, 4.5, 1.8, trajectory(2, first_step=11))), spec(F(1, 2)))
    assert (data.obs_from, data.obs_until) == ((3,), (2,)) and data.wp_start == (0, 1)
    model = NativeModel(data)
    assert all(model.obstacle_position(0, k) is None for k in range(10))


def test_float_noise_in_times_is_ignored():
    """Hand-built times such as ``0.1 * 3 = 0.30000000000000004`` are read to the nanosecond, so such
    a waypoint lies on sample 3 rather than being moved on to sample 4."""
    noisy = tuple(replace(w, time=0.1 * i) for i, w in enumerate(trajectory(30)))
    assert noisy[3].time != 0.3
    data = build_model_data(road_with(Obstacle(7, 4.5, 1.8, noisy)), spec(F(1, 10)))
    assert data.wp_time == tuple(range(31))
    assert data.wp_x == tuple(math.trunc(exact(w.x) * 1000) for w in noisy)


def test_waypoint_times_must_not_decrease():
    backwards = trajectory(3)[::-1]
    with pytest.raises(ValueError, match="must not decrease"):
        build_model_data(road_with(Obstacle(7, 4.5, 1.8, backwards)), spec(F(1, 2)))


# ---------------------------------------------------------------- property: C1 a multiple of dt
@st.composite
def sampled_obstacles(draw):
    """A random trajectory with a state every ``dt``, on a grid of ``C1 = m*dt``. The ego and the
    obstacle start on the ``dt`` grid, so that every sample in the obstacle's lifetime is a state's
    time."""
    dt = draw(st.sampled_from([0.1, 0.05, 0.2, 0.04, 0.25, 0.02]))
    m = draw(st.integers(1, 7))
    ego_step = draw(st.integers(0, 12))
    first_step = draw(st.integers(0, 12))
    count = draw(st.integers(1, 30))
    coordinate = st.decimals(-500, 500, places=4).map(float)
    waypoints = tuple(
        Waypoint(round((first_step + i) * dt, 9), draw(coordinate), draw(coordinate),
                 float(draw(st.decimals(-7, 7, places=5))), float(draw(st.decimals(0, 40, places=3))))
        for i in range(count))
    return dt, m, ego_step, waypoints, draw(st.integers(1, 4))


@settings(max_examples=200, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(sampled_obstacles())
def test_multiples_of_the_time_step_hit_the_states(case):
    """For every ``C1 = m*dt``, the obstacle is present exactly at the samples within its lifetime.
    Each of those samples has a waypoint, and obstacle_position there is that time's CommonRoad
    state in significands, bit for bit."""
    dt, m, ego_step, waypoints, exponent = case
    c1 = m * exact(dt)
    ego_time = round(ego_step * dt, 9)
    data = build_model_data(replace(road_with(Obstacle(7, 4.5, 1.8, waypoints), ego_time), dt=dt),
                            spec(c1, exponent))
    model = NativeModel(data)
    t0 = exact(ego_time)
    states = {exact(w.time): w for w in waypoints}
    first, last = exact(waypoints[0].time), exact(waypoints[-1].time)
    present = [k for k in range(-200, 200) if first <= t0 + k * c1 <= last]
    if not present:  # shorter than C1, between two samples
        assert data.obs_from[0] == data.obs_until[0] + 1 and len(data.wp_time) == 1
        return
    assert (data.obs_from[0], data.obs_until[0]) == (present[0], present[-1])
    assert data.wp_time == tuple(present)
    for k in (present[0] - 1, present[-1] + 1):
        assert model.obstacle_position(0, k) is None
    scale = float(data.scale)
    for k in present:
        state = states[t0 + k * c1]
        expected = tuple(math.trunc(exact(value) * data.scale) / scale for value in (state.x, state.y, state.heading))
        assert bits(model.obstacle_position(0, k)) == bits(expected), k
