"""Checked expressions back in ``.ra`` syntax, for messages and reports.

The checker inlines constants and resolves names; :func:`format_checked` prints the result with the
formatter of the language (:func:`rac.lang.format.format_expr`), names as written.
"""

from __future__ import annotations

from rac.ir import expr as ie
from rac.lang import ast
from rac.lang.format import format_expr

__all__ = ["format_checked"]


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
