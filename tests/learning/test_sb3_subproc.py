"""RacCallback's checks of the training environment where its environments live in other processes
(stable-baselines3's ``SubprocVecEnv``, as ``make_vec_env(..., vec_env_cls=SubprocVecEnv)`` builds it): they
cannot be walked from the learner's process, and the checks that walked a ``DummyVecEnv``'s ``envs`` saw nothing
there. ``start_method="fork"`` keeps each run to a second or two."""

from __future__ import annotations

import sys
import warnings
from collections.abc import Callable
from pathlib import Path
from typing import Any

import gymnasium
import numpy as np
import pytest
from gymnasium.wrappers import TimeLimit
from highway_like import HighwayLike, follow, inputs
from test_location_observation import Blank, alternate, took
from test_wrappers import Reach

from rac.learning.location_observation import LocationObservation
from rac.learning.wrappers import RewardAutomatonWrapper

pytest.importorskip("stable_baselines3", reason="the callback needs stable-baselines3 (pip install 'rac[rl]')")

from stable_baselines3 import DQN, PPO, SAC, HerReplayBuffer  # noqa: E402 - only where stable-baselines3 is installed
from stable_baselines3.common.env_util import make_vec_env  # noqa: E402
from stable_baselines3.common.vec_env import DummyVecEnv, SubprocVecEnv, VecEnv  # noqa: E402

from rac.learning import sb3  # noqa: E402


def automaton() -> RewardAutomatonWrapper:
    return RewardAutomatonWrapper(TimeLimit(HighwayLike(), 30), follow(), inputs, clip=True)


def subproc(make: Callable[[], gymnasium.Env[Any, Any]]) -> VecEnv:
    """Two environments ``make`` builds, each in a process of its own, under ``make_vec_env``'s ``Monitor``."""
    return make_vec_env(make, n_envs=2, seed=0, vec_env_cls=SubprocVecEnv, vec_env_kwargs={"start_method": "fork"})


def learned(model: Any, marker: str, steps: int = 16) -> list[str]:
    """The warnings whose text holds ``marker`` that ``model`` gives learning ``steps`` steps twice with one
    ``RacCallback`` (each of its warnings is said once)."""
    callback = sb3.RacCallback()
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        model.learn(steps, callback=callback)
        model.learn(steps, callback=callback, reset_num_timesteps=False)
    return [str(w.message) for w in caught if marker in str(w.message)]


def test_reward_changers_outside_the_automaton_are_seen_in_other_processes() -> None:
    # Asked env_is_wrapped(RewardAutomatonWrapper) first, SubprocVecEnv's environments with rac's wrapper answered
    # "no changer" whether NormalizeReward sat outside it (the learner's reward no longer the automaton's) or inside:
    # RacCallback's warning lapsed for every make_vec_env(..., vec_env_cls=SubprocVecEnv) run
    from gymnasium.wrappers import ClipReward, NormalizeReward, TransformReward

    def outside() -> gymnasium.Env[Any, Any]:
        return ClipReward(NormalizeReward(automaton()), -1.0, 1.0)

    def transformed() -> gymnasium.Env[Any, Any]:
        return TransformReward(automaton(), lambda reward: 2 * reward)

    def inside() -> gymnasium.Env[Any, Any]:
        return RewardAutomatonWrapper(NormalizeReward(TimeLimit(HighwayLike(), 30)), follow(), inputs, clip=True)

    def no_automaton() -> gymnasium.Env[Any, Any]:  # no automaton's reward to change
        return NormalizeReward(TimeLimit(HighwayLike(), 30))

    cases = ((outside, ["ClipReward", "NormalizeReward"]), (transformed, ["TransformReward"]), (inside, []),
             (no_automaton, []))
    for make, expected in cases:
        assert sb3.reward_changers(DummyVecEnv([make])) == expected  # the walk and the probes agree
        envs = subproc(make)
        try:
            assert sb3.reward_changers(envs) == expected, make.__name__
            if make is no_automaton:
                continue
            model = PPO("MlpPolicy", envs, n_steps=8, batch_size=16, n_epochs=1, seed=0, device="cpu")
            said = learned(model, "around the reward automaton's reward")
            assert said == []  # the workers said it (test_reward_changers_said_in_the_workers_are_not_said_again)
            assert sb3.reward_changers(envs) == expected  # still seen after learning
        finally:
            envs.close()


def test_reward_changers_said_in_the_workers_are_not_said_again(capfd: pytest.CaptureFixture[str]) -> None:
    # Each worker said at its first reset that NormalizeReward around the automaton changes its rewards, on the
    # terminal the learner shares; RacCallback, which asked only a DummyVecEnv's environments whether they had
    # said it, said it once more in the learner's process
    from gymnasium.wrappers import NormalizeReward

    def outside() -> gymnasium.Env[Any, Any]:
        return NormalizeReward(automaton())

    envs = make_vec_env(outside, n_envs=1, seed=0, vec_env_cls=SubprocVecEnv, vec_env_kwargs={"start_method": "fork"})
    try:
        model = PPO("MlpPolicy", envs, n_steps=8, batch_size=8, n_epochs=1, seed=0, device="cpu")
        said = learned(model, "around the reward automaton's reward")
        shown = capfd.readouterr().err
        assert shown.count("gymnasium's NormalizeReward around the reward automaton's reward") == 1, shown
        assert said == []
    finally:
        envs.close()


def test_frame_stacking_outside_the_location_is_seen_in_other_processes() -> None:
    # gymnasium's FrameStackObservation outside LocationObservation stacks the location's one-hot vectors, so
    # CounterfactualReplayBuffer's rows are no transitions the environment could have produced; frame_stacker
    # walked a DummyVecEnv's environments only, and under SubprocVecEnv RacCallback's warning never came
    from gymnasium.wrappers import FlattenObservation, FrameStackObservation

    def outside() -> gymnasium.Env[Any, Any]:
        return FlattenObservation(FrameStackObservation(LocationObservation(RewardAutomatonWrapper(
            Blank(), alternate(), took)), 2))

    def inside() -> gymnasium.Env[Any, Any]:
        return LocationObservation(RewardAutomatonWrapper(FlattenObservation(FrameStackObservation(Blank(), 2)),
                                                          alternate(), took))

    def no_location() -> gymnasium.Env[Any, Any]:  # stacked with no LocationObservation: counted, as in the walk
        return FlattenObservation(FrameStackObservation(RewardAutomatonWrapper(Blank(), alternate(), took), 2))

    for make, stacked in ((outside, True), (inside, False), (no_location, True)):
        expected = "FrameStackObservation" if stacked else None
        assert sb3.frame_stacker(DummyVecEnv([make])) == expected  # the walk and the probes agree
        envs = subproc(make)
        try:
            assert sb3.frame_stacker(envs) == expected, make.__name__
            if make is no_location:
                continue
            model = DQN("MlpPolicy", envs, learning_starts=1000, buffer_size=1000, seed=0, device="cpu",
                        replay_buffer_class=sb3.CounterfactualReplayBuffer,
                        replay_buffer_kwargs={"automaton": alternate()})
            said = learned(model, "under FrameStackObservation", steps=4)
            assert len(said) == (1 if stacked else 0), said
        finally:
            envs.close()


class Relabel(gymnasium.Wrapper[Any, Any, Any, Any]):
    """A wrapper outside rac's that answers compute_reward itself: HerReplayBuffer asks it, not rac's."""

    def compute_reward(self, achieved_goal: Any, desired_goal: Any, info: Any) -> Any:
        return np.zeros(np.shape(achieved_goal)[:-1])


def reach_inputs(obs: Any, info: dict[str, Any]) -> dict[str, object]:
    return {"headway": float(obs["observation"][0]), "collide": False}


def test_hindsight_relabelling_answered_outside_rac_is_not_refused_in_other_processes() -> None:
    # Under SubprocVecEnv, RacCallback refused HerReplayBuffer (NotImplementedError at the start of learn())
    # wherever rac's wrapper was, also where a wrapper outside it answers compute_reward itself and
    # HerReplayBuffer never asks rac's: a run that trains under DummyVecEnv could not start in other processes
    def answered() -> gymnasium.Env[Any, Any]:
        return Relabel(RewardAutomatonWrapper(Reach(), follow(), reach_inputs))

    def refused() -> gymnasium.Env[Any, Any]:
        return RewardAutomatonWrapper(Reach(), follow(), reach_inputs)

    for make in (answered, refused):
        envs = subproc(make)
        try:
            model = SAC("MultiInputPolicy", envs, replay_buffer_class=HerReplayBuffer, learning_starts=20,
                        buffer_size=200, batch_size=16, seed=0, device="cpu")
            if make is refused:
                with pytest.raises(NotImplementedError, match="depends on the run so far.*start of learn"):
                    model.learn(30, callback=sb3.RacCallback())
                assert model.num_timesteps == 0
            else:  # an episode (10 steps) in each process, then relabelled samples
                model.learn(30, callback=sb3.RacCallback())
                assert model.num_timesteps == 30
        finally:
            envs.close()


def test_an_environment_without_an_automaton_ends_no_process() -> None:
    # RacCallback asks every environment for its automaton's proof_subject at the start of learn() (the discounted
    # P2 check, gamma < 1: PPO's default 0.99); SubprocVecEnv's process for an environment without rac's wrapper
    # ended on the AttributeError, and learn() with EOFError, where the callback would have warned that no step's
    # info carries a reward automaton
    from stable_baselines3.common.monitor import Monitor

    def plain() -> gymnasium.Env[Any, Any]:
        return TimeLimit(HighwayLike(), 30)

    for make, seen in ((automaton, True), (plain, False)):
        envs = subproc(make)
        try:
            model = PPO("MlpPolicy", envs, n_steps=8, batch_size=16, n_epochs=1, seed=0, device="cpu")
            said = learned(model, "carry no reward automaton")
            assert len(said) == (0 if seen else 1), said
            if not seen:
                assert "step(s) of PPO" in said[0] and "RewardAutomatonWrapper" in said[0]
        finally:
            envs.close()
    # one process with the automaton, one without: the one that has it is asked, the other is not
    envs = SubprocVecEnv([lambda: Monitor(automaton()), lambda: Monitor(plain())], start_method="fork")
    try:
        assert [(a.name, n) for a, n in sb3.proof_subjects(envs)] == [("Follow", 1)]
        model = PPO("MlpPolicy", envs, n_steps=8, batch_size=16, n_epochs=1, seed=0, device="cpu", gamma=0.9)
        said = learned(model, "discounted by gamma=0.9")
        assert len(said) == 1 and "`Follow`" in said[0], said
    finally:
        envs.close()


def test_a_scenario_environment_under_counterfactual_rows_is_refused_in_other_processes(tmp_path: Path) -> None:
    # rac/Scenario-v0 with CounterfactualReplayBuffer was refused only at the first stored step; RacCallback refuses
    # it at the start of learn(), asking SubprocVecEnv's environments where they live
    from engine_files import write_engine_file

    from rac.compiler import compile_file
    from rac.learning.gym import ScenarioEnv

    scene = compile_file(write_engine_file(tmp_path, "avoidable_obstacle", queries={}))
    envs = subproc(lambda: LocationObservation(ScenarioEnv(scene)))
    try:
        assert sb3.scenario_environments(envs)
        model = DQN("MlpPolicy", envs, learning_starts=1000, buffer_size=1000, seed=0, device="cpu",
                    replay_buffer_class=sb3.CounterfactualReplayBuffer,
                    replay_buffer_kwargs={"automaton": scene.automaton})
        with pytest.raises(ValueError, match=r"scenario environments .* \(said at the start of learn\(\)"):
            model.learn(4, callback=sb3.RacCallback())
    finally:
        envs.close()
    plain = subproc(automaton)
    try:
        assert not sb3.scenario_environments(plain)
    finally:
        plain.close()


def test_normalised_locations_under_counterfactual_rows_are_refused_in_other_processes() -> None:
    # NormalizeObservation outside LocationObservation was refused only at the first stored step; RacCallback refuses
    # it at the start of learn() from the observations of the reset, wherever the environments live
    from gymnasium.wrappers import NormalizeObservation

    envs = subproc(lambda: NormalizeObservation(LocationObservation(RewardAutomatonWrapper(Blank(), alternate(),
                                                                                            took))))
    try:
        model = DQN("MlpPolicy", envs, learning_starts=1000, buffer_size=1000, seed=0, device="cpu",
                    replay_buffer_class=sb3.CounterfactualReplayBuffer, replay_buffer_kwargs={"automaton": alternate()})
        with pytest.raises(ValueError, match=r"not one-hot location vectors .* \(said at the start of learn\(\)"):
            model.learn(4, callback=sb3.RacCallback())
        assert model.num_timesteps == 0 and model.replay_buffer.size() == 0  # before any step
    finally:
        envs.close()

def test_a_warning_in_a_forked_worker_names_the_line_that_made_the_workers(tmp_path: Any) -> None:
    # a warning an environment gives in its SubprocVecEnv process named multiprocessing's process.py
    # (`self._target(*self._args, **self._kwargs)`): past the worker's launcher, a forked process still holds
    # the frames of the line that made it, the user's own
    where = tmp_path / "where.txt"

    def record(message: Any, category: Any, filename: str, lineno: int, *rest: Any) -> None:
        if "run past the automaton's horizon" in str(message):
            where.write_text(f"{filename}:{lineno}")

    def past_the_horizon() -> gymnasium.Env[Any, Any]:  # 40 steps of a 30-sample automaton, warned at step 31
        warnings.simplefilter("always")
        warnings.showwarning = record  # in the worker: its warnings, written where this test reads them
        return RewardAutomatonWrapper(TimeLimit(HighwayLike(), 40), follow(), inputs, clip=True)

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the timing warning of the construction here
        line = sys._getframe().f_lineno + 1  # the next one's
        envs = SubprocVecEnv([past_the_horizon], start_method="fork")
    try:
        envs.reset()
        for _ in range(31):
            envs.step(np.array([0]))  # slowing down: the gap only grows, no crash ends the episode early
    finally:
        envs.close()
    assert where.read_text() == f"{__file__}:{line}"


def test_masks_of_environments_without_them_end_no_process() -> None:
    # rac.learning.vector.action_masks asked a SubprocVecEnv's env_method("action_masks"); a process whose environment
    # has none ended on the AttributeError, and the parent got a bare EOFError
    from rac.learning.vector import action_masks

    envs = subproc(automaton)
    try:
        envs.reset()
        with pytest.raises(AttributeError, match=r"no action_masks\(\).*needs masks of its own"):
            action_masks(envs)  # type: ignore[arg-type]
        envs.step(np.array([1, 1]))  # the processes live on
    finally:
        envs.close()
