"""Gymnasium wrappers that hand out a reward automaton's reward instead of the environment's.

Example::

    import gymnasium
    from rac.learning.wrappers import RewardAutomatonWrapper

    def inputs(obs, info):
        return {"isClose": info["min_dist"] < 3.0, "prog": info["progress"] > 0,
                "comf": abs(obs[2]) < 1.0, "collide": info["collision"],
                "dgoal": min(info["dist_goal"], 500.0)}

    env = RewardAutomatonWrapper(gymnasium.make("MyDriving-v0"), "stdlib/driving.ra", inputs)
    obs, info = env.reset(seed=0)
    obs, reward, terminated, truncated, info = env.step(env.action_space.sample())
    info["rac"]  # {"location": ..., "rewards": {...}, "reward_steps": {...}, "objective": ..., ...}

Each ``step`` reads the automaton's inputs from the new observation and info, takes one sample,
and returns the objective's increase as the reward (divided by ``scale``); when the episode
terminates or is truncated, the ``at end`` clauses are applied with the same inputs and their
increase is added. An unscaled episode's return is thus the objective's final value. With
``episode ends when COND`` in the automaton, a step whose inputs satisfy COND ends the episode:
the wrapper reports ``terminated=True`` (whatever the environment said), the automaton has applied
its ``at end`` clauses in that step (``end`` is not called again), and the next call must be ``reset``. The
automaton's own ``sample every`` is not enforced: one environment step is one sample (a warning
says when the environment's time step differs). :class:`RewardAutomatonVectorWrapper` does the
same for a vector environment, with one :class:`~rac.runtime.batch.BatchRewardAutomaton`.
"""

from __future__ import annotations

import copy
import inspect
import math
import numbers
import os
import warnings
from collections.abc import Callable, Iterable, Iterator, Mapping
from fractions import Fraction
from pathlib import Path
from typing import Any, NoReturn, Protocol, SupportsFloat, runtime_checkable

import gymnasium
import numpy as np
from gymnasium.utils import RecordConstructorArgs
from gymnasium.vector import AutoresetMode, VectorEnv, VectorWrapper

from rac import ir
from rac.check.analysis.scale import sample_change_bound
from rac.compiler import compile_file
from rac.core.caller import callers, require_bool, user_stacklevel
from rac.core.diagnostics import RacValueError
from rac.learning.vector_info import merge_vector_info
from rac.runtime.batch import BatchRewardAutomaton
from rac.runtime.interpreter import RewardAutomaton
from rac.runtime.semantics import clip_inputs, clip_rows, input_specs

__all__ = ["MASKED_RESETS", "AutomatonLike", "ChangedRewards", "CutEpisodes", "RewardAutomatonVectorWrapper",
           "RewardAutomatonWrapper", "env_timing", "highway_steps", "outside_reward_changers", "outside_step_limit",
           "scale_factor", "within_proven", "wrapper_chain"]

#: ``inputs(obs, info)`` or ``inputs(obs, info, env)``: the automaton's inputs.
InputFn = Callable[..., Mapping[str, object]]
#: ``None`` (unscaled), ``"proven"`` (the proven bound, :func:`scale_factor`) or a positive factor.
Scale = str | float | None


@runtime_checkable
class AutomatonLike(Protocol):
    """What the wrapper needs: a :class:`~rac.runtime.interpreter.RewardAutomaton` or a generated class."""

    def reset(self) -> None: ...

    def step(self, inputs: Mapping[str, object]) -> float: ...

    def end(self, inputs: Mapping[str, object]) -> float: ...

    @property
    def location(self) -> str: ...

    @property
    def rewards(self) -> dict[str, float]: ...

    @property
    def objective(self) -> float: ...


def _load(automaton: str | os.PathLike[str] | ir.Automaton | AutomatonLike) -> AutomatonLike:
    if isinstance(automaton, (str, os.PathLike)):
        return RewardAutomaton(compile_file(Path(automaton)).raise_for_errors(warn=True))
    if isinstance(automaton, ir.Automaton):
        return RewardAutomaton(automaton)
    if isinstance(automaton, type):  # a generated class has reset/step/end too, unbound: it failed at reset
        raise TypeError(f"automaton is the class {automaton.__name__}: pass an instance, {automaton.__name__}()")
    if all(callable(getattr(automaton, method, None)) for method in ("reset", "step", "end")):
        # the wrapper's own copy: one object handed to several environments would share one run state
        # (a RewardAutomaton's copy shares the immutable IR, so this is cheap)
        return copy.deepcopy(automaton)
    raise TypeError("automaton must be a .ra path, an ir.Automaton, a RewardAutomaton or an object "
                    f"with reset/step/end, not {type(automaton).__name__}")


def _ir_of(automaton: object) -> ir.Automaton | None:
    found = getattr(automaton, "ir", None)
    return found if isinstance(found, ir.Automaton) else None


def automaton_ir(automaton: str | os.PathLike[str] | ir.Automaton | AutomatonLike) -> ir.Automaton | None:
    """The checked automaton behind what the wrappers take (a ``.ra`` path, compiled, ``CheckError`` on
    errors; an :class:`rac.ir.Automaton`; a runtime from :func:`rac.load`), or ``None`` for an object
    without one (an instance of a generated class)."""
    return _ir_of(_load(automaton))


def _takes_env(inputs: Callable[..., object], what: str) -> bool:
    """Whether ``inputs`` takes a third positional argument (the environment): one without a default,
    or named ``env`` (``inputs(obs, info, limit=0.1)`` keeps its ``limit``); read once."""
    if not callable(inputs):
        raise TypeError(f"inputs must be a callable {what} -> mapping of input values")
    try:
        parameters = list(inspect.signature(inputs).parameters.values())
    except (TypeError, ValueError):  # a builtin without a signature: the two-argument form
        return False
    if any(p.kind is p.VAR_POSITIONAL for p in parameters):
        return True
    positional = [p for p in parameters if p.kind in (p.POSITIONAL_ONLY, p.POSITIONAL_OR_KEYWORD)]
    if len(positional) < 2:  # said here, not after the environment's first step
        raise TypeError(f"inputs must take {what}, not {len(positional)} positional argument(s)")
    return len(positional) >= 3 and (positional[2].default is inspect.Parameter.empty or positional[2].name == "env")


def scale_factor(automaton: ir.Automaton | None, scale: Scale, samples: int = 1) -> float:
    """The positive number every reward is divided by: 1.0 for ``None``; the user's factor; or for
    ``"proven"`` the largest ``|objective increase|`` of a step of ``samples`` samples that may end
    the run, proved from the automaton (:meth:`rac.check.analysis.scale.SampleChange.step_bound`),
    so every scaled reward lies in [-1, 1]. A positive factor keeps the priority proofs."""
    if scale is None:
        return 1.0
    if isinstance(scale, str):
        if scale != "proven":
            raise ValueError(f"scale must be None, 'proven' or a positive number, not {scale!r}")
        if automaton is None:
            raise RacValueError("scale='proven' needs the automaton's IR (a .ra path, an ir.Automaton or a "
                                "RewardAutomaton), not a generated class")
        bound = sample_change_bound(automaton).step_bound(samples)
        if bound == 0:
            raise RacValueError("scale='proven': the objective never changes, so there is nothing to scale")
        return float(bound)
    # numpy's numbers too (np.float32(20.0), np.int64(20): a factor read from an array), not a bool
    if not _positive_real(scale):
        raise ValueError(f"scale must be None, 'proven' or a positive number, not {scale!r}")
    return float(scale)


#: How far past 1 a reward divided by the proven bound may come out by the floats' rounding alone: the bound is
#: exact, the objective's increase a difference of float sums, a few units in the last place off (pend.ra's
#: -5 on `sa` weighted 10, over a bound of 50, gave -1.000000000000001).
PROVEN_ROUNDING = 1e-9


def within_proven(reward: Any, proven: bool) -> Any:
    """``reward`` (a float, or an array of them) divided by the scale: with the proven scale (``proven``) its
    values a rounding past [-1, 1] (:data:`PROVEN_ROUNDING`) put back on the bound, as proved; any other left as
    it is (a value further out is no rounding: it shows, rather than being hidden)."""
    if not proven:
        return reward
    if isinstance(reward, np.ndarray):
        rounded = np.abs(reward) <= 1.0 + PROVEN_ROUNDING
        return np.where(rounded, np.clip(reward, -1.0, 1.0), reward)
    return max(-1.0, min(1.0, reward)) if abs(reward) <= 1.0 + PROVEN_ROUNDING else reward


def env_timing(env: object, dt: float | None = None) -> tuple[float | None, float | None]:
    """(seconds per step, seconds per episode) of ``env``, each None when unknown.

    The step: ``dt`` when given; else ``env.unwrapped.dt``; else highway-env's
    ``1 / config["policy_frequency"]``. The episode: the shortest of ``spec.max_episode_steps`` steps,
    the limit of every ``TimeLimit`` in the wrapper chain (one around an unregistered environment
    has no spec) and highway-env's ``config["duration"]`` (seconds in highway-env: its clock advances by
    ``1 / policy_frequency`` per step and the episode is truncated at ``time >= duration``, which in floats can
    take a step more than ``duration * policy_frequency``: :func:`highway_steps`), as the episode ends at
    whichever comes first.
    """
    unwrapped = getattr(env, "unwrapped", env)
    config = getattr(unwrapped, "config", None)
    config = config if isinstance(config, Mapping) else {}
    step = _seconds(dt)
    if step is None:
        own = getattr(unwrapped, "dt", None)
        if _positive_real(own):
            step = own
        elif isinstance(config.get("policy_frequency"), (int, float)) and config["policy_frequency"] > 0:
            step = 1.0 / config["policy_frequency"]
    ends: list[float] = []  # every limit the episode has: it ends at the first one reached
    if step is not None:
        ends.extend(limit * step for limit in _step_limits(env))
    if isinstance(config.get("duration"), (int, float)):
        counted = highway_steps(config)  # the steps highway-env's clock takes to reach it
        ends.append(counted * step if counted is not None and step is not None else float(config["duration"]))
    return step, min(ends, default=None)


def highway_steps(config: Mapping[str, Any]) -> int | None:
    """The steps after which highway-env's ``config["duration"]`` ends an episode, None without one (or past a
    million steps, not counted). highway-env adds ``1 / policy_frequency`` to its clock at every step, in floats,
    and truncates once the clock is ``>= duration``; the sum can fall short of a whole duration by a rounding, and
    the episode then takes a step more: a duration of 10 s at policy_frequency 5 ends after 51 steps, not 50 (the
    clock at 9.999999999999996 after 50)."""
    frequency, duration = config.get("policy_frequency"), config.get("duration")
    if frequency is None or duration is None or not _positive_real(frequency) or not _positive_real(duration) \
            or duration * frequency > 1e6:
        return None
    tick, clock, steps = 1 / frequency, 0.0, 0
    while not clock >= duration:  # as highway-env's AbstractEnv.step and _is_truncated count
        clock += tick
        steps += 1
    return steps


def _positive_real(value: object) -> bool:
    """Whether ``value`` is a positive finite real number (numpy's too), not a bool: a time step, a scale."""
    return (isinstance(value, numbers.Real) and not isinstance(value, (bool, np.bool_))
            and math.isfinite(value) and float(value) > 0)


def _seconds(dt: object) -> float | None:
    """The ``dt=`` given to a wrapper or :func:`env_timing`, checked: None, or a positive finite number of seconds
    (``RacValueError`` otherwise; 0 ended construction in ZeroDivisionError, a string in TypeError, and a NaN,
    negative or infinite step gave warnings of nonsense). A numpy float keeps its type: its precision is the
    tolerance of the timing check."""
    if dt is None:
        return None
    if not _positive_real(dt):
        raise RacValueError(f"dt must be the environment's seconds per step, a positive number, not {dt!r}")
    return dt  # type: ignore[return-value]


def _tolerance(step: float) -> float:
    """The relative tolerance of comparing ``step`` with the automaton's period: a float32 step (``np.float32(0.1)``,
    a configuration read as float32) is its period to float32 precision, not a mismatch."""
    return max(1e-9, 4 * float(np.finfo(step).eps)) if isinstance(step, np.floating) else 1e-9


def _step_limits(env: object) -> list[int]:
    """The step limits of ``env``'s episodes: its spec's ``max_episode_steps`` and that of every
    gymnasium ``TimeLimit`` in its wrapper chain. The spec alone misses a ``TimeLimit(env, n)`` put
    around an environment that was not made from a registered id (its spec is None), which is how
    the docs tell a limit to go inside the wrapper."""
    limits: list[int] = []
    spec_limit = getattr(getattr(env, "spec", None), "max_episode_steps", None)
    if isinstance(spec_limit, int):
        limits.append(spec_limit)
    for wrapper in wrapper_chain(env):
        if isinstance(wrapper, gymnasium.wrappers.TimeLimit):
            own = getattr(wrapper, "_max_episode_steps", None)  # gymnasium keeps it there, with no public name
            if isinstance(own, int):
                limits.append(own)
    return limits


def wrapper_chain(env: object) -> Iterator[Any]:
    """``env`` and the environments it wraps (each wrapper's ``env``), outermost first; at most 100 (a
    wrapper chain, not a cycle)."""
    for _ in range(100):
        if env is None:
            return
        yield env
        env = getattr(env, "env", None)


def _inside(wrapper: object, env: object) -> bool:
    """Whether ``env`` is in ``wrapper``'s chain of wrapped environments (below it)."""
    return any(inner is env for inner in wrapper_chain(getattr(wrapper, "env", None)))


#: The code of gymnasium's ``TimeLimit.reset`` and ``TimeLimit.step``, whose frames :func:`outside_step_limit` reads.
_TIME_LIMIT_CODE = {gymnasium.wrappers.TimeLimit.reset.__code__, gymnasium.wrappers.TimeLimit.step.__code__}


def outside_step_limit(env: object, frames: int = 12) -> int | None:
    """The step limit of a gymnasium ``TimeLimit`` outside ``env`` whose ``reset`` or ``step`` is
    calling ``env``'s now (one of the ``frames`` innermost callers), else None.

    ``gymnasium.make(id, max_episode_steps=N)`` puts that ``TimeLimit`` outside the environment it
    makes, and the spec it gives the environment itself has no limit: the callers are the only
    place the environment can learn that its episodes are cut after N steps, where it cannot see."""
    for frame in callers(frames):
        if frame.f_code not in _TIME_LIMIT_CODE:  # only a TimeLimit's own frames are read
            continue
        owner = frame.f_locals.get("self")
        if isinstance(owner, gymnasium.wrappers.TimeLimit) and _inside(owner, env):
            limit = getattr(owner, "_max_episode_steps", None)  # gymnasium keeps it there, with no public name
            return limit if isinstance(limit, int) else None
    return None


#: gymnasium's wrappers that change every reward they pass on, not by one fixed positive factor (a subclass before its
#: base, ClipReward before TransformReward: a wrapper is named by the first it is one of).
REWARD_CHANGERS = (gymnasium.wrappers.NormalizeReward, gymnasium.wrappers.ClipReward,
                   gymnasium.wrappers.TransformReward)
#: Their vector forms (gymnasium.wrappers.vector's ClipReward is a VectorizeTransformReward).
VECTOR_REWARD_CHANGERS = (gymnasium.wrappers.vector.NormalizeReward, gymnasium.wrappers.vector.ClipReward,
                          gymnasium.wrappers.vector.TransformReward, gymnasium.wrappers.vector.VectorizeTransformReward)
#: What a reward changer around the automaton's reward means (``{names}``: the wrappers), said once by the wrapper or
#: the scenario environment at a reset a changer calls, and by stable-baselines3's RacCallback.
REWARD_CHANGED = ("gymnasium's {names} around the reward automaton's reward changes every reward the learner sees "
                  "(NormalizeReward divides it by a running estimate of the returns' spread, which changes as training "
                  "goes on; ClipReward clips it; TransformReward applies a function of its own): the learner's reward "
                  "is no longer the automaton's up to one positive factor, so the priority proofs of rac check (no "
                  "penalty compensated by lower objectives' gains) do not cover what it learns from; scale the "
                  "automaton's reward with scale='proven' (every reward in [-1, 1], the proofs intact) instead")
#: The code of the resets through which a reward changer outside calls the environment's (gymnasium's Wrapper and
#: VectorWrapper pass reset on; the vector NormalizeReward has its own), read by :func:`outside_reward_changers`.
_RESET_CODE = {gymnasium.Wrapper.reset.__code__, VectorWrapper.reset.__code__,
               gymnasium.wrappers.vector.NormalizeReward.reset.__code__}


def outside_reward_changers(env: object, kinds: tuple[type, ...] = REWARD_CHANGERS, frames: int = 40) -> list[str]:
    """The names of gymnasium's reward wrappers of ``kinds`` (:data:`REWARD_CHANGERS`, :data:`VECTOR_REWARD_CHANGERS`)
    outside ``env`` whose ``reset`` is calling ``env``'s now (one of the ``frames`` innermost callers): the wrappers
    that change every reward ``env`` hands out on its way to the learner. Read from the callers, as
    :func:`outside_step_limit` reads a ``TimeLimit``: an environment does not know what is put around it, and a
    training loop of one's own (CleanRL's: ``NormalizeReward`` and a clipping ``TransformReward`` around every
    environment) has no stable-baselines3 callback to say it."""
    names: list[str] = []
    for frame in callers(frames):
        if frame.f_code not in _RESET_CODE:  # only the wrappers' own frames are read
            continue
        owner = frame.f_locals.get("self")
        kind = next((kind for kind in kinds if isinstance(owner, kind)), None)
        if kind is not None and _inside(owner, env) and kind.__name__ not in names:
            names.append(kind.__name__)
    return names


class ChangedRewards:
    """Warns once, at a reset, when gymnasium's reward wrappers outside an environment of rac's change every reward
    it hands out (:func:`outside_reward_changers`, :data:`REWARD_CHANGED`)."""

    def __init__(self) -> None:
        #: Said already (stable-baselines3's RacCallback, which says the same of its training environment later in
        #: ``learn()``, does not say it again of environments in its process that have).
        self.warned = False

    def check(self, env: object, kinds: tuple[type, ...]) -> None:
        """Called from ``env``'s ``reset``: warn when a wrapper of ``kinds`` outside it is calling it."""
        if self.warned:
            return
        names = outside_reward_changers(env, kinds)
        if names:
            self.warned = True
            warnings.warn(REWARD_CHANGED.format(names=", ".join(sorted(names))), UserWarning,
                          stacklevel=user_stacklevel())


#: The attribute of an environment whose own reward a rac reward wrapper replaces (ScenarioEnv's
#: ``reward_replaced``): set True by the wrapper, it stops that environment's warning of cut episodes,
#: which would take the wrapper's resets after its own `episode ends when` for a limit's cuts.
REPLACED = "reward_replaced"


def _replaces_reward_of(envs: Iterable[object]) -> None:
    """Tell each of ``envs`` (single environments, wrapped or not) that has :data:`REPLACED` that a rac
    wrapper replaces its reward."""
    for env in envs:
        inner = getattr(env, "unwrapped", env)
        if hasattr(inner, REPLACED):
            setattr(inner, REPLACED, True)


class _Timing:
    """Warns when the environment's step differs from the automaton's period, or its episode has more steps
    than the automaton's horizon has samples (a shorter one is a shorter run, which the proofs cover):
    checked at construction and at every reset, and said once per timing the environment has (an
    environment reconfigured between episodes, as highway-env's ``configure()`` then ``reset()``,
    is checked again)."""

    def __init__(self, automaton: object, dt: float | None, advice: str) -> None:
        period, steps = getattr(automaton, "period", None), getattr(automaton, "steps", None)
        self.period = float(period) if isinstance(period, (int, float, Fraction)) else None
        self.steps = steps if isinstance(steps, int) else None
        self.dt = _seconds(dt)
        self.checked: tuple[float, float | None] | None = None  # the timing last checked
        self.advice = advice.format(steps=self.steps)  # how to end the episodes at the horizon

    def check(self, env: object) -> None:
        if self.period is None:
            return
        step, episode = env_timing(env, self.dt)
        if step is None or (step, episode) == self.checked:
            return  # not known yet (perhaps after the first reset), or said already
        self.checked = (step, episode)
        horizon = (self.steps or 0) * self.period
        cover = (f"the priority proofs cover runs sampled every {self.period:g} s over a horizon of {horizon:g} s "
                 f"({self.steps} samples) only")
        tolerance = _tolerance(step)
        if not math.isclose(step, self.period, rel_tol=tolerance):
            warnings.warn(f"the environment's time step is {step:g} s but the automaton samples every "
                          f"{self.period:g} s (one step is one sample); {cover}: make the two agree, the "
                          f"environment's step (highway-env: config policy_frequency {1 / self.period:g}) or the "
                          f"automaton's `sample every` (then `rac check` proves it again)", UserWarning,
                          stacklevel=user_stacklevel())
        # a shorter episode is a shorter run, which every proof covers (runs of at most the horizon's samples);
        # the steps are counted, not the seconds: one step is one sample whatever the environment's time step
        if episode is not None and self.steps is not None:
            steps = episode / step
            if steps > self.steps and not math.isclose(steps, self.steps, rel_tol=tolerance):
                # steps against samples, each with its own period: seconds alone read as a contradiction when
                # the periods differ ("lasts 3 s ... horizon is 3 s")
                warnings.warn(f"the environment's episode has {steps:g} steps ({episode:g} s at {step:g} s a "
                              f"step{_late_note(env, round(steps))}) but the automaton's horizon has {self.steps} "
                              f"samples ({horizon:g} s at {self.period:g} s a sample), and one step is one sample; "
                              f"{cover}: end the episodes at the horizon, {self.advice}", UserWarning,
                              stacklevel=user_stacklevel())


def _late_note(env: object, steps: int) -> str:
    """Why an episode of ``steps`` steps ended by highway-env's ``duration`` is a step longer than the duration
    says (:func:`highway_steps`), or ""."""
    config = getattr(getattr(env, "unwrapped", env), "config", None)
    if not isinstance(config, Mapping) or highway_steps(config) != steps:
        return ""
    exact = math.ceil(Fraction(config["duration"]) * Fraction(config["policy_frequency"]))  # without the rounding
    if steps == exact:
        return ""
    return (f": highway-env ends it once its clock, adding 1/{config['policy_frequency']:g} s a step in floats, "
            f"reaches the duration of {config['duration']:g} s, which after {exact} steps it misses by a rounding")


class _PastHorizon:
    """Warns once when an episode runs past the automaton's horizon: the priority proofs, and a proven
    scale's bound on every reward, cover that many samples only (an environment without a time
    step, whose timing :class:`_Timing` cannot check, is caught here at the latest)."""

    def __init__(self, automaton: object, proven: bool, advice: str) -> None:
        steps = getattr(automaton, "steps", None)
        self.steps = steps if isinstance(steps, int) else None
        self.proven = proven
        self.advice = advice.format(steps=self.steps)
        self.warned = False

    def check(self, samples: Any) -> None:
        if self.warned or self.steps is None or samples is None or not np.any(np.asarray(samples) > self.steps):
            return
        self.warned = True
        also = " and the proven scale (every reward within [-1, 1])" if self.proven else ""
        warnings.warn(f"an episode has run past the automaton's horizon of {self.steps} samples: the priority "
                      f"proofs{also} cover {self.steps} samples only, and its rewards from here on are not covered; "
                      f"end the episodes there: {self.advice}", UserWarning, stacklevel=user_stacklevel())


#: How to end a single environment's episodes so the wrapper sees it (the limit inside, or it never
#: sees ``truncated`` and the ``at end`` clauses are lost).
SINGLE_LIMIT = ("put the limit inside the rac wrapper: RewardAutomatonWrapper(gymnasium.wrappers.TimeLimit(env, "
                "{steps}), ...) or gymnasium.make(id, max_episode_steps={steps}) as the wrapped env, not "
                "TimeLimit(RewardAutomatonWrapper(...), {steps})")
#: The same for a vector environment: each sub-environment carries its own limit.
VECTOR_LIMIT = ("limit each sub-environment inside the vector environment, e.g. "
                "SyncVectorEnv([lambda: gymnasium.wrappers.TimeLimit(make_env(), {steps})] * n) or "
                "gymnasium.make_vec(id, num_envs=n, max_episode_steps={steps}), then wrap that with "
                "RewardAutomatonVectorWrapper")


class CutEpisodes:
    """Warns once when episodes are cut where rac cannot see it: reset before they terminated or were
    truncated as far as rac saw, as a ``TimeLimit`` outside rac's wrapper does. Their ``at end``
    clauses were never applied, and their returns lack them. A time limit cuts every episode after
    the same number of steps, so the warning waits for a second cut episode of the same length,
    three steps or more, with no episode between the two that ended as rac saw it: a single reset in
    mid-episode (the end of a training run) is no limit, nor are stable-baselines3's ``learn()``
    called again and again (each resets the episode running, between complete ones) and gymnasium's
    ``check_env`` probes (four steps in all, so no two cut episodes of three). ``fix`` says how to
    end the episodes where rac sees it.

    Where the limit is known (``limit`` of :meth:`stepped`: a ``TimeLimit`` outside, as
    ``gymnasium.make(..., max_episode_steps=N)`` puts one, read by :func:`outside_step_limit`), the
    first episode that reaches it without ending is cut there: the warning comes at that step."""

    def __init__(self, fix: str) -> None:
        self.fix = fix
        self.warned = False
        self.steps = 0  # steps of the episode now running; 0 once it has ended
        self.cut: set[int] = set()  # the lengths of the episodes cut since the last one that ended

    def stepped(self, done: bool, limit: int | None = None) -> None:
        """One step taken; ``done``: the episode ended there, as rac saw it; ``limit``: the step limit
        known to be enforced outside (None: none known)."""
        self.steps = 0 if done else self.steps + 1
        if done:  # an episode rac saw end: the cuts before it were no limit's (a limit cuts them all)
            self.cut.clear()
        elif limit is not None and self.steps == limit and not self.warned:
            # the limit cuts this episode now: said at its first cut, not at the reset after a second
            self._warn(f"a TimeLimit outside rac (max_episode_steps={limit}) cuts episodes after {limit} step(s), "
                       "before rac sees them end (terminated or truncated)", "")

    def _warn(self, what: str, cause: str = ("if stable-baselines3's learn() is called again and again with "
                                             "fewer steps than an episode, pass reset_num_timesteps=False (each "
                                             "call resets the episode running, so none ends); if a TimeLimit or "
                                             "another wrapper outside ends them, ")) -> None:
        self.warned = True
        warnings.warn(f"{what}: the automaton's `at end` clauses were not applied and their returns lack them; "
                      f"{cause}{self.fix}", UserWarning, stacklevel=user_stacklevel())

    def reset(self) -> None:
        """An episode starts: warn when the last one was cut after as many steps as an earlier one
        since the last episode that ended."""
        if self.steps > 2 and not self.warned:
            if self.steps in self.cut:
                self._warn(f"episodes were reset after {self.steps} step(s) without rac seeing them end (terminated "
                           "or truncated)")
            self.cut.add(self.steps)
        self.steps = 0


def _monitor_inside(env: object) -> bool:
    """Whether stable-baselines3's ``Monitor`` wraps ``env`` somewhere (read by the class's module and
    name, so stable-baselines3 need not be installed, nor is it imported)."""
    return any(type(wrapper).__name__ == "Monitor" and type(wrapper).__module__.startswith("stable_baselines3")
               for wrapper in wrapper_chain(env))


def _statistics_inside(env: object, kind: type) -> bool:
    """Whether a gymnasium ``RecordEpisodeStatistics`` (``kind``: the single or the vector one) wraps
    ``env`` somewhere: it sums the environment's own rewards, not the automaton's."""
    return any(isinstance(wrapper, kind) for wrapper in wrapper_chain(env))


#: Why :meth:`RewardAutomatonWrapper.compute_reward` is refused (and ``RacCallback`` refuses ``HerReplayBuffer``).
NO_RELABELLING = ("RewardAutomatonWrapper has no compute_reward: the automaton's reward depends on the run so far, "
                  "not on a goal, so relabelled transitions (stable-baselines3's HerReplayBuffer) cannot be given it, "
                  "and the wrapped environment's compute_reward would mix its own reward into the automaton's; train "
                  "without hindsight relabelling")

#: What :func:`_statistics_inside` finding one inside rac's wrapper means, and the fix (``{outside}``).
STATISTICS_INSIDE = ("gymnasium's RecordEpisodeStatistics sits inside rac's wrapper: info['episode']['r'] is the "
                     "environment's own return, not the automaton's, and it never sees an episode the automaton "
                     "ends (`episode ends when`); wrap outside instead: {outside}")


#: The attribute of a vector environment class that says it resets only the sub-environments ``options["reset_mask"]``
#: selects (rac's ScenarioVectorEnv sets it True; gymnasium's SyncVectorEnv and AsyncVectorEnv are known without it).
MASKED_RESETS = "masked_resets"


def _honours_reset_mask(env: VectorEnv) -> bool:
    """Whether ``env``'s vector environment is known to reset only the sub-environments ``options["reset_mask"]``
    selects (gymnasium >= 1.1): gymnasium's ``SyncVectorEnv`` and ``AsyncVectorEnv``, and one whose
    :data:`MASKED_RESETS` is True (rac's :class:`~rac.learning.vector.ScenarioVectorEnv`). Others may ignore the
    option and reset every sub-environment, as gymnasium's own ``CartPoleVectorEnv`` does
    (``gymnasium.make_vec("CartPole-v1")``'s default)."""
    base = env.unwrapped
    return isinstance(base, (gymnasium.vector.SyncVectorEnv, gymnasium.vector.AsyncVectorEnv)) or \
        getattr(base, MASKED_RESETS, False) is True


def _rows_changed(before: Any, after: Any, rows: np.ndarray) -> bool:
    """Whether the batched observations ``after`` differ from ``before`` in a sub-environment of ``rows`` (a boolean
    mask): arrays, and ``Dict`` or ``Tuple`` observations of them; False where the two cannot be compared."""
    if isinstance(before, Mapping) and isinstance(after, Mapping):
        return any(_rows_changed(before[key], after[key], rows) for key in before if key in after)
    if isinstance(before, tuple) and isinstance(after, tuple):
        return len(before) == len(after) and any(_rows_changed(b, a, rows) for b, a in zip(before, after, strict=True))
    if not isinstance(before, np.ndarray) or not isinstance(after, np.ndarray) or before.shape != after.shape \
            or before.shape[:1] != rows.shape:
        return False
    # a NaN left where it was is no change
    return not np.array_equal(before[rows], after[rows], equal_nan=before.dtype.kind in "fc")


#: Why :class:`RewardAutomatonVectorWrapper` refuses a vector environment whose infos are no dict (``{found}``).
LISTED_INFOS = ("RewardAutomatonVectorWrapper reads and extends gymnasium's vector info (one dict of arrays, with "
                "_key masks), and {found}: put gymnasium's DictInfoToList outside it, "
                "DictInfoToList(RewardAutomatonVectorWrapper(envs, ...)), for a list of one info dict per "
                "sub-environment")


#: What :class:`RewardAutomatonVectorWrapper` says of a vector environment that restarted sub-environments its
#: ``options["reset_mask"]`` did not select (``{name}``: its class; ``{call}``: who asked for the reset).
IGNORED_RESET_MASK = (
    "{name} restarted sub-environments that options['reset_mask'] did not select, in {call}: their observations "
    "changed, so it ignores the mask and resets every sub-environment, while RewardAutomatonVectorWrapper reset the "
    "selected automata only: the other sub-environments' episodes started again under automata that go on, and "
    "their rewards are no longer their episodes'. The wrapper needs a vector environment that resets the selected "
    "sub-environments alone: gymnasium's SyncVectorEnv or AsyncVectorEnv, e.g. gymnasium.make_vec(id, num_envs=n, "
    "vectorization_mode='sync'), or a class of your own that does and says so (masked_resets = True); reset() every "
    "sub-environment before the next step")


def _clipping(automaton: ir.Automaton | None, clip: bool) -> tuple[Any, ...] | None:
    if not require_bool(clip, "clip"):  # clip="no" clipped
        return None
    if automaton is None:
        raise RacValueError("clip=True needs the automaton's declared ranges: pass a .ra path, an ir.Automaton "
                            "or a RewardAutomaton")
    return input_specs(automaton)


def _refused(exc: ValueError, program: ir.Automaton | None, clipping: bool, values: Mapping[str, object],
             rows: np.ndarray | None, state: str) -> RacValueError:
    """The automaton's refusal of the inputs ``values`` (``exc``), saying what state the environment and
    the automaton are in (``state``) and, where ``clip=True`` would have clipped a value the
    automaton refused, that it would: the usual cause is an input whose range the environment leaves
    (highway-env's gap to an empty lane), and the fix is one keyword away."""
    hint = ""
    if not clipping and program is not None:
        try:
            _, counts = clip_inputs(input_specs(program), values, rows, scalars=rows is None)
        except ValueError:  # NaN: no clipping helps
            counts = {}
        names = sorted(name for name, count in counts.items() if count)
        if names:
            hint = (f" (clip=True clips {', '.join(names)} to the declared range and counts every value clipped, "
                    "info['rac']['clipped'])")
    return RacValueError(f"{exc}{hint}; {state}")


class RewardAutomatonWrapper(gymnasium.Wrapper, RecordConstructorArgs):
    """Hand out a reward automaton's reward instead of the environment's.

    Args:
        env: the environment to wrap.
        automaton: a `.ra` file path (compiled with :func:`rac.compiler.compile_file`; errors
            raise :class:`rac.core.diagnostics.CheckError`), an :class:`rac.ir.Automaton`, a
            :class:`rac.runtime.interpreter.RewardAutomaton`, or any object with the same ``reset``/``step``/
            ``end`` API (e.g. an instance of a class generated by :mod:`rac.targets.python`; it
            cannot clip or prove a scale). An object is copied (``copy.deepcopy``): the wrapper
            steps its own copy, :attr:`automaton`, so one loaded automaton may be handed to
            several environments; the object passed in is left as it was.
        inputs: ``inputs(obs, info) -> {input name: value}``, or ``inputs(obs, info, env)`` (a third
            positional parameter without a default, or named ``env``; read once here) where ``env``
            is the wrapped environment (so ``env.unwrapped.road`` is reachable); called after every step.
        clip: numeric inputs outside their declared range are clipped to it
            (:func:`rac.runtime.semantics.clip_inputs`); NaN still raises ``ValueError``. The counts
            per input are in ``info["rac"]["clipped"]`` (this step) and :attr:`clipped_total`.
        scale: ``None`` (rewards unscaled), ``"proven"`` (divided by the largest change of the
            objective in one step proved from the automaton, so they lie in [-1, 1]), or a positive
            factor of your own (:func:`scale_factor`). The factor is :attr:`scale` and ``info["rac"]["scale"]``;
            ``info["rac"]["proven"]`` says it is the proven one (counterfactual rows keep its promise:
            :class:`rac.learning.replay.CounterfactualRows`).
        dt: the environment's seconds per step, when it does not say itself (:func:`env_timing`).

    Timing: a ``UserWarning`` (at construction, and at a reset when the environment's timing is
    new: it only knows it then, or it was reconfigured) when the environment's step differs from
    the automaton's ``sample every``, or its episode (the shortest of ``spec.max_episode_steps``
    steps, a ``TimeLimit``'s in the wrapper chain and highway-env's ``duration``) has more steps than
    the automaton's horizon has samples: the priority proofs cover runs of the automaton's period and
    of at most its horizon only (a shorter episode is a shorter run: covered, not warned of).
    When neither ``dt``, ``env.unwrapped.dt`` nor highway-env's ``policy_frequency`` is there,
    nothing is checked.

    stable-baselines3's ``Monitor`` goes outside (a ``UserWarning`` when ``env`` holds one): inside, it
    records the environment's reward and misses the episodes the automaton ends.

    Episode limits go inside: ``RewardAutomatonWrapper(TimeLimit(env, n), ...)``. A limit outside
    truncates episodes this wrapper never sees end, so their ``at end`` clauses are lost; a
    :meth:`reset` warns once when two episodes were cut so after as many steps (:class:`CutEpisodes`).

    ``info["rac"]`` holds ``location``, ``rewards`` (values), ``objective`` and ``scale`` after
    ``reset`` and ``step``; after ``step`` also ``reward_steps`` (each reward's change over the
    step, unscaled), ``env_reward`` (the environment's own reward), ``clipped`` and ``inputs`` (the
    values the automaton read, after clipping: what
    :func:`rac.learning.counterfactual.counterfactual_transitions` replays) and ``held`` (the inputs
    its rates read in the step: the previous step's ``inputs``, this step's at an episode's first).

    Example::

        env = RewardAutomatonWrapper(env, "stdlib/driving.ra", lambda obs, info: info["ra_inputs"],
                                     clip=True, scale="proven")
        obs, info = env.reset(seed=1)
        obs, reward, terminated, truncated, info = env.step(action)
    """

    def __init__(self, env: gymnasium.Env, automaton: str | os.PathLike[str] | ir.Automaton | AutomatonLike,
                 inputs: InputFn, *, clip: bool = False, scale: Scale = None, dt: float | None = None) -> None:
        RecordConstructorArgs.__init__(self, automaton=automaton, inputs=inputs, clip=clip, scale=scale, dt=dt)
        gymnasium.Wrapper.__init__(self, env)
        self._with_env = _takes_env(inputs, "(obs, info) or (obs, info, env)")
        self.automaton: AutomatonLike = _load(automaton)
        self.inputs = inputs
        program = _ir_of(self.automaton)
        self._program = program
        self._specs = _clipping(program, clip)
        #: The positive factor every reward is divided by (1.0 when unscaled).
        self.scale: float = scale_factor(program, scale)
        self._proven = scale == "proven"
        #: Per numeric input, how many values were clipped since the wrapper was made.
        self.clipped_total: dict[str, int] = {}
        if _monitor_inside(env):
            warnings.warn("stable-baselines3's Monitor sits inside rac's wrapper (as make_vec_env(..., "
                          "wrapper_class=...) builds it): it records the environment's own reward, so ep_rew_mean "
                          "and evaluate_policy report that, not the automaton's, and it never sees an episode the "
                          "automaton ends (`episode ends when`); wrap outside it instead: make_vec_env(lambda: "
                          "RewardAutomatonWrapper(gymnasium.make(id), ...), n_envs=n) (make_vec_env's Monitor then "
                          "sits outside), Monitor(RewardAutomatonWrapper(env, ...)), or VecMonitor on the vector "
                          "environment", UserWarning, stacklevel=user_stacklevel())
        if _statistics_inside(env, gymnasium.wrappers.RecordEpisodeStatistics):
            warnings.warn(STATISTICS_INSIDE.format(outside="RecordEpisodeStatistics(RewardAutomatonWrapper(env, ...))"),
                          UserWarning, stacklevel=user_stacklevel())
        if any(isinstance(wrapper, gymnasium.wrappers.Autoreset) for wrapper in wrapper_chain(env)):
            # its reset step would be taken as a sample of the run that ended: the inputs read from a reset info,
            # the automaton stepped after its `at end` (a RuntimeError, or the inputs' KeyError, at that step)
            raise RacValueError("gymnasium's Autoreset sits inside rac's wrapper: the step after an episode ends "
                                "would be the next episode's reset, which the automaton cannot take as a sample of "
                                "the run that ended; put it outside: Autoreset(RewardAutomatonWrapper(env, ...))")
        self._timing = _Timing(self.automaton, dt, SINGLE_LIMIT)
        self._timing.check(env)
        _replaces_reward_of([env])
        self._past = _PastHorizon(self.automaton, scale == "proven", SINGLE_LIMIT)
        steps = getattr(self.automaton, "steps", None)
        self._cut = CutEpisodes(SINGLE_LIMIT.format(steps=steps if isinstance(steps, int) else "N"))
        self._outside: int | None = None  # the limit of a TimeLimit outside, found at a reset it called
        #: Says once that gymnasium's reward wrappers outside change every reward (found at a reset they call).
        self.changed_rewards = ChangedRewards()
        self._last_inputs: dict[str, Any] | None = None  # the inputs the next step's rates read (none at a reset)

    @property
    def proof_subject(self) -> tuple[ir.Automaton, int] | None:
        """What ``rac check``'s priority proofs of this wrapper's reward are about: the automaton and the
        samples one step spans (1), which :class:`rac.learning.sb3.RacCallback` checks P2 of the
        discounted return on (:mod:`rac.check.analysis.discount`); None for an automaton without its
        checked form (an instance of a generated class)."""
        return None if self._program is None else (self._program, 1)

    def _snapshot(self) -> dict[str, Any]:
        ra = self.automaton
        return {"location": ra.location, "rewards": dict(ra.rewards), "objective": ra.objective, "scale": self.scale,
                "proven": self._proven}

    def reset(self, *, seed: int | None = None,
              options: dict[str, Any] | None = None) -> tuple[Any, dict[str, Any]]:
        """Reset the environment and the automaton."""
        obs, info = self.env.reset(seed=seed, options=options)
        self._timing.check(self.env)
        self._cut.reset()
        if self._outside is None:  # TimeLimit(RewardAutomatonWrapper(...), N): said at its first cut
            self._outside = outside_step_limit(self)
        self.changed_rewards.check(self, REWARD_CHANGERS)
        self.automaton.reset()
        self._last_inputs = None
        info = dict(info)
        info["rac"] = self._snapshot()
        return obs, info

    def step(self, action: Any) -> tuple[Any, SupportsFloat, bool, bool, dict[str, Any]]:
        """Step the environment; the reward is the automaton's (``at end`` included on the last step).
        ``terminated`` is the environment's, or true where the automaton's ``episode ends when`` held."""
        obs, env_reward, terminated, truncated, info = self.env.step(action)
        info = dict(info)
        try:
            values = self.inputs(obs, info, self.env) if self._with_env else self.inputs(obs, info)
        except Exception as exc:  # the user's callable: say what it did and what state things are in
            raise RacValueError(f"inputs(obs, info) raised {type(exc).__name__}: {exc}; the environment has taken "
                                "this step and the automaton has not: reset before the next step") from exc
        clipped: dict[str, int] = {}
        before = dict(self.automaton.rewards)
        try:
            if self._specs is not None:  # a NaN is refused here, not clipped: said as any refusal
                values, clipped = clip_inputs(self._specs, values, scalars=True)
                for name, count in clipped.items():
                    self.clipped_total[name] = self.clipped_total.get(name, 0) + count
            reward = self.automaton.step(values)
        except ValueError as exc:  # the inputs refused (the automaton is unchanged): say where things stand
            raise _refused(exc, self._program, self._specs is not None, values, None,
                           "the environment has taken this step and the automaton has not: reset before the "
                           "next step") from exc
        # the rates of this sample read the previous one's inputs (its own at the first: the language's hold)
        held, self._last_inputs = (self._last_inputs or dict(values)), dict(values)
        self._past.check(getattr(self.automaton, "samples", None))
        # `episode ends when`: the automaton ended the run itself, its end clauses applied in this step
        # (a class generated before the declaration existed has no `terminated`: it never ends a run)
        if getattr(self.automaton, "terminated", False):
            terminated = True
        elif terminated or truncated:
            reward += self.automaton.end(values)
        self._cut.stepped(bool(terminated or truncated), self._outside)
        info["rac"] = {**self._snapshot(), "env_reward": env_reward, "clipped": clipped, "inputs": dict(values),
                       "held": held, "reward_steps": {k: v - before[k] for k, v in self.automaton.rewards.items()}}
        return obs, within_proven(reward / self.scale, self._proven), terminated, truncated, info

    def compute_reward(self, achieved_goal: Any, desired_goal: Any, info: Any) -> NoReturn:
        """Refused (``NotImplementedError``): the automaton's reward of a step depends on the run so far (its
        location and rewards), not on a goal, so it cannot be computed again for another goal. Without this,
        stable-baselines3's ``HerReplayBuffer`` (``env_method("compute_reward", ...)``, which gymnasium's
        ``get_wrapper_attr`` resolves to the wrapped goal environment's) relabelled the stored transitions with
        the environment's own reward, mixed silently into the automaton's."""
        raise NotImplementedError(NO_RELABELLING)


class RewardAutomatonVectorWrapper(VectorWrapper):
    """:class:`RewardAutomatonWrapper` for a vector environment: one
    :class:`~rac.runtime.batch.BatchRewardAutomaton` steps the ``num_envs`` automata together.

    Args:
        env: a ``gymnasium.vector.VectorEnv`` whose ``metadata["autoreset_mode"]`` is
            ``NEXT_STEP`` (gymnasium's default; other modes are refused): the step after a
            sub-environment's episode ended resets it, so that step resets its automaton and its
            reward is 0.
        automaton: a `.ra` path, an :class:`rac.ir.Automaton` or a
            :class:`~rac.runtime.interpreter.RewardAutomaton` (its IR is batched).
        inputs: ``inputs(obs, infos) -> {input name: array of shape (num_envs,)}`` (scalars
            broadcast), or ``inputs(obs, infos, env)`` with the vector environment. Rows of
            sub-environments being reset are not read, and their infos are reset infos, which may
            lack the keys only a step gives (read those with ``infos.get`` or under the mask
            ``infos["_key"]``); when every sub-environment is being reset, ``inputs`` is not called.
        clip, scale, dt: as for :class:`RewardAutomatonWrapper` (``dt``: the sub-environments' step).

    ``infos["rac"]`` holds, per sub-environment (vector-info layout, ``infos["_rac"]`` the mask):
    ``location``, ``objective``, ``scale``, ``env_reward``, and dicts ``rewards``,
    ``reward_steps``, ``clipped``, ``inputs`` and ``held`` (the inputs the rates read: each
    sub-environment's previous step's, its own at an episode's first) of arrays;
    ``infos["rac"]["_reward_steps"]`` (and ``["_inputs"]``, for both) masks off the sub-environments
    in their reset step (no sample taken: as a reset info, they have no ``reward_steps``; ``inputs``
    and ``held`` are empty when all are). The ``at end`` clauses
    apply where a sub-environment terminated or was truncated.

    With ``episode ends when COND``: where a step's inputs satisfy COND, that sub-environment is
    reported ``terminated`` (its automaton applied the ``at end`` clauses in the step). When the
    sub-environment itself goes on, the wrapper ends its episode as NEXT_STEP would: on the next step,
    after the vector environment has stepped (that step of the old episode is discarded), it resets
    that sub-environment (``reset(options={"reset_mask": ...})``, gymnasium >= 1.1) and returns its
    reset observation with reward 0, ``terminated`` and ``truncated`` false. A vector environment other than
    gymnasium's ``SyncVectorEnv`` and ``AsyncVectorEnv`` and rac's ``ScenarioVectorEnv`` may ignore the mask and
    restart every sub-environment (gymnasium's ``CartPoleVectorEnv`` does): where another sub-environment's
    observation changes in such a reset (the wrapper's, or ``reset(options={"reset_mask": ...})``), ``RacValueError``
    (a vector environment class of your own that honours the mask says so with ``masked_resets = True``:
    :data:`MASKED_RESETS`).
    """

    def __init__(self, env: VectorEnv, automaton: str | os.PathLike[str] | ir.Automaton | RewardAutomaton,
                 inputs: InputFn, *, clip: bool = False, scale: Scale = None, dt: float | None = None) -> None:
        super().__init__(env)
        mode = env.metadata.get("autoreset_mode", AutoresetMode.NEXT_STEP)
        if mode not in (AutoresetMode.NEXT_STEP, AutoresetMode.NEXT_STEP.value):
            raise RacValueError(f"RewardAutomatonVectorWrapper supports the autoreset mode NEXT_STEP only, not "
                                f"{mode!r}: make the vector environment with autoreset_mode=AutoresetMode.NEXT_STEP")
        if any(isinstance(wrapper, gymnasium.wrappers.vector.DictInfoToList) for wrapper in wrapper_chain(env)):
            raise RacValueError(LISTED_INFOS.format(found="gymnasium's DictInfoToList sits inside it"))
        self._with_env = _takes_env(inputs, "(obs, infos) or (obs, infos, env)")
        program = automaton_ir(automaton)
        if program is None:
            raise TypeError("the vector wrapper batches the automaton's IR: pass a .ra path, an ir.Automaton or "
                            "a RewardAutomaton")
        self.automaton: BatchRewardAutomaton = RewardAutomaton(program).batch(self.num_envs)
        self._program = program
        self.inputs = inputs
        self._specs = _clipping(program, clip)
        #: The positive factor every reward is divided by (1.0 when unscaled).
        self.scale: float = scale_factor(program, scale)
        self._proven = scale == "proven"
        #: Per numeric input, how many values were clipped since the wrapper was made.
        self.clipped_total: dict[str, int] = {}
        self._resetting = np.zeros(self.num_envs, dtype=bool)
        self._last_inputs: dict[str, np.ndarray] = {}  # per input, each row's last step's (the next one's held)
        self._fresh = np.ones(self.num_envs, dtype=bool)  # rows whose next sample is their episode's first
        #: Sub-environments whose episode the automaton ended while they went on: reset on the next step.
        self._forced = np.zeros(self.num_envs, dtype=bool)
        self._timing = _Timing(self.automaton, dt, VECTOR_LIMIT)
        # another vector environment's masked resets are checked: the rows not selected must keep their observations
        self._checked_resets = not _honours_reset_mask(env)
        self._obs: Any = None  # the last observations, a copy, where masked resets are checked
        self._stand_in: object | None = None  # an AsyncVectorEnv's first sub-environment, made here for its timing
        self._timing.check(self._first_env())
        subs = getattr(self.env.unwrapped, "envs", None)  # a SyncVectorEnv's sub-environments
        # (an AsyncVectorEnv's live in its workers: its first one, made here, stands in for them)
        singles = subs or ([self._stand_in] if self._stand_in is not None else [])
        if _statistics_inside(env, gymnasium.wrappers.vector.RecordEpisodeStatistics) or any(
                _statistics_inside(single, gymnasium.wrappers.RecordEpisodeStatistics) for single in singles):
            warnings.warn(STATISTICS_INSIDE.format(outside="gymnasium.wrappers.vector.RecordEpisodeStatistics("
                                                           "RewardAutomatonVectorWrapper(envs, ...))"),
                          UserWarning, stacklevel=user_stacklevel())
        if subs:
            _replaces_reward_of(subs)
        elif hasattr(getattr(self._stand_in, "unwrapped", None), REPLACED):
            # an AsyncVectorEnv's live in its workers: told there when its first one (made here) has the attribute
            set_attr = getattr(self.env.unwrapped, "set_attr", None)
            if callable(set_attr):
                set_attr(REPLACED, True)
        self._past = _PastHorizon(self.automaton, scale == "proven", VECTOR_LIMIT)
        #: Says once that gymnasium's vector reward wrappers outside change every reward (found at a reset they call).
        self.changed_rewards = ChangedRewards()

    def _first_env(self) -> object:
        """The first sub-environment when the vector environment holds them (SyncVectorEnv), for its
        timing; for one whose sub-environments live in worker processes (AsyncVectorEnv), one made
        here from its first ``env_fns`` and closed, as AsyncVectorEnv itself reads the spaces (asking
        the workers for an attribute they lack breaks their pending-call state)."""
        envs = getattr(self.env.unwrapped, "envs", None)
        if envs:
            return envs[0]
        if self._stand_in is None:
            makers = getattr(self.env.unwrapped, "env_fns", None)
            if not makers:
                return self.env
            self._stand_in = makers[0]()
            close = getattr(self._stand_in, "close", None)
            if callable(close):
                close()
        return self._stand_in

    def _remember(self, obs: Any) -> None:
        """Keep a copy of the observations the vector environment returned, where its masked resets are checked."""
        if self._checked_resets:
            self._obs = copy.deepcopy(obs)

    def _check_kept(self, before: Any, after: Any, reset: np.ndarray, call: str) -> None:
        """Refuse a vector environment not known to honour ``reset_mask`` (:func:`_honours_reset_mask`) whose reset
        of the sub-environments ``reset`` changed another's observation: it restarted them all (``RacValueError``;
        gymnasium's ``CartPoleVectorEnv`` did so in silence, the automata going on over new episodes)."""
        if self._checked_resets and _rows_changed(before, after, ~reset):
            raise RacValueError(IGNORED_RESET_MASK.format(name=type(self.env.unwrapped).__name__, call=call))

    def _info(self, infos: dict[str, Any], extra: dict[str, Any]) -> dict[str, Any]:
        ra, n = self.automaton, self.num_envs
        infos = dict(infos)
        infos["rac"] = {"location": np.array(ra.location_names(), dtype=object), "rewards": ra.rewards,
                        "objective": ra.objective, "scale": np.full(n, self.scale), "proven": np.full(n, self._proven),
                        **extra}
        infos["_rac"] = np.ones(n, dtype=bool)
        return infos

    def reset(self, *, seed: int | None = None,
              options: dict[str, Any] | None = None) -> tuple[Any, dict[str, Any]]:
        """Reset every sub-environment and automaton, or with ``options["reset_mask"]`` (gymnasium >= 1.1)
        those the mask selects: the others go on, their automata untouched."""
        # read before the environment resets: gymnasium's SyncVectorEnv pops the mask out of the options
        mask = options.get("reset_mask") if options else None
        rows = np.ones(self.num_envs, dtype=bool) if mask is None else np.array(mask, dtype=bool).reshape(-1)
        if rows.shape != (self.num_envs,):
            raise ValueError(f"options['reset_mask'] must hold {self.num_envs} booleans, not {rows.shape}")
        obs, infos = self.env.reset(seed=seed, options=options)
        self.changed_rewards.check(self, VECTOR_REWARD_CHANGERS)
        if not isinstance(infos, Mapping):  # said before any automaton is reset
            raise RacValueError(LISTED_INFOS.format(found=f"the vector environment's reset gave {type(infos).__name__} "
                                                          "infos"))
        if mask is not None and self._obs is not None:
            self._check_kept(self._obs, obs, rows, "reset(options={'reset_mask': ...})")
        self._remember(obs)
        self._timing.check(self._first_env())
        self.automaton.reset(rows)
        self._fresh[rows] = True
        self._resetting[rows] = False
        self._forced[rows] = False
        return obs, self._info(infos, {})

    def step(self, actions: Any) -> tuple[Any, Any, Any, Any, dict[str, Any]]:
        """Step every sub-environment; the rewards are the automata's (0 on a sub-environment's reset step)."""
        obs, env_rewards, terminated, truncated, infos = self.env.step(actions)
        terminated, truncated = np.array(terminated, dtype=bool), np.array(truncated, dtype=bool)
        forced = self._forced
        if forced.any():  # the automaton ended these episodes, the environment did not: the reset step now
            stepped = copy.deepcopy(obs) if self._checked_resets else obs  # an env may reuse its arrays
            obs, reset_infos = self.env.reset(options={"reset_mask": forced.copy()})
            self._check_kept(stepped, obs, forced, "the reset the wrapper asks for to end the episodes its "
                                                   "automaton ended (`episode ends when`)")
            infos = merge_vector_info(infos, reset_infos, forced)  # their info is the reset info, as NEXT_STEP's
            terminated[forced] = truncated[forced] = False
            self._forced = np.zeros(self.num_envs, dtype=bool)
        resetting = self._resetting
        if resetting.any():
            self.automaton.reset(resetting)
            self._fresh[resetting] = True
        active = ~resetting
        clipped: dict[str, np.ndarray] = {}
        previous = self.automaton.rewards
        values: Mapping[str, object] = {}
        if active.any():
            try:
                values = self.inputs(obs, infos, self.env) if self._with_env else self.inputs(obs, infos)
            except Exception as exc:
                raise RacValueError(f"inputs(obs, infos) raised {type(exc).__name__}: {exc}; the environments have "
                                    "taken this step and the automata have not: reset before the next step") from exc
            try:
                if self._specs is not None:  # per sub-environment, counted by the clip rule itself; NaN refused
                    values, clipped = clip_rows(self._specs, values, self.num_envs, active)
                    for name, per_env in clipped.items():
                        self.clipped_total[name] = self.clipped_total.get(name, 0) + int(per_env.sum())
                rewards = self.automaton.step_batch(values, mask=active)
            except ValueError as exc:  # the inputs refused (the automata are unchanged): say where things stand
                raise _refused(exc, self._program, self._specs is not None, values, active,
                               "the environments have taken this step and the automata have not: reset before "
                               "the next step") from exc
        else:  # every sub-environment is in its reset step: nothing to read (their infos are reset infos)
            rewards = np.zeros(self.num_envs)
        self._past.check(self.automaton.samples)
        ended = self.automaton.terminated & active  # `episode ends when`: end clauses applied in this step
        self._forced = ended & ~terminated & ~truncated
        terminated = (terminated | ended) & active
        truncated = truncated & active
        done = terminated | truncated
        if (done & ~ended).any():
            rewards = rewards + self.automaton.end_batch(values, mask=done & ~ended)
        self._resetting = done
        now = self.automaton.rewards
        steps = {k: np.where(active, v - previous[k], 0.0) for k, v in now.items()}
        read = {name: np.broadcast_to(np.asarray(column), (self.num_envs,)).copy() for name, column in values.items()}
        # the rates of this sample read each row's previous one's inputs (its own at an episode's first)
        held = {name: np.where(self._fresh, column, self._last_inputs.get(name, column))
                for name, column in read.items()}
        for name, column in read.items():
            self._last_inputs[name] = np.where(active, column, self._last_inputs.get(name, column))
        self._fresh &= ~active
        self._remember(obs)
        infos = self._info(infos, {"env_reward": np.asarray(env_rewards, dtype=np.float64), "clipped": clipped,
                                   "reward_steps": steps, "_reward_steps": active.copy(),
                                   "inputs": read, "held": held, "_inputs": active.copy()})
        return obs, within_proven(rewards / self.scale, self._proven), terminated, truncated, infos
