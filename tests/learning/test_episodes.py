"""EpisodeBatch (rac.learning.episodes): n episodes of the scenario model with the automaton's reward.

Every episode of the batch equals a scalar reference — NativeModel moving the ego, the bindings
evaluated with Evaluator on one-row frames, rac.runtime.interpreter.RewardAutomaton taking the samples —
along random action sequences (hypothesis), on a tiny scenario with a probe automaton (numeric
inputs that get clipped, a rate and an update that read inputs, ``prev``, an ``at end`` clause,
a goal the ego can reach) and on examples/left_turn/model.ra. Also: the reward-expression mode,
goal termination, the automaton's `episode ends when`, frozen done episodes, observe(), the shield's state keys
and the errors.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from dataclasses import dataclass, field
from fractions import Fraction
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from tiny_scenarios import goal_ahead

from rac import ir
from rac.check.queries import lower_expression
from rac.compiler import CompileResult, compile_file, compile_text
from rac.core.diagnostics import CheckError
from rac.engine.evaluate import Evaluator, Frame
from rac.engine.explore import action_pairs, explore
from rac.lang import ast
from rac.learning.episodes import EpisodeBatch, StepResult, parse_expr
from rac.model import NativeModel, State
from rac.model.program import CheckedProgram
from rac.runtime.interpreter import RewardAutomaton
from rac.runtime.semantics import input_specs

REPO = Path(__file__).resolve().parents[2]
LEFT_TURN = REPO / "examples" / "left_turn" / "model.ra"

#: The probe automaton for the tiny scenario goal_ahead (``{model}`` is the model block).
PROBE = """\
automaton Probe {{
    input near : bool
    input prog : bool
    input d    : real in [0, 30]     // dist_goal() starts near 39 m: clipped
    input fast : real in [7, 9]      // the speed leaves [7, 9] when braking or speeding up: clipped

    reward sa, pr
    objective 10*sa + pr

    sample every 0.5
    horizon 4

    initial location Normal {{ sa' == 1;  pr' == fast }}
    location Close          {{ sa' == -1; pr' == 0 }}
    location Stalled        {{ sa' == 1;  pr' == -1 }}

    edge * -> Close   when near                 do sa = sa - 10
    edge * -> Stalled when !near && !prog
    edge * -> Normal  when !near && prog && d < 25 do pr = pr + d

    at end when d < 2 do pr = pr + 100

{model}}}
"""
PROBE_BINDINGS = ["near = mindist() < 3 * collision_distance", "prog = dist_goal() < prev(dist_goal())",
                  "d = dist_goal()", "fast = v"]
#: The paper's Eq. 9 shape over the probe's inputs, and one that reads prev, a location and a reward.
EQ9 = "10*!near + (5 + 100*goal())*prog + fast"
PREV_REWARD = "prev(d) - d + Stalled - 0.5 * Probe.location + sa"


@pytest.fixture(scope="module")
def probe(tmp_path_factory: pytest.TempPathFactory) -> CompileResult:
    folder = tmp_path_factory.mktemp("probe")
    tiny = goal_ahead()
    tiny.write(folder / "goal_ahead.xml")
    block = tiny.settings.model_block("goal_ahead.xml", PROBE_BINDINGS)
    path = folder / "probe.ra"
    path.write_text(PROBE.format(model="".join(f"    {line}\n" for line in block.splitlines())), encoding="utf-8")
    result = compile_file(path)
    assert result.ok, [d.message for d in result.diagnostics]
    return result


@pytest.fixture(scope="module")
def left_turn() -> CompileResult:
    result = compile_file(LEFT_TURN)
    assert result.ok
    return result


# ---------------------------------------------------------------- the scalar reference
@dataclass
class Reference:
    """One episode as the scalar reference plays it."""

    rewards: list[float] = field(default_factory=list)
    terminated: list[bool] = field(default_factory=list)
    truncated: list[bool] = field(default_factory=list)
    ended: list[bool] = field(default_factory=list)
    collided: list[bool] = field(default_factory=list)
    offroad: list[bool] = field(default_factory=list)
    k: int = 0
    state: State | None = None
    location: str = ""
    final_rewards: dict[str, float] = field(default_factory=dict)
    objective: float = 0.0
    clipped: int = 0


def one_frame(k: int, state: State, ra: RewardAutomaton | None = None, inputs: dict | None = None,
              prev: Frame | None = None) -> Frame:
    location = rewards = values = None
    if ra is not None:
        location = np.array([ra.locations.index(ra.location)])
        rewards = {name: np.array([value]) for name, value in ra.rewards.items()}
        values = {name: np.array([value]) for name, value in (inputs or {}).items()}
    return Frame(np.array([k]), np.array([state], dtype=np.int64), location=location, rewards=rewards,
                 inputs=values, prev=prev)


def reference(result: CompileResult | CheckedProgram, actions: list[int], horizon: int, *, goal: bool = True,
              reward: ast.Expr | None = None) -> Reference:
    """NativeModel + Evaluator (one row at a time) + RewardAutomaton, sample by sample."""
    data, automaton = result.model_data, result.automaton
    assert data is not None and automaton is not None and automaton.model is not None
    native, evaluator, ra = NativeModel(data), Evaluator(data, automaton), RewardAutomaton(automaton)
    checked = None if reward is None else lower_expression(automaton, reward, bool_numbers=True)
    pairs = action_pairs(data).tolist()
    specs = {spec.name: spec for spec in input_specs(automaton)}
    bindings = [(b.input, b.expr) for b in automaton.model.bindings]
    out = Reference()

    def read(frame: Frame) -> tuple[dict[str, object], int]:
        values: dict[str, object] = {}
        count = 0
        for name, expr in bindings:
            value = evaluator.evaluate(expr, frame)[0]
            spec = specs[name]
            if spec.is_bool:
                values[name] = bool(value)
                continue
            real = int(float(value) * data.scale) / data.scale
            clipped = min(max(real, spec.low), spec.high)
            count += clipped != real
            values[name] = clipped
        return values, count

    state, k = native.initial_state(), 0
    inputs, _ = read(one_frame(0, state))  # what sample 0 shows (prev(input) at the first sample)
    for action in actions:
        total, collided, offroad = 0.0, False, False
        moved = state._replace(jerk=pairs[action][0], turn=pairs[action][1])
        ended = reached = False
        for _ in range(data.decide_every):
            new = native.sense(moved)
            before = one_frame(k, state, ra, inputs)
            values, count = read(one_frame(k + 1, new, prev=before))
            out.clipped += count
            gain = ra.step(values)
            state, moved, k, inputs = new, new, k + 1, values
            collided |= native.collide(state, k)
            offroad |= native.offroad(state)
            if reward is None:
                total += gain
            else:
                total += float(evaluator.evaluate(checked, one_frame(k, state, ra, inputs, prev=before))[0])
            reached = goal and native.goal(state, k)
            if reached or k == horizon or ra.terminated:
                bonus = ra.end(values)  # 0.0 where `episode ends when` has ended the run (its clauses applied)
                total += bonus if reward is None else 0.0
                ended = True
                break
        out.rewards.append(total)
        out.terminated.append(reached)
        out.ended.append(ra.terminated)
        out.truncated.append(ended and not reached and not ra.terminated)
        out.collided.append(collided)
        out.offroad.append(offroad)
        if ended:
            break
    out.k, out.state, out.location = k, state, ra.location
    out.final_rewards, out.objective = ra.rewards, ra.objective
    return out


def play(batch: EpisodeBatch, plans: list[list[int]]) -> list[StepResult]:
    """Step the batch through ``plans`` (one action list per episode; a done episode's actions are
    ignored); the StepResults, and the batch checked to freeze done episodes."""
    batch.reset(len(plans))
    results = []
    for step in range(batch.max_steps + 1):  # one more: every episode is done by then
        actions = np.array([plan[min(step, len(plan) - 1)] for plan in plans])
        frozen = batch.done.copy()
        before = (batch.k.copy(), batch.ego.copy(), batch.location, batch.rewards, batch.objective)
        out = batch.step(actions)
        results.append(out)
        assert not (out.reward[frozen] != 0).any()
        for flag in (out.terminated, out.truncated, out.collided, out.offroad, out.ended):
            assert not flag[frozen].any()
        assert (batch.k[frozen] == before[0][frozen]).all() and (batch.ego[frozen] == before[1][frozen]).all()
        assert (batch.location[frozen] == before[2][frozen]).all()
        assert all((batch.rewards[r][frozen] == before[3][r][frozen]).all() for r in before[3])
        assert (batch.objective[frozen] == before[4][frozen]).all()
        assert (batch.done == (frozen | out.terminated | out.truncated | out.ended)).all()
    assert batch.done.all()
    return results


def compare(batch: EpisodeBatch, result: CompileResult | CheckedProgram, plans: list[list[int]], *, goal: bool = True,
            reward: ast.Expr | None = None) -> list[StepResult]:
    """Play ``plans`` (:func:`play`) and check every episode against :func:`reference`; the StepResults."""
    clipped = batch.clipped
    results = play(batch, plans)
    names = batch.automaton.location_names
    expected_clipped = 0
    for i, plan in enumerate(plans):
        ref = reference(result, plan, batch.horizon_samples, goal=goal, reward=reward)
        expected_clipped += ref.clipped
        steps = len(ref.rewards)
        assert [out.reward[i] for out in results[:steps]] == ref.rewards  # bit for bit
        for name in ("terminated", "truncated", "ended", "collided", "offroad"):
            assert [bool(getattr(out, name)[i]) for out in results[:steps]] == getattr(ref, name), name
        assert all(out.reward[i] == 0 for out in results[steps:])
        assert batch.k[i] == ref.k and tuple(batch.ego[i].tolist()) == tuple(ref.state)
        assert names[batch.location[i]] == ref.location
        assert {r: v[i] for r, v in batch.rewards.items()} == ref.final_rewards
        assert batch.objective[i] == ref.objective
    assert batch.clipped - clipped == expected_clipped
    assert batch.clipped == sum(batch.clipped_inputs.values())
    return results


def plans_of(n_actions: int, steps: int) -> st.SearchStrategy[list[list[int]]]:
    plan = st.lists(st.integers(0, n_actions - 1), min_size=steps, max_size=steps)
    return st.lists(plan, min_size=1, max_size=6)


HYPOTHESIS = settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])


# ---------------------------------------------------------------- agreement with the reference
@HYPOTHESIS
@given(data=st.data())
def test_probe_agrees_with_the_reference(probe: CompileResult, data: st.DataObject) -> None:
    batch = EpisodeBatch(probe, horizon_samples=data.draw(st.integers(1, 12)))
    plans = data.draw(plans_of(batch.n_actions, batch.max_steps))
    compare(batch, probe, plans)


@settings(max_examples=15, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(data=st.data())
def test_left_turn_agrees_with_the_reference(left_turn: CompileResult, data: st.DataObject) -> None:
    batch = EpisodeBatch(left_turn, horizon_samples=data.draw(st.integers(1, 24)))
    compare(batch, left_turn, data.draw(plans_of(batch.n_actions, batch.max_steps)))


@HYPOTHESIS
@given(data=st.data(), text=st.sampled_from([EQ9, PREV_REWARD]), goal=st.booleans())
def test_reward_expressions_sum_per_sample(probe: CompileResult, data: st.DataObject, text: str, goal: bool) -> None:
    expr = parse_expr(text)
    batch = EpisodeBatch(probe, reward=expr, goal=parse_expr("goal()") if goal else None)
    compare(batch, probe, data.draw(plans_of(batch.n_actions, batch.max_steps)), goal=goal, reward=expr)


def test_reward_text_is_parsed(probe: CompileResult) -> None:
    by_text, by_expr = EpisodeBatch(probe, reward=EQ9), EpisodeBatch(probe, reward=parse_expr(EQ9))
    for batch in (by_text, by_expr):
        batch.reset(3)
    actions = np.array([0, 4, 8])
    assert (by_text.step(actions).reward == by_expr.step(actions).reward).all()


# ---------------------------------------------------------------- termination, freezing
def speed_up(batch: EpisodeBatch) -> int:
    """The action index of (jerk +2, turn 0) in the tiny settings."""
    pairs = batch.action_pairs.tolist()
    return pairs.index([2 * batch.data.scale, 0])


def test_goal_terminates_at_the_first_goal_sample(probe: CompileResult) -> None:
    batch = EpisodeBatch(probe, horizon_samples=12)  # beyond the goal interval (4 s, sample 8)
    go, keep = speed_up(batch), batch.action_pairs.tolist().index([0, 0])
    results = compare(batch, probe, [[go] * batch.max_steps, [keep] * batch.max_steps])
    # speeding up reaches the goal region (goal_ahead's known answer); keeping the speed does not
    assert any(out.terminated[0] for out in results) and not any(out.truncated[0] for out in results)
    assert any(out.truncated[1] for out in results) and not any(out.terminated[1] for out in results)
    native = NativeModel(batch.data)
    state, k, first = native.initial_state()._replace(jerk=int(batch.action_pairs[go][0])), 0, None
    while first is None:
        state, k = native.sense(state), k + 1
        first = k if native.goal(state, k) else None
    assert batch.k[0] == first < batch.horizon_samples and batch.k[1] == batch.horizon_samples
    # without a goal the same run goes on to the horizon
    free = EpisodeBatch(probe, goal=None, horizon_samples=12)
    results = compare(free, probe, [[go] * free.max_steps], goal=False)
    assert free.k[0] == free.horizon_samples and results[free.max_steps - 1].truncated[0]
    assert not any(out.terminated.any() for out in results)


#: The probe's runs end when an obstacle is near or the goal is nearer than 28 m (the start is about 39 m away).
PROBE_ENDS = ir.BOr((ir.BInput("near"), ir.BAtom("d", "<", Fraction(28))))


@HYPOTHESIS
@given(data=st.data(), goal=st.booleans())
def test_episode_ends_when_the_automaton_ends_the_run(probe: CompileResult, data: st.DataObject, goal: bool) -> None:
    """`episode ends when`: the episode ends at the sample whose inputs satisfy the condition (StepResult.ended),
    the end clauses' increase in that sample's reward, exactly as the scalar runtime ends it."""
    program = CheckedProgram(dataclasses.replace(probe.automaton, episode_ends=PROBE_ENDS), probe.model_data)
    batch = EpisodeBatch(program, goal=parse_expr("goal()") if goal else None,
                         horizon_samples=data.draw(st.integers(1, 12)))
    compare(batch, program, data.draw(plans_of(batch.n_actions, batch.max_steps)), goal=goal)


def test_speeding_up_ends_the_episode_early(probe: CompileResult) -> None:
    program = CheckedProgram(dataclasses.replace(probe.automaton, episode_ends=PROBE_ENDS), probe.model_data)
    batch = EpisodeBatch(program, goal=None, horizon_samples=12)
    go, keep = speed_up(batch), batch.action_pairs.tolist().index([0, 0])
    results = compare(batch, program, [[go] * batch.max_steps, [keep] * batch.max_steps], goal=False)
    assert any(out.ended[0] for out in results) and batch.k[0] < batch.horizon_samples
    assert not any(out.truncated[0] or out.terminated[0] for out in results)


def test_a_custom_goal_may_read_the_automaton(probe: CompileResult) -> None:
    batch = EpisodeBatch(probe, goal=parse_expr("Close || sa >= 1"))  # sa reaches 1 after two samples
    batch.reset(2)
    out = batch.step(np.zeros(2, dtype=int))
    assert out.terminated.all() and batch.done.all() and (batch.k == 2).all()


def test_done_episodes_stay_frozen(probe: CompileResult) -> None:
    batch = EpisodeBatch(probe, horizon_samples=12)
    go = speed_up(batch)
    plans = [[go] * batch.max_steps, [0] * batch.max_steps, [4] * batch.max_steps]
    results = compare(batch, probe, plans)  # play() checks the freezing at every step
    assert batch.k[0] < batch.horizon_samples
    out = batch.step(np.array([0, 0, 0]))  # everything done: nothing moves
    assert not out.reward.any() and not out.terminated.any() and not out.truncated.any()
    assert sum(out.reward.sum() for out in results) == pytest.approx(batch.objective.sum())


def test_horizon_not_a_multiple_of_the_decision_period(probe: CompileResult) -> None:
    batch = EpisodeBatch(probe, horizon_samples=5, goal=None)
    assert batch.decide_every == 2 and batch.max_steps == 3
    batch.reset(2)
    flags = [batch.step(np.zeros(2, dtype=int)).truncated.all() for _ in range(3)]
    assert flags == [False, False, True] and (batch.k == 5).all()


# ---------------------------------------------------------------- observe, state keys
def test_observe_reads_the_current_frame(probe: CompileResult) -> None:
    batch = EpisodeBatch(probe)
    batch.reset(2)
    exprs = [parse_expr(text) for text in ("Probe.location", "Normal", "sa", "pr", "near", "d", "time", "x",
                                           "prev(x)", "dist_goal()")]
    start = batch.observe(exprs)
    assert start.shape == (2, len(exprs)) and start.dtype == np.float64
    scale = batch.data.scale
    x0 = batch.ego[0, 0] / scale
    # at the start: the initial location, rewards 0, the bindings on the start (d clipped to 30), prev = itself
    assert start[0].tolist() == [0.0, 1.0, 0.0, 0.0, 0.0, 30.0, 0.0, x0, x0, start[0, 9]]
    batch.step(np.array([0, 4]))
    now = batch.observe(exprs)
    assert (now[:, 6] == 2 * batch.data.period).all()
    assert (now[:, 7] == batch.ego[:, 0] / scale).all()
    assert (now[:, 2] == batch.rewards["sa"]).all() and (now[:, 3] == batch.rewards["pr"]).all()
    assert (now[:, 0] == batch.location).all()
    assert (now[:, 8] != now[:, 7]).all()  # prev(x): the sample before, the ego moved


def test_state_keys_are_states_of_the_explored_graph(probe: CompileResult) -> None:
    batch = EpisodeBatch(probe, goal=None)
    graph = explore(batch.data, horizon_samples=batch.horizon_samples)
    known = {tuple(row) for row in graph.states.tolist()}
    rng = np.random.default_rng(5)
    batch.reset(16)
    while not batch.done.all():
        keys = batch.state_keys()
        assert keys.dtype == np.int32 and keys.shape == (16, 8)
        assert all(tuple(row) in known for row in keys.tolist())
        assert (keys[:, 0] % batch.decide_every == 0).all()
        batch.step(rng.integers(batch.n_actions, size=16))


# ---------------------------------------------------------------- errors
def test_errors(probe: CompileResult) -> None:
    batch = EpisodeBatch(probe)
    with pytest.raises(RuntimeError, match="reset"):
        batch.step(np.zeros(1, dtype=int))
    batch.reset(2)
    with pytest.raises(ValueError, match="shape"):
        batch.step(np.zeros(3, dtype=int))
    with pytest.raises(ValueError, match="shape"):
        batch.step(np.zeros(2))
    with pytest.raises(ValueError, match=r"\[0, 9\)"):
        batch.step(np.array([0, 9]))
    with pytest.raises(ValueError, match="positive"):
        batch.reset(0)
    with pytest.raises(ValueError, match="at least 1"):
        EpisodeBatch(probe, horizon_samples=0)
    with pytest.raises(CheckError, match="unknown name `nonsense`"):
        EpisodeBatch(probe, reward="nonsense + 1")
    with pytest.raises(ValueError):
        parse_expr("1 +")
    plain = compile_text("automaton A { input b : bool\n reward r\n objective r\n sample every 1\n horizon 2\n"
                         " initial location L { r' == 1 } }")
    with pytest.raises(ValueError, match="model"):
        EpisodeBatch(plain)


def test_assume_broken_by_the_bindings(probe: CompileResult, tmp_path: Path) -> None:
    text = Path(probe.automaton.model.scenario_path).read_bytes()  # type: ignore[union-attr]
    (tmp_path / "goal_ahead.xml").write_bytes(text)
    source = Path(next(iter(probe.sources))).read_text(encoding="utf-8")
    source = source.replace("    reward sa, pr", "    assume near\n\n    reward sa, pr")  # never near: broken at once
    path = tmp_path / "assumes.ra"
    path.write_text(source, encoding="utf-8")
    result = compile_file(path)
    assert result.ok, [d.message for d in result.diagnostics]
    batch = EpisodeBatch(result)
    batch.reset(2)
    with pytest.raises(ValueError, match="assume"):
        batch.step(np.zeros(2, dtype=int))


# ---------------------------------------------------------------- speed
def test_left_turn_batches_end_every_episode(left_turn: CompileResult) -> None:
    """256 random episodes in batches of 64 all end within the horizon (episodes per minute are a
    row of ``python benchmarks/learning.py``)."""
    batch = EpisodeBatch(left_turn, horizon_samples=30)
    rng = np.random.default_rng(0)
    for _ in range(4):
        batch.reset(64)
        steps = 0
        while not batch.done.all():
            batch.step(rng.integers(batch.n_actions, size=64))
            steps += 1
        assert steps <= 30


# ---------------------------------------------------------------- restarting some rows
def snapshot(batch: EpisodeBatch, row: int) -> dict[str, object]:
    """Everything a learner reads of one episode of ``batch`` now, prev(e) included."""
    return {"k": int(batch.k[row]), "ego": batch.ego[row].tolist(), "done": bool(batch.done[row]),
            "location": int(batch.location[row]), "objective": float(batch.objective[row]),
            "rewards": {name: float(v[row]) for name, v in batch.rewards.items()},
            "inputs": {name: float(v[row]) for name, v in batch.inputs.items()},
            "observed": batch.observe(["prev(d)", "d", "prev(v)", "collide()"])[row].tolist()}


@pytest.mark.parametrize("reward", ["automaton", EQ9])
def test_reset_rows_restarts_only_those_episodes(probe: CompileResult, reward: str) -> None:
    """Rows restarted at different times (so they sit at different samples) play exactly as
    one-episode batches with the same actions; the other rows go on untouched."""
    n = 3
    batch = EpisodeBatch(probe, reward=reward)
    alone = [EpisodeBatch(probe, reward=reward) for _ in range(n)]
    batch.reset(n)
    for single in alone:
        single.reset(1)
    rng = np.random.default_rng(7)
    restarts, staggered = 0, False
    for step in range(40):
        actions = rng.integers(batch.n_actions, size=n)
        if step % 5 == 2:  # restart row 1 mid-episode, at a sample the others are not at
            batch.reset_rows(np.array([1]))
            alone[1].reset(1)
        out = batch.step(actions)
        for row, single in enumerate(alone):
            one = single.step(actions[row:row + 1])
            for name in ("reward", "terminated", "truncated", "collided", "offroad"):
                assert getattr(out, name)[row] == pytest.approx(getattr(one, name)[0]), (step, row, name)
            assert snapshot(batch, row) == snapshot(single, 0), (step, row)
        ended = np.flatnonzero(batch.done)
        if ended.size:
            restarts += ended.size
            batch.reset_rows(ended)
            for row in ended:
                alone[row].reset(1)
            for row in ended:
                assert snapshot(batch, row) == snapshot(alone[row], 0)
        staggered |= len(set(batch.k.tolist())) > 1
    assert restarts >= n and staggered
    assert batch.clipped == sum(single.clipped for single in alone)


def test_reset_rows_errors(probe: CompileResult) -> None:
    batch = EpisodeBatch(probe)
    with pytest.raises(RuntimeError, match="reset"):
        batch.reset_rows(np.array([0]))
    batch.reset(2)
    with pytest.raises(ValueError, match="rows"):
        batch.reset_rows(np.array([2]))
    batch.reset_rows(np.array([], dtype=np.int64))  # nothing to restart
    assert batch.n == 2


# ---------------------------------------------------------------- the memo of steps taken
def test_steps_taken_again_are_recalled(probe: CompileResult) -> None:
    """The same plans played again on one batch: every step's model part is recalled from the memo,
    and every episode still equals the scalar reference, bit for bit."""
    batch = EpisodeBatch(probe, horizon_samples=12)
    plans = [[speed_up(batch)] * batch.max_steps, [0, 4, 8, 4, 0, 4], [0, 4, 8, 4, 8, 8]]
    compare(batch, probe, plans)
    computed, recalled = batch.steps_computed, batch.steps_recalled
    compare(batch, probe, plans)
    assert batch.steps_computed == computed and batch.steps_recalled == recalled + computed > 0
    off = EpisodeBatch(probe, horizon_samples=12, memo=False)
    compare(off, probe, plans)
    assert off.steps_recalled == 0 and off.steps_computed == computed + recalled


def test_a_reward_or_goal_reading_the_automaton_is_not_memoised(probe: CompileResult) -> None:
    """The memo's key holds the model's state only: a reward or goal that reads a location, a reward
    or an earlier sample's input is computed at every step."""
    for reward, goal in ((PREV_REWARD, "goal()"), ("automaton", "Close || sa >= 1"), ("prev(near) + 1", "goal()")):
        batch = EpisodeBatch(probe, reward=reward, goal=goal)
        batch.reset(2)
        for _ in range(2):
            batch.step(np.zeros(2, dtype=int))
        batch.reset(2)
        batch.step(np.zeros(2, dtype=int))
        assert batch.steps_recalled == 0, (reward, goal)
    memoised = EpisodeBatch(probe, reward=EQ9)
    for _ in range(2):
        memoised.reset(2)
        memoised.step(np.zeros(2, dtype=int))
    assert memoised.steps_recalled == 2  # the second reset's episodes took the first one's step


def everything(batch: EpisodeBatch, out: StepResult, cf: object) -> list:
    """All a step shows: its result, every episode's state, rewards and inputs, and the counterfactuals."""
    def plain(values: tuple) -> list:
        return [value.tolist() if isinstance(value, np.ndarray)
                else {name: column.tolist() for name, column in value.items()} if isinstance(value, dict) else value
                for value in values]

    return [plain(dataclasses.astuple(out)), batch.k.tolist(), batch.ego.tolist(), batch.location.tolist(),
            {name: values.tolist() for name, values in batch.rewards.items()},
            {name: values.tolist() for name, values in batch.inputs.items()}, batch.done.tolist(),
            batch.clipped_inputs, plain(dataclasses.astuple(cf)) if cf is not None else None]


def drive_alike(data: st.DataObject, batches: list[EpisodeBatch], count: st.SearchStrategy[int], moves: list[str],
                *, counterfactuals: bool, observed: list[str] | None = None) -> None:
    """Drive the two ``batches`` alike, ``count`` moves drawn from ``moves`` (``step``, ``reset_rows``,
    ``select``, ``reset``), and assert that every step shows the same in both (:func:`everything`, with
    the step's counterfactuals and the ``observed`` expressions)."""
    for _ in range(data.draw(count)):
        n = batches[0].n
        move = data.draw(st.sampled_from(moves))
        if move == "reset":
            width = data.draw(st.integers(1, 4))
            for batch in batches:
                batch.reset(width)
        elif move == "reset_rows":
            rows = data.draw(st.lists(st.integers(0, n - 1), max_size=n))
            for batch in batches:
                batch.reset_rows(rows)
        elif move == "select":
            rows = data.draw(st.lists(st.integers(0, n - 1), min_size=1, max_size=5))
            for batch in batches:
                batch.select(rows)
        else:
            actions = np.array(data.draw(st.lists(st.integers(0, batches[0].n_actions - 1), min_size=n, max_size=n)))
            seen = []
            for batch in batches:
                out = batch.step(actions)
                seen.append(everything(batch, out, batch.counterfactual() if counterfactuals else None))
                if observed:
                    seen[-1].append(batch.observe(observed).tolist())
            assert seen[0] == seen[1]


@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(data=st.data(), reward=st.sampled_from(["automaton", EQ9]), ends=st.booleans())
def test_the_memo_changes_nothing(probe: CompileResult, data: st.DataObject, reward: str, ends: bool) -> None:
    """With and without the memo, batches driven alike — steps, restarted rows, selected rows, whole
    resets, an automaton that ends runs early — show the same values at every step, bit for bit."""
    program = CheckedProgram(dataclasses.replace(probe.automaton, episode_ends=PROBE_ENDS), probe.model_data) \
        if ends else probe
    horizon = data.draw(st.integers(1, 12))
    batches = [EpisodeBatch(program, reward=reward, horizon_samples=horizon, counterfactuals=True, memo=memo)
               for memo in (True, False)]
    n = data.draw(st.integers(1, 4))
    for batch in batches:
        batch.reset(n)
    drive_alike(data, batches, st.integers(1, 16), ["step", "step", "step", "reset_rows", "select", "reset"],
                counterfactuals=reward == "automaton")
    assert batches[0].steps_recalled + batches[0].steps_computed == batches[1].steps_computed


def test_the_memos_share_one_budget(probe: CompileResult, monkeypatch: pytest.MonkeyPatch) -> None:
    """All batches of a process keep at most EPISODE_MEMO_BYTES of steps together (a scene set has a
    batch per scene); a full memo stops growing and the batch goes on computing, with the same
    values; a batch that is gone hands its bytes back."""
    import gc

    from rac.engine.budget import EPISODE_MEMOS

    gc.collect()
    # batches of earlier tests that are still alive hold their share: the budget is counted above it
    held = EPISODE_MEMOS.held
    cap = held + 16_000
    monkeypatch.setattr(EPISODE_MEMOS, "cap", cap)
    rng = np.random.default_rng(3)
    plans = [rng.integers(9, size=6).tolist() for _ in range(6)]
    first = EpisodeBatch(probe, horizon_samples=12)
    compare(first, probe, plans)
    assert 0 < first.memo_bytes <= cap - held
    second = EpisodeBatch(probe, horizon_samples=12)
    compare(second, probe, [rng.integers(9, size=6).tolist() for _ in range(6)])
    compare(second, probe, plans)  # beyond the budget: computed again, the same values
    assert cap - 1_000 < held + first.memo_bytes + second.memo_bytes <= cap  # full: a step more would not fit
    full = second.memo_bytes
    del first
    gc.collect()
    compare(second, probe, [rng.integers(9, size=6).tolist() for _ in range(6)])
    assert full < second.memo_bytes <= cap - held


@pytest.fixture(scope="module")
def paper() -> CompileResult:
    result = compile_file(REPO / "examples" / "paper" / "model.ra")
    assert result.ok
    return result


class _OneByOne(EpisodeBatch):
    """A memoised batch that takes every computed sample by itself (EpisodeBatch._model_sample), never
    a step's samples ahead together: the general path the samples taken ahead must equal."""

    def _ahead(self, rows: np.ndarray, pairs: np.ndarray, samples: int) -> None:
        return None


@settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(data=st.data(), which=st.sampled_from(["probe", "left_turn", "paper"]),
       reward=st.sampled_from(["automaton", "eq9", "collide"]),
       ends=st.booleans(), sticky=st.booleans())
def test_samples_taken_ahead_are_the_samples_taken_one_by_one(probe: CompileResult, left_turn: CompileResult,
                                                              paper: CompileResult, data: st.DataObject, which: str,
                                                              reward: str,
                                                              ends: bool, sticky: bool) -> None:
    """A step's computed samples taken together (EpisodeBatch._ahead: the moves first, then the bindings,
    labels, goal and reward on all of them at once) show the same values at every step as the samples
    taken one by one, bit for bit: with collisions (the left turn's traffic; the paper's, 20 samples a
    step) under ``collision sticky`` (collide() so far, and its prev), clipped inputs (the probe's), an
    automaton that ends runs early, episodes restarted, selected or at different samples."""
    result = {"probe": probe, "left_turn": left_turn, "paper": paper}[which]
    assert result.automaton is not None and result.model_data is not None
    # `assume collide imply isClose` (the left turn's, the paper's) fails under `collision sticky`: left out
    automaton = dataclasses.replace(result.automaton, episode_ends=PROBE_ENDS) if ends and which == "probe" \
        else dataclasses.replace(result.automaton, assumptions=())
    program = CheckedProgram(automaton, dataclasses.replace(result.model_data, sticky=sticky))
    expression = {"automaton": "automaton", "eq9": EQ9 if which == "probe" else "10*!isClose + 5*prog + comf",
                  "collide": "10*collide() + 3*prev(collide()) + dist_goal()"}[reward]
    horizon = data.draw(st.integers(1, {"probe": 12, "left_turn": 100, "paper": 140}[which]))
    batches = [kind(program, reward=expression, horizon_samples=horizon, counterfactuals=True)
               for kind in (EpisodeBatch, _OneByOne)]
    assert batches[0].decide_every > 1
    n = data.draw(st.integers(1, 5))
    for batch in batches:
        batch.reset(n)
    drive_alike(data, batches, st.integers(1, 60), ["step"] * 8 + ["reset_rows", "select"],
                counterfactuals=reward == "automaton", observed=["prev(dist_goal())", "prev(collide())", "collide()"])
    assert [batch.steps_computed for batch in batches] == [batches[1].steps_computed] * 2


def test_collisions_so_far_taken_ahead(paper: CompileResult) -> None:
    """Under ``collision sticky`` a collision at one sample of a step makes collide() hold at its later
    samples (taken ahead: or-ed along the step's samples), as one sample after the other reads it: the
    paper's traffic, 20 samples a step, a reward reading collide() and its prev."""
    assert paper.automaton is not None and paper.model_data is not None
    program = CheckedProgram(dataclasses.replace(paper.automaton, assumptions=()),
                             dataclasses.replace(paper.model_data, sticky=True))
    collided = 0
    for seed in range(3):
        batches = [kind(program, reward="10*collide() + 3*prev(collide()) + dist_goal()")
                   for kind in (EpisodeBatch, _OneByOne)]
        for batch in batches:
            batch.reset(5)
        rng = np.random.default_rng(seed)
        while not batches[0].done.all():
            actions = rng.integers(batches[0].n_actions, size=5)
            seen = [everything(batch, batch.step(actions), None) for batch in batches]
            assert seen[0] == seen[1]
            collided += sum(seen[0][0][3])
    assert collided > 0


def taken_alone(make: Callable[[], EpisodeBatch], n: int, history: list[np.ndarray], action: int,
                observed: list[str]) -> np.ndarray:
    """What ``observed`` reads after every episode takes ``action`` next: a batch of its own, driven through
    ``history`` from the start."""
    batch = make()
    batch.reset(n)
    for actions in history:
        batch.step(actions)
    batch.step(np.full(n, action))
    return batch.observe(observed)


@settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(data=st.data(), reward=st.sampled_from(["automaton", EQ9]), memo=st.booleans())
def test_ahead_is_each_action_taken_and_changes_nothing(probe: CompileResult, data: st.DataObject, reward: str,
                                                        memo: bool) -> None:
    """``ahead()`` reads, per episode and action, what ``observe()`` reads after that action is taken (each
    action taken by a batch of its own; NaN for a done episode), and a batch asked it goes on exactly as one
    never asked: every step's values, counterfactuals and clipped counts, bit for bit."""
    horizon = data.draw(st.integers(1, 12))

    def make() -> EpisodeBatch:
        return EpisodeBatch(probe, reward=reward, horizon_samples=horizon, counterfactuals=True, memo=memo)

    observed = ["x", "v", "dist_goal()", "d", "Probe.location", "sa"]
    asked, twin = make(), make()
    n = data.draw(st.integers(1, 4))
    asked.reset(n)
    twin.reset(n)
    history: list[np.ndarray] = []
    for _ in range(data.draw(st.integers(1, 6))):
        some = np.array(data.draw(st.lists(st.booleans(), min_size=n * asked.n_actions,
                                           max_size=n * asked.n_actions))).reshape(n, asked.n_actions)
        got, only = asked.ahead(observed), asked.ahead(observed, np.arange(n), some)
        assert got.shape == only.shape == (n, asked.n_actions, len(observed))
        done = asked.done.copy()
        assert np.isnan(got[done]).all() and np.isnan(only[~some]).all()
        for action in range(asked.n_actions):
            expected = taken_alone(make, n, history, action, observed)
            np.testing.assert_array_equal(got[~done, action], expected[~done])
            asked_here = some[:, action] & ~done
            np.testing.assert_array_equal(only[asked_here, action], expected[asked_here])
        assert asked.steps_ahead > 0 or done.all()
        actions = np.array(data.draw(st.lists(st.integers(0, asked.n_actions - 1), min_size=n, max_size=n)))
        history.append(actions)
        seen = [everything(batch, out := batch.step(actions), batch.counterfactual() if reward == "automaton" else None)
                + [batch.observe(observed).tolist(), out.reward.tolist()] for batch in (asked, twin)]
        assert seen[0] == seen[1]
        assert (asked.clipped, asked.steps_recalled + asked.steps_computed) == (
            twin.clipped, twin.steps_recalled + twin.steps_computed)
