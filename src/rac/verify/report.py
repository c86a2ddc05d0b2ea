"""What ``rac verify`` answers, and how it is shown: :class:`QueryResult`, the verifyta-like text
(:func:`render_text`), JSON (:func:`render_json`), and the CSV files and plots of ``simulate``
(:func:`write_csv`, :func:`plot_series`; ``rac simulate`` writes the same)."""

from __future__ import annotations

import csv
import dataclasses
import io
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import IO

import numpy as np

from rac.core.diagnostics import counted
from rac.core.files import atomic_write
from rac.core.source import Span
from rac.engine.graph import LABELS
from rac.ir import expr as ie
from rac.ir.vocabulary import EGO_STATE
from rac.model.native import NEGATIVE_DISTANCE_TEXT
from rac.verify.status import METHODS, NOT_APPLICABLE, NOT_SATISFIED, SATISFIED, UNKNOWN, UNSUPPORTED, VALUE

__all__ = ["TRACE_FLAGS", "QueryResult", "TraceRow", "format_number", "plot_series", "render_json",
           "render_text", "write_csv", "write_runs"]


#: One state of a witness trace: ``time`` (s) and the sensed ego state (:data:`EGO_STATE`, reals); where
#: known the automaton's ``location``, a product state's ``phase`` and rewards, and the :data:`TRACE_FLAGS`.
TraceRow = dict[str, float | int | str]
#: The state labels a trace row carries (as bools): :data:`rac.engine.graph.LABELS` but ``safe``
#: (``!collide && !offroad``: a row flagged with neither is safe).
TRACE_FLAGS: tuple[str, ...] = tuple(label for label in LABELS if label != "safe")


@dataclass(frozen=True)
class QueryResult:
    """One query's answer, in the shape ``rac verify`` prints and ``--format json`` writes.

    ``status`` is one of :data:`rac.verify.status.STATUSES`: ``"satisfied"``, ``"not satisfied"``, ``"value"`` (a
    probability, an expectation or simulated runs), ``"unknown"`` (budget or horizon exceeded),
    ``"unsupported"`` or ``"not_applicable"`` (the strategy it depends on provably does not exist);
    ``message`` says why for the last three. ``method`` (a key of :data:`rac.verify.status.METHODS`, or None) says how
    the verdict was reached."""

    name: str
    formula: str
    kind: str
    status: str
    title: str | None = None
    interval: tuple[float, float] | None = None
    estimate: float | None = None
    runs: int | None = None
    states: int | None = None
    seconds: float = 0.0
    horizon_samples: int | None = None
    trace: tuple[TraceRow, ...] | None = None
    files: tuple[str, ...] = ()
    message: str | None = None
    seed: int | None = None
    confidence: float | None = None
    #: ``Pr`` without ``under``: the exact probability under uniform choices, computed by Storm
    #: on the explored model (what the interval estimates); None when the model is too large.
    exact: float | None = None
    #: How the verdict was reached: a key of :data:`rac.verify.status.METHODS` (None: not said).
    method: str | None = None
    #: A learning query: the exact optimum beside the learned strategy (:mod:`rac.learning.optimum`):
    #: ``value``, ``learned``, ``shortfall``, ``states``... or ``out_of_reach`` and why (None: not computed).
    optimum: dict[str, object] | None = None
    span: Span | None = field(default=None, compare=False)

    def to_json(self) -> dict[str, object]:
        out = {f.name: getattr(self, f.name) for f in dataclasses.fields(self) if f.name != "span"}
        out["interval"] = [_finite(v) for v in self.interval] if self.interval else None
        out["estimate"] = _finite(self.estimate)
        out["trace"] = list(self.trace) if self.trace else None
        out["files"] = list(self.files)
        if self.span is not None:
            out["location"] = {"file": self.span.file, "line": self.span.line, "column": self.span.column}
        return out


def write_csv(path: Path, times: np.ndarray, names: list[str], values: list[np.ndarray]) -> Path:
    """``run,time,expr...`` rows of simulated runs (``values``: one ``(N, T+1)`` array per name),
    written to a temporary file of its own and renamed (:func:`rac.core.files.atomic_write`: never half a
    file, and a second writer of ``path`` has its own temporary file); returns ``path``."""
    return write_runs(path, times, names, values)[0]


def write_runs(path: Path, times: np.ndarray, names: list[str], values: list[np.ndarray],
               plot: Callable[[], Path] | None = None, stale: Path | None = None,
               ends: np.ndarray | None = None) -> list[Path]:
    """:func:`write_csv`, and with ``plot`` (which writes the runs' plot, atomically, and returns its path) the
    CSV and its plot as a pair: the plot is drawn while the CSV's temporary file is open and the two are
    renamed one after the other at the end, so that Ctrl-C or an error while either is made (drawing takes
    a second) leaves the previous pair as it was, never a new CSV beside the plot of another run. Without
    ``plot``, ``stale`` (the plot an earlier run wrote beside the CSV: ``--no-plots``) is removed before the
    new CSV takes the old one's place, for the same reason. ``ends`` (per run, None: none) is the sample a run
    stopped at (:attr:`rac.engine.simulate.Runs.overflow`): its rows end before it. Returns the paths written,
    the CSV first."""
    plotted: list[Path] = []

    def write(binary: IO[bytes]) -> None:
        handle = io.TextIOWrapper(binary, encoding="utf-8", newline="")
        writer = csv.writer(handle)
        writer.writerow(["run", "time", *names])
        for run in range(values[0].shape[0] if values else 0):
            for k, t in enumerate(times[:None if ends is None else int(ends[run])]):
                writer.writerow([run, f"{t:.6g}", *(f"{v[run, k]:.9g}" for v in values)])
        handle.flush()
        handle.detach()  # atomic_write closes the file itself
        if plot is not None:
            plotted.append(plot())
        elif stale is not None:
            stale.unlink(missing_ok=True)

    return [atomic_write(path, write), *plotted]


def plot_series(path: Path, times: np.ndarray, names: list[str], values: list[np.ndarray], title: str,
                exprs: Sequence[ie.Expr] = ()) -> Path:
    """The plot of simulated runs (``values`` as for :func:`write_csv`): the paper's Fig. 7 for
    ``simulate{distance, threshold}`` (a constant second series is the threshold line); one line
    per run of the first series otherwise.

    ``exprs``, the checked expressions of ``names``, give the y axis its unit (``mindist() (m)``,
    :func:`rac.ir.expr.unit_of`) and, when the first is ``mindist()``, a note on what a
    distance below 0 means; without them the axis says the expression alone."""
    # matplotlib (via rac.output.plots): importing rac.verify.report stays light
    from rac.output.plots import plot_runs, quantity_label

    # NaN: a stopped run's samples after its stop (rac simulate)
    threshold = float(np.nanmax(values[1])) if len(values) == 2 and np.nanmax(values[1]) == np.nanmin(values[1]) \
        else None
    units = [ie.unit_of(expr) for expr in exprs] if len(exprs) == len(names) else [None] * len(names)
    # the threshold's own unit; a bare number (`1.5`) is in the unit of what it is compared with
    threshold_unit = (units[1] or units[0] or "") if threshold is not None else ""
    # only mindist() itself: below 0 it is an overlap (mindist() - 1 below 0 is not)
    distance = bool(exprs) and isinstance(exprs[0], ie.Call) and exprs[0].name == "mindist"
    return Path(plot_runs(times, values[0], path, threshold=threshold,
                          threshold_label=names[1] if threshold is not None else "threshold",
                          ylabel=quantity_label(names[0], units[0]), unit=threshold_unit, title=title,
                          below_zero=NEGATIVE_DISTANCE_TEXT if distance else None))


# ---------------------------------------------------------------- rendering
def format_number(value: float) -> str:
    """A value in a verdict's line: four significant digits (``inf`` and ``nan`` as Python writes them)."""
    return f"{value:.4g}" if math.isfinite(value) else str(value)


def render_text(results: list[QueryResult], *, traces: bool = False) -> str:
    """The results in the layout of UPPAAL's verifyta: ``Verifying`` then `` -- Formula is ...``."""
    lines: list[str] = []
    for r in results:
        where = f"  ({r.span.file}:{r.span.line})" if r.span is not None and not r.span.file.startswith("<") else ""
        lines.append(f"Verifying {r.name}: {r.formula}{where}")
        if r.title:
            lines.append(f"    ({r.title})")
        if r.status in ("satisfied", "not satisfied"):
            lines.append(f" -- Formula is {'satisfied' if r.status == 'satisfied' else 'NOT satisfied'}.")
        elif r.status == "unknown":
            lines.append(f" -- Formula is UNKNOWN: {r.message}")
        elif r.status == "unsupported":
            lines.append(f" -- Not answered: {r.message}")
        elif r.status == NOT_APPLICABLE:
            lines.append(f" -- Not applicable: {r.message}")
        if r.kind == "probability" and r.interval is not None:
            lines.append(f" -- Pr in [{r.interval[0]:.4f}, {r.interval[1]:.4f}] ({r.runs} runs, "
                         f"{_confidence(r)} CI)")
            if r.exact is not None:
                lines.append(f" -- exact (Storm, actions drawn uniformly): {r.exact:.4f}")
        elif r.kind == "probability" and r.runs is not None:
            lines.append(f" -- {r.runs} runs, {int(round((r.estimate or 0) * r.runs))} satisfied the formula")
        if r.kind == "probability" and r.message and r.status in (SATISFIED, NOT_SATISFIED, VALUE):
            lines.append(f"    {r.message}")  # what limits the answer (an undecided status has said it)
        elif r.kind == "expectation" and r.estimate is not None and r.interval is not None:
            half = (r.interval[1] - r.interval[0]) / 2
            lines.append(f" -- ({r.runs} runs) E = {format_number(r.estimate)} ± {format_number(half)} "
                         f"({_confidence(r)} CI)")
            if r.message:  # what is known beyond the interval (under a learned strategy: the value exactly)
                lines.append(f"    {r.message}")
        elif r.kind == "simulate" and r.message and r.status not in ("unknown", "unsupported", NOT_APPLICABLE):
            lines.append(f" -- {r.message}")  # what the runs wrote (an undecided status has said its message)
        elif r.kind == "learning" and r.status == "value" and r.message:
            first, *more = r.message.split("\n")
            lines.append(f" -- {first}")
            lines.extend(f"    {line}" for line in more)
        details = []
        if r.states is not None:
            details.append(counted(r.states, "state"))
        if r.horizon_samples is not None:
            details.append(f"horizon {r.horizon_samples} samples")
        details.append(f"{r.seconds:.2f} s")
        if r.seed is not None:
            details.append(f"seed {r.seed}")
        lines.append("    " + ", ".join(details))
        if r.method is not None and r.status in (SATISFIED, NOT_SATISFIED):
            lines.append(f"    {METHODS[r.method]}")
        if r.kind in ("strategy", "symbolic") and r.message and r.status not in (UNKNOWN, UNSUPPORTED, NOT_APPLICABLE):
            # (an undecided or inapplicable status has said its message on its own line)
            lines.append(f"    {r.message}")
        for file in r.files:
            lines.append(f"    wrote {file}")
        if r.trace:
            shown = r.trace if traces else (r.trace[:3] + r.trace[-3:] if len(r.trace) > 6 else r.trace)
            note = "" if traces or len(r.trace) <= 6 else ", first and last 3; --trace shows all"
            lines.append(f"    trace ({counted(len(r.trace), 'state')}{note}):")
            for row in shown:
                lines.append("      " + _trace_row(row))
    return "\n".join(lines)


def _confidence(result: QueryResult) -> str:
    return f"{(result.confidence or 0.95) * 100:g}%"


def _held(value: float | int | str) -> str:
    """A trace's number as the model holds it: a significand over the scale has at most 10 digits and
    ``exponent`` decimals, so 15 significant digits show it exactly (``sa=-214748.3648``, where ``:g``
    rounded it to ``-214748``, hiding which value is at the int32 limit)."""
    return f"{value:.15g}" if isinstance(value, (int, float)) else str(value)


def _trace_row(row: TraceRow) -> str:
    parts = [f"t={_held(row['time'])}s"]
    for name in EGO_STATE:
        parts.append(f"{name}={_held(row[name])}")
    if "location" in row:
        parts.append(str(row["location"]))
    if row.get("phase", "sampled") != "sampled":  # product states before the edge, after `at end`
        parts.append(f"({row['phase']})")
    # What is left are the product's rewards.
    known = {"time", *EGO_STATE, "location", "phase", *TRACE_FLAGS}
    parts.extend(f"{name}={_held(value)}" for name, value in row.items() if name not in known)
    flags = [name for name in TRACE_FLAGS if row.get(name)]
    if flags:
        parts.append("[" + ",".join(flags) + "]")
    return " ".join(parts)


def _finite(value: float | None) -> float | None:
    """``value``, or None when it is not finite (JSON has no infinities)."""
    return value if value is None or math.isfinite(value) else None


def render_json(results: list[QueryResult]) -> list[dict[str, object]]:
    """The results as JSON-ready dicts (``rac verify --format json``)."""
    return [r.to_json() for r in results]
