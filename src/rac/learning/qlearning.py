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
  Unseen table entries are 0. After each batch its transitions are *replayed backwards*
  (``replay`` times, default once; Lin's experience replay in reverse order): a reward at the end
  of an episode — reaching the goal — then reaches the episode's first decision at once rather
  than one step per later visit, which matters when the goal is rare (a few runs in a hundred).
- **Choices.** epsilon-greedy among the *allowed* actions (the shield's mask at the state key;
  all actions without a shield). A state where the shield allows nothing falls back to all
  actions; such decisions are counted (``fallbacks``). Greedy ties go to the lowest action index,
  so a strategy is deterministic. epsilon decays linearly per episode from ``epsilon[0]`` at the
  first episode to ``epsilon[1]`` at the last of the budget (a float keeps it constant).
- **Stopping rule.** After every batch the greedy strategy is evaluated by one run (the model is
  deterministic, so a deterministic strategy has exactly one run). A run *succeeds* when it
  reaches the goal and never collides nor leaves the road. The first episode count at which the
  greedy run succeeds is ``first_success_episode``. Learning stops when the episode budget is
  spent, or early once the best greedy run succeeded and ``stop_after`` evaluations in a row did
  not improve it (a success beats a failure; then the higher return, the lower for ``minE``).
  The strategy returned is the table as it was at the best evaluation (the best return when no
  greedy run succeeded), so its run is that run.
- **Rewards.** The batch's step reward: the automaton's objective increase, a reward expression
  summed over the samples, or (:class:`ObjectiveIncrease`) the increase of any expression over the
  automaton's rewards, such as a ``maxE(10*sa + 5*pr + co)`` that weighs them unlike ``objective``.

After learning, :func:`rac.learning.strategy.run_strategy` gives the strategy's run
(:meth:`StrategyRun.samples` every sample of it, for ``A[] p under S``) and
:func:`rac.learning.strategy.evaluate` a success rate (see there for why it is 0 or 1 without
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
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any, NamedTuple

import numpy as np

from rac.engine.shield import ShieldTable
from rac.ir import expr as ie
from rac.lang import ast
from rac.learning.episodes import Expression

# The strategy itself (observation keys, table, runs, evaluation) lives in rac.learning.strategy;
# its public names stay importable from here, where callers and the docs have always found them.
from rac.learning.strategy import (
    DEFAULT_BINS,
    Episodes,
    LearnedStrategy,
    StepOutcome,
    StrategyEvaluation,
    StrategyRun,
    allowed_actions,
    check_shield,
    default_bin,
    evaluate,
    greedy_actions,
    key_bytes,
    observation_keys,
    rollout,
    run_strategy,
    uniform_allowed,
)

__all__ = ["DEFAULT_BINS", "Episodes", "LearnedStrategy", "LearningResult", "ObjectiveIncrease", "StrategyEvaluation",
           "StrategyRun", "default_bin", "evaluate", "learn", "observation_keys", "run_strategy"]

#: ``progress(episodes_done, budget, mean_return)``: after every batch, with the batch's mean return.
Progress = Callable[[int, int, float], None]


def _texts(exprs: Sequence[Expression], labels: Sequence[str] | None) -> tuple[str, ...]:
    """The observations as text: ``labels``, else each as written (text, or a parsed node printed)."""
    from rac.lang.format import format_expr

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


class _QTable:
    """The growing table of learning: observation key -> row of Q-values, in the *maximised* sense
    (``sign * value``: for ``minE`` the negated costs)."""

    def __init__(self, width: int, n_actions: int) -> None:
        self.index: dict[bytes, int] = {}
        self.keys = np.zeros((64, width), dtype=np.float64)
        self.values = np.zeros((64, n_actions), dtype=np.float64)
        self.size = 0

    def rows(self, keys: np.ndarray, *, create: bool) -> np.ndarray:
        """Each key's row; a new key gets a row of zeros (``create``) or -1."""
        out = np.empty(keys.shape[0], dtype=np.int64)
        for i, raw in enumerate(key_bytes(keys)):
            row = self.index.get(raw)
            if row is None:
                if not create:
                    out[i] = -1
                    continue
                row = self._add(keys[i], raw)
            out[i] = row
        return out

    def _add(self, key: np.ndarray, raw: bytes) -> int:
        if self.size == self.keys.shape[0]:  # amortised doubling
            self.keys = np.concatenate([self.keys, np.zeros_like(self.keys)])
            self.values = np.concatenate([self.values, np.zeros_like(self.values)])
        self.keys[self.size] = key
        self.index[raw] = self.size
        self.size += 1
        return self.size - 1

    def utilities(self, rows: np.ndarray) -> np.ndarray:
        """``(n, P)``: the rows' values, zeros for unseen rows (-1)."""
        out = self.values[np.maximum(rows, 0)]
        out[rows < 0] = 0.0
        return out


class ObjectiveIncrease:
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
    def n_actions(self) -> int:
        return self.batch.n_actions

    @property
    def decide_every(self) -> int:
        return self.batch.decide_every

    @property
    def horizon_samples(self) -> int:
        return self.batch.horizon_samples

    @property
    def max_steps(self) -> int:
        return self.batch.max_steps

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

    def expression(self, expr: Expression) -> ie.Expr:
        return self.batch.expression(expr)

    def step(self, actions: np.ndarray) -> StepOutcome:
        active = ~np.asarray(self.batch.done, dtype=bool)
        before = self.batch.observe([self.expr])[:, 0]
        outcome = self.batch.step(actions)
        after = self.batch.observe([self.expr])[:, 0]
        # the batch's own result type with another reward (StepOutcome, a protocol, is not a dataclass type)
        return dataclasses.replace(outcome, reward=np.where(active, after - before, 0.0))  # type: ignore[type-var]


# ---------------------------------------------------------------- learning
@dataclass(frozen=True, eq=False)
class History:
    """Per learning episode (in the order they started): ``returns`` (undiscounted), ``reached``
    the goal, ``collided``, ``offroad`` (at any sample) and ``fallbacks``; per evaluation (after
    each batch): ``eval_episodes`` (episodes learned so far), ``eval_returns``, ``eval_success``."""

    returns: np.ndarray
    reached: np.ndarray
    collided: np.ndarray
    offroad: np.ndarray
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
    nothing), ``episodes`` learned, whether learning ``stopped_early``, ``seconds`` and ``seed``."""

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


class _Transition(NamedTuple):
    """One step of a batch: the ``active`` episodes' indices, then per episode (``(n,)`` or
    ``(n, P)``) the table row before, the action, the reward in the maximised sense, the row and
    allowed actions after, and whether the episode ``ends``."""

    active: np.ndarray
    rows: np.ndarray
    actions: np.ndarray
    reward: np.ndarray
    next_rows: np.ndarray
    next_masks: np.ndarray
    ends: np.ndarray


def _update(values: np.ndarray, step: _Transition, alpha: float, gamma: float) -> None:
    """Watkins' update of every active episode's transition, in episode order (a later row sees an
    earlier one's update). An ending episode does not bootstrap; the maximum runs over the actions
    allowed in the next state."""
    rows, actions = step.rows, step.actions
    for i in step.active:
        target = step.reward[i]
        if not step.ends[i]:
            target += gamma * values[step.next_rows[i]][step.next_masks[i]].max()
        values[rows[i], actions[i]] += alpha * (target - values[rows[i], actions[i]])


def _fresh_seed() -> int:
    """A seed from the operating system's entropy (recorded with the strategy, so a run can be repeated)."""
    entropy = np.random.SeedSequence().entropy
    assert isinstance(entropy, int)  # a SeedSequence made without entropy draws one int
    return entropy


def _epsilon_schedule(epsilon: float | tuple[float, float], episodes: int) -> Callable[[np.ndarray], np.ndarray]:
    start, end = (epsilon, epsilon) if isinstance(epsilon, int | float) else epsilon
    if not (0.0 <= start <= 1.0 and 0.0 <= end <= 1.0):
        raise ValueError(f"epsilon must lie in [0, 1], not {epsilon}")
    return lambda index: start + (end - start) * np.minimum(1.0, index / max(1, episodes - 1))


def learn(batch: Episodes, *, discrete: Sequence[Expression], continuous: Sequence[Expression], optimise: str = "max",
          shield: ShieldTable | None = None, episodes: int = 1000, parallel: int = 32, seed: int | None = None,
          alpha: float = 0.3, gamma: float = 1.0, epsilon: float | tuple[float, float] = (1.0, 0.05),
          bins: Sequence[float] | None = None, stop_after: int = 10, progress: Progress | None = None,
          meta: Mapping[str, object] | None = None, replay: int = 1,
          labels: Sequence[str] | None = None) -> LearningResult:
    """Learn a strategy by tabular Q-learning on ``batch`` (see the module docstring for the
    observation, the algorithm and the stopping rule). ``optimise``: ``"max"`` (``maxE``) or
    ``"min"`` (``minE``) of the episodes' rewards; ``shield``: the allowed actions at each state
    key; ``episodes``: the budget; ``parallel`` episodes per batch; ``bins``: one width per
    continuous expression (default :func:`default_bin`); ``progress(episodes_done, budget, mean_return)`` after
    every batch; ``meta``: stored with the strategy; ``replay``: backward replays of each finished
    batch (0: plain online Q-learning). The same ``seed`` gives the same result."""
    if optimise not in ("max", "min"):
        raise ValueError(f"optimise must be 'max' or 'min', not {optimise!r}")
    for name, value in (("episodes", episodes), ("parallel", parallel), ("stop_after", stop_after)):
        if isinstance(value, bool) or not isinstance(value, int) or value < 1:
            raise ValueError(f"{name} must be a positive integer, not {value!r}")
    if isinstance(replay, bool) or not isinstance(replay, int) or replay < 0:
        raise ValueError(f"replay must be a whole number >= 0, not {replay!r}")
    if not (0.0 < alpha <= 1.0 and 0.0 <= gamma <= 1.0):
        raise ValueError(f"alpha must lie in (0, 1] and gamma in [0, 1], not {alpha}, {gamma}")
    check_shield(batch, shield)
    texts = _texts((*discrete, *continuous), labels)
    discrete_exprs = [batch.expression(e) for e in discrete]
    continuous_exprs = [batch.expression(e) for e in continuous]
    exprs = (*discrete_exprs, *continuous_exprs)
    widths = tuple(float(b) for b in (bins if bins is not None else [default_bin(e) for e in continuous_exprs]))
    if len(widths) != len(continuous_exprs) or not all(w > 0 and math.isfinite(w) for w in widths):
        raise ValueError(f"bins must be {len(continuous_exprs)} positive widths, not {list(widths)}")
    seed = _fresh_seed() if seed is None else int(seed)
    rng = np.random.default_rng(seed)
    sign = 1.0 if optimise == "max" else -1.0
    n_discrete = len(discrete_exprs)
    table = _QTable(len(exprs), batch.n_actions)
    schedule = _epsilon_schedule(epsilon, episodes)
    pairs = getattr(batch, "action_pairs", None)

    def keys_now() -> np.ndarray:
        return observation_keys(batch.observe(exprs) if exprs else np.zeros((batch.n, 0)), n_discrete, widths)

    def snapshot() -> LearnedStrategy:
        return LearnedStrategy(texts[:n_discrete], texts[n_discrete:], widths, optimise, table.keys[:table.size].copy(),
                               sign * table.values[:table.size], None if pairs is None else np.array(pairs),
                               dict(meta or {}, seed=seed))

    def greedy_choice(observed: np.ndarray, masks: np.ndarray) -> np.ndarray:
        rows = table.rows(observation_keys(observed, n_discrete, widths), create=False)
        return greedy_actions(table.utilities(rows), masks)

    log: dict[str, list] = {name: [] for name in ("returns", "reached", "collided", "offroad", "fallbacks",
                                                  "eval_episodes", "eval_returns", "eval_success")}
    t0 = time.perf_counter()
    learned = 0
    first_success: int | None = None
    best: tuple[bool, float] | None = None
    best_strategy: LearnedStrategy | None = None
    best_run: StrategyRun | None = None
    stale = 0
    stopped_early = False
    while learned < episodes:
        n = min(parallel, episodes - learned)
        eps = schedule(learned + np.arange(n, dtype=np.float64))
        batch.reset(n)
        rows = table.rows(keys_now(), create=True)
        masks, empty = allowed_actions(batch, shield)
        fallbacks = empty.astype(np.int64)
        returns = np.zeros(n)
        reached, collided, offroad = (np.zeros(n, dtype=bool) for _ in range(3))
        steps: list[_Transition] = []  # this batch's transitions, for the backward replay
        for _ in range(batch.max_steps):
            active = ~np.asarray(batch.done, dtype=bool)
            if not active.any():
                break
            explore = rng.random(n) < eps
            random_actions = uniform_allowed(rng, masks)
            actions = np.where(explore, random_actions, greedy_actions(table.utilities(rows), masks))
            actions = np.where(active, actions, 0)
            outcome = batch.step(actions)
            reward = np.asarray(outcome.reward, dtype=np.float64)
            ends = np.asarray(outcome.terminated, dtype=bool) | np.asarray(outcome.truncated, dtype=bool)
            next_rows = table.rows(keys_now(), create=True)
            next_masks, next_empty = allowed_actions(batch, shield)
            transition = _Transition(np.flatnonzero(active), rows, actions, sign * reward, next_rows, next_masks, ends)
            _update(table.values, transition, alpha, gamma)
            steps.append(transition)
            returns[active] += reward[active]
            reached |= np.asarray(outcome.terminated, dtype=bool) & active
            collided |= np.asarray(outcome.collided, dtype=bool) & active
            offroad |= np.asarray(outcome.offroad, dtype=bool) & active
            fallbacks += next_empty & active & ~ends  # only a continuing episode decides there
            rows, masks = next_rows, next_masks
        # Backward replay: the batch's transitions again, last step first, so a reward at the end
        # of an episode reaches its first decision in one sweep instead of one step per visit.
        for _ in range(replay):
            for step in reversed(steps):
                _update(table.values, step, alpha, gamma)
        learned += n
        for name, column in (("returns", returns), ("reached", reached), ("collided", collided),
                             ("offroad", offroad), ("fallbacks", fallbacks)):
            log[name].append(column)
        # The stopping rule: evaluate the greedy strategy by its one run.
        run = rollout(batch, exprs, 1, shield, greedy_choice)
        success, ret = bool(run.success[0]), float(run.returns[0])
        log["eval_episodes"].append(learned)
        log["eval_returns"].append(ret)
        log["eval_success"].append(success)
        if success and first_success is None:
            first_success = learned
        if best is None or (success, sign * ret) > (best[0], sign * best[1]):
            best, best_strategy, best_run, stale = (success, ret), snapshot(), run, 0
        else:
            stale += 1
        if progress is not None:
            progress(learned, episodes, float(returns.mean()))
        if best[0] and stale >= stop_after and learned < episodes:
            stopped_early = True
            break
    assert best_strategy is not None and best_run is not None
    history = History(returns=np.concatenate(log["returns"]), reached=np.concatenate(log["reached"]),
                      collided=np.concatenate(log["collided"]), offroad=np.concatenate(log["offroad"]),
                      fallbacks=np.concatenate(log["fallbacks"]),
                      eval_episodes=np.array(log["eval_episodes"], dtype=np.int64),
                      eval_returns=np.array(log["eval_returns"]),
                      eval_success=np.array(log["eval_success"], dtype=bool))
    return LearningResult(best_strategy, best_run, history, first_success, int(history.collided.sum()),
                          int(history.offroad.sum()), int(history.fallbacks.sum()), learned, stopped_early,
                          time.perf_counter() - t0, seed)
