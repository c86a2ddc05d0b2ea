"""Counterfactual transitions for a replay buffer (rac.learning.replay) and stable-baselines3's
buffer built on them (rac.learning.sb3.CounterfactualReplayBuffer; skipped without SB3)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import gymnasium
import numpy as np
import pytest
from highway_like import FOLLOW, HighwayLike, follow, inputs, vector_inputs
from test_location_observation import Blank, alternate, took

from rac.compiler import compile_text
from rac.learning.counterfactual import counterfactual_transitions
from rac.learning.location_observation import LocationObservation, LocationVectorObservation
from rac.learning.replay import CounterfactualRows
from rac.learning.vector_info import split_vector_info
from rac.learning.wrappers import RewardAutomatonVectorWrapper, RewardAutomatonWrapper
from rac.runtime.interpreter import RewardAutomaton


def steps(seed: int, actions: list[int]) -> list[tuple[np.ndarray, np.ndarray, bool, dict[str, Any]]]:
    """(obs, next_obs, done, info) of each step of one episode on the highway-like environment."""
    env = LocationObservation(RewardAutomatonWrapper(HighwayLike(), follow(), inputs, clip=True, scale=3.0))
    obs, _ = env.reset(seed=seed)
    found = []
    for action in actions:
        after, _, terminated, truncated, info = env.step(action)
        found.append((obs, after, terminated or truncated, info))
        obs = after
        if terminated or truncated:
            break
    return found


def test_each_other_location_replayed_as_the_automaton_would() -> None:
    rows = CounterfactualRows(follow())
    names = rows.locations
    oracle = RewardAutomaton(follow()).batch(1)
    seen = set()
    for before, after, done, info in steps(1, [2] * 3 + [0] * 20):  # Unsafe, then a crash
        [batch] = rows.step(before[None, :], after[None, :], np.array([done]), [info])  # two locations: one other
        rac = info["rac"]
        real = names.index("Safe") if before[-2] == 1 else names.index("Unsafe")
        other = 1 - real
        assert batch.location.tolist() == [other] and batch.obs[0, -2:].tolist() == [float(other == 0),
                                                                                      float(other == 1)]
        assert batch.obs[0, :-2].tolist() == before[:-2].tolist()  # the environment's part is the real one
        # the oracle: one automaton put in the other location with the rewards before the step
        prior = {name: np.array([rac["rewards"][name] - rac["reward_steps"][name]]) for name in rac["rewards"]}
        oracle.resume(np.array([other]), prior)
        values = {name: np.array([value]) for name, value in rac["inputs"].items()}
        expected = oracle.step_batch(values)
        if done:
            expected = expected + oracle.end_batch(values)
        assert batch.reward[0] == pytest.approx(expected[0] / 3.0)
        assert batch.next_location.tolist() == oracle.locations.tolist()
        assert batch.next_obs[0, -2:].tolist() == [float(oracle.locations[0] == 0), float(oracle.locations[0] == 1)]
        seen.add((names[real], done))
    assert {name for name, _ in seen} == {"Safe", "Unsafe"} and any(done for _, done in seen)


def test_what_is_refused_is_said() -> None:
    rows = CounterfactualRows(follow())
    [(before, after, done, info)] = steps(3, [1])
    with pytest.raises(ValueError, match=r"infos\[0\] has no info\['rac'\]\['inputs'\].*RewardAutomatonWrapper"):
        rows.step(before[None, :], after[None, :], np.array([done]), [{"rac": {"location": "Safe"}}])
    with pytest.raises(ValueError, match="one dict per environment"):
        rows.step(before[None, :], after[None, :], np.array([done]), [info, info])
    with pytest.raises(ValueError, match=r"batches \(n environments, D columns\).*not \(4,\) and \(4,\)"):
        rows.step(before, after, np.array([done]), [info])  # one environment's, unbatched
    with pytest.raises(ValueError, match=r"'Safe', which this automaton does not have \(its locations: Want, Wait\)"):
        CounterfactualRows(alternate()).step(before[None, :], after[None, :], np.array([done]), [info])
    # one environment's info dict (no vector layout), gymnasium's SAME_STEP autoreset, a scenario environment's info
    with pytest.raises(ValueError, match="one environment's info.*vector layout"):
        rows.step(before[None, :], after[None, :], np.array([done]), info)
    same_step = {"rac": {}, "_rac": np.ones(1, dtype=bool), "final_obs": np.array([None]),
                 "_final_obs": np.zeros(1, dtype=bool)}
    with pytest.raises(ValueError, match="SAME_STEP.*NEXT_STEP"):
        rows.step(before[None, :], after[None, :], np.array([done]), same_step)
    scenario = {"location": "Safe", "rewards": {"sa": 0.0, "pr": 0.0}, "inputs": {"headway": 3.0, "collide": False}}
    with pytest.raises(ValueError, match="infos\\[0\\].*scenario environments.*several samples"):
        rows.step(before[None, :], after[None, :], np.array([done]), [scenario])
    squashed = before[None, :].copy()
    squashed[0, -2:] = [0.5, 0.5]  # a normalised observation
    with pytest.raises(ValueError, match="not one-hot location vectors"):
        rows.step(squashed, after[None, :], np.array([done]), [info])
    # only next_obs not one-hot, in an episode going on: nothing of stable-baselines3 stores one so
    with pytest.raises(ValueError, match=r"in next_obs of an episode going on, while obs's are"):
        rows.step(before[None, :], squashed, np.array([False]), [info])
    swapped = after[None, :].copy()
    swapped[0, -2:] = swapped[0, -2:][::-1]
    with pytest.raises(ValueError, match="differ from info\\['rac'\\]\\['location'\\]"):
        rows.step(before[None, :], swapped, np.array([done]), [info])


def _single_follow() -> gymnasium.Env:
    return LocationObservation(RewardAutomatonWrapper(gymnasium.wrappers.TimeLimit(HighwayLike(), 4), follow(), inputs,
                                                      clip=True))


def test_a_gymnasium_vector_environments_infos_are_replayed() -> None:
    # gymnasium's vector environments (SyncVectorEnv, AsyncVectorEnv, rac's RewardAutomatonVectorWrapper)
    # give one info dict of arrays: CounterfactualRows refused it, so their users had no counterfactual
    # rows. Now they are those of the per-environment dicts, without the sub-environments gymnasium
    # restarted in the step (NEXT_STEP: their obs -> next_obs is no transition), which `source` leaves out.
    rows = CounterfactualRows(follow())
    sync = gymnasium.vector.SyncVectorEnv([_single_follow] * 2)
    limited = gymnasium.vector.SyncVectorEnv([lambda: gymnasium.wrappers.TimeLimit(HighwayLike(), 4)] * 2)
    wrapped = LocationVectorObservation(RewardAutomatonVectorWrapper(limited, follow(), vector_inputs, clip=True))
    for envs in (sync, wrapped):
        before, _ = envs.reset(seed=0)
        restarted = np.zeros(2, dtype=bool)
        compared = skipped = 0
        for _ in range(11):
            after, _, terminated, truncated, infos = envs.step(np.array([2, 0]))
            done = terminated | truncated
            got = rows.step(before, after, done, infos)
            stepping = np.flatnonzero(~restarted)
            split = split_vector_info(infos, 2)
            expected = (rows.step(before[stepping], after[stepping], done[stepping], [split[i] for i in stepping])
                        if stepping.size else None)
            [batch] = got
            assert batch.source.tolist() == stepping.tolist() and batch.obs.shape == (stepping.size, 4)
            if expected is not None:
                [want] = expected
                for name in ("obs", "next_obs", "reward", "location", "next_location"):
                    assert np.array_equal(getattr(batch, name), getattr(want, name)), name
            compared += stepping.size
            skipped += int(restarted.sum())
            restarted, before = done, after
        assert compared > 12 and skipped >= 2


def test_gymnasiums_infos_made_a_list_are_replayed_as_the_vector_layout() -> None:
    # gymnasium's DictInfoToList turns a vector environment's info into a list of dicts, as stable-baselines3 gives
    # them; a sub-environment restarted in the step (NEXT_STEP) then has its reset info there, without the step's
    # inputs, and CounterfactualRows refused the whole step at the first restart ("infos[0] has no
    # info['rac']['inputs']: ... need the step info of RewardAutomatonWrapper"), which the wrapper did give
    from gymnasium.wrappers.vector import DictInfoToList

    limited = gymnasium.vector.SyncVectorEnv([lambda: gymnasium.wrappers.TimeLimit(HighwayLike(), 4)] * 2)
    listed = DictInfoToList(LocationVectorObservation(RewardAutomatonVectorWrapper(limited, follow(), vector_inputs,
                                                                                   clip=True)))
    limited = gymnasium.vector.SyncVectorEnv([lambda: gymnasium.wrappers.TimeLimit(HighwayLike(), 4)] * 2)
    layout = LocationVectorObservation(RewardAutomatonVectorWrapper(limited, follow(), vector_inputs, clip=True))
    rows, reference = CounterfactualRows(follow()), CounterfactualRows(follow())
    (before, _), (same, _) = listed.reset(seed=0), layout.reset(seed=0)
    restarts = 0
    for _ in range(11):
        after, _, terminated, truncated, infos = listed.step(np.array([2, 0]))
        again, _, _, _, dicts = layout.step(np.array([2, 0]))
        assert isinstance(infos, list) and np.array_equal(after, again)
        [got], [want] = rows.step(before, after, terminated | truncated, infos), \
            reference.step(same, again, terminated | truncated, dicts)
        for name in ("obs", "next_obs", "reward", "location", "next_location", "source"):
            assert np.array_equal(getattr(got, name), getattr(want, name)), name
        restarts += 2 - got.source.size
        before, same = after, again
    assert restarts >= 2


def test_an_ended_episodes_terminal_observation_gets_its_location_from_the_info() -> None:
    """stable-baselines3 stores an ended episode's terminal observation as VecNormalize normalised it,
    unnormalised again: a location not seen so far comes back clipped (0.001, not 1). The location is in
    the info: it is taken from there, for the real row and the counterfactual ones."""
    rows = CounterfactualRows(follow())
    [*_, (before, after, done, info)] = steps(1, [2] * 3 + [0] * 20)  # ends in a crash, in Unsafe
    assert done and info["rac"]["location"] == "Unsafe" and after[-2:].tolist() == [0.0, 1.0]
    squashed = after[None, :].copy()
    squashed[0, -2:] = [0.0, 0.001]
    mended = rows.terminal_located(squashed, np.array([True]), [info])
    assert mended[0].tolist() == after.tolist() and squashed[0, -1] == 0.001  # a copy
    assert rows.terminal_located(after[None, :], np.array([True]), [info]).tolist() == [after.tolist()]
    assert rows.terminal_located(squashed, np.array([False]), [info]).tolist() == squashed.tolist()  # going on
    [batch] = rows.step(before[None, :], squashed, np.array([True]), [info])
    [exact] = rows.step(before[None, :], after[None, :], np.array([True]), [info])
    assert batch.next_obs.tolist() == exact.next_obs.tolist() and batch.reward.tolist() == exact.reward.tolist()
    swapped = after[None, :].copy()
    swapped[0, -2:] = [1.0, 0.0]  # one-hot, but not the info's location: another automaton's, said
    with pytest.raises(ValueError, match="differ from info\\['rac'\\]\\['location'\\]"):
        rows.step(before[None, :], swapped, np.array([True]), [info])


LATE = """automaton Late {
    input last : bool
    reward r
    objective r
    sample every 1
    horizon 5
    initial location Going { r' == 0 }
    location Arrived       { r' == 0 }
    edge Going -> Arrived when last do r = r + 1
}
"""


class Five(gymnasium.Env):  # type: ignore[type-arg]
    """Episodes of five steps; ``info["last"]`` at the fifth, the only step that ends in ``Arrived``."""

    observation_space = gymnasium.spaces.Box(0.0, 1.0, shape=(1,), dtype=np.float32)
    action_space = gymnasium.spaces.Discrete(2)

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None) -> tuple[np.ndarray, dict]:
        super().reset(seed=seed)
        self.t = 0
        return np.zeros(1, dtype=np.float32), {}

    def step(self, action: int) -> tuple[np.ndarray, float, bool, bool, dict[str, Any]]:
        self.t += 1
        return np.full(1, self.t / 5, dtype=np.float32), 0.0, self.t >= 5, False, {"last": self.t >= 5}


def test_terminal_locations_are_mended_in_gymnasiums_vector_layout() -> None:
    """terminal_located takes gymnasium's vector layout too (one dict of arrays): an ended episode's
    squashed location columns are set from its info, the rows of sub-environments restarted in the step
    (which report no automaton step) are left as they are."""
    rows = CounterfactualRows(follow())
    sync = gymnasium.vector.SyncVectorEnv([_single_follow] * 2)
    sync.reset(seed=0)
    mended = restarted_seen = 0
    restarted = np.zeros(2, dtype=bool)
    for _ in range(11):
        after, _, terminated, truncated, infos = sync.step(np.array([2, 0]))
        done = terminated | truncated
        squashed = after.copy()
        squashed[:, -2:] = 0.25  # what VecNormalize's round trip may leave, on every row
        got = rows.terminal_located(squashed, done, infos)
        for i in range(2):
            if restarted[i] or not done[i]:  # not an ended episode's terminal observation: as it was
                assert got[i].tolist() == squashed[i].tolist()
            else:
                assert got[i].tolist() == after[i].tolist()
                mended += 1
        restarted_seen += int(restarted.sum())
        restarted = done
    assert mended >= 2 and restarted_seen >= 2


def test_stable_baselines3_buffer_under_vec_normalize() -> None:
    """DQN on VecNormalize (its default, norm_obs=True) with the counterfactual buffer: the first episode
    ended in a location not seen before, whose terminal observation came back from VecNormalize clipped,
    and the buffer refused it, ending training there."""
    pytest.importorskip("stable_baselines3", reason="needs stable-baselines3 (the rl extra)")
    from stable_baselines3 import DQN
    from stable_baselines3.common.vec_env import DummyVecEnv, VecNormalize

    from rac.learning.sb3 import CounterfactualReplayBuffer

    late = compile_text(LATE, "late.ra").raise_for_errors()
    envs = VecNormalize(DummyVecEnv([lambda: LocationObservation(RewardAutomatonWrapper(
        Five(), late, lambda obs, info: {"last": info["last"]}))]))
    model = DQN("MlpPolicy", envs, learning_starts=100, buffer_size=100, seed=0, device="cpu",
                replay_buffer_class=CounterfactualReplayBuffer, replay_buffer_kwargs={"automaton": late})
    model.learn(12)  # two episodes, and two steps of a third
    buffer = model.replay_buffer
    assert buffer.pos == 24  # a real row and a counterfactual one per step
    # Going (the real row), Arrived (the counterfactual one); at the episode's end both in Arrived
    episode = [[1.0, 0.0], [0.0, 1.0]] * 4 + [[0.0, 1.0]] * 2
    assert buffer.next_observations[:24, 0, -2:].tolist() == episode * 2 + [[1.0, 0.0], [0.0, 1.0]] * 2
    assert buffer.rewards[:24, 0].tolist() == ([0.0] * 8 + [1.0, 0.0]) * 2 + [0.0] * 4


def test_stable_baselines3_buffer_stores_every_location() -> None:
    pytest.importorskip("stable_baselines3", reason="needs stable-baselines3 (the rl extra)")
    from stable_baselines3 import DQN

    from rac.learning.sb3 import CounterfactualReplayBuffer

    env = LocationObservation(RewardAutomatonWrapper(Blank(), alternate(), took))
    model = DQN("MlpPolicy", env, learning_starts=1000, buffer_size=1000, seed=0,
                replay_buffer_class=CounterfactualReplayBuffer, replay_buffer_kwargs={"automaton": alternate()})
    model.learn(40)
    buffer = model.replay_buffer
    assert isinstance(buffer, CounterfactualReplayBuffer) and buffer.pos == 80  # two rows per step
    obs, rewards = buffer.observations[:80, 0], buffer.rewards[:80, 0]
    real, counterfactual = obs[0::2], obs[1::2]
    assert (real[:, 1:] != counterfactual[:, 1:]).any(axis=1).all()  # the other location, each time
    # exactly one of the two locations pays for any action: Want pays for a, Wait for !a
    assert (rewards[0::2] + rewards[1::2]).tolist() == [1.0] * 40
    with pytest.raises(ValueError, match="optimize_memory_usage"):
        CounterfactualReplayBuffer(10, env.observation_space, env.action_space, optimize_memory_usage=True,
                                   automaton=alternate())
    with pytest.raises(ValueError, match="one-hot vector"):
        CounterfactualReplayBuffer(10, Blank.observation_space, env.action_space, automaton=alternate())
    dict_env = LocationObservation(RewardAutomatonWrapper(Blank(), alternate(), took), layout="dict")
    dict_space = dict_env.observation_space
    with pytest.raises(ValueError, match="'concat' layout"):  # not ReplayBuffer's TypeError on a Dict space
        CounterfactualReplayBuffer(10, dict_space, env.action_space, automaton=alternate())


RATED = """automaton Rated {
    input headway : real in [0, 10]
    input collide : bool
    reward sa
    objective sa
    sample every 0.1
    horizon 3
    initial location Safe { sa' == headway }
    location Unsafe       { sa' == -headway }
    edge Safe -> Unsafe   when headway < 5
    edge Unsafe -> Safe   when headway >= 5 do sa = sa * 2
}
"""


def test_rates_that_read_inputs_read_the_previous_steps_inputs() -> None:
    # A rate reads the inputs held from the previous sample (language.md, semantics): replayed with the
    # step's own inputs, every counterfactual reward of such an automaton was wrong after the first step.
    rated = compile_text(RATED, "rated.ra").raise_for_errors()
    rows = CounterfactualRows(rated)
    env = LocationObservation(RewardAutomatonWrapper(HighwayLike(), rated, inputs, clip=True))
    before, _ = env.reset(seed=0)
    previous = None
    checked = 0
    for action in [2] * 5 + [0] * 10:
        after, reward, terminated, truncated, info = env.step(action)
        rac = info["rac"]
        held = rac["inputs"]["headway"] if previous is None else previous
        assert rac["held"]["headway"] == held
        real = int(np.argmax(before[-2:]))
        # the real step, replayed from its own location, pays what the wrapper paid
        prior = {name: np.array([rac["rewards"][name] - rac["reward_steps"][name]]) for name in rac["rewards"]}
        cf = counterfactual_transitions(rated, {name: np.array([v]) for name, v in rac["inputs"].items()},
                                        rewards=prior, held={"headway": np.array([held])},
                                        ended=np.array([terminated or truncated]))
        assert cf.reward[real] == pytest.approx(float(reward))
        # the other location accrues its rate on the held headway; the edge into Safe doubles sa
        [batch] = rows.step(before[None, :], after[None, :], np.array([terminated or truncated]), [info])
        accrued = prior["sa"][0] + (-held if real == 0 else held) * 0.1
        doubled = real == 0 and rac["inputs"]["headway"] >= 5  # from Unsafe, the edge back to Safe
        expected = (2 * accrued if doubled else accrued) - prior["sa"][0]
        assert batch.reward[0] == pytest.approx(expected)
        checked += 1
        previous = rac["inputs"]["headway"]
        before = after
        if terminated or truncated:
            break
    assert checked > 2


def test_rates_that_read_inputs_need_the_held_inputs() -> None:
    # Without held=, a transition was replayed as an episode's first sample, its rates reading its own
    # inputs: every counterfactual reward after the first step of such an automaton was wrong, silently.
    rated = compile_text(RATED, "rated.ra").raise_for_errors()
    inputs = {"headway": np.array([2.0, 8.0]), "collide": np.array([False, False])}
    with pytest.raises(ValueError, match=r"rates of `Rated` read the input\(s\) headway.*held="):
        counterfactual_transitions(rated, inputs)
    # at an episode's first step the held inputs are the step's own, as the wrapper's info["rac"]["held"] says
    first = counterfactual_transitions(rated, inputs, held={"headway": inputs["headway"]},
                                       rewards={"sa": np.zeros(2)})
    assert first.reward.reshape(2, 2)[:, 0].tolist() == pytest.approx([0.2, 0.8])
    # an automaton whose rates read no input is replayed exactly without them, as before
    constant = follow()
    assert not constant.rates_read_inputs
    plain = counterfactual_transitions(constant, {"headway": np.array([8.0]), "collide": np.array([False])})
    assert plain.reward.tolist() == pytest.approx([1.1, -1.0])  # objective 10 * sa + pr: Safe 1 + 0.1, Unsafe -1


def test_updates_that_read_rewards_need_the_rewards_before() -> None:
    # Without rewards=, every transition was replayed from rewards of 0: for an update that reads a
    # reward (`sa = sa * 2`) the counterfactual reward was wrong after the first step, silently.
    rated = compile_text(RATED, "rated.ra").raise_for_errors()
    inputs = {"headway": np.array([8.0]), "collide": np.array([False])}
    with pytest.raises(ValueError, match=r"update of `sa` on the edge Unsafe -> Safe reads the rewards'.*rewards="):
        counterfactual_transitions(rated, inputs, held={"headway": np.array([8.0])})
    cf = counterfactual_transitions(rated, inputs, held={"headway": np.array([8.0])}, rewards={"sa": np.array([3.0])})
    assert cf.reward.tolist() == pytest.approx([0.8, 1.4])  # Safe: +0.8; Unsafe: (3 - 0.8) * 2 - 3
    # constant updates (FOLLOW's `sa = sa - 10`) pay the same from any value: no rewards= needed
    assert len(counterfactual_transitions(follow(), inputs).reward) == 2


def test_an_automaton_without_inputs_is_replayed() -> None:
    # Its steps read no input, so no input column said how many transitions there were: every step
    # was refused with "inputs must name the automaton's inputs".
    clockwork = compile_text("""automaton Clockwork {
        reward r
        objective r
        sample every 1
        horizon 10
        initial location Up { r' == 1 }
        location Down       { r' == -1 }
    }""", "clockwork.ra").raise_for_errors(warn=False)
    env = LocationObservation(RewardAutomatonWrapper(Blank(), clockwork, lambda obs, info: {}))
    before, _ = env.reset(seed=0)
    after, _, _, _, info = env.step(0)
    [batch] = CounterfactualRows(clockwork).step(before[None, :], after[None, :], np.array([False]), [info])
    assert batch.location.tolist() == batch.next_location.tolist() == [1] and batch.reward.tolist() == [-1.0]
    with pytest.raises(ValueError, match="inputs name no input: pass ended="):
        counterfactual_transitions(clockwork, {})


def test_the_vector_wrapper_says_which_inputs_its_rates_read() -> None:
    # Each sub-environment's step replayed from its own location with the inputs held from its step
    # before (its own after a reset, NEXT_STEP's reset rows masked off) pays what the wrapper paid.
    rated = compile_text(RATED, "rated.ra").raise_for_errors()
    envs = gymnasium.vector.SyncVectorEnv([lambda: gymnasium.wrappers.TimeLimit(HighwayLike(), 4)] * 2)
    env = LocationVectorObservation(RewardAutomatonVectorWrapper(envs, rated, vector_inputs, clip=True))
    before, _ = env.reset(seed=0)
    replayed = 0
    for _ in range(12):
        after, rewards, terminated, truncated, infos = env.step(np.array([2, 1]))
        rac = infos["rac"]
        active = rac["_inputs"]
        if active.any():  # (no inputs read when every sub-environment is in its reset step)
            real = np.argmax(before[:, -2:], axis=1)
            prior = {name: values - rac["reward_steps"][name] for name, values in rac["rewards"].items()}
            cf = counterfactual_transitions(rated, rac["inputs"], rewards=prior, held=rac["held"],
                                            ended=terminated | truncated)
            paid = cf.reward.reshape(2, 2)[np.arange(2), real]
            assert np.allclose(paid[active], rewards[active], rtol=0, atol=1e-9)
            replayed += int(active.sum())
        before = after
    assert replayed > 12  # steps of both sub-environments, over several episodes


def test_an_episode_the_automaton_ends_is_replayed_exactly() -> None:
    # `episode ends when` reads the inputs only, so the step that ends the episode ends it from every
    # location: the docs called the rows of such an automaton inexact. Replayed at its own location,
    # every step pays what the wrapper paid, the ending one (its `at end` clauses) included.
    ending = compile_text(FOLLOW.replace("at end when", "episode ends when headway < 1\n    at end when"),
                          "ending.ra").raise_for_errors()
    env = LocationObservation(RewardAutomatonWrapper(HighwayLike(), ending, inputs, clip=True))
    ended = 0
    for seed in range(3):
        before, _ = env.reset(seed=seed)
        for _ in range(40):
            after, reward, terminated, truncated, info = env.step(2)
            rac = info["rac"]
            prior = {name: np.array([rac["rewards"][name] - rac["reward_steps"][name]]) for name in rac["rewards"]}
            read, held = ({name: np.array([v]) for name, v in rac[key].items()} for key in ("inputs", "held"))
            cf = counterfactual_transitions(ending, read, rewards=prior, held=held,
                                            ended=np.array([terminated or truncated]))
            assert cf.reward[int(np.argmax(before[-2:]))] == pytest.approx(float(reward))
            before = after
            if terminated or truncated:
                ended += int(env.get_wrapper_attr("automaton").terminated)
                break
    assert ended == 3


def test_the_callback_warns_of_counterfactual_rows_under_frame_stacking() -> None:
    # Under VecFrameStack the counterfactual rows replace the newest frame's location only: the earlier
    # frames still show the real locations, so the rows are no transitions the environment could have
    # produced. The docs said so, but nothing told a user who stacked frames around the buffer.
    pytest.importorskip("stable_baselines3", reason="needs stable-baselines3 (the rl extra)")
    import warnings

    from stable_baselines3 import DQN
    from stable_baselines3.common.vec_env import DummyVecEnv, VecFrameStack

    from rac.learning.sb3 import CounterfactualReplayBuffer, RacCallback

    def make() -> gymnasium.Env:
        return LocationObservation(RewardAutomatonWrapper(Blank(), alternate(), took))

    for stacked in (True, False):
        envs = DummyVecEnv([make])
        model = DQN("MlpPolicy", VecFrameStack(envs, 2) if stacked else envs, learning_starts=1000,
                    buffer_size=1000, seed=0, device="cpu", replay_buffer_class=CounterfactualReplayBuffer,
                    replay_buffer_kwargs={"automaton": alternate()})
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            model.learn(4, callback=RacCallback())
        said = [str(w.message) for w in caught if "VecFrameStack" in str(w.message)]
        assert len(said) == (1 if stacked else 0), said


def test_the_callback_warns_of_gymnasiums_frame_stacking_outside_the_location() -> None:
    # gymnasium's FrameStackObservation outside LocationObservation (flattened for an MLP) stacks the location's
    # one-hot vectors as VecFrameStack does, and the rows were as inexact; the callback looked for VecFrameStack
    # alone. Inside it the frames are stacked before the location is added, once, and the rows are exact.
    pytest.importorskip("stable_baselines3", reason="needs stable-baselines3 (the rl extra)")
    import warnings

    from gymnasium.wrappers import FlattenObservation, FrameStackObservation
    from stable_baselines3 import DQN
    from stable_baselines3.common.vec_env import DummyVecEnv

    from rac.learning import sb3

    def outside() -> gymnasium.Env:
        return FlattenObservation(FrameStackObservation(LocationObservation(RewardAutomatonWrapper(
            Blank(), alternate(), took)), 2))

    def inside() -> gymnasium.Env:
        return LocationObservation(RewardAutomatonWrapper(FlattenObservation(FrameStackObservation(Blank(), 2)),
                                                          alternate(), took))

    for make, stacked in ((outside, True), (inside, False)):
        envs = DummyVecEnv([make])
        model = DQN("MlpPolicy", envs, learning_starts=1000, buffer_size=1000, seed=0, device="cpu",
                    replay_buffer_class=sb3.CounterfactualReplayBuffer, replay_buffer_kwargs={"automaton": alternate()})
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            model.learn(4, callback=sb3.RacCallback())
        said = [str(w.message) for w in caught if "under FrameStackObservation" in str(w.message)]
        assert len(said) == (1 if stacked else 0), said
        assert sb3.frame_stacker(envs) == ("FrameStackObservation" if stacked else None)


def test_the_callback_refuses_counterfactual_rows_of_a_scenario_environment_before_it_steps(tmp_path: Path) -> None:
    # rac/Scenario-v0 (ScenarioEnv) with CounterfactualReplayBuffer was refused only when the buffer was given its
    # first step, after the environment was reset and stepped: RacCallback refuses it at the start of learn(), with
    # the buffer's words; under RewardAutomatonWrapper (whose infos the buffer reads) it is not refused there
    pytest.importorskip("stable_baselines3", reason="needs stable-baselines3 (the rl extra)")
    from engine_files import write_engine_file
    from stable_baselines3 import DQN
    from stable_baselines3.common.vec_env import DummyVecEnv

    from rac.compiler import compile_file
    from rac.learning.gym import ScenarioEnv
    from rac.learning.sb3 import CounterfactualReplayBuffer, RacCallback, scenario_environments

    scene = compile_file(write_engine_file(tmp_path, "avoidable_obstacle", queries={}))
    assert scene.automaton is not None
    stepped: list[Any] = []

    class Counting(gymnasium.Wrapper):  # type: ignore[type-arg]
        def step(self, action: Any) -> Any:
            stepped.append(action)
            return self.env.step(action)

    envs = DummyVecEnv([lambda: Counting(LocationObservation(ScenarioEnv(scene)))])
    model = DQN("MlpPolicy", envs, learning_starts=1000, buffer_size=1000, seed=0, device="cpu",
                replay_buffer_class=CounterfactualReplayBuffer, replay_buffer_kwargs={"automaton": scene.automaton})
    with pytest.raises(ValueError, match=r"training environment carries the automaton's location at its top level, "
                                         r"as rac's scenario environments .* \(said at the start of learn\(\)"):
        model.learn(4, callback=RacCallback())
    assert stepped == []  # refused before the environment took a step (stable-baselines3 resets it first)
    wrapped = DummyVecEnv([lambda: RewardAutomatonWrapper(ScenarioEnv(scene), scene.automaton, lambda obs, info: {
        "near": False})])
    assert scenario_environments(envs) and not scenario_environments(wrapped)



def test_the_callback_refuses_counterfactual_rows_of_normalised_locations_before_it_steps() -> None:
    # gymnasium's NormalizeObservation outside LocationObservation normalises the location's one-hot vector, which
    # CounterfactualReplayBuffer replaces: refused only when the buffer was given its first step, after learn() had
    # stepped the environment; RacCallback refuses it at the start of learn(), with the buffer's words. Inside it
    # (the location added after) and under VecNormalize (stable-baselines3 stores the unnormalised observations)
    # the location stays one-hot, and learning goes on
    pytest.importorskip("stable_baselines3", reason="needs stable-baselines3 (the rl extra)")
    from gymnasium.wrappers import NormalizeObservation
    from stable_baselines3 import DQN
    from stable_baselines3.common.vec_env import DummyVecEnv, VecNormalize

    from rac.learning.sb3 import CounterfactualReplayBuffer, RacCallback

    stepped: list[Any] = []

    class Counting(gymnasium.Wrapper):  # type: ignore[type-arg]
        def step(self, action: Any) -> Any:
            stepped.append(action)
            return self.env.step(action)

    def model(envs: Any) -> Any:
        return DQN("MlpPolicy", envs, learning_starts=1000, buffer_size=1000, seed=0, device="cpu",
                   replay_buffer_class=CounterfactualReplayBuffer, replay_buffer_kwargs={"automaton": alternate()})

    outside = DummyVecEnv([lambda: Counting(NormalizeObservation(LocationObservation(RewardAutomatonWrapper(
        Blank(), alternate(), took))))])
    with pytest.raises(ValueError, match=r"not one-hot location vectors .*not normalised.* \(said at the start of "
                                         r"learn\(\)"):
        model(outside).learn(4, callback=RacCallback())
    assert stepped == []  # refused before the environment took a step (stable-baselines3 resets it first)
    # without the callback, the buffer still refuses it at its first step
    with pytest.raises(ValueError, match="not one-hot location vectors"):
        model(outside).learn(4)
    assert stepped
    inside = DummyVecEnv([lambda: Counting(LocationObservation(RewardAutomatonWrapper(
        NormalizeObservation(Blank()), alternate(), took)))])
    normalised = VecNormalize(DummyVecEnv([lambda: Counting(LocationObservation(RewardAutomatonWrapper(
        Blank(), alternate(), took)))]), norm_obs=True, norm_reward=False)
    for envs in (inside, normalised):
        learner = model(envs)
        learner.learn(4, callback=RacCallback())
        assert learner.replay_buffer.size() == 4 * 2  # each step: the real row and the other location's

STRAY = """automaton Stray {
    input a : bool
    reward sa
    objective sa
    sample every 0.5
    horizon 10
    initial location Go   { sa' == 1 }
    location Never        { sa' == 40 }
    edge Never -> Go      when a
}
"""


def test_counterfactual_rows_keep_the_proven_scales_promise() -> None:
    # scale="proven" promises every reward in [-1, 1]; its bound is proved over the locations runs reach, and the
    # counterfactual rows of a location no run reaches (Never: 40 a second) came out at 40 under it, unclamped.
    # They are clamped, said once; the real rows, and every row without the proven scale, are as they were.
    import warnings

    stray = compile_text(STRAY, "stray.ra").raise_for_errors()
    found = {}
    for scale in ("proven", None):
        env = LocationObservation(RewardAutomatonWrapper(Blank(), stray, took, scale=scale))
        rows = CounterfactualRows(stray)
        obs, _ = env.reset(seed=0)
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            for _ in range(3):
                after, reward, terminated, truncated, info = env.step(1)
                [batch] = rows.step(obs[None], after[None], np.array([terminated or truncated]), [info])
                obs = after
        assert info["rac"]["proven"] is (scale == "proven") and reward == (1.0 if scale else 0.5)
        assert batch.location.tolist() == [1]  # Never
        found[scale] = (batch.reward.tolist(), [str(w.message) for w in caught if "counterfactual" in str(w.message)])
    assert found["proven"][0] == [1.0] and found[None] == ([20.0], [])
    [said] = found["proven"][1]
    assert "location `Never` got a reward of 40 under scale='proven'" in said and "W0302" in said
