"""Draw an ego trajectory into its CommonRoad scenario: a PNG of one instant, optionally an animated GIF.

The road, the obstacles and the planning problem are drawn by commonroad-io's ``MPRenderer`` on a
standalone Agg figure (no pyplot window, the caller's backend untouched, see :mod:`rac.output.plots`); the
ego is drawn on top as its path and a rectangle. Files are written atomically.

Example::

    import numpy as np
    from rac.output.render import render_trajectory

    t = np.arange(50) * 0.1
    trajectory = np.column_stack([np.full(50, 1.75), -18 + 6 * t, np.full(50, np.pi / 2)])  # x, y, head
    render_trajectory("examples/left_turn/left_turn.xml", trajectory, "run.png", gif_path="run.gif")
"""

from __future__ import annotations

import io
import math
import os
import warnings
from collections.abc import Sequence
from pathlib import Path
from typing import IO, Any
from xml.etree import ElementTree

import numpy as np
from matplotlib.axes import Axes
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.lines import Line2D
from matplotlib.patches import Patch, Polygon
from PIL import Image

from rac.core.diagnostics import RacError, counted
from rac.core.files import atomic_write
from rac.model.commonroad import (
    PlanningProblemError,
    ScenarioError,
    placed_outline,
    quiet_reader,
    reader_failure,
    shape_placement,
)
from rac.output.plots import fit_title, new_figure, save_figure, wrap_text

__all__ = ["EGO_COLOUR", "EVENT_MARKS", "RenderError", "SceneFrames", "render_trajectory"]

EGO_COLOUR = "#2e7d32"
#: Metres of scenery kept around the ego's path (and the goal) when no ``plot_limits`` are given.
MARGIN = 15.0
#: The last GIF frame stays this long (ms), so a looping animation visibly ends before restarting.
LAST_FRAME_MS = 1200
#: Inches added below the map for the legend's row (the legend lies outside the map, hiding none of it).
LEGEND_HEIGHT = 0.4
#: How the first collision and the first off-road sample are marked on the ego's path: colour, marker, legend text.
EVENT_MARKS = {"collision": ("#c62828", "X", "first collision"),
               "offroad": ("#ef6c00", "D", "first off-road sample")}


class RenderError(RacError):
    """A scenario file that cannot be drawn; ``str(error)`` is ``"<path>: <problem>"``."""

    def __init__(self, path: str | os.PathLike[str], problem: str) -> None:
        self.path = os.fspath(path)
        self.problem = problem
        super().__init__(f"{self.path}: {problem}")


def _read(path: Path) -> tuple[Any, Any]:
    """The commonroad-io scenario and planning problem set in ``path``, or :class:`RenderError`."""
    try:
        data = path.read_bytes()
    except OSError as error:
        raise RenderError(path, f"cannot be read ({error.strerror or error})") from None
    # commonroad: only when this runs; importing rac.output.render stays light
    from commonroad.common.file_reader import CommonRoadFileReader

    with quiet_reader():  # commonroad-io's warnings and log lines about the file
        try:
            scenario, problems = CommonRoadFileReader(data).open()
            _place_shapes(path, data, scenario)
            return scenario, problems
        except Exception as error:  # commonroad-io raises a bare Exception, lxml errors, KeyError...
            if not reader_failure(error):
                raise
            problem = f"is not a CommonRoad scenario commonroad-io can read ({type(error).__name__}: {error})"
    # rac's loader explains broken files far better (which element, which line); use its words if it fails too
    from rac.model.checks import load_file

    try:
        try:
            load_file(path)
        except PlanningProblemError as several:  # any one of them reads the file: the diagnosis is the file's
            load_file(path, several.ids[0])
    except ScenarioError as diagnosis:
        problem = f"{diagnosis.element} {diagnosis.problem}" if diagnosis.element else diagnosis.problem
    raise RenderError(path, problem)


def _place_shapes(path: Path, data: bytes, scenario: Any) -> None:
    """Redraw each obstacle whose rectangle or circle the file places by its own ``<center>`` or
    ``<orientation>`` with that placed outline (:func:`rac.model.commonroad.placed_outline`): commonroad-io
    reads past both, and drew the obstacle at its position while the model has it where the file puts it.
    (commonroad-io's obstacle shapes are immutable: such an obstacle is replaced by a copy.)"""
    # commonroad: only when this runs; importing rac.output.render stays light
    from commonroad.geometry.obstacle_shapes.polygon_obstacle_shape import PolygonObstacleShape

    # commonroad: only when this runs; importing rac.output.render stays light
    from commonroad.prediction.prediction import TrajectoryPrediction

    # commonroad: only when this runs; importing rac.output.render stays light
    from commonroad.scenario.obstacle import DynamicObstacle, StaticObstacle

    for node in ElementTree.fromstring(data):
        if node.tag not in ("staticObstacle", "dynamicObstacle", "obstacle") or node.find("shape") is None:
            continue
        obstacle = scenario.obstacle_by_id(int(node.get("id", "-1")))
        if not isinstance(obstacle, (StaticObstacle, DynamicObstacle)):
            continue
        outline = placed_outline(obstacle.obstacle_shape, shape_placement(path, f"obstacle {obstacle.obstacle_id}",
                                                                            node))
        if outline is None:
            continue
        shape = PolygonObstacleShape(vertices=outline)
        if isinstance(obstacle, StaticObstacle):
            placed = StaticObstacle(obstacle.obstacle_id, obstacle.obstacle_type, shape, obstacle.initial_state)
        else:
            prediction = obstacle.prediction
            if isinstance(prediction, TrajectoryPrediction):
                prediction = TrajectoryPrediction(prediction.trajectory, shape)
            placed = DynamicObstacle(obstacle.obstacle_id, obstacle.obstacle_type, shape, obstacle.initial_state,
                                     prediction)
        scenario.remove_obstacle(obstacle)
        scenario.add_objects(placed)


def _corners(x: float, y: float, head: float, length: float, width: float) -> np.ndarray:
    """The ego rectangle centred on (x, y), its length along ``head`` (as CommonRoad places shapes)."""
    c, s = math.cos(head), math.sin(head)
    local = np.array([[1, 1], [1, -1], [-1, -1], [-1, 1]]) * [length / 2, width / 2]
    return local @ np.array([[c, s], [-s, c]]) + [x, y]


def _limits(trajectory: np.ndarray, goal: tuple[float, float] | None) -> tuple[float, float, float, float]:
    points = trajectory[:, :2] if goal is None else np.vstack([trajectory[:, :2], goal])
    (x0, y0), (x1, y1) = points.min(axis=0) - MARGIN, points.max(axis=0) + MARGIN
    return float(x0), float(x1), float(y0), float(y1)


def _goal_center(problems: Any) -> tuple[float, float] | None:
    """Centre of the first goal region that has a shape position (for the default view), if any."""
    for problem in problems.planning_problem_dict.values():
        for state in problem.goal.state_list:
            position = getattr(state, "position", None)
            center = getattr(position, "center", None)
            if center is not None:
                point = np.asarray(getattr(center, "coords", [center])[0], dtype=float)
                return float(point[0]), float(point[1])
    return None


def _only(problems: Any, problem_id: int, path: Path) -> Any:
    """The planning problem set with the problem ``problem_id`` alone."""
    # commonroad: only when this runs; importing rac.output.render stays light
    from commonroad.planning.planning_problem import PlanningProblemSet

    chosen = problems.planning_problem_dict.get(problem_id)
    if chosen is None:
        ids = ", ".join(map(str, sorted(problems.planning_problem_dict))) or "none"
        raise RenderError(path, f"has no planning problem {problem_id} (its planning problems: {ids})")
    return PlanningProblemSet([chosen])


def _initial_step(problems: Any) -> int:
    steps = [problem.initial_state.time_step for problem in problems.planning_problem_dict.values()]
    return int(min(steps)) if steps else 0


class _Scene:
    """The scenario drawn once (road, planning problem) plus the parts that change per instant."""

    def __init__(self, scenario: Any, problems: Any, ax: Axes, limits: Sequence[float]) -> None:
        # commonroad: only when this runs; importing rac.output.render stays light
        from commonroad.visualization.mp_renderer import MPRenderer

        self.scenario = scenario
        self.ax = ax
        self.renderer = MPRenderer(ax=ax, plot_limits=list(limits))
        params = self.renderer.draw_params
        params.dynamic_obstacle.draw_icon = False
        params.dynamic_obstacle.show_label = False
        scenario.lanelet_network.draw(self.renderer)
        # commonroad-io layers a goal region (zorder 15) over the start (11): a goal around the start (a
        # lanelet goal the ego starts on, as in CommonRoad's tutorial scenario) hid the marker the legend names
        start = params.planning_problem.initial_state.state
        start.zorder = max(start.zorder or 0, params.planning_problem.goal_region.shape.zorder + 1)
        for problem in problems.planning_problem_dict.values():
            self.renderer.draw_planning_problem(problem, params.planning_problem)
        self.renderer.render_static()
        self.renderer.render_dynamic()  # the goal region lands among the "dynamic" patches...
        self.renderer.dynamic_artists = []  # ...but must survive remove_dynamic() of every later instant
        self.renderer.clear()

    def legend_handles(self, problems: Any) -> list[Any]:
        """Legend entries for what commonroad-io drew, in its colours: the static and the moving obstacles
        (those the scenario has), the goal region (if a goal has a shape) and the planning problem's start."""
        params = self.renderer.draw_params
        handles: list[Any] = []
        if self.scenario.static_obstacles:  # commonroad-io draws them in a colour of their own (red)
            shape = params.static_obstacle.occupancy.shape
            handles.append(Patch(facecolor=shape.facecolor, edgecolor=shape.edgecolor, label="static obstacles"))
        if self.scenario.dynamic_obstacles:
            shape = params.dynamic_obstacle.vehicle_shape.occupancy.shape
            label = "moving obstacles" if self.scenario.static_obstacles else "obstacles"
            handles.append(Patch(facecolor=shape.facecolor, edgecolor=shape.edgecolor, label=label))
            path = params.dynamic_obstacle.trajectory
            if path.draw_trajectory:  # commonroad-io dots each obstacle's positions still to come
                handles.append(Line2D([], [], color=path.facecolor, linestyle=":", linewidth=1.2,
                                      label="obstacle paths ahead"))
        if _goal_center(problems) is not None:
            goal = params.planning_problem.goal_region.shape
            handles.append(Patch(facecolor=goal.facecolor, edgecolor=goal.edgecolor, label="goal region"))
        start = params.planning_problem.initial_state.state
        # the problem's, which the ego's path leaves from only when the `model` block keeps it (no start_x,
        # start_y, start_heading): on benchmarks/zam_ramp.ra the ego starts 5 m beside it
        handles.append(Line2D([], [], color=start.facecolor, marker="o", linestyle="", markersize=7,
                              label="planning problem's start"))
        return handles

    def obstacles_note(self, time_step: int) -> str:
        """What to say when the scenario has obstacles but none shows at ``time_step`` in the view (the
        axes' limits): the legend names them, and a map without any read as a scenario without traffic.
        "" when one shows or the scenario has none."""
        (x0, x1), (y0, y1) = self.ax.get_xlim(), self.ax.get_ylim()
        present = 0
        for obstacle in self.scenario.obstacles:
            occupancy = obstacle.occupancy_at_time(time_step)
            if occupancy is None:  # its trajectory has ended: commonroad-io draws it no more
                continue
            present += 1
            # commonroad-io 2026 returns the shape itself, older versions an Occupancy holding it
            left, bottom, right, top = getattr(occupancy, "shape", occupancy).shapely_object.bounds
            if left <= x1 and right >= x0 and bottom <= y1 and top >= y0:
                return ""
        if not self.scenario.obstacles:
            return ""
        if present:
            return f"no obstacle in view at this instant ({counted(present, 'obstacle')} outside the picture)"
        return "no obstacle at this instant: every obstacle's trajectory has ended"

    def show_obstacles(self, time_step: int) -> None:
        """Replace the obstacles by those at ``time_step`` (gone ones vanish, as commonroad-io draws them)."""
        renderer = self.renderer
        renderer.remove_dynamic()
        renderer.clear()
        renderer.draw_params.time_begin = time_step  # propagates to every nested parameter set
        renderer.draw_params.time_end = max(time_step, renderer.draw_params.time_end)
        for obstacle in self.scenario.obstacles:
            obstacle.draw(renderer)
        renderer.render_dynamic()


class SceneFrames:
    """Frames of a CommonRoad scenario with the ego at one instant each, as ``(H, W, 3)`` uint8 RGB
    arrays (gymnasium's ``render_mode="rgb_array"``): the road, the goal, the obstacles at the
    instant and the ego as a ``length`` × ``width`` rectangle, in a ``view`` × ``view / 2`` metre
    window centred on the ego. The scenario is read and the road drawn once; every frame has the
    same size (``size`` pixels, width × height).

    Example::

        frames = SceneFrames("left_turn.xml", sample_period=0.1)
        image = frames.frame(0, x=1.75, y=-18.0, head=math.pi / 2)   # (240, 480, 3) uint8
    """

    def __init__(self, scenario_path: str | os.PathLike[str], *, sample_period: float | None = None,
                 planning_problem: int | None = None, length: float = 4.5, width: float = 1.8,
                 view: float = 80.0, size: tuple[int, int] = (480, 240)) -> None:
        from matplotlib.figure import Figure  # matplotlib: only when a plot is written

        path = Path(scenario_path)
        scenario, problems = _read(path)
        if planning_problem is not None:
            problems = _only(problems, planning_problem, path)
        self._dt = float(scenario.dt)
        self._period = self._dt if sample_period is None else float(sample_period)
        self._start = _initial_step(problems)
        self._view = view
        self._length, self._width = length, width
        dpi = 80
        # no layout engine: the axes fill the figure, and every frame has the same size
        self._figure = Figure(figsize=(size[0] / dpi, size[1] / dpi), dpi=dpi)
        FigureCanvasAgg(self._figure)
        self._ax = self._figure.add_axes((0.0, 0.0, 1.0, 1.0))
        self._ax.set_axis_off()
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # commonroad-io's drawing code warns about deprecated matplotlib use
            self._scene = _Scene(scenario, problems, self._ax, _road_limits(scenario))
        self._body = Polygon(_corners(0.0, 0.0, 0.0, length, width), closed=True, facecolor=EGO_COLOUR,
                             edgecolor="black", linewidth=0.8, zorder=30)
        self._ax.add_patch(self._body)

    def frame(self, sample: int, x: float, y: float, head: float) -> np.ndarray:
        """The picture at sample ``sample`` (CommonRoad time step ``t0 + sample * sample_period / dt``)
        with the ego centred at ``(x, y)`` heading ``head`` (metres, radians)."""
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            self._scene.show_obstacles(self._start + round(sample * self._period / self._dt))
            self._body.set_xy(_corners(x, y, head, self._length, self._width))
            half = self._view / 2
            self._ax.set_xlim(x - half, x + half)
            self._ax.set_ylim(y - half / 2, y + half / 2)
            self._ax.set_aspect("auto")
            canvas = self._figure.canvas
            canvas.draw()
            assert isinstance(canvas, FigureCanvasAgg)
            return np.asarray(canvas.buffer_rgba())[..., :3].copy()


def _road_limits(scenario: Any) -> list[float]:
    """The whole road's bounding box with a margin (commonroad-io draws what lies within)."""
    points = np.vstack([lanelet.polygon.vertices for lanelet in scenario.lanelet_network.lanelets])
    (x0, y0), (x1, y1) = points.min(axis=0) - MARGIN, points.max(axis=0) + MARGIN
    return [float(x0), float(x1), float(y0), float(y1)]


def _validated(trajectory: np.ndarray) -> np.ndarray:
    array = np.asarray(trajectory, dtype=float)
    if array.ndim != 2 or array.shape[0] < 1 or array.shape[1] < 3:
        raise ValueError(f"render_trajectory: trajectory must have shape (T, >=3) of x, y, head; got {array.shape}")
    if not np.isfinite(array[:, :3]).all():
        raise ValueError("render_trajectory: trajectory has non-finite x, y or head values")
    return array[:, :3]


def _frame_samples(n_samples: int, max_frames: int) -> np.ndarray:
    """Every k-th sample with k as small as keeps at most ``max_frames`` frames; always the last one."""
    if n_samples <= max_frames:
        return np.arange(n_samples)
    stride = math.ceil((n_samples - 1) / (max_frames - 1))
    samples = np.arange(0, n_samples, stride)
    return samples if samples[-1] == n_samples - 1 else np.append(samples, n_samples - 1)


def render_trajectory(scenario_path: str | os.PathLike[str], trajectory: np.ndarray, png_path: str | os.PathLike[str],
                      *, gif_path: str | os.PathLike[str] | None = None, time_step: int | None = None,
                      title: str | None = None, sample_period: float | None = None, length: float = 4.5,
                      width: float = 1.8, max_frames: int = 100, plot_limits: Sequence[float] | None = None,
                      figsize: tuple[float, float] | None = None, dpi: int = 100,
                      planning_problem: int | None = None, collision: int | None = None,
                      offroad: int | None = None, marked: dict[str, float] | None = None) -> Path:
    """Draw the CommonRoad scenario in ``scenario_path`` with the ego's trajectory; write the PNG
    (and with ``gif_path`` an animated GIF) and return the PNG's path.

    ``trajectory``: array (T, >=3) of x, y, head (metres, radians) per sample, further columns
    ignored (the engine's ego columns are x, y, v, acc, head: pass ``states[:, [0, 1, 4]]``).
    Sample i is at CommonRoad time step ``t0 + i * sample_period / dt``, where t0 is the planning
    problem's initial time step and ``sample_period`` (seconds) defaults to the scenario's dt.

    The PNG shows the road, the goal, the obstacles at ``time_step`` (default: the last sample's)
    with their remaining trajectories, the ego's path as a line and the ego as a ``length`` ×
    ``width`` rectangle at the sample nearest ``time_step``; a legend below the map names the ego's
    path, the ego, the obstacles, the goal region and the planning problem's start. A long title is
    wrapped to fit.
    The GIF has one frame per sample, or per k-th sample to keep at most ``max_frames`` frames
    (the last sample always included), played in real time, with obstacles and ego moving.
    ``plot_limits`` (xmin, xmax, ymin, ymax) defaults to the path and the goal with a 15 m margin;
    ``figsize`` (inches) to 8 wide and as high as that view and the legend need. ``length`` and
    ``width`` default to rac's vehicle (model.md).
    ``planning_problem`` (an id of the file's) draws that problem only and starts at its initial
    time step, as the model does with the `model` block's ``planning_problem``; None: all of them.
    ``collision`` and ``offroad`` are the samples of the run's first collision and first sample off
    the road (None: none): each is marked on the path (:data:`EVENT_MARKS`, named with its time in
    the legend), in the PNG when it lies at or before the drawn instant, in the GIF from its frame on.
    ``marked``, when given, is filled with the time (seconds, as the legend gives it) of each mark,
    under ``"collision"`` and ``"offroad"``: what a caller says of the picture is what it shows.

    Raises :class:`RenderError` naming the file when it is missing or not a readable CommonRoad
    scenario, ``ValueError`` for a malformed trajectory.

    Example::

        render_trajectory("left_turn.xml", states[:, [0, 1, 4]], "run.png", gif_path="run.gif",
                          sample_period=0.1, title="witness of E<> goal()")
    """
    path = Path(scenario_path)
    ego = _validated(trajectory)
    if max_frames < 2:
        raise ValueError(f"render_trajectory: max_frames must be at least 2, not {max_frames}")
    scenario, problems = _read(path)
    if planning_problem is not None:
        problems = _only(problems, planning_problem, path)
    dt = float(scenario.dt)
    period = dt if sample_period is None else float(sample_period)
    if period <= 0:
        raise ValueError(f"render_trajectory: sample_period must be positive, not {period}")
    start = _initial_step(problems)
    n_samples = ego.shape[0]

    def step_of(sample: int) -> int:
        return start + round(sample * period / dt)

    def time_of(sample: int) -> float:  # the sample's own time: the obstacles' step is only the nearest one
        return round(start * dt + sample * period, 9)

    events = {kind: sample for kind, sample in (("collision", collision), ("offroad", offroad)) if sample is not None}
    for kind, sample in events.items():
        if not 0 <= sample < n_samples:
            raise ValueError(f"render_trajectory: {kind} sample {sample} is not one of the run's 0..{n_samples - 1}")
    if marked is not None:
        marked.update({kind: time_of(sample) for kind, sample in events.items()})

    limits = tuple(plot_limits) if plot_limits is not None else _limits(ego, _goal_center(problems))
    name = title or str(scenario.scenario_id)

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # commonroad-io's drawing code warns about deprecated matplotlib use
        if figsize is None:  # fit the view's aspect, so little of the picture is blank margin
            ratio = (limits[3] - limits[2]) / max(limits[1] - limits[0], 1e-9)
            figsize = (8.0, min(max(7.2 * ratio + 1.0, 3.5), 11.0) + LEGEND_HEIGHT)
        figure = new_figure(*figsize)
        figure.set_dpi(dpi)
        ax = figure.add_subplot()
        scene = _Scene(scenario, problems, ax, limits)
        ax.set_xlim(limits[0], limits[1])
        ax.set_ylim(limits[2], limits[3])
        ax.set_aspect("equal")
        ax.set_xlabel("x (m)")
        ax.set_ylabel("y (m)")
        # the whole path faintly, the part driven so far solid: in the GIF one sees where the ego is going
        ax.plot(ego[:, 0], ego[:, 1], color=EGO_COLOUR, linewidth=1.2, linestyle="--", alpha=0.6, zorder=28)
        (driven,) = ax.plot([], [], color=EGO_COLOUR, linewidth=1.8, zorder=29)
        x0, y0, head0 = ego[0]
        body = Polygon(_corners(x0, y0, head0, length, width), closed=True, facecolor=EGO_COLOUR, edgecolor="black",
                       linewidth=0.8, alpha=0.9, zorder=30)
        ax.add_patch(body)
        marks: list[tuple[int, Line2D]] = []  # each shown from its sample on
        named: list[Line2D] = []  # their legend entries, shown whatever the instant drawn
        for kind, sample in events.items():
            colour, marker, text = EVENT_MARKS[kind]
            style: dict[str, Any] = {"linestyle": "", "marker": marker, "color": colour, "markeredgecolor": "white",
                     "markeredgewidth": 1.2}
            # above the ego's body (30) and commonroad-io's patches (up to 35): a crash lies under the car
            (mark,) = ax.plot([ego[sample, 0]], [ego[sample, 1]], markersize=11, zorder=40, clip_on=False, **style)
            marks.append((sample, mark))
            named.append(Line2D([], [], markersize=8, label=f"{text} (t = {time_of(sample):g} s)", **style))
        handles = [Line2D([], [], color=EGO_COLOUR, linewidth=1.8, label="ego path"),
                   Line2D([], [], color=EGO_COLOUR, linewidth=1.2, linestyle="--", alpha=0.6, label="ego path ahead"),
                   Patch(facecolor=EGO_COLOUR, edgecolor="black", label=f"ego ({length:g} m × {width:g} m)"),
                   *named, *scene.legend_handles(problems)]
        _place_legend(figure, handles)
        ax.set_title("", fontsize=10)
        note = ax.text(0.01, 0.99, "", transform=ax.transAxes, ha="left", va="top", fontsize=9, zorder=60,
                       bbox={"facecolor": "white", "alpha": 0.85, "edgecolor": "#9e9e9e", "boxstyle": "round"})
        wrap_at: list[int | None] = [None]  # the title's wrap width, fitted once (GIF frames reuse it)

        def show(sample: int, step: int) -> None:
            scene.show_obstacles(step)
            note.set_text(scene.obstacles_note(step))
            note.set_visible(bool(note.get_text()))
            driven.set_data(ego[: sample + 1, 0], ego[: sample + 1, 1])
            x, y, head = ego[sample]
            body.set_xy(_corners(x, y, head, length, width))
            for at_sample, mark in marks:
                mark.set_visible(at_sample <= sample)
            text = f"{name}: t = {time_of(sample):g} s (step {step}, sample {sample + 1} of {n_samples})"
            ax.title.set_text(text if wrap_at[0] is None else wrap_text(text, wrap_at[0]))

        if time_step is None:
            shown_sample, shown_step = n_samples - 1, step_of(n_samples - 1)
        else:
            shown_step = int(time_step)
            shown_sample = min(max(round((shown_step - start) * dt / period), 0), n_samples - 1)
        show(shown_sample, shown_step)
        wrap_at[0] = fit_title(figure, ax.title)
        if gif_path is None:
            return save_figure(figure, png_path, dpi=dpi)
        # with a GIF the PNG is kept in memory and the two are renamed together at the end: Ctrl-C while the
        # frames are drawn (seconds) leaves the previous run's pair, not a new picture beside an old animation
        picture = io.BytesIO()
        figure.savefig(picture, format="png", dpi=dpi)
        # the layout is settled by the PNG; re-solving it per frame would take half the frame time
        figure.set_layout_engine("none")
        samples = _frame_samples(n_samples, max_frames)
        frames: list[Image.Image] = []
        for sample in samples:
            show(int(sample), step_of(int(sample)))
            figure.canvas.draw()
            canvas = figure.canvas
            assert isinstance(canvas, FigureCanvasAgg)  # new_figure's
            frames.append(Image.fromarray(np.asarray(canvas.buffer_rgba())).convert("RGB"))
        frame_ms = period * 1000 * (samples[1] - samples[0] if len(samples) > 1 else 1)

        def write(file: IO[bytes]) -> None:
            file.write(picture.getvalue())
            _write_gif(frames, gif_path, frame_ms=frame_ms)

        return atomic_write(png_path, write)


def _place_legend(figure: Any, handles: list[Any]) -> None:
    """The legend below the map, outside the axes: commonroad-io's patches (zorder up to 35) cannot
    cover it and it covers no lanelet, obstacle or goal. One row if it fits the figure's width,
    else as few (full) rows as do."""
    renderer = figure.canvas.get_renderer()
    for rows in range(1, len(handles) + 1):
        columns = math.ceil(len(handles) / rows)
        legend = figure.legend(handles=handles, loc="outside lower center", ncols=columns, fontsize=8, frameon=False,
                               handlelength=1.8, columnspacing=1.2)
        if legend.get_window_extent(renderer).width <= figure.bbox.width - 4 or columns == 1:
            return
        legend.remove()


def _write_gif(frames: list[Image.Image], path: str | os.PathLike[str], frame_ms: float) -> Path:
    # one palette for all frames (taken from the first, which already shows road, goal, cars and ego):
    # per-frame palettes make flat areas flicker between slightly different colours
    first = frames[0].quantize(colors=255, method=Image.Quantize.MEDIANCUT, dither=Image.Dither.NONE)
    rest = [frame.quantize(palette=first, dither=Image.Dither.NONE) for frame in frames[1:]]
    # GIF delays are centiseconds and viewers slow anything under 20 ms down to 100 ms
    delay = max(20, round(frame_ms / 10) * 10)
    durations = [delay] * (len(frames) - 1) + [max(delay, LAST_FRAME_MS)]
    return atomic_write(path, lambda file: first.save(file, format="GIF", save_all=True, append_images=rest,
                                                      duration=durations, loop=0))
