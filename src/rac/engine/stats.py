"""Statistics of UPPAAL's statistical model checking, as pure functions (issue 4).

- :func:`clopper_pearson`: the exact (conservative) binomial confidence interval UPPAAL prints
  for ``Pr[...]``.
- :func:`estimate_probability`: ``Pr[<=T](<> p)`` — runs until the interval is narrow enough
  (UPPAAL's ``-E`` epsilon, default ±0.05, at ``1 - alpha`` = 95 %);
  :func:`estimate_probability_fixed`: ``Pr[<=T;N](<> p)`` — exactly ``N`` runs.
- :func:`sequential_test`: ``Pr[<=T](<> p) >= theta`` — Wald's sequential probability ratio
  test with an indifference region (UPPAAL's ``-a``, ``-B``, ``-d`` options).
- :func:`mean_interval`: ``E[<=T;N](max: e)`` — the mean with a Student-t interval.

The probability functions take a *sampler*: ``sample(n)`` returns an ``(n,)`` bool array, one
independent Bernoulli outcome per run (e.g. :func:`rac.engine.simulate.event_sampler`). They
draw runs in batches of ``batch`` but evaluate the stopping rule after *every* run of a batch and
discard the runs drawn beyond the stopping point, so the result is that of the one-run-at-a-time
procedure, whatever the batch size.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
from scipy import special  # betaincinv and stdtrit: scipy.stats' quantiles, without importing scipy.stats (~0.8 s)

__all__ = [
    "HypothesisResult",
    "ProbabilityEstimate",
    "RunningMean",
    "Sampler",
    "clopper_pearson",
    "estimate_probability",
    "estimate_probability_fixed",
    "mean_interval",
    "sequential_test",
]

#: ``sample(n) -> (n,) bool``: ``n`` fresh independent runs, True where the event holds.
Sampler = Callable[[int], np.ndarray]

DEFAULT_MAX_RUNS = 100_000
DEFAULT_BATCH = 100


@dataclass(frozen=True)
class ProbabilityEstimate:
    """A probability's confidence interval ``[lo, hi]`` from ``successes`` out of ``runs``.

    ``converged`` is False when :func:`estimate_probability` stopped at ``max_runs`` before the
    interval was narrow enough (the interval is then still valid, only wider than asked)."""

    lo: float
    hi: float
    successes: int
    runs: int
    confidence: float = 0.95
    converged: bool = True

    @property
    def estimate(self) -> float:
        """The point estimate ``successes / runs``."""
        return self.successes / self.runs if self.runs else math.nan

    @property
    def half_width(self) -> float:
        return (self.hi - self.lo) / 2


@dataclass(frozen=True)
class HypothesisResult:
    """The verdict of :func:`sequential_test`: ``accepted`` is ``Pr >= theta`` accepted.

    ``decided`` is False when ``max_runs`` ran out before either threshold was crossed; then
    ``accepted`` is only the point estimate's side of ``theta`` and carries no error bound."""

    accepted: bool
    runs: int
    successes: int
    decided: bool = True


# ---------------------------------------------------------------- validation
def _positive_int(name: str, value: object) -> int:
    if isinstance(value, bool) or not isinstance(value, int | np.integer) or value < 1:
        raise ValueError(f"{name} must be a positive integer, not {value!r}")
    return int(value)


def _open_unit(name: str, value: float) -> float:
    if not isinstance(value, int | float | np.floating) or not 0.0 < value < 1.0:
        raise ValueError(f"{name} must lie strictly between 0 and 1, not {value!r}")
    return float(value)


def _draw(sample: Sampler, n: int) -> np.ndarray:
    out = np.asarray(sample(n))
    if out.shape != (n,) or out.dtype != np.bool_:
        raise ValueError(f"sample({n}) must return a bool array of shape ({n},), not {out.dtype} {out.shape}")
    return out


# ---------------------------------------------------------------- Clopper-Pearson
def _cp(successes: np.ndarray, n: np.ndarray, alpha: float) -> tuple[np.ndarray, np.ndarray]:
    """Clopper-Pearson bounds over arrays (``n >= 1``): beta quantiles, closed at 0 and n."""
    s = np.asarray(successes, dtype=np.float64)
    n = np.asarray(n, dtype=np.float64)
    with np.errstate(invalid="ignore"):  # the quantiles at s == 0 / s == n are replaced below
        lo = np.where(s > 0, special.betaincinv(s, n - s + 1, alpha / 2), 0.0)
        hi = np.where(s < n, special.betaincinv(s + 1, n - s, 1 - alpha / 2), 1.0)
    return lo, hi


def clopper_pearson(successes: int, n: int, confidence: float = 0.95) -> tuple[float, float]:
    """The exact two-sided Clopper-Pearson interval for a binomial proportion.

    ``lo`` is the ``alpha/2`` quantile of Beta(s, n-s+1) (0 when ``s == 0``), ``hi`` the
    ``1-alpha/2`` quantile of Beta(s+1, n-s) (1 when ``s == n``), ``alpha = 1 - confidence``:
    the ``p`` at which seeing at least (at most) ``s`` successes has probability ``alpha/2``.
    Its coverage is at least ``confidence`` for every ``p`` and ``n``. ``n == 0`` gives ``(0, 1)``.
    """
    confidence = _open_unit("confidence", confidence)
    if isinstance(n, bool) or not isinstance(n, int | np.integer) or n < 0:
        raise ValueError(f"n must be a non-negative integer, not {n!r}")
    if isinstance(successes, bool) or not isinstance(successes, int | np.integer) or not 0 <= successes <= n:
        raise ValueError(f"successes must be an integer in [0, n={n}], not {successes!r}")
    if n == 0:
        return 0.0, 1.0
    lo, hi = _cp(np.asarray(successes), np.asarray(n), 1.0 - confidence)
    return float(lo), float(hi)


# ---------------------------------------------------------------- estimation
def estimate_probability(sample: Sampler, *, epsilon: float = 0.05, confidence: float = 0.95,
                         max_runs: int = DEFAULT_MAX_RUNS, batch: int = DEFAULT_BATCH) -> ProbabilityEstimate:
    """``Pr[<=T](<> p)``: estimate a probability to within ``±epsilon`` at ``confidence``.

    Stopping rule (UPPAAL's sequential estimation): after each run ``m``, with ``s`` successes so
    far, compute the Clopper-Pearson interval ``[lo, hi]`` of ``s / m``; stop at the first ``m``
    with ``hi - lo <= 2 * epsilon`` and return that interval. At the defaults (±0.05, 95 %) this
    takes 36 runs when every run agrees and about 400 when ``p`` is near 1/2. If ``max_runs`` runs
    do not suffice, the interval of all ``max_runs`` runs is returned with ``converged=False``.

    As in UPPAAL, the interval is the fixed-``n`` Clopper-Pearson interval evaluated at a random
    ``n``; its nominal confidence is not corrected for the sequential stopping.
    """
    epsilon = _open_unit("epsilon", epsilon)
    confidence = _open_unit("confidence", confidence)
    max_runs = _positive_int("max_runs", max_runs)
    batch = _positive_int("batch", batch)
    alpha = 1.0 - confidence
    successes = runs = 0
    while runs < max_runs:
        m = min(batch, max_runs - runs)
        cumulative = successes + np.cumsum(_draw(sample, m))
        counts = runs + np.arange(1, m + 1)
        lo, hi = _cp(cumulative, counts, alpha)
        narrow = hi - lo <= 2 * epsilon
        if narrow.any():
            i = int(np.argmax(narrow))
            return ProbabilityEstimate(float(lo[i]), float(hi[i]), int(cumulative[i]), int(counts[i]), confidence)
        successes, runs = int(cumulative[-1]), int(counts[-1])
    lo_all, hi_all = clopper_pearson(successes, runs, confidence)
    return ProbabilityEstimate(lo_all, hi_all, successes, runs, confidence, converged=False)


def estimate_probability_fixed(sample: Sampler, runs: int, *, confidence: float = 0.95,
                               batch: int | None = None) -> ProbabilityEstimate:
    """``Pr[<=T;N](<> p)``: the Clopper-Pearson interval of exactly ``runs`` runs (``N``).

    The runs are drawn ``batch`` at a time (default: all at once)."""
    runs = _positive_int("runs", runs)
    confidence = _open_unit("confidence", confidence)
    batch = runs if batch is None else _positive_int("batch", batch)
    successes = done = 0
    while done < runs:
        m = min(batch, runs - done)
        successes += int(_draw(sample, m).sum())
        done += m
    lo, hi = clopper_pearson(successes, runs, confidence)
    return ProbabilityEstimate(lo, hi, successes, runs, confidence)


# ---------------------------------------------------------------- hypothesis testing
def _log(x: float) -> float:
    return math.log(x) if x > 0 else -math.inf


def sequential_test(sample: Sampler, theta: float, *, alpha: float = 0.05, beta: float = 0.05, delta: float = 0.01,
                    max_runs: int = DEFAULT_MAX_RUNS, batch: int = DEFAULT_BATCH) -> HypothesisResult:
    """``Pr[<=T](<> p) >= theta``: Wald's sequential probability ratio test (SPRT).

    With the indifference region ``[theta - delta, theta + delta]`` the test decides
    ``H0: p >= p0 = theta + delta`` against ``H1: p <= p1 = theta - delta``. After ``m`` runs with
    ``s`` successes the log-likelihood ratio is
    ``L = s*log(p1/p0) + (m-s)*log((1-p1)/(1-p0))``; the test rejects (``accepted=False``) as soon
    as ``L >= log((1-beta)/alpha)`` and accepts as soon as ``L <= log(beta/(1-alpha))``. So the
    probability of rejecting when ``p >= theta + delta`` is at most about ``alpha`` (UPPAAL's
    ``-a``, false negatives) and of accepting when ``p <= theta - delta`` about ``beta`` (``-B``,
    false positives); inside the region either answer may come. A region touching 0 or 1 is
    allowed: ``p1 == 0`` accepts at the first success, ``p0 == 1`` rejects at the first failure.
    Undecided after ``max_runs`` runs: ``decided=False`` (see :class:`HypothesisResult`).
    """
    if not isinstance(theta, int | float | np.floating) or not 0.0 <= theta <= 1.0:
        raise ValueError(f"theta must lie in [0, 1], not {theta!r}")
    alpha = _open_unit("alpha", alpha)
    beta = _open_unit("beta", beta)
    if alpha + beta >= 1.0:
        raise ValueError(f"alpha + beta must be below 1, not {alpha + beta}")
    if not isinstance(delta, int | float | np.floating) or not delta > 0.0:
        raise ValueError(f"delta must be positive, not {delta!r}")
    p0, p1 = theta + delta, theta - delta
    if p1 < 0.0 or p0 > 1.0:
        raise ValueError(f"the indifference region [{p1}, {p0}] (theta -/+ delta) must lie within [0, 1]")
    max_runs = _positive_int("max_runs", max_runs)
    batch = _positive_int("batch", batch)
    per_success = _log(p1) - math.log(p0)  # -inf when p1 == 0
    per_failure = math.log(1.0 - p1) - _log(1.0 - p0)  # +inf when p0 == 1
    reject_at = math.log((1.0 - beta) / alpha)
    accept_at = math.log(beta / (1.0 - alpha))
    successes = runs = 0
    while runs < max_runs:
        m = min(batch, max_runs - runs)
        s = successes + np.cumsum(_draw(sample, m))
        n = runs + np.arange(1, m + 1)
        f = n - s
        # 0 * inf would be nan: a count of 0 contributes 0
        with np.errstate(invalid="ignore"):
            llr = np.where(s > 0, s * per_success, 0.0) + np.where(f > 0, f * per_failure, 0.0)
        reject, accept = llr >= reject_at, llr <= accept_at
        done = reject | accept
        if done.any():
            i = int(np.argmax(done))
            return HypothesisResult(bool(accept[i]), int(n[i]), int(s[i]))
        successes, runs = int(s[-1]), int(n[-1])
    return HypothesisResult(successes >= theta * runs, runs, successes, decided=False)


# ---------------------------------------------------------------- expectations
def mean_interval(values: Sequence[float] | np.ndarray, confidence: float = 0.95) -> tuple[float, float]:
    """``E[<=T;N](max: e)``: the mean of ``values`` (one per run) and the half-width of its
    Student-t confidence interval, ``t_{(1+confidence)/2, n-1} * s / sqrt(n)`` with ``s`` the
    sample standard deviation — UPPAAL prints ``≈ mean ± half-width``. Needs two or more finite
    values; equal values give half-width 0."""
    confidence = _open_unit("confidence", confidence)
    data = np.asarray(values, dtype=np.float64)
    if data.ndim != 1 or data.shape[0] < 2:
        raise ValueError(f"mean_interval needs a 1-D sequence of at least 2 values, not shape {data.shape}")
    if not np.isfinite(data).all():
        raise ValueError("mean_interval needs finite values")
    return RunningMean().add(data).interval(confidence)


@dataclass
class RunningMean:
    """The mean and the sum of squared deviations of values added in chunks (Chan et al.'s pairwise
    update): :func:`mean_interval` over many runs in bounded memory, one chunk of runs at a time."""

    count: int = 0
    mean: float = 0.0
    #: The sum of squared deviations from the mean.
    squares: float = 0.0

    def add(self, values: np.ndarray) -> RunningMean:
        """Take a chunk of finite values in; returns self."""
        data = np.asarray(values, dtype=np.float64)
        if data.size == 0:
            return self
        n, mean = int(data.size), float(data.mean())
        squares = float(((data - mean) ** 2).sum())
        total = self.count + n
        delta = mean - self.mean
        self.squares += squares + delta * delta * self.count * n / total
        self.mean += delta * n / total
        self.count = total
        return self

    def interval(self, confidence: float = 0.95) -> tuple[float, float]:
        """The mean and the half-width of its Student-t interval (as :func:`mean_interval`)."""
        confidence = _open_unit("confidence", confidence)
        if self.count < 2:
            raise ValueError(f"mean_interval needs at least 2 values, not {self.count}")
        sd = math.sqrt(self.squares / (self.count - 1))
        return self.mean, float(special.stdtrit(self.count - 1, (1.0 + confidence) / 2.0) * sd / math.sqrt(self.count))
