"""Searching for one run (rac.engine.witness, explore's ``stop_at`` and ``beam``): an exploration that
stops at the first layer with a witness is the full exploration's prefix, a beam keeps states and
choices of the model only and says it is incomplete, the cheap searches agree with the exhaustive
answer on the tiny scenarios, and every witness replays with the scalar model (a tampered one does
not, with a message that says where)."""

from __future__ import annotations

import dataclasses
import itertools
import time
from fractions import Fraction as F
from pathlib import Path

import numpy as np
import pytest
from test_explore import tiny_data
from test_model_native import straight_scenario
from tiny_scenarios import TINY_SCENARIOS

from rac.engine import storm
from rac.engine.explore import explore
from rac.engine.witness import (
    SAFETY_SECONDS,
    Bounds,
    ReplayMismatch,
    beam_search,
    layered_search,
    random_runs,
    replay,
    search,
    witness_graph,
)
from rac.model import ModelData
from rac.model.batch import batch_model

HORIZON = 12


def data_and_graph() -> tuple[ModelData, object]:
    # ego 12 m behind the obstacle that appears at sample 10 (tests/model/test_explore.py): some runs collide
    scenario = dataclasses.replace(straight_scenario(), ego=straight_scenario().ego.__class__(22.0, 1.75, 0.0, 10.0))
    data = tiny_data(scenario, F(2, 5))
    return data, explore(data, horizon_samples=HORIZON)


def fast(data: ModelData, speed: float):
    """The states at or above ``speed`` m/s."""
    return lambda k, rows: rows[:, 2] >= speed * data.scale


def layer_sets(graph) -> list[set[tuple[int, ...]]]:
    k = graph.states[:, 0]
    return [{tuple(row) for row in graph.states[k == sample].tolist()} for sample in range(int(k.max()) + 1)]


def transitions(graph) -> set[tuple[tuple[int, ...], int, tuple[int, ...]]]:
    """(source row, action, target row) of every choice."""
    owner = np.repeat(np.arange(graph.n_states), np.diff(graph.choice_offsets))
    rows = [tuple(row) for row in graph.states.tolist()]
    return {(rows[s], int(a), rows[t]) for s, a, t in zip(owner, graph.choice_action, graph.choice_target)}


def test_an_exploration_stops_at_the_first_layer_with_a_witness() -> None:
    data, full = data_and_graph()
    target = fast(data, 10.6)
    hits = np.flatnonzero(target(0, full.states[:, 1:]))
    first = int(full.states[hits, 0].min())
    assert 0 < first < HORIZON
    stopped = explore(data, horizon_samples=HORIZON, stop_at=target)
    stopped.validate()
    assert not stopped.complete and full.complete
    assert int(stopped.states[:, 0].max()) == first
    assert layer_sets(stopped) == layer_sets(full)[:first + 1]
    assert stopped.n_states < full.n_states
    found = layered_search(data, target, horizon_samples=HORIZON)
    assert found.witness is not None and found.witness.samples == first and found.witness.search == "breadth-first"
    replay(data, found.witness, target)
    # a witness only at the horizon: the exploration is the whole one, complete
    late = explore(data, horizon_samples=HORIZON, stop_at=lambda k, rows: np.full(rows.shape[0], k == HORIZON))
    assert late.complete and late.n_states == full.n_states


def test_a_beam_keeps_the_models_states_and_choices_and_says_it_is_incomplete() -> None:
    data, full = data_and_graph()
    reference, moves = layer_sets(full), transitions(full)
    rng = np.random.default_rng(3)

    def beam(k: int, rows: np.ndarray) -> np.ndarray:
        return np.sort(rng.permutation(rows.shape[0])[:20])

    cut = explore(data, horizon_samples=HORIZON, beam=beam)
    cut.validate()
    assert not cut.complete
    sizes = np.bincount(cut.states[:, 0])
    assert sizes.max() <= 20 and sizes.size == HORIZON + 1
    assert all(layer <= ref for layer, ref in zip(layer_sets(cut), reference))
    assert transitions(cut) <= moves
    assert cut.reachable().all()  # every kept state is reached through kept choices
    wide = explore(data, horizon_samples=HORIZON, beam=lambda k, rows: np.arange(rows.shape[0]))
    assert wide.complete and np.array_equal(wide.states, full.states)
    assert np.array_equal(wide.choice_target, full.choice_target)


def test_a_path_to_a_state_follows_the_graphs_choices() -> None:
    _, full = data_and_graph()
    last = full.n_states - 1
    path = full.path_to(last)
    assert path[0] == full.initial and path[-1] == last and len(path) == HORIZON + 1
    for source, following in zip(path, path[1:]):
        assert following in full.choice_target[full.choices(source).start:full.choices(source).stop]


def test_random_runs_and_the_beam_find_witnesses_that_replay() -> None:
    data, full = data_and_graph()
    target = fast(data, 10.6)
    runs = random_runs(data, target, horizon_samples=HORIZON, runs=200, seed=1)
    assert runs.witness is not None and runs.witness.search == "random runs"
    replay(data, runs.witness, target)
    again = random_runs(data, target, horizon_samples=HORIZON, runs=200, seed=1)
    assert again.witness is not None and np.array_equal(again.witness.states, runs.witness.states)  # seeded
    beam = beam_search(data, target, horizon_samples=HORIZON, width=5, seed=1, score=lambda k, rows: -rows[:, 2])
    assert beam.witness is not None and beam.graph is not None and not beam.graph.complete
    replay(data, beam.witness, target)
    trace = witness_graph(data, beam.witness)
    trace.validate()
    assert trace.path_to(trace.n_states - 1) == list(range(trace.n_states))
    # an impossible target: nothing found, and only the complete exploration proves it
    never = fast(data, 11.5)
    assert not np.any(never(0, full.states[:, 1:]))
    assert random_runs(data, never, horizon_samples=HORIZON, runs=50, seed=1).witness is None
    narrow = beam_search(data, never, horizon_samples=HORIZON, width=5, seed=1)
    assert narrow.witness is None and not narrow.proves_absence
    wide = beam_search(data, never, horizon_samples=HORIZON, width=10**6, seed=1)
    assert wide.witness is None and wide.proves_absence


def test_a_run_that_stays_in_a_set_to_the_horizon() -> None:
    """E[] p's witness: through p, p at the horizon. Below 10.2 m/s throughout exists (brake)."""
    data, _ = data_and_graph()
    slow = lambda k, rows: rows[:, 2] < 10.2 * data.scale  # noqa: E731
    to_end = lambda k, rows: slow(k, rows) & (k == HORIZON)  # noqa: E731
    found = search(data, to_end, horizon_samples=HORIZON, seed=2, through=slow)
    assert found.witness is not None and found.witness.samples == HORIZON
    replay(data, found.witness, to_end, through=slow)
    assert (found.witness.states[:, 3] < 10.2 * data.scale).all()


def test_a_start_outside_the_set_to_stay_in_has_no_run_staying_in_it() -> None:
    """Regression: the beam never tested the start against ``through`` (explore's beam chooses among new layers):
    `E[] v < 10` from a start at 10 m/s found a run braking below 10 from the second sample on, and its replay
    then failed at sample 0 (ReplayMismatch: rac verify's internal error, losing the answers before it)."""
    data, _ = data_and_graph()
    below = lambda k, rows: rows[:, 2] < 10 * data.scale  # noqa: E731 (the start is at 10 m/s exactly)
    to_end = lambda k, rows: below(k, rows) & (k == HORIZON)  # noqa: E731
    assert not below(0, np.asarray([batch_model(data).native.initial_state()]))[0]
    beam = beam_search(data, to_end, horizon_samples=HORIZON, width=10**6, seed=1, through=below)
    assert beam.witness is None and not beam.proves_absence
    assert search(data, to_end, horizon_samples=HORIZON, seed=2, through=below).witness is None
    # from a start inside the set the same search still finds one (below 10.2 m/s: the test above)


def test_a_tampered_witness_does_not_replay() -> None:
    data, _ = data_and_graph()
    target = fast(data, 10.6)
    witness = random_runs(data, target, horizon_samples=HORIZON, runs=200, seed=1).witness
    assert witness is not None
    states = witness.states.copy()
    states[2, 1] += 1  # x of sample 2 off by one significand
    with pytest.raises(ReplayMismatch, match=r"^the witness found by random runs does not replay with the scalar "
                                             r"model .* at sample 2: the search has x=.*\(a bug in rac"):
        replay(data, dataclasses.replace(witness, states=states), target)
    with pytest.raises(ReplayMismatch, match="does not satisfy the target"):
        replay(data, witness, fast(data, 99.0))
    # a run through an unsafe state is a run of the model, not of the pruned model
    full = explore(data, horizon_samples=HORIZON)
    unsafe = int(np.flatnonzero(~full.labels["safe"] & (full.states[:, 0] < HORIZON))[0])
    after = full.states[int(full.choice_target[full.choices(unsafe).start])]
    at = int(after[0])
    one = lambda k, rows: (k == at) & (rows == after[1:]).all(axis=1)  # noqa: E731
    through = layered_search(data, one, horizon_samples=HORIZON).witness
    assert through is not None and through.samples == at
    replay(data, through, one)
    with pytest.raises(ReplayMismatch, match="passes through an unsafe state"):
        replay(data, through, one, prune_unsafe=True)


@pytest.mark.parametrize("name", sorted(TINY_SCENARIOS))
def test_the_cheap_search_agrees_with_the_exhaustive_answer(name: str, tmp_path: Path) -> None:
    """Qc on the pruned model (a safe run reaching the goal) and Qb (a run safe to the horizon), on every
    tiny scenario: found by the search iff Storm finds it on the complete graph; without a witness, the
    wide beam is the complete exploration and proves it; a narrow beam never does."""
    tiny = TINY_SCENARIOS[name]()
    data = tiny.model_data(tmp_path)
    horizon = tiny.settings.horizon_samples
    pruned = explore(data, horizon_samples=horizon, prune_unsafe=True)
    model = batch_model(data)

    def safe(k: int, rows: np.ndarray) -> np.ndarray:
        return ~model.collide(rows[:, :7], k) & ~model.offroad(rows[:, :7], k)

    def goal(k: int, rows: np.ndarray) -> np.ndarray:
        return safe(k, rows) & model.goal(rows[:, :7], k)

    def to_end(k: int, rows: np.ndarray) -> np.ndarray:
        return safe(k, rows) & (k == horizon)

    safe_goal = pruned.labels["safe"] & pruned.labels["goal"]
    found = storm.safe_reach(pruned, safe_goal)
    reach = found.until.holds
    stays = storm.decide(pruned, "E[]", "safe").holds
    # safe_reach reads the graph; Storm agrees (E<> on the graph, Pmax G safe for the horizon)
    labelled = dataclasses.replace(pruned, labels={**pruned.labels, "t": safe_goal})
    assert reach == storm.decide(labelled, "E<>", "t").holds
    values, _ = storm.check_formula(storm.to_mdp(pruned), 'Pmax=? [G "safe"]')
    assert found.to_horizon == bool(np.any(safe_goal & (values > 0.5) & pruned.reachable()))
    if found.until.trace is not None:
        assert found.until.trace[0] == pruned.initial and safe_goal[found.until.trace[-1]]
    with pytest.raises(ValueError, match="complete graph"):
        storm.safe_reach(dataclasses.replace(pruned, complete=False), safe_goal)
    assert (reach, stays) == (tiny.reaches_goal, tiny.stays_safe)
    for target, through, expected in ((goal, None, reach), (to_end, safe, stays)):
        found = search(data, target, horizon_samples=horizon, seed=5, prune_unsafe=True, through=through)
        assert (found.witness is not None) == expected
        if found.witness is not None:
            replay(data, found.witness, target, prune_unsafe=True, through=through)
        elif through is None:
            assert found.proves_absence  # tiny: the beam never had to cut
        narrow = search(data, target, horizon_samples=horizon, seed=5, prune_unsafe=True, through=through,
                        bounds=Bounds(runs=1, width=1))
        if narrow.proves_absence:  # only when a beam of one state is the whole exploration
            assert narrow.graph is not None and narrow.graph.n_states == pruned.n_states


def slow_clock(monkeypatch: pytest.MonkeyPatch, step: float) -> None:
    """A machine so slow that ``step`` seconds pass between two readings of the clock."""
    readings = itertools.count(0.0, step)
    monkeypatch.setattr(time, "perf_counter", lambda: next(readings))


def test_what_the_search_finds_does_not_depend_on_the_machines_speed(monkeypatch: pytest.MonkeyPatch) -> None:
    """The searches stopped at 20 s of wall clock: on a slow machine the same seed found no witness (then the
    layered search, or UNKNOWN beyond its budget) where a fast one found it. Their work budget (runs, width,
    states) decides now; the clock is only a safety net far beyond it."""
    data, _ = data_and_graph()
    bounds = Bounds(runs=30, width=40)
    targets = (fast(data, 10.6), fast(data, 11.5))  # one the beam finds, one nothing reaches
    quick = [search(data, target, horizon_samples=HORIZON, seed=3, bounds=bounds) for target in targets]
    slow_clock(monkeypatch, 15.0)  # 15 s between two checks: a dozen layers take 3 minutes
    slow = [search(data, target, horizon_samples=HORIZON, seed=3, bounds=bounds) for target in targets]
    assert quick[0].witness is not None and quick[1].witness is None
    for fast_found, slow_found in zip(quick, slow):
        assert not fast_found.timed_out and not slow_found.timed_out
        assert slow_found.states == fast_found.states
        assert (slow_found.witness is None) == (fast_found.witness is None)
        if fast_found.witness is not None and slow_found.witness is not None:
            assert slow_found.witness.search == fast_found.witness.search
            assert np.array_equal(slow_found.witness.states, fast_found.witness.states)
    # past the safety net the search stops, and says it was the clock
    slow_clock(monkeypatch, 2 * SAFETY_SECONDS)
    cut = search(data, targets[1], horizon_samples=HORIZON, seed=3, bounds=bounds)
    assert cut.witness is None and cut.timed_out and not cut.proves_absence
