"""What every Python runtime of rac shares: the IR in floats, and input validation.

The interpreter (:mod:`rac.runtime.interpreter`), batch stepping (:mod:`rac.runtime.batch`) and the generated
module (:mod:`rac.targets.python`) must agree to the bit, so they take their numbers from
here: :func:`float_linear` rounds each rational once, and :func:`check_automaton` refuses
what cannot be represented faithfully.
"""

from __future__ import annotations

import math
import numbers
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from fractions import Fraction
from typing import Any

import numpy as np

from rac import ir

#: ``(float(const), ((float(coefficient), name), ...))`` — a Linear as every target evaluates it.
FloatLinear = tuple[float, tuple[tuple[float, str], ...]]

ENDED_MESSAGE = "the run has ended; call reset() first"


def to_float(value: Fraction | int, what: str) -> float:
    """``float(value)``, refusing values a float cannot carry (overflow, or a non-zero that rounds to 0).

    Refusing underflow keeps ``-0.0`` out of every constant, which the targets rely on.
    """
    try:
        result = float(value)
    except OverflowError:
        raise ValueError(f"{what}: {value} is too large for a float") from None
    if result == 0.0 and value != 0:
        raise ValueError(f"{what}: {value} is too small for a float (it would round to 0)")
    return result


def float_linear(linear: ir.Linear, what: str) -> FloatLinear:
    """The float form of ``linear``: constant and coefficients rounded, term order kept."""
    return (to_float(linear.const, what),
            tuple((to_float(c, f"{what} (coefficient of {n})"), n) for n, c in linear.terms))


#: An atom ``input op threshold`` as the runtimes evaluate it on a validated float: ``(op, float)``, a
#: comparison of the float with a float, or a constant truth (see :func:`float_atoms`).
FloatAtom = tuple[str, float] | bool

#: What ``x op t`` is, as a comparison with ``f = float(t)``, when the input at ``x == f`` stands for a
#: number below ``t`` (first) or above it (second); elsewhere ``x`` and ``f`` compare as ``x`` and ``t`` do.
_STANDS_BELOW: dict[str, FloatAtom] = {"<": ("<=", 0.0), "<=": ("<=", 0.0), ">": (">", 0.0), ">=": (">", 0.0),
                                      "==": False, "!=": True}
_STANDS_ABOVE: dict[str, FloatAtom] = {"<": ("<", 0.0), "<=": ("<", 0.0), ">": (">=", 0.0), ">=": (">=", 0.0),
                                      "==": False, "!=": True}


@dataclass(frozen=True)
class FloatAtoms:
    """:func:`float_atoms` of one automaton: call it on an atom (a plain object: batches pickle it)."""

    #: ``(input, double) -> number``: the number a float input equal to that double stands for.
    stands: Mapping[tuple[str, float], Fraction]

    def __call__(self, leaf: ir.BAtom) -> FloatAtom:
        near = to_float(leaf.threshold, f"threshold of {leaf.input}")
        stand = self.stands.get((leaf.input, near), Fraction(near))
        if stand == leaf.threshold:
            return leaf.op, near
        changed = (_STANDS_BELOW if stand < leaf.threshold else _STANDS_ABOVE)[leaf.op]
        return changed if isinstance(changed, bool) else (changed[0], near)


def float_atoms(automaton: ir.Automaton) -> FloatAtoms:
    """How every runtime compares a numeric input with a threshold: exactly, for one number the float stands for.

    The checker proves its facts for exact values, the runtimes read floats. A float input ``x`` stands
    for itself, except that a float which is the double nearest to some of the input's numbers (its
    bounds and the thresholds it is compared with, within its range; whole ones for an ``int`` input)
    stands for the nearest of them (the lower on a tie): ``x <= 0.1`` holds at ``x = 0.1`` (the float
    is a hair above 1/10), as the range check ``x <= high`` does at a bound. Every comparison then holds
    of one value within the range, so no guard sees a valuation the checker did not explore: with
    ``x <= 0.3333333333333333`` and ``x >= 1/3`` (one double, between the two), that float stands for
    the nearer, 0.3333333333333333, and only the first holds there (each compared with the double on its
    own, both held). The result is a comparison with ``float(threshold)``
    (the operator changed where the float stands for another number) or a constant truth.
    """
    numbers: dict[str, set[Fraction]] = {}
    for item in automaton.inputs:
        if item.kind != "bool":
            numbers[item.name] = {bound for bound in (item.low, item.high) if bound is not None}
    guards = [edge.guard for group in automaton.edges for edge in group]
    guards += [clause.guard for clause in automaton.end_clauses]
    guards += [assumption.guard for assumption in automaton.assumptions]
    guards += [guard for guard in (automaton.episode_ends, automaton.ending) if guard is not None]
    for guard in guards:
        for leaf in ir.guard_leaves(guard):
            if isinstance(leaf, ir.BAtom) and leaf.input in numbers:
                numbers[leaf.input].add(leaf.threshold)
    stands: dict[tuple[str, float], Fraction] = {}
    for item in automaton.inputs:
        for value in sorted(numbers.get(item.name, ())):
            if ((item.low is not None and value < item.low) or (item.high is not None and value > item.high)
                    or (item.kind == "int" and value.denominator != 1)):
                continue  # no value the input takes
            key = (item.name, to_float(value, f"a number of {item.name}"))
            best = stands.get(key)
            if best is None or abs(value - Fraction(key[1])) < abs(best - Fraction(key[1])):
                stands[key] = value
    return FloatAtoms(stands)


@dataclass(frozen=True)
class InputSpec:
    """One declared input as the runtimes validate it (bounds as floats, ±inf when absent)."""

    name: str
    kind: str
    low: float
    high: float

    @property
    def is_bool(self) -> bool:
        return self.kind == "bool"

    @property
    def bounded(self) -> bool:
        return math.isfinite(self.low) and math.isfinite(self.high)


def input_specs(automaton: ir.Automaton) -> tuple[InputSpec, ...]:
    """The validation data of every input, in declaration order."""
    specs = []
    for item in automaton.inputs:
        low = -math.inf if item.low is None else to_float(item.low, f"lower bound of {item.name}")
        high = math.inf if item.high is None else to_float(item.high, f"upper bound of {item.name}")
        specs.append(InputSpec(item.name, item.kind, low, high))
    return tuple(specs)


@dataclass(frozen=True)
class AssumeCheck:
    """One ``assume`` clause as every runtime checks and reports it.

    An input valuation that violates it raises ``ValueError(error text)``: ``label`` (the clause as
    written and its line), then the value of each input the clause reads, in the order it reads
    them: ``inputs violate `assume collide imply isClose` (driving.ra:9): collide=True, isClose=False``.
    The generated module (:mod:`rac.targets.python`) prints the same text with its own helper.
    """

    guard: ir.Guard
    #: ``inputs violate `assume TEXT` (FILE:LINE)``; FILE is the base name of the `.ra` file.
    label: str
    #: ``(name, kind)`` of each input the clause reads, first read first.
    reads: tuple[tuple[str, str], ...]

    def error(self, values: Mapping[str, object]) -> ValueError:
        """The error for the validated ``values`` (bools, and floats for numeric inputs)."""
        return ValueError(violation(self.label, [(name, shown(values[name], kind)) for name, kind in self.reads]))


def shown(value: Any, kind: str) -> bool | int | float:
    """A validated input value (a Python or numpy bool or float) as violation messages print it
    (with ``repr``): ``int`` inputs as whole numbers."""
    if kind == "bool":
        return bool(value)
    return int(value) if kind == "int" else float(value)


def violation(label: str, values: Sequence[tuple[str, object]]) -> str:
    """``label: name=value, ...`` (the values by ``repr``); ``label`` alone when the clause reads no input."""
    return label + (": " + ", ".join(f"{name}={value!r}" for name, value in values) if values else "")


def assume_checks(automaton: ir.Automaton) -> tuple[AssumeCheck, ...]:
    """The clauses the runtimes check, in source order (the first violated one is reported);
    a clause that is always true is left out."""
    kinds = {i.name: i.kind for i in automaton.inputs}
    checks = []
    for assumption in automaton.assumptions:
        if assumption.guard == ir.TRUE:
            continue
        label = f"inputs violate `assume {assumption.text}`"
        if assumption.span is not None:
            label += f" ({_base_name(assumption.span.file)}:{assumption.span.line})"
        names = dict.fromkeys(leaf.name if isinstance(leaf, ir.BInput) else leaf.input
                              for leaf in ir.guard_leaves(assumption.guard))
        checks.append(AssumeCheck(assumption.guard, label, tuple((name, kinds[name]) for name in names)))
    return tuple(checks)


def _base_name(path: str) -> str:
    """The file's name without its folders (either separator): the message is the same wherever rac ran."""
    return path.replace("\\", "/").rsplit("/", 1)[-1]


def check_automaton(automaton: ir.Automaton) -> None:
    """Check what the runtimes rely on (the compiler guarantees it; hand-built IR may not).

    Names resolve with the right kinds, rates read numeric inputs only, updates read rewards
    and numeric inputs, the objective reads rewards only, and every number fits a float.
    Raises :class:`ValueError` naming the first problem.
    """
    rewards = set(automaton.rewards)
    kinds = {i.name: i.kind for i in automaton.inputs}
    if len(rewards) != len(automaton.rewards) or len(kinds) != len(automaton.inputs):
        raise ValueError("duplicate reward or input names")
    if rewards & kinds.keys():
        raise ValueError(f"names used both as rewards and inputs: {sorted(rewards & kinds.keys())}")
    numeric = {name for name, kind in kinds.items() if kind != "bool"}
    n_loc = len(automaton.locations)
    if not automaton.locations or not 0 <= automaton.initial < n_loc:
        raise ValueError("the automaton needs locations and an initial location among them")
    if len(automaton.edges) != n_loc:
        raise ValueError("edges must be grouped by source location (one group per location)")
    if automaton.period <= 0:
        raise ValueError("the sample period must be positive")
    input_specs(automaton)

    def check_guard(guard: ir.Guard, where: str) -> None:
        for atom in ir.guard_leaves(guard):
            if isinstance(atom, ir.BInput):
                if kinds.get(atom.name) != "bool":
                    raise ValueError(f"{where}: {atom.name!r} is not a boolean input")
            else:
                assert isinstance(atom, ir.BAtom)
                if atom.input not in numeric:
                    raise ValueError(f"{where}: {atom.input!r} is not a numeric input")
                if atom.op not in ("<", "<=", ">", ">=", "==", "!="):
                    raise ValueError(f"{where}: unknown comparison {atom.op!r}")
                to_float(atom.threshold, f"{where}: threshold of {atom.input}")

    def check_linear(linear: ir.Linear, allowed: set[str], where: str) -> None:
        for name, _ in linear.terms:
            if name not in allowed:
                raise ValueError(f"{where}: {name!r} cannot appear here")
        float_linear(linear, where)

    def check_updates(updates: Sequence[ir.Assignment], where: str) -> None:
        for update in updates:
            if update.reward not in rewards:
                raise ValueError(f"{where}: {update.reward!r} is not a reward")
            check_linear(update.value, rewards | numeric, f"{where}: value of {update.reward}")

    for location in automaton.locations:
        if len(location.rates) != len(automaton.rewards):
            raise ValueError(f"location {location.name}: one rate per reward expected")
        for reward, rate in zip(automaton.rewards, location.rates):
            check_linear(rate.scaled(automaton.period), numeric, f"rate of {reward} in {location.name}")
    for index, group in enumerate(automaton.edges):
        for edge in group:
            where = f"edge {automaton.locations[index].name} -> {edge.target}"
            if edge.source != index or not 0 <= edge.target < n_loc:
                raise ValueError(f"{where}: source or target out of place")
            check_guard(edge.guard, where)
            check_updates(edge.updates, where)
    for clause in automaton.end_clauses:
        check_guard(clause.guard, "at end")
        check_updates(clause.updates, "at end")
    for assumption in automaton.assumptions:
        check_guard(assumption.guard, "assume")
    if automaton.episode_ends is not None:
        check_guard(automaton.episode_ends, "episode ends when")
    check_linear(automaton.objective, rewards, "objective")


#: The float types narrower than Python's whose value at a bound rounded to their precision is that
#: bound (:func:`number_input`; the batch's columns of these dtypes alike).
NARROW_FLOATS = ("float32", "float16")


def check_mapping(inputs: object, names: Sequence[str] = ()) -> None:
    """``ValueError`` unless ``inputs`` maps input names to values (``step(None)`` said TypeError) and
    holds each of ``names``: a ``defaultdict`` (or a ``Counter``) invents a missing one when it is read,
    so a misspelt name would be read as the default, and added to the caller's mapping."""
    if not isinstance(inputs, Mapping):
        raise ValueError(f"inputs must map input names to values, not {type(inputs).__name__}")
    if any(name not in inputs for name in names):
        raise key_error(inputs, names)


def one_value(raw: object) -> object:
    """``raw``, or for a 0-d numpy array (``np.array(3.0)``, what ``np.where`` of scalars gives) the one value it
    holds, as numpy's scalar of its dtype (``raw[()]``: a float32 stays a float32). ``step_batch`` broadcasts such an
    array as a scalar; one run reads it as its value too. Told by its type alone, as the generated module (no
    numpy) tells it; an array of another shape, a torch tensor, is left to be refused with :func:`array_hint`."""
    if type(raw).__name__ == "ndarray" and type(raw).__module__ == "numpy" and getattr(raw, "shape", None) == ():
        return raw[()]  # type: ignore[index]
    return raw


def boolean_input(name: str, raw: object) -> bool:
    """A boolean input's value: ``True``/``False`` (Python's or numpy's, a 0-d array of one: :func:`one_value`) or
    the integers 0 and 1; anything else (``"x"``, ``None``, ``0.5``, a duration) is ``ValueError``, not read by its
    truth."""
    raw = one_value(raw)
    if type(raw).__name__ == "timedelta64":
        raise ValueError(duration_message(name, raw))
    if type(raw).__name__ in ("bool", "bool_") or (isinstance(raw, numbers.Integral) and raw in (0, 1)):
        return bool(raw)
    raise ValueError(f"input {name!r} = {raw!r} is not a boolean (True or False){array_hint(raw)}")


def array_hint(raw: object) -> str:
    """What the refusal of an array (numpy's, a 0-d one too, or a torch tensor) adds: one value is read, not
    an array of them (``obs[0]``, not ``obs[0:1]``; ``value.item()``). A numpy scalar (``np.float64(1.0)``)
    has a shape ``()`` too but is one value, so it gets no hint. The generated module says the same."""
    shape = getattr(raw, "shape", None)
    if shape is None or not callable(getattr(raw, "item", None)) or numpy_scalar(raw):
        return ""
    try:
        dims = tuple(int(d) for d in shape)
    except (TypeError, ValueError):
        return ""
    return f": an array of shape {dims}, not one value (pass obs[i] rather than obs[i:i+1], or value.item())"


def duration_message(name: str, raw: object) -> str:
    """The refusal of a numpy ``timedelta64`` (a pandas ``diff()`` of times, a datetime difference): numpy
    registers it as an integer, so without this it was read as its count of units, 3 for 3 ms and 3 s alike
    (the batch refused it as a column). The generated module says the same."""
    return (f"input {name!r} = {raw!r} is a duration, not a number: give it in the input's unit, e.g. "
            "value / np.timedelta64(1, 's') for seconds")


def numpy_scalar(raw: object) -> bool:
    """Whether ``raw`` is a numpy scalar (``np.float64``, ``np.int8``, ``np.str_``, ...), not an array; told by
    its type alone, so that the generated module, which has no numpy, tells it the same way."""
    kind = type(raw)
    return kind.__module__ == "numpy" and kind.__name__ != "ndarray"


def number_input(name: str, raw: object, low: float = -math.inf, high: float = math.inf) -> float:
    """A numeric input's value as a float: a real number (``int``, ``float``, a ``Fraction``, a numpy
    number; a boolean, Python's or numpy's, counts 0 or 1); a string, ``None``, a complex number, a
    duration (numpy's ``timedelta64``, an integer to numpy) or a sequence is ``ValueError``,
    so is a number no float holds. A narrower float (numpy's float32 or
    float16, as environments observe) equal to the bound ``low`` or ``high`` rounded to its precision
    is that bound: MountainCar's ``np.float32(-1.2)`` is -1.2, not -1.2000000476837158. A 0-d numpy array is
    read as the value it holds (:func:`one_value`)."""
    raw = one_value(raw)
    if type(raw).__name__ in ("bool", "bool_"):  # a bool counts 0 or 1, numpy's (np.bool, np.bool_) too
        return 1.0 if raw else 0.0
    if type(raw).__name__ == "timedelta64":  # numpy makes it an Integral: its count of units, whatever the unit
        raise ValueError(duration_message(name, raw))
    if not isinstance(raw, numbers.Real):
        raise ValueError(f"input {name!r} = {raw!r} is not a number{array_hint(raw)}")
    try:
        value = float(raw)
    except OverflowError:
        raise ValueError(f"input {name!r} = {raw!r} is too large for a float") from None
    if not low <= value <= high and type(raw).__name__ in NARROW_FLOATS:
        narrow: Any = type(raw)
        if narrow(low) == raw:
            return low
        if narrow(high) == raw:
            return high
    return value


def column_array(raw: object) -> np.ndarray:
    """A batch input's values as an array: ``np.asarray(raw)``, except for a list or tuple that mixes numpy's
    narrower floats with wider numbers (``[np.float32(-1.2), 0.0]``), which numpy widens to float64, making the
    float32 at a bound a value outside it: read as an object column instead, each value by the scalar runtime's
    rule (:func:`number_input`), as the interpreter reads it (a list of float32 alone stays a float32 array)."""
    given = np.asarray(raw)
    if (isinstance(raw, (list, tuple)) and given.dtype.kind == "f" and given.dtype.name not in NARROW_FLOATS
            and any(type(value).__name__ in NARROW_FLOATS for value in raw)):
        column = np.empty(len(raw), dtype=object)
        column[:] = list(raw)
        return column
    return given


def object_column(spec: InputSpec, raw: np.ndarray, rows: np.ndarray | None) -> np.ndarray:
    """An object column of ``spec``'s values (bool, or float64 for a numeric input), each row read by the
    scalar runtime's rule: np.True_ is a boolean, a Fraction or a float32 at a bound a number, None
    neither (``ValueError`` naming the row). gymnasium's vector info holds numpy bools so, with None in
    the rows of sub-environments that did not report the key: rows outside ``rows`` are not read."""
    column = np.zeros(len(raw), dtype=bool if spec.is_bool else np.float64)
    for i in range(len(raw)) if rows is None else np.flatnonzero(rows).tolist():
        try:
            column[i] = (boolean_input(spec.name, raw[i]) if spec.is_bool
                         else number_input(spec.name, raw[i], spec.low, spec.high))
        except ValueError as exc:
            where = f"input {spec.name!r}"
            raise ValueError(str(exc).replace(where, f"{where}[{i}]", 1)) from None
    return column


def clip_inputs(specs: Sequence[InputSpec], inputs: Mapping[str, object],
                rows: np.ndarray | None = None, *, scalars: bool = False) -> tuple[dict[str, object], dict[str, int]]:
    """``inputs`` with every numeric value outside its declared range clipped to it, and how many
    values of each numeric input were clipped.

    Works on scalars and on arrays (a batch's columns; ``rows``: only those are clipped and counted);
    with ``scalars`` (a runtime reading one value per input) on scalars only (a 0-d numpy array as the value it
    holds, :func:`one_value`): another array or a list is left as it was given, in range or not, for validation
    to refuse in its own words.
    NaN is never clipped (it is no value on either side of a range): ``ValueError`` naming the input.
    What is not a real number, booleans, and an array that does not have ``rows``' shape are left for
    validation to report (it names the input and the shape); what is not a mapping is ``ValueError``.
    """
    check_mapping(inputs)  # an inputs() that forgot its `return`: said as the runtime says it, not TypeError
    out = dict(inputs)
    counts: dict[str, int] = {}
    for spec in specs:
        if spec.is_bool or spec.name not in inputs:
            continue
        raw = one_value(inputs[spec.name]) if scalars else inputs[spec.name]
        if isinstance(raw, numbers.Real) and type(raw).__name__ not in ("bool", "bool_"):
            try:  # a float32 at a bound rounded to float32 is that bound: nothing to clip or count
                value = number_input(spec.name, raw, spec.low, spec.high)
            except ValueError:
                continue  # validation says it is too large for a float
            if math.isnan(value):
                raise ValueError(f"input {spec.name!r} is NaN, which is never clipped")
            clipped = min(max(value, spec.low), spec.high)
            counts[spec.name] = int(clipped != value)
            if clipped != value:
                out[spec.name] = clipped
            continue
        if scalars:
            continue  # one run's input: validation refuses an array, whatever its value
        given = column_array(raw)
        if rows is not None and given.shape not in ((), np.shape(rows)):
            continue  # a column of another shape (obs[:, i:i+1]): validation names its shape
        array = _numbers(spec, given, rows)
        if array is None:
            continue
        bounded, moved = clip_column(spec, array, rows)
        counts[spec.name] = int(moved.sum())
        if counts[spec.name]:
            out[spec.name] = bounded
    return out, counts


def _numbers(spec: InputSpec, array: np.ndarray, rows: np.ndarray | None) -> np.ndarray | None:
    """A numeric input's array as :func:`clip_column` takes it: numbers as they are, an object column (a
    vector info's) read row by row (:func:`object_column`); None for what validation is left to report."""
    if array.dtype.kind in "iuf":
        return array
    if array.dtype.kind != "O" or array.ndim != 1:
        return None
    try:
        return object_column(spec, array, rows)
    except ValueError:
        return None


def at_bounds(spec: InputSpec, raw: np.ndarray) -> np.ndarray:
    """A numeric input's column as float64, where a narrower float (a float32 or float16 column) equal
    to a bound rounded to its precision is that bound (:func:`number_input`'s rule for arrays)."""
    value = raw.astype(np.float64, copy=False)
    if raw.dtype.name not in NARROW_FLOATS:
        return value
    narrow = raw.dtype.type
    low = (value < spec.low) & (raw == narrow(spec.low))
    high = (value > spec.high) & (raw == narrow(spec.high))
    return np.where(low, spec.low, np.where(high, spec.high, value))


def clip_column(spec: InputSpec, values: np.ndarray, rows: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """The numeric input ``spec``'s values (an array of numbers, any shape) clipped to its declared range
    as float64, and where each was clipped (bool, the same shape): the rule of :func:`clip_inputs`.
    ``rows`` (bool): only those are clipped and marked. ``ValueError`` naming the input for a NaN."""
    column = at_bounds(spec, np.asarray(values))
    nan = np.isnan(column) if rows is None else np.isnan(column) & rows
    if nan.any():
        where = "" if column.ndim == 0 else f"[{int(np.flatnonzero(nan)[0])}]"
        raise ValueError(f"input {spec.name!r}{where} is NaN, which is never clipped")
    bounded = np.clip(column, spec.low, spec.high)
    moved = bounded != column
    if rows is not None:  # rows outside are neither read nor counted (NaN there is no one's business)
        bounded = np.where(rows, bounded, column)
        moved &= rows
    return bounded, moved


def clip_rows(specs: Sequence[InputSpec], inputs: Mapping[str, object], n: int,
              rows: np.ndarray | None = None) -> tuple[dict[str, object], dict[str, np.ndarray]]:
    """:func:`clip_inputs` on a batch of ``n`` rows, with its counts per row: ``inputs`` with every numeric
    value clipped (a column, or a scalar that stands for every row, then a column when it was clipped),
    and per numeric input an ``(n,)`` int64 array, 1 where the row's value was clipped (``rows``: only
    those rows are clipped and counted). The counts sum to :func:`clip_inputs`' for columns. A value of
    another shape than ``()`` or ``(n,)`` is left for validation to report."""
    check_mapping(inputs)
    out = dict(inputs)
    counts: dict[str, np.ndarray] = {}
    for spec in specs:
        if spec.is_bool or spec.name not in inputs:
            continue
        raw = inputs[spec.name]
        if type(raw).__name__ in ("bool", "bool_"):
            continue  # left for validation to report
        given = column_array(raw)
        if given.shape not in ((), (n,)):
            continue  # validation names the shape (broadcast_to said numpy's own words)
        array = _numbers(spec, np.broadcast_to(given, (n,)), rows)
        if array is None:
            continue
        bounded, moved = clip_column(spec, array, rows)
        counts[spec.name] = moved.astype(np.int64)
        if moved.any():
            out[spec.name] = bounded
    return out, counts


def key_error(inputs: Mapping[str, object], names: Sequence[str]) -> ValueError:
    missing = [name for name in names if name not in inputs]
    known = set(names)
    unknown = sorted(repr(key) for key in inputs if key not in known)
    parts = []
    if missing:
        parts.append("missing input(s): " + ", ".join(missing))
    if unknown:
        parts.append("unknown input(s): " + ", ".join(unknown))
    return ValueError("; ".join(parts) or "the inputs do not match the declared inputs")


def range_error(spec: InputSpec, value: object, where: str = "") -> ValueError:
    in_range = isinstance(value, float) and math.isfinite(value) and spec.low <= value <= spec.high
    if spec.kind == "int" and in_range:
        return ValueError(f"input {spec.name!r}{where} = {value!r} is not an integer")
    message = f"input {spec.name!r}{where} = {value!r} is outside [{spec.low!r}, {spec.high!r}]"
    if isinstance(value, float) and math.isnan(value):  # "nan is outside [0, 10]" left the reader to see why
        return ValueError(f"{message}: NaN (not a number) is in no range, and clip=True refuses it too; replace "
                          "it before the step (a sensor's missing value, a division by zero upstream)")
    if isinstance(value, float) and any(value == float(np.float32(bound)) for bound in (spec.low, spec.high)):
        # a float32 bound made a Python float (float(np.float32(0.07)) == 0.07000000029802322): the float32
        # itself is read as the bound it rounds, its float64 widening is not (the range is not widened)
        message += (f": {value!r} is the float32 nearest a bound, widened to float64 (float(np.float32(...))); "
                    "pass the numpy float32 value itself (a float32 array or scalar), or clip=True")
    return ValueError(message)


class AutomatonDescription:
    """Read-only facts about the automaton a runtime runs (shared by scalar and batch runtimes)."""

    _ir: ir.Automaton
    _names: tuple[str, ...]

    @property
    def ir(self) -> ir.Automaton:
        """The checked automaton being run."""
        return self._ir

    @property
    def name(self) -> str:
        """The automaton's name."""
        return self._ir.name

    @property
    def inputs(self) -> tuple[str, ...]:
        """Input names, in declaration order."""
        return self._names

    @property
    def reward_names(self) -> tuple[str, ...]:
        """Reward names, in declaration order."""
        return self._ir.rewards

    @property
    def period(self) -> float:
        """Seconds per sample."""
        return float(self._ir.period)

    @property
    def horizon(self) -> float:
        """The horizon in seconds (as the generated module's class attribute; not enforced either)."""
        return float(self._ir.horizon)

    @property
    def steps(self) -> int:
        """Samples in a run of the full horizon (not enforced: the caller ends runs)."""
        return self._ir.steps


# ---------------------------------------------------------------- the integer mirrors of the rewards
# (the UPPAAL target emits them, the engine's product of model and automaton computes them)
def mirror_accrual(rate: ir.Linear, period: Fraction, scale: int) -> tuple[Fraction, list[tuple[Fraction, str]]]:
    """What a reward's integer mirror gains in one sample at ``rate``: ``(constant, [(coefficient, input)])``.

    The emitted ``accrue?`` edge adds ``constant`` (``rate.const * period * scale``, a whole number
    when representable) and, per numeric input, ``coefficient * significand`` written as
    ``p*input / q``: integer arithmetic, so each such term is truncated towards zero on its own.
    """
    return rate.const * period * scale, [(coef * period, name) for name, coef in rate.terms]


def mirror_update(value: ir.Linear, scale: int) -> tuple[Fraction, list[tuple[Fraction, str]]]:
    """A mirror's new value for the update ``reward = value``: ``(constant, [(coefficient, name)])``
    over the mirrors of rewards and the significands of numeric inputs (both hold ``v * scale``, so
    the coefficients are the update's own), printed by :func:`rac.targets.uppaal.expr.print_int_linear`:
    exact with whole coefficients, else the exact value truncated towards zero once."""
    return value.const * scale, [(coef, name) for name, coef in value.terms]


def first_sample_reads(automaton: ir.Automaton) -> bool:
    """Whether some rate reads an input: then the first sample's accrual, which has no held inputs
    yet, happens on ``read?`` with that sample's inputs instead of on ``accrue?``."""
    return automaton.rates_read_inputs
