"""stable-baselines3 helpers: a callback logging the reward automaton (:class:`RacCallback`) and a
replay buffer storing counterfactual transitions (:class:`CounterfactualReplayBuffer`).

stable-baselines3 is an optional dependency (``pip install 'rac[rl]'``); this module needs it,
:mod:`rac.learning.training_log` (what is recorded) does not.
"""

from __future__ import annotations

import warnings
from fractions import Fraction
from typing import Any

import numpy as np
from gymnasium.wrappers import ClipReward, FrameStackObservation, NormalizeReward, TransformReward

try:
    from stable_baselines3.common.buffers import ReplayBuffer
    from stable_baselines3.common.callbacks import BaseCallback
    from stable_baselines3.common.logger import HumanOutputFormat, Logger
    from stable_baselines3.common.off_policy_algorithm import OffPolicyAlgorithm
    from stable_baselines3.common.vec_env import DummyVecEnv, VecFrameStack, VecNormalize
    from stable_baselines3.her.her_replay_buffer import HerReplayBuffer
except ImportError as exc:  # pragma: no cover - depends on the environment
    raise ImportError("rac.learning.sb3 needs stable-baselines3: pip install 'rac[rl]'") from exc

from rac import ir
from rac.core.caller import user_stacklevel
from rac.learning.location_observation import LocationObservation, one_hot_index
from rac.learning.replay import CounterfactualRows, scenario_infos_refused
from rac.learning.scenario_env import ScenarioEnv
from rac.learning.training_log import TrainingLog
from rac.learning.wrappers import (
    NO_RELABELLING,
    REWARD_CHANGED,
    REWARD_CHANGERS,
    RewardAutomatonWrapper,
    wrapper_chain,
)

__all__ = ["CounterfactualReplayBuffer", "RacCallback", "discount_warnings", "frame_stacker", "proof_subjects",
           "reward_changers", "reward_normaliser", "scenario_environments", "text_table_clashes"]


class RacCallback(BaseCallback):
    """Records :class:`~rac.learning.training_log.TrainingLog`'s values with ``self.logger.record``
    (``rac/reward/<name>``, ``rac/location/<name>``, ``rac/shield/...``, ``rac/collisions``) over
    the steps since SB3's logger last wrote its table: the values so far are recorded at every
    rollout's end for an on-policy algorithm (PPO, A2C, MaskablePPO: its table follows a rollout,
    every ``log_interval`` rollouts), at every step for an off-policy one (DQN, SAC, ...: its table
    is written at an episode's end, within a rollout of a few steps). Needs stable-baselines3 (an
    optional dependency: ``pip install 'rac[rl]'``). Warns, once, when the training environment is
    under ``VecNormalize(norm_reward=True)`` (:func:`reward_normaliser`) or gymnasium's ``NormalizeReward``,
    ``ClipReward`` or ``TransformReward`` around the automaton's reward (:func:`reward_changers`): the learner's
    reward is then no longer the automaton's; and when a :class:`CounterfactualReplayBuffer` is filled under
    ``VecFrameStack`` or gymnasium's ``FrameStackObservation`` outside ``LocationObservation``
    (:func:`frame_stacker`): its rows are then inexact; and when the algorithm's ``gamma`` is below 1 and
    the priority order fails (or cannot be checked) for the return discounted by it
    (:func:`discount_warnings`: rac check's proofs are of the plain return). Refuses (``NotImplementedError``,
    at the start of ``learn()``) stable-baselines3's ``HerReplayBuffer`` on environments in
    ``RewardAutomatonWrapper``, whose ``compute_reward`` is refused: the buffer would first ask for it after
    ``learning_starts`` steps; and refuses (``ValueError``, at the start of ``learn()``) a
    :class:`CounterfactualReplayBuffer` on rac's scenario environments (:func:`scenario_environments`) or on
    observations whose location is not a one-hot vector (gymnasium's ``NormalizeObservation`` outside
    ``LocationObservation``), which the buffer itself refuses only when it is first given a step.

    Example::

        model = PPO("MlpPolicy", RewardAutomatonWrapper(env, "follow.ra", inputs, scale="proven"))
        model.learn(10_000, callback=RacCallback())
    """

    def __init__(self, verbose: int = 0) -> None:
        super().__init__(verbose)
        self.log = TrainingLog()
        self._per_step = False  # an off-policy algorithm: record the values at every step
        self._logged: dict[str, float] = {}  # what the logger was last given, until it writes them out
        self._handed = 0  # steps whose infos the algorithm handed over (self.locals["infos"])
        self._warned = False  # the reward normaliser's warning, said once
        self._warned_changers = False  # the warning of gymnasium's reward wrappers, said once
        self._warned_unseen = False  # the warning that no automaton was seen, said once
        self._warned_discount = False  # the discounted P2 check, made and said once
        self._warned_clashes: set[str] = set()  # keys left out of the text table, each said once

    def _init_callback(self) -> None:
        self._per_step = isinstance(self.model, OffPolicyAlgorithm)
        if isinstance(getattr(self.model, "replay_buffer", None), CounterfactualReplayBuffer) and \
                scenario_environments(self.training_env):
            # the buffer sees no environment, only its first step's infos: said before the first step is taken
            raise ValueError(scenario_infos_refused("each step's info of the training environment")
                             + " (said at the start of learn(): CounterfactualReplayBuffer sees the infos only when "
                             "it is given the first step)")
        counterfactual = getattr(self.model, "replay_buffer", None)
        if isinstance(counterfactual, CounterfactualReplayBuffer):
            _check_located(self.model, counterfactual)
        if isinstance(getattr(self.model, "replay_buffer", None), HerReplayBuffer) and _relabels_with_automaton(
                self.training_env):
            # the wrapper refuses compute_reward, but HerReplayBuffer first asks for it when it samples, after
            # learning_starts steps and a complete episode: said before any step is taken
            raise NotImplementedError(f"{NO_RELABELLING} (said at the start of learn(): HerReplayBuffer asks for "
                                      "it only when it first samples, after learning_starts steps)")
        normaliser = reward_normaliser(self.training_env)
        if normaliser is not None and not self._warned:  # learn() called again: said once
            self._warned = True
            warnings.warn(
                f"VecNormalize(norm_reward=True, clip_reward={normaliser.clip_reward:g}) divides every reward by a "
                "running estimate of the returns' spread, which changes as training goes on, and clips it: the "
                "learner's reward is no longer the automaton's up to one positive factor, so the priority proofs "
                "of rac check (no penalty compensated by lower objectives' gains) do not cover what it learns "
                "from, and a large penalty may count for less than a few steps' gains; scale the automaton's reward "
                "with scale='proven' (every reward in [-1, 1], the proofs intact) and use "
                "VecNormalize(norm_reward=False)", UserWarning, stacklevel=user_stacklevel())
        changers = reward_changers(self.training_env)
        if changers and not self._warned_changers:  # learn() called again: said once
            self._warned_changers = True
            if not _changers_said(self.training_env):  # the environments said it at learn()'s reset
                warnings.warn(REWARD_CHANGED.format(names=", ".join(changers)), UserWarning,
                              stacklevel=user_stacklevel())
        gamma = getattr(self.model, "gamma", None)
        # np.floating too: a numpy float32 gamma (np.float32(0.99)) is no float, and was never checked
        if not self._warned_discount and isinstance(gamma, (float, np.floating)) and 0 < gamma < 1:
            self._warned_discount = True  # learn() called again: said once
            for message in discount_warnings(self.training_env, gamma, type(self.model).__name__):
                warnings.warn(message, UserWarning, stacklevel=user_stacklevel())
        buffer = getattr(self.model, "replay_buffer", None)
        stacking = frame_stacker(self.training_env)
        if isinstance(buffer, CounterfactualReplayBuffer) and stacking is not None:
            if not buffer.warned_stacked:  # learn() called again, or several callbacks: said once
                buffer.warned_stacked = True
                warnings.warn(
                    f"CounterfactualReplayBuffer under {stacking}: each counterfactual row replaces the location of "
                    "the newest frame only, the earlier frames still show the real locations, so the rows are no "
                    "transitions the environment could have produced; stack no frames, or use the plain ReplayBuffer",
                    UserWarning, stacklevel=user_stacklevel())

    def _on_step(self) -> bool:
        # The logger's table is written when the algorithm says (A2C: every 100 rollouts; DQN: at an
        # episode's end, within a rollout): recording each rollout alone, the table showed the last few
        # steps (the collisions before them lost). The window runs until a dump has written it out (a
        # dump clears the logger's values).
        if any(self.logger.name_to_value.get(key) != value for key, value in self._logged.items()):
            self.log.record()  # written out: what follows is the next window's
            self._logged = {}
        infos = self.locals.get("infos")
        if infos is not None:
            self._handed += 1
            self.log.add(infos)
        if self._per_step:
            self._write()
        return True

    def _on_rollout_end(self) -> None:
        if not self._per_step:  # an on-policy table follows a rollout (an evaluation's may come within one)
            self._write()
        self._check_seen()

    def _check_seen(self) -> None:
        """Warn once when a rollout has ended and nothing of a reward automaton was seen: the log then held
        ``rac/collisions`` alone (0, whatever happened), or nothing at all, without saying why."""
        if self._warned_unseen or self.log.reported:
            return
        self._warned_unseen = True
        algorithm = type(self.model).__name__
        if not self._handed:
            warnings.warn(f"RacCallback: {algorithm} hands its callbacks no step infos (sb3-contrib's ARS evaluates "
                          "its candidates with evaluate_policy, without them), so nothing of the reward automaton "
                          "is logged; rac.learning.training_log.TrainingLog logs it from a loop of your own",
                          UserWarning, stacklevel=user_stacklevel())
        else:
            warnings.warn(f"RacCallback: the infos of {self.log.steps} step(s) of {algorithm} carry no reward "
                          "automaton (info['rac'] of rac.learning.wrappers.RewardAutomatonWrapper, or ScenarioEnv's "
                          "reward_steps and shield): only rac/collisions (info['collided'] or info['crashed']) is "
                          "logged; wrap each environment in RewardAutomatonWrapper (or train on ScenarioEnv), with "
                          "no wrapper between that drops the info", UserWarning, stacklevel=user_stacklevel())

    def _write(self) -> None:
        self._logged = self.log.values()
        # SB3's text table cuts keys to its width and raises ValueError when two cut keys are the same (two
        # long location names sharing a prefix): such keys go to the other outputs only, said once
        clashing = text_table_clashes(self.logger, self._logged)
        if clashing - self._warned_clashes:
            self._warned_clashes |= clashing
            warnings.warn(
                f"RacCallback: stable-baselines3's text table (stdout, log) cuts its keys to "
                f"{_text_width(self.logger)} characters, which makes {', '.join(sorted(clashing))} the same key "
                "there (its dump would raise ValueError and end training): they are left out of that table and "
                "written in full to the logger's other outputs (csv, tensorboard); shorter location or reward "
                "names in the .ra file put them in the table", UserWarning, stacklevel=user_stacklevel())
        for key, value in self._logged.items():
            self.logger.record(key, value, exclude=("stdout", "log") if key in clashing else None)


def _check_located(model: Any, buffer: CounterfactualReplayBuffer) -> None:
    """Refuse (``ValueError``) where the observations ``model`` will first store in ``buffer`` do not end in the
    location's one-hot vector, as the buffer's first step would (gymnasium's ``NormalizeObservation`` outside
    ``LocationObservation`` normalises it): the same test on the observations of the reset stable-baselines3 made
    before the callback started, the ones it stores as the first step's ``obs`` (``VecNormalize``'s unnormalised)."""
    normaliser = model.get_vec_normalize_env()
    first = normaliser.get_original_obs() if normaliser is not None else getattr(model, "_last_obs", None)
    if not isinstance(first, np.ndarray) or first.ndim != 2:  # nothing reset yet, or no batch: the buffer says
        return
    try:
        one_hot_index(first, len(buffer.rows.locations))
    except ValueError as exc:
        # the buffer sees the observations only when it is given the first step: said before it is taken
        raise ValueError(f"{exc} (said at the start of learn(): CounterfactualReplayBuffer sees the observations "
                         "only when it is given the first step)") from None


def _text_width(logger: Logger) -> int | None:
    """The narrowest key width of the text outputs (stdout, log) of stable-baselines3's ``logger``, or None."""
    widths = [output.max_length for output in logger.output_formats if isinstance(output, HumanOutputFormat)]
    return min(widths, default=None)


def text_table_clashes(logger: Logger, keys: Any) -> set[str]:
    """The ``keys`` that stable-baselines3's text table (``HumanOutputFormat``, stdout and log) would cut to
    the same shown key as another of them: it shows a key's part after its tag (``rac/``), indented three
    spaces, cut to ``max_length`` characters (36 by default) ending in ``...``, and raises ``ValueError`` in
    ``dump`` when two keys come out the same."""
    width = _text_width(logger)
    if width is None:
        return set()
    shown: dict[tuple[str, str], list[str]] = {}
    for key in keys:
        tag = key[: key.find("/") + 1] if key.find("/") > 0 else ""
        name = f"{'':3}{key[len(tag):]}" if tag else key
        if len(name) > width:  # as HumanOutputFormat._truncate cuts it
            name = name[: width - 3] + "..."
        shown.setdefault((tag, name), []).append(key)
    return {key for same in shown.values() if len(same) > 1 for key in same}


def reward_normaliser(venv: Any) -> VecNormalize | None:
    """The ``VecNormalize`` with ``norm_reward=True`` in stable-baselines3's chain of vector wrappers
    ``venv`` (each one's ``venv`` the next), or None."""
    found = _wrapper(venv, VecNormalize)
    return found if isinstance(found, VecNormalize) and found.norm_reward else None


def _changers_said(venv: Any) -> bool:
    """Whether an environment of ``venv`` has said, at a reset, that gymnasium's reward wrappers outside it change
    its rewards (:class:`~rac.learning.wrappers.ChangedRewards`): a ``DummyVecEnv``'s environments are walked,
    another vector environment's (``SubprocVecEnv``: said in the workers, whose warnings show on the same
    terminal) are asked with a :class:`_Probe`."""
    base = _wrapper(venv, DummyVecEnv)
    if isinstance(base, DummyVecEnv):
        return any(_said_changers(inner) for env in base.envs for inner in wrapper_chain(env))
    try:  # any of stable-baselines3's VecEnvs answers env_is_wrapped; anything else is no such environment
        return any(venv.env_is_wrapped(_SaidChangers))
    except (AttributeError, TypeError):
        return False


def _said_changers(env: object) -> bool:
    """Whether ``env`` (one layer) has said that reward wrappers outside it change its rewards."""
    return getattr(getattr(env, "changed_rewards", None), "warned", False) is True


def reward_changers(venv: Any) -> list[str]:
    """The names of gymnasium's reward wrappers (:data:`REWARD_CHANGERS`) that change the reward automaton's
    reward on its way to the learner in some environment of stable-baselines3's vector environment ``venv``:
    outside :class:`~rac.learning.wrappers.RewardAutomatonWrapper` or :class:`~rac.learning.scenario_env.ScenarioEnv`
    (one inside the automaton's wrapper changes a reward that the automaton's replaces; one in an environment without
    an automaton changes no automaton's reward). The environments of a ``DummyVecEnv`` are walked; another vector
    environment's (``SubprocVecEnv``: in other processes) are asked where they are, with :class:`_Probe`s: there a
    changer is named by the gymnasium class it derives from, and one between two automaton wrappers counts too (a
    probe sees a wrapper and what lies below it, not what lies above)."""
    base = _wrapper(venv, DummyVecEnv)
    if isinstance(base, DummyVecEnv):
        found: set[str] = set()
        for first in base.envs:
            above: list[str] = []  # the changers met before the automaton (none counts without one)
            for env in wrapper_chain(first):
                if isinstance(env, _AUTOMATA):
                    found.update(above)
                    break
                if isinstance(env, REWARD_CHANGERS):
                    above.append(type(env).__name__)
        return sorted(found)
    try:  # any of stable-baselines3's VecEnvs answers env_is_wrapped; anything else is no such environment
        return sorted(probe.kind.__name__ for probe in _AROUND_AUTOMATON if any(venv.env_is_wrapped(probe)))
    except (AttributeError, TypeError):
        return []


def _wraps_before(env: Any, found: type, stop: type) -> bool:
    """Whether ``env``'s chain of wrappers, walked from the outside in, meets a ``found`` before any ``stop``."""
    for layer in wrapper_chain(env):
        if isinstance(layer, stop):
            return False
        if isinstance(layer, found):
            return True
    return False


def frame_stacker(venv: Any) -> str | None:
    """What stacks the location's frames in stable-baselines3's vector environment ``venv``: ``"VecFrameStack"``
    in its chain of vector wrappers, ``"FrameStackObservation"`` where gymnasium's sits outside a
    :class:`~rac.learning.location_observation.LocationObservation` (or in an environment without one) in an
    environment of ``venv`` (inside it, the frames are stacked before the location is added, once), or None. The
    environments of a ``DummyVecEnv`` are walked; another vector environment's (``SubprocVecEnv``: in other
    processes) are asked where they are, with :class:`_Probe`s (there, one between two ``LocationObservation``
    counts too)."""
    if _wrapper(venv, VecFrameStack) is not None:
        return "VecFrameStack"
    base = _wrapper(venv, DummyVecEnv)
    if isinstance(base, DummyVecEnv):
        stacks = any(_wraps_before(env, FrameStackObservation, LocationObservation) for env in base.envs)
        return "FrameStackObservation" if stacks else None
    try:  # any of stable-baselines3's VecEnvs answers env_is_wrapped; anything else is no such environment
        located = venv.env_is_wrapped(LocationObservation)
        around = venv.env_is_wrapped(_StacksAroundLocation)
        stacked = venv.env_is_wrapped(FrameStackObservation)
    except (AttributeError, TypeError):
        return None
    # with a LocationObservation, a stack counts around it; without one, anywhere (as the walk above)
    if any(a if loc else s for loc, a, s in zip(located, around, stacked, strict=True)):
        return "FrameStackObservation"
    return None


def proof_subjects(venv: Any) -> list[tuple[ir.Automaton, int]]:
    """The automata whose rewards the environments of stable-baselines3's vector environment ``venv``
    hand out, each with the samples one step spans (``proof_subject`` of
    :class:`~rac.learning.wrappers.RewardAutomatonWrapper` and
    :class:`~rac.learning.scenario_env.ScenarioEnv`), each once; empty when none is known. Only the environments
    that have one are asked for it: ``SubprocVecEnv``'s process for an environment without one ends on the
    ``AttributeError`` (stable-baselines3's worker lets it through), and training with it. Where some have one and
    some not, those in other processes are told apart with a :class:`_Probe`, which sees wrapped environments
    only (an unwrapped environment's automaton is then not found)."""
    return _distinct(_subjects_found(venv))


def _distinct(found: list[tuple[ir.Automaton, int] | None]) -> list[tuple[ir.Automaton, int]]:
    """The subjects of ``found`` (:func:`_subjects_found`), each once, without the Nones."""
    subjects: list[tuple[ir.Automaton, int]] = []
    for subject in found:
        if subject is not None and not any(subject[1] == n and (subject[0] is a or subject[0] == a)
                                           for a, n in subjects):
            subjects.append(subject)
    return subjects


def _subjects_found(venv: Any) -> list[tuple[ir.Automaton, int] | None]:
    """The ``proof_subject`` of every environment of ``venv`` that has one (:func:`proof_subjects`), None where
    its automaton has no checked form (an instance of a generated class in ``RewardAutomatonWrapper``)."""
    try:
        # has_attr first: SubprocVecEnv's get_attr of an attribute an environment lacks kills its worker (an
        # AttributeError there, EOFError here); a VecEnv without has_attr (older stable-baselines3) is asked
        # get_attr alone
        has_attr = getattr(venv, "has_attr", None)
        if has_attr is None or has_attr("proof_subject"):
            found = venv.get_attr("proof_subject")
        else:
            held = venv.env_is_wrapped(_HasProofSubject)
            indices = [i for i, has in enumerate(held) if has]
            found = venv.get_attr("proof_subject", indices) if indices else []
    except (AttributeError, TypeError):  # no VecEnv of SB3's
        return []
    return list(found)


def discount_warnings(venv: Any, gamma: float | np.floating[Any], algorithm: str = "the learner") -> list[str]:
    """What :class:`RacCallback` warns of, once, when its algorithm discounts (``gamma < 1``): for each
    automaton of :func:`proof_subjects`, P2 of the return discounted by ``gamma`` per step checked
    (:func:`rac.check.analysis.discount.check_discounted`), and where it fails or is not checked, why; and that
    it is not checked where a wrapper runs an instance of a generated class (no checked automaton to check)."""
    from rac.check.analysis.discount import Discount, check_discounted  # numpy and the analyses: only when asked

    text = str(gamma)  # as written, to the last digit (`:g` made 0.9999999 "1", another return to check)
    exact = Fraction(text)  # 0.99 as written: 99/100
    messages = []
    found = _subjects_found(venv)  # once: a SubprocVecEnv's environments are asked across their pipes
    if any(subject is None for subject in found):  # a generated class: nothing to check it on
        messages.append(
            f"RacCallback: {algorithm} maximises the return discounted by gamma={text} per step, and whether the "
            "priority order holds for that return is not checked where RewardAutomatonWrapper runs an instance of "
            "a generated class (rac compile --target python), which carries no checked automaton; rac check proves "
            f"the order of the plain return only; `rac check --discount {text} FILE` checks it, or give the wrapper "
            "rac.load(FILE), which RacCallback checks")
    for automaton, samples in _distinct(found):
        for said in check_discounted(automaton, Discount(exact, samples)):
            option = f" --samples-per-step {samples}" if samples > 1 else ""
            # a check not made (W0405) has no run to show: the command says why instead
            what, shows = ("fails", "shows the run") if said.is_error else ("is not checked", "says why")
            hint = f"; {said.hints[0]}" if said.hints else ""
            messages.append(
                f"RacCallback: {algorithm} maximises the return discounted by gamma={text} per step, and the "
                f"priority order of `{automaton.name}` {what} for that return: {said.message}; rac check proves "
                f"the order of the plain return only; `rac check --discount {text}{option} FILE` {shows}{hint}")
    return messages


def scenario_environments(venv: Any) -> bool:
    """Whether an environment of stable-baselines3's vector environment ``venv`` is one of rac's scenario
    environments (:class:`~rac.learning.scenario_env.ScenarioEnv`, ``rac/Scenario-v0``) with no
    :class:`~rac.learning.wrappers.RewardAutomatonWrapper` above it: its step infos carry the automaton's location at
    their top level, and :class:`CounterfactualReplayBuffer` refuses them. A ``DummyVecEnv``'s environments are
    walked; another vector environment's (``SubprocVecEnv``) are asked with :class:`_Probe`s, which see wrapped
    environments only (an unwrapped one, not even in ``make_vec_env``'s ``Monitor``, is then refused at its first
    step, by the buffer)."""
    base = _wrapper(venv, DummyVecEnv)
    if isinstance(base, DummyVecEnv):
        return any(_wraps_before(env, ScenarioEnv, RewardAutomatonWrapper) for env in base.envs)
    try:  # any of stable-baselines3's VecEnvs answers env_is_wrapped; anything else is no such environment
        scenario = venv.env_is_wrapped(_AroundScenario)
        relabelled = venv.env_is_wrapped(_AutomatonAroundScenario)
    except (AttributeError, TypeError):
        return False
    return any(s and not r for s, r in zip(scenario, relabelled, strict=True))


def _relabels_with_automaton(venv: Any) -> bool:
    """Whether ``HerReplayBuffer`` would ask :class:`~rac.learning.wrappers.RewardAutomatonWrapper` for
    ``compute_reward`` in stable-baselines3's vector environment ``venv``: a ``DummyVecEnv``'s environments resolve it
    as ``env_method`` does (``get_wrapper_attr``: a wrapper outside rac's may answer it itself); another vector
    environment's (``SubprocVecEnv``: in other processes) are asked with :class:`_Probe`s whether they hold rac's
    wrapper with no wrapper above it answering ``compute_reward`` (one between two of rac's wrappers is taken to
    answer it: ``HerReplayBuffer`` then meets the refusal when it first samples)."""
    base = _wrapper(venv, DummyVecEnv)
    if isinstance(base, DummyVecEnv):
        for env in base.envs:
            try:
                method = env.get_wrapper_attr("compute_reward")
            except AttributeError:
                continue
            if isinstance(getattr(method, "__self__", None), RewardAutomatonWrapper):
                return True
        return False
    try:
        wrapped = venv.env_is_wrapped(RewardAutomatonWrapper)
        answered = venv.env_is_wrapped(_AnswersRelabelling)
    except (AttributeError, TypeError):  # no VecEnv of stable-baselines3's
        return False
    return any(w and not a for w, a in zip(wrapped, answered, strict=True))


def _below(env: object, kind: type | tuple[type, ...]) -> bool:
    """Whether an environment ``env`` wraps (not ``env`` itself) is a ``kind``."""
    return any(isinstance(inner, kind) for inner in wrapper_chain(getattr(env, "env", None)))


#: The environments whose rewards are a reward automaton's.
_AUTOMATA = (RewardAutomatonWrapper, ScenarioEnv)


class _Probe(type):
    """The metaclass of the questions :func:`reward_changers`, :func:`frame_stacker`, :func:`proof_subjects` and
    :func:`_relabels_with_automaton` put to environments in other processes (``SubprocVecEnv``), which cannot be
    walked from here: stable-baselines3's ``env_is_wrapped(probe)`` sends the probe (a class: pickled by its name,
    so each is a class of this module) to where each environment lives and asks ``isinstance(wrapper, probe)``
    of each of its wrappers, from the outermost in; the probe's ``holds(wrapper)`` answers, and only the answer
    comes back. A wrapper sees the environments below it, not the ones above: the questions are put that way."""

    def __instancecheck__(cls, env: object) -> bool:
        return bool(cls.holds(env))

    def holds(cls, env: object) -> bool:
        """Whether the wrapper ``env`` is what the probe asks for (each probe's own classmethod answers)."""
        return False


class _AroundAutomaton(metaclass=_Probe):
    """A wrapper of the gymnasium reward wrapper ``kind`` (the first of :data:`REWARD_CHANGERS` it is one of:
    ``ClipReward`` is a ``TransformReward``) with a reward automaton below it."""

    kind: type = object

    @classmethod
    def holds(cls, env: object) -> bool:
        kind = next((kind for kind in REWARD_CHANGERS if isinstance(env, kind)), None)
        return kind is cls.kind and _below(env, _AUTOMATA)


class _NormalizeRewardAround(_AroundAutomaton):
    kind = NormalizeReward


class _ClipRewardAround(_AroundAutomaton):
    kind = ClipReward


class _TransformRewardAround(_AroundAutomaton):
    kind = TransformReward


#: One probe per reward changer, as :func:`reward_changers` asks them.
_AROUND_AUTOMATON = (_NormalizeRewardAround, _ClipRewardAround, _TransformRewardAround)


class _SaidChangers(metaclass=_Probe):
    """A wrapper with an environment of rac's on it or below it that has said reward wrappers outside it change
    its rewards (the worker's warning, which :class:`RacCallback` does not repeat)."""

    @classmethod
    def holds(cls, env: object) -> bool:
        return any(_said_changers(inner) for inner in wrapper_chain(env))


class _StacksAroundLocation(metaclass=_Probe):
    """A gymnasium ``FrameStackObservation`` with a ``LocationObservation`` below it."""

    @classmethod
    def holds(cls, env: object) -> bool:
        return isinstance(env, FrameStackObservation) and _below(env, LocationObservation)


class _AnswersRelabelling(metaclass=_Probe):
    """A wrapper other than rac's with a ``compute_reward`` of its own (as ``get_wrapper_attr`` finds it) and
    rac's wrapper below it: ``HerReplayBuffer`` asks it, not rac's."""

    @classmethod
    def holds(cls, env: object) -> bool:
        return (not isinstance(env, RewardAutomatonWrapper) and hasattr(env, "compute_reward")
                and _below(env, RewardAutomatonWrapper))


class _AroundScenario(metaclass=_Probe):
    """A wrapper with a :class:`~rac.learning.scenario_env.ScenarioEnv` below it."""

    @classmethod
    def holds(cls, env: object) -> bool:
        return _below(env, ScenarioEnv)


class _AutomatonAroundScenario(metaclass=_Probe):
    """rac's :class:`~rac.learning.wrappers.RewardAutomatonWrapper` with a ScenarioEnv below it (its infos are the
    wrapper's)."""

    @classmethod
    def holds(cls, env: object) -> bool:
        return isinstance(env, RewardAutomatonWrapper) and _below(env, ScenarioEnv)


class _HasProofSubject(metaclass=_Probe):
    """A wrapper with ``proof_subject`` on it or below it, as ``get_wrapper_attr`` finds it."""

    @classmethod
    def holds(cls, env: object) -> bool:
        return any(hasattr(inner, "proof_subject") for inner in wrapper_chain(env))


def _wrapper(venv: Any, kind: type) -> Any:
    """The outermost ``kind`` in stable-baselines3's chain of vector wrappers ``venv``, or None."""
    for _ in range(100):  # a wrapper chain, not a cycle
        if venv is None or isinstance(venv, kind):
            return venv
        venv = getattr(venv, "venv", None)
    return None


class CounterfactualReplayBuffer(ReplayBuffer):
    """A ``ReplayBuffer`` that stores, beside each real transition, its counterfactual ones: the same
    environment transition from every other location of the reward automaton
    (:class:`rac.learning.replay.CounterfactualRows`; Toro Icarte et al.'s CRM). For an off-policy
    algorithm (DQN, SAC, ...) on environments wrapped ``LocationObservation(RewardAutomatonWrapper(env,
    automaton, inputs))`` (the ``"concat"`` layout): pass the same automaton in
    ``replay_buffer_kwargs``. Each step fills ``L`` rows per environment (``L`` locations), so the
    buffer holds ``buffer_size / L`` steps' worth of real transitions. Only the last ``L`` columns
    are replaced: under ``VecFrameStack`` the earlier frames would show the real locations (the
    buffer cannot see the vector wrappers; :class:`RacCallback` warns of it). Under ``VecNormalize`` an
    ended episode's terminal observation comes back inexact and clipped: its location is taken from the
    info (:meth:`~rac.learning.replay.CounterfactualRows.terminal_located`). rac's scenario environments
    (``ScenarioEnv``, ``rac/Scenario-v0``) are refused, and so are observations whose location columns are no
    one-hot vector (gymnasium's ``NormalizeObservation`` outside ``LocationObservation``; ``VecNormalize`` is fine,
    stable-baselines3 gives the buffer the unnormalised observations): :class:`RacCallback` says so at the start of
    ``learn()``, the buffer itself at the first step it is given (it sees no environment).

    Example::

        env = LocationObservation(RewardAutomatonWrapper(gymnasium.make(id), "driving.ra", inputs))
        model = DQN("MlpPolicy", env, replay_buffer_class=CounterfactualReplayBuffer,
                    replay_buffer_kwargs={"automaton": "driving.ra"})
    """

    def __init__(self, buffer_size: int, observation_space: Any, action_space: Any, device: Any = "auto",
                 n_envs: int = 1, optimize_memory_usage: bool = False, handle_timeout_termination: bool = True,
                 *, automaton: Any) -> None:
        if optimize_memory_usage:  # it reads a row's next observation from the row after: not so here
            raise ValueError("CounterfactualReplayBuffer stores several rows per step: optimize_memory_usage=True "
                             "reads a row's next observation from the next row, which would be another location's")
        rows = CounterfactualRows(automaton)
        # checked before ReplayBuffer sizes its arrays by the space (a Dict ended there in a TypeError)
        shape = getattr(observation_space, "shape", None)
        if shape is None or len(shape) != 1 or shape[0] <= len(rows.locations):
            raise ValueError(f"CounterfactualReplayBuffer needs a one-dimensional Box observation ending in the "
                             f"location's one-hot vector (LocationObservation's 'concat' layout), not "
                             f"{observation_space}")
        super().__init__(buffer_size, observation_space, action_space, device=device, n_envs=n_envs,
                         optimize_memory_usage=False, handle_timeout_termination=handle_timeout_termination)
        #: Builds the counterfactual rows; ``rows.locations`` the one-hot vector's order.
        self.rows = rows
        #: :class:`RacCallback` has warned that this buffer is filled under ``VecFrameStack``.
        self.warned_stacked = False

    def add(self, obs: np.ndarray, next_obs: np.ndarray, action: np.ndarray, reward: np.ndarray, done: np.ndarray,
            infos: list[dict[str, Any]]) -> None:
        """Store the real transitions, then one counterfactual transition per environment for each
        location the automaton was not in."""
        # an ended episode's location from its info: VecNormalize's terminal observation comes back inexact
        next_obs = self.rows.terminal_located(next_obs, done, infos)
        super().add(obs, next_obs, action, reward, done, infos)
        for batch in self.rows.step(obs, next_obs, done, infos):
            super().add(batch.obs, batch.next_obs, action, batch.reward, done, infos)
