"""rac.ir.text: checked expressions printed back in `.ra` syntax, and the guard printer the targets share."""

from __future__ import annotations

from fractions import Fraction
from pathlib import Path

import pytest

from rac import ir
from rac.compiler import compile_text
from rac.core.printing import C_BINARY, Level, Operator, OperatorTable, Printed
from rac.ir import expr as ie
from rac.ir.text import GuardPrinter, declaration_lines, format_checked, format_guard
from rac.lang.format import format_expr
from rac.lang.parser import parse_expression

LEFT_TURN = Path(__file__).resolve().parents[2] / "examples" / "left_turn" / "left_turn.xml"


def ref(name: str, kind: ie.RefKind = ie.RefKind.INPUT, type_: str = "num") -> ie.Ref:
    return ie.Ref(kind, name, type_)


@pytest.mark.parametrize(("expr", "text"), [
    (ie.Const(Fraction(3, 2)), "1.5"),
    (ie.Const(True), "true"),
    (ie.Binary("-", ref("a"), ie.Binary("-", ref("b"), ref("c"))), "a - (b - c)"),
    (ie.Binary("*", ie.Binary("+", ref("a"), ref("b")), ie.Const(Fraction(2))), "(a + b) * 2"),
    (ie.Unary("!", ie.Binary("&&", ref("p", type_="bool"), ref("q", type_="bool"))), "!(p && q)"),
    (ie.Compare("<", ref("a"), ie.Const(Fraction(-1))), "a < -1"),
])
def test_format_checked_prints_ra_text(expr: ie.Expr, text: str) -> None:
    assert format_checked(expr) == text
    # the text parses back and prints the same: the printer's parentheses keep the meaning
    assert format_expr(parse_expression(text)) == text


def test_format_checked_round_trips_bindings_of_a_checked_model(tmp_path: Path,
                                                               monkeypatch: pytest.MonkeyPatch) -> None:
    (tmp_path / "left_turn.xml").write_bytes(LEFT_TURN.read_bytes())
    monkeypatch.chdir(tmp_path)
    source = """automaton Small {
    input isClose : bool
    input prog : bool
    reward sa
    objective sa
    sample every 0.1
    horizon 30
    initial location Normal { sa' == 1 }
    location Unsafe         { sa' == -1 }
    edge * -> Unsafe when isClose
    edge * -> Normal when !isClose
    model {
        scenario "left_turn.xml"
        bind isClose = mindist() < 3 * collision_distance
        bind prog    = dist_goal() < prev(dist_goal())
    }
}
"""
    result = compile_text(source, "small.ra")
    assert result.automaton is not None, [d.message for d in result.diagnostics]
    printed = {b.input: format_checked(b.expr) for b in result.automaton.model.bindings}
    assert printed == {"isClose": "mindist() < 3 * collision_distance",
                       "prog": "dist_goal() < prev(dist_goal())"}


class _Toy(GuardPrinter):
    table = OperatorTable(binary={**C_BINARY, "&&": Operator(" and ", Level.AND), "||": Operator(" or ", Level.OR)},
                          prefix={"!": Operator("not ", Level.NOT)}, true="T", false="F")

    def print_BAtom(self, guard: ir.BAtom) -> Printed:
        return Printed(f"atom({guard})", Level.COMPARE)


def test_guard_printer_uses_the_names_and_the_target_table() -> None:
    printer = _Toy({"p": "in[0]", "q": "in[1]"})
    guard = ir.BOr((ir.BAnd((ir.BInput("p"), ir.BNot(ir.BInput("q")))), ir.BConst(False)))
    assert printer.print(guard).text == "in[0] and not in[1] or F"
    # an OR under an AND is parenthesised, the other way round it is not
    guard = ir.BAnd((ir.BOr((ir.BInput("p"), ir.BInput("q"))), ir.BConst(True)))
    assert printer.print(guard).text == "(in[0] or in[1]) and T"


OUTCOMES = """\
automaton A {
    input collide, near : bool
    input dgoal : real in [-5, 100]
    param P in [0.25, 0.5]
    reward sa
    objective sa
    sample every 1
    horizon 2
    initial location N { sa' == 1 }
    edge N -> N when !near
    episode ends when collide or not (dgoal >= -1.5 and near)
    goal when dgoal < 2 && !collide && near
    collision when collide
    require stalling_never_pays
    require risk <= P / 3
}
"""


def test_declaration_lines_print_issue_25s_declarations_and_read_back() -> None:
    automaton = compile_text(OUTCOMES, analyse=False).raise_for_errors()
    lines = declaration_lines(automaton)
    assert lines == ("episode ends when collide || !(dgoal >= -1.5 && near)",
                     "goal when dgoal < 2 && !collide && near", "collision when collide",
                     "require stalling_never_pays", "require risk <= (1 / 12)")
    # the lines in place of the declarations check to the same automaton
    head = OUTCOMES.split("    episode ends")[0]
    again = compile_text(head + "".join(f"    {line}\n" for line in lines) + "}\n",
                         analyse=False).raise_for_errors()
    assert (again.episode_ends, again.goal, again.collision, again.requirements) == \
        (automaton.episode_ends, automaton.goal, automaton.collision, automaton.requirements)


@pytest.mark.parametrize(("guard", "text"), [
    (ir.TRUE, "true"), (ir.BAnd(()), "true"), (ir.BOr(()), "false"),
    (ir.BAtom("v", "<=", Fraction(-1, 4)), "v <= -0.25"),
    (ir.BOr((ir.BAnd((ir.BInput("a"), ir.BInput("b"))), ir.BNot(ir.BInput("c")))), "(a && b) || !c"),
])
def test_format_guard(guard: ir.Guard, text: str) -> None:
    assert format_guard(guard) == text
