"""Monte Carlo simulation (rac.engine.simulate) and the exact probability it estimates
(rac.engine.storm.uniform_reach_probability).

The sensed states must be a scalar NativeModel replay of the recorded actions, bit for bit; the
ground truth must be the emitted Dynamics ODEs; and on a small model the SMC interval must cover
the probability Storm computes exactly under uniform choices.
"""

from __future__ import annotations

import math
from dataclasses import replace
from fractions import Fraction as F
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from test_explore import tiny_data
from test_model_native import crossing_scenario, make_spec, straight_scenario

from rac.engine import shield as shield_file
from rac.engine.explore import action_pairs, explore
from rac.engine.graph import ExploredGraph
from rac.engine.simulate import Runs, event_sampler, label_runs, simulate
from rac.engine.stats import estimate_probability, estimate_probability_fixed
from rac.engine.storm import safety_shield, uniform_reach_probability
from rac.model import ModelData, ModelRangeError, NativeModel, State, build_model_data
from rac.model.commonroad import EgoStart


def crossing_data() -> ModelData:
    return build_model_data(crossing_scenario(), make_spec(4, granularity=F(1, 4)))


def straight_data(exponent: int = 3, **ego: float) -> ModelData:
    start = straight_scenario().ego
    return build_model_data(replace(straight_scenario(), ego=replace(start, **ego)), make_spec(exponent))


def behind_obstacle() -> ModelData:
    """The ego 16 m behind where the obstacle appears (sample 10), 9 actions, decisions every 4
    samples: within 14 samples about half of the uniform runs collide."""
    return tiny_data(replace(straight_scenario(), ego=EgoStart(14.0, 1.75, 0.0, 10.0)), F(2, 5))


def only(data: ModelData, jerk: float, turn: float):
    """A policy allowing the single action (jerk, turn) (reals)."""
    pairs = action_pairs(data)
    mask = (pairs[:, 0] == round(jerk * data.scale)) & (pairs[:, 1] == round(turn * data.scale))
    assert mask.sum() == 1
    return lambda k, states: np.tile(mask, (states.shape[0], 1))


def replay(data: ModelData, actions: np.ndarray) -> list[tuple[int, ...]]:
    """The states of one run, replayed with the scalar NativeModel."""
    model = NativeModel(data)
    pairs = action_pairs(data).tolist()
    state = model.initial_state()
    out = [tuple(state)]
    for action in actions.tolist():
        if action >= 0:
            state = state._replace(jerk=pairs[action][0], turn=pairs[action][1])
        state = model.sense(state)
        out.append(tuple(state))
    return out


# ---------------------------------------------------------------- the runs
def test_runs_shape_reproducibility_and_decisions() -> None:
    data = crossing_data()
    calls: list[tuple[int, int]] = []
    runs = simulate(data, runs=40, horizon_samples=23, seed=7, progress=lambda *a: calls.append(a))
    assert isinstance(runs, Runs) and (runs.n_runs, runs.horizon, runs.seed) == (40, 23, 7)
    assert runs.states.shape == (40, 24, 7) and runs.states.dtype == np.int32
    assert runs.truth.shape == (40, 24, 5) and runs.truth.dtype == np.float64
    assert runs.actions.shape == (40, 23) and runs.actions.dtype == np.int64
    assert runs.left_policy.shape == (40,) and not runs.left_policy.any()
    assert calls == [(k, 23) for k in range(1, 24)]
    decide = np.arange(23) % data.decide_every == 0
    assert (runs.actions[:, decide] >= 0).all() and (runs.actions[:, decide] < len(action_pairs(data))).all()
    assert (runs.actions[:, ~decide] == -1).all()
    assert runs.times == pytest.approx(np.arange(24) * 0.1)
    assert np.array_equal(runs.sensed_real(), runs.states / 10_000.0)
    assert not runs.states.flags.writeable
    same = simulate(data, runs=40, horizon_samples=23, seed=7)
    for name in ("states", "truth", "actions", "left_policy"):
        assert np.array_equal(getattr(runs, name), getattr(same, name))
    other = simulate(data, runs=40, horizon_samples=23, seed=8)
    assert not np.array_equal(runs.actions, other.actions)
    fresh = simulate(data, runs=5, horizon_samples=6)  # a drawn seed is recorded and reproduces the runs
    assert np.array_equal(simulate(data, runs=5, horizon_samples=6, seed=fresh.seed).states, fresh.states)


def test_runs_without_the_truth_are_the_same_runs() -> None:
    """`truth=False` (the statistical queries whose expressions read the sensed state only) skips the ground
    truth's RK4 integration, nine tenths of the time: E[<=4;1000000](max: v) took 3 min 46 s, now 7 s. The runs
    (sensed states, actions, flags) are those with the truth; the truth is NaN, never a value that looks real."""
    data = crossing_data()
    whole = simulate(data, runs=40, horizon_samples=23, seed=7)
    sensed = simulate(data, runs=40, horizon_samples=23, seed=7, truth=False)
    for name in ("states", "actions", "left_policy"):
        assert np.array_equal(getattr(whole, name), getattr(sensed, name))
    assert sensed.truth.shape == whole.truth.shape and np.isnan(sensed.truth).all()
    assert not np.isnan(whole.truth).any()


@settings(max_examples=5, deadline=None)
@given(seed=st.integers(0, 2**63 - 1))
def test_states_are_a_native_replay_of_the_actions(seed: int) -> None:
    data = crossing_data()
    runs = simulate(data, runs=12, horizon_samples=25, seed=seed, truth_substeps=1)
    for n in range(runs.n_runs):
        assert [tuple(row) for row in runs.states[n].tolist()] == replay(data, runs.actions[n])
    # the jerk and turn chosen at k show in the state at k + 1 and are kept until the next decision
    pairs = action_pairs(data)
    for k in range(0, 25, data.decide_every):
        assert np.array_equal(runs.states[:, k + 1, 5:7], pairs[runs.actions[:, k]])


def test_actions_are_uniform_over_the_grid() -> None:
    data = tiny_data()
    runs = simulate(data, runs=9000, horizon_samples=1, seed=3, truth_substeps=1)
    counts = np.bincount(runs.actions[:, 0], minlength=9)
    assert counts.sum() == 9000 and (np.abs(counts - 1000) < 5 * math.sqrt(1000 * 8 / 9)).all()


def test_policy_is_respected_and_a_run_without_choices_is_flagged() -> None:
    data = crossing_data()
    n_pairs = len(action_pairs(data))
    seen: list[tuple[int, np.ndarray, np.ndarray]] = []

    def policy(k: int, states: np.ndarray) -> np.ndarray:
        # state-dependent: an even or odd action set by the sign of y, three actions at k = 5,
        # nothing at all for runs whose x significand is odd at k = 10
        parity = (states[:, 1] > 0)[:, None] == (np.arange(n_pairs) % 2 == 0)[None, :]
        if k == 5:
            parity = np.tile(np.isin(np.arange(n_pairs), [2, 40, 77]), (states.shape[0], 1))
        if k == 10:
            parity = parity & (states[:, 0] % 2 == 0)[:, None]
        seen.append((k, states.copy(), parity))
        return parity

    runs = simulate(data, runs=300, horizon_samples=16, seed=2, policy=policy, truth_substeps=1)
    assert [k for k, _, _ in seen] == [0, 5, 10, 15]
    empty_at_10 = ~seen[2][2].any(axis=1)
    assert empty_at_10.any() and not empty_at_10.all()
    assert np.array_equal(runs.left_policy, empty_at_10)
    for k, states, allowed in seen:
        assert np.array_equal(states, runs.states[:, k])
        chosen = runs.actions[:, k]
        ok = allowed[np.arange(300), chosen]
        assert ok[~empty_at_10].all() if k == 10 else ok.all()
    assert set(runs.actions[:, 5].tolist()) == {2, 40, 77}
    assert len(set(runs.actions[empty_at_10, 10].tolist())) > 2  # any action once the policy gives none


def test_a_policy_of_the_wrong_shape_is_an_error() -> None:
    data = tiny_data()
    with pytest.raises(ValueError, match="policy"):
        simulate(data, runs=3, horizon_samples=2, policy=lambda k, s: np.ones((s.shape[0], 4), dtype=bool))
    with pytest.raises(ValueError, match="policy"):
        simulate(data, runs=3, horizon_samples=2, policy=lambda k, s: np.ones((s.shape[0], 9), dtype=int))


@pytest.mark.parametrize("kwargs", [{"runs": 0}, {"runs": 2.0}, {"runs": 2, "horizon_samples": -1},
                                    {"runs": 2, "truth_substeps": 0}])
def test_bad_arguments(kwargs: dict) -> None:
    with pytest.raises(ValueError):
        simulate(tiny_data(), **{"horizon_samples": 3, **kwargs})


def test_a_run_leaving_int32_stops_there_and_the_others_go_on() -> None:
    """With `stop_at_overflow`, each run stops at the first sample whose sensed state leaves int32 (x past
    214.7 m at exponent 7, reached at different samples by different runs): its states up to there are the
    native replay, the native model raises at that sample, no action is drawn for it afterwards and the
    policy is asked about live runs only; a run that never leaves int32 is a whole replay. Without it the
    batch raises, as every other caller (rac simulate, render) wants."""
    data = straight_data(7, x=185.0)
    with pytest.raises(ModelRangeError):
        simulate(data, runs=60, horizon_samples=40, seed=3, truth_substeps=1)
    asked: dict[int, int] = {}

    def everything(k: int, states: np.ndarray) -> np.ndarray:
        asked[k] = states.shape[0]
        return np.ones((states.shape[0], len(action_pairs(data))), dtype=bool)

    runs = simulate(data, runs=60, horizon_samples=40, seed=3, truth_substeps=1, policy=everything,
                    stop_at_overflow=True)
    assert runs.overflow is not None and not runs.left_policy.any()
    assert len(set(runs.overflow.tolist())) > 3 and (runs.overflow == 41).any()  # some runs never leave it
    assert sorted(runs.overflow_errors) == np.flatnonzero(runs.overflow <= 40).tolist()
    assert asked == {k: int((runs.overflow > k).sum()) for k in range(0, 40, data.decide_every)}
    model, pairs = NativeModel(data), action_pairs(data).tolist()
    for n in range(runs.n_runs):
        stop = int(runs.overflow[n])
        assert [tuple(row) for row in runs.states[n, :stop].tolist()] == replay(data, runs.actions[n, :stop - 1])
        assert (runs.actions[n, stop:] == -1).all()
        if stop <= 40:
            state = State(*runs.states[n, stop - 1].tolist())
            action = int(runs.actions[n, stop - 1])
            if action >= 0:
                state = state._replace(jerk=pairs[action][0], turn=pairs[action][1])
            with pytest.raises(ModelRangeError) as raised:
                model.sense(state)
            assert str(raised.value) == str(runs.overflow_errors[n])


def test_horizon_defaults_to_the_goal_interval() -> None:
    data = tiny_data()
    assert simulate(data, runs=2, seed=0, truth_substeps=1).horizon == data.goal_high


# ---------------------------------------------------------------- the ground truth
def test_truth_is_exactly_linear_at_constant_speed_and_heading() -> None:
    data = straight_data(heading=0.3)
    runs = simulate(data, runs=3, horizon_samples=30, seed=1, policy=only(data, 0, 0))
    t = runs.times
    x0, y0, v0, h0 = (data.ego_x / 1000, data.ego_y / 1000, data.ego_v / 1000, data.ego_head / 1000)
    assert h0 == 0.3 and v0 == 10.0
    for truth in runs.truth:
        assert truth[:, 0] == pytest.approx(x0 + v0 * t * math.cos(h0), abs=1e-9)
        assert truth[:, 1] == pytest.approx(y0 + v0 * t * math.sin(h0), abs=1e-9)
        assert np.array_equal(truth[:, 2:], np.tile([v0, 0.0, h0], (31, 1)))


def test_truth_saturates_like_the_sensed_state() -> None:
    """Braking hard for 5 s from 10 m/s: the acceleration falls as -2t until it reaches -MA = -3
    (t = 1.5 s), the speed then falls linearly to VMIN = 0 (t = 1.5 + 7.75 / 3 s) and stays there:
    the truth stops instead of reversing (the emitted Dynamics saturates its rates the same way)."""
    data = straight_data()
    runs = simulate(data, runs=1, horizon_samples=50, seed=1, policy=only(data, -2, 0))
    t = runs.times
    truth, sensed = runs.truth[0], runs.sensed_real()[0]
    t_stop = 1.5 + 7.75 / 3
    acc = np.where(t < 1.5, -2 * t, np.where(t < t_stop, -3.0, -3.0))
    v = np.where(t < 1.5, 10 - t**2, np.maximum(7.75 - 3 * (t - 1.5), 0.0))
    x_at_1_5 = 10 + 10 * 1.5 - 1.5**3 / 3
    x_stop = x_at_1_5 + 7.75**2 / 6
    x = np.where(t < 1.5, 10 + 10 * t - t**3 / 3,
                 np.where(t < t_stop, x_at_1_5 + 7.75 * (t - 1.5) - 1.5 * (t - 1.5) ** 2, x_stop))
    assert truth[:, 3] == pytest.approx(acc, abs=1e-6)
    assert truth[:, 2] == pytest.approx(v, abs=1e-5)
    assert truth[:, 0] == pytest.approx(x, abs=1e-5)
    assert sensed[-1, 3] == -3.0 and sensed[-1, 2] == 0.0
    assert truth[-1, 2] == 0.0 and truth[-1, 3] == -3.0


def test_truth_converges_with_finer_substeps() -> None:
    data = crossing_data()
    runs = simulate(data, runs=50, horizon_samples=40, seed=4, truth_substeps=100)
    finer = simulate(data, runs=50, horizon_samples=40, seed=4, truth_substeps=400)
    coarse = simulate(data, runs=50, horizon_samples=40, seed=4, truth_substeps=1)
    assert np.array_equal(runs.states, finer.states)  # the draws do not depend on the integrator
    # RK4 is O(h^4) between saturation switches; a switch inside a step costs O(h^2) once, so the
    # agreement is sub-millimetre rather than machine precision.
    assert np.abs(runs.truth - finer.truth).max() < 5e-4
    assert np.abs(coarse.truth - finer.truth).max() > 5e-3  # the comparison can tell a coarse step apart
    assert (runs.truth[:, :, 4] != runs.truth[:, :1, 4]).any()  # the runs do turn


def test_a_coarse_exponent_drifts_further_from_the_truth() -> None:
    """The paper's pre-analysis (Qa): truncation to significands lags the sensed state behind the
    truth by up to one significand per period, so exponent 1 drifts far more than exponent 4."""
    drift = {}
    for exponent in (1, 4):
        data = straight_data(exponent)
        runs = simulate(data, runs=200, horizon_samples=10, seed=5)
        drift[exponent] = np.abs(runs.truth[:, -1, 0] - runs.sensed_real()[:, -1, 0]).mean()
    assert drift[1] > 10 * drift[4]
    assert drift[1] > 0.1  # decimetres at scale 10 ...
    assert drift[4] < 0.05  # ... against the sense() integrator's own millimetres at scale 10^4


# ---------------------------------------------------------------- labels and the exact probability
def test_labels_equal_native() -> None:
    data = behind_obstacle()
    runs = simulate(data, runs=30, horizon_samples=14, seed=6, truth_substeps=1)
    model = NativeModel(data)
    labels = {name: label_runs(data, runs, name) for name in ("collide", "offroad", "goal", "safe")}
    for n in range(30):
        for k in range(15):
            state = State(*map(int, runs.states[n, k]))
            collide, offroad = model.collide(state, k), model.offroad(state)
            assert (labels["collide"][n, k], labels["offroad"][n, k], labels["goal"][n, k], labels["safe"][n, k]) \
                == (collide, offroad, model.goal(state, k), not collide and not offroad)
    assert labels["collide"].any() and labels["safe"].any()
    with pytest.raises(ValueError, match="label"):
        label_runs(data, runs, "crash")


def reference_uniform_reach(graph: ExploredGraph, label: str) -> float:
    """Exact backward recursion (Fractions) over the acyclic explored graph, latest samples first."""
    p: list[F] = [F(0)] * graph.n_states
    for state in sorted(range(graph.n_states), key=lambda s: -int(graph.states[s, 0])):
        if graph.labels[label][state]:
            p[state] = F(1)
        elif len(graph.choices(state)):
            choices = graph.choices(state)
            p[state] = sum((p[int(graph.choice_target[c])] for c in choices), F(0)) / len(choices)
    return float(p[graph.initial])


def test_uniform_reach_probability_on_a_hand_made_graph() -> None:
    # 0 -> {1, 1, 2} (two choices share a target), 1 -> {3, 4}, 2 -> 3; 3 and 4 terminal; "hit" at 4
    graph = ExploredGraph(states=np.arange(5, dtype=np.int32)[:, None], columns=("k",),
                          choice_offsets=np.array([0, 3, 5, 6, 6, 6]), choice_action=np.array([0, 1, 2, 0, 1, -1]),
                          choice_target=np.array([1, 1, 2, 3, 4, 3]),
                          labels={"hit": np.array([False, False, False, False, True])})
    graph.validate()
    assert uniform_reach_probability(graph, "hit") == pytest.approx(1 / 3, abs=1e-9)  # 2/3 * 1/2
    with pytest.raises(KeyError):
        uniform_reach_probability(graph, "miss")


def test_smc_interval_covers_the_exact_probability() -> None:
    data = behind_obstacle()
    graph = explore(data, horizon_samples=14)
    exact = uniform_reach_probability(graph, "collide")
    assert exact == pytest.approx(reference_uniform_reach(graph, "collide"), abs=1e-6)
    assert 0.2 < exact < 0.8
    sample = event_sampler(data, lambda runs: label_runs(data, runs, "collide").any(axis=1), horizon_samples=14,
                           seed=12, truth_substeps=1)
    estimate = estimate_probability(sample, epsilon=0.02, batch=1000)
    assert estimate.converged and estimate.half_width <= 0.02
    assert estimate.lo <= exact <= estimate.hi
    # a different event on the same runs' model: off the road
    off = uniform_reach_probability(graph, "offroad")
    assert 0.1 < off < 0.9
    sample = event_sampler(data, lambda runs: label_runs(data, runs, "offroad").any(axis=1), horizon_samples=14,
                           seed=13, truth_substeps=1)
    fixed = estimate_probability_fixed(sample, 3000, batch=1000)
    assert fixed.lo <= off <= fixed.hi


def test_runs_under_the_safety_shield_stay_safe(tmp_path: Path) -> None:
    data = behind_obstacle()
    shield = safety_shield(explore(data, horizon_samples=14, prune_unsafe=True), "safe")
    assert shield.shield_exists
    table = shield_file.load(shield_file.save(shield, tmp_path / "safe.npz", n_actions=9), unseen="error")

    def policy(k: int, states: np.ndarray) -> np.ndarray:
        return np.stack([table.mask((k, *row)) for row in states.tolist()])

    runs = simulate(data, runs=300, horizon_samples=14, seed=9, policy=policy, truth_substeps=1)
    assert not runs.left_policy.any()
    assert label_runs(data, runs, "safe").all()
    unshielded = simulate(data, runs=300, horizon_samples=14, seed=9, truth_substeps=1)
    assert not label_runs(data, unshielded, "safe").all()
