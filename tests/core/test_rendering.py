"""The text renderer of diagnostics (:func:`rac.core.diagnostics.render_text`): the caret line."""

from __future__ import annotations

from rac.core.diagnostics import error, render_text
from rac.core.source import SourceFile


def test_the_caret_stands_under_its_span_after_wide_characters() -> None:
    """A comment in Japanese before the span put the caret 3 columns short: each of 日本語 takes two
    terminal columns, and the caret line gave each one space."""
    line = "    objective /* 日本語 */ qq"
    source = SourceFile("wide.ra", f"automaton A {{\n{line}\n}}\n")
    start = source.text.index("qq")
    text = render_text([error("E0101", "unknown name `qq`", source.span(start, start + 2))], {"wide.ra": source})
    shown, caret = text.splitlines()[2:4]
    assert shown == f"2 | {line}"
    assert caret == "  | " + " " * (len("    objective /* ") + 2 * 3 + len(" */ ")) + "^^"


def test_a_span_over_wide_characters_is_underlined_whole() -> None:
    source = SourceFile("wide.ra", 'scenario "日本.xml"\n')
    text = render_text([error("E0712", "cannot load the scenario", source.span(0, 17))], {"wide.ra": source})
    assert text.splitlines()[3] == "  | " + "^" * (len('scenario ""') + len(".xml") + 2 * 2)
