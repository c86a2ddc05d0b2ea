"""rac.verify.statistical: the StatisticalAnswerer on the tiny engine file, called directly: known
verdicts of sequential tests, a fixed-run estimate that is a count over the runs, and the same answer
as ``rac verify`` gives under the same seed."""

from __future__ import annotations

from fractions import Fraction
from pathlib import Path

import pytest
from engine_files import write_engine_file

from rac.compiler import CompileResult, compile_file
from rac.verify.context import Context
from rac.verify.runner import SEEDED, QueryResult, VerifyOptions, verify
from rac.verify.statistical import StatisticalAnswerer


@pytest.fixture(scope="module")
def compiled(tmp_path_factory: pytest.TempPathFactory) -> CompileResult:
    result = compile_file(write_engine_file(tmp_path_factory.mktemp("statistical"), "avoidable_obstacle"))
    assert result.ok and result.automaton is not None, result.diagnostics
    return result


def answer(result: CompileResult, name: str, method: str) -> QueryResult:
    """Query ``name`` answered by ``StatisticalAnswerer.<method>`` in a fresh context (seed 1), with the
    seed ``rac verify`` gives it: the one of its place among the file's seeded queries."""
    [decl] = [d for d in result.automaton.queries if d.name == name]
    context = Context(result, VerifyOptions(seed=1, plots=False))
    context.seed_slot = [d.name for d in result.automaton.queries if isinstance(d.query, SEEDED)].index(name)
    answerer = StatisticalAnswerer(context)
    base = QueryResult(decl.name, decl.text, "statistical", "unknown")
    return getattr(answerer, method)(decl.query, base)


def test_sequential_tests_decide_the_certain_and_the_impossible(compiled: CompileResult) -> None:
    assert answer(compiled, "Certain", "probability").status == "satisfied"  # v >= 0 always
    assert answer(compiled, "Impossible", "probability").status == "not satisfied"  # v < 0 never


def test_fixed_runs_estimate_is_a_count_over_the_runs(compiled: CompileResult) -> None:
    result = answer(compiled, "ProbRuns", "probability")
    assert result.status == "value" and result.runs == 30 and result.seed is not None
    assert result.estimate is not None and result.interval is not None
    assert abs(result.estimate * 30 - round(result.estimate * 30)) < 1e-9
    assert result.interval[0] <= result.estimate <= result.interval[1]


@pytest.mark.parametrize(("name", "method"), [("ProbRuns", "probability"), ("Speed", "expectation")])
def test_same_answer_as_rac_verify(compiled: CompileResult, name: str, method: str) -> None:
    direct = answer(compiled, name, method)
    [through_verify] = verify(compiled, VerifyOptions(seed=1, plots=False, only=(name,)))
    for field in ("status", "estimate", "interval", "runs", "seed"):
        assert getattr(direct, field) == getattr(through_verify, field), field


def test_simulate_draws_the_asked_runs(compiled: CompileResult) -> None:
    result = answer(compiled, "Sim", "simulate")
    assert result.status == "value" and result.runs == 4


def test_a_bound_past_the_horizon_of_its_shield_says_so() -> None:
    """``simulate[<=3] under safe`` with ``--horizon 2``: the shield ends at 2 s, so every run meets
    a decision it allows nothing at; the verdict says that the bound is past the shield's horizon, not
    that the strategy allows no action."""
    left_turn = compile_file(Path(__file__).resolve().parents[2] / "examples" / "left_turn" / "preanalysis.ra")
    results = verify(left_turn, VerifyOptions(seed=1, plots=False, horizon=Fraction(2), only=("Qd", "Fig7")))
    fig7 = next(r for r in results if r.name == "Fig7")
    assert fig7.status == "unsupported" and fig7.message is not None
    assert fig7.message.startswith("the query's bound (3 s) is past the horizon the strategy `safe` was "
                                   "computed to (2 s)"), fig7.message


def test_an_expectation_that_is_not_a_number_is_not_answered(tmp_path: Path) -> None:
    """`E[<=2;5](max: sqrt(v - 100))` (the ego never reaches 100 m/s): every run's maximum is NaN, and
    the answer was a value, `E = nan ± nan`, exit 0, though nothing was estimated. It is not answered,
    saying why; so is an infinite extreme, and a finite one is still estimated."""
    queries = {"Nan": "E[<=2;5](max: sqrt(v - 100))", "Inf": "E[<=2;5](min: -1 / (v - 100 + fabs(v - 100)))",
               "Fine": "E[<=2;5](max: sqrt(v))"}
    results = {r.name: r for r in verify(compile_file(write_engine_file(tmp_path, "avoidable_obstacle", queries)),
                                         VerifyOptions(seed=1, plots=False))}
    assert results["Nan"].status == "unsupported" and results["Nan"].estimate is None
    assert ("the max of `sqrt(v - 100)` over a run is not a number in 5 of 5 runs"
            in (results["Nan"].message or "")), results["Nan"].message
    assert results["Inf"].status == "unsupported"
    assert "is infinite in 5 of 5 runs" in (results["Inf"].message or ""), results["Inf"].message
    assert results["Fine"].status == "value" and results["Fine"].estimate is not None


def test_a_run_budget_that_runs_out_is_said(compiled: CompileResult, monkeypatch: pytest.MonkeyPatch) -> None:
    """With the run budget spent before a sequential test decides (a probability near its threshold;
    100,000 runs in rac, 20 here), the test's verdict was the estimate's side of the threshold, reported
    as satisfied or not, exit 0 or 1, its message shown nowhere in the text: it is UNKNOWN. An estimate
    whose interval is still wider than ±epsilon says so (it was a value like any other)."""
    import functools

    from rac.engine import stats
    from rac.verify.report import render_text

    monkeypatch.setattr(stats, "sequential_test", functools.partial(stats.sequential_test, max_runs=20))
    monkeypatch.setattr(stats, "estimate_probability", functools.partial(stats.estimate_probability, max_runs=20))
    # v >= 0 always, against 0.99 ± 0.01: accepting takes 146 runs (each success moves the ratio by 0.02)
    [result] = verify(compiled, VerifyOptions(seed=1, plots=False, only=("Certain",)))
    assert result.status == "unknown" and result.runs == 20, result
    assert (result.message or "").startswith("the sequential test did not decide within 20 runs")
    assert f"Formula is UNKNOWN: {result.message}" in render_text([result])
    [wide] = verify(compiled, VerifyOptions(seed=1, plots=False, only=("Prob",)))
    assert wide.status == "value" and wide.runs == 20
    assert (wide.message or "").startswith("the run budget (20 runs) ran out before the interval was ±0.05 wide")
    assert wide.message in render_text([wide])


def test_a_threshold_at_0_or_1_is_answered(tmp_path: Path) -> None:
    """`Pr[..](..) >= 0` (or `>= 1`, `<= 0`, `<= 1`) crashed `rac verify` with an internal error: the
    sequential test's indifference region [θ - 0.01, θ + 0.01] left [0, 1]. Every probability is
    within [0, 1], so `>= 0` and `<= 1` hold without a run; at 1 (and 0) the region is moved inward."""
    queries = {"AtLeast0": "Pr[<=1](<> v < 0) >= 0", "AtMost1": "Pr[<=1](<> v >= 0) <= 1",
               "Above1": "Pr[<=1](<> v >= 0) > 1", "Below0": "Pr[<=1](<> v < 0) < 0",
               "AtLeast1": "Pr[<=1](<> v >= 0) >= 1", "Never1": "Pr[<=1](<> v < 0) >= 1",
               "AtMost0": "Pr[<=1](<> v < 0) <= 0", "Sometimes0": "Pr[<=1](<> v >= 0) <= 0",
               "Near0": "Pr[<=1](<> v >= 0) >= 0.005"}
    results = {r.name: r for r in verify(compile_file(write_engine_file(tmp_path, "avoidable_obstacle", queries)),
                                         VerifyOptions(seed=1, plots=False))}
    status = {name: r.status for name, r in results.items()}
    assert status == {"AtLeast0": "satisfied", "AtMost1": "satisfied", "Above1": "not satisfied",
                      "Below0": "not satisfied", "AtLeast1": "satisfied", "Never1": "not satisfied",
                      "AtMost0": "satisfied", "Sometimes0": "not satisfied", "Near0": "satisfied"}, results
    assert results["AtLeast0"].runs is None and "needs no run" in (results["AtLeast0"].message or "")


def test_a_probability_equal_to_a_threshold_is_not_answered(tmp_path: Path) -> None:
    """`Pr[..](..) == 0.5` was answered as `<= 0.5` (and `!=` too): a sequential test cannot decide it."""
    queries = {"Equal": "Pr[<=1](<> v < 0) == 0.5", "Unequal": "Pr[<=1](<> v < 0) != 0.5"}
    results = verify(compile_file(write_engine_file(tmp_path, "avoidable_obstacle", queries)),
                     VerifyOptions(seed=1, plots=False))
    assert [r.status for r in results] == ["unsupported", "unsupported"], results
    assert "cannot decide `==`" in (results[0].message or ""), results[0].message


def test_rac_check_warns_of_a_probability_compared_for_equality() -> None:
    """W0606 at check time for what rac verify leaves unanswered (above); `>=` gets no warning."""
    from rac.compiler import compile_text

    text = ("automaton A { input b : bool\n reward r\n objective r\n sample every 1\n horizon 5\n"
            " initial location L { r' == 1 }\n location M { r' == 0 }\n edge L -> M when b\n"
            " query Qe: Pr[<=5](<> M) {op} 0.5\n}}\n")
    for op, warned in (("==", True), ("!=", True), (">=", False)):
        result = compile_text(text.replace("{op}", op).replace("}}", "}"))
        assert result.ok
        assert ("W0606" in [d.code for d in result.diagnostics]) == warned, op


def test_the_exact_probability_stays_within_the_memory_budget(tmp_path: Path) -> None:
    # Storm's exact value beside a Pr[...] estimate explored the model with no memory limit (up to 2 million
    # states and Storm's matrix): `--max-memory 150M` on the left turn ran to 370 MB. Within the budget it is
    # computed; beyond it the estimate stands alone.
    path = write_engine_file(tmp_path, "goal_ahead", {"Prob": "Pr[<=2](<> v >= 6)"})
    result = compile_file(path)
    roomy = verify(result, VerifyOptions(seed=1))[0]
    tight = verify(result, VerifyOptions(seed=1, max_bytes=10_000))[0]  # the runs fit, the graph (181 states) not
    assert roomy.exact == 1.0 and roomy.status == tight.status == "value"
    assert tight.exact is None and tight.runs == roomy.runs and tight.interval == roomy.interval
