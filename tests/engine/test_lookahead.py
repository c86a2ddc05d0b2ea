"""The runtime shield (rac.engine.lookahead) and the shield for every step (rac.engine.shield.StepShield)
against a brute force over all action sequences (issue 20, "a shield for every step of training").

The oracle (:func:`depths`) enumerates every action sequence of the next ``depth`` decisions with the
scalar model (rac.model.native, one state at a time, no search order, no early exit of the shield's
kind) and keeps, per first action, the most decisions some sequence survives: every sample safe
(no collision, on the road, under ``collision sticky`` no collision before either), every action
allowed by ``allow when``, a run stopping where ``allow when`` leaves nothing. The shield must allow
exactly the actions of the greatest depth found, and say which depth that is; at the exhaustive
shield's horizon its table must allow exactly the actions whose continuation reaches the horizon.
"""

from __future__ import annotations

import dataclasses
import functools
from pathlib import Path

import numpy as np
import pytest
from test_modelling_choices import ramp_file
from tiny_scenarios import avoidable_obstacle, goal_ahead, goal_behind_wall

from rac.compiler import compile_file
from rac.engine import shield as shields
from rac.engine.allow import ActionGuard, action_pairs
from rac.engine.explore import explore
from rac.engine.lookahead import Lookahead, LookaheadSettings
from rac.engine.storm import safety_shield
from rac.model import NativeModel, State
from rac.model.data import ModelData


# ---------------------------------------------------------------- the oracle
class Oracle:
    """Every action sequence, scalar: the most decisions each first action's best sequence survives."""

    def __init__(self, data: ModelData, horizon: int) -> None:
        self.data, self.horizon, self.every = data, horizon, data.decide_every
        self.native = NativeModel(data)
        self.guard = ActionGuard(data)
        self.pairs = [tuple(int(v) for v in pair) for pair in action_pairs(data)]

    def end(self, k: int) -> int:
        return min((k // self.every + 1) * self.every, self.horizon)

    def allowed(self, state: State, k: int) -> list[int]:
        if not self.guard.restricts:
            return list(range(len(self.pairs)))
        return np.flatnonzero(self.guard.masks(np.array([state], dtype=np.int32), k)[0]).tolist()

    def period(self, state: State, k: int, action: int, crashed: bool) -> tuple[State, bool, bool]:
        """The state after one decision period with ``action``, whether it was safe, and the collision flag."""
        jerk, turn = self.pairs[action]
        state = state._replace(jerk=jerk, turn=turn)
        safe = not (crashed and self.data.sticky)
        for sample in range(k + 1, self.end(k) + 1):
            state = self.native.sense(state)
            hit = self.native.collide(state, sample)
            crashed = crashed or hit
            safe = safe and not hit and not self.native.offroad(state, sample)
        return state, safe, crashed

    def best(self, state: State, k: int, remaining: int, crashed: bool) -> int:
        if remaining == 0 or k >= self.horizon:
            return remaining
        actions = self.allowed(state, k)
        if not actions:
            return remaining  # the run stops here
        found = 0
        for action in actions:
            after, safe, hit = self.period(state, k, action, crashed)
            if safe:
                found = max(found, 1 + self.best(after, self.end(k), remaining - 1, hit))
        return found

    def depths(self, state: State, k: int, depth: int, crashed: bool = False) -> tuple[np.ndarray, int]:
        """Per action, the most decisions its best sequence survives; and the decisions asked for."""
        target, sample = 0, k
        while sample < self.horizon and target < depth:
            sample, target = self.end(sample), target + 1
        out = np.zeros(len(self.pairs), dtype=np.int64)
        for action in self.allowed(state, k):
            after, safe, hit = self.period(state, k, action, crashed)
            if safe:
                out[action] = 1 + self.best(after, self.end(k), target - 1, hit)
        return out, target


def expected_mask(depths: np.ndarray) -> np.ndarray:
    best = depths.max()
    return depths == best if best > 0 else np.zeros(depths.size, dtype=bool)


def visited(data: ModelData, horizon: int, seed: int, runs: int = 6) -> list[tuple[int, State, bool]]:
    """Decision states of random runs (``(k, state, crashed)``): half of the actions drawn among those
    the runtime shield allows, so that the runs meet safe and doomed states alike."""
    rng = np.random.default_rng(seed)
    oracle = Oracle(data, horizon)
    shield = Lookahead(data, horizon, LookaheadSettings(depth=2, seconds=None))
    out = []
    for _ in range(runs):
        state, k = oracle.native.initial_state(), 0
        crashed = bool(oracle.native.collide(state, 0))
        while k < horizon:
            out.append((k, state, crashed))
            mask = shield.decide(np.array([k, *state]), crashed).mask
            allowed = oracle.allowed(state, k) or list(range(len(oracle.pairs)))
            if mask.any() and rng.random() < 0.5:
                action = int(rng.choice(np.flatnonzero(mask)))
            else:
                action = int(rng.choice(allowed))
            state, _, crashed = oracle.period(state, k, action, crashed)
            k = oracle.end(k)
    return out


@functools.cache
def scene(name: str, folder: str) -> tuple[ModelData, int]:
    """A tiny scene's model data and horizon (samples); ``sticky``: with ``collision sticky``;
    ``ramp``: the tiny ramp with CommonUppRoad's choices (``allow when`` among them)."""
    if name == "ramp":
        result = compile_file(ramp_file(Path(folder)))
        assert result.ok and result.model_data is not None and result.automaton is not None
        return result.model_data, result.automaton.steps
    builders = {"avoidable": avoidable_obstacle, "wall": goal_behind_wall, "ahead": goal_ahead,
                "sticky": avoidable_obstacle}
    tiny = builders[name]()
    data = tiny.model_data(folder)
    if name == "sticky":
        data = dataclasses.replace(data, sticky=True)
    return data, tiny.settings.horizon_samples


# ---------------------------------------------------------------- the runtime shield
@pytest.mark.parametrize("name", ["avoidable", "wall", "ahead", "sticky", "ramp"])
def test_the_runtime_shield_allows_what_the_brute_force_allows(name: str, tmp_path_factory: pytest.TempPathFactory
                                                               ) -> None:
    data, horizon = scene(name, str(tmp_path_factory.mktemp(name)))
    oracle = Oracle(data, horizon)
    states = visited(data, horizon, seed=len(name))
    kinds = set()
    for depth in (1, 2, 3, 4):
        shield = Lookahead(data, horizon, LookaheadSettings(depth=depth, seconds=None))
        for k, state, crashed in states[:: 1 if depth < 4 else 3]:
            want, target = oracle.depths(state, k, depth, crashed)
            got = shield.decide(np.array([k, *state]), crashed)
            assert got.complete and got.target == target
            # the depth per action is a lower bound (the search stops below an action at its first
            # full continuation), exact where it matters: the best, and which actions reach it
            assert got.depth == want.max(), (k, state, depth)
            assert got.mask.tolist() == expected_mask(want).tolist(), (k, state, depth)
            assert (got.depths <= want).all() and (got.depths[got.mask] == want.max()).all()
            assert not got.mask.any() or got.until == shield.sample_after(k, got.depth)
            kinds.add("full" if want.max() == target else "short" if want.max() else "none")
    assert "full" in kinds and (name == "ramp" or "none" in kinds)  # the runs met safe and doomed states


def test_a_doomed_state_allows_the_actions_that_last_longest(tmp_path: Path) -> None:
    """Where no action survives the lookahead, the mask is not empty while some action survives a
    decision: it allows those that stay safe longest and says how long (a depth below the target)."""
    data, horizon = scene("wall", str(tmp_path))  # at speed before the wall: a crash some decisions on
    oracle = Oracle(data, horizon)
    shield = Lookahead(data, horizon, LookaheadSettings(depth=4, seconds=None))
    short = []
    for k, state, crashed in visited(data, horizon, seed=0, runs=12):
        got = shield.decide(np.array([k, *state]), crashed)
        if 0 < got.depth < got.target:
            short.append(got)
            want, _ = oracle.depths(state, k, 4, crashed)
            assert got.mask.tolist() == expected_mask(want).tolist()
    assert short, "no doomed state with a partial continuation was met"


def test_the_time_budget_reports_itself(tmp_path: Path) -> None:
    """A search cut short says so (complete False), and what it does allow is still proved: each
    allowed action has a safe continuation of the depth it reports."""
    data, horizon = scene("ahead", str(tmp_path))
    oracle = Oracle(data, horizon)
    start = oracle.native.initial_state()
    want, target = oracle.depths(start, 0, 4)
    assert target == 4 and want.max() == 4
    # the smallest budgets: one node (the first decision period, always searched), a nanosecond
    for settings in (LookaheadSettings(depth=4, seconds=None, nodes=1), LookaheadSettings(depth=4, seconds=1e-9)):
        got = Lookahead(data, horizon, settings).decide(np.array([0, *start]))
        assert got.timed_out and not got.complete
        assert got.depth >= 1 and (want[got.mask] >= got.depth).all()
    full = Lookahead(data, horizon, LookaheadSettings(depth=4, seconds=None)).decide(np.array([0, *start]))
    assert full.complete and full.depth == 4 and full.mask.tolist() == expected_mask(want).tolist()
    # a node budget between the two: proved depths only, the mask within the complete one's
    partial = Lookahead(data, horizon, LookaheadSettings(depth=4, seconds=None, nodes=2)).decide(np.array([0, *start]))
    assert (want[partial.mask] >= partial.depth).all()


def test_a_held_continuation_stops_at_the_deadline(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """The fixed continuations (an action held to the horizon) checked the time only between layers:
    `rac verify --horizon 100000` on an on-demand shield held one for 5,000 decisions past its 20 s.
    Each clock reading here moves time on by a second, so the deadline passes inside the held run:
    the search must say it was cut short, and what it allows stays proved."""
    data, horizon = scene("ahead", str(tmp_path))
    oracle = Oracle(data, horizon)
    start = oracle.native.initial_state()
    want, _ = oracle.depths(start, 0, 4)
    clock = iter(range(10**6))
    monkeypatch.setattr("rac.engine.lookahead.time.perf_counter", lambda: float(next(clock)))
    got = Lookahead(data, horizon, LookaheadSettings(depth=4, seconds=2.5)).decide(np.array([0, *start]))
    assert not got.complete and got.depth < 4
    assert got.depth >= 1 and (want[got.mask] >= got.depth).all()


def test_the_memory_limit_stops_the_search_before_it_allocates_past_it(tmp_path: Path,
                                                                      monkeypatch: pytest.MonkeyPatch) -> None:
    """Qd's search from the start held about 1 GB at its work budget's worst (a layer of 45 actions' millions
    of successors), checked against no memory limit. With ``max_bytes`` the layers it merges stay within the
    limit by the estimate (:data:`SUCCESSOR_BYTES` a successor), it says that the limit stopped it, and what
    it allows is still proved; a limit it stays within changes nothing."""
    from rac.engine import lookahead

    data, horizon = scene("ahead", str(tmp_path))
    oracle = Oracle(data, horizon)
    start = np.array([0, *oracle.native.initial_state()])
    want, _ = oracle.depths(oracle.native.initial_state(), 0, 4)
    # every layer expanded (the fixed continuations would carry the actions at once)
    monkeypatch.setattr(Lookahead, "_fixed", lambda self, states, k, held, remaining: np.zeros(states.shape[0],
                                                                                             dtype=np.int64))
    merged: list[int] = []
    distinct = lookahead._distinct_rows
    monkeypatch.setattr(lookahead, "_distinct_rows", lambda parts: merged.append(sum(p.shape[0] for p in parts))
                        or distinct(parts))
    free = Lookahead(data, horizon, LookaheadSettings(depth=4, seconds=None, nodes=None)).decide(start)
    assert free.complete and not free.memory and max(merged) > 100
    limit = max(merged) * lookahead.SUCCESSOR_BYTES // 2  # half the largest layer's successors
    merged.clear()
    cut = Lookahead(data, horizon, LookaheadSettings(depth=4, seconds=None, nodes=None, max_bytes=limit)).decide(start)
    assert cut.memory and not cut.complete and not cut.clock
    assert max(merged) * lookahead.SUCCESSOR_BYTES <= limit
    assert cut.depth >= 1 and (want[cut.mask] >= cut.depth).all()
    roomy = Lookahead(data, horizon, LookaheadSettings(depth=4, seconds=None, nodes=None, max_bytes=10**9)).decide
    assert (answer := roomy(start)).complete and not answer.memory and (answer.depths == free.depths).all()


def test_settings_are_checked() -> None:
    for bad in ({"depth": 0}, {"depth": 1.5}, {"seconds": -1.0}, {"nodes": -1}, {"nodes": 2.5}, {"depth": True},
                {"seconds": "1"}, {"seconds": float("nan")}):
        with pytest.raises(ValueError):
            LookaheadSettings(**bad)  # type: ignore[arg-type]
    # a budget of 0 could not be kept (the first decision period is always searched) and reads like "no
    # limit": nodes=0 was accepted and gave every state a mask one decision deep
    with pytest.raises(ValueError, match=r"nodes must be a whole number >= 1 .* or None \(no budget\), not 0"):
        LookaheadSettings(nodes=0)
    with pytest.raises(ValueError, match=r"seconds must be a time > 0 .* or None \(no limit\), not 0.0"):
        LookaheadSettings(seconds=0.0)
    # numpy's integers (a depth swept over np.arange): depth=np.int64(6) was refused as no whole number
    settings = LookaheadSettings(depth=np.int64(6), nodes=np.int32(1000))  # type: ignore[arg-type]
    assert settings == LookaheadSettings(depth=6, nodes=1000) and type(settings.depth) is type(settings.nodes) is int
    for bad_bytes in (0, -1, 2.5, True):
        with pytest.raises(ValueError, match="max_bytes must be a whole number of bytes >= 1 or None"):
            LookaheadSettings(max_bytes=bad_bytes)  # type: ignore[arg-type]


# ---------------------------------------------------------------- the exhaustive shield at its horizon
@pytest.mark.parametrize("name", ["avoidable", "wall", "ahead", "ramp"])
def test_exhaustive_masks_agree_with_brute_force_up_to_their_horizon(name: str,
                                                                    tmp_path_factory: pytest.TempPathFactory) -> None:
    """The table computed to sample ``h`` allows exactly the actions with a safe continuation to ``h``,
    at every decision state up to its last one (the boundary, one decision before ``h``); past it the
    step shield hands out the runtime shield's masks, which agree with the brute force to the run's end."""
    data, horizon = scene(name, str(tmp_path_factory.mktemp(name)))
    every = data.decide_every
    cut = max(every, (horizon // 2) // every * every)  # the table's horizon: half the run, on a decision
    table = shields.table(safety_shield(explore(data, horizon_samples=cut, prune_unsafe=True), "safe"),
                          n_actions=len(action_pairs(data)))
    assert table.horizon == cut
    near, far = Oracle(data, cut), Oracle(data, horizon)
    step = shields.StepShield(data, horizon, table=table, lookahead=LookaheadSettings(depth=1, seconds=None))
    seen = {"exhaustive": 0, "lookahead": 0}
    for k, state, crashed in visited(data, horizon, seed=7, runs=8):
        key = np.array([k, *state])
        if k < cut and table.knows(key):
            want, _ = near.depths(state, k, horizon)  # every decision up to the table's horizon
            assert table.mask(key).tolist() == (want == near.depths(state, k, horizon)[1]).tolist(), (k, state)
        answer = step.decide(key, crashed)
        assert answer.mask.any()
        if answer.kind == "exhaustive":
            seen["exhaustive"] += 1
            assert k < cut and answer.until == cut
        elif answer.kind == "lookahead":
            seen["lookahead"] += 1
            want, _ = far.depths(state, k, 1, crashed)
            assert answer.mask.tolist() == expected_mask(want).tolist() and answer.guarantee == "lookahead 1"
            assert k >= cut or not table.knows(key) or not table.mask(key).any()
    assert seen["exhaustive"] and seen["lookahead"]


def test_step_shield_takes_the_table_it_can_have(tmp_path: Path) -> None:
    """``step_shield``: the exhaustive table when its exploration fits the budget, else none and the
    reason; the runtime shield covers every step either way, and ScenarioEnv takes the result."""
    data, horizon = scene("ahead", str(tmp_path))
    whole = shields.step_shield(data, horizon)
    assert whole.table is not None and whole.table.horizon == horizon and whole.reason is None
    start = np.array([0, data.ego_x, data.ego_y, data.ego_v, data.ego_acc, data.ego_head, 0, 0])
    assert whole.decide(start).guarantee == "exhaustive"
    none = shields.step_shield(data, horizon, max_states=10)
    assert none.table is None and none.reason is not None and "could not be computed" in none.reason
    assert none.decide(start).kind == "lookahead"
    assert shields.step_shield(data, horizon, table_horizon=0).table is None
