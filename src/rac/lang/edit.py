"""Edits of a ``.ra`` file's ``model`` block at the level of its syntax tree: the one owner of
"this file, with another scenario (and other settings)".

:func:`with_model` replaces the first automaton's ``model`` block's ``scenario`` with a given path
(made absolute) and each ``(name, value text)`` setting's item with the value (adding the item
when the block does not write it), and prints the result with rac's formatter, without comments
(their places are spans of the original text, which the new items lack). The caller checks that
text under the original file's name (:func:`rac.compiler.compile_text`), so every other relative
path still resolves from the original's folder. ``rac sweep`` (:mod:`rac.sweep.template`) and
:class:`rac.learning.scenario_env.ScenarioEnv`'s scene sets use it::

    text = with_model(path.read_text(), path, "scenes/highway_3.xml", [("exponent", "2")])
"""

from __future__ import annotations

import dataclasses
import os
from collections.abc import Sequence
from pathlib import Path

from rac.core.diagnostics import render_text
from rac.lang import ast
from rac.lang.format import format_module
from rac.lang.parser import ParseFailure, parse_expression, parse_text

__all__ = ["model_block", "parse_file_text", "setting_value", "with_model"]


def setting_value(name: str, text: str) -> ast.Expr:
    """The value ``text`` of the setting ``name`` as the block's item would hold it (an expression:
    ``0.5``, ``-2``, ``1/3``, or a word such as ``increments``); ``ValueError`` naming the setting
    when it is not one expression."""
    try:
        return parse_expression(text, name=f"<{name}>")
    except ValueError as exc:
        raise ValueError(f"`{name}={text}`: the value is not a number or a word ({exc})") from None


def parse_file_text(text: str, name: str | Path) -> ast.Module:
    """The module in ``text``; ``ValueError`` with the rendered syntax error when it does not parse."""
    try:
        return parse_text(text, str(name))
    except ParseFailure as failure:
        rendered = render_text([failure.diagnostic], {failure.source.name: failure.source}
                               if failure.source is not None else {})
        raise ValueError(f"{name} does not parse:\n{rendered}") from None


def model_block(module: ast.Module, name: str | Path) -> tuple[int, ast.ModelDecl]:
    """The index of the first automaton's ``model`` block among its members, and the block;
    ``ValueError`` when it has none."""
    automaton = module.automata[0]
    for index, member in enumerate(automaton.members):
        if isinstance(member, ast.ModelDecl):
            return index, member
    raise ValueError(f"{name} has no `model` block (docs/language.md, 'The model block')")


def with_model(text: str, name: str | Path, scenario: str | os.PathLike[str],
               settings: Sequence[tuple[str, str]] = ()) -> str:
    """``text`` (the file ``name``) with its ``model`` block's ``scenario`` replaced by ``scenario``
    (made absolute) and each ``(name, value text)`` of ``settings`` replacing the block's item for
    ``name`` (the first one, when the file writes it twice: the checker reports the second) or
    added after the block's last setting. ``ValueError`` when the text does not parse, has no
    ``model`` block or a value is not one expression."""
    module = parse_file_text(text, name)
    index, block = model_block(module, name)
    items = list(block.items)
    path = ast.ModelScenario(os.path.abspath(os.fspath(scenario)))
    scenarios = [i for i, item in enumerate(items) if isinstance(item, ast.ModelScenario)]
    if scenarios:
        items[scenarios[0]] = path
    else:
        items.insert(0, path)
    for setting, value in settings:
        item = ast.ModelSetting(ast.Ident(setting), setting_value(setting, value))
        written = [i for i, old in enumerate(items)
                   if isinstance(old, ast.ModelSetting) and old.name.name == setting]
        if written:
            items[written[0]] = item
            continue
        # after the last setting (or the scenario), where a reader looks for it
        last = max((i for i, old in enumerate(items) if isinstance(old, (ast.ModelSetting, ast.ModelScenario))),
                   default=-1)
        items.insert(last + 1, item)
    automaton = module.automata[0]
    members = list(automaton.members)
    members[index] = dataclasses.replace(block, items=tuple(items))
    automata = (dataclasses.replace(automaton, members=tuple(members)), *module.automata[1:])
    # without comments: their places are spans of the original text, which the new items lack
    return format_module(dataclasses.replace(module, automata=automata), comments=False)
