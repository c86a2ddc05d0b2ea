"""AST → IR: names, types and linearity.

This stage turns one parsed automaton into an :class:`rac.ir.Automaton`, or
reports why it cannot (unknown names, type errors, nonlinear rates, missing
declarations). Behavioural checks (determinism, priorities) run on the IR in
:mod:`rac.check.analysis`.
"""

from __future__ import annotations

import dataclasses
import difflib
from dataclasses import dataclass, field
from fractions import Fraction

from rac import ir
from rac.check.model_block import resolve_model
from rac.check.queries import Lowering, model_settings, type_word
from rac.check.standard import standard_queries
from rac.check.symbols import ModelContext, Scope, Symbol, Unresolvable
from rac.core.diagnostics import Diagnostic, Note, short_number, warning
from rac.core.source import Span
from rac.ir import query as iq
from rac.lang import ast

#: Most samples a run may have (horizon / period): the exact checks walk every one of them.
MAX_SAMPLES = 1_000_000


@dataclass(frozen=True)
class _Context:
    """What an expression may mention, and how to call it in messages."""

    what: str
    rewards: bool = False
    inputs: bool = True


GUARD = _Context("a guard")
RATE = _Context("a rate")
UPDATE = _Context("an update", rewards=True)
OBJECTIVE = _Context("the objective", rewards=True, inputs=False)
CONSTANT = _Context("a constant expression", inputs=False)


@dataclass
class _Used:
    inputs: set[str] = field(default_factory=set)


def _typed(kind: str, value: object) -> tuple[str, object]:
    return (kind, value)


class Resolver:
    """Resolve one automaton. Call :meth:`run`; read :attr:`diagnostics`."""

    def __init__(self, automaton: ast.Automaton):
        self.node = automaton
        self.diagnostics: list[Diagnostic] = []
        self.symbols: dict[str, Symbol] = {}
        #: What queries and bindings may name; shares the symbols and the diagnostics.
        self.scope = Scope(automaton.name.name, self.symbols, self.has_model, automaton.name.span,
                           diagnostics=self.diagnostics)
        self.used = _Used()
        #: Spans of the model block's settings the analyses point at ("model:exponent", "model:base").
        self.model_spans: dict[str, Span] = {}

    @property
    def has_model(self) -> bool:
        """Whether the automaton has a ``model`` block (its vocabulary is then legal in queries)."""
        return bool(self.node.of(ast.ModelDecl))

    # ------------------------------------------------------------ reporting
    def _error(self, code: str, message: str, span: Span | None, **kw) -> None:
        self.scope.error(code, message, span, **kw)

    def _declare(self, ident: ast.Ident, symbol: Symbol) -> bool:
        previous = self.symbols.get(ident.name)
        if previous is not None:
            self._error("E0102", f"`{ident.name}` is already declared (as {_kind_word(previous.kind)})",
                        ident.span, notes=[Note("first declared here", previous.span)])
            return False
        self.symbols[ident.name] = symbol
        return True

    def _unknown(self, name: str, span: Span | None, what: str = "name") -> None:
        self.scope.unknown(name, span, what)

    # ------------------------------------------------------------ expressions
    def expr(self, node: ast.Expr, ctx: _Context) -> tuple[str, object]:
        """Type an expression: ("num", Linear) or ("bool", Guard)."""
        if isinstance(node, ast.Number):
            return _typed("num", ir.Linear.constant(node.value))
        if isinstance(node, ast.BoolLit):
            return _typed("bool", ir.BConst(node.value))
        if isinstance(node, ast.Name):
            return self._name(node, ctx)
        if isinstance(node, ast.Unary):
            kind, value = self.expr(node.operand, ctx)
            if node.op == "-":
                self._expect("num", kind, node.operand, "`-`")
                return _typed("num", value.scaled(-1))  # type: ignore[union-attr]
            self._expect("bool", kind, node.operand, "`!`")
            return _typed("bool", _not(value))  # type: ignore[arg-type]
        if isinstance(node, ast.Binary):
            return self._binary(node, ctx)
        if isinstance(node, ast.Call):
            self._error("E0103", f"`{node.func}(...)` is not available in {ctx.what}", node.span,
                        hints=["function calls are allowed in queries only"])
            raise Unresolvable
        self._error("E0103", f"`{node.scope}.{node.id}` is not available in {ctx.what}", node.span,  # type: ignore[union-attr]
                    hints=["qualified names are allowed in queries only"])
        raise Unresolvable

    def _expect(self, want: str, got: str, node: ast.Expr, where: str) -> None:
        if want != got:
            hints = []
            if want == "bool":
                shown = node.id if isinstance(node, ast.Name) else "x"
                hints.append(f"a number is not a condition: compare it, e.g. `{shown} < 2`")
            self._error("E0201", f"{where} needs {type_word(want)}, found {type_word(got)}", node.span,
                        hints=hints)
            raise Unresolvable

    def _name(self, node: ast.Name, ctx: _Context) -> tuple[str, object]:
        symbol = self.symbols.get(node.id)
        if symbol is None:
            self._unknown(node.id, node.span)
            raise Unresolvable
        if symbol.kind == "const":
            if symbol.value is None:
                raise Unresolvable
            if isinstance(symbol.value, bool):
                return _typed("bool", ir.BConst(symbol.value))
            return _typed("num", ir.Linear.constant(symbol.value))
        if symbol.kind == "input":
            if not ctx.inputs:
                self._error("E0103", f"input `{node.id}` cannot appear in {ctx.what}", node.span,
                            hints=[_why_no_inputs(ctx)])
                raise Unresolvable
            self.used.inputs.add(node.id)
            if symbol.type == "bool":
                return _typed("bool", ir.BInput(node.id))
            return _typed("num", ir.Linear.variable(node.id))
        if symbol.kind == "reward":
            if not ctx.rewards:
                code = "E0202" if ctx is GUARD or ctx.what == "`assume`" else "E0203"
                self._error(code, f"reward `{node.id}` cannot appear in {ctx.what}", node.span,
                            hints=[_why_no_rewards(ctx)])
                raise Unresolvable
            return _typed("num", ir.Linear.variable(node.id))
        self._error("E0103", f"location `{node.id}` cannot appear in {ctx.what}", node.span,
                    hints=["location names are boolean only in queries (e.g. `A[] Unsafe imply ...`)"])
        raise Unresolvable

    def _binary(self, node: ast.Binary, ctx: _Context) -> tuple[str, object]:
        lk, lv = self.expr(node.left, ctx)
        rk, rv = self.expr(node.right, ctx)
        op = node.op
        if op in ast.ARITHMETIC_OPS:
            self._expect("num", lk, node.left, f"`{op}`")
            self._expect("num", rk, node.right, f"`{op}`")
            left, right = lv, rv
            assert isinstance(left, ir.Linear) and isinstance(right, ir.Linear)
            if op == "+":
                return _typed("num", left + right)
            if op == "-":
                return _typed("num", left - right)
            if op == "*":
                if left.is_constant:
                    return _typed("num", right.scaled(left.const))
                if right.is_constant:
                    return _typed("num", left.scaled(right.const))
                self._error("E0203", f"{ctx.what} must be linear: both sides of `*` vary", node.span,
                            hints=["multiply by constants only (rewards and inputs evolve linearly)"])
                raise Unresolvable
            if not right.is_constant:
                self._error("E0203", f"{ctx.what} must be linear: division by a varying value", node.span,
                            hints=["divide by constants only"])
                raise Unresolvable
            if right.const == 0:
                self._error("E0207", "division by zero", node.right.span)
                raise Unresolvable
            return _typed("num", left.scaled(1 / right.const))
        if op in ast.COMPARISON_OPS:
            if lk == "bool" and rk == "bool" and op in ("==", "!="):
                same = ir.BOr((ir.BAnd((lv, rv)), ir.BAnd((_not(lv), _not(rv)))))  # type: ignore[arg-type]
                return _typed("bool", same if op == "==" else _not(same))
            self._expect("num", lk, node.left, f"`{op}`")
            self._expect("num", rk, node.right, f"`{op}`")
            return _typed("bool", self._atom(node, lv - rv, op))  # type: ignore[operator]
        self._expect("bool", lk, node.left, f"`{op}`")
        self._expect("bool", rk, node.right, f"`{op}`")
        if op == "&&":
            return _typed("bool", ir.BAnd((lv, rv)))  # type: ignore[arg-type]
        if op == "||":
            return _typed("bool", ir.BOr((lv, rv)))  # type: ignore[arg-type]
        return _typed("bool", ir.BOr((_not(lv), rv)))  # type: ignore[arg-type]

    def _atom(self, node: ast.Binary, difference: ir.Linear, op: str) -> ir.Guard:
        """Normalise ``left op right`` (as ``left - right op 0``) to ``input op' threshold``."""
        if difference.is_constant:
            return ir.BConst(ir.compare(difference.const, op, 0))
        rewards = [n for n in difference.variables() if self.symbols[n].kind == "reward"]
        if rewards:
            self._error("E0202", f"reward `{rewards[0]}` cannot be compared", node.span,
                        hints=["rewards only flow and are updated; guards read inputs"])
            raise Unresolvable
        if len(difference.terms) > 1:
            names = ", ".join(f"`{n}`" for n in difference.variables())
            self._error("E0208", f"comparison mixes several numeric inputs ({names})", node.span,
                        hints=["compare each numeric input with a constant; "
                               "combine such conditions with `&&`/`||`, or add a bool input for it"])
            raise Unresolvable
        (name, coefficient), = difference.terms
        threshold = -difference.const / coefficient
        if coefficient < 0:
            op = {"<": ">", "<=": ">=", ">": "<", ">=": "<="}.get(op, op)
        return ir.BAtom(name, op, threshold)

    def guard(self, node: ast.Expr | None, ctx: _Context = GUARD) -> ir.Guard:
        if node is None:
            return ir.TRUE
        kind, value = self.expr(node, ctx)
        self._expect("bool", kind, node, ctx.what)
        return value  # type: ignore[return-value]

    def linear(self, node: ast.Expr, ctx: _Context) -> ir.Linear:
        kind, value = self.expr(node, ctx)
        self._expect("num", kind, node, ctx.what)
        return value  # type: ignore[return-value]

    def constant(self, node: ast.Expr, what: str) -> Fraction:
        value = self.linear(node, _Context(what, inputs=False))
        return value.const

    # ------------------------------------------------------------ declarations
    def run(self) -> ir.Automaton | None:
        node = self.node
        singles = self._singletons()
        self._declare_all()
        period = self._time_value(singles.get(ast.SampleDecl), "sample every", "period")
        horizon = self._time_value(singles.get(ast.HorizonDecl), "horizon", "length")
        if period is not None and horizon is not None and (horizon / period).denominator != 1:
            span = singles[ast.HorizonDecl].span
            self._error("E0206", f"the horizon ({_num(horizon)} s) is not a whole number of sample "
                        f"periods ({_num(period)} s)", span,
                        hints=[f"use a horizon of {_num(period * int(horizon / period))} or "
                               f"{_num(period * (int(horizon / period) + 1))}" if horizon > period
                               else f"use a horizon of {_num(period)} (one sample) or more"])
        elif period is not None and horizon is not None and horizon / period > MAX_SAMPLES:
            self._error("E0206", f"the horizon has too many samples ({int(horizon / period):,}; at most "
                        f"{MAX_SAMPLES:,})", singles[ast.HorizonDecl].span,
                        hints=["the exact checks follow every sample of a run: shorten the horizon "
                               "or sample less often"])
        inputs = self._inputs()
        rewards = tuple(n.name for d in node.of(ast.RewardDecl) for n in d.names)
        self._index(inputs, rewards)
        context = ModelContext(self.scope, self.node, self.constant, self.model_spans)
        model = resolve_model(context, inputs, period)
        self.scope.settings = model_settings(model) if model is not None else None
        locations, initial = self._locations(rewards)
        edges = self._edges(locations, rewards)
        ends = tuple(self._end(d, rewards) for d in node.of(ast.EndDecl))
        assume = self._assume()
        objective = self._objective(singles.get(ast.ObjectiveDecl), rewards)
        priority, strict = self._priority(singles.get(ast.PriorityDecl), rewards)
        queries = self._check_queries()
        if any(d.is_error for d in self.diagnostics):
            # Expressions with errors were not fully read: an "unused" input may be used there.
            return None
        self._unused_inputs(inputs)
        assert period is not None and horizon is not None and objective is not None
        automaton = ir.Automaton(
            name=node.name.name,
            inputs=inputs,
            rewards=rewards,
            locations=locations,
            initial=initial,
            edges=edges,
            end_clauses=ends,
            assume=assume,
            objective=objective,
            priority=priority,
            strict=strict,
            period=period,
            horizon=horizon,
            constants=tuple((n, s.value) for n, s in self.symbols.items()
                            if s.kind == "const" and s.value is not None),
            model=model,
            queries=queries,
            source=node,
            spans=self._spans(singles),
        )
        if model is None:
            return automaton
        return dataclasses.replace(automaton, standard_queries=standard_queries(automaton))

    def _index(self, inputs: tuple[ir.Input, ...], rewards: tuple[str, ...]) -> None:
        """Each input's, reward's and location's position, for the names queries resolve to."""
        for i, item in enumerate(inputs):
            self.symbols[item.name].index = i
        for i, reward in enumerate(rewards):
            if self.symbols.get(reward) is not None and self.symbols[reward].kind == "reward":
                self.symbols[reward].index = i
        for i, decl in enumerate(self.node.of(ast.LocationDecl)):
            symbol = self.symbols.get(decl.name.name)
            if symbol is not None and symbol.kind == "location" and symbol.span == decl.name.span:
                symbol.index = i

    def _spans(self, singles: dict[type, ast.Member]) -> dict[str, Span]:
        spans = {name: s.span for name, s in self.symbols.items() if s.span is not None}
        for kind, key in ((ast.PriorityDecl, "priority"), (ast.ObjectiveDecl, "objective"),
                          (ast.SampleDecl, "sample"), (ast.HorizonDecl, "horizon")):
            member = singles.get(kind)
            if member is not None and member.span is not None:
                spans[f"decl:{key}"] = member.span
        spans.update(self.model_spans)
        return spans

    def _singletons(self) -> dict[type, ast.Member]:
        words = {ast.SampleDecl: "sample every", ast.HorizonDecl: "horizon",
                 ast.ObjectiveDecl: "objective", ast.PriorityDecl: "priority"}
        found: dict[type, ast.Member] = {}
        for kind, word in words.items():
            members = self.node.of(kind)
            for extra in members[1:]:
                self._error("E0106", f"`{word}` is declared more than once", extra.span,
                            notes=[Note("first declared here", members[0].span)])
            if members:
                found[kind] = members[0]
            elif kind is not ast.PriorityDecl:
                example = {"sample every": "sample every 0.1", "horizon": "horizon 30",
                           "objective": "objective 10*sa + 5*pr + co"}[word]
                self._error("E0105", f"automaton `{self.node.name.name}` has no `{word}` declaration",
                            self.node.name.span, hints=[f"add e.g. `{example}`"])
        return found

    def _declare_all(self) -> None:
        for member in self.node.members:
            if isinstance(member, ast.InputDecl):
                kind = "bool" if isinstance(member.type, ast.BoolType) else "num"
                for ident in member.names:
                    self._declare(ident, Symbol("input", kind, ident.span))
            elif isinstance(member, ast.RewardDecl):
                for ident in member.names:
                    self._declare(ident, Symbol("reward", "num", ident.span))
            elif isinstance(member, ast.LocationDecl):
                self._declare(member.name, Symbol("location", "bool", member.name.span))
            elif isinstance(member, ast.ConstDecl):
                # Constants are evaluated in order: a later constant may use an earlier one.
                symbol = Symbol("const", "num", member.name.span)
                try:
                    kind, value = self.expr(member.expr, CONSTANT)
                    if kind == "bool":
                        if not isinstance(value, ir.BConst):
                            raise Unresolvable
                        symbol.type, symbol.value = "bool", value.value
                    else:
                        symbol.value = value.const  # type: ignore[union-attr]
                except Unresolvable:
                    pass
                self._declare(member.name, symbol)

    def _time_value(self, member: ast.Member | None, word: str, what: str) -> Fraction | None:
        if member is None:
            return None
        expr = member.period if isinstance(member, ast.SampleDecl) else member.length  # type: ignore[union-attr]
        try:
            value = self.constant(expr, f"the {what} of `{word}`")
        except Unresolvable:
            return None
        if value <= 0:
            self._error("E0206", f"`{word}` must be positive (found {_num(value)})", expr.span)
            return None
        return value

    def _inputs(self) -> tuple[ir.Input, ...]:
        result = []
        for decl in self.node.of(ast.InputDecl):
            for ident in decl.names:
                if isinstance(decl.type, ast.BoolType):
                    result.append(ir.Input(ident.name, "bool", span=ident.span))
                    continue
                numeric = decl.type
                if numeric.low is None or numeric.high is None:
                    self._error("E0204", f"numeric input `{ident.name}` has no bounds", numeric.span,
                                hints=[f"declare its range, e.g. `input {ident.name} : {numeric.kind} in [0, 100]`"])
                    continue
                try:
                    low = self.constant(numeric.low, "an input bound")
                    high = self.constant(numeric.high, "an input bound")
                except Unresolvable:
                    continue
                if low > high:
                    self._error("E0205", f"empty range [{_num(low)}, {_num(high)}] for `{ident.name}`",
                                numeric.span, hints=["write the lower bound first"])
                    continue
                if numeric.kind == "int" and (low.denominator != 1 or high.denominator != 1):
                    self._error("E0205", f"bounds of int input `{ident.name}` must be integers", numeric.span)
                    continue
                result.append(ir.Input(ident.name, numeric.kind, low, high, span=ident.span))
        return tuple(result)

    def _locations(self, rewards: tuple[str, ...]) -> tuple[tuple[ir.Location, ...], int]:
        decls = self.node.of(ast.LocationDecl)
        locations = []
        for decl in decls:
            rates: dict[str, ir.Linear] = {}
            spans: dict[str, Span | None] = {}
            for flow in decl.flows:
                name = flow.reward.name
                symbol = self.symbols.get(name)
                if symbol is None:
                    self._unknown(name, flow.reward.span, "reward")
                    continue
                if symbol.kind != "reward":
                    self._error("E0103", f"`{name}` is {_kind_word(symbol.kind)}, not a reward: "
                                "only rewards have flows", flow.reward.span)
                    continue
                if name in rates:
                    self._error("E0209", f"location `{decl.name.name}` gives `{name}` two rates", flow.span,
                                notes=[Note("first rate here", spans[name])])
                    continue
                try:
                    rates[name] = self.linear(flow.rate, RATE)
                    spans[name] = flow.span
                except Unresolvable:
                    rates[name] = ir.Linear()
                    spans[name] = flow.span
            locations.append(ir.Location(decl.name.name, tuple(rates.get(r, ir.Linear()) for r in rewards),
                                         decl.span))
        initial = [i for i, d in enumerate(decls) if d.initial]
        if not decls:
            self._error("E0104", f"automaton `{self.node.name.name}` has no locations", self.node.name.span,
                        hints=["add e.g. `initial location Normal { sa' == 1 }`"])
        elif not initial:
            self._error("E0104", "no location is marked `initial`", decls[0].span,
                        hints=[f"write `initial location {decls[0].name.name} {{ ... }}`"])
        elif len(initial) > 1:
            self._error("E0104", "more than one `initial` location", decls[initial[1]].span,
                        notes=[Note("the first initial location", decls[initial[0]].span)])
        return tuple(locations), (initial[0] if initial else 0)

    def _location_index(self, ident: ast.Ident) -> int | None:
        names = [d.name.name for d in self.node.of(ast.LocationDecl)]
        if ident.name in names:
            return names.index(ident.name)
        symbol = self.symbols.get(ident.name)
        if symbol is not None:
            self._error("E0103", f"`{ident.name}` is {_kind_word(symbol.kind)}, not a location", ident.span)
        else:
            candidates = difflib.get_close_matches(ident.name, names, n=1)
            self._error("E0101", f"unknown location `{ident.name}`", ident.span,
                        hints=[f"did you mean `{candidates[0]}`?"] if candidates else [])
        return None

    def _updates(self, updates: tuple[ast.Update, ...], rewards: tuple[str, ...]) -> tuple[ir.Assignment, ...]:
        result = []
        for update in updates:
            name = update.target.name
            symbol = self.symbols.get(name)
            if symbol is None:
                self._unknown(name, update.target.span, "reward")
                continue
            if symbol.kind != "reward":
                self._error("E0210", f"cannot assign to {_kind_word(symbol.kind)} `{name}`", update.target.span,
                            hints=["updates change rewards only"])
                continue
            try:
                value = self.linear(update.expr, UPDATE)
            except Unresolvable:
                continue
            if update.op == "+=":
                value = ir.Linear.variable(name) + value
            elif update.op == "-=":
                value = ir.Linear.variable(name) - value
            result.append(ir.Assignment(name, value.ordered(rewards), update.span))
        return tuple(result)

    def _edges(self, locations: tuple[ir.Location, ...], rewards: tuple[str, ...]) -> tuple[tuple[ir.Edge, ...], ...]:
        grouped: list[list[ir.Edge]] = [[] for _ in locations]
        for decl in self.node.of(ast.EdgeDecl):
            target = self._location_index(decl.target)
            source = None if decl.source is None else self._location_index(decl.source)
            if target is None or (decl.source is not None and source is None):
                continue
            try:
                guard = self.guard(decl.guard)
            except Unresolvable:
                continue
            updates = self._updates(decl.updates, rewards)
            sources = [source] if source is not None else [i for i in range(len(locations)) if i != target]
            for s in sources:
                grouped[s].append(ir.Edge(s, target, guard, updates, decl.span))  # type: ignore[arg-type]
        return tuple(tuple(g) for g in grouped)

    def _end(self, decl: ast.EndDecl, rewards: tuple[str, ...]) -> ir.EndClause:
        try:
            guard = self.guard(decl.guard)
        except Unresolvable:
            guard = ir.TRUE
        return ir.EndClause(guard, self._updates(decl.updates, rewards), decl.span)

    def _assume(self) -> ir.Guard:
        parts = []
        for decl in self.node.of(ast.AssumeDecl):
            try:
                parts.append(self.guard(decl.expr, _Context("`assume`")))
            except Unresolvable:
                pass
        if not parts:
            return ir.TRUE
        return parts[0] if len(parts) == 1 else ir.BAnd(tuple(parts))

    def _objective(self, member: ast.Member | None, rewards: tuple[str, ...]) -> ir.Linear | None:
        if member is None:
            return None
        try:
            return self.linear(member.expr, OBJECTIVE).ordered(rewards)  # type: ignore[union-attr]
        except Unresolvable:
            return None

    def _priority(self, member: ast.Member | None, rewards: tuple[str, ...]) -> tuple[tuple[str, ...], bool]:
        if member is None:
            return (), False
        assert isinstance(member, ast.PriorityDecl)
        seen: dict[str, Span | None] = {}
        for ident in member.names:
            symbol = self.symbols.get(ident.name)
            if symbol is None:
                self._unknown(ident.name, ident.span, "reward")
            elif symbol.kind != "reward":
                self._error("E0103", f"`{ident.name}` is {_kind_word(symbol.kind)}, not a reward: "
                            "priorities order rewards", ident.span)
            elif ident.name in seen:
                self._error("E0102", f"`{ident.name}` appears twice in the priority order", ident.span,
                            notes=[Note("first here", seen[ident.name])])
            else:
                seen[ident.name] = ident.span
        missing = [r for r in rewards if r not in seen]
        if missing and len(seen) == len(member.names):
            names = ", ".join(f"`{m}`" for m in missing)
            self._error("E0404", f"the priority order does not rank {names}", member.span,
                        hints=["list every reward, highest priority first: "
                               f"`priority {' > '.join(list(seen) + missing)}`"])
        return tuple(seen), member.strict

    def _unused_inputs(self, inputs: tuple[ir.Input, ...]) -> None:
        for item in inputs:
            if item.name not in self.used.inputs:
                self.diagnostics.append(warning(
                    "W0303", f"input `{item.name}` is never used", item.span,
                    hints=["remove it, or use it in a guard, a rate or an update"]))

    # ------------------------------------------------------------ queries
    def _check_queries(self) -> tuple[iq.QueryDecl, ...]:
        strategies: set[str] = set()
        names: dict[str, Span | None] = {}
        lowered = []
        for decl in self.node.of(ast.QueryDecl):
            if decl.name.name in names:
                self._error("E0102", f"query `{decl.name.name}` is declared twice", decl.name.span,
                            notes=[Note("first declared here", names[decl.name.name])])
            names[decl.name.name] = decl.name.span
            query = Lowering(self.scope).query(decl, strategies)
            if query is not None:
                lowered.append(query)
            if isinstance(decl.query, (ast.ControlStrategy, ast.LearnStrategy)):
                strategies.add(decl.query.name)
        return tuple(lowered)


def _not(guard: ir.Guard) -> ir.Guard:
    if isinstance(guard, ir.BConst):
        return ir.BConst(not guard.value)
    if isinstance(guard, ir.BNot):
        return guard.operand
    return ir.BNot(guard)


def _kind_word(kind: str) -> str:
    return {"input": "an input", "const": "a constant", "reward": "a reward", "location": "a location"}[kind]


def _why_no_rewards(ctx: _Context) -> str:
    if ctx.what == "a rate":
        return "rates are constants or linear in numeric inputs; rewards grow linearly between samples"
    return "rewards behave like UPPAAL hybrid clocks: they cannot steer the automaton"


def _why_no_inputs(ctx: _Context) -> str:
    if ctx.what == "the objective":
        return "the objective weighs rewards; let inputs act through guards, rates and updates"
    return "only constants are allowed here"


def _num(value: Fraction) -> str:
    """A rational as a short decimal for messages."""
    return short_number(value)
