"""The SMC statistics (rac.engine.stats) against independently derived reference values.

The Clopper-Pearson bounds are checked against closed forms, R's ``binom.test`` and a bisection
on exact binomial tails (math.comb, no scipy); the sequential procedures against a replay of
their stopping rules on the recorded outcomes.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from functools import cache

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from rac.engine.stats import (
    HypothesisResult,
    ProbabilityEstimate,
    clopper_pearson,
    estimate_probability,
    estimate_probability_fixed,
    mean_interval,
    sequential_test,
)


# ---------------------------------------------------------------- references
def binom_cdf(s: int, n: int, p: float) -> float:
    """P(X <= s) for X ~ Binomial(n, p), summed exactly term by term."""
    return math.fsum(math.comb(n, i) * p**i * (1 - p) ** (n - i) for i in range(s + 1))


def bisect(f: Callable[[float], float], lo: float = 0.0, hi: float = 1.0) -> float:
    """The root of an increasing f on [lo, hi]."""
    for _ in range(200):
        mid = (lo + hi) / 2
        if f(mid) < 0:
            lo = mid
        else:
            hi = mid
    return (lo + hi) / 2


def reference_cp(s: int, n: int, confidence: float) -> tuple[float, float]:
    """The defining equations: P(X >= s | lo) = alpha/2 and P(X <= s | hi) = alpha/2."""
    half = (1 - confidence) / 2
    lo = 0.0 if s == 0 else bisect(lambda p: (1 - binom_cdf(s - 1, n, p)) - half)
    hi = 1.0 if s == n else bisect(lambda p: half - binom_cdf(s, n, p))
    return lo, hi


class Stream:
    """A sampler replaying a fixed sequence of outcomes, recording how many were drawn."""

    def __init__(self, outcomes: np.ndarray) -> None:
        self.outcomes = outcomes
        self.used = 0

    def __call__(self, n: int) -> np.ndarray:
        out = self.outcomes[self.used:self.used + n]
        assert out.shape == (n,), "the procedure drew more outcomes than the test prepared"
        self.used += n
        return out


def bernoulli(p: float, seed: int, size: int = 200_000) -> Stream:
    return Stream(np.random.default_rng(seed).random(size) < p)


# ---------------------------------------------------------------- Clopper-Pearson
def test_clopper_pearson_known_values() -> None:
    # s = 0 and s = n have closed forms: 1 - (alpha/2)^(1/n) and (alpha/2)^(1/n)
    assert clopper_pearson(0, 10) == pytest.approx((0.0, 1 - 0.025 ** 0.1), abs=1e-12)
    assert clopper_pearson(0, 10)[1] == pytest.approx(0.3084971078187608, abs=1e-12)
    assert clopper_pearson(10, 10) == pytest.approx((0.025 ** 0.1, 1.0), abs=1e-12)
    # R: binom.test(5, 10)$conf.int -> 0.1870860 0.8129140
    assert clopper_pearson(5, 10) == pytest.approx((0.1870860, 0.8129140), abs=1e-7)
    # s = 1, n = 20: lo = 1 - 0.975^(1/20); hi solves (1-p)^20 + 20 p (1-p)^19 = 0.025
    assert clopper_pearson(1, 20)[0] == pytest.approx(1 - 0.975 ** (1 / 20), abs=1e-12)
    assert clopper_pearson(1, 20)[1] == pytest.approx(0.24873276, abs=1e-8)
    hi = clopper_pearson(1, 20)[1]
    assert (1 - hi) ** 20 + 20 * hi * (1 - hi) ** 19 == pytest.approx(0.025, abs=1e-12)
    # 99 %, from the defining equations
    assert clopper_pearson(3, 7, 0.99) == pytest.approx(reference_cp(3, 7, 0.99), abs=1e-9)
    assert clopper_pearson(0, 0) == (0.0, 1.0)


@settings(max_examples=60, deadline=None)
@given(n=st.integers(1, 60), data=st.data(), confidence=st.sampled_from([0.8, 0.9, 0.95, 0.99]))
def test_clopper_pearson_solves_its_defining_equations(n: int, data: st.DataObject, confidence: float) -> None:
    s = data.draw(st.integers(0, n))
    lo, hi = clopper_pearson(s, n, confidence)
    assert 0.0 <= lo <= s / n <= hi <= 1.0
    assert (lo, hi) == pytest.approx(reference_cp(s, n, confidence), abs=1e-9)


@cache
def intervals(n: int, confidence: float) -> tuple[tuple[float, float], ...]:
    return tuple(clopper_pearson(s, n, confidence) for s in range(n + 1))


@settings(max_examples=80, deadline=None)
@given(p=st.floats(0.0, 1.0), n=st.integers(1, 40), confidence=st.sampled_from([0.9, 0.95]))
def test_clopper_pearson_coverage_is_at_least_the_confidence(p: float, n: int, confidence: float) -> None:
    """The exact coverage sum_s P(X = s) [lo(s) <= p <= hi(s)] is never below the confidence."""
    coverage = math.fsum(math.comb(n, s) * p**s * (1 - p) ** (n - s)
                         for s, (lo, hi) in enumerate(intervals(n, confidence)) if lo <= p <= hi)
    assert coverage >= confidence - 1e-12


@pytest.mark.parametrize("args", [(-1, 10), (11, 10), (1, -1), (1.5, 10), (True, 10), (1, 10, 1.0), (1, 10, 0.0)])
def test_clopper_pearson_rejects_bad_arguments(args: tuple) -> None:
    with pytest.raises(ValueError):
        clopper_pearson(*args)


# ---------------------------------------------------------------- estimation
@settings(max_examples=40, deadline=None)
@given(p=st.sampled_from([0.0, 0.02, 0.3, 0.5, 0.77, 1.0]), epsilon=st.sampled_from([0.03, 0.05, 0.1]),
       seed=st.integers(0, 2**32 - 1), batch=st.integers(1, 500))
def test_estimate_stops_at_the_first_narrow_interval(p: float, epsilon: float, seed: int, batch: int) -> None:
    stream = bernoulli(p, seed)
    estimate = estimate_probability(stream, epsilon=epsilon, batch=batch)
    assert isinstance(estimate, ProbabilityEstimate) and estimate.converged
    drawn = stream.outcomes[:estimate.runs]
    assert estimate.successes == int(drawn.sum())
    assert (estimate.lo, estimate.hi) == clopper_pearson(estimate.successes, estimate.runs)
    assert estimate.hi - estimate.lo <= 2 * epsilon and estimate.half_width <= epsilon
    # one run fewer was not enough: the rule is checked after every run, not every batch
    before = clopper_pearson(int(drawn[:-1].sum()), estimate.runs - 1)
    assert before[1] - before[0] > 2 * epsilon
    assert stream.used - estimate.runs < batch  # no batch beyond the one that stopped


def test_estimate_known_run_counts_and_batch_independence() -> None:
    never = estimate_probability(lambda n: np.zeros(n, dtype=bool))
    # 1 - 0.025^(1/n) <= 0.1 first at n = 36 (UPPAAL prints [0, 0.0973938] after 36 runs)
    assert (never.runs, never.successes, never.lo) == (36, 0, 0.0)
    assert never.hi == pytest.approx(0.0973938, abs=1e-7)
    results = {estimate_probability(bernoulli(0.4, 11), batch=b) for b in (1, 7, 100, 5000)}
    assert len(results) == 1
    (half,) = results
    assert 350 < half.runs < 420  # about 1.96^2 / 4 / 0.05^2 = 384 near p = 1/2


def test_estimate_reports_when_max_runs_runs_out() -> None:
    estimate = estimate_probability(bernoulli(0.5, 3), epsilon=0.01, max_runs=250, batch=100)
    assert not estimate.converged and estimate.runs == 250
    assert estimate.hi - estimate.lo > 0.02


def test_estimate_fixed_runs() -> None:
    stream = bernoulli(0.3, 5)
    estimate = estimate_probability_fixed(stream, 1000, batch=64)
    assert stream.used == estimate.runs == 1000
    assert estimate.successes == int(stream.outcomes[:1000].sum())
    assert (estimate.lo, estimate.hi) == clopper_pearson(estimate.successes, 1000)
    assert estimate.lo < 0.3 < estimate.hi
    assert estimate_probability_fixed(bernoulli(0.3, 5), 1000) == estimate  # one batch or many


@pytest.mark.parametrize("kwargs", [{"epsilon": 0.0}, {"epsilon": 1.0}, {"confidence": 1.0}, {"max_runs": 0},
                                    {"batch": 0}, {"batch": 2.5}])
def test_estimate_rejects_bad_arguments(kwargs: dict) -> None:
    with pytest.raises(ValueError):
        estimate_probability(lambda n: np.zeros(n, dtype=bool), **kwargs)


@pytest.mark.parametrize("sampler", [lambda n: np.zeros(n + 1, dtype=bool), lambda n: np.zeros(n, dtype=int),
                                     lambda n: np.zeros((n, 1), dtype=bool)])
def test_a_sampler_returning_no_bool_array_is_an_error(sampler: Callable) -> None:
    with pytest.raises(ValueError, match="bool array"):
        estimate_probability(sampler)
    with pytest.raises(ValueError, match="bool array"):
        sequential_test(sampler, 0.5)


# ---------------------------------------------------------------- SPRT
def llr(s: int, m: int, theta: float, delta: float) -> float:
    p0, p1 = theta + delta, theta - delta
    return s * math.log(p1 / p0) + (m - s) * math.log((1 - p1) / (1 - p0))


@pytest.mark.parametrize("p, accepted", [(0.9, True), (0.65, True), (0.35, False), (0.05, False)])
def test_sprt_decides_clear_cases(p: float, accepted: bool) -> None:
    theta, delta, alpha, beta = 0.5, 0.05, 0.05, 0.05
    stream = bernoulli(p, 1)
    result = sequential_test(stream, theta, delta=delta, alpha=alpha, beta=beta, batch=50)
    assert isinstance(result, HypothesisResult) and result.decided
    assert result.accepted is accepted
    drawn = stream.outcomes[:result.runs]
    assert result.successes == int(drawn.sum())
    # the test stopped exactly where the log-likelihood ratio first left Wald's band
    upper, lower = math.log((1 - beta) / alpha), math.log(beta / (1 - alpha))
    final = llr(result.successes, result.runs, theta, delta)
    assert final <= lower if accepted else final >= upper
    previous = np.cumsum(drawn[:-1])
    assert all(lower < llr(int(s), m, theta, delta) < upper for m, s in enumerate(previous, start=1))


def test_sprt_error_rates_at_the_indifference_region_edges() -> None:
    """At p = theta + delta the test rejects with probability about alpha (Wald: at most
    alpha / (1 - beta)); at p = theta - delta it accepts with probability about beta."""
    theta, delta = 0.5, 0.1
    rejected = sum(not sequential_test(bernoulli(theta + delta, seed, 5000), theta, delta=delta).accepted
                   for seed in range(300))
    accepted = sum(sequential_test(bernoulli(theta - delta, seed, 5000), theta, delta=delta, alpha=0.2,
                                   beta=0.01).accepted for seed in range(300))
    assert 0 < rejected <= 0.05 / 0.95 * 300 + 10
    assert accepted <= 0.01 / 0.8 * 300 + 4


def test_sprt_region_touching_zero_or_one() -> None:
    # p1 = 0: the first success shows p > 0, so p >= theta + delta is accepted
    result = sequential_test(bernoulli(0.3, 2), 0.01, delta=0.01)
    assert result.accepted and result.successes == 1
    # p0 = 1: the first failure rejects
    result = sequential_test(bernoulli(0.7, 2), 0.99, delta=0.01)
    assert not result.accepted and result.runs - result.successes == 1


def test_sprt_undecided_after_max_runs() -> None:
    result = sequential_test(bernoulli(0.5, 4), 0.5, delta=0.001, max_runs=100)
    assert not result.decided and result.runs == 100


@pytest.mark.parametrize("theta, kwargs", [(1.2, {}), (-0.1, {}), (0.5, {"delta": 0.0}), (0.02, {"delta": 0.05}),
                                           (0.98, {"delta": 0.05}), (0.5, {"alpha": 0.0}),
                                           (0.5, {"alpha": 0.6, "beta": 0.5}), (0.5, {"max_runs": -1})])
def test_sprt_rejects_bad_arguments(theta: float, kwargs: dict) -> None:
    with pytest.raises(ValueError):
        sequential_test(lambda n: np.ones(n, dtype=bool), theta, **kwargs)


# ---------------------------------------------------------------- mean
def test_mean_interval_known_values() -> None:
    # R: t.test(1:5)$conf.int -> 1.036757 4.963243
    mean, half = mean_interval([1, 2, 3, 4, 5])
    assert mean == 3.0 and half == pytest.approx(1.963243, abs=1e-6)
    # two values 0 and 2 at 90 %: sd sqrt(2), so the half-width is t_{0.95, 1} = 6.313752
    assert mean_interval(np.array([0.0, 2.0]), 0.9) == pytest.approx((1.0, 6.313752), abs=1e-6)
    assert mean_interval([4.0, 4.0, 4.0]) == (4.0, 0.0)


def test_mean_interval_coverage() -> None:
    rng = np.random.default_rng(8)
    samples = rng.normal(2.5, 3.0, size=(2000, 8))
    covered = sum(abs(m - 2.5) <= h for m, h in map(mean_interval, samples))
    assert 0.93 * 2000 <= covered <= 0.97 * 2000


@pytest.mark.parametrize("values", [[1.0], [], [[1.0, 2.0]], [1.0, math.nan], [1.0, math.inf]])
def test_mean_interval_rejects_bad_values(values: list) -> None:
    with pytest.raises(ValueError):
        mean_interval(values)
    with pytest.raises(ValueError):
        mean_interval([1.0, 2.0], confidence=1.5)
