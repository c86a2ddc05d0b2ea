"""The scenario model as a gymnasium vector environment: ``num_envs`` episodes of one
:class:`rac.learning.episodes.EpisodeBatch` stepped as one array operation.

:class:`ScenarioVectorEnv` is :class:`rac.learning.scenario_env.ScenarioEnv` ``num_envs`` times, with
the same constructor arguments, observations, rewards, ``info`` keys and action masks as a
:class:`gymnasium.vector.SyncVectorEnv` of ScenarioEnvs, but one numpy step for all of them instead
of one Python step each. Autoreset is gymnasium's next-step mode: the step after an episode ended
restarts it (:meth:`rac.learning.episodes.EpisodeBatch.reset_rows`) and returns its first
observation with reward 0, ``terminated`` and ``truncated`` False, and its reset ``info``::

    envs = ScenarioVectorEnv("examples/left_turn/model.ra", num_envs=64)
    obs, info = envs.reset(seed=0)                  # (64, dim) float32
    masks = envs.action_masks()                     # (64, P) bool, never an all-False row
    # gymnasium's MultiDiscrete.sample takes one int8 mask per episode (bool is refused)
    actions = envs.action_space.sample(mask=tuple(masks.astype(np.int8)))
    obs, reward, terminated, truncated, info = envs.step(actions)

:func:`make_vector_env` is the registered id's vector entry point (``gymnasium.make_vec("rac/Scenario-v0",
num_envs=N, model=...)``, :mod:`rac.gym`): this class, or a SyncVectorEnv of ScenarioEnvs where one
batch cannot hold the episodes (a set of scenes) or where frames are rendered.
"""

from __future__ import annotations

import os
import warnings
from collections import Counter
from collections.abc import Sequence
from fractions import Fraction
from pathlib import Path
from typing import TYPE_CHECKING, Any, Literal

import gymnasium
import numpy as np
from gymnasium.vector import AutoresetMode
from gymnasium.vector.utils import batch_space

from rac.compiler import CompileResult, compile_file
from rac.core.caller import user_stacklevel
from rac.core.diagnostics import RacValueError
from rac.core.numbers import seconds_at
from rac.ir import expr as ie
from rac.lang import ast
from rac.learning.scenario_env import (
    UNSHIELDED_MASKS,
    ScenarioEnv,
    clock_warning,
    no_safe_action_warning,
    outside_mask_warning,
    warn_file,
)
from rac.learning.wrappers import VECTOR_REWARD_CHANGERS, ChangedRewards, Scale, within_proven

if TYPE_CHECKING:
    from rac.engine.lookahead import LookaheadSettings
    from rac.engine.shield import ShieldStep, ShieldTable, StepShield

__all__ = ["ScenarioSyncVectorEnv", "ScenarioVectorEnv", "action_masks", "make_vector_env"]

#: The ``info`` keys a step adds to the reset ones: what the mask of the state the step left carried.
SHIELD_KEYS = ("shield", "shield_until", "shield_short", "shield_timeout", "shield_clock", "no_safe_action",
               "shield_allowed", "model_allowed")


class ScenarioVectorEnv(gymnasium.vector.VectorEnv):  # type: ignore[type-arg]
    """``num_envs`` episodes of the scenario model stepped together (see the module docstring).

    Args: those of :class:`rac.learning.scenario_env.ScenarioEnv` (``model``, ``shield``, ``lookahead``,
    ``reward``, ``horizon``, ``observation``, ``scale``; ``render_mode`` must be None: use
    :func:`make_vector_env` for frames) and ``num_envs``, the number of episodes.

    Spaces: ``single_observation_space`` and ``single_action_space`` (``Discrete(P)``) are one
    ScenarioEnv's; ``observation_space`` and ``action_space`` their batches (``(num_envs, dim)``,
    ``MultiDiscrete``). ``info`` is in gymnasium's vector layout, as SyncVectorEnv gathers it from
    the ScenarioEnvs: every key of ScenarioEnv's info holds an array over the episodes (``location``
    and ``shield``: object arrays of text; ``rewards`` and ``inputs``: dicts of arrays) with a mask
    ``_key`` of the episodes that report it — the shield's keys are missing for an episode that was
    restarted in this step (its info is the reset info). Counted since construction over all
    episodes, as ScenarioEnv counts: :attr:`shield_steps`, :attr:`no_safe_action_steps`, :attr:`timeout_steps`,
    :attr:`clock_steps`, :attr:`disallowed_steps`, :attr:`outside_mask_steps` (the first warned of).
    """

    metadata = {"autoreset_mode": AutoresetMode.NEXT_STEP, "render_modes": []}
    #: ``reset(options={"reset_mask": m})`` restarts the selected episodes alone (rac.learning.wrappers.MASKED_RESETS).
    masked_resets = True

    def __init__(self, model: str | os.PathLike[str] | CompileResult, *, num_envs: int = 1,
                 shield: str | os.PathLike[str] | ShieldTable | StepShield | None = None,
                 lookahead: LookaheadSettings | int | Literal["auto"] | None = "auto",
                 reward: str | ast.Expr | ie.Expr = "automaton", horizon: float | Fraction | None = None,
                 render_mode: str | None = None, observation: str = "relative", scale: Scale = None) -> None:
        if isinstance(num_envs, bool) or not isinstance(num_envs, (int, np.integer)) or num_envs < 1:
            raise ValueError(f"num_envs must be a positive integer, not {num_envs!r}")
        if render_mode is not None:
            raise ValueError(f"ScenarioVectorEnv renders nothing (render_mode={render_mode!r}): make_vector_env "
                             "(gymnasium.make_vec) returns a SyncVectorEnv of ScenarioEnvs for frames")
        # One ScenarioEnv owns the arguments' meaning (model, shield, horizon, reward, observation);
        # its batch, reset to num_envs episodes, is this environment's.
        self._single = ScenarioEnv(model, shield=shield, lookahead=lookahead, reward=reward, horizon=horizon,
                                   observation=observation, scale=scale)
        self.episodes = self._single.episodes
        scenario = self.episodes.result.scenario
        self._planning_problem = scenario.planning_problem_id if scenario is not None else None
        self.num_envs = int(num_envs)
        #: What the agent observes (:mod:`rac.learning.observation`), read over the whole batch.
        self.observation = self._single.observation
        self.single_observation_space = self._single.observation_space
        self.single_action_space = self._single.action_space
        self.observation_space = batch_space(self.single_observation_space, self.num_envs)
        self.action_space = batch_space(self.single_action_space, self.num_envs)
        self.metadata = {**self.metadata, "render_fps": self._single.metadata["render_fps"]}
        self.render_mode = None
        self._step_shield = self._single.step_shield
        self._said_unshielded = False  # action_masks() without a shield was warned of
        #: Says once that gymnasium's vector reward wrappers outside change every reward (found at a reset they call).
        self.changed_rewards = ChangedRewards()
        #: Steps per guarantee of their mask (``info["shield"]``), since construction, over all episodes.
        self.shield_steps: Counter[str] = Counter()
        #: Steps whose state had no action known to be safe (``info["no_safe_action"]``).
        self.no_safe_action_steps = 0
        #: Steps whose runtime shield ran out of its budget (``info["shield_timeout"]``).
        self.timeout_steps = 0
        #: Of those, steps whose search the time limit stopped (``info["shield_clock"]``).
        self.clock_steps = 0
        #: Steps that took an action the model's ``allow when`` forbids (``info["model_allowed"]`` False).
        self.disallowed_steps = 0
        #: Steps that took an action the mask of their state did not allow (``info["shield_allowed"]`` False).
        self.outside_mask_steps = 0
        self._period = Fraction(self.episodes.automaton.period)  # times as written (rac.core.numbers.seconds_at)
        self._names = np.array(self.episodes.automaton.location_names, dtype=object)
        n = self.num_envs
        self._autoreset = np.zeros(n, dtype=bool)  # ended in the last step: restarted in the next
        self._crashed = np.zeros(n, dtype=bool)  # under `collision sticky`: nothing after a collision is safe
        self._last = {name: np.zeros(n, dtype=bool) for name in ("collided", "offroad", "goal")}
        self._decisions: list[ShieldStep | None] = [None] * n
        self._start: tuple[bool, bool] | None = None  # collide(), offroad() at the start (the same for all)

    # ------------------------------------------------------------ what ScenarioEnv also offers
    @property
    def step_shield(self) -> StepShield | None:
        """The shield behind :meth:`action_masks` (None: the masks are the model's ``allow when``)."""
        return self._step_shield

    @property
    def action_pairs(self) -> np.ndarray:
        """``(P, 2)`` int32: action ``a`` is the (jerk, turn) significand pair ``action_pairs[a]``."""
        return self.episodes.action_pairs

    @property
    def dt(self) -> float:
        """Seconds per step of every episode (:attr:`ScenarioEnv.dt <rac.learning.scenario_env.ScenarioEnv.dt>`)."""
        return self._single.dt

    def _require(self) -> None:
        if self.episodes.n != self.num_envs:
            raise RuntimeError("call reset() first")

    def _decision(self, row: int) -> ShieldStep:
        """The shield's answer at episode ``row``'s state (once per state; a shield is required)."""
        decision = self._decisions[row]
        if decision is None:
            assert self._step_shield is not None
            state = self.episodes.state_keys(slice(row, row + 1))[0]
            decision = self._step_shield.decide(state, crashed=bool(self._crashed[row]))
            self._decisions[row] = decision
        return decision

    def action_masks(self) -> np.ndarray:
        """``(num_envs, P)`` bool: each episode's :meth:`ScenarioEnv.action_masks
        <rac.learning.scenario_env.ScenarioEnv.action_masks>` (the shield's mask, never an all-False
        row; the model's ``allow when`` without a shield). An episode that ended in the last step is
        restarted by the next whatever its action: its row allows every action."""
        self._require()
        masks = self.episodes.model_masks()
        masks[self._autoreset] = True
        if self._step_shield is None and not self._said_unshielded:  # as ScenarioEnv's
            self._said_unshielded = True
            warnings.warn(UNSHIELDED_MASKS, UserWarning, stacklevel=user_stacklevel())
        if self._step_shield is not None:
            for row in np.flatnonzero(~self._autoreset).tolist():
                masks[row] = self._decision(row).mask
        return masks

    #: What :meth:`get_attr` gives: the attributes every episode shares (the model's, the shield's).
    SHARED = ("action_pairs", "reward_scale", "shield", "step_shield", "observation_space", "action_space",
              "metadata", "render_mode", "scenarios", "observation", "dt")

    def call(self, name: str, *args: Any, **kwargs: Any) -> tuple[Any, ...]:
        """SyncVectorEnv's ``call``, for what a batch of episodes answers per episode: ``"action_masks"``
        (each episode's row of :meth:`action_masks`) and the shared attributes (:meth:`get_attr`; a
        callable one is called). ``AttributeError`` for anything else: there is no ScenarioEnv per
        episode here to ask."""
        if name == "action_masks":
            return tuple(self.action_masks())
        values = self.get_attr(name)
        return tuple(value(*args, **kwargs) if callable(value) else value for value in values)

    def get_attr(self, name: str) -> tuple[Any, ...]:
        """SyncVectorEnv's ``get_attr`` for the attributes every episode shares (:data:`SHARED`), one per
        episode; ``AttributeError`` for the others (an episode's own state is in ``info`` and the batch)."""
        if name not in self.SHARED:
            raise AttributeError(f"ScenarioVectorEnv steps its {self.num_envs} episodes as one batch: it has no "
                                 f"ScenarioEnv per episode to give `{name}`; per episode it gives "
                                 f"{', '.join(self.SHARED)} and call('action_masks'), and each step's info (a "
                                 "SyncVectorEnv of ScenarioEnvs: gymnasium.make_vec(..., vectorization_mode='sync'))")
        value = getattr(self._single, name)
        return tuple(value for _ in range(self.num_envs))

    def set_attr(self, name: str, values: Any) -> None:
        """Not supported: the episodes share one model and shield (``AttributeError``, saying so)."""
        raise AttributeError(f"ScenarioVectorEnv cannot set `{name}` per episode: its episodes share one model, "
                             "shield and batch (a SyncVectorEnv of ScenarioEnvs can: vectorization_mode='sync')")

    # ------------------------------------------------------------ stepping
    def reset(self, *, seed: int | Sequence[int | None] | None = None,
              options: dict[str, Any] | None = None) -> tuple[np.ndarray, dict[str, Any]]:
        """Start every episode at the ego's start (the seed only seeds ``np_random``: the model is
        deterministic). ``seed`` may also be SyncVectorEnv's list of ``num_envs`` seeds (None for
        unseeded): its first seeds ``np_random``, so ``seed=s`` and ``seed=[s, s + 1, ...]`` (what
        SyncVectorEnv makes of ``s``) agree.

        ``options["reset_mask"]`` (``num_envs`` booleans, gymnasium >= 1.1, after a first reset)
        restarts the episodes it selects only, as SyncVectorEnv does: the observation is every
        episode's, the info the restarted ones' (what
        :class:`~rac.learning.wrappers.RewardAutomatonVectorWrapper` asks for when its automaton's
        ``episode ends when`` ends an episode this environment goes on with)."""
        self.changed_rewards.check(self, VECTOR_REWARD_CHANGERS)  # NormalizeReward(make_vec(...)) in a loop
        mask = options.get("reset_mask") if options else None
        if isinstance(seed, Sequence):  # SyncVectorEnv's per-environment seeds: one np_random here
            if len(seed) != self.num_envs:
                raise ValueError(f"a list of seeds must hold num_envs={self.num_envs} seeds, not {len(seed)}")
            seed = seed[0]
        if mask is not None:
            return self._reset_rows(mask, seed)
        super().reset(seed=seed)
        episodes = self.episodes
        episodes.reset(self.num_envs)
        collided, offroad = episodes.observe([ie.call("collide"), ie.call("offroad")])[0] != 0
        self._start = (bool(collided), bool(offroad))
        everyone = np.ones(self.num_envs, dtype=bool)
        self._restarted(everyone)
        self._autoreset[:] = False
        return self.observation.observe(episodes), self._info(everyone, None)

    def _reset_rows(self, mask: Any, seed: int | None) -> tuple[np.ndarray, dict[str, Any]]:
        """Restart the episodes ``mask`` selects (``options["reset_mask"]``), the others untouched."""
        rows = np.asarray(mask)
        if rows.dtype != bool or rows.shape != (self.num_envs,):
            raise ValueError(f"options['reset_mask'] must be a bool array of shape ({self.num_envs},), not "
                             f"{rows.dtype} {rows.shape}")
        if self.episodes.n != self.num_envs:
            raise RuntimeError("options['reset_mask'] restarts some episodes of a running batch: call reset() first")
        if seed is not None:
            super().reset(seed=seed)
        self.episodes.reset_rows(np.flatnonzero(rows))
        self._restarted(rows)
        self._autoreset[rows] = False  # restarted now: the next step steps them
        return self.observation.observe(self.episodes), self._info(rows.copy(), None)

    def _restarted(self, rows: np.ndarray) -> None:
        """The flags of the episodes ``rows`` (a mask) just started."""
        assert self._start is not None
        collided, offroad = self._start
        self._last["collided"][rows] = collided
        self._last["offroad"][rows] = offroad
        self._last["goal"][rows] = False  # an episode ends at the goal only after a step
        self._crashed[rows] = collided
        for row in np.flatnonzero(rows).tolist():
            self._decisions[row] = None

    def step(self, actions: Any) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, dict[str, Any]]:
        """One decision period of every episode (``actions`` ``(num_envs,)``, indices into
        :attr:`action_pairs`); the episodes that ended in the last step are restarted instead."""
        self._require()
        episodes = self.episodes
        actions = np.asarray(actions)
        if actions.shape != (self.num_envs,) or not np.issubdtype(actions.dtype, np.integer):
            raise ValueError(f"actions must be an integer array of shape ({self.num_envs},), not "
                             f"{actions.dtype} {actions.shape}")
        stepping = ~self._autoreset
        chosen = actions[stepping]
        if chosen.size and (chosen.min() < 0 or chosen.max() >= episodes.n_actions):
            raise ValueError(f"actions must be in [0, {episodes.n_actions}), got {chosen.min()}..{chosen.max()}")
        shield = self._shield_info(stepping, actions)  # the masks of the states the step leaves
        before = episodes.rewards
        out = episodes.step(np.where(stepping, actions, 0))  # ended episodes are frozen: not moved
        restart = self._autoreset.copy()
        episodes.reset_rows(np.flatnonzero(restart))
        self._restarted(restart)
        for name, flags in (("collided", out.collided), ("offroad", out.offroad), ("goal", out.terminated)):
            self._last[name][stepping] = flags[stepping]
        self._crashed |= out.collided
        if self._step_shield is not None:
            for row in np.flatnonzero(stepping).tolist():
                self._decisions[row] = None
        terminated = out.terminated | out.ended  # the goal, or the automaton's `episode ends when`
        self._autoreset = terminated | out.truncated
        info = self._info(np.ones(self.num_envs, dtype=bool), shield)
        # each reward's change over the step, for the episodes that stepped (a restarted one reports its reset info)
        if stepping.any():
            after = episodes.rewards
            changes = {name: np.where(stepping, after[name] - before[name], 0.0) for name in after}
            info["reward_steps"] = {**changes, **{f"_{name}": stepping.copy() for name in changes}}
            info["_reward_steps"] = stepping.copy()
        rewards = within_proven(out.reward / self._single.reward_scale, self._single.reward_proven)
        return self.observation.observe(episodes), rewards, terminated, out.truncated.copy(), info

    def _shield_info(self, stepping: np.ndarray, actions: np.ndarray) -> dict[str, np.ndarray] | None:
        """The shield's ``info`` keys for the episodes ``stepping`` (a mask), as ScenarioEnv sets
        them, counted; None when no episode steps."""
        if not stepping.any():
            return None
        # stormpy (via rac.engine.shield): importing rac.learning.vector stays light
        from rac.engine.shield import UnseenState

        n = self.num_envs
        kind = np.full(n, None, dtype=object)
        kind[stepping] = "none"
        until = np.where(stepping, seconds_at(self.episodes.k, self._period), 0.0)
        flags = {name: np.zeros(n, dtype=bool) for name in SHIELD_KEYS[2:]}
        rows = np.flatnonzero(stepping)
        model = self.episodes.model_masks()
        flags["model_allowed"][rows] = model[rows, actions[rows]]
        flags["shield_allowed"][rows] = flags["model_allowed"][rows]  # no shield: the mask was the model's
        unseen: set[int] = set()  # rows whose table (unseen="error") has no entry for their state
        if self._step_shield is not None:
            for row in rows.tolist():
                try:
                    decision = self._decision(row)
                except UnseenState:  # unseen="error" raises from action_masks(); the step itself goes on
                    flags["no_safe_action"][row] = True
                    unseen.add(row)
                    continue
                kind[row] = decision.guarantee
                until[row] = seconds_at(int(decision.until), self._period)
                flags["shield_short"][row] = decision.short
                flags["shield_timeout"][row] = decision.timed_out
                flags["shield_clock"][row] = decision.clock
                flags["no_safe_action"][row] = decision.no_safe_action
                flags["shield_allowed"][row] = bool(decision.mask[int(actions[row])])
        self.shield_steps.update(kind[stepping].tolist())
        lapsed = flags["no_safe_action"]
        if lapsed.any() and not self.no_safe_action_steps:  # as ScenarioEnv: an all-True mask says nothing else
            first = int(np.flatnonzero(lapsed)[0])
            warnings.warn(no_safe_action_warning(None if first in unseen else self._step_shield,
                                                 self.episodes.state_keys()[first], bool(self._crashed[first]),
                                                 bool(flags["shield_timeout"][first]),
                                                 lambda k: float(seconds_at(k, self._period))),
                          UserWarning, stacklevel=user_stacklevel())
        self.no_safe_action_steps += int(lapsed.sum())
        self.timeout_steps += int(flags["shield_timeout"].sum())
        clocked = int(flags["shield_clock"].sum())
        if clocked and not self.clock_steps:  # never silently: the node budget promises reproducible runs
            first = int(np.flatnonzero(flags["shield_clock"])[0])
            time = float(seconds_at(int(self.episodes.k[first]), self._period))
            warnings.warn(clock_warning(self._step_shield, time), RuntimeWarning, stacklevel=user_stacklevel())
        self.clock_steps += clocked
        self.disallowed_steps += int((stepping & ~flags["model_allowed"]).sum())
        outside = stepping & ~flags["shield_allowed"]
        if outside.any() and not self.outside_mask_steps:  # as ScenarioEnv: the info key alone goes unread
            first = int(np.flatnonzero(outside)[0])
            time = float(seconds_at(int(self.episodes.k[first]), self._period))
            warnings.warn(outside_mask_warning(int(actions[first]), time, str(kind[first])), UserWarning,
                          stacklevel=user_stacklevel())
        self.outside_mask_steps += int(outside.sum())
        info: dict[str, np.ndarray] = {"shield": kind, "shield_until": until, **flags}
        return {**info, **{f"_{key}": stepping.copy() for key in info}}

    def _info(self, rows: np.ndarray, shield: dict[str, np.ndarray] | None) -> dict[str, Any]:
        """ScenarioEnv's ``info`` of every episode in the vector layout (``rows``: the mask every
        key but the shield's carries)."""
        episodes = self.episodes

        def masked(values: dict[str, Any]) -> dict[str, Any]:
            return {**values, **{f"_{key}": rows.copy() for key in values}}

        inputs = {name: values if values.dtype == bool else values.astype(np.float64)
                  for name, values in episodes.inputs.items()}
        info = masked({"location": self._names[episodes.location],
                       "objective": np.asarray(episodes.objective, dtype=np.float64).copy(),
                       **{name: flags.copy() for name, flags in self._last.items()},
                       "time": seconds_at(episodes.k, self._period),
                       "scenario": np.full(self.num_envs, str(self._single.scenarios[0]), dtype=object),
                       "planning_problem": np.full(self.num_envs, self._planning_problem),  # as SyncVectorEnv stacks it
                       "scale": np.full(self.num_envs, self._single.reward_scale),
                       "proven": np.full(self.num_envs, self._single.reward_proven)})
        info.update(masked({"rewards": masked(episodes.rewards), "inputs": masked(inputs)}))
        if shield is not None:
            info.update(shield)
        return info


#: Why :func:`action_masks` finds none, and where masks come from.
#: What :func:`action_masks` says when an environment's process ended while answering (stable-baselines3's
#: ``SubprocVecEnv``: its worker ends on any exception of ``env_method``, which rac cannot prevent; ``{kind}``: the
#: VecEnv's class).
WORKER_ENDED = ("a process of the {kind} ended while answering action_masks(): its environment raised an error, "
                "printed on standard error above (stable-baselines3's SubprocVecEnv ends a process on any error of "
                "env_method); most often the environments were not reset yet: call reset() on the vector environment "
                "before action_masks(). The {kind} cannot be used further: close it and make another")
NO_MASKS = ("the environments have no action_masks(): the masks are those of rac's scenario environments "
            "(ScenarioEnv, rac/Scenario-v0: the safety shield's); another environment, RewardAutomatonWrapper's "
            "included, needs masks of its own (sb3-contrib's ActionMasker)")


def action_masks(envs: gymnasium.vector.VectorEnv) -> np.ndarray:  # type: ignore[type-arg]
    """``(num_envs, P)`` bool: the action masks of a vector environment of rac's scenario model, through
    any vector wrappers around it (gymnasium's ``RecordEpisodeStatistics``, rac's
    :class:`~rac.learning.wrappers.RewardAutomatonVectorWrapper`, ...).

    gymnasium's vector wrappers have no ``action_masks``, ``call`` or ``get_attr`` (1.4): those are
    the unwrapped environment's, so ``envs.call("action_masks")`` fails on a wrapped one. This asks
    ``envs.unwrapped``: :meth:`ScenarioVectorEnv.action_masks` and
    :meth:`ScenarioSyncVectorEnv.action_masks` (every action allowed for an episode awaiting its
    restart), else a ``SyncVectorEnv`` or ``AsyncVectorEnv``'s ``call("action_masks")`` of its
    ScenarioEnvs, or a stable-baselines3 ``VecEnv``'s ``env_method("action_masks")`` (also under
    ``VecNormalize`` and SB3's other vector wrappers: their ``unwrapped`` is the ``VecEnv``), asked
    ``has_attr("action_masks")`` first (``AttributeError`` when an environment has none)."""
    base = envs.unwrapped
    own = getattr(base, "action_masks", None)
    if callable(own):
        return np.asarray(own(), dtype=bool)
    call = getattr(base, "call", None)
    if not callable(call):
        # stable-baselines3's VecEnv (DummyVecEnv, SubprocVecEnv, under VecNormalize, ...): its env_method, which
        # resolves the name through each environment's wrappers, as sb3-contrib's get_action_masks does
        call = getattr(base, "env_method", None)
        has_attr = getattr(base, "has_attr", None)
        # asked first: a SubprocVecEnv's process asked env_method for a method its environment lacks ends, and the
        # parent gets EOFError, saying nothing
        if callable(has_attr) and not has_attr("action_masks"):
            raise AttributeError(NO_MASKS)
    if not callable(call):
        raise AttributeError(f"{type(base).__name__} has neither action_masks(), call() nor env_method(): not a "
                             "vector environment of ScenarioEnvs")
    try:
        masks = call("action_masks")
    except AttributeError as exc:  # gymnasium's: "wrapper TimeLimit has no attribute 'action_masks'"
        raise AttributeError(f"{NO_MASKS} ({exc})") from exc
    except (EOFError, ConnectionError) as exc:
        # SubprocVecEnv's process ends on any exception of the method it runs (ScenarioEnv's "call reset() before
        # action_masks()" most often) and prints it; the parent gets a bare EOFError, which says nothing
        raise RuntimeError(f"{WORKER_ENDED.format(kind=type(base).__name__)} ({type(exc).__name__})") from exc
    return np.stack([np.asarray(mask, dtype=bool) for mask in masks])


def make_vector_env(num_envs: int = 1, **kwargs: Any) -> gymnasium.vector.VectorEnv:  # type: ignore[type-arg]
    """The vector entry point of ``rac/Scenario-v0`` (``gymnasium.make_vec``): a
    :class:`ScenarioVectorEnv` of ``num_envs`` episodes, with ``kwargs`` those of
    :class:`rac.learning.scenario_env.ScenarioEnv`.

    Two cases get a :class:`ScenarioSyncVectorEnv` (a :class:`gymnasium.vector.SyncVectorEnv` of
    ScenarioEnvs) instead — the same autoreset, spaces, info, ``action_masks()`` and counters; one
    Python step per episode: a set of scenes (``scenarios=``, which ScenarioEnv
    draws from per episode: one EpisodeBatch holds one scene) and a ``render_mode`` (each ScenarioEnv
    renders its own frames). The model is compiled once for all of them.

    ``max_episode_steps`` (which ``gymnasium.make_vec`` hands to a vector entry point) is refused,
    naming the ``horizon`` that gives episodes of that many steps: a step limit outside the
    episodes would cut them where their ``at end`` clauses cannot apply. ``autoreset_mode`` may be
    ``NEXT_STEP`` only, what both environments do (another mode is refused, naming the
    SyncVectorEnv of ScenarioEnvs that takes it)."""
    steps = kwargs.pop("max_episode_steps", None)
    if steps is not None:
        raise RacValueError(_step_limit_refused(steps, kwargs.get("model")))
    mode = kwargs.pop("autoreset_mode", AutoresetMode.NEXT_STEP)
    if mode not in (AutoresetMode.NEXT_STEP, AutoresetMode.NEXT_STEP.value):
        # ScenarioSyncVectorEnv's masks assume NEXT_STEP: a restarted episode's row allows every action
        raise RacValueError(f"rac/Scenario-v0's vector environment restarts an ended episode in the next step "
                            f"(AutoresetMode.NEXT_STEP), not {mode!r}; for another mode make gymnasium's own "
                            "SyncVectorEnv of ScenarioEnvs: gymnasium.make_vec(..., vectorization_mode='sync', "
                            "vector_kwargs={'autoreset_mode': ...}), masks through "
                            "rac.learning.vector.action_masks(envs)")
    if kwargs.get("scenarios") is None and kwargs.get("render_mode") is None:
        kwargs.pop("scenarios", None)
        return ScenarioVectorEnv(num_envs=num_envs, **kwargs)
    model = kwargs.pop("model")
    # with a set, ScenarioEnv needs the file (its model block is the template) and shares each scene's check
    if isinstance(model, (str, os.PathLike)) and kwargs.get("scenarios") is None:

        model = compile_file(Path(model))  # ScenarioEnv reports its errors
        if model.ok:
            warn_file(model, frozenset({"W0728"}))  # once, as ScenarioEnv given the path would

    def single() -> gymnasium.Env:  # type: ignore[type-arg]
        return ScenarioEnv(model, **kwargs)

    return ScenarioSyncVectorEnv([single for _ in range(num_envs)])


def _step_limit_refused(steps: object, model: object) -> str:
    """Why ``max_episode_steps=steps`` is refused, with the ``horizon`` in seconds that gives
    episodes of ``steps`` decisions when ``model`` is a checked model or a readable file."""
    if isinstance(model, (str, os.PathLike)) and Path(model).is_file():
        model = compile_file(Path(model))
    spec = model.automaton.model if isinstance(model, CompileResult) and model.automaton is not None else None
    advice = "give horizon=<seconds> (a whole number of decision periods)"
    if spec is not None and isinstance(steps, int) and not isinstance(steps, bool) and steps > 0:
        period = Fraction(spec.decide_period)
        advice = f"give horizon={float(steps * period):g} ({steps} decisions of {float(period):g} s)"
    return (f"rac/Scenario-v0 truncates its episodes at its own horizon, where it applies the `at end` clauses; "
            f"max_episode_steps={steps!r} would cut them outside the environment, without them: {advice}")


class ScenarioSyncVectorEnv(gymnasium.vector.SyncVectorEnv):  # type: ignore[misc]
    """The SyncVectorEnv of ScenarioEnvs :func:`make_vector_env` returns for a set of scenes or a
    ``render_mode``, with :class:`ScenarioVectorEnv`'s ``action_masks()`` and counters, so that one
    training loop serves both."""

    def action_masks(self) -> np.ndarray:
        """``(num_envs, P)`` bool: each ScenarioEnv's mask; all True for an episode waiting for its
        restart (the next step restarts it whatever its action), as :meth:`ScenarioVectorEnv.action_masks`."""
        width: int = self.envs[0].unwrapped.action_pairs.shape[0]  # type: ignore[attr-defined]
        masks = np.ones((self.num_envs, width), dtype=bool)
        for row, env in enumerate(self.envs):
            if not self._autoreset_envs[row]:
                masks[row] = env.unwrapped.action_masks()  # type: ignore[attr-defined]
        return masks

    def _total(self, name: str) -> Any:
        return sum((getattr(env.unwrapped, name) for env in self.envs[1:]), start=getattr(self.envs[0].unwrapped, name))

    @property
    def shield_steps(self) -> Counter[str]:
        """Steps per guarantee of their mask, over all episodes (:attr:`ScenarioVectorEnv.shield_steps`)."""
        return Counter(self._total("shield_steps"))

    @property
    def no_safe_action_steps(self) -> int:
        """Steps whose state had no action known to be safe, over all episodes."""
        return int(self._total("no_safe_action_steps"))

    @property
    def timeout_steps(self) -> int:
        """Steps whose runtime shield ran out of its budget, over all episodes."""
        return int(self._total("timeout_steps"))

    @property
    def clock_steps(self) -> int:
        """Steps whose runtime shield's search its time limit stopped, over all episodes."""
        return int(self._total("clock_steps"))

    @property
    def disallowed_steps(self) -> int:
        """Steps that took an action the model's ``allow when`` forbids, over all episodes."""
        return int(self._total("disallowed_steps"))

    @property
    def outside_mask_steps(self) -> int:
        """Steps that took an action the mask of their state did not allow, over all episodes."""
        return int(self._total("outside_mask_steps"))
