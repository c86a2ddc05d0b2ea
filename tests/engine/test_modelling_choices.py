"""The model block's modelling choices (issue 11): `dynamics increments`, `allow when`, the
ego's start (`start_*`) and `offroad_from`, in the checker, the engine and the UPPAAL target alike.

The C side of `dynamics increments` and `offroad_from` is in tests/targets/test_model_c.py (the emitted
sense_state() and offroad() against rac.model.native, bit for bit)."""

from __future__ import annotations

import json
import math
from dataclasses import replace
from fractions import Fraction as F
from pathlib import Path

import numpy as np
import pytest
from engine_files import safety_source
from test_explore import random_states
from test_model_native import crossing_scenario, make_spec, rectangle, straight_scenario
from test_utap import compile_cli
from tiny_scenarios import ramp
from utap import Utap

from rac.cli.main import main
from rac.compiler import compile_file
from rac.engine.allow import ActionGuard, action_pairs
from rac.engine.explore import explore
from rac.engine.product import explore_product
from rac.engine.simulate import simulate
from rac.ir import Action
from rac.model import NativeModel, State, build_model_data
from rac.model.batch import BatchModel
from rac.model.commonroad import EgoStart, Goal, Obstacle, Scenario, Waypoint

#: The tiny ramp's model block before the choices under test (:func:`ramp_file` adds them).
RAMP_MODEL = """\
scenario "ramp.xml"
exponent 2
decide_period 0.1
granularity 1
width 1
max_speed 40
{settings}
action jerk in [0, 0] step 1
action turn in [-1, 1] step 1
bind close = mindist() < 2
"""
RAMP_QUERIES = {"Qd": "strategy safe = control: A[] !collide() && !offroad()", "Reach": "E<> goal()"}


#: CommonUppRoad's ZAM_Ramp choices on the tiny ramp: constant speed, a yaw step of 0.1 rad per
#: 0.1 s, turning allowed only while the next heading stays within 0.2 rad and the ego on the road.
CHOICES = """\
        dynamics increments
        start_speed 30
        start_heading 0.05
        offroad_from 1
        allow when turn == 0 || (fabs(head) <= 0.2 && !offroad())"""


def ramp_file(folder: Path, settings: str = CHOICES) -> Path:
    (folder / "ramp.xml").write_bytes(ramp())
    source = folder / "ramp.ra"
    source.write_text(safety_source("Ramp", 1, RAMP_MODEL.format(settings=settings), RAMP_QUERIES), encoding="utf-8")
    return source


# ---------------------------------------------------------------- the checker
def test_the_choices_reach_the_model_data(tmp_path: Path) -> None:
    result = compile_file(ramp_file(tmp_path))
    assert result.ok, result.diagnostics
    spec, data = result.automaton.model, result.model_data
    assert spec.dynamics == "increments" and spec.offroad_from == 1 and spec.allow is not None
    assert (spec.start_speed, spec.start_heading, spec.start_x) == (F(30), F(1, 20), None)
    # the start: speed and heading from the settings, the position from the planning problem
    assert (data.ego_x, data.ego_y, data.ego_v, data.ego_head) == (0, 175, 3000, 5)
    assert data.increments and data.offroad_from == 1 and data.allow is spec.allow


@pytest.mark.parametrize(("settings", "code", "excerpt"), [
    ("        dynamics euler", "E0702", "`dynamics` must be one of the words `integrated`, `increments`"),
    ("        allow when prev(x) < x", "E0717", "cannot read `prev(...)`"),
    ("        allow when head + 1", "E0717", "`allow when` needs a condition"),
    ("        offroad_from 0.5", "E0702", "`offroad_from` must be a whole number"),
    ("        start_speed -3", "E0702", "`start_speed` must be a number >= 0"),
    ("        dynamic increments", "E0701", "did you mean `dynamics`?"),
    ("        allow when true\n        allow when false", "E0102", "`allow when` is written twice"),
])
def test_a_wrong_choice_is_an_error_at_its_place(tmp_path: Path, capsys: pytest.CaptureFixture[str],
                                                 settings: str, code: str, excerpt: str) -> None:
    source = ramp_file(tmp_path, settings)
    assert main(["check", "--format", "json", str(source)]) == 1
    found = json.loads(capsys.readouterr().out)[0]
    diagnostics = [d for d in found["diagnostics"] if d["code"] == code]
    assert diagnostics, found
    text = json.dumps(diagnostics)
    assert excerpt in text
    assert diagnostics[0]["span"]["line"] > 12  # in the model block, at the item


def test_a_start_off_the_road_is_not_reported_when_the_start_is_not_checked(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    source = ramp_file(tmp_path, "        start_speed 30")  # the ramp's ego starts half before the road
    main(["check", str(source)])
    assert "W0716" in capsys.readouterr().out
    source = ramp_file(tmp_path, "        start_speed 30\n        offroad_from 1")
    main(["check", str(source)])
    assert "W0716" not in capsys.readouterr().out


@pytest.mark.parametrize(("speed", "offroad_from", "warned"), [(0, 1, True), (10, 1, True), (10, 3, False),
                                                                (30, 1, False)])
def test_offroad_from_that_ends_before_the_ego_can_reach_the_road_is_reported(
        tmp_path: Path, capsys: pytest.CaptureFixture[str], speed: int, offroad_from: int, warned: bool) -> None:
    """W0716's hint, `offroad_from 1`, silenced it on ZAM_Ramp-1_1-T-1, whose ego starts at standstill with
    its rear 2.25 m before the road: at sample 1 every run was still off the road, so Qd failed ("the longest
    any run keeps it is until t = 0 s") with no word on why. Now W0716 says so when a corner lies farther
    from the road than any run can move it by then (here: in 0.1 s at 0 or 10 m/s; 0.3 s or 30 m/s suffice)."""
    source = ramp_file(tmp_path, f"        start_speed {speed}\n        offroad_from {offroad_from}")
    assert main(["check", "--format", "json", str(source)]) == 0
    found = [d for d in json.loads(capsys.readouterr().out)[0]["diagnostics"] if d["code"] == "W0716"]
    assert bool(found) == warned
    if warned:
        assert found[0]["message"] == (f"the ego starts off the road and cannot be on it by sample {offroad_from} "
                                       f"(`offroad_from {offroad_from}`): its rear-right corner lies 2.25 m outside "
                                       "every lanelet")
        assert "`offroad()` holds at sample 1 in every run" in json.dumps(found[0]["notes"])
        assert found[0]["span"]["line"] > 12  # at the setting


# ---------------------------------------------------------------- integer increments
def test_increments_keep_whole_significands_where_integration_drifts() -> None:
    """The issue's drift: integrated on doubles and truncated, 0.35 + 0.1 rad is 0.44999999999999996
    and becomes 0.44; as an increment it is 0.45, and ten steps of 0.1 rad from 0.35 end at 1.35."""
    spec = replace(make_spec(2, granularity=F(1)), actions=make_spec(2).actions)
    data = build_model_data(straight_scenario(), spec)
    integrated = NativeModel(data)
    stepped = NativeModel(replace(data, increments=True))
    state = State(1000, -175, 1000, 0, 35, 0, 100)  # turn 1 rad/s over 0.1 s
    assert integrated.sense(state).head == 44
    after = state
    for _ in range(10):
        after = stepped.sense(after)
    assert after.head == 135
    # the position moves by truncated increments: x grows by d2i(v * cos(head) * u) each step
    one = stepped.sense(state)
    assert one.x == 1000 + int(10.0 * np.cos(0.45) * 0.1 * 100)


@pytest.mark.parametrize("scenario", [straight_scenario, crossing_scenario])
def test_batch_increments_equal_native(scenario) -> None:
    data = replace(build_model_data(scenario(), make_spec(3, granularity=F(1, 4))), increments=True)
    model, native = BatchModel(data), NativeModel(data)
    states, _ = random_states(data, 1500, seed=7)
    for size in (1, 5, 1500):
        assert model.sense(states[:size]).tolist() == [list(native.sense(State(*map(int, row))))
                                                       for row in states[:size]]


def test_offroad_from_leaves_the_early_samples_unchecked() -> None:
    data = replace(build_model_data(straight_scenario(), make_spec(3)), offroad_from=2)
    model, native = BatchModel(data), NativeModel(data)
    off = np.array([[-50000, 0, 10000, 0, 0, 0, 0]] * 3, dtype=np.int32)  # 50 m before the road
    assert model.offroad(off, np.array([0, 1, 2])).tolist() == [False, False, True]
    assert [native.offroad(State(*map(int, off[0])), k) for k in range(3)] == [False, False, True]
    assert model.offroad(off).all()  # without samples: the corners only


# ---------------------------------------------------------------- allow when
def test_explore_keeps_only_the_allowed_choices(tmp_path: Path) -> None:
    data = compile_file(ramp_file(tmp_path)).model_data
    free = replace(data, allow=None)
    graph, unguarded = explore(data, horizon_samples=8), explore(free, horizon_samples=8)
    heads = graph.states[:, 5]
    assert np.abs(heads[graph.states[:, 0] > 0]).max() <= 25  # 0.05 + k * 0.1 within 0.2 (and one step back)
    assert np.unique(heads).size < np.unique(unguarded.states[:, 5]).size
    assert graph.n_states < unguarded.n_states
    # every kept choice's successor meets the condition; every dropped one's does not
    guard = ActionGuard(data)
    decision = np.flatnonzero(np.diff(graph.choice_offsets) > 0)
    pairs = action_pairs(data)
    for state in decision[:200]:
        k, ego = int(graph.states[state, 0]), graph.states[state, 1:]
        mask = guard.masks(ego[None, :], k)[0]
        kept = graph.choice_action[graph.choice_offsets[state]:graph.choice_offsets[state + 1]]
        assert sorted(kept.tolist()) == np.flatnonzero(mask).tolist()
        assert mask[np.flatnonzero(pairs[:, 1] == 0)].all()  # going straight is always allowed here


def test_the_product_and_simulation_obey_the_rule(tmp_path: Path) -> None:
    result = compile_file(ramp_file(tmp_path))
    data = result.model_data
    product = explore_product(data, result.automaton, horizon_samples=6)
    ego_heads = product.states[:, product.columns.index("head")]
    assert np.abs(ego_heads).max() <= 25
    runs = simulate(data, runs=64, horizon_samples=10, seed=3)
    assert np.abs(runs.states[:, 1:, 4]).max() <= 25
    guard = ActionGuard(data)
    for k in range(10):
        masks = guard.masks(runs.states[:, k], k)
        assert masks[np.arange(64), runs.actions[:, k]].all()


def test_the_emitted_model_guards_the_choice(tmp_path: Path, capsys: pytest.CaptureFixture[str],
                                             utap: Utap) -> None:
    xml, queries = compile_cli(ramp_file(tmp_path), tmp_path / "ramp_model.xml", capsys)
    text = xml.read_text(encoding="utf-8")
    assert "void allow_actions()" in text and "bool ALLOWED[3];" in text
    assert "ALLOWED[j * TURN_COUNT + u]" in text  # the controllable edge's guard
    assert "const int32_t OFFROAD_FROM = 1;" in text
    assert "x = x + d2i(i2d(v) * cos(i2d(head)) * SENSE_UNIT);" in text
    utap.validate_files(xml, queries)


def test_without_choices_the_emitted_model_is_unchanged(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    xml, _ = compile_cli(ramp_file(tmp_path, "        start_speed 10"), tmp_path / "plain.xml", capsys)
    text = xml.read_text(encoding="utf-8")
    assert "allow_actions" not in text and "ALLOWED" not in text
    assert "const int32_t OFFROAD_FROM = 0;" in text
    assert "fx = fx + fv * cos(fh) * SENSE_UNIT;" in text


# ---------------------------------------------------------------- merging the action that led to a state
def test_forgetting_the_last_action_merges_states_and_changes_no_answer(tmp_path: Path) -> None:
    """At decision samples the carried (jerk, turn) is replaced before sense() reads it: states that
    differ only there are one state for every label, choice and successor, and the shield's answers
    on them are the same."""
    from rac.engine import shield as shields
    from rac.engine.explore import forgets_actions
    from rac.engine.storm import safety_shield

    data = compile_file(ramp_file(tmp_path)).model_data
    kept, merged = explore(data, horizon_samples=10), explore(data, horizon_samples=10, forget_actions=True)
    assert merged.n_states < 0.8 * kept.n_states
    forgotten = forgets_actions(merged.states[:, 0], data.decide_every, 10)
    assert not merged.states[forgotten][:, 6:8].any()
    # the same distinct (k, x, y, v, acc, head) with the same labels, in both graphs
    def labelled(graph):
        rows = {}
        for i, row in enumerate(graph.states[:, :6].tolist()):
            rows.setdefault(tuple(row), set()).add(tuple(bool(graph.labels[n][i]) for n in sorted(graph.labels)))
        return rows
    assert labelled(kept) == labelled(merged)
    a, b = safety_shield(kept, "safe"), safety_shield(merged, "safe")
    assert a.shield_exists == b.shield_exists
    table_kept = shields.table(a, n_actions=len(action_pairs(data)))
    table_merged = shields.table(b, n_actions=len(action_pairs(data)), forget_every=data.decide_every)
    # every decision state of the unmerged graph, looked up in the merged table with its own action
    assert np.array_equal(table_merged.masks_for(table_kept.states), table_kept.masks)
    saved = shields.load(shields.save(table_merged, tmp_path / "merged.shield.npz"))
    assert saved.forget_every == data.decide_every
    assert np.array_equal(saved.masks_for(table_kept.states), table_kept.masks)


def test_a_start_speed_beyond_the_limits_points_at_both_settings(tmp_path: Path,
                                                                 capsys: pytest.CaptureFixture[str]) -> None:
    source = ramp_file(tmp_path, "        start_speed 50")  # max_speed 40
    assert main(["check", "--format", "json", str(source)]) == 1
    (found,) = [d for d in json.loads(capsys.readouterr().out)[0]["diagnostics"] if d["code"] == "E0714"]
    assert found["message"] == "the ego starts at 50 m/s, faster than `max_speed` (40 m/s)"
    assert any("`start_speed` 50 m/s" in note["message"] for note in found["notes"])
    assert any(note["message"] == "the start speed is set here" and note["span"]["line"] == 19
               for note in found["notes"])
    assert found["hints"] == ["set `max_speed 50` (or more) in the `model` block, or change `start_speed`"]


def test_a_rule_that_leaves_no_action_is_reported(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """`allow when false`: the start has no successor. The verdicts stand (the run stops there, as
    the emitted model deadlocks) and say so; a simulation says who left no action."""
    source = ramp_file(tmp_path, "        start_speed 30\n        offroad_from 1\n        allow when false")
    assert main(["verify", "--format", "json", "-q", str(source)]) == 1  # Reach is not satisfied
    results = {r["name"]: r for r in json.loads(capsys.readouterr().out)["results"]}
    assert results["Qd"]["status"] == "satisfied" and results["Reach"]["status"] == "not satisfied"
    for result in results.values():
        assert "`allow when` leaves no action in 1 state before the horizon: runs stop there" in result["message"]
    assert main(["simulate", str(source), "--runs", "3", "--seed", "1", "-o", str(tmp_path / "runs")]) == 0
    assert "3 runs met a state where the model's `allow when` allowed nothing" in capsys.readouterr().out


# ---------------------------------------------------------------- collision sticky
def crossing_car() -> Scenario:
    """One lane along x; the ego at (0, 1.75) heading east at 10 m/s; a car crossing the lane going
    north at 10 m/s, through the ego's path at x = 20 at t = 2 s and gone by 2.5 s."""
    crossing = tuple(Waypoint(0.1 * i, 20.0, -18.25 + 1.0 * i, math.pi / 2, 10.0) for i in range(0, 51, 10))
    return Scenario(name="crossing_car", path="crossing_car.xml", dt=0.1,
                    road=(rectangle(-10.0, 0.0, 200.0, 3.5),), obstacles=(Obstacle(31, 4.5, 1.8, crossing),),
                    ego=EgoStart(0.0, 1.75, 0.0, 10.0), goal=Goal((rectangle(60.0, 0.0, 80.0, 3.5),), 0.0, 5.0))


def sticky_data(sticky: bool = True):
    spec = replace(make_spec(2, granularity=F(1, 2), decide=F(1, 2)),
                   actions=(Action("jerk", F(-2), F(2), F(2)), Action("turn", F(0), F(0), F(1, 10))),
                   collision="sticky" if sticky else "instant")
    return build_model_data(crossing_car(), spec)


def test_a_sticky_collision_holds_for_the_rest_of_the_run() -> None:
    """Keeping 10 m/s the ego meets the crossing car at about 2 s; the car is gone by 2.5 s. With
    `collision sticky` collide() holds from then on, in exploration, simulation and episodes alike."""
    data, instant = sticky_data(), sticky_data(False)
    assert data.sticky and not instant.sticky
    model = NativeModel(data)
    state, tests = model.initial_state(), []
    for k in range(1, 41):
        state = model.sense(state)
        tests.append(model.collide(state, k))
    first = tests.index(True) + 1
    assert not tests[-1]  # the car has gone: the test alone no longer holds
    # exploration: a `crashed` column, the collide label never falls back along a choice
    graph = explore(data, horizon_samples=40)
    assert graph.columns[-1] == "crashed"
    collide = graph.labels["collide"]
    source = np.repeat(np.arange(graph.n_states), np.diff(graph.choice_offsets))
    assert not (collide[source] & ~collide[graph.choice_target]).any()
    keep = graph.states[:, 0] == 40
    assert collide[keep].any() and not explore(instant, horizon_samples=40).labels["collide"][keep].all()
    # simulation under the constant action: the label stays up from the first collision
    runs = simulate(data, runs=2, horizon_samples=40, seed=1, policy=lambda k, s: np.eye(3, dtype=bool)[[1, 1]])
    from rac.engine.simulate import label_runs

    labels = label_runs(data, runs, "collide")
    assert labels[:, first:].all() and not labels[:, :first].any()


def test_sticky_collision_in_the_emitted_model(tmp_path: Path, capsys: pytest.CaptureFixture[str],
                                               utap: Utap) -> None:
    source = ramp_file(tmp_path, "        start_speed 30\n        collision sticky")
    xml, queries = compile_cli(source, tmp_path / "sticky.xml", capsys)
    text = xml.read_text(encoding="utf-8")
    assert "const bool STICKY_COLLISION = true;" in text and "bool crashed = false;" in text
    assert "sense_state(), keep_collision()" in text  # the Controller, after every sample
    assert text.count("keep_collision()") >= 3  # declared, at the start, after sensing
    utap.validate_files(xml, queries)


@pytest.mark.parametrize(("settings", "excerpt"), [
    ("        collision sometimes", "`collision` must be one of the words `instant`, `sticky`"),
    ("        collision sticky\n        allow when !collide()", "with `collision sticky`, `allow when` cannot read"),
])
def test_sticky_collision_errors(tmp_path: Path, capsys: pytest.CaptureFixture[str], settings: str,
                                 excerpt: str) -> None:
    assert main(["check", str(ramp_file(tmp_path, settings))]) == 1
    assert excerpt in capsys.readouterr().out


def test_episodes_remember_a_sticky_collision(tmp_path: Path) -> None:
    """A training loop's collide() (observations, bindings) holds from the first collision on."""
    from rac.learning.episodes import EpisodeBatch

    result = compile_file(ramp_file(tmp_path, "        start_speed 30"))
    seen = []
    for data in (sticky_data(), sticky_data(False)):
        batch = EpisodeBatch(result, data=data, horizon_samples=40, goal=None)
        batch.reset(1)
        observed = []
        for _ in range(8):  # 8 decisions of 5 samples, keeping the speed
            batch.step(np.array([1]))
            observed.append(bool(batch.observe(["collide()"])[0, 0]))
        seen.append(observed)
    sticky, instant = seen
    first = sticky.index(True)
    assert all(sticky[first:]) and not any(sticky[:first])
    assert instant[first] and not instant[-1]  # the same collision, forgotten once the car has gone


def test_the_product_remembers_a_sticky_collision(tmp_path: Path) -> None:
    result = compile_file(ramp_file(tmp_path, "        start_speed 30"))
    product = explore_product(sticky_data(), result.automaton, horizon_samples=40)
    assert product.columns[-1] == "crashed"
    collide = product.labels["collide"]
    source = np.repeat(np.arange(product.n_states), np.diff(product.choice_offsets))
    assert not (collide[source] & ~collide[product.choice_target]).any()
    last = product.states[:, 0] == 40
    assert collide[last].any()
    plain = explore_product(sticky_data(False), result.automaton, horizon_samples=40)
    assert not plain.labels["collide"][plain.states[:, 0] == 40].all()
