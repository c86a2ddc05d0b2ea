"""Counterfactual transitions for a deep learner's replay buffer, from rac's wrappers' infos.

One vector step of ``n`` environments, each a :class:`~rac.learning.wrappers.RewardAutomatonWrapper`
under :class:`~rac.learning.location_observation.LocationObservation` (``"concat"`` layout), as an
off-policy algorithm stores it (stable-baselines3's ``ReplayBuffer.add``: observations ``(n, D)``,
one info dict per environment; or gymnasium's vector layout, one dict of arrays, as ``SyncVectorEnv``,
``AsyncVectorEnv`` and :class:`~rac.learning.wrappers.RewardAutomatonVectorWrapper` give it):
:class:`CounterfactualRows` gives the ``L - 1`` other batches of ``n`` transitions, one per location
the automaton was not in — the same environment transitions, with the observation's location, the
reward and the next location the automaton would have had (:mod:`rac.learning.counterfactual`).
:class:`rac.learning.sb3.CounterfactualReplayBuffer` stores them beside the real ones.

Exact when the observation shows the automaton only through its location, as for
:mod:`rac.learning.counterfactual`: the episode's end does not depend on the automaton's location
(``episode ends when`` reads the inputs only, so it ends the episode from every location alike, its
``at end`` clauses in the step).
"""

from __future__ import annotations

import os
import warnings
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from rac import ir
from rac.core.caller import user_stacklevel
from rac.learning.counterfactual import Replayer, counterfactual_transitions
from rac.learning.location_observation import one_hot_index, replace_one_hot
from rac.learning.vector_info import is_vector_info, split_vector_info
from rac.learning.wrappers import AutomatonLike, automaton_ir, within_proven

__all__ = ["CounterfactualRows", "CounterfactualStep", "scenario_infos_refused"]

#: The keys of ``info["rac"]`` a counterfactual replay reads (RewardAutomatonWrapper's step info).
NEEDED = ("inputs", "held", "rewards", "reward_steps", "scale", "location")


@dataclass(frozen=True, eq=False)
class CounterfactualStep:
    """``m`` counterfactual transitions (one per environment that took a step) from locations the
    automaton was not in: ``obs`` and ``next_obs`` (``(m, D)``, the location columns replaced), the
    ``reward`` (``(m,)``, scaled as the wrapper scales; under ``scale="proven"`` within [-1, 1], as the real
    rewards: :meth:`CounterfactualRows.step`), the ``location`` and ``next_location``
    indices, and the environments they are of (``source``, indices into the step's batch: all ``n``,
    except the sub-environments a gymnasium vector environment restarted in this step, whose
    ``obs`` -> ``next_obs`` is no transition: in its layout, or in the list ``DictInfoToList`` makes of it)."""

    obs: np.ndarray
    next_obs: np.ndarray
    reward: np.ndarray
    location: np.ndarray
    next_location: np.ndarray
    source: np.ndarray


def _column(racs: Sequence[Mapping[str, Any]], key: str) -> dict[str, np.ndarray]:
    """The per-environment values of the mapping ``info["rac"][key]`` as one array per name."""
    return {name: np.array([rac[key][name] for rac in racs]) for name in racs[0][key]}


def scenario_infos_refused(what: str) -> str:
    """Why counterfactual transitions are refused for rac's scenario environments, ``what`` naming the infos
    (:class:`CounterfactualRows` at a step; :class:`rac.learning.sb3.RacCallback` at the start of ``learn()``)."""
    return (f"{what} carries the automaton's location at its top level, as rac's scenario environments (ScenarioEnv, "
            "ScenarioVectorEnv) do: their step is several samples of the automaton, which counterfactual transitions "
            "from one info do not replay (rac.learning.episodes.EpisodeBatch.counterfactual replays them); these need "
            "each environment wrapped in rac.learning.wrappers.RewardAutomatonWrapper")


class CounterfactualRows:
    """Builds the counterfactual transitions of vector steps (see the module docstring).

    Args:
        automaton: the automaton the wrappers run (a ``.ra`` path, an :class:`rac.ir.Automaton`, or a
            runtime from :func:`rac.load`); its location order is the one-hot vector's.
    """

    def __init__(self, automaton: str | os.PathLike[str] | ir.Automaton | AutomatonLike) -> None:
        program = automaton_ir(automaton)
        if program is None:  # a generated class's instance: no IR to replay
            raise TypeError(f"automaton must be a .ra path, an ir.Automaton or a RewardAutomaton, not {automaton!r}")
        self._replayer = Replayer(program)
        #: The location names, index ``i`` the one-hot column ``i``.
        self.locations: tuple[str, ...] = program.location_names
        self._index = {name: i for i, name in enumerate(self.locations)}
        self._warned_beyond = False  # rows clamped to scale='proven''s [-1, 1] were warned of

    def _infos(self, infos: Sequence[Mapping[str, Any]] | Mapping[str, Any],
               n: int) -> tuple[list[Mapping[str, Any]], np.ndarray]:
        """Each stepping environment's ``info["rac"]``, and which environments step (see :meth:`step`)."""
        stepping = np.arange(n)
        if isinstance(infos, Mapping):  # gymnasium's vector layout: split per sub-environment
            infos, stepping = _split(infos, n)
        elif len(infos) != n:
            raise ValueError(f"infos must hold one dict per environment ({n}), not {len(infos)}")
        else:  # a list: stable-baselines3's (every environment steps), or gymnasium's through DictInfoToList
            stepping = np.flatnonzero([not _restarted(info) for info in infos]).astype(np.int64)
            infos = [infos[i] for i in stepping.tolist()]
        found: list[Mapping[str, Any]] = []
        for i, info in zip(stepping.tolist(), infos):
            rac = info.get("rac") if isinstance(info, Mapping) else None
            if rac is None and isinstance(info, Mapping) and "location" in info:
                raise ValueError(scenario_infos_refused(f"infos[{i}]"))
            missing = [key for key in NEEDED if not isinstance(rac, Mapping) or key not in rac]
            if missing or not isinstance(rac, Mapping):
                raise ValueError(f"infos[{i}] has no info['rac'][{missing[0]!r}]: counterfactual transitions need "
                                 "the step info of rac.learning.wrappers.RewardAutomatonWrapper (inputs, held, "
                                 "rewards, reward_steps, scale, location), around each environment")
            found.append(rac)
        return found, stepping

    def _after(self, racs: Sequence[Mapping[str, Any]]) -> np.ndarray:
        """The location indices after the step, as the wrappers' infos report them."""
        unknown = sorted({str(rac["location"]) for rac in racs} - set(self._index))
        if unknown:  # the wrappers run another automaton than the one given here
            raise ValueError(f"info['rac']['location'] is {unknown[0]!r}, which this automaton does not have (its "
                             f"locations: {', '.join(self.locations)}): pass the automaton the wrappers run")
        return np.array([self._index[str(rac["location"])] for rac in racs], dtype=np.int64)

    def terminal_located(self, next_obs: np.ndarray, done: np.ndarray,
                         infos: Sequence[Mapping[str, Any]] | Mapping[str, Any]) -> np.ndarray:
        """``next_obs`` (``(n, D)``) with the location columns of each row whose episode ended (``done``) and
        whose columns are not a one-hot vector set from ``info["rac"]["location"]`` (a copy; ``next_obs`` as
        it is when no row needs it). stable-baselines3 stores an ended episode's terminal observation as
        ``VecNormalize`` normalised it, unnormalised again: inexact, and clipped (a location seen rarely so
        far, such as the one a crash ends in, comes back as 0.3 or 0.001, not 1); the location itself is
        known exactly from the info. Every other row is left for :meth:`step` to check; so are the rows of
        sub-environments a gymnasium vector environment restarted in the step (``infos`` in its layout)."""
        next_obs = np.asarray(next_obs)
        if next_obs.ndim != 2:
            return next_obs  # not a batch of observations: step() says what is wrong
        racs, source = self._infos(infos, int(next_obs.shape[0]))
        ended = np.asarray(done, dtype=bool).reshape(-1)
        if ended.shape != next_obs.shape[:1]:
            return next_obs
        stepping = next_obs[source]
        fixed = self._located(stepping, ended[source], self._after(racs))
        if fixed is stepping:
            return next_obs
        whole = np.array(next_obs)
        whole[source] = fixed
        return whole

    def _located(self, next_obs: np.ndarray, ended: np.ndarray, after: np.ndarray) -> np.ndarray:
        """:meth:`terminal_located` on the stepping rows, ``after`` their locations after the step."""
        count = len(self.locations)
        if next_obs.shape[1] <= count:
            return next_obs
        hot = next_obs[:, -count:]
        broken = ended & ~(np.isin(hot, (0, 1)).all(axis=1) & (hot.sum(axis=1) == 1))
        if not broken.any():
            return next_obs
        fixed = np.array(next_obs)
        rows = np.flatnonzero(broken)
        fixed[rows] = replace_one_hot(fixed[rows], after[rows], count)
        return fixed

    def step(self, obs: np.ndarray, next_obs: np.ndarray, done: np.ndarray,
             infos: Sequence[Mapping[str, Any]] | Mapping[str, Any]) -> list[CounterfactualStep]:
        """The ``L - 1`` batches of counterfactual transitions of one vector step: ``obs`` before and
        ``next_obs`` after it (``(n, D)``, the location's one-hot vector in the last ``L`` columns),
        ``done`` where the episode ended (the ``at end`` clauses apply), ``infos`` the wrappers' step
        infos: one dict per environment (stable-baselines3's ``VecEnv``), or gymnasium's vector layout
        (one dict of arrays; gymnasium's default ``NEXT_STEP`` autoreset: a sub-environment restarted
        in this step took no step, and its rows are left out, :attr:`CounterfactualStep.source`; so are they
        from the list gymnasium's ``DictInfoToList`` makes of that dict, their infos reset infos). Batch
        ``k`` starts each environment ``k`` locations after the one it was in. Under ``scale="proven"``
        (``info["rac"]["proven"]``) the rows' rewards lie within [-1, 1] as the real ones do; a row from a location
        no run reaches, which the proven bound does not cover, is clamped to it (warned once)."""
        obs, next_obs = np.asarray(obs), np.asarray(next_obs)
        if obs.ndim != 2 or next_obs.shape != obs.shape:  # one environment's (D,) was read as D environments
            raise ValueError(f"obs and next_obs must be batches (n environments, D columns) of the same shape, not "
                             f"{obs.shape} and {next_obs.shape}: one environment's observation is obs[None, :]")
        count = len(self.locations)
        racs, source = self._infos(infos, int(obs.shape[0]))
        done = np.asarray(done, dtype=bool).reshape(int(obs.shape[0]))[source]
        obs, next_obs = obs[source], next_obs[source]
        n = int(source.size)
        if n == 0:  # every sub-environment restarted: no transition
            empty = np.zeros(0, dtype=np.int64)
            return [CounterfactualStep(obs, next_obs, np.zeros(0), empty, empty, source) for _ in range(1, count)]
        real = one_hot_index(obs, count)
        after = self._after(racs)
        next_obs = self._located(next_obs, done, after)  # VecNormalize's terminal observations
        try:
            shown = one_hot_index(next_obs, count)
        except ValueError as exc:  # obs was one-hot, and an ended episode's next_obs is mended above
            raise ValueError(f"{exc}: in next_obs of an episode going on, while obs's are") from None
        if not np.array_equal(shown, after):
            raise ValueError("next_obs's location columns differ from info['rac']['location']: the observation's "
                             "one-hot vector is not this automaton's (another automaton, or another location order)")
        inputs = _column(racs, "inputs")
        prior = {name: np.array([float(rac["rewards"][name]) - float(rac["reward_steps"][name]) for rac in racs])
                 for name in racs[0]["rewards"]}
        scale = np.array([float(rac["scale"]) for rac in racs])
        proven = np.array([bool(rac.get("proven", False)) for rac in racs])
        held = _column(racs, "held")
        cf = counterfactual_transitions(self._replayer, inputs, rewards=prior, held=held,
                                        ended=done)
        rows = np.arange(n)
        batches = []
        for k in range(1, count):
            location = (real + k) % count
            pick = rows * count + location
            next_location = cf.next_location[pick]
            batches.append(CounterfactualStep(replace_one_hot(obs, location, count),
                                              replace_one_hot(next_obs, next_location, count),
                                              self._scaled(cf.reward[pick] / scale, proven, location),
                                              location, next_location, source))
        return batches

    def _scaled(self, reward: np.ndarray, proven: np.ndarray, location: np.ndarray) -> np.ndarray:
        """The counterfactual rows' rewards divided by the wrappers' scale (``reward``), kept within [-1, 1] where
        that scale is ``scale="proven"`` (``proven``, per row), as the wrapper keeps the real rewards: a rounding
        past the bound put back (:func:`rac.learning.wrappers.within_proven`), and a reward further out clamped,
        which only a row from a location no run reaches can give (the bound is proved over the locations runs
        reach, rac check's W0302 names the others): warned once, naming the ``location``."""
        if not proven.any():
            return reward
        kept = np.where(proven, within_proven(reward, True), reward)
        beyond = proven & (np.abs(kept) > 1.0)
        if beyond.any():
            if not self._warned_beyond:  # once per builder: every step from that location gives such rows
                self._warned_beyond = True
                first = int(np.flatnonzero(beyond)[0])
                warnings.warn(
                    f"counterfactual rows from location `{self.locations[int(location[first])]}` got a reward of "
                    f"{float(kept[first]):g} under scale='proven', past its bound: the bound is proved over the "
                    "locations a run reaches, and no run reaches this one (rac check warns of it, W0302), so these "
                    "rows' rewards are clamped to [-1, 1], which the priority proofs do not cover either; said once",
                    UserWarning, stacklevel=user_stacklevel())
            kept = np.where(beyond, np.clip(kept, -1.0, 1.0), kept)
        return kept


#: The ``info["rac"]`` keys only a step gives (a reset's snapshot has location, rewards, objective, scale;
#: RewardAutomatonVectorWrapper's reset rows carry its unmasked columns, held among them, too).
STEP_ONLY = ("inputs", "reward_steps")
#: The ``info["rac"]`` keys of every reset's snapshot.
SNAPSHOT = ("location", "rewards", "objective")


def _split(infos: Mapping[str, Any], n: int) -> tuple[list[Mapping[str, Any]], np.ndarray]:
    """The per-environment infos of gymnasium's vector layout, without the sub-environments it restarted
    in this step (their ``info["rac"]`` is the reset's snapshot), and which environments remain."""
    if "final_obs" in infos or "final_info" in infos:  # SAME_STEP: next_obs is the next episode's first
        raise ValueError("infos come from a vector environment with gymnasium's SAME_STEP autoreset: where an episode "
                         "ended, next_obs is the next episode's first observation (the last is in info['final_obs']), "
                         "so obs -> next_obs is no transition there; use the default NEXT_STEP autoreset")
    if not is_vector_info(infos):  # its length is its number of keys: "not 4 dicts" said nothing useful
        raise ValueError("infos is one environment's info dict, not in gymnasium's vector layout (arrays with _key "
                         "masks): pass a list of one info dict per environment (as stable-baselines3's VecEnv gives "
                         "them) or a gymnasium vector environment's info, each environment a RewardAutomatonWrapper")
    split = split_vector_info(infos, n)
    stepping = np.flatnonzero(~np.array([_restarted(info) for info in split], dtype=bool).reshape(n))
    return [split[i] for i in stepping.tolist()], stepping


def _restarted(info: object) -> bool:
    """Whether ``info`` is the reset info of a sub-environment a gymnasium vector environment restarted in this
    step (its ``info["rac"]`` the reset's snapshot, without :data:`STEP_ONLY`'s keys): no transition. A list of
    infos has one where gymnasium's ``DictInfoToList`` made it from the vector layout; stable-baselines3's never
    does (its environments restart within the step that ended them)."""
    rac = info.get("rac") if isinstance(info, Mapping) else None
    return isinstance(rac, Mapping) and all(key in rac for key in SNAPSHOT) and not any(key in rac for key in STEP_ONLY)
