"""The model's functions in Python, bit for bit what the emitted UPPAAL/C declarations compute.

The state is the controller's integer view: the significands ``x, y, v, acc, head, jerk, turn``
(:class:`State`) and, separately, the sample index ``k`` (UPPAAL's global ``count``; sample ``k``
is time ``k * C1``). Every function converts significands to doubles, computes on doubles and (for
:meth:`NativeModel.sense`) converts back with truncation toward zero — the paper's Eq. (1).

Exactness rules (docs/model.md, "Agreement with C"): the functions below are written in the
operation order of :mod:`rac.targets.uppaal.declarations`, so Python and C round identically:

- ``s / SCALE_D``: a significand to a double (``SCALE_D`` is ``float(scale)``; one IEEE division);
- ``int(d * SCALE_D)``: a double to a significand (the C cast / UPPAAL ``fint`` truncate too);
- ``a + b * c * d`` is ``a + ((b * c) * d)`` in both languages; no fused multiply-add (C is built
  with ``-ffp-contract=off``);
- ``math.sqrt`` (IEEE, correctly rounded) and ``math.cos``/``math.sin``, which call the C
  library's ``cos``/``sin`` — never ``math.hypot``, ``**`` or ``math.dist``;
- a clamp is two comparisons ``if a > hi: a = hi`` then ``if a < lo: a = lo``.

A later numpy version must keep these rules; note that numpy's own ``np.cos``/``np.sin`` may use
SIMD code that differs from the C library in the last bit.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import NamedTuple

from rac.core.numbers import INT32_BOUND
from rac.model.data import ModelData, ModelRangeError
from rac.model.sample import collides

__all__ = ["CORNERS", "CORNER_NAMES", "NEGATIVE_DISTANCE_TEXT", "NO_OBSTACLE", "NO_OBSTACLE_TEXT", "NativeModel",
           "State", "point_in_polygons"]

#: ``mindist()`` when no obstacle exists at the sample.
NO_OBSTACLE = 1.0e9
#: :data:`NO_OBSTACLE` as messages write it.
NO_OBSTACLE_TEXT = "1e9"
#: What a ``mindist()`` below 0 means, as plots say it: the discs covering the ego and an obstacle
#: (:meth:`NativeModel.mindist`) overlap, by that many metres; the vehicles have run into each other.
NEGATIVE_DISTANCE_TEXT = "below 0 m: the vehicles overlap (by that depth)"
#: The ego rectangle's corners as (along, across) signs, in the order offroad() visits them.
CORNERS = ((1, 1), (1, -1), (-1, -1), (-1, 1))
#: The corners of :data:`CORNERS` in words (across > 0 is the ego's left).
CORNER_NAMES = ("front-left", "front-right", "rear-right", "rear-left")


class State(NamedTuple):
    """The controller's state: significands at the model's scale; the fields are
    :data:`rac.ir.vocabulary.EGO_STATE` in order (tests/ir/test_vocabulary.py checks)."""

    x: int
    y: int
    v: int
    acc: int
    head: int
    jerk: int
    turn: int


def point_in_polygons(xs: Sequence[float], ys: Sequence[float], start: Sequence[int],
                      px: float, py: float) -> bool:
    """Whether ``(px, py)`` lies inside one of the polygons (crossing-number / ray casting).

    For each polygon, with ``j`` the previous vertex of ``i`` (cyclically): the edge crosses the
    horizontal ray to the right of the point when ``(yi > py) != (yj > py)`` and
    ``px < (xj - xi) * (py - yi) / (yj - yi) + xi``; an odd number of crossings means inside.
    A point on a boundary shared by two polygons is inside exactly one of them.
    """
    found = False
    for p in range(len(start) - 1):
        inside = False
        j = start[p + 1] - 1
        for i in range(start[p], start[p + 1]):
            xi = xs[i]
            yi = ys[i]
            xj = xs[j]
            yj = ys[j]
            if (yi > py) != (yj > py) and px < (xj - xi) * (py - yi) / (yj - yi) + xi:
                inside = not inside
            j = i
        if inside:
            found = True
    return found


class NativeModel:
    """The model's functions over one :class:`ModelData`.

    Example::

        model = NativeModel(build_model_data(scenario, spec))
        state = model.initial_state()
        state = model.sense(state._replace(jerk=5, turn=0))   # sample 0 -> sample 1
        model.collide(state, 1), model.offroad(state), model.goal(state, 1)
    """

    def __init__(self, data: ModelData) -> None:
        self.data = data
        scale = self.scale_d = float(data.scale)
        d = self._d
        self.length_d = d(data.length)
        self.width_d = d(data.width)
        self.max_acc_d = d(data.max_acc)
        self.min_speed_d = d(data.min_speed)
        self.max_speed_d = d(data.max_speed)
        self.td_d = d(data.td)
        self.goal_cx_d = d(data.goal_cx)
        self.goal_cy_d = d(data.goal_cy)
        self.road_xd = [s / scale for s in data.road_x]
        self.road_yd = [s / scale for s in data.road_y]
        self.goal_xd = [s / scale for s in data.goal_x]
        self.goal_yd = [s / scale for s in data.goal_y]

    def _d(self, significand: int) -> float:
        return significand / self.scale_d

    def significand(self, what: str, value: float) -> int:
        """``trunc(value · scale)``, or :class:`ModelRangeError` naming ``what`` when it leaves int32."""
        scaled = value * self.scale_d
        if not -INT32_BOUND < scaled < INT32_BOUND:  # also rejects NaN
            significand = int(scaled) if math.isfinite(scaled) else None
            raise ModelRangeError(f"sense(): {what}", value, significand, self.data.scale)
        return int(scaled)

    def initial_state(self) -> State:
        """The ego's start (jerk and turn 0): UPPAAL's initial values of the state variables."""
        data = self.data
        return State(data.ego_x, data.ego_y, data.ego_v, data.ego_acc, data.ego_head, 0, 0)

    # ------------------------------------------------------------ sense (Algorithm 1)
    def sense(self, state: State) -> State:
        """One sensing period ``C1`` of Algorithm 1: ``1/G`` Euler sub-steps of ``u = C1*G`` seconds.

        With every significand ``s`` read as the double ``s / SCALE_D``, each sub-step does, in order::

            acc = acc + jerk * u;  if acc > MA: acc = MA;  if acc < -MA: acc = -MA
            head = head + turn * u
            v = v + acc * u;       if v > VMAX: v = VMAX;  if v < VMIN: v = VMIN
            x = x + v * cos(head) * u
            y = y + v * sin(head) * u

        then each of x, y, v, acc, head becomes ``trunc(value * SCALE_D)``; jerk and turn are kept.
        The sample index is not touched (UPPAAL's Timer increments ``count``).
        :class:`ModelRangeError` if a result does not fit int32 (UPPAAL aborts there too).
        """
        if self.data.increments:
            return self.sense_increments(state)
        scale = self.scale_d
        x = state.x / scale
        y = state.y / scale
        v = state.v / scale
        acc = state.acc / scale
        head = state.head / scale
        jerk = state.jerk / scale
        turn = state.turn / scale
        u = self.data.unit
        ma = self.max_acc_d
        vmin = self.min_speed_d
        vmax = self.max_speed_d
        for _ in range(self.data.substeps):
            acc = acc + jerk * u
            if acc > ma:
                acc = ma
            if acc < -ma:
                acc = -ma
            head = head + turn * u
            v = v + acc * u
            if v > vmax:
                v = vmax
            if v < vmin:
                v = vmin
            x = x + v * math.cos(head) * u
            y = y + v * math.sin(head) * u
        sig = self.significand
        return State(sig("x", x), sig("y", y), sig("v", v), sig("acc", acc), sig("head", head),
                     state.jerk, state.turn)

    def sense_increments(self, state: State) -> State:
        """:meth:`sense` under ``dynamics increments``: each of the ``1/G`` sub-steps adds truncated
        increments to the significands (CommonUppRoad's model: ``x += d2i(v * cos(head))``), so a
        value that moves by whole significands stays on them. With ``d(e) = trunc(e * SCALE_D)``
        and every significand ``s`` read as ``s / SCALE_D``, a sub-step does, in order::

            acc = acc + d(jerk * u);        clamped to [-MA, MA] (significands)
            head = head + d(turn * u)
            v = v + d(acc * u);             clamped to [VMIN, VMAX]
            x = x + d(v * cos(head) * u)
            y = y + d(v * sin(head) * u)

        with the new acc, head and v. :class:`ModelRangeError` if a value leaves int32."""
        data = self.data
        scale = self.scale_d
        u = data.unit
        sig = self.significand
        x, y, v, acc, head = state.x, state.y, state.v, state.acc, state.head
        for _ in range(data.substeps):
            acc = acc + sig("acc", state.jerk / scale * u)
            if acc > data.max_acc:
                acc = data.max_acc
            if acc < -data.max_acc:
                acc = -data.max_acc
            head = head + sig("head", state.turn / scale * u)
            v = v + sig("v", acc / scale * u)
            if v > data.max_speed:
                v = data.max_speed
            if v < data.min_speed:
                v = data.min_speed
            h = head / scale
            x = x + sig("x", v / scale * math.cos(h) * u)
            y = y + sig("y", v / scale * math.sin(h) * u)
        for what, value in (("x", x), ("y", y), ("head", head)):
            if not -INT32_BOUND < value < INT32_BOUND:
                raise ModelRangeError(f"sense(): {what}", value / scale, value, data.scale)
        return State(x, y, v, acc, head, state.jerk, state.turn)

    # ------------------------------------------------------------ obstacles
    def waypoint(self, i: int, k: int) -> int:
        """Index of obstacle ``i``'s waypoint in force at sample ``k`` (the last one with time
        ``<= k``, else its first), or ``-1`` when the obstacle does not exist at ``k``."""
        data = self.data
        if k < data.obs_from[i] or k > data.obs_until[i]:
            return -1
        j = data.wp_start[i]
        for m in range(data.wp_start[i] + 1, data.wp_start[i + 1]):
            if data.wp_time[m] <= k:
                j = m
        return j

    def obstacle_position(self, i: int, k: int) -> tuple[float, float, float] | None:
        """Obstacle ``i`` at sample ``k``: ``(x, y, heading)`` as doubles, ``None`` when absent
        (before its first or after its last waypoint; a static obstacle is always present).

        From waypoint ``j`` (:meth:`waypoint`), with ``dt = (k - T[j]) * C1``::

            h = H[j] / SCALE_D
            x = X[j] / SCALE_D + V[j] / SCALE_D * cos(h) * dt
            y = Y[j] / SCALE_D + V[j] / SCALE_D * sin(h) * dt
        """
        j = self.waypoint(i, k)
        if j < 0:
            return None
        data = self.data
        scale = self.scale_d
        dt = (k - data.wp_time[j]) * data.period
        h = data.wp_head[j] / scale
        x = data.wp_x[j] / scale + data.wp_vel[j] / scale * math.cos(h) * dt
        y = data.wp_y[j] / scale + data.wp_vel[j] / scale * math.sin(h) * dt
        return (x, y, h)

    # ------------------------------------------------------------ distances
    def mindist(self, state: State, k: int) -> float:
        """The smallest distance between the ego and an obstacle at sample ``k`` (disc approximation).

        A rectangle of length ``l`` and width ``w`` centred at ``(cx, cy)`` with heading ``h`` is
        covered by 3 discs of radius ``r = sqrt((l / 6.0) * (l / 6.0) + (w / 2.0) * (w / 2.0))``
        centred at ``(cx + (a - 1) * (l / 3.0) * cos(h), cy + (a - 1) * (l / 3.0) * sin(h))``,
        ``a = 0, 1, 2``. The distance is the minimum over present obstacles and disc pairs of
        ``sqrt(dx * dx + dy * dy) - r_ego - r_obs`` (negative when discs overlap), or
        :data:`NO_OBSTACLE` (``1.0e9``) when no obstacle exists at ``k``.
        """
        data = self.data
        scale = self.scale_d
        ex = state.x / scale
        ey = state.y / scale
        eh = state.head / scale
        ec = math.cos(eh)
        es = math.sin(eh)
        el = self.length_d
        ew = self.width_d
        er = math.sqrt((el / 6.0) * (el / 6.0) + (ew / 2.0) * (ew / 2.0))
        eoff = el / 3.0
        best = NO_OBSTACLE
        for i in range(data.obstacle_count):
            position = self.obstacle_position(i, k)
            if position is None:
                continue
            ox, oy, oh = position
            oc = math.cos(oh)
            os_ = math.sin(oh)
            ol = data.obs_length[i] / scale
            ow = data.obs_width[i] / scale
            orad = math.sqrt((ol / 6.0) * (ol / 6.0) + (ow / 2.0) * (ow / 2.0))
            ooff = ol / 3.0
            for a in range(3):
                ax = ex + (a - 1) * eoff * ec
                ay = ey + (a - 1) * eoff * es
                for b in range(3):
                    bx = ox + (b - 1) * ooff * oc
                    by = oy + (b - 1) * ooff * os_
                    dx = ax - bx
                    dy = ay - by
                    d = math.sqrt(dx * dx + dy * dy) - er - orad
                    if d < best:
                        best = d
        return best

    def collide(self, state: State, k: int) -> bool:
        """``mindist(state, k) < TD``."""
        return collides(self.mindist(state, k), self.td_d)

    def offroad(self, state: State, k: int | None = None) -> bool:
        """Whether a corner of the ego rectangle lies outside every road polygon; false at samples
        ``k < offroad_from`` (``k`` None: the corners only).

        With ``c = cos(h)``, ``s = sin(h)``, ``hl = l / 2.0``, ``hw = w / 2.0``, corner ``(ca, cb)``
        of :data:`CORNERS` is ``(x + ca * hl * c - cb * hw * s, y + ca * hl * s + cb * hw * c)``;
        each is tested with :func:`point_in_polygons` against the road.
        """
        if k is not None and k < self.data.offroad_from:
            return False
        return any(self.corners_off(state))

    def corner_points(self, state: State) -> tuple[tuple[float, float], ...]:
        """The ego rectangle's corners (x, y) in the order of :data:`CORNERS`, as :meth:`offroad` computes them."""
        scale = self.scale_d
        ex = state.x / scale
        ey = state.y / scale
        eh = state.head / scale
        c = math.cos(eh)
        s = math.sin(eh)
        hl = self.length_d / 2.0
        hw = self.width_d / 2.0
        return tuple((ex + ca * hl * c - cb * hw * s, ey + ca * hl * s + cb * hw * c) for ca, cb in CORNERS)

    def corners_off(self, state: State) -> tuple[bool, ...]:
        """For each corner of :data:`CORNERS`, whether it lies outside every road polygon
        (:meth:`offroad` is their ``any``)."""
        return tuple(not point_in_polygons(self.road_xd, self.road_yd, self.data.road_start, px, py)
                     for px, py in self.corner_points(state))

    def goal(self, state: State, k: int) -> bool:
        """``GOAL_LOW <= k <= GOAL_HIGH`` and the ego's centre inside a goal polygon (any position
        with ``GOAL_ANYWHERE``)."""
        data = self.data
        if not data.goal_low <= k <= data.goal_high:
            return False
        if data.goal_anywhere:
            return True
        scale = self.scale_d
        return point_in_polygons(self.goal_xd, self.goal_yd, data.goal_start, state.x / scale, state.y / scale)

    def dist_goal(self, state: State) -> float:
        """``sqrt(dx * dx + dy * dy)`` with ``dx = x / SCALE_D - GOAL_CX / SCALE_D`` (and ``dy`` alike);
        0 with ``GOAL_ANYWHERE`` (every position is in the goal)."""
        if self.data.goal_anywhere:
            return 0.0
        scale = self.scale_d
        dx = state.x / scale - self.goal_cx_d
        dy = state.y / scale - self.goal_cy_d
        return math.sqrt(dx * dx + dy * dy)

