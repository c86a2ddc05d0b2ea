"""The text renderer of diagnostics (:func:`rac.core.diagnostics.render_text`): the caret line."""

from __future__ import annotations

import json
import os

from rac.core.diagnostics import display_text, error, json_text, render_json, render_text
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


def test_a_file_name_not_utf8_renders_alike_in_text_and_json() -> None:
    """A file name with the byte 0xff (not UTF-8) came out as ``\\udcff`` in text and as a lone surrogate in
    JSON, which strict readers reject; both show the byte, ``\\xff``, and the JSON is valid UTF-8."""
    name = os.fsdecode(b"caf\xe9/bad\xffname.ra")
    source = SourceFile(name, "automaton A {\n}\n")
    found = error("E0008", f"cannot read `{name}`", source.span(0, 9))
    assert render_text([found], {name: source}).startswith("caf\\xe9/bad\\xffname.ra:1:1: error[E0008]: cannot read "
                                                           "`caf\\xe9/bad\\xffname.ra`")
    text = render_json([found])
    text.encode("utf-8")  # no surrogate left: strict UTF-8 takes it
    assert json.loads(text)[0]["span"]["file"] == "caf\\xe9/bad\\xffname.ra"
    assert json.loads(json_text({name: [name, 1, None]}, indent=None)) == {display_text(name): [display_text(name),
                                                                                                 1, None]}
    assert display_text("caf\u00e9 \ud800") == "caf\u00e9 \\ud800" and display_text("plain.ra") == "plain.ra"
