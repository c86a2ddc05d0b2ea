"""The scenario model's vocabulary: the one table of what bindings and queries may read.

Besides the automaton's own names (inputs, rewards, locations, constants), a binding or a query
of a file with a ``model`` block reads the names and functions of the scenario model (model.md).
Each entry here says what the name is, its type and unit, and how the model holds it, which fixes
its value in every target:

- ``SIGNIFICAND``: an int32 significand ``s`` standing for ``s / SCALE`` (Eq. (1)). The sensed ego
  state, and every setting the model computes with (``length``, ``max_speed``, ``collision_distance``
  ...: ``length 4.55555`` at exponent 4 is held as 45555, so ``length`` reads 4.5555 — the length
  that ``collide()`` and ``sense_state()`` use). As a double it is ``s / SCALE_D`` (UPPAAL and C:
  ``i2d(s)``; the engine: the same division); compared with constants it is exact on ``s``.
- ``EXACT``: a setting the model does not compute with (``base``, the periods, ``sensor_error``):
  its rational value, read as the nearest double.
- ``TRUTH``: the ground truth (the ``Dynamics`` process's hybrid clocks in UPPAAL, the fine
  integrator in the engine): statistical queries only.
- ``TIME``: the time of the current sample, ``k * C1``. The emitted model reads it from the sample
  counter ``count`` in bindings and queries alike (its global clock ``time`` flows between samples).

The printers and evaluators of every target read this table, not their own copies.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from enum import Enum
from fractions import Fraction

from rac.core.numbers import INT32_MAX

__all__ = [
    "DEFAULT_BASE",
    "DEFAULT_EXPONENT",
    "MAX_ACTION_PAIRS",
    "MAX_ACTION_VALUES",
    "ACTIONS",
    "BINDING_MATH",
    "EGO_STATE",
    "FUNCTIONS",
    "MATH_FUNCTIONS",
    "MODEL_FUNCTIONS",
    "MODEL_NAMES",
    "NO_PLANNING_PROBLEM",
    "MODELLING",
    "SETTINGS",
    "WORD_SETTINGS",
    "TRUE_STATE",
    "held_value",
    "Function",
    "Holding",
    "ModelName",
    "Setting",
]


# ---------------------------------------------------------------- settings of the model block
@dataclass(frozen=True)
class Setting:
    """One setting of the ``model`` block: ``name value``."""

    name: str
    #: The value when the setting is not written; None: derived (see :attr:`derived`).
    default: Fraction | None
    unit: str
    description: str
    minimum: Fraction | None = None
    #: The value must exceed ``minimum`` (else: be at least ``minimum``).
    exclusive: bool = False
    maximum: Fraction | None = None
    whole: bool = False
    #: How the default is derived when ``default`` is None.
    derived: str = ""

    def accepts(self, value: Fraction) -> bool:
        if self.whole and value.denominator != 1:
            return False
        if self.minimum is not None and (value <= self.minimum if self.exclusive else value < self.minimum):
            return False
        return self.maximum is None or value <= self.maximum


def _f(text: str) -> Fraction:
    return Fraction(text)


#: ``planning_problem`` when the block does not write it: CommonRoad ids are positive, so 0 chooses
#: none, and the scenario must have exactly one planning problem (E0715 lists them otherwise).
NO_PLANNING_PROBLEM = 0


#: Every setting, in the order of :class:`rac.ir.ModelSpec` (docs/language.md shows this table).
SETTINGS: dict[str, Setting] = {s.name: s for s in (
    Setting("base", _f("10"), "", "base of the number representation", _f("2"), whole=True),
    Setting("exponent", _f("4"), "", "a real v is held as the integer significand trunc(v · base^exponent)",
            _f("1"), maximum=_f("6"), whole=True),
    Setting("sense_period", None, "s", "C1, the sensing period", _f("0"), exclusive=True,
            derived="the automaton's `sample every`"),
    Setting("decide_period", None, "s", "C2, the decision period: a whole multiple of C1", _f("0"),
            exclusive=True, derived="2 × `sense_period`"),
    Setting("granularity", _f("0.25"), "", "G: `sense()` integrates in 1/G Euler sub-steps of C1 · G",
            _f("0.001"), maximum=_f("1")),
    Setting("length", _f("4.5"), "m", "length of the ego vehicle", _f("0"), exclusive=True),
    Setting("width", _f("1.8"), "m", "width of the ego vehicle", _f("0"), exclusive=True),
    Setting("max_acceleration", _f("3"), "m/s²", "MA, the largest acceleration", _f("0"), exclusive=True),
    Setting("max_turn", _f("0.4"), "rad/s", "MT, the largest turning rate", _f("0"), exclusive=True),
    Setting("min_speed", _f("0"), "m/s", "the lowest speed", _f("0")),
    Setting("max_speed", _f("20"), "m/s", "the highest speed (more than `min_speed`)", _f("0"), exclusive=True),
    Setting("collision_distance", _f("0.5"), "m", "TD: `collide()` holds below this distance", _f("0"),
            exclusive=True),
    Setting("comfort_acceleration", _f("0.8"), "", "p1, the comfortable fraction of MA", _f("0"),
            exclusive=True, maximum=_f("1")),
    Setting("comfort_turn", _f("0.8"), "", "p2, the comfortable fraction of MT", _f("0"), exclusive=True,
            maximum=_f("1")),
    Setting("sensor_error", _f("0.5"), "m", "THD: the sensor-error threshold of query Qa", _f("0"), exclusive=True),
    Setting("planning_problem", None, "", "the id of the CommonRoad planning problem the ego's start and goal "
            "come from", _f("1"), whole=True, derived=f"{NO_PLANNING_PROBLEM}: none chosen, the scenario's only one"),
)}
#: Settings that choose how the model moves, not values an expression reads (docs/language.md,
#: "Modelling choices"): numbers whose absent value means "the scenario's" (``default`` None) or
#: the stated default.
MODELLING: dict[str, Setting] = {s.name: s for s in (
    Setting("start_x", None, "m", "the ego's start x", derived="the planning problem's initial state"),
    Setting("start_y", None, "m", "the ego's start y", derived="the planning problem's initial state"),
    Setting("start_heading", None, "rad", "the ego's start heading", derived="the planning problem's initial state"),
    Setting("start_speed", None, "m/s", "the ego's start speed", _f("0"),
            derived="the planning problem's initial state"),
    # a sample number: the model (and UPPAAL's `OFFROAD_FROM`) holds it in int32
    Setting("offroad_from", _f("0"), "samples", "`offroad()` is false before this sample (1: the start is "
            "not checked)", _f("0"), maximum=Fraction(INT32_MAX), whole=True),
)}
#: Settings whose value is a word: name -> the words, the default first.
WORD_SETTINGS: dict[str, tuple[str, ...]] = {
    # integrated: sense() integrates doubles and truncates the result (Algorithm 1);
    # increments: every sub-step adds truncated increments to the integer state (CommonUppRoad).
    "dynamics": ("integrated", "increments"),
    # instant: collide() is this sample's test; sticky: once it held, it holds for the rest of the run
    # (CommonUppRoad's `collide |= check_collision(...)`).
    "collision": ("instant", "sticky"),
}
#: The number representation of a model that does not set ``base`` and ``exponent``.
DEFAULT_BASE = int(SETTINGS["base"].default or 10)
DEFAULT_EXPONENT = int(SETTINGS["exponent"].default or 4)

#: The most values one action may offer (``action NAME in [LOW, HIGH] step S``, E0901): every value
#: is a column of the engine's action tables and a UPPAAL ``select`` value, and a grid is checked
#: by counting it (exact arithmetic on low, high and step), never by listing it.
MAX_ACTION_VALUES = 1_000
#: The most (jerk, turn) pairs the actions may offer together (E0901): every explored state and every
#: simulated decision holds a mask over the pairs.
MAX_ACTION_PAIRS = 10_000

#: The controller's actions and their defaults: (low, high, step, unit).
ACTIONS: dict[str, tuple[Fraction, Fraction, Fraction, str]] = {
    "jerk": (_f("-2"), _f("2"), _f("0.5"), "m/s³"),
    "turn": (_f("-0.4"), _f("0.4"), _f("0.1"), "rad/s"),
}


# ---------------------------------------------------------------- names
class Holding(Enum):
    """How the model holds a name's value (see the module docstring)."""

    SIGNIFICAND = "significand"
    EXACT = "exact"
    TRUTH = "truth"
    TIME = "time"


@dataclass(frozen=True)
class ModelName:
    """A name of the scenario model that bindings and queries read (all are numbers)."""

    name: str
    kind: str  # "ego" (sensed state), "truth" (ground truth), "setting", "time"
    unit: str
    description: str
    holding: Holding
    #: Where the engine reads it: the ego column (:data:`EGO_STATE` order), the truth column
    #: (:data:`TRUE_STATE` order) or the :class:`rac.model.ModelData` field of a significand setting.
    engine: str = ""
    #: The name that holds it in the emitted UPPAAL model (a global, a constant, a clock of the
    #: ``Dynamics`` process); "" when it is printed as a literal.
    uppaal: str = ""
    #: Bindings may read it (the ground truth is for queries only).
    in_bindings: bool = True


_EGO = (
    ("x", "m", "the sensed x position"), ("y", "m", "the sensed y position"), ("v", "m/s", "the sensed speed"),
    ("acc", "m/s²", "the sensed acceleration"), ("head", "rad", "the sensed heading"),
    ("jerk", "m/s³", "the chosen jerk"), ("turn", "rad/s", "the chosen turning rate"),
)
#: Settings the model holds as significands: setting -> (ModelData field, UPPAAL constant).
_SIGNIFICAND_SETTINGS = {
    "length": ("length", "LENGTH"), "width": ("width", "WIDTH"), "max_acceleration": ("max_acc", "MAX_ACC"),
    "max_turn": ("max_turn", "MAX_TURN"), "min_speed": ("min_speed", "MIN_SPEED"),
    "max_speed": ("max_speed", "MAX_SPEED"), "collision_distance": ("td", "TD"),
    "comfort_acceleration": ("p1", "P1"), "comfort_turn": ("p2", "P2"),
}
#: Settings held as exact values that the emitted model declares under a name.
_NAMED_EXACT = {"sensor_error": "THD", "sense_period": "SENSE_PERIOD_S"}


def _names() -> dict[str, ModelName]:
    names: dict[str, ModelName] = {}
    for name, unit, description in _EGO:
        names[name] = ModelName(name, "ego", unit, description, Holding.SIGNIFICAND, engine=name, uppaal=name)
    for name, unit, description in _EGO[:5]:
        true = f"true_{name}"
        names[true] = ModelName(true, "truth", unit, description.replace("sensed", "true"), Holding.TRUTH,
                                engine=name, uppaal=true, in_bindings=False)
    names["time"] = ModelName("time", "time", "s", "the time of the current sample, k · C1", Holding.TIME,
                              uppaal="time")
    for setting in SETTINGS.values():
        if setting.name in _SIGNIFICAND_SETTINGS:
            field, constant = _SIGNIFICAND_SETTINGS[setting.name]
            names[setting.name] = ModelName(setting.name, "setting", setting.unit, setting.description,
                                            Holding.SIGNIFICAND, engine=field, uppaal=constant)
        else:
            names[setting.name] = ModelName(setting.name, "setting", setting.unit, setting.description,
                                            Holding.EXACT, uppaal=_NAMED_EXACT.get(setting.name, ""))
    return names


#: Every name of the scenario model, by its ``.ra`` name.
MODEL_NAMES: dict[str, ModelName] = _names()
#: The ego vehicle's sensed state (significands), in the engine's column order.
EGO_STATE: tuple[str, ...] = tuple(n for n, m in MODEL_NAMES.items() if m.kind == "ego")
#: The ego vehicle's true state (the continuous dynamics): queries only.
TRUE_STATE: tuple[str, ...] = tuple(n for n, m in MODEL_NAMES.items() if m.kind == "truth")


# ---------------------------------------------------------------- functions
@dataclass(frozen=True, repr=False)
class Function:
    """A function bindings and queries may call."""

    name: str
    arity: int
    #: "bool" or "num"; None: the type of its argument (``prev(e)``).
    result: str | None
    kind: str  # "model" (of the scenario model) or "math"
    description: str
    #: Its name in UPPAAL and C (``abs`` is ``fabs``: UPPAAL's ``abs`` takes integers only).
    uppaal: str
    #: Bindings may call it (queries may call every function).
    in_bindings: bool = True
    #: How it is written in messages, e.g. ``fmin(a, b)``.
    signature: str = ""
    #: The unit of a model function's number (``mindist()``: ``"m"``); "" for truth values, for
    #: ``prev`` and the math functions (their unit is their arguments', :func:`rac.ir.expr.unit_of`).
    unit: str = ""

    def __repr__(self) -> str:
        return f"Function({self.name!r})"


MODEL_FUNCTIONS: dict[str, Function] = {f.name: f for f in (
    Function("collide", 0, "bool", "model", "the ego is closer than TD to an obstacle", "collide",
             signature="collide()"),
    Function("offroad", 0, "bool", "model", "part of the ego is off the road", "offroad", signature="offroad()"),
    Function("goal", 0, "bool", "model", "the ego is in the goal region, within its time interval", "goal",
             signature="goal()"),
    Function("mindist", 0, "num", "model", "the distance to the nearest obstacle (m)", "mindist",
             signature="mindist()", unit="m"),
    Function("dist_goal", 0, "num", "model", "the distance to the goal's centre (m)", "dist_goal",
             signature="dist_goal()", unit="m"),
    Function("prev", 1, None, "model", "the value of e at the previous sample", "", signature="prev(e)"),
)}
MATH_FUNCTIONS: dict[str, Function] = {f.name: f for f in (
    Function("fabs", 1, "num", "math", "absolute value", "fabs", signature="fabs(e)"),
    Function("abs", 1, "num", "math", "absolute value", "fabs", signature="abs(e)"),
    Function("sqrt", 1, "num", "math", "square root", "sqrt", signature="sqrt(e)"),
    Function("fmin", 2, "num", "math", "the smaller of two numbers", "fmin", signature="fmin(a, b)"),
    Function("fmax", 2, "num", "math", "the larger of two numbers", "fmax", signature="fmax(a, b)"),
    Function("floor", 1, "num", "math", "rounded down", "floor", in_bindings=False, signature="floor(e)"),
    Function("ceil", 1, "num", "math", "rounded up", "ceil", in_bindings=False, signature="ceil(e)"),
    Function("round", 1, "num", "math", "rounded half away from zero", "round", in_bindings=False,
             signature="round(e)"),
    Function("trunc", 1, "num", "math", "rounded towards zero", "trunc", in_bindings=False, signature="trunc(e)"),
)}
#: Every function, by name.
FUNCTIONS: dict[str, Function] = {**MODEL_FUNCTIONS, **MATH_FUNCTIONS}
#: The arithmetic functions a binding may call.
BINDING_MATH: tuple[str, ...] = tuple(n for n, f in MATH_FUNCTIONS.items() if f.in_bindings)


def held_value(name: str, value: Fraction, scale: int) -> Fraction:
    """A setting's value as the model holds it: a significand setting truncated towards zero to whole
    significands (``length 4.55555`` at scale 10000 is 4.5555), any other setting exactly."""
    if MODEL_NAMES[name].holding is Holding.SIGNIFICAND:
        return Fraction(math.trunc(value * scale), scale)
    return value
