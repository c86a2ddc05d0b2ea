"""What a learner observes of an episode of the scenario model: one owner for the observation's
meaning, shared by :class:`rac.learning.scenario_env.ScenarioEnv` and the vector environment
(:mod:`rac.learning.vector`), so the two cannot drift apart.

An :class:`Observation` reads a whole :class:`rac.learning.episodes.EpisodeBatch` at once (one row
per episode, float32) and has one :class:`gymnasium.spaces.Box` for one episode, with finite bounds
that do not depend on the scene (a policy trained on a set of scenes sees one space).

Kinds (:data:`KINDS`, :func:`make_observation`):

- ``"relative"`` (:class:`RelativeObservation`, ScenarioEnv's default): the ego relative to its
  lane, the road's edges and the goal, and the :data:`NEAREST` nearest obstacles relative to the
  ego — nothing in the scene's own coordinates, so a policy can carry over to other scenes.
- ``"ego"``: the sensed ``x, y, v, acc, head, jerk, turn`` (metres, seconds, radians:
  significand / scale) and the time in seconds — the scene's own coordinates; a policy can only
  memorise one scene with it.

The ``"relative"`` columns (SI units; each value clipped to its bounds, constants of this module,
so the space is the same for every scene). "Ahead" and "left" are the ego's frame: along its
heading and 90° counter-clockwise from it.

=====  ==============  ==================  =========================================================
col    name            bounds              meaning
=====  ==============  ==================  =========================================================
0      ``v``           ±60 m/s             the ego's sensed speed
1      ``acc``         ±20 m/s²            the ego's sensed acceleration
2      ``lane_head``   ±π rad              the ego's heading minus its lane's direction (wrapped)
3      ``lane_offset`` ±20 m               the ego's centre left (+) or right (−) of its lane's
                                           centre line
4      ``edge_left``   0 .. 50 m           from the ego's centre along the lane's left normal to the
                                           first crossing of the road's edge (50: none within 50 m)
5      ``edge_right``  0 .. 50 m           the same to the right (a hairline gap between
                                           lanelets is road, not its edge: :func:`_road_edges`)
6      ``goal_ahead``  ±500 m              the goal's centre (``goal_cx, goal_cy``) ahead of the ego
                                           (0 for a goal of time alone, ``goal_anywhere``)
7      ``goal_left``   ±500 m              ... and left of it
8      ``time_left``   0 .. 3600 s         the time to the episode's horizon
9+5j   ``present``     0 .. 1              1: obstacle slot ``j`` holds an obstacle (the ``j``-th
                                           nearest, centre to centre, that exists at the sample and
                                           lies within :data:`SENSING_RANGE` = 100 m); 0: the slot's
                                           five columns are all 0
10+5j  ``ahead``       ±100 m              its centre ahead of the ego's centre
11+5j  ``left``        ±100 m              ... and left of it
12+5j  ``v_ahead``     ±100 m/s            its velocity minus the ego's, ahead
13+5j  ``v_left``      ±100 m/s            ... and left
=====  ==============  ==================  =========================================================

The ego's lane is the lanelet centre-line segment (:attr:`rac.model.commonroad.Scenario.lanes`,
in the driving direction) that minimises the distance from the ego's centre plus
:data:`HEADING_WEIGHT` metres per radian of heading difference: on a multi-lane road the lane the
ego is in, at an intersection the overlapping lanelet it drives along. The obstacles' positions and
speeds at the sample are the model's (:meth:`rac.model.batch.BatchModel.obstacle_states`).
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any, Protocol

import gymnasium
import numpy as np

from rac.core.diagnostics import RacValueError
from rac.core.numbers import INT32_MAX
from rac.model.batch import batch_model
from rac.model.sample import POSITION, Ego

if TYPE_CHECKING:
    from rac.learning.episodes import EpisodeBatch

__all__ = ["HEADING_WEIGHT", "KINDS", "NEAREST", "RELATIVE_COLUMNS", "SENSING_RANGE", "EgoObservation",
           "Observation", "RelativeObservation", "make_observation"]

#: How many obstacles the ``"relative"`` observation holds (the nearest ones).
NEAREST = 4
#: m: obstacles farther from the ego's centre are not observed.
SENSING_RANGE = 100.0
#: m per radian: the lane is the centre-line segment nearest the ego with this weight on the heading difference.
HEADING_WEIGHT = 2.0
#: m: the farthest a road edge is looked for.
EDGE_RANGE = 50.0
#: m: gaps between lanelets narrower than twice this (or than two significands) are road, not its edge.
GAP = 1e-3
#: The ego's columns of ``"relative"``: name, low, high (see the module docstring's table).
EGO_COLUMNS: tuple[tuple[str, float, float], ...] = (
    ("v", -60.0, 60.0), ("acc", -20.0, 20.0), ("lane_head", -np.pi, np.pi), ("lane_offset", -20.0, 20.0),
    ("edge_left", 0.0, EDGE_RANGE), ("edge_right", 0.0, EDGE_RANGE), ("goal_ahead", -500.0, 500.0),
    ("goal_left", -500.0, 500.0), ("time_left", 0.0, 3600.0))
#: One obstacle slot's columns of ``"relative"``: name, low, high.
OBSTACLE_COLUMNS: tuple[tuple[str, float, float], ...] = (
    ("present", 0.0, 1.0), ("ahead", -SENSING_RANGE, SENSING_RANGE), ("left", -SENSING_RANGE, SENSING_RANGE),
    ("v_ahead", -100.0, 100.0), ("v_left", -100.0, 100.0))


def relative_columns(nearest: int = NEAREST) -> tuple[tuple[str, float, float], ...]:
    """Every column of ``"relative"`` with ``nearest`` obstacle slots: name (``obstacle{j}_{name}``
    for slot ``j``), low, high."""
    return EGO_COLUMNS + tuple((f"obstacle{j}_{name}", low, high) for j in range(nearest)
                               for name, low, high in OBSTACLE_COLUMNS)


#: The columns of ``"relative"`` with the default :data:`NEAREST` slots.
RELATIVE_COLUMNS = relative_columns()


class Observation(Protocol):
    """An observation of every episode of a batch."""

    #: The kind's name (one of :data:`KINDS`).
    kind: str
    #: The space of one episode's observation (float32, finite bounds).
    space: gymnasium.spaces.Box

    def observe(self, episodes: EpisodeBatch) -> np.ndarray:
        """``(episodes.n, dim)`` float32: each episode's observation now (after ``reset`` or ``step``)."""
        ...


class EgoObservation:
    """``"ego"``: the sensed ego state and the time (8 values; see the module docstring)."""

    kind = "ego"

    def __init__(self, episodes: EpisodeBatch) -> None:
        data = episodes.data
        self._scale = float(data.scale)
        self._period = float(data.period)
        bound = np.float32(INT32_MAX / self._scale)  # every sensed value is an int32 significand
        end = np.float32(episodes.horizon_samples * self._period)
        self.space = gymnasium.spaces.Box(
            low=np.array([-bound] * 7 + [0.0], dtype=np.float32),
            high=np.array([bound] * 7 + [end], dtype=np.float32), dtype=np.float32)

    def observe(self, episodes: EpisodeBatch) -> np.ndarray:
        out = np.empty((episodes.n, 8), dtype=np.float32)
        out[:, :7] = episodes.ego / self._scale
        out[:, 7] = episodes.k * self._period
        return out


def _road_edges(episodes: EpisodeBatch) -> tuple[np.ndarray, np.ndarray]:
    """The road's boundary (the union of its polygons, ModelData's) as segments: starts, ends ``(E, 2)``.

    Real maps leave hairline gaps between neighbouring lanelets (DEU_Muc-3_1_T-1 has 20 holes about 3e-5 m
    wide along its lane dividers), and truncating the vertices to significands makes gaps up to one
    significand wide. A gap's sides are no edge of the road: when closing the union (grown, then shrunk,
    by :data:`GAP` or one significand, the larger) fills holes or joins parts, its boundary is the road's;
    otherwise the exact union's is (a road without gaps keeps its boundary bit for bit)."""
    import shapely  # shapely: only when this runs; importing rac.learning.observation stays light

    data = episodes.data
    scale = float(data.scale)
    polygons = []
    for p in range(data.road_count):
        low, high = data.road_start[p], data.road_start[p + 1]
        points = np.column_stack([data.road_x[low:high], data.road_y[low:high]]) / scale
        polygons.append(shapely.Polygon(points).buffer(0))
    road = shapely.union_all(polygons)
    width = max(GAP, 1.0 / scale)
    closed = road.buffer(width).buffer(-width)
    if _holes_and_parts(closed) != _holes_and_parts(road):
        road = closed
    boundary = road.boundary
    starts, ends = [], []
    for line in getattr(boundary, "geoms", [boundary]):
        coords = np.asarray(line.coords)
        starts.append(coords[:-1])
        ends.append(coords[1:])
    if not starts:
        return np.zeros((0, 2)), np.zeros((0, 2))
    return np.concatenate(starts), np.concatenate(ends)


def _holes_and_parts(area: Any) -> tuple[int, int]:
    """A (multi)polygon's holes and parts: closing it changes them only where it fills a gap."""
    parts = list(getattr(area, "geoms", [area]))
    return sum(len(part.interiors) for part in parts), len(parts)


def _ray_hits(origin: np.ndarray, direction: np.ndarray, starts: np.ndarray, ends: np.ndarray) -> np.ndarray:
    """``(n,)``: the distance from each origin along its unit direction to the nearest segment it
    crosses, :data:`EDGE_RANGE` where none lies within it. Origins and directions ``(n, 2)``."""
    if starts.shape[0] == 0:
        return np.full(origin.shape[0], EDGE_RANGE)
    seg = (ends - starts)[None]  # (1, E, 2)
    rel = starts[None] - origin[:, None]  # (n, E, 2)
    dx, dy = direction[:, None, 0], direction[:, None, 1]
    denom = dx * seg[..., 1] - dy * seg[..., 0]
    with np.errstate(divide="ignore", invalid="ignore"):
        t = (rel[..., 0] * seg[..., 1] - rel[..., 1] * seg[..., 0]) / denom  # along the ray
        u = (rel[..., 0] * dy - rel[..., 1] * dx) / denom  # along the segment
    hit = (denom != 0) & (t >= 0) & (u >= 0) & (u <= 1)
    return np.minimum(np.where(hit, t, np.inf).min(axis=1), EDGE_RANGE)


def _wrap(angle: np.ndarray) -> np.ndarray:
    return (angle + np.pi) % (2 * np.pi) - np.pi


class RelativeObservation:
    """``"relative"``: the ego relative to its lane, the road and the goal, and the ``nearest``
    obstacles relative to the ego (``9 + 5 * nearest`` values; the module docstring's table)."""

    kind = "relative"

    def __init__(self, episodes: EpisodeBatch, nearest: int = NEAREST) -> None:
        data = episodes.data
        scenario = episodes.result.scenario
        if scenario is None or not scenario.lanes:
            raise RacValueError("the relative observation needs the scenario's lanes (a checked `model` block)")
        self.nearest = nearest
        self._scale = float(data.scale)
        self._period = float(data.period)
        self._horizon = episodes.horizon_samples
        self._model = batch_model(data)
        self._goal = np.array([data.goal_cx, data.goal_cy]) / self._scale
        self._anywhere = data.goal_anywhere
        starts, ends, half = [], [], []
        for lane in scenario.lanes:
            centre = np.asarray(lane.centre, dtype=np.float64)
            width = np.hypot(*(np.asarray(lane.left) - np.asarray(lane.right)).T)
            starts.append(centre[:-1])
            ends.append(centre[1:])
            half.append((width[:-1] + width[1:]) / 4)
        self._lane_start = np.concatenate(starts)
        step = np.concatenate(ends) - self._lane_start
        self._lane_length = np.hypot(step[:, 0], step[:, 1])
        keep = self._lane_length > 0
        self._lane_start, step, self._lane_length = self._lane_start[keep], step[keep], self._lane_length[keep]
        self._lane_dir = step / self._lane_length[:, None]
        self._lane_angle = np.arctan2(self._lane_dir[:, 1], self._lane_dir[:, 0])
        self._edge_start, self._edge_end = _road_edges(episodes)
        columns = relative_columns(nearest)
        self._low = np.array([c[1] for c in columns], dtype=np.float32)
        self._high = np.array([c[2] for c in columns], dtype=np.float32)
        self.space = gymnasium.spaces.Box(low=self._low, high=self._high, dtype=np.float32)

    def observe(self, episodes: EpisodeBatch) -> np.ndarray:
        n = episodes.n
        ego = episodes.ego / self._scale
        position, v, acc, head = ego[:, POSITION], ego[:, Ego.V], ego[:, Ego.ACC], ego[:, Ego.HEAD]
        cos, sin = np.cos(head), np.sin(head)
        out = np.zeros((n, self._low.size), dtype=np.float64)
        out[:, 0], out[:, 1] = v, acc
        # the lane: the centre-line segment nearest the ego, its heading difference weighed in
        rel = position[:, None] - self._lane_start[None]  # (n, S, 2)
        along = np.clip((rel * self._lane_dir[None]).sum(axis=2), 0.0, self._lane_length[None])
        foot = self._lane_start[None] + along[..., None] * self._lane_dir[None]
        distance = np.hypot(*(position[:, None] - foot).transpose(2, 0, 1))
        turn = _wrap(head[:, None] - self._lane_angle[None])
        segment = np.argmin(distance + HEADING_WEIGHT * np.abs(turn), axis=1)
        rows = np.arange(n)
        direction = self._lane_dir[segment]
        offset = rel[rows, segment]
        out[:, 2] = turn[rows, segment]
        out[:, 3] = direction[:, 0] * offset[:, 1] - direction[:, 1] * offset[:, 0]
        normal = np.column_stack([-direction[:, 1], direction[:, 0]])  # the lane's left
        out[:, 4] = _ray_hits(position, normal, self._edge_start, self._edge_end)
        out[:, 5] = _ray_hits(position, -normal, self._edge_start, self._edge_end)
        # a goal of time alone (GOAL_ANYWHERE) holds where the ego is: no direction to it
        goal = np.zeros_like(position) if self._anywhere else self._goal[None] - position
        out[:, 6] = goal[:, 0] * cos + goal[:, 1] * sin
        out[:, 7] = -goal[:, 0] * sin + goal[:, 1] * cos
        out[:, 8] = (self._horizon - episodes.k) * self._period
        if self.nearest > 0 and self._model.data.obstacle_count > 0:
            self._obstacles(out, episodes.k, position, v, cos, sin)
        return np.clip(out, self._low, self._high).astype(np.float32)

    def _obstacles(self, out: np.ndarray, k: np.ndarray, position: np.ndarray, v: np.ndarray, cos: np.ndarray,
                   sin: np.ndarray) -> None:
        """Fill the obstacle slots of ``out`` (the ``nearest`` obstacles of each row, nearest first)."""
        states = self._model.obstacle_states(k)  # (n, O, 4): x, y, heading, speed; NaN absent
        dx = states[..., 0] - position[:, 0, None]
        dy = states[..., 1] - position[:, 1, None]
        distance = np.hypot(dx, dy)
        seen = np.isfinite(distance) & (distance <= SENSING_RANGE)
        order = np.argsort(np.where(seen, distance, np.inf), axis=1, kind="stable")[:, :self.nearest]
        rows = np.arange(out.shape[0])[:, None]
        present = seen[rows, order]
        vx = states[..., 3] * np.cos(states[..., 2]) - (v * cos)[:, None]
        vy = states[..., 3] * np.sin(states[..., 2]) - (v * sin)[:, None]
        c, s = cos[:, None], sin[:, None]
        slots = np.stack([np.ones_like(dx), dx * c + dy * s, -dx * s + dy * c, vx * c + vy * s, -vx * s + vy * c],
                         axis=2)[rows, order]  # (n, nearest, 5)
        slots = np.where(present[..., None], slots, 0.0)
        width = len(OBSTACLE_COLUMNS)
        out[:, len(EGO_COLUMNS):len(EGO_COLUMNS) + width * order.shape[1]] = slots.reshape(out.shape[0], -1)


#: The kinds of observation, by name.
KINDS: dict[str, type] = {"ego": EgoObservation, "relative": RelativeObservation}


def make_observation(kind: str, episodes: EpisodeBatch) -> Observation:
    """The observation ``kind`` (one of :data:`KINDS`) of ``episodes``' model; :class:`ValueError` names
    the kinds for any other."""
    if kind not in KINDS:
        raise ValueError(f"observation must be one of {sorted(KINDS)}, not {kind!r}")
    observation: Observation = KINDS[kind](episodes)
    return observation
