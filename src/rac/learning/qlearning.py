"""Tabular Q-learning of strategies on the scenario model: UPPAAL Stratego's learning queries, natively (issue 5).

UPPAAL learns ``strategy reach = maxE(rf)[<=T]{d1, ...}->{c1, ...}: <> goal() under safe`` from
simulated episodes: the observation is the discrete list then the continuous list, the reward is
``rf``, the shield ``safe`` restricts the choices. :func:`learn` does the same on an
:class:`rac.learning.episodes.EpisodeBatch` (one step = one decision period):

- **Observation key.** The discrete expressions' values as they are (booleans 0/1, locations by
  index), then each continuous value binned: ``floor(value / width + 1e-9)`` (the tolerance keeps
  ``0.3 / 0.1`` in bin 3). Default widths (:func:`default_bin`, :data:`DEFAULT_BINS`): 1 m for
  positions and distances (``x, y, mindist(), dist_goal()``), 0.5 m/s for speeds, 0.5 m/s² for
  accelerations, 0.5 m/s³ for the jerk, 0.1 rad for headings, 0.05 rad/s for the turn rate, 0.1 s
  for ``time``, 1 (in the expression's unit) for anything else. The key holds only what the query
  lists (the sample is not added): put ``time`` in the discrete list for a time-dependent strategy.
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
- **Unseen observations.** A strategy picks the lowest-index allowed action in a state it never
  saw (its Q-values count as 0, and ties go to the lowest index).
- **Rewards.** The batch's step reward: the automaton's objective increase, a reward expression
  summed over the samples, or (:class:`ObjectiveIncrease`) the increase of any expression over the
  automaton's rewards, such as a ``maxE(10*sa + 5*pr + co)`` that weighs them unlike ``objective``.

After learning, :func:`run_strategy` gives the strategy's run (:meth:`StrategyRun.samples` every
sample of it, for ``A[] p under S``) and :func:`evaluate` a success rate (see there for why it is
0 or 1 without action noise).

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
import json
import math
import os
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Protocol

import numpy as np

from rac.engine.shield import ShieldTable
from rac.ir import expr as ie
from rac.lang import ast
from rac.learning.episodes import Expression

__all__ = ["DEFAULT_BINS", "Episodes", "LearnedStrategy", "LearningResult", "ObjectiveIncrease", "StrategyEvaluation",
           "StrategyRun", "default_bin", "evaluate", "learn", "observation_keys", "run_strategy"]

FORMAT = "rac-strategy-1"
#: Default bin widths of continuous observations, by name (a plain name, a model function, or
#: ``fabs``/``-`` of one); see the module docstring.
DEFAULT_BINS: dict[str, float] = {
    "x": 1.0, "y": 1.0, "true_x": 1.0, "true_y": 1.0, "mindist": 1.0, "dist_goal": 1.0,
    "v": 0.5, "true_v": 0.5, "acc": 0.5, "true_acc": 0.5, "jerk": 0.5,
    "head": 0.1, "true_head": 0.1, "turn": 0.05, "time": 0.1,
}
#: The width of a continuous expression :data:`DEFAULT_BINS` does not name.
DEFAULT_BIN = 1.0
#: Added to ``value / width`` before flooring, so that float noise does not drop a value on a
#: bin's edge into the bin below.
BIN_TOLERANCE = 1e-9

#: ``progress(episodes_done, budget, mean_return)``: after every batch, with the batch's mean return.
Progress = Callable[[int, int, float], None]


class StepOutcome(Protocol):
    """What a step returns (:class:`rac.learning.episodes.StepResult`): ``(n,)`` arrays."""

    reward: np.ndarray
    terminated: np.ndarray
    truncated: np.ndarray
    collided: np.ndarray
    offroad: np.ndarray


class Episodes(Protocol):
    """What learning needs of :class:`rac.learning.episodes.EpisodeBatch` (tests may pass a stand-in)."""

    n_actions: int
    decide_every: int
    horizon_samples: int
    max_steps: int
    n: int
    done: np.ndarray

    def reset(self, n: int) -> None: ...

    def state_keys(self) -> np.ndarray: ...

    def observe(self, exprs: Sequence[Expression]) -> np.ndarray: ...

    def expression(self, expr: Expression) -> ie.Expr: ...

    def step(self, actions: np.ndarray) -> StepOutcome: ...


# ---------------------------------------------------------------- observations
def default_bin(expr: ie.Expr | ast.Expr) -> float:
    """The default bin width of a continuous observation (:data:`DEFAULT_BINS`), checked or parsed:
    by the name it observes (``v``, ``fabs(turn)``, ``-acc``)."""
    if isinstance(expr, ie.Unary | ast.Unary) and expr.op == "-":
        return default_bin(expr.operand)
    if isinstance(expr, ie.Call) and expr.name in ("fabs", "abs") and len(expr.args) == 1:
        return default_bin(expr.args[0])
    if isinstance(expr, ast.Call) and expr.func in ("fabs", "abs") and len(expr.args) == 1:
        return default_bin(expr.args[0])
    name = (expr.name if isinstance(expr, ie.Ref | ie.Call) else expr.id if isinstance(expr, ast.Name)
            else expr.func if isinstance(expr, ast.Call) else None)
    return DEFAULT_BINS.get(name, DEFAULT_BIN) if name is not None else DEFAULT_BIN


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


def observation_keys(values: np.ndarray, n_discrete: int, bins: Sequence[float] | np.ndarray) -> np.ndarray:
    """``(n, d + c)`` float64 keys of observed values: the ``n_discrete`` first columns as they
    are, the others binned (``floor(value / width + 1e-9)``); ``-0.0`` becomes ``0.0`` (one key)."""
    keys = np.array(values, dtype=np.float64, ndmin=2, copy=True)
    widths = np.asarray(bins, dtype=np.float64)
    if keys.shape[1] != n_discrete + widths.size:
        raise ValueError(f"{keys.shape[1]} observed values, expected {n_discrete} discrete + {widths.size} binned")
    keys[:, n_discrete:] = np.floor(keys[:, n_discrete:] / widths + BIN_TOLERANCE)
    return keys + 0.0


def _key_bytes(keys: np.ndarray) -> list[bytes]:
    return [row.tobytes() for row in np.ascontiguousarray(keys, dtype=np.float64)]


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
        for i, raw in enumerate(_key_bytes(keys)):
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


def _greedy(utilities: np.ndarray, masks: np.ndarray) -> np.ndarray:
    """The best allowed action per row; ``argmax`` takes the first maximum, so ties go to the lowest index."""
    return np.argmax(np.where(masks, utilities, -np.inf), axis=1).astype(np.int64)


def _uniform(rng: np.random.Generator, masks: np.ndarray) -> np.ndarray:
    """One allowed action per row, uniformly (every row allows one)."""
    pick = rng.integers(0, masks.sum(axis=1))
    return np.argmax(np.cumsum(masks, axis=1) > pick[:, None], axis=1).astype(np.int64)


def _allowed(batch: Episodes, shield: ShieldTable | None) -> tuple[np.ndarray, np.ndarray]:
    """The allowed actions of every episode and which rows fell back to all actions (empty masks)."""
    if shield is None:
        return np.ones((batch.n, batch.n_actions), dtype=bool), np.zeros(batch.n, dtype=bool)
    masks = np.array(shield.masks_for(batch.state_keys()), dtype=bool)
    empty = ~masks.any(axis=1)
    masks[empty] = True
    return masks, empty


def _check_shield(batch: Episodes, shield: ShieldTable | None) -> None:
    if shield is not None and shield.n_actions != batch.n_actions:
        raise ValueError(f"the shield has {shield.n_actions} actions, the episodes {batch.n_actions}")


class ObjectiveIncrease:
    """``batch`` with each step's reward replaced by the increase of ``expr`` over the step
    (``expr`` observed before and after it; 0 for episodes already done): UPPAAL's ``maxE(e)`` for
    an ``e`` over the automaton's rewards, such as ``10*sa + 5*pr + co`` when the automaton's own
    objective weighs them differently. The increase after the last step includes the ``at end``
    clauses (the episodes' rewards hold them once an episode ended). Everything else is ``batch``'s."""

    def __init__(self, batch: Episodes, expr: Expression) -> None:
        self.batch = batch
        self.expr = batch.expression(expr)

    def __getattr__(self, name: str) -> object:
        return getattr(self.batch, name)

    def step(self, actions: np.ndarray) -> StepOutcome:
        active = ~np.asarray(self.batch.done, dtype=bool)
        before = self.batch.observe([self.expr])[:, 0]
        outcome = self.batch.step(actions)
        after = self.batch.observe([self.expr])[:, 0]
        return dataclasses.replace(outcome, reward=np.where(active, after - before, 0.0))  # type: ignore[type-var]


# ---------------------------------------------------------------- the learned strategy
@dataclass(frozen=True, eq=False)
class LearnedStrategy:
    """A learned Q-table and how to observe: ``keys (S, d + c)`` observation keys (see
    :func:`observation_keys`), ``values (S, P)`` their Q-values in the objective's sense (expected
    return for ``optimise="max"``, expected cost for ``"min"``), the expressions as text, the bin
    widths and ``meta`` (JSON-ready facts: the objective, the goal, the shield, the seed...)."""

    discrete: tuple[str, ...]
    continuous: tuple[str, ...]
    bins: tuple[float, ...]
    optimise: str
    keys: np.ndarray
    values: np.ndarray
    action_pairs: np.ndarray | None = None
    meta: Mapping[str, object] = field(default_factory=dict)

    def __post_init__(self) -> None:
        if self.optimise not in ("max", "min"):
            raise ValueError(f"optimise must be 'max' or 'min', not {self.optimise!r}")
        object.__setattr__(self, "_index", {raw: i for i, raw in enumerate(_key_bytes(self.keys))})

    @property
    def n_actions(self) -> int:
        return int(self.values.shape[1])

    @property
    def n_states(self) -> int:
        """How many observation keys the table holds."""
        return int(self.keys.shape[0])

    def observation_keys(self, observations: np.ndarray) -> np.ndarray:
        """The keys of ``(n, d + c)`` observed values (discrete then continuous, as :meth:`expressions`)."""
        return observation_keys(observations, len(self.discrete), self.bins)

    def expressions(self) -> tuple[ast.Expr, ...]:
        """The observed expressions, parsed back from their text (discrete first; the episodes check
        them against their automaton when observing)."""
        from rac.lang.parser import parse_text

        texts = (*self.discrete, *self.continuous)
        if not texts:
            return ()
        module = parse_text(f"automaton Observation {{ query Q: simulate[<=1;1]{{{', '.join(texts)}}} }}")
        return tuple(module.automata[0].members[0].query.exprs)  # type: ignore[union-attr]

    def lookup(self, keys: np.ndarray) -> np.ndarray:
        """Each key's row in :attr:`keys`, -1 for a key never seen."""
        index: dict[bytes, int] = self._index  # type: ignore[attr-defined]
        return np.array([index.get(raw, -1) for raw in _key_bytes(keys)], dtype=np.int64)

    def action(self, keys: np.ndarray, masks: np.ndarray | None = None) -> np.ndarray:
        """``(n,)`` the greedy action of every observation key among the allowed ones (``masks``
        ``(n, P)`` bool; None: all). An unseen key, or a row allowing nothing, gets the lowest-index
        allowed action (every action, for an empty row)."""
        keys = np.array(keys, dtype=np.float64, ndmin=2)
        rows = self.lookup(keys)
        sign = 1.0 if self.optimise == "max" else -1.0
        utilities = sign * self.values[np.maximum(rows, 0)] if self.n_states else np.zeros((len(rows), self.n_actions))
        utilities[rows < 0] = 0.0
        allowed = np.ones(utilities.shape, dtype=bool) if masks is None else np.array(masks, dtype=bool)
        allowed[~allowed.any(axis=1)] = True
        return _greedy(utilities, allowed)

    def act(self, observations: np.ndarray, masks: np.ndarray | None = None) -> np.ndarray:
        """:meth:`action` of raw observed values."""
        return self.action(self.observation_keys(observations), masks)

    def save(self, path: str | Path) -> Path:
        """Write the strategy to ``path`` (compressed .npz: ``keys``, ``values``, ``action_pairs`` and
        a JSON ``meta`` with the format, the expressions, bins and ``optimise``). The file is written
        under a temporary name and renamed, so an interrupted write leaves no half strategy."""
        path = Path(path)
        header = {"format": FORMAT, "discrete": list(self.discrete), "continuous": list(self.continuous),
                  "bins": list(self.bins), "optimise": self.optimise, "meta": dict(self.meta)}
        pairs = self.action_pairs if self.action_pairs is not None else np.zeros((0, 2), dtype=np.int64)
        partial = path.with_name(path.name + ".partial")
        try:
            with partial.open("wb") as handle:
                np.savez_compressed(handle, header=np.array(json.dumps(header)), keys=self.keys, values=self.values,
                                    action_pairs=pairs)
            os.replace(partial, path)
        finally:
            partial.unlink(missing_ok=True)
        return path

    @classmethod
    def load(cls, path: str | Path) -> LearnedStrategy:
        """Read a strategy written by :meth:`save` (``ValueError`` when the file is not one)."""
        path = Path(path)
        try:
            with np.load(path, allow_pickle=False) as data:
                header = json.loads(str(data["header"]))
                if header.get("format") != FORMAT:
                    raise ValueError(f"not a rac strategy (format {header.get('format')!r})")
                pairs = data["action_pairs"]
                return cls(tuple(header["discrete"]), tuple(header["continuous"]),
                           tuple(float(b) for b in header["bins"]), header["optimise"],
                           data["keys"].astype(np.float64), data["values"].astype(np.float64),
                           pairs if pairs.size else None, header.get("meta", {}))
        except FileNotFoundError:
            raise
        except (OSError, KeyError, ValueError, TypeError) as exc:
            raise ValueError(f"{path}: cannot read the strategy: {exc}") from None


# ---------------------------------------------------------------- runs
@dataclass(frozen=True, eq=False)
class StrategyRun:
    """Runs of the episodes under a strategy, one row per run, one column per decision.

    ``states (n, S+1, 8)`` int32 the state keys ``[k, x, y, v, acc, head, jerk, turn]`` before each
    step and after the last (a finished run's row repeats its last state); ``observations (n, S+1,
    d+c)`` the observed values there; ``actions (n, S)`` (-1 after the end), ``rewards (n, S)`` (0
    after the end); per run: ``returns`` (the undiscounted sum of rewards), ``reached`` the goal,
    ``collided``, ``offroad`` (at any sample), ``fallbacks`` (decisions where the shield allowed
    nothing) and ``steps`` taken. ``decide_every`` samples per step, ``horizon_samples`` the
    episodes' horizon."""

    states: np.ndarray
    observations: np.ndarray
    actions: np.ndarray
    rewards: np.ndarray
    returns: np.ndarray
    reached: np.ndarray
    collided: np.ndarray
    offroad: np.ndarray
    fallbacks: np.ndarray
    steps: np.ndarray
    decide_every: int
    horizon_samples: int

    @property
    def n_runs(self) -> int:
        return int(self.actions.shape[0])

    @property
    def success(self) -> np.ndarray:
        """``(n,)`` the run reached the goal and never collided nor left the road."""
        return self.reached & ~self.collided & ~self.offroad

    @property
    def samples_taken(self) -> np.ndarray:
        """``(n,)`` the last sample of each run (an episode ends at the sample that reaches the goal,
        which may lie inside a decision period, or at the horizon)."""
        return self.states[:, -1, 0].astype(np.int64)

    def samples(self, data: object, *, truth_substeps: int = 100):
        """Every sample of the runs (:class:`rac.engine.simulate.Runs`), replayed with
        :func:`rac.engine.simulate.simulate` forced to the runs' actions (``data``: the
        :class:`rac.model.data.ModelData`), to the longest run's last sample; beyond a run's own
        :attr:`samples_taken` its row is not part of the run. Also the ground truth.

        ``RuntimeError`` when the replay does not meet the recorded decision states."""
        from rac.engine.explore import action_pairs
        from rac.engine.simulate import simulate

        horizon = int(self.samples_taken.max()) if self.n_runs else 0
        actions = np.where(self.actions >= 0, self.actions, 0)  # past a run's end: any action
        n_actions = len(action_pairs(data))  # type: ignore[arg-type]

        def forced(k: int, states: np.ndarray) -> np.ndarray:
            mask = np.zeros((states.shape[0], n_actions), dtype=bool)
            mask[np.arange(states.shape[0]), actions[:, k // self.decide_every]] = True
            return mask

        runs = simulate(data, runs=self.n_runs, horizon_samples=horizon, seed=0, policy=forced,  # type: ignore[arg-type]
                        truth_substeps=truth_substeps)
        rows = np.arange(self.n_runs)
        for j in range(self.states.shape[1]):
            k = self.states[:, j, 0].astype(np.int64)
            if not np.array_equal(runs.states[rows, k], self.states[:, j, 1:]):
                raise RuntimeError(f"replaying the strategy's actions does not give its state at decision {j}")
        return runs


def _rollout(batch: Episodes, exprs: Sequence[Expression], n: int, shield: ShieldTable | None,
             choose: Callable[[np.ndarray, np.ndarray], np.ndarray]) -> StrategyRun:
    """``n`` episodes to their end; ``choose(observations, masks) -> actions`` at each decision."""
    batch.reset(n)
    steps_max = batch.max_steps
    states = np.zeros((n, steps_max + 1, 8), dtype=np.int32)
    observed = np.zeros((n, steps_max + 1, len(exprs)), dtype=np.float64)
    actions = np.full((n, steps_max), -1, dtype=np.int64)
    rewards = np.zeros((n, steps_max), dtype=np.float64)
    flags = {name: np.zeros(n, dtype=bool) for name in ("reached", "collided", "offroad")}
    fallbacks = np.zeros(n, dtype=np.int64)
    steps = np.zeros(n, dtype=np.int64)
    j = 0
    while True:
        states[:, j] = batch.state_keys()
        observed[:, j] = batch.observe(exprs) if exprs else np.zeros((n, 0))
        active = ~np.asarray(batch.done, dtype=bool)
        if j >= steps_max or not active.any():
            states[:, j + 1:] = states[:, j:j + 1]
            observed[:, j + 1:] = observed[:, j:j + 1]
            break
        masks, empty = _allowed(batch, shield)
        fallbacks += empty & active
        chosen = np.where(active, choose(observed[:, j], masks), 0)
        outcome = batch.step(chosen)
        actions[active, j] = chosen[active]
        rewards[active, j] = np.asarray(outcome.reward)[active]
        flags["reached"] |= np.asarray(outcome.terminated, dtype=bool) & active
        flags["collided"] |= np.asarray(outcome.collided, dtype=bool) & active
        flags["offroad"] |= np.asarray(outcome.offroad, dtype=bool) & active
        steps += active
        j += 1
    return StrategyRun(states, observed, actions, rewards, rewards.sum(axis=1), flags["reached"], flags["collided"],
                       flags["offroad"], fallbacks, steps, int(batch.decide_every), int(batch.horizon_samples))


def _strategy_chooser(strategy: LearnedStrategy) -> Callable[[np.ndarray, np.ndarray], np.ndarray]:
    return lambda observed, masks: strategy.act(observed, masks)


def run_strategy(batch: Episodes, strategy: LearnedStrategy, *, exprs: Sequence[Expression] | None = None,
                 shield: ShieldTable | None = None, runs: int = 1) -> StrategyRun:
    """The run(s) of the episodes under ``strategy`` (greedy among the actions ``shield`` allows):
    with the deterministic model and strategy all ``runs`` are the same run. ``exprs``: the
    observed expressions (default: :meth:`LearnedStrategy.expressions`). Use
    :meth:`StrategyRun.samples` for every sample of it (``A[] p under S``: ``p`` at each)."""
    _check_shield(batch, shield)
    exprs = tuple(exprs) if exprs is not None else strategy.expressions()
    return _rollout(batch, exprs, runs, shield, _strategy_chooser(strategy))


@dataclass(frozen=True)
class StrategyEvaluation:
    """:func:`evaluate`'s counts over ``runs`` runs; ``interval`` is the Clopper-Pearson 95%
    interval of the success rate."""

    runs: int
    successes: int
    reached: int
    collided: int
    offroad: int
    fallbacks: int
    mean_return: float
    interval: tuple[float, float]
    epsilon: float
    seed: int | None

    @property
    def success_rate(self) -> float:
        return self.successes / self.runs if self.runs else math.nan


def evaluate(batch: Episodes, strategy: LearnedStrategy, *, runs: int = 100, shield: ShieldTable | None = None,
             seed: int | None = None, epsilon: float = 0.0, exprs: Sequence[Expression] | None = None
             ) -> StrategyEvaluation:
    """The success rate of ``strategy`` over ``runs`` runs (success: the goal reached, never a
    collision nor off the road).

    The model and the greedy strategy are deterministic, so with ``epsilon == 0`` (default) every
    run is the one run and the rate is 0 or 1 — the honest answer, counted once per run. With
    ``epsilon > 0`` each decision takes, with that probability, a uniformly drawn *allowed* action
    instead of the greedy one (seeded by ``seed``): the rate then measures how well the strategy
    recovers from deviations, and under a shield the deviations stay safe. Action noise was
    chosen over perturbing the start because the episodes' start is the scenario's and a shield
    knows only the states reachable from it."""
    _check_shield(batch, shield)
    if not 0.0 <= epsilon <= 1.0:
        raise ValueError(f"epsilon must lie in [0, 1], not {epsilon}")
    from rac.engine.stats import clopper_pearson

    exprs = tuple(exprs) if exprs is not None else strategy.expressions()
    rng = np.random.default_rng(seed)

    def choose(observed: np.ndarray, masks: np.ndarray) -> np.ndarray:
        greedy = strategy.act(observed, masks)
        if epsilon == 0.0:
            return greedy
        return np.where(rng.random(len(greedy)) < epsilon, _uniform(rng, masks), greedy)

    run = _rollout(batch, exprs, runs, shield, choose)
    successes = int(run.success.sum())
    return StrategyEvaluation(runs, successes, int(run.reached.sum()), int(run.collided.sum()),
                              int(run.offroad.sum()), int(run.fallbacks.sum()), float(run.returns.mean()),
                              clopper_pearson(successes, runs), epsilon, seed)


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


def _update(values: np.ndarray, active: np.ndarray, rows: np.ndarray, actions: np.ndarray, reward: np.ndarray,
            next_rows: np.ndarray, next_masks: np.ndarray, ends: np.ndarray, alpha: float, gamma: float) -> None:
    """Watkins' update of every active episode's transition, in episode order (a later row sees an
    earlier one's update); ``reward`` already in the maximised sense. An ending episode does not
    bootstrap; the maximum runs over the actions allowed in the next state."""
    for i in active:
        target = reward[i]
        if not ends[i]:
            target += gamma * values[next_rows[i]][next_masks[i]].max()
        values[rows[i], actions[i]] += alpha * (target - values[rows[i], actions[i]])


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
    _check_shield(batch, shield)
    texts = _texts((*discrete, *continuous), labels)
    discrete = [batch.expression(e) for e in discrete]
    continuous = [batch.expression(e) for e in continuous]
    exprs = (*discrete, *continuous)
    widths = tuple(float(b) for b in (bins if bins is not None else [default_bin(e) for e in continuous]))
    if len(widths) != len(continuous) or not all(w > 0 and math.isfinite(w) for w in widths):
        raise ValueError(f"bins must be {len(continuous)} positive widths, not {list(widths)}")
    seed = int(np.random.SeedSequence().entropy) if seed is None else int(seed)
    rng = np.random.default_rng(seed)
    sign = 1.0 if optimise == "max" else -1.0
    n_discrete = len(discrete)
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
        return _greedy(table.utilities(rows), masks)

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
        masks, empty = _allowed(batch, shield)
        fallbacks = empty.astype(np.int64)
        returns = np.zeros(n)
        reached, collided, offroad = (np.zeros(n, dtype=bool) for _ in range(3))
        steps: list[tuple[np.ndarray, ...]] = []  # this batch's transitions, for the backward replay
        for _ in range(batch.max_steps):
            active = ~np.asarray(batch.done, dtype=bool)
            if not active.any():
                break
            explore = rng.random(n) < eps
            random_actions = _uniform(rng, masks)
            actions = np.where(explore, random_actions, _greedy(table.utilities(rows), masks))
            actions = np.where(active, actions, 0)
            outcome = batch.step(actions)
            reward = np.asarray(outcome.reward, dtype=np.float64)
            ends = np.asarray(outcome.terminated, dtype=bool) | np.asarray(outcome.truncated, dtype=bool)
            next_rows = table.rows(keys_now(), create=True)
            next_masks, next_empty = _allowed(batch, shield)
            _update(table.values, np.flatnonzero(active), rows, actions, sign * reward, next_rows, next_masks, ends,
                    alpha, gamma)
            steps.append((np.flatnonzero(active), rows, actions, sign * reward, next_rows, next_masks, ends))
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
                _update(table.values, *step, alpha, gamma)
        learned += n
        for name, value in (("returns", returns), ("reached", reached), ("collided", collided),
                            ("offroad", offroad), ("fallbacks", fallbacks)):
            log[name].append(value)
        # The stopping rule: evaluate the greedy strategy by its one run.
        run = _rollout(batch, exprs, 1, shield, greedy_choice)
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
    history = History(*(np.concatenate(log[name]) for name in ("returns", "reached", "collided", "offroad",
                                                                "fallbacks")),
                      np.array(log["eval_episodes"], dtype=np.int64), np.array(log["eval_returns"]),
                      np.array(log["eval_success"], dtype=bool))
    return LearningResult(best_strategy, best_run, history, first_success, int(history.collided.sum()),
                          int(history.offroad.sum()), int(history.fallbacks.sum()), learned, stopped_early,
                          time.perf_counter() - t0, seed)
