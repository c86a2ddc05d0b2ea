"""The engine commands of ``rac``: ``verify``, ``simulate``, ``render`` and ``preanalyse``.

They share the conventions of :mod:`rac.cli.common`: exit 0 when everything asked holds, 1 when a query is
not satisfied or the file has errors, 2 for bad usage or unreadable/unwritable files, 4 when a query
was not decided (``verify``: *unknown* or *unsupported*, and none not satisfied).
"""

from __future__ import annotations

import argparse
import functools
import json
import sys
from collections.abc import Callable, Sequence
from fractions import Fraction
from pathlib import Path
from typing import TYPE_CHECKING, TypeVar

from rac.cli.common import (
    EXIT_ERRORS,
    EXIT_OK,
    EXIT_UNDECIDED,
    EXIT_USAGE,
    OUTPUT_CONVENTION,
    OUTPUT_SUFFIX,
    output_folder,
    read_and_check,
    size_argument,
)
from rac.compiler import CompileResult
from rac.core.diagnostics import render_text as render_diagnostics

if TYPE_CHECKING:
    from rac.verify.report import QueryResult

#: A sub-command: its parsed arguments -> the exit code.
Command = Callable[[argparse.Namespace], int]
T = TypeVar("T")


def _argument(convert: Callable[[str], T], kind: str, accepts: Callable[[T], bool], need: str) -> Callable[[str], T]:
    """An argparse ``type``: ``convert(text)``, refused with "not KIND" when it cannot convert and
    with ``need`` when the value is not ``accepts``-ed."""

    def parse(text: str) -> T:
        try:
            value = convert(text)
        except (ValueError, ZeroDivisionError):  # Fraction("1/0") divides by zero
            raise argparse.ArgumentTypeError(f"not {kind}: {text!r}") from None
        if not accepts(value):
            raise argparse.ArgumentTypeError(f"{need}: {text!r}")
        return value

    return parse


_fraction = _argument(Fraction, "a number", lambda value: value > 0, "must be positive")
_positive_int = _argument(int, "a whole number", lambda value: value >= 1, "must be at least 1")
_probability = _argument(float, "a number", lambda value: 0 < value < 1, "must lie strictly between 0 and 1")


def _common(parser: argparse.ArgumentParser, outputs: str) -> None:
    """The options every engine command has; ``outputs`` says what goes into its output folder."""
    parser.add_argument("file", type=Path, metavar="FILE", help="a .ra file with a `model` block")
    parser.add_argument("-o", "--out", type=Path, metavar="DIR",
                        help=f"where {outputs} go (default: FILE{OUTPUT_SUFFIX}/{parser.prog.split()[-1]}/ "
                             "beside the file)")
    parser.add_argument("--horizon", type=_fraction, metavar="SECONDS",
                        help="horizon of exhaustive exploration (default: the automaton's `horizon`)")
    parser.add_argument("--seed", type=int, help="seed of the simulations (default: fresh, printed)")
    parser.add_argument("--max-states", type=_positive_int, default=5_000_000, metavar="N",
                        help="give up (verdict unknown) beyond this many states (default 5,000,000)")
    parser.add_argument("--max-memory", type=size_argument, default=None, metavar="SIZE",
                        help="give up (verdict unknown) before deciding would need more memory than this, "
                             "e.g. 4G (default: half the machine's memory)")
    parser.add_argument("-q", "--quiet", action="store_true", help="no progress bars")


def add_parsers(commands: argparse._SubParsersAction) -> None:
    """Add ``verify``, ``simulate``, ``render`` and ``preanalyse`` to ``rac``'s sub-commands."""
    verify = commands.add_parser("verify", help="answer the file's queries with the native engine (Storm)",
                                 epilog=OUTPUT_CONVENTION)
    _common(verify, "strategies, CSV files and plots (--standard's in standard/)")
    verify.add_argument("--query", action="append", metavar="NAME", help="only this query (repeatable)")
    verify.add_argument("--standard", action="store_true",
                        help="also answer the paper's pre-analysis queries Qa-Qd and the Fig. 7 simulations")
    verify.add_argument("--epsilon", type=_probability, default=0.05,
                        help="half-width of probability intervals (UPPAAL's -E, default 0.05)")
    verify.add_argument("--confidence", type=_probability, default=0.95, help="confidence of intervals (0.95)")
    verify.add_argument("--no-plots", action="store_true", help="no PNG plots for simulate queries")
    verify.add_argument("--trace", action="store_true", help="print whole traces")
    verify.add_argument("--learn-episodes", type=_positive_int, default=1000, metavar="N",
                        help="episode budget of learning queries (maxE/minE; default 1000)")
    verify.add_argument("--exact", action="store_true",
                        help="learning queries: emit the exact optimal strategy under the shield instead of "
                             "learning one (a backward pass over the shielded decision graph)")
    verify.add_argument("--format", choices=("text", "json"), default="text", help="output format")

    simulate = commands.add_parser("simulate", help="simulate runs; write CSV and the paper's Fig. 7 plot",
                                   epilog=OUTPUT_CONVENTION)
    _common(simulate, "runs.csv and runs.png")
    simulate.add_argument("--runs", type=_positive_int, default=100, help="number of runs (default 100)")
    simulate.add_argument("--expr", action="append", metavar="EXPR",
                          help="what to record per sample (default: mindist() and 3 * collision_distance)")
    simulate.add_argument("--shield", action="store_true",
                          help="choose actions under the safety shield (computed first, like Qd)")

    render = commands.add_parser("render", help="draw the scenario with a simulated trajectory (PNG, GIF)",
                                 epilog=OUTPUT_CONVENTION)
    _common(render, "run.png (and run.gif)")
    how = render.add_mutually_exclusive_group()
    how.add_argument("--shield", action="store_true", help="drive under the safety shield (random allowed actions)")
    how.add_argument("--strategy", metavar="NAME",
                     help="drive the file's learned strategy NAME (learned first, like rac verify does)")
    render.add_argument("--gif", action="store_true", help="also write an animated GIF, run.gif")

    pre = commands.add_parser("preanalyse", help="sweep number representation and periods: Qa-Qd per setting",
                              epilog=OUTPUT_CONVENTION)
    _common(pre, "the plots")
    pre.add_argument("--exponent", default=None, metavar="LIST", help="exponents, e.g. 1,2,4")
    pre.add_argument("--sense", default=None, metavar="LIST", help="sensing periods C1 in seconds, e.g. 0.1,0.2")
    pre.add_argument("--decide", default=None, metavar="LIST", help="decision periods C2 in seconds, e.g. 0.2,0.4")
    pre.add_argument("--runs", type=_positive_int, default=100, help="simulated runs per setting (default 100)")
    pre.add_argument("--threshold-factor", type=_positive_int, default=1, metavar="K",
                     help="a run is unsafe when its true distance drops below K * collision_distance (default 1)")
    pre.add_argument("--format", choices=("text", "json"), default="text", help="output format")

    exp = commands.add_parser("experiment", help="the paper's Table 2: learning with/without shield, automaton "
                                                 "or reward function, over seeds", epilog=OUTPUT_CONVENTION)
    _common(exp, "the table, JSON and plots")
    exp.add_argument("--seeds", metavar="LIST", help="seeds, e.g. 1,2,3 (default 1..5; --seed N is --seeds N)")
    exp.add_argument("--episodes", type=_positive_int, default=500, help="episode budget per run (default 500)")
    exp.add_argument("--runs", type=_positive_int, default=100, help="evaluation runs per strategy (default 100)")
    exp.add_argument("--reward-function", metavar="EXPR",
                     help="per-sample reward of the RF combinations (default: the paper's Eq. 9)")
    exp.add_argument("--bins", metavar="LIST",
                     help="widths of the continuous observations, e.g. 4,4,2,0.4 (default: derived from the model's "
                          "action grid and goal, docs/learning.md)")
    exp.add_argument("--no-counterfactuals", action="store_true",
                     help="the RA combinations learn from their own transitions only (default: also from every "
                          "automaton location's counterfactual)")
    exp.add_argument("--no-time", action="store_true",
                     help="observe only the file's discrete list (default: also the decision time, docs/learning.md)")
    exp.add_argument("--replay", type=int, default=1, metavar="N",
                     help="backward replays of each batch of episodes (default 1; 0: none)")
    exp.add_argument("--ablation", action="store_true",
                     help="also learn SS&RA with other bins, counterfactuals, replay, time and the learner switched "
                          "(ablation.md)")
    exp.add_argument("--combination", action="append", choices=("SS&RA", "SS&RF", "RA", "RF"),
                     help="only this combination (repeatable)")
    exp.add_argument("--format", choices=("text", "json"), default="text", help="output format")


def _load(path: Path, max_bytes: int | None) -> tuple[CompileResult | None, int]:
    result, problem = read_and_check(path, max_bytes)
    if result is None:
        assert problem is not None
        print(render_diagnostics([problem], {}), file=sys.stderr)
        return None, EXIT_USAGE
    errors = [d for d in result.diagnostics if d.is_error]
    if errors:
        print(render_diagnostics(result.diagnostics, result.sources), file=sys.stderr)
        return None, EXIT_ERRORS
    if result.automaton is None or result.automaton.model is None:
        print(f"{path}: this automaton has no `model` block; the engine answers queries on a scenario model "
              "(docs/language.md, 'The model block')", file=sys.stderr)
        return None, EXIT_ERRORS
    if result.model_data is None:
        print(f"{path}: the scenario model could not be built (see `rac check {path}`)", file=sys.stderr)
        return None, EXIT_ERRORS
    return result, EXIT_OK


def _prepare(args: argparse.Namespace) -> tuple[CompileResult | None, int]:
    """The checked file with a model (or None and the exit code, after saying why); ``--horizon``
    must be a whole number of samples (the sweep checks its own periods)."""
    from rac.engine.budget import default_max_bytes

    result, status = _load(args.file, args.max_memory or default_max_bytes())
    if result is not None and args.command != "preanalyse" and not _horizon_ok(result, args):
        return None, EXIT_USAGE
    return result, status


def _on_checked_file(command: Callable[[argparse.Namespace, CompileResult], int]) -> Command:
    """A command run as ``command(args, result)`` on ``args.file`` checked, with a model (:func:`_prepare`);
    when the file cannot be used, :func:`_prepare` said why and its exit code is the command's."""

    @functools.wraps(command)
    def run(args: argparse.Namespace) -> int:
        from rac.output.progress import Heartbeat

        # off a terminal (CI logs, pipes) a long command says what it does every few seconds, from the
        # scenario's load on
        with Heartbeat(f"rac {args.command}", enabled=False if args.quiet else None):
            result, status = _prepare(args)
            if result is None:
                return status
            return command(args, result)

    return run


def _announcer(quiet: bool) -> Callable[[str], None]:
    """``announce(message)``: a line on a terminal (unless ``quiet``), and the phase of the active heartbeat."""
    from rac.output.progress import Heartbeat

    def announce(message: str) -> None:
        if Heartbeat.active is not None:  # printed only off a terminal, and not with -q
            Heartbeat.active.phase(message)
        if not quiet and sys.stderr.isatty():
            print(f"… {message}", file=sys.stderr)

    return announce


def _shielded_runs(result: CompileResult, args: argparse.Namespace, samples: int, n: int):
    """``n`` simulated runs (under the safety shield with ``--shield``) and their seed, or None and
    the reason when no shield can be used."""
    import numpy as np

    from rac.engine.simulate import simulate

    policy = None
    if args.shield:
        policy, problem = _shield_policy(result, samples, args)
        if policy is None:
            return None, problem
    seed = args.seed if args.seed is not None else int(np.random.SeedSequence().generate_state(1)[0])
    assert result.model_data is not None  # _load refused a file without one
    return simulate(result.model_data, runs=n, horizon_samples=samples, seed=seed, policy=policy), seed


def _strategy_run(result: CompileResult, args: argparse.Namespace, samples: int):
    """The one run of the file's learned strategy ``args.strategy`` (learned now, with the shield it
    is learned under), and the seed; or None and why (None and "" after printing a usage error)."""
    from rac.engine.budget import default_max_bytes
    from rac.ir import query as iq
    from rac.verify.runner import VerifyOptions, run_queries

    assert result.automaton is not None
    learned = {d.query.name: d for d in result.automaton.queries if isinstance(d.query, iq.LearnStrategy)}
    if args.strategy not in learned:
        print(f"rac render: no learned strategy `{args.strategy}` in {args.file} (learning queries: "
              f"{', '.join(learned) or 'none'})", file=sys.stderr)
        return None, ""
    options = VerifyOptions(seed=args.seed, max_states=args.max_states, only=(learned[args.strategy].name,),
                            max_bytes=args.max_memory or default_max_bytes(), bars=not args.quiet)
    context, results = run_queries(result, options)
    if args.strategy not in context.learned:
        reasons = "; ".join(f"{r.name}: {r.message}" for r in results if r.message)
        return None, f"the strategy `{args.strategy}` could not be learned ({reasons})"
    _, runs = context.learned_run(args.strategy, samples)
    return runs, context.seed  # what --seed reproduces (the learning query's own seed derives from it)


def _how(args: argparse.Namespace) -> str:
    if args.strategy:
        return f"the run under the learned strategy {args.strategy}"
    return "one run under the shield" if args.shield else "one run"


def _short(args: argparse.Namespace) -> str:
    """:func:`_how` in a few words, for a plot's title."""
    if args.strategy:
        return f"strategy {args.strategy}"
    return "shielded" if args.shield else "random actions"


def _horizon_ok(result: CompileResult, args: argparse.Namespace) -> bool:
    """False (after saying why) when ``--horizon`` is not a whole number of samples."""
    try:
        _horizon_samples(result, args.horizon)
    except ValueError as exc:
        print(f"rac {args.command}: {exc}", file=sys.stderr)
        return False
    return True


def _explore_bar(quiet: bool):
    """A progress bar and an exploration callback for it; several explorations add up."""
    from rac.output.progress import Progress

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
    from rac.engine.budget import default_max_bytes
    from rac.verify.runner import UnknownQuery, VerifyOptions, render_json, render_text, verify

    out_dir = output_folder(args.file, "verify", args.out)
    quiet = args.quiet or args.format == "json"
    bar, callback = _explore_bar(quiet)
    announce = _announcer(quiet)
    options = VerifyOptions(horizon=args.horizon, max_states=args.max_states, seed=args.seed, epsilon=args.epsilon,
                            max_bytes=args.max_memory or default_max_bytes(),
                            confidence=args.confidence, out_dir=out_dir, standard=args.standard,
                            only=tuple(args.query) if args.query else None, plots=not args.no_plots,
                            progress=announce, explore_progress=callback, learn_episodes=args.learn_episodes,
                            bars=not quiet, exact=args.exact)
    try:
        with bar:
            results = verify(result, options)
    except UnknownQuery as exc:
        assert result.automaton is not None  # _load refused a file without one
        names = ", ".join(d.name for d in result.automaton.queries)
        print(f"rac verify: no query named {exc.args[0]} in {args.file} (names: {names or 'none'}; "
              "--standard adds Qa, Qb, Qc, Qd, Fig7, Fig7_safe, Unsafe_safe)", file=sys.stderr)
        return EXIT_USAGE
    except OSError as exc:
        print(f"rac verify: cannot write to {out_dir}: {exc.strerror or exc}", file=sys.stderr)
        return EXIT_USAGE
    if args.format == "json":
        print(json.dumps({"file": str(args.file), "results": render_json(results)}, indent=2))
    else:
        print(render_text(results, traces=args.trace))
    if not results:
        print(f"{args.file}: no queries (add `query NAME: ...` lines, or pass --standard)", file=sys.stderr)
    return verdict_status(results)


def verdict_status(results: Sequence[QueryResult]) -> int:
    """``rac verify``'s exit code: a query that does not hold outweighs one that was not decided (a
    query that is not applicable is neither: its failed defining query sets the code)."""
    from rac.verify.status import NOT_SATISFIED, UNDECIDED

    if any(r.status == NOT_SATISFIED for r in results):
        return EXIT_ERRORS
    if any(r.status in UNDECIDED for r in results):
        return EXIT_UNDECIDED
    return EXIT_OK


def _shield_policy(result: CompileResult, horizon_samples: int, args: argparse.Namespace):
    """The safety shield (Qd) at this horizon as a simulation policy, or an error message."""
    from rac.engine import shield as shields
    from rac.engine.budget import BudgetExceeded, default_max_bytes
    from rac.verify.context import over_budget

    assert result.model_data is not None
    bar, callback = _explore_bar(args.quiet)
    try:
        with bar:
            computed, table = shields.synthesise(result.model_data, horizon_samples, max_states=args.max_states,
                                                 max_bytes=args.max_memory or default_max_bytes(),
                                                 progress=callback)
    except BudgetExceeded as exc:
        return None, f"cannot compute the shield: {over_budget(exc)}"
    if not computed.shield_exists:
        return None, "no safe strategy exists from the start within the horizon (Qd is not satisfied)"
    return table.masks_at, None


def _horizon_samples(result: CompileResult, horizon: Fraction | None) -> int:
    """The horizon in samples; :class:`ValueError` when it is not a whole number of them."""
    automaton = result.automaton
    assert automaton is not None
    seconds = horizon if horizon is not None else Fraction(automaton.horizon)
    samples = seconds / Fraction(automaton.period)
    if samples.denominator != 1:
        raise ValueError(f"--horizon {float(seconds):g} is not a whole number of samples of "
                         f"{float(automaton.period):g} s")
    return int(samples)


def _parse_exprs(texts: list[str], automaton):
    """Each ``--expr`` as one checked expression of the query language over the file's automaton,
    or an error message naming it."""
    from rac.check.queries import lower_expression
    from rac.core.diagnostics import CheckError
    from rac.lang.parser import ExpressionError

    exprs = []
    for text in texts:
        try:
            exprs.append(lower_expression(automaton, text, name="<--expr>"))
        except ExpressionError as exc:
            if exc.count != 1:
                return None, f"`{text}`: one expression per --expr (repeat --expr for more)"
            return None, str(exc)
        except CheckError as exc:
            first = exc.diagnostics[0]
            hint = f" ({first.hints[0]})" if first.hints else ""
            return None, f"`{text}`: {first.message}{hint}"
    return exprs, None


@_on_checked_file
def simulate_command(args: argparse.Namespace, result: CompileResult) -> int:
    import numpy as np

    from rac.engine.evaluate import EvaluationError
    from rac.model.native import NO_OBSTACLE, NO_OBSTACLE_TEXT
    from rac.verify.context import Context, VerifyOptions
    from rac.verify.report import plot_series, write_csv

    texts = args.expr or ["mindist()", "3 * collision_distance"]
    exprs, problem = _parse_exprs(texts, result.automaton)
    if exprs is None:
        print(f"rac simulate: --expr: {problem}", file=sys.stderr)
        return EXIT_USAGE
    samples = _horizon_samples(result, args.horizon)
    runs, seed = _shielded_runs(result, args, samples, args.runs)
    if runs is None:
        print(f"rac simulate: {seed}", file=sys.stderr)
        return EXIT_ERRORS
    context = Context(result, VerifyOptions(seed=args.seed))
    try:
        values = context.values(runs, tuple(exprs))
    except EvaluationError as exc:
        print(f"rac simulate: --expr: {exc}", file=sys.stderr)
        return EXIT_USAGE
    out_dir = output_folder(args.file, "simulate", args.out)
    csv_path, png_path = out_dir / "runs.csv", out_dir / "runs.png"
    try:
        out_dir.mkdir(parents=True, exist_ok=True)
        write_csv(csv_path, runs.times, texts, values)
        title = f"{args.file.name}: {args.runs} runs{' under the shield' if args.shield else ''} (seed {seed})"
        plot_series(png_path, runs.times, texts, values, title, exprs)
    except OSError as exc:
        print(f"rac simulate: cannot write: {exc}", file=sys.stderr)
        return EXIT_USAGE
    print(f"simulated {args.runs} runs of {samples} samples (seed {seed}){' under the shield' if args.shield else ''}")
    if len(values) == 2 and np.ptp(values[1]) == 0:
        below = int(np.any(values[0] < values[1], axis=1).sum())
        print(f"{below} of {args.runs} runs go below {texts[1]} = {float(values[1].flat[0]):g}")
    if np.all(values[0] == NO_OBSTACLE):  # mindist() without an obstacle: say so, not "1e9 m"
        assert result.model_data is not None
        none = "the scenario has none" if result.model_data.obstacle_count == 0 else "none within the horizon"
        print(f"rac simulate: note: no obstacle at any sample ({none}): `{texts[0]}` reads {NO_OBSTACLE_TEXT}, "
              "its value without one", file=sys.stderr)
    left = int(runs.left_policy.sum())
    if left:
        guarded = result.model_data is not None and result.model_data.allow is not None
        who = "the shield or the model's `allow when`" if args.shield and guarded else \
            "the model's `allow when`" if guarded else "the shield"
        print(f"{left} runs met a state where {who} allowed nothing and continued with every action")
    print(f"wrote {csv_path}\nwrote {png_path}")
    return EXIT_OK


@_on_checked_file
def render_command(args: argparse.Namespace, result: CompileResult) -> int:
    from rac.output.render import RenderError, render_trajectory

    samples = _horizon_samples(result, args.horizon)
    if args.strategy:
        runs, seed = _strategy_run(result, args, samples)
    else:
        runs, seed = _shielded_runs(result, args, samples, 1)
    if runs is None:
        print(f"rac render: {seed}", file=sys.stderr)
        return EXIT_ERRORS if seed else EXIT_USAGE
    real = runs.sensed_real()[0]
    trajectory = real[:, [0, 1, 4]]
    out_dir = output_folder(args.file, "render", args.out)
    png, gif = out_dir / "run.png", out_dir / "run.gif" if args.gif else None
    automaton = result.automaton
    assert automaton is not None and automaton.model is not None  # _load refused a file without them
    spec = automaton.model
    try:
        out_dir.mkdir(parents=True, exist_ok=True)
        written = render_trajectory(spec.scenario_path, trajectory, png, gif_path=gif,
                                    planning_problem=spec.planning_problem or None,
                                    sample_period=float(automaton.period),
                                    length=float(spec.length), width=float(spec.width),
                                    title=f"{args.file.name}, {_short(args)}, seed {seed}")
    except RenderError as exc:
        print(f"rac render: {exc}", file=sys.stderr)
        return EXIT_ERRORS
    except OSError as exc:
        print(f"rac render: cannot write: {exc}", file=sys.stderr)
        return EXIT_USAGE
    print(f"rendered {_how(args)}: {samples} samples (seed {seed})")
    print(f"wrote {written}")
    if gif is not None:
        print(f"wrote {gif}")
    return EXIT_OK


@_on_checked_file
def preanalyse_command(args: argparse.Namespace, result: CompileResult) -> int:
    from rac.engine.budget import default_max_bytes
    from rac.studies.preanalysis import SweepError, render_table, sweep

    out_dir = output_folder(args.file, "preanalyse", args.out)
    try:
        rows = sweep(result, exponents=args.exponent, senses=args.sense, decides=args.decide, runs=args.runs,
                     horizon=args.horizon, seed=args.seed, max_states=args.max_states, out_dir=out_dir,
                     max_bytes=args.max_memory or default_max_bytes(),
                     threshold_factor=args.threshold_factor,
                     quiet=args.quiet or args.format == "json")
    except SweepError as exc:
        print(f"rac preanalyse: {exc}", file=sys.stderr)
        return EXIT_USAGE
    if args.format == "json":
        print(json.dumps({"file": str(args.file), "settings": rows}, indent=2, default=str))
    else:
        print(render_table(rows))
        print(f"\nplots in {out_dir}")
    return EXIT_OK


@_on_checked_file
def experiment_command(args: argparse.Namespace, result: CompileResult) -> int:
    from rac.engine.budget import default_max_bytes
    from rac.studies.experiment import ExperimentError, render_ablation, render_markdown, run_experiment, write_outputs

    if args.seed is not None and args.seeds is not None:
        print("rac experiment: give --seeds LIST or --seed N (one seed), not both", file=sys.stderr)
        return EXIT_USAGE
    text = args.seeds if args.seeds is not None else str(args.seed) if args.seed is not None else "1,2,3,4,5"
    try:
        seeds = [int(s) for s in text.split(",")]
    except ValueError:
        print(f"rac experiment: --seeds: not a list of whole numbers: {args.seeds!r}", file=sys.stderr)
        return EXIT_USAGE
    if args.replay < 0:
        print(f"rac experiment: --replay must be 0 or more, not {args.replay}", file=sys.stderr)
        return EXIT_USAGE
    bins = None
    if args.bins:
        try:
            bins = [float(b) for b in args.bins.split(",")]
        except ValueError:
            print(f"rac experiment: --bins: not a list of numbers: {args.bins!r}", file=sys.stderr)
            return EXIT_USAGE
    out_dir = output_folder(args.file, "experiment", args.out)
    announce = _announcer(args.quiet)
    try:
        report = run_experiment(result, seeds=seeds, episodes=args.episodes, evaluation_runs=args.runs,
                                reward_function=args.reward_function,
                                horizon_samples=_horizon_samples(result, args.horizon) if args.horizon else None,
                                max_states=args.max_states, combinations=args.combination, bins=bins,
                                counterfactuals=not args.no_counterfactuals, replay=args.replay,
                                ablation=args.ablation, observe_time=not args.no_time,
                                max_bytes=args.max_memory or default_max_bytes(), progress=announce)
        files = write_outputs(report, out_dir)
    except ExperimentError as exc:
        print(f"rac experiment: {exc}", file=sys.stderr)
        return EXIT_ERRORS
    except OSError as exc:
        print(f"rac experiment: cannot write to {out_dir}: {exc.strerror or exc}", file=sys.stderr)
        return EXIT_USAGE
    if args.format == "json":
        print((out_dir / "results.json").read_text(encoding="utf-8"))
    else:
        print(render_markdown(report))
        print()
        if report.get("ablation"):
            print(render_ablation(report))
            print()
        for path in files:
            print(f"wrote {path}")
    return EXIT_OK


HANDLERS: dict[str, Command] = {"experiment": experiment_command, "verify": verify_command,
                                "simulate": simulate_command, "render": render_command,
                                "preanalyse": preanalyse_command}
