"""``rac verify``'s learning queries (``strategy S = maxE(...)...``), learned by tabular Q-learning
(:mod:`rac.learning.qlearning`), and path queries ``under`` a learned strategy, answered on its one run."""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from typing import TYPE_CHECKING

import numpy as np

from rac.engine.budget import BudgetExceeded, TimeExceeded
from rac.engine.evaluate import EvaluationError
from rac.engine.graph import ExploredGraph
from rac.engine.simulate import label_runs
from rac.ir import query as iq
from rac.ir.text import format_checked
from rac.ir.vocabulary import EGO_STATE
from rac.learning import qlearning as learning
from rac.learning.optimum import shortfall, solve
from rac.verify.context import Context, Learned, UnknownVerdict, restricted
from rac.verify.report import TRACE_FLAGS, QueryResult, TraceRow, format_number

if TYPE_CHECKING:  # rac.learning is imported when a query learns (rac verify without one never loads it)
    from rac.engine.shield import ShieldTable
    from rac.learning.optimum import Optimum
    from rac.learning.qlearning import LearningResult, StrategyRun

__all__ = ["LearningAnswerer"]


class LearningAnswerer:
    """Learns strategies (kept in the context's :attr:`~rac.verify.context.Context.learned` for later
    queries ``under`` them) and answers path queries on a learned strategy's run."""

    def __init__(self, context: Context) -> None:
        self.context = context

    def learn(self, query: iq.LearnStrategy, base: QueryResult) -> QueryResult:
        """Q-learning (:func:`rac.learning.qlearning.learn`) on episodes ending at the first sample where
        ``p`` holds or at the bound. As in UPPAAL, ``maxE(e)`` maximises the value of ``e`` when the
        episode ends; the reward of a step is the increase of ``e`` over it, so the returns add up
        to that value. For ``e`` over the automaton's accumulating rewards (``10*sa + 5*pr + co``)
        the signal is dense; for a reward function of the current state (the paper's Eq. 9) only
        its value in the last state counts."""
        # tqdm (via rac.output.progress): importing rac.verify.learning stays light
        from rac.output.progress import Progress

        ctx = self.context
        if query.path != "<>":
            raise EvaluationError("only reachability goals (`: <> p`) are learned, as in UPPAAL")
        table = None
        if query.under is not None:
            if query.under in ctx.learned:
                raise EvaluationError(f"learning under the learned strategy `{query.under}` is not supported "
                                      "(only under a shield: `strategy S = control: A[] ...`)")
            table = ctx.shield_table(query.under)
        samples = ctx.bound_samples(query.bound)
        past = None if query.under is None else ctx.past_shield(query.under, samples)
        if past is not None:  # there learning (and the optimum) would choose among all actions, unshielded
            raise EvaluationError(past)
        if samples < 1:
            raise UnknownVerdict("the time bound is shorter than one sample")
        meta = {"query": base.formula, "objective": format_checked(query.objective),
                "goal": format_checked(query.expr), "under": query.under, "horizon_samples": samples,
                "reward": "the objective's increase per step (summed: its value at the episode's end minus its "
                "value at the start)"}
        if ctx.options.exact:
            return self._exact(query, base, table, samples, meta)
        batch = ctx.episodes("automaton", query.expr, samples)
        seed = ctx.next_seed()
        bar = Progress(total=ctx.options.learn_episodes, desc=f"learning {query.name}", unit="episodes",
                       enabled=None if ctx.options.bars else False)

        def report(done: int, budget: int, mean_return: float) -> None:
            bar.set_postfix(mean_return=f"{mean_return:.1f}")
            bar.update(done - bar.n)
            ctx.limit.check()  # --max-seconds, once per batch of episodes

        try:
            with bar:
                outcome = learning.learn(learning.ObjectiveIncrease(batch, query.objective),
                                         progress=report, discrete=query.discrete, continuous=query.continuous,
                                         optimise="max" if query.optimise == "maxE" else "min", shield=table,
                                         episodes=ctx.options.learn_episodes, parallel=ctx.options.learn_parallel,
                                         seed=seed, stop_after=ctx.options.learn_stop_after, meta=meta,
                                         labels=query.labels, max_bytes=ctx.memory_left())
        except EvaluationError:
            raise
        except BudgetExceeded as exc:  # refused on the estimate, before learning allocated it
            raise UnknownVerdict(f"{exc}{ctx.kept_note()}; the episode budget is --learn-episodes") from None
        except ValueError as exc:  # a sensed value out of range, bindings breaking `assume`
            raise UnknownVerdict(str(exc)) from None
        ctx.strategies.pop(query.name, None)  # the name now means the learned strategy
        ctx.deferred.pop(query.name, None)
        ctx.learned[query.name] = Learned(outcome.strategy, table, (*query.discrete, *query.continuous))
        files: tuple[str, ...] = ()
        if ctx.out_dir is not None:
            files = (str(outcome.strategy.save(ctx.out(f"{query.name}.strategy.npz"))),)
        learned = float(outcome.greedy.returns[0])
        optimum = self._optimum(query, table, samples, meta)
        start = self._start_value(query, samples)
        message = self._message(outcome, query, start) + "\n" + self._beside(learned, optimum, query)
        if not isinstance(optimum, str) and optimum.run.success[0] and not outcome.greedy.success[0]:
            # learning missed what the shield allows: say how to get the strategy that does not
            message += (f"; the optimal run reaches {format_checked(query.expr)} safely: `rac verify --exact` "
                        "emits that strategy instead of learning one")
        return dataclasses.replace(base, status="value", estimate=learned,
                                   runs=outcome.episodes, horizon_samples=samples, seed=seed, files=files,
                                   message=message, optimum=self._optimum_fields(optimum, learned, query, start))

    def _optimum(self, query: iq.LearnStrategy, table: ShieldTable | None, samples: int,
                 meta: Mapping[str, object]) -> Optimum | str:
        """The exact optimum of the learning query (:func:`rac.learning.optimum.solve`) on the episodes
        learning sees, or why it is out of reach (the budget: ``--max-states``, ``--max-memory``). Beside a
        learned strategy the search gives up as soon as its layers project far beyond ``--max-states``
        (``project``); ``--exact`` asks for the optimum itself and explores to the budget."""

        ctx = self.context
        try:
            batch = ctx.episodes("automaton", query.expr, samples)
            # per layer: the bar, and --max-seconds (past it the optimum is out of reach; under --exact, so
            # is the answer)
            return solve(batch, objective=query.objective, optimise="max" if query.optimise == "maxE" else "min",
                         shield=table, max_states=ctx.options.max_states, max_bytes=ctx.memory_left(),
                         meta=meta, project=not ctx.options.exact, progress=ctx.explore_progress)
        except BudgetExceeded as exc:
            return f"{exc}{ctx.kept_note()}"
        except TimeExceeded as exc:
            return f"{exc} (--max-seconds)"
        except (UnknownVerdict, ValueError) as exc:  # a sensed value out of range, bindings breaking `assume`
            return str(exc)

    @staticmethod
    def _beside(learned: float, optimum: Optimum | str, query: iq.LearnStrategy) -> str:
        """The learned return beside the optimum: "learned return X, optimum Y (how), Z% below"."""

        if isinstance(optimum, str):
            return f"optimum out of reach ({optimum}): the learned strategy stands alone"
        gap = shortfall(learned, optimum.value, optimum.optimise)
        worse = "below" if optimum.optimise == "max" else "above"
        text = (f"learned return {format_number(learned)}, optimum {format_number(optimum.value)} ({optimum.method}), "
                f"{100 * gap:.1f}% {worse}")
        if not optimum.run.success[0]:
            text += f"; the optimal run does not reach {format_checked(query.expr)} safely"
        # how hard the goal is to find by exploring: what a learner can expect before it has learned anything
        return text + f"\n{optimum.exploration}"

    @staticmethod
    def _optimum_fields(optimum: Optimum | str, learned: float | None, query: iq.LearnStrategy, start: float
                        ) -> dict[str, object]:
        """The optimum as ``--format json`` writes it, with the objective's value at the start (a return
        is its increase from there)."""

        if isinstance(optimum, str):
            return {"out_of_reach": optimum, "objective_at_start": start}
        fields: dict[str, object] = {
            "value": optimum.value, "backward_pass": optimum.backward, "states": optimum.states,
            "edges": optimum.edges, "additive": optimum.additive, "why_not_additive": optimum.why,
            "method": optimum.method, "arithmetic": "float64, as learning's rewards",
            "reaches_goal_safely": bool(optimum.run.success[0]), "actions": optimum.run.actions[0].tolist(),
            "seconds": optimum.seconds, "uniform_success": optimum.uniform_success, "objective_at_start": start}
        if learned is not None:
            fields["learned"] = learned
            fields["shortfall"] = shortfall(learned, optimum.value, optimum.optimise)
        return fields

    def _exact(self, query: iq.LearnStrategy, base: QueryResult, table: ShieldTable | None, samples: int,
               meta: Mapping[str, object]) -> QueryResult:
        """``rac verify --exact``: the optimal strategy instead of a learned one, kept and saved like one
        (queries ``under`` it decide on its one run)."""
        ctx = self.context
        optimum = self._optimum(query, table, samples, meta)
        if isinstance(optimum, str):
            raise UnknownVerdict(f"the exact optimum is out of reach: {optimum}")
        ctx.strategies.pop(query.name, None)  # the name now means the optimal strategy
        ctx.deferred.pop(query.name, None)
        ctx.learned[query.name] = Learned(optimum.strategy, table, optimum.observed)
        files: tuple[str, ...] = ()
        if ctx.out_dir is not None:
            files = (str(optimum.strategy.save(ctx.out(f"{query.name}.strategy.npz"))),)
        start = self._start_value(query, samples)
        message = (f"the optimal strategy ({optimum.method}; {optimum.edges:,} choices, {optimum.seconds:.2f} s): "
                   f"its run {self._run_text(optimum.run, query)}, return {format_number(optimum.value)}"
                   f"{self._from_start(optimum.value, start, query)}")
        return dataclasses.replace(base, status="value", estimate=optimum.value, states=optimum.states,
                                   horizon_samples=samples, files=files, message=message, method="exact optimum",
                                   optimum=self._optimum_fields(optimum, None, query, start))

    def _start_value(self, query: iq.LearnStrategy, samples: int) -> float:
        """The objective's value at the episodes' start: a return (the sum of its increases) is its value
        at the end minus this."""
        batch = self.context.episodes("automaton", query.expr, samples)
        batch.reset(1)
        return float(batch.observe([batch.expression(query.objective)])[0, 0])

    @staticmethod
    def _from_start(value: float, start: float, query: iq.LearnStrategy) -> str:
        """After a return: the objective's value at the start and at the end, when it is not 0 at the
        start (then the return, its increase, is not its value at the end)."""
        if start == 0:
            return ""
        return (f" (the increase of {format_checked(query.objective)} from {format_number(start)} at the start: "
                f"{format_number(start + value)} at the end)")

    def _run_text(self, run: StrategyRun, query: iq.LearnStrategy) -> str:
        """What a strategy's one run does: reaches the goal safely at some time, or not."""
        goal = format_checked(query.expr)
        at = f"{int(run.samples_taken[0]) * float(self.context.period):g} s"
        if run.success[0]:
            return f"reaches {goal} safely at {at}"
        if run.reached[0]:
            unsafe = "collides" if run.collided[0] else "leaves the road"
            return f"reaches {goal} at {at} but {unsafe}"
        return f"does not reach {goal}"

    def _message(self, outcome: LearningResult, query: iq.LearnStrategy, start: float = 0.0) -> str:
        """What learning found: the greedy run (its return, and the objective's value at the end when it
        was not 0 at the ``start``), when learning first succeeded, what went wrong on the way."""
        run = self._run_text(outcome.greedy, query)
        first = (f"first after {outcome.first_success_episode} episodes" if outcome.first_success_episode is not None
                 else "never")
        if outcome.first_success_episode is None:
            proof = self._unreachable(query)
            if proof is not None:
                first = f"never: {proof}"
        stop = ", stopped early" if outcome.stopped_early else ""
        learned = float(outcome.greedy.returns[0])
        lines = [f"learned in {outcome.episodes} episodes{stop}: the greedy run {run}, return "
                 f"{format_number(learned)}{self._from_start(learned, start, query)}",
                 f"greedy run safe until the goal: {first}; learning episodes that collided: "
                 f"{outcome.collisions_during_learning}, left the road: {outcome.offroad_during_learning}; "
                 f"{outcome.strategy.n_states:,} observations"]
        if outcome.fallbacks:
            lines.append(f"{outcome.fallbacks} decisions where `{query.under}` allowed no action chose among the "
                         "actions proved safe the longest where its search knew some, else among all")
        return "\n".join(lines)

    def _unreachable(self, query: iq.LearnStrategy) -> str | None:
        """Why no episode can succeed, when a complete graph proves it: no run the shield ``under``
        allows (or, without a shield, no run that stays safe) reaches the goal within the bound. None
        when there is no such graph or it does not prove it (its horizon is shorter than the bound,
        the goal reads the automaton)."""
        ctx = self.context
        samples = ctx.bound_samples(query.bound)
        graph: ExploredGraph | None
        if query.under is not None and query.under in ctx.on_demand:
            return None  # a shield computed state by state has no graph to prove anything on
        if query.under is not None:
            graph = restricted(ctx.strategy(query.under)[0])
            runs = f"no run the shield `{query.under}` allows"
        else:
            graph = ctx.graphs.get(True)  # the pruned model: unsafe states end a run there
            runs = "no run that stays safe"
        if graph is None or not graph.complete or samples > ctx.horizon_samples:
            return None
        try:
            goal = ctx.label(graph, query.expr)
        except EvaluationError:
            return None
        k = graph.states[:, graph.columns.index("k")]
        safe_goal = goal & graph.labels["safe"] & (k <= samples)
        if np.any(safe_goal & graph.reachable()):
            return None
        when = f"{samples * float(ctx.period):g} s"
        return (f"{runs} reaches {format_checked(query.expr)} safely within {when} (the complete graph proves it), "
                "so no episode can succeed")

    def path_under_learned(self, query: iq.PathQuery, under: str, base: QueryResult) -> QueryResult:
        """``A[] p``, ``E[] p``, ``A<> p``, ``E<> p`` under the learned strategy ``under``: the model and
        the greedy strategy are deterministic, so there is one run, followed to the horizon (it does not
        stop at the learning goal) and replayed sample by sample (:meth:`StrategyRun.samples`):
        ``[]`` holds iff ``p`` holds at every sample of it, ``<>`` iff at some sample."""

        ctx = self.context
        period = float(ctx.period)
        # p is evaluated on the replayed samples, which hold the model and the ground truth: the
        # evaluator reports a name of the automaton (a location, a reward, an input) as unsupported.
        run, runs = ctx.learned_run(under, ctx.horizon_samples)
        holds = np.array([bool(ctx.evaluator.evaluate_bool(query.expr, frame)[0]) for frame in ctx.frames(runs)])
        always = query.quantifier in ("A[]", "E[]")
        verdict = bool(holds.all()) if always else bool(holds.any())
        decisive = np.flatnonzero(~holds if always else holds)
        end = int(decisive[0]) if decisive.size else holds.size - 1
        scale = float(ctx.data.scale)
        labels = {name: label_runs(ctx.data, runs, name)[0] for name in TRACE_FLAGS}
        rows = []
        for k in range(end + 1):
            row: TraceRow = {"time": round(k * period, 9)}
            row.update({name: int(runs.states[0, k, i]) / scale for i, name in enumerate(EGO_STATE)})
            row.update({name: bool(values[k]) for name, values in labels.items()})
            rows.append(row)
        if decisive.size:
            outcome = f"{'fails' if always else 'holds'} at {end * period:g} s"
        else:
            outcome = "holds at every sample" if always else "holds at no sample"
        message = (f"the one run under `{under}` (deterministic model and strategy): "
                   f"{format_checked(query.expr)} {outcome}")
        if run.fallbacks[0]:
            message += f"; at {int(run.fallbacks[0])} decisions the shield allowed no action"
        return dataclasses.replace(base, status="satisfied" if verdict else "not satisfied", states=holds.size,
                                   horizon_samples=ctx.horizon_samples, trace=tuple(rows), message=message)
