"""What one ``rac sweep`` covers: the scenario files (:func:`scenario_files`) and the grid of model
settings (:func:`parse_set`, :func:`grid_points`); one task per scenario and grid point.

Example::

    files = scenario_files(["scenarios/", "more/*.xml"])
    points = grid_points(parse_set(["exponent=1,2", "decide_period=0.5,1"]))   # 4 points
"""

from __future__ import annotations

import difflib
import glob
import itertools
import os
from collections.abc import Sequence
from fractions import Fraction
from pathlib import Path

from rac.check.model_block import allowed
from rac.core.diagnostics import short_number
from rac.core.files import GENERATED_MARK, head
from rac.ir.vocabulary import ACTIONS, MODELLING, SETTINGS, WORD_SETTINGS
from rac.lang import ast
from rac.lang.format import format_expr
from rac.sweep.template import SETTING_NAMES, setting_value

__all__ = ["grid_points", "parse_set", "scenario_files"]

#: One point of the grid: ``(setting name, value text)`` per ``--set``, in the order given.
GridPoint = tuple[tuple[str, str], ...]


def _rac_output(path: Path) -> bool:
    """Whether ``path`` is a file rac wrote that is no CommonRoad scenario (a UPPAAL model of ``rac
    compile``; the scenes of :mod:`rac.model.scenes` carry the mark too, and are scenarios)."""
    start = head(path).lower()
    return GENERATED_MARK in start and b"<commonroad" not in start


def _xml_below(folder: Path) -> list[Path]:
    return [Path(root) / name for root, _, names in os.walk(folder) for name in names if name.endswith(".xml")]


def scenario_files(items: Sequence[str]) -> list[Path]:
    """The scenario files ``items`` name: files (of any name), folders (searched recursively for
    ``*.xml``) and globs (``**`` crosses folders; a folder a glob matches is searched too); absolute,
    sorted, each once. A folder or a glob never yields a file rac wrote (a UPPAAL model of ``rac
    compile`` in ``TEMPLATE.out/``, not a scene of :mod:`rac.model.scenes`); a file named outright is
    taken as it is. ``ValueError`` naming every item that matched no file (or when there are no
    items)."""
    if not items:
        raise ValueError("no scenarios: name CommonRoad files, folders holding them, or globs")
    found: set[Path] = set()
    empty: list[str] = []
    for item in items:
        matches = glob.glob(item, recursive=True) if glob.has_magic(item) else [item] if os.path.exists(item) else []
        files: list[Path] = []
        named = not glob.has_magic(item) and not os.path.isdir(item)
        for match in map(Path, matches):
            files.extend(_xml_below(match) if match.is_dir() else [match])
        if not named:  # searched, not named: rac's own outputs beside the scenarios are no scenarios
            files = [f for f in files if not _rac_output(f)]
        if not files:
            empty.append(item)
        found.update(Path(os.path.abspath(f)) for f in files)
    if empty:
        raise ValueError("no scenario file matched " + ", ".join(f"`{item}`" for item in empty)
                         + " (a folder is searched for *.xml files)")
    return sorted(found)


def _setting_name(name: str) -> str:
    if name in SETTING_NAMES:
        return name
    if name == "scenario":
        raise ValueError("`--set scenario=...`: the scenarios are the sweep's SCENARIOS arguments")
    if name in ACTIONS:
        raise ValueError(f"`{name}` is an action, not a setting: --set gives the `model` block's settings "
                         f"({', '.join(SETTING_NAMES)})")
    close = difflib.get_close_matches(name, SETTING_NAMES, n=1)
    hint = f"did you mean `{close[0]}`?" if close else f"the settings are {', '.join(SETTING_NAMES)}"
    raise ValueError(f"`--set {name}=...`: unknown setting `{name}` of the `model` block; {hint}")


def _number(expr: ast.Expr) -> Fraction | None:
    """The exact value of a value written with numbers alone (``7``, ``-2``, ``1/3``); None for anything
    else (a constant of the template's, which only the task's check can read)."""
    if isinstance(expr, ast.Number):
        return expr.value
    if isinstance(expr, ast.Unary) and expr.op == "-":
        value = _number(expr.operand)
        return None if value is None else -value
    if isinstance(expr, ast.Binary) and expr.op in ("+", "-", "*", "/"):
        left, right = _number(expr.left), _number(expr.right)
        if left is None or right is None or (expr.op == "/" and right == 0):
            return None
        return {"+": left + right, "-": left - right, "*": left * right}[expr.op] if expr.op != "/" else left / right
    return None


def _refusal(name: str, expr: ast.Expr) -> str | None:
    """Why every task would refuse the value ``expr`` of ``name`` (rac check's E0702 in its words), or None:
    a value outside the setting's own range fails on every scenario, so it is said before any task runs.
    What depends on the scenario or on another setting (``decide_period`` a multiple of ``sense_period``)
    is left to each task's check."""
    words = WORD_SETTINGS.get(name)
    if words is not None:
        if isinstance(expr, ast.Name) and expr.id in words:
            return None
        return f"`{name}` must be one of the words {', '.join(f'`{w}`' for w in words)} (found `{format_expr(expr)}`)"
    setting = SETTINGS.get(name) or MODELLING.get(name)
    value = _number(expr)
    if setting is None or value is None or setting.accepts(value):
        return None
    unit = f" {setting.unit}" if setting.unit else ""
    return f"`{name}` must be {allowed(setting)} (found {short_number(value)}{unit}), as rac check requires (E0702)"


def parse_set(texts: Sequence[str]) -> list[tuple[str, list[str]]]:
    """Each ``--set NAME=V1,V2,...`` as ``(NAME, [V1, V2, ...])`` (spaces around names and values
    dropped, a repeated value kept once, also when written another way: ``1`` and ``1.0``).
    ``ValueError`` on bad syntax, a value that is not a number or a word, an unknown setting name, or
    a setting given twice, or a value outside the setting's own range (a whole number from 1 to 6 for
    ``exponent``; a word setting's words). What depends on the scenario or on the other settings is
    checked by each task's ``rac check`` (a value it refuses fails that task)."""
    result: list[tuple[str, list[str]]] = []
    for text in texts:
        name, equals, values = (part.strip() for part in text.partition("="))
        if not equals or not name:
            raise ValueError(f"`--set {text}`: write NAME=V1,V2,... (e.g. exponent=1,2)")
        name = _setting_name(name)
        if any(name == seen for seen, _ in result):
            raise ValueError(f"`--set {name}=...` is given twice: list every value once, e.g. {name}=1,2")
        if not values:
            raise ValueError(f"`--set {text}`: no value for `{name}`")
        parts = [value.strip() for value in values.split(",")]
        if not all(parts):
            raise ValueError(f"`--set {text}`: an empty value between commas")
        kept: dict[str, str] = {}  # by the value as the block would print it: `1` and `1.0` are one value
        for part in parts:
            # a number or a word: a typo fails here, not in every task
            expr = setting_value(name, part)
            refusal = _refusal(name, expr)
            if refusal is not None:  # every task of this value would fail alike: one usage error instead
                raise ValueError(f"`--set {name}={part}`: {refusal}")
            kept.setdefault(format_expr(expr), part)
        result.append((name, list(kept.values())))
    return result


def grid_points(sets: Sequence[tuple[str, Sequence[str]]]) -> list[GridPoint]:
    """The cartesian product of :func:`parse_set`'s lists, in order (the last setting varies
    fastest); ``[()]`` (one point, the template's own settings) without any."""
    names = [name for name, _ in sets]
    return [tuple(zip(names, values)) for values in itertools.product(*(values for _, values in sets))]
