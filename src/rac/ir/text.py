"""The IR as text: checked expressions, guards and issue 25's declarations back in ``.ra`` syntax, and
the walk over guards the targets share.

The checker inlines constants and resolves names; :func:`format_checked` prints the result with the
formatter of the language (:func:`rac.lang.format.format_expr`), names as written.
:class:`GuardPrinter` prints the automaton's guards (:data:`rac.ir.Guard`) in a target's syntax: the
target gives the operator table and prints the comparisons of numeric inputs.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Callable, Mapping

from rac import ir
from rac.core.printing import Level, Printed, Printer
from rac.ir import expr as ie
from rac.lang import ast
from rac.lang.format import format_expr

__all__ = ["GuardPrinter", "declaration_lines", "format_checked", "format_guard"]


def format_checked(expr: ie.Expr) -> str:
    """A checked expression (:mod:`rac.ir.expr`) in ``.ra`` syntax, for messages and reports: names
    as written, the automaton's constants as their values (the checker inlined them)."""
    return format_expr(_to_ast(expr))


def _to_ast(expr: ie.Expr) -> ast.Expr:
    if isinstance(expr, ie.Const):
        return ast.BoolLit(expr.value) if isinstance(expr.value, bool) else ast.Number(expr.value)
    if isinstance(expr, ie.Ref):
        return ast.Name(expr.name)
    if isinstance(expr, ie.Call):
        return ast.Call(expr.name, tuple(_to_ast(a) for a in expr.args))
    if isinstance(expr, ie.Prev):
        return ast.Call("prev", (_to_ast(expr.operand),))
    if isinstance(expr, ie.Unary):
        return ast.Unary(expr.op, _to_ast(expr.operand))
    return ast.Binary(expr.op, _to_ast(expr.left), _to_ast(expr.right))


def format_guard(guard: ir.Guard) -> str:
    """A checked guard (:data:`rac.ir.Guard`) in ``.ra`` syntax: an edge's, or the condition of
    ``goal when``; parsing and checking the text gives the guard back."""
    return format_expr(_guard_ast(guard))


def _atom_ast(atom: ir.BAtom) -> ast.Expr:
    threshold = ast.Number(abs(atom.threshold))
    return ast.Binary(atom.op, ast.Name(atom.input), ast.Unary("-", threshold) if atom.threshold < 0 else threshold)


def _chain(op: str, empty: bool) -> Callable[[tuple[ast.Expr, ...]], ast.Expr]:
    """``a op b op c``, nested as the parser nests it (:func:`rac.lang.ast.fold_chain`); ``empty`` without
    operands."""
    def join(operands: tuple[ast.Expr, ...]) -> ast.Expr:
        if not operands:
            return ast.BoolLit(empty)
        return ast.fold_chain(operands, [op] * (len(operands) - 1), lambda o, left, right, flat: ast.Binary(
            o, left, right, flat=flat), lambda i: not ast.same_level(operands[i], op))
    return join


_guard_ast: ir.GuardFold[ast.Expr] = ir.GuardFold(
    const=ast.BoolLit, boolean=lambda guard: ast.Name(guard.name), atom=_atom_ast,
    negate=lambda operand: ast.Unary("!", operand), conjoin=_chain("&&", True), disjoin=_chain("||", False))


def declaration_lines(automaton: ir.Automaton) -> tuple[str, ...]:
    """Issue 25's declarations of a checked automaton back in ``.ra`` syntax, one per line:
    ``episode ends when``, ``goal when``, ``collision when`` (those it has), then its ``require``s
    in source order, bounds exact (a parameter's as the value it was resolved with)."""
    lines = [f"{word} when {format_guard(guard)}"
             for word, guard in (("episode ends", automaton.episode_ends), ("goal", automaton.goal),
                                 ("collision", automaton.collision)) if guard is not None]
    for requirement in automaton.requirements:
        bound = "" if requirement.bound is None else f" <= {format_expr(ast.Number(requirement.bound))}"
        lines.append(f"require {requirement.check}{bound}")
    return tuple(lines)


class GuardPrinter(Printer, ABC):
    """Prints guards with the table of a subclass (keys ``"!"``, ``"&&"``, ``"||"``); ``names`` maps
    each input to the target's expression holding it. A subclass prints :class:`rac.ir.BAtom`."""

    def __init__(self, names: Mapping[str, str]) -> None:
        self.names = names

    def print_BConst(self, guard: ir.BConst) -> Printed:
        return self.literal(guard.value)

    def print_BInput(self, guard: ir.BInput) -> Printed:
        return Printed(self.names[guard.name], Level.ATOM)

    @abstractmethod
    def print_BAtom(self, guard: ir.BAtom) -> Printed:
        """A comparison of a numeric input, as the target prints it."""

    def print_BNot(self, guard: ir.BNot) -> Printed:
        return self.prefix("!", self.print(guard.operand))

    def print_BAnd(self, guard: ir.BAnd) -> Printed:
        return self.infix("&&", *(self.print(g) for g in guard.operands))

    def print_BOr(self, guard: ir.BOr) -> Printed:
        return self.infix("||", *(self.print(g) for g in guard.operands))
