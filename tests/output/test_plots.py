"""The presentation layer: Fig. 7 and sweep / learning-curve plots, scenario rendering, progress bars."""

from __future__ import annotations

import io
import json
import re
from pathlib import Path

import matplotlib.colors
import numpy as np
import pytest
from matplotlib.collections import PathCollection
from matplotlib.patches import Patch
from PIL import Image

from rac.core.files import atomic_write
from rac.output.plots import (
    below_summary,
    plot_first_success,
    plot_learning_curves,
    plot_runs,
    plot_sweep,
    runs_below,
)
from rac.output.progress import Progress, explore_callback
from rac.output.render import RenderError, render_trajectory

LEFT_TURN = Path(__file__).resolve().parents[2] / "examples" / "left_turn" / "left_turn.xml"


def _image(path: Path, kind: str) -> Image.Image:
    image = Image.open(path)
    image.load()
    assert image.format == kind
    return image


def _no_leftovers(folder: Path) -> None:
    assert not [p.name for p in folder.iterdir() if p.name.endswith(".tmp")], "a temporary file was left behind"


# ---------------------------------------------------------------- Fig. 7
def test_runs_below_counts_strictly_below_and_ignores_nan() -> None:
    values = np.array([
        [5.0, 1.0, 4.0],     # below
        [5.0, 3.0, np.nan],  # ended early, never below
        [2.0, 2.0, 2.0],     # touches the threshold only: not below (mindist() < 3*TD is strict)
        [np.nan, np.nan, 0.5],
    ])
    assert runs_below(values, 2.0).tolist() == [True, False, False, True]
    assert below_summary(values, 2.0, "3·TD") == "2 of 4 runs below 3·TD"
    assert runs_below(np.array([3.0, 1.0]), 2.0).tolist() == [True]  # one run as a 1-D array


def test_plot_runs_writes_a_png(tmp_path: Path) -> None:
    rng = np.random.default_rng(7)
    times = np.arange(50) * 0.1
    values = 10 + rng.normal(0, 1, (40, 50)).cumsum(axis=1)
    out = plot_runs(times, values, tmp_path / "fig7.png", threshold=3.0, threshold_label="3·TD", title="test")
    assert out == tmp_path / "fig7.png"
    image = _image(out, "PNG")
    assert image.size == (880, 506) and image.mode == "RGBA"
    assert below_summary(values, 3.0, "3·TD") == f"{int((values.min(axis=1) < 3).sum())} of 40 runs below 3·TD"
    _no_leftovers(tmp_path)


def test_plot_runs_without_threshold_and_with_per_run_times(tmp_path: Path) -> None:
    times = np.tile(np.arange(5.0), (3, 1))
    values = np.array([[1.0, 2, 3, 4, 5], [2, 3, np.nan, np.nan, np.nan], [0, 0, 0, 0, 0]])
    _image(plot_runs(times, values, tmp_path / "a.png"), "PNG")
    with pytest.raises(ValueError, match="times has shape"):
        plot_runs(np.arange(4.0), values, tmp_path / "b.png")


def test_atomic_write_replaces_or_leaves_the_old_file(tmp_path: Path) -> None:
    target = tmp_path / "out.png"
    target.write_bytes(b"old")

    def fail(file: io.BufferedWriter) -> None:
        file.write(b"half")
        raise RuntimeError("disk full")

    with pytest.raises(RuntimeError):
        atomic_write(target, fail)
    assert target.read_bytes() == b"old"
    _no_leftovers(tmp_path)
    atomic_write(target, lambda file: file.write(b"new"))
    assert target.read_bytes() == b"new"


def test_atomic_write_onto_a_folder_names_the_file_asked_for(tmp_path: Path) -> None:
    """os.replace's error named the temporary file too: `python -m rac.model.scenes highway out.xml` with a
    folder out.xml said "Is a directory: '.out.xml.1234.abcd.tmp' -> 'out.xml'"."""
    folder = tmp_path / "out.xml"
    folder.mkdir()
    with pytest.raises(IsADirectoryError) as caught:
        atomic_write(folder, lambda file: file.write(b"new"))
    assert caught.value.filename == str(folder) and caught.value.filename2 is None
    assert ".tmp" not in str(caught.value) and str(folder) in str(caught.value)
    assert [path.name for path in tmp_path.iterdir()] == ["out.xml"]  # no temporary left


# ---------------------------------------------------------------- sweep and learning curves
def test_plot_sweep_writes_a_png(tmp_path: Path) -> None:
    rng = np.random.default_rng(1)
    rows = [{"exponent": e, "sense": 0.1, "decide": 0.2, "min_distances": rng.normal(e + 1, 1, 20),
             "threshold": 1.5, "probability": (0.01, 0.2)} for e in (1, 2, 3)]
    rows.append({"exponent": 4, "sense": 0.2, "decide": 0.4, "min_distances": [np.inf, 5.0], "threshold": 1.5})
    image = _image(plot_sweep(rows, tmp_path / "sweep.png", threshold_label="3·TD"), "PNG")
    assert image.width == 935 and image.height > 300
    with pytest.raises(ValueError, match="no rows"):
        plot_sweep([], tmp_path / "empty.png")


def test_plot_learning_curves_writes_a_png(tmp_path: Path) -> None:
    rng = np.random.default_rng(2)
    curves = {"shielded": rng.normal(0, 1, (4, 30)).cumsum(axis=1), "one seed": rng.normal(0, 1, 30)}
    for band in ("std", "minmax"):
        image = _image(plot_learning_curves(curves, tmp_path / f"{band}.png", band=band, smooth=3), "PNG")
        assert image.size == (825, 484)
    with pytest.raises(ValueError, match="band"):
        plot_learning_curves(curves, tmp_path / "x.png", band="iqr")  # type: ignore[arg-type]


# ---------------------------------------------------------------- progress
def test_progress_is_silent_when_disabled(capsys: pytest.CaptureFixture[str]) -> None:
    with Progress(total=10, desc="exploring", enabled=False) as bar:
        bar.update(3)
        bar.set_postfix(layer=1)
        callback = explore_callback(bar)
        callback(0, 1, 5)
        callback(1, 4, 9)
    assert bar.n == 9
    assert capsys.readouterr() == ("", "")


def test_progress_shows_only_on_a_terminal_unless_forced() -> None:
    pipe = io.StringIO()  # not a TTY
    with Progress(desc="exploring", file=pipe) as bar:
        bar.update(5)
    assert not bar.enabled and pipe.getvalue() == ""
    forced = io.StringIO()
    with Progress(desc="exploring", enabled=True, file=forced) as bar:
        explore_callback(bar)(2, 7, 12)
    assert bar.n == 12
    assert "exploring" in forced.getvalue() and "states" in forced.getvalue()


# ---------------------------------------------------------------- rendering
def _straight(samples: int) -> np.ndarray:
    """The ego driving north at 6 m/s from its start in the left-turn scenario, one sample per 0.1 s."""
    return np.column_stack([np.full(samples, 1.75), -18 + 0.6 * np.arange(samples), np.full(samples, np.pi / 2),
                            np.full(samples, 6.0)])  # an extra column (v) is ignored


def test_render_trajectory_png_and_gif(tmp_path: Path) -> None:
    png = render_trajectory(LEFT_TURN, _straight(10), tmp_path / "run.png", gif_path=tmp_path / "run.gif",
                            max_frames=4, figsize=(4.0, 3.0), dpi=60, title="straight")
    assert png == tmp_path / "run.png"
    assert _image(png, "PNG").size == (240, 180)
    gif = _image(tmp_path / "run.gif", "GIF")
    assert gif.size == (240, 180)
    assert gif.n_frames == 4  # samples 0, 3, 6, 9
    assert gif.info["duration"] == 300  # three samples of 0.1 s per frame
    _no_leftovers(tmp_path)


def test_render_trajectory_at_a_time_step(tmp_path: Path) -> None:
    png = render_trajectory(LEFT_TURN, _straight(5), tmp_path / "t.png", time_step=40, figsize=(4.0, 3.0), dpi=50)
    assert _image(png, "PNG").size == (200, 150)


def test_render_says_when_no_obstacle_is_in_view(figures: list, tmp_path: Path) -> None:
    """docs/images/learned_run.png, at t = 14 s: the cars had driven out of the picture, the legend still
    named "obstacles" and nothing said where they were: the map read as a scenario without traffic."""
    def note(figure) -> str:  # type: ignore[no-untyped-def]
        shown = [text.get_text() for text in figure.axes[0].texts if text.get_visible() and text.get_text()]
        return " ".join(shown)

    render_trajectory(LEFT_TURN, _straight(5), tmp_path / "a.png", time_step=0)   # the cars at their start
    render_trajectory(LEFT_TURN, _straight(5), tmp_path / "b.png", time_step=95,  # far away, still driving
                      plot_limits=(-10.0, 10.0, -30.0, 0.0))
    render_trajectory(LEFT_TURN, _straight(5), tmp_path / "c.png", time_step=400)  # their trajectories ended
    assert note(figures[0]) == ""
    assert note(figures[1]) == "no obstacle in view at this instant (3 obstacles outside the picture)"
    assert note(figures[2]) == "no obstacle at this instant: every obstacle's trajectory has ended"


def test_render_error_names_a_damaged_file(tmp_path: Path) -> None:
    damaged = tmp_path / "damaged.xml"
    data = LEFT_TURN.read_bytes()
    damaged.write_bytes(data[: len(data) // 2])
    with pytest.raises(RenderError, match="damaged.xml") as caught:
        render_trajectory(damaged, _straight(3), tmp_path / "x.png")
    assert caught.value.path == str(damaged)
    assert not (tmp_path / "x.png").exists()
    with pytest.raises(RenderError, match="missing.xml.*cannot be read"):
        render_trajectory(tmp_path / "missing.xml", _straight(3), tmp_path / "x.png")


def test_render_trajectory_rejects_a_malformed_trajectory(tmp_path: Path) -> None:
    with pytest.raises(ValueError, match="shape"):
        render_trajectory(LEFT_TURN, np.zeros((4, 2)), tmp_path / "x.png")
    with pytest.raises(ValueError, match="non-finite"):
        render_trajectory(LEFT_TURN, np.full((4, 3), np.nan), tmp_path / "x.png")


def test_render_draws_the_chosen_planning_problem(tmp_path: Path) -> None:
    """A file with two planning problems: the `model` block's `planning_problem` is the one drawn
    (and its start time the run's); an id the file lacks is a RenderError listing the ids."""
    from tiny_scenarios import SECOND_PROBLEM_ID, junction_with_two_problems

    junction = tmp_path / "junction.xml"
    junction.write_bytes(junction_with_two_problems())
    png = render_trajectory(junction, _straight(3), tmp_path / "one.png", planning_problem=SECOND_PROBLEM_ID,
                            figsize=(4.0, 3.0), dpi=50)
    assert _image(png, "PNG").size == (200, 150)
    with pytest.raises(RenderError, match=r"has no planning problem 999 \(its planning problems: 100, 101\)"):
        render_trajectory(junction, _straight(3), tmp_path / "x.png", planning_problem=999)


# ---------------------------------------------------------------- readable plots
@pytest.fixture
def figures(monkeypatch: pytest.MonkeyPatch) -> list:
    """Every figure the plot functions would save, instead of saving it (no file is written)."""
    import rac.output.plots as plots
    import rac.output.render as render

    caught: list = []

    def keep(figure, path, **options):  # type: ignore[no-untyped-def]
        caught.append(figure)
        return Path(path)

    monkeypatch.setattr(plots, "save_figure", keep)
    monkeypatch.setattr(render, "save_figure", keep)
    return caught


def _inside_figure(figure, artist) -> bool:  # type: ignore[no-untyped-def]
    """Whether ``artist``'s rendered box lies within the figure (Agg renderer, layout solved)."""
    figure.draw_without_rendering()
    box = artist.get_window_extent(figure.canvas.get_renderer())
    room = figure.bbox
    return room.x0 - 0.5 <= box.x0 and box.x1 <= room.x1 + 0.5 and room.y0 - 0.5 <= box.y0 and box.y1 <= room.y1 + 0.5


LONG_NAME = "a_very_long_scenario_file_name_from_an_automated_benchmark_generator_0001_left_turn_variant.ra"


def test_long_titles_fit_in_the_figure(figures: list, tmp_path: Path) -> None:
    """The review's Fig. 7 title was cut at both ends: every title is wrapped or shrunk to fit."""
    values = 5 + np.random.default_rng(3).normal(0, 1, (20, 40)).cumsum(axis=1)
    plot_runs(np.arange(40) * 0.1, values, tmp_path / "a.png", threshold=1.5, threshold_label="3 * collision_distance",
              title=f"{LONG_NAME}: 100 runs under the shield (seed 1641411168)")
    plot_sweep([{"exponent": 1, "sense": 0.1, "decide": 0.5, "min_distances": [1.0, 2.0], "threshold": 0.5}],
               tmp_path / "b.png", title=f"pre-analysis of {LONG_NAME}: runs under the shield")
    plot_learning_curves({"SS&RA": np.ones((2, 5))}, tmp_path / "c.png", title=f"learning curves of {LONG_NAME}")
    plot_first_success({"SS&RA": [3, None]}, 10, tmp_path / "d.png", title=f"first success in {LONG_NAME}")
    render_trajectory(LEFT_TURN, _straight(5), tmp_path / "e.png", title=LONG_NAME, figsize=(4.0, 3.0), dpi=60)
    assert len(figures) == 5
    for figure in figures:
        title = figure.axes[0].title
        assert LONG_NAME[:20] in title.get_text().replace("\n", "")
        assert _inside_figure(figure, title), title.get_text()


def test_a_short_title_is_left_alone(figures: list, tmp_path: Path) -> None:
    plot_runs(np.arange(3.0), np.ones((2, 3)), tmp_path / "a.png", title="left turn")
    assert figures[0].axes[0].get_title() == "left turn: 2 runs"


def test_a_threshold_of_zero_is_labelled_by_its_expression(figures: list, tmp_path: Path) -> None:
    from rac.verify.report import plot_series

    times = np.arange(4) * 0.5
    plot_series(tmp_path / "s.png", times, ["mindist()", "0"], [np.ones((2, 4)), np.zeros((2, 4))], "zero")
    legend = [text.get_text() for text in figures[0].axes[0].get_legend().get_texts()]
    assert "0 = 0" in legend and not any("None" in text for text in legend)


def test_units_of_model_expressions() -> None:
    """The y axis of a simulated quantity says its unit, taken from the vocabulary."""
    from fractions import Fraction

    from rac.ir import expr as ie

    td = ie.model_ref("collision_distance", Fraction(1, 2))
    assert ie.unit_of(ie.call("mindist")) == "m"
    assert ie.unit_of(ie.call("dist_goal")) == "m"
    assert ie.unit_of(ie.Binary("*", ie.Const(Fraction(3)), td)) == "m"
    assert ie.unit_of(ie.Binary("-", ie.call("mindist"), td)) == "m"
    assert ie.unit_of(ie.Prev(ie.model_ref("v"))) == "m/s"
    assert ie.unit_of(ie.call("fabs", ie.model_ref("head"))) == "rad"
    assert ie.unit_of(ie.model_ref("time")) == "s"
    assert ie.unit_of(ie.Binary("/", ie.call("mindist"), ie.model_ref("v"))) is None  # m/(m/s): not worked out
    assert ie.unit_of(ie.Binary("+", ie.call("mindist"), ie.model_ref("v"))) is None  # m + m/s: no unit
    assert ie.unit_of(ie.call("collide")) is None  # a truth value
    assert ie.unit_of(ie.Ref(ie.RefKind.INPUT, "speed", ie.NUM, 0)) is None  # the automaton's own: unknown


def test_simulate_labels_its_axes_with_units(figures: list, tmp_path: Path,
                                             capsys: pytest.CaptureFixture[str]) -> None:
    """``rac simulate`` and a ``simulate`` query: "mindist() (m)", "time (s)", the threshold in metres."""
    from engine_files import write_engine_file

    from rac.cli.main import main
    from rac.compiler import compile_file
    from rac.verify.context import VerifyOptions
    from rac.verify.runner import verify

    path = write_engine_file(tmp_path, "avoidable_obstacle")  # with its queries, "Sim" among them
    assert main(["simulate", str(path), "--runs", "2", "--seed", "1", "--horizon", "1"]) == 0
    results = verify(compile_file(path), VerifyOptions(seed=1, out_dir=tmp_path / "out", only=("Sim",)))
    assert [r.name for r in results] == ["Sim"]
    assert len(figures) == 2
    for figure in figures:
        axes = figure.axes[0]
        assert axes.get_ylabel() == "mindist() (m)" and axes.get_xlabel() == "time (s)"
        legend = [text.get_text() for text in axes.get_legend().get_texts()]
        assert "3 * collision_distance = 1.5 m" in legend


def test_negative_distances_are_explained(figures: list, tmp_path: Path) -> None:
    """A true distance below 0 is an overlap: the plot says so (only when one is drawn)."""
    from rac.model.native import NEGATIVE_DISTANCE_TEXT

    times = np.arange(3.0)
    plot_runs(times, np.array([[2.0, -0.5, 1.0], [3.0, 2.0, 1.0]]), tmp_path / "a.png", threshold=0.5,
              below_zero=NEGATIVE_DISTANCE_TEXT)
    plot_runs(times, np.array([[2.0, 0.7, 1.0]]), tmp_path / "b.png", threshold=0.5, below_zero=NEGATIVE_DISTANCE_TEXT)
    plot_sweep([{"exponent": 1, "sense": 0.1, "decide": 0.5, "min_distances": [-1.0, 2.0], "threshold": 0.5}],
               tmp_path / "c.png", below_zero=NEGATIVE_DISTANCE_TEXT)

    def legend(figure) -> list[str]:  # type: ignore[no-untyped-def]
        return [text.get_text() for text in figure.axes[0].get_legend().get_texts()]

    assert "overlap" in NEGATIVE_DISTANCE_TEXT
    assert NEGATIVE_DISTANCE_TEXT in legend(figures[0])
    assert NEGATIVE_DISTANCE_TEXT not in legend(figures[1])
    assert NEGATIVE_DISTANCE_TEXT in legend(figures[2])


def test_first_success_in_the_last_episode_is_drawn_inside_the_axes(figures: list, tmp_path: Path) -> None:
    """A seed first succeeding in the budget's last episode stepped up on the right frame of the axes
    (x limit = budget): the step and its marker were hidden by the frame, and the legend (lower right)
    covered what was left of it. The budget is marked too."""
    plot_first_success({"SS&RA": [60, 60], "RA": [20, None]}, 60, tmp_path / "f.png")
    (ax,) = figures[0].axes
    assert ax.get_xlim()[1] > 60
    steps = {line.get_label(): line for line in ax.get_lines()}
    ss_ra = steps["SS&RA (2 of 2 seeds)"]
    assert max(ss_ra.get_xdata()) == 60 and max(ss_ra.get_ydata()) == 1.0
    legend = ax.get_legend()
    assert any(text.get_text() == "budget: 60 episodes" for text in legend.get_texts())
    # the legend (lower right, inside) covered that step: now it is beside the axes
    figures[0].draw_without_rendering()
    assert not legend.get_window_extent().overlaps(ax.get_window_extent())


def test_learning_curves_say_they_are_smoothed(figures: list, tmp_path: Path) -> None:
    """returns.png (smooth=10) said only "mean ± sd over seeds": a reader took the 10-episode moving
    average for the episodes' own returns."""
    curves = {"RA": np.arange(40.0).reshape(2, 20)}
    plot_learning_curves(curves, tmp_path / "a.png", title="learning curves", smooth=10)
    plot_learning_curves(curves, tmp_path / "b.png", title="learning curves")
    assert figures[0].axes[0].get_title() == "learning curves (10-episode moving average, mean ± sd over seeds)"
    assert figures[1].axes[0].get_title() == "learning curves (mean ± sd over seeds)"


def test_the_learning_curves_legend_covers_no_band(figures: list, tmp_path: Path) -> None:
    """returns.png's legend (loc="best") sat on RA's shaded band of seeds: best weighs the mean
    lines, not the band around them. Here the bands fill every corner of the axes."""
    episodes = np.arange(60.0)
    curves = {"SS&RF": np.stack([episodes * 0, episodes * 0 + 10]),
              "RA": np.stack([-episodes * 100 - 500, -episodes * 100 + 5000])}
    plot_learning_curves(curves, tmp_path / "a.png")
    figure = figures[0]
    figure.draw_without_rendering()
    ax = figure.axes[0]
    assert not ax.get_legend().get_window_extent().overlaps(ax.get_window_extent())


def test_a_runs_lowest_point_at_the_horizon_is_drawn_whole(figures: list, tmp_path: Path) -> None:
    """Fig. 7 of rac preanalyse: runs lowest at their last sample (t = horizon, the x axis' end) had
    their red marker cut in half by the axes' frame."""
    times = np.arange(4) * 1.0
    plot_runs(times, np.array([[5.0, 4.0, 3.0, 0.2], [5.0, 5.0, 5.0, 5.0]]), tmp_path / "a.png", threshold=1.0)
    ax = figures[0].axes[0]
    (marks,) = ax.collections[-1:]
    assert marks.get_offsets().tolist() == [[3.0, 0.2]] and ax.get_xlim()[1] == 3.0
    assert not marks.get_clip_on()


def test_episode_axes_have_whole_ticks(figures: list, tmp_path: Path) -> None:
    """A learning curve of one episode had ticks at 0.96, 0.98, 1.00, ... episodes; a budget of 3 at 0.5."""
    plot_learning_curves({"RA": np.array([[5.0], [6.0]])}, tmp_path / "a.png")
    plot_first_success({"RA": [1, None]}, 3, tmp_path / "b.png")
    for figure in figures:
        figure.draw_without_rendering()
        ax = figure.axes[0]
        low, high = ax.get_xlim()
        ticks = [tick for tick in ax.get_xticks() if low <= tick <= high]
        assert ticks and all(float(tick).is_integer() for tick in ticks), ticks


def test_first_success_says_one_seed_in_the_singular(figures: list, tmp_path: Path) -> None:
    """`rac experiment --seeds 1`: the legend read "RA (0 of 1 seeds)"."""
    plot_first_success({"RA": [None], "RF": [4, None]}, 10, tmp_path / "a.png")
    texts = [text.get_text() for text in figures[0].axes[0].get_legend().get_texts()]
    assert texts[:2] == ["RA (0 of 1 seed)", "RF (1 of 2 seeds)"]


def test_a_run_of_one_sample_is_drawn(figures: list, tmp_path: Path) -> None:
    """A run with a single value (one sample, or one between two gaps) is no line segment: the runs
    plot drew nothing for it (and a single instant stood on the left frame). It is a dot now, in the
    run's colour."""
    nan = np.nan
    values = np.array([[4.0, nan, nan, nan], [nan, 3.0, nan, 2.0], [1.0, 0.5, nan, nan]])
    plot_runs(np.arange(4.0), values, tmp_path / "a.png", threshold=1.0, highlight_below=False)
    plot_runs(np.array([0.0]), np.array([[3.0], [0.5]]), tmp_path / "b.png", threshold=1.0)
    def dots(figure) -> list[tuple[float, float]]:  # type: ignore[no-untyped-def]
        return sorted(tuple(point) for c in figure.axes[0].collections if isinstance(c, PathCollection)
                      for point in c.get_offsets().tolist())

    assert dots(figures[0]) == [(0.0, 4.0), (1.0, 3.0), (3.0, 2.0)]  # not the two-sample run's
    assert (0.0, 3.0) in dots(figures[1])
    low, high = figures[1].axes[0].get_xlim()
    assert low < 0.0 < high  # the one instant inside the axes, not on its left frame


def test_a_learning_curve_without_values_says_so(figures: list, tmp_path: Path) -> None:
    """A combination with no episode (all NaN, or none at all) stood in the legend as if drawn."""
    plot_learning_curves({"RA": np.array([[5.0, 6.0]]), "RF": np.full((2, 2), np.nan),
                          "SS&RF": np.zeros((1, 0))}, tmp_path / "a.png")
    texts = [text.get_text() for text in figures[0].axes[0].get_legend().get_texts()]
    assert texts == ["RA (1 seed)", "RF (2 seeds): no episode to draw", "SS&RF (1 seed): no episode to draw"]


def _linestyle_and_marker(line) -> tuple[object, str]:  # type: ignore[no-untyped-def]
    return line.get_linestyle(), line.get_marker()


def test_learning_curves_cannot_hide_each_other(figures: list, tmp_path: Path) -> None:
    """Four identical curves: each has its own line style and marker; the title says the band once."""
    curves = {name: np.zeros((3, 50)) for name in ("SS&RA", "SS&RF", "RA", "RF")}
    plot_learning_curves(curves, tmp_path / "a.png", title="learning curves")
    plot_first_success({name: [5, None] for name in curves}, 50, tmp_path / "b.png")
    for figure in figures:
        lines = [line for line in figure.axes[0].get_lines() if line.get_label() and
                 not line.get_label().startswith("_")]
        assert len(lines) == 4
        styles = [line.get_linestyle() for line in lines]
        markers = [line.get_marker() for line in lines]
        assert len(set(styles)) == 4 and len(set(markers)) == 4, (styles, markers)
        assert all(marker not in ("", "None", None) for marker in markers)
    assert figures[0].axes[0].get_title() == "learning curves (mean ± sd over seeds)"


def test_the_render_legend_names_everything_and_lies_above_the_map(figures: list, tmp_path: Path) -> None:
    render_trajectory(LEFT_TURN, _straight(20), tmp_path / "r.png", time_step=10)
    (figure,) = figures
    ax = figure.axes[0]
    legends = [*figure.legends, *([ax.get_legend()] if ax.get_legend() else [])]
    assert len(legends) == 1
    (legend,) = legends
    labels = [text.get_text() for text in legend.get_texts()]
    assert labels[0] == "ego path" and any(label.startswith("ego (4.5 m") for label in labels)
    assert "obstacles" in labels and "goal region" in labels
    # the marker commonroad-io draws is the planning problem's initial state, not where the ego's path
    # begins (a `model` block's start_x, start_y move that): it was labelled "start"
    assert "planning problem's start" in labels and "start" not in labels
    figure.draw_without_rendering()
    renderer = figure.canvas.get_renderer()
    box = legend.get_window_extent(renderer)
    # outside the map, so no lanelet, obstacle or goal is hidden under it or drawn over it
    assert box.y1 <= ax.get_window_extent(renderer).y0 + 0.5 or box.x0 >= ax.get_window_extent(renderer).x1 - 0.5
    if legend in ax.get_children():  # an axes legend must also be drawn after every map artist
        assert legend.get_zorder() > max(a.get_zorder() for a in ax.get_children() if a is not legend)
    assert _inside_figure(figure, legend)


def test_the_planning_problems_start_is_drawn_over_a_goal_around_it(figures: list, tmp_path: Path) -> None:
    """commonroad-io layers the goal region over the start: a goal the ego starts in (a lanelet goal the
    ego starts on, as in CommonRoad's tutorial scenario) hid the marker the legend names."""
    text = LEFT_TURN.read_text(encoding="utf-8")
    goal = re.compile(r"(<goalState>.*?<position>).*?(</position>)", re.S)
    assert goal.search(text)
    around = r"\1<rectangle><length>12</length><width>12</width><center><x>1.75</x><y>-18</y></center></rectangle>\2"
    scene = tmp_path / "start_in_goal.xml"
    scene.write_text(goal.sub(around, text, count=1), encoding="utf-8")
    away = _straight(5)
    away[:, 1] += 30  # the drawn run starts elsewhere, so only the marker is at the problem's start
    render_trajectory(scene, away, tmp_path / "r.png")
    (figure,) = figures
    ax = figure.axes[0]
    figure.canvas.draw()
    pixels = np.asarray(figure.canvas.buffer_rgba())[..., :3]
    x, y = ax.transData.transform((1.75, -18.0))
    colour = pixels[int(round(pixels.shape[0] - y)), int(round(x))]
    assert tuple(int(c) for c in colour) == (0, 128, 0), colour  # commonroad-io's start marker ("g"), not the goal


def test_the_render_legend_names_static_obstacles_in_their_colour(figures: list, tmp_path: Path) -> None:
    """commonroad-io draws a static obstacle red, a moving one blue: the legend named only the blue ones."""
    parked = ('<staticObstacle id="900"><type>parkedVehicle</type><shape><rectangle><length>4</length>'
              "<width>2</width></rectangle></shape><initialState><position><point><x>5</x><y>-10</y></point>"
              "</position><orientation><exact>0</exact></orientation><time><exact>0</exact></time></initialState>"
              "</staticObstacle>\n  <planningProblem")
    scene = tmp_path / "parked.xml"
    scene.write_text(LEFT_TURN.read_text(encoding="utf-8").replace("<planningProblem", parked, 1), encoding="utf-8")
    render_trajectory(scene, _straight(5), tmp_path / "r.png")
    render_trajectory(LEFT_TURN, _straight(5), tmp_path / "s.png")
    parked_figure, plain_figure = figures

    def entries(figure) -> dict[str, str]:  # type: ignore[no-untyped-def]
        legend = figure.legends[0] if figure.legends else figure.axes[0].get_legend()
        return {text.get_text(): matplotlib.colors.to_hex(handle.get_facecolor())
                for text, handle in zip(legend.get_texts(), legend.legend_handles) if isinstance(handle, Patch)}

    colours = entries(parked_figure)
    assert colours["static obstacles"] == "#d95558" and colours["moving obstacles"] == "#1d7eea", colours
    assert "obstacles" in entries(plain_figure) and "static obstacles" not in entries(plain_figure)


def test_an_obstacle_is_drawn_where_its_shape_is_placed(figures: list, tmp_path: Path) -> None:
    """A rectangle placed by its own <center> in the obstacle's frame: the model has it there (load_scenario),
    commonroad-io's drawing stood it at the obstacle's position."""
    parked = ('<staticObstacle id="900"><type>parkedVehicle</type><shape><rectangle><length>4</length>'
              "<width>2</width><orientation>0</orientation><center><x>8</x><y>0</y></center></rectangle></shape>"
              "<initialState><position><point><x>-10</x><y>-10</y></point></position><orientation><exact>0</exact>"
              "</orientation><time><exact>0</exact></time></initialState></staticObstacle>\n  <planningProblem")
    scene = tmp_path / "placed.xml"
    scene.write_text(LEFT_TURN.read_text(encoding="utf-8").replace("<planningProblem", parked, 1), encoding="utf-8")
    render_trajectory(scene, _straight(5), tmp_path / "r.png")
    (figure,) = figures
    ax = figure.axes[0]
    figure.canvas.draw()
    pixels = np.asarray(figure.canvas.buffer_rgba())[..., :3]

    def colour(x: float, y: float) -> tuple[int, ...]:
        column, row = ax.transData.transform((x, y))
        return tuple(int(c) for c in pixels[int(round(pixels.shape[0] - row)), int(round(column))])

    static = tuple(int(round(255 * c)) for c in matplotlib.colors.to_rgb("#d95558"))  # commonroad-io's
    assert colour(-2.0, -10.0) == static  # where the file places it (8 m ahead of its position)
    assert colour(-10.0, -10.0) != static


def test_the_fig7_legend_goes_where_no_run_is(figures: list, tmp_path: Path) -> None:
    """matplotlib's loc="best" ignores LineCollections: the legend takes the corner with fewest samples."""
    times = np.arange(20.0)
    rising = np.tile(np.linspace(0.0, 10.0, 20), (5, 1))  # every run ends in the upper right
    plot_runs(times, rising, tmp_path / "a.png", threshold=1.0)
    plot_runs(times, rising[:, ::-1], tmp_path / "b.png", threshold=1.0)  # ... or starts in the upper left
    assert figures[0].axes[0].get_legend()._loc == 2  # upper left
    assert figures[1].axes[0].get_legend()._loc == 1  # upper right


def test_a_bare_threshold_takes_the_unit_it_is_compared_with(figures: list, tmp_path: Path) -> None:
    from fractions import Fraction

    from rac.ir import expr as ie
    from rac.model.native import NEGATIVE_DISTANCE_TEXT
    from rac.verify.report import plot_series

    distances = np.array([[3.0, -0.2, 1.0]])
    plot_series(tmp_path / "a.png", np.arange(3.0), ["mindist()", "1.5"], [distances, np.full((1, 3), 1.5)], "t",
                (ie.call("mindist"), ie.Const(Fraction(3, 2))))
    plot_series(tmp_path / "b.png", np.arange(3.0), ["mindist() - 1", "v"], [distances, np.ones((1, 3))], "t",
                (ie.Binary("-", ie.call("mindist"), ie.Const(Fraction(1))), ie.model_ref("v")))
    first, second = ([text.get_text() for text in figure.axes[0].get_legend().get_texts()] for figure in figures)
    assert "1.5 = 1.5 m" in first and NEGATIVE_DISTANCE_TEXT in first
    assert "v = 1 m/s" in second and NEGATIVE_DISTANCE_TEXT not in second  # below 0 is no overlap here
    assert figures[1].axes[0].get_ylabel() == "mindist() - 1 (m)"


def test_values_near_the_float_limit_are_drawn_clipped_and_judged_as_they_are(tmp_path: Path) -> None:
    # matplotlib cannot lay out an axis spanning ±1.7e308 (a `simulate[...]{1e308, 0-1e308}` query
    # was an internal error); the runs below the threshold are still counted on the values themselves
    values = np.array([[1.7e308, 1.0, 2.0], [-1.7e308, 1.0, 2.0]])
    path = plot_runs(np.arange(3) * 0.1, values, tmp_path / "far.png", threshold=-1e305, threshold_label="t")
    with Image.open(path) as image:
        assert image.format == "PNG"
    assert below_summary(values, -1e305, "t").startswith("1 of 2 runs")


def _event_marks(figure) -> dict[str, list]:  # type: ignore[no-untyped-def]
    """The lines of ``figure``'s map marking the first collision ("X") and off-road sample ("D")."""
    return {marker: [line for line in figure.axes[0].get_lines() if line.get_marker() == marker]
            for marker in ("X", "D")}


def test_render_marks_where_the_run_first_collides_and_leaves_the_road(figures: list, tmp_path: Path,
                                                                      capsys: pytest.CaptureFixture[str]) -> None:
    """`rac render` of a run that drove into the wall and off the road drew the path as if nothing had
    happened there: the first collision and the first off-road sample are marked on the path now, each
    with its own marker, named with its time in the legend."""
    from engine_files import write_engine_file

    from rac.cli.main import main

    path = write_engine_file(tmp_path, "goal_behind_wall")  # 8 m/s towards a wall across the road
    assert main(["render", str(path), "--seed", "1", "-o", str(tmp_path / "out"), "-q"]) == 0
    capsys.readouterr()
    (figure,) = figures
    marks = _event_marks(figure)
    assert [len(marks["X"]), len(marks["D"])] == [1, 1] and all(line.get_visible() for line in marks["X"] + marks["D"])
    texts = [text.get_text() for text in figure.legends[0].get_texts()]
    named = [text for text in texts if text.startswith(("first collision (t = ", "first off-road sample (t = "))]
    assert len(named) == 2, texts
    # at the run's own position at that time: the path (a line of the ego's samples, 0.5 s apart) passes there
    path_line = next(line for line in figure.axes[0].get_lines() if len(line.get_xdata()) == 9)
    collided_at = float(named[0].split("t = ")[1].split(" s")[0])
    sample = round(collided_at / 0.5)
    assert marks["X"][0].get_xydata().tolist() == [path_line.get_xydata()[sample].tolist()]


def test_render_says_the_marked_times_in_its_summary_and_json(figures: list, tmp_path: Path,
                                                             capsys: pytest.CaptureFixture[str]) -> None:
    """The picture marked the first collision and off-road sample with their times, but `rac render`'s
    printed summary and its `--format json` document said nothing of them: both give the legend's times
    now (null in the JSON when the run has none)."""
    from engine_files import write_engine_file

    from rac.cli.main import main

    path = write_engine_file(tmp_path, "goal_behind_wall")  # 8 m/s towards a wall across the road
    out = str(tmp_path / "out")
    assert main(["render", str(path), "--seed", "1", "-o", out, "--format", "json", "-q"]) == 0
    document = json.loads(capsys.readouterr().out)
    texts = [text.get_text() for text in figures[0].legends[0].get_texts()]
    assert f"first collision (t = {document['first_collision']:g} s)" in texts, (texts, document)
    assert f"first off-road sample (t = {document['first_offroad']:g} s)" in texts, (texts, document)
    assert main(["render", str(path), "--seed", "1", "-o", out]) == 0
    printed = capsys.readouterr().out
    assert (f"the run: first collision at t = {document['first_collision']:g} s; first off-road sample at "
            f"t = {document['first_offroad']:g} s") in printed, printed
    calm = write_engine_file(tmp_path, "goal_ahead", {})
    assert main(["render", str(calm), "--seed", "4", "-o", out, "--format", "json", "-q"]) == 0
    document = json.loads(capsys.readouterr().out)
    texts = [text.get_text() for text in figures[-1].legends[0].get_texts()]
    assert "first off-road sample (t = 1 s)" in texts and not any(t.startswith("first collision") for t in texts)
    assert document["first_collision"] is None and document["first_offroad"] == 1, document  # none: null


def test_the_marks_appear_from_their_instant_on(figures: list, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """The PNG drawn before the collision leaves it unmarked (the legend still names it); the GIF's
    frames show the mark from the collision's frame on, and the drawing stays deterministic."""
    render_trajectory(LEFT_TURN, _straight(20), tmp_path / "early.png", time_step=5, collision=12, offroad=3)
    marks = _event_marks(figures[0])
    assert [line.get_visible() for line in marks["X"]] == [False] and [m.get_visible() for m in marks["D"]] == [True]
    texts = [text.get_text() for text in figures[0].legends[0].get_texts()]
    assert "first collision (t = 1.2 s)" in texts and "first off-road sample (t = 0.3 s)" in texts
    with pytest.raises(ValueError, match="collision sample 20"):
        render_trajectory(LEFT_TURN, _straight(20), tmp_path / "x.png", collision=20)

    import rac.output.render as render
    from rac.output.plots import new_figure

    made: list = []
    shown: list[bool] = []  # whether the collision's mark is drawn, frame by frame
    original = Image.fromarray

    def made_figure(*size: float):  # type: ignore[no-untyped-def]
        made.append(new_figure(*size))
        return made[-1]

    def frame(*args, **options):  # type: ignore[no-untyped-def]  # each GIF frame is taken from the canvas here
        shown.append(_event_marks(made[-1])["X"][0].get_visible())
        return original(*args, **options)

    monkeypatch.setattr(render, "new_figure", made_figure)
    monkeypatch.setattr(Image, "fromarray", frame)
    gifs = []
    for name in ("a", "b"):
        shown.clear()
        render_trajectory(LEFT_TURN, _straight(20), tmp_path / f"{name}.png", gif_path=tmp_path / f"{name}.gif",
                          collision=12, figsize=(4.0, 3.0), dpi=50)
        gifs.append((tmp_path / f"{name}.gif").read_bytes())
        assert shown == [sample >= 12 for sample in range(20)]
    assert gifs[0] == gifs[1]
