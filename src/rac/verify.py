"""``rac verify``: a file's queries, and the paper's standard ones, answered by the native engine.

Every query form of the language is routed to the engine part that can answer it:

- ``A[] p``, ``E<> p``, ``E[] p``, ``A<> p`` and ``p --> q`` — exhaustive: the model is explored
  breadth-first (:func:`rac.engine.explore.explore`) up to the horizon, or its product with the
  automaton (:mod:`rac.engine.product`) when ``p`` reads the automaton's names, and Storm decides;
- ``strategy S = control: A[] p`` — the most permissive strategy keeping ``p`` (the shield),
  saved to ``OUT/S.shield.npz`` (load it with :func:`rac.shield.load`) and usable by later
  queries ``... under S``;
- ``Pr[<=T](<> p)`` (Clopper–Pearson interval), ``Pr[...] >= θ`` (sequential test),
  ``E[<=T;N](max: e)`` and ``simulate[<=T;N]{e...}`` — statistical: runs simulated with
  actions drawn uniformly (restricted to a shield ``under S``) and the ground truth integrated
  finely (:mod:`rac.engine.simulate`); ``simulate`` writes ``OUT/NAME.csv`` and a plot;
- ``strategy S = maxE(e)[<=T]{d...}->{c...}: <> p under S0`` — learned by tabular Q-learning on
  episodes of the model (:func:`rac.engine.learn.learn`), saved to ``OUT/S.strategy.npz`` (load it
  with :meth:`rac.engine.learn.LearnedStrategy.load`); ``A[] p``, ``E<> p``, ``E[] p``, ``A<> p``
  ``under S`` are answered on the strategy's one run (model and strategy are deterministic).

Exhaustive queries are answered within a horizon (default: the automaton's ``horizon``) and a
state budget: a model that grows beyond it gets the verdict *unknown* with the sample it reached,
never a crash. Example::

    results = verify(compile_file("model.ra"), VerifyOptions(horizon=Fraction(2)))
    print(render_text(results))
"""

from __future__ import annotations

import csv
import dataclasses
import math
import os
import time
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field
from fractions import Fraction
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from rac import ast, shield
from rac.compiler import CompileResult
from rac.engine import storm
from rac.engine.explore import EGO_COLUMNS, action_pairs, explore
from rac.engine.expr import EvaluationError, Evaluator, Frame, reads
from rac.engine.graph import ExploredGraph
from rac.model.data import ModelData, ModelRangeError
from rac.model_block import TRUE_STATE
from rac.parser import parse_source
from rac.printer import format_query
from rac.source import SourceFile, Span

if TYPE_CHECKING:
    from rac.engine.episodes import EpisodeBatch
    from rac.engine.learn import LearnedStrategy, LearningResult

__all__ = ["QueryResult", "UnknownQuery", "VerifyOptions", "render_json", "render_text", "standard_queries",
           "verify"]

#: The paper's pre-analysis queries (Table 1), over the model vocabulary; ``MAXT`` is replaced
#: by the automaton's horizon in seconds.
STANDARD_QUERIES = """
query Qa: Pr[<=MAXT](<> fabs(true_x - x) >= sensor_error)
query Qb: E[] !collide() && !offroad()
query Qc: E<> !collide() && !offroad() && goal()
query Qd: strategy safe = control: A[] !collide() && !offroad()
query Fig7: simulate[<=MAXT;100]{mindist(), 3 * collision_distance}
query Fig7_safe: simulate[<=MAXT;100]{mindist(), 3 * collision_distance} under safe
query Unsafe_safe: Pr[<=MAXT](<> mindist() <= 3 * collision_distance) under safe
"""
#: What each standard query asks, in words (printed under its name).
STANDARD_TITLES = {
    "Qa": "sensor error: Pr of the sensed x drifting sensor_error from the true x",
    "Qb": "a run that is never unsafe exists",
    "Qc": "a safe state in the goal is reachable",
    "Qd": "the safety shield (the most permissive safe strategy)",
    "Fig7": "the distance to the nearest obstacle against 3*TD, unshielded (the paper's Fig. 7)",
    "Fig7_safe": "the same under the shield",
    "Unsafe_safe": "Pr of coming closer than 3*TD under the shield",
}
_AUTOMATON_NAMES = ("location",)


@dataclass(frozen=True)
class VerifyOptions:
    """How :func:`verify` answers queries (the ``rac verify`` options)."""

    #: Horizon of exhaustive queries in seconds (None: the automaton's ``horizon``).
    horizon: Fraction | None = None
    #: Exhaustive exploration stops with *unknown* beyond this many states.
    max_states: int = 5_000_000
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
    #: Learning queries (``maxE``/``minE``, :func:`rac.engine.learn.learn`): the episode budget,
    #: the episodes stepped together, and the early stop after this many greedy evaluations
    #: without improvement once the greedy run succeeded.
    learn_episodes: int = 1000
    learn_parallel: int = 32
    learn_stop_after: int = 10
    #: Show a progress bar (on a terminal) while learning, with the running mean return.
    bars: bool = False


@dataclass(frozen=True)
class QueryResult:
    """One query's answer, in the shape ``rac verify`` prints and ``--format json`` writes.

    ``status`` is ``"satisfied"``, ``"not satisfied"``, ``"value"`` (a probability, an
    expectation or simulated runs), ``"unknown"`` (budget or horizon exceeded) or
    ``"unsupported"``; ``message`` says why for the last two."""

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
    trace: tuple[dict[str, float | int | str], ...] | None = None
    files: tuple[str, ...] = ()
    message: str | None = None
    seed: int | None = None
    confidence: float | None = None
    #: ``Pr`` without ``under``: the exact probability under uniform choices, computed by Storm
    #: on the explored model (what the interval estimates); None when the model is too large.
    exact: float | None = None
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


def standard_queries(horizon_seconds: Fraction) -> tuple[ast.QueryDecl, ...]:
    """The paper's pre-analysis queries (:data:`STANDARD_QUERIES`) as query declarations."""
    text = STANDARD_QUERIES.replace("MAXT", _decimal(horizon_seconds))
    module = parse_source(SourceFile("<standard queries>", f"automaton Standard {{{text}}}"))
    return tuple(m for m in module.automata[0].members if isinstance(m, ast.QueryDecl))


def _decimal(value: Fraction) -> str:
    return str(value.numerator) if value.denominator == 1 else repr(float(value))


class UnknownQuery(KeyError):
    """``VerifyOptions.only`` names a query the file (and ``--standard``) does not have; ``args[0]``
    lists the missing names."""


class _Unknown(Exception):
    """A query that cannot be decided within the options (message for the user)."""


class _Verifier:
    def __init__(self, result: CompileResult, options: VerifyOptions) -> None:
        automaton = result.raise_for_errors()
        if automaton.model is None or result.model_data is None:
            raise ValueError("rac verify needs a `model` block: the queries are answered on the scenario model")
        self.automaton = automaton
        self.data: ModelData = result.model_data
        self.options = options
        self.evaluator = Evaluator(self.data, automaton)
        self.period = Fraction(automaton.period)
        horizon = options.horizon if options.horizon is not None else Fraction(automaton.horizon)
        if (horizon / self.period).denominator != 1:
            raise ValueError(f"the horizon {_decimal(horizon)} s is not a whole number of samples of "
                             f"{_decimal(self.period)} s")
        self.horizon_samples = int(horizon / self.period)
        self.graphs: dict[bool, ExploredGraph] = {}
        self.strategies: dict[str, tuple[storm.Shield, shield.ShieldTable]] = {}
        #: Learned strategies (``strategy S = maxE(...)``) by name, for later queries ``under S``.
        self.learned: dict[str, _Learned] = {}
        self.result = result
        self.pairs = action_pairs(self.data)
        self.out_dir = options.out_dir
        self.seed_source = np.random.SeedSequence(options.seed)
        self.source_path = automaton.model.scenario_path

    # ------------------------------------------------------------ shared pieces
    def out(self, name: str) -> Path:
        if self.out_dir is None:
            raise _Unknown("no output folder")
        self.out_dir.mkdir(parents=True, exist_ok=True)
        return self.out_dir / name

    def graph(self, prune: bool) -> ExploredGraph:
        """The explored model up to the horizon (pruned: unsafe states are not expanded)."""
        if prune not in self.graphs:
            try:
                self.graphs[prune] = explore(self.data, horizon_samples=self.horizon_samples, prune_unsafe=prune,
                                             progress=self.options.explore_progress,
                                             max_states=self.options.max_states)
            except MemoryError as exc:
                raise _Unknown(f"{exc}: shorten the horizon (--horizon), coarsen the model (exponent, "
                               "action steps, decide_period) or raise --max-states") from None
            except ModelRangeError as exc:
                raise _Unknown(f"a sensed value left the int32 range: {exc}") from None
        return self.graphs[prune]

    def label(self, graph: ExploredGraph, expr: ast.Expr) -> np.ndarray:
        """A state formula on every state of a plain explored graph."""
        if "prev()" in reads(expr):
            raise _Unknown("`prev(...)` in an exhaustive query is not supported")
        frame = Frame(k=graph.states[:, 0].astype(np.int64), ego=graph.states[:, 1:8])
        return np.ascontiguousarray(self.evaluator.evaluate_bool(expr, frame), dtype=bool)

    def needs_product(self, expr: ast.Expr) -> bool:
        a = self.automaton
        names = reads(expr)
        return bool(names & {*(i.name for i in a.inputs), *a.rewards, *a.location_names, *_AUTOMATON_NAMES})

    def strategy(self, name: str) -> tuple[storm.Shield, shield.ShieldTable]:
        if name not in self.strategies:
            raise _Unknown(f"the strategy `{name}` has not been computed (it is defined by a query that was "
                           "skipped or failed; run it first)")
        if not self.strategies[name][0].shield_exists:
            # As in UPPAAL: a control query that is not satisfied yields no strategy to use.
            raise _Unknown(f"the strategy `{name}` does not exist: no safe strategy exists from the start")
        return self.strategies[name]

    def bound_samples(self, bound: ast.Bound) -> int:
        limit = self.evaluator.evaluate(bound.limit, Frame(k=np.zeros(1, dtype=np.int64),
                                                           ego=np.zeros((1, 7), dtype=np.int32)))
        value = float(limit[0])
        samples = int(math.floor(value + 1e-9)) if bound.kind == "steps" else int(math.floor(value / float(self.period)
                                                                                          + 1e-9))
        if samples < 0:
            raise _Unknown(f"the time bound {value} is negative")
        return samples

    def runs_of(self, expr: ast.Expr | None, default: int) -> int:
        if expr is None:
            return default
        value = float(self.evaluator.evaluate(expr, Frame(k=np.zeros(1, dtype=np.int64),
                                                          ego=np.zeros((1, 7), dtype=np.int32)))[0])
        if value < 1 or value != int(value):
            raise _Unknown(f"the number of runs must be a positive whole number, not {value}")
        return int(value)

    def next_seed(self) -> int:
        """A fresh seed per query, all derived from the options' seed (reproducible as a whole)."""
        return int(self.seed_source.spawn(1)[0].generate_state(1)[0])

    def policy(self, under: str | None):
        if under is None:
            return None
        _, table = self.strategy(under)

        def allowed(k: int, states: np.ndarray) -> np.ndarray:
            keys = np.column_stack([np.full(states.shape[0], k, dtype=np.int32), states]).astype(np.int32)
            return table.masks_for(keys)

        return allowed

    def trace_rows(self, graph: ExploredGraph, trace: list[int] | None) -> tuple[dict, ...] | None:
        if not trace:
            return None
        rows = []
        scale = float(self.data.scale)
        columns = list(graph.columns)
        for index in trace:
            state = graph.states[index]
            row: dict[str, float | int | str] = {"time": round(int(state[columns.index("k")]) * float(self.period), 9)}
            for name in EGO_COLUMNS:
                row[name] = int(state[columns.index(name)]) / scale
            if "location" in columns and self.automaton.location_names:
                row["location"] = self.automaton.location_names[int(state[columns.index("location")])]
            if "phase" in columns:  # a product state: which instant of its sample, and the rewards
                from rac.engine.product import PHASES

                row["phase"] = PHASES[int(state[columns.index("phase")])]
                for reward in self.automaton.rewards:
                    if reward not in row:  # a reward named like an ego column would hide it
                        row[reward] = int(state[columns.index(f"mirror:{reward}")]) / scale
            for label in ("collide", "offroad", "goal"):
                if label in graph.labels:
                    row[label] = bool(graph.labels[label][index])
            rows.append(row)
        return tuple(rows)

    # ------------------------------------------------------------ one query
    def answer(self, decl: ast.QueryDecl, title: str | None) -> QueryResult:
        query = decl.query
        base = QueryResult(decl.name.name, format_query(query), _kind(query), "unknown", title=title, span=decl.span)
        t0 = time.perf_counter()
        try:
            result = self._answer(query, base)
        except _Unknown as exc:
            result = dataclasses.replace(base, status="unknown", message=str(exc))
        except EvaluationError as exc:
            result = dataclasses.replace(base, status="unsupported", message=str(exc))
        return dataclasses.replace(result, seconds=time.perf_counter() - t0)

    def _answer(self, query: ast.Query, base: QueryResult) -> QueryResult:
        if isinstance(query, ast.PathQuery):
            return self.path(query, base)
        if isinstance(query, ast.LeadsToQuery):
            return self.leads_to(query, base)
        if isinstance(query, ast.ControlStrategy):
            return self.control(query, base)
        if isinstance(query, ast.ProbabilityQuery):
            return self.probability(query, base)
        if isinstance(query, ast.ExpectationQuery):
            return self.expectation(query, base)
        if isinstance(query, ast.SimulateQuery):
            return self.simulate(query, base)
        if isinstance(query, ast.LearnStrategy):
            return self.learn(query, base)
        return dataclasses.replace(base, status="unsupported", message=f"{type(query).__name__} is not answered")

    # ------------------------------------------------------------ exhaustive
    def path(self, query: ast.PathQuery, base: QueryResult) -> QueryResult:
        if query.under is not None and query.under in self.learned:
            return self.path_under_learned(query, base)
        if self.needs_product(query.expr):
            return self.path_in_product(query, base)
        # Pruning unsafe states is sound for A[]/E[] of a formula that unsafe states violate
        # (reaching one already decides the query), never for E<>/A<>.
        prune = query.quantifier in ("A[]", "E[]") and _implies_safe(query.expr) and query.under is None
        graph = self.graph(prune)
        if query.under is not None:
            shield_, _ = self.strategy(query.under)
            graph = _restricted(shield_)
        labelled = dataclasses.replace(graph, labels={**graph.labels, "query": self.label(graph, query.expr)})
        verdict = storm.decide(labelled, query.quantifier, "query")
        message = None
        if verdict.trace and "safe" in graph.labels and not graph.labels["safe"][verdict.trace[:-1]].all():
            # A collision does not end a run of the model (as in the emitted UPPAAL model), so a
            # witness may pass through unsafe states; say so, and whether a safe one exists.
            message = "the trace passes through unsafe states (a collision does not end a run)"
            if query.quantifier == "E<>" and query.under is None:
                safe_graph = self.graph(True)
                target = self.label(safe_graph, query.expr) & safe_graph.labels["safe"]
                safe_verdict = storm.decide(dataclasses.replace(safe_graph, labels={**safe_graph.labels,
                                                                                   "query": target}), "E<>", "query")
                message += ("; a run that stays safe also reaches it" if safe_verdict.holds
                            else "; NO run that stays safe reaches it")
        return dataclasses.replace(base, status="satisfied" if verdict.holds else "not satisfied",
                                   states=graph.n_states, horizon_samples=self.horizon_samples,
                                   trace=self.trace_rows(graph, verdict.trace), message=message)

    def path_in_product(self, query: ast.PathQuery, base: QueryResult) -> QueryResult:
        from rac.engine.product import decide_product, explore_product

        if query.under is not None:
            raise _Unknown("`under` a strategy is not supported on the product of model and automaton")
        try:
            graph = explore_product(self.data, self.automaton, horizon_samples=self.horizon_samples,
                                    progress=self.options.explore_progress, max_states=self.options.max_states)
        except MemoryError as exc:
            raise _Unknown(f"{exc}: the product of model and automaton grows quickly; shorten the horizon "
                           "(--horizon) or coarsen the model") from None
        verdict = decide_product(graph, query)
        return dataclasses.replace(base, status="satisfied" if verdict.holds else "not satisfied",
                                   states=graph.n_states, horizon_samples=self.horizon_samples,
                                   trace=self.trace_rows(graph, verdict.trace))

    def leads_to(self, query: ast.LeadsToQuery, base: QueryResult) -> QueryResult:
        if self.needs_product(query.left) or self.needs_product(query.right):
            raise _Unknown("`-->` over the automaton's names is not supported yet")
        graph = self.graph(False)
        p, q = self.label(graph, query.left), self.label(graph, query.right)
        # p --> q fails exactly when a reachable p-state has a run avoiding q forever (E[] !q there).
        values, _ = storm._check(storm.to_mdp(dataclasses.replace(graph, labels={"notq": ~q})), 'Pmax=? [G "notq"]')
        holds = not bool(np.any(p & (values > 0.5)))
        return dataclasses.replace(base, status="satisfied" if holds else "not satisfied", states=graph.n_states,
                                   horizon_samples=self.horizon_samples)

    def control(self, query: ast.ControlStrategy, base: QueryResult) -> QueryResult:
        if self.needs_product(query.expr):
            raise _Unknown("strategies over the automaton's names are not supported yet")
        if query.goal != "A[]":
            graph = self.graph(False)
            labelled = dataclasses.replace(graph, labels={**graph.labels, "query": self.label(graph, query.expr)})
            verdict = storm.decide(labelled, "E<>", "query")
            return dataclasses.replace(base, status="satisfied" if verdict.holds else "not satisfied",
                                       states=graph.n_states, horizon_samples=self.horizon_samples,
                                       message="reachability strategies are decided but not saved")
        graph = self.graph(_implies_safe(query.expr))
        labelled = dataclasses.replace(graph, labels={**graph.labels, "query": self.label(graph, query.expr)})
        computed = storm.safety_shield(labelled, "query")
        table = shield.table(computed, n_actions=len(self.pairs))
        self.strategies[query.name] = (computed, table)
        files: tuple[str, ...] = ()
        if self.out_dir is not None and computed.shield_exists:  # UPPAAL defines no strategy either
            files = (str(shield.save(table, self.out(f"{query.name}.shield.npz"))),)
        allowed = int(computed.allowed_choices.sum())
        message = (f"{int(computed.winning.sum()):,} winning states, {allowed:,} allowed choices"
                   if computed.shield_exists else "no safe strategy exists from the start")
        return dataclasses.replace(base, status="satisfied" if computed.shield_exists else "not satisfied",
                                   states=graph.n_states, horizon_samples=self.horizon_samples, files=files,
                                   message=message)

    # ------------------------------------------------------------ learning
    def episodes(self, reward: str | ast.Expr, goal: ast.Expr | None, samples: int) -> EpisodeBatch:
        """Episodes of the model with the automaton (:class:`rac.engine.episodes.EpisodeBatch`)."""
        from rac.engine.episodes import EpisodeBatch

        try:
            return EpisodeBatch(self.result, reward=reward, goal=goal, horizon_samples=samples, data=self.data)
        except EvaluationError:
            raise  # an expression the engine cannot read: "unsupported"
        except ValueError as exc:
            raise _Unknown(str(exc)) from None

    def learn(self, query: ast.LearnStrategy, base: QueryResult) -> QueryResult:
        """Q-learning (:func:`rac.engine.learn.learn`) on episodes ending at the first sample where
        ``p`` holds or at the bound. As in UPPAAL, ``maxE(e)`` maximises the value of ``e`` when the
        episode ends; the reward of a step is the increase of ``e`` over it, so the returns add up
        to that value. For ``e`` over the automaton's accumulating rewards (``10*sa + 5*pr + co``)
        the signal is dense; for a reward function of the current state (the paper's Eq. 9) only
        its value in the last state counts."""
        from rac.engine import learn as learning

        if query.path != "<>":
            raise _Unknown("only reachability goals (`: <> p`) are learned")
        table = None
        if query.under is not None:
            if query.under in self.learned:
                raise _Unknown(f"learning under the learned strategy `{query.under}` is not supported "
                               "(only under a shield: `strategy S = control: A[] ...`)")
            _, table = self.strategy(query.under)
        samples = self.bound_samples(query.bound)
        if samples < 1:
            raise _Unknown("the time bound is shorter than one sample")
        batch = self.episodes("automaton", query.expr, samples)
        seed = self.next_seed()
        meta = {"query": base.formula, "objective": _expr_text(query.objective), "goal": _expr_text(query.expr),
                "under": query.under, "horizon_samples": samples,
                "reward": "the objective's increase per step (its value at the episode's end)"}
        from rac.progress import Progress

        bar = Progress(total=self.options.learn_episodes, desc=f"learning {query.name}", unit="episodes",
                       enabled=None if self.options.bars else False)

        def report(done: int, budget: int, mean_return: float) -> None:
            bar.set_postfix(mean_return=f"{mean_return:.1f}")
            bar.update(done - bar.n)

        try:
            with bar:
                outcome = learning.learn(learning.ObjectiveIncrease(batch, query.objective), progress=report,
                                         discrete=query.discrete, continuous=query.continuous,
                                         optimise="max" if query.optimise == "maxE" else "min", shield=table,
                                         episodes=self.options.learn_episodes, parallel=self.options.learn_parallel,
                                         seed=seed, stop_after=self.options.learn_stop_after, meta=meta)
        except EvaluationError:
            raise
        except ValueError as exc:  # a sensed value out of range, bindings breaking `assume`
            raise _Unknown(str(exc)) from None
        self.strategies.pop(query.name, None)  # the name now means the learned strategy
        self.learned[query.name] = _Learned(outcome.strategy, table, (*query.discrete, *query.continuous))
        files: tuple[str, ...] = ()
        if self.out_dir is not None:
            files = (str(outcome.strategy.save(self.out(f"{query.name}.strategy.npz"))),)
        return dataclasses.replace(base, status="value", estimate=float(outcome.greedy.returns[0]),
                                   runs=outcome.episodes, horizon_samples=samples, seed=seed, files=files,
                                   message=self._learning_message(outcome, query))

    def _learning_message(self, outcome: LearningResult, query: ast.LearnStrategy) -> str:
        greedy = outcome.greedy
        at = f"{int(greedy.samples_taken[0]) * float(self.period):g} s"
        if greedy.success[0]:
            run = f"reaches {_expr_text(query.expr)} safely at {at}"
        elif greedy.reached[0]:
            unsafe = "collides" if greedy.collided[0] else "leaves the road"
            run = f"reaches {_expr_text(query.expr)} at {at} but {unsafe}"
        else:
            run = f"does not reach {_expr_text(query.expr)}"
        first = (f"first after {outcome.first_success_episode} episodes" if outcome.first_success_episode is not None
                 else "never")
        stop = ", stopped early" if outcome.stopped_early else ""
        lines = [f"learned in {outcome.episodes} episodes{stop}: the greedy run {run}, return "
                 f"{_number(float(greedy.returns[0]))}",
                 f"safe greedy run to the goal: {first}; learning episodes that collided: "
                 f"{outcome.collisions_during_learning}, left the road: {outcome.offroad_during_learning}; "
                 f"{outcome.strategy.n_states:,} observations"]
        if outcome.fallbacks:
            lines.append(f"{outcome.fallbacks} decisions where `{query.under}` allowed no action chose among all")
        return "\n".join(lines)

    def path_under_learned(self, query: ast.PathQuery, base: QueryResult) -> QueryResult:
        """``A[] p``, ``E[] p``, ``A<> p``, ``E<> p`` under a learned strategy: the model and the
        greedy strategy are deterministic, so there is one run, followed to the horizon (it does not
        stop at the learning goal) and replayed sample by sample (:meth:`StrategyRun.samples`):
        ``[]`` holds iff ``p`` holds at every sample of it, ``<>`` iff at some sample."""
        from rac.engine.learn import run_strategy
        from rac.engine.simulate import label_runs

        # p is evaluated on the replayed samples, which hold the model and the ground truth: the
        # evaluator reports a name of the automaton (a location, a reward, an input) as unsupported.
        entry = self.learned[query.under]  # type: ignore[index]
        batch = self.episodes("automaton", None, self.horizon_samples)
        try:
            run = run_strategy(batch, entry.strategy, exprs=entry.exprs, shield=entry.shield)
            runs = run.samples(self.data)
        except EvaluationError:
            raise
        except ValueError as exc:
            raise _Unknown(str(exc)) from None
        holds = np.array([bool(self.evaluator.evaluate_bool(query.expr, frame)[0]) for frame in self.frames(runs)])
        always = query.quantifier in ("A[]", "E[]")
        verdict = bool(holds.all()) if always else bool(holds.any())
        decisive = np.flatnonzero(~holds if always else holds)
        end = int(decisive[0]) if decisive.size else holds.size - 1
        scale = float(self.data.scale)
        labels = {name: label_runs(self.data, runs, name)[0] for name in ("collide", "offroad", "goal")}
        rows = []
        for k in range(end + 1):
            row: dict[str, float | int | str] = {"time": round(k * float(self.period), 9)}
            row.update({name: int(runs.states[0, k, i]) / scale for i, name in enumerate(EGO_COLUMNS)})
            row.update({name: bool(values[k]) for name, values in labels.items()})
            rows.append(row)
        if decisive.size:
            outcome = f"{'fails' if always else 'holds'} at {end * float(self.period):g} s"
        else:
            outcome = "holds at every sample" if always else "holds at no sample"
        message = f"the one run under `{query.under}` (deterministic model and strategy): {_expr_text(query.expr)} " \
                  f"{outcome}"
        if run.fallbacks[0]:
            message += f"; at {int(run.fallbacks[0])} decisions the shield allowed no action"
        return dataclasses.replace(base, status="satisfied" if verdict else "not satisfied", states=holds.size,
                                   horizon_samples=self.horizon_samples, trace=tuple(rows), message=message)

    # ------------------------------------------------------------ statistical
    def _runs(self, n: int, samples: int, under: str | None, seed: int):
        from rac.engine.simulate import simulate

        return simulate(self.data, runs=n, horizon_samples=samples, seed=seed, policy=self.policy(under))

    def frames(self, runs) -> Iterable[Frame]:
        """One frame per sample of the runs (``prev`` is the previous sample's frame)."""
        previous = None
        n = runs.n_runs
        for k in range(runs.horizon + 1):
            frame = Frame(k=np.full(n, k, dtype=np.int64), ego=np.ascontiguousarray(runs.states[:, k]),
                          truth=np.ascontiguousarray(runs.truth[:, k]), prev=previous)
            yield frame
            previous = dataclasses.replace(frame, prev=None)

    def values(self, runs, exprs: tuple[ast.Expr, ...]) -> list[np.ndarray]:
        """Each expression per run and sample: ``(N, T+1)`` arrays."""
        columns: list[list[np.ndarray]] = [[] for _ in exprs]
        for frame in self.frames(runs):
            for column, expr in zip(columns, exprs):
                column.append(np.asarray(self.evaluator.evaluate(expr, frame), dtype=np.float64))
        return [np.stack(column, axis=1) for column in columns]

    def _statistical_check(self, exprs: Iterable[ast.Expr]) -> None:
        for expr in exprs:
            if self.needs_product(expr):
                raise _Unknown("statistical queries over the automaton's names are not supported yet "
                               "(the model's vocabulary is)")

    def probability(self, query: ast.ProbabilityQuery, base: QueryResult) -> QueryResult:
        from rac.engine import stats

        self._statistical_check([query.expr])
        samples = self.bound_samples(query.bound)
        seed = self.next_seed()
        batch_seeds = np.random.SeedSequence(seed)
        every = query.path == "[]"

        def sample(n: int) -> np.ndarray:
            runs = self._runs(n, samples, query.under, int(batch_seeds.spawn(1)[0].generate_state(1)[0]))
            holds = self.values(runs, (query.expr,))[0] != 0
            return holds.all(axis=1) if every else holds.any(axis=1)

        if query.compare is not None:
            op, theta_expr = query.compare
            theta = float(self.evaluator.evaluate(theta_expr, Frame(k=np.zeros(1, dtype=np.int64),
                                                                     ego=np.zeros((1, 7), dtype=np.int32)))[0])
            test = stats.sequential_test(sample, theta, alpha=self.options.alpha, beta=self.options.beta,
                                         delta=self.options.delta)
            accepted = test.accepted if op in (">=", ">") else not test.accepted
            message = None if test.decided else "the run budget ran out before the test decided"
            return dataclasses.replace(base, status="satisfied" if accepted else "not satisfied", runs=test.runs,
                                       estimate=test.successes / test.runs if test.runs else None,
                                       horizon_samples=samples, seed=seed, message=message)
        if query.runs is not None:
            estimate = stats.estimate_probability_fixed(sample, self.runs_of(query.runs, 1),
                                                        confidence=self.options.confidence)
        else:
            estimate = stats.estimate_probability(sample, epsilon=self.options.epsilon,
                                                  confidence=self.options.confidence)
        return dataclasses.replace(base, status="value", interval=(estimate.lo, estimate.hi),
                                   estimate=estimate.estimate, runs=estimate.runs, horizon_samples=samples,
                                   seed=seed, confidence=self.options.confidence,
                                   exact=self.exact_probability(query, samples))

    def exact_probability(self, query: ast.ProbabilityQuery, samples: int) -> float | None:
        """``Pr[<=T](<> p)`` (or ``[] p``) under uniform choices, exactly, by Storm on the explored
        model — when ``p`` reads only the sensed model and the model up to ``T`` is small enough."""
        names = reads(query.expr)
        if query.under is not None or "prev()" in names or names & set(TRUE_STATE):
            return None
        try:
            graph = explore(self.data, horizon_samples=samples, max_states=min(self.options.max_states, 2_000_000))
        except (MemoryError, ModelRangeError):
            return None
        p = self.label(graph, query.expr)
        every = query.path == "[]"
        reached = storm.uniform_reach_probability(dataclasses.replace(graph, labels={"event": ~p if every else p}),
                                                  "event")
        return 1.0 - reached if every else reached

    def expectation(self, query: ast.ExpectationQuery, base: QueryResult) -> QueryResult:
        from rac.engine import stats

        self._statistical_check([query.expr])
        samples = self.bound_samples(query.bound)
        n = self.runs_of(query.runs, 1)
        seed = self.next_seed()
        values = self.values(self._runs(n, samples, query.under, seed), (query.expr,))[0]
        per_run = values.max(axis=1) if query.aggregate == "max" else values.min(axis=1)
        if n >= 2:
            mean, half = stats.mean_interval(per_run, self.options.confidence)
        else:
            mean, half = float(per_run[0]), math.inf
        return dataclasses.replace(base, status="value", estimate=mean, interval=(mean - half, mean + half), runs=n,
                                   horizon_samples=samples, seed=seed, confidence=self.options.confidence)

    def simulate(self, query: ast.SimulateQuery, base: QueryResult) -> QueryResult:
        self._statistical_check(query.exprs)
        samples = self.bound_samples(query.bound)
        n = self.runs_of(query.runs, 1)
        seed = self.next_seed()
        runs = self._runs(n, samples, query.under, seed)
        values = self.values(runs, query.exprs)
        files: list[str] = []
        names = [_expr_text(e) for e in query.exprs]
        if self.out_dir is not None:
            files.append(str(_write_csv(self.out(f"{base.name}.csv"), runs.times, names, values)))
            if self.options.plots:
                png = _plot(self.out(f"{base.name}.png"), runs.times, names, values, base.formula)
                if png is not None:
                    files.append(str(png))
        message = f"{n} runs of {samples} samples"
        if len(values) == 2 and np.ptp(values[1]) == 0:
            below = int(np.any(values[0] < values[1], axis=1).sum())
            message += f"; {below} of {n} runs go below {names[1]} = {float(values[1].flat[0]):g}"
        return dataclasses.replace(base, status="value", runs=n, horizon_samples=samples, seed=seed,
                                   files=tuple(files), message=message,
                                   estimate=float(np.min(values[0])) if values else None)

    # ------------------------------------------------------------ all
    def run(self, decls: Iterable[tuple[ast.QueryDecl, str | None]]) -> list[QueryResult]:
        results = []
        for decl, title in decls:
            if self.options.progress is not None:
                self.options.progress(f"{decl.name.name}: {format_query(decl.query)}")
            results.append(self.answer(decl, title))
        return results


def verify(result: CompileResult, options: VerifyOptions | None = None) -> list[QueryResult]:
    """Answer the queries of a checked file (and, with ``options.standard``, the paper's standard
    queries first). :class:`rac.diagnostics.CheckError` when the file has errors; ``ValueError``
    when it has no ``model`` block; :class:`UnknownQuery` when ``options.only`` names a missing query."""
    options = options or VerifyOptions()
    verifier = _Verifier(result, options)
    decls: list[tuple[ast.QueryDecl, str | None]] = []
    if options.standard:
        horizon = options.horizon if options.horizon is not None else Fraction(verifier.automaton.horizon)
        decls += [(d, STANDARD_TITLES.get(d.name.name)) for d in standard_queries(horizon)]
    decls += [(d, None) for d in verifier.automaton.queries]
    if options.only is not None:
        known = {d.name.name for d, _ in decls}
        missing = [name for name in options.only if name not in known]
        if missing:
            raise UnknownQuery(", ".join(missing))
        # A query `under S` needs S: keep the strategies it names, in order. Backwards, so that a
        # strategy learned `under` a shield brings the shield too (a strategy precedes its uses).
        wanted = set(options.only)
        for decl, _ in reversed(decls):
            if decl.name.name in wanted and getattr(decl.query, "under", None):
                wanted |= {d.name.name for d, _ in decls if getattr(d.query, "name", None) == decl.query.under}
        decls = [(d, t) for d, t in decls if d.name.name in wanted]
    return verifier.run(decls)


# ---------------------------------------------------------------- helpers
def _kind(query: ast.Query) -> str:
    return {ast.PathQuery: "symbolic", ast.LeadsToQuery: "symbolic", ast.ControlStrategy: "strategy",
            ast.ProbabilityQuery: "probability", ast.ExpectationQuery: "expectation",
            ast.SimulateQuery: "simulate"}.get(type(query), "learning")


def _implies_safe(expr: ast.Expr) -> bool:
    """``expr`` is a conjunction containing ``!collide()`` and ``!offroad()`` (so unsafe states violate it)."""
    found: set[str] = set()

    def walk(node: ast.Expr) -> None:
        if isinstance(node, ast.Binary) and node.op == "&&":
            walk(node.left)
            walk(node.right)
        elif (isinstance(node, ast.Unary) and node.op == "!" and isinstance(node.operand, ast.Call)
              and not node.operand.args):
            found.add(node.operand.func)

    walk(expr)
    return {"collide", "offroad"} <= found


@dataclass(frozen=True)
class _Learned:
    """A learned strategy, the shield it was learned (and is run) under, and its observed expressions."""

    strategy: LearnedStrategy
    shield: shield.ShieldTable | None
    exprs: tuple[ast.Expr, ...]


def _restricted(computed: storm.Shield) -> ExploredGraph:
    """The shield's graph with only the allowed choices (states without one become terminal)."""
    graph = computed.graph
    keep = computed.allowed_choices
    owner = np.repeat(np.arange(graph.n_states), np.diff(graph.choice_offsets))
    counts = np.bincount(owner[keep], minlength=graph.n_states)
    offsets = np.zeros(graph.n_states + 1, dtype=np.int64)
    np.cumsum(counts, out=offsets[1:])
    return dataclasses.replace(graph, choice_offsets=offsets, choice_action=graph.choice_action[keep],
                               choice_target=graph.choice_target[keep])


def _expr_text(expr: ast.Expr) -> str:
    from rac.printer import format_expr

    return format_expr(expr)


def _write_csv(path: Path, times: np.ndarray, names: list[str], values: list[np.ndarray]) -> Path:
    """``run,time,expr...`` rows, written to a temporary file and renamed (never half a file)."""
    partial = path.with_name(path.name + ".partial")
    with partial.open("w", newline="", encoding="utf-8") as handle:
        writer = csv.writer(handle)
        writer.writerow(["run", "time", *names])
        for run in range(values[0].shape[0] if values else 0):
            for k, t in enumerate(times):
                writer.writerow([run, f"{t:.6g}", *(f"{v[run, k]:.9g}" for v in values)])
    os.replace(partial, path)
    return path


def _plot(path: Path, times: np.ndarray, names: list[str], values: list[np.ndarray], title: str) -> Path | None:
    """The paper's Fig. 7 for ``simulate{distance, threshold}``; one line per run otherwise."""
    try:
        from rac.plots import plot_runs
    except ImportError:  # plotting is optional for verification
        return None
    threshold = float(values[1].flat[0]) if len(values) == 2 and np.ptp(values[1]) == 0 else None
    return Path(plot_runs(times, values[0], path, threshold=threshold, threshold_label=names[1] if threshold else None,
                          ylabel=names[0], title=title))


# ---------------------------------------------------------------- rendering
def _number(value: float) -> str:
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
        if r.kind == "probability" and r.interval is not None:
            lines.append(f" -- Pr in [{r.interval[0]:.4f}, {r.interval[1]:.4f}] ({r.runs} runs, "
                         f"{_confidence(r)} CI)")
            if r.exact is not None:
                lines.append(f" -- exact (Storm, actions drawn uniformly): {r.exact:.4f}")
        elif r.kind == "probability" and r.runs is not None:
            lines.append(f" -- {r.runs} runs, {int(round((r.estimate or 0) * r.runs))} satisfied the formula")
        elif r.kind == "expectation" and r.estimate is not None and r.interval is not None:
            half = (r.interval[1] - r.interval[0]) / 2
            lines.append(f" -- ({r.runs} runs) E = {_number(r.estimate)} ± {_number(half)} ({_confidence(r)} CI)")
        elif r.kind == "simulate" and r.message:
            lines.append(f" -- {r.message}")
        elif r.kind == "learning" and r.status == "value" and r.message:
            first, *more = r.message.split("\n")
            lines.append(f" -- {first}")
            lines.extend(f"    {line}" for line in more)
        details = []
        if r.states is not None:
            details.append(_count(r.states, "state"))
        if r.horizon_samples is not None:
            details.append(f"horizon {r.horizon_samples} samples")
        details.append(f"{r.seconds:.2f} s")
        if r.seed is not None:
            details.append(f"seed {r.seed}")
        lines.append("    " + ", ".join(details))
        if r.kind in ("strategy", "symbolic") and r.message and r.status != "unknown":
            lines.append(f"    {r.message}")
        for file in r.files:
            lines.append(f"    wrote {file}")
        if r.trace:
            shown = r.trace if traces else (r.trace[:3] + r.trace[-3:] if len(r.trace) > 6 else r.trace)
            note = "" if traces or len(r.trace) <= 6 else ", first and last 3; --trace shows all"
            lines.append(f"    trace ({_count(len(r.trace), 'state')}{note}):")
            for row in shown:
                lines.append("      " + _trace_row(row))
    return "\n".join(lines)


def _count(n: int, noun: str) -> str:
    return f"{n:,} {noun}{'' if n == 1 else 's'}"


def _confidence(result: QueryResult) -> str:
    return f"{(result.confidence or 0.95) * 100:g}%"


def _trace_row(row: dict) -> str:
    parts = [f"t={row['time']:g}s"]
    for name in ("x", "y", "v", "acc", "head", "jerk", "turn"):
        parts.append(f"{name}={row[name]:g}")
    if "location" in row:
        parts.append(str(row["location"]))
    if row.get("phase", "sampled") != "sampled":  # product states before the edge, after `at end`
        parts.append(f"({row['phase']})")
    known = {"time", "x", "y", "v", "acc", "head", "jerk", "turn", "location", "phase", "collide", "offroad", "goal"}
    parts.extend(f"{name}={value:g}" for name, value in row.items() if name not in known)
    flags = [name for name in ("collide", "offroad", "goal") if row.get(name)]
    if flags:
        parts.append("[" + ",".join(flags) + "]")
    return " ".join(parts)


def _finite(value: float | None) -> float | None:
    """``value``, or None when it is not finite (JSON has no infinities)."""
    return value if value is None or math.isfinite(value) else None


def render_json(results: list[QueryResult]) -> list[dict[str, object]]:
    """The results as JSON-ready dicts (``rac verify --format json``)."""
    return [r.to_json() for r in results]
