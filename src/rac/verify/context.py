"""What every answer of ``rac verify`` needs: the options (:class:`VerifyOptions`), the checked file,
and what earlier queries computed (explored graphs, shields, learned strategies), held by one
:class:`Context` that the answerers of :mod:`rac.verify.symbolic`, :mod:`rac.verify.statistical`
and :mod:`rac.verify.learning` receive.

An answer that cannot be given within the options raises :class:`UnknownVerdict`; the runner
turns it into the verdict *unknown* with its message.
"""

from __future__ import annotations

import contextlib
import dataclasses
import functools
import math
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from fractions import Fraction
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from rac import ir
from rac.compiler import CompileResult
from rac.core.diagnostics import RacError, RacValueError, short_number
from rac.core.numbers import samples_of
from rac.core.resources import memory_option
from rac.engine import shield, storm
from rac.engine.budget import BudgetExceeded, TimeLimit, default_max_bytes, format_bytes
from rac.engine.evaluate import EvaluationError, Evaluator, Frame
from rac.engine.explore import action_pairs, explore
from rac.engine.graph import ExploredGraph
from rac.engine.ondemand import OnDemandShield
from rac.engine.simulate import collided_so_far
from rac.engine.witness import Bounds, Predicate
from rac.ir import expr as ie
from rac.ir import query as iq
from rac.learning.episodes import EpisodeBatch
from rac.learning.qlearning import run_strategy
from rac.model.data import ModelData, ModelRangeError
from rac.model.program import CheckedProgram
from rac.model.sample import CRASHED, EGO, GRAPH_EGO, GraphColumn

if TYPE_CHECKING:
    from rac.engine.simulate import Policy, Runs
    from rac.learning.episodes import EpisodeBatch
    from rac.learning.qlearning import LearnedStrategy, StrategyRun

__all__ = ["Context", "Learned", "NotApplicable", "UnknownVerdict", "VerifyOptions", "over_budget", "restricted"]


class UnknownVerdict(RacError):
    """A query that cannot be decided within the options; the message says why, for the user."""


class NotApplicable(RacError):
    """A query that depends on a strategy that provably does not exist: nothing to decide (status
    ``not_applicable``); the message cites the defining query and why it failed."""


@dataclass(frozen=True)
class VerifyOptions:
    """How :func:`rac.verify.runner.verify` answers queries (the ``rac verify`` options)."""

    #: Horizon of exhaustive queries in seconds (None: the automaton's ``horizon``).
    horizon: Fraction | None = None
    #: Exhaustive exploration stops with *unknown* beyond this many states.
    max_states: int = 5_000_000
    #: ... or before deciding a query would need more memory than this (bytes; None: no limit).
    max_bytes: int | None = field(default_factory=default_max_bytes)
    #: Seed of the statistical queries (None: a fresh seed, printed with the result).
    seed: int | None = None
    #: ``Pr[...](<> p)``: stop when the interval's half-width is at most epsilon (UPPAAL's -E).
    epsilon: float = 0.05
    #: Confidence of intervals (UPPAAL's 1 - alpha).
    confidence: float = 0.95
    #: Error bounds and indifference region of ``Pr[...] >= θ`` (UPPAAL's -a, -B, -d).
    alpha: float = 0.05
    beta: float = 0.05
    delta: float = 0.01
    #: Where strategies, CSV files and plots go (None: ``<file>.out`` beside the .ra file).
    out_dir: Path | None = None
    #: Also answer the paper's standard queries Qa–Qd and the Fig. 7 simulations.
    standard: bool = False
    #: Only these queries (by name); None: all.
    only: tuple[str, ...] | None = None
    #: Draw plots for ``simulate`` queries.
    plots: bool = True
    #: ``progress(message)``: called before each query (the CLI shows it on a TTY).
    progress: Callable[[str], None] | None = None
    #: Exploration callback ``(layer, frontier, total)`` (the CLI's progress bar).
    explore_progress: Callable[[int, int, int], None] | None = None
    #: Each query is given up (*unknown*) past this many seconds (None: no limit), checked once per explored
    #: layer, simulated sample, learned batch of episodes, search of an on-demand shield and node of Qd's search
    #: from the start; a Storm decision already running ends first.
    max_seconds: float | None = None
    #: Learning queries (``maxE``/``minE``, :func:`rac.learning.qlearning.learn`): the episode budget,
    #: the episodes stepped together, and the early stop after this many greedy evaluations
    #: without improvement once the greedy run succeeded.
    learn_episodes: int = 1000
    learn_parallel: int = 32
    learn_stop_after: int = 10
    #: Learning queries: emit the exact optimal strategy (:func:`rac.learning.optimum.solve`) instead of
    #: learning one (``rac verify --exact``). Without it, the optimum is reported beside what was learned.
    exact: bool = False
    #: Show a progress bar (on a terminal) while learning, with the running mean return.
    bars: bool = False
    #: What the witness searches before an exhaustive exploration may spend (random runs, the beam's
    #: width, states; a time limit only as a safety net: :class:`rac.engine.witness.Bounds`).
    witness: Bounds = field(default_factory=Bounds)


@dataclass(frozen=True)
class Learned:
    """A learned strategy (``strategy S = maxE(...)``), the shield it was learned (and is run)
    under, and the expressions it observes."""

    strategy: LearnedStrategy
    shield: shield.ShieldTable | None
    exprs: tuple[ie.Expr, ...]


def _no_prev(expr: ie.Expr) -> None:
    if ie.uses_prev(expr):
        raise EvaluationError("`prev(...)` in an exhaustive query is not supported: a merged state has no "
                              "single previous sample")


def over_budget(exc: BudgetExceeded) -> str:
    """Why an exploration stopped, and what to change, in the options' terms."""
    if exc.kind == "states":
        change = "raise --max-states if the machine has the memory"
    else:
        change = f"raise {memory_option()} only if the machine has that much memory free"
    return (f"{exc}: shorten the horizon (--horizon), coarsen the model (exponent, action steps, "
            f"decide_period) or {change}")


def left_int32(exc: ModelRangeError) -> str:
    """What an undecided verdict says when a value of a run left int32 (UPPAAL's model aborts there
    too): a sensed value (``sense()``), or an input's binding or a reward's mirror."""
    what = "a sensed value" if exc.what.startswith("sense()") else "a value of a run"
    return f"{what} left the int32 range: {exc}"


class Context:
    """One file's verification in progress: the checked file and its model, the options, and what
    the queries answered so far computed, which later ones reuse (the explored graphs) or name
    (``under S``: :attr:`strategies`, :attr:`learned`).

    ``ValueError`` when the file has no ``model`` block or the horizon is not a whole number of
    samples; :class:`rac.core.diagnostics.CheckError` when the file has errors.
    """

    def __init__(self, source: CompileResult | CheckedProgram, options: VerifyOptions) -> None:
        program = source.checked() if isinstance(source, CompileResult) else source
        if program.automaton.model is None or program.model_data is None:
            raise RacValueError("rac verify needs a `model` block: the queries are answered on the scenario model")
        #: The checked file: its automaton, the scenario model the queries are answered on, the scenario.
        self.program = program
        automaton = program.automaton
        self.options = options
        #: The sample period ``C1`` in seconds.
        self.period = Fraction(automaton.period)
        horizon = options.horizon if options.horizon is not None else Fraction(automaton.horizon)
        try:  # the rule the command line checks --horizon by (one owner: rac.core.numbers)
            #: The horizon of exhaustive queries in samples.
            self.horizon_samples = samples_of(horizon, self.period, what="the horizon")
        except ValueError as exc:
            raise RacValueError(str(exc)) from None
        #: The explored model up to the horizon, by whether unsafe states were pruned (see :meth:`graph`).
        self.graphs: dict[bool, ExploredGraph] = {}
        #: Shields (``strategy S = control: A[] p``) by name, for later queries ``under S``.
        self.strategies: dict[str, tuple[storm.Shield, shield.ShieldTable]] = {}
        #: What each shield keeps (``p`` of ``control: A[] p``, as written), for messages.
        self.strategy_goals: dict[str, str] = {}
        #: Learned strategies (``strategy S = maxE(...)``) by name, for later queries ``under S``.
        self.learned: dict[str, Learned] = {}
        #: Strategies that provably do not exist, by name: why (the defining query and its failure).
        self.missing: dict[str, str] = {}
        #: Reachability strategies (``strategy S = control: E<> p``) that hold, by name: decided, not kept.
        self.reachability: set[str] = set()
        #: Safety shields computed state by state (the model was too large to explore), by name.
        self.on_demand: dict[str, OnDemandShield] = {}
        #: Shields decided without exploring (``control: A[] true``: a goal that reads no state and holds, so
        #: every action keeps it), by name: how to compute the table, done when a query under one first needs it.
        self.deferred: dict[str, Callable[[], tuple[storm.Shield, shield.ShieldTable]]] = {}
        #: The time limit of the query being answered (``--max-seconds``; set per query by the runner).
        self.limit = TimeLimit(None)
        #: How many witness searches their safety net (:data:`rac.engine.witness.SAFETY_SECONDS`) cut short
        #: before their work budget was spent: the runner says so in the answers that used one.
        self.witness_clocked = 0
        #: ... and how many of Qd's searches from the start (:data:`rac.verify.symbolic.START_SAFETY_SECONDS`).
        self.start_clocked = 0
        #: Why exploring the model failed, by ``prune`` (the budget): said again, not tried again.
        self.graph_failures: dict[bool, str] = {}
        #: The model's (jerk, turn) action pairs; a shield's masks index them.
        self.pairs = action_pairs(self.data)
        #: Where strategies, CSV files and plots go (None: nowhere).
        self.out_dir = options.out_dir
        self._seeds = np.random.SeedSequence(options.seed)
        #: The seed every query's seed derives from: the options' seed, or the fresh one drawn (give it
        #: as ``seed`` to reproduce the whole run).
        self.seed = int(self._seeds.entropy)  # type: ignore[arg-type]  # an int when given or drawn
        # The witness searches draw from a stream of their own, so that a reachability query does not
        # change the seeds of the statistical and learning queries after it.
        self._search_seeds = np.random.SeedSequence((self.seed, 1))
        #: The position of the query being answered among the seeded queries (statistical and learning)
        #: of the whole file, selected or not (:meth:`next_seed`); None: seeds are spawned in turn.
        self.seed_slot: int | None = None

    # ------------------------------------------------------------ the program, read through
    @property
    def automaton(self) -> ir.Automaton:
        """The checked automaton (:attr:`program`'s)."""
        return self.program.automaton

    @property
    def data(self) -> ModelData:
        """The scenario model's data (:attr:`program`'s)."""
        return self.program.data

    @functools.cached_property
    def evaluator(self) -> Evaluator:
        """Evaluates the queries' expressions on explored states and simulated samples (made once)."""
        return Evaluator(self.data, self.automaton)

    # ------------------------------------------------------------ files and seeds
    def out(self, name: str) -> Path:
        """The path of the output file ``name`` (its folder created); unknown without a folder."""
        if self.out_dir is None:
            raise UnknownVerdict("no output folder")
        self.out_dir.mkdir(parents=True, exist_ok=True)
        return self.out_dir / name

    @contextlib.contextmanager
    def outputs_in(self, subfolder: str) -> Iterator[None]:
        """Within the block, :meth:`out` writes into ``subfolder`` of the output folder: the standard
        queries' files go there, so a file query of the same name (a user's ``Fig7``) keeps its own."""
        saved = self.out_dir
        if saved is not None:
            self.out_dir = saved / subfolder
        try:
            yield
        finally:
            self.out_dir = saved

    def next_seed(self) -> int:
        """The query's seed, derived from the options' seed: the ``k``-th seed spawned from it for the
        ``k``-th seeded query of the whole file (:attr:`seed_slot`, set by
        :func:`rac.verify.runner.run_queries`), so that a query learns or simulates alike whether the
        queries before it run or not (``--query S``, ``rac render --strategy S``); without a slot, a
        fresh seed spawned in turn (reproducible as a whole)."""
        if self.seed_slot is not None:
            entropy = self._seeds.entropy
            return int(np.random.SeedSequence(entropy, spawn_key=(self.seed_slot,)).generate_state(1)[0])
        return int(self._seeds.spawn(1)[0].generate_state(1)[0])

    def search_seed(self) -> int:
        """A fresh seed per witness search (:mod:`rac.verify.reach`), derived from the options' seed but
        apart from :meth:`next_seed`'s: a search never shifts a statistical query's seed."""
        return int(self._search_seeds.spawn(1)[0].generate_state(1)[0])

    def bound_samples(self, bound: iq.Bound) -> int:
        """The samples within a query's time bound ``[<=T]`` (whole samples up to T s). A step bound
        ``[#<=K]`` is refused: UPPAAL counts transitions with it, and a sample of the model takes
        three or more (``accrue``, ``read``, ``sense``, at decisions ``decide`` and the choice)."""
        if bound.kind == "steps":
            raise EvaluationError("`[#<=K]` counts UPPAAL's transitions, not samples (a sample takes three or "
                                  "more): rac verify answers time bounds `[<=T]`")
        samples = math.floor(bound.limit / self.period)
        # the file's horizon, or a longer --horizon the user asked for (the standard queries' MAXT)
        horizon = max(Fraction(self.program.automaton.horizon), self.options.horizon or Fraction(0))
        if bound.limit > horizon:  # W0604 in rac check
            raise EvaluationError(
                f"the time bound ({short_number(bound.limit)} s) is past the horizon ({short_number(horizon)} s): "
                "the model takes no sample after it (in the emitted UPPAAL model nothing happens after the horizon "
                "while its clocks flow on), so runs beyond it have no answer both would give; bound the query by "
                f"the horizon (`[<={short_number(horizon)}]`)")
        return samples

    # ------------------------------------------------------------ the explored model
    def explore_progress(self, layer: int, frontier: int, total: int) -> None:
        """An exploration's per-layer ``progress``: the query's time limit (:class:`TimeExceeded` past it), then
        the options' callback (the CLI's bar)."""
        self.limit.check(layer, frontier, total)
        if self.options.explore_progress is not None:
            self.options.explore_progress(layer, frontier, total)

    def graph(self, prune: bool) -> ExploredGraph:
        """The explored model up to the horizon (pruned: unsafe states are not expanded), explored
        once and kept for later queries."""
        if prune in self.graph_failures:
            raise UnknownVerdict(self.graph_failures[prune])
        if prune not in self.graphs:
            try:
                self.graphs[prune] = explore(self.data, horizon_samples=self.horizon_samples, prune_unsafe=prune,
                                             progress=self.explore_progress,
                                             max_states=self.options.max_states, max_bytes=self.memory_left())
            except BudgetExceeded as exc:
                self.graph_failures[prune] = over_budget(exc) + self.kept_note()
                raise UnknownVerdict(self.graph_failures[prune]) from None
            except ModelRangeError as exc:
                raise UnknownVerdict(left_int32(exc)) from None
        return self.graphs[prune]

    def memory_left(self) -> int | None:
        """``--max-memory`` less the explored graphs kept for later queries (None: no limit): a new
        exploration or search must fit beside them, or two graphs within the limit each could together
        fill the machine."""
        if self.options.max_bytes is None:
            return None
        return max(1, self.options.max_bytes - self._kept_bytes())

    def kept_note(self) -> str:
        """What a refusal on :meth:`memory_left` adds: how much of the limit the kept graphs hold ('' for none)."""
        kept = self._kept_bytes()
        if not kept or self.options.max_bytes is None:
            return ""
        return (f" ({format_bytes(kept)} of {memory_option()} {format_bytes(self.options.max_bytes)} holds the model "
                "explored for earlier queries, kept for the later ones; verify this query in a run of its own to "
                "give it the whole limit)")

    def _kept_bytes(self) -> int:
        return sum(graph.nbytes for graph in self.graphs.values())

    def stopped_note(self) -> str | None:
        """What the exhaustive verdicts should say when the model's ``allow when`` leaves no action in
        some safe state before the horizon (None when it never does, or nothing was explored)."""
        if self.data.allow is None or not self.graphs:
            return None
        graph = self.graphs.get(False, self.graphs.get(True))
        assert graph is not None
        stopped = int((graph.stopped(self.horizon_samples) & graph.reachable()).sum())
        if not stopped:
            return None
        return (f"`allow when` leaves no action in {stopped:,} state{'s' if stopped != 1 else ''} before the "
                "horizon: runs stop there (the emitted model deadlocks), safe if that state is, never reaching "
                "a later goal")

    def label(self, graph: ExploredGraph, expr: ie.Expr) -> np.ndarray:
        """A state formula on every state of a plain explored graph."""
        _no_prev(expr)
        crashed = graph.states[:, graph.columns.index("crashed")] != 0 if "crashed" in graph.columns else None
        frame = Frame(k=graph.states[:, GraphColumn.K].astype(np.int64), ego=graph.states[:, GRAPH_EGO],
                      crashed=crashed)
        return np.ascontiguousarray(self.evaluator.evaluate_bool(expr, frame), dtype=bool)

    def predicate(self, expr: ie.Expr, *, negate: bool = False) -> Predicate:
        """The state formula ``expr`` (negated with ``negate``) on the states of one sample, as the
        witness searches read it (:data:`rac.engine.witness.Predicate`)."""
        _no_prev(expr)
        sticky = self.data.sticky

        def holds(k: int, rows: np.ndarray) -> np.ndarray:
            frame = Frame(k=np.full(rows.shape[0], k, dtype=np.int64), ego=np.ascontiguousarray(rows[:, EGO]),
                          crashed=rows[:, CRASHED] != 0 if sticky else None)
            value = np.asarray(self.evaluator.evaluate_bool(expr, frame), dtype=bool)
            return ~value if negate else value

        return holds

    # ------------------------------------------------------------ strategies
    def strategy(self, name: str) -> tuple[storm.Shield, shield.ShieldTable]:
        """The shield ``name`` computed by an earlier query; unknown when there is none to use."""
        if name in self.missing:
            raise NotApplicable(self.missing[name])
        if name in self.reachability:
            raise EvaluationError(f"the strategy `{name}` is a reachability strategy (`control: E<> p`): rac verify "
                                  "decides whether it exists but does not keep it, so queries under it are not "
                                  "answered; a safety strategy (`control: A[] p`) is kept for them")
        if name in self.on_demand:
            raise UnknownVerdict(f"the shield `{name}` was computed state by state (the model is too large to "
                                 "explore), so exhaustive queries under it are not decided; simulations and "
                                 "learning under it are")
        if name in self.deferred and name not in self.strategies:
            try:
                self.strategies[name] = self.deferred[name]()
            except UnknownVerdict as exc:
                raise UnknownVerdict(f"the strategy `{name}` allows every action (its goal reads no state), but a "
                                     f"query under it needs its table, which needs the whole model explored: {exc}"
                                     ) from None
        if name not in self.strategies:
            raise UnknownVerdict(f"the strategy `{name}` has not been computed (it is defined by a query that "
                                 "was skipped or failed; run it first)")
        if not self.strategies[name][0].shield_exists:
            # As in UPPAAL: a control query that is not satisfied yields no strategy to use.
            goal = self.strategy_goals.get(name, "its goal")
            raise NotApplicable(f"the strategy `{name}` does not exist: no strategy keeps `{goal}` from the start")
        return self.strategies[name]

    def forget_strategy(self, name: str) -> None:
        """Drop every record of the strategy ``name`` (a later query defines it again)."""
        for registry in (self.strategies, self.strategy_goals, self.learned, self.missing, self.on_demand,
                         self.deferred):
            registry.pop(name, None)
        self.reachability.discard(name)

    def strategy_exists(self, name: str) -> bool:
        """Whether the shield ``name`` was computed (or decided, its table deferred) and exists."""
        return name in self.on_demand or name in self.deferred or (
            name in self.strategies and self.strategies[name][0].shield_exists)

    def shield_table(self, name: str) -> shield.ShieldTable:
        """The masks of the shield ``name``: its table, or the on-demand shield computed state by state."""
        if name in self.on_demand and name not in self.missing:
            return self.on_demand[name]
        return self.strategy(name)[1]

    def policy(self, under: str | None) -> Policy | None:
        """The simulation policy of the shield ``under`` (None: every action)."""
        return None if under is None else self.shield_table(under).masks_at

    def past_shield(self, under: str, samples: int) -> str | None:
        """Why runs of ``samples`` samples under the shield ``under`` would leave it: a decision at or
        after the horizon it was computed to, where its table allows no action (an on-demand shield
        every action), so the choices there would not be the shield's; None when every decision of
        the runs lies before that horizon."""
        every = int(self.data.decide_every)
        first = -(-self.horizon_samples // every) * every  # the first decision at or after the horizon
        if first >= samples:
            return None
        return (f"the query's bound ({short_number(samples * self.period)} s) is past the horizon the strategy "
                f"`{under}` was computed to ({short_number(self.horizon_samples * self.period)} s), beyond which it "
                "does not choose the actions; bound the query by that horizon, or give a --horizon that covers "
                "the bound")

    def episodes(self, reward: str | ie.Expr, goal: ie.Expr | None, samples: int) -> EpisodeBatch:
        """Episodes of the model with the automaton (:class:`rac.learning.episodes.EpisodeBatch`);
        unknown when the episodes cannot be set up (an expression the engine cannot read stays an
        :class:`EvaluationError`: unsupported)."""

        try:
            return EpisodeBatch(self.program, reward=reward, goal=goal, horizon_samples=samples, data=self.data)
        except EvaluationError:
            raise
        except ValueError as exc:
            raise UnknownVerdict(str(exc)) from None

    def learned_run(self, name: str, samples: int) -> tuple[StrategyRun, Runs]:
        """The one run of the learned strategy ``name`` over ``samples`` samples (it does not stop at
        the learning goal): the :class:`rac.learning.qlearning.StrategyRun` and its samples replayed as
        :class:`rac.engine.simulate.Runs` (one run, with the ground truth)."""

        entry = self.learned[name]
        batch = self.episodes("automaton", None, samples)
        try:
            run = run_strategy(batch, entry.strategy, exprs=entry.exprs, shield=entry.shield)
            return run, run.samples(self.data)
        except EvaluationError:
            raise
        except ValueError as exc:
            raise UnknownVerdict(str(exc)) from None

    # ------------------------------------------------------------ simulated runs
    def frames(self, runs: Runs) -> Iterator[Frame]:
        """One frame per sample of the runs (``prev`` is the previous sample's frame)."""

        previous = None
        n = runs.n_runs
        crashed = collided_so_far(self.data, runs)
        for k in range(runs.horizon + 1):
            frame = Frame(k=np.full(n, k, dtype=np.int64), ego=np.ascontiguousarray(runs.states[:, k]),
                          truth=np.ascontiguousarray(runs.truth[:, k]), prev=previous,
                          crashed=None if crashed is None else crashed[:, k])
            yield frame
            previous = dataclasses.replace(frame, prev=None)

    def values(self, runs: Runs, exprs: tuple[ie.Expr, ...]) -> list[np.ndarray]:
        """Each expression per run and sample: ``(N, T+1)`` arrays."""
        columns: list[list[np.ndarray]] = [[] for _ in exprs]
        for frame in self.frames(runs):
            for column, expr in zip(columns, exprs):
                column.append(np.asarray(self.evaluator.evaluate(expr, frame), dtype=np.float64))
        return [np.stack(column, axis=1) for column in columns]


def restricted(computed: storm.Shield) -> ExploredGraph:
    """The shield's graph with only the allowed choices (states without one become terminal)."""
    graph = computed.graph
    keep = computed.allowed_choices
    owner = np.repeat(np.arange(graph.n_states), np.diff(graph.choice_offsets))
    counts = np.bincount(owner[keep], minlength=graph.n_states)
    offsets = np.zeros(graph.n_states + 1, dtype=np.int64)
    np.cumsum(counts, out=offsets[1:])
    return dataclasses.replace(graph, choice_offsets=offsets, choice_action=graph.choice_action[keep],
                               choice_target=graph.choice_target[keep])
