"""Monte Carlo simulation of the model: UPPAAL's statistical (SMC) semantics, natively (issue 4).

:func:`simulate` runs ``N`` runs of the model together as one numpy batch, one sense period per
loop iteration:

- **Controller (sensed state).** The integer state ``(x, y, v, acc, head, jerk, turn)`` advances by
  :meth:`rac.model.batch.BatchModel.sense`, bit for bit :meth:`rac.model.native.NativeModel.sense`,
  with the same ``sample_k`` convention as :func:`rac.engine.explore.explore`: the state at sample
  ``k + 1`` is ``sense()`` of the state at ``k`` with the jerk and turn chosen at ``k``.
- **Choices.** At a decision sample (``k % decide_every == 0``) every run picks one (jerk, turn)
  pair of :func:`rac.engine.explore.action_pairs` *uniformly at random* among the allowed ones —
  UPPAAL resolves non-determinism uniformly in its SMC queries. Between decisions jerk and turn
  are kept. A ``policy`` (a shield or a strategy) restricts the allowed pairs.
- **Ground truth (Dynamics).** The emitted UPPAAL model's ``Dynamics`` process (see
  :mod:`rac.targets.uppaal.model`) integrates, from the ego's start ``i2d(EGO_X0) ...``::

      true_x' = true_v * cos(true_head)    true_y' = true_v * sin(true_head)
      true_v' = true_acc                   true_acc' = jerk     true_head' = turn

  with ``jerk``, ``turn`` the chosen actions as reals, *saturated* like the sensed state: the
  acceleration stops changing at ``±MA`` (``true_acc' = 0`` while ``|true_acc| >= MA`` and the
  jerk pushes further) and the speed at ``VMIN``/``VMAX`` (``true_v' = 0`` likewise), so the
  truth brakes to a stop instead of reversing. Natively it is integrated with the classic
  fourth-order Runge-Kutta method, ``truth_substeps`` equal steps per sense period ``C1``, the
  acceleration and speed clipped to their ranges after each step (RK4 is ``O(h^4)`` between the
  saturation switches; at 100 steps per 0.1 s the error is far below a millimetre).

Example::

    runs = simulate(data, runs=1000, horizon_samples=50, seed=1)
    drift = np.abs(runs.truth[:, :, 0] - runs.sensed_real()[:, :, 0])   # Qa's |true_x - x|
    hit = label_runs(data, runs, "collide").any(axis=1)                  # <> collide(), per run
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from rac.core.diagnostics import counted
from rac.core.numbers import INT32_MAX
from rac.engine.allow import ActionGuard, action_pairs
from rac.engine.budget import check_estimate, simulation_bytes
from rac.engine.graph import LABELS
from rac.ir.vocabulary import EGO_STATE, TRUE_STATE
from rac.model.batch import BatchModel, batch_model
from rac.model.data import ModelData, ModelRangeError
from rac.model.sample import ACTION, Ego, safe

__all__ = ["LABELS", "TRUTH_COLUMNS", "Policy", "Runs", "collided_so_far", "event_sampler", "integrate_one",
           "integrate_truth", "label_runs", "simulate"]

#: The columns of :attr:`Runs.truth` (metres, metres per second, ..., radians).
TRUTH_COLUMNS: tuple[str, ...] = TRUE_STATE

#: ``policy(k, states) -> allowed``: ``states`` is ``(n, 7)`` int32 (the runs' sensed states at
#: decision sample ``k``), ``allowed`` an ``(n, P)`` bool mask over :func:`action_pairs`.
Policy = Callable[[int, np.ndarray], np.ndarray]
#: ``progress(sample, horizon)``: called after every simulated sample (``sample`` = 1 .. horizon).
Progress = Callable[[int, int], None]


@dataclass(frozen=True, eq=False)
class Runs:
    """``N`` simulated runs of ``T`` sense periods (``T + 1`` samples, sample 0 the start).

    - ``states (N, T+1, 7) int32``: the sensed significands ``x, y, v, acc, head, jerk, turn``
      per sample. ``jerk`` and ``turn`` at sample ``k`` are those in force when sample ``k`` was
      sensed (0 at sample 0); the pair chosen at ``k`` first shows at ``k + 1``.
    - ``truth (N, T+1, 5) float64``: the ground truth (:data:`TRUTH_COLUMNS`) at each sample.
    - ``actions (N, T) int64``: the action index (row of :func:`action_pairs`) chosen at sample
      ``k``, ``-1`` at samples that are not decisions.
    - ``left_policy (N,) bool``: the run met a decision at which the policy allowed no action;
      it then chose uniformly among *all* actions there (UPPAAL would stop such a run as a
      deadlock under a strategy; continuing keeps every run ``T`` periods long, and the flag
      lets the caller discard or count them).
    - ``seed``: the seed that reproduces the runs; ``period``: ``C1`` in seconds; ``scale``: the
      significands' scale.
    - ``overflow (N,) int64`` (only from ``simulate(..., stop_at_overflow=True)``, else None): the
      first sample whose sensed state left int32, ``T + 1`` for a run that never did. A run stops
      there (UPPAAL's model aborts): from that sample on its states repeat its last one, which are
      not the model's, and a caller reads only the samples before it. ``overflow_errors`` holds
      each such run's :class:`~rac.model.data.ModelRangeError`, by run.

    The arrays are read-only.
    """

    states: np.ndarray
    truth: np.ndarray
    actions: np.ndarray
    left_policy: np.ndarray
    seed: int
    period: float
    scale: int
    overflow: np.ndarray | None = None
    overflow_errors: dict[int, ModelRangeError] = field(default_factory=dict)

    @property
    def n_runs(self) -> int:
        return int(self.states.shape[0])

    @property
    def horizon(self) -> int:
        """``T``: the number of sense periods simulated."""
        return int(self.actions.shape[1])

    @property
    def times(self) -> np.ndarray:
        """``(T+1,)`` float64: each sample's time in seconds since the ego's start (``k * C1``)."""
        return np.arange(self.horizon + 1, dtype=np.float64) * self.period

    def sensed_real(self) -> np.ndarray:
        """``(N, T+1, 7)`` float64: the sensed state as reals, ``significand / SCALE_D`` (UPPAAL's ``i2d``)."""
        return self.states / float(self.scale)


def _check_policy(allowed: np.ndarray, n: int, n_pairs: int) -> np.ndarray:
    allowed = np.asarray(allowed)
    if allowed.shape != (n, n_pairs) or allowed.dtype != np.bool_:
        raise ValueError(f"policy must return a bool array of shape ({n}, {n_pairs}), "
                         f"not {allowed.dtype} {allowed.shape}")
    return allowed


def _choose(rng: np.random.Generator, allowed: np.ndarray) -> np.ndarray:
    """One index per row, uniform among the row's True entries (every row has one)."""
    counts = allowed.sum(axis=1)
    pick = rng.integers(0, counts)  # the pick-th allowed entry of each row
    return np.argmax(np.cumsum(allowed, axis=1) > pick[:, None], axis=1).astype(np.int64)


@dataclass(frozen=True)
class Limits:
    """The saturation of the ground truth: ``|acc| <= max_acc``, ``min_speed <= v <= max_speed``."""

    max_acc: float
    min_speed: float
    max_speed: float

    @staticmethod
    def of(data: ModelData) -> Limits:
        scale = float(data.scale)
        return Limits(data.max_acc / scale, data.min_speed / scale, data.max_speed / scale)


def saturated(value: np.ndarray, rate: np.ndarray, low: float, high: float) -> np.ndarray:
    """The rate of a value kept in ``[low, high]``: ``rate``, or 0 where the value is at a bound and
    the rate points outward — the emitted declarations' ``saturated()``, which the Dynamics uses."""
    return np.where(((value >= high) & (rate > 0)) | ((value <= low) & (rate < 0)), 0.0, rate)


def _derivative(state: np.ndarray, jerk: np.ndarray, turn: np.ndarray, limits: Limits) -> np.ndarray:
    """The Dynamics ODE's right-hand side for ``state`` = (x, y, v, acc, head) rows (5, n)."""
    _, _, v, acc, head = state
    dacc = saturated(acc, jerk, -limits.max_acc, limits.max_acc)
    dv = saturated(v, acc, limits.min_speed, limits.max_speed)
    return np.stack([v * np.cos(head), v * np.sin(head), dv, dacc, turn])


def integrate_truth(truth: np.ndarray, jerk: np.ndarray, turn: np.ndarray, period: float,
                    substeps: int, limits: Limits) -> np.ndarray:
    """Classic RK4 over one sense period in ``substeps`` equal steps; ``truth`` is (5, n).
    After each step speed and acceleration are clipped to their ranges (a step may overshoot
    the switch of the saturated right-hand side). One run (``n == 1``, a learned strategy's
    replay) is integrated on scalars by :func:`integrate_one`, to the same doubles."""
    if truth.shape[1] == 1:
        return integrate_one(truth, float(jerk[0]), float(turn[0]), period, substeps, limits)
    h = period / substeps
    for _ in range(substeps):
        k1 = _derivative(truth, jerk, turn, limits)
        k2 = _derivative(truth + (h / 2) * k1, jerk, turn, limits)
        k3 = _derivative(truth + (h / 2) * k2, jerk, turn, limits)
        k4 = _derivative(truth + h * k3, jerk, turn, limits)
        truth = truth + (h / 6) * (k1 + 2 * k2 + 2 * k3 + k4)
        truth[2] = np.clip(truth[2], limits.min_speed, limits.max_speed)
        truth[3] = np.clip(truth[3], -limits.max_acc, limits.max_acc)
    return truth


def _clip(value: float, low: float, high: float) -> float:
    """``np.clip`` of one double (a bound only where the value passes it; NaN stays)."""
    value = low if value < low else value
    return high if value > high else value


def integrate_one(truth: np.ndarray, jerk: float, turn: float, period: float, substeps: int,
                  limits: Limits) -> np.ndarray:
    """:func:`integrate_truth` of one run (``truth`` (5, 1)) on Python floats: the same operations in
    the same order (IEEE doubles, no fused multiply-add, ``np.cos``/``np.sin`` as the array version
    calls them), without numpy's cost per call on arrays of one element — about ten times faster."""
    x, y, v, acc, head = (float(value) for value in truth[:, 0])
    h = period / substeps
    half = h / 2
    sixth = h / 6
    max_acc, min_speed, max_speed = limits.max_acc, limits.min_speed, limits.max_speed
    cos, sin = np.cos, np.sin

    def rates(v: float, acc: float, head: float) -> tuple[float, float, float, float]:
        """x', y', v', acc' (head' is the turn): :func:`_derivative` of one state."""
        dacc = 0.0 if (acc >= max_acc and jerk > 0) or (acc <= -max_acc and jerk < 0) else jerk
        dv = 0.0 if (v >= max_speed and acc > 0) or (v <= min_speed and acc < 0) else acc
        return v * float(cos(head)), v * float(sin(head)), dv, dacc

    for _ in range(substeps):
        x1, y1, v1, a1 = rates(v, acc, head)
        x2, y2, v2, a2 = rates(v + half * v1, acc + half * a1, head + half * turn)
        x3, y3, v3, a3 = rates(v + half * v2, acc + half * a2, head + half * turn)
        x4, y4, v4, a4 = rates(v + h * v3, acc + h * a3, head + h * turn)
        x = x + sixth * (x1 + 2 * x2 + 2 * x3 + x4)
        y = y + sixth * (y1 + 2 * y2 + 2 * y3 + y4)
        v = _clip(v + sixth * (v1 + 2 * v2 + 2 * v3 + v4), min_speed, max_speed)
        acc = _clip(acc + sixth * (a1 + 2 * a2 + 2 * a3 + a4), -max_acc, max_acc)
        head = head + sixth * (turn + 2 * turn + 2 * turn + turn)
    return np.array([[x], [y], [v], [acc], [head]], dtype=np.float64)


def _sense_rows(model: BatchModel, states: np.ndarray) -> tuple[np.ndarray, np.ndarray, list[ModelRangeError]]:
    """``model.sense`` of each row that stays within int32: the next states (a row that leaves it kept
    as it was), which rows left it, and their errors in row order. The batch raises for its first bad
    row only, so a failing batch is halved until each bad row stands alone (rows are independent)."""
    try:
        return model.sense(states), np.zeros(states.shape[0], dtype=bool), []
    except ModelRangeError as error:
        if states.shape[0] == 1:
            return states.copy(), np.ones(1, dtype=bool), [error]
        half = states.shape[0] // 2
        head, tail = _sense_rows(model, states[:half]), _sense_rows(model, states[half:])
        return np.concatenate([head[0], tail[0]]), np.concatenate([head[1], tail[1]]), head[2] + tail[2]


def _horizon(data: ModelData, horizon_samples: int | None) -> int:
    if horizon_samples is None:
        if data.goal_high >= INT32_MAX:
            raise ValueError("simulate() needs horizon_samples: the goal's time interval is unbounded")
        return data.goal_high
    if horizon_samples < 0:
        raise ValueError(f"horizon_samples must be >= 0, not {horizon_samples}")
    return horizon_samples


def simulate(data: ModelData, *, runs: int, horizon_samples: int | None = None, seed: int | None = None,
             policy: Policy | None = None, truth_substeps: int = 100, progress: Progress | None = None,
             max_bytes: int | None = None, stop_at_overflow: bool = False, truth: bool = True) -> Runs:
    """Simulate ``runs`` runs of ``horizon_samples`` sense periods with uniformly drawn actions.

    See the module docstring for the semantics. ``horizon_samples`` defaults to the goal
    interval's last sample, like :func:`rac.engine.explore.explore` (``ValueError`` when that is
    unbounded). ``seed`` seeds ``numpy.random.default_rng``; the same seed gives identical runs
    (the random draws are the action choices only, so ``truth_substeps`` does not change them).
    Without a seed a fresh one is drawn and recorded in :attr:`Runs.seed`.

    ``policy(k, states)`` (None: every action allowed) returns the ``(n, P)`` bool mask of the
    actions allowed to each run at decision sample ``k``; the model's ``allow when`` restricts them
    further (:class:`rac.engine.allow.ActionGuard`). A run whose row allows nothing chooses
    among all actions there and is flagged in :attr:`Runs.left_policy`.

    :class:`rac.model.data.ModelRangeError` when a sensed value overflows int32 (as explore()); with
    ``stop_at_overflow`` that run stops there instead and the others go on (:attr:`Runs.overflow`), for
    a caller that can use a run's samples before it (``<> p`` satisfied earlier, as UPPAAL stops there).
    :class:`rac.engine.budget.EstimateExceeded`, before anything is allocated, when the runs would
    need more than ``max_bytes`` (None: no limit; :func:`rac.engine.budget.simulation_bytes`).

    ``truth`` False leaves the ground truth out (:attr:`Runs.truth` NaN), for callers that read the sensed
    state only: its RK4 integration is nine tenths of a simulation's time. The runs are the same either way.
    """
    if isinstance(runs, bool) or not isinstance(runs, int | np.integer) or runs < 1:
        raise ValueError(f"runs must be a positive integer, not {runs!r}")
    if isinstance(truth_substeps, bool) or not isinstance(truth_substeps, int | np.integer) or truth_substeps < 1:
        raise ValueError(f"truth_substeps must be a positive integer, not {truth_substeps!r}")
    horizon = _horizon(data, horizon_samples)
    check_estimate(f"simulating {counted(runs, 'run')} of {counted(horizon, 'sample')}",
                   simulation_bytes(runs, horizon, 0), max_bytes,
                   "lower the runs or the horizon")
    if seed is None:
        entropy = np.random.SeedSequence().entropy
        assert isinstance(entropy, int)  # a fresh SeedSequence draws one int from the OS
        seed = entropy
    rng = np.random.default_rng(seed)
    model = batch_model(data)
    pairs = action_pairs(data)
    guard = ActionGuard(data)
    n_pairs = len(pairs)
    scale = float(data.scale)
    period = data.period

    states = np.empty((runs, horizon + 1, len(EGO_STATE)), dtype=np.int32)
    true_states = np.full((runs, horizon + 1, len(TRUTH_COLUMNS)), np.nan) if not truth else \
        np.empty((runs, horizon + 1, len(TRUTH_COLUMNS)), dtype=np.float64)
    actions = np.full((runs, horizon), -1, dtype=np.int64)
    left_policy = np.zeros(runs, dtype=bool)

    current = np.tile(np.asarray(model.native.initial_state(), dtype=np.int32), (runs, 1))
    start = np.array([data.ego_x, data.ego_y, data.ego_v, data.ego_acc, data.ego_head]) / scale
    true_now = np.repeat(start[:, None], runs, axis=1)  # (5, n): rows are the ODE's variables
    states[:, 0, :] = current  # sample 0 of every run
    if truth:
        true_states[:, 0] = true_now.T
    everything = np.ones((runs, n_pairs), dtype=bool)
    limits = Limits.of(data)
    overflow = np.full(runs, horizon + 1, dtype=np.int64)
    errors: dict[int, ModelRangeError] = {}

    def allowed_at(k: int, rows: np.ndarray, every: np.ndarray) -> np.ndarray:
        """The actions allowed to ``rows`` at the decision sample ``k`` (``every``: all of them)."""
        allowed = every if policy is None else _check_policy(policy(k, rows.copy()), rows.shape[0], n_pairs)
        if guard.restricts:  # the model's own `allow when`, under any policy
            allowed = allowed & guard.masks(rows, k)
        return allowed

    for k in range(horizon):
        live = overflow > k  # runs whose state is still the model's (every run without stop_at_overflow)
        if k % data.decide_every == 0:
            if live.all():
                allowed = allowed_at(k, current, everything)
            else:  # a stopped run is neither asked about nor flagged: its state is no longer the model's
                allowed = everything.copy()
                allowed[live] = allowed_at(k, current[live], everything[live])
            empty = ~np.any(allowed, axis=1)
            if empty.any():
                left_policy |= empty
                allowed = allowed | empty[:, None]
            chosen = _choose(rng, allowed)  # every run draws, so the others' draws do not depend on stops
            actions[:, k] = np.where(live, chosen, -1)
            current = current.copy()
            current[live, ACTION] = pairs[chosen[live]]
        # the truth uses the same reals as the emitted ODE: jerk / SCALE_D, turn / SCALE_D
        if truth:
            true_now = integrate_truth(true_now, current[:, Ego.JERK] / scale, current[:, Ego.TURN] / scale, period,
                                       truth_substeps, limits)
        if not stop_at_overflow:
            current = model.sense(current)
        elif live.any():
            sensed, bad, failures = _sense_rows(model, current[live])
            current = current.copy()
            current[live] = sensed
            runs_bad = np.flatnonzero(live)[bad]
            overflow[runs_bad] = k + 1
            errors.update(zip(runs_bad.tolist(), failures))
        states[:, k + 1] = current
        if truth:
            true_states[:, k + 1] = true_now.T
        if progress is not None:
            progress(k + 1, horizon)
    for array in (states, true_states, actions, left_policy):
        array.setflags(write=False)
    if stop_at_overflow:
        overflow.setflags(write=False)
    return Runs(states=states, truth=true_states, actions=actions, left_policy=left_policy, seed=int(seed),
                period=period, scale=int(data.scale), overflow=overflow if stop_at_overflow else None,
                overflow_errors=errors)


def label_runs(data: ModelData, runs: Runs, label: str) -> np.ndarray:
    """``(N, T+1)`` bool: ``label`` (one of :data:`LABELS`) at every sample of every run.

    The labels are those of :func:`rac.engine.explore.explore` (``safe`` is ``!collide && !offroad``),
    evaluated on the sensed states with the sample index, so ``label_runs(...).any(axis=1)`` is
    UPPAAL's ``<> label`` per run over ``[0, T]``.
    """
    if label not in LABELS:
        raise ValueError(f"unknown label {label!r}; expected one of {LABELS}")
    model = batch_model(data)
    n, samples, _ = runs.states.shape
    flat = runs.states.reshape(n * samples, -1)
    k = np.tile(np.arange(samples, dtype=np.int64), n)
    if label == "goal":
        value = model.goal(flat, k)
    elif label == "offroad":
        value = model.offroad(flat, k)
    else:
        collide = model.collide(flat, k).reshape(n, samples)
        if data.sticky:
            collide = np.logical_or.accumulate(collide, axis=1)
        if label == "collide":
            return collide
        value = safe(collide.reshape(-1), model.offroad(flat, k))
    return value.reshape(n, samples)


def collided_so_far(data: ModelData, runs: Runs) -> np.ndarray | None:
    """``(N, T+1)`` bool under ``collision sticky``: whether ``collide()`` held at each sample or an
    earlier one of each run (what :class:`rac.engine.evaluate.Frame` ``crashed`` wants); None otherwise."""
    return label_runs(data, runs, "collide") if data.sticky else None


def event_sampler(data: ModelData, event: Callable[[Runs], np.ndarray], *, horizon_samples: int | None = None,
                  seed: int | None = None, policy: Policy | None = None,
                  truth_substeps: int = 100) -> Callable[[int], np.ndarray]:
    """A sampler for :mod:`rac.engine.stats`: ``sample(n)`` simulates ``n`` fresh runs and returns
    ``event(runs)``, an ``(n,)`` bool array (e.g. ``lambda r: label_runs(data, r, "collide").any(axis=1)``).

    Each call draws its runs' seed from one generator seeded with ``seed``, so successive batches
    are independent and the whole sequence is reproducible."""
    seeds = np.random.default_rng(seed)

    def sample(n: int) -> np.ndarray:
        runs = simulate(data, runs=n, horizon_samples=horizon_samples, seed=int(seeds.integers(2**63)),
                        policy=policy, truth_substeps=truth_substeps)
        return event(runs)

    return sample
