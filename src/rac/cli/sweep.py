"""``rac sweep``: a template ``.ra`` file over many scenarios and a grid of model settings, on Dask
(:mod:`rac.sweep`, docs/sweep.md).

Exit codes (:mod:`rac.cli.common`): 0 every task ok, 1 a task failed (errors in the file, a query not
satisfied), 2 bad usage (no scenario matched, a bad ``--set``; before any cluster starts) or an output
folder that cannot be written or that another sweep is running into, 4 none failed but a task could not run
(error, timeout, memory) or a verdict is unknown, 130 Ctrl-C, 143 SIGTERM (a batch system's time limit,
``kill``): in both, what was done is merged first.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Mapping, Sequence
from pathlib import Path

from rac.cli.common import (
    EXIT_ERRORS,
    EXIT_INTERRUPTED,
    EXIT_OK,
    EXIT_TERMINATED,
    EXIT_UNDECIDED,
    EXIT_USAGE,
    as_json,
    how_stopped,
    output_folder,
    print_diagnostics,
    terminate_as_interrupt,
    unreadable,
    unwritable,
    usage_error,
    with_ok,
)
from rac.core.diagnostics import Diagnostic, json_text
from rac.sweep import SweepResult, execute, plan
from rac.sweep.template import TemplateError
from rac.verify.status import UNDECIDED

__all__ = ["exit_status", "sweep_command"]

def exit_status(rows: Sequence[Mapping[str, object]]) -> int:
    """The exit code of a sweep's rows: 1 when a task failed (errors in the file, a query not satisfied),
    else 4 when a task could not run (error, timeout, memory) or a verdict is unknown or unsupported, else 0."""
    if any(row.get("status") == "failed" for row in rows):
        return EXIT_ERRORS

    undecided = set(UNDECIDED)
    for row in rows:
        verdicts = row.get("verdicts")
        if row.get("status") != "ok" or isinstance(verdicts, Mapping) and undecided & set(map(str, verdicts.values())):
            return EXIT_UNDECIDED
    return EXIT_OK


def _count(n: int, noun: str) -> str:
    return f"{n} {noun}{'s' * (n != 1)}"


def _document(template: Path, out: Path, status: int, summary: Mapping[str, object] | None,
              files: Sequence[Path], *, interrupted: bool, written: bool, error: Diagnostic | None = None) -> str:
    """The JSON document of ``--format json``: ``summary`` None when Ctrl-C came before there was one,
    ``written`` whether ``results.*`` and the plots were all written (``files`` holds those that were), and
    ``error`` (only when there is one) the file of the output folder that could not be written."""
    document = {"template": str(template), "out": str(out), "interrupted": interrupted,
                "exit_code": status, "summary": summary, "files": [str(f) for f in files], "written": written}
    if error is not None:  # one document: the error in it, not a second one beside it (as rac verify's)
        document["error"] = error.to_json()
    return json_text(with_ok(document, status), indent=2)


def _write_failed(result: SweepResult, out: Path) -> Diagnostic | None:
    """E0009 of the file the sweep could not write (a row, results.* or a plot), saying what stands: the rows
    stored in ``tasks/`` are kept, and the same command reuses them; None when every file was written."""
    from rac.sweep.store import TASKS_FOLDER  # matplotlib (via rac.sweep.store): only when this runs

    exc = result.outcome.write_error
    if exc is None:
        return None
    summary = result.summary
    stored = f"the rows of {_count(summary.finished, 'task')} are stored in {out / TASKS_FOLDER}"
    again = (f"the same command, once it can write there, runs only the {_count(summary.not_run, 'task')} left"
             if summary.not_run else "the same command, once it can write there, writes results.* and the plots")
    return unwritable(Path(exc.filename) if exc.filename else out, exc, kept=f"{stored}: {again}")


def sweep_command(args: argparse.Namespace) -> int:
    """``rac sweep``: plan (bad arguments exit 2 before any cluster starts), run, merge, summarise."""
    # matplotlib, numpy (via rac.sweep.report): only the command that uses it loads it
    from rac.sweep.report import render_summary

    # matplotlib, numpy (via rac.sweep.run): only the command that uses it loads it
    from rac.sweep.run import BadSchedulerAddress
    from rac.sweep.store import FolderBusy  # matplotlib (via rac.sweep.store): only the command that uses it loads it

    if args.workers:
        import dask  # dask: only the command that uses it loads it

        # the cluster that connect() would use instead of a local one: --workers would be ignored there
        where = "--scheduler" if args.scheduler else (
            "Dask's scheduler-address configuration" if dask.config.get("scheduler-address", None) else None)
        if where is not None:
            print_diagnostics([usage_error(f"--workers sizes the local cluster; the cluster at {where} has its own "
                                           "workers")], {}, as_json(args))
            return EXIT_USAGE
    options = {"horizon": args.horizon, "seed": args.seed, "max_states": args.max_states, "episodes": args.episodes,
               "runs": args.runs, "reward_function": args.reward_function, "explore": args.explore}
    out = output_folder(Path(args.template), "sweep", Path(args.out) if args.out else None)
    try:
        planned = plan(args.template, args.scenarios, sets=args.sets, task=args.task, out=out,
                       task_timeout=float(args.task_timeout) if args.task_timeout else None,
                       task_memory=args.task_memory, options={k: v for k, v in options.items() if v is not None})
    except KeyboardInterrupt:  # while the scenarios are found and read (thousands take a while): no task ran yet
        status = EXIT_TERMINATED if how_stopped() != "interrupted" else EXIT_INTERRUPTED
        if args.format == "json":  # the command's document (main's bare one lacked `summary`, `files`, `written`)
            print(_document(Path(args.template).absolute(), out, status, None, [], interrupted=True, written=False))
        print(f"rac sweep: {how_stopped()} while the scenarios were read; no task ran, nothing was written",
              file=sys.stderr)
        return status
    except OSError as exc:
        print_diagnostics([unreadable(Path(args.template), exc)], {}, as_json(args))
        return EXIT_USAGE
    except TemplateError as exc:  # the template's own error as rac check gives it (its code, its span), not as text
        print_diagnostics([usage_error(exc.summary), exc.diagnostic], exc.sources, as_json(args))
        return EXIT_USAGE
    except ValueError as exc:
        print_diagnostics([usage_error(str(exc))], {}, as_json(args))
        return EXIT_USAGE
    quiet = args.quiet or args.format == "json"
    say = (lambda _: None) if args.quiet else (lambda line: print(f"rac sweep: {line}", file=sys.stderr))
    scenes = _count(planned.scenarios, 'scenario')
    if planned.problems > planned.scenarios:  # files with several planning problems: a task per problem
        scenes += f" ({_count(planned.problems, 'planning problem')})"
    say(f"{_count(len(planned.specs), 'task')}: {scenes} × "
        f"{_count(planned.points, 'grid point')}, task {args.task}; outputs in {planned.out}")
    terminated: list[int] = []
    try:
        with terminate_as_interrupt() as terminated:
            result = execute(planned, scheduler=args.scheduler, workers=int(args.workers) if args.workers else None,
                             force=args.force, retry_failed=args.retry_failed, quiet=quiet, announce=say)
    except FolderBusy as exc:  # another sweep into the same folder, before any task ran: nothing was written
        print_diagnostics([usage_error(str(exc))], {}, as_json(args))
        return EXIT_USAGE
    except BadSchedulerAddress as exc:  # the address itself, before any connection: bad usage
        where = "--scheduler" if args.scheduler else "Dask's scheduler-address configuration"
        print_diagnostics([usage_error(f"{where}: {exc}")], {}, as_json(args))
        return EXIT_USAGE
    except OSError as exc:  # a file of the output folder (E0009), or no connection to the scheduler
        found = unwritable(Path(exc.filename), exc) if exc.filename else usage_error(str(exc))
        print_diagnostics([found], {}, as_json(args))
        return EXIT_USAGE
    except KeyboardInterrupt:  # outside the run and the writing (execute's own): before them, or between
        from rac.sweep.store import TASKS_FOLDER  # matplotlib (via rac.sweep.store): only when this runs

        status = EXIT_TERMINATED if terminated else EXIT_INTERRUPTED
        if args.format == "json":  # standard output stays one JSON document, whenever the interrupt came
            print(_document(planned.template, planned.out, status, None, [], interrupted=True, written=False))
        how = "terminated (SIGTERM)" if terminated else "interrupted"
        print(f"rac sweep: {how}; results.* not written (run the same command again: the rows of the tasks that "
              f"ran are stored in {planned.out / TASKS_FOLDER})", file=sys.stderr)
        return status
    status = exit_status(result.rows)
    if result.outcome.interrupted:  # the exit code the process ends with, which the JSON document says too
        status = EXIT_TERMINATED if terminated else EXIT_INTERRUPTED
    cancelled = result.outcome.cancelled
    if cancelled and status == EXIT_OK:  # tasks that could not run: no sweep of them all is ok
        status = EXIT_UNDECIDED
    failed = _write_failed(result, planned.out)
    if failed is not None:  # the rows stored before stand, and are summarised: the output folder is the user's to fix
        status = EXIT_USAGE
    if args.format == "json":
        print(_document(planned.template, planned.out, status, result.summary.to_json(), result.files,
                        interrupted=result.outcome.interrupted, written=result.written, error=failed))
    else:
        print(render_summary(result.summary))
        print()
        for path in result.files:
            print(f"wrote {path}")
        if failed is not None:
            print_diagnostics([failed])
    for note in result.notes:
        print(f"rac sweep: note: {note}", file=sys.stderr)
    if cancelled:
        they, them = ("it", "it") if cancelled == 1 else ("they", "them")
        print(f"rac sweep: the Dask cluster cancelled {_count(cancelled, 'task')} before {they} ran "
              f"(Dask's reason: {result.outcome.cancelled_why}); no row is stored for {them}: run the same command "
              "again, once the cluster is back, to run only those", file=sys.stderr)
    how = "terminated (SIGTERM)" if terminated else "interrupted"
    if not result.written and result.outcome.interrupted:
        print(f"rac sweep: {how} while writing results.* and the plots (run the same command again to write "
              "them: the tasks that ran are stored)", file=sys.stderr)
    if result.outcome.interrupted and (result.written or result.summary.not_run):
        # under --force the store holds rows of before this run for the tasks left: no command runs only those
        again = ("with --force the same command runs every task again; without it, it reuses every stored row, "
                 "those of earlier runs included" if args.force else
                 "run the same command again to run only those")
        print(f"rac sweep: {how}: {_count(result.summary.not_run, 'task')} not run ({again})", file=sys.stderr)
    return status
