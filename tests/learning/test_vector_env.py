"""The registered ids (rac.gym) and the vector environment (rac.learning.vector.ScenarioVectorEnv).

``import rac.gym`` registers ``rac/Scenario-v0`` (idempotently, importing gymnasium only);
gymnasium.make / make_vec / the ``module:id`` form work, masks reach through gymnasium's wrappers
and SB3's vector envs, MaskablePPO trains on make_vec_env. ScenarioVectorEnv equals a SyncVectorEnv
of ScenarioEnvs step for step (observations, rewards, flags, info in the vector layout, masks) over
several autoreset episodes, with and without a shield; seeding and errors.
"""

from __future__ import annotations

import dataclasses
import importlib
import importlib.util
import subprocess
import sys
import warnings
from pathlib import Path
from typing import Any

import gymnasium
import numpy as np
import pytest
from engine_files import ALLOW_WHEN, engine_source, write_engine_file
from gymnasium.utils.env_checker import check_env
from tiny_scenarios import WALL_EGO, GoalBox, StraightRoad, straight_road

import rac.gym
from rac import ir
from rac.compiler import CompileResult, compile_file
from rac.engine import shield as shield_file
from rac.engine.explore import explore
from rac.engine.shield import ShieldTable
from rac.engine.storm import safety_shield
from rac.learning.episodes import EpisodeBatch
from rac.learning.location_observation import LocationObservation
from rac.learning.scenario_env import ScenarioEnv
from rac.learning.vector import ScenarioSyncVectorEnv, ScenarioVectorEnv, action_masks, make_vector_env
from rac.learning.wrappers import RewardAutomatonVectorWrapper, RewardAutomatonWrapper

SRC = Path(__file__).resolve().parents[2] / "src"


@pytest.fixture(scope="module")
def files(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    """The engine test file on avoidable_obstacle (a van ahead; episodes run to the horizon) and
    on goal_ahead (random episodes reach the goal at different steps)."""
    folder = tmp_path_factory.mktemp("vector")
    files = {name: write_engine_file(folder, name, queries={}) for name in ("avoidable_obstacle", "goal_ahead")}
    # an empty road with the goal 10 m ahead of the ego (8 m/s): episodes end after 1 to 4 steps
    near = straight_road("near_goal", StraightRoad(80.0, WALL_EGO, GoalBox(20.0, 30.0)))
    near.write(folder / "near_goal.xml")
    files["near_goal"] = folder / "near_goal.ra"
    files["near_goal"].write_text(engine_source(near, {}), encoding="utf-8")
    return files


@pytest.fixture(scope="module")
def tiny(files: dict[str, Path]) -> CompileResult:
    result = compile_file(files["avoidable_obstacle"])
    assert result.ok, [d.message for d in result.diagnostics]
    return result


@pytest.fixture(scope="module")
def goal(files: dict[str, Path]) -> CompileResult:
    result = compile_file(files["goal_ahead"])
    assert result.ok, [d.message for d in result.diagnostics]
    return result


@pytest.fixture(scope="module")
def near(files: dict[str, Path]) -> CompileResult:
    result = compile_file(files["near_goal"])
    assert result.ok, [d.message for d in result.diagnostics]
    return result


@pytest.fixture(scope="module")
def allowing(files: dict[str, Path]) -> CompileResult:
    """The tiny file with an `allow when` rule: no heading beyond 0.25 rad (turning on is forbidden there)."""
    path = files["avoidable_obstacle"].with_name("allowing.ra")
    text = files["avoidable_obstacle"].read_text(encoding="utf-8")
    path.write_text(text.replace("        bind near =", ALLOW_WHEN + "        bind near =", 1), encoding="utf-8")
    result = compile_file(path)
    assert result.ok and result.model_data is not None and result.model_data.allow is not None, result.diagnostics
    return result


@pytest.fixture(scope="module")
def tiny_ends(tiny: CompileResult) -> CompileResult:
    """The tiny file whose automaton ends the episode where the van is near (`episode ends when near`)."""
    assert tiny.automaton is not None
    return dataclasses.replace(tiny, automaton=dataclasses.replace(tiny.automaton, episode_ends=ir.BInput("near")))


@pytest.fixture(scope="module")
def table(tiny: CompileResult) -> ShieldTable:
    data = tiny.model_data
    assert data is not None
    shield = safety_shield(explore(data, horizon_samples=8, prune_unsafe=True), "safe")
    return shield_file.table(shield, n_actions=EpisodeBatch(tiny).n_actions, unseen="none")


def run(code: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120,
                          env={"PYTHONPATH": str(SRC), "PATH": "/usr/bin:/bin"})


def checked(env: Any) -> list[str]:
    """check_env's warnings, except those about wrappers and specs (check_env asks for the raw env) and those
    of its random actions, which a shield's mask may not allow, and of the states they lead to, which a shield may
    not cover (true, and tested on their own)."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        check_env(env)
    return [str(w.message) for w in caught if not any(part in str(w.message)
                                                      for part in ("unwrapped", "spec", "not in the mask",
                                                                   "no action was known to be safe"))]


# ---------------------------------------------------------------- registration
def test_rac_gym_is_light_and_registration_is_idempotent() -> None:
    done = run("import rac.gym, sys; assert 'rac.learning.scenario_env' not in sys.modules; "
               "assert 'rac.learning' not in sys.modules; import gymnasium; "
               "assert 'rac/Scenario-v0' in gymnasium.registry")
    assert done.returncode == 0, done.stderr
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        importlib.reload(rac.gym)
        rac.gym.register()
    assert gymnasium.spec(rac.gym.SCENARIO).max_episode_steps is None  # the env truncates at its horizon


def test_make_without_the_import_in_a_fresh_process(files: dict[str, Path]) -> None:
    model = str(files["goal_ahead"])
    done = run(f"import gymnasium; env = gymnasium.make('rac.gym:rac/Scenario-v0', model={model!r}); "
               "env.reset(seed=0); print(env.get_wrapper_attr('action_masks')().shape)")
    assert done.returncode == 0, done.stderr
    assert done.stdout.strip() == "(9,)"


def test_make_masks_through_the_wrappers_and_check_env(files: dict[str, Path], table: ShieldTable) -> None:
    env = gymnasium.make(rac.gym.SCENARIO, model=files["avoidable_obstacle"], shield=table)
    assert isinstance(env.unwrapped, ScenarioEnv) and env is not env.unwrapped
    assert not isinstance(env, gymnasium.wrappers.TimeLimit)
    env.reset(seed=0)
    masks = env.get_wrapper_attr("action_masks")()  # the supported way through gymnasium's wrappers
    assert masks.dtype == bool and masks.any() and not masks.all()  # the shield's mask: a van ahead
    assert (masks == env.unwrapped.action_masks()).all()  # type: ignore[attr-defined]
    assert checked(env) == [] and checked(env.unwrapped) == []


def test_a_vector_reward_wrapper_outside_is_said_at_the_first_reset(files: dict[str, Path]) -> None:
    # gymnasium's vector NormalizeReward around make_vec's ScenarioVectorEnv in a loop without stable-baselines3
    # changed the automaton's reward without a word
    import warnings

    envs = gymnasium.wrappers.vector.NormalizeReward(gymnasium.make_vec(rac.gym.SCENARIO, num_envs=2,
                                                                        model=files["goal_ahead"]))
    with pytest.warns(UserWarning, match=r"^gymnasium's NormalizeReward around the reward automaton's reward"):
        envs.reset(seed=0)
    with warnings.catch_warnings():  # said once; nothing around: nothing said
        warnings.simplefilter("error", UserWarning)
        envs.reset(seed=1)
        gymnasium.make_vec(rac.gym.SCENARIO, num_envs=2, model=files["goal_ahead"]).reset(seed=0)


def test_make_vec_uses_the_native_vector_env(files: dict[str, Path]) -> None:
    envs = gymnasium.make_vec(rac.gym.SCENARIO, num_envs=3, model=files["goal_ahead"])
    assert isinstance(envs, ScenarioVectorEnv) and envs.num_envs == 3
    obs, _ = envs.reset(seed=0)
    assert obs.shape == (3, envs.single_observation_space.shape[0]) and envs.observation_space.contains(obs)
    sync = gymnasium.make_vec(rac.gym.SCENARIO, num_envs=2, model=files["goal_ahead"], render_mode="ansi")
    assert isinstance(sync, gymnasium.vector.SyncVectorEnv)  # frames: each ScenarioEnv renders its own
    sync.reset()
    assert all("Normal" in line for line in sync.render())  # type: ignore[union-attr]
    for env in sync.envs:  # the sub-envs are plain ScenarioEnvs
        assert checked(env.unwrapped) == []
    sync = gymnasium.make_vec(rac.gym.SCENARIO, num_envs=2, vectorization_mode="sync", model=files["goal_ahead"])
    assert isinstance(sync, gymnasium.vector.SyncVectorEnv) and checked(sync.envs[0]) == []


def test_make_vec_refuses_max_episode_steps_naming_the_horizon(files: dict[str, Path], tiny: CompileResult) -> None:
    # gymnasium.make_vec hands max_episode_steps to the vector entry point: it failed with "unexpected
    # keyword argument" (a TypeError saying nothing of horizon=, the environment's own limit)
    period = float(tiny.automaton.model.decide_period)  # type: ignore[union-attr]
    for model in (files["avoidable_obstacle"], tiny):
        with pytest.raises(ValueError, match=rf"max_episode_steps=3 .*horizon={3 * period:g} \(3 decisions"):
            gymnasium.make_vec(rac.gym.SCENARIO, num_envs=2, model=model, max_episode_steps=3)
    with pytest.raises(ValueError, match=r"give horizon=<seconds> \(a whole number"):
        make_vector_env(2, model=files["avoidable_obstacle"], max_episode_steps=0)
    assert make_vector_env(2, model=tiny, max_episode_steps=None).num_envs == 2  # no limit: nothing to refuse


def test_make_vec_with_a_set_of_scenes_steps_scenario_envs(files: dict[str, Path]) -> None:
    """A set of scenes cannot share one batch: the entry point hands ``scenarios`` to ScenarioEnvs,
    each drawing its scene per episode."""
    scenes = [files[name].with_suffix(".xml") for name in ("avoidable_obstacle", "goal_ahead")]
    envs = gymnasium.make_vec(rac.gym.SCENARIO, num_envs=2, model=files["avoidable_obstacle"], scenarios=scenes)
    assert isinstance(envs, gymnasium.vector.SyncVectorEnv)
    drawn: set[str] = set()
    for seed in range(8):
        obs, info = envs.reset(seed=seed)
        assert envs.observation_space.contains(obs)
        drawn |= {Path(name).name for name in info["scenario"]}
    assert drawn == {scene.name for scene in scenes}
    assert isinstance(make_vector_env(num_envs=2, model=files["avoidable_obstacle"], scenarios=None),
                      ScenarioVectorEnv)


def test_both_vector_envs_offer_the_same_masks_and_calls(files: dict[str, Path], table: ShieldTable) -> None:
    """The same loop serves what make_vec returns with and without frames (or a set of scenes):
    ``action_masks()`` on the SyncVectorEnv (it had none), ``call``/``get_attr`` on ScenarioVectorEnv
    (it had none)."""
    native = gymnasium.make_vec(rac.gym.SCENARIO, num_envs=2, model=files["avoidable_obstacle"], shield=table)
    sync = gymnasium.make_vec(rac.gym.SCENARIO, num_envs=2, model=files["avoidable_obstacle"], shield=table,
                              render_mode="ansi")
    assert isinstance(native, ScenarioVectorEnv) and isinstance(sync, ScenarioSyncVectorEnv)
    native.reset(seed=0)
    sync.reset(seed=0)
    rng = np.random.default_rng(1)
    for _ in range(6):  # past the 4-step horizon: the restarted rows allow every action in both
        masks = native.action_masks()
        assert (masks == sync.action_masks()).all() and masks.any(axis=1).all()  # type: ignore[attr-defined]
        assert [row.tolist() for row in native.call("action_masks")] == [row.tolist() for row in masks]
        assert [row.tolist() for row in sync.call("action_masks")] == [row.tolist() for row in masks]
        actions = np.array([rng.choice(np.flatnonzero(row)) for row in masks])
        native.step(actions)
        sync.step(actions)
    assert native.shield_steps == sync.shield_steps and native.shield_steps  # type: ignore[attr-defined]
    assert native.no_safe_action_steps == sync.no_safe_action_steps  # type: ignore[attr-defined]
    assert native.disallowed_steps == sync.disallowed_steps == 0  # type: ignore[attr-defined]
    assert native.get_attr("reward_scale") == sync.get_attr("reward_scale") == (1.0, 1.0)
    assert native.call("action_pairs")[0].tolist() == sync.get_attr("action_pairs")[0].tolist()
    with pytest.raises(AttributeError, match="no ScenarioEnv per episode to give `episodes`"):
        native.get_attr("episodes")
    with pytest.raises(AttributeError, match="cannot set `reward_scale` per episode"):
        native.set_attr("reward_scale", [2.0, 2.0])


def test_actions_outside_the_masks_are_warned_of_once_and_counted_by_both(files: dict[str, Path],
                                                                          table: ShieldTable) -> None:
    # a learner that ignores the masks (PPO, DQN, predict without action_masks=) stepped unshielded, and
    # only the info key said it: a vector env's info is gathered away by SB3's and gymnasium's loops
    for sync in (False, True):
        envs = gymnasium.make_vec(rac.gym.SCENARIO, num_envs=2, model=files["avoidable_obstacle"], shield=table,
                                  render_mode="ansi" if sync else None)
        envs.reset(seed=0)
        masks = envs.action_masks()  # type: ignore[attr-defined]
        actions = np.array([int(np.flatnonzero(~row)[0]) for row in masks])  # neither in its mask
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            _, _, _, _, info = envs.step(actions)
        assert not info["shield_allowed"].any() and info["_shield_allowed"].all()
        said = [str(w.message) for w in caught if "not in the mask" in str(w.message)]
        assert said and "t = 0 s" in said[0] and "use_masking=False" in said[0], said
        assert envs.outside_mask_steps == 2  # type: ignore[attr-defined]
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            envs.reset(seed=0)
            envs.step(actions)
        assert not [w for w in caught if "not in the mask" in str(w.message)]  # said once
        assert envs.outside_mask_steps == 4  # type: ignore[attr-defined]


def test_masks_with_no_guarantee_are_warned_of_once_by_both(files: dict[str, Path], tiny: CompileResult) -> None:
    # a table for the first second of 4 s episodes and no runtime shield: past it every row of the masks allowed
    # every action, and only info['no_safe_action'] (gathered away by the training loop) said so
    data = tiny.model_data
    assert data is not None
    short = shield_file.table(safety_shield(explore(data, horizon_samples=2, prune_unsafe=True), "safe"),
                              n_actions=EpisodeBatch(tiny).n_actions)
    for sync in (False, True):
        envs = gymnasium.make_vec(rac.gym.SCENARIO, num_envs=2, model=files["avoidable_obstacle"], shield=short,
                                  lookahead=None, render_mode="ansi" if sync else None)
        envs.reset(seed=0)
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            for _ in range(4):
                masks = envs.action_masks()  # type: ignore[attr-defined]
                envs.step(np.array([int(np.flatnonzero(row)[0]) for row in masks]))
        said = [str(w.message) for w in caught if "no action was known to be safe" in str(w.message)]
        # SyncVectorEnv: each ScenarioEnv says it once
        assert len(said) == (2 if sync else 1) and "past the shield table's horizon" in said[0], said
        assert envs.no_safe_action_steps == 6  # type: ignore[attr-defined]


def test_masks_reach_through_stock_vector_wrappers(files: dict[str, Path], table: ShieldTable) -> None:
    """gymnasium 1.4's vector wrappers have no ``call``, ``get_attr`` or ``action_masks``: the advice
    ``envs.call("action_masks")`` failed on ``RecordEpisodeStatistics(envs)``; ``action_masks(envs)``
    asks the unwrapped environment, whichever make_vec returned."""
    from gymnasium.wrappers.vector import RecordEpisodeStatistics

    model = files["avoidable_obstacle"]
    made = {"native": gymnasium.make_vec(rac.gym.SCENARIO, num_envs=2, model=model, shield=table),
            "frames": gymnasium.make_vec(rac.gym.SCENARIO, num_envs=2, model=model, shield=table, render_mode="ansi"),
            "sync": gymnasium.make_vec(rac.gym.SCENARIO, num_envs=2, model=model, shield=table,
                                       vectorization_mode="sync")}
    reference = made["native"]
    assert isinstance(reference, ScenarioVectorEnv)
    wrapped = {name: RecordEpisodeStatistics(envs) for name, envs in made.items()}
    with warnings.catch_warnings():  # one step of the environment is one sample: the timing warns
        warnings.simplefilter("ignore", UserWarning)
        wrapped["rac"] = RecordEpisodeStatistics(RewardAutomatonVectorWrapper(
            ScenarioVectorEnv(model, num_envs=2, shield=table), compile_file(model).automaton,  # type: ignore[arg-type]
            lambda obs, infos: {"near": infos["inputs"]["near"]}))
    for envs in wrapped.values():
        assert not hasattr(envs, "call")  # what the advice relied on
        envs.reset(seed=0)
    for actions in ([4, 0], [0, 4]):
        masks = reference.unwrapped.action_masks()
        for name, envs in wrapped.items():
            assert action_masks(envs).tolist() == masks.tolist(), name
            envs.step(np.array(actions))
        reference.step(np.array(actions))
    with pytest.raises(AttributeError, match="neither action_masks"):
        action_masks(RecordEpisodeStatistics(gymnasium.make_vec("CartPole-v1", num_envs=2,
                                                                vectorization_mode="vector_entry_point")))


class Sb3Like:
    """What stable-baselines3's DummyVecEnv offers here (no SB3 in CI): ``unwrapped`` and ``env_method``, which
    resolves the name through each environment's wrappers."""

    def __init__(self, envs: list[gymnasium.Env]) -> None:  # type: ignore[type-arg]
        self.envs = envs
        self.unwrapped = self

    def env_method(self, name: str) -> list[Any]:
        return [env.get_wrapper_attr(name)() for env in self.envs]


def test_masks_of_a_stable_baselines3_vec_env(files: dict[str, Path], table: ShieldTable) -> None:
    # action_masks(venv) of SB3's VecEnv said "has neither action_masks() nor call(): not a vector environment
    # of ScenarioEnvs", although it was one
    envs = [gymnasium.make(rac.gym.SCENARIO, model=files["avoidable_obstacle"], shield=table) for _ in range(2)]
    for env in envs:
        env.reset(seed=0)
    envs[1].step(4)
    masks = action_masks(Sb3Like(envs))  # type: ignore[arg-type]
    assert masks.tolist() == [env.unwrapped.action_masks().tolist() for env in envs]  # type: ignore[attr-defined]
    if importlib.util.find_spec("stable_baselines3") is not None:  # the real one, where it is installed
        from stable_baselines3.common.vec_env import DummyVecEnv, VecNormalize

        venv = VecNormalize(DummyVecEnv([lambda: envs[0], lambda: envs[1]]))
        assert action_masks(venv).tolist() == masks.tolist()  # type: ignore[arg-type]


class SubprocLike:
    """What stable-baselines3's SubprocVecEnv does here (no SB3 in CI): each environment in a process of its own,
    whose loop (SB3's ``_worker``) answers ``env_method`` and catches EOFError alone, so that any other error of the
    method ends the process and the parent's ``recv`` gets EOFError."""

    def __init__(self, make: Any) -> None:
        import multiprocessing

        context = multiprocessing.get_context("fork")
        self.remote, work = context.Pipe()
        self.process = context.Process(target=self.worker, args=(work, make), daemon=True)
        self.process.start()
        work.close()
        self.unwrapped = self

    @staticmethod
    def worker(remote: Any, make: Any) -> None:
        import os

        os.dup2(os.open(os.devnull, os.O_WRONLY), 2)  # the traceback SB3's process prints: not in the test's output
        env = make()
        while True:
            try:
                name = remote.recv()
                remote.send(env.get_wrapper_attr(name)())
            except EOFError:
                break

    def env_method(self, name: str) -> list[Any]:
        self.remote.send(name)
        return [self.remote.recv()]


def test_masks_of_a_subprocess_vec_env_before_reset_say_what_happened(files: dict[str, Path]) -> None:
    # action_masks(venv) of SB3's SubprocVecEnv before reset(): ScenarioEnv's "call reset() before action_masks()"
    # ended the environment's process (SB3's worker ends on any error of env_method) and the parent got a bare
    # EOFError; rac cannot keep the process alive (masks without a reset would be no guarantee), but says what happened
    venv = SubprocLike(lambda: gymnasium.make(rac.gym.SCENARIO, model=files["avoidable_obstacle"]))
    try:
        with pytest.raises(RuntimeError, match=r"a process of the SubprocLike ended while answering action_masks\(\)"
                                                r".*call reset\(\) on the vector environment before action_masks"):
            action_masks(venv)  # type: ignore[arg-type]
    finally:
        venv.process.join(30)
        venv.process.kill()


def test_masks_of_a_subprocess_vec_env_without_them_are_refused_saying_so() -> None:
    # action_masks(venv) of SB3's SubprocVecEnv whose environments have no action_masks() ended in EOFError (the
    # worker died on the AttributeError of env_method) and left the VecEnv broken: it is refused, saying why
    pytest.importorskip("stable_baselines3", reason="needs stable-baselines3 (the rl extra)")
    from stable_baselines3.common.vec_env import DummyVecEnv, SubprocVecEnv

    for kind in (SubprocVecEnv, DummyVecEnv):
        makers = [lambda: gymnasium.make("CartPole-v1")] * 2
        venv = kind(makers, start_method="fork") if kind is SubprocVecEnv else kind(makers)  # type: ignore[abstract]
        try:
            with pytest.raises(AttributeError, match=r"no action_masks\(\): the masks are those of rac's "):
                action_masks(venv)  # type: ignore[arg-type]
            assert venv.reset().shape == (2, 4)  # the workers live on
        finally:
            venv.close()


def test_environments_without_masks_are_said_to_have_none() -> None:
    # gymnasium's own error named a wrapper ("wrapper TimeLimit has no attribute 'action_masks'"), not that masks are
    # the scenario environments' and another environment needs its own
    from gymnasium.vector import SyncVectorEnv
    from gymnasium.wrappers import TimeLimit
    from highway_like import HighwayLike

    envs = SyncVectorEnv([lambda: TimeLimit(HighwayLike(), 30)] * 2)
    envs.reset(seed=0)
    with pytest.raises(AttributeError, match=r"no action_masks\(\): the masks are those of rac's .*ActionMasker"):
        action_masks(envs)


def test_the_action_space_samples_within_the_masks_as_the_module_says(files: dict[str, Path],
                                                                     table: ShieldTable) -> None:
    """The module docstring's loop: ``action_space.sample(mask=tuple(masks.astype(np.int8)))`` draws
    allowed actions only (gymnasium's MultiDiscrete refuses the bool masks themselves)."""
    envs = ScenarioVectorEnv(files["avoidable_obstacle"], num_envs=3, shield=table)
    envs.reset(seed=0)
    envs.action_space.seed(2)
    for _ in range(6):
        masks = envs.action_masks()
        with pytest.raises(AssertionError, match="int8"):
            envs.action_space.sample(mask=tuple(masks))
        actions = envs.action_space.sample(mask=tuple(masks.astype(np.int8)))
        assert masks[np.arange(3), actions].all()
        envs.step(actions)


# ---------------------------------------------------------------- sb3-contrib
@pytest.mark.parametrize("extra", [{}, {"render_mode": None}])  # make_vec_env asks for rgb_array first
def test_maskable_ppo_on_make_vec_env(files: dict[str, Path], table: ShieldTable, extra: dict[str, Any]) -> None:
    pytest.importorskip("sb3_contrib", reason="sb3-contrib is not installed")
    from sb3_contrib import MaskablePPO
    from sb3_contrib.common.maskable.utils import get_action_masks, is_masking_supported
    from stable_baselines3.common.env_util import make_vec_env

    venv = make_vec_env(rac.gym.SCENARIO, n_envs=2, seed=0,
                        env_kwargs={"model": files["avoidable_obstacle"], "shield": table, "lookahead": None,
                                    **extra})
    assert is_masking_supported(venv)
    venv.reset()
    masks = get_action_masks(venv)  # DummyVecEnv.env_method -> get_wrapper_attr through Monitor and make's wrappers
    assert masks.shape == (2, 9) and masks.any(axis=1).all() and not masks.all()
    model = MaskablePPO("MlpPolicy", venv, n_steps=64, batch_size=32, n_epochs=1, seed=0, device="cpu")
    model.learn(256)
    assert model.num_timesteps >= 256
    steps = venv.get_attr("shield_steps")
    assert sum(sum(counter.values()) for counter in steps) >= 256
    allowed = [env.unwrapped.no_safe_action_steps for env in venv.envs]  # type: ignore[attr-defined]
    assert allowed == [0, 0]  # every state the learner met had a safe action in the table


def test_maskable_ppo_with_the_location_observed(files: dict[str, Path], table: ShieldTable) -> None:
    """LocationObservation as make_vec_env's wrapper_class: outside SB3's Monitor, masks through it."""
    pytest.importorskip("sb3_contrib", reason="sb3-contrib is not installed")
    from sb3_contrib import MaskablePPO
    from sb3_contrib.common.maskable.utils import get_action_masks
    from stable_baselines3.common.env_util import make_vec_env

    venv = make_vec_env(rac.gym.SCENARIO, n_envs=2, seed=0, wrapper_class=LocationObservation,
                        env_kwargs={"model": files["avoidable_obstacle"], "shield": table, "lookahead": None})
    names = venv.get_attr("locations")[0]
    assert venv.observation_space.shape == (29 + len(names),)
    obs = venv.reset()
    assert obs[:, 29:].tolist() == [[float(name == names[0]) for name in names]] * 2  # the initial location
    assert not get_action_masks(venv).all()
    model = MaskablePPO("MlpPolicy", venv, n_steps=64, batch_size=32, n_epochs=1, seed=0, device="cpu")
    model.learn(128)
    assert [env.unwrapped.no_safe_action_steps for env in venv.envs] == [0, 0]  # type: ignore[attr-defined]


# ---------------------------------------------------------------- equivalence with SyncVectorEnv
def assert_same(left: Any, right: Any, where: str) -> None:
    if isinstance(left, dict):
        assert isinstance(right, dict) and sorted(left) == sorted(right), (where, sorted(left), sorted(right))
        for key in left:
            assert_same(left[key], right[key], f"{where}.{key}")
    else:
        left, right = np.asarray(left), np.asarray(right)
        assert left.dtype == right.dtype and left.shape == right.shape, (where, left.dtype, right.dtype)
        assert (left == right).all(), (where, left, right)


@pytest.mark.parametrize("scene, shielded", [("near", False), ("tiny", False), ("tiny", True), ("tiny_ends", False),
                                             ("allowing", False)])
def test_equals_a_sync_vector_env(request: pytest.FixtureRequest, scene: str, shielded: bool) -> None:
    result: CompileResult = request.getfixturevalue(scene)
    shield = request.getfixturevalue("table") if shielded else None
    n = 4
    native = ScenarioVectorEnv(result, num_envs=n, shield=shield)
    sync = gymnasium.vector.SyncVectorEnv([lambda: ScenarioEnv(result, shield=shield) for _ in range(n)])
    assert native.single_observation_space == sync.single_observation_space
    assert native.single_action_space == sync.single_action_space
    assert native.observation_space == sync.observation_space and native.action_space == sync.action_space
    assert native.metadata["autoreset_mode"] == sync.metadata["autoreset_mode"]
    a, a_info = native.reset(seed=5)
    b, b_info = sync.reset(seed=5)
    assert_same(a, b, "obs")
    assert_same(a_info, b_info, "info")
    rng = np.random.default_rng(2)
    pending = np.zeros(n, dtype=bool)
    ended, staggered, by_automaton = 0, False, 0
    for step in range(40):
        masks = native.action_masks()
        other = np.stack([env.action_masks() for env in sync.envs])  # type: ignore[attr-defined]
        assert masks.any(axis=1).all()
        assert (masks[~pending] == other[~pending]).all() and masks[pending].all()
        actions = np.array([rng.choice(np.flatnonzero(row)) for row in masks])
        ignoring = rng.random(n) < 0.25  # a learner that does not read the masks takes any action
        actions[ignoring] = rng.integers(native.single_action_space.n, size=int(ignoring.sum()))
        a_out = native.step(actions)
        b_out = sync.step(actions)
        for name, x, y in zip(("obs", "reward", "terminated", "truncated", "info"), a_out, b_out):
            assert_same(x, y, f"step {step} {name}")
        pending = a_out[2] | a_out[3]
        ended += int(pending.sum())
        by_automaton += int((a_out[2] & ~a_out[4]["goal"]).sum())  # terminated without the goal
        staggered |= len(set(native.episodes.k.tolist())) > 1
    # near_goal: episodes of 1 to 4 steps, restarted apart; the van near ends some episodes early
    assert staggered == (scene in ("near", "tiny_ends"))
    assert (by_automaton > 0) == (scene == "tiny_ends")
    assert ended >= 2 * n  # several episodes each, restarted by autoreset
    singles = [env.unwrapped for env in sync.envs]
    assert native.shield_steps == sum((env.shield_steps for env in singles), start=type(native.shield_steps)())
    assert native.no_safe_action_steps == sum(env.no_safe_action_steps for env in singles)  # type: ignore[attr-defined]
    assert native.disallowed_steps == sum(env.disallowed_steps for env in singles)  # type: ignore[attr-defined]
    # without a shield the masks are the model's `allow when`: some steps took what it forbids, and say so
    assert (native.disallowed_steps > 0) == (scene == "allowing")


def test_episodes_end_at_different_steps(near: CompileResult) -> None:
    """near_goal: some episodes reach the goal before others, so restarts are staggered (and the
    equivalence test above sees episodes at different samples)."""
    envs = ScenarioVectorEnv(near, num_envs=8)
    envs.reset(seed=0)
    rng = np.random.default_rng(0)
    samples = set()
    for _ in range(12):
        envs.step(rng.integers(9, size=8))
        samples.add(len(set(envs.episodes.k.tolist())))
    assert max(samples) > 1


def test_seeded_runs_repeat(goal: CompileResult) -> None:
    def play(seed: int) -> list[np.ndarray]:
        envs = ScenarioVectorEnv(goal, num_envs=3)
        envs.reset(seed=seed)
        envs.action_space.seed(seed)
        seen = []
        for _ in range(10):
            draw = envs.np_random.integers(9, size=3)
            obs, reward, *_ = envs.step(draw)
            seen += [draw, obs, reward, envs.action_space.sample()]
        return seen

    first, again, other = play(3), play(3), play(4)
    assert all((x == y).all() for x, y in zip(first, again))
    assert not all((x == y).all() for x, y in zip(first, other))


def test_a_list_of_seeds_as_sync_vector_env_takes_it(goal: CompileResult) -> None:
    # gymnasium's vector API takes a seed per sub-environment (SyncVectorEnv: seed=s is [s, s+1, ...]);
    # ScenarioVectorEnv, which stands in for a SyncVectorEnv, failed on a list inside gymnasium's seeding
    envs, listed = ScenarioVectorEnv(goal, num_envs=3), ScenarioVectorEnv(goal, num_envs=3)
    first, _ = envs.reset(seed=5)
    again, _ = listed.reset(seed=[5, 6, 7])
    assert (first == again).all()
    assert (envs.np_random.integers(1000, size=4) == listed.np_random.integers(1000, size=4)).all()
    listed.reset(seed=[None, None, None])
    with pytest.raises(ValueError, match="num_envs=3 seeds, not 2"):
        listed.reset(seed=[1, 2])


def test_errors(tiny: CompileResult) -> None:
    with pytest.raises(ValueError, match="num_envs"):
        ScenarioVectorEnv(tiny, num_envs=0)
    with pytest.raises(ValueError, match="renders nothing"):
        ScenarioVectorEnv(tiny, num_envs=2, render_mode="ansi")
    envs = ScenarioVectorEnv(tiny, num_envs=2)
    with pytest.raises(RuntimeError, match="reset"):
        envs.step(np.zeros(2, dtype=int))
    envs.reset()
    with pytest.raises(ValueError, match="shape"):
        envs.step(np.zeros(3, dtype=int))
    with pytest.raises(ValueError, match="in \\[0, 9\\)"):
        envs.step(np.array([0, 9]))
    with pytest.raises(ValueError, match="reset_mask"):
        envs.reset(options={"reset_mask": np.array([True, False, True])})
    with pytest.raises(RuntimeError, match="call reset"):
        ScenarioVectorEnv(tiny, num_envs=2).reset(options={"reset_mask": np.array([True, False])})


def test_the_vector_wrapper_ends_episodes_on_the_native_vector_env(tiny: CompileResult,
                                                                     tiny_ends: CompileResult) -> None:
    """RewardAutomatonVectorWrapper with `episode ends when` restarts an episode its automaton ended
    while the environment goes on with ``reset(options={"reset_mask": ...})``: ScenarioVectorEnv
    refused the option (a ValueError at the first such episode); it restarts the rows selected."""
    assert tiny_ends.automaton is not None
    envs = ScenarioVectorEnv(tiny, num_envs=3, lookahead=None)
    with warnings.catch_warnings():  # one step of the environment is one sample: the timing warns
        warnings.simplefilter("ignore", UserWarning)
        vector = RewardAutomatonVectorWrapper(envs, tiny_ends.automaton,
                                              lambda obs, infos: {"near": infos["inputs"]["near"]})
    start, _ = vector.reset(seed=0)
    ended, restart = 0, np.zeros(3, dtype=bool)
    for _ in range(8):
        obs, rewards, terminated, truncated, infos = vector.step(np.array([4, 0, 8]))
        if restart.any():  # the rows the automaton ended in the last step: restarted now, as NEXT_STEP does
            assert obs[restart].tolist() == start[restart].tolist() and not rewards[restart].any()
            assert (infos["time"][restart] == 0.0).all() and not terminated[restart].any()
            assert set(infos["rac"]["location"][restart]) == {"Normal"}
            assert not infos["_shield"][restart].any()  # their info is a reset info
        restart = terminated & ~truncated & infos["inputs"]["near"]  # the automaton's end, not the model's
        ended += int(restart.sum())
    assert ended >= 4  # the van comes near in episodes 0 and 2 again and again
    partial = ScenarioVectorEnv(tiny, num_envs=2, lookahead=None)
    first, _ = partial.reset(seed=0)
    partial.step(np.array([4, 4]))
    obs, info = partial.reset(options={"reset_mask": np.array([False, True])})
    assert obs[1].tolist() == first[1].tolist() and obs[0].tolist() != first[0].tolist()
    assert info["_time"].tolist() == [False, True] and info["time"][1] == 0.0


# ---------------------------------------------------------------- the benchmark
def test_the_benchmark_runs(tmp_path: Path) -> None:
    """benchmarks/vector_env.py --quick writes its table (the speed itself is not asserted)."""
    from conftest import rac_env

    output = tmp_path / "vector_env.md"
    benchmark = SRC.parent / "benchmarks" / "vector_env.py"
    done = subprocess.run([sys.executable, str(benchmark), "--quick", "--seconds", "0.2", "--output", str(output)],
                          env=rac_env(), capture_output=True, text=True, timeout=300, check=False)
    assert done.returncode == 0, done.stdout + done.stderr
    text = output.read_text(encoding="utf-8")
    rows = [row.split("|")[1:3] for row in text.splitlines() if row.startswith("| Scenario")]
    assert [(name.strip(), int(n)) for name, n in rows] == [("ScenarioEnv", 1)] + [
        ("ScenarioVectorEnv", n) for n in (1, 16, 64, 256)]
    assert "64 episodes: " in text and ("met" in text.splitlines()[-1])


def test_the_vector_env_scales_as_scenario_env(near: CompileResult) -> None:
    plain = ScenarioVectorEnv(near, num_envs=3)
    scaled = ScenarioVectorEnv(near, num_envs=3, scale=4.0)
    plain.reset(seed=0)
    _, info = scaled.reset(seed=0)
    assert (info["scale"] == 4.0).all() and not info["proven"].any()  # one's own factor: not the proven one
    assert ScenarioVectorEnv(near, num_envs=2, scale="proven").reset(seed=0)[1]["proven"].tolist() == [True, True]
    nonzero = 0
    for step in range(8):
        actions = np.full(3, step % plain.single_action_space.n)
        raw = plain.step(actions)[1]
        reward = scaled.step(actions)[1]
        assert np.allclose(reward, raw / 4.0)
        nonzero += int((raw != 0).sum())
    assert nonzero > 0


def test_make_vec_refuses_another_autoreset_mode_naming_the_sync_vector_env(files: dict[str, Path]) -> None:
    # gymnasium.make_vec refuses vector_kwargs for a vector entry point, so the mode comes as a keyword: it
    # failed with "ScenarioVectorEnv.__init__() got an unexpected keyword argument 'autoreset_mode'"
    from gymnasium.vector import AutoresetMode

    for mode in (AutoresetMode.SAME_STEP, "Disabled"):
        for extra in ({}, {"render_mode": "ansi"}):  # the native batch, and the SyncVectorEnv of frames
            with pytest.raises(ValueError, match=r"NEXT_STEP.*vectorization_mode='sync', vector_kwargs="):
                gymnasium.make_vec(rac.gym.SCENARIO, num_envs=2, model=files["goal_ahead"], autoreset_mode=mode,
                                   **extra)
    same = gymnasium.make_vec(rac.gym.SCENARIO, num_envs=2, model=files["goal_ahead"],
                              autoreset_mode=AutoresetMode.NEXT_STEP)
    assert isinstance(same, ScenarioVectorEnv)
    sync = gymnasium.make_vec(rac.gym.SCENARIO, num_envs=2, model=files["goal_ahead"], vectorization_mode="sync",
                              vector_kwargs={"autoreset_mode": AutoresetMode.SAME_STEP})
    assert sync.metadata["autoreset_mode"] == AutoresetMode.SAME_STEP  # what the message says to do works


def test_episodes_a_wrappers_automaton_ends_are_no_cuts_of_the_scenario_env(files: dict[str, Path],
                                                                            tiny: CompileResult,
                                                                            tiny_ends: CompileResult) -> None:
    """A rac reward wrapper whose automaton ends episodes (`episode ends when`) resets ScenarioEnvs before
    they ended them: each ScenarioEnv took those resets for a step limit outside it and warned that its
    `at end` clauses were lost — of a reward the wrapper replaces. The wrapper's own check stays."""
    assert tiny_ends.automaton is not None
    sync = gymnasium.make_vec(rac.gym.SCENARIO, num_envs=2, model=files["avoidable_obstacle"], lookahead=None,
                              render_mode="ansi")
    assert isinstance(sync, ScenarioSyncVectorEnv)
    with warnings.catch_warnings():  # one step of the environment is one sample: the timing warns
        warnings.simplefilter("ignore", UserWarning)
        vector = RewardAutomatonVectorWrapper(sync, tiny_ends.automaton,
                                              lambda obs, infos: {"near": infos["inputs"]["near"]})
        single = RewardAutomatonWrapper(ScenarioEnv(tiny, lookahead=None), tiny_ends.automaton,
                                        lambda obs, info: {"near": info["inputs"]["near"]})
    ended = 0
    with warnings.catch_warnings():
        warnings.simplefilter("error", UserWarning)
        vector.reset(seed=0)
        single.reset(seed=0)
        for _ in range(12):
            ended += int(vector.step(np.array([4, 4]))[2].sum())
            if single.step(4)[2]:
                single.reset()
    assert ended >= 6  # the van comes near after the same steps in every episode: cut alike, again and again


def test_an_async_vector_env_of_scenario_envs_is_told_too(files: dict[str, Path], tiny_ends: CompileResult,
                                                          capfd: pytest.CaptureFixture[str]) -> None:
    """The ScenarioEnvs of an AsyncVectorEnv live in its workers: they warned there, on stderr, of the
    episodes the wrapper's automaton ended as if a limit cut them."""
    assert tiny_ends.automaton is not None
    envs = gymnasium.make_vec(rac.gym.SCENARIO, num_envs=2, model=files["avoidable_obstacle"], lookahead=None,
                              vectorization_mode="async")
    with warnings.catch_warnings():  # one step of the environment is one sample: the timing warns
        warnings.simplefilter("ignore", UserWarning)
        vector = RewardAutomatonVectorWrapper(envs, tiny_ends.automaton,
                                              lambda obs, infos: {"near": infos["inputs"]["near"]})
    try:
        vector.reset(seed=0)
        ended = sum(int(vector.step(np.array([4, 4]))[2].sum()) for _ in range(12))
    finally:
        vector.close()
    assert ended >= 6
    assert "without rac seeing them end" not in capfd.readouterr().err


def test_the_vector_env_says_where_the_time_guard_cut_the_search(tiny: CompileResult,
                                                                 monkeypatch: pytest.MonkeyPatch) -> None:
    # As ScenarioEnv: info["shield_clock"] per episode, clock_steps counted, one warning.
    clock = iter(range(10**7))
    monkeypatch.setattr("rac.engine.lookahead.time.perf_counter", lambda: float(next(clock)) * 1000)
    envs = ScenarioVectorEnv(tiny, num_envs=2, lookahead=3)
    envs.reset(seed=0)
    with pytest.warns(RuntimeWarning, match="stopped its search at t = 0 s"):
        _, _, _, _, info = envs.step(np.array([np.flatnonzero(row)[0] for row in envs.action_masks()]))
    assert info["shield_clock"].tolist() == [True, True] and info["_shield_clock"].all()
    assert envs.clock_steps == 2 == envs.timeout_steps
