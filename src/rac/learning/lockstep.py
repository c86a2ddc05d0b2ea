"""Many learners and evaluations stepped together in one batch of episodes (issue 11).

A sample of an :class:`rac.learning.episodes.EpisodeBatch` costs about the same for one episode
as for a hundred, so independent runs — the seeds and combinations of ``rac experiment`` — are
cheapest stepped together. :func:`run_together` takes generators of steps
(:mod:`rac.learning.runs`: :func:`rac.learning.qlearning.learning`,
:func:`rac.learning.runs.evaluation_steps`, ...) and answers all their requests with one shared
batch, in *rounds*: when every generator asks for fresh episodes (:class:`rac.learning.runs.Reset`),
the batch is reset with all their widths side by side and each generator is sent a :class:`Lane`,
its own rows; then every step asked for is taken in one step of the batch, each generator getting
its rows' outcome. Before a step, the lookahead the generators ask for
(:class:`rac.learning.runs.Ahead`) is taken once for all the rows they ask, each getting its own
and charged its share. A generator whose episodes end before the others' waits for the next
round (its rows, done, cost nothing). Every episode is stepped row by row, a generator reads and draws
random numbers only for its own rows, so each result is the one the generator has alone
(:func:`rac.learning.runs.drive`); only the time changes. Each run is charged its own computing
time plus, for every step of the batch, a share of that step by its episodes still running.

With ``interruptible``, Ctrl-C (SIGINT) does not break into a generator halfway through its
computation: it is noted, and after the step under way every live generator is sent
:class:`rac.learning.runs.Stop`, so that it can return what it has (learning: the best strategy it
evaluated); :class:`Interrupted` then carries all results so far.

Example::

    shared = EpisodeBatch(result, reward="automaton")
    jobs = [Job(learning(shared, discrete=d, continuous=c, seed=seed)) for seed in (1, 2, 3)]
    for outcome, seconds in run_together(jobs, shared): ...
"""

from __future__ import annotations

import signal
import threading
import time
from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager, suppress
from dataclasses import dataclass
from typing import Any

import numpy as np

from rac.core.diagnostics import RacError
from rac.ir import expr as ie
from rac.learning.counterfactual import Counterfactuals
from rac.learning.episodes import EpisodeBatch, Expression, StepResult
from rac.learning.runs import Ahead, Reset, Steps, Stop, look_ahead
from rac.learning.strategy import Forwarding

__all__ = ["Between", "Interrupted", "Job", "Lane", "run_together"]


@dataclass
class Job:
    """A generator of steps for :func:`run_together`; with an ``objective`` (checked against the
    shared batch) each of its steps is rewarded with that expression's increase, as
    :class:`rac.learning.qlearning.ObjectiveIncrease` rewards it, else with the batch's reward."""

    steps: Steps[Any]
    objective: ie.Expr | None = None


class Between:
    """What lanes read of a shared batch between two of its steps, read once for every row (each lane
    takes its rows): the observed values of each list of expressions, the state keys and the model's
    masks. Twenty lanes of a batch then cost one reading, not twenty. :func:`run_together` empties it
    whenever it resets or steps the batch (:meth:`clear`). The values are those a lane's own reading
    gives: every quantity is computed row by row."""

    def __init__(self, shared: EpisodeBatch) -> None:
        self.shared = shared
        self.observed: dict[tuple[Expression, ...], np.ndarray] = {}  # equal expressions: the same values
        self.keys: np.ndarray | None = None
        self.masks: np.ndarray | None = None

    def clear(self) -> None:
        """The batch was reset or stepped: nothing read before holds."""
        self.observed.clear()
        self.keys = self.masks = None

    def observe(self, exprs: Sequence[Expression]) -> np.ndarray | None:
        """:meth:`rac.learning.episodes.EpisodeBatch.observe` of every row (read only); None for
        expressions that cannot be told apart (unhashable: parsed nodes holding lists)."""
        key = tuple(exprs)
        try:
            found = self.observed.get(key)
        except TypeError:
            return None
        if found is None:
            found = self.observed[key] = self.shared.observe(exprs)
        return found

    def state_keys(self) -> np.ndarray:
        """:meth:`rac.learning.episodes.EpisodeBatch.state_keys` of every row (read only)."""
        if self.keys is None:
            self.keys = self.shared.state_keys()
        return self.keys

    def model_masks(self) -> np.ndarray:
        """:meth:`rac.learning.episodes.EpisodeBatch.model_masks` of every row (read only)."""
        if self.masks is None:
            self.masks = self.shared.model_masks()
        return self.masks


class Lane(Forwarding):
    """The episodes ``rows`` of a shared batch, as a generator of steps reads them between its steps
    (:class:`rac.learning.strategy.Episodes`); :func:`run_together` resets and steps them. With
    ``between``, what the lane reads is read once for every lane (each reading is its own copy)."""

    def __init__(self, shared: EpisodeBatch, rows: slice, objective: ie.Expr | None = None,
                 between: Between | None = None) -> None:
        self.batch = self.shared = shared
        self.rows = rows
        self.objective = objective
        self.between = between

    @property
    def action_pairs(self) -> np.ndarray:
        return self.shared.action_pairs

    @property
    def n(self) -> int:
        return int(self.rows.stop - self.rows.start)

    @property
    def done(self) -> np.ndarray:
        return self.shared.done[self.rows]

    def reset(self, n: int) -> None:
        raise RuntimeError("a lane is reset by run_together: yield Reset(width)")

    def state_keys(self) -> np.ndarray:
        if self.between is None:
            return self.shared.state_keys(self.rows)
        return self.between.state_keys()[self.rows].copy()

    def model_masks(self) -> np.ndarray:
        if self.between is None:
            return self.shared.model_masks(self.rows)
        return self.between.model_masks()[self.rows].copy()

    def observe(self, exprs: Sequence[Expression]) -> np.ndarray:
        every = None if self.between is None else self.between.observe(exprs)
        if every is None:
            return self.shared.observe(exprs, self.rows)
        return every[self.rows].copy()

    def step(self, actions: np.ndarray) -> StepResult:
        raise RuntimeError("a lane is stepped by run_together: yield the actions")

    def counterfactual(self) -> Counterfactuals:
        """The last step of the lane's episodes replayed from every location of the automaton, with
        the lane's reward (:meth:`rac.learning.episodes.EpisodeBatch.counterfactual`)."""
        return self.shared.counterfactual(self.rows, self.objective)


class _Running:
    """One job in :func:`run_together`: its last request (None once finished), result and seconds."""

    def __init__(self, job: Job) -> None:
        self.job = job
        self.request: Any = None
        self.result: Any = None
        self.finished = False
        self.seconds = 0.0
        self.lane = slice(0, 0)

    def send(self, reply: Any) -> None:
        """Start the generator (``reply`` None) or answer its request; record the next one."""
        t0 = time.perf_counter()
        try:
            steps = self.job.steps
            self.request = next(steps) if reply is None else steps.send(reply)
        except StopIteration as stop:
            self.finished, self.result, self.request = True, stop.value, None
        self.seconds += time.perf_counter() - t0

    @property
    def stepping(self) -> bool:
        return not self.finished and not isinstance(self.request, Reset)


class Interrupted(RacError):
    """Ctrl-C stopped :func:`run_together` (``interruptible``): per job, in order, ``results`` holds
    what its generator returned, finished or stopped (None when it could not return anything), and
    the seconds charged to it. Only a caller that asks for ``interruptible`` meets it."""

    def __init__(self, results: list[tuple[Any, float]]) -> None:
        super().__init__("interrupted")
        self.results = results


@contextmanager
def _deferred_interrupts(wanted: bool) -> Iterator[Callable[[], bool]]:
    """While inside, SIGINT is only noted, and so is SIGTERM where a handler of the program's takes it as an
    interrupt (rac's command line: ``timeout``, a batch system's limit) (outside the main thread, or unless
    ``wanted``, both are left alone); yields whether one came. A SIGTERM noted is handed to that handler on
    the way out, the interrupt it raises left out (the stop is already under way), so that it knows."""
    if not wanted or threading.current_thread() is not threading.main_thread():
        yield lambda: False
        return
    came: list[int] = []
    previous = signal.signal(signal.SIGINT, lambda signum, frame: came.append(signum))
    # SIGTERM's default ends the process: only a handler of the program's is deferred. Before, that handler's
    # KeyboardInterrupt came in the middle of a step, and rac experiment dropped everything it had learned
    terminate = signal.getsignal(signal.SIGTERM)
    if callable(terminate):
        signal.signal(signal.SIGTERM, lambda signum, frame: came.append(signum))
    try:
        yield lambda: bool(came)
    finally:
        signal.signal(signal.SIGINT, previous)
        if callable(terminate):
            signal.signal(signal.SIGTERM, terminate)
            if signal.SIGTERM in came:
                with suppress(KeyboardInterrupt):
                    terminate(signal.SIGTERM, None)


def _stop(running: Sequence[_Running]) -> list[tuple[Any, float]]:
    """Send :class:`Stop` to every generator not finished; every job's result (None: nothing) and seconds."""
    for run in running:
        if run.finished:
            continue
        t0 = time.perf_counter()
        try:
            run.job.steps.throw(Stop())
        except StopIteration as stop:
            run.result = stop.value
        except Stop:
            run.result = None
        else:  # it went on asking for steps: it cannot stop early, so it has nothing to give
            run.job.steps.close()
            run.result = None
        run.finished = True
        run.seconds += time.perf_counter() - t0
    return [(run.result, run.seconds) for run in running]


def run_together(jobs: Sequence[Job], shared: EpisodeBatch, *, interruptible: bool = False) -> list[tuple[Any, float]]:
    """Run every job's generator to its end on the one batch ``shared`` (see the module docstring);
    per job, in order: its result and the seconds charged to it. ``interruptible``: Ctrl-C stops
    every job after the step under way, raising :class:`Interrupted` with what they returned."""
    running = [_Running(job) for job in jobs]
    with _deferred_interrupts(interruptible) as interrupted:
        try:
            results = _run(running, shared, Between(shared), interrupted)
        except _Stopping:
            raise Interrupted(_stop(running)) from None
        if interrupted():  # in the last step: every job finished, and the caller is told to stop too
            raise Interrupted(results)
        return results


class _Stopping(RacError):
    """Raised between two steps of :func:`_run` when a Ctrl-C was noted."""


def _run(running: list[_Running], shared: EpisodeBatch, between: Between,
         interrupted: Callable[[], bool]) -> list[tuple[Any, float]]:
    for run in running:
        run.send(None)
    while True:
        live = [run for run in running if not run.finished]
        if not live:
            return [(run.result, run.seconds) for run in running]
        widths = []
        for run in live:
            if not isinstance(run.request, Reset):  # every live generator waits for fresh episodes now
                raise RuntimeError(f"a generator stepped outside of a round: {run.request!r}")
            widths.append(int(run.request.width))
        t0 = time.perf_counter()
        shared.reset(sum(widths))
        between.clear()
        spent = time.perf_counter() - t0
        start = 0
        for run, width in zip(live, widths):
            run.lane = slice(start, start + width)
            run.seconds += spent * width / sum(widths)
            start += width
        for run in live:
            run.send(Lane(shared, run.lane, run.job.objective, between))
        while any(run.stepping for run in live):
            if interrupted():
                raise _Stopping
            _look(shared, live)
            _step(shared, [run for run in live if run.stepping], between)


def _every(between: Between, exprs: Sequence[ie.Expr]) -> np.ndarray:
    """``exprs`` observed in every row of the batch, kept in ``between`` where it can."""
    found = between.observe(exprs)
    return between.shared.observe(exprs) if found is None else found


def _look(shared: EpisodeBatch, live: list[_Running]) -> None:
    """Answer the lookahead requests (:class:`rac.learning.runs.Ahead`): one ``ahead`` of the batch per list of
    expressions, for every row asked, each requester charged by the rows it asked; until every request is a step."""
    while True:
        asking = [run for run in live if isinstance(run.request, Ahead)]
        if not asking:
            return
        groups: dict[Any, list[_Running]] = {}
        for run in asking:
            key: Any = tuple(run.request.exprs)
            try:
                hash(key)
            except TypeError:  # expressions that cannot be told apart (parsed nodes holding lists): asked alone
                key = run
            groups.setdefault(key, []).append(run)
        for runs in groups.values():
            rows = [run.lane.start + np.asarray(run.request.rows, dtype=np.int64) for run in runs]
            actions = [np.ones((part.size, shared.n_actions), dtype=bool) if run.request.actions is None
                       else run.request.actions for run, part in zip(runs, rows)]
            t0 = time.perf_counter()
            values = look_ahead(shared, runs[0].request.exprs, np.concatenate(rows), np.concatenate(actions))
            spent = time.perf_counter() - t0
            total = max(1, sum(part.size for part in rows))
            start = 0
            for run, part in zip(runs, rows):
                run.seconds += spent * part.size / total
                run.send(values[start:start + part.size])
                start += part.size


def _step(shared: EpisodeBatch, stepping: list[_Running], between: Between) -> None:
    """One step of ``shared`` with the actions the ``stepping`` jobs asked for; each is answered with
    its rows' outcome and charged a share of the step by its episodes still running."""
    actions = np.zeros(shared.n, dtype=np.int64)
    for run in stepping:
        actions[run.lane] = run.request
    running = ~shared.done
    objectives = list(dict.fromkeys(run.job.objective for run in stepping if run.job.objective is not None))
    t0 = time.perf_counter()
    # the objectives after one step are those before the next (kept in between until the batch changes)
    before = _every(between, objectives) if objectives else None
    outcome = shared.step(actions)
    between.clear()
    after = _every(between, objectives) if objectives else None
    spent = time.perf_counter() - t0
    # episodes still running before the step, up to each row: a lane's count is a difference (not a sum per lane)
    upto = [0, *np.cumsum(running).tolist()]
    weights = [upto[run.lane.stop] - upto[run.lane.start] for run in stepping]
    total = max(1, sum(weights))
    for run, weight in zip(stepping, weights):
        lane = run.lane
        reward = outcome.reward[lane]
        if run.job.objective is not None:
            assert before is not None and after is not None
            column = objectives.index(run.job.objective)
            with np.errstate(invalid="ignore"):  # inf - inf: a reward that is not a number, which its job refuses
                reward = np.where(running[lane], after[lane, column] - before[lane, column], 0.0)
        run.seconds += spent * weight / total
        run.send(StepResult(reward=reward, terminated=outcome.terminated[lane], truncated=outcome.truncated[lane],
                            collided=outcome.collided[lane], offroad=outcome.offroad[lane],
                            stranded=outcome.stranded[lane], ended=outcome.ended[lane]))
