"""The `model` block's scenario, checked against the model: E0712 (cannot load) and E0713 (int32).

:func:`check_scenario` loads the CommonRoad file of a checked automaton's `model` block once
(:func:`rac.model.commonroad.load_scenario`) and builds the model's data from it
(:func:`rac.model.data.build_model_data`), so that ``rac check`` reports, with a span:

* E0712: the file cannot be loaded (missing, not XML, not CommonRoad, an element rac cannot
  represent), or the model's data cannot be built from it; the loader's message names the file
  and the element. Anything else the loader or the builder raises becomes E0712 as well.
* E0713: a value of the scenario (a position, a speed, an obstacle's size, ...) whose
  significand ``trunc(v · base^exponent)`` overflows int32, with the largest exponent that fits.

The loaded :class:`~rac.model.commonroad.Scenario` and :class:`~rac.model.data.ModelData` are returned so
that :class:`rac.compiler.CompileResult` can hand them to the targets without reloading.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass, field, replace
from fractions import Fraction
from typing import TYPE_CHECKING

from rac import ir
from rac.core.diagnostics import Diagnostic, Note, error, short_number
from rac.core.numbers import exact_decimal

if TYPE_CHECKING:
    from rac.model.commonroad import Scenario
    from rac.model.data import ModelData

#: Loaded scenarios by (path, modification time, size): checking several files that share a
#: scenario, or the same file again, reads it once.
_CACHE: dict[tuple[str, int, int], Scenario] = {}
_CACHE_SIZE = 8


@dataclass
class ScenarioCheck:
    """What :func:`check_scenario` found: diagnostics, facts, and what it loaded."""

    diagnostics: list[Diagnostic] = field(default_factory=list)
    facts: list[str] = field(default_factory=list)
    scenario: Scenario | None = None
    data: ModelData | None = None


def _load(path: str) -> Scenario:
    """``load_scenario(path)``, cached while the file is unchanged."""
    from rac.model.commonroad import load_scenario

    try:
        stat = os.stat(path)
        key: tuple[str, int, int] | None = (os.path.abspath(path), stat.st_mtime_ns, stat.st_size)
    except OSError:
        key = None  # the loader reports it
    if key is not None and key in _CACHE:
        return _CACHE[key]
    scenario = load_scenario(path)
    if key is not None:
        if len(_CACHE) >= _CACHE_SIZE:
            _CACHE.pop(next(iter(_CACHE)))
        _CACHE[key] = scenario
    return scenario


def check_scenario(automaton: ir.Automaton) -> ScenarioCheck:
    """Load the scenario of ``automaton``'s `model` block and build the model's data from it."""
    result = ScenarioCheck()
    spec = automaton.model
    if spec is None:
        return result
    scenario_span = automaton.spans.get("model:scenario", spec.span)
    written = spec.scenario

    def cannot_load(message: str, hints: list[str]) -> ScenarioCheck:
        notes = [] if os.path.normpath(written) == spec.scenario_path else \
            [f"`scenario \"{written}\"` is the file `{spec.scenario_path}` (relative to the folder of this file)"]
        result.diagnostics.append(error("E0712", f"cannot load the scenario: {message}", scenario_span,
                                        notes=notes, hints=hints))
        return result

    from rac.model.commonroad import ScenarioError

    try:
        scenario = _load(spec.scenario_path)
    except ScenarioError as failure:
        return cannot_load(str(failure), _load_hints(failure, written))
    except Exception as failure:  # never a traceback: whatever the loader raises is a diagnostic
        return cannot_load(f"{spec.scenario_path}: {_text(failure)}", [_GENERIC_HINT])
    result.scenario = scenario

    from rac.model.data import ModelRangeError, build_model_data, max_significand

    try:
        data = build_model_data(scenario, spec)
    except ModelRangeError as failure:
        if failure.significand is None:
            return cannot_load(f"{spec.scenario_path}: {failure}", [_GENERIC_HINT])
        result.diagnostics.append(_overflow(automaton, spec, scenario, failure))
        return result
    except Exception as failure:
        return cannot_load(f"{spec.scenario_path}: {_text(failure)}", [_GENERIC_HINT])
    result.data = data
    try:
        what, largest = max_significand(scenario, spec)
    except Exception:  # only the fact's detail: the data is built
        what, largest = "", 0
    goal = scenario.goal
    obstacles = len(scenario.obstacles)
    detail = f" (the largest is {what}: {largest})" if what else ""
    result.facts.append(
        f"scenario {written}: {len(scenario.road)} lanelet{'s' if len(scenario.road) != 1 else ''}, "
        f"{obstacles} obstacle{'s' if obstacles != 1 else ''}, goal at t in [{_seconds(goal.time_low)}, "
        f"{_seconds(goal.time_high)}] s; every significand fits int32 at base {spec.base}, exponent "
        f"{spec.exponent}{detail}")
    return result


_GENERIC_HINT = ("rac reads CommonRoad XML files (formats 2018b and 2020a) with commonroad-io; "
                 "docs/scenario.md lists what it supports")


def _load_hints(failure, written: str) -> list[str]:
    if failure.element is None and failure.problem == "does not exist":
        return [f"the path is relative to the folder of this `.ra` file: put `{os.path.basename(written)}` "
                "there, or correct the path"]
    if failure.element is None and failure.problem.startswith("is a directory"):
        return ["name the CommonRoad XML file, not its folder"]
    return [_GENERIC_HINT]


def _text(failure: BaseException) -> str:
    text = str(failure).strip()
    return f"{type(failure).__name__}: {text}" if text else type(failure).__name__


def _seconds(value: float) -> str:
    if math.isinf(value):
        return "∞" if value > 0 else "-∞"
    return short_number(Fraction(repr(float(value))))


def _decimal(value: Fraction) -> str:
    """``value`` as an exact decimal when it has one (base 10: 214748.3647), else shortened."""
    return exact_decimal(value) or short_number(value)


def _fits(scenario, spec: ir.ModelSpec, exponent: int) -> bool:
    from rac.model.data import check_significands

    try:
        return check_significands(scenario, replace(spec, exponent=exponent)) is None
    except Exception:
        return False


def _overflow(automaton: ir.Automaton, spec: ir.ModelSpec, scenario, failure) -> Diagnostic:
    """E0713 for a significand that overflows int32, with the largest exponent that fits."""
    from rac.core.numbers import INT32_MAX

    base, exponent = spec.base, spec.exponent
    spans = automaton.spans
    value = failure.value
    shown = short_number(Fraction(value)) if isinstance(value, (int, Fraction)) else repr(value)
    if "(sense periods)" in failure.what:  # a count of sense periods: the exponent does not matter
        span = spans.get("model:sense_period", spans.get("decl:sample", spec.span))
        return error("E0713", f"the scenario's {failure.what.removesuffix(' (sense periods)')} = {shown} s is "
                     f"{failure.significand} sense periods of {short_number(spec.sense_period)} s from the "
                     "ego's start: that count overflows int32", span,
                     notes=[f"the model counts times in sense periods, which must stay within ±{INT32_MAX}"],
                     hints=["use a longer sensing period, or a scenario whose times lie closer to its start"])
    span = spans.get("model:exponent", spans.get("model:base", spec.span))
    limit = Fraction(INT32_MAX, base ** exponent)
    notes: list[Note | str] = [
        f"its significand trunc({shown} · {base}^{exponent}) = {failure.significand} is outside int32 "
        f"[-{INT32_MAX}, {INT32_MAX}], i.e. every value must lie within ±{_decimal(limit)}",
        Note(f"the scenario `{spec.scenario}` is named here", spans.get("model:scenario")),
    ]
    fitting = next((e for e in range(exponent - 1, 0, -1) if _fits(scenario, spec, e)), None)
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
