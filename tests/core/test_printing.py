"""rac.core.printing: the printer parenthesises by the target's table exactly where needed. Brute force:
every arithmetic tree of up to three operators over small numbers prints to text that Python (whose
precedence for these operators is C's) evaluates to the tree's value, with no redundant parentheses."""

from __future__ import annotations

import itertools
from dataclasses import dataclass
from fractions import Fraction

import pytest

from rac.core.printing import (
    C_BINARY,
    Associativity,
    Level,
    Operator,
    OperatorTable,
    Printed,
    Printer,
    number,
    signed_sum,
)


@dataclass(frozen=True)
class Num:
    value: int


@dataclass(frozen=True)
class Bin:
    op: str
    left: object
    right: object


@dataclass(frozen=True)
class Neg:
    operand: object


class Arith(Printer):
    table = OperatorTable(binary=C_BINARY, prefix={"-": Operator("-", Level.PREFIX)})

    def print_Num(self, node: Num) -> Printed:
        return number(str(node.value))

    def print_Bin(self, node: Bin) -> Printed:
        return self.infix(node.op, self.print(node.left), self.print(node.right))

    def print_Neg(self, node: Neg) -> Printed:
        return self.prefix("-", self.print(node.operand))


def value(node: object) -> Fraction:
    if isinstance(node, Num):
        return Fraction(node.value)
    if isinstance(node, Neg):
        return -value(node.operand)
    assert isinstance(node, Bin)
    left, right = value(node.left), value(node.right)
    return {"+": left + right, "-": left - right, "*": left * right, "/": left / right}[node.op]


def trees(depth: int):
    leaves = [Num(2), Num(3), Num(-1)]
    if depth == 0:
        yield from leaves
        return
    yield from trees(depth - 1)
    smaller = list(trees(depth - 1))
    for operand in smaller:
        yield Neg(operand)
    for op, left, right in itertools.product("+-*/", smaller, smaller):
        yield Bin(op, left, right)


def test_printed_text_keeps_the_value_of_every_small_tree() -> None:
    printer = Arith()
    seen = 0
    for tree in trees(2):
        try:
            expected = value(tree)
        except ZeroDivisionError:
            continue
        text = printer.print(tree).text
        assert "--" not in text  # `- -1` would be a decrement in C
        python = text.replace("/", "*Fraction(1)/")
        assert eval(python, {"Fraction": Fraction}) == expected, (tree, text)  # noqa: S307 - our own digits
        seen += 1
    assert seen > 1000


@pytest.mark.parametrize(("tree", "text"), [
    (Bin("-", Num(2), Bin("-", Num(3), Num(2))), "2 - (3 - 2)"),
    (Bin("-", Bin("-", Num(2), Num(3)), Num(2)), "2 - 3 - 2"),
    (Bin("*", Bin("+", Num(2), Num(3)), Num(2)), "(2 + 3) * 2"),
    (Bin("+", Num(2), Bin("*", Num(3), Num(2))), "2 + 3 * 2"),
    (Neg(Neg(Num(2))), "-(-2)"),
    (Bin("*", Num(2), Num(-1)), "2 * -1"),
    (Neg(Num(-1)), "-(-1)"),
])
def test_no_redundant_parentheses(tree: object, text: str) -> None:
    assert Arith().print(tree).text == text


def test_associativity_rules() -> None:
    class Table(Printer):
        table = OperatorTable(binary={"imply": Operator(" imply ", Level.IMPLY, Associativity.RIGHT),
                                      "and": Operator(" and ", Level.AND, Associativity.ASSOCIATIVE),
                                      "<": Operator(" < ", Level.COMPARE, Associativity.NONE)})

    t, atom = Table(), Printed("a", Level.ATOM)
    chained = t.infix("imply", atom, t.infix("imply", atom, atom))
    assert chained.text == "a imply a imply a"
    assert t.infix("imply", t.infix("imply", atom, atom), atom).text == "(a imply a) imply a"
    assert t.infix("and", t.infix("and", atom, atom), atom).text == "a and a and a"
    assert t.infix("<", t.infix("<", atom, atom), atom).text == "(a < a) < a"
    assert t.literal(True) == Printed("true", Level.ATOM)
    with pytest.raises(ValueError, match="unknown binary operator"):
        t.infix("+", atom, atom)
    with pytest.raises(ValueError, match="unknown unary operator"):
        t.prefix("!", atom)
    with pytest.raises(TypeError, match="not an expression"):
        t.print(object())


def test_signed_sum() -> None:
    assert signed_sum([]) == ""
    assert signed_sum([(True, "a"), (False, "b"), (True, "2 * c")]) == "-a + b - 2 * c"
    assert signed_sum([(False, "x")]) == "x"


def test_counted_says_one_in_the_singular_and_groups_thousands() -> None:
    from rac.core.diagnostics import counted

    assert [counted(n, "run") for n in (0, 1, 2, 2000)] == ["0 runs", "1 run", "2 runs", "2,000 runs"]
    assert counted(1, "strategy", "strategies") == "1 strategy"
    assert counted(3, "strategy", "strategies") == "3 strategies"
    assert counted(10**20, "state") == "1e20 states"  # as short_count: no 21 digits
