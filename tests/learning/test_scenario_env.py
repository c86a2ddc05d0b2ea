"""ScenarioEnv (rac.learning.gym): the scenario model as a gymnasium environment, with a shield's action masks.

gymnasium's env_checker passes; the observation, reward and info are those of EpisodeBatch with
one episode; a random walk under a safety shield (rac.engine.explore + rac.engine.storm.safety_shield
+ rac.engine.shield.table) never collides nor leaves the road on a tiny scenario, while unshielded ones do;
unseen states follow the shield's policy; horizon, seeding and errors; an automaton's `episode ends when`
terminates the episode.
"""

from __future__ import annotations

import dataclasses
import warnings
from pathlib import Path
from typing import Any

import gymnasium
import numpy as np
import pytest
from engine_files import ALLOW_WHEN, write_engine_file
from gymnasium.utils.env_checker import check_env
from tiny_scenarios import TINY_SCENARIOS, GoalBox, StraightRoad, traffic_rules

from rac import ir
from rac.compiler import CompileResult, compile_file, compile_text
from rac.core.diagnostics import CheckError
from rac.engine import shield as shield_file
from rac.engine.explore import COLUMNS, explore
from rac.engine.lookahead import Lookahead, LookaheadSettings
from rac.engine.shield import ShieldTable, UnseenState
from rac.engine.storm import safety_shield
from rac.learning.episodes import EpisodeBatch
from rac.learning.gym import ScenarioEnv
from rac.model.commonroad import EgoStart

REPO = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="module")
def tiny(tmp_path_factory: pytest.TempPathFactory) -> CompileResult:
    """The engine test file (one input `near`, reward `sa`) on avoidable_obstacle: a van 15 m ahead."""
    path = write_engine_file(tmp_path_factory.mktemp("env"), "avoidable_obstacle", queries={})
    result = compile_file(path)
    assert result.ok, [d.message for d in result.diagnostics]
    return result


def shield_table(result: CompileResult, horizon: int, unseen: str) -> ShieldTable:
    data = result.model_data
    assert data is not None
    graph = explore(data, horizon_samples=horizon, prune_unsafe=True)
    shield = safety_shield(graph, "safe")
    assert shield.shield_exists
    return shield_file.table(shield, n_actions=EpisodeBatch(result).n_actions, unseen=unseen)


@pytest.fixture(scope="module")
def table(tiny: CompileResult) -> ShieldTable:
    return shield_table(tiny, 8, "error")  # the whole 4 s horizon: an unseen state would raise


def checked(env: gymnasium.Env) -> list[str]:
    """check_env's warnings, except the one that only says the env was not made with gymnasium.make, and
    those of its random actions, which a shield's mask may not allow, and of the states they lead to, which
    a shield may not cover (true, and tested on their own)."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        check_env(env)
    return [str(w.message) for w in caught if not any(part in str(w.message) for part in (
        "spec", "not in the mask", "no action was known to be safe"))]


# ---------------------------------------------------------------- the gymnasium API
@pytest.mark.parametrize("render_mode", [None, "ansi"])
def test_check_env(tiny: CompileResult, table: ShieldTable, render_mode: str | None) -> None:
    assert checked(ScenarioEnv(tiny, shield=table, render_mode=render_mode)) == []


def test_check_env_left_turn() -> None:
    env = ScenarioEnv(REPO / "examples" / "left_turn" / "model.ra", horizon=1.0, render_mode="ansi")
    assert checked(env) == []
    assert env.action_space.n == 81 and env.episodes.horizon_samples == 10 and env.episodes.max_steps == 5
    obs, _ = env.reset()
    assert "Normal" in env.render() and obs.shape == (29,)  # the "relative" observation by default


def test_observation_reward_and_info_follow_the_episode(tiny: CompileResult) -> None:
    env = ScenarioEnv(tiny, observation="ego")
    batch = EpisodeBatch(tiny)
    obs, info = env.reset(seed=3)
    batch.reset(1)
    scale, period = batch.data.scale, batch.data.period
    assert obs.dtype == np.float32 and env.observation_space.contains(obs)
    assert obs.tolist() == np.append(batch.ego[0] / scale, 0.0).astype(np.float32).tolist()
    assert info == {"location": "Normal", "rewards": {"sa": 0.0}, "objective": 0.0, "inputs": {"near": False},
                    "collided": False, "offroad": False, "goal": False, "time": 0.0,
                    "scenario": tiny.automaton.model.scenario_path,  # type: ignore[union-attr]
                    "planning_problem": 100, "scale": 1.0, "proven": False}
    rng = np.random.default_rng(1)
    before = 0.0
    total, done = 0.0, False
    while not done:
        action = int(rng.integers(env.action_space.n))
        obs, reward, terminated, truncated, info = env.step(action)
        out = batch.step(np.array([action]))
        assert reward == out.reward[0] and terminated == out.terminated[0] and truncated == out.truncated[0]
        assert info["collided"] == out.collided[0] and info["offroad"] == out.offroad[0]
        assert info["goal"] == terminated
        assert obs.tolist() == np.append(batch.ego[0] / scale, batch.k[0] * period).astype(np.float32).tolist()
        assert info["time"] == batch.k[0] * period
        assert info["location"] == tiny.automaton.location_names[batch.location[0]]  # type: ignore[union-attr]
        assert info["rewards"] == {"sa": batch.rewards["sa"][0]} and info["objective"] == batch.objective[0]
        assert info["inputs"] == {"near": bool(batch.inputs["near"][0])}
        assert info["reward_steps"] == {"sa": info["rewards"]["sa"] - before}
        before = info["rewards"]["sa"]
        assert env.observation_space.contains(obs)
        total += reward
        done = terminated or truncated
    assert truncated and info["time"] == pytest.approx(4.0)
    assert total == pytest.approx(info["objective"])  # automaton mode: the return is the final objective
    with pytest.raises(RuntimeError, match="reset"):
        env.step(0)


def test_reward_expression(tiny: CompileResult) -> None:
    env = ScenarioEnv(tiny, reward="10 * !near + v")
    env.reset()
    _, reward, *_ = env.step(4)  # (jerk 0, turn 0): 5 m/s kept for two samples, nothing near
    assert reward == pytest.approx(2 * (10 + 5))


def test_the_proofs_subject_is_the_automaton_over_a_decision(tiny: CompileResult) -> None:
    # RacCallback checks P2 of the discounted return on it: one step spans a decision period's samples,
    # and a reward expression has no proof to check
    automaton, samples = ScenarioEnv(tiny).proof_subject
    assert automaton is tiny.automaton and samples == ScenarioEnv(tiny).episodes.decide_every > 1
    assert ScenarioEnv(tiny, reward="10 * !near + v").proof_subject is None


def test_seed_only_seeds_np_random(tiny: CompileResult) -> None:
    env = ScenarioEnv(tiny)
    first, _ = env.reset(seed=1)
    draw = env.np_random.integers(1000, size=4)
    again, _ = env.reset(seed=1)
    other, _ = env.reset(seed=2)
    assert first.tolist() == again.tolist() == other.tolist()  # the model is deterministic
    env.reset(seed=1)
    assert env.np_random.integers(1000, size=4).tolist() == draw.tolist()


def test_max_episode_steps_outside_is_said_at_the_first_cut(tiny: CompileResult) -> None:
    # gymnasium.make(..., max_episode_steps=N) puts a TimeLimit outside ScenarioEnv: the episode is
    # truncated where the environment cannot see it, and its `at end` clauses are lost; the limit is in
    # the spec, so the first cut is said, at the step it happens (it was said at the second cut's reset)
    env = gymnasium.make("rac.gym:rac/Scenario-v0", model=tiny, max_episode_steps=3)
    env.reset(seed=0)
    with warnings.catch_warnings():
        warnings.simplefilter("error", UserWarning)
        assert [env.step(4)[3] for _ in range(2)] == [False, False]
    with pytest.warns(UserWarning, match=r"\(max_episode_steps=3\) cuts episodes.*`at end` clauses were not "
                                         r"applied.*horizon=<seconds>"):
        assert env.step(4)[3]  # the first episode cut after 3 steps by the limit
    with warnings.catch_warnings():  # said once
        warnings.simplefilter("error", UserWarning)
        for seed in range(1, 3):
            env.reset(seed=seed)
            assert [env.step(4)[3] for _ in range(3)] == [False, False, True]
    own = gymnasium.make("rac.gym:rac/Scenario-v0", model=tiny, horizon=2.5)
    with warnings.catch_warnings():
        warnings.simplefilter("error", UserWarning)
        for seed in range(3):
            own.reset(seed=seed)
            assert [own.step(4)[3] for _ in range(3)] == [False, False, True]


def test_a_reward_wrapper_outside_is_said_at_the_first_reset(tiny: CompileResult) -> None:
    # gymnasium's ClipReward (or NormalizeReward, TransformReward) around rac/Scenario-v0 in a loop without
    # stable-baselines3 changed the automaton's reward without a word; under rac's reward wrapper it is that
    # wrapper's to say (the scenario environment's reward replaced)
    env = gymnasium.wrappers.ClipReward(gymnasium.make("rac.gym:rac/Scenario-v0", model=tiny), -1.0, 1.0)
    with pytest.warns(UserWarning, match=r"^gymnasium's ClipReward around the reward automaton's reward"):
        env.reset(seed=0)
    with warnings.catch_warnings():  # said once
        warnings.simplefilter("error", UserWarning)
        env.reset(seed=1)
        gymnasium.make("rac.gym:rac/Scenario-v0", model=tiny).reset(seed=0)  # nothing around it: nothing said


def test_horizon_in_seconds(tiny: CompileResult) -> None:
    env = ScenarioEnv(tiny, horizon=1.5, observation="ego")
    assert env.episodes.horizon_samples == 3 and env.episodes.max_steps == 2
    assert env.observation_space.high[-1] == np.float32(1.5)
    env.reset()
    assert not env.step(4)[3] and env.step(4)[3]  # truncated on the second step, after 3 samples
    for bad in (0.7, 0, -1, 1e12):  # 1e12 s: beyond int32 samples, as the command line refuses it
        with pytest.raises(ValueError, match="whole number|more than 2,147,483,647"):
            ScenarioEnv(tiny, horizon=bad)
    # the tiny automaton's horizon is 4 s: a longer episode leaves what the priority proofs cover, and says so
    with pytest.warns(UserWarning, match=r"episode's horizon is 4.5 s but the automaton's is 4 s \(8 samples\).*"
                      r"give a horizon= of at most 4 s, or lengthen the file's `horizon`"):  # and what to do
        ScenarioEnv(tiny, horizon=4.5)
    with warnings.catch_warnings():
        warnings.simplefilter("error", UserWarning)
        ScenarioEnv(tiny, horizon=4)


def test_a_horizon_of_no_whole_number_of_decisions_is_said(tiny: CompileResult) -> None:
    """horizon=1.5 with decisions of 1 s ended every episode with a step of one sample, half the others,
    without a word: a learner saw a step of another length and its reward summed over fewer samples."""
    with pytest.warns(UserWarning, match=r"horizon=1.5 s is no whole number of decisions of 1 s: the episode's last "
                                         r"step is 1 of 2 samples \(0.5 s\), shorter than the others; give a "
                                         r"multiple of 1 s \(1 or 2 s\)"):
        env = ScenarioEnv(tiny, horizon=1.5, lookahead=None)
    env.reset()
    assert not env.step(4)[3] and env.step(4)[3]  # still taken: two steps, the second of one sample
    with warnings.catch_warnings():
        warnings.simplefilter("error", UserWarning)
        ScenarioEnv(tiny, horizon=2, lookahead=None)  # two whole decisions: nothing to say
        ScenarioEnv(tiny, lookahead=None)  # the file's own horizon is rac check's to judge


def test_a_horizon_of_numpy_numbers_is_taken_and_no_number_refused(tiny: CompileResult) -> None:
    # a horizon from a numpy array (a sweep's settings): np.float32(1.5) raised "argument should be a string or
    # a Rational instance"; True was taken as 1 s, and NaN said "Invalid literal for Fraction: 'nan'"
    for horizon in (np.float32(1.5), np.float64(1.5), np.int64(3) / 2):
        assert ScenarioEnv(tiny, horizon=horizon, lookahead=None).episodes.horizon_samples == 3
    assert ScenarioEnv(tiny, horizon=np.float32(0.5), lookahead=None).episodes.horizon_samples == 1  # not 0.50000001
    with pytest.raises(TypeError, match="horizon must be a number of seconds, not True"):
        ScenarioEnv(tiny, horizon=True)
    for bad in (float("nan"), np.float32("inf")):
        with pytest.raises(ValueError, match="horizon must be a finite number of seconds"):
            ScenarioEnv(tiny, horizon=bad)


# ---------------------------------------------------------------- shield masks
def test_shielded_random_walks_never_collide(tiny: CompileResult, table: ShieldTable) -> None:
    env = ScenarioEnv(tiny, shield=table)
    rng = np.random.default_rng(0)
    for seed in range(15):
        env.reset(seed=seed)
        done = False
        while not done:
            mask = env.action_masks()
            assert mask.dtype == bool and mask.shape == (env.action_space.n,) and mask.any()
            _, _, terminated, truncated, info = env.step(int(rng.choice(np.flatnonzero(mask))))
            assert not info["collided"] and not info["offroad"]
            done = terminated or truncated
    # the shield is what keeps them safe: at the start it allows only braking straight on
    env.reset()
    assert env.action_masks().sum() == 1
    unshielded = ScenarioEnv(tiny)
    hits = 0
    for _ in range(15):
        unshielded.reset()
        assert unshielded.action_masks().all()
        done = False
        while not done:
            _, _, terminated, truncated, info = unshielded.step(int(rng.integers(unshielded.action_space.n)))
            hits += info["collided"] or info["offroad"]
            done = terminated or truncated
    assert hits > 0


def test_shield_from_a_file(tiny: CompileResult, table: ShieldTable, tmp_path: Path) -> None:
    path = shield_file.save(table, tmp_path / "safe.npz")
    env = ScenarioEnv(tiny, shield=path)
    env.reset()
    assert env.shield is not None and env.shield.unseen == "none"
    assert env.action_masks().tolist() == table.mask(env.episodes.state_keys()[0]).tolist()


@pytest.mark.parametrize("unseen", ["none", "all", "error"])
def test_unseen_states_without_a_runtime_shield(tiny: CompileResult, unseen: str) -> None:
    """Without a runtime shield an unseen state gets no guarantee, never an all-False mask: every action
    the model allows, flagged and counted (``unseen="error"`` still raises, as asked)."""
    short = shield_table(tiny, 2, unseen)  # a shield for the first second only: later states are unseen
    env = ScenarioEnv(tiny, shield=short, lookahead=None)
    env.reset()
    first = env.action_masks()
    assert 0 < first.sum() < first.size
    _, _, _, _, info = env.step(int(np.flatnonzero(first)[0]))  # now at sample 2: a state the shield never decided in
    assert info["shield"] == "exhaustive" and not info["no_safe_action"]
    if unseen == "error":
        with pytest.raises(UnseenState):
            env.action_masks()
        return
    mask = env.action_masks()
    assert mask.all()  # avoidable_obstacle has no `allow when`: the model allows every action
    _, _, _, _, info = env.step(0)
    assert info["shield"] == "none" and info["no_safe_action"] and info["shield_until"] == pytest.approx(1.0)
    assert env.episodes.k[0] == 4 and env.no_safe_action_steps == 1
    assert env.shield_steps == {"exhaustive": 1, "none": 1}


def test_a_mask_past_the_tables_horizon_without_a_runtime_shield_is_warned_of_once(tiny: CompileResult) -> None:
    # a table for the first second of a 4 s episode, lookahead=None: from 1 s on every mask allowed every action,
    # and only info['no_safe_action'] said so, which an evaluation loop or SB3's rollout never reads
    env = ScenarioEnv(tiny, shield=shield_table(tiny, 2, "none"), lookahead=None)
    for episode in range(2):
        env.reset()
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            done = False
            while not done:
                _, _, terminated, truncated, _ = env.step(int(np.flatnonzero(env.action_masks())[0]))
                done = terminated or truncated
        said = [str(w.message) for w in caught if "no action was known to be safe" in str(w.message)]
        if episode == 0:
            assert len(said) == 1, said
            assert "t = 1 s" in said[0] and "past the shield table's horizon" in said[0], said
            assert "lookahead=None" in said[0] and "no_safe_action" in said[0], said
        else:
            assert not said  # once
    assert env.no_safe_action_steps == 6 == env.shield_steps["none"]


def test_past_the_exhaustive_horizon_the_masks_are_the_runtime_shields(tiny: CompileResult) -> None:
    """A table for the first second of a 4 s episode: from there on the runtime shield's masks, each
    step's info saying which guarantee its mask carried (the depth the search reached)."""
    short = shield_table(tiny, 2, "none")
    env = ScenarioEnv(tiny, shield=short, lookahead=LookaheadSettings(depth=1, seconds=None))
    runtime = Lookahead(env.episodes.data, env.episodes.horizon_samples, LookaheadSettings(depth=1, seconds=None))
    rng = np.random.default_rng(2)
    kinds = []
    for _ in range(6):
        env.reset()
        done = False
        while not done:
            key = env.episodes.state_keys()[0]
            mask = env.action_masks()
            assert mask.any()
            expected = runtime.decide(key)
            _, _, terminated, truncated, info = env.step(int(rng.choice(np.flatnonzero(mask))))
            kinds.append(info["shield"])
            if key[0] < 2:
                assert info["shield"] == "exhaustive" and mask.tolist() == short.mask(key).tolist()
                assert info["shield_until"] == pytest.approx(1.0)
            elif expected.depth:
                assert info["shield"] == "lookahead 1" and mask.tolist() == expected.mask.tolist()
                assert info["shield_until"] == pytest.approx(expected.until * 0.5)
            else:
                assert info["shield"] == "none" and info["no_safe_action"]
            assert info["shield_allowed"] and not info["shield_timeout"] and not info["shield_short"]
            done = terminated or truncated
    assert kinds.count("exhaustive") == 6 and kinds.count("lookahead 1") > 0
    assert sum(env.shield_steps.values()) == len(kinds)
    assert env.shield_steps["lookahead 1"] == kinds.count("lookahead 1")


def test_an_on_demand_shield_past_its_horizon_claims_nothing(tiny: CompileResult) -> None:
    # an on-demand shield (rac.engine.ondemand) "knows" every state and allows every action at and past its
    # horizon; in a longer episode without a runtime shield those masks were called exhaustive, their
    # shield_until already past, while the run collided under them
    from rac.engine.ondemand import on_demand

    data = tiny.model_data
    assert data is not None
    env = ScenarioEnv(tiny, shield=on_demand(data, 4), lookahead=None)  # 2 s of the episode's 4 s
    _, info = env.reset()
    done, seen = False, []
    while not done:
        at = info["time"]  # the state's time, s
        mask = env.action_masks()
        _, _, terminated, truncated, info = env.step(int(np.flatnonzero(mask)[-1]))
        seen.append(info["shield"])
        if info["shield"] == "exhaustive":  # a guarantee that reaches beyond the state it was handed out in
            assert info["shield_until"] > at
        else:
            assert at >= 2.0 and info["shield"] == "none" and info["no_safe_action"] and mask.all()
        done = terminated or truncated
    assert seen == ["exhaustive", "exhaustive", "none", "none"]


def test_a_runtime_shield_alone_keeps_random_walks_safe(tiny: CompileResult) -> None:
    """Without any table, a lookahead over the rest of the episode is the exhaustive shield computed at
    run time: shielded random walks never collide nor leave the road."""
    env = ScenarioEnv(tiny, lookahead=LookaheadSettings(depth=4, seconds=None))
    rng = np.random.default_rng(0)
    for _ in range(10):
        env.reset()
        done = False
        while not done:
            _, _, terminated, truncated, info = env.step(int(rng.choice(np.flatnonzero(env.action_masks()))))
            assert not info["collided"] and not info["offroad"] and info["shield"].startswith("lookahead ")
            done = terminated or truncated
    assert set(env.shield_steps) == {"lookahead 4", "lookahead 3", "lookahead 2", "lookahead 1"}
    # a depth is any integer, numpy's too (np.int64(3) was a TypeError); a bool is not one
    assert ScenarioEnv(tiny, lookahead=np.int64(3)).step_shield.runtime.settings.depth == 3  # type: ignore[union-attr]
    with pytest.raises(TypeError, match="lookahead must be"):
        ScenarioEnv(tiny, lookahead=True)


def test_never_an_all_false_mask(tiny: CompileResult) -> None:
    """Random walks that ignore the masks run into the van: where no action has a safe continuation the
    mask allows every action of the model, with info["shield"] == "none" and the step flagged and counted."""
    env = ScenarioEnv(tiny, lookahead=LookaheadSettings(depth=2, seconds=None))
    rng = np.random.default_rng(5)
    flagged = 0
    for _ in range(10):
        env.reset()
        done = False
        while not done:
            mask = env.action_masks()
            assert mask.dtype == bool and mask.any()
            _, _, terminated, truncated, info = env.step(int(rng.integers(env.action_space.n)))
            assert info["no_safe_action"] == (info["shield"] == "none")
            if info["no_safe_action"]:
                assert mask.all()
                flagged += 1
            done = terminated or truncated
    assert flagged > 0 and env.no_safe_action_steps == flagged == env.shield_steps["none"]


def test_after_a_sticky_collision_nothing_is_safe(tmp_path: Path) -> None:
    """Under ``collision sticky`` a collision makes every later state unsafe: "none" to the end."""
    path = write_engine_file(tmp_path, "avoidable_obstacle", queries={})
    text = path.read_text(encoding="utf-8")
    path.write_text(text.replace("    model {\n", "    model {\n        collision sticky\n", 1), encoding="utf-8")
    result = compile_file(path)
    assert result.ok and result.model_data is not None and result.model_data.sticky
    env = ScenarioEnv(result, lookahead=LookaheadSettings(depth=2, seconds=None))
    env.reset()
    crashed, done, kinds = False, False, []
    while not done:
        _, _, terminated, truncated, info = env.step(8)  # full throttle, straight on: into the van
        if crashed:
            kinds.append(info["shield"])
        crashed = crashed or info["collided"]
        done = terminated or truncated
    assert crashed and kinds and set(kinds) == {"none"}


def test_the_time_budget_reports_itself_in_info(tiny: CompileResult) -> None:
    env = ScenarioEnv(tiny, lookahead=LookaheadSettings(depth=4, seconds=None, nodes=1))
    env.reset()
    _, _, _, _, info = env.step(int(np.flatnonzero(env.action_masks())[0]))
    assert info["shield_timeout"] and info["shield"] == "lookahead 1" and env.timeout_steps == 1
    assert info["shield_short"]  # 1 of the 4 decisions asked for


def test_the_step_info_without_a_shield(tiny: CompileResult) -> None:
    env = ScenarioEnv(tiny)
    env.reset()
    assert env.action_masks().all()
    _, _, _, _, info = env.step(4)
    assert info["shield"] == "none" and not info["no_safe_action"] and not info["shield_timeout"]
    assert env.no_safe_action_steps == 0 and env.shield_steps == {"none": 1}


class Reversed(gymnasium.ActionWrapper):  # type: ignore[type-arg]
    """A user's action wrapper: the learner's action a is the environment's P - 1 - a (the masks, read
    through it with get_wrapper_attr, are still the environment's own)."""

    def action(self, action: int) -> int:
        return int(self.action_space.n) - 1 - int(action)  # type: ignore[attr-defined]


def test_an_action_outside_the_mask_is_warned_of_once_and_counted(tiny: CompileResult) -> None:
    # a learner that chose from the mask behind an action wrapper (or MaskablePPO.predict without
    # action_masks=, evaluate_policy(use_masking=False), DQN) took unshielded steps; only
    # info["shield_allowed"] said so, which an evaluation loop drops: no warning, no counter
    env = Reversed(ScenarioEnv(tiny, shield=shield_table(tiny, 8, "none")))  # the runtime shield off the table
    outside = 0
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        for _ in range(2):  # the first step of two episodes: the table allows one action, the wrapper takes another
            env.reset()
            mask = env.get_wrapper_attr("action_masks")()
            chosen = int(np.flatnonzero(mask)[0])  # what a masked learner picks
            _, _, _, _, info = env.step(chosen)
            outside += not mask[env.action(chosen)]
            assert info["shield"] == "exhaustive" and info["shield_allowed"] == bool(mask[env.action(chosen)])
    assert outside == 2  # the wrapper took both steps out of the mask
    said = [str(w.message) for w in caught if "not in the mask" in str(w.message)]
    assert len(said) == 1 and "action wrapper" in said[0] and "t = 0 s" in said[0], said
    assert env.get_wrapper_attr("outside_mask_steps") == outside
    inner = env.unwrapped
    inner.reset()
    _, _, _, _, info = inner.step(int(np.flatnonzero(inner.action_masks())[0]))  # within the mask: not counted
    assert info["shield_allowed"] and inner.outside_mask_steps == outside


def test_steps_outside_the_mask_in_a_vector_environment_are_said_once_naming_the_first(tiny: CompileResult) -> None:
    # each sub-environment of a DummyVecEnv (SyncVectorEnv) said its own first step outside the mask, its text
    # naming its own action and time, so Python's warnings filter, which drops a repeated text, showed them all
    table = shield_table(tiny, 8, "none")
    envs = gymnasium.vector.SyncVectorEnv([lambda: Reversed(ScenarioEnv(tiny, shield=table))] * 3)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        envs.reset(seed=0)
        chosen = [int(np.flatnonzero(env.get_wrapper_attr("action_masks")())[0]) for env in envs.envs]
        envs.step(np.array(chosen))
    said = [str(w.message) for w in caught if "not in the mask" in str(w.message)]
    assert [env.get_wrapper_attr("outside_mask_steps") for env in envs.envs] == [1, 1, 1]  # each counted
    assert len(said) == 1 and "t = 0 s" in said[0], said  # the first's action and time kept
    assert said[0].endswith("(sub-environment 0 of the 3 of a SyncVectorEnv: said once for them all, each counts "
                            "its own)"), said
    assert caught[[str(w.message) for w in caught].index(said[0])].filename == __file__  # the line stepping them


def test_without_a_shield_the_mask_is_the_models_allow_when(tiny: CompileResult, tmp_path: Path) -> None:
    # `allow when` is part of the model: a mask without any shield still keeps to it (it allowed
    # every action), and a step that takes what it forbids is flagged and counted, never silent
    source = Path(tiny.sources and next(iter(tiny.sources))).read_text(encoding="utf-8")
    assert "        bind near =" in source
    path = tmp_path / "allowing.ra"
    path.write_text(source.replace("        bind near =", ALLOW_WHEN + "        bind near =", 1), encoding="utf-8")
    (tmp_path / "avoidable_obstacle.xml").write_bytes((Path(next(iter(tiny.sources))).parent
                                                      / "avoidable_obstacle.xml").read_bytes())
    env = ScenarioEnv(path)
    env.reset()
    left = int(np.flatnonzero((env.action_pairs[:, 1] > 0) & (env.action_pairs[:, 0] == 0))[0])  # turn on, jerk 0
    seen = []
    for _ in range(2):
        masks = env.action_masks()
        model = env.episodes.model_masks()[0]
        assert (masks == model).all() and masks.any()
        seen.append(bool(masks[left]))
        _, _, _, _, info = env.step(left)
        assert info["model_allowed"] == info["shield_allowed"] == seen[-1] and info["shield"] == "none"
    assert seen == [True, False]  # turning on is allowed at the start, forbidden once the heading has grown
    assert env.disallowed_steps == 1
    # beyond 0.25 rad the rule forbids everything: the run would stop there, so every action is allowed
    assert env.action_masks().all()


def test_shield_for_another_model(tiny: CompileResult, table: ShieldTable) -> None:
    other = ShieldTable(COLUMNS, table.states, table.masks[:, :4])
    with pytest.raises(ValueError, match="actions"):
        ScenarioEnv(tiny, shield=other)
    with pytest.raises(TypeError):
        ScenarioEnv(tiny, shield=42)  # type: ignore[arg-type]


def test_a_shield_of_another_scene_is_refused(tiny: CompileResult, tmp_path: Path) -> None:
    # a saved shield records the model it was computed for: the same states and actions of another
    # scene (here the van 2 m longer) would have had its masks called exhaustive with no proof behind them
    data = tiny.model_data
    assert data is not None
    computed, table = shield_file.synthesise(data, 8)
    assert computed.shield_exists and table.model == data.digest
    path = shield_file.save(table, tmp_path / "safe.shield.npz")
    assert shield_file.load(path).model == data.digest
    ScenarioEnv(tiny, shield=path).reset()  # its own model: used
    longer = dataclasses.replace(data, obs_length=tuple(n + 2 * data.scale for n in data.obs_length))
    assert longer.digest != data.digest
    other = dataclasses.replace(tiny, model_data=longer)
    with pytest.raises(ValueError, match=r"the shield .*safe\.shield\.npz was computed for another model"):
        ScenarioEnv(other, shield=path).reset()
    # a file without the record (written before rac kept one) is still read, as before
    with np.load(path) as npz:
        np.savez(tmp_path / "old.npz", **{k: npz[k] for k in npz.files if k != "model"})
    assert shield_file.load(tmp_path / "old.npz").model is None
    with pytest.warns(UserWarning, match="does not record the model"):
        ScenarioEnv(other, shield=tmp_path / "old.npz").reset()


def test_the_model_digest_ignores_layout_and_sees_allow_when(tiny: CompileResult, tmp_path: Path) -> None:
    source = Path(next(iter(tiny.sources))).read_text(encoding="utf-8")
    (tmp_path / "avoidable_obstacle.xml").write_bytes((Path(next(iter(tiny.sources))).parent
                                                      / "avoidable_obstacle.xml").read_bytes())
    digests = []
    for name, text in (("a", source.replace("        bind near =", ALLOW_WHEN + "        bind near =", 1)),
                       ("b", "// moved down a line\n\n" + source.replace(
                           "        bind near =", ALLOW_WHEN.replace("<= 0.25", "<=  0.25") + "        bind near =",
                           1)),
                       ("c", source.replace("        bind near =", ALLOW_WHEN.replace("0.25", "0.3")
                                            + "        bind near =", 1))):
        (tmp_path / f"{name}.ra").write_text(text, encoding="utf-8")
        result = compile_file(tmp_path / f"{name}.ra")
        assert result.ok and result.model_data is not None
        digests.append(result.model_data.digest)
    assert digests[0] == digests[1] != digests[2] != tiny.model_data.digest  # type: ignore[union-attr]


def test_a_wrapper_around_the_environment_sees_its_time_step(tiny: CompileResult) -> None:
    """RewardAutomatonWrapper around ScenarioEnv takes one sample per step, a decision period: with an
    automaton sampling every sense period it silently took one sample where ScenarioEnv takes two (the
    wrapper's objective half of the environment's); ScenarioEnv's ``dt`` lets the wrapper say so."""
    from rac.learning.wrappers import RewardAutomatonWrapper

    env = ScenarioEnv(tiny, lookahead=None)
    assert env.dt == 1.0 == float(env.episodes.decide_every * tiny.automaton.period)  # type: ignore[union-attr]
    with pytest.warns(UserWarning, match=r"time step is 1 s but the automaton samples every 0.5 s"):
        RewardAutomatonWrapper(env, tiny.automaton, lambda obs, info: info["inputs"])  # type: ignore[arg-type]
    from rac.learning.vector import ScenarioVectorEnv
    from rac.learning.wrappers import RewardAutomatonVectorWrapper

    vector = ScenarioVectorEnv(tiny, num_envs=2, lookahead=None)
    assert vector.dt == 1.0 and vector.get_attr("dt") == (1.0, 1.0)
    assert vector.reset()[1]["planning_problem"].tolist() == [100, 100]  # as ScenarioEnv's info says it
    with pytest.warns(UserWarning, match=r"time step is 1 s but the automaton samples every 0.5 s"):
        RewardAutomatonVectorWrapper(vector, tiny.automaton, lambda obs, infos: infos["inputs"])  # type: ignore[arg-type]


# ---------------------------------------------------------------- errors
def test_errors(tiny: CompileResult) -> None:
    with pytest.raises(CheckError):
        ScenarioEnv(REPO / "examples" / "naive_driving.ra")
    plain = compile_text("automaton A { input b : bool\n reward r\n objective r\n sample every 1\n horizon 2\n"
                         " initial location L { r' == 1 } }")
    with pytest.raises(ValueError, match="model"):
        ScenarioEnv(plain)
    with pytest.raises(ValueError, match="render_mode"):
        ScenarioEnv(tiny, render_mode="human")
    env = ScenarioEnv(tiny)
    with pytest.raises(RuntimeError, match="reset"):
        env.step(0)
    env.reset()
    with pytest.raises(ValueError, match="action"):
        env.step(9)
    assert env.render() is None


def test_a_step_shield_as_the_shield(tiny: CompileResult) -> None:
    from rac.engine.shield import step_shield

    data = tiny.model_data
    assert data is not None
    env = ScenarioEnv(tiny, shield=step_shield(data, 8, lookahead=LookaheadSettings(depth=2, seconds=None)))
    env.reset()
    _, _, _, _, info = env.step(int(np.flatnonzero(env.action_masks())[0]))
    assert info["shield"] == "exhaustive" and env.shield is not None
    with pytest.raises(ValueError, match="runs of 4 samples"):
        ScenarioEnv(tiny, shield=step_shield(data, 4))
    with pytest.raises(ValueError, match="lookahead"):
        ScenarioEnv(tiny, shield=step_shield(data, 8), lookahead=3)


def test_a_step_shield_of_another_scene_is_refused(tiny: CompileResult) -> None:
    """A StepShield searches its own model's obstacles (and its table is that model's): in another
    scene's environment its masks were handed out, exhaustive and lookahead guarantees and all."""
    from rac.engine.shield import StepShield

    data = tiny.model_data
    assert data is not None
    longer = dataclasses.replace(data, obs_length=tuple(n + 2 * data.scale for n in data.obs_length))
    other = dataclasses.replace(tiny, model_data=longer)
    runtime = LookaheadSettings(depth=2, seconds=None)
    ScenarioEnv(other, shield=StepShield(longer, 8, lookahead=runtime)).reset()  # its own model: used
    with pytest.raises(ValueError, match="StepShield was made for another model"):
        ScenarioEnv(other, shield=StepShield(data, 8, lookahead=runtime))


# ---------------------------------------------------------------- scene sets, the relative observation, frames
#: The model block of the highway scene the tests below share (9 actions every 0.5 s).
HIGHWAY_BLOCK = """\
        scenario "highway.xml"
        exponent 2
        decide_period 0.5
        granularity 0.25
        max_speed 30
        action jerk in [-2, 2] step 2
        action turn in [-0.2, 0.2] step 0.2
"""

HIGHWAY_MODEL = """\
automaton Drive {
    reward r
    objective r
    sample every 0.1
    horizon 2
    initial location L { r' == 1 }
    model {
""" + HIGHWAY_BLOCK + """    }
}
"""


@pytest.fixture(scope="module")
def highway_set(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, list[Path]]:
    """A .ra file on the highway scene and a set of three seeded highway variants."""
    from rac.model.scenes import scene_set, write_scene

    folder = tmp_path_factory.mktemp("set")
    write_scene("highway", folder / "highway.xml")
    (folder / "drive.ra").write_text(HIGHWAY_MODEL, encoding="utf-8")
    return folder / "drive.ra", scene_set("highway", 3, 0, folder / "scenes")


def test_a_table_made_from_a_graph_is_refused_on_another_scene(highway_set: tuple[Path, list[Path]]) -> None:
    # docs/python.md makes a table with shield.table(safety_shield(explore(data, ...), "safe"), n_actions=P),
    # without model=: it recorded no model, so the table of one highway variant passed on another (the
    # same ego start, other cars) had its masks called "exhaustive" there, without a word
    from rac.lang.edit import with_model

    model, scenes = highway_set
    text = model.read_text(encoding="utf-8")
    first, second = (compile_text(with_model(text, model, scene), name=str(model)) for scene in scenes[:2])
    data = first.model_data
    assert data is not None and second.model_data is not None and second.model_data.digest != data.digest
    table = shield_file.table(safety_shield(explore(data, horizon_samples=20, prune_unsafe=True), "safe"),
                              n_actions=EpisodeBatch(first).n_actions)
    assert table.model == data.digest  # the graph knows the model it explored
    env = ScenarioEnv(first, shield=table)
    env.reset()
    assert env.shield_step() is not None and env.shield_step().guarantee == "exhaustive"
    with pytest.raises(ValueError, match="computed for another model"):
        ScenarioEnv(second, shield=table)
    # a table that records none (built by hand, an old file) is still used, but not without a word
    with pytest.warns(UserWarning, match="does not record the model it was computed for"):
        ScenarioEnv(second, shield=dataclasses.replace(table, model=None))


def test_the_relative_observation_by_hand(highway_set: tuple[Path, list[Path]]) -> None:
    from rac.learning.observation import RELATIVE_COLUMNS

    env = ScenarioEnv(highway_set[0])
    obs, _ = env.reset()
    got = dict(zip([name for name, _, _ in RELATIVE_COLUMNS], obs.tolist()))
    # the ego at (30, 5.25) heading 0 at 20 m/s in the middle of three 3.5 m lanes, goal centre (200, 5.25)
    ego = {"v": 20.0, "acc": 0.0, "lane_head": 0.0, "lane_offset": 0.0, "edge_left": 5.25, "edge_right": 5.25,
           "goal_ahead": 170.0, "goal_left": 0.0, "time_left": 2.0}
    # nearest first: car 62 (10, 8.75) at 25 m/s, truck 61 (70, 5.25) at 15, car 63 (95, 1.75) at 17; slot 3 empty
    cars = [(1, -20.0, 3.5, 5.0, 0.0), (1, 40.0, 0.0, -5.0, 0.0), (1, 65.0, -3.5, -3.0, 0.0), (0, 0, 0, 0, 0)]
    expected = {**ego, **{f"obstacle{j}_{name}": float(value) for j, car in enumerate(cars)
                          for name, value in zip(["present", "ahead", "left", "v_ahead", "v_left"], car)}}
    assert got == pytest.approx(expected, abs=1e-5)
    # one step of jerk 0, turn 0.2: the ego turns left of the lane's direction and drifts left
    obs, *_ = env.step(int(np.flatnonzero((env.action_pairs[:, 0] == 0) & (env.action_pairs[:, 1] > 0))[0]))
    assert obs[2] > 0 and obs[3] > 0 and obs[4] < 5.25 < obs[5] and obs[8] == pytest.approx(1.5)


@pytest.mark.parametrize("gap", ["hole", "crack"])
def test_the_road_edges_skip_hairline_gaps_between_lanelets(tmp_path: Path, gap: str) -> None:
    """Real maps leave hairline gaps between neighbouring lanelets (DEU_Muc-3_1_T-1: 20 holes about 3e-5 m
    wide along its lane dividers, docs/scenario.md; at exponent 2, 9 holes up to one significand wide).
    `edge_left`/`edge_right` read such a gap as the road's edge: the ego in the middle of three lanes saw
    the edge at the lane divider, 1.75 m away, not 5.25 m."""
    from commonroad.scenario.lanelet import Lanelet
    from commonroad.scenario.scenario import Tag

    from rac.model.scenario_xml import scenario_bytes
    from rac.model.scenes import build_highway

    scenario, problems = build_highway()
    middle = scenario.lanelet_network.find_lanelet_by_id(2)
    right = middle.right_vertices.copy()
    # the middle lane's right bound one significand (1 cm at exponent 2) off its neighbour's left bound:
    # between its ends (a hole), or along the whole road (a crack that parts the road in two)
    right[1:-1 if gap == "hole" else None, 1] += 0.01
    scenario.remove_lanelet(middle)
    scenario.add_objects(Lanelet(middle.left_vertices, (middle.left_vertices + right) / 2, right, 2,
                                 adjacent_left=3, adjacent_left_same_direction=True, adjacent_right=1,
                                 adjacent_right_same_direction=True))
    (tmp_path / "highway.xml").write_bytes(scenario_bytes(scenario, problems, tags={Tag.HIGHWAY}, source="gap"))
    (tmp_path / "drive.ra").write_text(HIGHWAY_MODEL, encoding="utf-8")
    obs, _ = ScenarioEnv(tmp_path / "drive.ra").reset()
    # the ego at (30, 5.25) in the middle of the road from y = 0 to 10.5
    assert obs[4] == pytest.approx(5.25, abs=1e-3) and obs[5] == pytest.approx(5.25, abs=1e-3)


def test_the_relative_observation_of_a_goal_of_time_alone(highway_set: tuple[Path, list[Path]],
                                                          tmp_path: Path) -> None:
    """A goal state without a position holds wherever the ego is: no direction to the goal (0, 0),
    not the direction to the model's placeholder centre (0, 0) of the map, 30 m behind the ego."""
    import re

    text = (highway_set[0].parent / "highway.xml").read_text(encoding="utf-8")
    text, made = re.subn(r"(<goalState>.*?</time>)\s*<position>.*?</position>", r"\1", text, flags=re.S)
    assert made == 1
    (tmp_path / "highway.xml").write_text(text, encoding="utf-8")
    (tmp_path / "drive.ra").write_text(HIGHWAY_MODEL, encoding="utf-8")
    obs, _ = ScenarioEnv(tmp_path / "drive.ra").reset()
    assert obs[6] == 0.0 and obs[7] == 0.0 and obs[0] == pytest.approx(20.0)


def test_every_observation_lies_in_the_bounds(highway_set: tuple[Path, list[Path]]) -> None:
    env = ScenarioEnv(highway_set[0], scenarios=highway_set[1])
    space = env.observation_space
    assert np.isfinite(space.low).all() and np.isfinite(space.high).all() and space.shape == (29,)
    rng = np.random.default_rng(0)
    seen = []
    for episode in range(6):
        obs, _ = env.reset(seed=episode)
        done = False
        while not done:
            assert space.contains(obs), obs
            seen.append(obs)
            obs, _, terminated, truncated, _ = env.step(int(rng.integers(env.action_space.n)))
            done = terminated or truncated
        assert space.contains(obs)
    assert len({tuple(o[9:]) for o in seen}) > 10  # the obstacles move and differ from scene to scene


def test_a_scene_set_draws_from_np_random_and_picks_on_request(highway_set: tuple[Path, list[Path]]) -> None:
    model, scenes = highway_set
    env = ScenarioEnv(model, scenarios=scenes[0].parent)  # a folder: its .xml files in name order
    assert env.scenarios == tuple(scenes)
    drawn = [env.reset(seed=s)[1]["scenario"] for s in range(20)]
    assert drawn == [env.reset(seed=s)[1]["scenario"] for s in range(20)]  # reproducible per seed
    assert set(drawn) == {str(p) for p in scenes}
    first, info = env.reset(options={"scenario": 1})
    assert info["scenario"] == str(scenes[1])
    again, info = env.reset(options={"scenario": str(scenes[1])})
    assert info["scenario"] == str(scenes[1]) and first.tolist() == again.tolist()
    other, _ = env.reset(options={"scenario": 2})
    assert other[9:].tolist() != first[9:].tolist()  # other obstacles
    # a misspelt option drew a scene at random without a word
    with pytest.warns(UserWarning, match=r"reset\(options=\.\.\.\) ignores 'scene': ScenarioEnv reads only"):
        env.reset(seed=0, options={"scene": 1})
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        env.reset(seed=0, options={"scene": 1})  # said once
        env.reset(options={"scenario": 1, "reset_mask": None})
    with pytest.raises(ValueError, match=r"holds 3 scenes, numbered 0 \.\. 2"):
        env.reset(options={"scenario": 3})
    with pytest.raises(ValueError, match=r"holds 1 scene, numbered 0 \.\. 0"):  # said 'there are 1 scenes'
        ScenarioEnv(model, scenarios=scenes[:1]).reset(options={"scenario": 1})
    with pytest.raises(ValueError, match="not one of the scenes"):
        env.reset(options={"scenario": "elsewhere.xml"})
    with pytest.raises(ValueError, match="runtime shield"):
        ScenarioEnv(model, scenarios=scenes, shield="safe.shield.npz")
    shielded = ScenarioEnv(model, scenarios=scenes, lookahead=2)
    shielded.reset(seed=0)
    assert shielded.action_masks().any() and shielded.step(0)[4]["shield"].startswith("lookahead")


def test_a_broken_scene_names_its_file(highway_set: tuple[Path, list[Path]], tmp_path: Path) -> None:
    broken = tmp_path / "broken.xml"
    broken.write_text("<commonRoad>", encoding="utf-8")
    env = ScenarioEnv(highway_set[0], scenarios=[highway_set[1][0], broken])
    with pytest.raises(CheckError, match="broken.xml"):
        env.reset(options={"scenario": 1})
    with pytest.raises(CheckError, match="broken.xml"):
        ScenarioEnv(highway_set[0], scenarios=[broken])


def test_check_env_with_a_set_and_frames(highway_set: tuple[Path, list[Path]]) -> None:
    env = ScenarioEnv(highway_set[0], scenarios=highway_set[1], render_mode="rgb_array")
    assert "rgb_array" in env.metadata["render_modes"]
    assert checked(env) == []
    env.reset(seed=0)
    first = env.render()
    assert isinstance(first, np.ndarray) and first.dtype == np.uint8 and first.ndim == 3 and first.shape[2] == 3
    env.step(0)
    later = env.render()
    assert isinstance(later, np.ndarray) and later.shape == first.shape and (later != first).any()


def test_record_video(highway_set: tuple[Path, list[Path]], tmp_path: Path) -> None:
    pytest.importorskip("moviepy", reason="gymnasium's RecordVideo writes videos with moviepy, not installed here")
    from gymnasium.wrappers import RecordVideo

    env = RecordVideo(ScenarioEnv(highway_set[0], render_mode="rgb_array"), str(tmp_path / "videos"))
    env.reset(seed=0)
    done = False
    while not done:
        _, _, terminated, truncated, _ = env.step(0)
        done = terminated or truncated
    env.close()
    assert list((tmp_path / "videos").glob("*.mp4"))


# ---------------------------------------------------------------- the proven reward scale (issue 21)
#: Safety over progress on the highway scene, with rewards in the tens and a penalty of 100.
CAREFUL_MODEL = """\
automaton Careful {
    input isClose : bool
    input collide : bool
    assume collide imply isClose
    reward sa, pr
    priority sa > pr
    objective 10 * sa + pr
    sample every 0.1
    horizon 2
    initial location Normal { sa' == 1; pr' == 1 }
    location Unsafe { sa' == -1; pr' == 0 }
    edge * -> Unsafe when isClose do sa = sa - 100
    edge * -> Normal when !isClose
    model {
""" + HIGHWAY_BLOCK + """\
        bind isClose = mindist() < 3 * collision_distance
        bind collide = collide()
    }
}
"""


def test_the_proven_scale_keeps_every_reward_within_one(highway_set: tuple[Path, list[Path]]) -> None:
    """Rewards in the tens become rewards in [-1, 1], divided by one positive factor: the largest
    change of the objective over one step (decide_every samples and ``at end``) that the checker proves."""
    from rac.check.analysis.scale import sample_change_bound

    model = highway_set[0].with_name("careful.ra")
    model.write_text(CAREFUL_MODEL, encoding="utf-8")
    scenes = highway_set[1]
    plain = ScenarioEnv(model, scenarios=scenes, lookahead=None)
    scaled = ScenarioEnv(model, scenarios=scenes, lookahead=None, scale="proven")
    automaton = scaled.episodes.automaton
    factor = float(sample_change_bound(automaton).step_bound(scaled.episodes.decide_every))
    assert scaled.reward_scale == factor > 1 and plain.reward_scale == 1.0
    rng = np.random.default_rng(0)
    largest = 0.0
    for episode in range(6):
        _, info = scaled.reset(seed=episode)
        # info["proven"], as RewardAutomatonWrapper's info["rac"]["proven"]: a KeyError before
        assert info["scale"] == factor and info["proven"] is True
        assert plain.reset(seed=episode)[1]["proven"] is False
        done = False
        while not done:
            action = int(rng.integers(plain.action_space.n))
            _, raw, *_ = plain.step(action)
            _, reward, terminated, truncated, info = scaled.step(action)
            assert -1.0 <= float(reward) <= 1.0
            assert float(reward) == pytest.approx(float(raw) / factor, rel=1e-12)
            largest = max(largest, abs(float(raw)))
            done = terminated or truncated
    assert largest > 1.0  # the unscaled rewards would not have fitted


def test_a_scale_for_a_reward_expression_is_the_users(tiny: CompileResult) -> None:
    with pytest.raises(ValueError, match="proved for the automaton's reward"):
        ScenarioEnv(tiny, reward="10 * !collide()", scale="proven")
    plain = ScenarioEnv(tiny, reward="10 * !collide()")
    scaled = ScenarioEnv(tiny, reward="10 * !collide()", scale=10.0)
    plain.reset(seed=0)
    scaled.reset(seed=0)
    _, raw, *_ = plain.step(0)
    _, reward, *_ = scaled.step(0)
    assert float(raw) > 10 and float(reward) == pytest.approx(float(raw) / 10)


def test_the_automaton_ends_the_episode(tiny: CompileResult) -> None:
    """`episode ends when near`: the episode terminates at the first sample the van is near (the goal is
    not reached: info's goal stays False), with the reward EpisodeBatch gives; speeding up gets there."""
    ending = dataclasses.replace(tiny, automaton=dataclasses.replace(tiny.automaton, episode_ends=ir.BInput("near")))
    env, batch = ScenarioEnv(ending), EpisodeBatch(ending)
    env.reset(seed=0)
    batch.reset(1)
    fastest = int(np.argmax(env.episodes.action_pairs[:, 0] - np.abs(env.episodes.action_pairs[:, 1])))
    done, steps = False, 0
    while not done:
        _, reward, terminated, truncated, info = env.step(fastest)
        out = batch.step(np.array([fastest]))
        assert reward == out.reward[0] and terminated == bool(out.terminated[0] or out.ended[0])
        assert truncated == out.truncated[0] and info["goal"] == out.terminated[0]
        done, steps = terminated or truncated, steps + 1
    assert terminated and out.ended[0] and not info["goal"] and info["inputs"] == {"near": True}
    assert info["time"] < 4.0 and env.episodes.done.all()
    with pytest.raises(RuntimeError, match="reset"):
        env.step(0)


def test_a_file_that_ends_its_episodes(tmp_path: Path) -> None:
    """`episode ends when near` written in the file's automaton: ScenarioEnv terminates at the first sample
    the van is near, as with the declaration set on the IR above."""
    path = write_engine_file(tmp_path, "avoidable_obstacle", queries={})
    text = path.read_text(encoding="utf-8").replace("    model {", "    episode ends when near\n\n    model {")
    path.write_text(text, encoding="utf-8")
    env = ScenarioEnv(path)
    assert env.episodes.automaton.episode_ends == ir.BInput("near")
    env.reset(seed=0)
    fastest = int(np.argmax(env.episodes.action_pairs[:, 0] - np.abs(env.episodes.action_pairs[:, 1])))
    terminated = truncated = False
    while not (terminated or truncated):
        _, _, terminated, truncated, info = env.step(fastest)
    assert terminated and not info["goal"] and info["inputs"] == {"near": True} and info["time"] < 4.0


def test_an_environment_pickles_and_goes_on_alike(tiny: CompileResult, table: ShieldTable) -> None:
    # a process pool (ProcessPoolExecutor.submit(f, env), multiprocessing) pickles what it sends; the
    # compiled expressions are generated code in no module, and pickling them failed
    import pickle

    env = ScenarioEnv(tiny, shield=table)
    env.reset(seed=3)
    env.step(int(np.flatnonzero(env.action_masks())[0]))
    other = pickle.loads(pickle.dumps(env))
    for _ in range(3):
        masks = env.action_masks()
        assert (masks == other.action_masks()).all()
        action = int(np.flatnonzero(masks)[-1])
        mine, theirs = env.step(action), other.step(action)
        assert (mine[0] == theirs[0]).all() and mine[1:4] == theirs[1:4]
        assert mine[4]["objective"] == theirs[4]["objective"] and mine[4]["time"] == theirs[4]["time"]


def _masks_of_a_run(env: ScenarioEnv, seed: int) -> tuple[list[list[bool]], list[dict[str, object]]]:
    """The masks and the shield's info of one seeded masked random walk."""
    rng = np.random.default_rng(seed)
    env.reset(seed=seed)
    masks, infos, done = [], [], False
    while not done:
        mask = env.action_masks()
        masks.append(mask.tolist())
        _, _, terminated, truncated, info = env.step(int(rng.choice(np.flatnonzero(mask))))
        infos.append({key: info[key] for key in ("shield", "shield_timeout", "shield_clock")})
        done = terminated or truncated
    return masks, infos


def test_the_default_runtime_shield_does_not_depend_on_the_machines_speed(
        tiny: CompileResult, monkeypatch: pytest.MonkeyPatch) -> None:
    # The default runtime shield (lookahead=<depth>, or "auto" beside a table) had a time budget of
    # 0.1 s a decision and no node budget: on a loaded machine its searches were cut earlier, so the
    # same seed gave other masks, and other trajectories, than on an idle one. Its default budget is
    # now a number of search nodes; the clock is only a guard far above it, reported where it fires.
    fast = _masks_of_a_run(ScenarioEnv(tiny, lookahead=4), seed=3)
    assert not any(info["shield_clock"] for info in fast[1])
    clock = iter(range(10**7))
    # a slow or loaded machine: every reading of the clock 50 ms after the one before
    monkeypatch.setattr("rac.engine.lookahead.time.perf_counter", lambda: next(clock) * 0.05)
    slow = _masks_of_a_run(ScenarioEnv(tiny, lookahead=4), seed=3)
    assert slow == fast
    settings = ScenarioEnv(tiny, lookahead=4).step_shield.runtime.settings  # type: ignore[union-attr]
    assert settings.nodes is not None and settings.seconds is not None


def test_the_time_guard_says_where_it_cut_the_search(tiny: CompileResult, monkeypatch: pytest.MonkeyPatch) -> None:
    # Where the time guard does cut a search, the mask depended on the machine: info says so, the
    # environment counts it, and it warns once (the run at this seed may not be repeated).
    clock = iter(range(10**7))
    monkeypatch.setattr("rac.engine.lookahead.time.perf_counter", lambda: float(next(clock)) * 1000)
    env = ScenarioEnv(tiny, lookahead=4)
    with pytest.warns(RuntimeWarning, match="time limit .* stopped its search") as caught:
        _, infos = _masks_of_a_run(env, seed=0)
    assert len([w for w in caught if "stopped its search" in str(w.message)]) == 1
    assert all(info["shield_clock"] and info["shield_timeout"] for info in infos if info["shield"] != "none")
    assert env.clock_steps == sum(bool(info["shield_clock"]) for info in infos) > 0


def test_episodes_past_the_recorded_traffic_are_warned_of_once(tmp_path: Path) -> None:
    # ScenarioEnv(horizon=...) past the scene's recorded traffic ran episodes on a road whose cars had vanished,
    # with shield masks and rewards for that empty road, and said nothing (W0728 speaks of the file's horizon)
    from engine_files import write_short_traffic

    path = write_short_traffic(tmp_path, horizon="4")  # 2 s of traffic
    with pytest.warns(UserWarning, match=r"run past its recorded traffic: its moving obstacles are gone after "
                                         r"scenario time t = 2 s, an episode ends at t = 3 s"):
        env = ScenarioEnv(path, horizon=3)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        env.reset(seed=0)  # said once
        ScenarioEnv(path, horizon=2)  # the episodes end with the traffic: nothing to say


def test_a_scene_of_a_set_that_rac_check_would_warn_of_is_warned_of(tmp_path: Path) -> None:
    """A scene of a set is checked with the template's model block, never by `rac check`: a scene whose ego starts
    off the road (W0716: every episode unsafe from its first sample) or whose goal window opens after the episodes
    end (W0722: no episode can reach the goal) trained without a word. Each is warned of, naming the scene, on its
    first draw, and so is a goal window after an episode `horizon=` of its own; a scene fit for the model is not,
    and neither is the template's own scene with its own horizon."""
    template = write_engine_file(tmp_path, "goal_ahead", {})
    narrow = TINY_SCENARIOS["narrow_road"]()
    narrow.write(tmp_path / "narrow_road.xml")
    late = StraightRoad(100.0, EgoStart(10.0, 1.75, 0.0, 8.0), GoalBox(44.0, 54.0, 5.0, 6.0))  # the episodes: 4 s
    (tmp_path / "late.xml").write_bytes(late.xml("late"))
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        ScenarioEnv(template)
        env = ScenarioEnv(template, scenarios=[tmp_path / "goal_ahead.xml", tmp_path / "narrow_road.xml",
                                               tmp_path / "late.xml"], lookahead=None)
    with pytest.warns(UserWarning, match=r"the scene .*narrow_road.xml: the ego starts off the road: .* \(W0716 in rac "
                                         r"check\)"):
        env.reset(options={"scenario": 1})
    with pytest.warns(UserWarning, match=r"the scene .*late.xml: the goal's time window \[5, 6\] s opens after the "
                                         r"horizon ends \(scenario time t = 4 s\): `goal\(\)` never holds \(W0722"):
        env.reset(options={"scenario": 2})
    # a scene with a traffic light the model does not read (W0730): the shield's masks let a run pass it at red
    (tmp_path / "lights.xml").write_bytes(traffic_rules())
    env = ScenarioEnv(template, scenarios=[tmp_path / "goal_ahead.xml", tmp_path / "lights.xml"], lookahead=None)
    with pytest.warns(UserWarning, match=r"the scene .*lights.xml: `.*lights.xml` has 1 traffic light, 1 traffic sign "
                                         r"and 1 stop line, which the model does not read: .* \(W0730 in rac check\)"):
        env.reset(options={"scenario": 1})
    soon = StraightRoad(100.0, EgoStart(10.0, 1.75, 0.0, 8.0), GoalBox(44.0, 54.0, 3.0, 6.0))  # fine for 4 s
    (tmp_path / "soon.xml").write_bytes(soon.xml("soon"))
    env = ScenarioEnv(template, scenarios=[tmp_path / "goal_ahead.xml", tmp_path / "soon.xml"], lookahead=None)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        env.reset(options={"scenario": 1})
    env = ScenarioEnv(template, scenarios=[tmp_path / "goal_ahead.xml", tmp_path / "soon.xml"], lookahead=None,
                      horizon=2)
    with pytest.warns(UserWarning, match=r"the scene .*soon.xml: the goal's time window \[3, 6\] s opens after "
                                         r"horizon=2 ends \(scenario time t = 2 s\)"):
        env.reset(options={"scenario": 1})


def test_a_scene_set_chooses_each_files_planning_problem(tmp_path: Path) -> None:
    # a scene set could not choose a planning problem per file: the template's `planning_problem` applied to every
    # scene, so a file with several (real datasets number them per file) was a CheckError with no way out
    from engine_files import TEMPLATE
    from tiny_scenarios import SECOND_PROBLEM_ID, junction_with_two_problems

    (tmp_path / "junction.xml").write_bytes(junction_with_two_problems())
    block = ('    model {\n        scenario "junction.xml"\n'
             '        bind near = mindist() < 3 * collision_distance\n    }')
    model = tmp_path / "drive.ra"
    model.write_text(TEMPLATE.format(period="0.5", horizon="2", model=block, queries=""), encoding="utf-8")
    scene = tmp_path / "junction.xml"
    with pytest.raises(CheckError, match=r"E0715(.|\n)*a scene of a set chooses its planning problem as a pair"):
        ScenarioEnv(model, scenarios=[scene])
    env = ScenarioEnv(model, scenarios=[(scene, 100), (str(scene), np.int64(SECOND_PROBLEM_ID))])
    assert env.scenarios == (scene, scene) and env.planning_problems == (100, SECOND_PROBLEM_ID)
    first = env.reset(options={"scenario": 0})
    second = env.reset(options={"scenario": (str(scene), SECOND_PROBLEM_ID)})
    assert first[1]["planning_problem"] == 100 and second[1]["planning_problem"] == SECOND_PROBLEM_ID
    assert first[1]["scenario"] == second[1]["scenario"] == str(scene)
    assert first[0].tolist() != second[0].tolist()  # two egos: the second drives south from the north arm
    assert env.reset(options={"scenario": scene})[1]["planning_problem"] == 100  # a path alone: its first scene
    assert {env.reset(seed=s)[1]["planning_problem"] for s in range(12)} == {100, SECOND_PROBLEM_ID}
    with pytest.raises(ValueError, match=r"not one of the scenes: .*junction.xml \(planning problem 100\)"):
        env.reset(options={"scenario": (scene, 5)})
    with pytest.raises(CheckError, match=r"the scene .*junction.xml \(planning problem 7\) does not check(.|\n)*E0715"):
        ScenarioEnv(model, scenarios=[(scene, 7)])
    for wrong in ([(scene, True)], [(scene, -1)], [(scene, 1.5)], [(scene, 100, 1)], [3]):
        with pytest.raises(TypeError, match="planning problem|CommonRoad file's path"):
            ScenarioEnv(model, scenarios=wrong)
    with pytest.raises(TypeError, match="is one scene: write"):
        ScenarioEnv(model, scenarios=(scene, 100))


def test_the_files_warnings_are_said_as_rac_load_says_them(tmp_path: Path) -> None:
    # rac.load and the wrappers given a path warn of the file's W codes (RacCheckWarning); ScenarioEnv, the way the
    # docs train, said nothing, so a reward loophole (here W1004: delaying the goal pays) went unseen
    import shutil

    from rac.core.diagnostics import RacCheckWarning
    from rac.learning.vector import make_vector_env

    shutil.copy(REPO / "examples" / "deep_rl" / "highway.xml", tmp_path / "highway.xml")
    text = (REPO / "examples" / "deep_rl" / "driving.ra").read_text(encoding="utf-8")
    model = tmp_path / "ends.ra"
    model.write_text(text.replace("    model {", "    episode ends when collide || atGoal\n    goal when atGoal\n\n"
                                  "    model {", 1), encoding="utf-8")
    makers = {"path": lambda: ScenarioEnv(model, lookahead=1),
              "set": lambda: ScenarioEnv(model, lookahead=1, scenarios=[tmp_path / "highway.xml"]),
              "make": lambda: gymnasium.make("rac.gym:rac/Scenario-v0", model=model, lookahead=1),
              "make_vec": lambda: make_vector_env(num_envs=2, model=model, lookahead=1, render_mode="rgb_array")}
    for name, make in makers.items():
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            make()
        said = [w for w in caught if issubclass(w.category, RacCheckWarning)]
        assert len(said) == 1, (name, [str(w.message) for w in caught])  # make_vec: once, not per environment
        assert "W1004 delaying the goal pays" in str(said[0].message) and said[0].filename == __file__, name
    with warnings.catch_warnings():
        warnings.simplefilter("error", RacCheckWarning)
        ScenarioEnv(compile_file(model), lookahead=1)  # a CompileResult: its maker has the diagnostics


def test_a_warning_names_the_line_of_the_users_code(tiny: CompileResult) -> None:
    # gymnasium.make's wrappers stand between the user's reset() and ScenarioEnv's: a fixed stacklevel named a
    # line of gymnasium's (OrderEnforcing, PassiveEnvChecker), which nobody can act on
    env = gymnasium.make("rac.gym:rac/Scenario-v0", model=tiny)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        env.reset(seed=0, options={"scene": 1})
    (said,) = [w for w in caught if "ignores 'scene'" in str(w.message)]
    assert said.filename == __file__, said.filename


def test_user_stacklevel_counts_the_frames_inside_the_libraries() -> None:
    from rac.core.caller import user_stacklevel

    code = "def warn_site():\n    return user_stacklevel()\n"
    here: dict[str, object] = {"__name__": "test_module", "user_stacklevel": user_stacklevel}
    library: dict[str, object] = {"__name__": "gymnasium.core", "user_stacklevel": user_stacklevel}
    exec(code, here)
    exec(code, library)
    assert here["warn_site"]() == 1  # type: ignore[operator]  # a user's module: its own frame
    assert library["warn_site"]() == 2  # type: ignore[operator]  # gymnasium's: the frame above it (this test)


def test_user_stacklevel_passes_a_worker_process_launcher() -> None:
    # in a SubprocVecEnv or AsyncVectorEnv worker the first frame outside the libraries was multiprocessing's
    # (process.py: self._target(*self._args, **self._kwargs)), which every worker's warning named
    from rac.core.caller import user_stacklevel

    def chain(outer_name: str, outer_file: str, launcher: bool) -> int:
        """warn_site in rac, called by stable-baselines3's worker, [by multiprocessing,] by an outer frame."""
        modules = [("rac.learning.wrappers", "def call():\n    return user_stacklevel()\n", "<rac>"),
                   ("stable_baselines3.common.vec_env.subproc_vec_env", "def call():\n    return inner()\n", "<sb3>")]
        if launcher:
            modules.append(("multiprocessing.process", "def call():\n    return inner()\n", "<mp>"))
        modules.append((outer_name, "def call():\n    return inner()\n", outer_file))
        inner: Any = None
        for name, code, filename in modules:  # each calls the one before it, in a module of that name and file
            namespace: dict[str, Any] = {"__name__": name, "user_stacklevel": user_stacklevel, "inner": inner}
            exec(compile(code, filename, "exec"), namespace)
            inner = namespace["call"]
        return int(inner())

    assert chain("train", __file__, launcher=True) == 4  # forked: the parent's line that made the workers
    assert chain("__main__", "<string>", launcher=True) == 1  # spawned: its bootstrap, no user's line: rac's
    assert chain("__main__", "<string>", launcher=False) == 3  # `python -c` code of the user's own is the user's
