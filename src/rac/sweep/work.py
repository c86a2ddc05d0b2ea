"""What one task of ``rac sweep`` runs, inside its child process (:mod:`rac.sweep.task`): the template
instantiated for the task (:func:`rac.sweep.template.instantiate`), checked with
:func:`rac.compiler.compile_text`, then the command's own function on the checked file:

- ``check``: the diagnostics alone;
- ``verify``: :func:`rac.verify.runner.verify` (the verdict per query; states: the most any query explored);
- ``preanalyse``: :func:`rac.studies.preanalysis.sweep` at the file's own settings (details: its
  rows; verdicts: Qb, Qc and Qd);
- ``experiment``: :func:`rac.studies.experiment.run_experiment` and its
  :func:`~rac.studies.experiment.summary` (details: the table's rows; states: the shield's, also when it allows
  no safe strategy).

Nothing is written but into a temporary folder that is removed (verify's strategies, CSV files).
:func:`execute` returns the task's part of the row and never raises.
"""

from __future__ import annotations

import contextlib
import importlib
import json
import tempfile
import time
import traceback
from fractions import Fraction
from pathlib import Path
from typing import TYPE_CHECKING, Any

from rac.compiler import CompileResult, compile_text
from rac.core.diagnostics import RacError, Severity
from rac.core.files import atomic_write
from rac.core.numbers import MIN_SEED, format_bytes, fresh_seed, samples_of
from rac.core.resources import ScenarioTooLarge, memory_option_named
from rac.engine.budget import BudgetExceeded, default_max_bytes
from rac.model.checks import UNUSABLE_SCENARIO
from rac.sweep.kinds import MEMORY_OPTION
from rac.sweep.task import OPTIONS
from rac.sweep.template import instantiate
from rac.verify.status import UNDECIDED, VERDICTS

if TYPE_CHECKING:
    from rac.sweep.task import TaskSpec

__all__ = ["execute", "load"]

#: The modules each task needs (the check's, which it imports when it runs, first), imported by
#: :func:`load` before the memory limit is set.
CHECK_MODULES = ("rac.check.analysis", "rac.model.checks", "rac.model.commonroad", "rac.model.data",
                 # what rac's modules import only when they run: numpy (its OpenBLAS), shapely and commonroad-io's
                 # reader, loaded under --task-memory, failed to map their shared objects and made a task's row a
                 # numpy "bad install" ImportError or an OpenBLAS exit, not a memory row
                 "numpy", "shapely", "commonroad.common.file_reader")
MODULES = {"check": (), "verify": ("rac.verify.runner",), "preanalyse": ("rac.studies.preanalysis",),
           "experiment": ("rac.studies.experiment", "rac.learning.episodes", "rac.learning.lockstep",
                          "rac.learning.qlearning", "rac.learning.runs")}
#: The preanalysis answers that are verdicts, by the row's column.
PREANALYSIS_VERDICTS = {"qb": "Qb", "qc": "Qc", "qd": "Qd"}


class TaskError(RacError):
    """The task cannot run as asked (an option, the scenario file): an "error" row with this message."""


def load(task: str) -> None:
    """Import the modules ``task`` runs."""
    for name in (*CHECK_MODULES, *MODULES[task]):
        importlib.import_module(name)


def execute(spec: TaskSpec) -> dict[str, Any]:
    """Run ``spec`` here; its part of the row (status, error, seconds, states, scenario_size, verdicts,
    diagnostics, details)."""
    start = time.perf_counter()
    row: dict[str, Any] = {}
    try:
        # the budget's refusals name the sweep's option, not rac verify's; with --task-memory it is the limit too
        with memory_option_named(MEMORY_OPTION, limits=spec.memory is not None):
            row = _execute(spec, row)
    except TaskError as exc:
        row.update(status="error", error=str(exc))
    except BudgetExceeded as exc:  # an estimate, before the memory was used: the budget's words
        row.update(status="error", error=str(exc))
    except ScenarioTooLarge as exc:  # refused before the load: in the sweep's terms (its limit is --task-memory)
        row.update(status="memory", error=(
            f"MemoryError: the scenario {exc.path} ({format_bytes(exc.estimate.file_bytes)}) would need about "
            f"{format_bytes(exc.estimate.peak_bytes)} of memory to load, more than the task's limit of "
            f"{format_bytes(exc.limit)} ({MEMORY_OPTION}); nothing was loaded"))
    except MemoryError as exc:
        row.update(status="memory", error=f"MemoryError: {exc}".rstrip(": "))
    except Exception as exc:  # a bug or an unforeseen input: the row says where
        where = traceback.extract_tb(exc.__traceback__)[-1]
        row.update(status="error", error=f"{type(exc).__name__}: {exc} ({Path(where.filename).name}:{where.lineno})")
    row["seconds"] = time.perf_counter() - start
    return row


def _execute(spec: TaskSpec, row: dict[str, Any]) -> dict[str, Any]:
    options = _options(spec)
    scenario = Path(spec.scenario)
    try:
        if scenario.is_file() or not scenario.exists():  # opening a FIFO waits for a writer: the check refuses it
            with scenario.open("rb"):
                pass
    except OSError as exc:
        raise TaskError(f"cannot read the scenario {scenario}: {exc.strerror or exc}") from None
    try:
        chosen = () if spec.planning_problem is None else (("planning_problem", str(spec.planning_problem)),)
        text = instantiate(spec.template_text, spec.template, scenario, (*spec.settings, *chosen))
    except ValueError as exc:
        raise TaskError(str(exc)) from None
    # the task's memory limit is the scenario load's budget too: refused before it is read, not killed in it
    result = compile_text(text, name=spec.template, max_bytes=spec.memory)
    row["diagnostics"] = [f"{d.code} {d.message}" for d in result.diagnostics
                          if d.severity in (Severity.ERROR, Severity.WARNING)]
    row["scenario_size"] = _size(result)
    # a task killed at its timeout keeps it too: the slow tasks were the ones missing from time_vs_size.png
    _keep(spec.partial, {"scenario_size": row["scenario_size"], "kept": ""})
    errors = [d for d in result.diagnostics if d.is_error]
    if errors:
        # a scenario that cannot be loaded or is inconsistent: rac could not run the task ("error", not "failed")
        status = "error" if any(d.code in UNUSABLE_SCENARIO for d in errors) else "failed"
        row.update(status=status, error=f"{errors[0].code} {errors[0].message}")
        return row
    if result.automaton is None or result.automaton.model is None or result.model_data is None:
        raise TaskError("the instantiated template has no scenario model")  # the template has a model block
    row.update(status="ok", error=None)
    # the memory budget of `rac verify`, `rac preanalyse` and `rac experiment`: the task's limit, else theirs (half
    # the memory available); preanalyse and experiment ran without one, so a large model grew past a GB unchecked
    # (or into --task-memory, as an allocation that failed midway, not the estimate that says how far it got)
    max_bytes = spec.memory if spec.memory is not None else spec.budget or default_max_bytes()
    if spec.task == "verify":
        _verify(result, options, row, max_bytes, spec.partial)
    elif spec.task == "preanalyse":
        _preanalyse(result, options, row, max_bytes, spec.partial)
    elif spec.task == "experiment":
        _experiment(result, options, row, max_bytes)
    return row


def _size(result: CompileResult) -> int | None:
    """Lanelets + obstacles of the scenario the check loaded (None when it could not load it)."""
    scenario = result.scenario
    return None if scenario is None else len(scenario.road) + len(scenario.obstacles)


# ---------------------------------------------------------------- options
def _whole(name: str, text: str) -> int:
    try:
        value = int(text)
    except ValueError:
        raise TaskError(f"option {name}: not a whole number: {text!r}") from None
    least = MIN_SEED if name == "seed" else 1
    if value < least:
        raise TaskError(f"option {name}: must be at least {least}: {text!r}")
    return value


def _options(spec: TaskSpec) -> dict[str, Any]:
    """The task's options, converted; :class:`TaskError` for an unknown name or a bad value."""

    options: dict[str, Any] = {}
    for name, text in spec.options:
        if name not in OPTIONS:
            raise TaskError(f"unknown option `{name}` (the options are {', '.join(OPTIONS)})")
        if name == "horizon":
            try:
                options[name] = Fraction(text)
            except (ValueError, ZeroDivisionError):
                raise TaskError(f"option horizon: not a number: {text!r}") from None
            if options[name] <= 0:
                raise TaskError(f"option horizon: must be positive: {text!r}")
        elif name == "seeds":
            options[name] = [_whole("seed", part.strip()) for part in text.split(",")]
        elif name == "reward_function":
            options[name] = text
        elif name == "explore":  # its values are checked by the plan (rac.sweep.api.plan) and the experiment
            options[name] = text
        else:
            options[name] = _whole(name, text)
    return options


def _horizon_samples(result: CompileResult, horizon: Fraction | None) -> int | None:
    if horizon is None:
        return None
    assert result.automaton is not None
    try:  # the command line's rule (one owner: rac.core.numbers), beyond int32 samples too
        return samples_of(horizon, Fraction(result.automaton.period), what="option horizon:")
    except ValueError as exc:
        raise TaskError(str(exc)) from None


# ---------------------------------------------------------------- the tasks
def _budget(options: dict[str, Any]) -> dict[str, Any]:
    """``max_states`` when the option gives it (else the command's own default applies)."""
    return {"max_states": options["max_states"]} if "max_states" in options else {}


def _keep(partial_file: str | None, fields: dict[str, Any]) -> None:
    """Write ``fields`` (:data:`rac.sweep.task.PARTIAL_FIELDS`, ``kept`` and ``running``) into the task's partial
    file, if it has one: what a task killed at its timeout keeps."""
    if partial_file is None:
        return
    with contextlib.suppress(OSError):  # a full disk loses the partial answers, not the task
        atomic_write(partial_file, lambda file: file.write(json.dumps(fields, default=str).encode("utf-8")))


def _verify(result: CompileResult, options: dict[str, Any], row: dict[str, Any], max_bytes: int,
            partial_file: str | None) -> None:
    # numpy, rac.check.analysis, stormpy (via rac.verify.runner): importing rac.sweep.work stays light
    from rac.verify.runner import VerifyOptions, run_queries

    # drawn here when not given, as rac verify draws it, so that the row can say it: a statistical or learning
    # query's verdict that no seed reproduces could not be checked with `rac verify --seed N` on the file
    seed = options["seed"] if "seed" in options else fresh_seed()
    chosen: dict[str, Any] = {"horizon": options.get("horizon"), "seed": seed, "plots": False, "max_bytes": max_bytes,
                              **_budget(options)}
    if "episodes" in options:
        chosen["learn_episodes"] = options["episodes"]
    answered: list[Any] = []  # each query's result as it is found

    def starting(query: str) -> None:  # before each query: the answers so far, which a task killed later keeps
        names = [r.name for r in answered]
        kept = f"kept the answers of the queries before it ({', '.join(names)}); it was answering {query}"
        _keep(partial_file, {**_verify_fields(answered, seed), "kept": kept if names else "", "running": None,
                             "scenario_size": row.get("scenario_size")})

    with tempfile.TemporaryDirectory(prefix="rac-sweep-") as out:  # strategies and CSV files are not kept
        try:
            _, results = run_queries(result, VerifyOptions(out_dir=Path(out), progress=starting, **chosen),
                                     answered=answered)
        except ValueError as exc:  # the horizon is not a whole number of samples
            raise TaskError(str(exc)) from None
    row.update(_verify_fields(results, seed))
    failed = [r.name for r in results if r.status == "not satisfied"]
    undecided = [f"{r.name} ({r.status}: {r.message})" for r in results if r.status in UNDECIDED]
    if failed:
        row.update(status="failed", error="not satisfied: " + ", ".join(failed))
    elif undecided:
        row.update(status="undecided", error="not decided: " + "; ".join(undecided))


def _verify_fields(results: list[Any], seed: int) -> dict[str, Any]:
    """A verify task's row fields of the query ``results``: verdicts, states (the most any query explored) and,
    when a query drew runs, the ``seed`` that reproduces them with `rac verify --seed N`."""
    states = [r.states for r in results if r.states is not None]
    fields = {"verdicts": {r.name: r.status for r in results if r.status in VERDICTS},
              "states": max(states) if states else None}
    if any(r.seed is not None for r in results):
        fields["seed"] = seed
    return fields


def _preanalyse(result: CompileResult, options: dict[str, Any], row: dict[str, Any], max_bytes: int,
                partial_file: str | None) -> None:
    # numpy, scipy, stormpy (via rac.studies.preanalysis): importing rac.sweep.work stays light
    from rac.studies.preanalysis import SweepError, sweep

    def partial(rows: list[dict[str, Any]], running: bool) -> None:  # a task killed at its timeout keeps these
        found = [name for name in ("Qa", *PREANALYSIS_VERDICTS.values())
                 if any(r.get(name.lower()) is not None for r in rows)]
        _keep(partial_file, {**_preanalysis_fields(rows), "running": len(rows) - 1 if running else None,
                             "scenario_size": row.get("scenario_size"),
                             "kept": f"kept the answers found before it ({', '.join(found)}) in its details"
                             if found else ""})

    try:
        rows = sweep(result, horizon=options.get("horizon"), seed=options.get("seed"),
                     runs=options.get("runs", 100), quiet=True, max_bytes=max_bytes, partial=partial,
                     **_budget(options))
    except SweepError as exc:
        raise TaskError(str(exc)) from None
    row.update(_preanalysis_fields(rows))
    answered = [r for r in rows if "exponent" in r]
    problems = [r["error"] for r in answered if r.get("error")]
    if problems:  # a setting without answers (beyond a budget, a period that does not fit) is undecided, as in
        # `rac preanalyse` (exit 4): no answer failed
        row.update(status="undecided", error=problems[0])


def _preanalysis_fields(rows: list[dict[str, Any]]) -> dict[str, Any]:
    """A preanalyse task's row fields of the preanalysis ``rows``: details (the rows), verdicts (Qb-Qd of the file's
    own setting) and states (the most any setting explored)."""
    fields: dict[str, Any] = {"details": rows}
    answered = [r for r in rows if "exponent" in r]
    if len(answered) == 1:  # the file's own setting: Qb-Qd are its verdicts
        fields["verdicts"] = {query: "satisfied" if answered[0][column] else "not satisfied"
                              for column, query in PREANALYSIS_VERDICTS.items() if answered[0].get(column) is not None}
    states = [r["states"] for r in answered if r.get("states") is not None]
    fields["states"] = max(states) if states else None
    return fields


def _experiment(result: CompileResult, options: dict[str, Any], row: dict[str, Any], max_bytes: int) -> None:
    # numpy (via rac.studies.experiment): importing rac.sweep.work stays light
    from rac.studies.experiment import ExperimentError, goal_out_of_reach, run_experiment, summary

    if "seed" in options and "seeds" in options:
        raise TaskError("give the option seeds or seed, not both")
    seeds = options.get("seeds", [options["seed"]] if "seed" in options else [1, 2, 3, 4, 5])
    # what else the sweep can lower, for the budget's refusals: `rac sweep` has no option for the combinations, and
    # seeds only as the option seeds (the API's) or --seed N (one seed)
    fewer_runs = (None if len(seeds) == 1 else f"the seeds (option seeds, {len(seeds)})" if "seeds" in options
                  else f"the seeds (--seed N runs one seed instead of {len(seeds)})")
    try:
        report = run_experiment(result, seeds=seeds, episodes=options.get("episodes", 500),
                                fewer_runs=fewer_runs,
                                evaluation_runs=options.get("runs", 100),
                                reward_function=options.get("reward_function"),
                                explore=options.get("explore", "uniform"),
                                horizon_samples=_horizon_samples(result, options.get("horizon")),
                                max_bytes=max_bytes, **_budget(options))
    except ExperimentError as exc:
        # whose it is, as rac experiment's exit code says: a budget stops it undecided (as verify's and preanalyse's
        # tasks, docs/sweep.md), an option the task cannot run with is an error, the scenario's own failure (no safe
        # strategy from the start) fails it
        status = {"limit": "undecided", "usage": "error"}.get(exc.kind, "failed")
        row.update(status=status, error=str(exc))
        if exc.states is not None:  # the shield was computed (no safe strategy): its size, as an ok row's
            row["states"] = exc.states
        return
    row["details"] = summary(report)
    row["states"] = report["shield_states"]
    unreachable = goal_out_of_reach(report)
    if unreachable is not None:  # every row of the table must fail: as rac experiment's exit 1 says, a failure
        row.update(status="failed", error=unreachable)
