"""``rac verify``: a file's queries, and the paper's standard ones, answered by the native engine.

Every query form of the language is routed to the engine part that can answer it:

- ``A[] p``, ``E<> p``, ``E[] p``, ``A<> p`` and ``p --> q`` — the run that decides a path query (a
  witness, a counterexample) searched first (:mod:`rac.verify.reach`), else exhaustive: the model is
  explored breadth-first (:func:`rac.engine.explore.explore`) up to the horizon, or its product with
  the automaton (:mod:`rac.engine.product`) when ``p`` reads the automaton's names, and Storm decides;
- ``strategy S = control: A[] p`` — the most permissive strategy keeping ``p`` (the shield),
  saved to ``OUT/S.shield.npz`` (load it with :func:`rac.engine.shield.load`) and usable by later
  queries ``... under S``;
- ``Pr[<=T](<> p)`` (Clopper–Pearson interval), ``Pr[...] >= θ`` (sequential test),
  ``E[<=T;N](max: e)`` and ``simulate[<=T;N]{e...}`` — statistical: runs simulated with
  actions drawn uniformly (restricted to a shield ``under S``) and the ground truth integrated
  finely (:mod:`rac.engine.simulate`); ``simulate`` writes ``OUT/NAME.csv`` and a plot;
- ``strategy S = maxE(e)[<=T]{d...}->{c...}: <> p under S0`` — learned by tabular Q-learning on
  episodes of the model (:func:`rac.learning.qlearning.learn`), saved to ``OUT/S.strategy.npz`` (load it
  with :meth:`rac.learning.qlearning.LearnedStrategy.load`); ``A[] p``, ``E<> p``, ``E[] p``, ``A<> p``
  ``under S`` are answered on the strategy's one run (model and strategy are deterministic).

Exhaustive queries are answered within a horizon (default: the automaton's ``horizon``) and a
state budget: a model that grows beyond it gets the verdict *unknown* with the sample it reached,
never a crash.

One :class:`~rac.verify.context.Context` per file holds what every answer needs and what earlier
queries computed; each kind of query has an answerer that receives it
(:class:`~rac.verify.symbolic.SymbolicAnswerer`, :class:`~rac.verify.statistical.StatisticalAnswerer`,
:class:`~rac.verify.learning.LearningAnswerer`), and :class:`Verifier` sends each query to its
answerer. Example::

    results = verify(compile_file("model.ra"), VerifyOptions(horizon=Fraction(2)))
    print(render_text(results))
"""

from __future__ import annotations

import contextlib
import dataclasses
import time
from collections.abc import Callable, Iterable, Mapping
from fractions import Fraction
from typing import Any

from rac import ir
from rac.check.standard import STANDARD, at_horizon
from rac.compiler import CompileResult
from rac.core.diagnostics import RacError, counted
from rac.engine.budget import TimeExceeded, TimeLimit, out_of_memory
from rac.engine.evaluate import EvaluationError
from rac.ir import query as iq
from rac.model.data import ModelRangeError
from rac.model.program import CheckedProgram
from rac.verify import symbolic
from rac.verify.context import Context, NotApplicable, UnknownVerdict, VerifyOptions, left_int32
from rac.verify.learning import LearningAnswerer
from rac.verify.report import QueryResult, render_json, render_text
from rac.verify.statistical import StatisticalAnswerer
from rac.verify.status import NOT_APPLICABLE, NOT_SATISFIED, UNKNOWN, UNSUPPORTED

__all__ = ["QueryResult", "UnknownQuery", "Verifier", "VerifyOptions", "render_json", "render_text", "run_queries",
           "standard_queries", "verify"]

#: An answerer's method: ``answer(query, base)`` completes the result ``base`` (name, formula, kind)
#: of a query of the type it is registered for in :attr:`Verifier.answers`.
Answer = Callable[[Any, QueryResult], QueryResult]
#: What each standard query asks, in words (printed under its name); the queries themselves:
#: :data:`rac.check.standard.STANDARD`.
STANDARD_TITLES = {q.name: q.title for q in STANDARD if q.verify}
#: The queries that draw a seed (:meth:`Context.next_seed`): each gets the one of its place among them.
SEEDED = (iq.ProbabilityQuery, iq.ExpectationQuery, iq.SimulateQuery, iq.LearnStrategy)


def standard_queries(result: CompileResult | CheckedProgram, horizon_seconds: Fraction | None = None
                     ) -> tuple[iq.QueryDecl, ...]:
    """The paper's standard queries that ``rac verify --standard`` answers, as the checker lowered them
    against the file's automaton, with ``MAXT`` the horizon (default: the automaton's; another one
    replaces their time bounds, :func:`rac.check.standard.at_horizon`: they are not lowered again)."""
    automaton = result.raise_for_errors() if isinstance(result, CompileResult) else result.automaton
    decls = tuple(d for d in automaton.standard_queries if d.name in STANDARD_TITLES)
    if horizon_seconds is None or horizon_seconds == automaton.horizon:
        return decls
    return at_horizon(decls, horizon_seconds)


class UnknownQuery(RacError, KeyError):
    """``VerifyOptions.only`` names a query the file (and ``--standard``) does not have; ``args[0]``
    lists the missing names."""


class Verifier:
    """Answers one file's queries in order: each query goes to the answerer of its kind, all sharing
    :attr:`context` (so that a query ``under S`` finds the strategy ``S`` an earlier one computed).
    A verdict that cannot be reached becomes *unknown* (:class:`~rac.verify.context.UnknownVerdict`)
    or *unsupported* (:class:`~rac.engine.evaluate.EvaluationError`), never an exception; so does a query
    whose answer ran out of memory before its budget said so (the queries after it are still answered)."""

    def __init__(self, context: Context, seed_slots: Mapping[int, int] | None = None) -> None:
        self.context = context
        #: Each seeded query's place among the whole file's (by ``id`` of its declaration): its seed
        #: (:meth:`Context.next_seed`); a query not in it draws the next seed in turn.
        self.seed_slots: Mapping[int, int] = seed_slots or {}
        self.symbolic = symbolic.SymbolicAnswerer(context)
        self.statistical = StatisticalAnswerer(context)
        self.learning = LearningAnswerer(context)
        #: The answer to each type of query (called with a query of that type).
        self.answers: dict[type, Answer] = {
            iq.PathQuery: self.symbolic.path,
            iq.LeadsToQuery: self.symbolic.leads_to,
            iq.ControlStrategy: self.symbolic.control,
            iq.ProbabilityQuery: self.statistical.probability,
            iq.ExpectationQuery: self.statistical.expectation,
            iq.SimulateQuery: self.statistical.simulate,
            iq.LearnStrategy: self.learning.learn,
        }

    def run(self, decls: Iterable[tuple[iq.QueryDecl, str | None]], *,
            answered: list[QueryResult] | None = None) -> list[QueryResult]:
        """Answer each query (with the title printed under its name) in order; the results are appended to
        ``answered`` (returned) as they come, so that a caller stopped midway (Ctrl-C) still has them."""
        results: list[QueryResult] = [] if answered is None else answered
        for decl, title in decls:
            if self.context.options.progress is not None:
                self.context.options.progress(f"{decl.name}: {decl.text}")
            # a standard query's files go to standard/ (see Context.outputs_in)
            with self.context.outputs_in("standard") if decl.title else contextlib.nullcontext():
                results.append(self.answer(decl, title))
        return results

    def answer(self, decl: iq.QueryDecl, title: str | None) -> QueryResult:
        """One query's result, timed."""
        query = decl.query
        base = QueryResult(decl.name, decl.text, _kind(query), "unknown", title=title, span=decl.span)
        t0 = time.perf_counter()
        self.context.seed_slot = self.seed_slots.get(id(decl))
        clocked = {name: computed.stats.clocked_answers for name, computed in self.context.on_demand.items()}
        searches_clocked = self.context.witness_clocked
        starts_clocked = self.context.start_clocked
        redefined = _defines(query)
        if redefined is not None and getattr(query, "under", None) != redefined:
            # a strategy defined again replaces the earlier one of that name (whatever its kind)
            self.context.forget_strategy(redefined)
        self.context.limit = TimeLimit(self.context.options.max_seconds, what=f"query {decl.name}")
        try:
            result = self._dispatch(query, base)
        except TimeExceeded as exc:  # --max-seconds: undecided, never a verdict; the queries after it go on
            result = dataclasses.replace(base, status=UNKNOWN, message=f"{exc} (--max-seconds)")
        except UnknownVerdict as exc:
            result = dataclasses.replace(base, status="unknown", message=str(exc))
        except ModelRangeError as exc:  # a run's sensed value (UPPAAL's model would abort there too)
            result = dataclasses.replace(base, status="unknown", message=left_int32(exc))
        except NotApplicable as exc:
            result = dataclasses.replace(base, status=NOT_APPLICABLE, message=str(exc))
        except EvaluationError as exc:
            result = dataclasses.replace(base, status="unsupported", message=str(exc))
        except MemoryError as exc:
            if isinstance(exc, RacError):  # a budget's refusal: its callers say it in their terms
                raise
            # the machine's memory or `ulimit -v` ran out first: this query is undecided, the others stand
            result = dataclasses.replace(base, status=UNKNOWN, message=out_of_memory(exc, "answering it"))
        finally:
            self.context.limit = TimeLimit(None)  # what runs between queries (or after them) has no query's limit
        defined = _defines(query)
        if defined is not None and result.status in (NOT_SATISFIED, NOT_APPLICABLE) and \
                not (defined in self.context.learned or self.context.strategy_exists(defined)):
            # later queries `under` it have nothing to be decided on; they cite this query
            failed = "not satisfied" if result.status == NOT_SATISFIED else "not applicable"
            self.context.missing[defined] = (f"the strategy `{defined}` does not exist: its defining query "
                                             f"{decl.name} is {failed} ({result.message or failed})")
        if result.method is None and result.status not in (UNKNOWN, UNSUPPORTED, NOT_APPLICABLE):
            result = dataclasses.replace(result, method=_method(query, self.context))
        note = self.context.stopped_note() if result.states is not None else None
        if note is not None and result.status in ("satisfied", "not satisfied"):
            result = dataclasses.replace(result, message=f"{result.message}; {note}" if result.message else note)
        for note in self._clock_notes(clocked, self.context.witness_clocked - searches_clocked,
                                      self.context.start_clocked - starts_clocked):
            result = dataclasses.replace(result, message=f"{result.message}; {note}" if result.message else note)
        return dataclasses.replace(result, seconds=time.perf_counter() - t0)

    def _clock_notes(self, before: dict[str, int], searches: int = 0, starts: int = 0) -> list[str]:
        """Per on-demand shield that handed out masks its time guard cut while this query ran (``before``:
        each one's count of such masks before it), for the ``searches`` witness searches and the ``starts``
        searches from the start (Qd beyond the budget) their safety net cut short: that the answer depends on
        the machine's speed."""
        notes = []
        if starts:
            start_net = symbolic.START_SAFETY_SECONDS
            notes.append(f"the search from the start ran into its safety time limit ({start_net:g} s) before "
                         "spending its work budget, so this answer (its verdict, or its count of actions) "
                         "depends on the machine's speed and load and may differ on another run")
        if searches:
            net = self.context.options.witness.safety_seconds
            their = "its" if searches == 1 else "their"
            notes.append(f"{counted(searches, 'witness search', 'witness searches')} ran into the safety time limit "
                         f"({net:g} s) before spending {their} work budget, so this answer (its method, its trace, "
                         "whether it is known) depends on the machine's speed and load and may differ on another "
                         "run at the same seed")
        for name, computed in self.context.on_demand.items():
            cut = computed.stats.clocked_answers - before.get(name, 0)
            if cut > 0:
                notes.append(f"{cut:,} {'mask' if cut == 1 else 'masks'} of the shield `{name}` came from searches "
                             f"its time guard ({computed.seconds:g} s a state) cut short, so this answer depends on "
                             "the machine's speed and load and may differ on another run at the same seed")
        return notes

    def _dispatch(self, query: iq.Query, base: QueryResult) -> QueryResult:
        refusal = _ending_refusal(self.context.program.automaton, query, self.context.learned)
        if refusal is not None:
            raise EvaluationError(refusal)
        if isinstance(query, iq.PathQuery) and query.under is not None and query.under in self.context.learned:
            # A learned strategy has one run (model and strategy are deterministic): answered on it.
            return self.learning.path_under_learned(query, query.under, base)
        answer = self.answers.get(type(query))
        if answer is None:
            return dataclasses.replace(base, status="unsupported", message=f"{type(query).__name__} is not answered")
        return answer(query, base)


def verify(result: CompileResult | CheckedProgram, options: VerifyOptions | None = None) -> list[QueryResult]:
    """Answer the queries of a checked file (and, with ``options.standard``, the paper's standard
    queries first). :class:`rac.core.diagnostics.CheckError` when the file has errors; ``ValueError``
    when it has no ``model`` block; :class:`UnknownQuery` when ``options.only`` names a missing query."""
    return run_queries(result, options)[1]


def run_queries(result: CompileResult | CheckedProgram, options: VerifyOptions | None = None, *,
                answered: list[QueryResult] | None = None) -> tuple[Context, list[QueryResult]]:
    """:func:`verify`, also returning the context, which keeps the strategies the queries computed
    (:attr:`~Context.strategies` for shields, :attr:`~Context.learned` and :meth:`~Context.learned_run`
    for learned ones). Each result is appended to ``answered`` (when given) as soon as it is found: after
    Ctrl-C (``KeyboardInterrupt``) it holds the queries answered before."""
    options = options or VerifyOptions()
    context = Context(result, options)
    decls: list[tuple[iq.QueryDecl, str | None]] = []
    if options.standard:
        decls += [(d, d.title or None) for d in standard_queries(context.program, options.horizon)]
    decls += [(d, None) for d in context.automaton.queries]
    # each seeded query's seed by its place in the whole list, before --query selects (Context.next_seed)
    slots = {id(d): k for k, d in enumerate(d for d, _ in decls if isinstance(d.query, SEEDED))}
    if options.only is not None:
        decls = _selected(decls, options.only)
    verifier = Verifier(context, slots)
    results = verifier.run(decls, answered=answered)
    verifier.symbolic.settle(results)
    return context, results


def _selected(decls: list[tuple[iq.QueryDecl, str | None]], only: tuple[str, ...]
              ) -> list[tuple[iq.QueryDecl, str | None]]:
    """The queries named in ``only``, and the strategies they use, in order."""
    known = {d.name for d, _ in decls}
    missing = [name for name in only if name not in known]
    if missing:
        raise UnknownQuery(", ".join(missing))
    # A query `under S` needs S: keep the strategies it names, in order. Backwards, so that a
    # strategy learned `under` a shield brings the shield too (a strategy precedes its uses).
    wanted = set(only)
    for decl, _ in reversed(decls):
        under = getattr(decl.query, "under", None)
        if decl.name in wanted and under:
            wanted |= {d.name for d, _ in decls if getattr(d.query, "name", None) == under}
    return [(d, t) for d, t in decls if d.name in wanted]


def _defines(query: iq.Query) -> str | None:
    """The strategy a query defines (a shield or a learned strategy), if any."""
    name = getattr(query, "name", None)
    return name if isinstance(query, (iq.ControlStrategy, iq.LearnStrategy)) and isinstance(name, str) else None


def _method(query: iq.Query, context: Context) -> str:
    """How a verdict was reached when its answerer did not say: the complete graph for the symbolic
    queries, simulation for the statistical ones, the one run under a learned strategy."""
    if isinstance(query, iq.PathQuery) and query.under is not None and query.under in context.learned:
        return "strategy run"
    if isinstance(query, (iq.PathQuery, iq.LeadsToQuery, iq.ControlStrategy)):
        return "exhaustive"
    if isinstance(query, iq.LearnStrategy):
        return "learning"
    return "simulation"


def _kind(query: iq.Query) -> str:
    """The kind a result reports (``symbolic``, ``strategy``, ``probability``, ...)."""
    return {iq.PathQuery: "symbolic", iq.LeadsToQuery: "symbolic", iq.ControlStrategy: "strategy",
            iq.ProbabilityQuery: "probability", iq.ExpectationQuery: "expectation",
            iq.SimulateQuery: "simulate"}.get(type(query), "learning")


def _ending_refusal(automaton: ir.Automaton, query: iq.Query, learned: Mapping[str, object]) -> str | None:
    """Why ``query`` is not answered for an automaton whose ``episode ends when`` ends runs early,
    None when it is. The emitted UPPAAL model ends a run there (its Timer stops); the product of
    model and automaton does too, and so do learning's episodes, but the engines over the scenario
    model alone (shields, runs, ``-->``) go on to the horizon, so their answers would differ."""
    if automaton.ending is None:
        return None
    if isinstance(query, iq.LearnStrategy):
        return None  # learning's episodes end where the automaton ends them
    if isinstance(query, iq.PathQuery) and (query.under is None or query.under in learned):
        return None  # the product of model and automaton (SymbolicAnswerer.path), or a learned run
    return ("the automaton ends runs early (`episode ends when`), as the emitted UPPAAL model does, but this "
            "query is answered on the scenario model alone, whose runs go on to the horizon, so the two would "
            "answer differently; rac answers path queries (A[], E<>, E[], A<>) without `under` here, on the "
            "product of model and automaton")
