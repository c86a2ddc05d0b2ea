"""Edits of a ``.ra`` file's ``model`` block at the level of its syntax tree: the one owner of
"this file, with another scenario (and other settings)".

:func:`with_model` replaces the first automaton's ``model`` block's ``scenario`` with a given path
(made absolute) and each ``(name, value text)`` setting's item with the value (adding the item
when the block does not write it), changing only those items' text: every other line, comment and
column stays where the file has it, so diagnostics of the edited text point where the user wrote.
The caller checks that text under the original file's name (:func:`rac.compiler.compile_text`), so
every other relative path still resolves from the original's folder. ``rac sweep`` (:mod:`rac.sweep.template`) and
:class:`rac.learning.scenario_env.ScenarioEnv`'s scene sets use it::

    text = with_model(path.read_text(), path, "scenes/highway_3.xml", [("exponent", "2")])
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from pathlib import Path

from rac.core.diagnostics import render_text
from rac.lang import ast
from rac.lang.format import format_model_item
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
    ``model`` block or a value is not one expression.

    Only those items' text changes, each on its own line (a new item joins the line of the item before
    it, or of the block's ``{``): every other line, comment and column stays where the file has it, so a
    diagnostic of the edited text points at the place the user wrote (the whole file printed again, without
    comments, had moved them)."""
    module = parse_file_text(text, name)
    _, block = model_block(module, name)
    assert block.span is not None  # parsed from text: every item has its span
    edits: list[tuple[int, int, str]] = []  # (start, end, new text) in the original text

    def replace(item: ast.ModelItem, new: ast.ModelItem) -> None:
        assert item.span is not None
        edits.append((item.span.start, item.span.end, format_model_item(new)))

    path = ast.ModelScenario(os.path.abspath(os.fspath(scenario)))
    opening = text.index("{", block.span.start) + 1
    after = opening  # where an item the block does not write is added: after its last setting (or scenario)
    written = block.of(ast.ModelScenario)
    if written:
        replace(written[0], path)
    else:
        edits.append((opening, opening, f" {format_model_item(path)}"))
    for item in block.items:
        if isinstance(item, (ast.ModelSetting, ast.ModelScenario)) and item.span is not None:
            after = max(after, item.span.end)
    for setting, value in settings:
        new = ast.ModelSetting(ast.Ident(setting), setting_value(setting, value))
        same = [old for old in block.of(ast.ModelSetting) if old.name.name == setting]
        if same:
            replace(same[0], new)
        else:
            edits.append((after, after, f" {format_model_item(new)}"))
    # from the end backwards, so the offsets before each edit still hold: an insertion at an item's end before
    # that item's replacement, and insertions at one place last to first, so that they read in the order given
    order = sorted(range(len(edits)), key=lambda i: (edits[i][0], edits[i][1], i), reverse=True)
    for start, end, new_text in (edits[i] for i in order):
        text = text[:start] + new_text + text[end:]
    return text
