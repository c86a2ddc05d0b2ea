"""The `model` block's scenario, checked against the model: E0712-E0715, W0716, E0718-W0724, W0727, W0730 and E0801.

:func:`check_scenario` loads the CommonRoad file of a checked automaton's `model` block once
(:func:`load`, the one caller of :func:`rac.model.commonroad.load_scenario`) and builds the model's data from it
(:func:`rac.model.data.build_model_data_and_largest`), so that ``rac check`` reports, with a span:

* E0712: the file cannot be loaded (missing, not XML, not CommonRoad, an element rac cannot
  represent), or the model's data cannot be built from it; the loader's message names the file
  and the element. Anything else the loader or the builder raises becomes E0712 as well, except
  a ``MemoryError``: the file is not at fault, so it propagates (``rac`` reports a resource error).
* E0713: a value of the scenario (a position, a speed, an obstacle's size, ...) whose
  significand ``trunc(v · base^exponent)`` overflows int32, with the largest exponent that fits;
  at the setting, when the value is one the ``model`` block writes (``width 1e30``).
* E0714: the ego starts outside the model's limits (a speed outside [`min_speed`, `max_speed`],
  an acceleration beyond ±`max_acceleration`), which ``sense()`` would clamp at the first
  sample; the hint names the setting to change and the value that holds the start.
* E0718-E0721, E0729: the file reads but is inconsistent (:class:`~rac.model.commonroad.InconsistentScenarioError`):
  a time step that makes the model's times meaningless (E0718), an obstacle's trajectory whose time
  steps repeat, go back or skip (E0719), a lanelet's predecessor, successor or neighbour that the file
  lacks (E0720), a lanelet without width (E0721), a lanelet whose bounds run in opposite directions
  (E0729); the message names the file with the element's
  line:column, the element and the attribute.
* E0715: the planning problem is not clear: the file has several and the block writes no
  `planning_problem`, or the one it writes is not in the file; the message lists the ids.
* W0716: the ego starts off the road: ``offroad()`` holds in the initial state, so no run is
  safe from the start. A warning, not an error: the model is consistent and answers every query
  (CommonUppRoad's ZAM_Ramp starts so, and its model does not check the start).
* W0722: the goal's time window holds no sample of the model (it closes before the ego starts,
  lies between two samples, or opens after the horizon ends; :func:`goal_window` for a command's
  ``--horizon`` too): ``goal()`` never holds.
* W0723: the goal also asks for a velocity or an orientation, which ``goal()`` does not read.
* W0724: the ego starts in a collision (``collide()`` holds at the start), like W0716 a warning.
* W0727: a binding reads ``dist_goal()`` while the goal has no position (a goal of time alone): it reads 0
  everywhere, so the binding never changes with it.
* W0730: the scenario has traffic lights, traffic signs or stop lines, which the model does not read.
* E0801: a numeric binding whose value leaves int32 wherever no obstacle exists (``bind d =
  mindist()``: ``mindist()`` reads 1e9 there), when some sample of the horizon has none; the hint
  bounds it (``fmin(mindist(), 100)``).

The loaded :class:`~rac.model.commonroad.Scenario` and :class:`~rac.model.data.ModelData` are returned so
that :class:`rac.compiler.CompileResult` can hand them on (:class:`rac.model.program.CheckedProgram`)
without reloading.
"""

from __future__ import annotations

import enum
import math
import os
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from fractions import Fraction
from typing import TYPE_CHECKING

from rac import ir
from rac.core.diagnostics import Diagnostic, Fact, Note, error, short_count, short_number, warning
from rac.core.numbers import INT32_BOUND, INT32_LOW, INT32_MAX, exact_decimal, format_bytes
from rac.core.resources import (  # the load's budget (its owner; the CLI catches the refusal without loading this)
    LOAD_NOTICE_BYTES,
    ScenarioTooLarge,
    estimate_load,
)
from rac.core.source import Span
from rac.ir import expr as ie
from rac.ir.text import format_checked
from rac.ir.vocabulary import MODELLING, NO_PLANNING_PROBLEM, SETTINGS, Setting
from rac.model.commonroad import InconsistentScenarioError, PlanningProblemError, ScenarioError, TrafficRules
from rac.model.data import ModelDataError, ModelRangeError, check_significands
from rac.model.native import CORNER_NAMES, NO_OBSTACLE, NO_OBSTACLE_TEXT, NativeModel

if TYPE_CHECKING:
    from rac.model.commonroad import Scenario
    from rac.model.data import ModelData

#: The codes of a scenario rac cannot build a model from: unreadable (E0712) or inconsistent (E0718-E0721,
#: E0729). ``rac sweep`` counts a task that ends in one as an error of its input, not a verdict ("error", not "failed").
UNUSABLE_SCENARIO = ("E0712", "E0718", "E0719", "E0720", "E0721", "E0729")

#: Loaded scenarios by (path, modification time, size, planning problem): checking several files
#: that share a scenario, or the same file again, reads it once.
_CACHE: dict[tuple[str, int, int, int | None], Scenario] = {}
_CACHE_SIZE = 8


@dataclass
class ScenarioCheck:
    """What :func:`check_scenario` found: diagnostics, facts, and what it loaded."""

    diagnostics: list[Diagnostic] = field(default_factory=list)
    facts: list[Fact] = field(default_factory=list)
    scenario: Scenario | None = None
    data: ModelData | None = None


def load(spec: ir.ModelSpec, *, max_bytes: int | None = None) -> Scenario:
    """The scenario of a `model` block: the one place rac loads one (``rac check`` through
    :func:`check_scenario`, and every consumer handed an automaton without it,
    :meth:`rac.model.program.CheckedProgram.of`), so that all of them read the same planning problem.
    The block's `planning_problem` is honoured as the checks honour it: none chosen in a file with
    several, or one the file lacks, is a :class:`~rac.model.commonroad.PlanningProblemError` (what
    E0715 reports), never a silent choice. Cached and ``max_bytes`` as in :func:`load_file`."""
    chosen = spec.planning_problem
    return load_file(spec.scenario_path, None if chosen == NO_PLANNING_PROBLEM else chosen, max_bytes=max_bytes)


def load_file(path: str | os.PathLike[str], planning_problem: int | None = None, *,
              max_bytes: int | None = None) -> Scenario:
    """``load_scenario(path, planning_problem, require_choice=True)``, cached while the file is
    unchanged: without a planning problem, a file with several is a
    :class:`~rac.model.commonroad.PlanningProblemError`. :class:`ScenarioTooLarge`, before anything is
    read, when the file is not cached and its :class:`LoadEstimate` exceeds ``max_bytes``."""

    path = os.fspath(path)
    try:
        stat = os.stat(path)
        key: tuple[str, int, int, int | None] | None = (os.path.abspath(path), stat.st_mtime_ns, stat.st_size,
                                                        planning_problem)
    except OSError:
        key = None  # the loader reports it
    if key is not None and key in _CACHE:
        return _CACHE[key]
    if key is not None and max_bytes is not None:
        estimate = estimate_load(key[2])
        if estimate.peak_bytes > max_bytes:
            raise ScenarioTooLarge(path, estimate, max_bytes)
    # looked up at each load: tests put a slow or failing loader in rac.model.commonroad's place
    from rac.model.commonroad import load_scenario

    scenario = load_scenario(path, planning_problem, require_choice=True)
    if key is not None:
        if len(_CACHE) >= _CACHE_SIZE:
            _CACHE.pop(next(iter(_CACHE)))
        _CACHE[key] = scenario
    return scenario


def check_scenario(automaton: ir.Automaton, progress: Callable[[str], None] | None = None,
                   max_bytes: int | None = None) -> ScenarioCheck:
    """Load the scenario of ``automaton``'s `model` block and build the model's data from it;
    ``progress`` (the caller's: this layer prints nothing) hears of a load expected to take a while,
    and of each of its phases. ``max_bytes`` (None: no limit) is the memory budget: a scenario whose
    :class:`LoadEstimate` exceeds it is refused before it loads, with :class:`ScenarioTooLarge`."""
    result = ScenarioCheck()
    spec = automaton.model
    if spec is None:
        return result
    announced = progress is not None and _announce(spec.scenario_path, progress)
    scenario_span = automaton.spans.get("model:scenario", spec.span)
    written = spec.scenario

    def cannot_load(message: str, hints: list[str], missing: bool = False) -> ScenarioCheck:
        notes = [] if os.path.normpath(written) == spec.scenario_path else \
            [f"`scenario \"{written}\"` is the file `{spec.scenario_path}` (relative to the folder of this file)"]
        if missing and not notes and os.path.dirname(written):  # a path through folders: where did it lead?
            notes = [f"`scenario \"{written}\"` is the file `{os.path.abspath(spec.scenario_path)}` (relative to "
                     "the folder of this file)"]
        result.diagnostics.append(error("E0712", f"cannot load the scenario: {message}", scenario_span,
                                        notes=notes, hints=hints))
        return result

    try:
        scenario = load(spec, max_bytes=max_bytes)
    except PlanningProblemError as failure:
        result.diagnostics.append(_planning_problem(automaton, spec, failure))
        return result
    except InconsistentScenarioError as failure:
        result.diagnostics.append(_inconsistent(spec, scenario_span, failure))
        return result
    except ScenarioError as failure:
        return cannot_load(str(failure), _load_hints(failure, written),
                           missing=failure.element is None and failure.problem == "does not exist")
    # anything else (MemoryError: the budget or the machine, not the file) propagates: the loader
    # reports every fault of the file as a ScenarioError, so another failure is rac's own
    result.scenario = scenario

    if announced and progress is not None:  # a phase of its own: a heartbeat says which one is slow
        progress(f"building the model's data from {len(scenario.road):,} lanelets and "
                 f"{len(scenario.obstacles):,} obstacles")
    try:
        # looked up at each check: tests put a failing builder in rac.model.data's place
        from rac.model.data import build_model_data_and_largest

        data, (what, largest) = build_model_data_and_largest(scenario, spec)
    except ModelRangeError as failure:
        if failure.significand is None:
            return cannot_load(f"{spec.scenario_path}: {failure}", [_GENERIC_HINT])
        result.diagnostics.append(_overflow(automaton, spec, scenario, failure))
        return result
    except ModelDataError as failure:
        return cannot_load(f"{spec.scenario_path}: {_text(failure)}", [_GENERIC_HINT])
    result.data = data
    result.diagnostics.extend(_start(automaton, spec, scenario, data))
    if any(d.is_error for d in result.diagnostics):
        return result  # a start the model would clamp: nothing to sum up
    result.diagnostics.extend(_goal(automaton, spec, scenario, data))
    result.diagnostics.extend(_distance_to_anywhere(spec, scenario))
    result.diagnostics.extend(traffic_ends(automaton, scenario))
    result.diagnostics.extend(traffic_rules(automaton, scenario))
    result.diagnostics.extend(_sentinel_bindings(automaton, spec, data))
    goal = scenario.goal
    obstacles = len(scenario.obstacles)
    detail = f" (the largest is {what}: {largest})" if what else ""
    ids = scenario.planning_problem_ids
    problem = f", planning problem {scenario.planning_problem_id} (of {_ids(ids)})" if len(ids) > 1 else ""

    counted = (f"{obstacles} obstacle{'s' if obstacles != 1 else ''}" if obstacles else
               f"no obstacle (`mindist()` reads {NO_OBSTACLE_TEXT} and `collide()` never holds)")
    if scenario.recorded_ego is not None:  # said, or the file's obstacle count would not match
        counted += (f" (obstacle {scenario.recorded_ego} left out: the planning problem's own vehicle, recorded "
                    "from its start)")
    result.facts.append(Fact(
        "scenario",
        f"scenario {written}{problem}: {len(scenario.road)} lanelet{'s' if len(scenario.road) != 1 else ''}, "
        f"{counted}, goal{_ANYWHERE if goal.anywhere else ''} at scenario time t in [{_number(goal.time_low)}, "
        f"{_number(goal.time_high)}] s{_model_time(scenario)}; every significand fits int32 at base {spec.base}, "
        f"exponent {spec.exponent}{detail}",
        {"scenario": written, "lanelets": len(scenario.road), "obstacles": obstacles, "base": spec.base,
         "exponent": spec.exponent}))
    return result


#: The `proved:` line's words for a goal of time alone (a goal state without a position).
_ANYWHERE = " at any position (the file's goal has no position; `dist_goal()` reads 0)"


def _model_time(scenario: Scenario) -> str:
    """Where the model's time (from the ego's start) differs from the scenario's, say so."""
    start = scenario.ego.time
    return f" (the model's time counts from the ego's start at {_number(start)} s)" if start else ""


def _goal(automaton: ir.Automaton, spec: ir.ModelSpec, scenario: Scenario, data: ModelData) -> list[Diagnostic]:
    """W0722 for a goal window that holds no sample of the model, W0723 for goal constraints the model
    does not read (velocity, orientation)."""
    span = automaton.spans.get("model:scenario", spec.span)
    goal = scenario.goal
    found = goal_window(automaton, scenario, data)
    asked = [f"velocity in [{_number(goal.velocity[0])}, {_number(goal.velocity[1])}] m/s"] if goal.velocity else []
    if goal.orientation:
        asked.append(f"orientation in [{_number(goal.orientation[0])}, {_number(goal.orientation[1])}] rad")
    if asked:
        where = "in the window" if goal.anywhere else "inside the goal region"
        found.append(warning(
            "W0723", f"the goal of `{spec.scenario}` also asks for {' and '.join(asked)}, which the model does not "
            f"read: `goal()` holds at any speed and heading {where}", span,
            notes=[f"`goal()` reads only the goal region and its time window (planning problem "
                   f"{scenario.planning_problem_id} of `{spec.scenario_path}`)"],
            hints=["add the condition to the query or the automaton (`v`, `head`), or read goal verdicts knowing "
                   "that they ignore it"]))
    return found


class GoalNever(enum.Enum):
    """Why ``goal()`` holds at no sample of a run (W0722), its value the reason in a few words."""

    BEFORE_START = "the goal's window closes before the ego starts"
    BETWEEN_SAMPLES = "the goal's window lies between two samples"
    AFTER_HORIZON = "the goal's window opens after the horizon"


def goal_never(data: ModelData, samples: Fraction | int) -> GoalNever | None:
    """Why ``goal()`` holds at none of the samples ``0..samples`` of ``data``'s model, or None when one lies in
    the goal's window (W0722's cases; ``rac preanalyse`` says it per setting)."""
    if data.goal_high < 0:
        return GoalNever.BEFORE_START
    if data.goal_low > data.goal_high:
        return GoalNever.BETWEEN_SAMPLES
    if data.goal_low > samples:
        return GoalNever.AFTER_HORIZON
    return None


def goal_window(automaton: ir.Automaton, scenario: Scenario, data: ModelData,
                horizon: Fraction | None = None, option: str = "--horizon") -> list[Diagnostic]:
    """W0722 when the goal's window holds no sample of the runs (``horizon`` s long, a command's ``--horizon``;
    default the automaton's): it closes before the ego starts, lies between two samples, or opens only after
    the runs end, so ``goal()`` holds at no sample of any run and every goal query is "no" for that reason
    alone (a horizon of 3 s before a window of [4, 10] s passed ``rac check`` without a word, and ``rac
    verify`` then proved that no run reaches the goal). ``option`` names where ``horizon`` came from
    (``horizon=`` in Python)."""
    spec = automaton.model
    if spec is None:
        return []
    span = automaton.spans.get("model:scenario", spec.span)
    goal = scenario.goal
    window = f"[{_number(goal.time_low)}, {_number(goal.time_high)}] s"
    period = Fraction(spec.sense_period)
    seconds = Fraction(automaton.horizon if horizon is None else horizon)
    never = goal_never(data, seconds / period)
    if never is None:
        return []
    if never is GoalNever.BEFORE_START:
        return [warning(
            "W0722", f"the goal's time window {window} closes before the ego starts (at {_number(scenario.ego.time)} "
            "s of the scenario): `goal()` never holds", span,
            notes=[f"the scenario file is `{spec.scenario_path}`; the model's time counts from the ego's start, and "
                   "`goal()` holds only at the samples inside the window"],
            hints=["choose a planning problem whose goal lies after its start, or correct the goal's time interval"])]
    if never is GoalNever.BETWEEN_SAMPLES:
        return [warning(
            "W0722", f"the goal's time window {window} holds no sample of the model (every {short_number(period)} s "
            f"from the ego's start at {_number(scenario.ego.time)} s): `goal()` never holds", span,
            notes=[f"the scenario file is `{spec.scenario_path}`; `goal()` holds only at the samples inside the "
                   "window, and the window lies between two samples"],
            hints=["sample more often (`sample every`), or widen the goal's time interval"])]
    which, where = _horizon_named(horizon, option)
    first = data.goal_low * period  # the window's first sample, in the model's time
    return [warning(
        "W0722", f"the goal's time window {window} opens after {which} ends (scenario time t = "
        f"{_number(scenario.ego.time + float(seconds))} s): `goal()` never holds", span,
        notes=[f"the scenario file is `{spec.scenario_path}`; the runs end {_decimal(seconds)} s after the ego's "
               f"start at {_number(scenario.ego.time)} s, and the first sample inside the window is {_decimal(first)} "
               "s after it, so every query that asks for the goal is answered for a goal no run can reach in time"],
        hints=[f"lengthen the horizon to at least {_decimal(first)} s ({where}), or choose a planning problem whose "
               "goal window opens within it"])]


def _horizon_named(horizon: Fraction | None, option: str) -> tuple[str, str]:
    """The horizon a warning speaks of, and where it is set: the automaton's (``horizon`` None), or the
    value of a command's ``option`` (``--horizon 12``, ScenarioEnv's ``horizon=12``)."""
    if horizon is None:
        return "the horizon", "`horizon`"
    return f"{option}{'' if option.endswith('=') else ' '}{_decimal(horizon)}", option


def _distance_to_anywhere(spec: ir.ModelSpec, scenario: Scenario) -> list[Diagnostic]:
    """W0727 for each binding that reads ``dist_goal()`` when the goal has no position (a goal of time
    alone, :attr:`~rac.model.commonroad.Goal.anywhere`): ``dist_goal()`` reads 0 everywhere, so what the
    binding makes of it never changes (``dist_goal() < prev(dist_goal())`` is ``0 < 0`` at every sample)."""
    goal = scenario.goal
    if not goal.anywhere:
        return []
    return [warning(
        "W0727", f"binding `{binding.input} = {format_checked(binding.expr)}` reads `dist_goal()`, which is 0 "
        f"everywhere: the goal of `{spec.scenario}` has no position", binding.span or spec.span,
        notes=[f"planning problem {scenario.planning_problem_id} of `{spec.scenario_path}` asks only that the ego "
               f"be anywhere at scenario time t in [{_number(goal.time_low)}, {_number(goal.time_high)}] s, so there "
               f"is no distance to the goal: `{binding.input}` reads `dist_goal()` as 0 at every sample"],
        hints=["measure progress by the ego's state instead (e.g. `x > prev(x)` or `v > 0`), or choose a planning "
               "problem whose goal has a position"])
        for binding in spec.bindings
        if any(isinstance(node, ie.Call) and node.name == "dist_goal" for node in ie.walk(binding.expr))]


def traffic_ends(automaton: ir.Automaton, scenario: Scenario, horizon: Fraction | None = None) -> list[Diagnostic]:
    """W0728 when the horizon (``horizon`` s, a command's ``--horizon``; default the automaton's) runs past the
    recorded traffic: CommonRoad regards a moving obstacle as gone after its last time step, and so does the
    model, so once the last one ends the road holds only static obstacles and every verdict, shield and learned
    strategy after it covers a road without moving traffic (a recording cut off at 8 s under a 30 s horizon said
    nothing of it)."""
    spec = automaton.model
    ends = scenario.traffic_ends
    if spec is None or ends is None:
        return []
    seconds = float(automaton.horizon if horizon is None else horizon)
    if not scenario.outruns_traffic(seconds):
        return []
    moving = [obstacle for obstacle in scenario.obstacles if not obstacle.static]
    horizon_ends = scenario.ego.time + seconds
    count = f"{len(moving)} moving obstacle{'s are' if len(moving) != 1 else ' is'}"
    left = f" and {len(scenario.obstacles) - len(moving)} static" if len(scenario.obstacles) > len(moving) else ""
    span = automaton.spans.get("model:scenario", spec.span)
    which, where = _horizon_named(horizon, "--horizon")
    return [warning(
        "W0728", f"{which} runs past the recorded traffic of `{spec.scenario}`: its {count} gone after "
        f"scenario time t = {_number(ends)} s, the horizon ends at t = {_number(horizon_ends)} s", span,
        notes=[f"CommonRoad regards an obstacle as gone after its last time step, and so does the model: from "
               f"t = {_number(ends)} s the road holds no moving obstacle{left}, so what rac proves, shields or "
               "learns after it covers a road without the traffic"],
        hints=[f"shorten the horizon to {_number(ends - scenario.ego.time)} s ({where}), or use a scenario whose "
               "obstacles' trajectories reach the horizon"])]


def traffic_rules(automaton: ir.Automaton, scenario: Scenario) -> list[Diagnostic]:
    """W0730 when the scenario has traffic lights, traffic signs or stop lines: the model reads the road, the
    obstacles and the goal only, so a run may pass a red light or a stop line, and what rac proves, shields or
    learns says nothing of them (an urban scene's lights were ignored without a word)."""
    spec = automaton.model
    counted = scenario.traffic_rules.counted()
    if spec is None or not counted:
        return []
    listed = counted[0] if len(counted) == 1 else f"{', '.join(counted[:-1])} and {counted[-1]}"
    return [warning(
        "W0730", f"`{spec.scenario}` has {listed}, which the model does not read: runs ignore them",
        automaton.spans.get("model:scenario", spec.span),
        notes=[f"the model of `{spec.scenario_path}` reads the road, the obstacles and the goal; a red light, a "
               "stop sign or a stop line stops no run, so a safety shield, a verdict or a learned strategy covers "
               "collisions and leaving the road, not the traffic rules"],
        hints=[_rules_hint(scenario.traffic_rules)])]


def _rules_hint(rules: TrafficRules) -> str:
    """W0730's hint: how to make the model or the automaton read the rules (a speed limit: ``max_speed``)."""
    limits = rules.speed_limits
    if limits and not rules.lights and not rules.stop_lines:
        return ("set the model's `max_speed` to the limit (the ego then never drives faster), or bind an input such "
                "as `bind fast = v > 13.9` and penalise it; or read verdicts knowing that they ignore the limit")
    return ("write a rule into the automaton as an input bound from the ego's state and `time` (e.g. `bind pastStop "
            "= x > 40 && time < 12`, penalised like `isClose`)" + (", a speed limit as `max_speed`" if limits else "") +
            ", or read verdicts knowing that they ignore the rules")


def _inconsistent(spec: ir.ModelSpec, scenario_span, failure) -> Diagnostic:
    """E0718-E0721, E0729: the file reads, but contradicts itself or the model; the message names the file with
    the element's line:column, the element and the attribute."""
    notes: list[Note | str] = [f"the scenario file is `{spec.scenario_path}`; the attribute at fault is "
                               f"`{failure.attribute}`"]
    return error(failure.code, f"inconsistent scenario: {failure}", scenario_span, notes=notes,
                 hints=[failure.hint])


def _announce(path: str, progress: Callable[[str], None]) -> bool:
    """Tell ``progress`` of a scenario larger than :data:`LOAD_NOTICE_BYTES`: its size, the time and
    the memory expected (the load cannot report its own progress: commonroad-io reads the file in one
    call); whether it was announced."""
    try:
        size = os.path.getsize(path)
    except OSError:
        return False  # the loader reports it
    if size <= LOAD_NOTICE_BYTES:
        return False
    estimate = estimate_load(size)
    seconds = estimate.seconds
    expected = f"{seconds / 60:.0f} min" if seconds >= 120 else f"{seconds:.0f} s"
    progress(f"loading the scenario {path} ({size / 2**20:.0f} MB): about {expected}, at most about "
             f"{format_bytes(estimate.peak_bytes)} of memory")
    return True


def _ids(ids: tuple[int, ...]) -> str:
    return ", ".join(map(str, ids))


def _planning_problem(automaton: ir.Automaton, spec: ir.ModelSpec, failure) -> Diagnostic:
    """E0715: several planning problems and none chosen, or a chosen one the file lacks."""
    spans = automaton.spans
    scenario_span = spans.get("model:scenario", spec.span)
    ids = failure.ids
    # an id the setting cannot name (commonroad-io reads id 0, which CommonRoad's schema does not allow, and
    # `planning_problem 0` is the setting left out): hinting at it would contradict E0702
    choosable = [i for i in ids if i > NO_PLANNING_PROBLEM]
    choices = [f"`planning_problem {i}`" for i in choosable]
    if failure.chosen is None:
        listed = choices[0] if len(choices) == 1 else ", ".join(choices[:-1]) + f" or {choices[-1]}" \
            if len(choices) <= 4 else f"{choices[0]} (or another id above)"
        notes = ["each planning problem has its own start and goal; the model is built for one"]
        unnamed = [i for i in ids if i <= NO_PLANNING_PROBLEM]
        if unnamed:
            notes.append(f"planning problem {_ids(tuple(unnamed))} cannot be chosen: `planning_problem` is a whole "
                         "number >= 1 (CommonRoad's ids are positive); renumber it in the file to use it")
        return error("E0715", f"the scenario has {len(ids)} planning problems ({_ids(ids)}) and the `model` block "
                     "chooses none", scenario_span, notes=notes,
                     hints=[f"choose one with {listed} in the `model` block"])
    which = f"its only planning problem is {ids[0]}" if len(ids) == 1 else f"its planning problems are {_ids(ids)}"
    if len(ids) == 1:
        hint = "leave the setting out (the file has one planning problem)"
        hint = f"write `planning_problem {ids[0]}`, or {hint}" if choices else hint
    else:
        hint = f"write one of its ids, e.g. {choices[0]}"
    return error("E0715", f"the scenario has no planning problem {failure.chosen}",
                 spans.get("model:planning_problem", scenario_span),
                 notes=[which, Note(f"the scenario `{spec.scenario}` is named here", scenario_span)], hints=[hint])


def _start(automaton: ir.Automaton, spec: ir.ModelSpec, scenario, data) -> list[Diagnostic]:
    """E0714 for an ego start outside the model's speed and acceleration limits, W0716 for a start
    off the road."""
    found = []
    ego = scenario.ego
    speed, low, high = data.ego_v, data.min_speed, data.max_speed
    origin = "scenario's" if spec.start_speed is None else "`start_speed`"
    if not low <= speed <= high:
        setting = "max_speed" if speed > high else "min_speed"
        limit = spec.max_speed if speed > high else spec.min_speed
        words = "faster than" if speed > high else "slower than"
        found.append(_limit(automaton, spec, setting, Fraction(speed, data.scale), "m/s",
                            f"the ego starts at {_number(speed / data.scale)} m/s, {words} `{setting}` "
                            f"({short_number(limit)} m/s)",
                            f"the model holds the speed within [`min_speed`, `max_speed`] = "
                            f"[{short_number(spec.min_speed)}, {short_number(spec.max_speed)}] m/s at every Euler "
                            f"sub-step of `sense()`: from the first sample on the ego would drive at "
                            f"{short_number(limit)} m/s, not the {origin} {_number(speed / data.scale)} m/s"))
    if abs(data.ego_acc) > data.max_acc:
        bound = spec.max_acceleration if ego.acceleration > 0 else -spec.max_acceleration
        found.append(_limit(automaton, spec, "max_acceleration", Fraction(abs(data.ego_acc), data.scale), "m/s²",
                            f"the ego starts with the acceleration {_number(ego.acceleration)} m/s², beyond "
                            f"`max_acceleration` ({short_number(spec.max_acceleration)} m/s²)",
                            f"the model holds the acceleration within ±`max_acceleration` at every Euler sub-step "
                            f"of `sense()`: from the first sample on the ego would accelerate at "
                            f"{short_number(bound)} m/s², not the scenario's {_number(ego.acceleration)} m/s²"))

    model = NativeModel(data)
    off = [name for name, outside in zip(CORNER_NAMES, model.corners_off(model.initial_state())) if outside]
    written = any(getattr(spec, f"start_{name}") is not None for name in ("x", "y", "heading"))
    where = ("the `start_*` settings start" if written else f"planning problem {scenario.planning_problem_id} starts")
    start = tuple(_number(value / data.scale) for value in (data.ego_x, data.ego_y, data.ego_head))
    if off and data.offroad_from == 0:
        listed = off[0] if len(off) == 1 else ", ".join(off[:-1]) + " and " + off[-1]
        corners = "all four of its corners lie" if len(off) == 4 else \
            f"its {listed} corner{'s lie' if len(off) > 1 else ' lies'}"
        found.append(warning(
            "W0716", f"the ego starts off the road: {corners} outside every lanelet",
            automaton.spans.get("model:scenario", spec.span),
            notes=[f"{where} the ego's {short_number(spec.length)} m × "
                   f"{short_number(spec.width)} m rectangle at ({start[0]}, {start[1]}), heading {start[2]} rad",
                   "`offroad()` holds in the initial state: no run is safe from the start, so `E[] !offroad()` "
                   "and the safety shield (`control: A[] !collide() && !offroad()`) fail there"],
            hints=["move the ego's start onto the road (`start_x`, `start_y`, `start_heading`, or the scenario's "
                   "planning problem), or write `offroad_from 1` to leave the start unchecked, as CommonUppRoad's "
                   "model does"]))
    elif off and data.offroad_from > 0:
        found.extend(_still_off(automaton, spec, data, model, where, start))
    found.extend(_start_collision(automaton, spec, scenario, data, model))
    return found


def _still_off(automaton: ir.Automaton, spec: ir.ModelSpec, data, model: NativeModel, where: str,
               start: tuple[str, ...]) -> list[Diagnostic]:
    """W0716 for a start off the road that `offroad_from N` leaves unchecked, when a corner lies farther
    from every lanelet than any run can move it in N samples: `offroad()` then holds at sample N in
    every run (ZAM_Ramp-1_1-T-1 at standstill with `offroad_from 1`, as W0716's hint suggests, kept
    Qd failing with no word on why). The reach is a bound: the centre at most `max_speed` and at most
    the start speed plus `max_acceleration` at every Euler sub-step, a corner turned by at most the
    largest turn rate, and a significand lost to truncation per sample, coordinate and heading."""
    samples = data.offroad_from
    seconds = samples * data.period
    steps = seconds / data.unit
    speed = model.max_speed_d
    centre = min(speed * seconds, data.ego_v / data.scale * seconds + model.max_acc_d * seconds * (seconds + data.unit)
                 / 2) if steps < 1e9 else speed * seconds
    turn = max((abs(value) for value in data.action("turn").values), default=0) / data.scale
    radius = math.hypot(model.length_d, model.width_d) / 2
    # truncation: a significand of each coordinate and of the heading per sample
    reach = centre + radius * (turn * seconds + samples / data.scale) + 2 * samples / data.scale
    state = model.initial_state()
    gaps = [(name, _road_distance(model, data, *point)) for name, point, outside
            in zip(CORNER_NAMES, model.corner_points(state), model.corners_off(state)) if outside]
    name, gap = max(gaps, key=lambda pair: pair[1])
    if gap <= reach:
        return []
    return [warning(
        "W0716", f"the ego starts off the road and cannot be on it by sample {samples} (`offroad_from "
        f"{samples}`): its {name} corner lies {gap:.3g} m outside every lanelet",
        automaton.spans.get("model:offroad_from", automaton.spans.get("model:scenario", spec.span)),
        notes=[f"{where} the ego's {short_number(spec.length)} m × {short_number(spec.width)} m rectangle at "
               f"({start[0]}, {start[1]}), heading {start[2]} rad; in {_number(seconds)} s no run moves a corner "
               f"more than {reach:.2g} m",
               f"`offroad()` holds at sample {samples} in every run: no run is safe from there, so `E[] !offroad()` "
               "and the safety shield (`control: A[] !collide() && !offroad()`) fail"],
        hints=["move the ego's start onto the road (`start_x`, `start_y`, `start_heading`, or the scenario's "
               "planning problem), or raise `offroad_from` to the sample by which the ego is on the road"])]


def _road_distance(model: NativeModel, data, px: float, py: float) -> float:
    """The distance from ``(px, py)`` to the nearest edge of a road polygon (metres)."""
    xs, ys, starts = model.road_xd, model.road_yd, data.road_start
    best = math.inf
    for p in range(len(starts) - 1):
        j = starts[p + 1] - 1
        for i in range(starts[p], starts[p + 1]):
            ax, ay, bx, by = xs[j], ys[j], xs[i], ys[i]
            dx, dy = bx - ax, by - ay
            length = dx * dx + dy * dy
            along = 0.0 if length == 0 else max(0.0, min(1.0, ((px - ax) * dx + (py - ay) * dy) / length))
            best = min(best, math.hypot(px - ax - along * dx, py - ay - along * dy))
            j = i
    return best


#: An interval of doubles a binding's value lies in (its ends may be infinite).
_Interval = tuple[float, float]
_ANY: _Interval = (-math.inf, math.inf)


def _absent(data: ModelData, k: int) -> bool:
    """Whether no obstacle exists at sample ``k`` (``mindist()`` reads :data:`NO_OBSTACLE` there)."""
    return not any(start <= k <= until for start, until in zip(data.obs_from, data.obs_until))


def _without_obstacle(automaton: ir.Automaton, data: ModelData) -> list[tuple[int, float | None, float | None]]:
    """Where the bindings read `mindist()` without an obstacle: ``(sample, mindist(), prev(mindist()))``
    with :data:`NO_OBSTACLE` where it is known to read it (None: some distance). The first sample the
    bindings are read at (1 up to the horizon; only 1 when `episode ends when` may end runs earlier) at
    which no obstacle exists, and sample 1 when none exists at the start (``prev(e)`` reads it there)."""
    last = automaton.steps if automaton.ending is None else min(automaton.steps, 1)
    first = next((k for k in range(1, last + 1) if _absent(data, k)), None)
    found: list[tuple[int, float | None, float | None]] = []
    if first is not None:
        found.append((first, NO_OBSTACLE, NO_OBSTACLE if _absent(data, first - 1) else None))
    if _absent(data, 0) and first != 1 and last >= 1:
        found.append((1, None, NO_OBSTACLE))
    return found


def _interval(expr: ie.Expr, mindist: float | None, before: float | None, held: float) -> _Interval:
    """Where the double a binding computes lies, whatever the state, when ``mindist()`` reads ``mindist``
    and ``prev(mindist())`` reads ``before`` (None: any distance), the ego state being significands (within
    ``±held``, int32 over the scale): interval arithmetic, sound, not tight; a value it cannot bound is
    :data:`_ANY`."""
    if isinstance(expr, ie.Const) and not isinstance(expr.value, bool):
        return float(expr.value), float(expr.value)
    if isinstance(expr, ie.Ref) and expr.value is not None:  # a setting, as the model holds it
        return float(expr.value), float(expr.value)
    if isinstance(expr, ie.Ref) and expr.is_model and expr.model.kind == "ego":
        return -held, held
    if isinstance(expr, ie.Unary) and expr.op == "-":
        low, high = _interval(expr.operand, mindist, before, held)
        return -high, -low
    if isinstance(expr, ie.Binary) and expr.op in ("+", "-", "*", "/"):
        left, right = _interval(expr.left, mindist, before, held), _interval(expr.right, mindist, before, held)
        if expr.op == "+":
            return left[0] + right[0], left[1] + right[1]
        if expr.op == "-":
            return left[0] - right[1], left[1] - right[0]
        if expr.op == "/":
            if right[0] <= 0.0 <= right[1]:
                return _ANY
            right = (1.0 / right[1], 1.0 / right[0])
        ends = [a * b for a in left for b in right]
        return _ANY if any(math.isnan(end) for end in ends) else (min(ends), max(ends))
    if isinstance(expr, ie.Prev):
        return _interval(expr.operand, before, None, held)  # no prev(prev(e)) (E0711)
    if isinstance(expr, ie.Call):
        args = [_interval(arg, mindist, before, held) for arg in expr.args if arg.type == ie.NUM]
        if expr.name == "mindist":
            return (mindist, mindist) if mindist is not None else (-math.inf, math.inf)
        if expr.name == "dist_goal":
            return 0.0, math.inf
        if expr.name in ("fabs", "abs") and args:
            low, high = args[0]
            return (0.0 if low <= 0.0 <= high else min(abs(low), abs(high))), max(abs(low), abs(high))
        if expr.name == "sqrt" and args and args[0][1] >= 0.0:
            return math.sqrt(max(args[0][0], 0.0)), math.sqrt(args[0][1])
        if expr.name in ("fmin", "fmax") and len(args) == 2:
            pick = min if expr.name == "fmin" else max
            return pick(args[0][0], args[1][0]), pick(args[0][1], args[1][1])
    return _ANY  # the ego state, time, prev(e) when an obstacle exists at the sample before, ...


def _sentinel_bindings(automaton: ir.Automaton, spec: ir.ModelSpec, data: ModelData) -> list[Diagnostic]:
    """E0801 for a numeric binding that has no int32 significand wherever no obstacle exists: there
    ``mindist()`` reads :data:`NO_OBSTACLE` (1e9), and ``bind d = mindist()`` needs the significand
    ``1e9 · 10^4``. rac's engine refuses such a reading (the verdicts are unknown); the emitted model's
    ``d2i()`` would truncate it out of int32 (a C compiler gives -2147483648, which the guards then read),
    so the file is refused before either runs."""
    found: list[Diagnostic] = []
    numeric = {item.name: item for item in automaton.inputs if not item.is_bool}
    bindings = [b for b in spec.bindings if b.input in numeric
                and any(isinstance(node, ie.Call) and node.name == "mindist" for node in ie.walk(b.expr))]
    limit = INT32_BOUND / data.scale
    cases = _without_obstacle(automaton, data) if bindings else []
    for binding in bindings:
        overflows = [(case, _interval(binding.expr, case[1], case[2], INT32_MAX / data.scale)) for case in cases]
        leaving = next(((case, ends) for case, ends in overflows if ends[0] >= limit or ends[1] <= -limit), None)
        if leaving is None:
            continue  # it may fit: the engine checks every value it reads
        (sample, now, _), (low, high) = leaving
        if not data.obs_from:
            where = "the scenario has no obstacle"
        elif now is None:
            where = "no obstacle exists at the start (t = 0 s), which `prev(...)` reads at the first sample"
        else:
            where = f"no obstacle exists at t = {short_number(sample * automaton.period)} s (sample {sample})"
        bound = low if low >= limit else high
        item = numeric[binding.input]
        text = format_checked(binding.expr)
        fits = INT32_MAX // data.scale  # the largest whole number whose significand fits
        cap = (f"`bind {binding.input} = fmin({text}, {short_number(item.high)})` (the upper bound of "
               f"`{binding.input}`)" if item.high is not None and low >= limit and item.high <= fits else
               f"`bind {binding.input} = fmin({text}, {min(1000, fits)})`" if low >= limit else
               f"`bind {binding.input} = fmax({text}, -{min(1000, fits)})`")
        words = "at least" if low >= limit else "at most"
        found.append(error(
            "E0801", f"binding `{binding.input} = {text}` leaves int32 at base {spec.base}, exponent "
                     f"{spec.exponent} where no obstacle exists",
            binding.span or spec.span,
            notes=[f"{where}; there `mindist()` reads {NO_OBSTACLE_TEXT}, its value without one, and `{binding.input}` "
                   f"is {words} {_magnitude(bound)}: its significand (· {data.scale}) is {words} "
                   f"{_magnitude(bound * data.scale)}, beyond int32 [{INT32_LOW}, {INT32_MAX}]",
                   "rac's engine cannot read the input there, and the emitted UPPAAL model's `d2i()` would leave "
                   "int32 (compiled as C it reads -2147483648, which the guards then compare)"],
            hints=[f"bound the distance, e.g. {cap}"],
            data={"base": spec.base, "exponent": spec.exponent, "input": binding.input, "sample": sample}))
    return found


def _start_collision(automaton: ir.Automaton, spec: ir.ModelSpec, scenario: Scenario, data: ModelData,
                     model: NativeModel) -> list[Diagnostic]:
    """W0724: ``collide()`` holds at the start (sample 0): one ``mindist()`` over the obstacles, as cheap
    as the off-road test."""
    state = model.initial_state()
    if not model.collide(state, 0):
        return []
    ex, ey = state.x / data.scale, state.y / data.scale
    present = [(math.hypot(p[0] - ex, p[1] - ey), i, p) for i in range(data.obstacle_count)
               if (p := model.obstacle_position(i, 0)) is not None]
    _, nearest, (ox, oy, _) = min(present)
    obstacle = next(o for o in scenario.obstacles if o.id == data.obs_id[nearest])
    kind = f" ({obstacle.kind})" if obstacle.kind else ""
    return [warning(
        "W0724", f"the ego starts in a collision: `collide()` holds at the start (the nearest obstacle is "
        f"{'static' if obstacle.static else 'dynamic'} obstacle {obstacle.id}{kind} at ({_number(ox)}, {_number(oy)}))",
        automaton.spans.get("model:scenario", spec.span),
        notes=[f"`mindist()` reads {_number(model.mindist(state, 0))} m at the start, below `collision_distance` "
               f"({short_number(spec.collision_distance)} m), with the ego at ({_number(ex)}, {_number(ey)})",
               "no run is safe from the start, so `E[] !collide()` and the safety shield fail there"],
        hints=["move the ego's start away from the obstacle (`start_x`, `start_y`, or the scenario's planning "
               "problem), or remove the obstacle from the scenario"])]


def _limit(automaton: ir.Automaton, spec: ir.ModelSpec, setting: str, held: Fraction, unit: str, message: str,
           why: str) -> Diagnostic:
    """E0714 for ``setting``: at the setting when written, else at the scenario (with its default)."""
    spans = automaton.spans
    scenario_span = spans.get("model:scenario", spec.span)
    written = spans.get(f"model:{setting}")
    notes: list[Note | str] = [why]
    if written is None:
        notes.append(f"`{setting}` defaults to {short_number(Fraction(getattr(spec, setting)))} {unit}")
    else:
        notes.append(Note(f"the scenario `{spec.scenario}` is named here", scenario_span))
    if setting == "min_speed" and held < 0:
        hint = "the model's speeds are >= 0 (`min_speed` cannot be negative): choose a planning problem whose ego " \
               "does not start backwards"
    else:
        hint = f"set `{setting} {short_number(held)}` (or {'less' if setting == 'min_speed' else 'more'}) in the " \
               "`model` block"
    start = spans.get("model:start_speed")
    if start is not None and setting in ("min_speed", "max_speed"):
        notes.append(Note("the start speed is set here", start))
        hint += ", or change `start_speed`"
    return error("E0714", message, written or scenario_span, notes=notes, hints=[hint])


_GENERIC_HINT = ("rac reads CommonRoad XML files (formats 2018b and 2020a) with commonroad-io; "
                 "docs/scenario.md lists what it supports")


def _load_hints(failure, written: str) -> list[str]:
    if failure.element is None and failure.problem == "does not exist":
        return [f"the path is relative to the folder of this `.ra` file: put `{os.path.basename(written)}` "
                "there, or correct the path"]
    if failure.element is None and failure.problem.startswith("is a symbolic link to"):
        return ["restore the file the link points to, or name the scenario file itself"]
    if failure.element is None and failure.problem.startswith("is a directory"):
        return ["name the CommonRoad XML file, not its folder"]
    if failure.element is None and failure.problem.startswith("is not a regular file"):
        return ["name a CommonRoad XML file saved on disk: rac reads the scenario whole, not from a pipe or a device"]
    if failure.element is None and failure.problem.startswith("cannot be read ("):  # the file is fine, its access not
        return ["make the file readable for you (`chmod +r`, or ask its owner), or copy it next to this `.ra` file"]
    if " is not a number" in failure.problem or " is not a whole number" in failure.problem:
        return ["correct that value in the file: CommonRoad's values are plain decimal numbers (3.5, not 3.5s), "
                "time steps whole ones"]
    return [_GENERIC_HINT]


def _text(failure: BaseException) -> str:
    text = str(failure).strip()
    return f"{type(failure).__name__}: {text}" if text else type(failure).__name__


def _number(value: float) -> str:
    """A scenario's float as its shortest decimal (33.0 is 33; an open goal interval ends at ∞)."""
    if math.isinf(value):
        return "∞" if value > 0 else "-∞"
    return short_number(Fraction(repr(float(value))))


def _magnitude(value: float) -> str:
    """A large double as messages write it: ``1e9``, ``-2.5e13`` (a smaller one as :func:`_number`)."""
    if math.isfinite(value) and abs(value) >= 1e6:
        mantissa, exponent = f"{value:.6e}".split("e")
        return f"{mantissa.rstrip('0').rstrip('.')}e{int(exponent)}"
    return _number(value)


def _decimal(value: Fraction) -> str:
    """``value`` as an exact decimal when it has one (base 10: 214748.3647), else shortened."""
    return exact_decimal(value) or short_number(value)


def _fits(scenario, spec: ir.ModelSpec, exponent: int) -> bool:
    try:
        return check_significands(scenario, replace(spec, exponent=exponent)) is None
    except ModelDataError:
        return False


def _written_setting(spec: ir.ModelSpec, spans: dict[str, Span], value: object) -> Setting | None:
    """The setting the ``model`` block writes whose value is ``value`` (a ``Fraction``: the block's
    numbers are exact, the scenario's are floats), or None."""
    if not isinstance(value, Fraction):
        return None
    return next((setting for name, setting in (*SETTINGS.items(), *MODELLING.items())
                 if f"model:{name}" in spans and getattr(spec, name, None) == value), None)


def representation_span(automaton: ir.Automaton) -> Span | None:
    """Where the `model` block chooses its number representation, what a value beyond int32 points at: its
    `exponent`, else its `base`, else the block itself (both defaults)."""
    spans, spec = automaton.spans, automaton.model
    return spans.get("model:exponent", spans.get("model:base", spec.span if spec is not None else None))


def _overflow(automaton: ir.Automaton, spec: ir.ModelSpec, scenario, failure) -> Diagnostic:
    """E0713 for a significand that overflows int32, with the largest exponent that fits."""

    base, exponent = spec.base, spec.exponent
    spans = automaton.spans
    value = failure.value
    shown = short_number(Fraction(value)) if isinstance(value, (int, Fraction)) else repr(value)
    if "(sense periods)" in failure.what:  # a count of sense periods: the exponent does not matter
        span = spans.get("model:sense_period", spans.get("decl:sample", spec.span))
        return error("E0713", f"the scenario's {failure.what.removesuffix(' (sense periods)')} = {shown} s is "
                     f"{short_count(failure.significand)} sense periods of {short_number(spec.sense_period)} s "
                     "from the ego's start: that count overflows int32", span,
                     notes=[f"the model counts times in sense periods, which must stay within ±{INT32_MAX}"],
                     hints=["use a longer sensing period, or a scenario whose times lie closer to its start"])
    span = representation_span(automaton)
    limit = Fraction(INT32_MAX, base ** exponent)
    notes: list[Note | str] = [
        f"its significand trunc({shown} · {base}^{exponent}) = {short_number(Fraction(failure.significand))} is "
        f"outside int32 [-{INT32_MAX}, {INT32_MAX}], i.e. every value must lie within ±{_decimal(limit)}",
        Note(f"the scenario `{spec.scenario}` is named here", spans.get("model:scenario")),
    ]
    fitting = next((e for e in range(exponent - 1, 0, -1) if _fits(scenario, spec, e)), None)
    setting = _written_setting(spec, spans, value)
    if setting is not None:  # the block's own number (`width 1e30`), not the scenario's: said, and pointed at
        unit = f" {setting.unit}" if setting.unit else ""
        return error("E0713", f"`{setting.name}` {shown}{unit} overflows int32 at base {base}, exponent {exponent}",
                     spans[f"model:{setting.name}"], notes=notes[:1],
                     hints=[f"write a `{setting.name}` within ±{_decimal(limit)}{unit}"
                            + (f", or set `exponent {fitting}` in the `model` block" if fitting is not None else "")])
    if fitting is None:
        hint = (f"no exponent from 1 to {exponent - 1} fits at base {base}: use a smaller `base`, or a "
                "scenario whose coordinates are smaller")
    else:
        scale = Fraction(base) ** fitting
        actions_whole = all((v * scale).denominator == 1 for a in spec.actions for v in (a.low, a.step))
        hint = f"set `exponent {fitting}` in the `model` block (the largest at which every significand of " \
               "this scenario fits)"
        if not actions_whole:
            hint += f"; the actions' ranges and steps must then be multiples of {short_number(1 / scale)}"
    return error("E0713", f"the scenario's {failure.what} = {shown} overflows int32 at base {base}, "
                 f"exponent {exponent}", span, notes=notes, hints=[hint])
