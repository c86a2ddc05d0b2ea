"""What a sweep leaves behind: its rows merged into one table (``results.parquet``, or ``results.csv`` when
pyarrow is not installed) and ``results.json``, a summary table and two plots.

The rows are those of :func:`rac.sweep.task.run_task` (one per task). ``results.json`` holds them as they
are; the table flattens them: one column per row field, ``settings.NAME`` per model setting of the grid,
``verdicts.QUERY`` per query, ``grid_point`` (the settings in words) and ``diagnostics``/``details`` as JSON
text. The plots use :mod:`rac.output.plots` (Agg only, written atomically).

Example::

    paths, notes = write_results(rows, Path("driving.out/sweep"))
    print(render_summary(summarise(rows, tasks=len(rows))))
"""

from __future__ import annotations

import csv
import io
import json
import math
from collections import Counter
from collections.abc import Mapping, Sequence
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

from rac.core.diagnostics import counted
from rac.core.files import atomic_write
from rac.model.commonroad import with_planning_problem
from rac.output.plots import fit_title, new_figure, save_figure, whole_ticks
from rac.sweep.store import write_text
from rac.sweep.task import NOT_FAILED, STATUSES, VERDICTS  # STATUSES, VERDICTS: in the order tables and plots show them

__all__ = ["FAILURE_WORDS", "RESULTS_CSV", "RESULTS_JSON", "RESULTS_PARQUET", "Summary", "failure_kind", "frame",
           "grid_label", "render_summary", "remove_results", "scenario_labels", "summarise", "table", "write_plots",
           "write_results"]

RESULTS_PARQUET, RESULTS_CSV, RESULTS_JSON = "results.parquet", "results.csv", "results.json"
VERDICT_PLOT, TIME_PLOT = "verdicts.png", "time_vs_size.png"
#: The most grid points ``verdicts.png`` draws (the first ones, in the sweep's order): a bar each, 0.8 inch wide, so
#: a grid of 1,000 points made a PNG 88,000 pixels wide in 20 s; the results hold every point.
PLOTTED_POINTS = 40
#: The row's fields, in the table's order (``settings`` and ``verdicts`` become one column per name).
_FIELDS = ("key", "scenario", "scenario_name", "planning_problem", "task", "status", "error", "seconds", "peak_memory",
           "states", "scenario_size")
_COLOURS = {"satisfied": "#55a868", "not satisfied": "#c44e52", "unknown": "#8c8c8c", "unsupported": "#ccb974",
            "ok": "#4c72b0", "failed": "#dd8452", "undecided": "#ccb974", "error": "#8172b3", "timeout": "#937860",
            "memory": "#da8bc3"}
#: Hatching of the verdict bars' segments beside their colours: red, orange and green look alike to a colour-blind
#: reader, and the segments stack on one another.
_HATCHES = {"satisfied": "", "not satisfied": "///", "unknown": "...", "unsupported": "\\\\\\", "ok": "",
            "failed": "xx", "undecided": "\\\\\\", "error": "oo", "timeout": "--", "memory": "++"}
#: Markers of the task statuses in time_vs_size.png beside their colours, for the same reason.
_MARKERS = {"ok": "o", "failed": "X", "undecided": "D", "error": "s", "timeout": "^", "memory": "v"}


def grid_label(settings: Mapping[str, object]) -> str:
    """A grid point in words, ``exponent=1 decide_period=0.5``; ``template settings`` without ``--set``."""
    return " ".join(f"{name}={value}" for name, value in settings.items()) or "template settings"


def _mapping(row: Mapping[str, object], name: str) -> Mapping[str, object]:
    value = row.get(name)
    return value if isinstance(value, Mapping) else {}


def table(rows: Sequence[Mapping[str, object]]) -> tuple[list[str], list[dict[str, object]]]:
    """The rows flattened into one table: its column names and one record per row."""
    settings = list(dict.fromkeys(name for row in rows for name in _mapping(row, "settings")))
    queries = list(dict.fromkeys(name for row in rows for name in _mapping(row, "verdicts")))
    known = {*_FIELDS, "settings", "verdicts", "diagnostics", "details"}
    extra = list(dict.fromkeys(name for row in rows for name in row if name not in known))  # e.g. wall_seconds
    columns = [*_FIELDS[:5], "grid_point", *(f"settings.{name}" for name in settings), *_FIELDS[5:], *extra,
               *(f"verdicts.{name}" for name in queries), "diagnostics", "details"]
    records = []
    for row in rows:
        record: dict[str, object] = {name: row.get(name) for name in _FIELDS}
        record.update({name: _scalar(row.get(name)) for name in extra})
        record["grid_point"] = grid_label(_mapping(row, "settings"))
        record.update({f"settings.{name}": _mapping(row, "settings").get(name) for name in settings})
        record.update({f"verdicts.{name}": _mapping(row, "verdicts").get(name) for name in queries})
        record["diagnostics"] = json.dumps(row.get("diagnostics") or [])
        record["details"] = None if row.get("details") is None else json.dumps(row.get("details"), default=str)
        records.append({name: record[name] for name in columns})
    return columns, records


def _scalar(value: object) -> object:
    """A table cell: numbers, text, truth values and None as they are, anything else as JSON text."""
    return value if value is None or isinstance(value, str | int | float | bool) else json.dumps(value, default=str)


def frame(rows: Sequence[Mapping[str, object]]) -> Any:
    """The table of :func:`table` as a pandas DataFrame; the rows themselves (a list of dicts) when pandas
    is not installed."""
    try:
        import pandas as pd  # pandas: only when this runs; importing rac.sweep.report stays light
    except ImportError:
        return [dict(row) for row in rows]
    return _dataframe(pd, *table(rows))


def _dataframe(pd: Any, columns: list[str], records: list[dict[str, object]]) -> Any:
    """The records as a DataFrame whose columns of whole numbers stay whole with a row that has none (pandas'
    nullable ``Int64``): ``states`` of 94468 read 94468.0 in results.parquet beside a failed task's empty cell."""
    data = pd.DataFrame.from_records(records, columns=columns)
    for name in columns:
        values = [record[name] for record in records if record[name] is not None]
        if values and all(isinstance(v, int) and not isinstance(v, bool) for v in values):
            data[name] = data[name].astype("Int64")
    return data


def _parquet_writer() -> Any:
    """pandas, when it can write Parquet (it needs pyarrow); else None."""
    try:
        import pandas as pd  # pandas: only when this runs; importing rac.sweep.report stays light
        import pyarrow  # noqa: F401  (pandas' Parquet engine)
    except ImportError:
        return None
    return pd


def remove_results(folder: Path) -> None:
    """Remove ``results.*`` and the plots an earlier sweep wrote into ``folder``, before this sweep writes its
    own: a write that fails midway (a full disk, Ctrl-C) then leaves some of this sweep's files and none of the
    earlier one's, never this sweep's ``results.parquet`` beside an earlier ``results.json`` or plot (the rows
    of both are in ``tasks/``, and the same command writes these files again). Raises ``OSError`` when a file
    cannot be removed."""
    for name in (RESULTS_PARQUET, RESULTS_CSV, RESULTS_JSON, VERDICT_PLOT, TIME_PLOT):
        (folder / name).unlink(missing_ok=True)


def write_results(rows: Sequence[Mapping[str, object]], folder: Path) -> tuple[list[Path], list[str]]:
    """Write ``results.parquet`` (or ``results.csv`` when pandas or pyarrow is missing; the other of the
    two, left by an earlier run, is removed) and ``results.json`` into ``folder``; return the files written
    and notes for the user. Raises ``OSError`` when a file cannot be written."""
    folder.mkdir(parents=True, exist_ok=True)
    columns, records = table(rows)
    pd = _parquet_writer()
    notes = []
    if pd is not None:
        data = _dataframe(pd, columns, records)
        written = atomic_write(folder / RESULTS_PARQUET, lambda file: data.to_parquet(file, index=False))
        (folder / RESULTS_CSV).unlink(missing_ok=True)
    else:
        text = io.StringIO()
        writer = csv.DictWriter(text, fieldnames=columns, lineterminator="\n")
        writer.writeheader()
        writer.writerows(records)
        written = write_text(folder / RESULTS_CSV, text.getvalue())
        (folder / RESULTS_PARQUET).unlink(missing_ok=True)
        notes.append(f"wrote {RESULTS_CSV}, not {RESULTS_PARQUET}: Parquet needs pandas and pyarrow "
                     "(pip install 'rac[sweep]')")
    json_path = folder / RESULTS_JSON
    write_text(json_path, json.dumps([dict(row) for row in rows], indent=1, default=str) + "\n")
    return [written, json_path], notes


# ---------------------------------------------------------------- summary
@dataclass
class Summary:
    """The numbers of the summary table: tasks in the sweep, finished (ok or not), skipped (their rows were
    stored by an earlier run), not run (Ctrl-C); the count of each status; per query the count of each
    verdict; the seconds per task (50th and 90th percentile, maximum; over the rows that have them); and the
    tasks that did not end ok as ``(status, scenario name, grid point, error)``."""

    tasks: int
    finished: int
    skipped: int
    not_run: int
    statuses: dict[str, int]
    queries: dict[str, dict[str, int]]
    seconds: dict[str, float] = field(default_factory=dict)
    problems: list[tuple[str, str, str, str]] = field(default_factory=list)
    #: of the skipped tasks, those whose stored row is not ok: reused as they are, unless --retry-failed
    skipped_not_ok: int = 0
    #: the tasks not ok nor undecided by why (:func:`failure_kind`), in the order of :data:`FAILURE_WORDS`
    failures: dict[str, int] = field(default_factory=dict)

    @property
    def ok(self) -> int:
        """Tasks that ended ok."""
        return self.statuses.get("ok", 0)

    @property
    def undecided(self) -> int:
        """Tasks that finished without a failure but with a query not decided (unknown, unsupported)."""
        return self.statuses.get("undecided", 0)

    @property
    def failed(self) -> int:
        """Tasks that finished neither ok nor undecided (failed, error, timeout, memory)."""
        return sum(n for status, n in self.statuses.items() if status not in NOT_FAILED)

    def to_json(self) -> dict[str, object]:
        """The summary as JSON-serialisable data."""
        return {**asdict(self), "ok": self.ok, "failed": self.failed, "undecided": self.undecided,
                "problems": [dict(zip(("status", "scenario", "grid_point", "error"), p)) for p in self.problems]}


def scenario_labels(rows: Sequence[Mapping[str, object]]) -> dict[str, str]:
    """The name the summary gives each row's scenario, by its path: the file's stem (``scenario_name``), or,
    where files of the same name in other folders are swept together (``a/s.xml``, ``b/s.xml``), as many of
    the folders above it as tell them apart (``a/s``, ``b/s``): the stem alone named two files alike."""
    paths = list(dict.fromkeys(str(row.get("scenario")) for row in rows))
    by_stem: dict[str, list[str]] = {}
    for path in paths:
        by_stem.setdefault(Path(path).stem, []).append(path)
    labels = {}
    for stem, alike in by_stem.items():
        parts = {path: Path(path).with_suffix("").parts for path in alike}
        depth = 1
        while len({part[-depth:] for part in parts.values()}) < len(alike) and depth < max(map(len, parts.values())):
            depth += 1
        labels.update({path: "/".join(part[-depth:]) if len(alike) > 1 else stem for path, part in parts.items()})
    return labels


def _problem(row: Mapping[str, object]) -> int | None:
    """The planning problem the sweep chose for a row's task (None: the template's choice)."""
    problem = row.get("planning_problem")
    return problem if isinstance(problem, int) else None


#: How the summary's "failed:" line says each kind of failure (:func:`failure_kind`), in its order: the
#: status "failed" alone would say "2 failed" and not whether a query failed or the file did not check.
FAILURE_WORDS: dict[str, str] = {
    "not satisfied": "with a query not satisfied",
    "file": "with errors in the file",
    "run": "that failed when run (e.g. an experiment with no safe strategy)",
    "error": "that rac could not run",
    "timeout": "timed out",
    "memory": "out of memory",
}


def failure_kind(row: Mapping[str, object]) -> str | None:
    """Why a row failed, a key of :data:`FAILURE_WORDS` (None: ok or undecided): a row of status "failed" is
    "not satisfied" when one of its queries is, "file" when its check found errors (a diagnostic ``E...``), else
    "run" (the command failed on a file that checks: an experiment with no safe strategy from the start);
    other statuses are themselves."""
    status = str(row.get("status"))
    if status in NOT_FAILED:
        return None
    if status == "failed":
        if "not satisfied" in _mapping(row, "verdicts").values():
            return "not satisfied"
        diagnostics = row.get("diagnostics")
        errors = isinstance(diagnostics, (list, tuple)) and any(str(d).startswith("E") for d in diagnostics)
        return "file" if errors else "run"
    return status


def summarise(rows: Sequence[Mapping[str, object]], *, tasks: int, skipped: int = 0,
              skipped_not_ok: int = 0) -> Summary:
    """The :class:`Summary` of ``rows`` out of ``tasks`` tasks, ``skipped`` of them reused from the store
    (``skipped_not_ok`` of those not ok)."""
    statuses = Counter(str(row.get("status")) for row in rows)
    kinds = Counter(kind for row in rows if (kind := failure_kind(row)) is not None)
    failures = {kind: kinds[kind] for kind in sorted(kinds, key=lambda k: (list(FAILURE_WORDS) + [k]).index(k))}
    queries: dict[str, Counter[str]] = {}
    for row in rows:
        for name, verdict in _mapping(row, "verdicts").items():
            queries.setdefault(name, Counter())[str(verdict)] += 1
    seconds = sorted(float(s) for row in rows if isinstance(s := row.get("seconds"), int | float) and math.isfinite(s))
    percentiles = {}
    if seconds:
        import numpy as np  # numpy: only when this runs; importing rac.sweep.report stays light

        percentiles = {"p50": float(np.percentile(seconds, 50)), "p90": float(np.percentile(seconds, 90)),
                       "max": seconds[-1]}
    shown = scenario_labels(rows)
    problems = [(str(row.get("status")), with_planning_problem(shown[str(row.get("scenario"))], _problem(row)),
                 grid_label(_mapping(row, "settings")),
                 str(row.get("error") or "")) for row in rows if row.get("status") != "ok"]
    order = {status: i for i, status in enumerate(STATUSES)}
    return Summary(tasks=tasks, finished=len(rows), skipped=skipped, not_run=tasks - len(rows),
                   skipped_not_ok=skipped_not_ok,
                   statuses={s: n for s, n in sorted(statuses.items(), key=lambda item: order.get(item[0], 99))},
                   queries={name: {v: counts.get(v, 0) for v in VERDICTS} for name, counts in queries.items()},
                   seconds=percentiles, problems=problems, failures=failures)


def _aligned(header: Sequence[str], lines: Sequence[Sequence[object]], *, names: bool = True) -> list[str]:
    """A plain text table, numbers right-aligned; the first column left-aligned when it holds ``names``."""
    cells = [list(map(str, header)), *([str(cell) for cell in line] for line in lines)]
    widths = [max(len(line[i]) for line in cells) for i in range(len(header))]
    return ["  ".join(cell.ljust(w) if i == 0 and names else cell.rjust(w)
                      for i, (cell, w) in enumerate(zip(line, widths))).rstrip() for line in cells]


def render_summary(summary: Summary, *, problems_shown: int = 10) -> str:
    """The summary as text: the task counts, each status, the verdicts per query, the seconds per task,
    and the first ``problems_shown`` tasks that did not end ok (with why)."""
    out = _aligned(["tasks", "ok", "failed", "undecided", "skipped", "not run"],
                   [[summary.tasks, summary.ok, summary.failed, summary.undecided, summary.skipped,
                     summary.not_run]], names=False)
    if summary.skipped:
        # a stored error (a worker's environment since fixed) is shown again as it was: said, with the way out
        stale = (f"; {summary.skipped_not_ok} of them not ok, shown as stored (--retry-failed runs those again)"
                 if summary.skipped_not_ok else "")
        out.append(f"skipped: {summary.skipped} stored by an earlier run (--force runs them again){stale}")
    if summary.failed:
        out.append("failed: " + ", ".join(f"{n} {FAILURE_WORDS.get(kind, kind)}"
                                          for kind, n in summary.failures.items()))
    if summary.queries:
        out.append("")
        out.extend(_aligned(["query", *VERDICTS],
                            [[name, *(counts[v] for v in VERDICTS)] for name, counts in summary.queries.items()]))
    if summary.seconds:
        s = summary.seconds
        out.append("")
        out.append(f"time per task: p50 {s['p50']:.2f} s, p90 {s['p90']:.2f} s, max {s['max']:.2f} s")
    if summary.problems:
        out.append("")
        for status, scenario, point, error in summary.problems[:problems_shown]:
            first = error.splitlines()[0] if error else ""
            out.append(f"{status}: {scenario} [{point}]{': ' + first if first else ''}")
        if len(summary.problems) > problems_shown:
            out.append(f"... and {len(summary.problems) - problems_shown} more (results.json has every row)")
    return "\n".join(out)


# ---------------------------------------------------------------- plots
def _outcomes(row: Mapping[str, object], queries: int) -> list[str]:
    """What a row adds to the verdict mix: one verdict per query, or its status when it has no verdicts, once per
    query the other rows answer (``queries``; 1 when none has verdicts), so that a bar stays queries × scenarios."""
    verdicts = _mapping(row, "verdicts")
    return [str(v) for v in verdicts.values()] if verdicts else [f"task {row.get('status')}"] * queries


def write_plots(rows: Sequence[Mapping[str, object]], folder: Path) -> list[Path]:
    """``verdicts.png`` (the verdict mix per grid point, stacked bars; a task without verdicts counts as
    its status, once per query the other tasks answer) and ``time_vs_size.png`` (seconds per task against the
    scenario's size, lanelets plus obstacles, one colour and marker per status) in ``folder``; without rows none,
    and those an earlier sweep wrote there are removed (they would show its rows beside this sweep's empty results).
    Returns the files written."""
    if not rows:
        for name in (VERDICT_PLOT, TIME_PLOT):
            (folder / name).unlink(missing_ok=True)
        return []
    folder.mkdir(parents=True, exist_ok=True)
    return [_plot_verdicts(rows, folder / VERDICT_PLOT), _plot_times(rows, folder / TIME_PLOT)]


def _plot_verdicts(rows: Sequence[Mapping[str, object]], path: Path) -> Path:
    from matplotlib.ticker import MaxNLocator  # matplotlib: only when a plot is written

    every = list(dict.fromkeys(grid_label(_mapping(row, "settings")) for row in rows))
    points = every[:PLOTTED_POINTS]
    counts = {point: Counter[str]() for point in points}
    # a task without verdicts (a file that does not check, a timeout) stands for the queries it did not answer: it
    # counted once in bars of "queries × scenarios" (a failed preanalyse task 1 beside the others' Qb-Qd 3 each)
    queries = max((len(_mapping(row, "verdicts")) for row in rows), default=0) or 1
    for row in rows:
        label = grid_label(_mapping(row, "settings"))
        if label in counts:
            counts[label].update(_outcomes(row, queries))
    known = [*VERDICTS, *(f"task {status}" for status in STATUSES)]
    seen = {outcome for c in counts.values() for outcome in c}
    categories = [c for c in known if c in seen] + sorted(seen - set(known))
    figure = new_figure(max(5.0, 1.2 + 0.8 * len(points)), 4.4)
    ax = figure.add_subplot()
    bottom = [0] * len(points)
    for category in categories:
        heights = [counts[point][category] for point in points]
        kind = category.removeprefix("task ")
        ax.bar(range(len(points)), heights, bottom=bottom, label=category, width=0.7,
               color=_COLOURS.get(kind, "#64b5cd"), hatch=_HATCHES.get(kind, "||"), edgecolor="white", linewidth=0.5)
        bottom = [b + h for b, h in zip(bottom, heights)]
    ax.set_xticks(range(len(points)), points, rotation=30 if len(points) > 3 else 0, ha="right"
                  if len(points) > 3 else "center", fontsize=8)
    ax.yaxis.set_major_locator(MaxNLocator(integer=True))  # counts
    ax.set_ylabel("queries × scenarios" if any(_mapping(row, "verdicts") for row in rows) else "tasks")
    handles, labels = ax.get_legend_handles_labels()
    # top to bottom as the segments stack: the legend listed the bottom segment (satisfied) first, beside the top
    ax.legend(handles[::-1], labels[::-1], loc="upper left", bbox_to_anchor=(1.0, 1.0), frameon=False, fontsize=8)
    ax.grid(True, axis="y", color="#e0e0e0", linewidth=0.6)
    ax.set_axisbelow(True)
    shown = f"; the first {len(points)} of {len(every)} grid points, results.* hold all" \
        if len(every) > len(points) else ""
    ax.set_title(f"verdicts per grid point ({len(rows)} tasks{shown})")
    fit_title(figure, ax.title)
    return save_figure(figure, path)


def _number(value: object) -> float:
    return float(value) if isinstance(value, int | float) else math.nan


def _plot_times(rows: Sequence[Mapping[str, object]], path: Path) -> Path:
    figure = new_figure(7.3, 4.4)
    ax = figure.add_subplot()
    sized = [row for row in rows if isinstance(row.get("scenario_size"), int) and
             isinstance(row.get("seconds"), int | float)]
    for status in [*STATUSES, *sorted({str(r.get("status")) for r in sized} - set(STATUSES))]:
        mine = [row for row in sized if row.get("status") == status]
        if mine:
            ax.scatter([_number(row["scenario_size"]) for row in mine], [_number(row["seconds"]) for row in mine],
                       s=26, alpha=0.8, marker=_MARKERS.get(status, "P"),
                       color=_COLOURS.get(status, "#64b5cd"), label=f"{status} ({len(mine)})", linewidths=0)
    if sized:  # beside the axes, as in verdicts.png: inside, "best" still covered points of a crowded plot
        ax.legend(loc="upper left", bbox_to_anchor=(1.0, 1.0), frameon=False, fontsize=8)
    else:  # every file failed to load (or no task timed): a blank axes read as a plot that failed to draw
        ax.text(0.5, 0.5, "no task has a scenario size and a time: nothing to draw", transform=ax.transAxes,
                ha="center", va="center", fontsize=11, color="#212121")
    whole_ticks(ax.xaxis)  # sizes are counts: scenarios all of one size got ticks at 2.96, 2.98, ...
    ax.set_xlabel("scenario size (lanelets + obstacles)")
    ax.set_ylabel("seconds per task")
    ax.grid(True, color="#e0e0e0", linewidth=0.6)
    missing = len(rows) - len(sized)
    ax.set_title("task time against scenario size" + (f" ({counted(missing, 'task')} without a size not shown)"
                                                      if missing else ""))
    fit_title(figure, ax.title)
    return save_figure(figure, path)
