"""The scenario model of a ``.ra`` file's ``model`` block as a gymnasium environment.

:class:`ScenarioEnv`: one step per decision period, with the automaton's reward
(:class:`rac.learning.episodes.EpisodeBatch` with one episode) and, optionally, a safety shield's
action masks — the exhaustive table where it applies, the runtime shield
(:mod:`rac.engine.lookahead`) elsewhere (:class:`rac.engine.shield.StepShield`)::

    env = ScenarioEnv("examples/left_turn/model.ra", shield="safe.shield.npz", horizon=3)
    obs, info = env.reset(seed=0)
    mask = env.action_masks()                       # (P,) bool: the actions the shield allows, never all False
    obs, reward, terminated, truncated, info = env.step(int(np.flatnonzero(mask)[0]))
    info["shield"]                                  # "exhaustive", "lookahead 5" or "none"

A set of scenes: the ``.ra`` file's ``model`` block is the template, its scenario swapped for each
file (:func:`rac.lang.edit.with_model`; every other setting kept), each scene checked once, on
its first draw; :meth:`ScenarioEnv.reset` draws one from ``np_random``::

    env = ScenarioEnv("model.ra", scenarios="scenes/", lookahead=3, render_mode="rgb_array")
    obs, info = env.reset(seed=0)                   # info["scenario"]: the scene drawn
    obs, info = env.reset(options={"scenario": 2})  # or a path of the set
    frame = env.render()                            # (H, W, 3) uint8
"""

from __future__ import annotations

import functools
import numbers
import os
import warnings
import weakref
from collections import Counter
from fractions import Fraction
from pathlib import Path
from typing import TYPE_CHECKING, Any, Literal, SupportsFloat

import gymnasium
import numpy as np

from rac import ir
from rac.compiler import CompileResult, compile_file, compile_text
from rac.core.caller import callers, user_stacklevel
from rac.core.diagnostics import CheckError, RacCheckWarning, RacValueError, check_warning_text, counted
from rac.core.numbers import samples_of, seconds_at
from rac.engine.explore import COLUMNS
from rac.engine.lookahead import LookaheadSettings
from rac.ir import expr as ie
from rac.lang import ast
from rac.lang.edit import with_model
from rac.learning.episodes import EpisodeBatch
from rac.learning.observation import Observation, make_observation
from rac.learning.wrappers import (
    REWARD_CHANGERS,
    ChangedRewards,
    CutEpisodes,
    Scale,
    outside_step_limit,
    scale_factor,
    within_proven,
)
from rac.model.checks import goal_window
from rac.model.commonroad import with_planning_problem
from rac.model.sample import MOTION

if TYPE_CHECKING:
    from collections.abc import Callable, Sequence

    from rac.compiler import CompileResult
    from rac.engine.lookahead import LookaheadSettings
    from rac.engine.shield import ShieldStep, ShieldTable, StepShield
    from rac.learning.episodes import EpisodeBatch
    from rac.output.render import SceneFrames

__all__ = ["RESET_OPTIONS", "ScenarioEnv"]

#: The render modes of :class:`ScenarioEnv`.
RENDER_MODES = ["ansi", "rgb_array"]


def _compile(model: str | os.PathLike[str] | CompileResult) -> CompileResult:
    result = compile_file(Path(model)) if isinstance(model, (str, os.PathLike)) else model
    if not isinstance(result, CompileResult):
        raise TypeError(f"model must be a .ra path or a CompileResult, not {type(model).__name__}")
    if not result.ok or result.automaton is None:
        raise CheckError(result.diagnostics, result.sources)
    return result


#: The warnings of ``rac check`` about one scene, which :class:`ScenarioEnv` says of each scene of a set as it is
#: drawn (W0716, W0722, W0724, W0730) and of every scene's episodes (W0728, for the episodes' own horizon).
SCENE_WARNINGS = frozenset({"W0716", "W0722", "W0724", "W0728", "W0730"})


def warn_file(result: CompileResult, skip: frozenset[str] = frozenset()) -> None:
    """Say the warnings of a ``.ra`` file given by its path (but those in ``skip``) as one
    :class:`~rac.core.diagnostics.RacCheckWarning`, as :func:`rac.load` and the wrappers do: a loophole of the
    reward (W1002 ending early pays, W1004 delaying the goal pays) is no less open in a scenario environment."""
    text = check_warning_text(d for d in result.diagnostics if d.code not in skip)
    if text is not None:
        warnings.warn(text, RacCheckWarning, stacklevel=user_stacklevel())


#: A scene of a set as :class:`ScenarioEnv` takes it: a CommonRoad file, or a file and the id of the planning
#: problem its ego and goal come from (a file with several planning problems, each set's files numbering theirs).
Scene = str | os.PathLike[str] | tuple[str | os.PathLike[str], int]


def _scene_entry(entry: object) -> tuple[Path, int | None]:
    """One entry of ``scenarios=``: its file and the planning problem asked for (None: the template's choice)."""
    if isinstance(entry, (str, os.PathLike)):
        return Path(entry), None
    if isinstance(entry, tuple) and len(entry) == 2 and isinstance(entry[0], (str, os.PathLike)):
        problem = entry[1]
        if isinstance(problem, (int, np.integer)) and not isinstance(problem, (bool, np.bool_)) and problem >= 0:
            return Path(entry[0]), int(problem)
        raise TypeError(f"a scene's planning problem must be a whole number >= 0 (an id of the file's "
                        f"planningProblem), not {problem!r}, in {entry!r}")
    raise TypeError(f"a scene must be a CommonRoad file's path or a (path, planning problem id) pair, not {entry!r}")


def _scene_paths(scenarios: Sequence[Scene] | str | os.PathLike[str]) -> list[tuple[Path, int | None]]:
    """The scenes of a set, each a file and the planning problem asked for (None: the template's): the
    entries given, or a folder's ``*.xml`` files in name order."""
    if isinstance(scenarios, (str, os.PathLike)):
        folder = Path(scenarios)
        if not folder.is_dir():
            raise RacValueError(f"scenarios must be a folder of CommonRoad files or a list of them; {folder} is no "
                                "folder")
        paths = sorted(folder.glob("*.xml"))
        if not paths:
            raise RacValueError(f"the folder {folder} holds no .xml scenario")
        return [(path, None) for path in paths]
    if isinstance(scenarios, tuple) and len(scenarios) == 2 and isinstance(scenarios[1], (int, np.integer)):
        raise TypeError(f"scenarios must be a list of scenes; {scenarios!r} is one scene: write [{scenarios!r}]")
    entries = [_scene_entry(entry) for entry in scenarios]
    if not entries:
        raise RacValueError("scenarios is empty: give at least one CommonRoad file")
    return entries


def _compile_scene(model: Path, text: str, scenario: Path, planning_problem: int | None = None) -> CompileResult:
    """The model file ``model`` (text ``text``) with the scene ``scenario`` (and its ``planning_problem``, None:
    the template's choice); errors name the scene. Checked once per process for the same model text and
    scene (the sub-environments of a vector environment share it): a changed scene file (size or time) is
    checked again."""
    try:
        stat = scenario.stat()
        stamp = (stat.st_size, stat.st_mtime_ns)
    except OSError:  # the checker names the missing file
        stamp = (-1, -1)
    return _checked_scene(str(model), text, str(scenario), stamp, planning_problem)


@functools.lru_cache(maxsize=256)
def _checked_scene(model: str, text: str, scenario: str, stamp: tuple[int, int],
                   planning_problem: int | None) -> CompileResult:
    settings = () if planning_problem is None else (("planning_problem", str(planning_problem)),)
    result = compile_text(with_model(text, Path(model), Path(scenario), settings), name=model)
    if not result.ok or result.automaton is None:
        error = CheckError(result.diagnostics, result.sources)
        # the diagnostics speak of the model file; say which scene of the set broke it
        hint = ("\n(a scene of a set chooses its planning problem as a pair in scenarios=: "
                f"({scenario!r}, ID))" if any(d.code == "E0715" for d in result.diagnostics) else "")
        error.args = (f"the scene {with_planning_problem(scenario, planning_problem)} does not check with the model "
                      f"block of {model}:\n{error}{hint}",)
        raise error
    return result


def _shield(shield: str | os.PathLike[str] | ShieldTable | None, columns: tuple[str, ...],
            n_actions: int) -> ShieldTable | None:
    # stormpy (via rac.engine.shield): importing rac.learning.scenario_env stays light
    from rac.engine import shield as shield_file

    if shield is None:
        return None
    table = shield_file.load(Path(shield)) if isinstance(shield, (str, os.PathLike)) else shield
    if not isinstance(table, shield_file.ShieldTable):
        raise TypeError(f"shield must be a shield file or a ShieldTable, not {type(shield).__name__}")
    if tuple(table.columns) != columns or table.n_actions != n_actions:
        raise RacValueError(f"the shield is for states {tuple(table.columns)} and {table.n_actions} actions; this "
                            f"model has states {columns} and {n_actions} actions")
    return table


def _lookahead(lookahead: LookaheadSettings | int | Literal["auto"] | None,
               table: ShieldTable | None) -> LookaheadSettings | None:
    """The runtime shield's settings: ``"auto"`` — the defaults when there is a table (so that every
    step beyond it is shielded too), none without one; a number is the depth."""

    if lookahead == "auto":
        return LookaheadSettings() if table is not None else None
    if lookahead is None or isinstance(lookahead, LookaheadSettings):
        return lookahead
    if isinstance(lookahead, numbers.Integral) and not isinstance(lookahead, (bool, np.bool_)):
        return LookaheadSettings(depth=int(lookahead))  # numpy's integers too (a depth from a sweep's array)
    raise TypeError(f"lookahead must be LookaheadSettings, a depth, 'auto' or None, not {lookahead!r}")


#: The warning of the first action_masks() of an environment without a shield: a masked learner (MaskablePPO)
#: asking for masks may believe they keep its runs safe, and nothing else says there is no shield.
UNSHIELDED_MASKS = ("action_masks() of an environment without a shield: the masks are only the actions the model's "
                    "`allow when` permits, and nothing keeps the runs safe (info['shield'] is 'none'); give "
                    "shield=<the table rac verify wrote> or lookahead=<depth> for a shield")


def clock_warning(step_shield: StepShield | None, time: float) -> str:
    """The warning of the first step whose runtime shield (of ``step_shield``) the time limit stopped (at
    ``time``, s)."""
    runtime = step_shield.runtime if step_shield is not None else None
    settings = runtime.settings if runtime is not None else None
    limit = f"{settings.seconds:g} s" if settings is not None and settings.seconds is not None else "its time"
    nodes = settings.nodes if settings is not None else None
    how = (f"its node budget ({nodes} a decision) is the same on every machine, the time limit ({limit}) is not; "
           "raise seconds= or lower nodes= of LookaheadSettings") if nodes is not None else (
        f"it has no node budget, only the time limit ({limit}): give it one, LookaheadSettings(nodes=...)")
    return (f"the runtime shield's time limit ({limit} a decision) stopped its search at t = {time:g} s: that mask "
            "(sound for the depth it states) depends on the machine's speed and load, so a run at the same seed may "
            f"get other masks elsewhere; info['shield_clock'] marks such steps, clock_steps counts them ({how})")


def outside_mask_warning(action: int, time: float, guarantee: str) -> str:
    """The warning of the first step that took an action (``action``, at ``time`` s) the mask of its state
    did not allow (the mask carried ``guarantee``: ``info["shield"]``)."""
    mask = ("the model's own (`allow when`)" if guarantee == "none" else f"the shield's ({guarantee})")
    return (f"the action {action} taken at t = {time:g} s was not in the mask of its state, {mask}: the mask only "
            "offers actions, it does not change the one taken, so no guarantee covers this step. A learner that "
            "ignores the masks takes such actions: plain PPO or DQN, MaskablePPO.predict(obs) without "
            "action_masks=, sb3-contrib's evaluate_policy(..., use_masking=False), or an action wrapper that changes "
            "the action after it was chosen from the mask; info['shield_allowed'] marks such steps, "
            "outside_mask_steps counts them")


#: The vector environments (SB3's DummyVecEnv, gymnasium's SyncVectorEnv: their ``envs``) stepping ScenarioEnvs in
#: this process, each with the masks (``info["shield"]``) whose step outside a sub-environment has said: the others
#: do not say it again (each text names its own action and time, so Python's warnings filter showed every one).
_SAID_OUTSIDE: weakref.WeakKeyDictionary[object, set[str]] = weakref.WeakKeyDictionary()


def _stepping_vector(env: object, frames: int = 12) -> tuple[object, int, int] | None:
    """The vector environment among the ``frames`` innermost callers whose ``envs`` hold ``env`` (wrapped or not),
    with ``env``'s index and their number; None when it is stepped on its own."""
    for frame in callers(frames):
        owner = frame.f_locals.get("self")
        envs = getattr(owner, "envs", None)
        if owner is not env and isinstance(envs, (list, tuple)):
            index = next((i for i, sub in enumerate(envs) if getattr(sub, "unwrapped", sub) is env), None)
            if index is not None:
                return owner, index, len(envs)
    return None


def no_safe_action_warning(step_shield: StepShield | None, state: np.ndarray, crashed: bool, timed_out: bool,
                           seconds: Callable[[int], float]) -> str:
    """The warning of the first step whose mask carried no guarantee (``info["no_safe_action"]``): the
    state ``state`` (``k, x, y, v, acc, head, jerk, turn``; ``crashed``: a collision happened before
    it; ``timed_out``: the runtime shield's search ran out of its budget), why ``step_shield`` knew no
    safe action there (None: a table with ``unseen="error"`` raised), and what the mask was instead
    (``seconds``: a sample's time)."""
    k = int(state[0])
    table = step_shield.table if step_shield is not None else None
    runtime = step_shield.runtime if step_shield is not None else None
    if step_shield is None:
        why = "the shield table (unseen='error') has no entry for it"
    elif crashed and step_shield.data.sticky:
        why = "the run collided earlier (`collision sticky`): no continuation of it is safe"
    elif runtime is not None:
        why = (f"the runtime shield (depth {runtime.settings.depth}) found no action that stays safe for even one "
               "decision" + ("; its search ran out of its budget first" if timed_out else ""))
    elif table is not None and table.horizon is not None and k >= table.horizon:
        why = (f"it lies past the shield table's horizon, t = {seconds(table.horizon):g} s (the episodes run to "
               f"{seconds(step_shield.horizon):g} s), and there is no runtime shield (lookahead=None) to take over "
               "there: give the environment a lookahead, or a table computed to the episodes' horizon")
    elif table is not None and not table.knows(state):
        why = ("the shield table has not seen this state (it holds the states runs under its masks reach) and there "
               "is no runtime shield (lookahead=None) to take over")
    else:
        why = "the shield allows no action here (no run from this state stays safe to its horizon)"
    return (f"no action was known to be safe at t = {seconds(k):g} s: {why}. The mask there allowed every action of "
            "the model (an all-False mask would not stop a masked learner), so no guarantee covers such steps; "
            "info['no_safe_action'] marks them (info['shield'] == 'none'), no_safe_action_steps counts them")


#: The keys of ``reset(options=...)`` that :class:`ScenarioEnv` reads (``reset_mask``: gymnasium's vector
#: environments' own, which they may pass on); another is warned of once.
RESET_OPTIONS = frozenset({"scenario", "reset_mask"})


class ScenarioEnv(gymnasium.Env):
    """The scenario model of a ``.ra`` file's ``model`` block as a gymnasium environment.

    One :meth:`step` is one decision period of :class:`rac.learning.episodes.EpisodeBatch` (one
    episode): the action (``Discrete(P)``, an index into ``action_pairs``: jerk-major over the
    ``model`` block's action grid) is held for ``decide_every`` samples.

    Args:
        model: a ``.ra`` file with a ``model`` block (compiled; errors raise
            :class:`rac.core.diagnostics.CheckError`) or a :class:`rac.compiler.CompileResult`.
        shield: the exhaustive shield for :meth:`action_masks`: a shield file (:func:`rac.engine.shield.load`,
            ``unseen="none"``), a :class:`rac.engine.shield.ShieldTable`, or a whole
            :class:`rac.engine.shield.StepShield` (table and runtime shield, e.g. from
            :func:`rac.engine.shield.step_shield`; then ``lookahead`` stays ``"auto"``).
        lookahead: the runtime shield beyond the table (:class:`rac.engine.lookahead.LookaheadSettings`,
            or its depth in decisions); ``"auto"`` (default): the default settings when there is a
            table, none without one; None: no runtime shield. Without table and runtime shield the
            mask is the model's ``allow when`` (every action where the model has no such rule).
        reward: ``"automaton"`` (the objective's increase, plus the ``at end`` bonus on the last
            step) or a reward expression (its text, or a parsed or checked expression), as ``EpisodeBatch``.
        horizon: the episode's length in seconds (default the automaton's ``horizon``); a whole
            number of sense periods.
        render_mode: None, ``"ansi"`` (:meth:`render` returns one line of text) or ``"rgb_array"``
            (an ``(H, W, 3)`` uint8 picture of the scene now: road, obstacles, ego;
            :class:`rac.output.render.SceneFrames`).
        scale: None (default: rewards as the automaton gives them), ``"proven"`` (divided by the
            largest change of the objective over one step that ``rac check``'s analysis proves,
            :func:`rac.check.analysis.scale.sample_change_bound`: every reward in [-1, 1], and the
            priority proofs still hold, a positive factor) or a positive number of your own (the
            only choice for a reward expression); the factor is :attr:`reward_scale` and ``info["scale"]``,
            and ``info["proven"]`` says it is the proven one (as the wrapper's ``info["rac"]["proven"]``).
        observation: what the agent observes, a kind of :mod:`rac.learning.observation`:
            ``"relative"`` (default; the ego against its lane, the road, the goal and the nearest
            obstacles) or ``"ego"`` (the sensed ego state and the time, in the scene's coordinates).
        scenarios: a set of scenes instead of the ``model`` block's own: CommonRoad files, or a
            folder whose ``*.xml`` files are the set. An entry may be a pair ``(path, id)`` choosing the
            file's planning problem (as the model block's ``planning_problem`` setting, which the other
            entries take from the template): the same file may come twice with two of its problems.
            ``model`` must then be a ``.ra`` file; its
            ``model`` block is the template (:func:`rac.lang.edit.with_model`), checked with each scene
            on the scene's first draw (a scene that does not check raises
            :class:`rac.core.diagnostics.CheckError` naming it; one whose ego starts off the road or in a
            collision, or whose goal window holds no sample of an episode, is a ``UserWarning`` naming it).
            Every scene must give the same
            number of actions and the same observation space. Only the runtime shield
            (``lookahead``) works with a set: a shield table is computed for one scene.

    Observation: :attr:`observation` (:mod:`rac.learning.observation`; ``"relative"``: ``float32``
    ``(29,)``, ``"ego"``: ``(8,)``). ``terminated`` when the
    goal is reached or the automaton's ``episode ends when`` holds (its ``at end`` clauses then apply at
    that sample), ``truncated`` at the horizon; a collision alone does not end the episode.
    ``info``: ``location``, ``rewards``, ``objective``, ``inputs`` (the bindings' values at the
    current sample), ``collided``/``offroad`` (at some sample of the step; after :meth:`reset`:
    at the start), ``goal`` (the episode reached the goal; after reset: False) and ``time``. After
    :meth:`step`, what the mask of the state the step left carried (the mask a masked learner chose
    from; :class:`rac.engine.shield.ShieldStep`): ``shield`` (``"exhaustive"``, ``"lookahead d"``,
    ``"none"``), ``shield_until`` (the time, s, up to which every allowed action had a safe
    continuation), ``shield_short`` (the runtime shield reached fewer decisions than asked for at
    that state: no action survived them all, or its budget ran out), ``shield_timeout`` (the
    runtime shield's budget ran out: the mask was sound for its depth but may have allowed fewer
    actions), ``shield_clock`` (of those, the time limit stopped the search, not the node budget:
    the mask depended on the machine's speed and load; warned once), ``no_safe_action`` (the shield knew no safe
    action: the mask allowed every action of the model; the first is warned of, saying why),
    ``shield_allowed`` (the action taken was in the mask) and ``model_allowed`` (the action taken was
    one the model's ``allow when`` permits: a learner that ignores the masks can take another, and
    that step is no step of the model, which no proof covers). Counted since construction:
    :attr:`shield_steps` (steps per ``shield`` value), :attr:`no_safe_action_steps`, :attr:`timeout_steps`,
    :attr:`clock_steps`, :attr:`disallowed_steps`, :attr:`outside_mask_steps` (``shield_allowed`` False;
    the first is warned of).

    The runtime shield's default budget is a number of search nodes
    (:class:`rac.engine.lookahead.LookaheadSettings`), so the masks, and a masked learner's run at a
    seed, are the same on every machine; its time limit is a guard far above what the nodes take.

    ``info["scenario"]``: the scene's file; ``info["planning_problem"]``: the id of the planning problem its
    ego and goal come from; ``info["scale"]``: :attr:`reward_scale`; ``info["proven"]``: it is ``scale="proven"``'s
    bound (:attr:`reward_proven`). After :meth:`step`,
    ``info["reward_steps"]``: each reward's change over the step (unscaled), as
    :class:`rac.learning.wrappers.RewardAutomatonWrapper` reports it in ``info["rac"]``.

    The model is deterministic: with one scene, ``reset(seed=...)`` only seeds :attr:`np_random`
    (for wrappers and agents that draw from it) and every episode starts from the same state. With
    a set, :meth:`reset` draws the scene from :attr:`np_random` (so ``reset(seed=s)`` gives the same
    scene again), or takes ``options={"scenario": i}`` (an index into :attr:`scenarios`, a path, or a
    ``(path, planning problem id)`` pair).
    """

    metadata = {"render_modes": RENDER_MODES}

    def __init__(self, model: str | os.PathLike[str] | CompileResult, *,
                 shield: str | os.PathLike[str] | ShieldTable | StepShield | None = None,
                 lookahead: LookaheadSettings | int | Literal["auto"] | None = "auto",
                 reward: str | ast.Expr | ie.Expr = "automaton", horizon: float | Fraction | None = None,
                 render_mode: str | None = None, observation: str = "relative",
                 scenarios: Sequence[Scene] | str | os.PathLike[str] | None = None,
                 scale: Scale = None) -> None:
        if render_mode is not None and render_mode not in self.metadata["render_modes"]:
            raise ValueError(f"render_mode must be None or one of {self.metadata['render_modes']}, not {render_mode!r}")
        self._template: tuple[Path, str] | None = None
        if scenarios is not None:
            if not isinstance(model, (str, os.PathLike)):
                raise TypeError("with scenarios, model must be a .ra file (its model block is the scenes' template)")
            if shield is not None:
                raise RacValueError("a shield table is computed for one scene; with a set of scenes only the runtime "
                                    "shield works: pass lookahead=<depth> instead of shield=")
            entries = _scene_paths(scenarios)
            self._template = (Path(model), Path(model).read_text(encoding="utf-8"))
            result = _compile_scene(*self._template, *entries[0])
            warn_file(result, SCENE_WARNINGS)  # the automaton's; each scene's own are said as it is drawn
        else:
            result = _compile(model)
            if isinstance(model, (str, os.PathLike)):  # a CompileResult's maker has its diagnostics
                warn_file(result, frozenset({"W0728"}))  # said of the episodes' horizon (_warn_past_traffic)
            spec = result.automaton.model if result.automaton is not None else None
            entries = [(Path(spec.scenario_path), None)] if spec is not None else []  # none: EpisodeBatch says why
        #: The scene files (one without ``scenarios``: the ``model`` block's).
        self.scenarios: tuple[Path, ...] = tuple(path for path, _ in entries)
        #: The planning problem each scene of :attr:`scenarios` was given as a pair in ``scenarios=``
        #: (None: the model block's choice; ``info["planning_problem"]`` is the one an episode runs).
        self.planning_problems: tuple[int | None, ...] = tuple(problem for _, problem in entries)
        self._reward, self._observation_kind = reward, observation
        self._shield_args = (shield, lookahead)
        automaton = result.automaton
        assert automaton is not None
        samples = None
        if horizon is not None:
            if isinstance(horizon, (bool, np.bool_)) or not isinstance(horizon, (numbers.Real, str)):
                raise TypeError(f"horizon must be a number of seconds, not {horizon!r}")
            try:
                # a float (numpy's too) through its shortest repr: 0.3 is 3/10, as written in a .ra file
                seconds = Fraction(str(horizon)) if isinstance(horizon, (float, np.floating)) else Fraction(horizon)
            except ValueError:  # NaN, infinity, text that is no number
                raise RacValueError(f"horizon must be a finite number of seconds, not {horizon!r}") from None
            try:  # the command line's rule (one owner), beyond int32 samples too
                samples = samples_of(seconds, Fraction(automaton.period), what="horizon")
            except ValueError as exc:
                raise RacValueError(str(exc)) from None
            if samples < 1:
                raise RacValueError(f"horizon {horizon} s is not a positive whole number of samples of "
                                    f"{float(automaton.period):g} s")
            if samples > automaton.steps:  # a shorter episode is a prefix of the runs the checks covered
                warnings.warn(f"the episode's horizon is {float(seconds):g} s but the automaton's is "
                              f"{float(automaton.horizon):g} s ({automaton.steps} samples): the priority proofs "
                              f"cover runs over a horizon of {float(automaton.horizon):g} s only; give a horizon= "
                              f"of at most {float(automaton.horizon):g} s, or lengthen the file's `horizon` (rac "
                              "check then proves it again)", UserWarning, stacklevel=user_stacklevel())
        self._samples = samples
        #: Per scene, once checked: its episodes, observation and shield (:meth:`_scene`).
        self._scenes: dict[int, tuple[EpisodeBatch, Observation, StepShield | None]] = {}
        self._frames: dict[int, SceneFrames] = {}
        self._index = 0
        self._said_traffic = False  # a scene whose episodes run past its traffic was warned of (once)
        self.episodes, self.observation, self._step_shield = self._scene(0, result)
        if horizon is not None:
            self._warn_short_last_step()
        #: The exhaustive shield's table (None without one).
        self.shield = self._step_shield.table if self._step_shield is not None else None
        #: Steps per guarantee of their mask (``info["shield"]``), since construction.
        self.shield_steps: Counter[str] = Counter()
        #: Steps whose state had no action known to be safe (``info["no_safe_action"]``).
        self.no_safe_action_steps = 0
        #: Steps whose runtime shield ran out of its budget (``info["shield_timeout"]``).
        self.timeout_steps = 0
        #: Of those, steps whose search the time limit stopped (``info["shield_clock"]``): their masks
        #: depended on the machine's speed and load.
        self.clock_steps = 0
        #: Steps that took an action the model's ``allow when`` forbids (``info["model_allowed"]`` False).
        self.disallowed_steps = 0
        #: Steps that took an action the mask of their state did not allow (``info["shield_allowed"]`` False;
        #: the first one is warned of): no guarantee covers them.
        self.outside_mask_steps = 0
        self._said_options = False  # an option reset() does not read was warned of
        #: Says once that gymnasium's reward wrappers outside change every reward (found at a reset they call).
        self.changed_rewards = ChangedRewards()
        self._said_unshielded = False  # action_masks() without a shield was warned of
        self._decision: ShieldStep | None = None
        self._crashed = False
        self.render_mode = render_mode
        data = self.episodes.data
        # one frame per step: a decision period
        self.metadata = {**self.metadata, "render_fps": 1.0 / (data.period * self.episodes.decide_every)}
        self._scale = float(data.scale)
        self._period = Fraction(self.episodes.automaton.period)
        self._names = automaton.location_names
        if reward != "automaton" and isinstance(scale, str):
            raise RacValueError(f"scale={scale!r} is proved for the automaton's reward; for a reward expression give "
                                "your own positive factor (scale=<number>)")
        #: What every reward is divided by (1.0 unscaled; ``info["scale"]``): with ``scale="proven"``
        #: the largest change of the objective over one step (:func:`rac.learning.wrappers.scale_factor`).
        self.reward_scale = scale_factor(automaton, scale, samples=self.episodes.decide_every)
        #: ``scale="proven"``: every reward within [-1, 1], a rounding past it put back (wrappers.within_proven).
        self.reward_proven: bool = scale == "proven"
        self.observation_space = self.observation.space
        self.action_space: gymnasium.spaces.Discrete = gymnasium.spaces.Discrete(self.episodes.n_actions)
        self._last: dict[str, bool] = {}
        #: The step limit of a ``TimeLimit`` outside (``gymnasium.make(..., max_episode_steps=N)``), found at a
        #: reset it called: the first episode it cuts is warned of at that step. None: none known.
        self.outside_step_limit: int | None = None
        #: Set by rac's reward wrappers around this environment (:data:`rac.learning.wrappers.REPLACED`):
        #: their automaton's reward replaces this one's, and an episode they end (`episode ends when`) is
        #: reset before this environment ended it, so it does not warn of episodes cut outside it.
        self.reward_replaced = False
        # gymnasium.make(..., max_episode_steps=N) puts a TimeLimit outside, which this environment cannot see
        self._cut = CutEpisodes("end the episodes with ScenarioEnv's own horizon=<seconds> (it truncates there and "
                                "applies them), not with max_episode_steps= or a TimeLimit")

    def _scene(self, index: int, result: CompileResult | None = None
               ) -> tuple[EpisodeBatch, Observation, StepShield | None]:
        """Scene ``index``'s episodes, observation and shield, built on first use (``result``: its
        checked model, when the caller has it); a scene whose actions or observation space differ
        from the first's is a ``ValueError`` naming it."""

        scene = self._scenes.get(index)
        if scene is not None:
            return scene
        if result is None:
            assert self._template is not None
            result = _compile_scene(*self._template, self.scenarios[index], self.planning_problems[index])
        episodes = EpisodeBatch(result, reward=self._reward, horizon_samples=self._samples)
        observation = make_observation(self._observation_kind, episodes)
        if self._scenes:
            first, first_observation, _ = self._scenes[0]
            if (episodes.n_actions != first.n_actions or episodes.horizon_samples != first.horizon_samples
                    or observation.space != first_observation.space):
                raise RacValueError(f"the scene {self._name(index)} gives {episodes.n_actions} actions, "
                                    f"{episodes.horizon_samples} samples and {observation.space}; the first scene "
                                    f"{self._name(0)} gives {first.n_actions}, {first.horizon_samples} and "
                                    f"{first_observation.space}: a set's scenes must agree")
        scene = (episodes, observation, self._shields(episodes, *self._shield_args, COLUMNS))
        self._scenes[index] = scene
        self._warn_past_traffic(result, index, episodes.horizon_samples)
        self._warn_unfit_scene(result, index, episodes.horizon_samples)
        return scene

    def _name(self, index: int) -> str:
        """Scene ``index`` as messages name it."""
        return with_planning_problem(str(self.scenarios[index]), self.planning_problems[index])

    def _warn_unfit_scene(self, result: CompileResult, index: int, samples: int) -> None:
        """Warn of what ``rac check`` would have said of this scene's episodes and nobody has seen: for a scene
        of a set (checked here with the template's model block, never by ``rac check``), a start off the road
        (W0716) or in a collision (W0724), where every episode is unsafe from its first sample, and traffic rules
        the model does not read (W0730: the shield's masks let a run pass a red light); and, for a set
        or an episode ``horizon=`` of its own, a goal window that holds no sample of an episode (W0722), where
        no episode can reach the goal. A set's scene of either kind trained without a word."""
        scenario, automaton, data = result.scenario, result.automaton, result.model_data
        if scenario is None or automaton is None or data is None or (self._template is None and self._samples is None):
            return
        found = [d for d in result.diagnostics if d.code in ("W0716", "W0724", "W0730")] \
            if self._template is not None else []
        if self._template is not None or not any(d.code == "W0722" for d in result.diagnostics):
            horizon = None if self._samples is None else samples * Fraction(automaton.period)  # None: the file's
            found += goal_window(automaton, scenario, data, horizon, option="horizon=")
        for diagnostic in found:
            warnings.warn(f"the scene {self._name(index)}: {diagnostic.message} ({diagnostic.code} in rac check)",
                          UserWarning, stacklevel=user_stacklevel())

    def _warn_short_last_step(self) -> None:
        """Warn when ``horizon=`` is no whole number of decision periods: the episode's last step is then
        shorter than the others (a learner sees one step of another length, its reward summed over fewer
        samples). Allowed, as a file's own horizon is: the model's runs end there too."""
        episodes = self.episodes
        left = episodes.horizon_samples % episodes.decide_every
        if left:
            period = Fraction(episodes.automaton.period)
            decision = period * episodes.decide_every
            shorter = (episodes.horizon_samples - left) * period
            warnings.warn(f"horizon={float(episodes.horizon_samples * period):g} s is no whole number of decisions "
                          f"of {float(decision):g} s: the episode's last step is {left} of "
                          f"{episodes.decide_every} samples ({float(left * period):g} s), shorter than the others; "
                          f"give a multiple of {float(decision):g} s ({float(shorter):g} or "
                          f"{float(shorter + decision):g} s) for steps of one length", UserWarning,
                          stacklevel=user_stacklevel())

    def _warn_past_traffic(self, result: CompileResult, index: int, samples: int) -> None:
        """Warn once when this scene's episodes run past its recorded traffic (``rac check``'s W0728 for the
        file's horizon; here for the episode's, ``horizon=`` included): after it the road holds no moving
        obstacle, and neither the shield's masks nor the rewards there speak of the traffic."""
        scenario, automaton = result.scenario, result.automaton
        if self._said_traffic or scenario is None or automaton is None:
            return
        seconds = float(samples * Fraction(automaton.period))
        if scenario.outruns_traffic(seconds):
            self._said_traffic = True
            episode_ends = scenario.ego.time + seconds
            warnings.warn(f"the episodes of {self._name(index)} run past its recorded traffic: its moving "
                          f"obstacles are gone after scenario time t = {scenario.traffic_ends:g} s, an episode ends at "
                          f"t = {episode_ends:g} s, so from then on the road holds no moving obstacle, and the "
                          "shield's masks and the rewards speak of a road without the traffic (W0728 in rac check; "
                          "a shorter horizon= ends the episodes with the traffic)", UserWarning,
                          stacklevel=user_stacklevel())

    def _shields(self, episodes: EpisodeBatch, shield: str | os.PathLike[str] | ShieldTable | StepShield | None,
                 lookahead: LookaheadSettings | int | Literal["auto"] | None,
                 columns: tuple[str, ...]) -> StepShield | None:
        # stormpy (via rac.engine.shield): importing rac.learning.scenario_env stays light
        from rac.engine.shield import StepShield

        if isinstance(shield, StepShield):
            if lookahead != "auto":
                raise RacValueError("a StepShield brings its own runtime shield: leave lookahead as 'auto'")
            if shield.horizon != episodes.horizon_samples or shield.n_actions != episodes.n_actions:
                raise RacValueError(f"the shield is for runs of {shield.horizon} samples and {shield.n_actions} "
                                    f"actions; this environment's have {episodes.horizon_samples} and "
                                    f"{episodes.n_actions}")
            if shield.data.digest != episodes.data.digest:  # its masks would speak of another scene's obstacles
                raise RacValueError(f"the StepShield was made for another model (digest {shield.data.digest}, this "
                                    f"environment's {episodes.data.digest}): another scene, or the model block or "
                                    "its scenario changed since; make it from this model's data")
            return shield
        table = _shield(shield, columns, episodes.n_actions)
        settings = _lookahead(lookahead, table)
        if table is None and settings is None:
            return None
        return StepShield(episodes.data, episodes.horizon_samples, table=table, lookahead=settings)

    @property
    def step_shield(self) -> StepShield | None:
        """The shield behind :meth:`action_masks` (None: every action allowed)."""
        return self._step_shield

    def shield_step(self) -> ShieldStep | None:
        """What the shield hands out in the current state (computed once per state; None without a
        shield): the mask and the guarantee it carries."""
        if self.episodes.n != 1:
            raise RuntimeError("call reset() before asking the shield")
        if self._step_shield is None:
            return None
        if self._decision is None:
            self._decision = self._step_shield.decide(self.episodes.state_keys()[0], crashed=self._crashed)
        return self._decision

    @property
    def proof_subject(self) -> tuple[ir.Automaton, int] | None:
        """What ``rac check``'s priority proofs of this environment's reward are about: the automaton and
        the samples one step spans (a decision period), which :class:`rac.learning.sb3.RacCallback` checks
        P2 of the discounted return on (:mod:`rac.check.analysis.discount`); None for a reward expression,
        which no proof covers."""
        if self._reward != "automaton":
            return None
        return self.episodes.automaton, self.episodes.decide_every

    @property
    def dt(self) -> float:
        """Seconds per step: one decision period (gymnasium's convention, as MuJoCo's environments give
        it), which :class:`rac.learning.wrappers.RewardAutomatonWrapper` compares with its automaton's
        ``sample every`` (one wrapper step is one sample of it)."""
        return float(self._period * self.episodes.decide_every)

    @property
    def action_pairs(self) -> np.ndarray:
        """``(P, 2)`` int32: action ``a`` is the (jerk, turn) significand pair ``action_pairs[a]``."""
        return self.episodes.action_pairs

    def _seconds(self, sample: int | np.integer) -> float:
        """The time of ``sample``, as written: 7.1 s, not 7.1000000000000005 (:func:`seconds_at`)."""
        return float(seconds_at(int(sample), self._period))

    def _obs(self) -> np.ndarray:
        return self.observation.observe(self.episodes)[0]

    def _info(self) -> dict[str, Any]:
        episodes = self.episodes
        scenario = episodes.result.scenario
        inputs = {name: bool(values[0]) if values.dtype == bool else float(values[0])
                  for name, values in episodes.inputs.items()}
        return {"location": self._names[int(episodes.location[0])],
                "rewards": {name: float(values[0]) for name, values in episodes.rewards.items()},
                "objective": float(episodes.objective[0]), "inputs": inputs, **self._last,
                "time": self._seconds(episodes.k[0]),
                "scenario": str(self.scenarios[self._index]),
                "planning_problem": scenario.planning_problem_id if scenario is not None else None,
                "scale": self.reward_scale, "proven": self.reward_proven}

    def reset(self, *, seed: int | None = None,
              options: dict[str, Any] | None = None) -> tuple[np.ndarray, dict[str, Any]]:
        """Start an episode at the ego's start: of the scene ``options["scenario"]`` (an index into
        :attr:`scenarios`, one of its paths, or a ``(path, planning problem id)`` pair of the set), else of
        one drawn from ``np_random`` (with one
        scene: that one; the seed only seeds ``np_random``, the model is deterministic)."""
        super().reset(seed=seed)
        if not self.reward_replaced:
            self._cut.reset()
            if self.outside_step_limit is None:
                self.outside_step_limit = outside_step_limit(self)
            self.changed_rewards.check(self, REWARD_CHANGERS)  # NormalizeReward(ScenarioEnv(...)) in a loop
        unknown = sorted(map(str, set(options or {}) - RESET_OPTIONS))
        if unknown and not self._said_options:  # a typo (`{"scene": 1}`) drew a scene at random without a word
            self._said_options = True
            warnings.warn(f"reset(options=...) ignores {', '.join(map(repr, unknown))}: ScenarioEnv reads only "
                          f"{', '.join(map(repr, sorted(RESET_OPTIONS)))} (the scene to start in, else one drawn "
                          "from np_random)", UserWarning, stacklevel=user_stacklevel())
        self._index = self._pick((options or {}).get("scenario"))
        self.episodes, self.observation, self._step_shield = self._scene(self._index)
        episodes = self.episodes
        episodes.reset(1)
        collided, offroad = episodes.observe([ie.call("collide"), ie.call("offroad")])[0] != 0
        # "goal" is False at the start: an episode ends at the goal only after a step
        self._last = {"collided": bool(collided), "offroad": bool(offroad), "goal": False}
        self._crashed = bool(collided)  # under `collision sticky`: nothing after a collision is safe
        self._decision = None
        return self._obs(), self._info()

    def _pick(self, chosen: Any) -> int:
        """The index of the scene ``chosen`` (None: one drawn from ``np_random``)."""
        count = len(self.scenarios)
        if chosen is None:
            return int(self.np_random.integers(count)) if count > 1 else 0
        if isinstance(chosen, (int, np.integer)) and not isinstance(chosen, bool):
            if not 0 <= chosen < count:
                raise RacValueError(f"options['scenario'] = {chosen}: the set holds {counted(count, 'scene')}, "
                                    f"numbered 0 .. {count - 1}")
            return int(chosen)
        if isinstance(chosen, (str, os.PathLike, tuple)):
            try:
                path, problem = _scene_entry(chosen)
            except TypeError:
                raise TypeError(f"options['scenario'] must be an index, a path or a (path, planning problem id) "
                                f"pair, not {chosen!r}") from None
            wanted = path.resolve()
            for index, (scene, asked) in enumerate(zip(self.scenarios, self.planning_problems, strict=True)):
                if scene.resolve() == wanted and (problem is None or problem == asked):
                    return index  # a path alone: its first scene of the set
            raise RacValueError(f"options['scenario'] = {chosen!r} is not one of the scenes: "
                                f"{', '.join(self._name(i) for i in range(count))}")
        raise TypeError(f"options['scenario'] must be an index, a path or a (path, planning problem id) pair, "
                        f"not {chosen!r}")

    def step(self, action: Any) -> tuple[np.ndarray, SupportsFloat, bool, bool, dict[str, Any]]:
        """One decision period with action ``action`` (an index into :attr:`action_pairs`)."""
        if self.episodes.n != 1:
            raise RuntimeError("call reset() before step()")
        if self.episodes.done[0]:
            raise RuntimeError("the episode has ended; call reset() first")
        if not self.action_space.contains(action):
            raise ValueError(f"action must be an integer in [0, {self.action_space.n}), not {action!r}")
        # stormpy (via rac.engine.shield): importing rac.learning.scenario_env stays light
        from rac.engine.shield import UnseenState

        time = self._seconds(self.episodes.k[0])
        try:
            decision = self.shield_step()  # the mask of the state this step leaves
            unseen = False
        except UnseenState:  # unseen="error" raises from action_masks(); the step itself goes on
            decision, unseen = None, True
        model_allowed = bool(self.episodes.model_masks()[0][int(action)])
        lapsed = unseen if decision is None else decision.no_safe_action
        if lapsed and not self.no_safe_action_steps:  # an all-True mask said nothing else; said of the state left
            warnings.warn(no_safe_action_warning(self._step_shield if decision is not None else None,
                                                 self.episodes.state_keys()[0], self._crashed,
                                                 decision is not None and decision.timed_out, self._seconds),
                          UserWarning, stacklevel=user_stacklevel())
        before = self.episodes.rewards
        out = self.episodes.step(np.array([int(action)]))
        # terminated: the goal, or the automaton's `episode ends when` (its end clauses already applied)
        terminated, truncated = bool(out.terminated[0] or out.ended[0]), bool(out.truncated[0])
        if not self.reward_replaced:
            self._cut.stepped(terminated or truncated, self.outside_step_limit)
        self._last = {"collided": bool(out.collided[0]), "offroad": bool(out.offroad[0]),
                      "goal": bool(out.terminated[0])}
        self._crashed = self._crashed or bool(out.collided[0])
        self._decision = None
        shield: dict[str, Any]
        if decision is None:
            # no shield: the mask handed out was the model's own
            shield = {"shield": "none", "shield_until": time, "shield_short": False, "shield_timeout": False,
                      "shield_clock": False, "no_safe_action": unseen, "shield_allowed": model_allowed}
        else:
            shield = {"shield": decision.guarantee,
                      "shield_until": self._seconds(decision.until),
                      "shield_short": decision.short, "shield_timeout": decision.timed_out,
                      "shield_clock": decision.clock, "no_safe_action": decision.no_safe_action,
                      "shield_allowed": bool(decision.mask[int(action)])}
        shield["model_allowed"] = model_allowed
        self.shield_steps[shield["shield"]] += 1
        self.no_safe_action_steps += shield["no_safe_action"]
        self.timeout_steps += shield["shield_timeout"]
        if shield["shield_clock"]:
            if not self.clock_steps:  # never silently: a reproducible run is what the node budget promises
                warnings.warn(clock_warning(self._step_shield, time), RuntimeWarning, stacklevel=user_stacklevel())
            self.clock_steps += 1
        self.disallowed_steps += not model_allowed
        if not shield["shield_allowed"]:
            if not self.outside_mask_steps:  # the info key alone went unread: an evaluation loop drops it
                self._warn_outside_mask(int(action), time, shield["shield"])
            self.outside_mask_steps += 1
        info = self._info()
        # each reward's change over the step, unscaled (what a training log averages per objective)
        info["reward_steps"] = {name: value - float(before[name][0]) for name, value in info["rewards"].items()}
        reward = within_proven(float(out.reward[0]) / self.reward_scale, self.reward_proven)
        return self._obs(), reward, terminated, truncated, {**info, **shield}

    def _warn_outside_mask(self, action: int, time: float, guarantee: str) -> None:
        """Say the first step of this environment outside the mask (:func:`outside_mask_warning`), once per mask's
        guarantee among the sub-environments of the vector environment stepping it, naming which one it is."""
        vector = _stepping_vector(self)
        text = outside_mask_warning(action, time, guarantee)
        if vector is not None:
            owner, index, count = vector
            try:
                said = _SAID_OUTSIDE.setdefault(owner, set())
            except TypeError:  # no weak reference to it: said by each
                said = set()
            if guarantee in said:
                return
            said.add(guarantee)
            text += (f" (sub-environment {index} of the {count} of a {type(owner).__name__}: said once for them all, "
                     "each counts its own)")
        warnings.warn(text, UserWarning, stacklevel=user_stacklevel())

    def action_masks(self) -> np.ndarray:
        """``(P,)`` bool: the actions the shield allows in the current state (without a shield, those
        the model's ``allow when`` permits); never all False.

        The exhaustive table's row where it applies, the runtime shield's mask elsewhere (beyond the
        table's horizon, in a state it has not seen, where it allows nothing; :class:`rac.engine.shield.StepShield`).
        Where neither knows a safe action the mask allows every action of the model, and the step
        is flagged (``info["no_safe_action"]``, ``info["shield"] == "none"``) and counted: an
        all-False mask would not stop a masked learner — sb3-contrib's ``MaskableCategorical``
        samples uniformly from one, without a warning — so it is never handed out. A table loaded
        with ``unseen="error"`` still raises :class:`rac.engine.shield.UnseenState` for a state it has
        not seen."""
        if self.episodes.n != 1:
            raise RuntimeError("call reset() before action_masks()")
        decision = self.shield_step()
        if decision is None:  # the model's own rule still holds (all of them where it leaves none)
            if not self._said_unshielded:
                self._said_unshielded = True
                warnings.warn(UNSHIELDED_MASKS, UserWarning, stacklevel=user_stacklevel())
            return self.episodes.model_masks()[0].copy()
        return decision.mask.copy()

    def render(self) -> str | np.ndarray | None:
        """``"ansi"``: one line with the time, the sensed state and the automaton's location and
        objective; ``"rgb_array"``: an ``(H, W, 3)`` uint8 picture of the scene now (road, goal,
        obstacles, ego; :class:`rac.output.render.SceneFrames`)."""
        if self.render_mode == "rgb_array":
            return self._frame()
        if self.render_mode != "ansi":
            return None
        if self.episodes.n != 1:
            return "(not reset)"
        x, y, v, acc, head, jerk, turn = (self.episodes.ego[0] / self._scale).tolist()
        time = self._seconds(self.episodes.k[0])
        info = self._info()
        return (f"t={time:.2f}s x={x:.2f} y={y:.2f} v={v:.2f} acc={acc:.2f} head={head:.3f} jerk={jerk:g} "
                f"turn={turn:g} {info['location']} objective={info['objective']:.3f}")

    def _frame(self) -> np.ndarray:
        # PIL, matplotlib (via rac.output.render): importing rac.learning.scenario_env stays light
        from rac.output.render import SceneFrames

        episodes = self.episodes
        frames = self._frames.get(self._index)
        if frames is None:
            data = episodes.data
            scenario = episodes.result.scenario
            frames = SceneFrames(self.scenarios[self._index], sample_period=float(self._period),
                                 planning_problem=scenario.planning_problem_id if scenario is not None else None,
                                 length=data.length / self._scale, width=data.width / self._scale)
            self._frames[self._index] = frames
        if episodes.n != 1:  # before reset: the ego at its start
            data = episodes.data
            return frames.frame(0, data.ego_x / self._scale, data.ego_y / self._scale, data.ego_head / self._scale)
        x, y, _, _, head = (episodes.ego[0, MOTION] / self._scale).tolist()
        return frames.frame(int(episodes.k[0]), x, y, head)
