"""Counterfactual experiences (issue 23): a transition replayed from every automaton location
(rac.learning.counterfactual), the episodes' step replayed (EpisodeBatch.counterfactual), tabular
Q-learning updating every location, and the bins derived from the model."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from engine_files import write_engine_file
from hypothesis import given, settings
from hypothesis import strategies as st

from rac.compiler import compile_file, compile_text
from rac.engine.budget import REPLAY_MEMOS
from rac.learning.counterfactual import Replayer, Sample, counterfactual_transitions
from rac.learning.episodes import EpisodeBatch, parse_expr
from rac.learning.qlearning import learn, location_column
from rac.learning.strategy import derived_bins
from rac.runtime.batch import BatchRewardAutomaton
from rac.runtime.semantics import input_specs

#: Two locations: A earns 1 per sample, B loses 1; A -> B when p, B -> A when !p (+10 on the way);
#: at the end in A, +100.
TINY = """
automaton Tiny {
    input p : bool
    reward r
    objective r
    sample every 1
    horizon 10
    initial location A { r' == 1 }
    location B { r' == -1 }
    edge A -> B when p
    edge B -> A when !p do r = r + 10
    at end when !p do r = r + 100
}
"""
#: Rates reading a numeric input (held from the sample before), an update reading a reward (not a translation).
HELD = """
automaton Held {
    input p : bool
    input x : real in [0, 10]
    reward r
    objective r
    sample every 1
    horizon 10
    initial location A { r' == x }
    location B { r' == -2 * x }
    edge A -> B when p && x > 5 do r = r * 2
    edge B -> A when !p do r = r + x
    at end when !p do r = r + 100
}
"""
ROOT = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="module")
def tiny():
    return compile_text(TINY).raise_for_errors()


def test_one_sample_from_every_location_by_hand(tiny) -> None:
    # Per sample: accrue at the current location's rate, then take the edge (its update after).
    cf = counterfactual_transitions(tiny, {"p": np.array([True, False])}, ended=np.array([False, True]))
    assert cf.source.tolist() == [0, 0, 1, 1] and cf.location.tolist() == [0, 1, 0, 1]
    # p: from A +1 then to B; from B -1 and stay.  !p and the end: from A +1 +100; from B -1, +10 to A, +100.
    assert cf.next_location.tolist() == [1, 1, 0, 0]
    assert cf.reward.tolist() == [1.0, -1.0, 101.0, 109.0]
    assert cf.ended.tolist() == [False, False, True, True]


def test_a_transition_of_several_samples_by_hand(tiny) -> None:
    # Two episodes, three samples: p, !p, p; the second episode ends after the second sample.
    on, off = np.array([True, True]), np.array([False, False])
    samples = [Sample({"p": on}, np.array([True, True]), np.array([False, False])),
               Sample({"p": off}, np.array([True, True]), np.array([False, True])),
               Sample({"p": on}, np.array([True, False]), np.array([False, False]))]
    cf = Replayer(tiny).replay(samples, 2, {"r": np.array([5.0, 0.0])})
    # Episode 0 from A: +1 (to B), -1 +10 (to A), +1 (to B) = 11; from B: -1, -1 +10 (A), +1 (B) = 9.
    # Episode 1 from A: +1 (B), -1 +10 (A), end +100 = 110; from B: -1, -1 +10 (A), end +100 = 108.
    assert cf.reward.tolist() == [[11.0, 9.0], [110.0, 108.0]]
    assert cf.next_location.tolist() == [[1, 1], [0, 0]]
    assert cf.rewards["r"].tolist() == [[16.0, 14.0], [110.0, 108.0]]


def test_the_helper_for_replay_buffers_equals_stepping_from_each_location(tiny) -> None:
    from rac.runtime.batch import BatchRewardAutomaton

    rng = np.random.default_rng(3)
    inputs = {"p": rng.random(50) < 0.5}
    ended = rng.random(50) < 0.2
    cf = counterfactual_transitions(tiny, inputs, ended=ended)
    assert cf.reward.shape == cf.location.shape == cf.next_location.shape == cf.source.shape == (100,)
    for location in (0, 1):  # stepping a fresh batch put in that location, one sample (and the end)
        batch = BatchRewardAutomaton(tiny, 50)
        batch.resume(np.full(50, location))
        expected = batch.step_batch(inputs) + batch.end_batch(inputs, mask=ended)
        rows = cf.location == location
        assert np.array_equal(cf.reward[rows], expected)
        assert np.array_equal(cf.next_location[rows], batch.locations)


def test_the_episodes_step_replayed_at_its_own_location_is_the_step() -> None:
    result = compile_file(ROOT / "examples" / "paper" / "model.ra")
    batch = EpisodeBatch(result, horizon_samples=60, counterfactuals=True)
    batch.reset(6)
    rng = np.random.default_rng(1)
    for _ in range(3):
        where = batch.location
        out = batch.step(rng.integers(batch.n_actions, size=6))
        cf = batch.counterfactual()
        assert cf.reward.shape == (6, 4)
        rows = np.arange(6)
        assert np.allclose(cf.reward[rows, where], out.reward)
        assert np.array_equal(cf.next_location[rows, where], batch.location)
        objective = batch.counterfactual(objective="10 * sa + 5 * pr + co")
        assert np.allclose(objective.reward, cf.reward)  # the automaton's objective, as an expression
        part = batch.counterfactual(slice(2, 4))
        assert np.array_equal(part.reward, cf.reward[2:4])


def counterfactual_bytes(cf) -> list[bytes]:
    """Everything a :class:`Counterfactuals` holds, as bytes: equal bytes, equal experiences to the last bit."""
    return [cf.reward.tobytes(), cf.next_location.tobytes(),
            *(cf.rewards[name].tobytes() for name in sorted(cf.rewards))]


def test_rows_replayed_with_the_whole_batch_are_their_replay_alone() -> None:
    """EpisodeBatch replays a step once for all its episodes and hands each caller its rows (learners
    sharing a batch each ask for theirs): those rows must be what replaying them alone gives, bit for
    bit. Batches of a part of the rows, driven alike, replay only those; rows restarted at other samples
    end mid-step while the others go on (partly inactive samples)."""
    result = compile_file(ROOT / "examples" / "paper" / "model.ra")
    parts = [slice(0, 2), slice(2, 5), slice(5, 6)]
    whole = EpisodeBatch(result, horizon_samples=50, counterfactuals=True, memo=False)
    alone = [EpisodeBatch(result, horizon_samples=50, counterfactuals=True, memo=False) for _ in parts]
    whole.reset(6)
    for part, batch in zip(parts, alone):
        batch.reset(part.stop - part.start)
    rng = np.random.default_rng(7)
    ran_apart = False
    for step in range(8):
        if step == 2:  # rows 1 and 3 start again: they end at another step than their neighbours
            whole.reset_rows([1, 3])
            alone[0].reset_rows([1])
            alone[1].reset_rows([1])
        actions = rng.integers(whole.n_actions, size=6)
        whole.step(actions)
        for part, batch in zip(parts, alone):
            batch.step(actions[part])
            assert counterfactual_bytes(whole.counterfactual(part)) == counterfactual_bytes(batch.counterfactual())
        ran_apart |= bool(whole.done.any() and not whole.done.all())
        if whole.done.all():
            break
    assert ran_apart


def test_a_rate_reading_an_input_replays_on_the_inputs_held_before_the_step() -> None:
    """A rate reads the inputs of the sample before (zero-order hold): the step's first sample reads the
    previous step's last inputs. Replayed with none held, it read its own, and the step replayed at its
    own location paid other than the step (by 0.1 here)."""
    paper = ROOT / "examples" / "paper" / "model.ra"
    text = (paper.read_text()
            .replace("input atGoal  : bool", "input atGoal  : bool\n    input clock : real in [0, 10]")
            .replace("initial location Normal { sa' == 1;  pr' == 1;  co' == 1 }",
                     "initial location Normal { sa' == 1;  pr' == 1;  co' == clock }")
            .replace("location Stalled        { sa' == 1;  pr' == -1; co' == 0 }",
                     "location Stalled        { sa' == 1;  pr' == -1; co' == -100 * clock }")
            .replace("bind atGoal  = goal()", "bind atGoal  = goal()\n        bind clock = time / 10"))
    assert text.count("clock") == 5
    batch = EpisodeBatch(compile_text(text, str(paper)), horizon_samples=60, counterfactuals=True)
    batch.reset(6)
    rng = np.random.default_rng(1)
    for _ in range(4):
        where = batch.location
        out = batch.step(rng.integers(batch.n_actions, size=6))
        cf = batch.counterfactual()
        assert np.allclose(cf.reward[np.arange(6), where], out.reward, rtol=0, atol=1e-9)


def test_counterfactuals_need_the_location_in_the_observation() -> None:
    result = compile_file(ROOT / "examples" / "paper" / "model.ra")
    batch = EpisodeBatch(result, horizon_samples=20)
    exprs = [batch.expression(t) for t in ("Driving.location", "x")]
    assert location_column(exprs[:1], exprs[1:]) == 0
    with pytest.raises(ValueError, match="location in the discrete"):
        location_column([batch.expression("x")])
    with pytest.raises(ValueError, match="only through its location"):
        location_column(exprs[:1], [batch.expression("sa")])


def test_learning_refuses_counterfactuals_on_episodes_that_do_not_record_their_steps() -> None:
    # said before any episode is stepped, not after the first step as a replay with nothing recorded
    batch = EpisodeBatch(compile_file(ROOT / "examples" / "paper" / "model.ra"), horizon_samples=20)
    with pytest.raises(ValueError, match=r"EpisodeBatch\(\.\.\., counterfactuals=True\)"):
        learn(batch, discrete=["Driving.location"], continuous=["x"], episodes=2, parallel=1, seed=1,
              counterfactuals=True)
    assert (batch.n, batch.done.size) == (0, 0)  # nothing was reset or stepped


def test_q_learning_updates_every_location(tmp_path: Path) -> None:
    path = write_engine_file(tmp_path, "goal_ahead", {
        "reach": "strategy reach = maxE(sa)[<=4]{Tiny.location}->{x, v}: <> goal()"})
    batch = EpisodeBatch(compile_file(path), counterfactuals=True)
    kwargs = dict(discrete=["Tiny.location"], continuous=["x", "v"], episodes=8, parallel=4, seed=1)
    plain = learn(batch, **kwargs)
    with_cf = learn(batch, counterfactuals=True, **kwargs)
    n_locations = len(batch.automaton.locations)
    start = tuple(plain.strategy.keys[0][1:])  # the first decision's observation, in the initial location
    # a decision's observation is learned in every location (its counterfactuals), not only in its own
    assert sorted(key[0] for key in with_cf.strategy.keys if tuple(key[1:]) == start) == list(range(n_locations))
    assert [key[0] for key in plain.strategy.keys if tuple(key[1:]) == start] == [batch.automaton.initial]
    assert with_cf.strategy.n_states > plain.strategy.n_states


def test_bins_derived_from_the_action_grid_and_the_goal() -> None:
    result = compile_file(ROOT / "examples" / "paper" / "model.ra")
    exprs = [parse_expr(t) for t in ("x", "y", "v", "head", "fabs(acc)", "time", "sa")]
    # jerk step 2 m/s^3, turn step 0.2 rad/s, decisions every 2 s, goal 8 m x 3.5 m:
    # positions min(2 * 8 / 6, 3.5 / 2), v 2 * 4 / 2, head 0.2 * 2, acc 2 * 2, time 2, anything else 1
    assert derived_bins(result.model_data, exprs) == pytest.approx((1.75, 1.75, 4.0, 0.4, 4.0, 2.0, 1.0))



@pytest.mark.parametrize("source", ["tiny", "paper"])
def test_run_samples_is_step_batch_bit_for_bit(source: str, tiny) -> None:
    # The lean path (table edges, constant rates) against step_batch/end_batch on the repeated
    # inputs: random valuations and start states, some samples partly inactive, some episodes ending.
    automaton = tiny if source == "tiny" else compile_file(ROOT / "examples" / "paper" / "model.ra").raise_for_errors()
    names = [spec.name for spec in automaton.inputs]
    n_loc = len(automaton.locations)

    @settings(max_examples=60, deadline=None)
    @given(st.integers(1, 4), st.integers(1, 5), st.integers(0, 2**32 - 1))
    def check(rows: int, length: int, seed: int) -> None:
        rng = np.random.default_rng(seed)
        samples, done = [], np.zeros(rows, dtype=bool)
        for _ in range(length):
            inputs = {name: rng.random(rows) < 0.5 for name in names}
            if "collide" in inputs:  # the paper's `assume collide imply isClose`
                inputs["collide"] &= inputs["isClose"]
            active = (rng.random(rows) < 0.8) & ~done
            ending = active & (rng.random(rows) < 0.2)
            done |= ending
            samples.append((inputs, active, ending))
        start = rng.integers(0, n_loc, rows * n_loc)
        rewards = {name: np.repeat(rng.integers(-50, 50, rows).astype(float), n_loc) for name in automaton.rewards}
        lean, plain = BatchRewardAutomaton(automaton, rows * n_loc), BatchRewardAutomaton(automaton, rows * n_loc)
        lean.resume(start, rewards)
        plain.resume(start, rewards)
        got = lean.run_samples(samples, repeat=n_loc)
        want = np.zeros(rows * n_loc)
        for inputs, active, ending in samples:
            spread = {name: np.repeat(values, n_loc) for name, values in inputs.items()}
            if active.any():
                want += plain.step_batch(spread, mask=np.repeat(active, n_loc))
            if ending.any():
                want += plain.end_batch(spread, mask=np.repeat(ending, n_loc))
        assert got.tobytes() == want.tobytes()
        assert lean.locations.tolist() == plain.locations.tolist()
        assert all(lean.rewards[name].tobytes() == plain.rewards[name].tobytes() for name in automaton.rewards)
        assert lean.samples.tolist() == plain.samples.tolist() and lean.ended.tolist() == plain.ended.tolist()

    check()


def test_run_samples_refuses_a_repeat_that_does_not_divide(tiny) -> None:
    with pytest.raises(ValueError, match="repeat must be"):
        BatchRewardAutomaton(tiny, 4).run_samples([], repeat=3)


def test_run_samples_refuses_what_step_batch_refuses() -> None:
    # An assume violated at the second sample, a missing input, a row stepped after it ended: the
    # same errors as stepping sample by sample.
    automaton = compile_file(ROOT / "examples" / "paper" / "model.ra").raise_for_errors()
    ok = {"isClose": np.array([True]), "prog": np.array([True]), "comf": np.array([True]),
          "collide": np.array([False]), "atGoal": np.array([False])}
    bad = dict(ok, isClose=np.array([False]), collide=np.array([True]))
    yes, no = np.array([True]), np.array([False])
    batch = BatchRewardAutomaton(automaton, 4)
    with pytest.raises(ValueError, match="collide"):
        batch.run_samples([(ok, yes, no), (bad, yes, no)], repeat=4)
    with pytest.raises(ValueError, match="missing input"):
        BatchRewardAutomaton(automaton, 4).run_samples([({"isClose": yes}, yes, no)], repeat=4)
    with pytest.raises(RuntimeError, match="ended"):
        BatchRewardAutomaton(automaton, 4).run_samples([(ok, yes, yes), (ok, yes, no)], repeat=4)


def replay_calls(automaton, rng: np.random.Generator, calls: int) -> list[tuple]:
    """Calls of :meth:`Replayer.replay` whose transitions repeat: each row drawn from a pool of a few
    transitions (inputs, which samples are taken and ended at, rewards before, held inputs), most of
    them alike but in one of these; neighbours and the number of rows change from call to call. A sample
    a transition neither takes nor ends at gets inputs that change (out of range, too: they are not read)."""
    specs = input_specs(automaton)
    length = int(rng.integers(1, 5))
    held = [spec.name for spec in specs if not spec.is_bool]

    def flags() -> tuple[list[bool], list[bool]]:
        active, ending, done = [], [], False
        for _ in range(length):
            takes = not done and rng.random() < 0.85
            ends = not done and rng.random() < 0.2  # at a sample it takes, or after its last one
            done |= ends
            active.append(takes)
            ending.append(ends)
        return active, ending

    def inputs() -> list[dict]:
        out = []
        for _ in range(length):
            values = {spec.name: bool(rng.random() < 0.5) if spec.is_bool else float(rng.integers(0, 21)) / 2
                      for spec in specs}
            if "collide" in values:  # the paper's `assume collide imply isClose`
                values["collide"] &= values["isClose"]
            out.append(values)
        return out

    def rewards() -> dict:
        return {name: float(rng.integers(-30, 30)) / 4 for name in automaton.rewards}

    def holding() -> dict:
        return {name: float(rng.integers(0, 21)) / 2 for name in held}

    base = (inputs(), *flags(), rewards(), holding())
    pool = [base]
    for _ in range(5):  # the base but for one thing
        change = int(rng.integers(-1, 4))
        if change == -1:  # the inputs of one sample
            at = int(rng.integers(0, length))
            pool.append(([*base[0][:at], inputs()[at], *base[0][at + 1:]], *base[1:]))
        elif change == 0:
            pool.append((inputs(), *base[1:]))
        elif change == 1:
            pool.append((base[0], *flags(), *base[3:]))
        elif change == 2:
            pool.append((*base[:3], rewards(), base[4]))
        else:
            pool.append((*base[:4], holding()))
    out = []
    for _ in range(calls):
        rows = [pool[i] for i in rng.integers(0, len(pool), int(rng.integers(1, 6)))]
        samples = []
        for j in range(length):
            columns = {}
            unread = np.array([not (row[1][j] or row[2][j]) for row in rows])
            for spec in specs:
                column = np.array([row[0][j][spec.name] for row in rows], dtype=bool if spec.is_bool else float)
                noise = rng.random(len(rows)) < 0.5 if spec.is_bool else rng.uniform(-100, 100, len(rows))
                columns[spec.name] = np.where(unread, noise, column)
            samples.append(Sample(columns, np.array([row[1][j] for row in rows]),
                                  np.array([row[2][j] for row in rows])))
        before = {name: np.array([row[3][name] for row in rows]) for name in automaton.rewards}
        given = None if not held or rng.random() < 0.3 else {name: np.array([row[4][name] for row in rows])
                                                              for name in held}
        out.append((samples, len(rows), before, given))
    return out


@pytest.mark.parametrize("source", ["tiny", "held", "paper"])
def test_a_recalled_replay_is_the_replay(source: str, tiny) -> None:
    """A Replayer with a memo recalls a transition replayed before (by everything its replay reads)
    instead of replaying it again: whatever its neighbours then and now, the rows missing padded to a
    batch size, rates reading held inputs or updates reading rewards, the recalled values must be
    those of replaying it, bit for bit."""
    automaton = {"tiny": tiny, "held": compile_text(HELD).raise_for_errors(),
                 "paper": compile_file(ROOT / "examples" / "paper" / "model.ra").raise_for_errors()}[source]
    recalled = 0

    @settings(max_examples=40, deadline=None)
    @given(st.integers(0, 2**32 - 1))
    def check(seed: int) -> None:
        nonlocal recalled
        memo = Replayer(automaton, memo=True)
        for samples, n, rewards, held in replay_calls(automaton, np.random.default_rng(seed), 6):
            got = memo.replay(samples, n, rewards, held)
            want = Replayer(automaton).replay(samples, n, rewards, held)
            assert counterfactual_bytes(got) == counterfactual_bytes(want)
        recalled += memo.rows_recalled

    check()
    assert recalled > 0


def test_the_replay_memos_share_one_budget(tiny, monkeypatch: pytest.MonkeyPatch) -> None:
    """All replayers of a process keep at most REPLAY_MEMO_BYTES together; a full memo starts afresh
    and the values stay the same; a replayer that is gone hands its bytes back."""
    import gc

    gc.collect()
    held = REPLAY_MEMOS.held  # memos of earlier tests still alive: counted above them
    cap = held + 20_000
    monkeypatch.setattr(REPLAY_MEMOS, "cap", cap)
    rng = np.random.default_rng(5)
    memo = Replayer(tiny, memo=True)
    seen = []
    for _ in range(40):
        n = int(rng.integers(1, 40))
        samples = [Sample({"p": rng.random(n) < 0.5}, np.ones(n, dtype=bool), np.zeros(n, dtype=bool))
                   for _ in range(3)]
        rewards = {"r": rng.integers(0, 40, n).astype(float)}
        got = memo.replay(samples, n, rewards)
        assert counterfactual_bytes(got) == counterfactual_bytes(Replayer(tiny).replay(samples, n, rewards))
        seen.append(REPLAY_MEMOS.held - held)
        assert REPLAY_MEMOS.held <= cap
    assert memo.rows_recalled > 0 and max(seen) > cap - held - 5_000  # it filled up
    assert any(later < earlier for earlier, later in zip(seen, seen[1:]))  # and started afresh
    del memo
    gc.collect()
    assert REPLAY_MEMOS.held == held


def test_the_batch_memo_recalls_the_replays_of_steps_taken_again() -> None:
    """EpisodeBatch(memo=True) replays a step taken again (same episode state, same action) from its
    replayer's memo: the same counterfactuals as a batch without memo, bit for bit."""
    result = compile_file(ROOT / "examples" / "paper" / "model.ra")
    batches = [EpisodeBatch(result, horizon_samples=60, counterfactuals=True, memo=memo) for memo in (True, False)]
    rng = np.random.default_rng(2)
    plans = [rng.integers(batches[0].n_actions, size=(3, 4)) for _ in range(2)]
    for plan in plans * 2:
        for batch in batches:
            batch.reset(4)
        for actions in plan:
            seen = [counterfactual_bytes((batch.step(actions), batch.counterfactual())[1]) for batch in batches]
            assert seen[0] == seen[1]
    assert batches[0]._replayer.rows_recalled >= 12 and batches[1]._replayer.rows_recalled == 0
