"""The presentation layer: Fig. 7 and sweep / learning-curve plots, scenario rendering, progress bars."""

from __future__ import annotations

import io
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from rac.output.plots import atomic_write, below_summary, plot_learning_curves, plot_runs, plot_sweep, runs_below
from rac.output.progress import Progress, explore_callback
from rac.output.render import RenderError, render_trajectory

LEFT_TURN = Path(__file__).resolve().parent.parent / "examples" / "left_turn" / "left_turn.xml"


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
