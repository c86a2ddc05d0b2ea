"""The gymnasium wrapper on a scripted environment."""

from __future__ import annotations

import types
from pathlib import Path
from typing import Any

import gymnasium
import pytest
from driving_ir import driving_automaton, inputs

from rac.learning.gym import RewardAutomatonWrapper
from rac.runtime.interpreter import RewardAutomaton
from rac.targets.python import generate_python

TRACE = [inputs(dgoal=50.0), inputs(comf=False, dgoal=40.0), inputs(is_close=True, dgoal=30.0),
         inputs(is_close=True, collide=True, dgoal=20.0), inputs(prog=False, dgoal=10.0), inputs(dgoal=1.0)]
INITIAL = {"location": "Normal", "rewards": {"sa": 0.0, "pr": 0.0, "co": 0.0}, "objective": 0.0, "scale": 1.0,
           "proven": False}


class Scripted(gymnasium.Env):
    """Observation k at step k; the automaton's inputs come from ``info``; the env pays 7.0 per step."""

    def __init__(self, trace: list[dict[str, object]], *, terminate_at: int | None = None,
                 truncate_at: int | None = None) -> None:
        self.trace = trace
        self.terminate_at, self.truncate_at = terminate_at, truncate_at
        self.observation_space = gymnasium.spaces.Discrete(len(trace) + 1)
        self.action_space = gymnasium.spaces.Discrete(2)
        self.k = 0
        self.resets = 0

    def reset(self, *, seed: int | None = None,
              options: dict[str, Any] | None = None) -> tuple[int, dict[str, Any]]:
        super().reset(seed=seed)
        self.k = 0
        self.resets += 1
        return 0, {"start": True}

    def step(self, action: int) -> tuple[int, float, bool, bool, dict[str, Any]]:
        values = self.trace[self.k]
        self.k += 1
        terminated = self.k == self.terminate_at
        truncated = self.k == self.truncate_at
        return self.k, 7.0, terminated, truncated, {"values": values, "k": self.k}


def from_info(obs: int, info: dict[str, Any]) -> dict[str, object]:
    assert info["k"] == obs
    return info["values"]


def expected_rewards(steps: int, *, end: bool) -> list[float]:
    ra = RewardAutomaton(driving_automaton())
    out = [ra.step(x) for x in TRACE[:steps]]
    if end:
        out[-1] += ra.end(TRACE[steps - 1])
    return out


def episode(env: RewardAutomatonWrapper) -> list[tuple[Any, ...]]:
    out = []
    done = False
    while not done:
        obs, reward, terminated, truncated, info = env.step(0)
        out.append((obs, reward, terminated, truncated, info))
        done = terminated or truncated
    return out


@pytest.mark.parametrize("mode", ["terminate", "truncate"])
def test_rewards_are_the_automatons_and_end_is_applied(mode: str) -> None:
    steps = len(TRACE)
    env = RewardAutomatonWrapper(Scripted(TRACE, **{f"{mode}_at": steps}), driving_automaton(), from_info)
    obs, info = env.reset(seed=3)
    assert (obs, info["start"]) == (0, True)
    assert info["rac"] == INITIAL
    run = episode(env)
    assert [r[1] for r in run] == expected_rewards(steps, end=True)
    reference = RewardAutomaton(driving_automaton())
    held = TRACE[0]  # the first step's rates read its own inputs, each later one the step before's
    for (obs, _, terminated, truncated, info), values in zip(run, TRACE):
        before = reference.rewards
        reference.step(values)
        if terminated or truncated:
            reference.end(values)
        assert info["k"] == obs
        assert info["rac"] == {"location": reference.location, "rewards": reference.rewards,
                               "objective": reference.objective, "env_reward": 7.0, "scale": 1.0, "proven": False,
                               "clipped": {}, "inputs": values, "held": held,
                               "reward_steps": {k: v - before[k] for k, v in reference.rewards.items()}}
        held = values
    assert run[-1][1] == pytest.approx(run[-1][4]["rac"]["objective"] - run[-2][4]["rac"]["objective"])
    assert run[-1][4]["rac"]["rewards"]["pr"] > 100  # the end bonus (dgoal < 2)
    assert sum(r[1] for r in run) == pytest.approx(run[-1][4]["rac"]["objective"])
    assert env.automaton.ended


def test_no_end_before_the_episode_stops() -> None:
    env = RewardAutomatonWrapper(Scripted(TRACE, truncate_at=3), driving_automaton(), from_info)
    env.reset()
    rewards = [env.step(1)[1] for _ in range(2)]
    assert rewards == expected_rewards(2, end=False)
    assert not env.automaton.ended
    _, last, _, truncated, _ = env.step(1)
    assert truncated and env.automaton.ended
    assert [*rewards, last] == expected_rewards(3, end=True)


def test_reset_resets_the_automaton() -> None:
    scripted = Scripted(TRACE, terminate_at=4)
    env = RewardAutomatonWrapper(scripted, driving_automaton(), from_info)
    env.reset()
    first = [r[1] for r in episode(env)]
    _, info = env.reset()
    assert scripted.resets == 2
    assert info["rac"] == INITIAL
    assert [r[1] for r in episode(env)] == first == expected_rewards(4, end=True)
    env.reset()
    env.step(0)  # the automaton's step after a finished episode would raise without the reset
    assert env.automaton.samples == 1


def generated_instance() -> Any:
    module = types.ModuleType("driving_generated")
    exec(compile(generate_python(driving_automaton()), "<generated>", "exec"), module.__dict__)  # noqa: S102
    return module.Driving()


@pytest.mark.parametrize("kind", ["ir", "interpreter", "generated", "path"])
def test_automaton_forms(kind: str) -> None:
    automaton: Any = {
        "ir": driving_automaton,
        "interpreter": lambda: RewardAutomaton(driving_automaton()),
        "generated": generated_instance,
        "path": lambda: Path(__file__).parents[2] / "stdlib" / "driving.ra",
    }[kind]()
    env = RewardAutomatonWrapper(Scripted(TRACE, truncate_at=len(TRACE)), automaton, from_info)
    env.reset()
    assert [r[1] for r in episode(env)] == expected_rewards(len(TRACE), end=True)
    if kind in ("interpreter", "generated"):  # the wrapper's own copy; the object passed in untouched
        assert type(env.automaton) is type(automaton) and env.automaton is not automaton
        assert automaton.objective == 0.0 and env.automaton.objective != 0.0


def test_one_automaton_handed_to_several_environments_is_not_shared() -> None:
    # one rac.load() object handed to every env: they shared one run state, each step of one env
    # advancing the other's automaton too
    ra = RewardAutomaton(driving_automaton())
    one, two = (RewardAutomatonWrapper(Scripted(TRACE, truncate_at=len(TRACE)), ra, from_info) for _ in range(2))
    alone = RewardAutomatonWrapper(Scripted(TRACE, truncate_at=len(TRACE)), driving_automaton(), from_info)
    for env in (one, two, alone):
        env.reset()
    rewards = [(one.step(0)[1], two.step(0)[1], alone.step(0)[1]) for _ in range(3)]
    assert all(a == b == c for a, b, c in rewards)
    assert one.automaton.objective == two.automaton.objective == alone.automaton.objective
    assert one.automaton is not two.automaton and ra.objective == 0.0


def test_bad_automata_are_refused(tmp_path: Path) -> None:
    with pytest.raises(TypeError, match="automaton"):
        RewardAutomatonWrapper(Scripted(TRACE), 42, from_info)  # type: ignore[arg-type]
    with pytest.raises(TypeError, match="inputs"):
        RewardAutomatonWrapper(Scripted(TRACE), driving_automaton(), None)  # type: ignore[arg-type]
    from rac.core.diagnostics import CheckError

    bad = tmp_path / "bad.ra"
    bad.write_text("automaton Bad {\n    reward r\n    objective r + nope\n}\n", encoding="utf-8")
    with pytest.raises(CheckError) as caught:
        RewardAutomatonWrapper(Scripted(TRACE), str(bad), from_info)
    assert caught.value.diagnostics and any(d.is_error for d in caught.value.diagnostics)


def test_invalid_inputs_propagate() -> None:
    env = RewardAutomatonWrapper(Scripted([inputs(collide=True)]), driving_automaton(), from_info)
    env.reset()
    with pytest.raises(ValueError, match="assume"):
        env.step(0)


def test_an_inputs_callable_that_fails_says_where_things_stand() -> None:
    """A KeyError from the user's inputs(obs, info) escaped after the environment had stepped and
    before the automaton had (issue 12): now a ValueError that says so."""
    env = RewardAutomatonWrapper(Scripted(TRACE, truncate_at=3), driving_automaton(),
                                 lambda obs, info: info["no such key"])
    env.reset(seed=0)
    with pytest.raises(ValueError, match=r"inputs\(obs, info\) raised KeyError: 'no such key'; the environment has "
                                         "taken this step and the automaton has not"):
        env.step(0)
    assert env.automaton.samples == 0


def test_the_vector_wrapper_is_one_import_away_too() -> None:
    # docs/python.md shows both signatures under `rac.learning.gym`; only the single wrapper was there
    import rac.learning.gym as gym
    from rac.learning.wrappers import RewardAutomatonVectorWrapper

    assert gym.RewardAutomatonVectorWrapper is RewardAutomatonVectorWrapper
    assert "RewardAutomatonVectorWrapper" in gym.__all__


def test_the_declared_gymnasium_has_what_rac_learning_imports() -> None:
    """rac.learning imports gymnasium.vector.AutoresetMode and resets sub-environments with
    ``options={"reset_mask": ...}``, both new in gymnasium 1.1: the extras allowed gymnasium 1.0, with
    which ``import rac.learning.gym`` fails."""
    import re
    import tomllib

    pyproject = Path(__file__).resolve().parents[2] / "pyproject.toml"
    extras = tomllib.loads(pyproject.read_text(encoding="utf-8"))["project"]["optional-dependencies"]
    floors = [requirement for requirements in extras.values() for requirement in requirements
              if re.match(r"gymnasium\b", requirement)]
    assert floors
    for requirement in floors:
        found = re.search(r">=\s*(\d+)\.(\d+)", requirement)
        assert found and (int(found.group(1)), int(found.group(2))) >= (1, 1), requirement
    assert hasattr(gymnasium.vector, "AutoresetMode")  # what the floor provides, here installed
