"""Tabular Q-learning of strategies on the scenario model: UPPAAL Stratego's learning queries, natively (issue 5).

UPPAAL learns ``strategy reach = maxE(rf)[<=T]{d1, ...}->{c1, ...}: <> goal() under safe`` from
simulated episodes: the observation is the discrete list then the continuous list, the reward is
``rf``, the shield ``safe`` restricts the choices. :func:`learn` does the same on an
:class:`rac.learning.episodes.EpisodeBatch` (one step = one decision period):

- **Observation key.** The discrete expressions' values, then the continuous ones binned
  (:mod:`rac.learning.strategy`, which also holds the learned strategy, its runs and evaluation).
- **Algorithm.** Watkins' Q-learning, one table shared by ``parallel`` episodes stepped together;
  after each step the updates ``Q(s,a) += alpha (r + gamma max_a' Q(s',a') - Q(s,a))`` are applied
  row by row in episode order (so two episodes in the same state see each other's update). The
  maximum runs over the actions allowed in ``s'``; an episode that ends (goal reached or horizon)
  does not bootstrap. ``minE`` minimises: the table then holds costs and every max is a min.
  Unseen table entries are 0 (``optimism``: another value), or with ``pessimistic`` a value below
  any return (:data:`rac.learning.tabular.UNTRIED`): an untried action is never preferred to a
  tried one, a tried one whose future is unknown yet ranks below every known one, and an entry's
  first update sets it (rather than moving it by ``alpha`` from an arbitrary start). With
  ``alpha=1`` on a deterministic model whose observation is the decision state (``time`` among
  the discrete observations), every tried entry then holds the best return seen after it, and
  the greedy strategy follows the best run seen; exploration is epsilon's alone. After each
  batch its transitions are *replayed backwards*
  (``replay`` times, default once; Lin's experience replay in reverse order): a reward at the end
  of an episode — reaching the goal — then reaches the episode's first decision at once rather
  than one step per later visit, which matters when the goal is rare (a few runs in a hundred).
- **Choices.** epsilon-greedy among the *allowed* actions (the shield's mask at the state key;
  all actions without a shield). A state where the shield allows nothing falls back to all
  actions; such decisions are counted (``fallbacks``). Greedy ties go to the lowest action index,
  so a strategy is deterministic (``random_ties``: a learning episode breaks them at random, so a
  state where nothing was tried yet continues at random rather than always with action 0).
  epsilon decays linearly per episode from ``epsilon[0]`` at the first episode to ``epsilon[1]``
  at the last of the budget (a float keeps it constant). An exploring choice is uniform among the
  allowed actions, or with ``steer`` half of them take the allowed action whose ``steer`` is least
  one decision later, looked up in the model (:class:`rac.learning.runs.Ahead`).
- **The best run replayed** (``replay_best``). After each batch the best learning episode seen so
  far (reaching the goal safely first, then the return) is replayed backwards once more: where
  the continuous observations are binned, a later, worse run through the same key overwrites a
  value (``alpha=1``), and the greedy strategy stops following the best run; the replay restores
  its values every batch (as self-imitation learning keeps good episodes).
- **Stopping rule.** After every batch the greedy strategy is evaluated by one run (the model is
  deterministic, so a deterministic strategy has exactly one run). That run is one more episode
  of the next batch, which chooses greedily from a copy of the table as it was, draws no random
  numbers and is not learned from (:mod:`rac.learning.tabular`): the same run as alone, at almost
  no cost (issue 11). When its verdict stops learning, the batch that carried it is discarded;
  the last batch's evaluation runs alone. A run *succeeds* when it
  reaches the goal and never collides nor leaves the road. The first episode count at which the
  greedy run succeeds is ``first_success_episode``. Learning stops when the episode budget is
  spent, or early once the best greedy run succeeded and ``stop_after`` evaluations in a row did
  not improve it (a success beats a failure; then the higher return, the lower for ``minE``).
  The strategy returned is the table as it was at the best evaluation (the best return when no
  greedy run succeeded), so its run is that run.
- **Rewards.** The batch's step reward: the automaton's objective increase, a reward expression
  summed over the samples, or (:class:`ObjectiveIncrease`) the increase of any expression over the
  automaton's rewards, such as a ``maxE(10*sa + 5*pr + co)`` that weighs them unlike ``objective``.

After learning, :func:`rac.learning.runs.run_strategy` gives the strategy's run
(:meth:`StrategyRun.samples` every sample of it, for ``A[] p under S``) and
:func:`rac.learning.runs.evaluate` a success rate (see there for why it is 0 or 1 without
action noise).

Example::

    from rac.learning.episodes import EpisodeBatch, parse_expr

    batch = EpisodeBatch(result, reward="automaton", horizon_samples=8)
    outcome = learn(batch, discrete=[parse_expr("Driving.location")], continuous=[parse_expr("x")],
                    shield=rac.engine.shield.load("safe.shield.npz"), seed=1)
    outcome.strategy.save("reach.strategy.npz")
    run = run_strategy(batch, LearnedStrategy.load("reach.strategy.npz"))   # run.success[0], run.returns[0]
"""

from __future__ import annotations

import dataclasses
import math
import numbers
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from rac.core.caller import require_bool
from rac.core.diagnostics import RacValueError
from rac.engine.budget import check_estimate, learning_bytes
from rac.engine.shield import ShieldTable
from rac.ir import expr as ie
from rac.lang import ast
from rac.lang.format import format_expr
from rac.learning.counterfactual import Counterfactuals
from rac.learning.episodes import Expression

# The strategy itself (observation keys, table) lives in rac.learning.strategy, its runs and evaluation
# in rac.learning.runs; their public names stay importable from here, where callers and the docs
# have always found them.
from rac.learning.runs import Steps, Stop, StrategyEvaluation, StrategyRun, alone, evaluate, run_strategy
from rac.learning.strategy import (
    DEFAULT_BINS,
    Episodes,
    Forwarding,
    LearnedStrategy,
    StepOutcome,
    check_shield,
    default_bin,
    observation_keys,
)
from rac.learning.tabular import UNTRIED, BatchLog, Frozen, Learner, QTable

__all__ = ["DEFAULT_BINS", "Episodes", "LearnedStrategy", "LearningResult", "ObjectiveIncrease", "ObservationError",
           "StrategyEvaluation", "StrategyRun", "default_bin", "evaluate", "learn", "learning", "location_column",
           "observation_keys", "run_strategy"]

#: ``progress(episodes_done, budget, mean_return)``: after every batch, with the batch's mean return.
Progress = Callable[[int, int, float], None]


def _texts(exprs: Sequence[Expression], labels: Sequence[str] | None) -> tuple[str, ...]:
    """The observations as text: ``labels``, else each as written (text, or a parsed node printed)."""

    if labels is not None:
        if len(labels) != len(exprs):
            raise ValueError(f"labels must name the {len(exprs)} observations, not {len(labels)}")
        return tuple(labels)
    texts = []
    for expr in exprs:
        if isinstance(expr, str):
            texts.append(expr)
        elif isinstance(expr, ast.Number | ast.BoolLit | ast.Name | ast.Qualified | ast.Call | ast.Unary | ast.Binary):
            texts.append(format_expr(expr))
        else:
            raise ValueError("checked observations need their texts: pass labels=")
    return tuple(texts)


class ObjectiveIncrease(Forwarding):
    """``batch`` with each step's reward replaced by the increase of ``expr`` over the step
    (``expr`` observed before and after it; 0 for episodes already done): UPPAAL's ``maxE(e)`` for
    an ``e`` over the automaton's rewards, such as ``10*sa + 5*pr + co`` when the automaton's own
    objective weighs them differently. The increase after the last step includes the ``at end``
    clauses (the episodes' rewards hold them once an episode ended). Everything else is ``batch``'s."""

    def __init__(self, batch: Episodes, expr: Expression) -> None:
        self.batch = batch
        self.expr = batch.expression(expr)

    def __getattr__(self, name: str) -> Any:
        return getattr(self.batch, name)  # what Episodes does not name (e.g. EpisodeBatch.action_pairs)

    # What Episodes names is forwarded explicitly, so that ObjectiveIncrease is one (mypy checks).
    @property
    def n(self) -> int:
        return self.batch.n

    @property
    def done(self) -> np.ndarray:
        return self.batch.done

    def reset(self, n: int) -> None:
        self.batch.reset(n)

    def state_keys(self) -> np.ndarray:
        return self.batch.state_keys()

    def observe(self, exprs: Sequence[Expression]) -> np.ndarray:
        return self.batch.observe(exprs)

    def counterfactual(self) -> Counterfactuals:
        """The last step replayed from every location, rewarded with ``expr``'s increase
        (:meth:`rac.learning.episodes.EpisodeBatch.counterfactual`)."""
        return self.batch.counterfactual(objective=self.expr)  # type: ignore[attr-defined]

    def step(self, actions: np.ndarray) -> StepOutcome:
        active = ~np.asarray(self.batch.done, dtype=bool)
        before = self.batch.observe([self.expr])[:, 0]
        outcome = self.batch.step(actions)
        after = self.batch.observe([self.expr])[:, 0]
        with np.errstate(invalid="ignore"):  # inf - inf: a reward that is not a number, which its user refuses
            increase = np.where(active, after - before, 0.0)
        # the batch's own result type with another reward (StepOutcome, a protocol, is not a dataclass type)
        return dataclasses.replace(outcome, reward=increase)  # type: ignore[type-var]


# ---------------------------------------------------------------- learning
@dataclass(frozen=True, eq=False)
class History:
    """Per learning episode (in the order they started): ``returns`` (undiscounted), ``reached``
    the goal, ``collided``, ``offroad`` (at any sample), ``stranded`` and ``fallbacks``; per evaluation (after
    each batch): ``eval_episodes`` (episodes learned so far), ``eval_returns``, ``eval_success``."""

    returns: np.ndarray
    reached: np.ndarray
    collided: np.ndarray
    offroad: np.ndarray
    stranded: np.ndarray
    fallbacks: np.ndarray
    eval_episodes: np.ndarray
    eval_returns: np.ndarray
    eval_success: np.ndarray


@dataclass(frozen=True, eq=False)
class LearningResult:
    """What :func:`learn` returns: the ``strategy`` (the table at the best evaluation), its
    ``greedy`` run, the ``history``, ``first_success_episode`` (episodes learned when the greedy
    run first succeeded; None: never), ``collisions_during_learning`` / ``offroad_during_learning``
    (learning episodes with at least one), ``fallbacks`` (decisions where the shield allowed
    nothing), ``episodes`` learned, whether learning ``stopped_early``, ``seconds``, ``seed`` and whether it
    was ``interrupted``."""

    strategy: LearnedStrategy
    greedy: StrategyRun
    history: History
    first_success_episode: int | None
    collisions_during_learning: int
    offroad_during_learning: int
    fallbacks: int
    episodes: int
    stopped_early: bool
    seconds: float
    seed: int
    #: Learning was stopped from outside (:class:`rac.learning.runs.Stop`, e.g. Ctrl-C in
    #: ``rac experiment``) after ``episodes``: the strategy is the best evaluated until then.
    interrupted: bool = False


def _fresh_seed() -> int:
    """A seed from the operating system's entropy (recorded with the strategy, so a run can be repeated)."""
    entropy = np.random.SeedSequence().entropy
    assert isinstance(entropy, int)  # a SeedSequence made without entropy draws one int
    return entropy


class ObservationError(RacValueError):
    """An observation that cannot serve counterfactual experiences (:func:`location_column`); ``index``
    is the observation at fault (discrete ones first), None when the location is missing."""

    def __init__(self, message: str, index: int | None = None) -> None:
        super().__init__(message)
        self.index = index


def location_column(discrete: Sequence[ie.Expr], continuous: Sequence[ie.Expr] = ()) -> int:
    """The column of the observation holding the automaton's location (``A.location`` among the
    discrete expressions), for counterfactual experiences; :class:`ObservationError` (a ``ValueError``)
    when there is none, or when another observation reads the automaton's locations or rewards (its
    counterfactual value would be unknown)."""
    found = [i for i, e in enumerate(discrete) if isinstance(e, ie.Ref) and e.kind is ie.RefKind.LOCATION_INDEX]
    if not found:
        raise ObservationError("counterfactual experiences need the automaton's location in the discrete observations "
                               "(e.g. {Driving.location})")
    automaton_state = (ie.RefKind.REWARD, ie.RefKind.LOCATION, ie.RefKind.LOCATION_INDEX)
    for i, e in enumerate((*discrete, *continuous)):
        if i != found[0] and any(r.kind in automaton_state for r in ie.refs(e)):
            raise ObservationError("counterfactual experiences need an observation that sees the automaton only "
                                   "through its location: another observation reads its locations or rewards", i)
    return found[0]


def _epsilon_schedule(epsilon: float | tuple[float, float], episodes: int) -> Callable[[np.ndarray], np.ndarray]:
    if isinstance(epsilon, numbers.Real):
        start = end = epsilon
    elif isinstance(epsilon, tuple | list) and len(epsilon) == 2:
        start, end = epsilon
    else:
        raise ValueError(f"epsilon must be a number or a pair (first, last), not {epsilon!r}")
    if not (0.0 <= start <= 1.0 and 0.0 <= end <= 1.0):
        raise ValueError(f"epsilon must lie in [0, 1], not {epsilon}")
    return lambda index: start + (end - start) * np.minimum(1.0, index / max(1, episodes - 1))


def learning(batch: Episodes, *, discrete: Sequence[Expression], continuous: Sequence[Expression],
             optimise: str = "max", shield: ShieldTable | None = None, episodes: int = 1000, parallel: int = 32,
             seed: int | None = None, alpha: float = 0.3, gamma: float = 1.0,
             epsilon: float | tuple[float, float] = (1.0, 0.05), bins: Sequence[float] | None = None,
             stop_after: int = 10, progress: Progress | None = None, meta: Mapping[str, object] | None = None,
             replay: int = 1, labels: Sequence[str] | None = None,
             evaluate_in_batch: bool = True, counterfactuals: bool = False,
             growth: float | None = None, optimism: float = 0.0, pessimistic: bool = False,
             random_ties: bool = False, max_bytes: int | None = None,
             replay_best: bool = False, steer: Expression | None = None) -> Steps[LearningResult]:
    """Learn a strategy by tabular Q-learning on ``batch`` (see the module docstring for the
    observation, the algorithm and the stopping rule): ``learn(batch, ...)`` learns on ``batch``
    alone; ``learning(batch, ...)`` is the same as a generator of steps (:mod:`rac.learning.runs`),
    which reads ``batch`` for its actions and expressions and steps the episodes it is sent, for
    :func:`rac.learning.lockstep.run_together`. ``optimise``: ``"max"`` (``maxE``) or
    ``"min"`` (``minE``) of the episodes' rewards; ``shield``: the allowed actions at each state
    key; ``episodes``: the budget; ``parallel`` episodes per batch; ``bins``: one width per
    continuous expression (default :func:`default_bin`); ``progress(episodes_done, budget, mean_return)`` after
    every batch; ``meta``: stored with the strategy; ``replay``: backward replays of each finished
    batch (0: plain online Q-learning); ``evaluate_in_batch``: run each greedy evaluation in the
    next batch (default) or alone after its batch — the results are the same, alone is slower.
    ``optimism``: the value of untried entries (0 by default); ``pessimistic``: untried entries are
    never preferred to tried ones (:data:`rac.learning.tabular.UNTRIED`; their first update sets them, so with
    ``alpha=1`` on a deterministic model whose observation is its decision state every tried entry
    holds the best return seen after it and the greedy strategy is the best run seen);
    ``random_ties``: learning episodes break greedy ties at random (the greedy strategy keeps the
    lowest index); ``replay_best``: after each batch, the best learning episode seen so far (a safe goal
    first, then the return) is replayed backwards too; ``steer``: half the exploring choices take the
    allowed action whose value of this expression one decision later is least (``"dist_goal()"``: towards
    the goal), looked up in the model (:attr:`rac.learning.tabular.Learner.steer`; None: uniform);
    ``max_bytes``: the memory budget (None: none): :class:`rac.engine.budget.EstimateExceeded` before
    anything is learned when :func:`rac.engine.budget.learning_bytes` estimates more. The same ``seed``
    gives the same result."""
    if optimise not in ("max", "min"):
        raise ValueError(f"optimise must be 'max' or 'min', not {optimise!r}")
    for name, value in (("episodes", episodes), ("parallel", parallel), ("stop_after", stop_after)):
        if isinstance(value, bool) or not isinstance(value, numbers.Integral) or value < 1:
            raise ValueError(f"{name} must be a positive integer, not {value!r}")
    episodes, parallel, stop_after = int(episodes), int(parallel), int(stop_after)  # a NumPy integer as well
    if seed is not None and (isinstance(seed, bool) or not isinstance(seed, numbers.Integral) or seed < 0):
        raise ValueError(f"seed must be a whole number >= 0, not {seed!r}")  # 1.5 and "1" were read as 1
    if growth is not None and not (isinstance(growth, numbers.Real) and 0 < growth < math.inf):
        raise ValueError(f"growth must be a positive number (or None), not {growth!r}")  # NaN, 0: batches of 1
    if not (isinstance(optimism, numbers.Real) and math.isfinite(optimism)):
        raise ValueError(f"optimism must be a finite number, not {optimism!r}")  # NaN or inf in every entry
    for name, value in (("evaluate_in_batch", evaluate_in_batch), ("counterfactuals", counterfactuals),
                        ("pessimistic", pessimistic), ("random_ties", random_ties), ("replay_best", replay_best)):
        require_bool(value, name)  # "no" was true
    if isinstance(replay, bool) or not isinstance(replay, int) or replay < 0:
        raise ValueError(f"replay must be a whole number >= 0, not {replay!r}")
    if not (0.0 < alpha <= 1.0 and 0.0 <= gamma <= 1.0):
        raise ValueError(f"alpha must lie in (0, 1] and gamma in [0, 1], not {alpha}, {gamma}")
    check_shield(batch, shield)
    if counterfactuals and getattr(batch, "counterfactuals", None) is False:  # said before any episode runs
        raise RacValueError("counterfactual experiences replay each step from every location: make the episodes "
                            "with EpisodeBatch(..., counterfactuals=True)")
    texts = _texts((*discrete, *continuous), labels)
    discrete_exprs = [batch.expression(e) for e in discrete]
    continuous_exprs = [batch.expression(e) for e in continuous]
    exprs = (*discrete_exprs, *continuous_exprs)
    widths = tuple(float(b) for b in (bins if bins is not None else [default_bin(e) for e in continuous_exprs]))
    if len(widths) != len(continuous_exprs) or not all(w > 0 and math.isfinite(w) for w in widths):
        raise ValueError(f"bins must be {len(continuous_exprs)} positive widths, not {list(widths)}")
    # Refused before the table exists: the estimate bounds what the learning would allocate.
    check_estimate("learning", learning_bytes(episodes=episodes, parallel=parallel, steps=batch.max_steps,
                                              observations=len(exprs), actions=batch.n_actions), max_bytes,
                   f"lower the episode budget ({episodes:,}) or shorten the time bound")
    seed = _fresh_seed() if seed is None else int(seed)
    sign = 1.0 if optimise == "max" else -1.0
    n_discrete = len(discrete_exprs)
    if pessimistic and optimism:
        raise ValueError("optimism and pessimistic exclude each other: untried entries have one value")
    table = QTable(len(exprs), batch.n_actions, UNTRIED if pessimistic else optimism)
    learner = Learner(table, exprs, n_discrete, widths, shield, np.random.default_rng(seed), sign, alpha, gamma, replay,
                      location_column(discrete_exprs, continuous_exprs) if counterfactuals else None, random_ties,
                      replay_best=replay_best, steer=None if steer is None else batch.expression(steer))
    schedule = _epsilon_schedule(epsilon, episodes)
    pairs = getattr(batch, "action_pairs", None)

    def strategy(frozen: Frozen) -> LearnedStrategy:
        return LearnedStrategy(texts[:n_discrete], texts[n_discrete:], widths, optimise,
                               table.keys[:frozen.size].copy(), sign * frozen.values,
                               None if pairs is None else np.array(pairs), dict(meta or {}, seed=seed))

    logs: list[BatchLog] = []
    evaluations: list[tuple[int, float, bool]] = []  # (episodes learned, return, success)
    t0 = time.perf_counter()
    learned = 0
    first_success: int | None = None
    best: tuple[bool, float] | None = None
    best_strategy: LearnedStrategy | None = None
    best_run: StrategyRun | None = None
    best_after = 0  # episodes learned at the best evaluation
    stopped_early = False

    def batch_size(learned: int) -> int:
        """The next batch's episodes: ``parallel``, or with ``growth`` a batch growing with the
        episodes learned (the greedy strategy is evaluated after every batch: early, often)."""
        if growth is None:
            return parallel
        return max(1, min(parallel, math.ceil(growth * learned)))

    def judge(frozen: Frozen, after: int, mean_return: float, run: StrategyRun) -> bool:
        """The stopping rule on the greedy run of the table ``frozen`` after ``after`` episodes:
        whether learning stops there."""
        nonlocal first_success, best, best_strategy, best_run, best_after
        success, ret = bool(run.success[0]), float(run.returns[0])
        evaluations.append((after, ret, success))
        if success and first_success is None:
            first_success = after
        if best is None or (success, sign * ret) > (best[0], sign * best[1]):
            best, best_strategy, best_run, best_after = (success, ret), strategy(frozen), run, after
        if progress is not None:
            progress(after, episodes, mean_return)
        return best[0] and after - best_after >= stop_after * parallel and after < episodes

    # After each batch the greedy strategy is evaluated by its one run (the stopping rule). With
    # evaluate_in_batch that run rides along in the next batch, choosing from the table as it was
    # (Frozen): the next batch is learned before the verdict on this one, and when the verdict
    # stops learning that batch is discarded (its episodes are not counted, its table not kept).
    pending: tuple[Frozen, int, float] | None = None  # the table, episodes learned, mean return
    interrupted = False
    try:
        while learned < episodes:
            n = min(batch_size(learned), episodes - learned)
            riding, pending = pending, None
            log, run = yield from learner.run(n, schedule(learned + np.arange(n, dtype=np.float64)),
                                              None if riding is None else riding[0])
            if riding is not None and run is not None and judge(*riding, run):
                stopped_early = True
                break
            learned += n
            logs.append(log)
            pending = (table.freeze(), learned, float(log.returns.mean()))
            if not evaluate_in_batch:
                evaluated, pending = pending, None
                if judge(*evaluated, (yield from learner.greedy_run())):
                    stopped_early = True
                    break
        if pending is not None:  # the last batch's evaluation: no batch follows to carry it
            judge(*pending, (yield from learner.greedy_run()))
    except Stop:  # the caller was interrupted: the batch under way is dropped, the best evaluated stands
        if best_strategy is None:
            raise
        interrupted = True
    assert best_strategy is not None and best_run is not None
    history = History(returns=np.concatenate([log.returns for log in logs]),
                      reached=np.concatenate([log.reached for log in logs]),
                      collided=np.concatenate([log.collided for log in logs]),
                      offroad=np.concatenate([log.offroad for log in logs]),
                      stranded=np.concatenate([log.stranded for log in logs]),
                      fallbacks=np.concatenate([log.fallbacks for log in logs]),
                      eval_episodes=np.array([e[0] for e in evaluations], dtype=np.int64),
                      eval_returns=np.array([e[1] for e in evaluations]),
                      eval_success=np.array([e[2] for e in evaluations], dtype=bool))
    return LearningResult(best_strategy, best_run, history, first_success, int(history.collided.sum()),
                          int(history.offroad.sum()), int(history.fallbacks.sum()), learned, stopped_early,
                          time.perf_counter() - t0, seed, interrupted)


#: :func:`learning` on one batch alone (same arguments): ``learn(batch, discrete=..., continuous=..., ...)``.
learn = alone(learning)
