"""Names and types in queries (the automaton's vocabulary, ``time``, and model functions).

The resolver runs a :class:`QueryChecker` over every query; the model block's binding
checker extends it with the scenario model's vocabulary.
"""

from __future__ import annotations

from typing import Any

from rac import ast

#: Functions of the scenario model (model.md); usable in queries once a model is attached
#: (their types and arities: :data:`rac.model_block.MODEL_FUNCTIONS`).
MODEL_FUNCTIONS = ("collide", "offroad", "goal", "mindist", "dist_goal", "prev")
#: Arithmetic functions UPPAAL offers in queries.
QUERY_FUNCTIONS = ("abs", "fabs", "fmin", "fmax", "sqrt", "floor", "ceil", "round", "trunc")
#: Names that exist in every query.
QUERY_BUILTINS = ("time", "deadlock")


def type_word(kind: str) -> str:
    return "a boolean" if kind == "bool" else "a number"



class QueryChecker:
    """Names and types in queries: the automaton's vocabulary plus ``time``.

    The model's vocabulary (its functions, the ego state, the true state and the settings)
    is legal once the automaton has a ``model`` block; its functions are E0601 without one.
    """

    def __init__(self, resolver: Any, strategies: set[str]):
        self.r = resolver
        self.strategies = strategies

    def check(self, query: ast.Query) -> None:
        under = getattr(query, "under", None)
        if under is not None and under not in self.strategies:
            self.r._error("E0602", f"unknown strategy `{under}` after `under`", query.span,
                          hints=["define it first with `query Q: strategy NAME = control: A[] ...`"])
        for expr, want in _query_exprs(query):
            got = self.walk(expr)
            if want is not None and got is not None and got != want:
                self.r._error("E0201", f"this part of the query needs {type_word(want)}, "
                              f"found {type_word(got)}", expr.span)

    def walk(self, node: ast.Expr) -> str | None:
        """The type of a query expression ("bool", "num"), or None when unknown (already reported)."""
        if isinstance(node, ast.Number):
            return "num"
        if isinstance(node, ast.BoolLit):
            return "bool"
        if isinstance(node, ast.Name):
            symbol = self.r.symbols.get(node.id)
            if symbol is not None:
                return symbol.type
            if node.id in QUERY_BUILTINS:
                return "num" if node.id == "time" else "bool"
            if self.r.has_model:
                from rac.model_block import query_name_type

                kind = query_name_type(node.id)
                if kind is not None:
                    return kind
            self.r._unknown(node.id, node.span)
            return None
        if isinstance(node, ast.Qualified):
            automaton = self.r.node.name.name
            symbol = self.r.symbols.get(node.id)
            if node.scope != automaton:
                self.r._error("E0101", f"unknown process `{node.scope}`", node.span,
                              hints=[f"this automaton is `{automaton}`"])
            elif node.id == "location":
                return "num"
            elif symbol is None or symbol.kind != "location":
                self.r._unknown(node.id, node.span, "location")
            return "bool"
        if isinstance(node, ast.Call):
            if node.func in MODEL_FUNCTIONS and self.r.has_model:
                from rac.model_block import model_call_type

                return model_call_type(self, node)
            if node.func in MODEL_FUNCTIONS:
                self.r._error("E0601", f"`{node.func}()` is a function of the scenario model, and this "
                              "automaton has no model", node.span,
                              hints=["attach a model (a `model` block), or bind the condition to an input"])
            elif node.func not in QUERY_FUNCTIONS:
                self.r._unknown(node.func, node.span, "function")
            for arg in node.args:
                self._expect(arg, "num")
            return "num" if node.func in QUERY_FUNCTIONS else None
        if isinstance(node, ast.Unary):
            want = "num" if node.op == "-" else "bool"
            self._expect(node.operand, want)
            return want
        assert isinstance(node, ast.Binary)
        if node.op in ast.ARITHMETIC_OPS:
            self._expect(node.left, "num")
            self._expect(node.right, "num")
            return "num"
        if node.op in ast.COMPARISON_OPS:
            left, right = self.walk(node.left), self.walk(node.right)
            if left is not None and right is not None and left != right:
                self.r._error("E0201", f"`{node.op}` compares {type_word(left)} with {type_word(right)}",
                              node.span)
            elif node.op not in ("==", "!=") and "bool" in (left, right):
                self.r._error("E0201", f"`{node.op}` needs numbers, found booleans", node.span)
            return "bool"
        self._expect(node.left, "bool")
        self._expect(node.right, "bool")
        return "bool"

    def _expect(self, node: ast.Expr, want: str) -> None:
        got = self.walk(node)
        if got is not None and got != want:
            self.r._error("E0201", f"expected {type_word(want)}, found {type_word(got)}", node.span)


def _query_exprs(query: ast.Query) -> list[tuple[ast.Expr, str | None]]:
    """The expressions of a query with the type each must have (None: any)."""
    if isinstance(query, ast.PathQuery):
        return [(query.expr, "bool")]
    if isinstance(query, ast.LeadsToQuery):
        return [(query.left, "bool"), (query.right, "bool")]
    if isinstance(query, ast.ProbabilityQuery):
        return ([(query.bound.limit, "num"), (query.expr, "bool")]
                + ([(query.runs, "num")] if query.runs else [])
                + ([(query.compare[1], "num")] if query.compare else []))
    if isinstance(query, ast.ExpectationQuery):
        return [(query.bound.limit, "num"), (query.runs, "num"), (query.expr, "num")]
    if isinstance(query, ast.SimulateQuery):
        return ([(query.bound.limit, "num")] + [(e, None) for e in query.exprs]
                + ([(query.runs, "num")] if query.runs else []))
    if isinstance(query, ast.ControlStrategy):
        return [(query.expr, "bool")]
    return ([(query.objective, "num"), (query.bound.limit, "num")]
            + [(e, None) for e in (*query.discrete, *query.continuous)] + [(query.expr, "bool")])


