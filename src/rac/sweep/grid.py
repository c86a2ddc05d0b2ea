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
from pathlib import Path

from rac.core.files import GENERATED_MARK, head
from rac.ir.vocabulary import ACTIONS
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


def parse_set(texts: Sequence[str]) -> list[tuple[str, list[str]]]:
    """Each ``--set NAME=V1,V2,...`` as ``(NAME, [V1, V2, ...])`` (spaces around names and values
    dropped, a repeated value kept once, also when written another way: ``1`` and ``1.0``).
    ``ValueError`` on bad syntax, a value that is not a number or a word, an unknown setting name, or
    a setting given twice. Values are checked against the setting's range by each task's ``rac
    check`` (a value it refuses fails that task)."""
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
            kept.setdefault(format_expr(setting_value(name, part)), part)
        result.append((name, list(kept.values())))
    return result


def grid_points(sets: Sequence[tuple[str, Sequence[str]]]) -> list[GridPoint]:
    """The cartesian product of :func:`parse_set`'s lists, in order (the last setting varies
    fastest); ``[()]`` (one point, the template's own settings) without any."""
    names = [name for name, _ in sets]
    return [tuple(zip(names, values)) for values in itertools.product(*(values for _, values in sets))]
