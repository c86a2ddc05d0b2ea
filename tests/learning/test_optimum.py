"""``rac.learning.optimum``: the exact optimum of a learning query under a shield, by a backward pass over
the shielded decision graph, checked against brute force over every allowed action sequence.

On the tiny scenarios of :mod:`tiny_scenarios` (4 decisions of 9 actions: at most 6,561 sequences) the
backward pass must give exactly the best return of all action sequences the shield allows (replayed
through the same episodes learning uses), for ``maxE`` and ``minE``, with and without a shield, with
the automaton's own reward, an objective's increase, and automata whose updates are not translations
(a reset: the rewards are then part of the decision state). Also: ``rac verify`` reports the optimum
beside the learned strategy, and ``rac verify --exact`` emits the optimal strategy, verified like a
learned one.
"""

from __future__ import annotations

import json
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest
from engine_files import QUERIES, write_engine_file
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from rac.compiler import CompileResult, compile_file
from rac.engine import budget, shield
from rac.engine.budget import BudgetExceeded, ProjectionExceeded
from rac.learning import optimum
from rac.learning.episodes import EpisodeBatch, Expression, parse_expr
from rac.learning.optimum import shortfall, solve, why_not_additive
from rac.learning.qlearning import LearnedStrategy, ObjectiveIncrease, learn
from rac.learning.strategy import Episodes, allowed_actions
from rac.learning.tabular import STEERED
from rac.verify.runner import VerifyOptions, verify

HORIZON = 8  # samples: the tiny scenarios' 4 s at 0.5 s, 4 decisions
#: A tiny scenario's file, compiled, and its safety shield.
Compiled = tuple[CompileResult, shield.ShieldTable]


def brute_force(batch: EpisodeBatch, objective: Expression | None, table: shield.ShieldTable | None,
                optimise: str) -> tuple[float, int]:
    """The best return over every action sequence the shield allows (each replayed from the start), and
    how many sequences there are."""
    scored: Episodes = batch if objective is None else ObjectiveIncrease(batch, objective)
    prefixes = np.zeros((1, 0), dtype=np.int64)
    complete: list[float] = []
    while prefixes.shape[0]:
        n, depth = prefixes.shape
        scored.reset(n)
        returns = np.zeros(n)
        for j in range(depth):
            returns += scored.step(prefixes[:, j]).reward
        done = np.asarray(batch.done, dtype=bool)
        complete += returns[done].tolist()
        if done.all():
            break
        masks, _ = allowed_actions(scored, table)
        masks[done] = False
        rows, actions = np.nonzero(masks)
        prefixes = np.column_stack([prefixes[rows], actions])
    best = max(complete) if optimise == "max" else min(complete)
    return best, len(complete)


def brute_force_chance(batch: EpisodeBatch, table: shield.ShieldTable | None, steer: str | None = None) -> float:
    """The probability that an episode choosing uniformly among the allowed actions reaches the goal
    safely: the sum over every allowed action sequence that succeeds of the product of 1 / (the actions
    allowed) at its decisions, each sequence replayed from the start. With ``steer``, an episode exploring
    as the learner's ``steer`` does: a share STEERED of each choice uniform among the allowed actions whose
    ``steer`` one decision later is least (read by ``batch.ahead``), the rest uniform."""
    prefixes = np.zeros((1, 0), dtype=np.int64)
    chance = np.ones(1)
    total = 0.0
    while prefixes.shape[0]:
        n, depth = prefixes.shape
        batch.reset(n)
        safe, reached, stranded = np.ones(n, dtype=bool), np.zeros(n, dtype=bool), np.zeros(n, dtype=bool)
        for j in range(depth):
            outcome = batch.step(prefixes[:, j])
            safe &= ~(outcome.collided | outcome.offroad)
            reached |= outcome.terminated
            stranded |= outcome.stranded
        done = np.asarray(batch.done, dtype=bool)
        total += float(chance[done & safe & reached & ~stranded].sum())
        if done.all():
            break
        masks, _ = allowed_actions(batch, table)
        masks[done] = False
        rows, actions = np.nonzero(masks)
        share = masks / np.maximum(masks.sum(axis=1, keepdims=True), 1)
        if steer is not None:
            values = np.where(masks, batch.ahead([steer])[:, :, 0], np.inf)
            least = masks & (values == values.min(axis=1, keepdims=True))
            share = STEERED * least / np.maximum(least.sum(axis=1, keepdims=True), 1) + (1 - STEERED) * share
        chance = chance[rows] * share[rows, actions]
        prefixes = np.column_stack([prefixes[rows], actions])
    return total


@pytest.fixture(scope="module")
def tiny(tmp_path_factory: pytest.TempPathFactory) -> Callable[..., Compiled]:
    cache: dict[tuple[str, str | None], Compiled] = {}

    def get(name: str, edit: str | None = None) -> Compiled:
        if (name, edit) not in cache:
            folder = tmp_path_factory.mktemp(name)
            path = write_engine_file(folder, name, {"safe": QUERIES["safe"]})
            if edit is not None:
                path.write_text(path.read_text().replace("do sa -= 10", edit))
            result = compile_file(path)
            result.raise_for_errors()
            (safe,) = verify(result, VerifyOptions(out_dir=folder / "out", plots=False))
            assert safe.status == "satisfied"
            cache[(name, edit)] = (result, shield.load(folder / "out" / "safe.shield.npz"))
        return cache[(name, edit)]

    return get


CASES = [  # scenario, the goal, the objective (None: the automaton's reward), shielded, optimise
    ("goal_ahead", "goal()", "sa", True, "max"),
    ("goal_ahead", "goal()", "sa", True, "min"),
    ("goal_ahead", "goal()", None, False, "max"),
    ("goal_ahead", "goal()", "3 * sa - x", False, "min"),
    ("avoidable_obstacle", "time >= 4", "sa", False, "max"),
    ("avoidable_obstacle", "time >= 4", "-2 * sa + v", True, "max"),
]


@pytest.mark.parametrize(("name", "goal", "objective", "shielded", "optimise"), CASES)
def test_the_backward_pass_is_brute_force(tiny: Callable[..., Compiled], name: str,
                                          goal: str, objective: str | None, shielded: bool, optimise: str) -> None:
    result, table = tiny(name)
    under = table if shielded else None
    objective_expr = None if objective is None else parse_expr(objective)
    expected, sequences = brute_force(EpisodeBatch(result, goal=parse_expr(goal), horizon_samples=HORIZON),
                                      objective_expr, under, optimise)
    best = solve(EpisodeBatch(result, goal=parse_expr(goal), horizon_samples=HORIZON), objective=objective_expr,
                 optimise=optimise, shield=under, steer="dist_goal()")
    assert best.additive and best.why is None
    assert best.value == pytest.approx(expected, rel=1e-12, abs=1e-9)
    assert best.backward == pytest.approx(best.value, rel=1e-12, abs=1e-9)
    assert best.states < sequences or sequences < 50  # merging: fewer decision states than sequences
    # the optimal strategy, saved and loaded, has the optimal run
    assert best.run.returns[0] == best.value
    # uniform exploration's chance of a safe goal, over the merged graph, is the sequences' sum
    chance = brute_force_chance(EpisodeBatch(result, goal=parse_expr(goal), horizon_samples=HORIZON), under)
    assert best.uniform_success == pytest.approx(chance, rel=1e-12, abs=1e-15)
    assert best.expected_first == pytest.approx(1 / chance if chance > 0 else float("inf"), rel=1e-12)
    # and exploring steered towards the goal (--explore goal), each step's least distance read by ahead()
    steered = brute_force_chance(EpisodeBatch(result, goal=parse_expr(goal), horizon_samples=HORIZON), under,
                                 "dist_goal()")
    assert best.steered_success == pytest.approx(steered, rel=1e-12, abs=1e-15)


def test_steering_changes_some_chance(tiny: Callable[..., Compiled]) -> None:
    """The steered chance is not the uniform one under another name: on the goal ahead, heading for the goal
    changes it."""
    result, table = tiny("goal_ahead")
    batch = EpisodeBatch(result, horizon_samples=HORIZON)
    steered = brute_force_chance(batch, table, "dist_goal()")
    uniform = brute_force_chance(EpisodeBatch(result, horizon_samples=HORIZON), table)
    assert steered != pytest.approx(uniform, rel=1e-6)
    assert solve(EpisodeBatch(result, horizon_samples=HORIZON), shield=table, steer="dist_goal()").steered_success \
        == pytest.approx(steered, rel=1e-12)


def test_a_reset_puts_the_rewards_into_the_state(tiny: Callable[..., Compiled],
                                                 tmp_path: Path) -> None:
    result, table = tiny("goal_ahead", "do sa = 0")  # not a translation: the future depends on sa
    assert result.automaton is not None
    why = why_not_additive(result.automaton)
    assert why is not None and "`sa = sa + c`" in why
    for optimise in ("max", "min"):
        batch = EpisodeBatch(result, horizon_samples=HORIZON)
        expected, _ = brute_force(batch, parse_expr("sa"), None, optimise)
        best = solve(EpisodeBatch(result, horizon_samples=HORIZON), objective=parse_expr("sa"), optimise=optimise)
        assert not best.additive and best.why == why and "with their rewards" in best.method
        assert best.value == pytest.approx(expected, rel=1e-12, abs=1e-9)


def test_an_objective_not_affine_in_the_rewards(tiny: Callable[..., Compiled]) -> None:
    result, table = tiny("goal_ahead")
    square = parse_expr("sa * sa")
    batch = EpisodeBatch(result, horizon_samples=HORIZON)
    assert why_not_additive(result.automaton, objective=batch.expression(square)) is not None  # type: ignore[arg-type]
    assert why_not_additive(result.automaton, objective=batch.expression(parse_expr("2 * sa - sa / 4 + x"))) is None  # type: ignore[arg-type]
    assert why_not_additive(result.automaton, goal=batch.expression(parse_expr("sa > 2"))) is not None  # type: ignore[arg-type]
    expected, _ = brute_force(batch, square, table, "max")
    best = solve(EpisodeBatch(result, horizon_samples=HORIZON), objective=square, shield=table)
    assert not best.additive and best.value == pytest.approx(expected, rel=1e-12)


def test_the_optimum_bounds_what_is_learned(tiny: Callable[..., Compiled],
                                            tmp_path: Path) -> None:
    result, table = tiny("goal_ahead")
    best = solve(EpisodeBatch(result, horizon_samples=HORIZON), objective=parse_expr("sa"), shield=table)
    outcome = learn(ObjectiveIncrease(EpisodeBatch(result, horizon_samples=HORIZON), parse_expr("sa")),
                    discrete=[parse_expr("Tiny.location")], continuous=[parse_expr("x")], shield=table,
                    episodes=64, seed=1)
    learned = float(outcome.greedy.returns[0])
    assert learned <= best.value + 1e-9
    assert shortfall(learned, best.value) == pytest.approx(max(0.0, (best.value - learned) / abs(best.value)))
    # saved and loaded, the optimal strategy runs its optimal run again
    loaded = LearnedStrategy.load(best.strategy.save(tmp_path / "best.strategy.npz"))
    from rac.learning.runs import run_strategy
    again = run_strategy(ObjectiveIncrease(EpisodeBatch(result, horizon_samples=HORIZON), parse_expr("sa")), loaded,
                         shield=table)
    assert again.returns[0] == best.value and again.actions.tolist() == best.run.actions.tolist()


def test_out_of_reach_beyond_the_budget(tiny: Callable[..., Compiled]) -> None:
    result, _ = tiny("goal_ahead")
    with pytest.raises(BudgetExceeded, match="decision graph"):
        solve(EpisodeBatch(result, horizon_samples=HORIZON), max_states=5)


def test_beside_an_answer_the_search_gives_up_on_a_projection(tiny: Callable[..., Compiled],
                                                               monkeypatch: pytest.MonkeyPatch) -> None:
    """``project=True`` stops as soon as the layers so far project beyond the margin, before the shield
    is asked about the next layer; without it the same budget holds the whole graph and solves it."""
    result, table = tiny("goal_ahead")  # layers of 1, 3, 9, 37 decision states: 50 in all
    whole = solve(EpisodeBatch(result, horizon_samples=HORIZON), shield=table, max_states=100)
    assert whole.states == 50
    # at 3 per decision from 9 states, the last layer would hold 27: 40 states, over 0.3 x 100
    monkeypatch.setattr(budget, "PROJECTION_MARGIN", 0.3)
    with pytest.raises(ProjectionExceeded) as raised:
        solve(EpisodeBatch(result, horizon_samples=HORIZON), shield=table, max_states=100, project=True)
    assert raised.value.states == 13 and raised.value.projected_states == 40 and raised.value.sample == 4
    assert "would have about 40 states by the horizon (sample 8), growing ×3 per decision from 13 states" in str(
        raised.value) and "not explored further" in str(raised.value)
    # judged only once a thousandth of the budget is explored: here, never
    monkeypatch.setattr(budget, "PROJECTION_FROM", 1.0)
    assert solve(EpisodeBatch(result, horizon_samples=HORIZON), shield=table, max_states=100,
                 project=True).value == whole.value


def test_verify_gives_up_on_a_projection_beside_learning_but_not_with_exact(tmp_path: Path,
                                                                            monkeypatch: pytest.MonkeyPatch) -> None:
    result = compile_file(write_engine_file(tmp_path, "goal_ahead", LEARN))
    monkeypatch.setattr(budget, "PROJECTION_MARGIN", 0.01)
    _, fast, _ = verify(result, VerifyOptions(out_dir=tmp_path / "out", plots=False, seed=1, learn_episodes=32,
                                              max_states=1000))
    assert fast.status == "value" and fast.optimum is not None and "not explored further" in str(
        fast.optimum["out_of_reach"])
    _, exact, _ = verify(result, VerifyOptions(out_dir=tmp_path / "out", plots=False, seed=1, exact=True,
                                               max_states=1000))
    assert exact.status == "value" and exact.method == "exact optimum"


def test_the_budget_is_checked_before_the_shield_is_asked(tiny: Callable[..., Compiled],
                                                          monkeypatch: pytest.MonkeyPatch) -> None:
    """The next layer's states are bounded by the (state, action) pairs the model allows, and that bound
    is checked before the shield is asked about the layer: an on-demand shield proves every pair, so a
    layer checked only after it was masked (the tutorial's 45 actions: a million states, 6.7 GB and
    minutes) could cost far more than the budget it then exceeded."""
    result, table = tiny("goal_ahead")  # layers of 1, 3, 9, 37 decision states, 9 actions each
    asked: list[int] = []
    allowed = optimum.allowed_actions

    def counted(batch: Episodes, shield: object) -> tuple[np.ndarray, np.ndarray]:
        asked.append(batch.n)
        return allowed(batch, shield)  # type: ignore[arg-type]

    monkeypatch.setattr(optimum, "allowed_actions", counted)
    assert solve(EpisodeBatch(result, horizon_samples=HORIZON), shield=table).states == 1 + 3 + 9 + 37
    assert asked == [1, 3, 9, 37]
    asked.clear()
    with pytest.raises(BudgetExceeded, match="decision graph"):
        solve(EpisodeBatch(result, horizon_samples=HORIZON), shield=table, max_states=20)
    assert asked == [1]  # 1 + 3 states, then up to 3 * 9 more: refused before the 3 were masked (was [1, 3, 9])


@settings(max_examples=8, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(rates=st.lists(st.integers(-3, 3), min_size=2, max_size=2), penalty=st.integers(-20, 20),
       weights=st.lists(st.integers(-3, 3), min_size=2, max_size=2), reset=st.booleans(),
       optimise=st.sampled_from(["max", "min"]))
def test_random_automata_agree_with_brute_force(tmp_path_factory: pytest.TempPathFactory, rates: list[int],
                                                penalty: int, weights: list[int], reset: bool, optimise: str) -> None:
    """Random rates, updates (translations or resets) and objectives over two rewards."""
    folder = tmp_path_factory.mktemp("random")
    path = write_engine_file(folder, "goal_ahead", {})
    text = path.read_text()
    update = "sa = 0" if reset else f"sa = sa + {penalty}"
    text = (text.replace("reward sa\n", "reward sa, pr\n").replace("objective sa", f"objective sa + {weights[0]} * pr")
            .replace("{ sa' == 1 }", f"{{ sa' == 1; pr' == {rates[0]} }}")
            .replace("{ sa' == -1 }", f"{{ sa' == -1; pr' == {rates[1]} }}").replace("do sa -= 10", f"do {update}"))
    path.write_text(text)
    result = compile_file(path)
    result.raise_for_errors()
    objective = parse_expr(f"{weights[1]} * pr - sa")
    expected, _ = brute_force(EpisodeBatch(result, horizon_samples=HORIZON), objective, None, optimise)
    best = solve(EpisodeBatch(result, horizon_samples=HORIZON), objective=objective, optimise=optimise)
    assert best.additive == (not reset)
    assert best.value == pytest.approx(expected, rel=1e-12, abs=1e-9)
    automatic, _ = brute_force(EpisodeBatch(result, horizon_samples=HORIZON), None, None, optimise)
    assert solve(EpisodeBatch(result, horizon_samples=HORIZON), optimise=optimise).value == pytest.approx(
        automatic, rel=1e-12, abs=1e-9)


# ---------------------------------------------------------------- rac verify
LEARN = {"safe": QUERIES["safe"], "fast": QUERIES["Learn"], "SafeUnder": "A[] !collide() under fast"}


def test_verify_reports_the_optimum_beside_the_learned_strategy(tmp_path: Path) -> None:
    result = compile_file(write_engine_file(tmp_path, "goal_ahead", LEARN))
    _, fast, _ = verify(result, VerifyOptions(out_dir=tmp_path / "out", plots=False, seed=1, learn_episodes=64))
    assert fast.optimum is not None and fast.estimate is not None and fast.message is not None
    value = fast.optimum["value"]
    assert isinstance(value, float) and fast.estimate <= value + 1e-9
    assert fast.optimum["learned"] == fast.estimate and fast.optimum["reaches_goal_safely"] is True
    assert "(exact, backward pass over" in fast.message and "% below" in fast.message
    assert "--exact" not in fast.message  # the learned strategy reaches the goal: nothing to point to
    json.dumps(fast.to_json())  # JSON-ready


def test_verify_points_to_exact_when_learning_missed_a_goal_the_optimum_reaches(tmp_path: Path) -> None:
    """One learning episode on examples/paper: the greedy run misses the goal, the optimal run under the
    same shield reaches it, and the message says how to get that strategy."""
    result = compile_file(Path(__file__).resolve().parents[2] / "examples" / "paper" / "model.ra")
    _, learned = verify(result, VerifyOptions(out_dir=tmp_path / "out", plots=False, seed=1, learn_episodes=1,
                                              only=("Qd", "reachSafe")))
    assert learned.optimum is not None and learned.optimum["reaches_goal_safely"] is True
    assert learned.message is not None and "the greedy run does not reach goal()" in learned.message
    assert learned.message.endswith("the optimal run reaches goal() safely: `rac verify --exact` emits that "
                                    "strategy instead of learning one")


def test_verify_exact_emits_the_optimal_strategy(tmp_path: Path) -> None:
    result = compile_file(write_engine_file(tmp_path, "goal_ahead", LEARN))
    _, fast, under = verify(result, VerifyOptions(out_dir=tmp_path / "out", plots=False, seed=1, exact=True))
    assert fast.status == "value" and fast.method == "exact optimum" and fast.optimum is not None
    assert fast.estimate == fast.optimum["value"] and fast.message is not None
    assert fast.message.startswith("the optimal strategy (exact, backward pass over")
    assert (tmp_path / "out" / "fast.strategy.npz").exists()
    assert under.status == "satisfied" and under.message is not None and "under `fast`" in under.message


def test_verify_says_when_the_optimum_is_out_of_reach(tmp_path: Path) -> None:
    unshielded = {"fast": QUERIES["Learn"].replace(" under safe", "")}  # no shield to explore first
    result = compile_file(write_engine_file(tmp_path, "goal_ahead", unshielded))
    (fast,) = verify(result, VerifyOptions(out_dir=tmp_path / "out", plots=False, seed=1, learn_episodes=32,
                                           max_states=10))
    assert fast.status == "value" and fast.optimum is not None and "out_of_reach" in fast.optimum
    assert fast.message is not None and "optimum out of reach" in fast.message
    (exact,) = verify(result, VerifyOptions(out_dir=tmp_path / "out", plots=False, seed=1, exact=True,
                                            max_states=10))
    assert exact.status == "unknown" and exact.message is not None and "out of reach" in exact.message


def test_the_cli_exact_flag(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    from rac.cli.main import main

    path = write_engine_file(tmp_path, "goal_ahead", LEARN)
    code = main(["verify", str(path), "--seed", "1", "--exact", "-o", str(tmp_path / "out"), "--format", "json",
                 "--no-plots", "-q"])
    out = json.loads(capsys.readouterr().out)
    fast = next(r for r in out["results"] if r["name"] == "fast")
    assert code == 0 and fast["method"] == "exact optimum" and fast["optimum"]["states"] > 0
