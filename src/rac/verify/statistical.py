"""``rac verify``'s statistical queries: ``Pr[...]``, ``Pr[...] >= θ``, ``E[...]`` and ``simulate``,
answered on runs simulated with actions drawn uniformly (among a shield's with ``under``) and the
ground truth integrated finely (UPPAAL's SMC semantics, :mod:`rac.engine.simulate`)."""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Iterable, Sequence
from fractions import Fraction
from typing import TYPE_CHECKING

import numpy as np

from rac.core.diagnostics import counted, short_number
from rac.core.resources import memory_option
from rac.engine import storm
from rac.engine.budget import TimeExceeded, format_bytes, runs_within, simulation_bytes
from rac.engine.evaluate import EvaluationError
from rac.engine.explore import explore
from rac.engine.simulate import simulate
from rac.ir import expr as ie
from rac.ir import query as iq
from rac.ir.text import format_checked
from rac.model.data import ModelRangeError
from rac.model.native import NO_OBSTACLE, NO_OBSTACLE_TEXT
from rac.verify.context import Context, UnknownVerdict, left_int32
from rac.verify.report import QueryResult, plot_series, write_runs
from rac.verify.status import NOT_SATISFIED, SATISFIED

if TYPE_CHECKING:
    from rac.engine.simulate import Runs

__all__ = ["StatisticalAnswerer"]


#: ``Pr[..](..) op θ`` that holds (or fails) for every probability: decided without a run.
_TRIVIAL: dict[tuple[str, Fraction], bool] = {(">=", Fraction(0)): True, ("<=", Fraction(1)): True,
                                              (">", Fraction(1)): False, ("<", Fraction(0)): False}

#: The most runs ``E[<=T;N](max: e)`` simulates at once (its chunks), whatever the memory budget allows.
EXPECTATION_CHUNK = 1_000_000


class StatisticalAnswerer:
    """Answers probability, expectation and ``simulate`` queries; each draws its own seed from the
    context (reported with the result)."""

    def __init__(self, context: Context) -> None:
        self.context = context

    def probability(self, query: iq.ProbabilityQuery, base: QueryResult) -> QueryResult:
        """``Pr[<=T](<> p)`` or ``[] p``: a Clopper–Pearson interval (with ``;N`` runs, else until its
        half-width is at most epsilon) and the exact value where Storm can give it;
        ``Pr[...] >= θ``: a sequential test."""
        from rac.engine import stats  # scipy (via rac.engine.stats): importing rac.verify.statistical stays light

        ctx = self.context
        _refuse_automaton_names([query.expr])
        samples = ctx.bound_samples(query.bound)
        seed = ctx.next_seed()
        batch_seeds = np.random.SeedSequence(seed)
        every = query.path == "[]"

        chunk = self.chunk(1, samples, "this probability")

        def sample(n: int) -> np.ndarray:
            runs = self.runs(n, samples, query.under, int(batch_seeds.spawn(1)[0].generate_state(1)[0]),
                             (query.expr,), stop_at_overflow=True)
            holds = ctx.values(runs, (query.expr,))[0] != 0
            return _path_outcomes(holds, every, runs, query)

        if query.compare is not None:
            op, threshold = query.compare
            theta = float(threshold)
            if query.runs is not None:
                raise EvaluationError("a probability compared with a threshold is tested sequentially, which "
                                      "chooses the number of runs (as UPPAAL does): drop `;N` from the bound")
            if op not in (">=", "<=", ">", "<"):
                raise EvaluationError(f"a sequential test tells a probability above a threshold from one below it, "
                                      f"so it cannot decide `{op}`: ask for the probability itself (drop "
                                      f"`{op} {short_number(threshold)}`)")
            if (op, threshold) in _TRIVIAL:  # `Pr[..](..) >= 0` holds of every probability: no run decides it
                return dataclasses.replace(base, status=SATISFIED if _TRIVIAL[op, threshold] else NOT_SATISFIED,
                                           method="probability bounds", horizon_samples=samples,
                                           message=f"every probability lies in [0, 1], so `{op} "
                                                   f"{short_number(threshold)}` needs no run")
            # the indifference region [theta - delta, theta + delta] must lie within [0, 1]: at a threshold
            # nearer to 0 or 1 than delta it is moved inward, still holding the threshold
            centre = min(max(theta, ctx.options.delta), 1.0 - ctx.options.delta)
            test = stats.sequential_test(sample, centre, alpha=ctx.options.alpha, beta=ctx.options.beta,
                                         delta=ctx.options.delta, batch=min(stats.DEFAULT_BATCH, chunk))
            accepted = test.accepted if op in (">=", ">") else not test.accepted
            status = "satisfied" if accepted else "not satisfied"
            # a statistical verdict, not a proof: its error bound, and where it has none (UPPAAL's -a, -B, -u)
            wrong = ctx.options.beta if test.accepted else ctx.options.alpha
            message = (f"decided by Wald's sequential test: wrong with probability at most {wrong:g} if the "
                       f"probability lies outside [{centre - ctx.options.delta:g}, {centre + ctx.options.delta:g}] "
                       "(within it either answer may come)")
            if not test.decided:  # the estimate's side of theta carries no error bound: not a verdict
                status = "unknown"
                message = (f"the sequential test did not decide within {test.runs:,} runs (its budget): the "
                           f"probability, about {test.successes / test.runs:.4f}, lies too near {theta:g} (within "
                           f"±{ctx.options.delta:g}, where either answer may come)")
            one = self._one_run(query.under)
            if one is not None and test.runs:  # every run the same: the probability is exactly 0 or 1
                message += (f"; {one}, so the probability is exactly {test.successes // test.runs} and the "
                            "verdict holds with no error")
            return dataclasses.replace(base, status=status, runs=test.runs,
                                       estimate=test.successes / test.runs if test.runs else None,
                                       horizon_samples=samples, seed=seed, message=message)
        if query.runs is not None:
            estimate = stats.estimate_probability_fixed(sample, query.runs, confidence=ctx.options.confidence,
                                                        batch=min(query.runs, chunk))
        else:
            estimate = stats.estimate_probability(sample, epsilon=ctx.options.epsilon,
                                                  confidence=ctx.options.confidence,
                                                  batch=min(stats.DEFAULT_BATCH, chunk))
        wider = None if estimate.converged else (
            f"the run budget ({estimate.runs:,} runs) ran out before the interval was ±{ctx.options.epsilon:g} "
            f"wide: it is ±{estimate.half_width:.4f} (--epsilon)")
        one = self._one_run(query.under)
        if one is not None:  # the interval is what N runs give (UPPAAL's too); the value itself is known
            wider = (f"{one}, so the probability is exactly {estimate.estimate:g}; the interval is the one "
                     f"{counted(estimate.runs, 'run')} give, as UPPAAL's")
        return dataclasses.replace(base, status="value", interval=(estimate.lo, estimate.hi),
                                   estimate=estimate.estimate, runs=estimate.runs, horizon_samples=samples,
                                   seed=seed, confidence=ctx.options.confidence, message=wider,
                                   exact=self.exact_probability(query, samples))

    def exact_probability(self, query: iq.ProbabilityQuery, samples: int) -> float | None:
        """``Pr[<=T](<> p)`` (or ``[] p``) under uniform choices, exactly, by Storm on the explored
        model — when ``p`` reads only the sensed model and the model up to ``T`` is small enough."""
        ctx = self.context
        if query.under is not None or ie.uses_prev(query.expr) or ie.reads_truth(query.expr):
            return None
        if samples == ctx.horizon_samples and False in ctx.graphs:
            graph = ctx.graphs[False]  # the exhaustive queries' graph: the same model, the same horizon
        else:
            try:
                # within --max-memory as every exploration (with Storm's share), and --max-seconds (checked per
                # layer, with the bar): beyond either the value is left out, the simulated answer stands
                graph = explore(ctx.data, horizon_samples=samples, progress=ctx.explore_progress,
                                max_states=min(ctx.options.max_states, 2_000_000), max_bytes=ctx.memory_left())
            except (MemoryError, ModelRangeError, TimeExceeded):
                return None
        p = ctx.label(graph, query.expr)
        every = query.path == "[]"
        reached = storm.uniform_reach_probability(dataclasses.replace(graph, labels={"event": ~p if every else p}),
                                                  "event")
        return 1.0 - reached if every else reached

    def expectation(self, query: iq.ExpectationQuery, base: QueryResult) -> QueryResult:
        """``E[<=T;N](max: e)`` (or ``min``): the mean over runs of each run's extreme of ``e``, with
        its confidence interval (infinite for one run)."""
        from rac.engine import stats  # scipy (via rac.engine.stats): importing rac.verify.statistical stays light

        ctx = self.context
        _refuse_automaton_names([query.expr])
        samples = ctx.bound_samples(query.bound)
        n = _runs_of(query.runs)
        seed = ctx.next_seed()
        # at most EXPECTATION_CHUNK runs at once even where memory allows more: half the machine's memory held
        # tens of millions of runs whose every sample took half a minute, past any --max-seconds and Ctrl-C
        chunk = min(self.chunk(1, samples, f"`{base.name}`"), EXPECTATION_CHUNK)
        # Runs in chunks that fit the memory budget, the mean aggregated as they come; the chunks' seeds
        # derive from the query's, so the answer depends on the seed and the budget only.
        seeds = np.random.SeedSequence(seed)
        running = stats.RunningMean()
        for start in range(0, n, chunk):
            ctx.limit.check()  # --max-seconds, between chunks as within them
            count = min(chunk, n - start)
            chunk_seed = seed if count == n else int(seeds.spawn(1)[0].generate_state(1)[0])
            values = ctx.values(self.runs(count, samples, query.under, chunk_seed, (query.expr,)), (query.expr,))[0]
            extremes = values.max(axis=1) if query.aggregate == "max" else values.min(axis=1)
            if not np.isfinite(extremes).all():  # a mean of them would be `nan ± nan`, printed as a value
                nan = int(np.isnan(extremes).sum())
                where = " and ".join(f"{what} in {k:,} of {count:,} runs" for what, k in
                                     (("not a number", nan), ("infinite", extremes.size - nan)) if k)
                raise EvaluationError(
                    f"the {query.aggregate} of `{format_checked(query.expr)}` over a run is {where} (a square root "
                    "of a negative number, a division by zero at some sample), so their mean has no value")
            running.add(extremes)
            last = float(extremes[-1])
        if n >= 2:
            mean, half = running.interval(ctx.options.confidence)
        else:
            mean, half = running.mean, math.inf
        one = self._one_run(query.under)
        # the one run's value itself (shortest repr): the mean of n copies of it may differ in its last bit
        exactly = None if one is None else f"{one}, so the value is exactly {last!r}"
        return dataclasses.replace(base, status="value", estimate=mean, interval=(mean - half, mean + half), runs=n,
                                   horizon_samples=samples, seed=seed, confidence=ctx.options.confidence,
                                   message=exactly)

    def _one_run(self, under: str | None) -> str | None:
        """What makes every run under ``under`` the same, when it is a learned strategy (None otherwise)."""
        if under is None or under not in self.context.learned:
            return None
        return f"every run is the one run of the strategy `{under}` (it and the model are deterministic)"

    def simulate(self, query: iq.SimulateQuery, base: QueryResult) -> QueryResult:
        """``simulate[<=T;N]{e...}``: the expressions per run and sample, written to ``OUT/NAME.csv``
        and plotted (``OUT/NAME.png``); the message counts the runs below a constant second one."""
        ctx = self.context
        _refuse_automaton_names(query.exprs)
        samples = ctx.bound_samples(query.bound)
        n = _runs_of(query.runs)
        seed = ctx.next_seed()
        if n > self.chunk(len(query.exprs), samples, f"`{base.name}`"):
            fit = runs_within(ctx.memory_left(), samples, len(query.exprs))
            raise UnknownVerdict(
                f"simulate keeps every run's trace: {n:,} runs of {samples + 1} samples would need about "
                f"{format_bytes(simulation_bytes(n, samples, len(query.exprs)))}, more than the memory budget of "
                f"{self.budget_text()}: ask for at most {fit:,} runs, or raise {memory_option()}{ctx.kept_note()}")
        runs = self.runs(n, samples, query.under, seed, query.exprs)
        values = ctx.values(runs, query.exprs)
        files: list[str] = []
        names = list(query.labels)
        if ctx.out_dir is not None:
            png = ctx.out(f"{base.name}.png")
            plot = (lambda: plot_series(png, runs.times, names, values, base.formula, query.exprs)) \
                if ctx.options.plots else None
            files += [str(path) for path in write_runs(ctx.out(f"{base.name}.csv"), runs.times, names, values, plot,
                                                       stale=png)]
        message = f"{counted(n, 'run')} of {samples} samples"
        if len(values) == 2 and np.ptp(values[1]) == 0:
            below = int(np.any(values[0] < values[1], axis=1).sum())
            message += f"; {below} of {n} runs go below {names[1]} = {float(values[1].flat[0]):g}"
        for name, expr, value in zip(names, query.exprs, values):
            if isinstance(expr, ie.Call) and expr.name == "mindist" and np.all(value == NO_OBSTACLE):
                none = "the scenario has none" if ctx.data.obstacle_count == 0 else "none within the horizon"
                message += (f"; no obstacle at any sample ({none}): `{name}` reads {NO_OBSTACLE_TEXT}, "
                            "its value without one")
        return dataclasses.replace(base, status="value", runs=n, horizon_samples=samples, seed=seed,
                                   files=tuple(files), message=message,
                                   estimate=float(np.min(values[0])) if values else None)

    def chunk(self, columns: int, samples: int, what: str) -> int:
        """The most runs of ``samples`` samples, with ``columns`` expressions evaluated on them, that fit
        the memory budget at once (:func:`rac.engine.budget.runs_within`); unknown when not even one does."""

        fit = runs_within(self.context.memory_left(), samples, columns)
        if fit < 1:
            raise UnknownVerdict(f"one run of {what} ({samples + 1} samples) would need about "
                                 f"{format_bytes(simulation_bytes(1, samples, columns))}, more than the memory "
                                 f"budget of {self.budget_text()}: raise it, or shorten the time bound"
                                 f"{self.context.kept_note()}")
        return fit

    def budget_text(self) -> str:
        """The memory budget runs get, as a refusal names it: ``--max-memory``, less what the graphs
        kept for later queries hold."""
        ctx = self.context
        left = ctx.memory_left()
        if left == ctx.options.max_bytes:
            return f"{format_bytes(left or 0)} ({memory_option()})"
        return f"{format_bytes(left or 0)} (what {memory_option()} leaves beside the kept graphs)"

    def runs(self, n: int, samples: int, under: str | None, seed: int, read: Sequence[ie.Expr], *,
             stop_at_overflow: bool = False) -> Runs:
        """``n`` runs of ``samples`` samples: actions drawn uniformly (among a shield's with
        ``under``), or, under a learned strategy, its one deterministic run ``n`` times. With
        ``stop_at_overflow`` a run whose sensed state leaves int32 stops there (:attr:`Runs.overflow`)
        instead of the whole batch raising :class:`ModelRangeError`. ``read``: the expressions the runs are read by;
        the ground truth is integrated only when one reads it (:func:`rac.ir.expr.reads_truth`)."""

        ctx = self.context
        if under is not None and under in ctx.learned:
            _, one = ctx.learned_run(under, samples)
            return dataclasses.replace(one, states=np.repeat(one.states, n, axis=0),
                                       truth=np.repeat(one.truth, n, axis=0),
                                       actions=np.repeat(one.actions, n, axis=0),
                                       left_policy=np.repeat(one.left_policy, n, axis=0))
        past = None if under is None else ctx.past_shield(under, samples)
        if past is not None:  # a shield ends at the horizon: said before any run is drawn
            raise EvaluationError(past)
        # tqdm (via rac.output.progress): importing rac.verify.statistical stays light
        from rac.output.progress import Progress, simulate_callback

        # a long time bound takes minutes per batch (a million samples of 0.1 s: over five): a bar on a
        # terminal, the samples in the heartbeat's line; the query said only its elapsed time before
        with Progress(total=samples, desc=f"simulating {counted(n, 'run')}", unit="samples",
                      enabled=None if ctx.options.bars else False) as bar:
            runs = simulate(ctx.data, runs=n, horizon_samples=samples, seed=seed, policy=ctx.policy(under),
                            progress=simulate_callback(bar, ctx.limit.check), stop_at_overflow=stop_at_overflow,
                            truth=any(ie.reads_truth(expr) for expr in read))
        stuck = int(runs.left_policy.sum())
        if stuck:  # the emitted model deadlocks there, and its run ends: rac's runs would go on
            who = " or ".join(([f"the strategy `{under}`"] if under is not None else [])
                              + (["the model's `allow when`"] if ctx.data.allow is not None else []))
            raise EvaluationError(f"{stuck:,} of {n:,} runs met a decision where {who or 'nothing'} allowed no "
                                  "action; the emitted model deadlocks there and ends the run, while rac's runs "
                                  "go on with any action, so the two would answer differently")
        return runs


def _path_outcomes(holds: np.ndarray, every: bool, runs: Runs, query: iq.ProbabilityQuery) -> np.ndarray:
    """Whether each run satisfies ``<> p`` (``[] p`` with ``every``), ``holds`` being ``p`` per run and
    sample. UPPAAL stops checking a run at the first sample that decides the path formula (``p`` for
    ``<> p``, ``!p`` for ``[] p``), so a run that stopped later because a sensed value left int32
    (:attr:`Runs.overflow`) is decided by its samples before that; one that stopped first has no
    outcome (UPPAAL's model aborts there), which leaves the query unknown, as every such run did."""
    if runs.overflow is None or not runs.overflow_errors:
        return np.asarray(holds.all(axis=1) if every else holds.any(axis=1))
    model_states = np.arange(holds.shape[1])[None, :] < runs.overflow[:, None]  # the samples before the stop
    decided = ((~holds if every else holds) & model_states).any(axis=1)  # !p for [] p, p for <> p, before it
    undecided = ~decided & (runs.overflow < holds.shape[1])
    if undecided.any():
        first = int(np.argmax(undecided))
        path = "[]" if every else "<>"
        count = int(undecided.sum())
        raise UnknownVerdict(
            f"{left_int32(runs.overflow_errors[first])} (sample {runs.overflow[first]}); in {count:,} of a batch "
            f"of {undecided.size:,} runs this came before `{path} {format_checked(query.expr)}` was decided, so "
            "whether they satisfy it is not known (UPPAAL's model aborts there too)")
    return np.asarray(~decided if every else decided)


def _runs_of(runs: int | None) -> int:
    """The runs a query asks for with ``;N`` (one without)."""
    return 1 if runs is None else runs


def _refuse_automaton_names(exprs: Iterable[ie.Expr]) -> None:
    """Unsupported when an expression reads the automaton's state: simulated runs hold the model only."""
    for expr in exprs:
        if ie.reads_automaton(expr):
            raise EvaluationError("statistical queries over the automaton's names are not supported yet "
                                 "(the model's vocabulary is)")
