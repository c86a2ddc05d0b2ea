"""Round trips through the canonical printer: print ∘ parse is the identity on trees.

* random trees (hypothesis) print to text that parses back to an equal tree, and
  printing is idempotent;
* comments sprinkled anywhere a token boundary allows survive formatting exactly once;
* the language reference's example formats to a reviewed golden file;
* tricky precedence cases keep their meaning.
"""

from __future__ import annotations

import re
import time
from fractions import Fraction
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from rac.lang import ast
from rac.lang.format import format_expr, format_module, format_query, format_source
from rac.lang.parser import parse_expression, parse_text

GOLDEN = Path(__file__).parents[1] / "golden" / "driving.fmt.ra"

# The example of the language reference (/work/shared/design/language.md), copied verbatim.
DRIVING = """\
// Three objectives, safety > progress > comfort (Gu, FMAS 2024, Fig. 8 and Table 3)
automaton Driving {
    input isClose : bool              // an obstacle is nearer than the unsafe distance
    input prog    : bool              // the distance to the goal shrank since the last sample
    input comf    : bool              // acceleration and turning rate below the comfort limits
    input collide : bool
    input dgoal   : real in [0, 500]  // numeric inputs carry bounds

    assume collide imply isClose      // input valuations that cannot occur

    const PENALTY = 100               // large enough that progress and comfort can never
                                      // compensate an unsafe moment within the horizon

    reward sa, pr, co                 // accumulate like UPPAAL hybrid clocks; start at 0
    priority sa > pr > co             // highest first
    objective 10*sa + 5*pr + co       // the scalar the learner maximises

    sample every 0.1                  // inputs are read once per period (seconds)
    horizon 30                        // runs last at most 30 s

    initial location Normal  { sa' == 1;  pr' == 1;  co' == 1 }
    location Uncomfortable   { sa' == 1;  pr' == 1;  co' == -1 }
    location Stalled         { sa' == 1;  pr' == -1; co' == 0 }
    location Unsafe          { sa' == -1; pr' == 0;  co' == 0 }

    edge * -> Unsafe        when isClose                 do sa = sa - PENALTY
    edge * -> Stalled       when !isClose && !prog
    edge * -> Uncomfortable when !isClose && prog && !comf
    edge * -> Normal        when !isClose && prog && comf
    edge Unsafe -> Unsafe   when collide                 do sa = sa - 100

    at end when dgoal < 2 do pr = pr + 100              // terminal bonus, applied once

    query Qe: A[] isClose imply Unsafe
    query Qh: A[] Unsafe imply 10*sa + 5*pr + co <= 0
}
"""


def roundtrip(module: ast.Module) -> str:
    """Format, check the text parses back to ``module`` and formats to itself; return it."""
    text = format_module(module)
    reparsed = parse_text(text, "<formatted>")
    assert reparsed == module, text
    assert format_module(reparsed) == text
    return text


# ---------------------------------------------------------------- strategies
KEYWORDS = {
    "automaton", "input", "assume", "const", "reward", "priority", "strict", "objective", "sample", "every",
    "horizon", "initial", "location", "edge", "when", "do", "at", "end", "query", "under", "strategy",
    "control", "simulate", "maxE", "minE", "max", "min", "bool", "real", "int", "in", "true", "false",
    "imply", "not", "and", "or", "model", "scenario", "action", "bind", "step", "except",
}

# Plain names, names that start like keywords, and the letters of UPPAAL's quantifiers.
NAME_POOL = ["a", "b", "x1", "sa", "pr", "co", "_t", "Unsafe", "A", "E", "Pr", "inputs", "ends", "atx",
             "maxEx", "notably", "order", "android", "integer", "reals", "ifs", "truth", "E2", "Ax",
             # keywords only where a member starts (issue 25): names everywhere else
             "episode", "goal", "collision", "require"]
assert not KEYWORDS & set(NAME_POOL)

names = st.sampled_from(NAME_POOL)
idents = names.map(ast.Ident)

# Finite decimals >= 0 (negative numbers are unary minus applied to a number).
numbers = st.builds(lambda n, places: ast.Number(Fraction(n, 10**places)),
                    st.one_of(st.integers(0, 1000), st.integers(0, 10**12)), st.integers(0, 5))
leaves = st.one_of(
    numbers,
    st.booleans().map(ast.BoolLit),
    names.map(ast.Name),
    st.builds(ast.Qualified, names, names),
)
BINARY_OPS = ["+", "-", "*", "/", "<", "<=", ">", ">=", "==", "!=", "&&", "||", "imply"]


def _extend(children: st.SearchStrategy) -> st.SearchStrategy:
    return st.one_of(
        st.builds(ast.Unary, st.sampled_from(["-", "!"]), children),
        st.builds(ast.Binary, st.sampled_from(BINARY_OPS), children, children),
        st.builds(ast.Call, names, st.lists(children, max_size=3).map(tuple)),
    )


exprs = st.recursive(leaves, _extend, max_leaves=10)
small_exprs = st.recursive(leaves, _extend, max_leaves=3)


def tuples(elements: st.SearchStrategy, min_size: int = 0, max_size: int = 3) -> st.SearchStrategy:
    return st.lists(elements, min_size=min_size, max_size=max_size).map(tuple)


input_types = st.one_of(
    st.builds(ast.BoolType),
    st.builds(lambda kind: ast.NumericType(kind, None, None), st.sampled_from(["real", "int"])),
    st.builds(ast.NumericType, st.sampled_from(["real", "int"]), small_exprs, small_exprs),
)
updates = st.builds(ast.Update, idents, st.sampled_from(["=", "+=", "-="]), exprs)
bounds = st.builds(ast.Bound, st.sampled_from(["time", "steps"]), small_exprs)
unders = st.one_of(st.none(), names)
paths = st.sampled_from(["<>", "[]"])

queries = st.one_of(
    st.builds(ast.PathQuery, st.sampled_from(["A[]", "E<>", "E[]", "A<>"]), exprs, unders),
    st.builds(ast.LeadsToQuery, exprs, exprs, unders),
    st.builds(ast.ProbabilityQuery, bounds, st.one_of(st.none(), small_exprs), paths, exprs,
              st.one_of(st.none(), st.tuples(st.sampled_from(["<", "<=", ">", ">=", "==", "!="]),
                                             small_exprs)),
              unders),
    st.builds(ast.ExpectationQuery, bounds, small_exprs, st.sampled_from(["max", "min"]), exprs, unders),
    st.builds(ast.SimulateQuery, bounds, st.one_of(st.none(), small_exprs), tuples(exprs, 1), unders),
    st.builds(ast.ControlStrategy, names, st.sampled_from(["A[]", "E<>"]), exprs, unders),
    st.builds(ast.LearnStrategy, names, st.sampled_from(["maxE", "minE"]), exprs, bounds,
              tuples(small_exprs), tuples(small_exprs), paths, exprs, unders),
)

members = st.one_of(
    st.builds(ast.InputDecl, tuples(idents, 1), input_types),
    st.builds(ast.AssumeDecl, exprs),
    st.builds(ast.ConstDecl, idents, exprs),
    st.builds(ast.ParamDecl, tuples(idents, 1), small_exprs, small_exprs),
    st.builds(ast.RewardDecl, tuples(idents, 1)),
    st.builds(ast.PriorityDecl, st.booleans(), tuples(idents, 1, 4)),
    st.builds(ast.ObjectiveDecl, exprs),
    st.builds(ast.SampleDecl, small_exprs),
    st.builds(ast.HorizonDecl, small_exprs),
    st.builds(ast.LocationDecl, idents, st.booleans(), tuples(st.builds(ast.Flow, idents, exprs))),
    st.builds(ast.EdgeDecl, idents, idents, st.one_of(st.none(), exprs), tuples(updates)),
    # `*`, with or without `except` (only a `*` edge can exclude locations)
    st.builds(ast.EdgeDecl, st.none(), idents, st.one_of(st.none(), exprs), tuples(updates), tuples(idents)),
    st.builds(ast.EndDecl, st.one_of(st.none(), exprs), tuples(updates, 1)),
    st.builds(ast.EpisodeEndsDecl, exprs),
    st.builds(ast.GoalDecl, exprs),
    st.builds(ast.CollisionDecl, exprs),
    # the grammar reads any name as a check (the checker knows which exist) and any bound
    st.builds(ast.RequireDecl, st.one_of(idents, st.sampled_from(["risk", "stalling_never_pays"]).map(ast.Ident)),
              st.one_of(st.none(), small_exprs)),
    st.builds(ast.QueryDecl, idents, queries),
)
# The model block: settings under any name (the resolver, not the grammar, knows the real ones),
# scenario paths with characters that look like comments.
setting_names = st.sampled_from([*NAME_POOL, "base", "exponent", "sense_period", "granularity", "max_turn",
                                 "dynamics", "start_x", "offroad_from"])
model_items = st.one_of(
    st.builds(ast.ModelScenario, st.text(alphabet="ab_./*-:\\", max_size=12)),
    st.builds(ast.ModelAction, idents, small_exprs, small_exprs, small_exprs),
    st.builds(ast.ModelBinding, idents, exprs),
    st.builds(ast.ModelAllow, exprs),
    st.builds(ast.ModelSetting, setting_names.map(ast.Ident), exprs),
)
members = st.one_of(members, st.builds(ast.ModelDecl, tuples(model_items, 0, 6)))
automata = st.builds(ast.Automaton, idents, tuples(members, 0, 14))
modules = st.builds(ast.Module, tuples(automata, 1, 3))


# ---------------------------------------------------------------- random trees
@settings(max_examples=200, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(modules)
def test_random_modules_roundtrip(module: ast.Module) -> None:
    text = roundtrip(module)
    assert text.endswith("\n")
    assert not text.endswith("\n\n")


@settings(max_examples=200, deadline=None)
@given(exprs)
def test_random_expressions_roundtrip(expr: ast.Expr) -> None:
    module = parse_text(f"automaton M {{ assume {format_expr(expr)} }}")
    assert module.automata[0].members[0] == ast.AssumeDecl(expr)


@settings(max_examples=200, deadline=None)
@given(queries)
def test_random_queries_roundtrip(query: ast.Query) -> None:
    module = parse_text(f"automaton M {{ query Q: {format_query(query)} }}")
    assert module.automata[0].members[0] == ast.QueryDecl(ast.Ident("Q"), query)


def _sprinkle(text: str, data: st.DataObject) -> tuple[str, list[str]]:
    """Insert uniquely marked comments at token boundaries, line ends and on lines of their own."""
    markers: list[str] = []

    def comment(kind: str) -> str:
        marker = f"@{len(markers)}@"
        markers.append(marker)
        return {"line": f"// {marker}", "block": f"/* {marker} */", "multi": f"/* {marker}\n   more */"}[kind]

    kinds = st.sampled_from(["line", "block", "multi"])
    out: list[str] = []
    for line in text.split("\n"):
        if data.draw(st.integers(0, 5)) == 0:  # an own-line comment before this line
            indent = data.draw(st.sampled_from(["", "    "]))
            out.append(indent + comment(data.draw(kinds)))
        pieces = line.split(" ")
        rebuilt = pieces[0]
        for piece in pieces[1:]:  # every space of canonical text separates tokens
            if data.draw(st.integers(0, 12)) == 0:
                rebuilt += " " + comment(data.draw(st.sampled_from(["block", "multi"])))
            rebuilt += " " + piece
        if data.draw(st.integers(0, 3)) == 0:  # a trailing comment
            rebuilt += "  " + comment(data.draw(kinds))
        out.append(rebuilt)
    return "\n".join(out), markers


@settings(max_examples=200, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(modules, st.data())
def test_comments_survive_formatting(module: ast.Module, data: st.DataObject) -> None:
    commented, markers = _sprinkle(format_module(module), data)
    parsed = parse_text(commented)
    assert parsed == module
    assert len(parsed.comments) == len(markers)
    formatted = format_module(parsed)
    for marker in markers:
        assert formatted.count(marker) == 1, (marker, commented, formatted)
    reparsed = parse_text(formatted)
    assert reparsed == module
    assert format_module(reparsed) == formatted, (commented, formatted)
    assert format_module(parsed, comments=False) == format_module(module)


# ---------------------------------------------------------------- the reference example
def test_example_roundtrips_and_keeps_comments() -> None:
    original = parse_text(DRIVING, "driving.ra")
    formatted = format_source(DRIVING, "driving.ra")
    reparsed = parse_text(formatted, "driving.fmt.ra")
    assert reparsed == original
    assert len(original.comments) == 14
    for comment in original.comments:
        assert formatted.count(comment.text) == 1, comment.text
    assert [c.text for c in reparsed.comments] == [c.text for c in original.comments]
    assert format_source(formatted, "again") == formatted


def test_example_matches_golden() -> None:
    assert format_source(DRIVING, "driving.ra") == GOLDEN.read_text(encoding="utf-8")


def test_golden_is_a_fixed_point() -> None:
    golden = GOLDEN.read_text(encoding="utf-8")
    assert format_source(golden, "golden") == golden


def test_continuation_comment_stays_under_its_trailing_comment() -> None:
    text = format_source("automaton M {\n  const P = 1 // first\n              // second\n  horizon 3\n}\n")
    assert text == ("automaton M {\n"
                    "    const P = 1  // first\n"
                    "                 // second\n"
                    "\n"
                    "    horizon 3\n"
                    "}\n")


def test_comment_under_a_second_trailing_comment_is_not_a_continuation() -> None:
    """Continuations are printed under the first trailing comment, so only that column continues."""
    header = "automaton a /* x */ {  // y"
    second = " /* p */  /* q */"
    source = f"{header}\n{second.ljust(header.index('//'))}/* r */ assume 0\n}}\n"
    formatted = format_source(source)
    assert formatted == "automaton a {  /* x */ // y\n    /* p */\n    /* q */\n    /* r */\n    assume 0\n}\n"
    assert format_source(formatted) == formatted


# ---------------------------------------------------------------- comment placement
@pytest.mark.parametrize(("source", "expected"), [
    # leading comments, inside a declaration (even at the end of its first line),
    # before the closing brace, after it, at the end of the file
    (("// top\nautomaton M { // head\n  // lead\n  input a : bool\n  edge * -> L // tail\n"
      "  when /* inner */ a\n  // last\n} // done\n// bottom\n"),
     ("// top\nautomaton M {  // head\n    // lead\n    input a : bool\n\n    // tail\n    /* inner */\n"
      "    edge * -> L when a\n    // last\n}  // done\n\n// bottom\n")),
    # comments between automata lead the next one
    ("automaton A { }\n// about B\nautomaton B { horizon 1 }\n",
     "automaton A {\n}\n\n// about B\nautomaton B {\n    horizon 1\n}\n"),
    # a comment within a location body moves before the location
    ("automaton M {\n  location L {\n    sa' == 1; // grows\n    pr' == 0\n  }\n}\n",
     "automaton M {\n    // grows\n    location L { sa' == 1; pr' == 0 }\n}\n"),
    # several trailing comments on one line stay on it
    ("automaton M {\n  horizon 1 /* a */ // b\n}\n", "automaton M {\n    horizon 1  /* a */ // b\n}\n"),
])
def test_comment_placement(source: str, expected: str) -> None:
    assert format_source(source) == expected
    assert format_source(expected) == expected


# ---------------------------------------------------------------- precedence
@pytest.mark.parametrize(("source", "expected"), [
    ("a - (b - c)", "a - (b - c)"),
    ("(a - b) - c", "a - b - c"),
    ("a / (b * c)", "a / (b * c)"),
    ("(a + b) * c", "(a + b) * c"),
    ("-(a + b)", "-(a + b)"),
    ("-a + b", "-a + b"),
    ("- -1", "-(-1)"),
    ("-(-a)", "-(-a)"),
    ("!!a", "!!a"),
    ("!(a && b)", "!(a && b)"),
    ("not a && b", "!a && b"),
    ("not a < b", "!(a < b)"),
    ("a and b or c", "(a && b) || c"),  # not needed by the grammar; kept for the reader
    ("a && (b || c)", "a && (b || c)"),
    ("a || (b || c)", "a || (b || c)"),
    ("a imply (b imply c)", "a imply b imply c"),
    ("(a imply b) imply c", "(a imply b) imply c"),
    ("(a < b) == c", "(a < b) == c"),
    ("a == (b < c)", "a == (b < c)"),
    ("a + b < c * d", "a + b < c * d"),
    ("(a || b) && c", "(a || b) && c"),
    ("a imply b || c", "a imply b || c"),
    ("(a imply b) || c", "(a imply b) || c"),
    ("f(a imply b, -(1), g())", "f(a imply b, -1, g())"),
    ("D.Unsafe && 2.50 > 0.125", "D.Unsafe && 2.5 > 0.125"),
    ("1e3 + 2.5E-2 + 007", "1000 + 0.025 + 7"),
    ("a - -b * -c", "a - -b * -c"),
])
def test_precedence(source: str, expected: str) -> None:
    parsed = parse_text(f"automaton M {{ assume {source} }}").automata[0].members[0].expr
    assert format_expr(parsed) == expected
    again = parse_text(f"automaton M {{ assume {expected} }}").automata[0].members[0].expr
    assert again == parsed


def test_numbers() -> None:
    assert format_expr(ast.Number(Fraction(1, 10))) == "0.1"
    assert format_expr(ast.Number(Fraction(9, 4))) == "2.25"
    assert format_expr(ast.Number(Fraction(1, 1024))) == "0.0009765625"
    assert format_expr(ast.Number(Fraction(10**20))) == "1" + "0" * 20
    assert format_expr(ast.Number(Fraction(10**30))) == "1e30"  # long: with an exponent
    assert format_expr(ast.Number(Fraction(1, 3))) == "(1 / 3)"  # no decimal: an equal value


@pytest.mark.parametrize("query", [
    "A[] a imply b",
    "E<> D.Unsafe under S",
    "E[] a",
    "A<> a",
    "a --> b under S",
    "Pr[<=30](<> a)",
    "Pr[#<=10;100]([] a) >= 0.9 under S",
    "E[<=30;100](max: 10 * sa + co)",
    "simulate[<=30]{sa, pr}",
    "simulate[#<=5;3]{sa}",
    "strategy S = control: A[] !Unsafe",
    "strategy S = control: E<> a under T",
    "strategy S = maxE(sa)[<=30]{a, b}->{c}: <> a under S0",
    "strategy S = minE(sa)[#<=30]{}->{}: [] a",
])
def test_queries_are_canonical(query: str) -> None:
    module = parse_text(f"automaton M {{ query Q: {query} }}")
    assert format_query(module.automata[0].members[0].query) == query
    assert re.search(r"\n    query Q: ", format_module(module))


@settings(max_examples=300, deadline=None)
@given(st.integers(1, 10**30), st.integers(-307, 290))
def test_numbers_of_any_size_print_and_read_back(digits: int, exponent: int) -> None:
    """Numbers up to the limits of E0010 print in a form that parses back to the same value, also
    where the plain decimal would be hundreds of digits (``rac fmt`` printed 1e308 as 309 digits,
    which no longer parsed)."""
    value = Fraction(digits) * Fraction(10) ** exponent
    if not Fraction(1, 10**307) <= value <= Fraction(10**308):
        return
    text = format_expr(ast.Number(value))
    assert len(text) <= 60
    assert parse_expression(text) == ast.Number(value)



def test_a_large_commented_file_formats_in_linear_time() -> None:
    """Each comment was placed by a scan of every declaration: 6,000 commented edges took 9 s to format
    (quadratic in the file's size; a file may have 1 MB). Now a bisection: well under a second."""
    lines = ["automaton Big {", "    input x : real in [0, 100]", "    reward r", "    objective r",
             "    sample every 1", "    horizon 10", "    initial location L0 { r' == 1 }  // the start",
             *(f"    location L{i} {{ r' == {i % 3 - 1} }}  // location {i}" for i in range(1, 300)),
             *(f"    edge L{i % 300} -> L{(i + 1) % 300} when x > {i % 100} do r += {i % 7}  // edge {i}"
               for i in range(6000)), "}"]
    module = parse_text("\n".join(lines) + "\n")
    start = time.process_time()
    text = format_module(module)
    assert time.process_time() - start < 2
    assert text.count("// edge ") == 6000 and text.count("// location ") == 299
