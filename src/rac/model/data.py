"""The scenario model's data, every number an int32 significand (the paper's Eq. (1)).

A real value ``v`` is held as the integer ``trunc(v * SCALE)`` with ``SCALE = base ** exponent``
(:attr:`rac.ir.ModelSpec.scale`); truncation is toward zero, computed exactly: a ``Fraction`` (the
``model`` block's numbers) is used as is, a float (the scenario's numbers, parsed from CommonRoad
XML) as the shortest decimal that reads back as it (``repr``), so ``0.57`` at scale 100 is ``57``,
not the ``56`` that ``0.57 * 100 == 56.99999999999999`` would give.

Times are counted in sense periods ``C1`` from the ego's start ``t0`` (the planning problem's
initial time, :attr:`rac.model.commonroad.EgoStart.time`): sample ``k`` is the time ``t0 + k * C1``. A dynamic
obstacle is resampled at these times (:func:`_resample`): its waypoints lie on whole samples and
each is the obstacle's state at that sample's time, so the model's projection from a waypoint is
exact however the CommonRoad time step relates to ``C1``. The goal interval is the samples inside
it: ``ceil((low - t0) / C1)`` to ``floor((high - t0) / C1)``, exactly (``goal_low > goal_high`` when
no sample lies inside; ``rac check`` warns of it, W0722).

Every significand must lie in ``[-2147483647, 2147483647]`` (int32 without ``INT32_MIN``, which has
no literal in UPPAAL); :func:`build_model_data` raises :class:`ModelRangeError` naming the first
one that does not, :func:`check_significands` returns it, :func:`max_significand` reports the
largest. Example::

    data = build_model_data(scenario, spec)       # ModelRangeError if the exponent is too fine
    NativeModel(data).sense(NativeModel(data).initial_state())
"""

from __future__ import annotations

import dataclasses
import enum
import hashlib
import math
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass
from fractions import Fraction

from rac.core.diagnostics import RacError
from rac.core.numbers import INT32_LOW, INT32_MAX
from rac.ir import ModelSpec
from rac.ir.expr import Expr
from rac.model.commonroad import Polygon, Scenario

__all__ = [
    "ActionData",
    "ModelData",
    "ModelRangeError",
    "build_model_data",
    "build_model_data_and_largest",
    "check_significands",
    "exact",
    "max_significand",
]

#: The resolution of scenario times (s). load_scenario reads a time as ``round(step * dt, 9)``, so
#: anything finer is the float noise of a product like ``0.1 * 30`` in a hand-built scenario, and
#: would otherwise push a waypoint that lies on a sample just past it.
NANOSECOND = Fraction(1, 10**9)

Number = Fraction | int | float
Point = tuple[float, float]

#: Road vertices of two lanelets closer than this (m) are one point: :func:`_road` gives them one
#: value, so that they truncate alike (3.4999999999 and 3.5000000001 are 349 and 350 at exponent 2). A
#: map's float noise is about 1e-9 m and a significand at exponent 5 is 1e-5 m: 1e-6 m joins what
#: is meant to be one point and moves nothing by an amount the model can tell.
ROAD_SNAP = 1e-6
#: A road vertex of one lanelet this close (m) to the inside of another lanelet's edge lies on that
#: edge: :func:`_road` makes it a vertex of the edge as well. Neighbouring lanelets often sample
#: their shared divider at different points (DEU_Muc-3_1_T-1: 5 mm apart along it, each rounded to the
#: file's 4 decimals, so up to 1.5e-4 m off the other's edge); truncated separately, the two edges
#: part by up to a significand. 1 mm covers maps written to 4 decimals with room to spare and moves an
#: edge by no more than a tenth of a significand at exponent 2 (the road is the lanelets' union, so a
#: vertex of an overlapping lanelet inserted alike changes nothing that matters).
ROAD_JOIN = 1e-3


class ModelDataError(RacError, ValueError):
    """A scenario whose data the model cannot be built from (a value that is not finite, an obstacle
    without waypoints, ...): the file's fault, reported as E0712 by :mod:`rac.model.checks`."""


class ModelRangeError(RacError, ValueError):
    """A value whose significand (or count of sense periods) does not fit int32 at this scale.

    ``what`` names it (e.g. ``"obstacle 3 waypoint 2 x"``), ``value`` is the real value and
    ``significand`` the integer it would need (``None`` when the value is not finite); ``low`` the least
    value allowed (:data:`INT32_LOW` for what rac writes or reads, ``INT32_MIN`` for a computed mirror);
    ``binding`` the input whose ``bind`` it is, when it is a binding's value (a message points at that line).
    """

    def __init__(self, what: str, value: Number, significand: int | None, scale: int, low: int = INT32_LOW, *,
                 binding: str | None = None) -> None:
        self.what = what
        self.binding = binding
        self.value = value
        self.significand = significand
        self.scale = scale
        if significand is None:
            text = f"{what} is {value}, which has no significand"
        else:
            text = (f"{what} = {_show(value)} needs the significand {significand} at scale {scale}, "
                    f"outside int32 [{low}, {INT32_MAX}]")
        super().__init__(text)


@dataclass(frozen=True)
class ActionData:
    """One action (``jerk``, ``turn``) in significands: ``values`` are ``trunc(value * SCALE)`` of
    :attr:`rac.ir.Action.values` — the authoritative list (at a coarse scale ``low + i * step``
    in significands may differ from it, and ``step`` may truncate to 0)."""

    name: str
    low: int
    high: int
    step: int
    values: tuple[int, ...]

    @property
    def count(self) -> int:
        return len(self.values)


@dataclass(frozen=True)
class ModelData:
    """Everything the model's functions read, as int32 significands at ``scale`` unless noted.

    Polygons are flattened: polygon ``p`` has the vertices ``xs[start[p]:start[p + 1]]`` (and the
    same ``ys``); ``start`` has one entry more than there are polygons. Obstacle ``i`` has the
    waypoints ``wp_*[wp_start[i]:wp_start[i + 1]]``, times in sense periods from the ego's start
    (negative before it), increasing, each the obstacle's state at that sample (resampled from the
    scenario, :func:`_resample`); it exists at samples ``obs_from[i] <= k <= obs_until[i]``, those
    within its CommonRoad lifetime (``obs_from[i] == obs_until[i] + 1`` if none is). A static
    obstacle has one waypoint at time 0, velocity 0, and exists at every sample (``0 .. INT32_MAX``).
    """

    name: str  # the scenario's name (not a number)
    base: int
    exponent: int
    scale: int
    # ---- periods
    unit: float  # the Euler sub-step C1 * G in seconds, the double nearest to it
    period: float  # C1 in seconds, the double nearest to it
    sense_period: int  # significand of C1
    decide_period: int  # significand of C2
    decide_every: int  # C2 / C1 (a decision every so many samples)
    substeps: int  # 1 / G
    # ---- road: the union of these polygons
    road_x: tuple[int, ...]
    road_y: tuple[int, ...]
    road_start: tuple[int, ...]
    # ---- obstacles
    obs_id: tuple[int, ...]  # CommonRoad ids (not significands)
    obs_length: tuple[int, ...]
    obs_width: tuple[int, ...]
    obs_from: tuple[int, ...]  # first sample at which it exists
    obs_until: tuple[int, ...]  # last sample at which it exists
    wp_start: tuple[int, ...]
    wp_time: tuple[int, ...]  # sense periods
    wp_x: tuple[int, ...]
    wp_y: tuple[int, ...]
    wp_head: tuple[int, ...]
    wp_vel: tuple[int, ...]
    # ---- ego start
    ego_x: int
    ego_y: int
    ego_v: int
    ego_acc: int
    ego_head: int
    # ---- goal
    goal_x: tuple[int, ...]
    goal_y: tuple[int, ...]
    goal_start: tuple[int, ...]
    goal_low: int  # sense periods
    goal_high: int  # sense periods
    goal_cx: int
    goal_cy: int
    # ---- vehicle
    length: int
    width: int
    max_acc: int  # MA
    max_turn: int  # MT
    min_speed: int
    max_speed: int
    td: int  # collision distance TD
    p1: int
    p2: int
    actions: tuple[ActionData, ...]
    # ---- modelling choices (docs/language.md, "Modelling choices")
    #: ``dynamics increments``: every sub-step adds truncated increments to the significands
    #: (:meth:`rac.model.native.NativeModel.sense`); False: Algorithm 1 on doubles.
    increments: bool = False
    #: ``offroad()`` is false at samples ``k < offroad_from``.
    offroad_from: int = 0
    #: ``allow when e``: the condition an action's successor must meet (None: every action is allowed).
    allow: Expr | None = None
    #: ``collision sticky``: ``collide()`` holds from the first sample it held at to the end of the run.
    sticky: bool = False
    #: The goal holds at any position inside its window (:attr:`rac.model.commonroad.Goal.anywhere`, a
    #: goal of time alone): ``goal()`` reads the time only, ``dist_goal()`` is 0 (``GOAL_ANYWHERE``).
    goal_anywhere: bool = False

    @property
    def road_count(self) -> int:
        return len(self.road_start) - 1

    @property
    def obstacle_count(self) -> int:
        return len(self.obs_length)

    @property
    def goal_count(self) -> int:
        return len(self.goal_start) - 1

    def action(self, name: str) -> ActionData:
        return next(a for a in self.actions if a.name == name)

    def waypoints(self, i: int) -> range:
        """Indices into ``wp_*`` of obstacle ``i``'s waypoints."""
        return range(self.wp_start[i], self.wp_start[i + 1])

    @property
    def digest(self) -> str:
        """A fingerprint of everything the model's runs depend on (the scenario's data at this scale,
        the periods, the vehicle, the actions, the modelling choices; not where in the .ra file the
        ``allow when`` condition is written): what a saved shield records, so that a shield computed
        for another scene or setting is refused rather than trusted."""
        return hashlib.sha256(_canonical(self).encode("utf-8")).hexdigest()[:32]


def _canonical(value: object) -> str:
    """``value`` as text that two equal models share: dataclasses field by field, without source spans."""
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        inner = ",".join(f"{f.name}={_canonical(getattr(value, f.name))}" for f in dataclasses.fields(value)
                         if f.name != "span")
        return f"{type(value).__name__}({inner})"
    if isinstance(value, (tuple, list)):
        return "(" + ",".join(_canonical(item) for item in value) + ")"
    if isinstance(value, enum.Enum):
        return f"{type(value).__name__}.{value.name}"
    return repr(value)


# ---------------------------------------------------------------- conversion
def exact(value: Number) -> Fraction:
    """The exact value a number stands for: a Fraction or int as is, a float as its ``repr`` decimal."""
    if isinstance(value, Fraction):
        return value
    if isinstance(value, int) and not isinstance(value, bool):
        return Fraction(value)
    number = float(value)
    if not math.isfinite(number):
        raise ModelDataError(f"{number} is not finite")
    return Fraction(repr(number))


def _show(value: Number) -> str:
    if isinstance(value, Fraction):
        return str(value) if value.denominator == 1 else f"{float(value)!r}"
    return repr(value)


class _Converter:
    """Turns reals into significands; ``strict`` raises on the first overflow, otherwise records."""

    def __init__(self, spec: ModelSpec, strict: bool, origin: Fraction = Fraction(0)) -> None:
        self.scale = spec.scale
        self.period = spec.sense_period
        self.origin = origin  # the time of sample 0, seconds
        self.strict = strict
        self.seen: list[tuple[str, int]] = []

    def _fit(self, what: str, value: Number, significand: int) -> int:
        self.seen.append((what, significand))
        if INT32_LOW <= significand <= INT32_MAX:
            return significand
        if self.strict:
            raise ModelRangeError(what, value, significand, self.scale)
        return max(INT32_LOW, min(INT32_MAX, significand))

    def _exact(self, what: str, value: Number) -> Fraction:
        try:
            return exact(value)
        except ValueError:
            raise ModelRangeError(what, value, None, self.scale) from None

    def sig(self, what: str, value: Number) -> int:
        """``trunc(value * SCALE)``."""
        return self._fit(what, value, math.trunc(self._exact(what, value) * self.scale))

    def seconds(self, what: str, value: Number) -> Fraction:
        """A time in seconds, exactly, to the nanosecond (:data:`NANOSECOND`; ties to even)."""
        return round(self._exact(what, value) / NANOSECOND) * NANOSECOND

    def clamp(self, what: str, value: Number, count: int) -> int:
        """A count of sense periods, checked (and recorded) like a significand."""
        return self._fit(what, value, count)

    def periods(self, what: str, seconds: Number, rounding: Callable[[Fraction], int], unbounded: int = 0) -> int:
        """``rounding((seconds - t0) / C1)`` (``math.ceil`` for a window's first sample, ``math.floor`` for
        its last: a window rounded outward would widen it); with ``unbounded``, ``±inf`` (an open goal
        interval) becomes ``±INT32_MAX``."""
        if unbounded and isinstance(seconds, float) and math.isinf(seconds):
            return INT32_MAX if seconds > 0 else INT32_LOW
        return self._fit(what, seconds, rounding((self._exact(what, seconds) - self.origin) / self.period))


def _converter(scenario: Scenario, spec: ModelSpec, strict: bool) -> _Converter:
    start = _Converter(spec, strict)
    return _Converter(spec, strict, start.seconds("ego start time", scenario.ego.time))


def _snapped(road: Sequence[Polygon]) -> list[list[Point]]:
    """The road's vertices, each within :data:`ROAD_SNAP` of an earlier polygon's vertex given that
    vertex's value (the first polygon's, in road order); the rest as they are."""
    polygons = [list(polygon.points) for polygon in road]
    # cells of ROAD_SNAP: the earlier vertices within it are in the cell or its 8 neighbours
    cells: dict[tuple[int, int], list[tuple[int, float, float, Point]]] = {}
    done: dict[Point, Point] = {}  # each value's outcome: most vertices are another lanelet's exactly
    for p, points in enumerate(polygons):
        for v, point in enumerate(points):
            if point in done:
                points[v] = done[point]
                continue
            x, y = float(point[0]), float(point[1])
            cx, cy = math.floor(x / ROAD_SNAP), math.floor(y / ROAD_SNAP)
            twin = next((value for dx in (-1, 0, 1) for dy in (-1, 0, 1)
                         for q, qx, qy, value in cells.get((cx + dx, cy + dy), ())
                         if q != p and math.hypot(qx - x, qy - y) <= ROAD_SNAP), None)
            if twin is None:
                cells.setdefault((cx, cy), []).append((p, x, y, point))
            else:
                points[v] = twin
            done[point] = points[v]
    return polygons


def _road(conv: Callable[[str, Number], int],
          road: Sequence[Polygon]) -> tuple[tuple[int, ...], tuple[int, ...], tuple[int, ...]]:
    """The road's polygons in significands, with the edges that neighbouring lanelets share made one.

    Lanelets meet along dividers whose vertices the map gives twice, once per lanelet, and not always
    alike: a vertex off its twin by float noise truncates to another significand, and a divider sampled
    at other points along it is another polyline; either way a hairline gap, up to a significand wide,
    opens between the lanelets, and a corner of the ego in it is off the road. So vertices of different
    lanelets that are one point get one value before truncation (:func:`_snapped`); then a vertex of
    another lanelet within :data:`ROAD_JOIN` of the inside of an edge becomes a vertex of that edge
    too (in order along it, with its own significands), unless its significands lie on the edge's
    already: both lanelets then carry the same vertices along their divider. Where the significands
    already agree (every generated scene) the polygons are the vertices' significands, nothing added.
    """
    import numpy as np  # numpy: only when the model's data is built; importing rac.model.data stays light

    polygons = _snapped(road)
    xs, ys, start = _polygons(conv, "road polygon", polygons)
    flat = [point for points in polygons for point in points]
    fx = np.array([float(x) for x, _ in flat])
    fy = np.array([float(y) for _, y in flat])
    owner = np.repeat(np.arange(len(polygons)), np.diff(start))
    following = np.arange(1, len(flat) + 1)  # each vertex's next in its polygon, cyclically
    for low, high in zip(start, start[1:]):
        if high > low:
            following[high - 1] = low
    ex, ey = fx[following] - fx, fy[following] - fy  # edge i runs from vertex i to vertex following[i]
    length2 = ex * ex + ey * ey
    order = np.argsort(fx, kind="stable")
    sorted_x = fx[order]
    out_x: list[int] = []
    out_y: list[int] = []
    out_start = [0]
    for p in range(len(polygons)):
        low, high = start[p], start[p + 1]
        found: dict[int, dict[tuple[int, int], tuple[float, int]]] = {}  # edge -> point -> (along, vertex)
        if high - low >= 2:
            box_x, box_y = fx[low:high], fy[low:high]
            near = order[np.searchsorted(sorted_x, box_x.min() - ROAD_JOIN, "left"):
                         np.searchsorted(sorted_x, box_x.max() + ROAD_JOIN, "right")]
            near = near[(owner[near] != p) & (fy[near] >= box_y.min() - ROAD_JOIN)
                        & (fy[near] <= box_y.max() + ROAD_JOIN)]
        else:
            near = order[:0]
        if near.size:
            # rows: the polygon's edges; columns: the other polygons' vertices near it
            e_x, e_y, e_2 = ex[low:high, None], ey[low:high, None], length2[low:high, None]
            rx, ry = fx[near][None, :] - box_x[:, None], fy[near][None, :] - box_y[:, None]
            with np.errstate(divide="ignore", invalid="ignore"):
                along = (rx * e_x + ry * e_y) / e_2
                off = np.abs(rx * e_y - ry * e_x) / np.sqrt(e_2)
            hit = (e_2 > 0) & (along > 0) & (along < 1) & (off <= ROAD_JOIN)
            own = set(zip(xs[low:high], ys[low:high]))
            for e, c in zip(*np.nonzero(hit)):
                i, w = low + int(e), int(near[c])
                j = int(following[i])
                point = (xs[w], ys[w])
                if point in own:
                    continue  # the polygon has it already (at an end of the edge): once is enough
                # exactly on the truncated edge (integers): the two lanelets' edges agree there already
                ax, ay, bx, by = xs[j] - xs[i], ys[j] - ys[i], point[0] - xs[i], point[1] - ys[i]
                if ax * by == ay * bx and 0 <= ax * bx + ay * by <= ax * ax + ay * ay:
                    continue
                found.setdefault(i, {})[point] = (float(along[e, c]), w)  # once, however many lanelets share it
        for i in range(low, high):
            out_x.append(xs[i])
            out_y.append(ys[i])
            for _, w in sorted(found.get(i, {}).values()):  # in order along the edge
                out_x.append(xs[w])
                out_y.append(ys[w])
        out_start.append(len(out_x))
    return tuple(out_x), tuple(out_y), tuple(out_start)


def _polygons(conv: Callable[[str, Number], int], name: str,
              polygons: Iterable[Sequence[Point]]) -> tuple[tuple[int, ...], tuple[int, ...], tuple[int, ...]]:
    xs: list[int] = []
    ys: list[int] = []
    start = [0]
    for p, points in enumerate(polygons):
        for v, (px, py) in enumerate(points):
            xs.append(conv(f"{name} {p} vertex {v} x", px))
            ys.append(conv(f"{name} {p} vertex {v} y", py))
        start.append(len(xs))
    return tuple(xs), tuple(ys), tuple(start)


@dataclass(frozen=True)
class _Resampled:
    """A dynamic obstacle on the sample grid: it exists at samples ``first .. last``; ``in_force``
    maps each sample that gets a waypoint to the CommonRoad waypoint in force there (the last one
    at or before the sample's time), in increasing order of samples."""

    first: int
    last: int
    in_force: dict[int, int]


def _resample(conv: _Converter, times: list[Fraction]) -> _Resampled:
    """Where a dynamic obstacle with waypoints at ``times`` (seconds, not decreasing) gets its
    model waypoints.

    It exists from its first waypoint's time to its last's, as in CommonRoad: at the samples ``k``
    with ``times[0] <= t0 + k*C1 <= times[-1]``. A waypoint is emitted at the first of them and at
    every later one at which a new CommonRoad waypoint has come into force since the sample before.
    Between those samples the waypoint in force does not change, and it moves in a straight line
    (:class:`rac.model.commonroad.Waypoint`), so the model's projection from the sample's waypoint is the
    obstacle's own motion and another waypoint would add nothing. So a trajectory with a state
    every ``dt`` gets a waypoint at every sample of its lifetime when ``C1 >= dt``, at most one per
    state when ``C1 <= dt`` (the scenario's own waypoints, unchanged, when each lies on a sample),
    and never more waypoints than it has states.
    """
    # the sample at or after each waypoint: the first at which it is in force
    samples = [math.ceil((t - conv.origin) / conv.period) for t in times]
    first = samples[0]
    last = math.floor((times[-1] - conv.origin) / conv.period)
    in_force: dict[int, int] = {}
    for j, k in enumerate(samples):
        # ``k == first`` keeps one waypoint for an obstacle that lives between two samples
        # (first == last + 1, absent at every sample): the arrays want at least one per obstacle.
        if k <= last or k == first:
            in_force[k] = j  # samples do not decrease, so the last waypoint at or before k wins
    return _Resampled(first, last, in_force)


def _build(scenario: Scenario, spec: ModelSpec, conv: _Converter) -> ModelData:
    sig = conv.sig
    road_x, road_y, road_start = _road(sig, scenario.road)

    obs_id: list[int] = []
    obs_length: list[int] = []
    obs_width: list[int] = []
    obs_from: list[int] = []
    obs_until: list[int] = []
    wp_start = [0]
    wp: dict[str, list[int]] = {key: [] for key in ("time", "x", "y", "head", "vel")}
    for obstacle in scenario.obstacles:
        name = f"obstacle {obstacle.id}"
        obs_id.append(obstacle.id)
        obs_length.append(sig(f"{name} length", obstacle.length))
        obs_width.append(sig(f"{name} width", obstacle.width))
        waypoints = obstacle.waypoints
        if not waypoints:
            raise ModelDataError(f"{name} has no waypoints")
        if obstacle.static:
            point = waypoints[0]
            where = f"{name} waypoint 0"
            wp["time"].append(0)
            wp["vel"].append(0)
            wp["x"].append(sig(f"{where} x", point.x))
            wp["y"].append(sig(f"{where} y", point.y))
            wp["head"].append(sig(f"{where} heading", point.heading))
            obs_from.append(0)
            obs_until.append(INT32_MAX)
            wp_start.append(len(wp["time"]))
            continue
        times = [conv.seconds(f"{name} waypoint {j} time", point.time) for j, point in enumerate(waypoints)]
        if any(b < a for a, b in zip(times, times[1:])):
            raise ModelDataError(f"{name}: waypoint times must not decrease")
        grid = _resample(conv, times)
        # Every waypoint's sample lies in first .. max(first, last): checking those two checks them all.
        obs_from.append(conv.clamp(f"{name} waypoint 0 time (sense periods)", waypoints[0].time, grid.first))
        obs_until.append(conv.clamp(f"{name} waypoint {len(waypoints) - 1} time (sense periods)",
                                    waypoints[-1].time, grid.last))
        for k, j in grid.in_force.items():
            point = waypoints[j]
            elapsed = conv.origin + k * conv.period - times[j]  # seconds since waypoint j, >= 0
            where = f"{name} waypoint {j}" if elapsed == 0 else f"{name} waypoint {j} moved on to sample {k}"
            wp["time"].append(max(INT32_LOW, min(INT32_MAX, k)))
            wp["vel"].append(sig(f"{where} velocity", point.velocity))
            x: Number
            y: Number
            if elapsed == 0:  # the state itself: its decimals as they are
                x, y = point.x, point.y
            else:  # straight on from it, exactly but for the double cos and sin of its heading
                speed = conv._exact(f"{where} velocity", point.velocity)
                heading = float(conv._exact(f"{where} heading", point.heading))
                x = conv._exact(f"{where} x", point.x) + speed * Fraction(math.cos(heading)) * elapsed
                y = conv._exact(f"{where} y", point.y) + speed * Fraction(math.sin(heading)) * elapsed
            wp["x"].append(sig(f"{where} x", x))
            wp["y"].append(sig(f"{where} y", y))
            wp["head"].append(sig(f"{where} heading", point.heading))
        wp_start.append(len(wp["time"]))

    ego = scenario.ego
    goal = scenario.goal
    goal_x, goal_y, goal_start = _polygons(sig, "goal polygon", [region.points for region in goal.regions])
    # Goal.center owns the point dist_goal() measures to (inside the first region)
    center = tuple(exact(c) for c in goal.center) if goal.regions else (Fraction(0), Fraction(0))

    actions = tuple(
        ActionData(a.name, sig(f"action {a.name} low", a.low), sig(f"action {a.name} high", a.high),
                   sig(f"action {a.name} step", a.step),
                   tuple(sig(f"action {a.name} value {v}", v) for v in a.values))
        for a in spec.actions)
    decide_every = spec.decide_period / spec.sense_period
    if decide_every.denominator != 1 or decide_every < 1:
        raise ModelDataError(f"the decision period {spec.decide_period} is not a multiple of {spec.sense_period}")

    return ModelData(
        name=scenario.name, base=spec.base, exponent=spec.exponent, scale=spec.scale,
        unit=float(spec.sense_period * spec.granularity), period=float(spec.sense_period),
        sense_period=sig("sense period C1", spec.sense_period),
        decide_period=sig("decide period C2", spec.decide_period),
        decide_every=int(decide_every), substeps=spec.substeps,
        road_x=road_x, road_y=road_y, road_start=road_start,
        obs_id=tuple(obs_id), obs_length=tuple(obs_length), obs_width=tuple(obs_width),
        obs_from=tuple(obs_from), obs_until=tuple(obs_until), wp_start=tuple(wp_start),
        wp_time=tuple(wp["time"]), wp_x=tuple(wp["x"]), wp_y=tuple(wp["y"]),
        wp_head=tuple(wp["head"]), wp_vel=tuple(wp["vel"]),
        ego_x=sig("ego start x", _start(spec.start_x, ego.x)), ego_y=sig("ego start y", _start(spec.start_y, ego.y)),
        ego_v=sig("ego start velocity", _start(spec.start_speed, ego.velocity)),
        ego_acc=sig("ego start acceleration", ego.acceleration),
        ego_head=sig("ego start heading", _start(spec.start_heading, ego.heading)),
        goal_x=goal_x, goal_y=goal_y, goal_start=goal_start,
        # the samples inside the goal's window, never one outside it
        goal_low=conv.periods("goal time low (sense periods)", goal.time_low, math.ceil, unbounded=1),
        goal_high=conv.periods("goal time high (sense periods)", goal.time_high, math.floor, unbounded=1),
        goal_cx=sig("goal centre x", center[0]), goal_cy=sig("goal centre y", center[1]),
        length=sig("vehicle length", spec.length), width=sig("vehicle width", spec.width),
        max_acc=sig("max acceleration MA", spec.max_acceleration), max_turn=sig("max turn rate MT", spec.max_turn),
        min_speed=sig("min speed", spec.min_speed), max_speed=sig("max speed", spec.max_speed),
        td=sig("collision distance TD", spec.collision_distance),
        p1=sig("comfort fraction p1", spec.comfort_acceleration), p2=sig("comfort fraction p2", spec.comfort_turn),
        actions=actions,
        increments=spec.dynamics == "increments", offroad_from=spec.offroad_from, allow=spec.allow,
        sticky=spec.collision == "sticky", goal_anywhere=goal.anywhere,
    )


def _start(setting: Fraction | None, scenario: float) -> Number:
    """A ``start_*`` setting where written, else the planning problem's value."""
    return scenario if setting is None else setting


def build_model_data(scenario: Scenario, spec: ModelSpec) -> ModelData:
    """The model's data for ``scenario`` under ``spec``; :class:`ModelRangeError` names the first
    value whose significand overflows int32 (or that is not finite). :class:`ModelDataError` for a scenario
    that makes no sense (an obstacle without waypoints, C2 not a multiple of C1)."""
    return _build(scenario, spec, _converter(scenario, spec, strict=True))


def build_model_data_and_largest(scenario: Scenario, spec: ModelSpec) -> tuple[ModelData, tuple[str, int]]:
    """:func:`build_model_data` and :func:`max_significand` in one pass: ``rac check`` reports both, and
    building twice doubled the time of a large scenario's check (the exact arithmetic dominates). When
    nothing overflows, the strict pass saw the values the lenient one would."""
    conv = _converter(scenario, spec, strict=True)
    data = _build(scenario, spec, conv)
    return data, max(conv.seen, key=lambda item: abs(item[1])) if conv.seen else ("nothing", 0)


def check_significands(scenario: Scenario, spec: ModelSpec) -> ModelRangeError | None:
    """The first value that overflows int32 under ``spec``'s scale (as the error), or ``None``."""
    try:
        build_model_data(scenario, spec)
    except ModelRangeError as error:
        return error
    return None


def max_significand(scenario: Scenario, spec: ModelSpec) -> tuple[str, int]:
    """The value with the largest significand in absolute value: ``(what, significand)``.

    Counts of sense periods (waypoint and goal times) are included; an open goal interval is not.
    """
    conv = _converter(scenario, spec, strict=False)
    _build(scenario, spec, conv)
    if not conv.seen:
        return ("nothing", 0)
    return max(conv.seen, key=lambda item: abs(item[1]))
