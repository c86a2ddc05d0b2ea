"""``rac verify``'s learning queries (``strategy S = maxE(...)...``) and path queries ``under`` a
learned strategy (a mixin of :class:`rac.verify.runner._Verifier`; see :mod:`rac.verify.runner`)."""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from rac.engine import shield
from rac.engine.evaluate import EvaluationError
from rac.ir import expr as ie
from rac.ir import query as iq
from rac.ir.vocabulary import EGO_STATE
from rac.verify.report import QueryResult, _expr_text, _number, _Unknown

if TYPE_CHECKING:
    from rac.learning.episodes import EpisodeBatch
    from rac.learning.qlearning import LearnedStrategy, LearningResult

__all__ = ["LearningQueries"]


@dataclass(frozen=True)
class _Learned:
    """A learned strategy, the shield it was learned (and is run) under, and its observed expressions."""

    strategy: LearnedStrategy
    shield: shield.ShieldTable | None
    exprs: tuple[ie.Expr, ...]


class LearningQueries:
    """Q-learning of strategies (:mod:`rac.learning.qlearning`) and their verification."""

    def episodes(self, reward: str | ie.Expr, goal: ie.Expr | None, samples: int) -> EpisodeBatch:
        """Episodes of the model with the automaton (:class:`rac.learning.episodes.EpisodeBatch`)."""
        from rac.learning.episodes import EpisodeBatch

        try:
            return EpisodeBatch(self.result, reward=reward, goal=goal, horizon_samples=samples, data=self.data)
        except EvaluationError:
            raise  # an expression the engine cannot read: "unsupported"
        except ValueError as exc:
            raise _Unknown(str(exc)) from None

    def learn(self, query: iq.LearnStrategy, base: QueryResult) -> QueryResult:
        """Q-learning (:func:`rac.learning.qlearning.learn`) on episodes ending at the first sample where
        ``p`` holds or at the bound. As in UPPAAL, ``maxE(e)`` maximises the value of ``e`` when the
        episode ends; the reward of a step is the increase of ``e`` over it, so the returns add up
        to that value. For ``e`` over the automaton's accumulating rewards (``10*sa + 5*pr + co``)
        the signal is dense; for a reward function of the current state (the paper's Eq. 9) only
        its value in the last state counts."""
        from rac.learning import qlearning as learning

        if query.path != "<>":
            raise EvaluationError("only reachability goals (`: <> p`) are learned, as in UPPAAL")
        table = None
        if query.under is not None:
            if query.under in self.learned:
                raise EvaluationError(f"learning under the learned strategy `{query.under}` is not supported "
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
        from rac.output.progress import Progress

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
                                         seed=seed, stop_after=self.options.learn_stop_after, meta=meta,
                                         labels=query.labels)
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

    def _learning_message(self, outcome: LearningResult, query: iq.LearnStrategy) -> str:
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

    def learned_run(self, name: str, samples: int):
        """The one run of the learned strategy ``name`` over ``samples`` samples (it does not stop at
        the learning goal): the :class:`rac.learning.qlearning.StrategyRun` and its samples replayed as
        :class:`rac.engine.simulate.Runs` (one run, with the ground truth)."""
        from rac.learning.qlearning import run_strategy

        entry = self.learned[name]
        batch = self.episodes("automaton", None, samples)
        try:
            run = run_strategy(batch, entry.strategy, exprs=entry.exprs, shield=entry.shield)
            return run, run.samples(self.data)
        except EvaluationError:
            raise
        except ValueError as exc:
            raise _Unknown(str(exc)) from None

    def path_under_learned(self, query: iq.PathQuery, base: QueryResult) -> QueryResult:
        """``A[] p``, ``E[] p``, ``A<> p``, ``E<> p`` under a learned strategy: the model and the
        greedy strategy are deterministic, so there is one run, followed to the horizon (it does not
        stop at the learning goal) and replayed sample by sample (:meth:`StrategyRun.samples`):
        ``[]`` holds iff ``p`` holds at every sample of it, ``<>`` iff at some sample."""
        from rac.engine.simulate import label_runs

        # p is evaluated on the replayed samples, which hold the model and the ground truth: the
        # evaluator reports a name of the automaton (a location, a reward, an input) as unsupported.
        run, runs = self.learned_run(query.under, self.horizon_samples)  # type: ignore[arg-type]
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
            row.update({name: int(runs.states[0, k, i]) / scale for i, name in enumerate(EGO_STATE)})
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
