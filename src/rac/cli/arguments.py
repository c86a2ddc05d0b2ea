"""The ``rac`` command's arguments: every sub-command's parser, the option types, and which module
runs each sub-command (:data:`COMMANDS`).

Building the parser loads no command code: ``rac --version``, ``rac --help`` and a usage error cost
only this module (issue 24: no numpy, no checker), and :mod:`rac.cli.main` imports the one
command module it runs.
"""

from __future__ import annotations

import argparse
import math
import re
import sys
from collections.abc import Callable, Sequence
from fractions import Fraction
from pathlib import Path
from typing import NoReturn, TypeVar

from rac import __version__
from rac.cli.common import size_argument
from rac.core.diagnostics import RacError
from rac.core.numbers import MIN_SEED
from rac.output.paths import OUTPUT_CONVENTION, OUTPUT_SUFFIX
from rac.sweep.kinds import MEMORY_OPTION, TASKS

__all__ = ["COMMANDS", "CommandLineError", "DEFAULT_TEMPLATE", "MIN_SEED", "TARGETS", "asks_json", "build_parser",
           "positive_fraction", "horizons_argument", "counting", "probability", "seed_argument", "seeds_argument"]

T = TypeVar("T")

#: Each sub-command: the module and the function (arguments -> exit code) that runs it.
COMMANDS: dict[str, tuple[str, str]] = {
    "check": ("rac.cli.files", "check_command"), "compile": ("rac.cli.files", "compile_command"),
    "fmt": ("rac.cli.files", "fmt_command"), "tune": ("rac.cli.tune", "tune_command"),
    "verify": ("rac.cli.engine", "verify_command"), "simulate": ("rac.cli.engine", "simulate_command"),
    "render": ("rac.cli.engine", "render_command"), "preanalyse": ("rac.cli.engine", "preanalyse_command"),
    "experiment": ("rac.cli.engine", "experiment_command"), "sweep": ("rac.cli.sweep", "sweep_command"),
    "new": ("rac.cli.new", "new_command"),
}
#: ``rac compile --target``.
TARGETS = ("python", "uppaal")
#: The standard-library file ``rac new`` copies when ``--from`` is not given.
DEFAULT_TEMPLATE = "driving.ra"
#: ``--max-memory``'s default, as every command's help says it (rac.engine.budget.default_max_bytes).
MEMORY_DEFAULT = "(default: half the memory available: machine, container or ulimit -v)"
_DECIMAL = re.compile(r"[+-]?(\d+(\.\d*)?|\.\d+)")


def build_parser() -> argparse.ArgumentParser:
    """The ``rac`` command's argument parser: every sub-command and option (no command code loaded)."""
    parser = _RacParser(
        prog="rac", description="The reward-automata compiler: check, compile and format .ra files; verify "
                    "their queries, simulate and pre-analyse them on a CommonRoad scenario.",
        epilog=f"{OUTPUT_CONVENTION} Exit codes: 0 ok, 1 errors in the input or a query not satisfied, 2 bad "
               "usage or a file that cannot be read or written (standard output too), 3 an internal error (a "
               "bug in rac), 4 something left undecided (a query, a check stopped at its limit, a setting or "
               "task without an answer), 130 interrupted (Ctrl-C), 143 terminated (SIGTERM, taken as Ctrl-C).")
    parser.add_argument("--version", action="version", version=f"rac {__version__}")
    # not required here: _RacParser says so itself, after an unknown option (`rac --bogus`) was named
    commands = parser.add_subparsers(dest="command", metavar="COMMAND", parser_class=_CommandParser)

    check = commands.add_parser("check", help="type-check files and prove or refute their priority order")
    check.add_argument("files", nargs="+", type=Path, metavar="FILE")
    check.add_argument("--format", choices=("text", "json"), default="text", help="output format")
    check.add_argument("-q", "--quiet", action="store_true", help="print diagnostics only, not what was proved")
    check.add_argument("--max-memory", type=size_argument, default=None, metavar="SIZE",
                       help="refuse, before loading it, a scenario whose load would need more memory than this, "
                            "e.g. 4G " + MEMORY_DEFAULT)
    check.add_argument("--discount", type=discount_argument, default=None, metavar="GAMMA",
                       help="also prove or refute the priority order (P2) for the return discounted by GAMMA "
                            "per learner step, what stable-baselines3 maximises (its gamma, 0.99 by default); "
                            "a number in (0, 1], read exactly")
    check.add_argument("--samples-per-step", type=positive_int, default=None, metavar="N",
                       help="with --discount: the samples one learner step spans (1, as RewardAutomatonWrapper "
                            "steps; a ScenarioEnv step is a decision period of several)")

    compile_ = commands.add_parser("compile", help="generate code for a target")
    compile_.add_argument("file", type=Path, metavar="FILE")
    compile_.add_argument("--target", choices=TARGETS, required=True)
    compile_.add_argument("-o", "--output", type=Path, help="output file (default: standard output)")
    compile_.add_argument("--format", choices=("text", "json"), default="text", help="diagnostics format")
    compile_.add_argument("--max-memory", type=size_argument, default=None, metavar="SIZE",
                          help="as for `rac check` " + MEMORY_DEFAULT)

    fmt = commands.add_parser("fmt", help="rewrite files in canonical layout (comments are kept)")
    fmt.add_argument("files", nargs="+", type=Path, metavar="FILE")
    fmt.add_argument("--check", action="store_true", help="only report files that would change (exit 1)")
    fmt.add_argument("--stdout", action="store_true", help="print the result instead of rewriting")

    _add_tune(commands)
    _add_engine(commands)
    _add_sweep(commands)
    _add_new(commands)
    return parser


class _RacParser(argparse.ArgumentParser):
    """``rac``'s own parser: an unknown option before the command (``rac --bogus``) is named as such. With the
    sub-command required by argparse, the missing COMMAND was reported first, and the option not at all."""

    def parse_args(self, args: Sequence[str] | None = None,  # type: ignore[override]  # argparse's overloads
                   namespace: argparse.Namespace | None = None) -> argparse.Namespace:
        parsed = super().parse_args(args, namespace)  # unknown arguments: "unrecognized arguments: ...", exit 2
        if parsed.command is None:
            self.error("the following arguments are required: COMMAND")
        return parsed


class _Once(argparse.Action):
    """argparse's ``store`` for an option that takes one value, which says when it is given twice with
    different values (``--target python --target uppaal``, ``-o a.py -o b.py``): argparse kept the last
    silently, so the command did something else than one of the two asked for, without a word. The last
    still counts — a script that appends an override to its defaults is a common way to call a command —
    and a warning on standard error names the option and both values. Options that may be repeated say
    so with ``action="append"``."""

    def __call__(self, parser: argparse.ArgumentParser, namespace: argparse.Namespace,
                 values: str | Sequence[object] | None, option_string: str | None = None) -> None:
        given = parser.given if isinstance(parser, _CommandParser) and self.option_strings else {}
        if self.dest in given and given[self.dest] != values:  # compared as converted: `30` and `30.0` agree
            sys.stderr.write(f"{parser.prog}: warning: argument {'/'.join(self.option_strings)}: given twice with "
                             f"different values, `{given[self.dest]}` and `{values}`: the last one counts\n")
        given[self.dest] = values
        setattr(namespace, self.dest, values)  # argparse's `store`


class _CommandParser(argparse.ArgumentParser):
    """A sub-command's parser that refuses an option it does not know itself, with its own usage: argparse
    leaves that to ``rac``'s parser, whose usage (``rac [-h] [--version] COMMAND ...``) shows none of the
    command's options, where every other mistake in them (a missing value, a bad choice) shows the command's.
    An option of one value given twice with different values is warned of (:class:`_Once`)."""

    def __init__(self, *args: object, **kwargs: object) -> None:
        super().__init__(*args, **kwargs)  # type: ignore[arg-type]
        self.register("action", None, _Once)  # argparse's default action, `store`, in this parser and its groups
        self.register("action", "store", _Once)
        #: The values of the :class:`_Once` options given in the parse under way.
        self.given: dict[str, object] = {}
        #: Whether the command line being parsed asks for ``--format json`` (:func:`asks_json`).
        self.json_asked = False

    def parse_known_args(self, args: Sequence[str] | None = None,  # type: ignore[override]  # argparse's overloads
                         namespace: argparse.Namespace | None = None) -> tuple[argparse.Namespace, list[str]]:
        self.given = {}
        self.json_asked = any(action.dest == "format" for action in self._actions) and asks_json(args or ())
        parsed, extras = super().parse_known_args(args, namespace)
        if extras:
            self.error(f"unrecognized arguments: {' '.join(extras)}")
        return parsed, extras

    def error(self, message: str) -> NoReturn:  # type: ignore[override]  # argparse's exits; this may raise
        """argparse's usage message and exit 2, or with ``--format json`` on the command line
        :class:`CommandLineError`: a script that asked for JSON reads one document on standard output
        whatever went wrong, a mistake in its own command line too."""
        if self.json_asked:
            raise CommandLineError(self, message)
        super().error(message)


class CommandLineError(RacError):
    """A mistake the command line's parser found (an unknown option, a value that is not a number, a missing
    argument) in a command whose line asks for ``--format json``: :func:`rac.cli.main.main` prints it as an
    E0014 diagnostic on standard output, and argparse's usage message on standard error (exit 2)."""

    def __init__(self, parser: argparse.ArgumentParser, message: str) -> None:
        super().__init__(message)
        self.parser = parser
        self.message = message


def asks_json(args: Sequence[str]) -> bool:
    """Whether a command line asks for ``--format json`` (``--format=json``, or an abbreviation argparse
    accepts such as ``--form json``), found before the line is parsed: its own mistakes are then JSON too."""
    asked = False
    for i, arg in enumerate(args):
        if arg == "--":  # what follows is positional
            break
        name, equals, value = arg.partition("=")
        if len(name) > 3 and "--format".startswith(name):
            asked = (value if equals else args[i + 1] if i + 1 < len(args) else "") == "json"  # the last counts
    return asked


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


positive_fraction = _argument(Fraction, "a number", lambda value: value > 0, "must be positive")
counting = _argument(int, "a whole number", lambda value: value >= 1, "must be at least 1")
probability = _argument(float, "a number", lambda value: 0 < value < 1, "must lie strictly between 0 and 1")
positive_seconds = _argument(float, "a number of seconds", lambda value: 0 < value < math.inf,
                             "must be positive and finite")
seed_argument = _argument(int, "a whole number", lambda value: value >= MIN_SEED,
                          f"a seed must be a whole number of at least {MIN_SEED}")


def seeds_argument(text: str) -> tuple[int, ...]:
    """An argparse ``type`` for ``--seeds 1,2,3``: seeds as :data:`seed_argument` takes each, each once
    (a seed twice would be learned twice and counted twice in the means and spreads)."""
    seeds = tuple(seed_argument(item) for item in text.split(","))
    twice = sorted({seed for seed in seeds if seeds.count(seed) > 1})
    if twice:
        raise argparse.ArgumentTypeError(f"seed {', '.join(map(str, twice))} given twice in {text!r}")
    return seeds


def _seed_text(text: str) -> str:
    """``rac sweep --seed``: :data:`seed_argument`'s rule, the value kept as text (a task's option)."""
    return str(seed_argument(text))


#: What ``--horizon``, ``--max-states`` and ``--max-memory`` mean, per engine command: the verdicts
#: are verify's; the other commands have runs to draw or learn, and stop with a resource limit.
_HORIZON = {"verify": "horizon of exhaustive exploration, and MAXT of --standard",
            "simulate": "length of the simulated runs", "render": "length of the drawn run",
            "preanalyse": "horizon of every setting's runs and exploration",
            "experiment": "length of the learning episodes and of the shield"}


def _common(parser: argparse.ArgumentParser, outputs: str) -> None:
    """The options every engine command has; ``outputs`` says what goes into its output folder."""
    command = parser.prog.split()[-1]
    stop = "give up (verdict unknown)" if command == "verify" else \
        "give up (a row without answers)" if command == "preanalyse" else "stop (a resource limit, exit 2)"
    parser.add_argument("file", type=Path, metavar="FILE", help="a .ra file with a `model` block")
    parser.add_argument("-o", "--out", type=Path, metavar="DIR",
                        help=f"where {outputs} go (default: FILE{OUTPUT_SUFFIX}/{parser.prog.split()[-1]}/ "
                             "beside the file)")
    parser.add_argument("--horizon", type=positive_fraction, metavar="SECONDS",
                        help=f"{_HORIZON.get(command, 'horizon')} (default: the automaton's `horizon`)")
    parser.add_argument("--seed", type=seed_argument, metavar="N",
                        help=f"seed of the simulations, a whole number of at least {MIN_SEED} (default: fresh, "
                             "printed)")
    parser.add_argument("--max-states", type=counting, default=5_000_000, metavar="N",
                        help=f"{stop} beyond this many states (default 5,000,000)")
    parser.add_argument("--max-memory", type=size_argument, default=None, metavar="SIZE",
                        help=f"{stop} before the work would need more memory than this, "
                             "e.g. 4G " + MEMORY_DEFAULT)
    parser.add_argument("-q", "--quiet", action="store_true", help="no progress bars")


def _add_engine(commands: argparse._SubParsersAction) -> None:
    """Add ``verify``, ``simulate``, ``render`` and ``preanalyse`` to ``rac``'s sub-commands."""
    verify = commands.add_parser("verify", help="answer the file's queries with the native engine (Storm)",
                                 epilog=OUTPUT_CONVENTION)
    _common(verify, "strategies, CSV files and plots (--standard's in standard/)")
    verify.add_argument("--query", action="append", metavar="NAME", help="only this query (repeatable)")
    verify.add_argument("--standard", action="store_true",
                        help="also answer the paper's pre-analysis queries Qa-Qd and the Fig. 7 simulations")
    verify.add_argument("--epsilon", type=probability, default=0.05,
                        help="half-width of probability intervals (UPPAAL's -E, default 0.05)")
    verify.add_argument("--confidence", type=probability, default=0.95, help="confidence of intervals (0.95)")
    verify.add_argument("--no-plots", action="store_true", help="no PNG plots for simulate queries")
    verify.add_argument("--trace", action="store_true", help="print whole traces")
    verify.add_argument("--learn-episodes", type=counting, default=1000, metavar="N",
                        help="episode budget of learning queries (maxE/minE; default 1000)")
    verify.add_argument("--exact", action="store_true",
                        help="learning queries: emit the exact optimal strategy under the shield instead of "
                             "learning one (a backward pass over the shielded decision graph)")
    verify.add_argument("--max-seconds", type=positive_seconds, default=None, metavar="S",
                        help="give up a query (verdict unknown) after this many seconds, checked per explored layer, "
                             "simulated sample and learned batch of episodes; a Storm decision under way ends first "
                             "(default: no limit)")
    verify.add_argument("--format", choices=("text", "json"), default="text", help="output format")

    simulate = commands.add_parser("simulate", help="simulate runs; write CSV and the paper's Fig. 7 plot",
                                   epilog=OUTPUT_CONVENTION)
    _common(simulate, "runs.csv and runs.png")
    simulate.add_argument("--runs", type=counting, default=100, help="number of runs (default 100)")
    simulate.add_argument("--expr", action="append", metavar="EXPR",
                          help="what to record per sample (default: mindist() and 3 * collision_distance)")
    simulate.add_argument("--shield", action="store_true",
                          help="choose actions under the safety shield (computed first, like Qd)")
    simulate.add_argument("--format", choices=("text", "json"), default="text",
                          help="output format (json: a summary of the runs and the files written)")

    render = commands.add_parser("render", help="draw the scenario with a simulated trajectory (PNG, GIF)",
                                 epilog=OUTPUT_CONVENTION)
    _common(render, "run.png (and run.gif)")
    how = render.add_mutually_exclusive_group()
    how.add_argument("--shield", action="store_true", help="drive under the safety shield (random allowed actions)")
    how.add_argument("--strategy", metavar="NAME",
                     help="drive the file's learned strategy NAME (learned first, like rac verify does)")
    render.add_argument("--gif", action="store_true", help="also write an animated GIF, run.gif")
    render.add_argument("--exact", action="store_true",
                        help="with --strategy: draw the exact optimal strategy under the shield instead of a "
                             "learned one (as rac verify --exact)")
    render.add_argument("--format", choices=("text", "json"), default="text",
                        help="output format (json: the run drawn and the files written)")

    pre = commands.add_parser("preanalyse", help="sweep number representation and periods: Qa-Qd per setting",
                              epilog=OUTPUT_CONVENTION)
    _common(pre, "the plots")
    pre.add_argument("--exponent", default=None, metavar="LIST", help="exponents, e.g. 1,2,4")
    pre.add_argument("--sense", default=None, metavar="LIST", help="sensing periods C1 in seconds, e.g. 0.1,0.2")
    pre.add_argument("--decide", default=None, metavar="LIST", help="decision periods C2 in seconds, e.g. 0.2,0.4")
    pre.add_argument("--runs", type=counting, default=100, help="simulated runs per setting (default 100)")
    pre.add_argument("--max-seconds", type=positive_seconds, default=None, metavar="S",
                     help="give up (a row without all its answers) on a setting after this many seconds, checked "
                          "between its steps, per explored layer and per simulated sample (default: no limit)")
    pre.add_argument("--threshold-factor", type=counting, default=1, metavar="K",
                     help="a run is unsafe when its true distance drops below K * collision_distance (default 1)")
    pre.add_argument("--format", choices=("text", "json"), default="text", help="output format")

    exp = commands.add_parser("experiment", help="the paper's Table 2: learning with/without shield, automaton "
                                                 "or reward function, over seeds", epilog=OUTPUT_CONVENTION)
    _common(exp, "the table, JSON and plots")
    exp.add_argument("--seeds", type=seeds_argument, metavar="LIST",
                     help="seeds, e.g. 1,2,3 (default 1..5; --seed N is --seeds N)")
    exp.add_argument("--episodes", type=counting, default=500,
                     help="episode budget per run (default 500; on examples/paper/model.ra, 1500 brought each of "
                          "seeds 1-20 within 5 %% of the exact optimum: docs/learning.md)")
    exp.add_argument("--runs", type=counting, default=100, help="evaluation runs per strategy (default 100)")
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
    exp.add_argument("--explore", choices=("uniform", "goal"), default="uniform",
                     help="how learning episodes explore: uniform among the allowed actions (default), or goal: "
                          "half the exploring choices take the action nearest the goal one decision later, looked "
                          "up in the model (every combination alike; on examples/paper/model.ra, with --episodes "
                          "1000, seeds 1-20 reached the goal safely after 11 episodes on average, and each ended "
                          "within 5 %% of the exact optimum: docs/learning.md)")
    exp.add_argument("--replay", type=int, default=1, metavar="N",
                     help="backward replays of each batch of episodes (default 1; 0: none)")
    exp.add_argument("--ablation", action="store_true",
                     help="also learn SS&RA with other bins, counterfactuals, replay, time, the learner and the "
                          "best episode's replay switched (ablation.md)")
    exp.add_argument("--combination", action="append", choices=("SS&RA", "SS&RF", "RA", "RF"),
                     help="only this combination (repeatable)")
    exp.add_argument("--format", choices=("text", "json"), default="text", help="output format")




def _add_tune(commands: argparse._SubParsersAction) -> None:
    """Register ``rac tune`` on the ``rac`` command's subparsers."""
    tune = commands.add_parser(
        "tune", help="synthesise a file's `param` values and write them back into it as `const` lines",
        description="Synthesise the values of FILE's `param` declarations (as `rac check` does) and write "
                    "FILE back with each declaration replaced by `const` lines at those values (atomically, "
                    "comments kept; the result is checked first). --print or --horizon write nothing.")
    tune.add_argument("file", type=Path, metavar="FILE")
    tune.add_argument("--print", dest="show", action="store_true",
                      help="show the values, their set and the lines that would be written; write nothing")
    tune.add_argument("--horizon", type=horizons_argument, metavar="H,H,...",
                      help="synthesise at each horizon (seconds, whole numbers of sample periods) and print a "
                           "table and the formula in the horizon where it is linear (implies --print)")
    tune.add_argument("--format", choices=("text", "json"), default="text", help="output format")
    tune.add_argument("--max-memory", type=size_argument, default=None, metavar="SIZE",
                      help="as for `rac check` " + MEMORY_DEFAULT)


def horizons_argument(text: str) -> tuple[Fraction, ...]:
    """An argparse ``type`` for ``--horizon 30,60,120``: positive decimal numbers of seconds, each once."""
    values = []
    for item in text.split(","):
        item = item.strip()
        if not _DECIMAL.fullmatch(item):
            raise argparse.ArgumentTypeError(f"`{item}` is not a horizon: give positive numbers of seconds, "
                                             "such as 30,60,120")
        value = Fraction(item)
        if value <= 0:
            raise argparse.ArgumentTypeError(f"the horizon `{item}` must be more than 0 s")
        if value in values:  # a row twice would be synthesised twice (as rac preanalyse refuses a value twice)
            raise argparse.ArgumentTypeError(f"the horizon `{item}` is given twice")
        values.append(value)
    return tuple(values)




def discount_argument(text: str) -> Fraction:
    """An argparse ``type`` for ``--discount``: an exact number in (0, 1] (``0.99`` is 99/100)."""
    try:
        value = Fraction(text.strip())
    except (ValueError, ZeroDivisionError):
        raise argparse.ArgumentTypeError(f"not a number: {text!r}") from None
    if not 0 < value <= 1:
        raise argparse.ArgumentTypeError(f"a discount lies in (0, 1]: {text!r} does not")
    return value


def positive_int(text: str) -> int:
    """An argparse ``type`` for a count of at least 1."""
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not a whole number: {text!r}") from None
    if value < 1:
        raise argparse.ArgumentTypeError(f"must be at least 1: {text!r}")
    return value


def _checked(check, kind: str):
    """An argparse ``type`` that keeps the text and refuses it when ``check(text)`` is false or raises."""

    def parse(text: str) -> str:
        try:
            ok = check(text)
        except (ValueError, ZeroDivisionError):
            ok = False
        if not ok:
            raise argparse.ArgumentTypeError(f"not {kind}: {text!r}")
        return text

    return parse




def _add_sweep(commands: argparse._SubParsersAction) -> None:
    """Add ``sweep`` to ``rac``'s sub-commands."""
    sweep = commands.add_parser(
        "sweep", help="run a template over many scenarios and a grid of settings, on Dask",
        description="Run TASK of the template .ra file (with a `model` block) on every scenario and every point "
                    "of the --set grid, one Dask task each: on a local cluster started for the sweep, or on the "
                    "cluster at --scheduler. Rows already stored in the output folder are reused.",
        epilog=f"{OUTPUT_CONVENTION} The sweep keeps one file per task in tasks/ and merges them into "
               "results.parquet (results.csv without pyarrow) and results.json. Exit codes: 0 every task ok, "
               "1 a task failed, 2 bad usage, 4 a task could not run or a verdict is unknown, 130 interrupted, "
               "143 terminated (SIGTERM).")
    sweep.add_argument("template", metavar="TEMPLATE.ra", help="a .ra file with a `model` block")
    sweep.add_argument("scenarios", nargs="+", metavar="SCENARIOS",
                       help="CommonRoad files, folders (searched for *.xml) or globs")
    sweep.add_argument("--set", action="append", default=[], dest="sets", metavar="NAME=V1,V2",
                       help="a model setting's values (repeatable: the grid is every combination)")
    sweep.add_argument("--task", choices=TASKS, default="verify", help="what each task runs (default verify)")
    sweep.add_argument("--scheduler", metavar="ADDR",
                       help="an existing Dask cluster, tcp://HOST:PORT (default: Dask's `scheduler-address` "
                            "configuration, else a local cluster)")
    sweep.add_argument("--workers", type=_checked(lambda t: int(t) >= 1, "a whole number of at least 1"),
                       metavar="N", help="worker processes of the local cluster (default: one per core rac may use)")
    sweep.add_argument("--task-timeout",
                       type=_checked(lambda t: 0 < float(t) < math.inf, "a positive number of seconds"),
                       metavar="S", help="seconds per task; past them the task is a timeout row")
    sweep.add_argument(MEMORY_OPTION, type=size_argument, metavar="SIZE",
                       help="memory per task, e.g. 2G; past it the task is a memory row")
    sweep.add_argument("--force", action="store_true", help="run every task again, even those already stored")
    sweep.add_argument("--retry-failed", action="store_true",
                       help="run the stored tasks that are not ok again (those whose process was killed always are)")
    sweep.add_argument("-o", "--out", metavar="DIR",
                       help=f"the output folder (default: TEMPLATE{OUTPUT_SUFFIX}/sweep/ beside the template)")
    sweep.add_argument("--horizon", type=_checked(lambda t: Fraction(t) > 0, "a positive number"),
                       metavar="SECONDS", help="horizon of each task (default: the automaton's)")
    sweep.add_argument("--seed", type=_seed_text, metavar="N",
                       help=f"seed of each task's simulations, a whole number of at least {MIN_SEED}")
    sweep.add_argument("--max-states", type=_checked(lambda t: int(t) >= 1, "a whole number of at least 1"),
                       metavar="N", help="each task gives up (verdict unknown) beyond this many states")
    sweep.add_argument("--episodes", type=counting, metavar="N",
                       help="experiment: the episode budget per run (default 500)")
    sweep.add_argument("--runs", type=counting, metavar="N",
                       help="preanalyse: simulated runs per setting; experiment: evaluation runs (default 100)")
    sweep.add_argument("--reward-function", metavar="EXPR",
                       help="experiment: the per-sample reward of the RF combinations (default: the paper's Eq. 9)")
    sweep.add_argument("--explore", choices=("uniform", "goal"),
                       help="experiment: how learning episodes explore (default uniform; rac experiment --explore)")
    sweep.add_argument("-q", "--quiet", action="store_true", help="no progress, no dashboard address")
    sweep.add_argument("--format", choices=("text", "json"), default="text", help="the summary's format")




def _add_new(commands: argparse._SubParsersAction) -> None:
    """Register ``rac new`` on the ``rac`` command's subparsers."""
    new = commands.add_parser("new", help="start a new .ra file from a standard-library automaton")
    new.add_argument("name", metavar="NAME", help="the file to write, NAME.ra (may include a folder)")
    new.add_argument("--from", dest="template", default=None, metavar="FILE",
                     help=f"a .ra file, or a standard-library name such as speed_limit (default: the standard "
                          f"library's {DEFAULT_TEMPLATE}, whatever file of that name the folder holds)")


