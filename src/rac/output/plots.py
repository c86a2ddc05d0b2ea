"""Figures of simulated runs, of the pre-analysis sweep and of learning curves, written as PNG files.

Every function draws on a standalone :class:`matplotlib.figure.Figure` rendered by the Agg canvas:
pyplot is never imported here, so no GUI window can open and the caller's matplotlib backend is
left alone. Files are written atomically (:func:`rac.core.files.atomic_write`: a temporary file in
the same folder, then :func:`os.replace`), so a reader never sees half a PNG, and each function returns the path.

Example::

    import numpy as np
    from rac.output.plots import plot_runs, runs_below

    times = np.arange(0, 30, 0.1)
    values = np.random.default_rng(0).uniform(0.5, 20, (100, times.size))  # e.g. mindist() per sample
    plot_runs(times, values, "fig7.png", threshold=1.5, threshold_label="3·TD")
    print(runs_below(values, 1.5).sum(), "runs go below 3·TD")
"""

from __future__ import annotations

import os
import textwrap
import warnings
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any, Literal

import matplotlib
import numpy as np
from matplotlib.axes import Axes
from matplotlib.axis import Axis
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.collections import LineCollection
from matplotlib.figure import Figure
from matplotlib.lines import Line2D
from matplotlib.patches import Patch
from matplotlib.text import Text
from matplotlib.ticker import MaxNLocator
from matplotlib.transforms import blended_transform_factory

from rac.core.diagnostics import counted
from rac.core.files import atomic_write
from rac.model.native import NO_OBSTACLE

__all__ = [
    "ABOVE_COLOUR", "BELOW_COLOUR", "CURVE_STYLES", "THRESHOLD_COLOUR", "below_summary", "curve_style",
    "fit_title", "new_figure", "plot_first_success", "plot_learning_curves", "plot_runs", "plot_sweep",
    "quantity_label", "runs_below", "save_figure", "whole_ticks", "wrap_text",
]

ABOVE_COLOUR = "#4c72b0"  #: runs / settings that stay at or above the threshold
BELOW_COLOUR = "#c62828"  #: runs / settings that go below it
THRESHOLD_COLOUR = "#212121"
#: boxplot's keyword for horizontal boxes: ``vert`` is deprecated from matplotlib 3.11, ``orientation`` new in 3.10
_HORIZONTAL: dict[str, Any] = (
    {"orientation": "horizontal"} if tuple(int(p) for p in matplotlib.__version__.split(".")[:2]) >= (3, 10)
    else {"vert": False})
_CYCLE = ("#4c72b0", "#dd8452", "#55a868", "#c44e52", "#8172b3", "#937860", "#da8bc3", "#8c8c8c", "#ccb974",
          "#64b5cd")
#: Line styles and markers of curves drawn over one another (learning curves often coincide: the
#: style and marker tell them apart where the colours hide each other). Pairs repeat after 12.
CURVE_STYLES: tuple[tuple[str, ...], tuple[str, ...]] = (("-", "--", "-.", ":"), ("o", "s", "^", "D", "v", "P"))
#: The region of values below 0 (an overlap, for distances) is tinted with this colour.
_NEGATIVE_TINT = "#fdeeee"
#: The smallest font size a title is shrunk to before it is wrapped into more lines.
_SMALLEST_TITLE = 7.0


# ---------------------------------------------------------------- figures
def new_figure(width: float, height: float) -> Figure:
    """A figure of ``width`` × ``height`` inches on an Agg canvas, independent of pyplot."""
    figure = Figure(figsize=(width, height), layout="constrained")
    FigureCanvasAgg(figure)
    return figure


def save_figure(figure: Figure, path: str | os.PathLike[str], *, dpi: int = 110) -> Path:
    """Write ``figure`` as a PNG to ``path`` atomically and return the path."""
    return atomic_write(path, lambda file: figure.savefig(file, format="png", dpi=dpi))


def whole_ticks(axis: Axis) -> None:
    """Ticks at whole numbers only on ``axis`` (an axis of counts: episodes, lanelets), with matplotlib's
    default steps: its default locator put a short range's ticks at 0.96, 0.98, ..."""
    axis.set_major_locator(MaxNLocator("auto", steps=[1, 2, 2.5, 5, 10], integer=True, min_n_ticks=1))


# ---------------------------------------------------------------- labels
def quantity_label(text: str, unit: str | None) -> str:
    """An axis label: the quantity and its unit in brackets, ``"mindist() (m)"``; the text alone
    when it has no unit (None or "").

    Example::

        >>> quantity_label("3 * collision_distance", "m")
        '3 * collision_distance (m)'
    """
    return f"{text} ({unit})" if unit else text


def curve_style(index: int) -> tuple[str, str, str]:
    """The colour, line style and marker of the ``index``-th of several curves on one axes."""
    styles, markers = CURVE_STYLES
    return _CYCLE[index % len(_CYCLE)], styles[index % len(styles)], markers[index % len(markers)]


def wrap_text(text: str, width: int) -> str:
    """``text`` wrapped at spaces into lines of at most ``width`` characters (a longer word, such as
    a file name, is broken); its own line breaks are kept."""
    return "\n".join(line for paragraph in text.split("\n")
                     for line in textwrap.wrap(paragraph, max(width, 1), break_on_hyphens=False) or [""])


def fit_title(figure: Figure, title: Text) -> int | None:
    """Wrap ``title`` into shorter lines, and shrink its font when that takes more than three lines
    or the lines become very short, until its rendered box lies inside ``figure``: a long title
    (a long file name) is otherwise cut off at both ends. Returns the width in characters it was
    wrapped at (None: it fitted as it was), so a text that later changes a little (a GIF frame's
    time) can be wrapped alike with :func:`wrap_text`. Each try lays the figure out once (no pixels)."""
    text = title.get_text()
    width: int | None = None
    renderer = figure.canvas.get_renderer()  # type: ignore[attr-defined]  # Agg: new_figure's canvas
    for _ in range(30):
        figure.draw_without_rendering()
        box, room = title.get_window_extent(renderer), figure.bbox
        centre = (box.x0 + box.x1) / 2
        available = 2 * min(centre - room.x0, room.x1 - centre) - 2  # a title is centred: the nearer edge counts
        fits_across = box.width <= available
        if fits_across and box.y0 >= room.y0 and box.y1 <= room.y1:
            return width
        smallest = float(title.get_fontsize()) <= _SMALLEST_TITLE
        if fits_across:  # too tall: only a smaller font helps
            if smallest:
                return width
            chars = 0
        else:
            longest = max(len(line) for line in title.get_text().split("\n"))
            chars = min(longest - 1, int(longest * max(available, 0.0) / max(box.width, 1.0)))
        wrapped = wrap_text(text, chars) if chars >= 1 else text
        lines = wrapped.count("\n")
        while chars > 1 and wrap_text(text, chars - 1).count("\n") == lines:  # balanced: no word alone below
            chars -= 1
            wrapped = wrap_text(text, chars)
        if chars >= 1 and (smallest or (chars >= 16 and lines < 3)):
            title.set_text(wrapped)
            width = chars
        elif not smallest:  # too many or too short lines, or too tall: a smaller font, then wrap again
            title.set_fontsize(max(_SMALLEST_TITLE, float(title.get_fontsize()) - 1))
            title.set_text(text)
            width = None
        else:
            return width
    return width


# ---------------------------------------------------------------- Fig. 7: runs against a threshold
def runs_below(values: np.ndarray, threshold: float) -> np.ndarray:
    """Which runs go strictly below ``threshold`` at some sample: a bool array, one per run.

    ``values`` has shape (N, T) (or (T,) for one run); NaN samples (runs that ended early) never
    count, matching a guard like ``mindist() < 3 * TD``.

    Example::

        >>> runs_below(np.array([[5.0, 1.0, 4.0], [5.0, 3.0, np.nan]]), 2.0)
        array([ True, False])
    """
    values = np.atleast_2d(np.asarray(values, dtype=float))
    with np.errstate(invalid="ignore"):
        return np.any(values < threshold, axis=1)


def below_summary(values: np.ndarray, threshold: float, threshold_label: str = "threshold") -> str:
    """The count :func:`plot_runs` puts in its title, e.g. ``"12 of 100 runs below 3·TD"``.

    Example::

        >>> below_summary(np.array([[5.0, 1.0], [5.0, 3.0]]), 2.0, "3·TD")
        '1 of 2 runs below 3·TD'
    """
    below = runs_below(values, threshold)
    return f"{int(below.sum())} of {below.size} run{'s' * (below.size != 1)} below {threshold_label}"


#: :func:`plot_runs` draws values beyond ± this at it: matplotlib cannot lay out an axis whose span
#: overflows a float (values near ±1e308), and no plot of such values is read for their digits.
DRAW_LIMIT = 1e300


def plot_runs(times: np.ndarray, values: np.ndarray, path: str | os.PathLike[str], *,
              threshold: float | None = None, threshold_label: str = "threshold", ylabel: str = "distance (m)",
              xlabel: str = "time (s)", title: str | None = None, highlight_below: bool = True,
              missing: float | None = NO_OBSTACLE, missing_label: str = "no obstacle", unit: str = "",
              below_zero: str | None = None) -> Path:
    """The paper's Fig. 7: N simulated runs of a quantity (e.g. ``mindist()``) over time, against a
    horizontal threshold line; write the PNG to ``path`` and return it.

    ``values`` has shape (N, T), one row per run; ``times`` shape (T,) shared by every run or (N, T).
    NaN samples leave gaps (a run that ended early). With ``threshold`` the runs that go below it
    (:func:`runs_below`) are drawn in red on top of the others, their lowest point marked, and
    counted in the legend and the title: "12 of 100 runs below 3·TD".

    Samples equal to ``missing`` (default :data:`rac.model.native.NO_OBSTACLE`, what ``mindist()``
    reads when no obstacle exists) have no value: they leave gaps too, the legend says
    ``missing_label`` (and at how many samples), and the axes are scaled to the other values; when
    every sample is missing, the plot says so instead of drawing a line at 1e9.

    ``unit`` follows the threshold's value in the legend (``3·TD = 1.5 m``). ``below_zero``
    explains values below 0 (for ``mindist()``: :data:`rac.model.native.NEGATIVE_DISTANCE_TEXT`):
    when a run goes below 0, that region is tinted and the legend says ``below_zero``. A long
    title is wrapped to fit (:func:`fit_title`).

    Example::

        plot_runs(np.arange(300) * 0.1, mindist, "fig7.png", threshold=3 * 0.5, threshold_label="3·TD",
                  title="left turn, exponent 2", unit="m", ylabel="mindist() (m)")
    """
    values = np.atleast_2d(np.asarray(values, dtype=float))
    absent = values == missing if missing is not None else np.zeros(values.shape, dtype=bool)
    values = np.where(absent, np.nan, values)
    n_runs, n_samples = values.shape
    times = np.asarray(times, dtype=float)
    if times.shape == (n_samples,):
        times = np.broadcast_to(times, values.shape)
    elif times.shape != values.shape:
        raise ValueError(f"plot_runs: times has shape {times.shape}; expected ({n_samples},) or {values.shape}")

    below = runs_below(values, threshold) if threshold is not None else np.zeros(n_runs, dtype=bool)
    clipped = int((np.abs(values) > DRAW_LIMIT).sum())  # counted and judged above as they are, drawn clipped
    values = np.clip(values, -DRAW_LIMIT, DRAW_LIMIT)  # NaN stays NaN
    drawn = None if threshold is None else float(np.clip(threshold, -DRAW_LIMIT, DRAW_LIMIT))
    n_below = int(below.sum())
    emphasise = highlight_below and threshold is not None
    figure = new_figure(8.0, 4.6)
    ax = figure.add_subplot()
    # one collection per colour instead of N Line2D artists: thousands of runs stay fast to draw
    segments = np.stack([times, values], axis=-1)
    alpha = float(np.clip(8.0 / max(n_runs, 1), 0.15, 0.9))  # many runs: lighter, so density shows
    others = ~below if emphasise else np.ones(n_runs, dtype=bool)
    ax.add_collection(LineCollection(segments[others], colors=ABOVE_COLOUR, linewidths=0.9, alpha=alpha, zorder=2))
    handles: list[Any] = []
    finite = np.isfinite(values)
    # a sample without a finite neighbour (a run of one sample, one stopped after its first, a value between
    # two "no obstacle" gaps) is no line segment: drawn as a dot, else it was not drawn at all
    padded = np.pad(finite, ((0, 0), (1, 1)))
    alone = finite & ~padded[:, :-2] & ~padded[:, 2:]
    for rows, colour in ((others, ABOVE_COLOUR), (~others, BELOW_COLOUR)):
        dots = alone & rows[:, None]
        if dots.any():
            ax.scatter(times[dots], values[dots], s=16, color=colour, zorder=3, linewidths=0, clip_on=False)
    if not finite.any():
        pass  # no run to show: only the threshold and the note below
    elif emphasise:
        handles.append(Line2D([], [], color=ABOVE_COLOUR, lw=1.5,
                              label=f"{counted(n_runs - n_below, 'run')} staying above"))
        if n_below:
            ax.add_collection(LineCollection(segments[below], colors=BELOW_COLOUR, linewidths=1.1,
                                             alpha=max(alpha, 0.6), zorder=3))
            lowest = np.nanargmin(values[below], axis=1)
            rows = np.flatnonzero(below)
            # unclipped: a run lowest at its last sample (or first) had half its marker cut off by the frame
            ax.scatter(times[rows, lowest], values[rows, lowest], s=14, color=BELOW_COLOUR, zorder=4,
                       edgecolors="white", linewidths=0.5, clip_on=False)
        handles.append(Line2D([], [], color=BELOW_COLOUR, lw=1.5, marker="o", markersize=4,
                              label=f"{counted(n_below, 'run')} below {threshold_label}"))
    else:
        handles.append(Line2D([], [], color=ABOVE_COLOUR, lw=1.5, label=counted(n_runs, "run")))
    if drawn is not None:  # a threshold, drawn within the axis
        ax.axhline(drawn, color=THRESHOLD_COLOUR, linestyle="--", linewidth=1.4, zorder=5)
        handles.append(Line2D([], [], color=THRESHOLD_COLOUR, linestyle="--", lw=1.4,
                              label=f"{threshold_label} = {threshold:g}{' ' * bool(unit)}{unit}"))

    if clipped:
        handles.append(Line2D([], [], color="none", label=f"{clipped} values beyond ±{DRAW_LIMIT:g} drawn at it"))
    if absent.any() and finite.any():
        handles.append(Line2D([], [], color="none", label=f"gaps: {missing_label} at {int(absent.sum())} of "
                                                          f"{absent.size} samples"))
    if finite.any() or threshold is not None:
        # nothing drawn: the threshold in the middle of the axis
        low, high = (float(values[finite].min()), float(values[finite].max())) if finite.any() else \
            (0.0, 2 * (drawn or 0.0))
        if drawn is not None:
            low, high = min(low, drawn), max(high, drawn)
        pad = 0.05 * (high - low) or 1.0
        bottom, top = (min(0.0, low) if low >= 0 else low - pad), high + pad  # distances: keep 0 in view
        ax.set_ylim(bottom, top)
        if below_zero is not None and low < 0:
            ax.axhspan(bottom, 0.0, color=_NEGATIVE_TINT, zorder=0.5, linewidth=0)
            handles.append(Patch(facecolor=_NEGATIVE_TINT, edgecolor="#e0b4b4", label=below_zero))
    if np.isfinite(times).any():
        start, end = float(np.nanmin(times)), float(np.nanmax(times))
        # one instant: centred, not on the left frame where its dots hid behind the spine
        ax.set_xlim((start, end) if end > start else (start - 0.5, start + 0.5))
    ax.set_xlabel(xlabel)
    ax.set_ylabel(ylabel)
    ax.grid(True, color="#e0e0e0", linewidth=0.6, zorder=0)
    count = below_summary(values, threshold, threshold_label) if threshold is not None else counted(n_runs, "run")
    if not finite.any():
        nothing = f"{missing_label} at any sample" if absent.all() else "no value at any sample"
        ax.text(0.5, 0.75, f"{nothing}: nothing to draw", transform=ax.transAxes, ha="center", va="center",
                fontsize=11, color=THRESHOLD_COLOUR)
        count = f"{nothing} of {n_runs} run{'s' * (n_runs != 1)}"
    ax.set_title(f"{title}: {count}" if title else count)
    ax.legend(handles=handles, loc=_emptiest_corner(ax, times, values, len(handles)), framealpha=0.9)
    fit_title(figure, ax.title)
    return save_figure(figure, path)


_Corner = Literal["upper right", "upper left", "lower right", "lower left"]


def _emptiest_corner(ax: Axes, times: np.ndarray, values: np.ndarray, entries: int) -> _Corner:
    """The corner of ``ax`` where a legend of ``entries`` lines covers the fewest samples (upper
    right on a tie). Matplotlib's ``loc="best"`` ignores the runs' LineCollections."""
    (x0, x1), (y0, y1) = ax.get_xlim(), ax.get_ylim()
    with np.errstate(invalid="ignore"):
        fx, fy = (times - x0) / ((x1 - x0) or 1.0), (values - y0) / ((y1 - y0) or 1.0)
    width, height = 0.5, 0.04 + 0.075 * entries  # roughly the legend's size, as a fraction of the axes
    right, left, top, bottom = fx > 1 - width, fx < width, fy > 1 - height, fy < height
    corners: dict[_Corner, np.ndarray] = {"upper right": right & top, "upper left": left & top,
                                          "lower right": right & bottom, "lower left": left & bottom}
    counts = {corner: int(np.count_nonzero(inside)) for corner, inside in corners.items()}
    return min(counts, key=lambda corner: counts[corner])  # dicts keep order: upper right wins a tie


# ---------------------------------------------------------------- pre-analysis sweep
def _setting_label(row: Mapping[str, Any]) -> str:
    return f"e={row['exponent']}  C1={row['sense']:g} s  C2={row['decide']:g} s"


def plot_sweep(rows: Sequence[Mapping[str, Any]], path: str | os.PathLike[str], *,
               xlabel: str = "minimum distance of a run (m)", threshold_label: str = "threshold",
               title: str = "pre-analysis sweep", missing_label: str = "no obstacle", unit: str = "",
               below_zero: str | None = None) -> Path:
    """One line per setting of the pre-analysis sweep: each run's minimum distance as a dot, a box
    of their quartiles, the threshold as a dashed line, and on the right how many runs went below
    it and the probability interval. Settings with a run below the threshold are drawn in red
    (label, box, the dots below), the others in blue, so the unsafe settings stand out.

    Each row is a mapping with the keys ``exponent`` (int), ``sense`` and ``decide`` (the periods
    C1 and C2 in seconds), ``min_distances`` (the minimum distance reached in each run, sequence
    of floats; non-finite values are ignored: a run that met no obstacle has none), ``threshold``
    (float) and optionally ``probability`` (the (low, high) interval of the probability of going
    below). Rows are drawn top to bottom in the given order; a row without any distance says
    ``missing_label``. ``unit`` follows the threshold's value in the legend and ``below_zero``
    explains distances below 0, as in :func:`plot_runs`.

    Example::

        plot_sweep([{"exponent": 2, "sense": 0.1, "decide": 0.2, "min_distances": [2.1, 0.9, 3.4],
                     "threshold": 1.5, "probability": (0.05, 0.61)}], "sweep.png")
    """
    if not rows:
        raise ValueError("plot_sweep: no rows to plot")
    figure = new_figure(8.5, 1.6 + 0.42 * len(rows))
    ax = figure.add_subplot()
    rng = np.random.default_rng(0)  # fixed jitter: the same data gives the same picture
    thresholds = [float(row["threshold"]) for row in rows]
    right = blended_transform_factory(ax.transAxes, ax.transData)
    labels = []
    reds = []
    for i, row in enumerate(rows):
        y = -i  # first row on top
        distances = np.asarray(row["min_distances"], dtype=float)
        distances = distances[np.isfinite(distances)]
        threshold = thresholds[i]
        below = distances < threshold
        colour = BELOW_COLOUR if below.any() else ABOVE_COLOUR
        reds.append(bool(below.any()))
        labels.append(_setting_label(row))
        if distances.size:
            box = ax.boxplot(distances, positions=[y], **_HORIZONTAL, widths=0.55, showfliers=False,
                             patch_artist=True, manage_ticks=False, zorder=2)
            for patch in box["boxes"]:
                patch.set(facecolor=colour, alpha=0.18, edgecolor=colour)
            for part in ("whiskers", "caps", "medians"):
                for line in box[part]:
                    line.set(color=colour, linewidth=1.0)
            jitter = rng.uniform(-0.18, 0.18, distances.size)
            ax.scatter(distances[~below], y + jitter[~below], s=9, color=ABOVE_COLOUR, alpha=0.55, zorder=3,
                       linewidths=0)
            ax.scatter(distances[below], y + jitter[below], s=12, color=BELOW_COLOUR, alpha=0.85, zorder=4,
                       linewidths=0)
        # one short threshold segment per row: settings may differ in their threshold (e.g. TD)
        ax.plot([threshold, threshold], [y - 0.4, y + 0.4], color=THRESHOLD_COLOUR, linestyle="--", linewidth=1.3,
                zorder=5)
        note = f"{int(below.sum())}/{distances.size} below" if distances.size else missing_label
        probability = row.get("probability")
        if probability is not None and distances.size:
            low, high = probability
            note += f"   P ∈ [{low:.3f}, {high:.3f}]"
        ax.text(1.01, y, note, transform=right, va="center", ha="left", fontsize=9, color=colour,
                fontweight="bold" if below.any() else "normal")

    ax.set_yticks([-i for i in range(len(rows))], labels, fontsize=9)
    for tick, red in zip(ax.get_yticklabels(), reds):
        tick.set_color(BELOW_COLOUR if red else "#212121")
    ax.set_ylim(-len(rows) + 0.4, 0.6)
    ax.set_xlabel(xlabel)
    left, right_end = ax.get_xlim()
    negative = below_zero is not None and left < 0
    if negative:
        ax.axvspan(left, 0.0, color=_NEGATIVE_TINT, zorder=0.5, linewidth=0)
        ax.set_xlim(left, right_end)
    ax.grid(True, axis="x", color="#e0e0e0", linewidth=0.6, zorder=0)
    same = len(set(thresholds)) == 1
    handles: list[Any] = [
        Line2D([], [], color=THRESHOLD_COLOUR, linestyle="--", lw=1.3,
               label=f"{threshold_label} = {thresholds[0]:g}{' ' * bool(unit)}{unit}" if same else threshold_label),
        Line2D([], [], color=BELOW_COLOUR, marker="o", linestyle="", markersize=5, label="run below"),
        Line2D([], [], color=ABOVE_COLOUR, marker="o", linestyle="", markersize=5, label="run above"),
    ]
    if negative:
        handles.append(Patch(facecolor=_NEGATIVE_TINT, edgecolor="#e0b4b4", label=below_zero))
    ax.legend(handles=handles, loc="lower center", bbox_to_anchor=(0.5, 1.0), ncols=2 if negative else 3,
              frameon=False, fontsize=9)
    ax.set_title(f"{title}: {sum(reds)} of {len(rows)} settings go below {threshold_label}",
                 pad=40 if negative else 24)
    fit_title(figure, ax.title)
    return save_figure(figure, path)


# ---------------------------------------------------------------- learning curves
def _moving_average(values: np.ndarray, window: int) -> np.ndarray:
    if window <= 1:
        return values
    kernel = np.ones(window) / window
    # "valid" would shorten the curve; a trailing average keeps one value per episode
    padded = np.concatenate([np.repeat(values[:, :1], window - 1, axis=1), values], axis=1)
    return np.apply_along_axis(lambda row: np.convolve(row, kernel, mode="valid"), 1, padded)


def _draw_curve(ax: Axes, index: int, count: int, every: int, label: str, data: np.ndarray, *,
                band: Literal["std", "minmax"], smooth: int) -> str:
    """One learning curve on ``ax``: the mean over seeds and its band; returns its legend text."""
    runs = _moving_average(np.atleast_2d(np.asarray(data, dtype=float)), smooth)
    episodes = np.arange(1, runs.shape[1] + 1)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # an all-NaN episode: NaN is what we want drawn
        mean = np.nanmean(runs, axis=0)
        if band == "std":
            spread = np.nanstd(runs, axis=0)
            low, high = mean - spread, mean + spread
        else:
            low, high = np.nanmin(runs, axis=0), np.nanmax(runs, axis=0)
    colour, style, marker = curve_style(index)
    seeds = runs.shape[0]
    # a curve with no value (no episode learned) is in the legend but draws nothing: the legend says so
    empty = "" if np.isfinite(mean).any() else ": no episode to draw"
    text = f"{label} ({seeds} seed{'s' * (seeds != 1)}){empty}"
    ax.plot(episodes, mean, color=colour, linewidth=1.6, linestyle=style, marker=marker, markersize=5,
            markevery=(index * every // count, every), label=text)
    if seeds > 1:
        ax.fill_between(episodes, low, high, color=colour, alpha=0.2, linewidth=0)
    ax.grid(True, color="#e0e0e0", linewidth=0.6)
    return text


def plot_learning_curves(curves: Mapping[str, np.ndarray], path: str | os.PathLike[str], *, ylabel: str = "return",
                         xlabel: str = "episode", title: str | None = None, band: Literal["std", "minmax"] = "std",
                         smooth: int = 1, panels: bool = False) -> Path:
    """Learning curves: for each label an array (seeds, episodes), drawn as the mean over seeds with
    a shaded band (mean ± standard deviation, or min to max with ``band="minmax"``). Each curve has
    its own colour, line style and marker (:func:`curve_style`), so a curve on top of another does
    not hide it; the title ends in what is drawn, e.g. ``"(mean ± sd over seeds)"``, and says the
    moving average when ``smooth`` > 1.

    With ``panels`` each label gets its own axes, one below the other, sharing the episode axis but
    each with its own value range (the panel's title names the label): curves of very different
    scales (an unshielded learner's returns of -12,000 beside shielded ones near 0) are all readable.

    A 1-D array is one seed. ``smooth`` > 1 first takes a trailing moving average over that many
    episodes of each seed. NaN entries (a seed with fewer episodes) are left out of the statistics.

    Example::

        plot_learning_curves({"shielded": returns_a, "unshielded": returns_b}, "learning.png", smooth=10)
    """
    if not curves:
        raise ValueError("plot_learning_curves: no curves to plot")
    if band not in ("std", "minmax"):
        raise ValueError(f"plot_learning_curves: band must be 'std' or 'minmax', not {band!r}")
    # a marker every 1/12 of the longest curve (a short curve gets fewer), each curve's shifted:
    # where curves coincide, every curve's markers still show
    every = max(1, max(np.atleast_2d(np.asarray(data)).shape[1] for data in curves.values()) // 12)
    spread_name = "mean ± sd over seeds" if band == "std" else "mean, min–max over seeds"
    if smooth > 1:  # else a reader takes the smoothed curve for the episodes' own values
        spread_name = f"{smooth}-episode moving average, {spread_name}"
    heading = f"{title} ({spread_name})" if title else spread_name
    if panels:
        figure = new_figure(7.5, 1.2 + 1.9 * len(curves))
        grid = figure.subplots(len(curves), 1, sharex=True, squeeze=False)[:, 0]
        for i, (label, data) in enumerate(curves.items()):
            panel = grid[i]
            panel.set_title(_draw_curve(panel, i, len(curves), every, label, data, band=band, smooth=smooth),
                            fontsize=10, loc="left")
            panel.set_ylabel(ylabel, fontsize=9)
        grid[-1].set_xlabel(xlabel)
        whole_ticks(grid[-1].xaxis)  # shared: every panel's
        fit_title(figure, figure.suptitle(heading))
        return save_figure(figure, path)
    figure = new_figure(7.5, 4.4)
    ax: Axes = figure.add_subplot()
    for i, (label, data) in enumerate(curves.items()):
        _draw_curve(ax, i, len(curves), every, label, data, band=band, smooth=smooth)
    ax.set_xlabel(xlabel)
    ax.set_ylabel(ylabel)
    whole_ticks(ax.xaxis)
    ax.set_title(heading)
    # beside the axes: loc="best" weighs the mean lines only, so it settled on a seed band (RA's, returns.png)
    ax.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), borderaxespad=0.0, fontsize=9)
    fit_title(figure, ax.title)
    return save_figure(figure, path)


# ---------------------------------------------------------------- learning: time to the first success
def plot_first_success(first: Mapping[str, Sequence[int | None]], budget: int, path: str | os.PathLike[str], *,
                       title: str = "learning until the greedy strategy first reaches the goal safely") -> Path:
    """For each label, the fraction of seeds whose greedy strategy has reached the goal safely
    after ``e`` episodes (a step curve over ``e``; None: the seed never did within ``budget``).

    Example::

        plot_first_success({"SS&RA": [96, 128, None], "RA": [None, 1500, None]}, 2000, "first.png")
    """
    if not first:
        raise ValueError("plot_first_success: nothing to plot")
    figure = new_figure(7.5, 4.2)
    axes = figure.add_subplot()
    for index, (label, episodes) in enumerate(first.items()):
        seeds = len(episodes)
        reached = sorted(e for e in episodes if e is not None)
        xs = [0, *reached, budget]
        ys = [0, *(i / seeds for i in range(1, len(reached) + 1)), len(reached) / seeds]
        colour, style, marker = curve_style(index)  # curves often coincide: style and marker tell them apart
        axes.step(xs, ys, where="post", linewidth=2, color=colour, linestyle=style, marker=marker, markersize=6,
                  markerfacecolor="none" if index % 2 else colour,
                  label=f"{label} ({len(reached)} of {counted(seeds, 'seed')})")
    # a little room past the budget: a seed that first succeeds in the last episode steps up at the budget,
    # which at the axes' edge was drawn on the frame, its marker cut in half
    axes.set_xlim(0, budget + max(0.03 * budget, 1.0))
    axes.axvline(budget, color="#9e9e9e", linestyle=(0, (1, 2)), linewidth=1.0, zorder=0.5)
    axes.set_ylim(-0.02, 1.05)
    whole_ticks(axes.xaxis)
    axes.set_xlabel("episodes learned")
    axes.set_ylabel("fraction of seeds")
    axes.set_title(title)
    axes.grid(alpha=0.3)
    handles, _ = axes.get_legend_handles_labels()
    handles.append(Line2D([], [], color="#9e9e9e", linestyle=(0, (1, 2)), linewidth=1.0,
                          label=f"budget: {budget:,} episodes"))
    # beside the axes: inside, any corner can hide a step (lower right: a seed succeeding near the budget)
    axes.legend(handles=handles, loc="upper left", bbox_to_anchor=(1.01, 1.0), borderaxespad=0.0, fontsize=9)
    fit_title(figure, axes.title)
    return save_figure(figure, path)
