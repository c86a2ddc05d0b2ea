"""``rac verify``'s statistical queries: ``Pr[...]``, ``Pr[...] >= θ``, ``E[...]`` and ``simulate``
(a mixin of :class:`rac.verify.runner._Verifier`; see :mod:`rac.verify.runner`)."""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Iterable

import numpy as np

from rac.engine import storm
from rac.engine.evaluate import EvaluationError, Frame
from rac.engine.explore import explore
from rac.ir import expr as ie
from rac.ir import query as iq
from rac.model.data import ModelRangeError
from rac.verify.report import QueryResult, _count, _plot, _Unknown, _write_csv

__all__ = ["StatisticalQueries"]


class StatisticalQueries:
    """Simulation-based answers (UPPAAL's SMC semantics, :mod:`rac.engine.simulate`)."""

    def _runs(self, n: int, samples: int, under: str | None, seed: int):
        """``n`` runs of ``samples`` samples: actions drawn uniformly (among a shield's with
        ``under``), or, under a learned strategy, its one deterministic run ``n`` times."""
        from rac.engine.simulate import simulate

        if under is not None and under in self.learned:
            _, one = self.learned_run(under, samples)
            return dataclasses.replace(one, **{name: np.repeat(getattr(one, name), n, axis=0)
                                               for name in ("states", "truth", "actions", "left_policy")})
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

    def values(self, runs, exprs: tuple[ie.Expr, ...]) -> list[np.ndarray]:
        """Each expression per run and sample: ``(N, T+1)`` arrays."""
        columns: list[list[np.ndarray]] = [[] for _ in exprs]
        for frame in self.frames(runs):
            for column, expr in zip(columns, exprs):
                column.append(np.asarray(self.evaluator.evaluate(expr, frame), dtype=np.float64))
        return [np.stack(column, axis=1) for column in columns]

    def _statistical_check(self, exprs: Iterable[ie.Expr]) -> None:
        for expr in exprs:
            if self.needs_product(expr):
                raise _Unknown("statistical queries over the automaton's names are not supported yet "
                               "(the model's vocabulary is)")

    def probability(self, query: iq.ProbabilityQuery, base: QueryResult) -> QueryResult:
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
            op, threshold = query.compare
            theta = float(threshold)
            if query.runs is not None:
                raise EvaluationError("a probability compared with a threshold is tested sequentially, which "
                                      "chooses the number of runs (as UPPAAL does): drop `;N` from the bound")
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

    def exact_probability(self, query: iq.ProbabilityQuery, samples: int) -> float | None:
        """``Pr[<=T](<> p)`` (or ``[] p``) under uniform choices, exactly, by Storm on the explored
        model — when ``p`` reads only the sensed model and the model up to ``T`` is small enough."""
        if query.under is not None or ie.uses_prev(query.expr) or ie.reads_truth(query.expr):
            return None
        if samples == self.horizon_samples and False in self.graphs:
            graph = self.graphs[False]  # the exhaustive queries' graph: the same model, the same horizon
        else:
            try:
                graph = explore(self.data, horizon_samples=samples,
                                max_states=min(self.options.max_states, 2_000_000))
            except (MemoryError, ModelRangeError):
                return None
        p = self.label(graph, query.expr)
        every = query.path == "[]"
        reached = storm.uniform_reach_probability(dataclasses.replace(graph, labels={"event": ~p if every else p}),
                                                  "event")
        return 1.0 - reached if every else reached

    def expectation(self, query: iq.ExpectationQuery, base: QueryResult) -> QueryResult:
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

    def simulate(self, query: iq.SimulateQuery, base: QueryResult) -> QueryResult:
        self._statistical_check(query.exprs)
        samples = self.bound_samples(query.bound)
        n = self.runs_of(query.runs, 1)
        seed = self.next_seed()
        runs = self._runs(n, samples, query.under, seed)
        values = self.values(runs, query.exprs)
        files: list[str] = []
        names = list(query.labels)
        if self.out_dir is not None:
            files.append(str(_write_csv(self.out(f"{base.name}.csv"), runs.times, names, values)))
            if self.options.plots:
                files.append(str(_plot(self.out(f"{base.name}.png"), runs.times, names, values, base.formula)))
        message = f"{_count(n, 'run')} of {samples} samples"
        if len(values) == 2 and np.ptp(values[1]) == 0:
            below = int(np.any(values[0] < values[1], axis=1).sum())
            message += f"; {below} of {n} runs go below {names[1]} = {float(values[1].flat[0]):g}"
        return dataclasses.replace(base, status="value", runs=n, horizon_samples=samples, seed=seed,
                                   files=tuple(files), message=message,
                                   estimate=float(np.min(values[0])) if values else None)
