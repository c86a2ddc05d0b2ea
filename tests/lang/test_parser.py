"""The grammar's start rules (a file, a list of expressions, a list of queries), their syntax
errors in user terms, and the typed expressions of the resolver (:mod:`rac.check.linear`)."""

from __future__ import annotations

from fractions import Fraction
from pathlib import Path

import pytest

from rac.check.linear import GUARD, RATE, Bool, ExpressionTyper, Num
from rac.check.symbols import Scope, Symbol, Unresolvable
from rac.compiler import compile_file
from rac.core.source import SourceFile
from rac.ir import BAtom, BInput, Linear
from rac.lang import ast
from rac.lang.parser import (
    ExpressionError,
    ParseFailure,
    parse_expression,
    parse_expressions,
    parse_queries,
    parse_text,
)

ROOT = Path(__file__).resolve().parents[2]
QUERIES = """query Qa: Pr[<=30](<> fabs(true_x - x) >= sensor_error)
query Qd: strategy safe = control: A[] !collide() && !offroad()
query Fig7: simulate[<=30;100]{mindist(), 3 * collision_distance} under safe
"""


def failure(parse, text: str) -> ParseFailure:
    with pytest.raises(ParseFailure) as caught:
        parse(SourceFile("<text>", text))
    return caught.value


def test_expression_list() -> None:
    exprs = parse_expressions(SourceFile("<text>", "mindist(), 3 * collision_distance"))
    assert exprs == (ast.Call("mindist", ()),
                     ast.Binary("*", ast.Number(3), ast.Name("collision_distance")))
    assert exprs[1].span is not None and (exprs[1].span.start, exprs[1].span.end) == (11, 33)


def test_one_expression_and_its_errors() -> None:
    assert parse_expression("10*!isClose + comf") == ast.Binary(
        "+", ast.Binary("*", ast.Number(10), ast.Unary("!", ast.Name("isClose"))), ast.Name("comf"))
    cases = {
        "3 *": ("`3 *`: the expression is incomplete", True, 1),
        "": ("``: the expression is incomplete", True, 1),
        "a,": ("`a,`: the expression is incomplete", True, 1),
        "a b": ("`a b`: unexpected `b`", False, 1),
        "x, y": ("`x, y`: expected one expression, not 2", False, 2),
        "a /* c": ("`a /* c`: unterminated block comment", False, 1),
        # no longer read as the end of a wrapping query: a `}` is a `}`
        "x }": ("`x }`: unexpected `}`", False, 1),
    }
    for text, (message, incomplete, count) in cases.items():
        with pytest.raises(ExpressionError) as caught:
            parse_expression(text)
        assert (str(caught.value), caught.value.incomplete, caught.value.count) == (message, incomplete, count)


def test_query_list_parses_as_inside_an_automaton() -> None:
    decls = parse_queries(SourceFile("<queries>", QUERIES))
    module = parse_text("automaton A {\n" + QUERIES + "}\n")
    assert decls == module.automata[0].members
    assert [d.name.name for d in decls] == ["Qa", "Qd", "Fig7"]
    assert decls[2].span is not None and decls[2].span.line == 3
    assert parse_queries(SourceFile("<queries>", "// none\n")) == ()


def test_syntax_errors_of_the_new_start_rules_speak_user_terms() -> None:
    error = failure(parse_queries, "query A: E<> x y").diagnostic
    assert (error.message, [n.message for n in error.notes]) == (
        "unexpected `y`", ["expected `query`, `under` or end of file"])
    error = failure(parse_queries, "query A: E<> x &&").diagnostic
    assert (error.message, [n.message for n in error.notes]) == ("unexpected end of file", ["expected an expression"])
    error = failure(parse_expressions, "(a - 100").diagnostic
    assert error.message == "unexpected end of file"
    assert error.notes[0].message == "expected an operator, `)`, `imply` or a comparison (`<`, `<=`, `==`, ...)"


def test_an_unfinished_file_still_lists_what_could_follow_the_last_token() -> None:
    # The end of an expression list or a query list is the end of the text: lark reduces there
    # before failing. The note is read before that, so it still offers the operators.
    error = failure(lambda s: parse_text(s.text), "automaton A {\n edge * -> B do r = r - 100").diagnostic
    assert error.notes[0].message.startswith("expected a declaration (`input`, `reward`, `location`, `edge`, "
                                             "`query`, ...), an operator, `,`")


def test_standard_queries_keep_their_lines() -> None:
    result = compile_file(ROOT / "examples" / "left_turn" / "model.ra")
    assert result.automaton is not None
    lines = [d.span.line for d in result.automaton.standard_queries if d.span is not None]
    assert lines == list(range(2, 2 + len(lines)))  # line 1 is the header, as it always was


def test_the_resolver_types_numbers_and_conditions() -> None:
    symbols = {"close": Symbol("input", "bool", None), "d": Symbol("input", "num", None),
               "sa": Symbol("reward", "num", None)}
    typer = ExpressionTyper(Scope("A", symbols, False, None))
    assert typer.expr(parse_expression("2 * d - 1"), RATE) == Num(Linear(Fraction(-1), (("d", Fraction(2)),)))
    assert typer.expr(parse_expression("close && d < 3"), GUARD) == Bool(
        typer.guard(parse_expression("close && d < 3")))
    assert typer.guard(parse_expression("2 * d < 3")) == BAtom("d", "<", Fraction(3, 2))
    assert typer.guard(parse_expression("close")) == BInput("close")
    assert typer.used_inputs == {"close", "d"}
    with pytest.raises(Unresolvable):
        typer.guard(parse_expression("d + 1"))
    with pytest.raises(Unresolvable):
        typer.linear(parse_expression("sa"), RATE)
    assert [d.message for d in typer.scope.diagnostics] == [
        "a guard needs a boolean, found a number", "reward `sa` cannot appear in a rate"]


def test_words_of_expressions_cannot_name_anything():
    """`and`, `or`, `not`, `imply`, `true`, `false` in a declaration are E0013 (an expression would read
    the word, and queries over an automaton called `not` did not parse: an internal error)."""
    import re as _re

    from rac.compiler import compile_text
    from rac.lang.parser import EXPRESSION_WORDS

    grammar = (Path(__file__).resolve().parents[2] / "grammar" / "rac.lark").read_text(encoding="utf-8")
    words = {w for name in ("IMPLY", "NOT_WORD", "OR_WORD", "AND_WORD", "TRUE", "FALSE")
             for w in _re.findall(rf'^{name}: "(\w+)"', grammar, _re.M)}
    assert words == set(EXPRESSION_WORDS)
    template = """automaton {a} {{
    input {i} : bool
    const {c} = 2
    reward {r}
    objective {r}
    sample every 1
    horizon 2
    initial location {loc} {{ {r}' == 1 }}
    edge * -> {loc} when {i}
    model {{
        bind {i} = offroad()
        scenario "x.xml"
    }}
}}
"""
    names = {"a": "A", "i": "gap", "c": "K", "r": "pr", "loc": "Go"}
    for word in EXPRESSION_WORDS:
        for slot in names:
            text = template.format(**{**names, slot: word})
            result = compile_text(text, "w.ra")
            codes = [d.code for d in result.diagnostics]
            if slot in ("i", "r") and codes == ["E0001"]:
                # Read in an expression too, where the word can start one (`when not`): the syntax
                # error there comes first.
                assert word in ("not",), (word, slot)
                continue
            assert codes == ["E0013"], (word, slot)
            assert f"`{word}` is a word of the language" in result.diagnostics[0].message


def test_an_empty_path_is_no_file_rather_than_the_working_folder(tmp_path: Path) -> None:
    # Path("") is "."; rac.load("") said ". is a directory"
    import rac
    from rac.lang.parser import read_source

    with pytest.raises(FileNotFoundError, match="the path is empty"):
        read_source("")
    with pytest.raises(FileNotFoundError, match="the path is empty"):
        rac.load("")
    with pytest.raises(IsADirectoryError, match="is a directory"):
        read_source(tmp_path)
