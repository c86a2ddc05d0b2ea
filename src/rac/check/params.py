"""Where parameters enter a file non-linearly: the synthesis is exact only where every value that
depends on a parameter is affine in the parameters (docs/checks.md, "Parameters").

The walk is over the AST, before any value is computed, so the verdict is a proof rather than a
sample: ``100 / P`` or ``P * Q`` is refused whatever values the bounds allow.
"""

from __future__ import annotations

import dataclasses
from typing import get_args

from rac.core.source import Span
from rac.lang import ast


def nonlinear_use(node: ast.Automaton, parameters: set[str]) -> tuple[str, Span | None, str] | None:
    """The first place where a parameter enters non-linearly, as (parameter, span, why), or None.

    Constants defined from parameters carry their degree into the expressions that read them.
    """
    walk = _Walk(parameters)
    for member in node.members:
        if isinstance(member, ast.ConstDecl):
            degree = walk.degree(member.expr)
            if degree:
                walk.degrees[member.name.name] = degree
        elif not isinstance(member, ast.ParamDecl):
            for expr in _expressions(member):
                walk.degree(expr)
        if walk.found is not None:
            return walk.found
    return None


def _expressions(node: object) -> list[ast.Expr]:
    """The outermost expressions of a declaration (a walk over the frozen dataclasses' fields)."""
    if isinstance(node, get_args(ast.Expr)):
        return [node]  # type: ignore[list-item]
    if isinstance(node, (tuple, list)):
        return [e for item in node for e in _expressions(item)]
    if dataclasses.is_dataclass(node) and not isinstance(node, type):
        return [e for f in dataclasses.fields(node) for e in _expressions(getattr(node, f.name))]
    return []


class _Walk:
    """Degrees in the parameters, and the first non-affine place found."""

    def __init__(self, parameters: set[str]) -> None:
        self.parameters = parameters
        self.degrees: dict[str, int] = dict.fromkeys(parameters, 1)
        self.found: tuple[str, Span | None, str] | None = None

    def degree(self, expr: ast.Expr) -> int:
        """The degree of ``expr`` in the parameters (0 or 1 when affine)."""
        if isinstance(expr, ast.Name):
            return self.degrees.get(expr.id, 0)
        if isinstance(expr, ast.Unary):
            return self.degree(expr.operand)
        if isinstance(expr, ast.Call):
            if any([self.degree(a) for a in expr.args]):
                self.refuse(expr, f"it is an argument of `{expr.func}(...)`")
            return 0
        if isinstance(expr, ast.Binary):
            left, right = self.degree(expr.left), self.degree(expr.right)
            if expr.op == "*":
                if left and right:
                    self.refuse(expr, "two parameters (or one twice) are multiplied")
                return left + right
            if expr.op == "/":
                if right:
                    self.refuse(expr, "it divides")
                return left
            return max(left, right)
        return 0

    def refuse(self, expr: ast.Expr, why: str) -> None:
        if self.found is not None:
            return
        # The parameter itself where one is named, else the constant computed from one.
        names = sorted({n.id for n in ast.names_in(expr) if self.degrees.get(n.id)},
                       key=lambda n: (n not in self.parameters, n))
        self.found = (names[0], expr.span, f"{why} (the checks would not be linear in it)")
