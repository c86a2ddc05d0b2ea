"""Queries and bindings: names and types checked, and each lowered once into the IR.

The resolver (:mod:`rac.check.resolve`) hands every query of a file, and the model block
(:mod:`rac.check.model_block`) every binding, to a :class:`Lowering`. It reports unknown names and type
errors with their spans, and turns each expression into a typed, resolved
:mod:`rac.ir.expr` node and each query into a :mod:`rac.ir.query` node: names resolved (inputs,
rewards, locations, the scenario model's names of :mod:`rac.ir.vocabulary`), the automaton's
constants inlined, time bounds and run counts evaluated. Downstream, nothing looks a name up again.

:func:`lower_expression` and :func:`lower_queries` do the same for an expression or queries given
later (the command line's ``--expr``, the paper's standard queries), against a checked automaton.
"""

from __future__ import annotations

import difflib
from collections.abc import Iterator
from fractions import Fraction

from rac import ir
from rac.check.symbols import DIVISION_BY_ZERO_HINT, Scope, Symbol, kind_word
from rac.core.diagnostics import CheckError, short_number
from rac.core.numbers import INT32_MAX
from rac.core.source import SourceFile, Span
from rac.ir import expr as ie
from rac.ir import query as iq
from rac.ir.vocabulary import (
    BINDING_MATH,
    EGO_STATE,
    FUNCTIONS,
    MATH_FUNCTIONS,
    MODEL_FUNCTIONS,
    MODEL_NAMES,
    SETTINGS,
    TRUE_STATE,
    held_value,
)
from rac.lang import ast
from rac.lang.format import format_expr, format_query
from rac.lang.parser import parse_expression

__all__ = ["FUNCTIONS_HINT", "QUERY_FUNCTIONS", "VOCABULARY_HINT", "Lowering", "Scope", "Symbol",
           "lower_expression", "lower_queries", "model_settings", "model_settings_of", "scope_of", "strategy_names",
           "type_word"]

#: Arithmetic functions UPPAAL offers in queries (all of :data:`rac.ir.vocabulary.MATH_FUNCTIONS`).
QUERY_FUNCTIONS = tuple(MATH_FUNCTIONS)

_SIGNATURES = tuple(f.signature for f in MODEL_FUNCTIONS.values()) + tuple(
    MATH_FUNCTIONS[n].signature for n in BINDING_MATH)
FUNCTIONS_HINT = "the model's functions are " + ", ".join(f"`{s}`" for s in _SIGNATURES)
VOCABULARY_HINT = ("a binding reads the scenario model: its functions, the ego state ("
                   + ", ".join(f"`{name}`" for name in EGO_STATE) + "), `time`, the model's settings and constants")


def _call_it(name: str) -> str | None:
    """The hint for a function named without its parentheses (`bind near = mindist < 3`), or None."""
    function = MODEL_FUNCTIONS.get(name) or MATH_FUNCTIONS.get(name)
    return None if function is None else f"`{name}` is a function: write `{function.signature}`"


def type_word(kind: str) -> str:
    return "a boolean" if kind == "bool" else "a number"


#: A lowered expression: its type ("bool", "num", None when unknown) and its node (None on errors).
Lowered = tuple[str | None, ie.Expr | None]


class Lowering:
    """Check and lower query expressions (``binding=False``) or binding expressions (``binding=True``).

    Query names are the automaton's first, then ``time`` and ``deadlock``, then (with a model block)
    the scenario model's. Binding names are the scenario model's first, then the automaton's
    constants; the automaton's state cannot appear in a binding.
    """

    def __init__(self, scope: Scope, *, binding: bool = False, bool_numbers: bool = False,
                 model_first: bool = False) -> None:
        self.s = scope
        self.binding = binding
        #: The scenario model's names hide the automaton's (the standard queries, written over the model).
        self.model_first = model_first
        #: A boolean counts as the number 0 or 1 where a number is expected (reward expressions, as in C).
        self.bool_numbers = bool_numbers
        self.failed = False
        self._in_prev = False

    def report(self, code: str, message: str, span: Span | None, **kw) -> None:
        self.failed = True
        self.s.error(code, message, span, **kw)

    # ------------------------------------------------------------ expressions
    def expr(self, node: ast.Expr) -> ie.Expr | None:
        """The lowered expression, or None when it has errors (reported)."""
        before = len(self.s.diagnostics)
        _, lowered = self.walk(node)
        if len(self.s.diagnostics) > before:
            self.failed = True
            return None
        return lowered

    def typed(self, node: ast.Expr) -> Lowered:
        """The type (None when unknown) and the lowered expression (None when it has errors)."""
        before = len(self.s.diagnostics)
        kind, lowered = self.walk(node)
        if len(self.s.diagnostics) > before:
            self.failed = True
            return kind, None
        return kind, lowered

    def walk(self, node: ast.Expr) -> Lowered:
        if isinstance(node, ast.Number):
            return "num", ie.Const(node.value, node.span)
        if isinstance(node, ast.BoolLit):
            return "bool", ie.Const(node.value, node.span)
        if isinstance(node, ast.Name):
            return self._binding_name(node) if self.binding else self._query_name(node)
        if isinstance(node, ast.Qualified):
            return self._qualified(node)
        if isinstance(node, ast.Call):
            return self._binding_call(node) if self.binding else self._query_call(node)
        if isinstance(node, ast.Unary):
            want = "num" if node.op == "-" else "bool"
            operand = self._expect(node.operand, want)
            return want, None if operand is None else ie.Unary(node.op, operand, node.span)
        assert isinstance(node, ast.Binary)
        if node.op in ast.ARITHMETIC_OPS or node.op in ast.LOGICAL_OPS:
            want = "num" if node.op in ast.ARITHMETIC_OPS else "bool"
            left, right = self._expect(node.left, want), self._expect(node.right, want)
            if left is None or right is None:
                return want, None
            if node.op == "/" and _is_zero(right):  # as in the automaton's own expressions (rac.check.linear)
                self.report("E0207", "division by zero", node.right.span, hints=[DIVISION_BY_ZERO_HINT])
                return want, None
            return want, ie.Binary(node.op, left, right, node.span)
        (lt, left), (rt, right) = self.walk(node.left), self.walk(node.right)
        if lt is not None and rt is not None and lt != rt:
            self.report("E0201", f"`{node.op}` compares {type_word(lt)} with {type_word(rt)}", node.span)
            return "bool", None
        if node.op not in ("==", "!=") and "bool" in (lt, rt):
            self.report("E0201", f"`{node.op}` needs numbers, found booleans", node.span)
            return "bool", None
        if left is None or right is None:
            return "bool", None
        return "bool", ie.Compare(node.op, left, right, ie.difference(left, right), node.span)

    def _expect(self, node: ast.Expr, want: str) -> ie.Expr | None:
        got, lowered = self.walk(node)
        if self.bool_numbers and want == "num" and got == "bool":
            return lowered
        if got is not None and got != want:
            self.report("E0201", f"expected {type_word(want)}, found {type_word(got)}", node.span)
            return None
        return lowered

    # ------------------------------------------------------------ names
    def _symbol(self, name: str, symbol: Symbol, span: Span | None) -> Lowered:
        if symbol.kind == "const":
            return symbol.type, None if symbol.value is None else ie.Const(symbol.value, span)
        kind = {"input": ie.RefKind.INPUT, "reward": ie.RefKind.REWARD, "location": ie.RefKind.LOCATION}[symbol.kind]
        return symbol.type, ie.Ref(kind, name, symbol.type, symbol.index, None, span)

    def _model_name(self, name: str, span: Span | None) -> Lowered:
        value = None
        if MODEL_NAMES[name].kind == "setting":
            if self.s.settings is None or name not in self.s.settings:
                return "num", None  # the model block has errors (reported there)
            value = self.s.settings[name]
        ref = ie.model_ref(name, value)
        return "num", ie.Ref(ref.kind, ref.name, ref.type, ref.index, ref.value, span)

    def _query_name(self, node: ast.Name) -> Lowered:
        if self.model_first and self.s.has_model and node.id in MODEL_NAMES:
            return self._model_name(node.id, node.span)
        symbol = self.s.symbols.get(node.id)
        if symbol is not None:
            return self._symbol(node.id, symbol, node.span)
        if node.id == "time":
            return self._model_name("time", node.span)
        if node.id == "deadlock":
            return "bool", ie.Ref(ie.RefKind.DEADLOCK, "deadlock", "bool", span=node.span)
        if self.s.has_model and node.id in MODEL_NAMES:
            return self._model_name(node.id, node.span)
        if (call := _call_it(node.id)) is not None:  # `A[] mindist > 3`
            self.s.error("E0101", f"unknown name `{node.id}`", node.span, hints=[call])
            return None, None
        self.s.unknown(node.id, node.span)
        return None, None

    def _binding_name(self, node: ast.Name) -> Lowered:
        name = node.id
        if name in EGO_STATE or name in SETTINGS or name == "time":
            return self._model_name(name, node.span)
        symbol = self.s.symbols.get(name)
        if symbol is not None and symbol.kind == "const":
            return self._symbol(name, symbol, node.span) if symbol.value is not None else (None, None)
        if symbol is not None:
            self.report("E0103", f"{symbol.kind} `{name}` cannot appear in a binding", node.span,
                        hints=[VOCABULARY_HINT])
            return None, None
        if name in TRUE_STATE:
            self.report("E0103", f"`{name}` (the true state) cannot appear in a binding", node.span,
                        hints=[f"bindings read what the vehicle senses: `{name.removeprefix('true_')}`; "
                               "the true state is for queries"])
            return None, None
        known = [*EGO_STATE, "time", *SETTINGS, *(n for n, s in self.s.symbols.items() if s.kind == "const")]
        close = difflib.get_close_matches(name, known, n=1)
        self.report("E0101", f"unknown name `{name}`", node.span,
                    hints=[_call_it(name) or (f"did you mean `{close[0]}`?" if close else VOCABULARY_HINT)])
        return None, None

    def _qualified(self, node: ast.Qualified) -> Lowered:
        if self.binding:
            self.report("E0103", f"`{node.scope}.{node.id}` is not available in a binding", node.span,
                        hints=[VOCABULARY_HINT])
            return None, None
        symbol = self.s.symbols.get(node.id)
        if node.scope != self.s.automaton:
            self.s.error("E0101", f"unknown process `{node.scope}`", node.span,
                         hints=[f"this automaton is `{self.s.automaton}`"])
            return None, None  # what `P.x` is, nobody knows: no type error on top (`A[] P.r < 0`)
        if node.id == "location":
            return "num", ie.Ref(ie.RefKind.LOCATION_INDEX, f"{node.scope}.location", "num", span=node.span)
        elif symbol is not None and symbol.kind != "location":
            # `Q.s` for a reward `s`, as a UPPAAL process's own variable would be written: say what `s`
            # is (the scope's "unknown location `s`, did you mean `s`?" named the name written), and
            # give no type, so that `Q.s <= 10` gets no second error comparing a boolean with a number
            self.s.error("E0103", f"`{node.id}` is {kind_word(symbol.kind)}, not a location: only locations "
                         f"(and `{node.scope}.location`) are qualified by the automaton's name", node.span,
                         hints=[f"write `{node.id}`"])
            return None, None
        elif symbol is None:
            self.s.unknown(node.id, node.span, "location")
        else:
            return "bool", ie.Ref(ie.RefKind.LOCATION, node.id, "bool", symbol.index, span=node.span)
        return "bool", None

    # ------------------------------------------------------------ calls
    def _unknown_function(self, node: ast.Call) -> None:
        """E0101 for a call of no function a query has: its hint names the closest function or lists them (a
        hint to declare it as an input or a constant, as for an unknown name, does not fit a call)."""
        known = (*(MODEL_FUNCTIONS if self.s.has_model else ()), *QUERY_FUNCTIONS)
        close = difflib.get_close_matches(node.func, known, n=1)
        signatures = ", ".join(f"`{FUNCTIONS[name].signature}`" for name in known)
        self.s.error("E0101", f"unknown function `{node.func}`", node.span,
                     hints=[f"did you mean `{FUNCTIONS[close[0]].signature}`?" if close else
                            f"a query may call {signatures}"])

    def _query_call(self, node: ast.Call) -> Lowered:
        if node.func in MODEL_FUNCTIONS and self.s.has_model:
            return self._model_call(node)
        if node.func in MODEL_FUNCTIONS:
            self.s.error("E0601", f"`{node.func}()` is a function of the scenario model, and this "
                         "automaton has no model", node.span,
                         hints=["attach a model (a `model` block), or bind the condition to an input"])
        elif node.func not in QUERY_FUNCTIONS:
            self._unknown_function(node)
        args = [self._expect(arg, "num") for arg in node.args]
        if node.func not in QUERY_FUNCTIONS:
            return None, None
        function = MATH_FUNCTIONS[node.func]
        if len(node.args) != function.arity:
            self.s.error("E0711", f"`{node.func}()` takes {_arguments(function.arity)}, found {len(node.args)}",
                         node.span)
            return "num", None
        present = tuple(a for a in args if a is not None)
        if len(present) != len(args):
            return "num", None
        return "num", ie.Call(function, present, node.span)

    def _model_call(self, node: ast.Call) -> Lowered:
        """A model function called in a query (a model is attached); wrong arity: E0711."""
        function = MODEL_FUNCTIONS[node.func]
        if len(node.args) != function.arity:
            self.s.error("E0711", f"`{node.func}()` takes {_arguments(function.arity)}, found {len(node.args)}",
                         node.span, hints=[FUNCTIONS_HINT])
            self._walk_all(node.args)
            return None, None
        if node.func == "prev":
            return self._prev(node)
        return function.result, ie.Call(function, (), node.span)

    def _walk_all(self, nodes: tuple[ast.Expr, ...]) -> None:
        """Check the arguments of a call that has an error of its own: theirs are reported too."""
        for node in nodes:
            self.walk(node)

    def _prev(self, node: ast.Call) -> Lowered:
        if self._in_prev:
            self.report("E0711", "`prev()` cannot be nested", node.span,
                        hints=["`prev(e)` is the value of `e` at the previous sample; the model keeps "
                               "one sample of history"])
            self._walk_all(node.args)
            return None, None
        self._in_prev = True
        try:
            kind, operand = self.walk(node.args[0])
        finally:
            self._in_prev = False
        return kind, None if operand is None else ie.Prev(operand, node.span)

    def _binding_call(self, node: ast.Call) -> Lowered:
        func = node.func
        if func not in MODEL_FUNCTIONS and func not in BINDING_MATH:
            close = difflib.get_close_matches(func, [*MODEL_FUNCTIONS, *BINDING_MATH], n=1)
            self.report("E0711", f"unknown function `{func}()` in a binding", node.span,
                        hints=([f"did you mean `{close[0]}()`?"] if close else []) + [FUNCTIONS_HINT])
            self._walk_all(node.args)
            return None, None
        function = FUNCTIONS[func]
        if len(node.args) != function.arity:
            self.report("E0711", f"`{func}()` takes {_arguments(function.arity)}, found {len(node.args)}", node.span,
                        hints=[FUNCTIONS_HINT])
            self._walk_all(node.args)
            return None, None
        if func == "prev":
            return self._prev(node)
        args = [self._expect(arg, "num") for arg in node.args]
        present = tuple(a for a in args if a is not None)
        if len(present) != len(args):
            return function.result, None
        return function.result, ie.Call(function, present, node.span)

    # ------------------------------------------------------------ queries
    def query(self, decl: ast.QueryDecl, strategies: set[str], title: str = "") -> iq.QueryDecl | None:
        """Check one query declaration and lower it; None when it has errors (reported)."""
        before = len(self.s.diagnostics)
        query = decl.query
        under = getattr(query, "under", None)
        if under is not None and under not in strategies:
            self.s.error("E0602", f"unknown strategy `{under}` after `under`", query.span,
                         hints=["define it first with `query Q: strategy NAME = control: A[] ...`"])
        lowered: dict[str, ie.Expr] = {}
        complete = True
        for name, node, want in _query_parts(query):
            got, value = self.walk(node)
            if want is not None and got is not None and got != want:
                self.s.error("E0201", f"this part of the query needs {type_word(want)}, "
                             f"found {type_word(got)}", node.span,
                             hints=["compare a number to make a condition (`sa <= 0`)" if want == "bool" else
                                    "write a number here: a condition is not one"])
            if value is None:
                complete = False
            else:
                lowered[name] = value
        if len(self.s.diagnostics) > before or not complete:
            return None
        built = self._build(query, lowered)
        if built is None:
            return None
        return iq.QueryDecl(decl.name.name, built, format_query(query), decl.span, title)

    def _constant(self, node: ast.Expr, value: ie.Expr | None, what: str, *, whole: bool = False,
                  positive: bool = False) -> Fraction | None:
        form = ie.linear_form(value) if value is not None else None
        if form is None or not form.is_constant:
            self.s.error("E0603", f"{what} must be a constant", node.span,
                         hints=["write a number or an expression of constants and settings"])
            return None
        number = form.const
        if (whole and number.denominator != 1) or (positive and number <= 0) or number < 0:
            need = "a positive whole number" if whole and positive else "a whole number >= 0" if whole else (
                "a positive number" if positive else "a number >= 0")
            self.s.error("E0603", f"{what} must be {need} (found {short_number(number, 12)})", node.span,
                         hints=[f"write {need} here"])
            return None
        if whole and number > INT32_MAX:  # UPPAAL's queries hold a step bound and a run count as int32
            self.s.error("E0603", f"{what} must be at most {INT32_MAX} (found {short_number(number)})", node.span,
                         hints=["UPPAAL holds it as a 32-bit integer"])
            return None
        return number

    def _bound(self, bound: ast.Bound, value: ie.Expr | None) -> iq.Bound | None:
        steps = bound.kind == "steps"
        limit = self._constant(bound.limit, value, "the step bound" if steps else "the time bound", whole=steps)
        return None if limit is None else iq.Bound(bound.kind, limit)

    def _runs(self, node: ast.Expr | None, value: ie.Expr | None) -> int | None:
        if node is None:
            return None
        count = self._constant(node, value, "the number of runs", whole=True, positive=True)
        return None if count is None else int(count)

    def _build(self, query: ast.Query, parts: dict[str, ie.Expr]) -> iq.Query | None:
        before = len(self.s.diagnostics)
        p = parts
        result: iq.Query | None = None
        if isinstance(query, ast.PathQuery):
            result = iq.PathQuery(query.quantifier, p["expr"], query.under)
        elif isinstance(query, ast.LeadsToQuery):
            result = iq.LeadsToQuery(p["left"], p["right"], query.under)
        elif isinstance(query, ast.ControlStrategy):
            result = iq.ControlStrategy(query.name, query.goal, p["expr"], query.under)
        elif isinstance(query, ast.ProbabilityQuery):
            bound, runs = self._bound(query.bound, p["bound"]), self._runs(query.runs, p.get("runs"))
            compare = None
            if query.compare is not None:
                theta = self._constant(query.compare[1], p["compare"], "the probability threshold")
                if theta is not None and theta > 1:
                    self.s.error("E0603", "the probability threshold must be at most 1 "
                                 f"(found {short_number(theta, 12)})", query.compare[1].span)
                compare = None if theta is None else (query.compare[0], theta)
            if bound is not None:
                result = iq.ProbabilityQuery(bound, runs, query.path, p["expr"], compare, query.under)
        elif isinstance(query, ast.ExpectationQuery):
            bound, runs = self._bound(query.bound, p["bound"]), self._runs(query.runs, p["runs"])
            if bound is not None and runs is not None:
                result = iq.ExpectationQuery(bound, runs, query.aggregate, p["expr"], query.under)
        elif isinstance(query, ast.SimulateQuery):
            bound, runs = self._bound(query.bound, p["bound"]), self._runs(query.runs, p.get("runs"))
            exprs = tuple(p[f"expr{i}"] for i in range(len(query.exprs)))
            if bound is not None:
                result = iq.SimulateQuery(bound, runs, exprs, tuple(format_expr(e) for e in query.exprs),
                                          query.under)
        else:
            bound = self._bound(query.bound, p["bound"])
            discrete = tuple(p[f"discrete{i}"] for i in range(len(query.discrete)))
            continuous = tuple(p[f"continuous{i}"] for i in range(len(query.continuous)))
            labels = tuple(format_expr(e) for e in (*query.discrete, *query.continuous))
            if bound is not None:
                result = iq.LearnStrategy(query.name, query.optimise, p["objective"], bound, discrete,
                                          continuous, query.path, p["expr"], query.under, labels)
        return result if len(self.s.diagnostics) == before else None


def _query_parts(query: ast.Query) -> Iterator[tuple[str, ast.Expr, str | None]]:
    """The expressions of a query, each with its key and the type it must have (None: any)."""
    if isinstance(query, ast.PathQuery | ast.ControlStrategy):
        yield "expr", query.expr, "bool"
    elif isinstance(query, ast.LeadsToQuery):
        yield "left", query.left, "bool"
        yield "right", query.right, "bool"
    elif isinstance(query, ast.ProbabilityQuery):
        yield "bound", query.bound.limit, "num"
        yield "expr", query.expr, "bool"
        if query.runs:
            yield "runs", query.runs, "num"
        if query.compare:
            yield "compare", query.compare[1], "num"
    elif isinstance(query, ast.ExpectationQuery):
        yield "bound", query.bound.limit, "num"
        yield "runs", query.runs, "num"
        yield "expr", query.expr, "num"
    elif isinstance(query, ast.SimulateQuery):
        yield "bound", query.bound.limit, "num"
        for i, expr in enumerate(query.exprs):
            yield f"expr{i}", expr, None
        if query.runs:
            yield "runs", query.runs, "num"
    else:
        yield "objective", query.objective, "num"
        yield "bound", query.bound.limit, "num"
        for i, expr in enumerate(query.discrete):
            yield f"discrete{i}", expr, None
        for i, expr in enumerate(query.continuous):
            yield f"continuous{i}", expr, None
        yield "expr", query.expr, "bool"


def _is_zero(divisor: ie.Expr) -> bool:
    """Whether a divisor is the constant zero (``1 / 0``, ``x / (TD - TD)``, ``x / (v - v)``)."""
    form = ie.linear_form(divisor)
    return form is not None and form.is_constant and form.const == 0


def _arguments(count: int) -> str:
    return "no arguments" if count == 0 else "1 argument" if count == 1 else f"{count} arguments"


# ---------------------------------------------------------------- against a checked automaton
def scope_of(automaton: ir.Automaton) -> Scope:
    """The names a query of ``automaton`` may read (its inputs, rewards, locations, constants, model)."""
    symbols: dict[str, Symbol] = {}
    for i, item in enumerate(automaton.inputs):
        symbols[item.name] = Symbol("input", "bool" if item.is_bool else "num", item.span, index=i)
    for i, reward in enumerate(automaton.rewards):
        symbols[reward] = Symbol("reward", "num", automaton.spans.get(reward), index=i)
    for i, location in enumerate(automaton.locations):
        symbols[location.name] = Symbol("location", "bool", location.span, index=i)
    for name, value in automaton.constants:
        symbols[name] = Symbol("const", "bool" if isinstance(value, bool) else "num", automaton.spans.get(name), value)
    settings = model_settings(automaton.model) if automaton.model is not None else None
    span = automaton.source.name.span if automaton.source is not None else None
    return Scope(automaton.name, symbols, automaton.model is not None, span, settings)


def model_settings(spec: ir.ModelSpec) -> dict[str, Fraction]:
    """Every setting of a model block as the model holds it (:func:`rac.ir.vocabulary.held_value`)."""
    return model_settings_of({name: Fraction(getattr(spec, name)) for name in SETTINGS}, spec.scale)


def model_settings_of(values: dict[str, Fraction], scale: int) -> dict[str, Fraction]:
    """The settings ``values`` as a model at ``scale`` holds them."""
    return {name: held_value(name, value, scale) for name, value in values.items() if name in SETTINGS}


def lower_expression(automaton: ir.Automaton, source: str | ast.Expr, *, name: str = "<expression>",
                     bool_numbers: bool = False) -> ie.Expr:
    """One query expression over ``automaton`` (text or a parsed node), checked and lowered. With
    ``bool_numbers`` a boolean counts as 0 or 1 in arithmetic (reward expressions such as the
    paper's ``10*!isClose + comf``).

    Raises :class:`rac.lang.parser.ExpressionError` (a ``ValueError``) when the text is not one
    expression, :class:`rac.core.diagnostics.CheckError` with the diagnostics when it names something
    unknown or mixes types."""

    node = parse_expression(source, name) if isinstance(source, str) else source
    scope = scope_of(automaton)
    lowered = Lowering(scope, bool_numbers=bool_numbers).expr(node)
    if lowered is None:
        raise CheckError(scope.diagnostics, {name: SourceFile(name, source)} if isinstance(source, str) else {})
    return lowered


def lower_queries(automaton: ir.Automaton, decls: tuple[ast.QueryDecl, ...] | list[ast.QueryDecl], *,
                  strategies: set[str] | None = None, titles: dict[str, str] | None = None,
                  sources: dict[str, SourceFile] | None = None, model_first: bool = False) -> tuple[iq.QueryDecl, ...]:
    """Queries parsed elsewhere (the standard queries), checked and lowered against ``automaton``;
    ``strategies`` are those they may use ``under`` besides their own; with ``model_first`` the
    scenario model's names hide the automaton's. Raises :class:`rac.core.diagnostics.CheckError` when
    one has errors."""
    scope = scope_of(automaton)
    known = set(strategies or ())
    result = []
    for decl in decls:
        lowered = Lowering(scope, model_first=model_first).query(decl, known, (titles or {}).get(decl.name.name, ""))
        if lowered is not None:
            result.append(lowered)
            if isinstance(lowered.query, iq.STRATEGY_QUERIES):
                known.add(lowered.query.name)
    if scope.diagnostics:
        raise CheckError(scope.diagnostics, sources or {})
    return tuple(result)


def strategy_names(decls: tuple[iq.QueryDecl, ...]) -> set[str]:
    """The strategies a list of checked queries defines."""
    return {d.query.name for d in decls if isinstance(d.query, iq.STRATEGY_QUERIES)}

