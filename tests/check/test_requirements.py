"""Issue 25's declarations resolved into the IR: ``episode ends when``, ``goal when`` and ``collision when``
typed like edge guards, and ``require`` (E1009, E1010, E0106) with its bound exact."""

from __future__ import annotations

from fractions import Fraction

import pytest

from rac import ir
from rac.check.resolve import Resolver
from rac.compiler import compile_text
from rac.core.diagnostics import Diagnostic
from rac.lang.parser import parse_text

SOURCE = """\
automaton Driving {
    input collide : bool
    input dgoal   : real in [0, 100]
    input lane    : int in [0, 3]

    const BOUND = 1 / 1000

    reward sa
    objective sa

    sample every 0.1
    horizon 3

    initial location Normal { sa' == 1 }
    location Crashed        { sa' == -1 }

    edge Normal -> Crashed when collide

    episode ends when collide || dgoal < 2
    goal when dgoal < 2 && lane != 3
    collision when collide
    require risk <= 1e-4
    require ending_early_never_pays
}
"""

DGOAL_NEAR = ir.BAtom("dgoal", "<", Fraction(2))


def resolved(text: str = SOURCE) -> ir.Automaton:
    result = compile_text(text, analyse=False)
    assert result.ok, [d.message for d in result.diagnostics]
    assert result.automaton is not None
    return result.automaton


def errors(text: str) -> list[Diagnostic]:
    return [d for d in compile_text(text, analyse=False).diagnostics if d.is_error]


def only_error(text: str, code: str) -> Diagnostic:
    found = errors(text)
    assert [d.code for d in found] == [code], [d.message for d in found]
    return found[0]


def test_the_declarations_fill_the_automaton() -> None:
    automaton = resolved()
    assert automaton.episode_ends == ir.BOr((ir.BInput("collide"), DGOAL_NEAR))
    assert automaton.goal == ir.BAnd((DGOAL_NEAR, ir.BAtom("lane", "!=", Fraction(3))))
    assert automaton.collision == ir.BInput("collide")
    assert automaton.requirements == (ir.Requirement("risk", Fraction(1, 10000)),
                                      ir.Requirement("ending_early_never_pays"))
    risk, ending = automaton.requirements
    assert type(risk.bound) is Fraction
    assert risk.span is not None and (risk.span.line, risk.span.column) == (22, 5)
    assert ending.span is not None and (ending.span.line, ending.span.end_column) == (23, 36)
    assert automaton.spans["decl:goal"].line == 20
    assert automaton.spans["decl:episode_ends"].line == 19
    assert automaton.spans["decl:collision"].line == 21


def test_without_them_the_fields_keep_their_defaults() -> None:
    bare = SOURCE.split("    episode ends")[0] + "}\n"
    automaton = resolved(bare.replace("    input lane    : int in [0, 3]\n", "")
                         .replace("    input dgoal   : real in [0, 100]\n", ""))
    assert (automaton.episode_ends, automaton.goal, automaton.collision, automaton.requirements) == \
        (None, None, None, ())


def test_an_input_read_only_by_a_goal_is_used() -> None:
    diagnostics = compile_text(SOURCE, analyse=False).diagnostics
    assert not [d for d in diagnostics if d.code == "W0303"]


@pytest.mark.parametrize(("bound", "value"), [
    ("0", Fraction(0)), ("1", Fraction(1)), ("BOUND", Fraction(1, 1000)), ("BOUND / 2 + 0.25", Fraction(501, 2000)),
    ("1e-307", Fraction(1, 10**307)),
])
def test_the_risk_bound_is_exact(bound: str, value: Fraction) -> None:
    automaton = resolved(SOURCE.replace("require risk <= 1e-4", f"require risk <= {bound}"))
    assert automaton.requirements[0] == ir.Requirement("risk", value)


def test_a_parameter_bounds_the_risk_at_its_value() -> None:
    text = SOURCE.replace("    const BOUND = 1 / 1000\n", "    param P in [0.001, 0.01]\n") \
        .replace("require risk <= 1e-4", "require risk <= P")
    assert resolved(text).requirements[0].bound == Fraction(1, 1000)
    automaton = Resolver(parse_text(text).automata[0], {"P": Fraction(1, 200)}).run()
    assert automaton is not None and automaton.requirements[0].bound == Fraction(1, 200)


@pytest.mark.parametrize(("wrong", "message", "hints"), [
    ("require riks", "unknown requirement `riks`", ["did you mean `risk`?"]),
    ("require stalling_never_pay", "unknown requirement `stalling_never_pay`",
     ["did you mean `stalling_never_pays`?"]),
    ("require speed", "unknown requirement `speed`", []),
    ("require risk", "`require risk` needs a bound: the largest risk tolerance p* allowed",
     ["write e.g. `require risk <= 1e-4`"]),
    ("require risk <= 1.5", "the bound of `require risk` must lie in [0, 1] (found 1.5)",
     ["write a probability, e.g. `require risk <= 1e-4`"]),
    ("require risk <= -BOUND", "the bound of `require risk` must lie in [0, 1] (found -0.001)",
     ["write a probability, e.g. `require risk <= 1e-4`"]),
    ("require stalling_never_pays <= 0.5", "`require stalling_never_pays` takes no bound",
     ["write `require stalling_never_pays`; only `risk` has a bound"]),
])
def test_e1010_a_requirement_not_understood(wrong: str, message: str, hints: list[str]) -> None:
    found = only_error(SOURCE.replace("require risk <= 1e-4", wrong), "E1010")
    assert found.message == message
    assert list(found.hints) == hints
    assert found.span is not None and found.span.line == 22


def test_e1010_lists_the_checks() -> None:
    found = only_error(SOURCE.replace("require risk <= 1e-4", "require riks"), "E1010")
    assert [n.message for n in found.notes] == [
        "`require` takes one of: `risk`, `ending_early_never_pays`, `goal_earlier_never_pays_less`, "
        "`stalling_never_pays`"]
    assert found.span is not None and (found.span.column, found.span.end_column) == (13, 17)


def test_a_bound_reading_an_input_is_the_constant_error() -> None:
    found = only_error(SOURCE.replace("require risk <= 1e-4", "require risk <= dgoal"), "E0103")
    assert found.message == "input `dgoal` cannot appear in the bound of `require risk`"


@pytest.mark.parametrize(("check", "drop", "message", "hint"), [
    ("risk <= 0.1", "    collision when collide\n", "`require risk` needs a `collision when` declaration",
     "declare what a collision means, e.g. `collision when collide`"),
    ("risk <= 0.1", "    goal when dgoal < 2 && lane != 3\n    collision when collide\n",
     "`require risk` needs `goal when` and `collision when` declarations",
     "declare what reaching the goal means, e.g. `goal when dgoal < 2` and what a collision means, "
     "e.g. `collision when collide`"),
    ("ending_early_never_pays", "    episode ends when collide || dgoal < 2\n",
     "`require ending_early_never_pays` needs an `episode ends when` declaration",
     "declare when a run ends, e.g. `episode ends when collide || dgoal < 2`"),
    ("goal_earlier_never_pays_less", "    goal when dgoal < 2 && lane != 3\n",
     "`require goal_earlier_never_pays_less` needs a `goal when` declaration",
     "declare what reaching the goal means, e.g. `goal when dgoal < 2`"),
    ("stalling_never_pays", "    goal when dgoal < 2 && lane != 3\n",
     "`require stalling_never_pays` needs a `goal when` declaration",
     "declare what reaching the goal means, e.g. `goal when dgoal < 2`"),
])
def test_e1009_a_requirement_without_what_its_check_reads(check: str, drop: str, message: str, hint: str) -> None:
    text = SOURCE.replace("    require risk <= 1e-4\n    require ending_early_never_pays\n", f"    require {check}\n")
    found = errors(text.replace(drop, ""))
    assert [(d.code, d.message, list(d.hints)) for d in found] == [("E1009", message, [hint])]


def test_the_declarations_a_check_does_not_read_are_not_needed() -> None:
    text = SOURCE.replace("    episode ends when collide || dgoal < 2\n", "") \
        .replace("    require ending_early_never_pays\n", "    require stalling_never_pays\n"
                 "    require goal_earlier_never_pays_less\n")
    assert [r.check for r in resolved(text).requirements] == ["risk", "stalling_never_pays",
                                                              "goal_earlier_never_pays_less"]


@pytest.mark.parametrize(("extra", "message", "first_line"), [
    ("    goal when collide\n", "`goal when` is declared more than once", 20),
    ("    collision when dgoal < 1\n", "`collision when` is declared more than once", 21),
    ("    episode ends when collide\n", "`episode ends when` is declared more than once", 19),
    ("    require risk <= 0.5\n", "`require risk` is declared more than once", 22),
    ("    require ending_early_never_pays\n", "`require ending_early_never_pays` is declared more than once", 23),
])
def test_e0106_declared_twice(extra: str, message: str, first_line: int) -> None:
    found = only_error(SOURCE.removesuffix("}\n") + extra + "}\n", "E0106")
    assert found.message == message
    assert found.span is not None and found.span.line == 24
    assert [n.span.line for n in found.notes if n.span is not None] == [first_line]


@pytest.mark.parametrize(("condition", "code", "message"), [
    ("dgoal < 2 && sa > 1", "E0202", "reward `sa` cannot appear in `goal when`"),
    ("dgoal", "E0201", "`goal when` needs a boolean, found a number"),
    ("Normal", "E0103", "location `Normal` cannot appear in `goal when`"),
    ("speed < 2", "E0101", "unknown name `speed`"),
])
def test_the_conditions_are_typed_like_guards(condition: str, code: str, message: str) -> None:
    found = only_error(SOURCE.replace("goal when dgoal < 2 && lane != 3", f"goal when {condition}"), code)
    assert found.message == message
    edge = errors(SOURCE.replace("edge Normal -> Crashed when collide", f"edge Normal -> Crashed when {condition}"))
    assert [d.code for d in edge] == [code]
    assert edge[0].message == message.replace("`goal when`", "a guard")
