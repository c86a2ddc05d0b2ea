"""RewardAutomatonWrapper and RewardAutomatonVectorWrapper on a small highway-like environment."""

from __future__ import annotations

import dataclasses
import math
import warnings
from fractions import Fraction
from typing import Any

import gymnasium
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env
from gymnasium.vector import AutoresetMode, SyncVectorEnv
from gymnasium.wrappers import TimeLimit
from highway_like import FOLLOW, HighwayLike, follow, inputs, vector_inputs

import rac
from rac import ir
from rac.check.analysis.scale import sample_change_bound
from rac.compiler import compile_text
from rac.learning.wrappers import (
    RewardAutomatonVectorWrapper,
    RewardAutomatonWrapper,
    env_timing,
    highway_steps,
    within_proven,
)
from rac.runtime.interpreter import RewardAutomaton

ENV_ID = "rac-test/HighwayLike-v0"
if ENV_ID not in gymnasium.registry:
    gymnasium.register(ENV_ID, entry_point=HighwayLike, max_episode_steps=30)


def wrapped(**kwargs: Any) -> RewardAutomatonWrapper:
    return RewardAutomatonWrapper(gymnasium.make(ENV_ID), follow(), inputs, clip=True, **kwargs)


def test_check_env_and_make_from_the_spec() -> None:
    with warnings.catch_warnings():
        warnings.simplefilter("error", UserWarning)  # the timing matches: no warning
        env = wrapped(scale="proven")
    check_env(env, skip_render_check=True)
    remade = gymnasium.make(env.spec)
    assert isinstance(remade, RewardAutomatonWrapper) and remade.scale == env.scale
    a, b = env.reset(seed=4), remade.reset(seed=4)
    assert a[0].tolist() == b[0].tolist()
    assert [env.step(2)[1] for _ in range(5)] == [remade.step(2)[1] for _ in range(5)]


def test_clip_must_be_a_bool() -> None:
    """clip="yes" (or "no", or 1) was taken by its truth: "no" clipped every input."""
    for clip in ("yes", "no", 1, None):
        with pytest.raises(TypeError, match=f"clip must be True or False, not {clip!r}"):
            RewardAutomatonWrapper(gymnasium.make(ENV_ID), follow(), inputs, clip=clip)
        with pytest.raises(TypeError, match=f"clip must be True or False, not {clip!r}"):
            RewardAutomatonVectorWrapper(SyncVectorEnv([lambda: TimeLimit(HighwayLike(), 30)]), follow(),
                                         vector_inputs, clip=clip)
    env = RewardAutomatonWrapper(gymnasium.make(ENV_ID), follow(), inputs, clip=np.True_)  # NumPy's bool is one
    assert env.reset(seed=1) is not None


def test_the_inputs_may_read_the_environment() -> None:
    seen = []

    def three(obs: Any, info: dict[str, Any], env: gymnasium.Env) -> dict[str, object]:
        seen.append(env.unwrapped.road)  # type: ignore[attr-defined]
        return inputs(obs, info)

    env = RewardAutomatonWrapper(gymnasium.make(ENV_ID), follow(), three, clip=True)
    env.reset(seed=0)
    env.step(1)
    assert seen == ["the road"]
    # a third parameter with a default is the caller's own (it was handed the environment)

    def tuned(obs: Any, info: dict[str, Any], limit: float = 2.0) -> dict[str, object]:
        return {"headway": float(obs[0]), "collide": bool(info["collision"]) and float(obs[0]) < limit}

    def with_env(obs: Any, info: dict[str, Any], env: Any = None) -> dict[str, object]:
        seen.append(env.unwrapped.road)
        return inputs(obs, info)

    for given in (tuned, with_env):
        env = RewardAutomatonWrapper(gymnasium.make(ENV_ID), follow(), given, clip=True)
        env.reset(seed=0)
        env.step(1)
    assert seen == ["the road", "the road"]


def test_a_generated_class_instead_of_an_instance_is_refused_at_once() -> None:
    import types

    from rac.targets.python import generate_python

    module = types.ModuleType("follow_generated")
    exec(compile(generate_python(follow()), "<generated>", "exec"), module.__dict__)  # noqa: S102
    cls = getattr(module, module.__all__[0])
    with pytest.raises(TypeError, match=rf"automaton is the class {cls.__name__}: pass an instance"):
        RewardAutomatonWrapper(gymnasium.make(ENV_ID), cls, inputs)
    env = RewardAutomatonWrapper(gymnasium.make(ENV_ID), cls(), lambda obs, info: {"headway": 5.0, "collide": False})
    env.reset(seed=0)
    assert isinstance(env.step(1)[1], float)


def test_out_of_range_inputs_are_clipped_and_counted_and_nan_refused() -> None:
    env = RewardAutomatonWrapper(gymnasium.make(ENV_ID), follow(), inputs)
    env.reset(seed=1)
    env.unwrapped.gap = 40.0  # type: ignore[attr-defined]
    with pytest.raises(ValueError, match=r"input 'headway' = 3\d\.\d+ is outside \[0.0, 10.0\]"):
        env.step(1)
    env = wrapped()
    env.reset(seed=1)
    env.unwrapped.gap = 40.0  # type: ignore[attr-defined]
    info = env.step(1)[4]
    assert info["rac"]["clipped"] == {"headway": 1} and env.clipped_total == {"headway": 1}
    assert info["rac"]["inputs"] == {"headway": 10.0, "collide": False}  # what the automaton read: clipped
    env.unwrapped.gap = 5.0  # type: ignore[attr-defined]
    info = env.step(1)[4]
    assert info["rac"]["clipped"] == {"headway": 0} and env.clipped_total == {"headway": 1}
    nan = RewardAutomatonWrapper(gymnasium.make(ENV_ID), follow(), lambda o, i: {"headway": math.nan,
                                                                                   "collide": False}, clip=True)
    nan.reset(seed=0)
    with pytest.raises(ValueError, match="'headway' is NaN"):
        nan.step(1)


def test_a_refused_input_names_clip_and_the_state_things_are_in() -> None:
    # an input outside its range (a gap to an empty lane) is the usual first error: the message named
    # the value only, not clip=True (the fix), nor that the environment had stepped and the automaton not
    env = RewardAutomatonWrapper(gymnasium.make(ENV_ID), follow(), inputs)
    env.reset(seed=1)
    env.unwrapped.gap = 40.0  # type: ignore[attr-defined]
    with pytest.raises(ValueError, match=r"is outside \[0.0, 10.0\] \(clip=True clips headway .*; the environment "
                                         r"has taken this step and the automaton has not: reset"):
        env.step(1)
    missing = RewardAutomatonWrapper(gymnasium.make(ENV_ID), follow(), lambda o, i: {"headway": 3.0})
    missing.reset(seed=0)
    with pytest.raises(ValueError, match=r"^missing input\(s\): collide; the environment has taken") as raised:
        missing.step(1)
    assert "clip" not in str(raised.value)  # clipping would not have helped
    vector = RewardAutomatonVectorWrapper(SyncVectorEnv([lambda: TimeLimit(HighwayLike(), 30)] * 2), follow(),
                                          lambda o, i: {**vector_inputs(o, i), "headway": np.array([1.0, 40.0])})
    vector.reset(seed=0)
    with pytest.raises(ValueError, match=r"'headway'\[1\] = 40.0 is outside .*clip=True clips headway.*the "
                                         r"environments have taken this step"):
        vector.step(np.ones(2, dtype=int))


def test_a_nan_under_clip_says_the_state_things_are_in_too() -> None:
    # clip=True refuses a NaN before the automaton sees it: that refusal was a bare "input 'headway' is NaN,
    # which is never clipped", without what every other refusal says (the environment stepped, reset next)
    env = RewardAutomatonWrapper(gymnasium.make(ENV_ID), follow(), lambda o, i: {"headway": float("nan"),
                                                                                  "collide": False}, clip=True)
    env.reset(seed=0)
    with pytest.raises(ValueError, match=r"'headway' is NaN, which is never clipped; the environment has taken this "
                                         r"step and the automaton has not: reset"):
        env.step(1)
    vector = RewardAutomatonVectorWrapper(SyncVectorEnv([lambda: TimeLimit(HighwayLike(), 30)] * 2), follow(),
                                          lambda o, i: {**vector_inputs(o, i), "headway": np.array([1.0, np.nan])},
                                          clip=True)
    vector.reset(seed=0)
    with pytest.raises(ValueError, match=r"'headway'\[1\] is NaN, which is never clipped; the environments have "
                                         r"taken this step and the automata have not"):
        vector.step(np.ones(2, dtype=int))
    assert vector.clipped_total == {} and env.clipped_total == {}  # nothing counted for a refused step


@pytest.mark.parametrize("clip", [False, True])
@pytest.mark.parametrize("returned", [None, (3.0, False)], ids=["none", "tuple"])
def test_inputs_that_return_no_mapping_are_said_so(clip: bool, returned: object) -> None:
    # an inputs() that forgot its `return` gave "TypeError: 'NoneType' object is not iterable" from the
    # clip rule (or from the refusal's clip hint), naming neither inputs() nor the state things are in
    env = RewardAutomatonWrapper(gymnasium.make(ENV_ID), follow(), lambda o, i: returned, clip=clip)
    env.reset(seed=0)
    with pytest.raises(ValueError, match=rf"^inputs must map input names to values, not {type(returned).__name__}; "
                                         "the environment has taken this step"):
        env.step(1)
    vector = RewardAutomatonVectorWrapper(SyncVectorEnv([lambda: TimeLimit(HighwayLike(), 30)] * 2), follow(),
                                          lambda o, i: returned, clip=clip)
    vector.reset(seed=0)
    with pytest.raises(ValueError, match=rf"^inputs must map input names to values, not {type(returned).__name__}; "
                                         "the environments have taken this step"):
        vector.step(np.ones(2, dtype=int))


def test_a_0d_array_input_is_its_value_with_clip_as_without() -> None:
    # a 0-d array is the one value it holds, as the runtime reads it (it was refused, as an array of shape ()):
    # the wrapper treats it as that value, clipped and counted with clip, refused as that value without
    for clip in (False, True):
        said = []
        for headway in (np.array(40.0), 40.0):
            env = RewardAutomatonWrapper(gymnasium.make(ENV_ID), follow(),
                                         lambda o, i, h=headway: {"headway": h, "collide": False}, clip=clip)
            env.reset(seed=0)
            if clip:
                said.append((env.step(1)[1], env.clipped_total))
            else:
                with pytest.raises(ValueError) as raised:
                    env.step(1)
                said.append(str(raised.value))
        assert said[0] == said[1], said


def test_a_column_of_the_wrong_shape_is_named_under_clip_too() -> None:
    # obs[:, 0:1] is (n, 1): without clip the message named the shape, with clip it was numpy's own
    # "input operand has more dimensions than allowed by the axis remapping"
    vector = RewardAutomatonVectorWrapper(SyncVectorEnv([lambda: TimeLimit(HighwayLike(), 30)] * 2), follow(),
                                          lambda o, i: {**vector_inputs(o, i), "headway": np.array([[1.0], [40.0]])},
                                          clip=True)
    vector.reset(seed=0)
    with pytest.raises(ValueError, match=r"^input 'headway' must have shape \(2,\), not \(2, 1\); the environments"):
        vector.step(np.ones(2, dtype=int))


def test_proven_scale_keeps_every_reward_within_one_and_reports_the_steps() -> None:
    bound = sample_change_bound(follow())
    env, raw = wrapped(scale="proven"), wrapped()
    # a collision in Unsafe: 10 * (-0.1 - 20); the end bonus 5
    assert env.scale == float(bound.per_sample + bound.at_end) == 201 + 5
    for seed in range(5):
        env.reset(seed=seed)
        raw.reset(seed=seed)
        done = False
        while not done:
            action = seed % 3
            _, reward, terminated, truncated, info = env.step(action)
            _, unscaled, *_, raw_info = raw.step(action)
            assert -1.0 <= float(reward) <= 1.0
            assert reward == unscaled / env.scale and info["rac"]["scale"] == env.scale
            steps = info["rac"]["reward_steps"]
            assert sum(c * steps[r] for r, c in (("sa", 10), ("pr", 1))) == pytest.approx(unscaled)
            done = terminated or truncated
    assert wrapped(scale=20.0).scale == 20.0
    # a factor from a numpy array: np.float32 and np.int64 were refused as "not a positive number"
    assert wrapped(scale=np.float32(20.0)).scale == wrapped(scale=np.int64(20)).scale == 20.0
    for bad in (0, -1.0, "big", math.inf, True, np.float32("nan")):
        with pytest.raises(ValueError, match="scale"):
            wrapped(scale=bad)


# Its bound, 50, is reached by each entry into Wild (sa -= 5, weighted 10): the objective's increase is a
# difference of float sums, a rounding off -50.
SWING = """automaton Swing {
    input speed : real in [-8, 8]
    reward sa, pr
    priority sa > pr
    objective 10 * sa + pr
    sample every 0.05
    horizon 10
    initial location Calm { sa' == 0; pr' == 0 }
    location Wild         { sa' == -1; pr' == 0 }
    location Fast         { sa' == 0; pr' == 1 }
    edge * -> Wild when speed > 6 do sa = sa - 5
    edge * -> Calm when speed <= 6 && speed >= 1
    edge * -> Fast when speed < 1
}
"""


class Swinging(gymnasium.Env[np.ndarray, int]):
    """Observes the speed it plays back: wild four samples, calm one, then wild again."""

    observation_space = gymnasium.spaces.Box(-8.0, 8.0, shape=(1,), dtype=np.float64)
    action_space = gymnasium.spaces.Discrete(1)
    SPEEDS = (7.0, 7.0, 7.0, 7.0, 2.0, 7.0)

    def reset(self, *, seed: int | None = None,
              options: dict[str, Any] | None = None) -> tuple[np.ndarray, dict[str, Any]]:
        super().reset(seed=seed)
        self.t = 0
        return np.zeros(1), {}

    def step(self, action: int) -> tuple[np.ndarray, float, bool, bool, dict[str, Any]]:
        self.t += 1
        return np.array([self.SPEEDS[self.t - 1]]), 0.0, False, self.t >= len(self.SPEEDS), {}


def test_a_proven_scale_keeps_a_reward_at_the_bound_within_one_despite_rounding() -> None:
    """The last step's increase is -50.00000000000001 in floats, the bound 50: the reward was
    -1.0000000000000002, outside the [-1, 1] the proof and the docs promise (both wrappers)."""
    swing = rac.loads(SWING, "swing.ra")
    raw = RewardAutomatonWrapper(Swinging(), swing, lambda obs, info: {"speed": float(obs[0])})
    env = RewardAutomatonWrapper(Swinging(), swing, lambda obs, info: {"speed": float(obs[0])}, scale="proven")
    assert env.scale == 50.0
    raw.reset()
    env.reset()
    unscaled = [float(raw.step(0)[1]) for _ in Swinging.SPEEDS]
    assert abs(unscaled[-1]) > 50.0  # the rounding this test is about
    rewards = [float(env.step(0)[1]) for _ in Swinging.SPEEDS]
    assert rewards[-1] == -1.0 and all(-1.0 <= r <= 1.0 for r in rewards)
    vector = RewardAutomatonVectorWrapper(SyncVectorEnv([Swinging] * 2), swing,
                                          lambda obs, infos: {"speed": obs[:, 0]}, scale="proven")
    vector.reset(seed=0)
    batched = [vector.step(np.zeros(2, dtype=int))[1] for _ in Swinging.SPEEDS]
    assert batched[-1].tolist() == [-1.0, -1.0] and all(np.abs(b).max() <= 1.0 for b in batched)


def test_within_proven_leaves_rewards_past_a_rounding_as_they_are() -> None:
    # a value further out than a rounding is no rounding: it shows, not hidden on the bound
    assert within_proven(1.5, True) == 1.5 and within_proven(-1.0000000000000002, True) == -1.0
    assert within_proven(-1.0000000000000002, False) == -1.0000000000000002
    assert within_proven(np.array([1.0000000000000002, -2.0, 0.5]), True).tolist() == [1.0, -2.0, 0.5]


def test_timing_warnings_name_both_numbers() -> None:
    with pytest.warns(UserWarning, match=r"time step is 0.5 s but the automaton samples every 0.1 s.*priority proofs"):
        RewardAutomatonWrapper(TimeLimit(HighwayLike(dt=0.5), 6), follow(), inputs)
    with pytest.warns(UserWarning, match=r"episode has 50 steps \(5 s at 0.1 s a step\) but the automaton's horizon "
                                         r"has 30 samples \(3 s at 0.1 s a sample\)"):
        RewardAutomatonWrapper(gymnasium.make(ENV_ID, max_episode_steps=50), follow(), inputs)
    with pytest.warns(UserWarning, match="time step is 0.25 s"):
        RewardAutomatonWrapper(gymnasium.make(ENV_ID), follow(), inputs, dt=0.25)


def test_an_episode_past_the_horizon_under_another_time_step_says_steps_and_samples() -> None:
    # 60 steps of 0.05 s against 30 samples of 0.1 s warned "the environment's episode lasts 3 s ... but the
    # automaton's horizon is 3 s": the seconds agree, what differs is 60 steps against 30 samples
    with pytest.warns(UserWarning) as said:
        RewardAutomatonWrapper(TimeLimit(HighwayLike(dt=0.05), 60), follow(), inputs)
    [text] = [str(w.message) for w in said if "horizon has" in str(w.message)]
    assert text.startswith("the environment's episode has 60 steps (3 s at 0.05 s a step) but the automaton's "
                           "horizon has 30 samples (3 s at 0.1 s a sample), and one step is one sample"), text


def test_a_shorter_episode_is_no_timing_mismatch_and_a_longer_one_says_what_to_do() -> None:
    # an episode shorter than the horizon is a shorter run, which every proof covers, yet it warned "the priority
    # proofs cover runs ... over a horizon of 3 s only" (highway-env's roundabout-v0, 11 s, under a 30 s automaton);
    # and neither warning said what to do
    with warnings.catch_warnings():
        warnings.simplefilter("error", UserWarning)
        RewardAutomatonWrapper(TimeLimit(HighwayLike(dt=0.1), 20), follow(), inputs)
        RewardAutomatonVectorWrapper(SyncVectorEnv([lambda: TimeLimit(HighwayLike(dt=0.1), 20)]), follow(),
                                     vector_inputs)
    # steps are samples, whatever the seconds: 2 s of 0.05 s steps are 40 samples, past the 30 of the horizon
    with pytest.warns(UserWarning) as said:
        RewardAutomatonWrapper(TimeLimit(HighwayLike(dt=0.05), 40), follow(), inputs)
    texts = [str(w.message) for w in said]
    assert any("time step is 0.05 s" in text and "make the two agree" in text for text in texts), texts
    assert any("has 40 steps (2 s at 0.05 s a step)" in text and "TimeLimit(env, 30)" in text for text in texts), texts
    with pytest.warns(UserWarning, match=r"has 50 steps \(5 s.*SyncVectorEnv\(\[lambda: gymnasium.wrappers.Time"):
        RewardAutomatonVectorWrapper(SyncVectorEnv([lambda: TimeLimit(HighwayLike(dt=0.1), 50)]), follow(),
                                     vector_inputs)


def test_gymnasiums_autoreset_is_refused_inside_and_restarts_the_automaton_outside() -> None:
    # Autoreset inside: the step after an episode's end, a reset, went to the ended automaton, and training ended
    # at the first episode's end with "inputs(obs, info) raised KeyError" (a reset info) or "the run has ended"
    from gymnasium.wrappers import Autoreset

    with pytest.raises(ValueError, match=r"Autoreset sits inside.*Autoreset\(RewardAutomatonWrapper\(env, \.\.\.\)\)"):
        RewardAutomatonWrapper(Autoreset(TimeLimit(HighwayLike(), 5)), follow(), inputs, clip=True)
    env = Autoreset(RewardAutomatonWrapper(TimeLimit(HighwayLike(), 5), follow(), inputs, clip=True))
    env.reset(seed=0)
    steps = [env.step(0) for _ in range(12)]  # two episodes of 5 steps and the reset steps after them
    assert [step[3] for step in steps] == [False] * 4 + [True] + [False] * 5 + [True, False]
    assert sum(step[1] for step in steps[6:11]) == pytest.approx(steps[10][4]["rac"]["objective"])  # at end too


def test_inputs_taking_too_few_arguments_are_refused_at_construction() -> None:
    # inputs(obs) was taken, and the first step raised after the environment had stepped
    with pytest.raises(TypeError, match=r"inputs must take \(obs, info\) or \(obs, info, env\), not 1 positional"):
        RewardAutomatonWrapper(HighwayLike(), follow(), lambda obs: {})
    with pytest.raises(TypeError, match=r"inputs must take \(obs, infos\) or \(obs, infos, env\), not 0 positional"):
        RewardAutomatonVectorWrapper(SyncVectorEnv([HighwayLike]), follow(), lambda: {})
    RewardAutomatonWrapper(HighwayLike(), follow(), lambda *args: inputs(*args[:2]))  # *args takes them all


@pytest.mark.parametrize("dt", [0, 0.0, -0.1, math.nan, math.inf, "0.1", True])
def test_a_time_step_that_is_no_positive_number_is_refused(dt: object) -> None:
    # 0 ended the construction in ZeroDivisionError, "0.1" in TypeError; NaN, -0.1, inf and True gave warnings
    # of nonsense ("the environment's episode lasts -2 s")
    with pytest.raises(ValueError, match="dt must be the environment's seconds per step, a positive number"):
        RewardAutomatonWrapper(TimeLimit(HighwayLike(), 30), follow(), inputs, dt=dt)  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="dt must be"):
        RewardAutomatonVectorWrapper(SyncVectorEnv([HighwayLike]), follow(), vector_inputs, dt=dt)  # type: ignore[arg-type]


def test_a_float32_time_step_equal_to_the_period_is_no_mismatch() -> None:
    # np.float32(0.1) (a configuration read as float32) warned "time step is 0.1 s but the automaton samples every
    # 0.1 s"; an environment's own float32 dt was not read at all (no timing checked)
    with warnings.catch_warnings():
        warnings.simplefilter("error", UserWarning)
        RewardAutomatonWrapper(TimeLimit(HighwayLike(), 30), follow(), inputs, dt=np.float32(0.1))  # type: ignore[arg-type]
        RewardAutomatonWrapper(TimeLimit(HighwayLike(dt=np.float32(0.1)), 30), follow(), inputs)  # type: ignore[arg-type]
    with pytest.warns(UserWarning, match="time step is 0.2 s"):
        RewardAutomatonWrapper(TimeLimit(HighwayLike(dt=np.float32(0.2)), 30), follow(), inputs)  # type: ignore[arg-type]
    with pytest.warns(UserWarning, match=r"episode has 31 steps \(3.1 s"):
        RewardAutomatonWrapper(TimeLimit(HighwayLike(), 31), follow(), inputs, dt=np.float32(0.1))  # type: ignore[arg-type]


def test_a_time_limit_around_an_unregistered_environment_is_checked() -> None:
    # the docs put the limit inside the wrapper as RewardAutomatonWrapper(TimeLimit(env, n), ...); around
    # an environment made without an id the TimeLimit's spec is None, and an episode of 5 s against
    # the automaton's 3 s went unsaid (so did the vector wrapper's own advice, SyncVectorEnv of TimeLimits)
    assert HighwayLike(dt=0.1).spec is None
    assert env_timing(TimeLimit(HighwayLike(dt=0.1), 50)) == (0.1, 5.0)
    assert env_timing(TimeLimit(TimeLimit(HighwayLike(dt=0.1), 20), 50)) == (0.1, 2.0)  # the first limit reached
    with pytest.warns(UserWarning, match=r"episode has 50 steps \(5 s at 0.1 s a step\) but the automaton's horizon "
                                         r"has 30 samples \(3 s at 0.1 s a sample\)"):
        RewardAutomatonWrapper(TimeLimit(HighwayLike(dt=0.1), 50), follow(), inputs)
    with pytest.warns(UserWarning, match=r"episode has 50 steps \(5 s at 0.1 s a step\)"):
        RewardAutomatonVectorWrapper(SyncVectorEnv([lambda: TimeLimit(HighwayLike(dt=0.1), 50)] * 2), follow(),
                                     vector_inputs)


def test_timing_is_checked_again_when_the_environment_is_reconfigured() -> None:
    # highway-env's usual pattern: make, wrap, then env.unwrapped.configure({...}) and reset(); the
    # wrapper checked the timing at construction only, and the new one went unsaid
    inner = HighwayLike(dt=0.1)
    env = RewardAutomatonWrapper(TimeLimit(inner, 30), follow(), inputs)
    with warnings.catch_warnings():
        warnings.simplefilter("error", UserWarning)
        env.reset(seed=0)  # the same timing as at construction: nothing new to say
    inner.dt = 0.2  # type: ignore[attr-defined]
    with pytest.warns(UserWarning, match=r"time step is 0.2 s but the automaton samples every 0.1 s"):
        env.reset(seed=1)
    with warnings.catch_warnings():
        warnings.simplefilter("error", UserWarning)
        env.reset(seed=2)  # said once per timing


def test_highway_env_timing_is_read_from_its_config() -> None:
    class Highway:
        config = {"policy_frequency": 5, "duration": 40}

    assert env_timing(Highway()) == (0.2, 40.0)
    assert env_timing(object()) == (None, None)
    # gymnasium.make("highway-fast-v0", max_episode_steps=40): the episode ends at whichever limit comes
    # first, here 40 steps of 0.2 s (8 s) before the 40 s duration; the spec won, whatever its length
    for steps, seconds in ((40, 8.0), (1000, 40.0)):
        limited = Highway()
        limited.spec = gymnasium.envs.registration.EnvSpec("rac-test/Limited-v0", max_episode_steps=steps)  # type: ignore[attr-defined]
        assert env_timing(limited) == (0.2, seconds)


class Clocked(HighwayLike):
    """HighwayLike truncated as highway-env truncates: its clock adds ``1 / policy_frequency`` per step, in floats,
    and the episode ends once it reaches ``duration``."""

    def __init__(self, frequency: int, duration: float) -> None:
        super().__init__(dt=1 / frequency)
        self.config = {"policy_frequency": frequency, "duration": duration}
        self.time = 0.0

    def reset(self, *, seed: int | None = None,
              options: dict[str, Any] | None = None) -> tuple[np.ndarray, dict[str, Any]]:
        self.time = 0.0
        return super().reset(seed=seed, options=options)

    def step(self, action: int) -> tuple[np.ndarray, float, bool, bool, dict[str, Any]]:
        self.time += 1 / self.config["policy_frequency"]
        obs, reward, terminated, _, info = super().step(action)
        return obs, reward, terminated, self.time >= self.config["duration"], info


def test_a_highway_env_duration_that_its_clock_reaches_a_step_late_is_counted() -> None:
    # highway-env at policy_frequency 5 with a duration of 10 s sums 0.2 s 50 times to 9.999999999999996, so its
    # episodes last 51 steps: one past the 50 samples of an automaton sampled every 0.2 s for 10 s, where the
    # construction said nothing (10 s of 0.2 s steps) and the proofs stopped a step before the episode did
    longer = FOLLOW.replace("sample every 0.1", "sample every 0.2").replace("horizon 3", "horizon 10")
    slower = compile_text(longer.replace("sa = sa - 10", "sa = sa - 100"), "follow.ra").raise_for_errors()
    env = Clocked(5, 10)
    env.reset(seed=0)
    env.gap = 1e9  # no crash before the clock ends it
    steps = 1
    while not env.step(1)[3]:
        steps += 1
    assert steps == 51 == highway_steps(env.config)
    assert env_timing(env)[1] == pytest.approx(10.2)
    with pytest.warns(UserWarning, match=r"has 51 steps \(10.2 s at 0.2 s a step: highway-env ends it once its clock, "
                                         r"adding 1/5 s a step in floats, reaches the duration of 10 s, which after 50 "
                                         r"steps it misses by a rounding\) but the automaton's horizon has 50 "
                                         r"samples \(10 s"):
        RewardAutomatonWrapper(Clocked(5, 10), slower, inputs, clip=True)
    with warnings.catch_warnings():  # 9.9 s: 50 steps, within the horizon, as the clock counts them too
        warnings.simplefilter("error", UserWarning)
        RewardAutomatonWrapper(Clocked(5, 9.9), slower, inputs, clip=True)
    assert highway_steps({"policy_frequency": 1, "duration": 30}) == 30 and highway_steps({"duration": 30}) is None


#: Follow whose episode ends when the gap closes below 3 m or opens to 9.5 m (where its end bonus applies).
FOLLOW_ENDS = dataclasses.replace(follow(), episode_ends=ir.BOr((ir.BAtom("headway", "<", Fraction(3)),
                                                                 ir.BAtom("headway", ">=", Fraction(19, 2)))))


@pytest.mark.parametrize("automaton", [follow(), FOLLOW_ENDS], ids=["follow", "episode-ends"])
def test_the_vector_wrapper_equals_single_wrappers_over_whole_episodes(automaton: ir.Automaton) -> None:
    """With `episode ends when`, episodes the automaton ends while the environment goes on are reset by
    the vector wrapper on the next step, as a single wrapper's user resets after `terminated`."""
    n, seed = 3, 7
    vector = RewardAutomatonVectorWrapper(
        SyncVectorEnv([lambda: TimeLimit(HighwayLike(), 30) for _ in range(n)]), automaton, vector_inputs,
        clip=True, scale="proven")
    singles = [RewardAutomatonWrapper(TimeLimit(HighwayLike(), 30), automaton, inputs, clip=True, scale="proven")
               for _ in range(n)]
    vector.reset(seed=seed)
    for i, single in enumerate(singles):
        single.reset(seed=seed + i)
    rng = np.random.default_rng(0)
    resetting = [False] * n
    episodes = 0
    ended_early = 0
    for _ in range(120):
        actions = rng.integers(0, 3, n)
        obs, rewards, terminated, truncated, infos = vector.step(actions)
        assert infos["_rac"].all()
        for i, single in enumerate(singles):
            if resetting[i]:
                single_obs, _ = single.reset()
                assert rewards[i] == 0.0 and infos["rac"]["location"][i] == "Safe" and not infos["rac"]["_inputs"][i]
                assert obs[i].tolist() == single_obs.tolist() and not terminated[i] and not truncated[i]
                resetting[i] = False
                continue
            single_obs, reward, term, trunc, info = single.step(int(actions[i]))
            ended_early += bool(term) and not single.env.unwrapped.gap <= 0.0  # the automaton ended it
            assert obs[i].tolist() == single_obs.tolist()
            assert rewards[i] == reward
            assert (term, trunc) == (terminated[i], truncated[i])
            assert infos["rac"]["location"][i] == info["rac"]["location"]
            assert infos["rac"]["reward_steps"]["sa"][i] == info["rac"]["reward_steps"]["sa"]
            assert infos["rac"]["clipped"]["headway"][i] == info["rac"]["clipped"]["headway"]
            assert infos["rac"]["_inputs"][i]
            assert {k: v[i] for k, v in infos["rac"]["inputs"].items()} == info["rac"]["inputs"]
            if term or trunc:
                resetting[i] = True
                episodes += 1
    assert episodes >= n  # whole episodes, with autoreset
    assert (ended_early > 0) == (automaton.episode_ends is not None)
    assert vector.clipped_total == {"headway": sum(s.clipped_total.get("headway", 0) for s in singles)}


class Gap(gymnasium.Env):
    """Observation [gap]; the action is the next gap (a fake environment that never ends by itself)."""

    observation_space = gymnasium.spaces.Box(0.0, 10.0, (1,), dtype=np.float32)
    action_space = gymnasium.spaces.Box(0.0, 10.0, (1,), dtype=np.float32)

    def reset(self, *, seed: int | None = None,
              options: dict[str, Any] | None = None) -> tuple[np.ndarray, dict[str, Any]]:
        super().reset(seed=seed)
        return np.array([5.0], dtype=np.float32), {"collision": False}

    def step(self, action: Any) -> tuple[np.ndarray, float, bool, bool, dict[str, Any]]:
        return np.asarray(action, dtype=np.float32).reshape(1), 0.0, False, False, {"collision": False}


class Goal(Gap):
    """Gap as a goal environment: its own reward is compute_reward's, as highway-env's parking-v0."""

    def compute_reward(self, achieved_goal: Any, desired_goal: Any, info: Any) -> float:
        return -1.0


def test_hindsight_relabelling_cannot_reach_the_wrapped_environments_reward() -> None:
    # stable-baselines3's HerReplayBuffer relabels with env_method("compute_reward"), which resolves it
    # through the wrappers (get_wrapper_attr): it found the goal environment's and mixed its reward,
    # silently, into the automaton's
    env = RewardAutomatonWrapper(Goal(), follow(), inputs)
    with pytest.raises(NotImplementedError, match="depends on the run so far.*HerReplayBuffer"):
        env.get_wrapper_attr("compute_reward")(np.zeros(1), np.zeros(1), {})


class Reach(gymnasium.Env[Any, Any]):
    """A goal environment as stable-baselines3's HerReplayBuffer takes it: move a point towards a goal in 10 steps."""

    observation_space = gymnasium.spaces.Dict({key: gymnasium.spaces.Box(0.0, 10.0, (1,), dtype=np.float32)
                                               for key in ("observation", "achieved_goal", "desired_goal")})
    action_space = gymnasium.spaces.Box(-1.0, 1.0, (1,), dtype=np.float32)

    def _obs(self) -> dict[str, np.ndarray]:
        here = np.array([self.x], dtype=np.float32)
        return {"observation": here, "achieved_goal": here, "desired_goal": np.array([8.0], dtype=np.float32)}

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None) -> Any:
        super().reset(seed=seed)
        self.x, self.t = 5.0, 0
        return self._obs(), {"collision": False}

    def step(self, action: Any) -> Any:
        self.x, self.t = float(np.clip(self.x + float(np.asarray(action).reshape(-1)[0]), 0.0, 10.0)), self.t + 1
        return self._obs(), 0.0, False, self.t >= 10, {"collision": False}

    def compute_reward(self, achieved_goal: Any, desired_goal: Any, info: Any) -> Any:
        return -np.abs(np.asarray(achieved_goal) - np.asarray(desired_goal)).sum(axis=-1)


def test_the_callback_refuses_hindsight_relabelling_before_the_first_step() -> None:
    # the wrapper refuses compute_reward, but HerReplayBuffer asks for it only when it first samples: after
    # learning_starts steps and a complete episode SAC ended there, minutes into a run with large settings
    pytest.importorskip("stable_baselines3", reason="the callback needs stable-baselines3 (pip install 'rac[rl]')")
    from stable_baselines3 import SAC, HerReplayBuffer

    from rac.learning.sb3 import RacCallback

    def automaton_inputs(obs: Any, info: dict[str, Any]) -> dict[str, object]:
        return {"headway": float(obs["observation"][0]), "collide": False}

    env = RewardAutomatonWrapper(Reach(), follow(), automaton_inputs)
    model = SAC("MultiInputPolicy", env, replay_buffer_class=HerReplayBuffer, learning_starts=20, buffer_size=200,
                seed=0, device="cpu")
    with pytest.raises(NotImplementedError, match="depends on the run so far.*start of learn"):
        model.learn(60, callback=RacCallback())
    assert model.num_timesteps == 0
    # the plain replay buffer is no matter
    SAC("MultiInputPolicy", env, learning_starts=10, buffer_size=200, batch_size=16, seed=0, device="cpu").learn(
        15, callback=RacCallback())

    class Relabel(gymnasium.Wrapper[Any, Any, Any, Any]):
        """A wrapper outside rac's that answers compute_reward itself: HerReplayBuffer asks it, not rac's."""

        def compute_reward(self, achieved_goal: Any, desired_goal: Any, info: Any) -> Any:
            return np.zeros(np.shape(achieved_goal)[:-1])

    answered = SAC("MultiInputPolicy", Relabel(env), replay_buffer_class=HerReplayBuffer, learning_starts=10,
                   buffer_size=200, batch_size=16, seed=0, device="cpu")
    answered.learn(15, callback=RacCallback())  # a complete episode (10 steps), then relabelled samples
    assert answered.num_timesteps == 15


def test_the_automaton_ends_the_episode_with_its_end_clauses() -> None:
    env = RewardAutomatonWrapper(Gap(), FOLLOW_ENDS, inputs)
    reference = RewardAutomaton(FOLLOW_ENDS)
    env.reset(seed=0)
    for gap in (5.0, 8.0):
        _, reward, terminated, truncated, _ = env.step(np.array([gap]))
        assert reward == reference.step({"headway": gap, "collide": False}) and not terminated and not truncated
    _, reward, terminated, truncated, info = env.step(np.array([9.5]))
    expected = reference.step({"headway": 9.5, "collide": False})  # the end bonus pr + 5 in this step
    assert terminated and not truncated and reward == expected and info["rac"]["rewards"] == reference.rewards
    assert info["rac"]["reward_steps"]["pr"] == pytest.approx(5.1) and env.automaton.ended  # type: ignore[attr-defined]
    with pytest.raises(RuntimeError, match="the run has ended"):
        env.step(np.array([5.0]))  # gymnasium's contract: reset after terminated
    env.reset()
    assert not env.step(np.array([4.0]))[2]


def test_the_vector_wrapper_refuses_other_autoreset_modes() -> None:
    env = SyncVectorEnv([HighwayLike], autoreset_mode=AutoresetMode.SAME_STEP)
    with pytest.raises(ValueError, match="NEXT_STEP"):
        RewardAutomatonVectorWrapper(env, follow(), vector_inputs)


class Counting(Gap):
    """Gap whose reset info says so and whose step info counts the steps (the two infos tell apart)."""

    def reset(self, *, seed: int | None = None,
              options: dict[str, Any] | None = None) -> tuple[np.ndarray, dict[str, Any]]:
        self.t = 0
        obs, _ = super().reset(seed=seed)
        return obs, {"collision": False, "reset": True}

    def step(self, action: Any) -> tuple[np.ndarray, float, bool, bool, dict[str, Any]]:
        self.t += 1
        obs, reward, terminated, truncated, _ = super().step(action)
        return obs, reward, terminated, truncated, {"collision": False, "t": self.t}


def gap_inputs(obs: np.ndarray, infos: dict[str, Any]) -> dict[str, object]:
    return {"headway": obs[:, 0].astype(np.float64), "collide": False}


def test_a_forced_reset_reports_the_reset_info() -> None:
    # the automaton ended env 0's episode (headway >= 9.5) while the env went on: the next step resets it,
    # and its info is the reset's, as NEXT_STEP's autoreset gives (it was the discarded step's)
    from rac.learning.vector_info import split_vector_info

    vector = RewardAutomatonVectorWrapper(SyncVectorEnv([Counting, Counting]), FOLLOW_ENDS, gap_inputs)
    vector.reset(seed=0)
    _, _, terminated, _, _ = vector.step(np.array([[9.5], [5.0]], dtype=np.float32))
    assert terminated.tolist() == [True, False]
    _, rewards, terminated, _, infos = vector.step(np.array([[5.0], [5.0]], dtype=np.float32))
    first, second = split_vector_info(infos)
    assert rewards[0] == 0.0 and not terminated[0]
    assert first.get("reset") is True and "t" not in first
    assert second["t"] == 2 and "reset" not in second


def test_a_partial_reset_resets_those_automata_only() -> None:
    # gymnasium >= 1.1: reset(options={"reset_mask": m}) resets the selected sub-environments; the
    # wrapper reset every automaton, and the others' returns stopped matching their objectives
    vector = RewardAutomatonVectorWrapper(SyncVectorEnv([Counting, Counting]), follow(), gap_inputs)
    vector.reset(seed=0)
    for _ in range(3):
        vector.step(np.array([[5.0], [5.0]], dtype=np.float32))
    kept = vector.automaton.objective[1]
    vector.reset(options={"reset_mask": np.array([True, False])})
    assert vector.automaton.samples.tolist() == [0, 3] and vector.automaton.objective[1] == kept
    vector.step(np.array([[5.0], [5.0]], dtype=np.float32))
    assert vector.automaton.samples.tolist() == [1, 4]
    with pytest.raises(ValueError, match="reset_mask"):
        vector.reset(options={"reset_mask": np.array([True, False, True])})


def test_infos_made_a_list_inside_the_vector_wrapper_are_refused_saying_where_it_goes() -> None:
    # gymnasium's DictInfoToList inside the vector wrapper handed it a list of dicts: reset ended in "ValueError:
    # dictionary update sequence element #0 has length 3; 2 is required", naming nothing of either
    from gymnasium.wrappers.vector import DictInfoToList

    with pytest.raises(ValueError, match=r"DictInfoToList sits inside it: put gymnasium's DictInfoToList outside it, "
                                         r"DictInfoToList\(RewardAutomatonVectorWrapper\(envs, ...\)\)"):
        RewardAutomatonVectorWrapper(DictInfoToList(SyncVectorEnv([Gap, Gap])), FOLLOW_ENDS, gap_inputs)

    class Listing(gymnasium.vector.VectorWrapper):  # a vector environment of one's own with SB3's info layout
        def reset(self, **kwargs: Any) -> tuple[Any, Any]:
            obs, infos = self.env.reset(**kwargs)
            return obs, [{} for _ in range(self.num_envs)]

    vector = RewardAutomatonVectorWrapper(Listing(SyncVectorEnv([Gap, Gap])), FOLLOW_ENDS, gap_inputs)
    with pytest.raises(ValueError, match="the vector environment's reset gave list infos"):
        vector.reset(seed=0)
    outside = DictInfoToList(RewardAutomatonVectorWrapper(SyncVectorEnv([Gap, Gap]), FOLLOW_ENDS, gap_inputs))
    outside.reset(seed=0)
    infos = outside.step(np.array([[5.0], [9.5]], dtype=np.float32))[4]
    assert [info["rac"]["location"] for info in infos] == ["Safe", "Safe"]


def test_reward_wrappers_outside_are_said_in_a_loop_without_stable_baselines3() -> None:
    # CleanRL's make_env puts NormalizeReward and a clipping TransformReward around every environment: around the
    # automaton's reward the learner's reward is no longer the automaton's, and only stable-baselines3's RacCallback
    # said so; a loop of one's own trained on it without a word
    from gymnasium.wrappers import NormalizeReward, RecordEpisodeStatistics, TransformReward

    def cleanrl() -> gymnasium.Env[Any, Any]:
        env = RecordEpisodeStatistics(RewardAutomatonWrapper(TimeLimit(HighwayLike(), 30), follow(), inputs, clip=True))
        return TransformReward(NormalizeReward(env), lambda reward: float(np.clip(reward, -10, 10)))

    envs = SyncVectorEnv([cleanrl, cleanrl])
    with pytest.warns(UserWarning, match=r"^gymnasium's NormalizeReward, TransformReward around the reward automaton's "
                                         r"reward changes every reward the learner sees") as said:
        envs.reset(seed=0)
    assert all(w.filename == __file__ for w in said if "NormalizeReward" in str(w.message))
    with warnings.catch_warnings():
        warnings.simplefilter("error", UserWarning)
        envs.reset(seed=1)  # said once per environment
        envs.step(np.ones(2, dtype=int))
        # inside the automaton's wrapper it changes a reward the automaton's replaces: nothing to say
        RewardAutomatonWrapper(NormalizeReward(TimeLimit(HighwayLike(), 30)), follow(), inputs, clip=True).reset(seed=0)
    vector = gymnasium.wrappers.vector.NormalizeReward(RewardAutomatonVectorWrapper(
        SyncVectorEnv([lambda: TimeLimit(HighwayLike(), 30)] * 2), follow(), vector_inputs, clip=True))
    with pytest.warns(UserWarning, match=r"^gymnasium's NormalizeReward around the reward automaton's reward"):
        vector.reset(seed=0)


class GapVector(gymnasium.vector.VectorEnv):  # type: ignore[type-arg]
    """Gap's vector form, with a reset that ignores options["reset_mask"] and restarts every sub-environment, as
    gymnasium's own CartPoleVectorEnv (gymnasium.make_vec("CartPole-v1")'s default) does."""

    metadata = {"autoreset_mode": AutoresetMode.NEXT_STEP}

    def __init__(self, num_envs: int) -> None:
        self.num_envs = num_envs
        self.single_observation_space = Gap.observation_space
        self.single_action_space = Gap.action_space
        self.observation_space = gymnasium.vector.utils.batch_space(Gap.observation_space, num_envs)
        self.action_space = gymnasium.vector.utils.batch_space(Gap.action_space, num_envs)

    def reset(self, *, seed: int | None = None,
              options: dict[str, Any] | None = None) -> tuple[np.ndarray, dict[str, Any]]:
        return np.full((self.num_envs, 1), 5.0, dtype=np.float32), {}

    def step(self, actions: Any) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, dict[str, Any]]:
        off = np.zeros(self.num_envs, dtype=bool)
        return np.asarray(actions, dtype=np.float32), np.zeros(self.num_envs), off, off, {}


def test_a_vector_env_that_ignores_the_reset_mask_is_refused() -> None:
    # env 0's automaton ends its episode (headway >= 9.5); the next step resets env 0 alone through reset_mask. A
    # vector environment that ignores the mask restarted env 1 too, whose automaton went on over its new episode,
    # in silence; it is refused there, and so is a masked reset of the user's
    vector = RewardAutomatonVectorWrapper(GapVector(2), FOLLOW_ENDS, gap_inputs)
    vector.reset(seed=0)
    vector.step(np.array([[9.5], [6.0]], dtype=np.float32))
    with pytest.raises(ValueError, match="GapVector restarted sub-environments that options.'reset_mask'. did not "
                                         "select, in the reset the wrapper asks for.*vectorization_mode='sync'"):
        vector.step(np.array([[5.0], [6.0]], dtype=np.float32))
    vector.reset(seed=0)
    vector.step(np.array([[6.0], [7.0]], dtype=np.float32))
    with pytest.raises(ValueError, match=r"in reset\(options=\{'reset_mask': ...\}\)"):
        vector.reset(options={"reset_mask": np.array([True, False])})
    # a class that says it honours the mask (masked_resets = True, as ScenarioVectorEnv) is taken at its word
    declared = type("Declared", (GapVector,), {"masked_resets": True})
    trusted = RewardAutomatonVectorWrapper(declared(2), FOLLOW_ENDS, gap_inputs)
    trusted.reset(seed=0)
    trusted.step(np.array([[9.5], [6.0]], dtype=np.float32))
    assert trusted.step(np.array([[5.0], [6.0]], dtype=np.float32))[1][0] == 0.0
    # SyncVectorEnv resets the selected sub-environment alone: the other keeps its observation, and goes on
    honest = RewardAutomatonVectorWrapper(SyncVectorEnv([Gap, Gap]), FOLLOW_ENDS, gap_inputs)
    honest.reset(seed=0)
    honest.step(np.array([[9.5], [6.0]], dtype=np.float32))
    obs, rewards, *_ = honest.step(np.array([[5.0], [6.0]], dtype=np.float32))
    assert obs[:, 0].tolist() == [5.0, 6.0] and rewards[0] == 0.0 and honest.automaton.samples.tolist() == [0, 2]


def test_gymnasiums_cartpole_vector_env_ignores_the_reset_mask_and_is_refused() -> None:
    # gymnasium.make_vec("CartPole-v1", num_envs=n) is gymnasium's CartPoleVectorEnv, whose reset restarts every
    # sub-environment whatever the mask
    envs = gymnasium.make_vec("CartPole-v1", num_envs=2)
    ends = dataclasses.replace(follow(), episode_ends=ir.BAtom("headway", "<", Fraction(3)))
    vector = RewardAutomatonVectorWrapper(envs, ends, lambda obs, infos: {"headway": np.where(obs[:, 0] > 0.01, 1.0,
                                                                                            5.0), "collide": False})
    vector.reset(seed=0)
    with pytest.raises(ValueError, match="CartPoleVectorEnv restarted sub-environments"):
        for _ in range(100):  # env 0 pushed right until its cart passes 0.01 m: the automaton ends its episode
            vector.step(np.array([1, 0]))


@pytest.mark.parametrize("scale", [None, "proven"])
def test_an_episode_past_the_horizon_is_said_once(scale: str | None) -> None:
    # an environment without a time step (nothing to compare) and longer episodes than the automaton's
    # 30 samples: the 31st sample's reward is beyond the proofs (and the proven scale's bound)
    env = RewardAutomatonWrapper(Gap(), follow(), inputs, scale=scale)
    env.reset(seed=0)
    with warnings.catch_warnings():
        warnings.simplefilter("error", UserWarning)
        for _ in range(30):
            env.step(np.array([5.0]))
    also = "and the proven scale " if scale else ""
    with pytest.warns(UserWarning, match=f"past the automaton's horizon of 30 samples: the priority proofs {also}"):
        env.step(np.array([5.0]))
    with warnings.catch_warnings():
        warnings.simplefilter("error", UserWarning)
        env.step(np.array([5.0]))  # said once
    vector = RewardAutomatonVectorWrapper(SyncVectorEnv([Counting, Counting]), follow(), gap_inputs, scale=scale)
    vector.reset(seed=0)
    for _ in range(30):
        vector.step(np.array([[5.0], [5.0]], dtype=np.float32))
    with pytest.warns(UserWarning, match="past the automaton's horizon of 30 samples"):
        vector.step(np.array([[5.0], [5.0]], dtype=np.float32))


def test_the_vector_wrapper_checks_the_timing_of_an_async_vector_env() -> None:
    # AsyncVectorEnv keeps its sub-environments in worker processes (no .envs): the timing was not
    # checked at all; it is read from one made from its first env_fns
    from gymnasium.vector import AsyncVectorEnv

    envs = AsyncVectorEnv([lambda: TimeLimit(HighwayLike(dt=0.5), 6) for _ in range(2)])
    try:
        with pytest.warns(UserWarning, match=r"time step is 0.5 s but the automaton samples every 0.1 s"):
            RewardAutomatonVectorWrapper(envs, follow(), vector_inputs)
    finally:
        envs.close()
    same = AsyncVectorEnv([lambda: TimeLimit(HighwayLike(), 30) for _ in range(2)])
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("error", UserWarning)
            RewardAutomatonVectorWrapper(same, follow(), vector_inputs).reset(seed=0)
    finally:
        same.close()


class Cutting(gymnasium.Wrapper):  # type: ignore[type-arg]
    """A step limit that is no gymnasium ``TimeLimit``: rac cannot read its limit, only see its cuts."""

    def __init__(self, env: gymnasium.Env, steps: int) -> None:  # type: ignore[type-arg]
        super().__init__(env)
        self.steps, self.taken = steps, 0

    def reset(self, **kwargs: Any) -> Any:
        self.taken = 0
        return self.env.reset(**kwargs)

    def step(self, action: Any) -> Any:
        obs, reward, terminated, truncated, info = self.env.step(action)
        self.taken += 1
        return obs, reward, terminated, truncated or self.taken >= self.steps, info


def test_a_time_limit_outside_the_wrapper_is_said_at_its_first_cut() -> None:
    """TimeLimit(RewardAutomatonWrapper(...), N), as gymnasium.make(id, max_episode_steps=N) around
    ScenarioEnv: the limit is read from the TimeLimit calling reset, and its first cut warns at that
    step (the warning waited for a second cut, at the reset after it)."""
    outside = TimeLimit(RewardAutomatonWrapper(Gap(), follow(), inputs), 4)
    outside.reset(seed=0)
    with warnings.catch_warnings():
        warnings.simplefilter("error", UserWarning)
        for _ in range(3):
            outside.step(np.array([6.0]))
    with pytest.warns(UserWarning, match=r"a TimeLimit outside rac \(max_episode_steps=4\) cuts episodes after 4 "
                                         r"step\(s\).*`at end` clauses were not applied.*put the limit inside"):
        assert outside.step(np.array([6.0]))[3]
    with warnings.catch_warnings():  # said once
        warnings.simplefilter("error", UserWarning)
        for seed in range(1, 3):
            outside.reset(seed=seed)
            for _ in range(4):
                outside.step(np.array([6.0]))


def test_an_episode_cut_outside_the_wrapper_is_said_at_the_next_reset() -> None:
    # a limit outside rac's wrapper: the wrapper never saw `truncated`, so the `at end` bonus
    # (pr + 5 at headway >= 5) was silently missing from the return
    outside = Cutting(RewardAutomatonWrapper(Gap(), follow(), inputs), 4)
    outside.reset(seed=0)
    truncated = False
    while not truncated:
        _, _, _, truncated, info = outside.step(np.array([6.0]))
    assert info["rac"]["rewards"]["pr"] == pytest.approx(0.4)  # no bonus: end() was never called
    with warnings.catch_warnings():
        warnings.simplefilter("error", UserWarning)
        outside.reset(seed=1)  # one cut episode may be a training run's end: a limit cuts every episode alike
        outside.step(np.array([6.0]))
        outside.reset(seed=2)  # nor does one of another length
        for _ in range(4):
            outside.step(np.array([6.0]))
    with pytest.warns(UserWarning, match=r"reset after 4 step\(s\) .*`at end` clauses were not applied.*"
                                         r"put the limit inside the rac wrapper"):
        outside.reset(seed=3)
    for _ in range(4):
        outside.step(np.array([6.0]))
    with warnings.catch_warnings():
        warnings.simplefilter("error", UserWarning)
        outside.reset(seed=4)  # said once
    inside = RewardAutomatonWrapper(TimeLimit(Gap(), 4), follow(), inputs)
    with warnings.catch_warnings():
        warnings.simplefilter("error", UserWarning)
        for seed in range(2):
            inside.reset(seed=seed)
            for _ in range(4):
                *_, info = inside.step(np.array([6.0]))
        assert info["rac"]["rewards"]["pr"] == pytest.approx(5.4)
        inside.reset(seed=3)  # an episode reset before its first step is no cut episode
        inside.reset(seed=4)


def test_training_runs_cut_between_complete_episodes_are_no_limit() -> None:
    """stable-baselines3's ``learn()`` resets its environment when it starts: called again and again
    (``for chunk in ...: model.learn(16)``), it cuts an episode at the same step of every chunk when the
    episodes have one length, with complete episodes between the cuts. That warned as a limit outside
    the wrapper, which cuts every episode; it is no limit, and the at end clauses of the complete ones applied."""
    env = RewardAutomatonWrapper(TimeLimit(Gap(), 6), follow(), inputs)
    with warnings.catch_warnings():
        warnings.simplefilter("error", UserWarning)
        for chunk in range(4):  # 16 steps a chunk: two complete episodes of 6, then 4 steps of the third
            env.reset(seed=chunk)
            for _ in range(16):
                *_, terminated, truncated, _ = env.step(np.array([6.0]))
                if terminated or truncated:
                    env.reset()
    outside = Cutting(RewardAutomatonWrapper(Gap(), follow(), inputs), 4)  # a limit outside still warns
    with pytest.warns(UserWarning, match=r"reset after 4 step\(s\)"):
        for seed in range(3):
            outside.reset(seed=seed)
            for _ in range(4):
                outside.step(np.array([6.0]))


def test_training_runs_shorter_than_an_episode_are_said_with_their_cause() -> None:
    """``for _ in range(5): model.learn(32)`` on episodes of more than 32 steps: each call resets the episode
    running, so none ever ends and no `at end` clause applies. The warning is right, but it named only a
    TimeLimit outside the wrapper; it now names SB3's ``learn()`` and ``reset_num_timesteps=False`` too."""
    env = RewardAutomatonWrapper(TimeLimit(Gap(), 50), follow(), inputs)
    with pytest.warns(UserWarning, match=r"reset after 4 step\(s\).*learn\(\) is called again and again.*"
                                         r"reset_num_timesteps=False"):
        for chunk in range(3):  # learn(4) three times: every chunk resets the episode at its 4th step
            env.reset(seed=chunk)
            for _ in range(4):
                env.step(np.array([6.0]))


def test_the_past_horizon_advice_puts_the_limit_inside() -> None:
    env = RewardAutomatonWrapper(Gap(), follow(), inputs)
    env.reset(seed=0)
    with pytest.warns(UserWarning, match=r"RewardAutomatonWrapper\(gymnasium.wrappers.TimeLimit\(env, 30\), ...\)"):
        for _ in range(31):
            env.step(np.array([5.0]))
    vector = RewardAutomatonVectorWrapper(SyncVectorEnv([Counting, Counting]), follow(), gap_inputs)
    vector.reset(seed=0)
    with pytest.warns(UserWarning, match=r"limit each sub-environment inside the vector environment.*"
                                         r"TimeLimit\(make_env\(\), 30\)"):
        for _ in range(31):
            vector.step(np.array([[5.0], [5.0]], dtype=np.float32))


def test_inputs_are_not_read_when_every_sub_environment_is_resetting() -> None:
    # episodes of one fixed length: every sub-environment truncates on the same step, so the next step
    # is everyone's reset step, whose infos lack the step-only key "t": inputs() was called anyway
    def step_only(obs: np.ndarray, infos: dict[str, Any]) -> dict[str, object]:
        assert "t" in infos, "a reset step's infos were read"
        return gap_inputs(obs, infos)

    vector = RewardAutomatonVectorWrapper(SyncVectorEnv([lambda: TimeLimit(Counting(), 3)] * 2), follow(), step_only)
    vector.reset(seed=0)
    action = np.array([[5.0], [5.0]], dtype=np.float32)
    for _ in range(3):
        *_, truncated, _ = vector.step(action)
    assert truncated.all()
    _, rewards, terminated, truncated, infos = vector.step(action)  # everyone's reset step
    assert rewards.tolist() == [0.0, 0.0] and not terminated.any() and not truncated.any()
    assert vector.automaton.samples.tolist() == [0, 0] and infos["rac"]["location"].tolist() == ["Safe", "Safe"]
    _, rewards, *_ = vector.step(action)
    assert vector.automaton.samples.tolist() == [1, 1] and (rewards != 0).all()


def test_a_monitor_inside_the_wrapper_is_said() -> None:
    # make_vec_env(..., wrapper_class=<rac wrapper>) puts SB3's Monitor inside: ep_rew_mean then
    # reported the environment's reward and missed the episodes the automaton ended
    pytest.importorskip("stable_baselines3")
    from stable_baselines3.common.env_util import make_vec_env
    from stable_baselines3.common.monitor import Monitor

    with pytest.warns(UserWarning, match=r"Monitor sits inside rac's wrapper.*make_vec_env\(lambda: "):
        venv = make_vec_env(ENV_ID, n_envs=1, wrapper_class=lambda env: RewardAutomatonWrapper(env, follow(), inputs))
    venv.close()
    with warnings.catch_warnings():
        warnings.simplefilter("error", UserWarning)
        outside = make_vec_env(lambda: RewardAutomatonWrapper(gymnasium.make(ENV_ID), follow(), inputs), n_envs=1)
        assert isinstance(outside.envs[0], Monitor)  # type: ignore[attr-defined]
        outside.close()
        Monitor(RewardAutomatonWrapper(gymnasium.make(ENV_ID), follow(), inputs)).close()


def test_episode_statistics_inside_the_wrapper_are_said() -> None:
    """gymnasium's RecordEpisodeStatistics inside rac's wrapper (a CleanRL-style make_env) sums the
    environment's own rewards: info['episode']['r'] was the environment's return, silently; outside it
    is the automaton's."""
    from gymnasium.wrappers import RecordEpisodeStatistics
    from gymnasium.wrappers.vector import RecordEpisodeStatistics as VectorStatistics

    with pytest.warns(UserWarning, match=r"RecordEpisodeStatistics sits inside rac's wrapper.*"
                                         r"RecordEpisodeStatistics\(RewardAutomatonWrapper\(env"):
        inside = RewardAutomatonWrapper(RecordEpisodeStatistics(TimeLimit(HighwayLike(), 3)), follow(), inputs,
                                        clip=True)
    inside.reset(seed=0)
    for _ in range(3):
        *_, info = inside.step(1)
    assert info["episode"]["r"] == 3.0 != info["rac"]["objective"]  # the environment's return, 1 a step
    with pytest.warns(UserWarning, match=r"RecordEpisodeStatistics sits inside.*vector.RecordEpisodeStatistics\("):
        RewardAutomatonVectorWrapper(VectorStatistics(SyncVectorEnv([lambda: TimeLimit(HighwayLike(), 3)] * 2)),
                                     follow(), vector_inputs)
    for kind in (SyncVectorEnv, gymnasium.vector.AsyncVectorEnv):  # in the sub-environments
        with pytest.warns(UserWarning, match=r"RecordEpisodeStatistics sits inside"):
            RewardAutomatonVectorWrapper(kind([lambda: RecordEpisodeStatistics(HighwayLike())] * 2),
                                         follow(), vector_inputs).close()
    with warnings.catch_warnings():  # (the 3 steps are not the automaton's horizon: the timing warns)
        warnings.filterwarnings("error", message=".*RecordEpisodeStatistics")
        outside = RecordEpisodeStatistics(RewardAutomatonWrapper(TimeLimit(HighwayLike(), 3), follow(), inputs,
                                                                  clip=True))
        outside.reset(seed=0)
        for _ in range(3):
            *_, info = outside.step(1)
        assert info["episode"]["r"] == pytest.approx(info["rac"]["objective"])
        VectorStatistics(RewardAutomatonVectorWrapper(SyncVectorEnv([lambda: TimeLimit(HighwayLike(), 3)] * 2),
                                                      follow(), vector_inputs))

class NumpyBools(Counting):
    """Counting whose step info holds a numpy bool (``action > 9``, as numpy comparisons give): gymnasium's
    vector info stores it in an object array, None in the rows of sub-environments being reset."""

    def step(self, action: Any) -> tuple[np.ndarray, float, bool, bool, dict[str, Any]]:
        obs, reward, terminated, truncated, info = super().step(action)
        return obs, reward, terminated or self.t >= 2, truncated, {**info, "collision": np.asarray(action)[0] > 9}


def test_numpy_bools_in_the_vector_info_are_booleans() -> None:
    # the batch refused the object column ("must hold booleans ..., not object values") on the first step
    vector = RewardAutomatonVectorWrapper(SyncVectorEnv([NumpyBools, NumpyBools]), follow(),
                                          lambda obs, infos: {"headway": obs[:, 0].astype(np.float64),
                                                              "collide": infos["collision"]})
    single = RewardAutomaton(follow())
    vector.reset(seed=0)
    rewards = vector.step(np.array([[5.0], [5.0]], dtype=np.float32))[1]
    assert rewards.tolist() == [single.step({"headway": 5.0, "collide": False})] * 2
    # env 1 is reset first (its own limit), env 0's row of that reset step holds None in the info's column
    vector.reset(options={"reset_mask": np.array([False, True])})
    _, rewards, terminated, _, infos = vector.step(np.array([[5.0], [5.0]], dtype=np.float32))
    assert infos["collision"].dtype == object and terminated.tolist() == [True, False]
    vector.step(np.array([[5.0], [5.0]], dtype=np.float32))  # env 0 in its reset step: its row (None) is not read
