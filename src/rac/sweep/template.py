"""The template of ``rac sweep``: an ordinary ``.ra`` file with a ``model`` block, instantiated once
per task with one scenario and one point of the ``--set`` grid.

:func:`check_template` reads the template and refuses one that does not parse or has no ``model``
block, before any task runs. :func:`instantiate` is :func:`rac.lang.edit.with_model` (the one owner
of the edit, shared with the learning environment's scene sets): the block's ``scenario`` becomes
the task's (absolute) scenario path and each grid setting's item the grid's value; the task then
checks that text with :func:`rac.compiler.compile_text` under the template's name, so that every
other relative path still resolves from the template's folder.

The names a grid may set are the ``model`` block's settings, whose table the checker reads from
:mod:`rac.ir.vocabulary` (:data:`SETTING_NAMES`).
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

from rac.core.diagnostics import Diagnostic, RacError, render_text
from rac.core.source import SourceFile
from rac.ir.vocabulary import MODELLING, SETTINGS, WORD_SETTINGS
from rac.lang import ast
from rac.lang.edit import model_block, parse_file_text, setting_value, with_model
from rac.lang.parser import ParseFailure, parse_text, read_source

__all__ = ["SETTING_NAMES", "TemplateError", "check_template", "instantiate", "setting_value", "template_inputs",
           "template_settings"]

#: Every name a ``--set`` may give: the ``model`` block's settings (numbers and words).
SETTING_NAMES: tuple[str, ...] = (*SETTINGS, *MODELLING, *WORD_SETTINGS)


class TemplateError(RacError, ValueError):
    """The template is no ``.ra`` file rac can read, or does not parse: ``summary`` says so of the template,
    ``diagnostic`` is the file's own (E0001-E0005, with its span, as ``rac check`` reports it) and ``sources``
    the text it points into; the message has both, rendered as text."""

    diagnostic: Diagnostic  # always set: the file's own error

    def __init__(self, summary: str, failure: ParseFailure) -> None:
        self.summary = summary
        self.diagnostic = failure.diagnostic
        self.sources: dict[str, SourceFile] = {failure.source.name: failure.source} if failure.source else {}
        super().__init__(f"{summary}:\n{render_text([self.diagnostic], self.sources)}")


def check_template(path: str | Path) -> str:
    """The template's text, read once as ``rac check`` reads a file (a byte-order mark dropped, CR line
    ends as LF; a FIFO or a device refused, never read to its end); ``ValueError`` (with a message for
    the user) when it is no UTF-8 text, does not parse or has no ``model`` block, ``OSError`` when it
    cannot be read. Its scenario need not exist: each task replaces it."""
    try:  # Windows line ends as \n: they make no new task key (nor did they before)
        text = read_source(path).text.replace("\r\n", "\n")
    except ParseFailure as failure:  # not UTF-8, NUL bytes, too large: E0004/E0005 as rac check says them
        raise TemplateError(f"the template {path} is not a .ra file rac can read", failure) from None
    try:
        module = parse_text(text, str(path))
    except ParseFailure as failure:  # the syntax error itself, with its span (as rac check reports it)
        raise TemplateError(f"the template {path} does not parse", failure) from None
    try:
        model_block(module, str(path))
    except ValueError:
        raise ValueError(f"the template {path} has no `model` block: rac sweep replaces the block's scenario "
                         "and settings, so the template needs one (docs/language.md, 'The model block')") from None
    return text


def template_inputs(text: str, path: str | Path) -> list[str]:
    """The names of the inputs the template's automaton declares (its text as :func:`check_template`
    returned it: it parses)."""
    automaton = parse_file_text(text, str(path)).automata[0]
    return [ident.name for decl in automaton.of(ast.InputDecl) for ident in decl.names]


def template_settings(text: str, path: str | Path) -> frozenset[str]:
    """The names of the settings the template's ``model`` block writes (its text as :func:`check_template`
    returned it: it parses and has the block)."""
    _, block = model_block(parse_file_text(text, str(path)), str(path))
    return frozenset(item.name.name for item in block.items if isinstance(item, ast.ModelSetting))


def instantiate(template_text: str, template: str | Path, scenario: str | Path,
                settings: Sequence[tuple[str, str]]) -> str:
    """The template's text for one task (:func:`rac.lang.edit.with_model`): its ``model`` block's
    ``scenario`` is ``scenario`` (made absolute) and each ``(name, value text)`` of ``settings``
    replaces the block's item for ``name`` or is added after the block's last setting.
    ``ValueError`` when the template has no ``model`` block, a value is not one expression or the scenario's
    path cannot be written in a ``.ra`` file (a quote, a line break)."""
    try:
        return with_model(template_text, str(template), scenario, settings)
    except ValueError as exc:  # its words name what is wrong (the template, a value, the path): said of this task
        raise ValueError(f"cannot instantiate the template {template} with the scenario {scenario}: {exc}") from None

