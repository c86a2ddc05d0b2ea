"""The scenario a model is built from: road, obstacles, ego start and goal, in plain numbers.

:func:`load_scenario` (with commonroad-io) turns a CommonRoad XML file into these frozen
values; everything downstream (the native model, the UPPAAL target) reads only them.
Units: metres, seconds, radians, m/s.
"""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class Polygon:
    """A simple polygon, counter-clockwise or clockwise, not closed (first point not repeated)."""

    points: tuple[tuple[float, float], ...]


@dataclass(frozen=True)
class Waypoint:
    """An obstacle's state at one time: it moves in a straight line at ``velocity`` along
    ``heading`` until the next waypoint (velocity and heading change only at waypoints)."""

    time: float
    x: float
    y: float
    heading: float
    velocity: float


@dataclass(frozen=True)
class Obstacle:
    """A static or dynamic obstacle, a ``length`` × ``width`` rectangle centred on its position."""

    id: int
    length: float
    width: float
    waypoints: tuple[Waypoint, ...]  # one waypoint for a static obstacle
    static: bool = False


@dataclass(frozen=True)
class EgoStart:
    x: float
    y: float
    heading: float
    velocity: float
    acceleration: float = 0.0


@dataclass(frozen=True)
class Goal:
    """The planning problem's goal: the ego's position inside one of ``regions`` while
    ``time_low <= time <= time_high`` (seconds)."""

    regions: tuple[Polygon, ...]
    time_low: float
    time_high: float

    @property
    def center(self) -> tuple[float, float]:
        """Centroid of the first region's vertices (``dist_goal()`` measures to it)."""
        points = self.regions[0].points
        return (sum(p[0] for p in points) / len(points), sum(p[1] for p in points) / len(points))


@dataclass(frozen=True)
class Scenario:
    name: str
    path: str
    dt: float  # the CommonRoad time step (s)
    road: tuple[Polygon, ...]  # the lanelets' polygons; the road is their union
    obstacles: tuple[Obstacle, ...]
    ego: EgoStart
    goal: Goal
