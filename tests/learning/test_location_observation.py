"""LocationObservation / LocationVectorObservation: the automaton's location in the observation.

The first test is the reason they exist: an automaton whose reward depends on its location cannot be
learned from an observation without it (the reward is not Markov in what the policy sees)."""

from __future__ import annotations

import types
from pathlib import Path
from typing import Any

import gymnasium
import numpy as np
import pytest
from engine_files import write_engine_file
from gymnasium.utils.env_checker import check_env
from gymnasium.vector import SyncVectorEnv
from highway_like import HighwayLike, follow, inputs, vector_inputs

import rac.gym
from rac import ir
from rac.compiler import compile_file, compile_text
from rac.engine import shield as shield_file
from rac.engine.explore import explore
from rac.engine.storm import safety_shield
from rac.learning.counterfactual import counterfactual_transitions
from rac.learning.episodes import EpisodeBatch
from rac.learning.location_observation import (
    LOCATION_KEY,
    LocationObservation,
    LocationVectorObservation,
    location_names,
)
from rac.learning.vector import action_masks
from rac.learning.wrappers import RewardAutomatonVectorWrapper, RewardAutomatonWrapper
from rac.targets.python import generate_python

# Pays 1 for each switch of the action: a then !a then a ... The environment shows nothing.
ALTERNATE = """automaton Alternate {
    input a : bool
    reward r
    objective r
    sample every 1
    horizon 10
    initial location Want { r' == 0 }
    location Wait         { r' == 0 }
    edge Want -> Wait when a  do r = r + 1
    edge Wait -> Want when !a do r = r + 1
}
"""


def alternate() -> ir.Automaton:
    return compile_text(ALTERNATE, "alternate.ra").raise_for_errors()


class Blank(gymnasium.Env[np.ndarray, int]):
    """A constant observation, two actions, episodes of 10 steps; ``info["a"]`` is the action taken."""

    observation_space = gymnasium.spaces.Box(0.0, 1.0, shape=(1,), dtype=np.float32)
    action_space = gymnasium.spaces.Discrete(2)

    def reset(self, *, seed: int | None = None,
              options: dict[str, Any] | None = None) -> tuple[np.ndarray, dict[str, Any]]:
        super().reset(seed=seed)
        self.t = 0
        return np.zeros(1, dtype=np.float32), {}

    def step(self, action: int) -> tuple[np.ndarray, float, bool, bool, dict[str, Any]]:
        self.t += 1
        return np.zeros(1, dtype=np.float32), 0.0, False, self.t >= 10, {"a": bool(action)}


def took(obs: Any, info: dict[str, Any]) -> dict[str, object]:
    return {"a": info["a"]}


def q_learning(env: gymnasium.Env[Any, Any], episodes: int = 300) -> float:
    """Tabular Q-learning on the observation's bytes (discount 0.9: the horizon is not observed); the
    greedy run's return at the end."""
    rng = np.random.default_rng(0)
    q: dict[tuple[bytes, int], float] = {}

    def greedy(key: bytes) -> int:
        return int(np.argmax([q.get((key, a), 0.0) for a in (0, 1)]))

    for episode in range(episodes + 1):
        explore = episode < episodes
        obs, _ = env.reset(seed=episode)
        total, done = 0.0, False
        while not done:
            key = np.asarray(obs).tobytes()
            action = int(rng.integers(2)) if explore and rng.random() < 0.3 else greedy(key)
            obs, reward, terminated, truncated, _ = env.step(action)
            total += float(reward)
            done = terminated or truncated
            if explore:
                # a truncation is no end of the task: bootstrap from the next observation
                after = 0.0 if terminated else max(q.get((np.asarray(obs).tobytes(), a), 0.0) for a in (0, 1))
                old = q.get((key, action), 0.0)
                q[(key, action)] = old + 0.5 * (float(reward) + 0.9 * after - old)
    return total


def test_the_location_makes_a_location_dependent_reward_learnable() -> None:
    blind = RewardAutomatonWrapper(Blank(), alternate(), took)
    seeing = LocationObservation(RewardAutomatonWrapper(Blank(), alternate(), took))
    # without the location, every greedy policy repeats one action: one switch at most
    assert q_learning(blind) <= 1.0
    # with it, the learner alternates: a switch every step
    assert q_learning(seeing) == 10.0


def test_concat_layout_one_hot_matches_the_info() -> None:
    env = LocationObservation(RewardAutomatonWrapper(HighwayLike(), follow(), inputs, clip=True))
    assert env.layout == "concat" and env.locations == ("Safe", "Unsafe")
    assert env.observation_space.shape == (4,) and env.observation_space.dtype == np.float32
    assert env.observation_space.low[2:].tolist() == [0, 0] and env.observation_space.high[2:].tolist() == [1, 1]
    check_env(env, skip_render_check=True)
    obs, info = env.reset(seed=3)
    seen = {info["rac"]["location"]}
    assert obs[2:].tolist() == [1.0, 0.0] and obs.dtype == np.float32
    for action in [2] * 30:  # speeding up closes the gap: Unsafe at some step
        obs, _, terminated, truncated, info = env.step(action)
        assert env.observation_space.contains(obs)
        assert obs[2:].tolist() == [float(name == info["rac"]["location"]) for name in env.locations]
        seen.add(info["rac"]["location"])
        if terminated or truncated:
            break
    assert seen == {"Safe", "Unsafe"}


def test_a_chain_made_by_gymnasium_make_passes_check_env_and_is_remade_from_its_spec() -> None:
    """gymnasium's check_env remakes an environment made by ``gymnasium.make`` from its spec, wrappers
    included: a wrapper that does not record its arguments ended it in "cannot be recreated"."""
    env_id = "rac-test/LocationHighwayLike-v0"
    if env_id not in gymnasium.registry:
        gymnasium.register(env_id, entry_point=HighwayLike, max_episode_steps=30)
    env = LocationObservation(RewardAutomatonWrapper(gymnasium.make(env_id), follow(), inputs, clip=True),
                              layout="dict", locations=["Safe", "Unsafe"])
    check_env(env, skip_render_check=True)
    remade = gymnasium.make(env.spec)
    assert isinstance(remade, LocationObservation) and remade.layout == "dict"
    assert remade.locations == ("Safe", "Unsafe")
    a, b = env.reset(seed=4)[0], remade.reset(seed=4)[0]
    assert a[LOCATION_KEY] == b[LOCATION_KEY] and a["observation"].tolist() == b["observation"].tolist()


def test_dict_layout_for_other_spaces_and_on_request() -> None:
    env = LocationObservation(RewardAutomatonWrapper(HighwayLike(), follow(), inputs, clip=True), layout="dict")
    assert isinstance(env.observation_space, gymnasium.spaces.Dict)
    assert env.observation_space[LOCATION_KEY] == gymnasium.spaces.Discrete(2)
    obs, _ = env.reset(seed=0)
    assert obs[LOCATION_KEY] == 0 and obs["observation"].shape == (2,) and env.observation_space.contains(obs)
    check_env(env, skip_render_check=True)

    class Image(Blank):
        observation_space = gymnasium.spaces.Box(0, 255, shape=(2, 2), dtype=np.uint8)  # type: ignore[assignment]

        def reset(self, **kwargs: Any) -> tuple[Any, dict[str, Any]]:
            super().reset(**kwargs)
            return np.zeros((2, 2), dtype=np.uint8), {}

        def step(self, action: int) -> tuple[Any, float, bool, bool, dict[str, Any]]:
            _, *rest = super().step(action)
            return (np.zeros((2, 2), dtype=np.uint8), *rest)  # type: ignore[return-value]

    image = LocationObservation(RewardAutomatonWrapper(Image(), alternate(), took))
    assert image.layout == "dict"
    obs, _ = image.reset()
    assert obs[LOCATION_KEY] == 0
    obs, *_ = image.step(1)
    assert obs[LOCATION_KEY] == 1 and image.observation_space.contains(obs)
    with pytest.raises(ValueError, match="layout='dict'"):
        LocationObservation(RewardAutomatonWrapper(Image(), alternate(), took), layout="concat")


def test_a_dict_observation_gets_a_key_and_a_clash_is_refused() -> None:
    class Keys(Blank):
        observation_space = gymnasium.spaces.Dict({"x": Blank.observation_space})  # type: ignore[assignment]

        def reset(self, **kwargs: Any) -> tuple[Any, dict[str, Any]]:
            obs, info = super().reset(**kwargs)
            return {"x": obs}, info

        def step(self, action: int) -> tuple[Any, float, bool, bool, dict[str, Any]]:
            obs, *rest = super().step(action)
            return ({"x": obs}, *rest)  # type: ignore[return-value]

    env = LocationObservation(RewardAutomatonWrapper(Keys(), alternate(), took))
    obs, _ = env.reset()
    assert set(obs) == {"x", LOCATION_KEY} and env.observation_space.contains(obs)

    class Clash(Keys):
        observation_space = gymnasium.spaces.Dict({LOCATION_KEY: Blank.observation_space})  # type: ignore[assignment]

    with pytest.raises(ValueError, match="key 'location' already"):
        LocationObservation(RewardAutomatonWrapper(Clash(), alternate(), took))


def test_errors_say_what_is_missing() -> None:
    with pytest.raises(TypeError, match="found no reward automaton"):
        LocationObservation(Blank())
    with pytest.raises(ValueError, match="distinct location names"):
        LocationObservation(Blank(), locations=["A", "A"])
    env = LocationObservation(Blank(), locations=["Want", "Wait"])  # the names given, but nothing reports one
    with pytest.raises(RuntimeError, match="reported no automaton location"):
        env.reset()
    wrong = LocationObservation(RewardAutomatonWrapper(Blank(), alternate(), took), locations=["A", "B"])
    with pytest.raises(RuntimeError, match="location 'Want', which the automaton does not have"):
        wrong.reset()


def test_the_names_are_found_through_other_wrappers() -> None:
    inner = RewardAutomatonWrapper(Blank(), alternate(), took)
    assert location_names(gymnasium.wrappers.TimeLimit(inner, 5)) == ("Want", "Wait")
    env = LocationObservation(gymnasium.wrappers.TimeLimit(inner, 5))
    obs, _ = env.reset()
    assert obs.tolist() == [0.0, 1.0, 0.0]


def test_vector_wrapper_follows_each_automaton_through_autoreset() -> None:
    envs = SyncVectorEnv([lambda i=i: gymnasium.wrappers.TimeLimit(HighwayLike(), 12 + i) for i in range(3)])
    wrapped = LocationVectorObservation(RewardAutomatonVectorWrapper(envs, follow(), vector_inputs, clip=True))
    assert wrapped.single_observation_space.shape == (4,) and wrapped.observation_space.shape == (3, 4)
    obs, infos = wrapped.reset(seed=1)
    assert obs[:, 2:].tolist() == [[1.0, 0.0]] * 3
    ended = np.zeros(3, dtype=bool)
    restarted, seen = [], set()  # the locations of sub-environments in their reset step; every location
    for _ in range(30):
        obs, _, terminated, truncated, infos = wrapped.step(np.full(3, 2))  # speeding up: Unsafe, crashes
        assert wrapped.observation_space.contains(obs)
        names = infos["rac"]["location"]
        assert obs[:, 2:].tolist() == [[float(name == n) for n in wrapped.locations] for name in names]
        restarted += [obs[i, 2:].tolist() for i in np.flatnonzero(ended)]
        seen.update(names.tolist())
        ended = terminated | truncated
    assert seen == {"Safe", "Unsafe"}
    assert restarted and all(row == [1.0, 0.0] for row in restarted)  # a new episode starts in Safe


def test_the_vector_observation_reads_infos_made_a_list() -> None:
    # gymnasium's DictInfoToList turns the vector info into one dict per sub-environment (SB3's layout): the location
    # observation around it ended at the first reset in "AttributeError: 'list' object has no attribute 'get'"
    from gymnasium.wrappers.vector import DictInfoToList

    def wrapped() -> RewardAutomatonVectorWrapper:
        envs = SyncVectorEnv([lambda i=i: gymnasium.wrappers.TimeLimit(HighwayLike(), 5 + i) for i in range(3)])
        return RewardAutomatonVectorWrapper(envs, follow(), vector_inputs, clip=True)

    outside, inside = LocationVectorObservation(DictInfoToList(wrapped())), LocationVectorObservation(wrapped())
    (got, listed), (want, _) = outside.reset(seed=1), inside.reset(seed=1)
    assert isinstance(listed, list) and np.array_equal(got, want)
    for _ in range(12):  # through the restarts of the NEXT_STEP autoreset, whose infos are reset infos
        got, want = outside.step(np.full(3, 2))[0], inside.step(np.full(3, 2))[0]
        assert np.array_equal(got, want)


def blank_with_alternate() -> RewardAutomatonWrapper:
    """A sub-environment for a vector environment: Blank under the wrapper (a module function: picklable)."""
    return RewardAutomatonWrapper(Blank(), alternate(), took)


@pytest.mark.parametrize("vector", [gymnasium.vector.SyncVectorEnv, gymnasium.vector.AsyncVectorEnv])
def test_a_vector_env_of_wrapped_sub_environments_names_their_locations(vector: Any) -> None:
    """gymnasium's own vector environments of rac's wrappers (a SyncVectorEnv; an AsyncVectorEnv, its
    sub-environments in workers) report the locations per sub-environment: the names were not found, a
    TypeError at construction (the wrapper around each sub-environment, not around the vector env)."""
    # through a vector wrapper of gymnasium's (it forwards `envs` to the base)
    envs = LocationVectorObservation(gymnasium.wrappers.vector.RecordEpisodeStatistics(
        vector([blank_with_alternate] * 2)))
    try:
        assert envs.locations == ("Want", "Wait")
        obs, _ = envs.reset(seed=0)
        assert obs.tolist() == [[0.0, 1.0, 0.0]] * 2
        obs, *_, infos = envs.step(np.array([1, 0]))
        assert infos["rac"]["location"].tolist() == ["Wait", "Want"]
        assert obs.tolist() == [[0.0, 0.0, 1.0], [0.0, 1.0, 0.0]]
    finally:
        envs.close()


def test_sub_environments_of_other_automata_are_refused() -> None:
    switch = compile_text(ALTERNATE.replace("Wait", "Hold"), "hold.ra").raise_for_errors()
    envs = SyncVectorEnv([blank_with_alternate, lambda: RewardAutomatonWrapper(Blank(), switch, took)])
    with pytest.raises(ValueError, match="different locations"):
        LocationVectorObservation(envs)
    with pytest.raises(TypeError, match="found no reward automaton"):
        LocationVectorObservation(SyncVectorEnv([Blank, Blank]))


def test_with_locations_builds_counterfactual_observations() -> None:
    env = LocationObservation(RewardAutomatonWrapper(Blank(), alternate(), took))
    obs, _ = env.reset()
    batch = np.stack([obs, obs])
    cf = counterfactual_transitions(alternate(), {"a": np.array([True, False])})
    # every transition from every location: the observation's location part is the counterfactual one
    replaced = env.with_locations(batch[cf.source], cf.location)
    assert replaced.tolist() == [[0, 1, 0], [0, 0, 1], [0, 1, 0], [0, 0, 1]]
    assert cf.reward.tolist() == [1.0, 0.0, 0.0, 1.0]  # Want on a, Wait on !a: the switches pay
    with pytest.raises(ValueError, match="location indices"):
        env.with_locations(batch, np.array([0, 2]))
    with pytest.raises(ValueError, match="location indices"):
        env.with_locations(batch, np.array([0.0, 1.0]))


@pytest.fixture(scope="module")
def scene_file(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The engine test file on avoidable_obstacle (a van ahead), with its shield's table."""
    return write_engine_file(tmp_path_factory.mktemp("located"), "avoidable_obstacle", queries={})


def test_scenario_envs_and_their_masks(scene_file: Path) -> None:
    result = compile_file(scene_file)
    assert result.ok and result.model_data is not None, result.diagnostics
    shield = safety_shield(explore(result.model_data, horizon_samples=8, prune_unsafe=True), "safe")
    table = shield_file.table(shield, n_actions=EpisodeBatch(result).n_actions, unseen="none")
    env = LocationObservation(gymnasium.make(rac.gym.SCENARIO, model=scene_file, shield=table))
    names = result.automaton.location_names  # type: ignore[union-attr]
    assert env.locations == names and env.observation_space.shape == (29 + len(names),)
    obs, info = env.reset(seed=0)
    assert obs[29:].tolist() == [float(name == info["location"]) for name in names]
    masks = env.get_wrapper_attr("action_masks")()  # MaskablePPO's way to the masks, through this wrapper
    assert masks.any() and not masks.all()
    obs, *_, info = env.step(int(np.flatnonzero(masks)[0]))
    assert obs[29:].tolist() == [float(name == info["location"]) for name in names]
    assert env.observation_space.contains(obs)
    check_env(env, skip_render_check=True)  # made by gymnasium.make: remade from its spec, this wrapper too

    envs = LocationVectorObservation(gymnasium.make_vec(rac.gym.SCENARIO, num_envs=2, model=scene_file,
                                                        shield=table))
    obs, infos = envs.reset(seed=0)
    assert obs.shape == (2, 29 + len(names)) and envs.observation_space.contains(obs)
    masks = action_masks(envs)
    obs, *_, infos = envs.step(np.array([int(np.flatnonzero(row)[0]) for row in masks]))
    assert obs[:, 29:].tolist() == [[float(name == n) for n in names] for name in infos["location"]]

    # a SyncVectorEnv of ScenarioEnvs (what make_vec gives for a set of scenes, or asked for): its names were
    # not found (TypeError), so a set of scenes could not be trained on with the location observed
    synced = LocationVectorObservation(gymnasium.make_vec(rac.gym.SCENARIO, num_envs=2, model=scene_file,
                                                          shield=table, vectorization_mode="sync"))
    assert synced.locations == names
    obs, infos = synced.reset(seed=0)
    assert obs[:, 29:].tolist() == [[float(name == n) for n in names] for name in infos["location"]]


def test_a_generated_class_names_its_locations() -> None:
    module = types.ModuleType("alternate_generated")
    exec(compile(generate_python(alternate()), "<generated>", "exec"), module.__dict__)  # noqa: S102
    ra = getattr(module, module.__all__[0])()
    env = LocationObservation(RewardAutomatonWrapper(Blank(), ra, took))
    assert env.locations == ("Want", "Wait")
    env.reset()
    assert env.step(1)[0].tolist() == [0.0, 0.0, 1.0]


def test_the_infos_inputs_replay_to_the_real_transition() -> None:
    """What a counterfactual replay buffer does with the wrapper's info: the row of the real location
    is the real transition (reward and next location); the others are the automaton's from there."""
    env = LocationObservation(RewardAutomatonWrapper(HighwayLike(), follow(), inputs, clip=True))
    env.reset(seed=3)
    names, visited = env.locations, set()
    for _ in range(30):
        before = env.get_wrapper_attr("automaton").location
        visited.add(before)
        obs, reward, terminated, truncated, info = env.step(2)
        rac = info["rac"]
        visited.add(rac["location"])
        prior = {name: np.array([value - rac["reward_steps"][name]]) for name, value in rac["rewards"].items()}
        cf = counterfactual_transitions(follow(), {k: np.array([v]) for k, v in rac["inputs"].items()},
                                        rewards=prior, ended=np.array([terminated or truncated]))
        real = names.index(before)
        assert cf.reward[real] == pytest.approx(float(reward) * rac["scale"], abs=1e-9)
        assert names[cf.next_location[real]] == rac["location"]
        assert env.with_locations(obs[None, :], cf.next_location[real:real + 1]).tolist() == [obs.tolist()]
        if terminated or truncated:
            break
    assert visited == {"Safe", "Unsafe"}
