"""The engine commands of ``rac``: ``verify``, ``simulate``, ``render`` and ``preanalyse``.

They share the conventions of :mod:`rac.cli.common`: exit 0 when everything asked holds, 1 when a query is
not satisfied or the file has errors, 2 for bad usage or unreadable/unwritable files, 4 when a query
was not decided (``verify``: *unknown* or *unsupported*, and none not satisfied).
"""

from __future__ import annotations

import argparse
import dataclasses
import functools
import json
import sys
from collections.abc import Callable, Mapping, Sequence
from fractions import Fraction
from pathlib import Path
from typing import TYPE_CHECKING, TypeVar

from rac.check.queries import lower_expression
from rac.cli.common import (
    EXIT_ERRORS,
    EXIT_INTERRUPTED,
    EXIT_OK,
    EXIT_UNDECIDED,
    EXIT_USAGE,
    as_json,
    held_source,
    how_stopped,
    interrupts_as_such,
    output_folder,
    overwrites_source_in,
    print_diagnostics,
    resource_limit,
    stopping_signal,
    unusable_file,
    unwritable,
    usage_error,
    with_ok,
)
from rac.cli.files import read_and_check
from rac.compiler import CompileResult
from rac.core.diagnostics import CheckError, Diagnostic, RacError, counted, json_text, sort_key
from rac.core.diagnostics import render_text as render_diagnostics
from rac.core.numbers import fresh_seed, samples_of
from rac.core.source import SourceFile
from rac.engine.budget import BudgetExceeded, default_max_bytes, out_of_memory
from rac.ir import query as iq
from rac.lang.parser import ExpressionError
from rac.model.checks import goal_window, representation_span, traffic_ends
from rac.model.data import ModelRangeError
from rac.model.native import NO_OBSTACLE, NO_OBSTACLE_TEXT
from rac.model.sample import Ego
from rac.output.progress import Heartbeat, Progress, simulate_callback
from rac.verify.status import NOT_SATISFIED, UNDECIDED

if TYPE_CHECKING:
    from rac.engine.graph import ExploredGraph
    from rac.engine.simulate import Runs
    from rac.verify.report import QueryResult

#: A sub-command: its parsed arguments -> the exit code.
Command = Callable[[argparse.Namespace], int]
T = TypeVar("T")


def _load(path: Path, max_bytes: int | None, structured: bool = False) -> tuple[CompileResult | None, int]:
    result, problem = read_and_check(path, max_bytes)
    if result is None:
        assert problem is not None
        print_diagnostics([problem], {}, structured)
        return None, EXIT_USAGE
    errors = [d for d in result.diagnostics if d.is_error]
    if errors:
        print_diagnostics(result.diagnostics, result.sources, structured)
        return None, EXIT_ERRORS
    if result.automaton is None or result.automaton.model is None:
        print_diagnostics([unusable_file(
            f"`{path}` has no `model` block: the engine answers queries on a scenario model",
            hints=["add a `model` block naming a CommonRoad scenario (docs/language.md, 'The model block')"])],
            {}, structured)
        return None, EXIT_ERRORS
    if result.model_data is None:
        print_diagnostics([unusable_file(f"`{path}`: the scenario model could not be built",
                                         hints=[f"`rac check {path}` says why"])], {}, structured)
        return None, EXIT_ERRORS
    warned = [d for d in result.diagnostics if not d.is_error]
    if warned and not structured:  # rac check's warnings hold for the answers too (JSON: the document's `warnings`)
        print_diagnostics(warned, result.sources, False)
    return result, EXIT_OK


def _warnings(result: CompileResult) -> list[dict[str, object]]:
    """``rac check``'s warnings of the file, as a command's ``--format json`` document holds them: they bear
    on its answers (an ego that starts off the road fails Qd), and text prints them on standard error."""
    return [d.to_json() for d in sorted((d for d in result.diagnostics if not d.is_error), key=sort_key)]


def _prepare(args: argparse.Namespace) -> tuple[CompileResult | None, int]:
    """The checked file with a model (or None and the exit code, after saying why); ``--horizon``
    must be a whole number of samples (preanalyse's sweep checks it against each sensing period of its
    grid instead)."""

    result, status = _load(args.file, args.max_memory or default_max_bytes(), as_json(args))
    if result is not None and args.command != "preanalyse" and not _horizon_ok(result, args):
        return None, EXIT_USAGE
    # preanalyse checks its --horizon per setting later: an unchecked 1e400 must not reach a float here
    if result is not None and args.command != "preanalyse":
        result = _horizon_warnings(result, args)
    return result, status


def _horizon_warnings(result: CompileResult, args: argparse.Namespace, *, goal: bool = True) -> CompileResult:
    """``result`` with the warnings of a ``--horizon`` other than the file's, printed unless the output is
    JSON: W0728 (it runs past the recorded traffic: its answers after it are for an empty road) and W0722
    (it ends before the goal's window opens: every goal query is "no" for that reason alone). A code the
    file's own horizon drew already is not said again. ``--horizon`` must have been checked (a whole number
    of samples). Without ``goal``, W0728 only (preanalyse says per setting where its goal never holds)."""
    horizon = getattr(args, "horizon", None)
    if result.automaton is None or result.scenario is None or horizon is None:
        return result
    said = {d.code for d in result.diagnostics}
    found = [] if "W0728" in said else traffic_ends(result.automaton, result.scenario, horizon)
    if goal and "W0722" not in said and result.model_data is not None:
        found += goal_window(result.automaton, result.scenario, result.model_data, horizon)
    if not found:
        return result
    if not as_json(args):
        print_diagnostics(found, result.sources, False)
    return dataclasses.replace(result, diagnostics=(*result.diagnostics, *found))


def _out_dir(args: argparse.Namespace) -> Path:
    """The command's output folder: ``-o``, else ``FILE.out/COMMAND/`` (each engine command's folder is
    named after the command)."""
    return output_folder(args.file, args.command, args.out)


def _written(out_dir: Path, exc: OSError) -> Path:
    """The path a write into ``out_dir`` failed on: the file the error names (a folder where ``run.png``
    goes), else the folder (naming the folder alone, with the hint "name a file, not a folder", sent
    users to the ``-o`` they gave)."""
    return Path(exc.filename) if isinstance(exc.filename, str) and exc.filename else out_dir


def _report(args: argparse.Namespace, diagnostic: Diagnostic, sources: Mapping[str, SourceFile] | None = None) -> None:
    """Print ``diagnostic`` as the command's ``--format`` asks (:func:`rac.cli.common.print_diagnostics`)."""
    print_diagnostics([diagnostic], sources, as_json(args))


def _on_checked_file(command: Callable[[argparse.Namespace, CompileResult], int]) -> Command:
    """A command run as ``command(args, result)`` on ``args.file`` checked, with a model (:func:`_prepare`);
    when the file cannot be used, :func:`_prepare` said why and its exit code is the command's. An output
    folder holding the input file under a name an output may take is refused first (E0009, exit 2)."""

    @functools.wraps(command)
    def run(args: argparse.Namespace) -> int:
        # every output of the engine commands goes into this folder: rac never overwrites the file it reads
        held = held_source(_out_dir(args), args.file)
        if held is not None:
            _report(args, overwrites_source_in(_out_dir(args), held, args.file), {})
            return EXIT_USAGE
        # off a terminal (CI logs, pipes) a long command says what it does every few seconds, from the
        # scenario's load on
        with Heartbeat(f"rac {args.command}", enabled=False if args.quiet else None):
            result, status = _prepare(args)
            if result is None:
                return status
            try:
                return command(args, result)
            except ModelRangeError as exc:  # a run's value, not the file's data (rac check has those)
                _report(args, _left_int32_diagnostic(result, exc), result.sources)
                return EXIT_ERRORS
            except RacError as exc:
                if exc.diagnostic is None:
                    raise
                # the failure points into the file: rendered with its source line, like rac check's findings
                _report(args, exc.diagnostic, result.sources)
                return EXIT_ERRORS

    return run


def _left_int32_diagnostic(result: CompileResult, exc: ModelRangeError, *, notes: Sequence[str] = ()) -> Diagnostic:
    """E0015 of a run's value beyond int32, pointing into the file: at the binding whose value it is, else at the
    `model` block's number representation (its `exponent`), whose choice it is; ``notes`` after the reason."""
    from rac.verify.context import left_int32  # the verdicts' wording (loaded only here)

    automaton = result.automaton
    assert automaton is not None and automaton.model is not None  # _prepare refused a file without them
    sensed = exc.what.startswith("sense()")
    binding = next((b for b in automaton.model.bindings if b.input == exc.binding), None)
    hints = [] if sensed else ["bound the binding (`fmin(e, 1000)`, `fmax(e, -1000)`) so that its value "
                               "keeps a significand"]
    return unusable_file(
        left_int32(exc),
        notes=["UPPAAL's model aborts there too; the run cannot go on" if sensed else
               "the emitted model has no int32 for it either (UPPAAL does not document what `fint()` "
               "gives beyond int32); the run cannot go on", *notes],
        hints=[*hints, "a coarser `exponent` in the model block (`rac preanalyse` compares them) or a "
                       f"shorter horizon keeps the {'sensed ' if sensed else ''}values within int32"],
        span=binding.span if binding is not None else representation_span(automaton))


def _note(args: argparse.Namespace, notes: list[str], text: str) -> None:
    """A note on what a command's outputs mean: on standard error as ``rac COMMAND: note: text``, or with
    ``--format json`` kept in ``notes`` for the command's JSON document (standard output stays JSON)."""
    if as_json(args):
        notes.append(text)
    else:
        print(f"rac {args.command}: note: {text}", file=sys.stderr)


def _print_summary(args: argparse.Namespace, document: dict[str, object], lines: Sequence[str]) -> None:
    """A command's result: ``document`` as JSON with ``--format json``, else ``lines`` of text."""
    if as_json(args):
        print(json_text(document, indent=2))
    else:
        for line in lines:
            print(line)


def _seed(args: argparse.Namespace) -> int:
    """``--seed``, or a fresh seed drawn now: short, so that a run printing it is reproduced by
    ``--seed N``."""
    if args.seed is not None:
        return int(args.seed)
    return fresh_seed()


def _announcer(quiet: bool) -> Callable[[str], None]:
    """``announce(message)``: a line on a terminal (unless ``quiet``), and the phase of the active heartbeat."""

    def announce(message: str) -> None:
        if Heartbeat.active is not None:  # printed only off a terminal, and not with -q
            Heartbeat.active.phase(message)
        if not quiet and sys.stderr.isatty():
            print(f"… {message}", file=sys.stderr)

    return announce


def _shielded_runs(result: CompileResult, args: argparse.Namespace, samples: int, n: int, notes: list[str]):
    """``n`` simulated runs (under the safety shield with ``--shield``) and their seed, or None, the
    reason when no shield can be used and the exit code it calls for (:func:`_shield_policy`); what the
    runs' guarantee was goes into ``notes`` (:func:`_note`)."""
    # numpy (via rac.engine.shield): only the command that uses it loads it
    from rac.engine.shield import StepShieldPolicy

    # numpy (via rac.engine.simulate): only the command that uses it loads it
    from rac.engine.simulate import simulate

    policy = None
    if args.shield:
        policy, problem, status = _shield_policy(result, samples, args, n, notes)
        if policy is None:
            return None, problem, status
    seed = _seed(args)
    assert result.model_data is not None  # _load refused a file without one
    # a run of many samples takes minutes (900,000 at 1 ms): a bar on a terminal, the count in the heartbeat
    with Progress(total=samples, desc="simulating", unit="samples",
                  enabled=False if args.quiet or as_json(args) else None) as bar:
        # a run whose sensed state leaves int32 stops there (UPPAAL's model aborts), the others go on: the caller
        # shows each up to its stop and says where it stopped (_stopped_runs), where one such run dropped them all
        runs = simulate(result.model_data, runs=n, horizon_samples=samples, seed=seed, policy=policy,
                        max_bytes=args.max_memory or default_max_bytes(), progress=simulate_callback(bar),
                        stop_at_overflow=True)
    if isinstance(policy, StepShieldPolicy):  # the guarantee the runs had, said beside them
        _note(args, notes, f"the runs' actions, {policy.summary()}")
    return runs, seed, EXIT_OK


def _stopped_runs(result: CompileResult, runs: Runs, shown: str) -> Diagnostic | None:
    """E0015 of the runs that stopped where their sensed state left int32 (:func:`_left_int32_diagnostic`, of the
    first to stop), saying which stopped where, then ``shown`` (what the outputs hold of them); None when no run
    stopped."""
    overflow = runs.overflow
    if not runs.overflow_errors or overflow is None:
        return None
    stopped = sorted(runs.overflow_errors, key=lambda run: (int(overflow[run]), run))

    def at(run: int) -> str:
        sample = int(overflow[run])
        return f"run {run} at sample {sample} (t = {runs.times[sample]:g} s)"

    which = ", ".join(at(run) for run in stopped[:3]) + (f" and {len(stopped) - 3} more" if len(stopped) > 3 else "")
    others = runs.n_runs - len(stopped)
    went_on = f"; the other {counted(others, 'run')} went on to the horizon" if others else ""
    return _left_int32_diagnostic(result, runs.overflow_errors[stopped[0]], notes=[
        f"{len(stopped)} of {counted(runs.n_runs, 'run')} stopped there: {which}; {shown}{went_on}"])


def _no_runs(reason: str, status: int) -> Diagnostic:
    """Why no runs were drawn: the file's (no safe strategy, exit 1) or the options' (exit 2)."""
    if status == EXIT_ERRORS:
        return unusable_file(reason, hints=["without --shield the runs show how the ego fails; `rac verify --standard` "
                                            "answers Qa-Qd, whose Qd is this shield's query"])
    return usage_error(reason)


def _strategy_run(result: CompileResult, args: argparse.Namespace, samples: int):
    """The one run of the file's learned strategy ``args.strategy`` (learned now, with the shield it
    is learned under; with ``--exact`` the optimal strategy under that shield, as ``rac verify --exact``
    computes it), and the seed; or None and why (None and "" after printing a usage error)."""
    # numpy, rac.check.analysis, stormpy (via rac.verify.runner): only the command that uses it loads it
    from rac.verify.runner import VerifyOptions, run_queries

    assert result.automaton is not None
    learned = {d.query.name: d for d in result.automaton.queries if isinstance(d.query, iq.LearnStrategy)}
    if args.strategy not in learned:
        _report(args, usage_error(f"no learned strategy `{args.strategy}` in {args.file} (learning queries: "
                                  f"{', '.join(learned) or 'none'})",
                                  hints=["name a `strategy NAME = maxE(...)` or `minE(...)` query of the file"]))
        return None, ""
    # the shield the strategy is learned under covers the drawn run: a --horizon past the file's is its
    # horizon too (as `rac verify --horizon`), else past the file's horizon the run chose among all actions
    longer = args.horizon if args.horizon is not None and args.horizon > Fraction(result.automaton.horizon) else None
    options = VerifyOptions(seed=_seed(args), max_states=args.max_states, only=(learned[args.strategy].name,),
                            horizon=longer,
                            max_bytes=args.max_memory or default_max_bytes(), bars=not (args.quiet or as_json(args)),
                            exact=args.exact)
    context, results = run_queries(result, options)
    if args.strategy not in context.learned:
        reasons = "; ".join(f"{r.name}: {r.message}" for r in results if r.message)
        how = "computed exactly" if args.exact else "learned"
        return None, f"the strategy `{args.strategy}` could not be {how} ({reasons})"
    _, runs = context.learned_run(args.strategy, samples)
    return runs, context.seed  # what --seed reproduces (the learning query's own seed derives from it)


def _how(args: argparse.Namespace) -> str:
    if args.strategy:
        return f"the run under the {'optimal' if args.exact else 'learned'} strategy {args.strategy}"
    return "one run under the shield" if args.shield else "one run"


def _short(args: argparse.Namespace) -> str:
    """:func:`_how` in a few words, for a plot's title."""
    if args.strategy:
        return f"{'optimal ' if args.exact else ''}strategy {args.strategy}"
    return "shielded" if args.shield else "random actions"


def _horizon_ok(result: CompileResult, args: argparse.Namespace) -> bool:
    """False (after saying why) when ``--horizon`` is not a whole number of samples."""
    try:
        _horizon_samples(result, args.horizon)
    except ValueError as exc:
        _report(args, usage_error(str(exc)))
        return False
    return True


def _explore_bar(quiet: bool):
    """A progress bar and an exploration callback for it; several explorations add up."""

    bar = Progress(desc="exploring", unit="states", enabled=False if quiet else None)
    seen = {"last": 0}

    def callback(layer: int, frontier: int, total: int) -> None:
        if total < seen["last"]:  # a new exploration started: count its states on top
            seen["last"] = 0
        bar.set_postfix(sample=layer, frontier=frontier)
        bar.update(total - seen["last"])
        seen["last"] = total

    return bar, callback


@_on_checked_file
def verify_command(args: argparse.Namespace, result: CompileResult) -> int:
    # numpy, rac.check.analysis (via rac.verify.penalties): only the command that uses it loads it
    from rac.verify.penalties import check_penalties, render_penalties

    # numpy, rac.check.analysis, stormpy (via rac.verify.runner): only the command that uses it loads it
    from rac.verify.runner import UnknownQuery, VerifyOptions, render_json, render_text, run_queries

    out_dir = _out_dir(args)
    quiet = args.quiet or args.format == "json"
    bar, callback = _explore_bar(quiet)
    shown = _announcer(quiet)
    doing: list[str] = []  # what runs now: said when Ctrl-C stops it

    def announce(message: str) -> None:
        doing[:] = [message]
        shown(message)

    seed = _seed(args)
    options = VerifyOptions(horizon=args.horizon, max_states=args.max_states, seed=seed, epsilon=args.epsilon,
                            max_bytes=args.max_memory or default_max_bytes(),
                            confidence=args.confidence, out_dir=out_dir, standard=args.standard,
                            only=tuple(args.query) if args.query else None, plots=not args.no_plots,
                            progress=announce, explore_progress=callback, learn_episodes=args.learn_episodes,
                            bars=not quiet, exact=args.exact, max_seconds=args.max_seconds)
    results: list[QueryResult] = []  # filled as each query is answered: Ctrl-C still shows those
    penalties = None
    stopped: str | None = None
    write_failed: Diagnostic | None = None  # E0009 of a query's file: the queries before it are shown
    try:
        with bar, interrupts_as_such():
            context, results = run_queries(result, options, answered=results)
            # The check explores a product of its own (seconds on a real scene): a run of chosen
            # queries (--query) asks for those answers only.
            if not args.query:
                announce("penalties that no action avoids")
                penalties = check_penalties(context)
    except KeyboardInterrupt:  # the answers found stand (their files are written): shown, then exit 130
        stopped = doing[0] if doing else "the queries"
    except UnknownQuery as exc:
        assert result.automaton is not None  # _load refused a file without one
        names = ", ".join(d.name for d in result.automaton.queries)
        _report(args, usage_error(f"--query: no query named {exc.args[0]} in {args.file}",
                                  notes=[f"its queries: {names or 'none'}; --standard adds Qa, Qb, Qc, Qd, Fig7, "
                                         "Fig7_safe, Unsafe_safe"]))
        return EXIT_USAGE
    except OSError as exc:
        failed = unwritable(_written(out_dir, exc), exc)
        if not results:  # nothing answered to show: the error alone
            _report(args, failed)
            return EXIT_USAGE
        # a full disk at a later query's files: the answers found before stand (their files are written),
        # shown as after Ctrl-C, then the error (exit 2); they were dropped with it
        write_failed, stopped = failed, doing[0] if doing else "the queries"
    except MemoryError as exc:
        # memory that ran out outside a query's own answer (the penalty check after them, with the queries'
        # graphs still held) or a budget's refusal: the answers found stand, shown before the error (exit 2,
        # as rac's other resource limits); rac.cli.main's report of it dropped them all
        failed = resource_limit(f"resource limit: {exc}" if isinstance(exc, RacError)
                                else out_of_memory(exc, "rac verify"))
        if not results:
            _report(args, failed)
            return EXIT_USAGE
        write_failed, stopped = failed, doing[0] if doing else "the queries"
    # the exit status, decided before the document that carries it as `ok`
    status = verdict_status(results) if stopped is None else EXIT_USAGE if write_failed is not None \
        else EXIT_INTERRUPTED
    if args.format == "json":
        document: dict[str, object] = {"file": str(args.file), "seed": seed, "warnings": _warnings(result),
                                       "results": render_json(results),
                                       "penalties": penalties.to_json() if penalties is not None else None}
        if stopped is not None:
            document["interrupted"] = stopped
        if write_failed is not None:  # one document: the error in it, not a second one beside it
            document["error"] = write_failed.to_json()
        print(json_text(with_ok(document, status), indent=2))
    else:
        if results:
            print(render_text(results, traces=args.trace))
        if penalties is not None and penalties.diagnostics:  # W1011, rendered like rac check's findings
            print(render_diagnostics(penalties.diagnostics, result.sources))
        if penalties is not None:
            print(render_penalties(penalties))
        if args.seed is None and any(r.seed is not None for r in results):
            # each query prints its own seed, derived from this one: this one reproduces them all
            print(f"rac verify: the random queries drew seed {seed}; `--seed {seed}` reproduces their answers",
                  file=sys.stderr)
    if stopped is not None:
        n = len(results)
        # under --format json the answers and the error are in the document on standard output, not above
        where = "above" if args.format == "text" else "in the JSON document"
        answered = f"{n} {'query' if n == 1 else 'queries'} answered before it {'is' if n == 1 else 'are'} {where}" \
            if n else "no query was answered"
        if write_failed is not None:
            if args.format == "text":
                print_diagnostics([write_failed])
            print(f"rac verify: stopped during {stopped} by the error {where}; {answered}", file=sys.stderr)
        else:
            print(f"rac verify: {how_stopped()} during {stopped}; {answered}", file=sys.stderr)
    elif not results:
        print(f"{args.file}: no queries (add `query NAME: ...` lines, or pass --standard)", file=sys.stderr)
    return status


def verdict_status(results: Sequence[QueryResult]) -> int:
    """``rac verify``'s exit code: a query that does not hold outweighs one that was not decided (a
    query that is not applicable is neither: its failed defining query sets the code)."""

    if any(r.status == NOT_SATISFIED for r in results):
        return EXIT_ERRORS
    if any(r.status in UNDECIDED for r in results):
        return EXIT_UNDECIDED
    return EXIT_OK


def _shield_policy(result: CompileResult, horizon_samples: int, args: argparse.Namespace, runs: int,
                   notes: list[str]):
    """The safety shield (Qd) at this horizon as a simulation policy, or None, an error message and
    the exit code (1 when no safe strategy exists: Qd does not hold). When the exhaustive shield is
    beyond the budget the runs choose under the runtime shield instead
    (:class:`rac.engine.shield.StepShieldPolicy`, which says what it guaranteed), as training does."""
    # numpy, stormpy (via rac.engine.shield): only the command that uses it loads it
    from rac.engine import shield as shields

    # numpy (via rac.engine.lookahead): only the command that uses it loads it
    from rac.engine.lookahead import GUARD_SECONDS, NODE_BUDGET, LookaheadSettings

    # numpy, stormpy (via rac.verify.context): only the command that uses it loads it
    from rac.verify.context import over_budget

    assert result.model_data is not None
    bar, callback = _explore_bar(args.quiet or as_json(args))
    try:
        with bar:
            computed, table = shields.synthesise(result.model_data, horizon_samples, max_states=args.max_states,
                                                 max_bytes=args.max_memory or default_max_bytes(),
                                                 progress=callback)
    except BudgetExceeded as exc:
        # a node budget: the same runs at the same seed on every machine (the time limit only a safety net)
        settings = LookaheadSettings(seconds=GUARD_SECONDS, nodes=NODE_BUDGET)
        fallback = shields.StepShield(result.model_data, horizon_samples, lookahead=settings, reason=over_budget(exc))
        decisions = runs * len(range(0, horizon_samples, int(result.model_data.decide_every)))
        _note(args, notes, f"the exhaustive shield is beyond the budget ({fallback.reason}); the runs choose under "
              f"the runtime shield instead ({decisions:,} decisions, up to {NODE_BUDGET} search nodes each)")
        return shields.StepShieldPolicy(fallback), None, EXIT_OK
    if not computed.shield_exists:
        return None, _no_shield(args.file, computed.graph, float(result.model_data.period), horizon_samples), \
            EXIT_ERRORS
    return table.masks_at, None, EXIT_OK


def _no_shield(file: str, graph: ExploredGraph, period: float, horizon_samples: int) -> str:
    """Why the safety shield (Qd) does not exist, naming the file: the ego unsafe at the start (off the road,
    in a collision), or the last sample some run stays safe until; ``graph``: the shield's pruned graph,
    where a state reached is reached safely."""
    head = (f"no safe strategy exists from the start within the horizon of `{file}` "
            f"({horizon_samples * period:g} s; Qd is not satisfied)")
    start = [what for what, label in (("off the road", "offroad"), ("in a collision", "collide"))
             if graph.labels[label][graph.initial]]
    if start:
        return f"{head}: the ego starts {' and '.join(start)}"
    safe = graph.labels["safe"]
    last = int(graph.states[safe, graph.columns.index("k")].max())
    return f"{head}: the longest any run stays safe is until t = {last * period:g} s"


def _horizon_samples(result: CompileResult, horizon: Fraction | None) -> int:
    """The horizon in samples; :class:`ValueError` when it is not a whole number of them."""
    automaton = result.automaton
    assert automaton is not None
    return samples_of(horizon if horizon is not None else Fraction(automaton.horizon), Fraction(automaton.period))


def _parse_exprs(texts: list[str], automaton):
    """Each ``--expr`` as one checked expression of the query language over the file's automaton,
    or an error message naming it."""

    exprs = []
    for text in texts:
        try:
            exprs.append(lower_expression(automaton, text, name="<--expr>"))
        except ExpressionError as exc:
            if exc.count != 1:
                return None, f"`{text}`: one expression per --expr (repeat --expr for more)"
            return None, str(exc)
        except CheckError as exc:
            return None, f"`{text}`: {exc.brief()}"
    return exprs, None


@_on_checked_file
def simulate_command(args: argparse.Namespace, result: CompileResult) -> int:
    import numpy as np  # numpy: only the command that uses it loads it

    # numpy (via rac.engine.evaluate): only the command that uses it loads it
    from rac.engine.evaluate import EvaluationError

    # numpy, stormpy (via rac.verify.context): only the command that uses it loads it
    from rac.verify.context import Context, VerifyOptions

    # numpy (via rac.verify.report): only the command that uses it loads it
    from rac.verify.report import plot_series, write_runs

    texts = args.expr or ["mindist()", "3 * collision_distance"]
    exprs, problem = _parse_exprs(texts, result.automaton)
    if exprs is None:
        _report(args, usage_error(f"--expr: {problem}"))
        return EXIT_USAGE
    samples = _horizon_samples(result, args.horizon)
    notes: list[str] = []
    runs, seed, status = _shielded_runs(result, args, samples, args.runs, notes)
    if runs is None:
        _report(args, _no_runs(seed, status))
        return status
    context = Context(result, VerifyOptions(seed=args.seed))
    try:
        values = context.values(runs, tuple(exprs))
    except EvaluationError as exc:
        _report(args, usage_error(f"--expr: {exc}"))
        return EXIT_USAGE
    stopped = _stopped_runs(result, runs, "runs.csv and runs.png hold each up to its stop")
    if stopped is not None:  # from its stop on a run's states are not the model's: no values there
        assert runs.overflow is not None
        after = np.arange(samples + 1)[None, :] >= runs.overflow[:, None]
        values = [np.where(after, np.nan, column) for column in values]
    out_dir = _out_dir(args)
    csv_path, png_path = out_dir / "runs.csv", out_dir / "runs.png"
    try:
        out_dir.mkdir(parents=True, exist_ok=True)
        # no count here: the plot adds it ("3 runs", "2 of 3 runs below ..."), which read "1 run (seed 1): 1 run"
        title = f"{args.file.name}{', under the shield' if args.shield else ''}, seed {seed}"
        # the pair renamed together at the end: Ctrl-C while plotting keeps the previous run's pair
        write_runs(csv_path, runs.times, texts, values, lambda: plot_series(png_path, runs.times, texts, values,
                                                                            title, exprs), ends=runs.overflow)
    except OSError as exc:
        _report(args, unwritable(_written(out_dir, exc), exc))
        return EXIT_USAGE
    under = " under the shield" if args.shield else ""
    lines = [f"simulated {counted(args.runs, 'run')} of {counted(samples, 'sample')} (seed {seed}){under}"]
    document: dict[str, object] = {"file": str(args.file), "warnings": _warnings(result), "runs": args.runs,
                                   "samples": samples, "seed": seed, "shield": bool(args.shield), "expressions": texts}
    if result.automaton is not None and result.automaton.ending is not None:
        _note(args, notes, "the runs go on to the horizon; the automaton's `episode ends when`, which ends them in "
                           "the emitted model, is not applied here")
    if len(values) == 2 and np.nanmax(values[1]) == np.nanmin(values[1]):  # NaN: a stopped run's samples after it
        below = int(np.any(values[0] < values[1], axis=1).sum())
        verb = "goes" if args.runs == 1 else "go"
        threshold = float(np.nanmax(values[1]))
        lines.append(f"{below} of {counted(args.runs, 'run')} {verb} below {texts[1]} = {threshold:g}")
        document["runs_below"] = below
    if np.all((values[0] == NO_OBSTACLE) | np.isnan(values[0])):  # mindist() without an obstacle: not "1e9 m"
        assert result.model_data is not None
        none = "the scenario has none" if result.model_data.obstacle_count == 0 else "none within the horizon"
        _note(args, notes, f"no obstacle at any sample ({none}): `{texts[0]}` reads {NO_OBSTACLE_TEXT}, its value "
                           "without one")
    left = int(runs.left_policy.sum())
    document["runs_left_policy"] = left
    if left:
        guarded = result.model_data is not None and result.model_data.allow is not None
        who = "the shield or the model's `allow when`" if args.shield and guarded else \
            "the model's `allow when`" if guarded else "the shield"
        lines.append(f"{counted(left, 'run')} met a state where {who} allowed nothing and continued with every action")
    document["notes"], document["wrote"] = notes, [str(csv_path), str(png_path)]
    return _summary_and_stop(args, document, [*lines, f"wrote {csv_path}", f"wrote {png_path}"], stopped, result)


def _summary_and_stop(args: argparse.Namespace, document: dict[str, object], lines: Sequence[str],
                      stopped: Diagnostic | None, result: CompileResult) -> int:
    """The command's summary (:func:`_print_summary`), then the E0015 of its stopped runs (``stopped``: in the JSON
    document's ``"error"``, one document), and the exit code: 1 when a run stopped, else 0."""
    status = EXIT_OK if stopped is None else EXIT_ERRORS
    if stopped is not None and as_json(args):
        document["error"] = stopped.to_json()
    _print_summary(args, with_ok(document, status), lines)
    if stopped is not None and not as_json(args):
        print_diagnostics([stopped], result.sources)
    return status


def _first_sample(held: Sequence[bool]) -> int | None:
    """The first sample at which ``held`` is true; None when it never is."""
    return next((sample for sample, value in enumerate(held) if value), None)


@_on_checked_file
def render_command(args: argparse.Namespace, result: CompileResult) -> int:
    # numpy (via rac.engine.simulate): only the command that uses it loads it
    from rac.engine.simulate import label_runs

    # PIL, matplotlib, numpy (via rac.output.render): only the command that uses it loads it
    from rac.output.render import RenderError, render_trajectory

    samples = _horizon_samples(result, args.horizon)
    notes: list[str] = []
    if args.exact and args.strategy is None:
        _report(args, usage_error("--exact draws a file's learning query's optimal strategy: give --strategy NAME"))
        return EXIT_USAGE
    if args.strategy is not None:  # `--strategy ""` names no strategy: said, not a random run drawn
        runs, seed = _strategy_run(result, args, samples)
        status = EXIT_ERRORS if seed else EXIT_USAGE  # "": _strategy_run has said why (a usage error)
    else:
        runs, seed, status = _shielded_runs(result, args, samples, 1, notes)
    if runs is None:
        if seed:
            _report(args, _no_runs(seed, status))
        return status
    real = runs.sensed_real()[0]
    stopped = _stopped_runs(result, runs, "the picture shows the run up to there")
    if stopped is not None and runs.overflow is not None:  # it stopped where its sensed state left int32: drawn so far
        real = real[:int(runs.overflow[0])]
    trajectory = real[:, [Ego.X, Ego.Y, Ego.HEAD]]
    assert result.model_data is not None  # _load refused a file without one
    # where the run first collides and first leaves the road, as collide() and offroad() judge it: marked on the path
    first = {label: _first_sample(label_runs(result.model_data, runs, label)[0][:len(real)])
             for label in ("collide", "offroad")}
    out_dir = _out_dir(args)
    png, gif = out_dir / "run.png", out_dir / "run.gif" if args.gif else None
    automaton = result.automaton
    assert automaton is not None and automaton.model is not None  # _load refused a file without them
    spec = automaton.model
    marked: dict[str, float] = {}  # the marks' times, as the picture's legend gives them
    try:
        out_dir.mkdir(parents=True, exist_ok=True)
        written = render_trajectory(spec.scenario_path, trajectory, png, gif_path=gif,
                                    planning_problem=spec.planning_problem or None,
                                    sample_period=float(automaton.period),
                                    length=float(spec.length), width=float(spec.width),
                                    title=f"{args.file.name}, {_short(args)}, seed {seed}",
                                    collision=first["collide"], offroad=first["offroad"], marked=marked)
    except RenderError as exc:
        _report(args, unusable_file(str(exc)))
        return EXIT_ERRORS
    except OSError as exc:
        _report(args, unwritable(_written(out_dir, exc), exc))
        return EXIT_USAGE
    if automaton.ending is not None and args.strategy is None:
        _note(args, notes, "the run goes on to the horizon; the automaton's `episode ends when`, which ends it in "
                           "the emitted model, is not applied here")
    dt = Fraction(repr(result.scenario.dt)) if result.scenario is not None else None
    if dt is not None and (Fraction(automaton.period) / dt).denominator != 1:
        # commonroad-io draws an obstacle at a time step only: the picture and the model part by up to dt/2
        _note(args, notes, f"the scenario's time step ({float(dt):g} s) does not divide the sampling period "
                           f"({float(automaton.period):g} s): the picture draws the obstacles at the nearest "
                           f"CommonRoad time step, up to {float(dt / 2):g} s from the ego's sample (the model "
                           "moves them on in a straight line between steps: docs/model.md)")
    wrote = [str(written), *([str(gif)] if gif is not None else [])]
    document: dict[str, object] = {"file": str(args.file), "warnings": _warnings(result), "how": _how(args),
                                   "samples": samples, "seed": seed,
                                   "first_collision": marked.get("collision"), "first_offroad": marked.get("offroad"),
                                   "notes": notes, "wrote": wrote}
    drawn = f"{samples} samples" if len(real) == samples + 1 else f"{len(real) - 1} of {samples} samples"
    events = [f"{what} at t = {marked[kind]:g} s" for kind, what in (("collision", "first collision"),
                                                                    ("offroad", "first off-road sample"))
              if kind in marked]
    said = "; ".join(events) if events else "no collision, never off the road"
    return _summary_and_stop(args, document, [f"rendered {_how(args)}: {drawn} (seed {seed})", f"the run: {said}",
                                              *(f"wrote {path}" for path in wrote)], stopped, result)


@_on_checked_file
def preanalyse_command(args: argparse.Namespace, result: CompileResult) -> int:
    # numpy, scipy, stormpy (via rac.studies.preanalysis): only the command that uses it loads it
    from rac.studies.preanalysis import SweepError, answered, render_table, sweep

    out_dir = _out_dir(args)
    done: list[dict[str, object]] = []  # each setting's row as it is found: Ctrl-C still shows those
    removed: list[Path] = []  # an earlier run's plots, removed as this one started
    interrupted = False
    write_failed: Diagnostic | None = None  # E0009 of a plot: the settings finished before it are shown
    try:
        with interrupts_as_such():
            rows = sweep(result, exponents=args.exponent, senses=args.sense, decides=args.decide, runs=args.runs,
                         horizon=args.horizon, seed=args.seed, max_states=args.max_states, out_dir=out_dir,
                         max_bytes=args.max_memory or default_max_bytes(),
                         threshold_factor=args.threshold_factor, max_seconds=args.max_seconds,
                         quiet=args.quiet or args.format == "json", done=done, removed=removed)
    except KeyboardInterrupt:  # the settings finished stand (their plots are written): shown, then exit 130
        rows, interrupted = done, True
    except SweepError as exc:
        _report(args, usage_error(str(exc)))
        return EXIT_USAGE
    except OSError as exc:  # the plots' folder: a file, under a file, too long a name, no permission, a full disk
        failed = unwritable(_written(out_dir, exc), exc)
        if not done:  # no setting finished: the error alone
            _report(args, failed)
            return EXIT_USAGE
        # the settings finished before it stand (their plots are written): shown as after Ctrl-C, then the error
        rows, write_failed = done, failed
    if rows:  # a setting ran, so the sweep checked --horizon: past the recorded traffic, its runs end on an empty road
        result = _horizon_warnings(result, args, goal=False)
    # an earlier run's plots this run did not draw again: said, where they were left beside this run's as if its own
    gone = [path for path in removed if not path.exists()]
    # how far each setting is answered (not the sweep plot's entry): a row that lost some answers is not "not answered"
    extent = [answered(row) for row in rows if "exponent" in row]
    partly, unanswered = extent.count("partly"), extent.count("not")
    # the exit status, decided before the document that carries it as `ok`; a setting without all its answers
    # is undecided, which never exits 0
    status = EXIT_USAGE if write_failed is not None else EXIT_INTERRUPTED if interrupted \
        else EXIT_UNDECIDED if partly or unanswered else EXIT_OK
    if args.format == "json":
        document: dict[str, object] = {"file": str(args.file), "warnings": _warnings(result), "settings": rows,
                                       "answered": {how: extent.count(how) for how in ("fully", "partly", "not")}}
        if gone:
            document["removed"] = [str(path) for path in gone]
        if interrupted:
            document["interrupted"] = True
        if write_failed is not None:  # one document: the error in it
            document["error"] = write_failed.to_json()
        print(json_text(with_ok(document, status), indent=2, default=str))
    elif rows or not interrupted:
        print(render_table(rows))
        if any("plot" in row or "sweep_plot" in row for row in rows):  # no setting answered: no plot, maybe no folder
            print(f"\nplots in {out_dir}")
    if gone:
        print(f"rac preanalyse: removed {_earlier_plots(gone, out_dir)}", file=sys.stderr)
    # under --format json the rows and the error are in the document on standard output, not above
    where = "above" if args.format == "text" else "in the JSON document"
    if write_failed is not None:
        if args.format == "text":
            print_diagnostics([write_failed])
        n = len(rows)
        print(f"rac preanalyse: stopped by the error {where}; {counted(n, 'setting')} finished before "
              f"it ({where})", file=sys.stderr)
    elif interrupted:
        n = len(rows)
        print(f"rac preanalyse: {how_stopped()}; {counted(n, 'setting')} finished before it "
              f"({where if n else 'none'})", file=sys.stderr)
    elif status == EXIT_UNDECIDED:
        late = sum(1 for row in rows if "time_limit" in row)
        why = f"; {late} given up past --max-seconds {args.max_seconds:g}" if late else ""
        if not partly:
            how = "were not answered"
        elif not unanswered:
            how = "were answered only in part"
        else:
            how = f"were not answered in full ({partly} in part, {unanswered} not at all)"
        print(f"rac preanalyse: {partly + unanswered} of {len(extent)} settings {how} (their rows say why{why})",
              file=sys.stderr)
    return status


def _earlier_plots(gone: list[Path], out_dir: Path) -> str:
    """What the note on an earlier run's plots removed (``gone``, from ``out_dir``) says after "removed"."""
    if len(gone) == 1:
        return f"{gone[0]}, an earlier run's plot of settings or runs this run did not draw"
    names = ", ".join(path.name for path in gone[:5]) + (f" and {len(gone) - 5} more" if len(gone) > 5 else "")
    return f"{len(gone)} plots of an earlier run from {out_dir}, of settings or runs this run did not draw: {names}"


@_on_checked_file
def experiment_command(args: argparse.Namespace, result: CompileResult) -> int:
    # numpy (via rac.studies.experiment): only the command that uses it loads it
    from rac.studies.experiment import (
        ExperimentError,
        goal_out_of_reach,
        render_ablation,
        render_markdown,
        results_json,
        run_experiment,
        write_outputs,
    )

    if args.seed is not None and args.seeds is not None:
        _report(args, usage_error("give --seeds LIST or --seed N (one seed), not both"))
        return EXIT_USAGE
    # --seed and --seeds are parsed as seeds (rac.cli.arguments.seed_argument)
    seeds = list(args.seeds) if args.seeds is not None else [args.seed] if args.seed is not None else [1, 2, 3, 4, 5]
    if args.replay < 0:
        _report(args, usage_error(f"--replay must be 0 or more, not {args.replay}"))
        return EXIT_USAGE
    bins = None
    if args.bins is not None:  # `--bins ""` is a list of no widths: refused, not the derived bins learned
        try:
            bins = [float(b) for b in args.bins.split(",")]
        except ValueError:
            _report(args, usage_error(f"--bins: not a list of numbers: {args.bins!r}"))
            return EXIT_USAGE
    out_dir = _out_dir(args)
    shown = _announcer(args.quiet)
    # the shield's exploration counts its states, as rac verify's do (a bar; off a terminal, the heartbeat)
    bar, callback = _explore_bar(args.quiet)

    def announce(message: str) -> None:
        if bar.n:  # the shield's exploration is over: its bar would sit still under the learning's lines
            bar.close()
        shown(message)

    try:
        with bar:
            report = run_experiment(result, seeds=seeds, episodes=args.episodes, evaluation_runs=args.runs,
                                    reward_function=args.reward_function,
                                    horizon_samples=_horizon_samples(result, args.horizon) if args.horizon else None,
                                    max_states=args.max_states, combinations=args.combination, bins=bins,
                                    counterfactuals=not args.no_counterfactuals, replay=args.replay,
                                    ablation=args.ablation, observe_time=not args.no_time,
                                    max_bytes=args.max_memory or default_max_bytes(), progress=announce,
                                    explore_progress=callback, explore=args.explore)
    except ExperimentError as exc:
        # an option to change or a budget, as simulate's; the file's own failure (no safe strategy), with
        # its source line when it points into the file
        _report(args, exc.diagnostic if exc.diagnostic is not None else usage_error(str(exc)) if exc.kind == "usage"
                else resource_limit(f"resource limit: {exc}") if exc.kind == "limit" else unusable_file(str(exc)),
                result.sources)
        return EXIT_USAGE if exc.kind in ("usage", "limit") else EXIT_ERRORS
    if report.get("interrupted"):  # the study sees a KeyboardInterrupt either way; which signal it was, the CLI knows
        report = {**report, "stopped_by": stopping_signal()}
    # the file's warnings bear on the results; JSON drops them from standard error (_load): the document has them
    warnings = {"warnings": _warnings(result)}

    def unwritten(extra: dict[str, object], status: int) -> int:
        """The results that were not written, shown: one JSON document with ``extra`` in it, or the tables;
        returns ``status``, the exit status the document's ``ok`` says."""
        if args.format == "json":
            print(json_text(with_ok({**json.loads(results_json(report)), **warnings, **extra}, status), indent=1))
        else:
            print(render_markdown(report))
            if report.get("ablation"):
                print()
                print(render_ablation(report))
        return status

    try:
        files = write_outputs(report, out_dir)
    except KeyboardInterrupt:
        # Ctrl-C or SIGTERM while the files were made (the plots take seconds): none of them changed, and what
        # was learned (minutes to hours) is shown all the same; it was dropped with a bare "rac: interrupted"
        status = unwritten({"interrupted": report.get("interrupted") or "writing"}, EXIT_INTERRUPTED)
        print(f"rac experiment: {how_stopped()} while writing the results above; none of the files in {out_dir} "
              "changed", file=sys.stderr)
        return status
    except OSError as exc:
        # a full disk, a folder in the way: what was learned (minutes to hours) is shown all the same, then
        # the error; it was dropped with it
        failed = unwritable(_written(out_dir, exc), exc)
        # with --format json one document: the results and the error
        status = unwritten({"error": failed.to_json()}, EXIT_USAGE)
        if args.format != "json":
            print_diagnostics([failed])
        print("rac experiment: the results above were not all written (the error above)", file=sys.stderr)
        return status
    # the exit status, decided before the document that carries it as `ok`. Ctrl-C: what was learned is shown
    # and written, and the exit code says it was cut short; a table every row of which must fail is the file's
    # finding, as `no safe strategy` is (exit 1): exit 0 said the experiment had measured something
    unreachable = None if report.get("interrupted") else goal_out_of_reach(report)
    status = EXIT_INTERRUPTED if report.get("interrupted") else EXIT_ERRORS if unreachable is not None else EXIT_OK
    if args.format == "json":  # results.json, with the file's warnings and the files written, as simulate's `wrote`
        document = json.loads((out_dir / "results.json").read_text(encoding="utf-8"))
        print(json_text(with_ok({**document, **warnings, "wrote": [str(path) for path in files]}, status), indent=1))
    else:
        print(render_markdown(report))
        print()
        if report.get("ablation"):
            print(render_ablation(report))
            print()
        for path in files:
            print(f"wrote {path}")
    if unreachable is not None:
        print(f"rac experiment: {unreachable}; the results above are written all the same", file=sys.stderr)
    return status


