"""The alignment rules of ``rac fmt``'s canonical layout (docs/language.md, "rac fmt").

A run is a block of consecutive declarations of one kind: a blank line (printed where the kind
of declaration changes) or an own-line comment ends it. In a run

* inputs align their ``:``, constants and model bindings their ``=``;
* locations start their bodies ``{`` in one column, and the i-th flows of the bodies in one column;
* edges align ``when`` and ``do``, ``at end`` clauses their ``do``;

and trailing comments of consecutive lines share one column, continuation lines included.
"""

from __future__ import annotations

import pytest

from rac.lang.columns import align_cells
from rac.lang.format import format_member, format_source
from rac.lang.parser import parse_text


def fmt(body: str) -> str:
    """The formatted members of ``automaton M { BODY }``, without the automaton's first and last lines."""
    text = format_source(f"automaton M {{\n{body}\n}}\n")
    assert format_source(text) == text  # idempotent
    assert parse_text(text) == parse_text(f"automaton M {{\n{body}\n}}\n")  # the same tree
    return "\n".join(text.splitlines()[1:-1]) + "\n"


# ---------------------------------------------------------------- the column helper
@pytest.mark.parametrize(("rows", "lines"), [
    ([["a", "bb", "c"], ["aaa", "b", "cc"]], ["a   bb c", "aaa b  cc"]),
    # an empty cell before a filled one keeps its column; trailing empty cells add nothing
    ([["a", "", "c"], ["aaa", "bb", ""], ["a"]], ["a      c", "aaa bb", "a"]),
    # a column empty in every row takes no room
    ([["a", "", "c"], ["bb", "", "d"]], ["a  c", "bb d"]),
    ([], []),
])
def test_align_cells(rows: list[list[str]], lines: list[str]) -> None:
    assert align_cells(rows) == lines


# ---------------------------------------------------------------- inputs, constants, bindings
def test_a_run_of_inputs_aligns_its_colons() -> None:
    assert fmt("input a : bool\ninput long_name, b : real in [0, 1]\n input c:int in [0,3]") == (
        "    input a            : bool\n"
        "    input long_name, b : real in [0, 1]\n"
        "    input c            : int in [0, 3]\n"
    )


def test_an_own_line_comment_ends_a_run_of_inputs() -> None:
    assert fmt("input a : bool\ninput bb : bool\n// the numeric ones\ninput long_name : real in [0, 1]\n"
               "input c : int in [0, 3]") == (
        "    input a  : bool\n"
        "    input bb : bool\n"
        "    // the numeric ones\n"
        "    input long_name : real in [0, 1]\n"
        "    input c         : int in [0, 3]\n"
    )


def test_constants_align_their_equals_signs() -> None:
    assert fmt("const P = 100\nconst MARGIN = P / 4") == (
        "    const P      = 100\n"
        "    const MARGIN = P / 4\n"
    )


def test_model_bindings_align_their_equals_signs_but_not_other_items() -> None:
    text = format_source("automaton M {\n model {\n  exponent 2\n  bind a = x()\n  bind long = y()\n"
                         "  allow when z()\n  bind b = w()\n }\n}\n")
    assert text == ("automaton M {\n"
                    "    model {\n"
                    "        exponent 2\n"
                    "        bind a    = x()\n"
                    "        bind long = y()\n"
                    "        allow when z()\n"
                    "        bind b = w()\n"
                    "    }\n"
                    "}\n")
    assert format_source(text) == text


# ---------------------------------------------------------------- locations
def test_a_run_of_locations_aligns_bodies_and_flows() -> None:
    assert fmt("initial location Normal { sa' == 1; pr' == 1; co' == 1 }\n"
               "location Uncomfortable { sa' == 1; pr' == 1; co' == -1 }\n"
               "location Stalled { sa' == 1; pr' == -1; co' == 0 }\n"
               "location Unsafe { sa' == -1; pr' == 0; co' == 0 }\n"
               "location Idle { }") == (
        "    initial location Normal { sa' == 1;  pr' == 1;  co' == 1 }\n"
        "    location Uncomfortable  { sa' == 1;  pr' == 1;  co' == -1 }\n"
        "    location Stalled        { sa' == 1;  pr' == -1; co' == 0 }\n"
        "    location Unsafe         { sa' == -1; pr' == 0;  co' == 0 }\n"
        "    location Idle           { }\n"
    )


def test_a_location_alone_is_printed_as_format_member_prints_it() -> None:
    member = parse_text("automaton M { location L { a' == 1; b' == -1 } }").automata[0].members[0]
    assert format_member(member) == "location L { a' == 1; b' == -1 }"
    assert fmt("location L { a' == 1; b' == -1 }") == "    location L { a' == 1; b' == -1 }\n"


# ---------------------------------------------------------------- edges and `at end`
def test_a_run_of_edges_aligns_when_and_do() -> None:
    assert fmt("edge * -> Unsafe when isClose do sa = sa - 100\n"
               "edge * -> Uncomfortable when !isClose && !comf\n"
               "edge Unsafe -> Unsafe when collide do sa -= 100\n"
               "edge A -> B do sa += 1\n"
               "edge B -> A") == (
        "    edge * -> Unsafe        when isClose           do sa = sa - 100\n"
        "    edge * -> Uncomfortable when !isClose && !comf\n"
        "    edge Unsafe -> Unsafe   when collide           do sa -= 100\n"
        "    edge A -> B                                    do sa += 1\n"
        "    edge B -> A\n"
    )


def test_edges_without_guards_put_do_right_after_the_heads() -> None:
    assert fmt("edge A -> B do x = 1\nedge Long -> A do x = 2") == (
        "    edge A -> B    do x = 1\n"
        "    edge Long -> A do x = 2\n"
    )


def test_an_own_line_comment_ends_a_run_of_edges() -> None:
    assert fmt("edge * -> Unsafe when isClose do sa -= 1\n// recovery\nedge Unsafe -> Normal when !isClose") == (
        "    edge * -> Unsafe when isClose do sa -= 1\n"
        "    // recovery\n"
        "    edge Unsafe -> Normal when !isClose\n"
    )


def test_at_end_clauses_align_do() -> None:
    assert fmt("at end when goal do pr += 100\nat end when !goal && near do pr += 10\nat end do co += 1") == (
        "    at end when goal          do pr += 100\n"
        "    at end when !goal && near do pr += 10\n"
        "    at end                    do co += 1\n"
    )


# ---------------------------------------------------------------- trailing comments
def test_trailing_comments_of_a_run_share_a_column() -> None:
    """A line without a comment stays in the run (and does not move the column); continuation
    lines are printed in the column."""
    assert fmt("input a : bool // first\ninput collide : bool\ninput long_name : real in [0, 1] // third\n"
               "                                 // more about it\ninput b : bool // fourth") == (
        "    input a         : bool            // first\n"
        "    input collide   : bool\n"
        "    input long_name : real in [0, 1]  // third\n"
        "                                      // more about it\n"
        "    input b         : bool            // fourth\n"
    )


def test_a_blank_line_ends_a_run_of_trailing_comments() -> None:
    """Another kind of declaration starts after a blank line, and its comments a new column."""
    assert fmt("input isClose : bool // a\nassume isClose // b\nconst P = 100 // c\n              // d\n"
               "reward sa, pr // e\npriority sa > pr // f\nobjective 10 * sa + pr // g") == (
        "    input isClose : bool  // a\n"
        "\n"
        "    assume isClose  // b\n"
        "\n"
        "    const P = 100  // c\n"
        "                   // d\n"
        "\n"
        "    reward sa, pr           // e\n"
        "    priority sa > pr        // f\n"
        "    objective 10 * sa + pr  // g\n"
    )


def test_an_own_line_comment_ends_a_run_of_trailing_comments() -> None:
    assert fmt("horizon 30 // a\n// about the period\nsample every 0.1 // b") == (
        "    horizon 30  // a\n"
        "    // about the period\n"
        "    sample every 0.1  // b\n"
    )


def test_a_long_line_keeps_its_comment_close_and_the_others_aligned() -> None:
    long_guard = " && ".join(f"c{i}" for i in range(20))
    text = fmt(f"assume a // x\nassume {long_guard} // y\nassume bb // z")
    assert text == (
        "    assume a   // x\n"
        f"    assume {long_guard}  // y\n"
        "    assume bb  // z\n"
    )


def test_comments_in_a_model_block_align_per_run() -> None:
    text = format_source("automaton M {\n model {\n  exponent 2 // a\n  decide_period 0.2 // b\n"
                         "  // own line\n  bind a = x() // c\n  bind long = y() // d\n }\n}\n")
    assert text == ("automaton M {\n"
                    "    model {\n"
                    "        exponent 2         // a\n"
                    "        decide_period 0.2  // b\n"
                    "        // own line\n"
                    "        bind a    = x()  // c\n"
                    "        bind long = y()  // d\n"
                    "    }\n"
                    "}\n")
    assert format_source(text) == text


def test_multiplication_is_spaced_like_every_binary_operator() -> None:
    assert fmt("objective 10*sa + 5*pr/2 + co") == "    objective 10 * sa + 5 * pr / 2 + co\n"


def test_and_inside_or_keeps_its_parentheses() -> None:
    """The grammar does not need them; a reader does. The tree is the same either way."""
    from rac.lang.format import format_expr
    from rac.lang.parser import parse_expression

    for text, printed in [("turn == 0 || (a && !b)", "turn == 0 || (a && !b)"),
                          ("a && b || c", "(a && b) || c"),
                          ("(a || b) && c", "(a || b) && c"),
                          ("a || b || c", "a || b || c")]:
        assert format_expr(parse_expression(text)) == printed
        assert parse_expression(printed) == parse_expression(text)
