"""The ``model`` block: its settings table, their defaults and checks, and the bindings.

:func:`resolve_model` reads the block of one automaton into an :class:`rac.ir.ModelSpec`
(called by :meth:`rac.check.resolve.Resolver.run` with a :class:`rac.check.symbols.ModelContext`).
Settings not written take the defaults of
:data:`SETTINGS` and :data:`ACTIONS` (the paper's values); every problem becomes a
diagnostic with a span:

* E0701 unknown setting, E0702 a value out of range, E0703 ``decide_period`` not a whole
  multiple of ``sense_period``, E0704 ``sense_period`` differs from ``sample every``, E0705
  ``1/granularity`` not a whole number;
* E0706 an action's range (empty, not a whole number of steps, values that are not whole
  significands), E0707 an action other than ``jerk`` and ``turn``;
* E0708 a binding for something that is not an input, E0709 an input without a binding,
  E0710 a binding whose type differs from its input's, E0711 an unknown model function (or a
  known one with the wrong arguments); E0717 an ``allow when`` that is not a condition or reads
  ``prev``; W0726 an ``int`` input bound to a number that need not be whole (bindings cannot round);
  W0731 a horizon that is no whole multiple of ``decide_period`` (the last decision is shorter);
* the modelling choices (:data:`MODELLING`, :data:`WORD_SETTINGS`): ``start_*``, ``offroad_from``,
  ``dynamics`` (a word, E0702 for another), and ``allow when`` (:attr:`rac.ir.ModelSpec.allow`);
* the generic codes where they fit: E0102 an item written twice, E0105 no ``scenario``, E0106
  a second ``model`` block, E0101/E0103/E0201 for names and types inside bindings.

The vocabulary of bindings (and, once a model is attached, of queries) is defined here too.
"""

from __future__ import annotations

import difflib
import math
import os
from dataclasses import dataclass
from fractions import Fraction

from rac import ir
from rac.check.queries import Lowering, model_settings_of, type_word
from rac.check.symbols import ModelContext, Unresolvable
from rac.core.diagnostics import Note, short_count, short_number, warning
from rac.core.numbers import INT32_MAX
from rac.core.source import Span
from rac.ir import expr as ie
from rac.ir.significands import decimal_text, off_grid, vanishing
from rac.ir.vocabulary import (
    ACTIONS,
    MAX_ACTION_PAIRS,
    MAX_ACTION_VALUES,
    MODEL_FUNCTIONS,
    MODELLING,
    NO_PLANNING_PROBLEM,
    SETTINGS,
    WORD_SETTINGS,
    Setting,
    held_value,
)
from rac.lang import ast

__all__ = ["allowed", "resolve_model"]


def allowed(setting: Setting) -> str:
    """A setting's allowed values in words, e.g. "a whole number from 1 to 6"."""
    kind = "a whole number" if setting.whole else "a number"
    low, high = setting.minimum, setting.maximum
    if low is not None and high is not None:
        if setting.exclusive:
            return f"{kind} in ({_num(low)}, {_num(high)}]"
        return f"{kind} from {_num(low)} to {_num(high)}"
    if low is not None:
        return f"{kind} {'>' if setting.exclusive else '>='} {_num(low)}"
    return kind


# ---------------------------------------------------------------- the model block
@dataclass
class _Value:
    value: Fraction
    span: Span | None  # the item that set it; None: the default


class _ModelResolver:
    def __init__(self, r: ModelContext, block: ast.ModelDecl, inputs: tuple[ir.Input, ...],
                 period: Fraction | None, horizon: Fraction | None):
        self.r = r
        self.block = block
        self.inputs = inputs
        self.period = period
        self.horizon = horizon
        self.ok = True
        #: Settings whose written value was rejected: checks that compare them are skipped.
        self.rejected: set[str] = set()
        #: The word-valued settings as written (:data:`WORD_SETTINGS`).
        self.words: dict[str, str] = {}

    def error(self, code: str, message: str, span: Span | None, **kw) -> None:
        self.ok = False
        self.r.scope.error(code, message, span or self.block.span, **kw)

    def constant(self, expr: ast.Expr, what: str) -> Fraction | None:
        try:
            return self.r.constant(expr, what)
        except Unresolvable:
            self.ok = False
            return None

    # ------------------------------------------------------------ the whole block
    def run(self) -> ir.ModelSpec | None:
        scenario = self._scenario()
        values = self._settings()
        actions = self._actions(values)
        bindings = self._bindings(values)
        allow = self._allow()
        if not self.ok or scenario is None:
            return None
        folder = os.path.dirname(scenario.span.file) if scenario.span is not None else ""
        v = {name: item.value for name, item in values.items()}
        return ir.ModelSpec(
            scenario=scenario.path,
            scenario_path=os.path.normpath(os.path.join(folder, scenario.path)),
            base=int(v["base"]),
            exponent=int(v["exponent"]),
            sense_period=v["sense_period"],
            decide_period=v["decide_period"],
            granularity=v["granularity"],
            actions=actions,
            length=v["length"],
            width=v["width"],
            max_acceleration=v["max_acceleration"],
            max_turn=v["max_turn"],
            min_speed=v["min_speed"],
            max_speed=v["max_speed"],
            collision_distance=v["collision_distance"],
            comfort_acceleration=v["comfort_acceleration"],
            comfort_turn=v["comfort_turn"],
            bindings=bindings,
            sensor_error=v["sensor_error"],
            planning_problem=int(v["planning_problem"]),
            dynamics=self.words.get("dynamics", WORD_SETTINGS["dynamics"][0]),
            collision=self.words.get("collision", WORD_SETTINGS["collision"][0]),
            start_x=v.get("start_x"),
            start_y=v.get("start_y"),
            start_heading=v.get("start_heading"),
            start_speed=v.get("start_speed"),
            offroad_from=int(v["offroad_from"]),
            allow=allow,
            span=self.block.span,
        )

    def _twice(self, what: str, span: Span | None, first: Span | None, verb: str = "set") -> None:
        self.error("E0102", f"{what} is {verb} twice in the `model` block", span,
                   notes=[Note(f"first {verb} here", first)], hints=["keep one and delete the other"])

    def _scenario(self) -> ast.ModelScenario | None:
        items = self.block.of(ast.ModelScenario)
        for extra in items[1:]:
            self._twice("`scenario`", extra.span, items[0].span)
        if not items:
            self.error("E0105", "the `model` block has no `scenario`", self.block.span,
                       hints=['name the CommonRoad file, relative to this file\'s folder: '
                              '`scenario "left_turn.xml"`'])
            return None
        if not items[0].path.strip():
            self.error("E0702", "the `scenario` file name is empty", items[0].span,
                       hints=['name the CommonRoad file, e.g. `scenario "left_turn.xml"`'])
            return None
        return items[0]

    # ------------------------------------------------------------ settings
    def _settings(self) -> dict[str, _Value]:
        written: dict[str, ast.ModelSetting] = {}
        values: dict[str, _Value] = {}
        for item in self.block.of(ast.ModelSetting):
            name = item.name.name
            setting = SETTINGS.get(name) or MODELLING.get(name)
            if setting is None and name not in WORD_SETTINGS:
                self._unknown_setting(item)
                continue
            if name in written:
                self._twice(f"`{name}`", item.name.span, written[name].name.span)
                continue
            written[name] = item
            if setting is None:
                self._word(item)
                continue
            value = self.constant(item.value, f"the value of `{name}`")
            if value is None:
                self.rejected.add(name)
                continue
            if not setting.accepts(value):
                self.rejected.add(name)
                unit = f" {setting.unit}" if setting.unit else ""
                self.error("E0702", f"`{name}` must be {allowed(setting)} (found {_num(value)}{unit})",
                           item.value.span, notes=[f"`{name}`: {setting.description}"],
                           hints=[_range_hint(setting)])
                continue
            values[name] = _Value(value, item.span)
        values = self._defaults(values)
        # These checks compare values with each other: they skip values already reported.
        if not self.rejected & {"sense_period", "decide_period", "granularity"}:
            self._check_timing(values)
        if not self.rejected & {"min_speed", "max_speed"}:
            self._check_speeds(values)
        if not self.rejected & {"base", "exponent"}:
            self._check_scale(values)
        if not self.rejected & {"base", "exponent"}:
            self._check_held(values)
        return values

    def _check_scale(self, values: dict[str, _Value]) -> None:
        """E0702 for a ``base`` and ``exponent`` whose scale base^exponent is beyond ``int32``: the model
        holds every real as a 32-bit significand, and the number 1 would not have one (``SCALE``, a 32-bit
        constant of the emitted model, would overflow)."""
        base, exponent = values["base"], values["exponent"]
        if base.value ** int(exponent.value) <= INT32_MAX:
            return
        self.rejected |= {"base", "exponent"}
        fits = next((e for e in range(int(exponent.value) - 1, 0, -1) if base.value ** e <= INT32_MAX), None)
        self.error("E0702", f"base {short_number(base.value)} at exponent {int(exponent.value)} is beyond the 32-bit "
                   "integer range: the model holds a real v as the 32-bit significand trunc(v · base^exponent), "
                   "and even v = 1 would not fit", base.span or exponent.span,
                   notes=[f"base^exponent is {short_number(base.value ** int(exponent.value))}, more than "
                          f"{INT32_MAX}"],
                   hints=[f"`exponent {fits}` is the largest that fits at this base"
                          if fits is not None and exponent.span is not None
                          else "use a smaller base (the default is `base 10`)"])

    def _check_held(self, values: dict[str, _Value]) -> None:
        """E0702 for a positive setting that the model holds as 0: its significand truncates to 0 at
        this base and exponent (``width 0.00001`` at exponent 4), so the model would use 0, not it."""
        base, exponent = int(values["base"].value), int(values["exponent"].value)
        scale = base ** exponent
        self._check_truncated(values, base, exponent)
        for name in vanishing({n: v.value for n, v in values.items() if n not in self.rejected}, scale):
            setting, item = SETTINGS[name], values[name]
            unit = f" {setting.unit}" if setting.unit else ""
            value = decimal_text(item.value)
            which = f"`{name}` {value}{unit}" if item.span is not None else f"the default `{name}` {value}{unit}"
            needed = next((e for e in range(exponent + 1, int(SETTINGS["exponent"].maximum or exponent) + 1)
                           if held_value(name, item.value, base ** e) != 0), None)
            self.error("E0702", f"{which} truncates to 0 at base {base}, exponent {exponent}: the model would use "
                       f"0, and `{name}` must be positive", item.span or values["exponent"].span or values["base"].span,
                       notes=[f"its significand is trunc({value} · {base}^{exponent}) = "
                              f"trunc({decimal_text(item.value * scale)}) = 0",
                              f"`{name}`: {setting.description}"],
                       hints=[f"the smallest positive `{name}` at base {base}, exponent {exponent} is "
                              f"{_fraction_text(Fraction(1, scale))}{unit}: set `{name}` to at least that"
                              + (f", or raise the exponent (`exponent {needed}` holds {value})" if needed else "")])

    def _check_truncated(self, values: dict[str, _Value], base: int, exponent: int) -> None:
        """W0725 for a setting the model holds truncated to a smaller value (``width 4.55555`` at exponent 2
        is 4.55, ``min_speed 0.00001`` at exponent 4 is 0): the model, and every check of it, uses that
        value, not the one written. One warning per written setting, one for the defaults together (they
        change with ``base`` and ``exponent``). A positive setting truncated to 0 is E0702
        (:meth:`_check_held`)."""
        scale = base ** exponent
        defaults: list[str] = []
        vanished = set(vanishing({n: v.value for n, v in values.items() if n not in self.rejected}, scale))
        for name, item in values.items():
            if name in self.rejected or name not in SETTINGS or name in vanished:
                continue
            held = held_value(name, item.value, scale)
            if held == item.value:
                continue
            setting = SETTINGS[name]
            unit = f" {setting.unit}" if setting.unit else ""
            value = decimal_text(item.value)
            if item.span is None:
                defaults.append(f"`{name}` {value}{unit} as {decimal_text(held)}{unit}")
                continue
            needed = next((e for e in range(exponent + 1, int(SETTINGS["exponent"].maximum or exponent) + 1)
                           if held_value(name, item.value, base ** e) == item.value), None)
            self.r.scope.diagnostics.append(warning(
                "W0725", f"`{name}` {value}{unit} is truncated to whole significands at base {base}, exponent "
                f"{exponent}: the model uses {decimal_text(held)}{unit}", item.span,
                notes=[f"its significand is trunc({value} · {base}^{exponent}) = "
                       f"{math.trunc(item.value * scale)}, whole units of {_fraction_text(Fraction(1, scale))}",
                       f"`{name}`: {setting.description}"],
                hints=[f"write `{name} {_fraction_text(held)}` to say what the model uses"
                       + (f", or raise the exponent (`exponent {needed}` holds {value})" if needed else "")]))
        if defaults:
            self.r.scope.diagnostics.append(warning(
                "W0725", f"at base {base}, exponent {exponent} the model holds default settings truncated to whole "
                f"significands: {', '.join(defaults)}", values["base"].span or values["exponent"].span,
                hints=["set them to values that are whole multiples of "
                       f"{_fraction_text(Fraction(1, scale))}, or choose a base and exponent that hold them"]))

    def _word(self, item: ast.ModelSetting) -> None:
        """A setting whose value is one of a few words (:data:`WORD_SETTINGS`), e.g. ``dynamics increments``."""
        name = item.name.name
        words = WORD_SETTINGS[name]
        value = item.value
        if isinstance(value, ast.Name) and value.id in words:
            self.words[name] = value.id
            return
        self.rejected.add(name)
        choices = " or ".join(f"`{name} {w}`" for w in words)
        self.error("E0702", f"`{name}` must be one of the words {', '.join(f'`{w}`' for w in words)}",
                   value.span, hints=[f"write {choices}; the default is `{name} {words[0]}`"])

    def _allow(self) -> ir.Expr | None:
        """``allow when e``: a condition over the model's vocabulary, read one sense period ahead."""
        items = self.block.of(ast.ModelAllow)
        for extra in items[1:]:
            self._twice("`allow when`", extra.span, items[0].span, "written")
        if not items:
            return None
        item = items[0]
        lowering = Lowering(self.r.scope, binding=True)
        got, expr = lowering.typed(item.expr)
        if lowering.failed:
            self.ok = False
            return None
        if got is not None and got != "bool":
            self.error("E0717", f"`allow when` needs a condition, but this is {type_word(got)}", item.expr.span,
                       hints=["compare a value, e.g. `allow when fabs(head) <= 0.2 && !offroad()`"])
            return None
        if expr is not None and self.words.get("collision") == "sticky" and any(
                isinstance(node, ie.Call) and node.name == "collide" for node in ie.walk(expr)):
            self.error("E0717", "with `collision sticky`, `allow when` cannot read `collide()`: the rule is "
                       "checked on the state an action would lead to, which carries no run history",
                       item.expr.span, hints=["compare `mindist()` with `collision_distance` instead"])
            return None
        if expr is not None and ie.prev_operands([expr]):
            self.error("E0717", "`allow when` cannot read `prev(...)`: the rule is checked on the state each "
                       "action would lead to, before the model takes that sample (it keeps `prev` only "
                       "while reading the inputs)", item.expr.span,
                       hints=["compare the next state's values with constants, e.g. `fabs(head) <= 0.2`"])
            return None
        return expr

    def _unknown_setting(self, item: ast.ModelSetting) -> None:
        name = item.name.name
        hints = []
        close = difflib.get_close_matches(name, [*SETTINGS, *MODELLING, *WORD_SETTINGS], n=1)
        if name in ACTIONS:
            low, high, step, _ = ACTIONS[name]
            hints.append(f"an action is declared with its range: `action {name} in [{_num(low)}, {_num(high)}] "
                         f"step {_num(step)}`")
        elif name in self.r.scope.symbols and self.r.scope.symbols[name].kind == "input":
            hints.append(f"an input is bound with `bind`: `bind {name} = ...`")
        elif close:
            hints.append(f"did you mean `{close[0]}`?")
        else:
            hints.append("the settings are " + ", ".join(f"`{s}`" for s in (*SETTINGS, *MODELLING, *WORD_SETTINGS)))
        self.error("E0701", f"unknown setting `{name}` in the `model` block", item.name.span, hints=hints)

    def _defaults(self, values: dict[str, _Value]) -> dict[str, _Value]:
        """Every setting: the written ones, else their defaults (derived ones from the timing;
        ``planning_problem`` :data:`NO_PLANNING_PROBLEM`, none chosen)."""
        result = dict(values)
        for name, setting in (*SETTINGS.items(), *MODELLING.items()):
            if name in result:
                continue
            if name in MODELLING:  # absent: the scenario's value, or the default
                if setting.default is not None:
                    result[name] = _Value(setting.default, None)
                continue
            if setting.default is not None:
                result[name] = _Value(setting.default, None)
            elif name == "planning_problem":
                result[name] = _Value(Fraction(NO_PLANNING_PROBLEM), None)
            elif name == "sense_period":
                result[name] = _Value(self.period if self.period is not None else Fraction(1, 10), None)
            else:  # decide_period
                result[name] = _Value(2 * result["sense_period"].value, None)
        return result

    def _check_timing(self, values: dict[str, _Value]) -> None:
        sense, decide, granularity = values["sense_period"], values["decide_period"], values["granularity"]
        if sense.span is not None and self.period is not None and sense.value != self.period:
            sample = self.r.automaton.of(ast.SampleDecl)
            self.error("E0704", f"`sense_period` ({_num(sense.value)} s) differs from `sample every` "
                       f"({_num(self.period)} s)", sense.span,
                       notes=[Note("the automaton samples here", sample[0].span if sample else None)],
                       hints=["the automaton reads its inputs at every sensing instant: remove "
                              "`sense_period` (it defaults to `sample every`), or change `sample every`"])
        ratio = decide.value / sense.value
        if ratio.denominator != 1 and (sense.span is not None or self.period is not None):
            below = int(ratio) * sense.value
            choices = [f"`decide_period {_num(c)}`" for c in (below, below + sense.value) if c > 0]
            self.error("E0703", f"`decide_period` ({_num(decide.value)} s) is not a whole multiple of "
                       f"`sense_period` ({_num(sense.value)} s)",
                       decide.span or sense.span,
                       notes=[] if decide.span else [f"`decide_period` defaults to 2 × `sense_period` = "
                                                     f"{_num(decide.value)} s"],
                       hints=["the controller decides at sensing instants only: use " + " or ".join(choices)])
        elif ratio.denominator == 1 and (sense.span is None or self.period is None or sense.value == self.period):
            self._check_last_decision(sense, decide)
        substeps = 1 / granularity.value
        if substeps.denominator != 1:
            n = int(substeps)
            choices = [f"`granularity {_fraction_text(Fraction(1, k))}`" for k in (n, n + 1) if k >= 1]
            self.error("E0705", f"`granularity` {_num(granularity.value)} does not divide the sensing period "
                       f"into whole sub-steps (1/G = {_num(substeps)})", granularity.span,
                       hints=["`sense()` takes 1/G Euler sub-steps: use " + " or ".join(choices)])

    def _check_last_decision(self, sense: _Value, decide: _Value) -> None:
        """W0731 for a horizon that is a whole number of samples but no whole multiple of ``decide_period``:
        every run ends at the horizon, so its last decision holds for fewer samples than the others (a
        learner's last step is shorter, its reward summed over fewer samples). Allowed: the model's runs
        end there too; said, since nothing else does."""
        horizon, declared = self.horizon, self.r.automaton.of(ast.HorizonDecl)
        if horizon is None or not declared or (horizon / sense.value).denominator != 1:
            return  # no horizon, or one of no whole number of samples (E0206)
        left = horizon % decide.value
        if left == 0:
            return
        below = horizon - left
        choices = [f"`horizon {_num(h)}`" for h in (below, below + decide.value) if h > 0]
        samples = int(decide.value / sense.value)
        notes = [f"a run ends at the horizon, so the controller's last choice holds for {_num(left)} s "
                 f"({int(left / sense.value)} of the {samples} sensing periods of a decision) in every run of "
                 "`rac verify`, `simulate`, `render`, `preanalyse` and `experiment`"]
        if decide.span is None:
            notes.append(f"`decide_period` defaults to 2 × `sense_period` = {_num(decide.value)} s")
        self.r.scope.diagnostics.append(warning(
            "W0731", f"the horizon ({_num(horizon)} s) is not a whole multiple of `decide_period` "
            f"({_num(decide.value)} s): the last decision is shorter than the others", declared[0].span,
            notes=notes,
            hints=[f"for decisions of one length use {' or '.join(choices)}"
                   + (", or a `decide_period` that divides the horizon" if decide.span is not None else "")]))

    def _check_speeds(self, values: dict[str, _Value]) -> None:
        low, high = values["min_speed"], values["max_speed"]
        if low.value >= high.value:
            span = high.span or low.span
            self.error("E0702", f"`max_speed` ({_num(high.value)} m/s) must be more than `min_speed` "
                       f"({_num(low.value)} m/s)", span,
                       notes=[f"`{n}` defaults to {_num(Fraction(SETTINGS[n].default or 0))} m/s"
                              for n, v in (("min_speed", low), ("max_speed", high)) if v.span is None],
                       hints=["the speed range is [`min_speed`, `max_speed`]"])

    # ------------------------------------------------------------ actions
    def _actions(self, values: dict[str, _Value]) -> tuple[ir.Action, ...]:
        written: dict[str, ast.ModelAction] = {}
        result: dict[str, ir.Action] = {}
        for item in self.block.of(ast.ModelAction):
            name = item.name.name
            if name not in ACTIONS:
                close = difflib.get_close_matches(name, list(ACTIONS), n=1)
                self.error("E0707", f"unknown action `{name}`", item.name.span,
                           hints=[f"did you mean `{close[0]}`?" if close else
                                  "the vehicle has two actions, `jerk` (m/s³) and `turn` (rad/s)"])
                continue
            if name in written:
                self._twice(f"action `{name}`", item.name.span, written[name].name.span, "declared")
                continue
            written[name] = item
            low = self.constant(item.low, f"the range of action `{name}`")
            high = self.constant(item.high, f"the range of action `{name}`")
            step = self.constant(item.step, f"the step of action `{name}`")
            if low is None or high is None or step is None:
                continue
            action = self._check_action(item, ir.Action(name, low, high, step))
            if action is not None:
                result[name] = action
        for name, (low, high, step, _) in ACTIONS.items():
            if name not in written:
                result[name] = ir.Action(name, low, high, step)
        if len(result) == len(ACTIONS) and written and not self._check_pairs(result, written):
            return tuple(result[name] for name in ACTIONS)
        if not self.rejected & {"base", "exponent"} and len(result) == len(ACTIONS):
            self._check_significands(result, written, values)
        return tuple(result[name] for name in ACTIONS if name in result)

    def _check_action(self, item: ast.ModelAction, action: ir.Action) -> ir.Action | None:
        name, low, high, step = action.name, action.low, action.high, action.step
        shown = f"[{_num(low)}, {_num(high)}]"
        if low > high:
            self.error("E0706", f"empty range {shown} for action `{name}`", item.span,
                       hints=["write the lower bound first"])
        elif step <= 0:
            self.error("E0706", f"the step of action `{name}` must be positive (found {_num(step)})",
                       item.step.span, hints=["the step is the distance between two values of the action, e.g. "
                                              "`step 0.5`"])
        elif ((high - low) / step).denominator != 1:
            count = int((high - low) / step)
            self.error("E0706", f"the range {shown} of action `{name}` is not a whole number of steps of "
                       f"{_num(step)}", item.span,
                       notes=[f"{_num(high - low)} / {_num(step)} = {_num((high - low) / step)}"],
                       hints=[f"end the range at {_num(low + count * step)} or {_num(low + (count + 1) * step)}, "
                              "or choose a step that divides its width"])
        elif action.count > MAX_ACTION_VALUES:
            self.error("E0901", f"action `{name}` in {shown} step {_num(step)} offers "
                       f"{short_count(action.count)} values, more than the limit of {MAX_ACTION_VALUES:,}", item.span,
                       notes=["the controller chooses among every value at every decision: each one is a "
                              "column of the engine's tables and of the UPPAAL model"],
                       hints=[f"choose a coarser step or a narrower range, e.g. step "
                              f"{_num(_coarser(low, high, MAX_ACTION_VALUES))}"])
        else:
            return action
        return None

    def _check_pairs(self, actions: dict[str, ir.Action], written: dict[str, ast.ModelAction]) -> bool:
        """E0901 when the actions together offer more than :data:`MAX_ACTION_PAIRS` pairs."""
        counts = [actions[name].count for name in ACTIONS]
        pairs = math.prod(counts)
        if pairs <= MAX_ACTION_PAIRS:
            return True
        item = list(written.values())[-1]  # the action written last makes the grid too large
        self.error("E0901", f"the actions offer {pairs:,} ({', '.join(ACTIONS)}) pairs "
                   f"({' × '.join(map(str, counts))}), more than the limit of {MAX_ACTION_PAIRS:,}", item.span,
                   notes=["the controller chooses one pair at every decision: every explored state and every "
                          "simulated decision holds a mask over the pairs"],
                   hints=["choose coarser steps or narrower ranges"])
        return False

    def _check_significands(self, actions: dict[str, ir.Action], written: dict[str, ast.ModelAction],
                            values: dict[str, _Value]) -> None:
        """Every action value must be a whole significand: the controller chooses among significands."""
        base, exponent = int(values["base"].value), int(values["exponent"].value)
        scale = Fraction(base) ** exponent
        for name, action in actions.items():
            bad = off_grid(action, scale)
            if bad is None:
                continue
            item = written.get(name)
            span = item.span if item is not None else values["exponent"].span or values["base"].span
            which = "" if item is not None else "the default "
            self.error("E0706", f"{which}action `{name}` in [{_num(action.low)}, {_num(action.high)}] step "
                       f"{_num(action.step)} does not fall on whole significands at base {base}, exponent "
                       f"{exponent}", span,
                       notes=[f"{_num(bad)} · {base}^{exponent} = {_num(bad * scale)} is not a whole number: "
                              "the controller chooses among significands"],
                       hints=["use a range and step that are multiples of "
                              f"{_fraction_text(1 / scale)}, or raise the exponent"])

    # ------------------------------------------------------------ bindings
    def _check_whole(self, item: ast.ModelBinding, expr: ie.Expr, values: dict[str, _Value]) -> None:
        """W0726 for an ``int`` input bound to a number that need not be whole (``bind n = v``): bindings
        cannot round, so the model feeds the input significands between whole numbers, which ``rac verify``
        and the emitted UPPAAL model read as they are, while ``rac check``'s analysis of the automaton takes
        the input to be whole (``n > 8 && n < 9`` never holds there) and the Python runtime refuses them.
        A warning, as a binding beyond the input's declared range is not an error: the model's answers
        stay right, the automaton's analysis does not describe them."""
        declared = next((i for i in self.inputs if i.name == item.input.name), None)
        if declared is None or declared.kind != "int" or _whole(expr, values["sense_period"].value):
            return
        base, exponent = int(values["base"].value), int(values["exponent"].value)
        bounds = f" in [{_num(declared.low)}, {_num(declared.high)}]" \
            if declared.low is not None and declared.high is not None else ""
        self.r.scope.diagnostics.append(warning(
            "W0726", f"input `{declared.name}` is an `int`, but its binding need not be a whole number",
            item.expr.span,
            notes=[Note(f"`{declared.name}` is declared here", declared.span),
                   f"bindings cannot round: the model feeds `{declared.name}` its value in whole significands at "
                   f"base {base}, exponent {exponent} (steps of {_fraction_text(Fraction(1, base ** exponent))}), "
                   "which `rac verify` and the emitted UPPAAL model read as it is",
                   f"`rac check` analyses `{declared.name}` as a whole number, so its verdicts over the automaton "
                   "(reachable locations, edges that fire) may not hold in the model, and the Python runtime "
                   "refuses a value that is not whole"],
            hints=[f"declare the input `real`: `input {declared.name} : real{bounds}`"]))

    def _bindings(self, values: dict[str, _Value]) -> tuple[ir.Binding, ...]:
        bound: dict[str, ast.ModelBinding] = {}
        lowered: dict[str, ir.Binding] = {}
        suggested: set[str] = set()  # inputs a misspelt binding probably meant: not reported unbound
        scale = int(values["base"].value) ** int(values["exponent"].value)
        self.r.scope.settings = model_settings_of({n: v.value for n, v in values.items()}, scale)
        for item in self.block.of(ast.ModelBinding):
            name = item.input.name
            symbol = self.r.scope.symbols.get(name)
            lowering = Lowering(self.r.scope, binding=True)
            got, expr = lowering.typed(item.expr)
            if lowering.failed:
                self.ok = False
            if symbol is None or symbol.kind != "input":
                inputs = [i.name for i in self.inputs]
                close = difflib.get_close_matches(name, inputs, n=1)
                suggested.update(close)
                what = f"unknown input `{name}`" if symbol is None else \
                    f"`{name}`, which is {_kind(symbol.kind)}, not an input"
                self.error("E0708", f"`bind` names {what}", item.input.span,
                           hints=[f"did you mean `{close[0]}`?" if close else
                                  "bindings drive the automaton's inputs: "
                                  + (", ".join(f"`{i}`" for i in inputs) or "it declares none")])
                continue
            if name in bound:
                self._twice(f"input `{name}`", item.input.span, bound[name].input.span, "bound")
                continue
            bound[name] = item
            if got is not None and got != symbol.type:
                declared = next((i for i in self.inputs if i.name == name), None)
                kind = f" ({declared.kind})" if declared is not None and not declared.is_bool else ""
                self.error("E0710", f"input `{name}` is {type_word(symbol.type)}{kind}, but its binding is "
                           f"{type_word(got)}", item.expr.span,
                           notes=[Note(f"`{name}` is declared here", symbol.span)],
                           hints=["compare the value to get a condition, e.g. `mindist() < 3 * collision_distance`"
                                  if symbol.type == "bool" else
                                  "a numeric input needs a number, e.g. `dist_goal()`"])
            elif expr is not None:
                lowered[name] = ir.Binding(name, expr, item.span)
                self._check_whole(item, expr, values)
        for item in self.inputs:
            if item.name not in bound and item.name not in suggested:
                example = _binding_example(item.name, item.is_bool)
                self.error("E0709", f"input `{item.name}` has no binding in the `model` block", item.span,
                           notes=[Note("the `model` block", self.block.span)],
                           hints=["with a model, every input is computed from it: add "
                                  f"`bind {item.name} = ...` to the block, e.g. `bind {item.name} = {example}`"])
        return tuple(lowered[i.name] for i in self.inputs if i.name in lowered)


def _binding_example(name: str, is_bool: bool) -> str:
    """An example binding for an unbound input: the model function of its type the input is named
    after (``collide`` -> ``collide()``, ``atGoal`` -> ``goal()``, ``dgoal`` -> ``dist_goal()``), else
    the usual one. A user who named an input after a predicate most likely means that predicate."""
    wanted = "bool" if is_bool else "num"
    lowered = name.lower().replace("_", "")
    named = [f for f in MODEL_FUNCTIONS.values() if f.result == wanted and f.name.replace("_", "") in lowered]
    if not named and not is_bool and "goal" in lowered:
        named = [MODEL_FUNCTIONS["dist_goal"]]
    if named:
        return max(named, key=lambda f: len(f.name)).signature
    return "mindist() < 3 * collision_distance" if is_bool else "dist_goal()"


def _whole(expr: ie.Expr, period: Fraction) -> bool:
    """Whether a numeric binding's value is a whole number at every sample, whatever the model's state:
    whole constants and settings, ``time`` when the sensing period is whole, and what ``+``, ``-``, ``*``,
    ``prev``, ``fabs``/``abs``, ``fmin`` and ``fmax`` make of whole numbers. Sound, not complete: anything
    else (the ego's state, ``mindist()``, ``dist_goal()``, ``/``, ``sqrt``) may not be."""
    if isinstance(expr, ie.Const):
        return not isinstance(expr.value, bool) and expr.value.denominator == 1
    if isinstance(expr, ie.Ref):
        if expr.value is not None:  # a setting, as the model holds it
            return expr.value.denominator == 1
        return expr.is_model and expr.model.kind == "time" and period.denominator == 1
    if isinstance(expr, ie.Unary):
        return expr.op == "-" and _whole(expr.operand, period)
    if isinstance(expr, ie.Binary):
        return expr.op in ("+", "-", "*") and _whole(expr.left, period) and _whole(expr.right, period)
    if isinstance(expr, ie.Prev):
        return _whole(expr.operand, period)
    if isinstance(expr, ie.Call):
        return expr.name in ("fabs", "abs", "fmin", "fmax") and all(_whole(arg, period) for arg in expr.args)
    return False


def resolve_model(r: ModelContext, inputs: tuple[ir.Input, ...], period: Fraction | None,
                  horizon: Fraction | None = None) -> ir.ModelSpec | None:
    """The automaton's ``model`` block as a :class:`ModelSpec`; None without one or on errors. ``horizon``
    (the file's, in seconds) is checked against the decision period (W0731)."""
    blocks = r.automaton.of(ast.ModelDecl)
    if not blocks:
        return None
    for extra in blocks[1:]:
        r.scope.error("E0106", "`model` is declared more than once", extra.span,
                 notes=[Note("first declared here", blocks[0].span)],
                 hints=["an automaton has one model: merge the blocks"])
    resolver = _ModelResolver(r, blocks[0], inputs, period, horizon)
    spec = resolver.run()
    for item in blocks[0].of(ast.ModelSetting):  # where each setting is written (the scenario's checks point there)
        if (item.name.name in SETTINGS or item.name.name in MODELLING) and item.span is not None:
            r.spans.setdefault(f"model:{item.name.name}", item.span)
    for scenario in blocks[0].of(ast.ModelScenario)[:1]:
        if scenario.span is not None:
            r.spans["model:scenario"] = scenario.span
    return spec if resolver.ok else None


# ---------------------------------------------------------------- words
def _num(value: Fraction) -> str:
    return short_number(value)


def _coarser(low: Fraction, high: Fraction, most: int) -> Fraction:
    """A round step (1, 2 or 5 times a power of ten) that splits ``[low, high]`` into at most ``most - 1``
    steps: the hint's example of a grid within the limit."""
    width = high - low
    scale = Fraction(10) ** math.floor(math.log10(max(float(width / (most - 1)), 1e-12)))
    return next(scale * k for k in (1, 2, 5, 10, 20, 50) if width / (scale * k) <= most - 1)


def _fraction_text(value: Fraction) -> str:
    """A value as the user would write it: a decimal when exact, else ``1/3``."""
    text = short_number(value)
    return text if not text.endswith("…") else f"{value.numerator}/{value.denominator}"


def _range_hint(setting: Setting) -> str:
    if setting.default is not None:
        return f"use {allowed(setting)}; the default is `{setting.name} {_num(setting.default)}`"
    return f"use {allowed(setting)}; without it, `{setting.name}` is {setting.derived}"


def _arguments(count: int) -> str:
    return "no arguments" if count == 0 else "1 argument" if count == 1 else f"{count} arguments"


def _kind(kind: str) -> str:
    return {"input": "an input", "const": "a constant", "reward": "a reward", "location": "a location"}[kind]

