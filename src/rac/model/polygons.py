"""Points in polygons for arrays of points: the crossing test of
:func:`rac.model.native.point_in_polygons`, vectorised (:class:`Polygons`; used by
:class:`rac.model.batch.BatchModel` for ``offroad`` and ``goal``), with the same answers; most
points get theirs from a grid of cells wholly inside or outside the polygons."""

from __future__ import annotations

import bisect
import math

import numpy as np

__all__ = ["BOX_CELLS", "FEW_POINTS", "GRID_CELLS", "GRID_SIZE", "GRID_POLYGONS", "GRID_WORK", "Polygons"]

#: :class:`Polygons` matches up to this many (point, polygon) pairs with the polygons' boxes at once.
BOX_CELLS = 1 << 15
#: :class:`Polygons` answers from a grid of at most about this many cells (one byte each) ...
GRID_CELLS = 1 << 22
#: ... and no smaller than this (a 16th of a metre in the model: finer cells cost more to build than they save).
GRID_SIZE = 2.0 ** -4
#: ... and is built only when its polygons' boxes hold at most this many cells in all (each such cell's
#: centre is tested once while building): on a large map (thousands of lanelets) building would cost
#: more than it saves, and the crossing test alone answers, as before the grid.
GRID_WORK = 1 << 22
#: ... and over at most this many polygons (the build handles one at a time, about 0.75 ms each: 0.3 s at most).
GRID_POLYGONS = 400
#: Up to this many points run the crossing test on Python floats (:meth:`Polygons.exact_few`): numpy's
#: calls cost more than a few points' loops over the polygons' boxes and their bands' edges.
FEW_POINTS = 6
#: A grid cell's state: no point in it is inside a polygon / every point is / test each point.
OUTSIDE, INSIDE, EXACT = 0, 1, 2


class Polygons:
    """Flattened polygons (``xs[start[p]:start[p + 1]]``, ``ys`` likewise) prepared for
    :meth:`inside`, the crossing test of :func:`rac.model.native.point_in_polygons` on arrays.

    Per polygon: its bounding box, and its *bands*: between two consecutive distinct vertex
    y-values ``Y[b] <= y < Y[b + 1]`` the same edges pass the test ``(yi > py) != (yj > py)``,
    namely those with ``min(yi, yj) <= Y[b]`` and ``Y[b + 1] <= max(yi, yj)`` (both ends are
    vertex y-values, and none lies strictly inside a band). So a point tests only the (few)
    edges of its band: ``px < (xj - xi) * (py - yi) / (yj - yi) + xi`` with the same operations
    on the same doubles, and it is inside when an odd number of them hold.

    Every polygon's bands are columns of one table (a row per edge slot, unused slots masked), and
    a point's band in a polygon is found for all (point, polygon) pairs at once, on integers: with
    ``U`` every polygon's distinct bounds and ``r`` the number of them at or below the point's y,
    the bounds of polygon ``q`` at or below it are those with a rank in ``U`` below ``r``, counted
    by one ``np.searchsorted`` in the sorted keys ``q * (len(U) + 1) + rank``.

    :meth:`inside` first looks each point up in a grid of square cells over the polygons' boxes
    (:meth:`_build_grid`): a cell far from a polygon's edges is wholly inside or wholly outside
    it, so most points get their answer from one lookup; only the points in cells near an edge
    (and beyond the grid) run the crossing test (:meth:`exact`)."""

    def __init__(self, xs: list[float], ys: list[float], start: tuple[int, ...]) -> None:
        self._prepare(xs, ys, start)
        self._build_grid(xs, ys, start)

    def _prepare(self, xs: list[float], ys: list[float], start: tuple[int, ...]) -> None:
        """The boxes, bands and tables of :meth:`exact`."""
        boxes: list[tuple[float, float, float, float]] = []
        polygon_bounds: list[np.ndarray] = []
        tables: list[tuple[np.ndarray, ...]] = []
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
            boxes.append((low - margin, high + margin, min(pys), max(pys)))
            polygon_bounds.append(bounds)
            tables.append(((xj - xi)[edge], yi[edge], (yj - yi)[edge], xi[edge], used))
        #: per polygon: x low - margin, x high + margin, y low, y high
        self.boxes = np.array(boxes, dtype=np.float64).reshape(-1, 4)
        #: per polygon, its own (band, slot) tables: many points test only the polygon's own slots
        self.tables = tables
        self.bounds = polygon_bounds
        self.levels = np.unique(np.concatenate(polygon_bounds)) if polygon_bounds else np.zeros(0)
        width = self.levels.size + 1
        self.keys = np.concatenate([q * width + np.searchsorted(self.levels, bounds)
                                    for q, bounds in enumerate(polygon_bounds)]) if polygon_bounds else np.zeros(0)
        sizes = [bounds.size for bounds in polygon_bounds]
        self.first = np.cumsum([0, *sizes[:-1]]).astype(np.int64)  # each polygon's first key
        self.band_start = np.cumsum([0, *(size - 1 for size in sizes[:-1])]).astype(np.int64)
        slots = max((table[0].shape[1] for table in tables), default=1)
        #: (slot, band) over every polygon's bands: xj - xi, yi, yj - yi, xi, and whether the slot holds an edge
        self.table = [np.ascontiguousarray(np.concatenate([np.pad(table[i], ((0, 0), (0, slots - table[i].shape[1])))
                                                           for table in tables]).T)
                      if tables else np.zeros((slots, 0), dtype=bool if i == 4 else np.float64) for i in range(5)]
        #: per polygon as Python floats (:meth:`exact_few`): its box, its bounds, and per band the used
        #: slots' (xj - xi, yi, yj - yi, xi)
        self.few = [(box, bounds.tolist(), [[edge for edge, used in zip(zip(*(column.tolist() for column in band[:4])),
                                                                        band[4].tolist()) if used]
                                            for band in zip(*(part for part in table))])
                    for box, bounds, table in zip(self.boxes.tolist(), polygon_bounds, tables)]

    def _build_grid(self, xs: list[float], ys: list[float], start: tuple[int, ...]) -> None:
        """The cell grid of :meth:`inside`: ``cells[row, column]`` is OUTSIDE, INSIDE or EXACT for
        the points ``x0 + column * size <= x < x0 + (column + 1) * size`` (rows likewise in y).

        Why a cell's answer is exact: at a distance ``d`` from every edge of a polygon the crossing
        test on doubles gives the true answer (the edge's x at the point's y is off by a few ulps of
        the coordinates, far less than ``d``), and the true answer is the same all over a convex
        region touching none of its edges. So a cell whose box, grown by ``margin`` (far more than
        rounding, also that of finding a point's cell), meets no box of the polygon's edges is
        wholly inside or outside it, as its centre is. INSIDE: wholly inside some polygon;
        OUTSIDE: wholly outside every polygon; otherwise EXACT. The grid has a ring of cells beyond
        the polygons and their margin; a point beyond the grid (or NaN) looks up a cell of that ring,
        and is outside every polygon, far from its edges (or NaN: no comparison holds), as the ring's
        cells are (OUTSIDE, or EXACT if rounding put an edge's margin in one)."""
        polygons = [(np.asarray(xs[start[p]:start[p + 1]], dtype=np.float64),
                     np.asarray(ys[start[p]:start[p + 1]], dtype=np.float64))
                    for p in range(len(start) - 1) if start[p + 1] > start[p]]
        finite = bool(polygons) and all(np.isfinite(pxs).all() and np.isfinite(pys).all() for pxs, pys in polygons)
        if not finite:
            self._no_grid()
            return
        low_x = min(float(pxs.min()) for pxs, _ in polygons)
        high_x = max(float(pxs.max()) for pxs, _ in polygons)
        low_y = min(float(pys.min()) for _, pys in polygons)
        high_y = max(float(pys.max()) for _, pys in polygons)
        reach = max(abs(low_x), abs(high_x), abs(low_y), abs(high_y))
        margin = 1e-6 * (1.0 + reach)
        # a power of two (a point's cell is then one rounding away): at most GRID_CELLS cells, at least GRID_SIZE
        span = max(high_x - low_x, high_y - low_y, margin)
        size = 2.0 ** math.ceil(math.log2(max(span / math.sqrt(GRID_CELLS), GRID_SIZE)))
        # one more ring of cells beyond the polygons' boxes (and their margin) on every side
        x0 = low_x - margin - size
        y0 = low_y - margin - size
        columns = int((high_x + margin - x0) / size) + 2
        rows = int((high_y + margin - y0) / size) + 2
        work = sum((int((float(pxs.max()) - float(pxs.min()) + 2 * margin) / size) + 2)
                   * (int((float(pys.max()) - float(pys.min()) + 2 * margin) / size) + 2) for pxs, pys in polygons)
        if work > GRID_WORK or len(polygons) > GRID_POLYGONS:
            self._no_grid()
            return
        inside = np.zeros((rows, columns), dtype=bool)  # wholly inside some polygon
        outside = np.ones((rows, columns), dtype=bool)  # wholly outside every polygon so far

        def cell_range(low: float, high: float, origin: float, count: int) -> tuple[int, int]:
            """The cells ``[first, end)`` that ``[low, high]`` grown by the margin meets (a rounding of
            ``first`` or ``end`` by one cell leaves a point at least nearly the margin away)."""
            return (max(0, int((low - margin - origin) / size)),
                    min(count, int((high + margin - origin) / size) + 1))

        for pxs, pys in polygons:
            # beyond the cells of the polygon's box no cell is near it or inside it
            c0, c1 = cell_range(float(pxs.min()), float(pxs.max()), x0, columns)
            r0, r1 = cell_range(float(pys.min()), float(pys.max()), y0, rows)
            near = np.zeros((r1 - r0, c1 - c0), dtype=bool)  # the cells near one of the polygon's edges
            for xi, yi, xj, yj in zip(pxs.tolist(), pys.tolist(), np.roll(pxs, 1).tolist(), np.roll(pys, 1).tolist()):
                e0, e1 = cell_range(min(xi, xj), max(xi, xj), x0, columns)
                f0, f1 = cell_range(min(yi, yj), max(yi, yj), y0, rows)
                near[f0 - r0:f1 - r0, e0 - c0:e1 - c0] = True
            one = Polygons.__new__(Polygons)
            one._prepare(pxs.tolist(), pys.tolist(), (0, pxs.size))
            free_rows, free_columns = np.nonzero(~near)
            hit = one.exact(x0 + (free_columns + c0 + 0.5) * size, y0 + (free_rows + r0 + 0.5) * size)  # centres
            inside[free_rows[hit] + r0, free_columns[hit] + c0] = True
            outside[r0:r1, c0:c1] &= ~near
            outside[free_rows[hit] + r0, free_columns[hit] + c0] = False
        cells = np.full((rows, columns), EXACT, dtype=np.int8)
        cells[outside] = OUTSIDE
        cells[inside] = INSIDE
        self.grid_origin = (x0, y0)
        self.grid_scale = 1.0 / size
        self.cells = cells

    def _no_grid(self) -> None:
        """A grid of one EXACT cell: every point runs the crossing test."""
        self.grid_origin, self.grid_scale, self.cells = (0.0, 0.0), 0.0, np.full((1, 1), EXACT, dtype=np.int8)

    def inside(self, px: np.ndarray, py: np.ndarray) -> np.ndarray:
        """Whether each point lies inside one of the polygons (bool array like ``px``): the grid's
        answer where it has one (:meth:`_build_grid`), else :meth:`exact`'s."""
        px = np.asarray(px, dtype=np.float64)
        py = np.asarray(py, dtype=np.float64)
        cells = self.cells
        rows, columns = cells.shape
        x0, y0 = self.grid_origin
        scale = self.grid_scale
        # the cell's column and row, clipped into the grid (NaN to 0: fmax skips it) before the cast
        column = (px - x0) * scale
        np.fmin(np.fmax(column, 0.0, out=column), columns - 1, out=column)
        row = (py - y0) * scale
        np.fmin(np.fmax(row, 0.0, out=row), rows - 1, out=row)
        row = row.astype(np.int64)
        row *= columns
        row += column.astype(np.int64)
        state = cells.reshape(-1)[row]
        found = state == INSIDE
        test = state == EXACT
        if test.any():
            where = np.flatnonzero(test)
            if where.size <= FEW_POINTS:  # near an edge, a few points (as a sample of few episodes has)
                found.reshape(-1)[where] = self.exact_few(px.reshape(-1)[where].tolist(),
                                                          py.reshape(-1)[where].tolist())
            else:
                found[test] = self.exact(px[test], py[test])
        return found

    def exact_few(self, px: list[float], py: list[float]) -> list[bool]:
        """:meth:`exact` of a few points given as Python floats: the same comparisons and the same
        operations on the same doubles (``px < (xj - xi) * (py - yi) / (yj - yi) + xi`` per edge of the
        point's band in each polygon whose box holds it), one point and polygon at a time."""
        out = []
        for qx, qy in zip(px, py):
            hit = False
            for (x_low, x_high, y_low, y_high), bounds, bands in self.few:
                if not (y_low <= qy < y_high and x_low <= qx <= x_high):
                    continue  # NaN fails every comparison, as in exact()
                odd = False
                for dx, yi, dy, xi in bands[bisect.bisect_right(bounds, qy) - 1]:
                    if qx < dx * (qy - yi) / dy + xi:
                        odd = not odd
                if odd:
                    hit = True
                    break
            out.append(hit)
        return out

    def exact(self, px: np.ndarray, py: np.ndarray) -> np.ndarray:
        """Whether each point lies inside one of the polygons (bool array like ``px``), by the
        crossing test itself.

        Few points are matched with every polygon's box at once (one array operation per step for
        all (point, polygon) pairs); many points go polygon by polygon, each testing only the points
        in its box not found inside an earlier one (fewer pairs when boxes overlap)."""
        px = np.asarray(px, dtype=np.float64)
        py = np.asarray(py, dtype=np.float64)
        shape = px.shape
        px = px.reshape(-1)
        py = py.reshape(-1)
        found = np.zeros(px.shape, dtype=bool)
        boxes = self.boxes
        with np.errstate(divide="ignore", invalid="ignore"):
            if px.size * boxes.shape[0] <= BOX_CELLS:
                bx = px[:, None]
                by = py[:, None]
                points, polygons = np.nonzero((by >= boxes[:, 2]) & (by < boxes[:, 3]) & (bx >= boxes[:, 0])
                                              & (bx <= boxes[:, 1]))
                below = np.searchsorted(self.levels, py[points], side="right")
                local = np.searchsorted(self.keys, polygons * (self.levels.size + 1) + below) - self.first[polygons]
                found[points[self._odd(px[points], py[points], self.band_start[polygons] - 1 + local)]] = True
                return found.reshape(shape)
            for polygon, (x_low, x_high, y_low, y_high) in enumerate(boxes.tolist()):
                rows = np.flatnonzero((py >= y_low) & (py < y_high) & (px >= x_low) & (px <= x_high) & ~found)
                if rows.size:
                    qy = py[rows]
                    band = np.searchsorted(self.bounds[polygon], qy, side="right") - 1
                    found[rows] = _odd_in(self.tables[polygon], px[rows], qy, band)
        return found.reshape(shape)

    def _odd(self, qx: np.ndarray, qy: np.ndarray, band: np.ndarray) -> np.ndarray:
        """Whether an odd number of the edges of each point's band (a row of :attr:`table`) cross the
        ray from the point: ``px < (xj - xi) * (py - yi) / (yj - yi) + xi``."""
        dx, yi, dy, xi, used = self.table
        crosses = qx < dx[:, band] * (qy - yi[:, band]) / dy[:, band] + xi[:, band]  # (slot, point)
        crosses &= used[:, band]
        return np.logical_xor.reduce(crosses, axis=0)


def _odd_in(table: tuple[np.ndarray, ...], qx: np.ndarray, qy: np.ndarray, band: np.ndarray) -> np.ndarray:
    """:meth:`Polygons._odd` on one polygon's own table (``band`` indexes its bands), a slot at a
    time: the points of a large batch test only as many edges as the polygon's widest band has."""
    dx, yi, dy, xi, used = table
    inside = np.zeros(qx.shape, dtype=bool)
    for slot in range(used.shape[1]):
        crosses = qx < dx[band, slot] * (qy - yi[band, slot]) / dy[band, slot] + xi[band, slot]
        if not used[:, slot].all():
            crosses &= used[band, slot]
        inside ^= crosses
    return inside
