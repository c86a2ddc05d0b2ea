"""Issue 25's members: ``episode ends when``, ``goal when``, ``collision when`` and ``require``, parsed
into their nodes with spans, printed by ``rac fmt``, and their keywords reserved only where a member
starts (inputs, settings and the model's ``goal()`` keep those names)."""

from __future__ import annotations

from fractions import Fraction

import pytest

from rac.core.source import SourceFile
from rac.lang import ast
from rac.lang.format import format_member, format_source
from rac.lang.parser import CONTEXTUAL_WORDS, ParseFailure, parse_queries, parse_text

SOURCE = """\
automaton Driving {
    input collide : bool
    input dgoal   : real in [0, 100]

    reward sa
    objective sa

    sample every 0.1
    horizon 3

    initial location Normal { sa' == 1 }

    episode ends when collide || dgoal < 2
    goal when dgoal < 2
    collision when collide

    require risk <= 1e-4
    require ending_early_never_pays
}
"""


def members(text: str) -> tuple[ast.Member, ...]:
    return parse_text(text).automata[0].members


def test_each_form_parses_into_its_node_with_spans() -> None:
    parsed = members(SOURCE)
    episode, goal, collision, risk, ending = parsed[-5:]
    assert episode == ast.EpisodeEndsDecl(ast.Binary("||", ast.Name("collide"),
                                                     ast.Binary("<", ast.Name("dgoal"), ast.Number(Fraction(2)))))
    assert goal == ast.GoalDecl(ast.Binary("<", ast.Name("dgoal"), ast.Number(Fraction(2))))
    assert collision == ast.CollisionDecl(ast.Name("collide"))
    assert risk == ast.RequireDecl(ast.Ident("risk"), ast.Number(Fraction(1, 10000)))
    assert ending == ast.RequireDecl(ast.Ident("ending_early_never_pays"), None)
    # spans: the whole member, the check's name, the bound
    lines = SOURCE.splitlines()
    assert episode.span is not None and (episode.span.line, episode.span.column) == (13, 5)
    assert SOURCE[episode.span.start:episode.span.end] == "episode ends when collide || dgoal < 2"
    assert risk.span is not None and SOURCE[risk.span.start:risk.span.end] == "require risk <= 1e-4"
    assert risk.check.span is not None and (risk.check.span.line, risk.check.span.column) == (17, 13)
    assert risk.bound is not None and risk.bound.span is not None
    assert SOURCE[risk.bound.span.start:risk.bound.span.end] == "1e-4"
    assert lines[risk.check.span.line - 1].startswith("    require risk")


@pytest.mark.parametrize("word", CONTEXTUAL_WORDS)
def test_the_words_are_names_everywhere_but_where_a_member_starts(word: str) -> None:
    text = f"""\
automaton A {{
    input {word} : bool
    const k_{word} = 1
    reward r
    objective r
    sample every 1
    horizon 2
    initial location {word}_at {{ r' == 1 }}
    edge {word}_at -> {word}_at when {word} do r += 1
    at end when !{word} do r -= 1
    goal when {word}
    require {word}
    query Q: A[] {word} imply r >= 0
    model {{
        exponent 4
        {word} 3
        bind {word} = goal()
    }}
}}
"""
    parsed = members(text)
    assert parsed[0] == ast.InputDecl((ast.Ident(word),), ast.BoolType())
    assert ast.GoalDecl(ast.Name(word)) in parsed
    assert ast.RequireDecl(ast.Ident(word)) in parsed
    model = parsed[-1]
    assert isinstance(model, ast.ModelDecl)
    assert model.items[1] == ast.ModelSetting(ast.Ident(word), ast.Number(Fraction(3)))
    assert model.items[2] == ast.ModelBinding(ast.Ident(word), ast.Call("goal", ()))


def test_a_word_setting_after_another_setting_stays_a_setting() -> None:
    """LALR merges the states after an expression in and out of a `model` block: `collision sticky`
    after `exponent 4` was once read as the start of `collision when`."""
    model = members("automaton A {\n model {\n  exponent 4\n  collision sticky\n  goal 2\n }\n}\n")[0]
    assert isinstance(model, ast.ModelDecl)
    assert [item.name.name for item in model.of(ast.ModelSetting)] == ["exponent", "collision", "goal"]


def test_queries_read_goal_as_the_model_function() -> None:
    decls = parse_queries(SourceFile("<q>", "query Qg: E<> goal()\nquery Qc: A[] !collision"))
    assert [d.query for d in decls] == [ast.PathQuery("E<>", ast.Call("goal", ())),
                                       ast.PathQuery("A[]", ast.Unary("!", ast.Name("collision")))]


@pytest.mark.parametrize(("member", "found", "hint"), [
    ("goal dgoal < 2", "`dgoal`", "the declaration is written `goal when CONDITION`"),
    ("collision collide", "`collide`", "the declaration is written `collision when CONDITION`"),
    ("episode when collide", "`when`", "the declaration is written `episode ends when CONDITION`"),
    ("episode ends collide", "`collide`", "the declaration is written `episode ends when CONDITION`"),
    ("require risk < 0.1", "`<`", "a requirement's bound is written `require risk <= BOUND`, with `<=`; "
                                  "the other requirements take none"),
    ("require risk 0.1", "`0.1`", "a requirement's bound is written `require risk <= BOUND`, with `<=`; "
                                  "the other requirements take none"),
    ("require 3", "`3`", "write `require CHECK` (e.g. `require ending_early_never_pays`) or "
                         "`require risk <= BOUND`"),
])
def test_slips_in_the_forms_read_well(member: str, found: str, hint: str) -> None:
    text = SOURCE.replace("    collision when collide\n", f"    {member}\n")
    with pytest.raises(ParseFailure) as caught:
        parse_text(text)
    diagnostic = caught.value.diagnostic
    assert diagnostic.code == "E0001"
    assert diagnostic.message == f"unexpected {found}"
    assert diagnostic.span is not None and diagnostic.span.line == 15
    assert list(diagnostic.hints) == [hint]


def test_members_print_on_one_line() -> None:
    printed = [format_member(m) for m in members(SOURCE)[-5:]]
    assert printed == ["episode ends when collide || dgoal < 2", "goal when dgoal < 2", "collision when collide",
                       "require risk <= 0.0001", "require ending_early_never_pays"]


def test_fmt_groups_the_members_and_keeps_comments() -> None:
    messy = SOURCE.replace("    goal when dgoal < 2\n", "\n  goal   when dgoal<2 // reached\n") \
        .replace("    require ending_early_never_pays\n", "    // enforced\n  require   ending_early_never_pays\n")
    formatted = format_source(messy)
    assert formatted == SOURCE.replace("1e-4", "0.0001") \
        .replace("    goal when dgoal < 2\n", "    goal when dgoal < 2  // reached\n") \
        .replace("    require ending_early_never_pays\n", "    // enforced\n    require ending_early_never_pays\n")
    assert format_source(formatted) == formatted
