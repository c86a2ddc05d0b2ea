"""``rac.learning.qlearning``: tabular Q-learning of strategies on the scenario model, and ``rac verify``'s
learning queries (``strategy S = maxE(...)``) and path queries ``under S``.

On the tiny scenarios of :mod:`tiny_scenarios` (known plans): on :func:`goal_ahead` speeding up
reaches the goal, and learning under the safety shield finds a strategy whose one run does so
safely, without a single unsafe learning episode; on :func:`avoidable_obstacle` only braking at
once avoids the van, so unshielded learning collides while shielded learning never does. Also:
observation keys and bins, greedy ties, unseen keys, save/load, seeds, fallbacks of a shield that
does not know a state, the objective's increase as the reward, and the replayed samples of a run;
the greedy evaluation inside the next batch, and runs stepped together in one batch, each the
same as alone.
"""

from __future__ import annotations

import dataclasses
import json
import warnings
from collections.abc import Callable
from fractions import Fraction
from pathlib import Path

import numpy as np
import pytest
from engine_files import QUERIES, write_engine_file

from rac.compiler import CompileResult, compile_file
from rac.engine import shield
from rac.engine.stats import clopper_pearson
from rac.learning.episodes import EpisodeBatch, parse_expr
from rac.learning.lockstep import Job, Lane, run_together
from rac.learning.qlearning import (
    LearnedStrategy,
    LearningResult,
    ObjectiveIncrease,
    default_bin,
    evaluate,
    learn,
    learning,
    observation_keys,
    run_strategy,
)
from rac.learning.runs import Reset, Steps, evaluation_steps
from rac.verify.runner import VerifyOptions, render_text, verify

X, V, LOCATION = parse_expr("x"), parse_expr("v"), parse_expr("Tiny.location")
SURVIVE = parse_expr("time >= 4")  # the goal of "stay safe for the whole 4 s horizon"
HORIZON = 8  # samples: the tiny scenarios' 4 s at 0.5 s


@dataclasses.dataclass(frozen=True)
class Scenario:
    """A tiny scenario's engine file, compiled, with its safety shield (at the 4 s horizon)."""

    result: CompileResult
    table: shield.ShieldTable
    folder: Path


@pytest.fixture(scope="module")
def scenario(tmp_path_factory: pytest.TempPathFactory) -> Callable[[str], Scenario]:
    cache: dict[str, Scenario] = {}

    def get(name: str) -> Scenario:
        if name not in cache:
            folder = tmp_path_factory.mktemp(name)
            result = compile_file(write_engine_file(folder, name, {"safe": QUERIES["safe"]}))
            (safe,) = verify(result, VerifyOptions(out_dir=folder / "out", plots=False))
            assert safe.status == "satisfied"
            cache[name] = Scenario(result, shield.load(folder / "out" / "safe.shield.npz"), folder)
        return cache[name]

    return get


# ---------------------------------------------------------------- observations and the table
def test_default_bins_and_keys() -> None:
    assert [default_bin(parse_expr(t)) for t in ("x", "true_y", "v", "head", "fabs(turn)", "-acc", "mindist()",
                                                 "time", "x + y", "Tiny.location")] == \
        [1.0, 1.0, 0.5, 0.1, 0.05, 0.5, 1.0, 0.1, 1.0, 1.0]
    keys = observation_keys(np.array([[1.0, 0.3, -0.0], [2.0, 0.29, 0.74]]), 1, [0.1, 0.5])
    # discrete as it is; 0.3 / 0.1 stays in bin 3 despite float noise; -0.0 and 0.0 are one key
    assert keys.tolist() == [[1.0, 3.0, 0.0], [2.0, 2.0, 1.0]]
    assert observation_keys(np.array([[-0.0]]), 1, []).tobytes() == np.array([[0.0]]).tobytes()
    with pytest.raises(ValueError, match="expected 1 discrete"):
        observation_keys(np.zeros((1, 3)), 1, [1.0])


def test_greedy_ties_masks_and_unseen_keys(tmp_path: Path) -> None:
    values = np.array([[1.0, 5.0, 5.0, 0.0], [-1.0, -2.0, -3.0, -1.0]])
    strategy = LearnedStrategy(("d",), ("c",), (1.0,), "max", np.array([[0.0, 0.0], [0.0, 1.0]]), values)
    keys = np.array([[0.0, 0.0], [0.0, 1.0], [7.0, 7.0], [0.0, 0.0]])
    masks = np.array([[1, 1, 1, 1], [1, 1, 1, 1], [0, 0, 1, 1], [1, 0, 0, 0]], dtype=bool)
    # the first maximum (ties go to the lowest index), the best allowed one, unseen: lowest allowed
    assert strategy.action(keys, masks).tolist() == [1, 0, 2, 0]
    # nothing allowed: all, said once per strategy (a caller's empty row no longer lapses unseen)
    with pytest.warns(UserWarning, match=r"1 of 1 mask rows allowed no action: the strategy chose among every"):
        assert strategy.action(keys[:1], np.zeros((1, 4), dtype=bool)).tolist() == [1]
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert strategy.action(keys[:1], np.zeros((1, 4), dtype=bool)).tolist() == [1]  # once only
    cost = dataclasses.replace(strategy, optimise="min")
    assert cost.action(keys[:2]).tolist() == [3, 2]  # minE: the lowest cost, ties to the lowest index
    loaded = LearnedStrategy.load(strategy.save(tmp_path / "s.strategy.npz"))
    assert loaded.action(keys, masks).tolist() == [1, 0, 2, 0] and loaded.optimise == "max"
    assert not list(tmp_path.glob("*.partial"))
    (tmp_path / "bad.npz").write_bytes(b"not a strategy")
    # numpy's own words advised loading the file "unsafely using the `allow_pickle=` keyword argument"
    with pytest.raises(ValueError, match="cannot read the strategy: not a NumPy .npz archive$"):
        LearnedStrategy.load(tmp_path / "bad.npz")
    # a shield file said "cannot read the strategy: 'header is not a file in the archive'"
    shield.save(shield.ShieldTable(("k",), np.zeros((1, 1), dtype=np.int32), np.ones((1, 4), dtype=bool)),
                 tmp_path / "safe.shield.npz")
    with pytest.raises(ValueError, match=r"not a rac strategy: a rac shield \(rac.engine.shield.load reads it\)"):
        LearnedStrategy.load(tmp_path / "safe.shield.npz")


def test_learn_rejects_bad_arguments(scenario: Callable[[str], Scenario]) -> None:
    batch = EpisodeBatch(scenario("goal_ahead").result, horizon_samples=HORIZON)
    with pytest.raises(ValueError, match="optimise"):
        learn(batch, discrete=[], continuous=[X], optimise="best")
    with pytest.raises(ValueError, match="bins"):
        learn(batch, discrete=[], continuous=[X], bins=[1.0, 2.0])
    with pytest.raises(ValueError, match="episodes"):
        learn(batch, discrete=[], continuous=[X], episodes=0)
    # a switch given as text or a number was taken by its truth: "no" turned it on
    for name in ("evaluate_in_batch", "counterfactuals", "pessimistic", "random_ties", "replay_best"):
        with pytest.raises(TypeError, match=f"{name} must be True or False, not 'no'"):
            learn(batch, discrete=[], continuous=[X], **{name: "no"})
    with pytest.raises(TypeError, match="counterfactuals must be True or False, not 1"):
        EpisodeBatch(scenario("goal_ahead").result, horizon_samples=HORIZON, counterfactuals=1)


# ---------------------------------------------------------------- learning on the tiny scenarios
def test_learning_under_the_shield_reaches_the_goal_safely(scenario: Callable[[str], Scenario],
                                                            tmp_path: Path) -> None:
    item = scenario("goal_ahead")
    batch = EpisodeBatch(item.result, reward=V, horizon_samples=HORIZON)  # reward: the speed, per sample
    outcome = learn(batch, discrete=[LOCATION], continuous=[X, V], shield=item.table, episodes=600, seed=3)
    assert outcome.collisions_during_learning == 0 and outcome.offroad_during_learning == 0
    assert outcome.fallbacks == 0  # the shield knows every state reachable under it
    assert outcome.first_success_episode is not None and outcome.first_success_episode <= outcome.episodes
    assert outcome.history.returns.shape == (outcome.episodes,) and not outcome.history.collided.any()
    greedy = outcome.greedy
    assert greedy.success.tolist() == [True] and greedy.samples_taken.tolist() == [HORIZON]
    # the known plan speeds up first: keeping 8 m/s would reach only x = 42 < 44 at 4 s
    assert tuple(batch.action_pairs[greedy.actions[0, 0]]) == (200, 0)
    # the returned strategy's one run is the greedy run it was chosen by
    run = run_strategy(batch, outcome.strategy, shield=item.table, runs=3)
    assert (run.actions == greedy.actions).all() and (run.returns == greedy.returns[0]).all()
    assert run.success.all()
    # saved and loaded: the same actions, the same run
    path = outcome.strategy.save(tmp_path / "reach.strategy.npz")
    loaded = LearnedStrategy.load(path)
    assert loaded.expressions() == (LOCATION, X, V) and loaded.meta["seed"] == 3
    assert np.array_equal(loaded.values, outcome.strategy.values) and np.array_equal(loaded.keys,
                                                                                     outcome.strategy.keys)
    observed = run.observations.reshape(-1, 3)
    assert (loaded.act(observed) == outcome.strategy.act(observed)).all()
    assert (run_strategy(batch, loaded, shield=item.table).actions == greedy.actions).all()
    # the deterministic run counted once per run; with action noise still safe under the shield
    assert evaluate(batch, loaded, shield=item.table, runs=20).success_rate == 1.0
    noisy = evaluate(batch, loaded, shield=item.table, runs=50, epsilon=0.3, seed=1)
    assert noisy.collided == 0 and noisy.offroad == 0
    # the success rate's interval, computed when asked (not by the evaluation: rac experiment never reads it)
    assert noisy.interval == clopper_pearson(noisy.successes, 50)
    assert noisy.interval[0] <= noisy.success_rate <= noisy.interval[1] <= 1.0


def test_learning_is_reproducible_with_a_seed(scenario: Callable[[str], Scenario]) -> None:
    batch = EpisodeBatch(scenario("goal_ahead").result, reward=V, horizon_samples=HORIZON)

    calls: list[tuple[int, int]] = []

    def once(seed: int):
        return learn(batch, discrete=[], continuous=[X, V], episodes=96, parallel=16, seed=seed, stop_after=50,
                     progress=lambda done, budget, mean_return: calls.append((done, budget)))

    first, again, other = once(5), once(5), once(6)
    assert calls[:6] == [(16 * i, 96) for i in range(1, 7)] and first.episodes == 96 and not first.stopped_early
    assert np.array_equal(first.strategy.values, again.strategy.values)
    assert np.array_equal(first.history.returns, again.history.returns)
    assert first.first_success_episode == again.first_success_episode
    assert not np.array_equal(first.history.returns, other.history.returns)


def test_the_obstacle_collides_only_without_the_shield(scenario: Callable[[str], Scenario]) -> None:
    item = scenario("avoidable_obstacle")
    batch = EpisodeBatch(item.result, reward=parse_expr("x - 100 * collide()"), goal=SURVIVE,
                         horizon_samples=HORIZON)
    free = learn(batch, discrete=[], continuous=[X, V], episodes=128, seed=1)
    assert free.collisions_during_learning > 0 and free.history.collided.sum() == free.collisions_during_learning
    shielded = learn(batch, discrete=[], continuous=[X, V], shield=item.table, episodes=128, seed=1)
    assert shielded.collisions_during_learning == 0 and shielded.offroad_during_learning == 0
    # the shield allows only braking straight on at the start (the scenario's known answer)
    assert shielded.greedy.success.tolist() == [True]
    assert tuple(batch.action_pairs[shielded.greedy.actions[0, 0]]) == (-200, 0)


def test_a_shield_that_does_not_know_a_state_falls_back_and_counts(scenario: Callable[[str], Scenario],
                                                                   tmp_path: Path) -> None:
    item = scenario("goal_ahead")
    (short,) = verify(item.result, VerifyOptions(out_dir=tmp_path, horizon=Fraction(2), plots=False))
    table = shield.load(tmp_path / "safe.shield.npz")  # decision states up to 2 s only
    batch = EpisodeBatch(item.result, reward=V, horizon_samples=HORIZON)
    outcome = learn(batch, discrete=[], continuous=[X, V], shield=table, episodes=32, seed=1)
    # decisions at 2 s and 3 s are unknown to it: every episode falls back twice
    assert outcome.fallbacks == 2 * 32 and (outcome.history.fallbacks == 2).all()


def test_the_objective_increase_is_the_automatons_reward(scenario: Callable[[str], Scenario]) -> None:
    result = scenario("avoidable_obstacle").result
    plain = EpisodeBatch(result, horizon_samples=HORIZON)
    doubled = ObjectiveIncrease(EpisodeBatch(result, horizon_samples=HORIZON), parse_expr("2 * sa"))
    rng = np.random.default_rng(0)
    plain.reset(8)
    doubled.reset(8)
    while not plain.done.all():
        actions = rng.integers(plain.n_actions, size=8)
        a, b = plain.step(actions), doubled.step(actions)
        assert np.allclose(2 * a.reward, b.reward) and (a.collided == b.collided).all()
    assert doubled.done.all() and doubled.n == 8  # the rest is the batch's


def test_the_replayed_samples_are_the_run(scenario: Callable[[str], Scenario]) -> None:
    item = scenario("goal_ahead")
    batch = EpisodeBatch(item.result, reward=V, goal=None, horizon_samples=HORIZON)
    outcome = learn(batch, discrete=[], continuous=[X, V], shield=item.table, episodes=64, seed=2)
    run = run_strategy(batch, outcome.strategy, shield=item.table)
    runs = run.samples(item.result.model_data)
    assert runs.states.shape == (1, HORIZON + 1, 7) and runs.truth.shape == (1, HORIZON + 1, 5)
    decisions = run.states[0, :, 0]
    assert (runs.states[0, decisions] == run.states[0, :, 1:]).all()
    assert runs.actions[0, ::batch.decide_every].tolist() == run.actions[0].tolist()


# ---------------------------------------------------------------- the greedy run in the batch, runs together
def same_learning(a: LearningResult, b: LearningResult) -> bool:
    """Everything but the seconds, bit for bit."""
    arrays = [(getattr(a.history, f.name), getattr(b.history, f.name)) for f in dataclasses.fields(a.history)]
    arrays += [(getattr(a.greedy, f.name), getattr(b.greedy, f.name)) for f in dataclasses.fields(a.greedy)]
    arrays += [(a.strategy.keys, b.strategy.keys), (a.strategy.values, b.strategy.values)]
    return all(np.array_equal(x, y) for x, y in arrays) and (
        (a.first_success_episode, a.episodes, a.stopped_early, a.fallbacks, a.seed)
        == (b.first_success_episode, b.episodes, b.stopped_early, b.fallbacks, b.seed))


def test_the_greedy_run_in_the_next_batch_is_the_greedy_run_alone(scenario: Callable[[str], Scenario]) -> None:
    """Evaluating the greedy strategy as one more episode of the next batch (frozen table, no random
    numbers, not learned from; that batch discarded when the verdict stops learning) changes nothing."""
    goal, van = scenario("goal_ahead"), scenario("avoidable_obstacle")
    cases = [(EpisodeBatch(goal.result, reward=V, horizon_samples=HORIZON), goal.table, "max", 2),
             (EpisodeBatch(van.result, reward=parse_expr("x - 100 * collide()"), goal=SURVIVE,
                           horizon_samples=HORIZON), None, "max", 3),
             (EpisodeBatch(goal.result, reward=V, horizon_samples=HORIZON), None, "min", 50)]
    stopped = []
    for batch, table, optimise, stop_after in cases:
        for seed in (1, 2):
            options = dict(discrete=[LOCATION], continuous=[X, V], shield=table, optimise=optimise, episodes=160,
                           parallel=8, seed=seed, stop_after=stop_after)
            inside, alone = learn(batch, **options), learn(batch, evaluate_in_batch=False, **options)
            assert same_learning(inside, alone)
            assert len(inside.history.eval_episodes) == inside.episodes // 8
            stopped.append(inside.stopped_early)
    assert any(stopped) and not all(stopped)  # both ends of learning are compared


@pytest.mark.parametrize("steer", [None, "dist_goal()"])
def test_runs_learned_together_are_the_runs_learned_alone(scenario: Callable[[str], Scenario],
                                                          steer: str | None) -> None:
    """Also exploring steered by a lookahead (``steer``), which the lanes read once for every row."""
    item = scenario("avoidable_obstacle")
    shared = EpisodeBatch(item.result, reward="automaton", horizon_samples=HORIZON)
    objective = parse_expr("x - 100 * sa")
    runs = [(item.table, None, 1, 8), (None, None, 2, 8), (None, objective, 1, 5), (item.table, objective, 3, 16)]

    def options(table: shield.ShieldTable | None, seed: int, parallel: int) -> dict[str, object]:
        return dict(discrete=[LOCATION], continuous=[X, V], shield=table, episodes=48, parallel=parallel, seed=seed,
                    stop_after=2, steer=steer)

    jobs = [Job(learning(shared, **options(table, seed, parallel)),
                None if reward is None else shared.expression(reward)) for table, reward, seed, parallel in runs]
    together = run_together(jobs, shared)
    for (table, reward, seed, parallel), (outcome, seconds) in zip(runs, together):
        batch = EpisodeBatch(item.result, reward="automaton", horizon_samples=HORIZON)
        alone = learn(batch if reward is None else ObjectiveIncrease(batch, reward), **options(table, seed, parallel))
        assert same_learning(outcome, alone) and seconds > 0
    assert (shared.steps_ahead > 0) == (steer is not None)
    evaluations = run_together([Job(evaluation_steps(outcome.strategy, runs=runs_, shield=table, seed=4,
                                                     epsilon=0.3))
                                for (table, _, _, _), (outcome, _), runs_ in zip(runs, together, (10, 1, 7, 30))],
                               shared)
    batch = EpisodeBatch(item.result, reward="automaton", horizon_samples=HORIZON)
    for (table, _, _, _), (outcome, _), runs_, (evaluation, _) in zip(runs, together, (10, 1, 7, 30), evaluations):
        assert evaluation == evaluate(batch, outcome.strategy, runs=runs_, shield=table, seed=4, epsilon=0.3)


@pytest.mark.parametrize("steer", [None, "dist_goal()"])
def test_ctrl_c_stops_runs_together_after_the_step_with_what_they_learned(
        scenario: Callable[[str], Scenario], steer: str | None) -> None:
    """With ``interruptible``, Ctrl-C (SIGINT) is noted, not raised halfway into a generator: after the
    step under way every learning run returns the strategy of its last evaluation (the same as the
    uninterrupted run had then), a job finished before keeps its result, a run not evaluated yet and
    a generator that cannot stop give None, and the previous SIGINT handler is back."""
    import signal

    from rac.learning.lockstep import Interrupted

    item = scenario("avoidable_obstacle")
    shared = EpisodeBatch(item.result, reward="automaton", horizon_samples=HORIZON)
    evaluations: list[int] = []

    def ctrl_c_at_the_third(after: int, budget: int, mean: float) -> None:
        evaluations.append(after)
        if len(evaluations) == 3:
            signal.raise_signal(signal.SIGINT)

    # with steer, the runs also wait on lookahead requests between their steps
    options: dict[str, object] = dict(discrete=[LOCATION], continuous=[X, V], shield=item.table, episodes=400,
                                      parallel=4, seed=5, stop_after=1000, steer=steer)
    full = learn(EpisodeBatch(item.result, reward="automaton", horizon_samples=HORIZON), **options)
    before = signal.getsignal(signal.SIGINT)
    jobs = [Job(learning(shared, **options, progress=ctrl_c_at_the_third)),  # type: ignore[arg-type]
            Job(evaluation_steps(full.strategy, runs=10_000, shield=item.table, seed=1))]
    with pytest.raises(Interrupted) as info:
        run_together(jobs, shared, interruptible=True)
    assert signal.getsignal(signal.SIGINT) is before
    (stopped, seconds), (evaluation, _) = info.value.results
    assert evaluation.runs == 10_000 and seconds > 0  # finished in the first round: its result stands
    assert isinstance(stopped, LearningResult) and stopped.interrupted
    assert evaluations[2] <= stopped.episodes < 400  # the batch under way was dropped
    assert len(stopped.history.returns) == stopped.episodes
    assert stopped.history.eval_episodes.tolist() == full.history.eval_episodes.tolist()[:len(evaluations)]
    assert stopped.history.returns.tolist() == full.history.returns.tolist()[:stopped.episodes]
    assert not full.interrupted

    def ctrl_c_at_once() -> Steps[None]:
        yield Reset(1)
        signal.raise_signal(signal.SIGINT)
        while True:
            yield np.zeros(1, dtype=np.int64)

    with pytest.raises(Interrupted) as info:  # a learning run not evaluated yet has nothing to give
        run_together([Job(learning(shared, **options)), Job(ctrl_c_at_once())], shared, interruptible=True)
    assert [result for result, _ in info.value.results] == [None, None]
    assert signal.getsignal(signal.SIGINT) is before

    def ctrl_c_at_the_last_step() -> Steps[str]:
        yield Reset(1)
        yield np.zeros(1, dtype=np.int64)
        signal.raise_signal(signal.SIGINT)
        return "done"

    with pytest.raises(Interrupted) as info:  # every job finished in that step: all results, and told so
        run_together([Job(ctrl_c_at_the_last_step())], shared, interruptible=True)
    assert [result for result, _ in info.value.results] == ["done"]


def test_a_lane_is_some_rows_of_the_shared_batch(scenario: Callable[[str], Scenario]) -> None:
    batch = EpisodeBatch(scenario("avoidable_obstacle").result, horizon_samples=HORIZON)
    batch.reset(6)
    batch.step(np.arange(6) % batch.n_actions)
    lane = Lane(batch, slice(2, 5))
    exprs = [X, V, LOCATION, parse_expr("prev(x)"), parse_expr("mindist()")]
    assert np.array_equal(lane.observe(exprs), batch.observe(exprs)[2:5])
    assert np.array_equal(lane.state_keys(), batch.state_keys()[2:5]) and lane.n == 3
    with pytest.raises(RuntimeError, match="run_together"):
        lane.step(np.zeros(3, dtype=np.int64))
    with pytest.raises(RuntimeError, match="run_together"):
        lane.reset(3)



def test_lanes_read_the_shared_batch_once_per_step(scenario: Callable[[str], Scenario]) -> None:
    """Under run_together the lanes' readings (observations, state keys, the model's masks) are read
    once for every row between two steps (Between): each lane gets exactly its rows' own reading, a
    copy of its own, and a step or a reset makes them read again."""
    shared = EpisodeBatch(scenario("avoidable_obstacle").result, horizon_samples=HORIZON)
    exprs = (X, V, LOCATION, parse_expr("prev(x)"), parse_expr("mindist()"))
    checked: list[int] = []

    def reader(width: int, seed: int) -> Steps[int]:
        rng = np.random.default_rng(seed)
        for _ in range(2):  # two rounds: the readings after a reset are the new episodes'
            lane = yield Reset(width)
            assert isinstance(lane, Lane)
            while not lane.done.all():
                for name, direct in (("observe", shared.observe(exprs, lane.rows)),
                                     ("state_keys", shared.state_keys(lane.rows)),
                                     ("model_masks", shared.model_masks(lane.rows))):
                    args = (list(exprs),) if name == "observe" else ()
                    first = getattr(lane, name)(*args)
                    assert first.dtype == direct.dtype and np.array_equal(first, direct, equal_nan=True)
                    first[...] = 0  # a lane's own copy: the next reading is untouched
                    assert np.array_equal(getattr(lane, name)(*args), direct, equal_nan=True)
                checked.append(width)
                yield rng.integers(0, lane.n_actions, size=width)
        return width

    results = run_together([Job(reader(width, seed)) for seed, width in enumerate((3, 1, 4))], shared)
    assert [result for result, _ in results] == [3, 1, 4] and set(checked) == {3, 1, 4}


# ---------------------------------------------------------------- rac verify
VERIFY_QUERIES = {
    "safe": QUERIES["safe"],
    "reach": "strategy reach = maxE(v)[<=4]{Tiny.location}->{x, v}: <> goal() under safe",
    "SafeUnderReach": "A[] !collide() && !offroad() under reach",
    "GoalUnderReach": "A<> goal() under reach",
    "SlowUnderReach": "E<> v < 8 under reach",
    "RewardUnderReach": "A[] sa >= 0 under reach",  # the automaton's names: not on the replayed run
    "rush": "strategy rush = maxE(sa + x)[<=4]{}->{x, v}: <> goal()",
    "SafeUnderRush": "A[] !collide() && !offroad() under rush",
}


def test_verify_learns_and_checks_under_the_strategy(tmp_path: Path) -> None:
    results = {r.name: r for r in verify(compile_file(write_engine_file(tmp_path, "goal_ahead", VERIFY_QUERIES)),
                                         VerifyOptions(seed=1, out_dir=tmp_path / "out", plots=False,
                                                       only=("SafeUnderReach", "GoalUnderReach",
                                                             "SlowUnderReach", "RewardUnderReach")))}
    assert list(results)[:2] == ["safe", "reach"]  # `under reach` brings reach, and reach `under safe` safe
    reach = results["reach"]
    assert reach.kind == "learning" and reach.status == "value" and reach.files == (
        str(tmp_path / "out" / "reach.strategy.npz"),)
    assert "reaches goal() safely" in (reach.message or "") and "collided: 0" in (reach.message or "")
    assert reach.runs is not None and 0 < reach.runs <= 1000 and reach.seed is not None
    assert LearnedStrategy.load(reach.files[0]).meta["under"] == "safe"
    assert results["SafeUnderReach"].status == "satisfied"
    goal = results["GoalUnderReach"]
    assert goal.status == "satisfied" and goal.trace is not None and goal.trace[-1]["goal"]
    assert [row["time"] for row in goal.trace] == [k * 0.5 for k in range(HORIZON + 1)]
    assert results["SlowUnderReach"].status == "not satisfied"  # the one run speeds up from 8 m/s
    assert results["RewardUnderReach"].status == "unsupported" and "sa" in (results["RewardUnderReach"].message or "")
    text = render_text(list(results.values()))
    assert " -- learned in " in text and "wrote " + str(tmp_path / "out" / "reach.strategy.npz") in text


def test_verify_an_unshielded_strategy_into_the_van(tmp_path: Path) -> None:
    path = write_engine_file(tmp_path, "avoidable_obstacle", VERIFY_QUERIES)
    options = VerifyOptions(seed=2, out_dir=tmp_path / "out", plots=False, only=("SafeUnderRush",))
    results = {r.name: r for r in verify(compile_file(path), options)}
    assert list(results) == ["rush", "SafeUnderRush"]  # `under rush` pulls in the learning query
    assert "learning episodes that collided: 0" not in (results["rush"].message or "")
    unsafe = results["SafeUnderRush"]  # maximising the distance driven runs into the van
    assert unsafe.status == "not satisfied" and unsafe.trace is not None
    assert unsafe.trace[-1]["collide"] or unsafe.trace[-1]["offroad"]
    assert not any(row["collide"] or row["offroad"] for row in unsafe.trace[:-1])
    again = {r.name: r for r in verify(compile_file(path), options)}
    assert again["rush"].estimate == results["rush"].estimate and again["rush"].runs == results["rush"].runs


def test_when_no_allowed_run_reaches_the_goal_the_report_says_so(tmp_path: Path) -> None:
    """On the avoidable obstacle the van blocks the only lane: the shield exists, but no run it allows
    reaches the goal — the complete graph proves it, and the learning report says that rather than a
    bare "never". Without a shield the complete pruned graph (the shield's) proves that no run staying
    safe reaches it."""
    queries = {"safe": VERIFY_QUERIES["safe"],
               "go": "strategy go = maxE(sa + x)[<=4]{}->{x, v}: <> goal() under safe",
               "rush": VERIFY_QUERIES["rush"]}
    path = write_engine_file(tmp_path, "avoidable_obstacle", queries)
    results = {r.name: r for r in verify(compile_file(path), VerifyOptions(seed=1, plots=False, learn_episodes=64))}
    assert results["safe"].status == "satisfied"
    assert ("greedy run safe until the goal: never: no run the shield `safe` allows reaches goal() safely within "
            "4 s (the complete graph proves it), so no episode can succeed") in (results["go"].message or "")
    assert ("greedy run safe until the goal: never: no run that stays safe reaches goal() safely within 4 s"
            in (results["rush"].message or ""))
    # where a run reaches it, no such claim
    reachable = write_engine_file(tmp_path, "goal_ahead", queries, ra_name="reachable")
    learned = {r.name: r for r in verify(compile_file(reachable), VerifyOptions(seed=1, plots=False,
                                                                                learn_episodes=8))}
    assert "proves it" not in (learned["go"].message or "")


def test_statistical_queries_under_a_learned_strategy_use_its_one_run(tmp_path: Path) -> None:
    queries = {**VERIFY_QUERIES, "Trace": "simulate[<=4;3]{x, v} under reach",
               "PrGoal": "Pr[<=4](<> goal()) under reach", "MaxSpeed": "E[<=4;5](max: v) under reach"}
    path = write_engine_file(tmp_path, "goal_ahead", queries)
    results = {r.name: r for r in verify(compile_file(path), VerifyOptions(
        seed=1, out_dir=tmp_path / "out", plots=False, only=("Trace", "PrGoal", "MaxSpeed", "GoalUnderReach")))}
    assert results["GoalUnderReach"].status == "satisfied"
    rows = (tmp_path / "out" / "Trace.csv").read_text().splitlines()
    by_run = [[line.split(",", 1)[1] for line in rows[1:] if line.startswith(f"{run},")] for run in range(3)]
    assert len(by_run[0]) == HORIZON + 1 and by_run[0] == by_run[1] == by_run[2]  # deterministic: one run
    goal = results["PrGoal"]
    assert goal.interval is not None and goal.interval[0] > 0.9 and goal.estimate == 1.0
    speed = results["MaxSpeed"]
    assert speed.interval is not None and speed.interval[0] == speed.interval[1] == speed.estimate


def test_render_draws_the_learned_strategys_run(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    from PIL import Image

    from rac.cli.main import main

    path = write_engine_file(tmp_path, "goal_ahead", VERIFY_QUERIES)
    png = tmp_path / "run.png"  # in the folder -o names
    assert main(["render", str(path), "--strategy", "reach", "--seed", "1", "-o", str(tmp_path), "-q"]) == 0
    assert "the run under the learned strategy reach" in capsys.readouterr().out
    with Image.open(png) as image:
        assert image.format == "PNG"
    assert main(["render", str(path), "--strategy", "nope", "-o", str(tmp_path)]) == 2
    assert "learning queries: reach, rush" in capsys.readouterr().err
    assert main(["render", str(path), "--strategy", "reach", "--shield", "-o", str(tmp_path)]) == 2  # one or the other
    # --exact draws the optimal strategy's run (rac verify --exact's), and needs --strategy
    capsys.readouterr()
    assert main(["render", str(path), "--strategy", "reach", "--exact", "--seed", "1", "-o", str(tmp_path / "x"),
                 "-q", "--format", "json"]) == 0
    assert json.loads(capsys.readouterr().out)["how"] == "the run under the optimal strategy reach"
    assert (tmp_path / "x" / "run.png").is_file()
    assert main(["render", str(path), "--exact", "-o", str(tmp_path / "y"), "-q"]) == 2
    assert "--exact draws a file's learning query's optimal strategy: give --strategy NAME" in capsys.readouterr().err


def test_render_draws_the_learned_strategy_under_its_shield_past_the_files_horizon(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """`rac render --strategy reach --horizon 8` (the file's: 4 s) learned under a shield computed to 4 s and
    drew 8 s: past 4 s the shield allowed nothing and the run chose among all actions, silently (on ZAM_Ramp
    the drawn run "under safe" left the road). The shield now covers the drawn run, as under `rac verify
    --horizon 8`: the shield chooses at every decision of it."""
    from rac.cli.main import main
    from rac.verify import runner

    contexts = []
    answer = runner.run_queries

    def keep(*args, **kwargs):
        context, results = answer(*args, **kwargs)
        contexts.append(context)
        return context, results

    monkeypatch.setattr(runner, "run_queries", keep)
    path = write_engine_file(tmp_path, "goal_ahead", VERIFY_QUERIES)
    assert main(["render", str(path), "--strategy", "reach", "--horizon", "8", "--seed", "1", "-o", str(tmp_path),
                 "-q"]) == 0
    [context] = contexts
    run, _ = context.learned_run("reach", 2 * HORIZON)
    assert int(run.fallbacks[0]) == 0


# ---------------------------------------------------------------- learning within --max-memory (issue 22)
def test_learning_beyond_the_memory_budget_is_refused_before_it_allocates(scenario: Callable[[str], Scenario],
                                                                          monkeypatch: pytest.MonkeyPatch) -> None:
    """The estimate (Q-table rows up to one per decision, the replay, the history) is checked before the
    table exists: with a tiny budget no table is made; a budget that fits learns as without one."""
    from rac.engine.budget import EstimateExceeded, learning_bytes
    from rac.learning import tabular

    batch = EpisodeBatch(scenario("goal_ahead").result, horizon_samples=HORIZON)
    options: dict[str, object] = dict(discrete=[LOCATION], continuous=[X, V], episodes=500, seed=1)
    needed = learning_bytes(episodes=500, parallel=32, steps=batch.max_steps, observations=3,
                            actions=batch.n_actions)
    assert needed > 500 * batch.max_steps * (3 + batch.n_actions) * 8  # at least the table's rows, once
    made: list[int] = []
    real = tabular.QTable.__init__

    def counting(self: tabular.QTable, width: int, n_actions: int, *rest: float) -> None:
        made.append(width)
        real(self, width, n_actions, *rest)

    monkeypatch.setattr(tabular.QTable, "__init__", counting)
    with pytest.raises(EstimateExceeded, match=r"learning would need about .*--max-memory.*episode budget") as info:
        learn(batch, max_bytes=needed - 1, **options)  # type: ignore[arg-type]
    assert isinstance(info.value, MemoryError) and info.value.needed_bytes == needed and not made
    fits = learn(batch, max_bytes=needed, **options)  # type: ignore[arg-type]
    assert made == [3] and same_learning(fits, learn(batch, **options))  # type: ignore[arg-type]


def test_verify_and_experiment_refuse_learning_beyond_max_memory(tmp_path: Path,
                                                                 capsys: pytest.CaptureFixture[str]) -> None:
    """rac verify: the learning query is unknown (exit 4) and says what to change; rac experiment stops
    with the estimate as a resource limit (exit 2); the same commands within the default budget learn."""
    from rac.cli.main import main

    path = write_engine_file(tmp_path, "goal_ahead", VERIFY_QUERIES)
    (rush,) = verify(compile_file(path), VerifyOptions(seed=1, only=("rush",), out_dir=tmp_path / "out",
                                                       max_bytes=64 * 2**10))
    assert rush.status == "unknown" and rush.message is not None
    assert "--max-memory" in rush.message and "--learn-episodes" in rush.message
    assert not (tmp_path / "out" / "rush.strategy.npz").exists()
    capsys.readouterr()
    assert main(["verify", str(path), "--query", "rush", "--seed", "1", "--max-memory", "64k", "-q",
                 "-o", str(tmp_path / "cli")]) == 4
    assert "learning would need about" in capsys.readouterr().out
    assert main(["verify", str(path), "--query", "rush", "--seed", "1", "-q", "-o", str(tmp_path / "cli")]) == 0
    assert "learned in" in capsys.readouterr().out
    assert main(["experiment", str(path), "--seeds", "1,2", "--episodes", "16", "--runs", "2", "--reward-function",
                 "v", "--max-memory", "64k", "-q", "-o", str(tmp_path / "exp")]) == 2
    err = capsys.readouterr().err
    assert err.startswith("error[E0016]: resource limit: ")
    assert "learning 8 runs together would need about" in err and "--episodes" in err and "--max-memory" in err
    assert not (tmp_path / "exp" / "results.json").exists()


def test_learn_refuses_what_it_used_to_read_otherwise(scenario: Callable[[str], Scenario]) -> None:
    """A seed of 1.5 or "1" learned with seed 1, growth 0 or NaN gave batches of one episode or a bare
    "cannot convert float NaN to integer", an optimism of NaN filled the table with NaN, epsilon=(1.0,)
    said "not enough values to unpack"; a NumPy integer budget was refused as not an integer."""
    batch = EpisodeBatch(scenario("goal_ahead").result, horizon_samples=HORIZON)
    for options, said in (({"seed": 1.5}, "seed must be a whole number"), ({"seed": "1"}, "seed must be a whole"),
                          ({"growth": 0}, "growth must be a positive number"),
                          ({"growth": float("nan")}, "growth must be a positive number"),
                          ({"optimism": float("nan")}, "optimism must be a finite number"),
                          ({"epsilon": (1.0,)}, r"epsilon must be a number or a pair \(first, last\)")):
        with pytest.raises(ValueError, match=said):
            learn(batch, discrete=[], continuous=[X], episodes=2, **options)
    assert learn(batch, discrete=[], continuous=[X], episodes=np.int64(2), seed=np.int64(1)).episodes == 2
    for samples in (1.5, True):  # episodes of 1 sample
        with pytest.raises(ValueError, match="horizon_samples must be a whole number of samples"):
            EpisodeBatch(scenario("goal_ahead").result, horizon_samples=samples)  # type: ignore[arg-type]
    assert EpisodeBatch(scenario("goal_ahead").result, horizon_samples=np.int64(4)).horizon_samples == 4
