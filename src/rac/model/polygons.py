"""Points in polygons for arrays of points: the crossing test of
:func:`rac.model.native.point_in_polygons`, vectorised (:class:`Polygons`; used by
:class:`rac.model.batch.BatchModel` for ``offroad`` and ``goal``), with the same answers."""

from __future__ import annotations

import numpy as np

__all__ = ["BOX_CELLS", "Polygons"]

#: :class:`Polygons` matches up to this many (point, polygon) pairs with the polygons' boxes at once.
BOX_CELLS = 1 << 15


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
    by one ``np.searchsorted`` in the sorted keys ``q * (len(U) + 1) + rank``."""

    def __init__(self, xs: list[float], ys: list[float], start: tuple[int, ...]) -> None:
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
                      if tables else np.zeros((slots, 0)) for i in range(5)]

    def inside(self, px: np.ndarray, py: np.ndarray) -> np.ndarray:
        """Whether each point lies inside one of the polygons (bool array like ``px``).

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
