"""``edge * except A, B -> T``: a ``*`` edge that leaves some locations out.

* the parser keeps each excluded name with its span, ``except`` is a keyword only after ``*``,
  and the formatter prints the canonical form;
* the checker resolves the excluded names once (E0101 with a "did you mean", E0103), warns about an
  exclusion that changes nothing (W0108) and about an edge that leaves every location out (W0109),
  and expands ``*`` into edges from the remaining locations only;
* the analyses see the expansion: determinism (E0301), P2 (E0402) and reachability (W0302) give
  other answers for the same file with plain ``*``;
* the IR, both targets and the engine needed no change: the Python module, the UPPAAL network
  (run sample by sample, and accepted by UPPAAL's parser) and the engine's arithmetic follow the
  interpreter, and none of them leaves an excluded location by the edge.
"""

from __future__ import annotations

import random

import numpy as np
import pytest
from test_uppaal import Parsed, run_network
from utap import Utap

from rac.compiler import CompileResult, compile_text
from rac.engine.product import MirrorArithmetic
from rac.lang import ast
from rac.lang.format import format_source
from rac.lang.parser import ParseFailure, parse_text
from rac.runtime.interpreter import RewardAutomaton
from rac.targets.python import generate_python
from rac.targets.uppaal.automaton import generate_uppaal

#: Parked is for good: no edge leaves it, not even into Unsafe. With plain `*`, a run parks, earns
#: progress at 100/s, and then enters Unsafe with an objective far above 0 (P2 fails).
PARKING = """\
automaton Parking {
    input close   : bool
    input arrived : bool

    reward sa, pr
    priority sa > pr
    objective 10*sa + pr

    sample every 1
    horizon 20

    initial location Driving { sa' == 1; pr' == 1 }
    location Parked          { sa' == 1; pr' == 100 }
    location Unsafe          { sa' == -1 }

    edge * except Parked -> Unsafe when close do sa -= 100
    edge Driving -> Parked when arrived && !close
    edge Unsafe -> Driving when !close
}
"""

#: Crashed fines itself every sample; with plain `*` the edges to Near and Normal also leave it.
CRASH = """\
automaton Crash {
    input close : bool
    input hit   : bool

    assume hit imply close

    reward sa
    objective sa

    sample every 1
    horizon 10

    initial location Normal { sa' == 1 }
    location Near           { }
    location Crashed        { sa' == -1 }

    edge * except Crashed -> Near   when close && !hit
    edge * except Crashed -> Normal when !close
    edge * -> Crashed when hit do sa -= 10
    edge Crashed -> Crashed do sa -= 1
}
"""

#: Three locations, edges written between `EDGES` and the end.
SMALL = """\
automaton Small {
    input x : bool
    input y : bool

    reward r
    objective r

    sample every 1
    horizon 10

    initial location A { r' == 1 }
    location B { }
    location C { }

EDGES
}
"""


def small(*edges: str) -> str:
    return SMALL.replace("EDGES", "\n".join(f"    {e}" for e in edges))


def checked(text: str) -> CompileResult:
    return compile_text(text, "test.ra")


def codes(result: CompileResult) -> list[str]:
    return [d.code for d in result.diagnostics]


def plain(text: str) -> str:
    """The same file with every exclusion removed (`*` from every location but the target)."""
    for name in ("Parked", "Crashed", "A"):
        text = text.replace(f" except {name} ", " ")
    assert " except " not in text
    return text


# ---------------------------------------------------------------- syntax
def test_the_excluded_names_are_kept_with_their_spans() -> None:
    text = "automaton M {\n    edge * except Unsafe, Parked -> Normal when close\n}\n"
    (edge,) = parse_text(text).automata[0].members
    assert isinstance(edge, ast.EdgeDecl)
    assert edge.source is None and edge.target == ast.Ident("Normal")
    assert edge.excluded == (ast.Ident("Unsafe"), ast.Ident("Parked"))
    spans = [(i.span.line, i.span.column, text[i.span.start:i.span.end]) for i in edge.excluded if i.span]
    assert spans == [(2, 19, "Unsafe"), (2, 27, "Parked")]


def test_except_is_a_keyword_only_after_the_star() -> None:
    module = parse_text("automaton M {\n input except : bool\n location except { }\n"
                        " edge except -> except when except\n edge * except except -> B\n}")
    members = module.automata[0].members
    assert members[2] == ast.EdgeDecl(ast.Ident("except"), ast.Ident("except"), ast.Name("except"), ())
    assert members[3] == ast.EdgeDecl(None, ast.Ident("B"), None, (), (ast.Ident("except"),))


@pytest.mark.parametrize(("text", "message", "expected"), [
    ("edge A except B -> C", "unexpected `except`", "expected `->`"),
    ("edge * except -> C", "unexpected `->`", "expected a name"),
    ("edge * except B, -> C", "unexpected `->`", "expected a name"),
    ("edge * B -> C", "unexpected `B`", "expected `->` or `except`"),
])
def test_except_syntax_errors(text: str, message: str, expected: str) -> None:
    with pytest.raises(ParseFailure) as caught:
        parse_text(f"automaton M {{\n    {text}\n}}\n")
    diagnostic = caught.value.diagnostic
    assert (diagnostic.code, diagnostic.message, diagnostic.notes[0].message) == ("E0001", message, expected)


def test_an_edge_without_except_excludes_nothing() -> None:
    (edge,) = parse_text("automaton M { edge * -> B }").automata[0].members
    assert isinstance(edge, ast.EdgeDecl) and edge.excluded == ()


def test_only_a_star_edge_can_exclude() -> None:
    with pytest.raises(ValueError, match="only a `\\*` edge"):
        ast.EdgeDecl(ast.Ident("A"), ast.Ident("B"), None, (), (ast.Ident("C"),))


def test_the_formatter_prints_the_canonical_form() -> None:
    text = "automaton M {\n  edge   *  except  A ,B,C->  T when x   do r -= 1 // not A\n}\n"
    formatted = format_source(text)
    assert "    edge * except A, B, C -> T when x do r -= 1  // not A\n" in formatted
    assert format_source(formatted) == formatted


# ---------------------------------------------------------------- the checker
def test_star_is_expanded_without_the_excluded_locations() -> None:
    automaton = checked(PARKING).raise_for_errors()
    names = automaton.location_names
    edges = {(names[e.source], names[e.target]) for e in automaton.all_edges()}
    assert edges == {("Driving", "Unsafe"), ("Driving", "Parked"), ("Unsafe", "Driving")}
    assert automaton.edges[names.index("Parked")] == ()


def test_an_unknown_excluded_location_says_what_it_may_be() -> None:
    result = checked(small("edge * except Cc -> B when x"))
    (diagnostic,) = result.diagnostics
    assert (diagnostic.code, diagnostic.message) == ("E0101", "unknown location `Cc`")
    assert diagnostic.hints == ("did you mean `C`?",)
    assert diagnostic.span is not None and (diagnostic.span.line, diagnostic.span.column) == (15, 19)


def test_every_bad_name_of_an_edge_is_reported() -> None:
    result = checked(small("edge * except x, Zz -> Q when x"))
    assert sorted((d.code, d.message) for d in result.diagnostics) == [
        ("E0101", "unknown location `Q`"), ("E0101", "unknown location `Zz`"),
        ("E0103", "`x` is an input, not a location")]
    assert result.automaton is None


def test_a_location_excluded_twice_is_a_warning() -> None:
    result = checked(small("edge * except C, C -> B when x", "edge B -> A when !x"))
    (diagnostic,) = [d for d in result.diagnostics if d.code == "W0108"]
    assert diagnostic.message == "`C` is excluded twice"
    assert diagnostic.span is not None and diagnostic.span.column == 22
    assert diagnostic.notes[0].span is not None and diagnostic.notes[0].span.column == 19
    assert result.ok


def test_excluding_the_target_is_a_warning() -> None:
    result = checked(small("edge * except B -> B when x", "edge B -> A when !x"))
    (diagnostic,) = [d for d in result.diagnostics if d.code == "W0108"]
    assert diagnostic.message == "`B` is the edge's target, which `*` leaves out already"
    assert result.ok


def test_excluding_every_location_is_a_warning() -> None:
    result = checked(small("edge * except A, C -> B when x && !x", "edge A -> C when y", "edge C -> A when !y"))
    # the edge is never expanded: no W0304 for its guard, one W0109 for the exclusion
    assert codes(result).count("W0109") == 1 and "W0304" not in codes(result)
    (diagnostic,) = [d for d in result.diagnostics if d.code == "W0109"]
    assert diagnostic.message == "this edge leaves out every location: it never applies"
    assert result.automaton is not None and all(e.target != 1 for e in result.automaton.all_edges())


# ---------------------------------------------------------------- the analyses see the exclusion
def test_determinism_sees_the_exclusion() -> None:
    assert "E0301" in codes(checked(plain(CRASH)))
    result = checked(CRASH)
    assert result.ok and not result.diagnostics
    assert any(f.startswith("deterministic") for f in result.proved)


def test_p2_sees_the_exclusion() -> None:
    plain_result = checked(plain(PARKING))
    (p2,) = [d for d in plain_result.diagnostics if d.code == "E0402"]
    assert "Parked" in str(p2.data)
    result = checked(PARKING)
    assert result.ok and not result.diagnostics
    assert any(f.startswith("P2 holds for `sa`") for f in result.proved)


def test_reachability_sees_the_exclusion() -> None:
    edges = ("edge * except A -> B when x", "edge B -> C when !x")
    assert "W0302" not in codes(checked(plain(small(*edges))))
    result = checked(small(*edges))
    assert sorted(d.message for d in result.diagnostics if d.code == "W0302") == [
        "location `B` is unreachable", "location `C` is unreachable"]


# ---------------------------------------------------------------- targets and engine: unchanged
def parking_trace(seed: int, length: int) -> list[dict[str, object]]:
    rng = random.Random(seed)
    return [{"close": rng.random() < 0.4, "arrived": rng.random() < 0.3} for _ in range(length)]


@pytest.mark.parametrize("seed", range(3))
def test_the_python_target_follows_the_interpreter(seed: int) -> None:
    automaton = checked(PARKING).raise_for_errors()
    namespace: dict[str, object] = {}
    exec(compile(generate_python(automaton, source_name="test.ra"), "<parking>", "exec"), namespace)  # noqa: S102
    generated, interpreter = namespace["Parking"](), RewardAutomaton(automaton)
    trace = [{"close": False, "arrived": True}, {"close": True, "arrived": False}, *parking_trace(seed, 18)]
    for inputs in trace:
        assert generated.step(inputs) == interpreter.step(inputs)
        assert generated.location == interpreter.location
        assert generated.rewards == interpreter.rewards
    # parked at the first sample, and `close` at the second did not leave Parked
    assert interpreter.location == "Parked" and interpreter.rewards["sa"] == 20


@pytest.mark.parametrize("seed", range(3))
def test_the_uppaal_network_follows_the_interpreter(seed: int) -> None:
    run_network(checked(PARKING).raise_for_errors(), seed)


def test_the_uppaal_model_has_no_edge_from_the_excluded_location(utap: Utap) -> None:
    model = generate_uppaal(checked(PARKING).raise_for_errors(), source_name="parking.ra",
                            model_name="parking.xml")
    template = Parsed(model.xml).templates["Parking"]
    names = {loc.get("id"): loc.findtext("name") for loc in template.findall("location")}
    # the edges of the automaton synchronise on `sense?` (the self-loops on `accrue?` accrue the rewards)
    moves = {(names[t.find("source").get("ref")], names[t.find("target").get("ref")])
             for t in template.findall("transition")
             if t.findtext("label[@kind='synchronisation']") == "sense?"}
    assert moves == {("Driving", "Unsafe"), ("Driving", "Parked"), ("Unsafe", "Driving")}
    utap.validate(model.xml, model.queries, "parking")


def test_the_engine_does_not_leave_an_excluded_location() -> None:
    automaton = checked(PARKING).raise_for_errors()
    names = automaton.location_names
    loc = np.array([names.index("Driving"), names.index("Parked")])
    inputs = np.array([[1, 0], [1, 0]], dtype=np.int64)  # close, not arrived
    after, mirrors = MirrorArithmetic(automaton, 10_000).edges(loc, inputs, np.zeros((2, 2), dtype=np.int64))
    assert [names[int(i)] for i in after] == ["Unsafe", "Parked"]
    assert mirrors[:, 0].tolist() == [-1_000_000, 0]
