"""The best run replayed (issue 23, third round): ``learn(..., replay_best=True)`` replays the best
learning episode seen (a safe goal first, then the return) backwards after every batch, so a later
episode through the same observation key does not leave the greedy strategy off the best run."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from engine_files import write_engine_file

from rac.compiler import compile_file
from rac.core.diagnostics import RacValueError
from rac.learning.episodes import EpisodeBatch, parse_expr
from rac.learning.optimum import solve
from rac.learning.qlearning import learn
from rac.learning.runs import Ahead, Steps, drive
from rac.learning.tabular import UNTRIED, Learner, QTable, Transition, update


def _one_step(rewards: list[float]) -> Transition:
    n = len(rewards)
    return Transition(np.arange(n), np.zeros(n, dtype=np.int64), np.ones(n, dtype=np.int64), np.array(rewards),
                      np.ones(n, dtype=np.int64), np.ones((n, 2), dtype=bool), np.ones(n, dtype=bool))


def test_the_best_run_is_replayed() -> None:
    table = QTable(1, 2, UNTRIED)
    table.rows(np.array([[0.0], [1.0]]), create=True)
    learner = Learner(table, (), 0, (), None, np.random.default_rng(0), 1.0, 1.0, 1.0, 1, replay_best=True)
    step = _one_step([5.0, -3.0])  # two episodes through the same key: the later one overwrites it
    update(table.values, step, 1.0, 1.0, UNTRIED)
    assert table.values[0, 1] == -3.0
    learner._replay_best([step], np.array([5.0, -3.0]), np.array([False, False]))
    assert table.values[0, 1] == 5.0 and learner.best is not None and learner.best[0] == (False, 5.0)
    worse = _one_step([-7.0])  # a later batch's worse episode: the best one is replayed again
    update(table.values, worse, 1.0, 1.0, UNTRIED)
    learner._replay_best([worse], np.array([-7.0]), np.array([False]))
    assert table.values[0, 1] == 5.0
    safe = _one_step([-9.0])  # an episode that reached the goal safely beats any that did not
    learner._replay_best([safe], np.array([-9.0]), np.array([True]))
    assert learner.best is not None and learner.best[0] == (True, -9.0) and table.values[0, 1] == -9.0


@pytest.mark.parametrize("scene", ["avoidable_obstacle", "goal_behind_wall", "goal_ahead"])
@pytest.mark.parametrize("seed", [1, 2])
def test_learning_with_the_best_run_replayed(tmp_path: Path, scene: str, seed: int) -> None:
    """The greedy run is still the best learning episode's (exact keys), and the same seed gives the
    same result."""
    batch = EpisodeBatch(compile_file(write_engine_file(tmp_path, scene)), reward="automaton", horizon_samples=8)

    def run() -> tuple[float, np.ndarray]:
        outcome = learn(batch, discrete=["Tiny.location", "time"], continuous=["x", "v"], bins=[1e-6, 1e-6],
                        episodes=24, parallel=4, seed=seed, alpha=1.0, pessimistic=True, random_ties=True,
                        epsilon=(1.0, 0.2), stop_after=100, replay_best=True)
        history = outcome.history
        assert history.eval_returns[-1] == pytest.approx(history.returns.max())
        return float(history.eval_returns[-1]), history.returns

    first, second = run(), run()
    assert first[0] == second[0] and np.array_equal(first[1], second[1])


def test_steered_exploration_succeeds_as_often_as_its_exact_chance(tmp_path: Path) -> None:
    """``steer``: at epsilon 1 every choice explores, a share STEERED of them towards the least ``dist_goal()``
    one decision later; the learning episodes then reach the goal safely as often as the exact chance of such
    an episode (:attr:`rac.learning.optimum.Optimum.steered_success`, brute-forced in test_optimum.py) says,
    and not as often as uniform ones do. On the tiny goal ahead without a shield: 17.9 % against 0.59 %."""
    result = compile_file(write_engine_file(tmp_path, "goal_ahead"))
    exact = solve(EpisodeBatch(result, horizon_samples=8), steer="dist_goal()")
    assert exact.steered_success is not None and exact.steered_success > 10 * exact.uniform_success
    episodes = 2000
    for steer, chance in ((None, exact.uniform_success), ("dist_goal()", exact.steered_success)):
        history = learn(EpisodeBatch(result, horizon_samples=8), discrete=["time"], continuous=["x", "y"],
                        episodes=episodes, epsilon=1.0, seed=3, steer=steer, parallel=32, stop_after=10**6).history
        assert history.returns.size == episodes
        rate = float((history.reached & ~history.collided & ~history.offroad & ~history.stranded).mean())
        spread = 4 * np.sqrt(chance * (1 - chance) / episodes) + 1e-3
        assert abs(rate - chance) < spread, (steer, rate, chance)


def test_steering_needs_episodes_that_look_ahead() -> None:
    """A stand-in for the episodes without ``ahead()`` cannot answer a lookahead: said, not an AttributeError."""
    def asks() -> Steps[None]:
        yield Ahead((parse_expr("dist_goal()"),), np.array([0]))

    with pytest.raises(RacValueError, match="cannot look ahead"):
        drive(asks(), object())  # type: ignore[arg-type]


def test_the_steered_choice_is_the_least_value_among_the_allowed() -> None:
    """Ties at random among the least allowed values; an action not allowed never, however small its value; a
    row of no numbers (a done episode) uniform among its allowed actions."""
    learner = Learner(QTable(1, 4), (), 0, (), None, np.random.default_rng(0), 1.0, 1.0, 1.0, 1)
    values = np.array([[3.0, 1.0, 1.0, 0.5], [np.nan] * 4])
    masks = np.array([[True, True, True, False], [True, False, True, False]])
    picks = np.array([learner.toward(values, masks) for _ in range(200)])
    assert set(picks[:, 0]) == {1, 2} and set(picks[:, 1]) == {0, 2}
