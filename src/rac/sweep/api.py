"""``rac sweep``'s Python API (:func:`sweep`, :func:`plan`, :func:`execute`), re-exported by
:mod:`rac.sweep` on first use.

May import: rac, rac.compiler, core, lang, ir, check, model, runtime, engine, output, learning, verify, studies.
"""


from __future__ import annotations

import contextlib
import math
import warnings
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import rac
from rac.engine.budget import parse_size
from rac.lang.parser import parse_expression
from rac.model.commonroad import planning_problem_ids
from rac.output.paths import output_folder
from rac.sweep.grid import grid_points, parse_set, scenario_files
from rac.sweep.kinds import TASKS
from rac.sweep.task import OPTIONS, TASK_OPTIONS, TaskSpec, digest_of, scenario_bytes, scenario_digest
from rac.sweep.template import check_template, template_inputs, template_settings

if TYPE_CHECKING:
    from rac.sweep.report import Summary
    from rac.sweep.run import Outcome, Row
    from rac.sweep.task import TaskSpec

__all__ = ["Plan", "SweepResult", "default_folder", "execute", "plan", "sweep"]

@dataclass(frozen=True)
class Plan:
    """The tasks of one sweep, before any runs: the template, the output folder and one spec per
    (scenario, grid point), scenarios outermost; a scenario with several planning problems is one scenario per
    problem (``problems`` counts them all) unless the template or the grid chooses one."""

    template: Path
    out: Path
    specs: tuple[TaskSpec, ...]
    scenarios: int
    points: int
    problems: int = 0  #: the (scenario, planning problem) pairs: ``scenarios`` when no file has several


@dataclass
class SweepResult:
    """A finished (or interrupted) sweep: its plan, what ran, the rows in the plan's order, the summary,
    the files written, notes for the user, and whether ``results.*`` and the plots were all written (not when
    Ctrl-C came while they were: the rows are stored in ``tasks/`` all the same)."""

    plan: Plan
    outcome: Outcome
    rows: list[Row]
    summary: Summary
    files: list[Path] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)
    written: bool = True


def _set_texts(sets: Mapping[str, object] | Sequence[str] | None) -> list[str]:
    """``--set`` texts from ``{"exponent": [1, 2]}`` (any iterable of values: a range, a numpy array; or one
    value) or ``["exponent=1,2"]``."""
    if sets is None:
        return []
    if isinstance(sets, Mapping):
        texts = []
        for name, values in sets.items():
            # a range or an array is a list of values too: its text, "range(1, 3)", was refused as one value
            listed = [values] if isinstance(values, str | bytes) or not isinstance(values, Iterable) else values
            texts.append(f"{name}={','.join(map(str, listed))}")
        return texts
    if isinstance(sets, str):
        return [sets]
    return list(sets)


def plan(template: str | Path, scenarios: Sequence[str | Path] | str | Path, *,
         sets: Mapping[str, object] | Sequence[str] | None = None, task: str = "verify", out: str | Path | None = None,
         task_timeout: float | None = None, task_memory: int | str | None = None,
         options: Mapping[str, object] | None = None) -> Plan:
    """The tasks of a sweep (nothing runs). ``ValueError`` with a message for the user on a bad
    argument (no scenario matched, a bad ``sets``, an unknown task or option, an option the task does not use
    (:data:`rac.sweep.task.TASK_OPTIONS`), an ``explore`` that is not one of
    :data:`rac.studies.experiment.EXPLORE`, a ``reward_function`` that
    is not one expression, or none for an ``experiment`` of an automaton without the paper's inputs, a
    template that does not parse or has no ``model`` block); ``OSError`` when the template cannot be read."""

    if task not in TASKS:
        raise ValueError(f"unknown task `{task}`: choose one of {', '.join(TASKS)}")
    unknown = sorted(set(options or {}) - set(OPTIONS))
    if unknown:
        raise ValueError(f"unknown option {', '.join(unknown)}: the options are {', '.join(OPTIONS)}")
    unused = [name for name, value in (options or {}).items() if value is not None and name not in TASK_OPTIONS[task]]
    if unused:  # the task would run without it, as if it had not been given
        takes = ", ".join(TASK_OPTIONS[task]) or "none"
        raise ValueError(f"--task {task} does not use the option{'s' * (len(unused) > 1)} "
                         f"{', '.join(f'`{name}`' for name in unused)} (its options: {takes})")
    if task_timeout is not None and not 0 < task_timeout < math.inf:  # inf: no JSON number holds it
        raise ValueError(f"the task timeout must be a finite number of seconds more than 0, not {task_timeout}")
    memory = _bytes(task_memory)
    function = (options or {}).get("reward_function")
    if function is not None:  # its syntax is the same for every task: a typo fails here, not in each
        try:
            parse_expression(str(function), name="<--reward-function>")
        except ValueError as exc:
            raise ValueError(f"--reward-function: {exc}") from None  # the message starts with the text
    items = [scenarios] if isinstance(scenarios, str | Path) else list(scenarios)
    files = scenario_files([str(item) for item in items])
    points = grid_points(parse_set(_set_texts(sets)))
    path = Path(template).absolute()
    text = check_template(path)
    if task == "experiment" and function is None:  # the same for every task: said here, not in a failed row each
        # numpy (via rac.studies.experiment): only an experiment sweep loads it
        from rac.studies.experiment import default_reward_problem

        problem = default_reward_problem(template_inputs(text, path))
        if problem is not None:
            raise ValueError(f"--task experiment: {problem}")
    explore = (options or {}).get("explore")
    if explore is not None:  # the same for every task: said here, not in an error row each
        # numpy (via rac.studies.experiment): only an experiment sweep loads it
        from rac.studies.experiment import EXPLORE

        if explore not in EXPLORE:
            raise ValueError(f"--explore: one of {', '.join(EXPLORE)}, not {explore!r}")
    given = tuple(sorted((name, str(value)) for name, value in (options or {}).items() if value is not None))
    # a file with several planning problems is that many scenes (real datasets number them per file): a task
    # each, unless the template or the grid chooses one for every file
    chosen = "planning_problem" in template_settings(text, path) or any(
        name == "planning_problem" for point in points for name, _ in point)
    scanned = {scenario: _scan(scenario, chosen) for scenario in files}  # each file read once, not per point
    digests = {scenario: digest for scenario, (digest, _) in scanned.items()}
    problems = {scenario: ids for scenario, (_, ids) in scanned.items()}
    specs = tuple(TaskSpec(template=str(path), template_text=text, scenario=str(scenario), settings=point,
                           task=task, options=given, timeout=task_timeout, memory=memory,
                           scenario_digest=digests[scenario], planning_problem=problem)
                  for scenario in files for problem in problems[scenario] for point in points)
    folder = Path(out) if out is not None else default_folder(Path(template))
    return Plan(template=path, out=folder, specs=specs, scenarios=len(files), points=len(points),
                problems=sum(map(len, problems.values())))


def _scan(scenario: Path, chosen: bool) -> tuple[str, tuple[int | None, ...]]:
    """From one read of ``scenario``: its key's digest, and the planning problems a task each: every one when
    it has several and none is ``chosen`` for every file; else ``(None,)``, one task taking the template's
    choice or the file's only one (or saying why the file cannot be read)."""
    try:
        data = scenario_bytes(scenario)
    except OSError:
        return scenario_digest(scenario), (None,)
    ids = () if chosen else planning_problem_ids(data)
    return digest_of(data), ids if len(ids) > 1 else (None,)


def default_folder(template: Path) -> Path:
    """``TEMPLATE.out/sweep/`` beside the template: the output convention of every rac command
    (:data:`rac.cli.common.OUTPUT_CONVENTION`, which sits above this package and cannot be imported here)."""
    return output_folder(template, "sweep")


def _bytes(size: int | str | None) -> int | None:
    if size is None:
        return None
    if isinstance(size, str):
        size = parse_size(size)
    if size <= 0:
        raise ValueError(f"the task memory limit must be more than 0 bytes, not {size}")
    return size


def execute(plan: Plan, *, scheduler: str | None = None, workers: int | None = None, force: bool = False,
            retry_failed: bool = False, quiet: bool = False, announce: Any = None) -> SweepResult:
    """Run ``plan`` on Dask (:func:`rac.sweep.run.connect`), store each row as it arrives, then merge the
    rows into ``results.parquet`` (or CSV) and ``results.json`` and draw the plots in ``plan.out``.
    Stored rows are reused, except those of another version (or other source files) of rac and those whose
    task's process was killed (run again, and ``announce`` says how many), every row not ok with
    ``retry_failed``, and all of them with ``force``.
    ``announce(line)`` receives the dashboard's address; ``quiet`` turns the progress off. Ctrl-C stops the
    sweep: what is done is merged, and the result says ``outcome.interrupted`` (and ``written`` whether the
    merged files were all written: Ctrl-C may come while they are). A file of the output folder that cannot be
    written (a full disk) stops the sweep as Ctrl-C does, ``outcome.write_error`` saying why (the rows stored
    before stand). Raises ``OSError`` when the scheduler cannot be reached or the output folder cannot be
    created, ``ValueError`` (before anything runs) when ``workers`` is not a whole number of at least 1, and
    :class:`rac.sweep.store.FolderBusy` (before anything runs) when another sweep is running into ``plan.out``."""
    from rac.sweep.store import holding  # matplotlib, numpy (via rac.sweep.store): importing rac.sweep stays light

    if workers is not None and (isinstance(workers, bool) or not isinstance(workers, int) or workers < 1):
        # 0 was taken as "one per core", and fewer as a cluster without workers, which waited for ever
        raise ValueError(f"workers must be a whole number of at least 1, not {workers!r}")
    # the folder is this sweep's until its results are written: another at once would interleave them
    with holding(plan.out):
        return _execute(plan, scheduler=scheduler, workers=workers, force=force, retry_failed=retry_failed,
                        quiet=quiet, announce=announce)


def _execute(plan: Plan, *, scheduler: str | None, workers: int | None, force: bool, retry_failed: bool,
             quiet: bool, announce: Any) -> SweepResult:
    """:func:`execute` once the output folder is held."""
    from rac.sweep import report  # matplotlib, numpy (via rac.sweep.report): importing rac.sweep stays light

    # matplotlib, numpy, tqdm (via rac.sweep.run): importing rac.sweep stays light
    from rac.sweep.run import Tracker, connect, pending, rows_in_order, run_tasks, workers_of
    from rac.sweep.store import Store  # matplotlib, numpy (via rac.sweep.store): importing rac.sweep stays light

    store = Store(plan.out)
    store.folder.mkdir(parents=True, exist_ok=True)  # an unwritable folder fails before the cluster starts
    outcome, todo = pending(plan.specs, store, force=force, retry_failed=retry_failed)
    say = announce or (lambda _: None)
    versions = ", ".join(sorted(outcome.other_versions))
    for count, why in ((outcome.rerun_version, f"stored by another version of rac ({versions}; this is "
                                               f"{rac.__version__})"),
                       (outcome.rerun_source, f"stored by rac {rac.__version__} of other source files (rac's "
                                              "files changed since)"),
                       (outcome.rerun_killed, "whose process was killed"),
                       (outcome.rerun_limits, "stopped by another --task-timeout or --task-memory"),
                       (outcome.rerun_failed, "stored as not ok (--retry-failed)")):  # undecided too
        if count:
            say(f"rerunning {count} task{'s' * (count != 1)} {why}")
    if todo:  # everything stored already: no cluster
        try:
            with Tracker(quiet=quiet) as tracker, connect(scheduler, workers, announce=announce) as client:
                # per spec, as the tracker hears of rows: a key shared by two specs (one file under two paths) is two
                tracker.start(sum(1 for key in outcome.keys if key in todo), outcome.skipped)
                tracker.workers = lambda: workers_of(client)
                try:
                    run_tasks(client, plan.specs, todo, outcome, store, on_row=tracker.row)
                finally:  # the client closes next: the progress's thread no longer asks it
                    tracker.workers = None
        except KeyboardInterrupt:  # while the cluster started or closed: the rows stored are still merged
            outcome.interrupted = True
    rows = rows_in_order(plan.specs, outcome)
    result = SweepResult(plan=plan, outcome=outcome, rows=rows,
                         summary=report.summarise(rows, tasks=len(plan.specs), skipped=outcome.skipped,
                                                           skipped_not_ok=outcome.skipped_not_ok))
    if outcome.write_error is not None:  # a row could not be stored: nor could these files, most likely
        result.written = False
        with contextlib.suppress(OSError):  # an earlier sweep's files are not this one's results: not left as such
            report.remove_results(plan.out)
        return result
    try:
        report.remove_results(plan.out)  # a write failing midway leaves none of an earlier sweep's files among these
        files, result.notes = report.write_results(rows, plan.out)
        result.files += files
        result.files += report.write_plots(rows, plan.out)
    except KeyboardInterrupt:  # each row is stored in tasks/ already: the same command writes these files again
        outcome.interrupted, result.written = True, False
    except OSError as exc:  # a full disk: each row is stored already, and the summary of them is still said
        outcome.write_error, result.written = exc, False
    return result


def sweep(template: str | Path, scenarios: Sequence[str | Path] | str | Path, *,
          sets: Mapping[str, object] | Sequence[str] | None = None, task: str = "verify",
          scheduler: str | None = None, workers: int | None = None, out: str | Path | None = None,
          force: bool = False, retry_failed: bool = False, task_timeout: float | None = None,
          task_memory: int | str | None = None,
          options: Mapping[str, object] | None = None, quiet: bool = False) -> Any:
    """Run ``task`` (``check``, ``verify``, ``preanalyse`` or ``experiment``) of the template ``.ra``
    file on every scenario (files, folders searched for ``*.xml``, globs) and every point of the grid
    ``sets`` (``{"exponent": [1, 2]}`` or ``["exponent=1,2"]``), as Dask tasks: on the cluster at
    ``scheduler`` (``tcp://HOST:PORT``), else on a local cluster of ``workers`` processes (default: one
    per core). ``options`` are the task's (:data:`rac.sweep.task.OPTIONS`: ``horizon``, ``seed``,
    ``max_states``, ...); ``task_timeout``
    (seconds) and ``task_memory`` (bytes, or e.g. ``"2G"``) limit each task. Rows already in the output
    folder ``out`` (default ``TEMPLATE.out/sweep/``) are reused unless ``force``; a row whose task's
    process was killed is not a result and runs again, and so does every row not ok with ``retry_failed``.

    Returns one row per task: a pandas DataFrame (columns as in ``results.parquet``, docs/sweep.md) when
    pandas is installed, else the rows as a list of dicts. ``ValueError`` on bad arguments; on Ctrl-C the
    rows done are merged and ``KeyboardInterrupt`` is raised again."""
    from rac.sweep.report import frame  # matplotlib, numpy (via rac.sweep.report): importing rac.sweep stays light

    result = execute(plan(template, scenarios, sets=sets, task=task, out=out, task_timeout=task_timeout,
                          task_memory=task_memory, options=options),
                     scheduler=scheduler, workers=workers, force=force, retry_failed=retry_failed, quiet=quiet)
    if result.outcome.write_error is not None:  # the rows stored before it stand: the same call runs the rest
        raise result.outcome.write_error
    if result.outcome.interrupted:
        raise KeyboardInterrupt
    if result.outcome.cancelled:  # their rows are missing from the frame: said, not left to be noticed
        n = result.outcome.cancelled
        them = "it" if n == 1 else "them"
        warnings.warn(f"the Dask cluster cancelled {n} task{'s' * (n != 1)} before running {them} "
                      f"({result.outcome.cancelled_why}): the result lacks their rows, and the same call runs {them}",
                      RuntimeWarning, stacklevel=2)
    return frame(result.rows)
