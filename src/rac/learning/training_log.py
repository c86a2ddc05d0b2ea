"""What a deep-RL training loop records about the reward automaton, with no RL library needed.

:class:`TrainingLog` is fed the ``infos`` of each vector step — a list of per-env info dicts, as
stable-baselines3 hands them to callbacks, or one dict in gymnasium's vector layout, as
:class:`~rac.learning.vector.ScenarioVectorEnv` and gymnasium's vector envs return it
(:func:`rac.learning.vector_info.split_vector_info`), or a single environment's info dict — and
aggregates, until :meth:`TrainingLog.record`.
Under gymnasium's same-step autoreset a sub-environment whose episode ended reports its reset info,
and the info of the step that ended it under ``final_info``: that one is the step's, and is read.


- ``rac/reward/<name>``: each reward's mean change per step (``info["rac"]["reward_steps"]`` of the
  wrapper, ``info["reward_steps"]`` of ScenarioEnv);
- ``rac/location/<name>``: the share of steps that ended in each automaton location (both over the
  steps that report ``reward_steps``: a vector env's reset steps, whose info is a reset info, do not);
- ``rac/shield/<guarantee>``: the share of steps per shield guarantee (``info["shield"]`` of
  :class:`~rac.learning.scenario_env.ScenarioEnv`: ``"exhaustive"``, ``"lookahead d"``, ``"none"``),
  and ``rac/shield/no_safe_action``, the share of steps with ``info["no_safe_action"]``; both over
  the steps that report a shield (a vector env's reset steps, which chose from no mask, do not);
- ``rac/shield/outside_mask``: the share of those steps whose action the mask did not allow
  (``info["shield_allowed"]`` False: a learner that ignores the masks, plain PPO or DQN, where no
  guarantee covers the step; recorded once such a step happened);
- ``rac/shield/clock``: the share of those steps whose mask the runtime shield's time limit cut
  (``info["shield_clock"]``: it depended on the machine's speed and load, so the run at its seed may
  not repeat; recorded once such a step happened);
- ``rac/shield/timeout``: the share of those steps whose runtime shield ran out of its search budget
  (``info["shield_timeout"]``: the mask sound for its depth, but perhaps allowing fewer actions;
  recorded once such a step happened);
- ``rac/collisions``: steps with a collision (``info["collided"]`` in ScenarioEnv,
  ``info["crashed"]`` in highway-env), not counting the reset infos of a vector env's reset steps
  (rac's, which say so: no ``reward_steps``), whose flags are the new episode's start;
- ``rac/clipped/<input>``: values clipped (``info["rac"]["clipped"]``);
- ``rac/disallowed``: steps whose action the model's ``allow when`` forbids
  (``info["model_allowed"]`` False: a learner that ignores the masks).

A key once recorded is recorded at every later call (0 when nothing of it happened since), so a
CSV log has no blank cells for it.
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Iterable, Mapping
from typing import Any

from rac.learning.vector_info import is_vector_info, split_vector_info

__all__ = ["TrainingLog"]


class TrainingLog:
    """Aggregates the wrapper's and the scenario environment's infos between two :meth:`record` calls."""

    def __init__(self) -> None:
        self._clear()
        self._recorded: set[str] = set()  # every key recorded so far
        #: Steps added since construction (not cleared by :meth:`record`) whose info reported a step of a
        #: reward automaton or a shield: 0 after many steps means the infos are no rac environment's.
        self.reported = 0

    def _clear(self) -> None:
        self.steps = 0
        self._reward: dict[str, float] = {}
        self._location: Counter[str] = Counter()
        self._shield: Counter[str] = Counter()
        self._clipped: Counter[str] = Counter()
        self._no_safe = 0
        self._outside = 0  # shielded steps whose action the mask did not allow
        self._clock = 0  # shielded steps whose mask the runtime shield's time limit cut
        self._timeout = 0  # shielded steps whose runtime shield ran out of its budget
        self._shielded = 0  # steps that report a shield: the shield shares' denominator
        self._disallowed = 0
        self._collisions = 0
        self._rac_steps = 0

    def add(self, infos: Iterable[Mapping[str, Any]] | Mapping[str, Any]) -> None:
        """One vector step: the info dict of every sub-environment, or one dict in gymnasium's vector
        layout (:func:`rac.learning.vector_info.split_vector_info`); or one step of a single
        environment, its info dict."""
        if isinstance(infos, Mapping):
            # a single environment's info, read as a vector layout, was no environment's: nothing was logged
            infos = split_vector_info(infos) if is_vector_info(infos) or not infos else [infos]
        for info in infos:
            # gymnasium's SAME_STEP autoreset: the step's own info (its crash, its location, its reward
            # changes) is under final_info, beside the reset info of the next episode
            final = info.get("final_info")
            if isinstance(final, Mapping):
                info = final
            self.steps += 1
            # the wrapper's keys are under info["rac"]; ScenarioEnv's (the same names) in info itself
            rac = info.get("rac", info if "reward_steps" in info else None)
            # a step's info has reward_steps; a reset info (a vector env's reset step) has none: it is
            # no sample of the automaton, and counted it would dilute the means and the initial location
            self.reported += (isinstance(rac, Mapping) and "reward_steps" in rac) or "shield" in info
            if isinstance(rac, Mapping) and "reward_steps" in rac:
                self._rac_steps += 1
                for name, change in rac.get("reward_steps", {}).items():
                    self._reward[name] = self._reward.get(name, 0.0) + float(change)
                if "location" in rac:
                    self._location[str(rac["location"])] += 1
                for name, count in rac.get("clipped", {}).items():
                    self._clipped[name] += int(count)
            if "shield" in info:
                self._shielded += 1
                self._shield[str(info["shield"])] += 1
                self._no_safe += bool(info.get("no_safe_action", False))
                self._outside += not info.get("shield_allowed", True)
                self._clock += bool(info.get("shield_clock", False))
                self._timeout += bool(info.get("shield_timeout", False))
            self._disallowed += not info.get("model_allowed", True)
            if not _is_reset(info):  # a reset info's flags are the new episode's start, not a step's
                self._collisions += bool(info.get("collided", False) or info.get("crashed", False))

    def record(self) -> dict[str, float]:
        """The values to log since the last call (then cleared); ``{}`` when no step was added."""
        out = self.values()
        self._recorded.update(out)
        self._clear()
        return out

    def values(self) -> dict[str, float]:
        """What :meth:`record` would return now, without clearing (a running view of the window)."""
        if not self.steps:
            return {}
        out: dict[str, float] = {}
        if self._rac_steps:
            out.update({f"rac/reward/{k}": v / self._rac_steps for k, v in self._reward.items()})
            out.update({f"rac/location/{k}": v / self._rac_steps for k, v in self._location.items()})
            out.update({f"rac/clipped/{k}": float(v) for k, v in self._clipped.items()})
        if self._shielded:  # shares, as the guarantees' (a count would grow with the number of envs)
            out.update({f"rac/shield/{k}": v / self._shielded for k, v in self._shield.items()})
            out["rac/shield/no_safe_action"] = self._no_safe / self._shielded
            if self._outside:  # the shares above say what the masks offered, this how often they were ignored
                out["rac/shield/outside_mask"] = self._outside / self._shielded
            if self._clock:  # a run that may not repeat at its seed: said where the learner's numbers are
                out["rac/shield/clock"] = self._clock / self._shielded
            if self._timeout:  # masks cut short by the budget: sound, perhaps less permissive
                out["rac/shield/timeout"] = self._timeout / self._shielded
        out["rac/collisions"] = float(self._collisions)
        if self._disallowed:  # once recorded, a later call without any records 0 (below)
            out["rac/disallowed"] = float(self._disallowed)
        return {**dict.fromkeys(self._recorded, 0.0), **out}  # nothing of a known key since: 0, not a blank


def _is_reset(info: Mapping[str, Any]) -> bool:
    """Whether ``info`` is a reset info of rac's: the wrapper's ``info["rac"]`` or ScenarioEnv's info, a
    snapshot of the automaton (``location``, ``rewards``, ``objective``) without the ``reward_steps``
    every step adds. A vector env's autoreset step (NEXT_STEP's reset step, the vector wrapper's reset
    of an episode its automaton ended) hands it out: its ``collided`` is the start's (a start in a
    collision, W0724), which the episode's first step reports again: counted at both, one crash was two."""
    rac = info.get("rac")
    snapshot = rac if isinstance(rac, Mapping) else info
    # all three of the snapshot's keys: another environment's info may well have an "objective"
    return all(key in snapshot for key in ("location", "rewards", "objective")) and "reward_steps" not in snapshot
