"""The scenario model's functions over arrays of states, vectorised with numpy (issue 4).

:class:`BatchModel` and the ``*_many`` shorthands: ``sense_many``, ``mindist_many``, ``collide_many``,
``offroad_many``, ``goal_many``, ``dist_goal_many``. ``states`` is an ``(n, 7)`` integer array with
the columns of :class:`rac.model.native.State` (``x, y, v, acc, head, jerk, turn``: significands)
and ``k`` is one sample index or an ``(n,)`` array of them. Each result equals what
:class:`rac.model.native.NativeModel` gives for every row, bit for bit: the same operations in the
same order on doubles (numpy's ufuncs neither fuse nor reorder), ``np.sqrt`` (correctly rounded,
like ``math.sqrt``), and cos/sin taken from ``math.cos``/``math.sin`` (the C library) over the
distinct headings only, because numpy's SIMD ``np.cos``/``np.sin`` may differ from the C library in
the last bit on some platforms.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

from rac.ir.vocabulary import EGO_STATE
from rac.model.data import ModelData, ModelRangeError
from rac.model.native import CORNERS, NO_OBSTACLE, NativeModel

__all__ = ["BLOCK", "BatchModel", "batch_model", "collide_many", "dist_goal_many", "distinct_values", "goal_many",
           "mindist_many", "offroad_many", "sense_many"]

#: The model functions of :class:`BatchModel` work through larger arrays in blocks of this many rows.
BLOCK = 1 << 16


def _cos_sin(angles: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``math.cos`` and ``math.sin`` of every element, called once per distinct bit pattern."""
    flat = np.ascontiguousarray(angles, dtype=np.float64)
    bits, inverse = np.unique(flat.view(np.int64), return_inverse=True)
    values = bits.view(np.float64).tolist()
    cos = np.array([math.cos(t) for t in values], dtype=np.float64)
    sin = np.array([math.sin(t) for t in values], dtype=np.float64)
    inverse = inverse.reshape(-1)
    return cos[inverse], sin[inverse]


#: :func:`distinct_values` marks values in a table instead of sorting them while they span at most this
#: many integers (or four times the number of values, when that is more).
_DENSE_SPAN = 1 << 16


def distinct_values(values: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``np.unique(values, return_inverse=True)`` of a 1-d integer array (int64 results).

    When the values span few integers this marks them in a table instead of sorting (linear
    time); the result is the same: the distinct values ascending, and each element's index
    among them."""
    values = np.asarray(values, dtype=np.int64).reshape(-1)
    if values.size == 0:
        return values.copy(), np.zeros(0, dtype=np.int64)
    low = int(values.min())
    span = int(values.max()) - low + 1
    if span > max(_DENSE_SPAN, 4 * values.size):
        distinct, inverse = np.unique(values, return_inverse=True)
        return distinct, inverse.reshape(-1).astype(np.int64, copy=False)
    offset = values - low
    present = np.zeros(span, dtype=bool)
    present[offset] = True
    distinct = np.flatnonzero(present)
    rank = np.cumsum(present, dtype=np.int64)
    rank -= 1
    return distinct + low, rank[offset]


def _cos_sin_of_significands(head: np.ndarray, scale: float) -> tuple[np.ndarray, np.ndarray]:
    """:func:`_cos_sin` of ``head / scale`` for integer ``head``: equal integers give equal
    doubles, so the distinct integers are found without sorting doubles."""
    distinct, inverse = distinct_values(head)
    cos, sin = _cos_sin(distinct / scale)
    return cos[inverse], sin[inverse]


class _Polygons:
    """Flattened polygons (``xs[start[p]:start[p + 1]]``, ``ys`` likewise) prepared for
    :meth:`inside`, the crossing test of :func:`rac.model.native.point_in_polygons` on arrays.

    Per polygon: its bounding box, and its *bands*: between two consecutive distinct vertex
    y-values ``Y[b] <= y < Y[b + 1]`` the same edges pass the test ``(yi > py) != (yj > py)``,
    namely those with ``min(yi, yj) <= Y[b]`` and ``Y[b + 1] <= max(yi, yj)`` (both ends are
    vertex y-values, and none lies strictly inside a band). So a point tests only the (few)
    edges of its band: ``px < (xj - xi) * (py - yi) / (yj - yi) + xi`` with the same operations
    on the same doubles, and it is inside when an odd number of them hold."""

    def __init__(self, xs: list[float], ys: list[float], start: tuple[int, ...]) -> None:
        #: Per polygon: (x low, x high, margin, y low, y high, band bounds Y, table of
        #: (band, slot) -> xj - xi, yi, yj - yi, xi and whether the slot holds an edge).
        self.parts: list[tuple[float, float, float, float, float, np.ndarray, np.ndarray, np.ndarray,
                               np.ndarray, np.ndarray, np.ndarray]] = []
        for p in range(len(start) - 1):
            if start[p + 1] == start[p]:
                continue
            pxs, pys = xs[start[p]:start[p + 1]], ys[start[p]:start[p + 1]]
            low, high = min(pxs), max(pxs)
            margin = 1e-6 * (abs(low) + abs(high)) + 1e-6
            xi = np.asarray(pxs, dtype=np.float64)
            yi = np.asarray(pys, dtype=np.float64)
            xj = np.roll(xi, 1)  # the vertex before i, cyclically
            yj = np.roll(yi, 1)
            bounds = np.unique(yi)
            if bounds.size < 2:
                continue  # no band: no point has min(y) <= py < max(y)
            crossing = ((np.minimum(yi, yj)[None, :] <= bounds[:-1, None])
                        & (bounds[1:, None] <= np.maximum(yi, yj)[None, :]))  # (band, edge)
            slots = max(1, int(crossing.sum(axis=1).max()))
            edge = np.zeros((len(bounds) - 1, slots), dtype=np.int64)
            used = np.zeros((len(bounds) - 1, slots), dtype=bool)
            for band, edges in enumerate(crossing):
                found = np.flatnonzero(edges)
                edge[band, :found.size] = found
                used[band, :found.size] = True
            self.parts.append((low, high, margin, min(pys), max(pys), bounds, (xj - xi)[edge], yi[edge],
                               (yj - yi)[edge], xi[edge], used))

    def inside(self, px: np.ndarray, py: np.ndarray) -> np.ndarray:
        """Whether each point lies inside one of the polygons (bool array like ``px``)."""
        px = np.asarray(px, dtype=np.float64)
        py = np.asarray(py, dtype=np.float64)
        found = np.zeros(px.shape, dtype=bool)
        with np.errstate(divide="ignore", invalid="ignore"):
            for low, high, margin, y_low, y_high, bounds, dx, yi, dy, xi, used in self.parts:
                # (a point found inside an earlier polygon need not be tested again)
                rows = np.flatnonzero((py >= y_low) & (py < y_high) & (px >= low - margin)
                                      & (px <= high + margin) & ~found)
                if rows.size == 0:
                    continue
                qx = px[rows]
                qy = py[rows]
                band = np.searchsorted(bounds, qy, side="right") - 1
                inside = np.zeros(rows.shape, dtype=bool)
                for slot in range(used.shape[1]):
                    crosses = qx < dx[band, slot] * (qy - yi[band, slot]) / dy[band, slot] + xi[band, slot]
                    if not used[:, slot].all():
                        crosses &= used[band, slot]
                    inside ^= crosses
                found[rows] = inside
        return found


def _inside(xs: list[float], ys: list[float], start: tuple[int, ...], px: np.ndarray,
            py: np.ndarray) -> np.ndarray:
    """:func:`rac.model.native.point_in_polygons` for arrays of points (same crossing test).

    Only the points in a polygon's bounding box are tested against it; that changes no answer:
    below ``min(y)`` or at/above ``max(y)`` no edge passes the test ``(yi > py) != (yj > py)``;
    left of the box every crossing edge counts, and there is an even number of them; right of
    the box (beyond a margin far larger than rounding) none counts. Within the box a point tests
    only the edges that pass that test for it (:class:`_Polygons`)."""
    return _Polygons(xs, ys, start).inside(px, py)


class BatchModel:
    """:class:`NativeModel`'s functions over arrays of states (see the module docstring)."""

    def __init__(self, data: ModelData) -> None:
        self.data = data
        self.native = NativeModel(data)
        self._road = _Polygons(self.native.road_xd, self.native.road_yd, data.road_start)
        self._goal = _Polygons(self.native.goal_xd, self.native.goal_yd, data.goal_start)

    def _ego(self, states: np.ndarray) -> np.ndarray:
        states = np.asarray(states)
        if states.ndim != 2 or states.shape[1] != len(EGO_STATE):
            raise ValueError(f"states must have shape (n, {len(EGO_STATE)}), not {states.shape}")
        return states

    def _samples(self, k: int | np.ndarray, n: int) -> np.ndarray:
        return np.broadcast_to(np.asarray(k, dtype=np.int64), (n,))

    def _blockwise(self, method: Callable[..., np.ndarray], states: np.ndarray,
                   k: int | np.ndarray | None = None) -> np.ndarray:
        """``method(states[, k])`` over blocks of :data:`BLOCK` rows, concatenated. Every result
        is row by row, so blocks change no value; they keep the temporaries small (in cache,
        and not allocated afresh by the operating system for every operation)."""
        n = states.shape[0]
        if n <= BLOCK:
            return method(states) if k is None else method(states, k)
        samples = None if k is None or np.ndim(k) == 0 else self._samples(k, n)
        parts = []
        for low in range(0, n, BLOCK):
            block = states[low:low + BLOCK]
            if k is None:
                parts.append(method(block))
            else:
                parts.append(method(block, k if samples is None else samples[low:low + BLOCK]))
        return np.concatenate(parts)

    def sense(self, states: np.ndarray) -> np.ndarray:
        """:meth:`NativeModel.sense` of every row: an ``(n, 7)`` int32 array (jerk, turn kept).
        :class:`ModelRangeError` for the first row whose result does not fit int32."""
        states = self._ego(states)
        try:
            return self._blockwise(self._sense, states)
        except ModelRangeError:
            if states.shape[0] <= BLOCK:
                raise
            return self._sense(states)  # the error of the first value out of range in the whole array

    def _sense(self, states: np.ndarray) -> np.ndarray:
        native = self.native
        scale = native.scale_d
        x = states[:, 0] / scale
        y = states[:, 1] / scale
        v = states[:, 2] / scale
        acc = states[:, 3] / scale
        jerk = states[:, 5] / scale
        # A row's headings depend on its (head, turn) only: they are followed for the distinct
        # pairs (the same operations on the same doubles) and gathered back (``pair``).
        heads, head_rank = distinct_values(states[:, 4])
        turns, turn_rank = distinct_values(states[:, 6])
        pairs, pair = distinct_values(head_rank * len(turns) + turn_rank)
        head = heads[pairs // len(turns)] / scale
        turn = turns[pairs % len(turns)] / scale
        u = self.data.unit
        ma = native.max_acc_d
        vmin = native.min_speed_d
        vmax = native.max_speed_d
        for _ in range(self.data.substeps):
            acc = acc + jerk * u
            acc = np.where(acc > ma, ma, acc)
            acc = np.where(acc < -ma, -ma, acc)
            head = head + turn * u
            v = v + acc * u
            v = np.where(v > vmax, vmax, v)
            v = np.where(v < vmin, vmin, v)
            cos, sin = _cos_sin(head)
            x = x + v * cos[pair] * u
            y = y + v * sin[pair] * u
        head = head[pair]
        out = np.empty(states.shape, dtype=np.int32)
        for column, (what, value) in enumerate((("x", x), ("y", y), ("v", v), ("acc", acc), ("head", head))):
            scaled = value * scale
            bad = ~((scaled > -2147483648.0) & (scaled < 2147483648.0))  # also NaN
            if bad.any():
                row = int(np.flatnonzero(bad)[0])
                native.significand(what, float(value[row]))  # raises the same error as native
                raise ModelRangeError(f"sense(): {what}", float(value[row]), None, self.data.scale)
            out[:, column] = scaled.astype(np.int64)  # truncation toward zero, like int()
        out[:, 5] = states[:, 5]
        out[:, 6] = states[:, 6]
        return out

    def mindist(self, states: np.ndarray, k: int | np.ndarray) -> np.ndarray:
        """:meth:`NativeModel.mindist` of every row at its sample: ``(n,)`` float64."""
        return self._blockwise(self._mindist, self._ego(states), k)

    def _mindist(self, states: np.ndarray, k: int | np.ndarray) -> np.ndarray:
        n = states.shape[0]
        data = self.data
        native = self.native
        scale = native.scale_d
        best = np.full(n, NO_OBSTACLE, dtype=np.float64)
        if data.obstacle_count == 0 or n == 0:
            return best
        if np.ndim(k) == 0:
            samples, where = np.asarray([k], dtype=np.int64), None  # one sample: scalars below
        else:
            samples, where = np.unique(self._samples(k, n), return_inverse=True)
            where = where.reshape(-1)
        ex = states[:, 0] / scale
        ey = states[:, 1] / scale
        ec, es = _cos_sin_of_significands(states[:, 4], scale)
        el = native.length_d
        ew = native.width_d
        er = math.sqrt((el / 6.0) * (el / 6.0) + (ew / 2.0) * (ew / 2.0))
        eoff = el / 3.0
        for i in range(data.obstacle_count):
            # the obstacle's discs per distinct sample, computed by the scalar code of native.py
            present = np.zeros(len(samples), dtype=bool)
            bx = np.zeros((3, len(samples)))
            by = np.zeros((3, len(samples)))
            ol = data.obs_length[i] / scale
            ow = data.obs_width[i] / scale
            orad = math.sqrt((ol / 6.0) * (ol / 6.0) + (ow / 2.0) * (ow / 2.0))
            ooff = ol / 3.0
            for s, sample in enumerate(samples.tolist()):
                position = native.obstacle_position(i, sample)
                if position is None:
                    continue
                ox, oy, oh = position
                oc = math.cos(oh)
                os_ = math.sin(oh)
                present[s] = True
                for b in range(3):
                    bx[b, s] = ox + (b - 1) * ooff * oc
                    by[b, s] = oy + (b - 1) * ooff * os_
            if not present.any():
                continue
            here = None if where is None else present[where]  # one sample: present (else skipped)
            for a in range(3):
                ax = ex + (a - 1) * eoff * ec
                ay = ey + (a - 1) * eoff * es
                for b in range(3):
                    dx = ax - (bx[b, 0] if where is None else bx[b][where])
                    dy = ay - (by[b, 0] if where is None else by[b][where])
                    d = np.sqrt(dx * dx + dy * dy) - er - orad
                    closer = d < best
                    if here is not None:
                        closer &= here
                    best = np.where(closer, d, best)
        return best

    def collide(self, states: np.ndarray, k: int | np.ndarray) -> np.ndarray:
        """``mindist < TD`` per row: ``(n,)`` bool."""
        return self.mindist(states, k) < self.native.td_d

    def offroad(self, states: np.ndarray) -> np.ndarray:
        """:meth:`NativeModel.offroad` per row: a corner of the ego outside every road polygon."""
        return self._blockwise(self._offroad, self._ego(states))

    def _offroad(self, states: np.ndarray) -> np.ndarray:
        native = self.native
        scale = native.scale_d
        ex = states[:, 0] / scale
        ey = states[:, 1] / scale
        c, s = _cos_sin_of_significands(states[:, 4], scale)
        hl = native.length_d / 2.0
        hw = native.width_d / 2.0
        px = np.concatenate([ex + ca * hl * c - cb * hw * s for ca, cb in CORNERS])
        py = np.concatenate([ey + ca * hl * s + cb * hw * c for ca, cb in CORNERS])
        inside = self._road.inside(px, py)
        return ~np.all(inside.reshape(len(CORNERS), states.shape[0]), axis=0)

    def goal(self, states: np.ndarray, k: int | np.ndarray) -> np.ndarray:
        """:meth:`NativeModel.goal` per row: in the goal interval and the centre in a goal polygon."""
        return self._blockwise(self._goal_block, self._ego(states), k)

    def _goal_block(self, states: np.ndarray, k: int | np.ndarray) -> np.ndarray:
        data = self.data
        native = self.native
        samples = self._samples(k, states.shape[0])
        scale = native.scale_d
        inside = self._goal.inside(states[:, 0] / scale, states[:, 1] / scale)
        return inside & (samples >= data.goal_low) & (samples <= data.goal_high)

    def dist_goal(self, states: np.ndarray) -> np.ndarray:
        """:meth:`NativeModel.dist_goal` per row: ``(n,)`` float64."""
        states = self._ego(states)
        native = self.native
        scale = native.scale_d
        dx = states[:, 0] / scale - native.goal_cx_d
        dy = states[:, 1] / scale - native.goal_cy_d
        return np.sqrt(dx * dx + dy * dy)


_models: dict[int, tuple[ModelData, BatchModel]] = {}


def batch_model(data: ModelData) -> BatchModel:
    """One :class:`BatchModel` per ModelData object (a small identity cache)."""
    entry = _models.get(id(data))
    if entry is None or entry[0] is not data:
        if len(_models) > 16:
            _models.clear()
        entry = _models[id(data)] = (data, BatchModel(data))
    return entry[1]


def sense_many(data: ModelData, states: np.ndarray) -> np.ndarray:
    """:meth:`BatchModel.sense`."""
    return batch_model(data).sense(states)


def mindist_many(data: ModelData, states: np.ndarray, k: int | np.ndarray) -> np.ndarray:
    """:meth:`BatchModel.mindist`."""
    return batch_model(data).mindist(states, k)


def collide_many(data: ModelData, states: np.ndarray, k: int | np.ndarray) -> np.ndarray:
    """:meth:`BatchModel.collide`."""
    return batch_model(data).collide(states, k)


def offroad_many(data: ModelData, states: np.ndarray) -> np.ndarray:
    """:meth:`BatchModel.offroad`."""
    return batch_model(data).offroad(states)


def goal_many(data: ModelData, states: np.ndarray, k: int | np.ndarray) -> np.ndarray:
    """:meth:`BatchModel.goal`."""
    return batch_model(data).goal(states, k)


def dist_goal_many(data: ModelData, states: np.ndarray) -> np.ndarray:
    """:meth:`BatchModel.dist_goal`."""
    return batch_model(data).dist_goal(states)
