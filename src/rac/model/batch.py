"""The scenario model's functions over arrays of states, vectorised with numpy (issue 4).

:class:`BatchModel` and the ``*_many`` shorthands: ``sense_many``, ``mindist_many``, ``collide_many``,
``offroad_many``, ``goal_many``, ``dist_goal_many``. ``states`` is an ``(n, 7)`` integer array with
the columns of :class:`rac.model.native.State` (``x, y, v, acc, head, jerk, turn``: significands)
and ``k`` is one sample index or an ``(n,)`` array of them. Each result equals what
:class:`rac.model.native.NativeModel` gives for every row, bit for bit: the same operations in the
same order on doubles (numpy's ufuncs neither fuse nor reorder), ``np.sqrt`` (correctly rounded,
like ``math.sqrt``), and cos/sin taken from ``math.cos``/``math.sin`` (the C library), because
numpy's SIMD ``np.cos``/``np.sin`` may differ from the C library in the last bit on some platforms.

What depends on a few integers only is computed once per distinct value and kept
(:class:`rac.model.memo.KeyedRows`; issue 11): the cos/sin of a heading; the ``1/G`` Euler
sub-steps' headings and their cos/sin, per (head, turn) pair; the sub-steps' speeds and the
final acceleration, per (v, acc, jerk); the obstacles' discs per sample. A sample of ``n``
episodes is then a fixed number of array operations: the positions add up the sub-steps' moves
``v * cos(head) * u`` in order (``np.add.accumulate``, a left-to-right sum), and ``mindist`` takes
every (ego disc, obstacle disc) pair at once (an absent obstacle's discs are NaN, which
``np.fmin`` skips as the scalar code skips the obstacle).
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

from rac.core.numbers import INT32_BOUND
from rac.ir.vocabulary import EGO_STATE
from rac.model.data import ModelData, ModelRangeError
from rac.model.memo import KeyedRows, cos_sin, distinct_values
from rac.model.native import CORNERS, NO_OBSTACLE, NativeModel
from rac.model.polygons import Polygons
from rac.model.sample import ACTION, MOTION, Ego, collides

__all__ = ["BLOCK", "BatchModel", "batch_model", "collide_many", "dist_goal_many", "distinct_values", "goal_many",
           "mindist_many", "offroad_many", "sense_many"]

#: The model functions of :class:`BatchModel` work through larger arrays in blocks of this many rows.
BLOCK = 1 << 16
#: ... and ``sense`` in blocks of this many (its kept sub-steps are rows of 2 * substeps + 1 doubles).
SENSE_BLOCK = 1 << 13
#: ``mindist`` compares the ego's discs with at most this many obstacle discs' doubles at a time.
DISC_CELLS = 1 << 16
#: Up to this many states look their kept rows up one by one; more look up their distinct keys.
_DIRECT_ROWS = 256
#: :meth:`BatchModel._sense_few` sums the moves of up to this many rows along each row (one numpy call),
#: of more rows one sub-step at a time over all rows (m calls, each cheaper than the strided sum's share).
_RUNNING_ROWS = 32
#: New keys up to this many are computed on Python floats (numpy costs more per call than per row there).
_SCALAR_ROWS = 48
#: (v, acc, jerk) significands in ``(-_FIELD, _FIELD)`` pack into one int64 key (21 bits each).
_FIELD = 1 << 20


def _pair_keys(head: np.ndarray, turn: np.ndarray) -> np.ndarray:
    """One int64 per (head, turn) pair of int32 significands: head in the high 32 bits."""
    return (np.asarray(head, dtype=np.int64) << 32) | (np.asarray(turn, dtype=np.int64) & 0xFFFFFFFF)


class BatchModel:
    """:class:`NativeModel`'s functions over arrays of states (see the module docstring)."""

    def __init__(self, data: ModelData) -> None:
        self.data = data
        self.native = NativeModel(data)
        self._road = Polygons(self.native.road_xd, self.native.road_yd, data.road_start)
        self._goal = Polygons(self.native.goal_xd, self.native.goal_yd, data.goal_start)
        m = data.substeps
        #: heading significand -> cos, sin of it
        self._trig = KeyedRows(2, self._trig_rows)
        #: (head, turn) -> the sub-steps' cos (m), sin (m), then the last heading
        self._headings = KeyedRows(2 * m + 1, self._heading_rows)
        #: (v, acc, jerk) -> the sub-steps' speeds (m), then the last speed and acceleration
        self._speeds = KeyedRows(m + 2, self._speed_rows)
        #: the heads of the last few-row cos_sin() call (a copy) and their cos and sin (read only)
        self._last_trig: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None
        #: sample -> the obstacles' disc centres (x then y, 3 per obstacle; NaN: absent)
        self._discs: dict[int, np.ndarray] = {}
        #: sample -> the obstacles' x, y, heading, speed (NaN: absent)
        self._states: dict[int, np.ndarray] = {}
        radii = []
        for i in range(data.obstacle_count):
            ol = data.obs_length[i] / self.native.scale_d
            ow = data.obs_width[i] / self.native.scale_d
            radii += [math.sqrt((ol / 6.0) * (ol / 6.0) + (ow / 2.0) * (ow / 2.0))] * 3
        self._radii = np.asarray(radii, dtype=np.float64)
        hl = self.native.length_d / 2.0
        hw = self.native.width_d / 2.0
        el = self.native.length_d
        ew = self.native.width_d
        eoff = el / 3.0
        #: the ego's disc radius, its discs' offsets ``(a - 1) * eoff`` along its heading (3, 1, 1): _mindist
        self._ego_discs = (math.sqrt((el / 6.0) * (el / 6.0) + (ew / 2.0) * (ew / 2.0)),
                           np.array([(a - 1) * eoff for a in range(3)])[:, None, None])
        #: (4, 1) each: the corners' ``ca * hl`` and ``cb * hw`` (:meth:`_offroad`, every corner at once)
        self._corners = (np.array([ca * hl for ca, _ in CORNERS])[:, None],
                         np.array([cb * hw for _, cb in CORNERS])[:, None])

    def _ego(self, states: np.ndarray) -> np.ndarray:
        states = np.asarray(states)
        if states.ndim != 2 or states.shape[1] != len(EGO_STATE):
            raise ValueError(f"states must have shape (n, {len(EGO_STATE)}), not {states.shape}")
        return states

    def _samples(self, k: int | np.ndarray, n: int) -> np.ndarray:
        """``k`` as ``(n,)`` int64 sample indices, not to be written (one sample: a broadcast view)."""
        if isinstance(k, np.ndarray) and k.shape == (n,) and k.dtype == np.int64:
            return k  # already one per row (broadcast_to costs more than the rest of a small call)
        return np.broadcast_to(np.asarray(k, dtype=np.int64), (n,))

    def _blockwise(self, method: Callable[..., np.ndarray], states: np.ndarray,
                   k: int | np.ndarray | None = None, block: int = BLOCK) -> np.ndarray:
        """``method(states[, k])`` over blocks of ``block`` rows, concatenated. Every result is row
        by row, so blocks change no value; they keep the temporaries small (in cache, and not
        allocated afresh by the operating system for every operation)."""
        n = states.shape[0]
        if n <= block:
            return method(states) if k is None else method(states, k)
        samples = None if k is None or np.ndim(k) == 0 else self._samples(k, n)
        parts = []
        for low in range(0, n, block):
            rows = states[low:low + block]
            if k is None:
                parts.append(method(rows))
            else:
                parts.append(method(rows, k if samples is None else samples[low:low + block]))
        return np.concatenate(parts)

    def sense(self, states: np.ndarray) -> np.ndarray:
        """:meth:`NativeModel.sense` of every row: an ``(n, 7)`` int32 array (jerk, turn kept).
        :class:`ModelRangeError` for the first row whose result does not fit int32."""
        states = self._ego(states)
        if self.data.increments:
            return self._blockwise(self._sense_increments, states)
        try:
            return self._blockwise(self._sense, states, block=SENSE_BLOCK)
        except ModelRangeError:
            if states.shape[0] <= BLOCK:
                raise
            return self._sense(states)  # the error of the first value out of range in the whole array

    def _sense(self, states: np.ndarray) -> np.ndarray:
        native = self.native
        scale = native.scale_d
        m = self.data.substeps
        n = states.shape[0]
        if n <= _DIRECT_ROWS:
            return self._sense_few(states)
        # The sub-steps' cos, sin (and last heading) per (head, turn) pair and speeds (and last
        # speed and acceleration) per (v, acc, jerk), kept: a table of rows and each state's row.
        # The distinct pairs from the distinct heads and turns (few values: no sorting).
        heads, head_rank = distinct_values(states[:, Ego.HEAD])
        turns, turn_rank = distinct_values(states[:, Ego.TURN])
        pairs, pair = distinct_values(head_rank * len(turns) + turn_rank)
        heading = self._headings(_pair_keys(heads[pairs // len(turns)], turns[pairs % len(turns)]))
        speeds, speed = self._speed_table(states)
        x, y = (self._moved(states[:, column] / scale, speeds, speed, heading[:, part], pair)
                for column, part in ((Ego.X, slice(0, m)), (Ego.Y, slice(m, 2 * m))))
        values = np.stack([x, y, speeds[speed, m], speeds[speed, m + 1], heading[pair, 2 * m]])  # x, y, v, acc, head
        return self._sensed(states, values)

    def _sensed(self, states: np.ndarray, values: np.ndarray) -> np.ndarray:
        """The sensed states: ``states``' actions with the motion ``values`` ``(5, n)`` (x, y, v, acc, head,
        as doubles) as significands, truncated toward zero like ``int()``; native's error for the first
        value out of the int32 range (its column first, then its row)."""
        native = self.native
        scaled = values * native.scale_d
        bad = ~((scaled > -INT32_BOUND) & (scaled < INT32_BOUND))  # also NaN
        if bad.any():  # the first column with a value out of range, at its first row (as native)
            column, row = divmod(int(np.argmax(bad)), states.shape[0])
            what = ("x", "y", "v", "acc", "head")[column]
            native.significand(what, float(values[column, row]))  # raises the same error as native
            raise ModelRangeError(f"sense(): {what}", float(values[column, row]), None, self.data.scale)
        out = np.empty(states.shape, dtype=np.int32)
        out[:, MOTION] = scaled.T.astype(np.int64)
        out[:, ACTION] = states[:, ACTION]
        return out

    def _sense_few(self, states: np.ndarray) -> np.ndarray:
        """:meth:`_sense` of up to ``_DIRECT_ROWS`` rows, each looking its kept rows up itself: the same
        operations on the same doubles, x and y moved together (one running sum along each of their rows)."""
        native = self.native
        scale = native.scale_d
        m = self.data.substeps
        n = states.shape[0]
        heading = self._headings(_pair_keys(states[:, Ego.HEAD], states[:, Ego.TURN]))  # (n, 2m + 1)
        speeds = self._speed_table(states)[0]  # (n, m + 2): every row its own
        values = np.empty((n, 5), dtype=np.float64)  # x, y, v, acc, head
        if n <= _RUNNING_ROWS:  # (n, 2, m + 1): x then y, each its start and the moves v * cos * u, v * sin * u
            moves = np.empty((n, 2, m + 1), dtype=np.float64)
            moves[:, 0, 0] = states[:, Ego.X] / scale
            moves[:, 1, 0] = states[:, Ego.Y] / scale
            np.multiply(speeds[:, None, :m], heading[:, :2 * m].reshape(n, 2, m), out=moves[:, :, 1:])
            moves[:, :, 1:] *= self.data.unit
            values[:, :2] = np.add.accumulate(moves, axis=2)[:, :, m]  # one running sum along each row
        else:  # the moves as (m, 2, n), added to the starts one sub-step after the other (as _moved)
            steps = np.empty((m, 2, n), dtype=np.float64)
            np.multiply(speeds[:, :m].T[:, None, :], heading[:, :2 * m].reshape(n, 2, m).transpose(2, 1, 0),
                        out=steps)
            steps *= self.data.unit
            position = np.empty((2, n), dtype=np.float64)
            position[0] = states[:, Ego.X] / scale
            position[1] = states[:, Ego.Y] / scale
            for step in steps:
                position += step
            values[:, :2] = position.T
        values[:, 2:4] = speeds[:, m:m + 2]
        values[:, 4] = heading[:, 2 * m]
        return self._sensed(states, values.T)

    def _sense_increments(self, states: np.ndarray) -> np.ndarray:
        """:meth:`NativeModel.sense_increments` of every row, the same operations on int64 and doubles."""
        data = self.data
        scale = self.native.scale_d
        u = data.unit
        x, y, v, acc, head = (states[:, column].astype(np.int64) for column in Ego if column < Ego.JERK)
        jerk_step = self._increment("acc", states[:, Ego.JERK] / scale * u)
        turn_step = self._increment("head", states[:, Ego.TURN] / scale * u)
        for _ in range(data.substeps):
            acc = np.clip(acc + jerk_step, -data.max_acc, data.max_acc)  # two comparisons: hi, then lo
            head = head + turn_step
            v = v + self._increment("v", acc / scale * u)
            v = np.where(v > data.max_speed, data.max_speed, v)
            v = np.where(v < data.min_speed, data.min_speed, v)
            cos, sin = self.cos_sin(head)
            speed = v / scale
            x = x + self._increment("x", speed * cos * u)
            y = y + self._increment("y", speed * sin * u)
        out = np.empty(states.shape, dtype=np.int32)
        for column, (what, value) in enumerate((("x", x), ("y", y), ("v", v), ("acc", acc), ("head", head))):
            bad = (value <= -INT32_BOUND) | (value >= INT32_BOUND)
            if bad.any():
                row = int(np.argmax(bad))
                raise ModelRangeError(f"sense(): {what}", int(value[row]) / scale, int(value[row]), data.scale)
            out[:, column] = value
        out[:, ACTION] = states[:, ACTION]
        return out

    def _increment(self, what: str, value: np.ndarray) -> np.ndarray:
        """``trunc(value * SCALE_D)`` as int64, or :class:`ModelRangeError` (as native) for the first
        value beyond int32."""
        scaled = value * self.native.scale_d
        bad = ~((scaled > -INT32_BOUND) & (scaled < INT32_BOUND))
        if bad.any():
            self.native.significand(what, float(value[int(np.argmax(bad))]))
        return scaled.astype(np.int64)

    def _moved(self, start: np.ndarray, speeds: np.ndarray, speed: np.ndarray, trig: np.ndarray,
               pair: np.ndarray) -> np.ndarray:
        """``start`` plus the sub-steps' moves ``v * trig * u`` (``v``: rows ``speed`` of ``speeds``,
        ``trig``: rows ``pair`` of ``trig``), added in order as the scalar loop adds them (many rows:
        :meth:`_sense_few` moves a few)."""
        m = self.data.substeps
        u = self.data.unit
        steps = np.take(np.ascontiguousarray(speeds[:, :m].T), speed, axis=1)  # (m, n)
        steps *= np.take(np.ascontiguousarray(trig.T), pair, axis=1)
        steps *= u
        for move in steps:
            start = start + move
        return start

    def _speed_table(self, states: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """:meth:`_speed_rows` of the rows' (v, acc, jerk), kept while they fit the key: the rows and
        each state's row."""
        triple = states[:, (Ego.V, Ego.ACC, Ego.JERK)].astype(np.int64)
        if triple.size and (triple.min() <= -_FIELD or triple.max() >= _FIELD):
            return self._speed_rows(None, triple), np.arange(states.shape[0])
        triple += _FIELD
        keys = (triple[:, 0] << 42) | (triple[:, 1] << 21) | triple[:, 2]
        return self._speeds.table(keys) if keys.size > _DIRECT_ROWS else (self._speeds(keys), np.arange(keys.size))

    def _speed_rows(self, keys: np.ndarray | None, triple: np.ndarray | None = None) -> np.ndarray:
        """``(n, m + 2)``: the speed after each of the ``m`` Euler sub-steps of :meth:`NativeModel.sense`,
        then the last speed and acceleration, for (v, acc, jerk) significands (packed ``keys``, or
        ``triple`` rows)."""
        if triple is None:
            assert keys is not None
            triple = np.stack([keys >> 42, (keys >> 21) & (2 * _FIELD - 1), keys & (2 * _FIELD - 1)], axis=1) - _FIELD
        native = self.native
        scale = native.scale_d
        m = self.data.substeps
        u = self.data.unit
        ma = native.max_acc_d
        vmin = native.min_speed_d
        vmax = native.max_speed_d
        if triple.shape[0] <= _SCALAR_ROWS:  # a few new keys: on Python floats, the same operations
            return np.array([self._speed_row(*row) for row in triple.tolist()], dtype=np.float64).reshape(-1, m + 2)
        v = triple[:, 0] / scale
        acc = triple[:, 1] / scale
        jerk = triple[:, 2] / scale
        out = np.empty((triple.shape[0], m + 2), dtype=np.float64)
        for step in range(m):
            acc = acc + jerk * u
            acc = np.where(acc > ma, ma, acc)
            acc = np.where(acc < -ma, -ma, acc)
            v = v + acc * u
            v = np.where(v > vmax, vmax, v)
            v = np.where(v < vmin, vmin, v)
            out[:, step] = v
        out[:, m] = v
        out[:, m + 1] = acc
        return out

    def _speed_row(self, v_sig: int, acc_sig: int, jerk_sig: int) -> list[float]:
        """One row of :meth:`_speed_rows` on Python floats (IEEE doubles, as numpy's)."""
        native = self.native
        scale = native.scale_d
        u = self.data.unit
        ma, vmin, vmax = native.max_acc_d, native.min_speed_d, native.max_speed_d
        v = v_sig / scale
        acc = acc_sig / scale
        jerk = jerk_sig / scale
        speeds = []
        for _ in range(self.data.substeps):
            acc = acc + jerk * u
            acc = ma if acc > ma else acc
            acc = -ma if acc < -ma else acc
            v = v + acc * u
            v = vmax if v > vmax else v
            v = vmin if v < vmin else v
            speeds.append(v)
        return [*speeds, v, acc]

    def _heading_rows(self, keys: np.ndarray) -> np.ndarray:
        """``(n, 2m + 1)`` for (head, turn) keys (:func:`_pair_keys`): the heading after each Euler
        sub-step of :meth:`NativeModel.sense` (``head = head + turn * u``), its cos (m columns) and
        sin (m columns), then the last heading."""
        scale = self.native.scale_d
        m = self.data.substeps
        u = self.data.unit
        if keys.size <= _SCALAR_ROWS:  # a few new keys: on Python floats, the same operations
            return np.array([self._heading_row(key) for key in keys.tolist()], dtype=np.float64).reshape(-1, 2 * m + 1)
        low = keys & 0xFFFFFFFF
        head = (keys >> 32) / scale
        turn = np.where(low >= INT32_BOUND, low - 2 * INT32_BOUND, low) / scale  # the low 32 bits as an int32
        angles = np.empty((keys.size, m), dtype=np.float64)
        for step in range(m):
            head = head + turn * u
            angles[:, step] = head
        cos, sin = cos_sin(angles)
        return np.concatenate([cos, sin, head[:, None]], axis=1)

    def _heading_row(self, key: int) -> list[float]:
        """One row of :meth:`_heading_rows` on Python floats (IEEE doubles, as numpy's; ``math.cos`` and
        ``math.sin``, as :func:`rac.model.memo.cos_sin`)."""
        scale = self.native.scale_d
        u = self.data.unit
        low = key & 0xFFFFFFFF
        head = (key >> 32) / scale
        turn = (low - 2 * INT32_BOUND if low >= INT32_BOUND else low) / scale
        angles = []
        for _ in range(self.data.substeps):
            head = head + turn * u
            angles.append(head)
        return [*map(math.cos, angles), *map(math.sin, angles), head]

    def _trig_rows(self, heads: np.ndarray) -> np.ndarray:
        """``(n, 2)``: cos and sin of heading significands over the scale (``math.cos``/``math.sin``)."""
        cos, sin = cos_sin(heads / self.native.scale_d)
        return np.stack([cos, sin], axis=1)

    def cos_sin(self, head: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``math.cos`` and ``math.sin`` of ``head / SCALE_D`` for integer heading significands."""
        head = np.asarray(head, dtype=np.int64)
        if head.size <= _DIRECT_ROWS:
            # mindist() and offroad() of one frame ask for the same heads: the last answer is kept
            last = self._last_trig
            if last is not None and last[0].shape == head.shape and np.array_equal(last[0], head):
                return last[1], last[2]
            trig = self._trig(head)
            cos, sin = trig[:, 0], trig[:, 1]
            cos.flags.writeable = sin.flags.writeable = False  # shared by the callers: read only
            self._last_trig = (head.copy(), cos, sin)
            return cos, sin
        trig, inverse = self._trig.table(head)
        return trig[inverse, 0], trig[inverse, 1]

    def mindist(self, states: np.ndarray, k: int | np.ndarray) -> np.ndarray:
        """:meth:`NativeModel.mindist` of every row at its sample: ``(n,)`` float64."""
        return self._blockwise(self._mindist, self._ego(states), k)

    def _obstacle_discs(self, sample: int) -> np.ndarray:
        """``(2, 3 * O)``: the centres' x and y of every obstacle's three discs at ``sample``, by
        the scalar code of :meth:`NativeModel.mindist`; NaN for an obstacle absent at the sample."""
        discs = self._discs.get(sample)
        if discs is not None:
            return discs
        data = self.data
        native = self.native
        discs = np.full((2, 3 * data.obstacle_count), np.nan)
        positions = [native.obstacle_position(i, sample) for i in range(data.obstacle_count)]
        for i, (ox, oy, oh) in ((i, p) for i, p in enumerate(positions) if p is not None):
            cos_sin_oh = (math.cos(oh), math.sin(oh))
            ooff = data.obs_length[i] / native.scale_d / 3.0
            for b in range(3):  # ox + (b - 1) * ooff * cos(oh), as NativeModel.mindist
                discs[0, 3 * i + b] = ox + (b - 1) * ooff * cos_sin_oh[0]
                discs[1, 3 * i + b] = oy + (b - 1) * ooff * cos_sin_oh[1]
        if len(self._discs) > 4096:
            self._discs.clear()
        self._discs[sample] = discs
        return discs

    def obstacle_states(self, k: int | np.ndarray) -> np.ndarray:
        """``(n, O, 4)`` float64 for ``n`` samples ``k`` (one sample: ``n = 1``): each obstacle's
        ``x, y, heading`` (:meth:`NativeModel.obstacle_position`, the one owner of an obstacle's
        position) and speed (its waypoint's) at the sample, in metres, radians and m/s; NaN where
        the obstacle does not exist. Computed once per distinct sample and kept."""
        samples = np.atleast_1d(np.asarray(k, dtype=np.int64))
        distinct, where = np.unique(samples, return_inverse=True)
        table = np.stack([self._obstacle_state(int(sample)) for sample in distinct.tolist()]) if distinct.size else \
            np.zeros((0, self.data.obstacle_count, 4))
        return table[where.reshape(-1)]

    def _obstacle_state(self, sample: int) -> np.ndarray:
        row = self._states.get(sample)
        if row is not None:
            return row
        data = self.data
        native = self.native
        row = np.full((data.obstacle_count, 4), np.nan)
        for i in range(data.obstacle_count):
            position = native.obstacle_position(i, sample)
            if position is not None:
                row[i] = (*position, data.wp_vel[native.waypoint(i, sample)] / native.scale_d)
        if len(self._states) > 4096:
            self._states.clear()
        self._states[sample] = row
        return row

    def _mindist(self, states: np.ndarray, k: int | np.ndarray) -> np.ndarray:
        n = states.shape[0]
        data = self.data
        native = self.native
        scale = native.scale_d
        best = np.full(n, NO_OBSTACLE, dtype=np.float64)
        if data.obstacle_count == 0 or n == 0:
            return best
        samples = self._samples(k, n)
        if samples[0] == samples[-1] and (np.ndim(k) == 0 or (samples == samples[0]).all()):
            discs, where = self._obstacle_discs(int(samples[0]))[:, None, :], None  # (2, 1, D): one row for all
        else:
            distinct, where = distinct_values(samples)
            discs = np.stack([self._obstacle_discs(sample) for sample in distinct.tolist()], axis=1)  # (2, S, D)
        ec, es = self.cos_sin(states[:, Ego.HEAD])
        er, along = self._ego_discs
        # the ego's disc centres ex + (a - 1) * eoff * ec (a = 0, 1, 2) as (3, 1, n): the states last
        ax = states[:, Ego.X] / scale + along * ec
        ay = states[:, Ego.Y] / scale + along * es
        width = discs.shape[2]
        chunk = max(1, min(width, DISC_CELLS // (3 * n)))  # temporaries of at most DISC_CELLS doubles
        with np.errstate(invalid="ignore"):
            for low in range(0, width, chunk):
                columns = slice(low, low + chunk)
                # the obstacles' disc centres as (1, c, 1) (one sample) or (1, c, n) (each row's)
                bx = discs[0, :, columns].T[None] if where is None else discs[0][where, columns].T[None]
                by = discs[1, :, columns].T[None] if where is None else discs[1][where, columns].T[None]
                # d = sqrt(dx * dx + dy * dy) - er - radius, each operation in place (the same doubles)
                d = np.subtract(ax, bx)
                d *= d
                dy = np.subtract(ay, by)
                dy *= dy
                d += dy
                np.sqrt(d, out=d)
                d -= er
                d -= self._radii[columns, None]
                # the smallest d (NaN, an absent obstacle, is skipped as the scalar code skips it)
                np.fmin(best, np.fmin.reduce(d.reshape(-1, n), axis=0), out=best)
        return best

    def collide(self, states: np.ndarray, k: int | np.ndarray) -> np.ndarray:
        """``mindist < TD`` per row: ``(n,)`` bool."""
        return collides(self.mindist(states, k), self.native.td_d)

    def offroad(self, states: np.ndarray, k: int | np.ndarray | None = None) -> np.ndarray:
        """:meth:`NativeModel.offroad` per row: a corner of the ego outside every road polygon (and,
        with samples ``k``, not before ``offroad_from``)."""
        states = self._ego(states)
        start = self.data.offroad_from
        if k is None or start == 0 or (np.ndim(k) == 0 and int(k) >= start):
            return self._blockwise(self._offroad, states)
        checked = self._samples(k, states.shape[0]) >= start
        out = np.zeros(states.shape[0], dtype=bool)
        if checked.all():  # no copy of the rows
            return self._blockwise(self._offroad, states)
        if checked.any():
            out[checked] = self._blockwise(self._offroad, states[checked])
        return out

    def _offroad(self, states: np.ndarray) -> np.ndarray:
        native = self.native
        scale = native.scale_d
        ex = states[:, Ego.X] / scale
        ey = states[:, Ego.Y] / scale
        c, s = self.cos_sin(states[:, Ego.HEAD])
        along, across = self._corners
        px = ex + along * c - across * s
        py = ey + along * s + across * c
        return ~np.logical_and.reduce(self._road.inside(px, py), axis=0)

    def goal(self, states: np.ndarray, k: int | np.ndarray) -> np.ndarray:
        """:meth:`NativeModel.goal` per row: in the goal interval and the centre in a goal polygon."""
        return self._blockwise(self._goal_block, self._ego(states), k)

    def _goal_block(self, states: np.ndarray, k: int | np.ndarray) -> np.ndarray:
        data = self.data
        native = self.native
        scale = native.scale_d
        if np.ndim(k) == 0:  # one sample for all rows: no array of samples
            if not data.goal_low <= int(k) <= data.goal_high:
                return np.zeros(states.shape[0], dtype=bool)
            if data.goal_anywhere:
                return np.ones(states.shape[0], dtype=bool)
            return self._goal.inside(states[:, Ego.X] / scale, states[:, Ego.Y] / scale)
        samples = self._samples(k, states.shape[0])
        due = (samples >= data.goal_low) & (samples <= data.goal_high)
        if not due.any() or data.goal_anywhere:  # outside the window nothing is tested; anywhere: the window alone
            return due
        if due.all():
            return self._goal.inside(states[:, Ego.X] / scale, states[:, Ego.Y] / scale)
        rows = np.flatnonzero(due)
        due[rows] = self._goal.inside(states[rows, Ego.X] / scale, states[rows, Ego.Y] / scale)
        return due

    def dist_goal(self, states: np.ndarray) -> np.ndarray:
        """:meth:`NativeModel.dist_goal` per row: ``(n,)`` float64."""
        states = self._ego(states)
        if self.data.goal_anywhere:
            return np.zeros(states.shape[0], dtype=np.float64)
        native = self.native
        scale = native.scale_d
        dx = states[:, Ego.X] / scale - native.goal_cx_d
        dy = states[:, Ego.Y] / scale - native.goal_cy_d
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


def offroad_many(data: ModelData, states: np.ndarray, k: int | np.ndarray | None = None) -> np.ndarray:
    """:meth:`BatchModel.offroad`."""
    return batch_model(data).offroad(states, k)


def goal_many(data: ModelData, states: np.ndarray, k: int | np.ndarray) -> np.ndarray:
    """:meth:`BatchModel.goal`."""
    return batch_model(data).goal(states, k)


def dist_goal_many(data: ModelData, states: np.ndarray) -> np.ndarray:
    """:meth:`BatchModel.dist_goal`."""
    return batch_model(data).dist_goal(states)
