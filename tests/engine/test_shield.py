"""Shields saved to a file and loaded back: same allowed actions, documented unseen states."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from rac.engine import shield as shields
from rac.engine.graph import ExploredGraph
from rac.engine.storm import safety_shield


def layered_graph() -> ExploredGraph:
    """k=0: one decision state with 3 actions; action 2 leads to an unsafe state.

    state 0 (k=0) --a0--> 1, --a1--> 2, --a2--> 3 (unsafe)
    states 1, 2 (k=1) decide again: from 1, a0 -> 4 (safe), a1 -> 5 (unsafe); from 2 only a0 -> 4.
    """
    states = np.array([[0, 0], [1, 10], [1, 20], [1, 30], [2, 40], [2, 50]], dtype=np.int32)
    offsets = np.array([0, 3, 5, 6, 6, 6, 6], dtype=np.int64)
    action = np.array([0, 1, 2, 0, 1, 0], dtype=np.int64)
    target = np.array([1, 2, 3, 4, 5, 4], dtype=np.int64)
    safe = np.array([True, True, True, False, True, False])
    return ExploredGraph(states, ("k", "x"), offsets, action, target, 0, {"safe": safe})


def test_saved_shield_allows_what_the_shield_allows(tmp_path: Path) -> None:
    graph = layered_graph()
    shield = safety_shield(graph, "safe")
    path = shields.save(shield, tmp_path / "safe.shield.npz")
    table = shields.load(path)
    assert table.columns == ("k", "x") and table.n_actions == 3
    for state in range(graph.n_states):
        if graph.choice_action[graph.choices(state)].size and (graph.choice_action[graph.choices(state)] >= 0).all():
            assert list(table.allowed(graph.states[state])) == sorted(shield.allowed(state).tolist())
    assert list(table.allowed([0, 0])) == [0, 1]
    assert list(table.mask([1, 10])) == [True, False, False]
    assert list(table.allowed([1, 20])) == [0]


def test_unseen_states_follow_the_chosen_policy(tmp_path: Path) -> None:
    path = shields.save(safety_shield(layered_graph(), "safe"), tmp_path / "s.npz")
    assert not shields.load(path).mask([7, 7]).any()
    assert shields.load(path, unseen="all").mask([7, 7]).all()
    with pytest.raises(shields.UnseenState):
        shields.load(path, unseen="error").allowed([7, 7])
    with pytest.raises(ValueError, match="unseen"):
        shields.load(path, unseen="maybe")
    assert not shields.load(path).knows([1, 30])  # unsafe, terminal: no decision there


def test_a_file_that_is_not_a_shield_is_refused(tmp_path: Path) -> None:
    bad = tmp_path / "bad.npz"
    bad.write_bytes(b"not a shield")
    with pytest.raises(ValueError, match="bad.npz"):
        shields.load(bad)
    other = tmp_path / "other.npz"
    np.savez(other, format=np.array("something else"))
    with pytest.raises(ValueError, match="not a rac shield"):
        shields.load(other)
    with pytest.raises(FileNotFoundError):
        shields.load(tmp_path / "missing.npz")


def test_a_strategy_file_given_as_a_shield_is_named(tmp_path: Path) -> None:
    # rac verify writes NAME.strategy.npz beside safe.shield.npz; the one for the other said only
    # "cannot read the shield: 'format is not a file in the archive'"
    from rac.learning.qlearning import LearnedStrategy

    path = LearnedStrategy(("x",), (), (), "max", np.zeros((1, 1)), np.zeros((1, 2))).save(tmp_path / "s.strategy.npz")
    with pytest.raises(ValueError, match=r"not a rac shield: a rac strategy \(rac.learning.qlearning.LearnedStrategy"):
        shields.load(path)
    np.savez(tmp_path / "arrays.npz", a=np.zeros(2))
    with pytest.raises(ValueError, match="not a rac shield: arrays a"):
        shields.load(tmp_path / "arrays.npz")


def test_the_table_keeps_its_horizon(tmp_path: Path) -> None:
    """A table knows the sample it was computed to (the graph's last layer by default), through a file;
    a file written before it was recorded loads with None (taken to cover every run)."""
    table = shields.table(safety_shield(layered_graph(), "safe"))
    assert table.horizon == 2
    assert shields.load(shields.save(table, tmp_path / "s.npz")).horizon == 2
    assert shields.table(safety_shield(layered_graph(), "safe"), horizon=5).horizon == 5
    old = tmp_path / "old.npz"
    np.savez_compressed(old, format=np.array(shields.FORMAT), columns=np.array(table.columns), states=table.states,
                        masks=table.masks, forget_every=np.array(0))
    assert shields.load(old).horizon is None


def test_too_few_actions_for_the_table_are_refused_by_name() -> None:
    # the graph takes actions 0..2: n_actions=2 was a raw IndexError from the mask's fill
    shield = safety_shield(layered_graph(), "safe")
    with pytest.raises(ValueError, match=r"n_actions=2, but the shield's graph has choices of action index up to 2"):
        shields.table(shield, n_actions=2)
    assert shields.table(shield, n_actions=5).n_actions == 5  # wider masks: the extra actions never allowed


def test_a_synthesised_shield_saved_as_computed_keeps_its_masks(tmp_path: Path) -> None:
    """``synthesise`` explores with ``forget_actions`` (jerk and turn held as 0 at decision samples): the
    computed shield saved as such (``save(computed, path)``, as the module documents) and its
    ``SafeOnward`` look states up that way too. They looked up a run's own jerk and turn, found no
    decision state after the start, and allowed nothing there (every action with ``unseen="all"``)."""
    from engine_files import QUERIES, write_engine_file

    from rac.compiler import compile_file
    from rac.engine.simulate import simulate

    result = compile_file(write_engine_file(tmp_path, "avoidable_obstacle", {"safe": QUERIES["safe"]}))
    data = result.model_data
    assert data is not None and result.automaton is not None
    horizon = result.automaton.steps
    computed, table = shields.synthesise(data, horizon)
    saved = shields.load(shields.save(computed, tmp_path / "computed.shield.npz"))
    assert saved.forget_every == table.forget_every == data.decide_every
    runs = simulate(data, runs=30, horizon_samples=horizon, seed=3, policy=table.masks_at)
    later = range(data.decide_every, horizon, data.decide_every)
    for k in later:
        expected = table.masks_at(k, runs.states[:, k])
        assert expected.any(axis=1).all() and (saved.masks_at(k, runs.states[:, k]) == expected).all(), k
    onward = shields.SafeOnward(computed, horizon)
    keys = np.column_stack([np.full(30, later[0]), runs.states[:, later[0]]]).astype(np.int32)
    assert onward(keys).all()


def test_the_step_shield_policy_says_which_budget_stopped_its_searches(tmp_path: Path) -> None:
    """A search stopped by its node budget is reproducible, one stopped by its time budget is not: the
    summary told them apart by neither (every one "ran out of their time budget")."""
    from engine_files import QUERIES, write_engine_file

    from rac.compiler import compile_file
    from rac.engine.lookahead import LookaheadSettings
    from rac.engine.simulate import simulate

    result = compile_file(write_engine_file(tmp_path, "avoidable_obstacle", {"safe": QUERIES["safe"]}))
    data = result.model_data
    assert data is not None and result.automaton is not None
    horizon = result.automaton.steps
    summaries = {}
    for name, settings in {"nodes": LookaheadSettings(depth=4, seconds=None, nodes=1),
                           "clock": LookaheadSettings(depth=4, seconds=1e-9)}.items():
        policy = shields.StepShieldPolicy(shields.StepShield(data, horizon, lookahead=settings))
        simulate(data, runs=3, horizon_samples=horizon, seed=1, policy=policy)
        assert policy.timed_out > 0
        summaries[name] = policy.summary()
    assert "ran out of their search budget" in summaries["nodes"] and "time limit" not in summaries["nodes"]
    assert "by its time limit, so the runs depend on the machine's speed" in summaries["clock"]


def test_the_step_shields_table_gives_way_within_the_machines_memory(tmp_path: Path,
                                                                    monkeypatch: pytest.MonkeyPatch) -> None:
    """``step_shield`` computes the table "if it can be had": by default within the memory budget rac's
    commands use (half the memory the process may use), so a table too large for the machine gives
    way to the runtime shield and says why, instead of exploring into swap (it had no limit)."""
    from engine_files import QUERIES, write_engine_file

    from rac.compiler import compile_file
    from rac.engine.lookahead import LookaheadSettings

    result = compile_file(write_engine_file(tmp_path, "avoidable_obstacle", {"safe": QUERIES["safe"]}))
    data = result.model_data
    assert data is not None and result.automaton is not None
    runtime = LookaheadSettings(depth=2, seconds=None)
    assert shields.step_shield(data, result.automaton.steps, lookahead=runtime).table is not None
    monkeypatch.setattr(shields, "default_max_bytes", lambda: 4096)  # a machine far too small for the table
    small = shields.step_shield(data, result.automaton.steps, lookahead=runtime)
    assert small.table is None and "memory budget of 4 kB" in (small.reason or ""), small.reason
    assert shields.step_shield(data, result.automaton.steps, lookahead=runtime, max_bytes=None).table is not None


@pytest.mark.parametrize("state", [[1], [1, 10, 0], np.array([1.0, 10.5]), np.zeros((1, 1, 2))])
def test_a_row_that_is_no_state_of_the_table_is_refused(tmp_path: Path, state: object) -> None:
    # an observation (29 floats, or the "ego" observation's 8 in metres) or the ego's 7 columns without k was
    # looked up as an unseen state: an empty mask (or all True under unseen="all"), with no word
    path = shields.save(safety_shield(layered_graph(), "safe"), tmp_path / "s.npz")
    for table in (shields.load(path), shields.load(path, unseen="all")):
        with pytest.raises(ValueError, match=r"a row of 2 integers \(k, x"):
            table.mask(state)
        with pytest.raises(ValueError, match="state_keys"):
            table.masks_for(np.array(state, ndmin=2))
    # the way to the state through gymnasium.make's wrappers (env.episodes there is an AttributeError)
    with pytest.raises(ValueError, match=r"a ScenarioEnv's env\.unwrapped\.episodes\.state_keys\(\)\[0\]"):
        table.mask(state)
    table = shields.load(path)
    assert table.mask(np.array([1.0, 10.0])).tolist() == [True, False, False]  # whole floats are significands too
    assert table.masks_for(np.zeros((0, 2), dtype=np.int32)).shape == (0, 3)
