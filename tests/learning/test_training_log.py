"""TrainingLog (no RL library) and the stable-baselines3 RacCallback on a real PPO run."""

from __future__ import annotations

import csv
import importlib
import sys
from pathlib import Path
from typing import Any

import pytest
from gymnasium.wrappers import TimeLimit
from highway_like import SCALING, HighwayLike, follow, inputs
from test_location_observation import Blank, took

from rac.compiler import compile_text
from rac.learning.training_log import TrainingLog
from rac.learning.wrappers import RewardAutomatonWrapper


def info(location: str, sa: float, **extra: object) -> dict[str, object]:
    return {"rac": {"location": location, "reward_steps": {"sa": sa, "pr": 1.0}, "clipped": {"x": 1}}, **extra}


def test_the_log_aggregates_and_clears() -> None:
    log = TrainingLog()
    assert log.record() == {}
    log.add([info("Safe", 1.0, shield="exhaustive", collided=False),
             info("Unsafe", -10.0, shield="lookahead 3", no_safe_action=True)])
    log.add([info("Safe", 2.0, shield="exhaustive", crashed=True), {"shield": "none", "collided": True}])
    assert log.record() == {
        "rac/reward/sa": (1.0 - 10.0 + 2.0) / 3, "rac/reward/pr": 1.0,
        "rac/location/Safe": 2 / 3, "rac/location/Unsafe": 1 / 3, "rac/clipped/x": 3.0,
        "rac/shield/exhaustive": 2 / 4, "rac/shield/lookahead 3": 1 / 4, "rac/shield/none": 1 / 4,
        "rac/shield/no_safe_action": 1 / 4, "rac/collisions": 2.0}
    assert log.record() == {}
    # steps without a shield (a vector env's reset steps, which chose from no mask) are no share's steps
    log.add([{"shield": "exhaustive", "no_safe_action": True}, {"shield": "none"}, {}, {"collided": False}])
    recorded = log.record()
    assert recorded["rac/shield/exhaustive"] == recorded["rac/shield/none"] == 1 / 2
    assert recorded["rac/shield/no_safe_action"] == 1 / 2


def test_masks_the_clock_cut_are_logged() -> None:
    # ScenarioEnv says in info["shield_clock"] that a step's mask depended on the machine's speed (the
    # runtime shield's time limit cut its search); the log, where a training run's numbers are read,
    # did not show it.
    log = TrainingLog()
    log.add([{"shield": "lookahead 3", "shield_clock": True}, {"shield": "lookahead 3", "shield_clock": False},
             {"shield": "lookahead 2"}, {"shield": "exhaustive"}])
    assert log.record()["rac/shield/clock"] == 1 / 4
    log.add([{"shield": "lookahead 3", "shield_clock": False}])
    assert log.record()["rac/shield/clock"] == 0.0  # once recorded, recorded (no blank cell)
    log = TrainingLog()
    log.add([{"shield": "lookahead 3", "shield_clock": False}])
    assert "rac/shield/clock" not in log.record()


def test_the_callback_records_with_a_real_ppo(tmp_path: Path) -> None:
    pytest.importorskip("stable_baselines3", reason="the callback needs stable-baselines3 (pip install 'rac[rl]')")
    from stable_baselines3 import PPO
    from stable_baselines3.common.logger import configure

    from rac.learning.sb3 import RacCallback

    env = RewardAutomatonWrapper(TimeLimit(HighwayLike(), 30), follow(), inputs, clip=True, scale="proven")
    model = PPO("MlpPolicy", env, n_steps=128, batch_size=64, n_epochs=1, seed=0, device="cpu")
    model.set_logger(configure(str(tmp_path), ["csv"]))
    model.learn(256, callback=RacCallback())
    with open(tmp_path / "progress.csv", encoding="utf-8") as handle:
        rows = list(csv.DictReader(handle))
    assert rows, "nothing was logged"
    keys = set(rows[0])
    assert {"rac/reward/sa", "rac/reward/pr", "rac/location/Safe", "rac/collisions"} <= keys
    assert all(0.0 <= float(row["rac/location/Safe"] or 0) <= 1.0 for row in rows)


def test_the_callback_warns_of_a_reward_normaliser() -> None:
    # VecNormalize(norm_reward=True) divides every reward by a running spread of the returns and clips
    # it at clip_reward (10): FOLLOW's collision, -200 in its objective, then counts as little as -10
    # times that spread, so the learner's reward is no longer the automaton's up to a fixed factor and
    # the priority proofs cover nothing it learns from. Nothing said so.
    pytest.importorskip("stable_baselines3", reason="the callback needs stable-baselines3 (pip install 'rac[rl]')")
    import warnings

    from stable_baselines3 import PPO
    from stable_baselines3.common.vec_env import DummyVecEnv, VecNormalize

    from rac.learning.sb3 import RacCallback

    def make() -> RewardAutomatonWrapper:
        return RewardAutomatonWrapper(TimeLimit(HighwayLike(), 30), follow(), inputs, clip=True)

    for norm_reward in (True, False):
        envs = VecNormalize(DummyVecEnv([make]), norm_obs=False, norm_reward=norm_reward)
        model = PPO("MlpPolicy", envs, n_steps=16, batch_size=16, n_epochs=1, seed=0, device="cpu")
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            model.learn(32, callback=RacCallback())
        said = [str(w.message) for w in caught if "norm_reward" in str(w.message)]
        if norm_reward:
            assert len(said) == 1 and "clip_reward=10" in said[0] and "priority" in said[0], said
            # at the script's learn() line, not stable-baselines3's callbacks.py (the warning's first line)
            (where,) = [w for w in caught if "norm_reward" in str(w.message)]
            assert where.filename == __file__, where.filename
        else:
            assert said == []


def test_the_callback_warns_when_the_discount_breaks_the_priority_order() -> None:
    # rac check proves FOLLOW's priority order of the plain return; PPO maximises the return discounted
    # by its gamma, for which the order may fail (gains early outweighing a penalty late). At gamma 0.9
    # it fails for FOLLOW (rac check --discount 0.9), at 0.99 it holds: the callback says the one, not the other.
    pytest.importorskip("stable_baselines3", reason="the callback needs stable-baselines3 (pip install 'rac[rl]')")
    import warnings

    import numpy as np
    from stable_baselines3 import PPO
    from stable_baselines3.common.vec_env import DummyVecEnv

    from rac.learning.sb3 import RacCallback, proof_subjects

    def make() -> RewardAutomatonWrapper:
        return RewardAutomatonWrapper(TimeLimit(HighwayLike(), 30), follow(), inputs, clip=True)

    envs = DummyVecEnv([make, make])
    assert [(a.name, n) for a, n in proof_subjects(envs)] == [("Follow", 1)]  # two copies of one automaton
    # a numpy gamma (float32 is no Python float) is checked as well: it was skipped, nothing said
    for gamma in (0.9, 0.99, np.float32(0.9)):
        model = PPO("MlpPolicy", envs, n_steps=16, batch_size=16, n_epochs=1, seed=0, device="cpu", gamma=gamma)
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            callback = RacCallback()
            model.learn(32, callback=callback)
            model.learn(32, callback=callback, reset_num_timesteps=False)  # said once
        said = [str(w.message) for w in caught if "discounted" in str(w.message)]
        if gamma < 0.95:
            assert len(said) == 1, (gamma, said)
            assert "gamma=0.9" in said[0] and "`Follow`" in said[0] and "rac check --discount 0.9" in said[0]
            assert "P2 no compensation fails for the discounted return" in said[0]
        else:
            assert said == []


def test_the_discount_warning_names_the_gamma_to_the_last_digit() -> None:
    # the warning wrote gamma with `:g`, six digits: 0.123456789 became 0.123457 and 0.9999999 became 1,
    # so the command it gave (`rac check --discount 1`) checked the plain return, not the learner's
    pytest.importorskip("stable_baselines3", reason="the callback needs stable-baselines3 (pip install 'rac[rl]')")
    from stable_baselines3.common.vec_env import DummyVecEnv

    from rac.learning.sb3 import discount_warnings

    envs = DummyVecEnv([lambda: RewardAutomatonWrapper(TimeLimit(HighwayLike(), 30), follow(), inputs, clip=True)])
    said = discount_warnings(envs, 0.123456789, "PPO")
    assert len(said) == 1 and "gamma=0.123456789 per step" in said[0], said
    assert "`rac check --discount 0.123456789 FILE` shows the run" in said[0]


def test_the_discount_check_says_it_was_not_made_on_a_generated_class() -> None:
    # the wrapper takes an instance of a generated class, which has no checked automaton: the callback skipped the
    # discounted P2 check there in silence, where rac.load's automaton got the warning that it fails at gamma 0.9
    pytest.importorskip("stable_baselines3", reason="the callback needs stable-baselines3 (pip install 'rac[rl]')")
    import types
    import warnings

    from stable_baselines3 import PPO
    from stable_baselines3.common.vec_env import DummyVecEnv

    from rac.learning.sb3 import RacCallback, discount_warnings
    from rac.targets.python import generate_python

    module = types.ModuleType("follow_generated")
    exec(compile(generate_python(follow()), "<generated>", "exec"), module.__dict__)  # noqa: S102 - the code under test
    generated = getattr(module, module.__all__[0])

    def clipped(obs: Any, info: dict[str, Any]) -> dict[str, object]:  # a generated class does not clip in the wrapper
        return {**inputs(obs, info), "headway": min(max(float(obs[0]), 0.0), 10.0)}

    envs = DummyVecEnv([lambda: RewardAutomatonWrapper(TimeLimit(HighwayLike(), 30), generated(), clipped)] * 2)
    said = discount_warnings(envs, 0.9, "PPO")
    assert len(said) == 1 and "gamma=0.9 per step" in said[0] and "generated class" in said[0], said
    assert "`rac check --discount 0.9 FILE` checks it" in said[0], said
    model = PPO("MlpPolicy", envs, n_steps=16, batch_size=16, n_epochs=1, seed=0, device="cpu", gamma=0.9)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        model.learn(16, callback=RacCallback())
    assert [str(w.message) for w in caught if "discounted" in str(w.message)] == said
    assert discount_warnings(envs, 0.99, "PPO") == [said[0].replace("0.9", "0.99")]  # whatever it is: not checked
    mixed = DummyVecEnv([lambda: RewardAutomatonWrapper(TimeLimit(HighwayLike(), 30), generated(), clipped),
                         lambda: RewardAutomatonWrapper(TimeLimit(HighwayLike(), 30), follow(), inputs, clip=True)])
    said = discount_warnings(mixed, 0.9, "PPO")  # the generated one, and the checked automaton's failure
    assert len(said) == 2 and "generated class" in said[0] and "`Follow` fails" in said[1], said


def test_the_discount_warning_of_a_check_not_made_promises_no_run() -> None:
    # an automaton whose update scales a reward is not checked under a discount (W0405): there is no run,
    # and the warning said `rac check --discount 0.99 FILE` "shows the run"
    pytest.importorskip("stable_baselines3", reason="the callback needs stable-baselines3 (pip install 'rac[rl]')")
    from stable_baselines3.common.vec_env import DummyVecEnv

    from rac.learning.sb3 import discount_warnings

    scaling = compile_text(SCALING, "scaling.ra").raise_for_errors()
    envs = DummyVecEnv([lambda: RewardAutomatonWrapper(TimeLimit(HighwayLike(dt=1), 5), scaling,
                                                       lambda obs, info: {"hit": bool(obs[0] < 2)})])
    said = discount_warnings(envs, 0.99, "PPO")
    assert len(said) == 1 and "is not checked for that return" in said[0] and "scales a reward" in said[0], said
    assert said[0].endswith("`rac check --discount 0.99 FILE` says why"), said


def test_the_discount_check_asks_subprocess_environments_without_killing_them() -> None:
    # SubprocVecEnv's get_attr of an attribute its environments lack raises in the worker, which dies,
    # and the learner saw EOFError: RacCallback crashed PPO (gamma 0.99) at the start of learn() on plain
    # environments, which it should only warn of; with rac's wrapper the automaton comes across the pipe
    pytest.importorskip("stable_baselines3", reason="the callback needs stable-baselines3 (pip install 'rac[rl]')")
    import warnings

    from stable_baselines3 import PPO
    from stable_baselines3.common.vec_env import SubprocVecEnv, VecMonitor

    from rac.learning.sb3 import RacCallback, proof_subjects

    def plain() -> Any:
        return TimeLimit(HighwayLike(), 30)

    def wrapped() -> RewardAutomatonWrapper:
        return RewardAutomatonWrapper(TimeLimit(HighwayLike(), 30), follow(), inputs, clip=True)

    envs = VecMonitor(SubprocVecEnv([plain, plain], start_method="fork"))
    try:
        assert proof_subjects(envs) == []
        model = PPO("MlpPolicy", envs, n_steps=16, batch_size=16, n_epochs=1, seed=0, device="cpu")
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # no automaton seen: said, and not what this test is about
            model.learn(32, callback=RacCallback())
        assert model.num_timesteps == 32
    finally:
        envs.close()
    envs = SubprocVecEnv([wrapped, wrapped], start_method="fork")
    try:
        assert [(a.name, n) for a, n in proof_subjects(envs)] == [("Follow", 1)]
    finally:
        envs.close()


    class Older:
        """A vector environment with get_attr and no has_attr (stable-baselines3 before 2.6)."""

        def get_attr(self, name: str) -> list[Any]:
            return [getattr(wrapped(), name)]

    assert [(a.name, n) for a, n in proof_subjects(Older())] == [("Follow", 1)]


def test_the_callback_warns_of_gymnasiums_reward_wrappers_outside_the_automaton() -> None:
    # gymnasium's NormalizeReward (the CleanRL way of VecNormalize's norm_reward), ClipReward and
    # TransformReward put around the automaton's reward change what the learner learns from, as
    # VecNormalize(norm_reward=True) does, and nothing said so; one inside the automaton's wrapper changes
    # a reward the automaton's replaces, and is no matter
    pytest.importorskip("stable_baselines3", reason="the callback needs stable-baselines3 (pip install 'rac[rl]')")
    import warnings

    from gymnasium.wrappers import ClipReward, NormalizeReward
    from stable_baselines3 import PPO
    from stable_baselines3.common.vec_env import DummyVecEnv, VecMonitor

    from rac.learning.sb3 import RacCallback, reward_changers

    def outside() -> Any:
        return ClipReward(NormalizeReward(RewardAutomatonWrapper(TimeLimit(HighwayLike(), 30), follow(), inputs,
                                                                 clip=True)), -1.0, 1.0)

    def inside() -> RewardAutomatonWrapper:
        return RewardAutomatonWrapper(NormalizeReward(TimeLimit(HighwayLike(), 30)), follow(), inputs, clip=True)

    for make, expected in ((outside, ["ClipReward", "NormalizeReward"]), (inside, [])):
        envs = VecMonitor(DummyVecEnv([make]))
        assert reward_changers(envs) == expected
        model = PPO("MlpPolicy", envs, n_steps=16, batch_size=16, n_epochs=1, seed=0, device="cpu")
        callback = RacCallback()
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            model.learn(16, callback=callback)
            model.learn(16, callback=callback, reset_num_timesteps=False)  # said once
        said = [str(w.message) for w in caught if "around the reward automaton's reward" in str(w.message)]
        if expected:
            assert len(said) == 1 and "ClipReward, NormalizeReward" in said[0] and "priority" in said[0], said
        else:
            assert said == []


def test_without_stable_baselines3_the_import_says_what_to_install(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setitem(sys.modules, "stable_baselines3.common.callbacks", None)  # as if not installed
    monkeypatch.delitem(sys.modules, "rac.learning.sb3", raising=False)
    with pytest.raises(ImportError, match=r"pip install 'rac\[rl\]'"):
        importlib.import_module("rac.learning.sb3")


def test_scenario_env_infos_are_logged_per_objective(tmp_path: Path) -> None:
    """ScenarioEnv reports each reward's change over a step (``info["reward_steps"]``) and its
    location: the log averages them as it does the wrapper's ``info["rac"]``."""
    from engine_files import write_engine_file

    from rac.learning.scenario_env import ScenarioEnv

    env = ScenarioEnv(write_engine_file(tmp_path, "avoidable_obstacle", queries={}), lookahead=None)
    log = TrainingLog()
    _, info = env.reset(seed=0)
    start = dict(info["rewards"])
    steps = []
    for action in (0, 1, 2, 3):
        _, _, _, _, info = env.step(action)
        steps.append(info)
    log.add(steps)
    recorded = log.record()
    for name, value in info["rewards"].items():
        assert recorded[f"rac/reward/{name}"] == pytest.approx((value - start[name]) / 4)
    assert sum(v for k, v in recorded.items() if k.startswith("rac/location/")) == pytest.approx(1.0)


def test_a_key_once_recorded_is_recorded_as_zero_not_left_blank() -> None:
    # a CSV logger writes every key it has seen: a share missing from one rollout was a blank cell
    log = TrainingLog()
    log.add([info("Unsafe", -1.0, shield="lookahead 3", no_safe_action=True, model_allowed=False)])
    first = log.record()
    assert first["rac/location/Unsafe"] == 1.0 and first["rac/disallowed"] == 1.0
    log.add([info("Safe", 1.0, shield="exhaustive")])
    second = log.record()
    assert set(first) <= set(second)
    assert second["rac/location/Unsafe"] == second["rac/shield/lookahead 3"] == second["rac/disallowed"] == 0.0
    assert second["rac/location/Safe"] == second["rac/shield/exhaustive"] == 1.0


def test_gymnasiums_vector_layout_is_logged_as_the_per_env_infos(tmp_path: Path) -> None:
    """ScenarioVectorEnv (and gymnasium's vector envs) hand out one dict of arrays with ``_key`` masks;
    the log reads it as it reads the same steps' per-env dicts (it failed on it: 'str' has no 'get')."""
    import numpy as np
    from engine_files import ALLOW_WHEN, write_engine_file

    from rac.learning.scenario_env import ScenarioEnv
    from rac.learning.vector import ScenarioVectorEnv
    from rac.learning.vector_info import split_vector_info

    path = write_engine_file(tmp_path, "avoidable_obstacle", queries={})
    path.write_text(path.read_text(encoding="utf-8").replace("        bind near =", ALLOW_WHEN + "        bind near =",
                                                             1), encoding="utf-8")
    n = 3
    vector, singles = ScenarioVectorEnv(path, num_envs=n, lookahead=None), [ScenarioEnv(path) for _ in range(n)]
    vector.reset(seed=0)
    for env in singles:
        env.reset(seed=0)
    by_vector, by_env = TrainingLog(), TrainingLog()
    for actions in ([0, 5, 8], [5, 5, 4], [2, 5, 6]):  # turning on twice (5, 5) goes past what `allow when` permits
        _, _, _, _, layout = vector.step(np.array(actions))
        infos = [env.step(action)[4] for env, action in zip(singles, actions)]
        split = split_vector_info(layout)
        assert [sorted(i) for i in split] == [sorted(i) for i in infos]
        assert [i["location"] for i in split] == [i["location"] for i in infos]
        by_vector.add(layout)
        by_env.add(infos)
    expected = by_env.record()
    assert expected["rac/disallowed"] >= 1.0 and by_vector.record() == pytest.approx(expected)
    assert split_vector_info({}) == []


def test_the_vector_wrapper_infos_are_logged() -> None:
    """RewardAutomatonVectorWrapper's ``infos["rac"]`` nests dicts of arrays without masks of their
    own (``rewards``, ``reward_steps``): the log recorded nothing of them, as if no step had a reward."""
    import numpy as np
    from gymnasium.vector import SyncVectorEnv
    from highway_like import vector_inputs

    from rac.learning.vector_info import split_vector_info
    from rac.learning.wrappers import RewardAutomatonVectorWrapper

    env = RewardAutomatonVectorWrapper(SyncVectorEnv([lambda: TimeLimit(HighwayLike(), 30)] * 3), follow(),
                                       vector_inputs, clip=True)
    env.reset(seed=0)
    log, sums, locations, steps = TrainingLog(), {"sa": 0.0, "pr": 0.0}, {}, 0
    for t in range(40):
        *_, infos = env.step(np.array([t % 3, 1, 2]))
        log.add(infos)
        stepped = infos["rac"]["_reward_steps"]  # the others are in their reset step: no sample
        steps += int(stepped.sum())
        for name in sums:
            sums[name] += float(infos["rac"]["reward_steps"][name].sum())
        for location in infos["rac"]["location"][stepped]:
            locations[location] = locations.get(location, 0) + 1
    first = split_vector_info(infos)[0]["rac"]
    assert set(first["reward_steps"]) == {"sa", "pr"} and isinstance(first["location"], str)
    assert 100 < steps < 120  # some episodes ended, and the next step restarted them
    recorded = log.record()
    for name, total in sums.items():
        assert recorded[f"rac/reward/{name}"] == pytest.approx(total / steps)
    for location, count in locations.items():
        assert recorded[f"rac/location/{location}"] == pytest.approx(count / steps)


def test_reset_steps_are_no_steps_whatever_the_vector_form() -> None:
    """The same 24 steps (two episodes of 5 twice over, plus the first 2) through SB3's DummyVecEnv, gymnasium's
    SyncVectorEnv of wrappers and the vector wrapper log the same: the vector forms counted their reset steps
    (a reset info, no sample taken) as steps in the initial location with no reward, diluting every mean."""
    import numpy as np
    from gymnasium.vector import SyncVectorEnv
    from highway_like import vector_inputs

    from rac.learning.wrappers import RewardAutomatonVectorWrapper

    def single() -> RewardAutomatonWrapper:
        return RewardAutomatonWrapper(TimeLimit(HighwayLike(), 5), follow(), inputs, clip=True)

    actions = [2, 1, 0, 1, 2, 2, 0]
    logs = {}
    stable_baselines3 = pytest.importorskip("stable_baselines3.common.vec_env")
    dummy = stable_baselines3.DummyVecEnv([single] * 2)
    dummy.seed(0)
    dummy.reset()
    logs["dummy"] = TrainingLog()
    for t in range(12):
        logs["dummy"].add(dummy.step(np.array([actions[t % 7]] * 2))[3])
    vector = RewardAutomatonVectorWrapper(SyncVectorEnv([lambda: TimeLimit(HighwayLike(), 5)] * 2), follow(),
                                          vector_inputs, clip=True)
    for name, env in (("sync", SyncVectorEnv([single] * 2)), ("vector wrapper", vector)):
        env.reset(seed=0)
        logs[name] = TrainingLog()
        t = 0
        for step in range(14):  # two more: the steps that restart the episodes
            restarting = step in (5, 11)
            logs[name].add(env.step(np.array([0 if restarting else actions[t % 7]] * 2))[4])
            t += not restarting
    recorded = {name: log.record() for name, log in logs.items()}
    assert recorded["sync"] == pytest.approx(recorded["dummy"])
    assert recorded["vector wrapper"] == pytest.approx(recorded["dummy"])


def test_same_step_autoreset_logs_the_step_that_ended_the_episode() -> None:
    """Under gymnasium's SAME_STEP autoreset a sub-environment whose episode ended reports its reset info
    and the step's own under ``final_info``: the log read the reset info, so the step that ended an
    episode (a crash, the end bonus) was logged as a fresh start (highway-env: 9 crashes, 0 logged)."""
    import numpy as np
    from gymnasium.vector import AutoresetMode, SyncVectorEnv

    env = SyncVectorEnv([lambda: RewardAutomatonWrapper(TimeLimit(HighwayLike(), 30), follow(), inputs, clip=True)] * 2,
                        autoreset_mode=AutoresetMode.SAME_STEP)
    env.reset(seed=0)
    log, total, ended = TrainingLog(), 0.0, 0
    for t in range(40):
        _, rewards, terminated, truncated, infos = env.step(np.array([2, t % 3]))  # 2: faster, into the lead car
        log.add(infos)
        total += float(rewards.sum())
        ended += int((terminated | truncated).sum())
    assert ended >= 2
    recorded = log.record()
    # every step's reward is the objective's increase 10 * sa + pr over it (the end bonus included)
    assert 10 * recorded["rac/reward/sa"] + recorded["rac/reward/pr"] == pytest.approx(total / 80)
    assert recorded["rac/location/Unsafe"] > 0


def test_steps_whose_action_the_mask_did_not_allow_are_said(tmp_path: Path) -> None:
    """A learner that ignores the masks (plain PPO, DQN) on a shielded ScenarioEnv: the guarantee shares
    say what the masks offered, and ``rac/shield/outside_mask`` how often the action was not among them
    (the log said 'lookahead 2' for every step, as if the learner had been shielded)."""
    import numpy as np
    from engine_files import write_engine_file

    from rac.learning.scenario_env import ScenarioEnv

    env = ScenarioEnv(write_engine_file(tmp_path, "avoidable_obstacle", queries={}), lookahead=2)
    masked, ignoring = TrainingLog(), TrainingLog()
    for log, obey in ((masked, True), (ignoring, False)):
        env.reset(seed=0)
        for _ in range(3):
            mask = env.action_masks()
            action = int(np.flatnonzero(mask if obey else ~mask)[0]) if obey or not mask.all() else 0
            log.add([env.step(action)[4]])
    assert "rac/shield/outside_mask" not in masked.record()
    recorded = ignoring.record()
    assert recorded["rac/shield/outside_mask"] > 0  # at least the start, where only braking is safe
    assert recorded["rac/shield/outside_mask"] <= 1.0


def test_the_callback_logs_every_step_since_the_logger_last_wrote(tmp_path: Path) -> None:
    """DQN collects rollouts of ``train_freq`` steps and writes its log at an episode's end, within a
    rollout; A2C writes it every ``log_interval`` rollouts: recording each rollout alone, each table held
    the last few steps (4 collisions of 10; 5 of 15)."""
    pytest.importorskip("stable_baselines3", reason="the callback needs stable-baselines3 (pip install 'rac[rl]')")
    import gymnasium
    import numpy as np
    from stable_baselines3 import DQN
    from stable_baselines3.common.logger import configure

    from rac.learning.sb3 import RacCallback

    class Crashing(gymnasium.Env):  # type: ignore[type-arg]
        """Every step is a collision (highway-env's info["crashed"]); episodes of 10 steps."""

        observation_space = gymnasium.spaces.Box(0.0, 1.0, shape=(1,))
        action_space = gymnasium.spaces.Discrete(2)

        def reset(self, *, seed: int | None = None, options: dict | None = None) -> tuple[np.ndarray, dict]:
            super().reset(seed=seed)
            self.t = 0
            return np.zeros(1, dtype=np.float32), {}

        def step(self, action: int) -> tuple[np.ndarray, float, bool, bool, dict]:
            self.t += 1
            return np.zeros(1, dtype=np.float32), 0.0, False, self.t >= 10, {"crashed": True}

    model = DQN("MlpPolicy", Crashing(), learning_starts=0, train_freq=4, seed=0, device="cpu")
    model.set_logger(configure(str(tmp_path), ["csv"]))
    model.learn(40, callback=RacCallback(), log_interval=1)  # a dump at every episode's end
    with open(tmp_path / "progress.csv", encoding="utf-8") as handle:
        rows = list(csv.DictReader(handle))
    assert [float(row["rac/collisions"]) for row in rows] == [10.0] * 4

    # PPO's table follows each rollout, whatever an evaluation writes within it (in the same step here)
    from stable_baselines3 import PPO
    from stable_baselines3.common.callbacks import EvalCallback

    model = PPO("MlpPolicy", Crashing(), n_steps=10, batch_size=10, n_epochs=1, seed=0, device="cpu")
    model.set_logger(configure(str(tmp_path / "ppo"), ["csv"]))
    model.learn(30, callback=[RacCallback(), EvalCallback(Crashing(), eval_freq=10, n_eval_episodes=1)])
    with open(tmp_path / "ppo" / "progress.csv", encoding="utf-8") as handle:
        rows = [row for row in csv.DictReader(handle) if row["time/iterations"]]
    assert [float(row["rac/collisions"]) for row in rows] == [10.0] * 3

    # A2C writes its table every log_interval rollouts (100 by default): each table holds them all
    from stable_baselines3 import A2C

    model = A2C("MlpPolicy", Crashing(), n_steps=5, seed=0, device="cpu")
    model.set_logger(configure(str(tmp_path / "a2c"), ["csv"]))
    model.learn(30, callback=RacCallback(), log_interval=3)
    with open(tmp_path / "a2c" / "progress.csv", encoding="utf-8") as handle:
        rows = list(csv.DictReader(handle))
    assert [float(row["rac/collisions"]) for row in rows] == [15.0] * 2


def test_a_single_environments_info_is_one_step() -> None:
    """``log.add(info)`` in a loop over one environment: the dict was read as a vector layout without
    masks, i.e. of no environment, and the log stayed empty (``record()`` gave ``{}``)."""
    env = RewardAutomatonWrapper(TimeLimit(HighwayLike(), 30), follow(), inputs, clip=True)
    env.reset(seed=0)
    single, listed = TrainingLog(), TrainingLog()
    for _ in range(5):
        info = env.step(1)[4]
        single.add(info)
        listed.add([info])
    assert single.steps == 5 and single.record() == listed.record() != {}
    single.add({})  # an empty vector info is still no step
    assert single.steps == 0


def test_a_crash_at_the_start_is_counted_once_per_episode_not_at_the_reset_rows(tmp_path: Path) -> None:
    """A start in a collision (W0724): ScenarioVectorEnv's reset step (NEXT_STEP) reports the new
    episode's start, ``collided`` True, and its first step the crash again; the log counted both, so
    every episode after the first had its crash counted twice (8 for 4 crashing steps)."""
    import numpy as np
    from engine_files import engine_source
    from tiny_scenarios import avoidable_obstacle, blocked_start

    from rac.compiler import compile_file
    from rac.learning.vector import ScenarioVectorEnv
    from rac.learning.vector_info import split_vector_info

    (tmp_path / "blocked.xml").write_bytes(blocked_start())  # the ego starts inside a parked car
    path = tmp_path / "blocked.ra"
    path.write_text(engine_source(avoidable_obstacle(), {}, scenario_file="blocked.xml"), encoding="utf-8")
    result = compile_file(path)
    assert result.ok and [d.code for d in result.diagnostics] == ["W0724"]
    envs = ScenarioVectorEnv(result, num_envs=2, lookahead=None)
    _, start = envs.reset(seed=0)
    assert start["collided"].all()
    log, crashing_steps, reset_rows = TrainingLog(), 0, 0
    for _ in range(10):  # two episodes of 4 steps and their reset steps
        *_, info = envs.step(np.array([4, 4]))
        for row in split_vector_info(info):
            if "reward_steps" in row:
                crashing_steps += row["collided"]
            else:
                reset_rows += 1
                assert row["collided"]  # the start's flag, in the reset info
        log.add(info)
    assert reset_rows == 4 and crashing_steps == 4  # each episode's first step passes through the car
    assert log.record()["rac/collisions"] == crashing_steps
    wrapped = TrainingLog()  # the vector wrapper's reset rows (info["rac"] without reward_steps) alike
    snapshot = {"location": "Safe", "rewards": {"sa": 0.0}, "objective": 0.0}
    wrapped.add([{"crashed": True, "rac": snapshot},
                 {"crashed": True, "rac": {**snapshot, "reward_steps": {"sa": 1.0}}},
                 {"crashed": True, "objective": 3.0}])  # another environment's info, with a key of that name
    assert wrapped.record()["rac/collisions"] == 2.0


def test_steps_whose_shield_ran_out_of_its_budget_are_said(tmp_path: Path) -> None:
    """A runtime shield whose budget runs out hands out a mask that may allow fewer actions (and, with a
    time budget, other masks on another run or machine): ``rac/shield/timeout`` says how often, where the
    log said only the guarantee, as for a complete search."""
    import numpy as np
    from engine_files import write_engine_file

    from rac.engine.lookahead import LookaheadSettings
    from rac.learning.scenario_env import ScenarioEnv

    model = write_engine_file(tmp_path, "avoidable_obstacle", queries={})
    logs = {}
    for nodes in (None, 1):  # unbounded, then one node a decision: cut short at every decision
        env = ScenarioEnv(model, lookahead=LookaheadSettings(depth=3, seconds=None, nodes=nodes))
        log = TrainingLog()
        env.reset(seed=0)
        for _ in range(3):
            log.add([env.step(int(np.flatnonzero(env.action_masks())[0]))[4]])
        logs[nodes] = (log.record(), env.timeout_steps)
    assert "rac/shield/timeout" not in logs[None][0] and logs[None][1] == 0
    recorded, timeouts = logs[1]
    assert timeouts == 3 and recorded["rac/shield/timeout"] == 1.0
    log = TrainingLog()
    log.add([{"shield": "lookahead 2", "shield_timeout": True}, {"shield": "lookahead 3"}])
    assert log.record()["rac/shield/timeout"] == 1 / 2
    assert log.record() == {}  # a window without steps: nothing to record
    log.add([{"shield": "lookahead 3"}])
    assert log.record()["rac/shield/timeout"] == 0.0  # once recorded, 0 rather than a blank cell


def test_the_callback_says_when_it_sees_no_reward_automaton(tmp_path: Path) -> None:
    """RacCallback on steps whose infos carry no automaton (an environment without rac's wrapper, or a
    wrapper between that drops the info) logged rac/collisions alone, 0 whatever happened, and on an
    algorithm that hands its callbacks no infos (sb3-contrib's ARS) nothing at all: neither said why."""
    pytest.importorskip("stable_baselines3", reason="the callback needs stable-baselines3 (pip install 'rac[rl]')")
    import warnings

    import gymnasium
    from stable_baselines3 import PPO

    from rac.learning.sb3 import RacCallback

    def warned(model: Any, steps: int = 64) -> list[str]:
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            model.learn(steps, callback=RacCallback())
        return [str(w.message) for w in caught if "RacCallback" in str(w.message)]

    def ppo(env: gymnasium.Env) -> PPO:  # type: ignore[type-arg]
        return PPO("MlpPolicy", env, n_steps=32, batch_size=32, n_epochs=1, seed=0, device="cpu")

    assert warned(ppo(RewardAutomatonWrapper(TimeLimit(HighwayLike(), 30), follow(), inputs, clip=True))) == []
    plain = warned(ppo(TimeLimit(HighwayLike(), 30)))
    assert len(plain) == 1 and "carry no reward automaton" in plain[0] and "RewardAutomatonWrapper" in plain[0]
    try:
        from sb3_contrib import ARS
    except ImportError:
        return
    env = RewardAutomatonWrapper(TimeLimit(HighwayLike(), 30), follow(), inputs, clip=True)
    silent = warned(ARS("MlpPolicy", env, n_delta=1, seed=0, device="cpu"), steps=60)
    assert len(silent) == 1 and "ARS hands its callbacks no step infos" in silent[0]


LONG_NAMES = """automaton Turn {
    input a : bool
    reward r
    objective r
    sample every 1
    horizon 10
    initial location WaitingForTheOncomingTrafficLeft { r' == 0 }
    location WaitingForTheOncomingTrafficRight        { r' == 0 }
    edge WaitingForTheOncomingTrafficLeft -> WaitingForTheOncomingTrafficRight when a do r = r + 1
    edge WaitingForTheOncomingTrafficRight -> WaitingForTheOncomingTrafficLeft when !a do r = r + 1
}
"""


def test_location_names_that_the_text_table_cuts_alike_do_not_end_training(tmp_path: Path) -> None:
    # SB3's stdout table cuts a key to 36 characters and raises ValueError in dump when two keys come out the
    # same: two locations of 22 or more characters sharing their first 21 ended PPO's learn() at its first table
    pytest.importorskip("stable_baselines3", reason="the callback needs stable-baselines3 (pip install 'rac[rl]')")
    import io
    import warnings

    from stable_baselines3 import PPO
    from stable_baselines3.common.logger import CSVOutputFormat, HumanOutputFormat, Logger

    import rac
    from rac.learning import sb3

    env = RewardAutomatonWrapper(Blank(), rac.loads(LONG_NAMES, "turn.ra"), took)
    text = io.StringIO()
    model = PPO("MlpPolicy", env, n_steps=32, batch_size=32, n_epochs=1, seed=0, device="cpu")
    model.set_logger(Logger(None, [HumanOutputFormat(text), CSVOutputFormat(str(tmp_path / "progress.csv"))]))
    left, right = "rac/location/WaitingForTheOncomingTrafficLeft", "rac/location/WaitingForTheOncomingTrafficRight"
    callback = sb3.RacCallback()
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        model.learn(64, callback=callback)
        model.learn(32, callback=callback, reset_num_timesteps=False)
    said = [str(w.message) for w in caught if "text table" in str(w.message)]
    assert len(said) == 1 and left in said[0] and right in said[0], said
    assert "reward/r" in text.getvalue() and "WaitingFor" not in text.getvalue()
    with open(tmp_path / "progress.csv", encoding="utf-8") as handle:
        rows = list(csv.DictReader(handle))
    assert len(rows) == 3 and {left, right} <= set(rows[0])
    assert all(abs(float(row[left]) + float(row[right]) - 1.0) < 1e-9 for row in rows)
    assert sb3.text_table_clashes(model.logger, [left, right, "rac/reward/r"]) == {left, right}
