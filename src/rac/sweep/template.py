"""The template of ``rac sweep``: an ordinary ``.ra`` file with a ``model`` block, instantiated once
per task with one scenario and one point of the ``--set`` grid.

:func:`check_template` reads the template and refuses one that does not parse or has no ``model``
block, before any task runs. :func:`instantiate` replaces the block's ``scenario`` with the task's
(absolute) scenario path and each grid setting's item with the grid's value (adding the item when
the template does not write it), and prints the result with rac's formatter; the task then checks
that text with :func:`rac.compiler.compile_text` under the template's name, so that every other
relative path still resolves from the template's folder.

The names a grid may set are the ``model`` block's settings, whose table the checker reads from
:mod:`rac.ir.vocabulary` (:data:`SETTING_NAMES`).
"""

from __future__ import annotations

import dataclasses
import os
from collections.abc import Sequence
from pathlib import Path

from rac.core.diagnostics import render_text
from rac.ir.vocabulary import MODELLING, SETTINGS, WORD_SETTINGS
from rac.lang import ast
from rac.lang.format import format_module
from rac.lang.parser import ParseFailure, parse_expression, parse_text

__all__ = ["SETTING_NAMES", "check_template", "instantiate", "setting_value"]

#: Every name a ``--set`` may give: the ``model`` block's settings (numbers and words).
SETTING_NAMES: tuple[str, ...] = (*SETTINGS, *MODELLING, *WORD_SETTINGS)


def setting_value(name: str, text: str) -> ast.Expr:
    """The value ``text`` of the setting ``name`` as the block's item would hold it (an expression:
    ``0.5``, ``-2``, ``1/3``, or a word such as ``increments``); ``ValueError`` naming the setting
    when it is not one expression."""
    try:
        return parse_expression(text, name=f"<{name}>")
    except ValueError as exc:
        raise ValueError(f"`{name}={text}`: the value is not a number or a word ({exc})") from None


def _parse(text: str, name: str) -> ast.Module:
    try:
        return parse_text(text, name)
    except ParseFailure as failure:
        rendered = render_text([failure.diagnostic], {failure.source.name: failure.source}
                               if failure.source is not None else {})
        raise ValueError(f"the template {name} does not parse:\n{rendered}") from None


def _model_block(module: ast.Module, name: str) -> tuple[int, ast.ModelDecl]:
    """The index of the first automaton's ``model`` block among its members, and the block."""
    automaton = module.automata[0]
    for index, member in enumerate(automaton.members):
        if isinstance(member, ast.ModelDecl):
            return index, member
    raise ValueError(f"the template {name} has no `model` block: rac sweep replaces the block's scenario and "
                     "settings, so the template needs one (docs/language.md, 'The model block')")


def check_template(path: str | Path) -> str:
    """The template's text, read once; ``ValueError`` (with a message for the user) when it does not
    parse or has no ``model`` block, ``OSError`` when it cannot be read. Its scenario need not exist:
    each task replaces it."""
    text = Path(path).read_text(encoding="utf-8")
    _model_block(_parse(text, str(path)), str(path))
    return text


def instantiate(template_text: str, template: str | Path, scenario: str | Path,
                settings: Sequence[tuple[str, str]]) -> str:
    """The template's text for one task: its ``model`` block's ``scenario`` is ``scenario`` (made
    absolute) and each ``(name, value text)`` of ``settings`` replaces the block's item for ``name``
    (the first one, when the template writes it twice: the checker reports the second) or is added
    after the block's last setting. ``ValueError`` when the template has no ``model`` block or a
    value is not one expression."""
    module = _parse(template_text, str(template))
    index, block = _model_block(module, str(template))
    items = list(block.items)
    path = ast.ModelScenario(os.path.abspath(os.fspath(scenario)))
    scenarios = [i for i, item in enumerate(items) if isinstance(item, ast.ModelScenario)]
    if scenarios:
        items[scenarios[0]] = path
    else:
        items.insert(0, path)
    for name, text in settings:
        item = ast.ModelSetting(ast.Ident(name), setting_value(name, text))
        written = [i for i, old in enumerate(items) if isinstance(old, ast.ModelSetting) and old.name.name == name]
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
    # without comments: their places are spans of the template's text, which the new items lack
    return format_module(dataclasses.replace(module, automata=automata), comments=False)
