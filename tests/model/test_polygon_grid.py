"""The cell grid of rac.model.polygons.Polygons.inside must give the crossing test's own answer
(Polygons.exact, and rac.model.native.point_in_polygons) for every point: inside a cell, on a cell's
border, on a polygon's edge or vertex, a rounding beside them, beyond the grid, and NaN or infinite.
"""

from __future__ import annotations

from functools import cache

import numpy as np
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from test_explore import left_turn_data

from rac.model import NativeModel
from rac.model.native import point_in_polygons
from rac.model.polygons import Polygons

#: A few irregular polygons (an L, a thin sliver, a triangle sharing a vertex with the L, a diamond
#: overlapping the L) beside the roads of the left-turn example.
SHAPES = (
    [(0.0, 0.0), (4.0, 0.0), (4.0, 1.0), (1.0, 1.0), (1.0, 3.0), (0.0, 3.0)],
    [(5.0, 0.0), (5.3, 0.0), (5.3, 2.7)],
    [(4.0, 1.0), (6.0, 2.5), (3.3, 2.9)],
    [(0.5, 2.0), (1.7, 3.1), (0.5, 4.2), (-0.7, 3.1)],
)


@cache
def polygon_sets() -> list[tuple[list[float], list[float], tuple[int, ...]]]:
    """(xs, ys, start): the left-turn example's road, its goal, and :data:`SHAPES`."""
    data = left_turn_data()
    model = NativeModel(data)
    xs = [x for shape in SHAPES for x, _ in shape]
    ys = [y for shape in SHAPES for _, y in shape]
    start = tuple(int(i) for i in np.cumsum([0, *(len(shape) for shape in SHAPES)]))
    return [(list(model.road_xd), list(model.road_yd), tuple(data.road_start)),
            (list(model.goal_xd), list(model.goal_yd), tuple(data.goal_start)),
            (xs, ys, start)]


@cache
def prepared(which: int) -> Polygons:
    xs, ys, start = polygon_sets()[which]
    return Polygons(xs, ys, start)


def awkward_points(which: int, rng: np.random.Generator, n: int) -> tuple[np.ndarray, np.ndarray]:
    """Points on and beside vertices, edges (between two vertices) and cell borders, and anywhere."""
    xs, ys, _ = polygon_sets()[which]
    x, y = np.asarray(xs), np.asarray(ys)
    polygons = prepared(which)
    pick = rng.integers(0, x.size, n)
    other = rng.integers(0, x.size, n)
    share = rng.choice([0.0, 0.5, 1.0, 1e-12, 1 - 1e-12, 1 / 3, rng.random()], n)
    nudge = np.array([0.0, 1e-9, -1e-9, 1e-6, -1e-6, 1e-3, 5e-324])
    ex = x[pick] + (x[other] - x[pick]) * share + rng.choice(nudge, n)
    ey = y[pick] + (y[other] - y[pick]) * share + rng.choice(nudge, n)
    # cell borders: origin + i * size, exactly and a rounding either side
    x0, y0 = polygons.grid_origin
    size = 1.0 / polygons.grid_scale
    rows, columns = polygons.cells.shape
    bx = x0 + rng.integers(0, columns + 1, n) * size
    by = y0 + rng.integers(0, rows + 1, n) * size
    bx = np.where(rng.random(n) < 0.5, bx, np.nextafter(bx, rng.choice([-np.inf, np.inf], n)))
    wide = 3.0 + 0.1 * (x.max() - x.min())
    ux = rng.uniform(x.min() - wide, x.max() + wide, n)
    uy = rng.uniform(y.min() - wide, y.max() + wide, n)
    px = np.concatenate([ex, bx, ux, ex, bx])
    py = np.concatenate([ey, by, uy, by, ey])
    return px, py


def test_the_grid_answers_as_the_crossing_test_on_awkward_points() -> None:
    rng = np.random.default_rng(11)
    for which in range(len(polygon_sets())):
        polygons = prepared(which)
        px, py = awkward_points(which, rng, 40_000)
        found = polygons.inside(px, py)
        assert found.tolist() == polygons.exact(px, py).tolist()
        assert found.any() and not found.all()
        assert (polygons.cells != 2).mean() > 0.5  # the grid answers most cells itself
        # in blocks of another shape (the offroad test's (4, n)), and point by point with native
        assert polygons.inside(px[:4000].reshape(4, -1), py[:4000].reshape(4, -1)).tolist() == \
            found[:4000].reshape(4, -1).tolist()
        xs, ys, start = polygon_sets()[which]
        for a, b, answer in zip(px[::40].tolist(), py[::40].tolist(), found[::40].tolist()):
            assert point_in_polygons(xs, ys, start, a, b) == answer


def test_points_beyond_the_grid_nan_and_infinite() -> None:
    special = [np.nan, np.inf, -np.inf, 1e300, -1e300, 0.0, 1.0]
    px = np.array([a for a in special for _ in special])
    py = np.array([b for _ in special for b in special])
    for which in range(len(polygon_sets())):
        polygons = prepared(which)
        assert polygons.inside(px, py).tolist() == polygons.exact(px, py).tolist()


@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(which=st.integers(0, 2), seed=st.integers(0, 2**32 - 1),
       x=st.floats(-100, 100, allow_nan=False), y=st.floats(-100, 100, allow_nan=False))
def test_the_grid_answers_as_the_crossing_test(which: int, seed: int, x: float, y: float) -> None:
    polygons = prepared(which)
    px, py = awkward_points(which, np.random.default_rng(seed), 50)
    px = np.append(px, x)
    py = np.append(py, y)
    assert polygons.inside(px, py).tolist() == polygons.exact(px, py).tolist()


@settings(max_examples=60, deadline=None)
@given(points=st.lists(st.tuples(st.integers(-8, 8), st.integers(-8, 8)), min_size=3, max_size=7),
       dx=st.floats(-3, 3), dy=st.floats(-3, 3))
def test_random_polygons(points: list[tuple[int, int]], dx: float, dy: float) -> None:
    """Any polygon (self-crossing, degenerate, repeated vertices) on a lattice of quarter units: its
    vertices and edges, and points a rounding beside them."""
    xs = [a / 4 for a, _ in points]
    ys = [b / 4 for _, b in points]
    polygons = Polygons(xs, ys, (0, len(xs)))
    rng = np.random.default_rng(len(points))
    t = rng.choice([0.0, 0.5, 0.25, 1.0, rng.random()], 400)
    i = rng.integers(0, len(xs), 400)
    j = (i + 1) % len(xs)
    x, y = np.asarray(xs), np.asarray(ys)
    px = np.concatenate([x[i] + (x[j] - x[i]) * t, rng.uniform(-3, 3, 200), x + dx * 1e-9, np.full(3, dx)])
    py = np.concatenate([y[i] + (y[j] - y[i]) * t, rng.uniform(-3, 3, 200), y - dy * 1e-9, np.full(3, dy)])
    px = np.where(rng.random(px.size) < 0.2, np.nextafter(px, np.inf), px)
    assert polygons.inside(px, py).tolist() == polygons.exact(px, py).tolist()


def test_many_polygons_skip_the_grid_and_answer_the_same(monkeypatch) -> None:
    # Beyond GRID_POLYGONS (or GRID_WORK cells) building the grid would cost more than it saves: the
    # crossing test alone answers, and the answers are the same.
    import rac.model.polygons as polygons

    xs, ys, start = polygon_sets()[0]
    with_grid = Polygons(xs, ys, start)
    assert with_grid.cells.size > 1
    monkeypatch.setattr(polygons, "GRID_POLYGONS", 0)
    without = Polygons(xs, ys, start)
    assert without.cells.shape == (1, 1) and without.cells[0, 0] == polygons.EXACT
    monkeypatch.setattr(polygons, "GRID_POLYGONS", 10**6)
    monkeypatch.setattr(polygons, "GRID_WORK", 0)
    assert Polygons(xs, ys, start).cells.shape == (1, 1)
    rng = np.random.default_rng(3)
    px = rng.uniform(min(xs) - 5, max(xs) + 5, 5000)
    py = rng.uniform(min(ys) - 5, max(ys) + 5, 5000)
    assert np.array_equal(with_grid.inside(px, py), without.inside(px, py))


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(which=st.integers(0, 2), seed=st.integers(0, 2**32 - 1), n=st.integers(1, 12))
def test_a_few_points_on_python_floats_answer_as_the_array_test(which: int, seed: int, n: int) -> None:
    """Polygons.exact_few (a few points, on Python floats) is Polygons.exact bit for bit, and inside()
    gives the same answers whichever of the two it takes for the points in undecided cells."""
    polygons = prepared(which)
    px, py = awkward_points(which, np.random.default_rng(seed), n)
    px = np.concatenate([px, [np.nan, np.inf, -np.inf]])
    py = np.concatenate([py, [0.0, np.nan, 1.0]])
    assert polygons.exact_few(px.tolist(), py.tolist()) == polygons.exact(px, py).tolist()
    for low in range(0, px.size, 3):  # a few points at a time: inside() takes the scalar test
        assert polygons.inside(px[low:low + 3], py[low:low + 3]).tolist() == polygons.exact(px[low:low + 3],
                                                                                           py[low:low + 3]).tolist()
