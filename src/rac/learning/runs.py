"""Runs of episodes under a strategy, and the protocol that lets several of them share a batch.

:func:`rollout` runs ``n`` episodes to their end, choosing at each decision; :func:`run_strategy`
is a learned strategy's run (:meth:`StrategyRun.samples` every sample of it, for ``A[] p under
S``) and :func:`evaluate` its success rate.

**Steps as requests (issue 11).** Whatever runs episodes — a rollout, an evaluation, learning
(:func:`rac.learning.qlearning.learning`) — is written as a generator that *requests* what it
needs from its episodes instead of calling them: it yields :class:`Reset` (``width`` fresh
episodes; it is sent the :class:`rac.learning.strategy.Episodes` to read them through), an
:class:`Ahead` (it is sent what some expressions would read one decision later under each
action: a lookahead in the model, for steered exploration) or the actions of one step (it is
sent the step's outcome). Everything else (observing, the state keys, ``done``) it reads
directly. :func:`drive` answers the requests with one batch of episodes;
:func:`rac.learning.lockstep.run_together` answers many generators with one shared batch, each
reading its own rows, so that they pay for a sample together.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Callable, Generator, Sequence
from dataclasses import dataclass
from typing import Any, Concatenate, ParamSpec, TypeVar

import numpy as np

from rac.core.diagnostics import RacError, RacValueError
from rac.engine.shield import ShieldTable
from rac.learning.episodes import Expression
from rac.learning.strategy import (
    Episodes,
    LearnedStrategy,
    StepOutcome,
    StrategyRun,
    allowed_actions,
    check_shield,
    uniform_allowed,
)

__all__ = ["Ahead", "Request", "Reset", "RunRecorder", "Steps", "Stop", "StrategyEvaluation", "alone", "drive",
           "evaluate", "evaluation_steps", "look_ahead", "rollout", "rollout_steps", "run_strategy"]

T = TypeVar("T")
P = ParamSpec("P")


@dataclass(frozen=True)
class Reset:
    """A request for ``width`` fresh episodes (answered with the episodes to read them through)."""

    width: int


@dataclass(frozen=True, eq=False)
class Ahead:
    """A request for ``exprs`` one decision later under each action, in the episodes ``rows`` (indices into
    the requester's episodes), under the ``actions`` of each (a ``(len(rows), n_actions)`` mask; None: all):
    answered with the ``(len(rows), n_actions, len(exprs))`` values of
    :meth:`rac.learning.episodes.EpisodeBatch.ahead` (NaN for an action not asked). As a request, the
    lookahead of several generators sharing a batch is taken together
    (:func:`rac.learning.lockstep.run_together`), for the rows and actions they ask."""

    exprs: tuple[Expression, ...]
    rows: np.ndarray
    actions: np.ndarray | None = None


class Stop(RacError):
    """Thrown into a generator of steps to end it now (its caller was interrupted): it returns what it
    has so far if it can (learning: the best strategy it evaluated), or lets this propagate."""


#: What a generator of steps yields: a :class:`Reset`, an :class:`Ahead`, or the ``(n,)`` actions of one step.
Request = Reset | Ahead | np.ndarray
#: A generator of steps returning a ``T``; it is sent an :class:`Episodes` after a :class:`Reset`, the
#: values after an :class:`Ahead` and a :class:`StepOutcome` after actions.
Steps = Generator[Request, Any, T]


def drive(steps: Steps[T], episodes: Episodes) -> T:
    """Answer every request of ``steps`` with ``episodes`` alone (``reset``, ``ahead``, ``step``); its result."""
    try:
        request = next(steps)
        while True:
            if isinstance(request, Reset):
                episodes.reset(request.width)
                request = steps.send(episodes)
            elif isinstance(request, Ahead):
                request = steps.send(look_ahead(episodes, request.exprs, request.rows, request.actions))
            else:
                request = steps.send(episodes.step(request))
    except StopIteration as stop:
        return stop.value


def look_ahead(episodes: Episodes, exprs: Sequence[Expression], rows: np.ndarray,
               actions: np.ndarray | None = None) -> np.ndarray:
    """``episodes.ahead(exprs, rows, actions)`` (:meth:`rac.learning.episodes.EpisodeBatch.ahead`); episodes that
    cannot look ahead (a stand-in without ``ahead``) are said so, not met as an AttributeError."""
    ahead = getattr(episodes, "ahead", None)
    if ahead is None:
        raise RacValueError("these episodes cannot look ahead in the model (no ahead()): explore uniformly")
    values: np.ndarray = ahead(exprs, rows, actions)
    return values


def alone(steps: Callable[Concatenate[Episodes, P], Steps[T]]) -> Callable[Concatenate[Episodes, P], T]:
    """``steps(batch, ...)``, a function making a generator of steps, as the function that drives
    it on ``batch`` alone (:func:`drive`) and returns its result."""

    @functools.wraps(steps)
    def run(batch: Episodes, /, *args: P.args, **kwargs: P.kwargs) -> T:
        return drive(steps(batch, *args, **kwargs), batch)

    return run


class RunRecorder:
    """Records rows ``rows`` of a batch of episodes, decision by decision, as the
    :class:`StrategyRun` :func:`rollout` returns: :meth:`before` each decision (and once after the
    last), :meth:`after` each step, then :meth:`finish`. Learning records its greedy episode so
    while it steps it next to the learning episodes (:func:`rac.learning.qlearning.learn`)."""

    def __init__(self, batch: Episodes, rows: slice, n: int, width: int) -> None:
        steps_max = batch.max_steps
        self.batch = batch
        self.rows = rows
        self.j = 0
        self.states = np.zeros((n, steps_max + 1, 8), dtype=np.int32)
        self.observed = np.zeros((n, steps_max + 1, width), dtype=np.float64)
        self.actions = np.full((n, steps_max), -1, dtype=np.int64)
        self.rewards = np.zeros((n, steps_max), dtype=np.float64)
        self.reached, self.collided, self.offroad, self.stranded = (np.zeros(n, dtype=bool) for _ in range(4))
        self.fallbacks = np.zeros(n, dtype=np.int64)
        self.steps = np.zeros(n, dtype=np.int64)

    def before(self, observed: np.ndarray, states: np.ndarray | None = None) -> None:
        """The recorded rows' state keys and ``observed`` values (every row of the batch) at decision
        ``j``; ``states``: the batch's :meth:`rac.learning.strategy.Episodes.state_keys` now, when the
        caller has them."""
        self.states[:, self.j] = (self.batch.state_keys() if states is None else states)[self.rows]
        self.observed[:, self.j] = observed[self.rows]

    def after(self, active: np.ndarray, empty: np.ndarray, chosen: np.ndarray, outcome: StepOutcome) -> None:
        """One step of the batch (arrays over every row): which rows were ``active``, had an
        ``empty`` shield mask, the actions ``chosen`` and the step's ``outcome``."""
        j, rows = self.j, self.rows
        live = active[rows]
        # every recorded row still runs (learning's greedy episode, always): a slice, no row to leave out
        at = slice(None) if live.all() else live
        self.fallbacks[at] += empty[rows][at]
        self.actions[at, j] = chosen[rows][at]
        self.rewards[at, j] = np.asarray(outcome.reward)[rows][at]
        for flag, value in ((self.reached, outcome.terminated), (self.collided, outcome.collided),
                            (self.offroad, outcome.offroad), (self.stranded, outcome.stranded)):
            flag[at] |= np.asarray(value, dtype=bool)[rows][at]
        self.steps[at] += 1
        self.j += 1

    def finish(self) -> StrategyRun:
        """The run: after the last recorded decision every row repeats its last state."""
        j = self.j
        self.states[:, j + 1:] = self.states[:, j:j + 1]
        self.observed[:, j + 1:] = self.observed[:, j:j + 1]
        return StrategyRun(self.states, self.observed, self.actions, self.rewards, self.rewards.sum(axis=1),
                           self.reached, self.collided, self.offroad, self.stranded, self.fallbacks,
                           self.steps, int(self.batch.decide_every), int(self.batch.horizon_samples))


def rollout_steps(exprs: Sequence[Expression], n: int, shield: ShieldTable | None,
                  choose: Callable[[np.ndarray, np.ndarray], np.ndarray]) -> Steps[StrategyRun]:
    """:func:`rollout` as a generator of steps (see the module docstring)."""
    batch: Episodes = yield Reset(n)
    recorder = RunRecorder(batch, slice(None), n, len(exprs))
    while True:
        observed = batch.observe(exprs) if exprs else np.zeros((n, 0))
        recorder.before(observed)
        active = ~np.asarray(batch.done, dtype=bool)
        if recorder.j >= batch.max_steps or not active.any():
            return recorder.finish()
        masks, empty = allowed_actions(batch, shield)
        chosen = np.where(active, choose(observed, masks), 0)
        outcome: StepOutcome = yield chosen
        recorder.after(active, empty, chosen, outcome)


def rollout(batch: Episodes, exprs: Sequence[Expression], n: int, shield: ShieldTable | None,
            choose: Callable[[np.ndarray, np.ndarray], np.ndarray]) -> StrategyRun:
    """``n`` episodes to their end; ``choose(observations, masks) -> actions`` at each decision."""
    return drive(rollout_steps(exprs, n, shield, choose), batch)


def _strategy_chooser(strategy: LearnedStrategy) -> Callable[[np.ndarray, np.ndarray], np.ndarray]:
    return lambda observed, masks: strategy.act(observed, masks)


def run_strategy(batch: Episodes, strategy: LearnedStrategy, *, exprs: Sequence[Expression] | None = None,
                 shield: ShieldTable | None = None, runs: int = 1) -> StrategyRun:
    """The run(s) of the episodes under ``strategy`` (greedy among the actions ``shield`` allows):
    with the deterministic model and strategy all ``runs`` are the same run. ``exprs``: the
    observed expressions (default: :meth:`LearnedStrategy.expressions`). Use
    :meth:`StrategyRun.samples` for every sample of it (``A[] p under S``: ``p`` at each)."""
    check_shield(batch, shield)
    exprs = tuple(exprs) if exprs is not None else strategy.expressions()
    return rollout(batch, exprs, runs, shield, _strategy_chooser(strategy))


@dataclass(frozen=True)
class StrategyEvaluation:
    """:func:`evaluate`'s counts over ``runs`` runs; :attr:`interval` is the Clopper-Pearson 95%
    interval of the success rate."""

    runs: int
    successes: int
    reached: int
    collided: int
    offroad: int
    fallbacks: int
    mean_return: float
    epsilon: float
    seed: int | None

    @property
    def success_rate(self) -> float:
        return self.successes / self.runs if self.runs else math.nan

    @property
    def interval(self) -> tuple[float, float]:
        """The Clopper-Pearson 95% interval of the success rate (computed when asked: its scipy import
        costs ~0.15 s of CPU, and ``rac experiment`` evaluates 20 strategies without reading it)."""
        from rac.engine.stats import clopper_pearson  # scipy: only when the interval is asked for

        return clopper_pearson(self.successes, self.runs)


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
    check_shield(batch, shield)
    return drive(evaluation_steps(strategy, runs=runs, shield=shield, seed=seed, epsilon=epsilon, exprs=exprs), batch)


def evaluation_steps(strategy: LearnedStrategy, *, runs: int = 100, shield: ShieldTable | None = None,
                     seed: int | None = None, epsilon: float = 0.0, exprs: Sequence[Expression] | None = None
                     ) -> Steps[StrategyEvaluation]:
    """:func:`evaluate` as a generator of steps (see the module docstring)."""
    if not 0.0 <= epsilon <= 1.0:
        raise ValueError(f"epsilon must lie in [0, 1], not {epsilon}")
    exprs = tuple(exprs) if exprs is not None else strategy.expressions()
    rng = np.random.default_rng(seed)

    def choose(observed: np.ndarray, masks: np.ndarray) -> np.ndarray:
        greedy = strategy.act(observed, masks)
        if epsilon == 0.0:
            return greedy
        return np.where(rng.random(len(greedy)) < epsilon, uniform_allowed(rng, masks), greedy)

    run = yield from rollout_steps(exprs, runs, shield, choose)
    successes = int(run.success.sum())
    return StrategyEvaluation(runs, successes, int(run.reached.sum()), int(run.collided.sum()),
                              int(run.offroad.sum()), int(run.fallbacks.sum()), float(run.returns.mean()),
                              epsilon, seed)
