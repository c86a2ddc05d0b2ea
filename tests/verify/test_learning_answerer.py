"""rac.verify.learning: the LearningAnswerer on the tiny engine file, called directly. The query
``maxE(sa)[<=4] ... under safe`` has a known optimum: the shield keeps the car in `Normal`, where
``sa' == 1``, so the best return over 4 s is 4; learning reaches it, the exact backward pass equals it."""

from __future__ import annotations

import dataclasses
from fractions import Fraction
from pathlib import Path

import pytest
from engine_files import write_engine_file

from rac.compiler import CompileResult, compile_file
from rac.engine.evaluate import EvaluationError
from rac.verify.context import Context, UnknownVerdict
from rac.verify.learning import LearningAnswerer
from rac.verify.runner import QueryResult, Verifier, VerifyOptions


@pytest.fixture(scope="module")
def compiled(tmp_path_factory: pytest.TempPathFactory) -> CompileResult:
    result = compile_file(write_engine_file(tmp_path_factory.mktemp("learning"), "avoidable_obstacle"))
    assert result.ok and result.automaton is not None, result.diagnostics
    return result


def decl(result: CompileResult, name: str):
    [found] = [d for d in result.automaton.queries if d.name == name]
    return found


def shielded_context(result: CompileResult, **options: object) -> Context:
    """A context (seed 1) in which the shield `safe` has been computed, as `rac verify` does first."""
    context = Context(result, VerifyOptions(seed=1, plots=False, learn_episodes=200, **options))  # type: ignore[arg-type]
    assert Verifier(context).answer(decl(result, "safe"), None).status == "satisfied"
    return context


def learn(context: Context, query) -> QueryResult:
    return LearningAnswerer(context).learn(query, QueryResult("Learn", "maxE", "learning", "unknown"))


def test_learning_reaches_the_known_optimum(compiled: CompileResult) -> None:
    context = shielded_context(compiled)
    result = learn(context, decl(compiled, "Learn").query)
    assert result.status == "value" and result.runs == 200
    assert result.estimate == 4.0
    assert result.optimum["value"] == 4.0 and result.optimum["shortfall"] == 0.0
    # beside it, what exploring can expect (exact, from the same graph: tests/learning/test_optimum.py)
    assert result.optimum["uniform_success"] == 1.0  # every allowed run speeds into the goal region
    assert "every uniformly random episode reaches the goal safely (exact)" in result.message
    assert "fast" in context.learned  # later queries `under fast` find it


def test_exact_mode_gives_the_optimum_without_episodes(compiled: CompileResult) -> None:
    result = learn(shielded_context(compiled, exact=True), decl(compiled, "Learn").query)
    assert result.status == "value" and result.estimate == 4.0 and result.runs is None


def test_learning_needs_the_shield_and_refuses_a_learned_one(compiled: CompileResult) -> None:
    query = decl(compiled, "Learn").query
    with pytest.raises(UnknownVerdict, match="has not been computed"):
        learn(Context(compiled, VerifyOptions(seed=1, plots=False)), query)
    context = shielded_context(compiled)
    learn(context, query)
    with pytest.raises(EvaluationError, match="learned strategy `fast`"):
        learn(context, dataclasses.replace(query, under="fast"))


def test_an_objective_not_zero_at_the_start_has_its_value_at_the_end_said(tmp_path: Path) -> None:
    """`maxE(sa + 10)`: the return is the objective's increase (4, as for `maxE(sa)`), which is its value at
    the end (14) only when it is 0 at the start; the report said "return 4" alone (and `maxE(-dist_goal())`
    on the highway a positive "return 141.5" for an objective never above 0) and called it the value at
    the end."""
    queries = {"safe": "strategy safe = control: A[] !collide() && !offroad()",
               "Learn": "strategy fast = maxE(sa + 10)[<=4]{Tiny.location}->{x}: <> time >= 4 under safe"}
    result = compile_file(write_engine_file(tmp_path, "avoidable_obstacle", queries))
    assert result.ok, result.diagnostics
    for exact in (False, True):
        answer = learn(shielded_context(result, exact=exact), decl(result, "Learn").query)
        assert answer.estimate == 4.0 and answer.optimum["value"] == 4.0
        assert answer.optimum["objective_at_start"] == 10.0
        assert "return 4 (the increase of sa + 10 from 10 at the start: 14 at the end)" in (answer.message or "")
    (tmp_path / "plain").mkdir()
    plain_file = compile_file(write_engine_file(tmp_path / "plain", "avoidable_obstacle"))
    plain = learn(shielded_context(plain_file), decl(plain_file, "Learn").query)
    assert "at the start" not in (plain.message or "")  # `maxE(sa)` starts at 0: its return is its value


@pytest.mark.parametrize("exact", [False, True])
def test_a_bound_past_the_shields_horizon_is_not_learned(compiled: CompileResult, exact: bool) -> None:
    """`--horizon 2` computes the shield to 2 s; learning `[<=4] ... under safe` went on past it, where the
    table allows no action and learning (and the exact optimum) chose among all of them: on ZAM_Ramp 22
    learning episodes "under safe" left the road and the optimum was reported as the shield's. The
    query is not answered, as a simulation under the shield past its horizon is not."""
    context = shielded_context(compiled, horizon=Fraction(2), exact=exact)
    with pytest.raises(EvaluationError, match=r"past the horizon the strategy `safe` was computed to \(2 s\)"):
        learn(context, decl(compiled, "Learn").query)
    assert "fast" not in context.learned


def test_statistics_under_a_learned_strategy_say_the_value_is_exact(tmp_path: Path,
                                                                     capsys: pytest.CaptureFixture[str]) -> None:
    """Under a learned strategy every run is its one deterministic run: `Pr[<=4;100]` gave [0.9638, 1] and
    `Pr >= 0.5` "wrong with probability at most 0.05" where the probability is exactly 1; the interval stays
    (UPPAAL's N runs give it), and the answer says the value is exact."""
    import json

    from rac.cli.main import main

    queries = {"safe": "strategy safe = control: A[] !collide() && !offroad()",
               "Learn": "strategy fast = maxE(sa)[<=4]{Tiny.location}->{x}: <> time >= 4 under safe",
               "P": "Pr[<=4; 100](<> v > 6) under fast", "Never": "Pr[<=4; 20](<> v > 60) under fast",
               "Test": "Pr[<=4](<> v > 6) >= 0.5 under fast", "E": "E[<=4; 50](max: v) under fast",
               "Uniform": "Pr[<=4; 30](<> v > 6)"}
    path = write_engine_file(tmp_path, "goal_ahead", queries)
    main(["verify", str(path), "--seed", "1", "--format", "json", "--no-plots"])
    answers = {q["name"]: q for q in json.loads(capsys.readouterr().out)["results"]}
    one = "every run is the one run of the strategy `fast` (it and the model are deterministic)"
    assert answers["P"]["interval"][0] < 1 and answers["P"]["message"] == (
        f"{one}, so the probability is exactly 1; the interval is the one 100 runs give, as UPPAAL's")
    assert answers["Never"]["message"].startswith(f"{one}, so the probability is exactly 0;")
    assert answers["Test"]["status"] == "satisfied" and answers["Test"]["message"].endswith(
        f"; {one}, so the probability is exactly 1 and the verdict holds with no error")
    expected = answers["E"]["estimate"]
    assert answers["E"]["message"] == f"{one}, so the value is exactly {expected!r}"
    assert not answers["Uniform"]["message"]  # random runs: no such claim


def test_exploration_when_every_episode_reaches_the_goal() -> None:
    from rac.learning.optimum import exploration_text

    assert exploration_text(1.0) == "every uniformly random episode reaches the goal safely (exact)"
    assert "(exact; 2 episodes on average until the first)" in exploration_text(0.5)
