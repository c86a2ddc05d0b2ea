"""rac.lang.grammar: one LALR parser for every start rule, and the terminals read back from the grammar."""

from __future__ import annotations

import re

import pytest
from lark.exceptions import UnexpectedInput

from rac.lang.grammar import EXPRESSIONS, MODULE, QUERIES, START_RULES, lark_parser, literal_terminal, terminal_regexp


def test_the_parser_is_built_once() -> None:
    assert lark_parser() is lark_parser()
    assert START_RULES == ("start", "expr_list", "query_list")


def test_every_start_rule_parses_its_own_text() -> None:
    parser = lark_parser()
    assert parser.parse("mindist(), 3 * collision_distance", start=EXPRESSIONS).data == EXPRESSIONS
    assert parser.parse("query Qb: E[] !collide()", start=QUERIES).data == QUERIES
    module = "automaton A { input p : bool  reward r  objective r  initial location L { r' == 1 } }"
    assert parser.parse(module, start=MODULE).data == MODULE


def test_a_start_rule_refuses_the_text_of_another() -> None:
    with pytest.raises(UnexpectedInput):
        lark_parser().parse("query Qb: E[] !collide()", start=EXPRESSIONS)


def test_literal_terminals_are_their_text() -> None:
    assert literal_terminal("RBRACE") == "}"
    assert literal_terminal("LBRACE") == "{"
    assert literal_terminal("NAME") is None  # a pattern, not a literal
    assert literal_terminal("NO_SUCH_TERMINAL") is None


def test_terminal_regexp_matches_as_the_lexer_does() -> None:
    comment = re.compile(terminal_regexp("LINE_COMMENT"))
    assert comment.fullmatch("// a comment")
    assert not comment.fullmatch("/ not a comment")
    name = re.compile(terminal_regexp("NAME"))
    assert name.fullmatch("isClose_2") and not name.fullmatch("2x")
    with pytest.raises(KeyError):
        terminal_regexp("NO_SUCH_TERMINAL")
