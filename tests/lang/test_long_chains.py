"""Long flat chains (``a1 + a2 + ... + a300``, a guard of 300 conditions): rac.lang.ast.fold_chain splits them,
so they are not E0006's deep nesting, mean what they say, and print back as written."""

from __future__ import annotations

import random
from fractions import Fraction

import pytest

from rac import ir
from rac.ir.text import format_guard
from rac.lang import ast
from rac.lang.format import format_expr
from rac.lang.parser import ExpressionError, parse_expression


def depth(expr: ast.Expr) -> int:
    """Operators nested in one another, as E0006 counts them (a call is one)."""
    if isinstance(expr, ast.Call):
        return 1 + max((depth(a) for a in expr.args), default=0)
    if isinstance(expr, ast.Binary):
        return 1 + max(depth(expr.left), depth(expr.right))
    if isinstance(expr, ast.Unary):
        return 1 + depth(expr.operand)
    return 0


def value(expr: ast.Expr) -> Fraction | bool:
    """The exact value of a tree of numbers, booleans and the chain operators."""
    if isinstance(expr, ast.Number):
        return expr.value
    if isinstance(expr, ast.BoolLit):
        return expr.value
    if isinstance(expr, ast.Unary):
        return -value(expr.operand)  # type: ignore[operator]
    assert isinstance(expr, ast.Binary)
    left, right = value(expr.left), value(expr.right)
    return {"+": lambda: left + right, "-": lambda: left - right, "*": lambda: left * right,
            "/": lambda: left / right, "&&": lambda: left and right, "||": lambda: left or right}[expr.op]()


def left_to_right(operands: list, operators: list[str]) -> Fraction | bool:
    result = operands[0]
    for op, operand in zip(operators, operands[1:]):
        result = {"+": result + operand, "-": result - operand, "*": result * operand, "/": result / operand,
                  "&&": result and operand, "||": result or operand}[op]
    return result


@pytest.mark.parametrize("length", [300, 5000])
@pytest.mark.parametrize("op", ["+", "*", "&&", "||"])
def test_a_long_chain_of_one_operator_is_shallow(op: str, length: int) -> None:
    expr = parse_expression(f" {op} ".join(["x"] * length))
    assert depth(expr) <= ast.CHAIN_BLOCK + length.bit_length()
    assert format_expr(expr) == f" {op} ".join(["x"] * length)


def test_a_short_chain_nests_to_the_left_as_before() -> None:
    expr = parse_expression(" + ".join(f"x{i}" for i in range(ast.CHAIN_BLOCK)))
    for i in reversed(range(1, ast.CHAIN_BLOCK)):
        assert isinstance(expr, ast.Binary) and expr.right == ast.Name(f"x{i}") and not expr.flat
        expr = expr.left
    assert expr == ast.Name("x0")


@pytest.mark.parametrize("seed", range(20))
@pytest.mark.parametrize("level", [("+", "-"), ("*", "/")])
def test_a_split_chain_means_what_it_says(level: tuple[str, str], seed: int) -> None:
    """Split only at `+` (`*`), a mixed chain keeps its value exactly; printed, it reads back as the same tree."""
    rng = random.Random(seed)
    length = rng.randrange(33, 400)
    numbers = [Fraction(rng.randrange(1, 9), rng.choice([1, 2, 4])) for _ in range(length)]
    operators = [rng.choice(level) for _ in range(length - 1)]
    text = f"{float(numbers[0]):g}" + "".join(f" {op} {float(n):g}" for op, n in zip(operators, numbers[1:]))
    expr = parse_expression(text)
    assert value(expr) == left_to_right(numbers, operators)
    assert parse_expression(format_expr(expr)) == expr
    assert format_expr(parse_expression(format_expr(expr))) == format_expr(expr)


@pytest.mark.parametrize("seed", range(10))
def test_parenthesised_operands_keep_their_parentheses(seed: int) -> None:
    rng = random.Random(seed)
    parts = [rng.choice(["a", "(b + c)", "(b - c)", "f(d + e)", "2 * e"]) for _ in range(rng.randrange(33, 300))]
    text = "a" + "".join(f" {rng.choice('+-')} {p}" for p in parts)  # as rac fmt writes it
    expr = parse_expression(text)
    assert format_expr(expr) == text
    assert parse_expression(format_expr(expr)) == expr


def test_a_chain_without_an_associative_operator_stays_deep() -> None:
    expr = parse_expression(" - ".join(["x"] * 90))
    assert depth(expr) == 89


@pytest.mark.parametrize(("guard", "op"), [(ir.BAnd, "&&"), (ir.BOr, "||")])
def test_a_checked_guard_of_many_conditions_prints(guard: type, op: str) -> None:
    """The IR's n-ary guards print back through the same split (ir.text built them left-nested, 1000 deep)."""
    conditions = tuple(ir.BAtom("d", "<", Fraction(i)) for i in range(1000))
    text = format_guard(guard(conditions))
    assert text == f" {op} ".join(f"d < {i}" for i in range(1000))


@pytest.mark.parametrize("seed", range(10))
def test_e0006_counts_the_levels_the_tree_has(seed: int) -> None:
    """The parser's count (on lark's tree, before the AST is built) is the depth of the AST it builds."""
    rng = random.Random(seed)
    parts = [rng.choice(["a", "(b + c)", "(b - c - d)", "f(d + e)", "2 * e"]) for _ in range(rng.randrange(33, 300))]
    text = "a" + "".join(f" {rng.choice('+-')} {p}" for p in parts)
    levels = depth(parse_expression(text))
    assert levels < 100
    parse_expression("-(" * (100 - levels) + text + ")" * (100 - levels))
    with pytest.raises(ExpressionError, match=r"nested too deeply \(101 levels; at most 100\)"):
        parse_expression("-(" * (101 - levels) + text + ")" * (101 - levels))
