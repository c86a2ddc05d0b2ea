"""Breadth-first exploration of the model's state space, vectorised with numpy (issue 4).

Two layers:

- The model's functions over *arrays* of states (:class:`BatchModel` and the ``*_many``
  shorthands): ``sense_many``, ``mindist_many``, ``collide_many``, ``offroad_many``,
  ``goal_many``, ``dist_goal_many``. ``states`` is an ``(n, 7)`` integer array with the columns
  of :class:`rac.model.native.State` (``x, y, v, acc, head, jerk, turn``: significands) and ``k``
  is one sample index or an ``(n,)`` array of them. Each result equals what
  :class:`rac.model.native.NativeModel` gives for every row, bit for bit: the same operations in
  the same order on doubles (numpy's ufuncs neither fuse nor reorder), ``np.sqrt`` (correctly
  rounded, like ``math.sqrt``), and cos/sin taken from ``math.cos``/``math.sin`` (the C library)
  over the distinct headings only, because numpy's SIMD ``np.cos``/``np.sin`` may differ from the
  C library in the last bit on some platforms.
- :func:`explore`: breadth-first over the whole frontier at once, producing an
  :class:`rac.engine.graph.ExploredGraph`.

Example::

    graph = explore(data, horizon_samples=20, prune_unsafe=True)
    graph.labels["safe"], graph.states[graph.initial]
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

from rac.engine.graph import ExploredGraph
from rac.model.data import INT32_MAX, ModelData, ModelRangeError
from rac.model.native import CORNERS, NO_OBSTACLE, NativeModel, State

__all__ = [
    "COLUMNS",
    "EGO_COLUMNS",
    "BatchModel",
    "collide_many",
    "dist_goal_many",
    "explore",
    "goal_many",
    "mindist_many",
    "offroad_many",
    "sense_many",
]

#: The columns of the ``states`` arrays the ``*_many`` functions take (those of ``State``).
EGO_COLUMNS: tuple[str, ...] = State._fields
#: The columns of :attr:`ExploredGraph.states` produced by :func:`explore`.
COLUMNS: tuple[str, ...] = ("k", *EGO_COLUMNS)

Progress = Callable[[int, int, int], None]


def _cos_sin(angles: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``math.cos`` and ``math.sin`` of every element, called once per distinct bit pattern."""
    flat = np.ascontiguousarray(angles, dtype=np.float64)
    bits, inverse = np.unique(flat.view(np.int64), return_inverse=True)
    values = bits.view(np.float64).tolist()
    cos = np.array([math.cos(t) for t in values], dtype=np.float64)
    sin = np.array([math.sin(t) for t in values], dtype=np.float64)
    inverse = inverse.reshape(-1)
    return cos[inverse], sin[inverse]


def _inside(xs: list[float], ys: list[float], start: tuple[int, ...], px: np.ndarray,
            py: np.ndarray) -> np.ndarray:
    """:func:`rac.model.native.point_in_polygons` for arrays of points (same crossing test).

    Only the points in a polygon's bounding box are tested against it; that changes no answer:
    below ``min(y)`` or at/above ``max(y)`` no edge passes the test ``(yi > py) != (yj > py)``;
    left of the box every crossing edge counts, and there is an even number of them; right of
    the box (beyond a margin far larger than rounding) none counts."""
    found = np.zeros(px.shape, dtype=bool)
    with np.errstate(divide="ignore", invalid="ignore"):
        for p in range(len(start) - 1):
            if start[p + 1] == start[p]:
                continue
            pxs, pys = xs[start[p]:start[p + 1]], ys[start[p]:start[p + 1]]
            low, high = min(pxs), max(pxs)
            margin = 1e-6 * (abs(low) + abs(high)) + 1e-6
            rows = np.flatnonzero((py >= min(pys)) & (py < max(pys)) & (px >= low - margin)
                                  & (px <= high + margin))
            if rows.size == 0:
                continue
            qx = px[rows]
            qy = py[rows]
            inside = np.zeros(rows.shape, dtype=bool)
            j = start[p + 1] - 1
            for i in range(start[p], start[p + 1]):
                xi, yi, xj, yj = xs[i], ys[i], xs[j], ys[j]
                crosses = (yi > qy) != (yj > qy)
                # native evaluates the division only where the edge crosses (no division by 0 there)
                crosses &= qx < (xj - xi) * (qy - yi) / (yj - yi) + xi
                inside ^= crosses
                j = i
            found[rows] |= inside
    return found


class BatchModel:
    """:class:`NativeModel`'s functions over arrays of states (see the module docstring)."""

    def __init__(self, data: ModelData) -> None:
        self.data = data
        self.native = NativeModel(data)

    def _ego(self, states: np.ndarray) -> np.ndarray:
        states = np.asarray(states)
        if states.ndim != 2 or states.shape[1] != len(EGO_COLUMNS):
            raise ValueError(f"states must have shape (n, {len(EGO_COLUMNS)}), not {states.shape}")
        return states

    def _samples(self, k: int | np.ndarray, n: int) -> np.ndarray:
        return np.broadcast_to(np.asarray(k, dtype=np.int64), (n,))

    def sense(self, states: np.ndarray) -> np.ndarray:
        """:meth:`NativeModel.sense` of every row: an ``(n, 7)`` int32 array (jerk, turn kept).
        :class:`ModelRangeError` for the first row whose result does not fit int32."""
        states = self._ego(states)
        native = self.native
        scale = native.scale_d
        x = states[:, 0] / scale
        y = states[:, 1] / scale
        v = states[:, 2] / scale
        acc = states[:, 3] / scale
        head = states[:, 4] / scale
        jerk = states[:, 5] / scale
        turn = states[:, 6] / scale
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
            x = x + v * cos * u
            y = y + v * sin * u
        out = np.empty(states.shape, dtype=np.int32)
        for column, (what, value) in enumerate((("x", x), ("y", y), ("v", v), ("acc", acc), ("head", head))):
            scaled = value * scale
            bad = ~((scaled > -2147483648.0) & (scaled < 2147483648.0))  # also NaN
            if bad.any():
                row = int(np.flatnonzero(bad)[0])
                native._sig(what, float(value[row]))  # raises the same error as native
                raise ModelRangeError(f"sense(): {what}", float(value[row]), None, self.data.scale)
            out[:, column] = scaled.astype(np.int64)  # truncation toward zero, like int()
        out[:, 5] = states[:, 5]
        out[:, 6] = states[:, 6]
        return out

    def mindist(self, states: np.ndarray, k: int | np.ndarray) -> np.ndarray:
        """:meth:`NativeModel.mindist` of every row at its sample: ``(n,)`` float64."""
        states = self._ego(states)
        n = states.shape[0]
        data = self.data
        native = self.native
        scale = native.scale_d
        best = np.full(n, NO_OBSTACLE, dtype=np.float64)
        if data.obstacle_count == 0 or n == 0:
            return best
        samples, where = np.unique(self._samples(k, n), return_inverse=True)
        where = where.reshape(-1)
        ex = states[:, 0] / scale
        ey = states[:, 1] / scale
        ec, es = _cos_sin(states[:, 4] / scale)
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
            here = present[where]
            for a in range(3):
                ax = ex + (a - 1) * eoff * ec
                ay = ey + (a - 1) * eoff * es
                for b in range(3):
                    dx = ax - bx[b][where]
                    dy = ay - by[b][where]
                    d = np.sqrt(dx * dx + dy * dy) - er - orad
                    best = np.where(here & (d < best), d, best)
        return best

    def collide(self, states: np.ndarray, k: int | np.ndarray) -> np.ndarray:
        """``mindist < TD`` per row: ``(n,)`` bool."""
        return self.mindist(states, k) < self.native.td_d

    def offroad(self, states: np.ndarray) -> np.ndarray:
        """:meth:`NativeModel.offroad` per row: a corner of the ego outside every road polygon."""
        states = self._ego(states)
        native = self.native
        scale = native.scale_d
        ex = states[:, 0] / scale
        ey = states[:, 1] / scale
        c, s = _cos_sin(states[:, 4] / scale)
        hl = native.length_d / 2.0
        hw = native.width_d / 2.0
        off = np.zeros(states.shape[0], dtype=bool)
        for ca, cb in CORNERS:
            px = ex + ca * hl * c - cb * hw * s
            py = ey + ca * hl * s + cb * hw * c
            off |= ~_inside(native.road_xd, native.road_yd, self.data.road_start, px, py)
        return off

    def goal(self, states: np.ndarray, k: int | np.ndarray) -> np.ndarray:
        """:meth:`NativeModel.goal` per row: in the goal interval and the centre in a goal polygon."""
        states = self._ego(states)
        data = self.data
        native = self.native
        samples = self._samples(k, states.shape[0])
        scale = native.scale_d
        inside = _inside(native.goal_xd, native.goal_yd, data.goal_start, states[:, 0] / scale,
                         states[:, 1] / scale)
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


def _model(data: ModelData) -> BatchModel:
    """One :class:`BatchModel` per ModelData object (a small identity cache)."""
    entry = _models.get(id(data))
    if entry is None or entry[0] is not data:
        if len(_models) > 16:
            _models.clear()
        entry = _models[id(data)] = (data, BatchModel(data))
    return entry[1]


def sense_many(data: ModelData, states: np.ndarray) -> np.ndarray:
    """:meth:`BatchModel.sense`."""
    return _model(data).sense(states)


def mindist_many(data: ModelData, states: np.ndarray, k: int | np.ndarray) -> np.ndarray:
    """:meth:`BatchModel.mindist`."""
    return _model(data).mindist(states, k)


def collide_many(data: ModelData, states: np.ndarray, k: int | np.ndarray) -> np.ndarray:
    """:meth:`BatchModel.collide`."""
    return _model(data).collide(states, k)


def offroad_many(data: ModelData, states: np.ndarray) -> np.ndarray:
    """:meth:`BatchModel.offroad`."""
    return _model(data).offroad(states)


def goal_many(data: ModelData, states: np.ndarray, k: int | np.ndarray) -> np.ndarray:
    """:meth:`BatchModel.goal`."""
    return _model(data).goal(states, k)


def dist_goal_many(data: ModelData, states: np.ndarray) -> np.ndarray:
    """:meth:`BatchModel.dist_goal`."""
    return _model(data).dist_goal(states)


# ---------------------------------------------------------------- exploration
def action_pairs(data: ModelData) -> np.ndarray:
    """``(P, 2)`` int32: every (jerk, turn) pair; row ``a`` is action index ``a`` of the graph,
    ``a = jerk_index * turn_count + turn_index`` over :attr:`ActionData.values`."""
    jerk = np.asarray(data.action("jerk").values, dtype=np.int32)
    turn = np.asarray(data.action("turn").values, dtype=np.int32)
    return np.stack([np.repeat(jerk, len(turn)), np.tile(turn, len(jerk))], axis=1)


def explore(data: ModelData, *, horizon_samples: int | None = None, prune_unsafe: bool = False,
            progress: Progress | None = None, max_states: int | None = None) -> ExploredGraph:
    """Explore every state reachable from the ego's start, breadth-first, one sample per layer.

    A state is ``(k, x, y, v, acc, head, jerk, turn)`` (:data:`COLUMNS`; int32); state 0 is the
    start ``(0, ego..., 0, 0)``. At a decision sample (``k % decide_every == 0``) a state has one
    choice per (jerk, turn) pair (action index as in :func:`action_pairs`); at other samples one
    choice, action ``-1``, keeping its jerk and turn. The successor of a choice is ``sense()`` of
    the state with the chosen actions, at ``k + 1``. Each layer's successors are merged
    (``np.unique`` over rows; states at different samples never coincide, so this merges every
    duplicate). States at ``k == horizon_samples`` are terminal.

    ``horizon_samples`` defaults to the goal interval's last sample (``goal()`` is false ever
    after); ``ValueError`` when that is unbounded. With ``prune_unsafe=True`` states that collide
    or are off-road are also terminal (not expanded): enough for ``E[] safe``, ``E<> safe && goal``
    and the safety shield, and far smaller; their choices are then absent, so a consumer must not
    read a terminal state before the horizon as "the run ends safely".

    Labels (``(n,)`` bool): ``collide``, ``offroad``, ``goal``, ``safe`` (``!collide && !offroad``).
    ``progress(layer, frontier_size, total_states)`` is called once per explored layer.
    ``max_states``: ``MemoryError`` as soon as more states than that have been found.
    """
    if horizon_samples is None:
        if data.goal_high >= INT32_MAX:
            raise ValueError("explore() needs horizon_samples: the goal's time interval is unbounded")
        horizon_samples = data.goal_high
    if horizon_samples < 0:
        raise ValueError(f"horizon_samples must be >= 0, not {horizon_samples}")
    model = _model(data)
    native = model.native
    pairs = action_pairs(data)
    n_pairs = len(pairs)
    frontier = np.asarray([native.initial_state()], dtype=np.int32)  # ego columns of layer k
    layers: list[np.ndarray] = []
    counts: list[np.ndarray] = []  # choices per state
    actions: list[np.ndarray] = []
    targets: list[np.ndarray] = []
    labels: dict[str, list[np.ndarray]] = {"collide": [], "offroad": [], "goal": [], "safe": []}
    total = 0
    for k in range(horizon_samples + 1):
        size = frontier.shape[0]
        layers.append(frontier)
        collide = model.collide(frontier, k)
        offroad = model.offroad(frontier)
        safe = ~collide & ~offroad
        for name, mask in (("collide", collide), ("offroad", offroad), ("goal", model.goal(frontier, k)),
                           ("safe", safe)):
            labels[name].append(mask)
        base = total + size  # index of the next layer's first state
        total = base
        if progress is not None:
            progress(k, size, total)
        if max_states is not None and total > max_states:
            raise MemoryError(f"explore(): more than {max_states} states by sample {k}")
        if k == horizon_samples:
            counts.append(np.zeros(size, dtype=np.int64))
            break
        expand = safe if prune_unsafe else np.ones(size, dtype=bool)
        sources = frontier[expand]
        if k % data.decide_every == 0:
            chosen = np.repeat(sources, n_pairs, axis=0)
            chosen[:, 5:7] = np.tile(pairs, (sources.shape[0], 1))
            action = np.tile(np.arange(n_pairs, dtype=np.int64), sources.shape[0])
            per_state = n_pairs
        else:
            chosen = sources
            action = np.full(sources.shape[0], -1, dtype=np.int64)
            per_state = 1
        counts.append(np.where(expand, per_state, 0).astype(np.int64))
        successors = model.sense(chosen)
        if successors.shape[0]:
            frontier, inverse = np.unique(successors, axis=0, return_inverse=True)
            frontier = np.ascontiguousarray(frontier, dtype=np.int32)
        else:
            frontier, inverse = successors, np.zeros(0, dtype=np.int64)
        actions.append(action)
        targets.append(base + inverse.reshape(-1).astype(np.int64))
        if frontier.shape[0] == 0:
            break
    states = np.concatenate([np.column_stack([np.full(layer.shape[0], k, dtype=np.int32), layer])
                             for k, layer in enumerate(layers)]).astype(np.int32, copy=False)
    offsets = np.zeros(states.shape[0] + 1, dtype=np.int64)
    np.cumsum(np.concatenate(counts), out=offsets[1:])
    return ExploredGraph(
        states=states, columns=COLUMNS, choice_offsets=offsets,
        choice_action=np.concatenate(actions) if actions else np.zeros(0, dtype=np.int64),
        choice_target=np.concatenate(targets) if targets else np.zeros(0, dtype=np.int64),
        initial=0, labels={name: np.concatenate(masks) for name, masks in labels.items()})
