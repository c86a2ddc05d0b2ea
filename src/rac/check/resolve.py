"""AST → IR: names, types and linearity.

This stage turns one parsed automaton into an :class:`rac.ir.Automaton`, or
reports why it cannot (unknown names, type errors, nonlinear rates, missing
declarations). Its expressions are typed by :mod:`rac.check.linear`, its queries
lowered by :mod:`rac.check.queries`. Behavioural checks (determinism, priorities)
run on the IR in :mod:`rac.check.analysis`.
"""

from __future__ import annotations

import dataclasses
import difflib
from collections.abc import Mapping
from fractions import Fraction
from typing import TypeVar

from rac import ir
from rac.check.linear import CONSTANT, OBJECTIVE, RATE, UPDATE, Bool, Context, ExpressionTyper
from rac.check.model_block import resolve_model
from rac.check.queries import Lowering, model_settings
from rac.check.standard import standard_queries
from rac.check.symbols import ModelContext, Scope, Symbol, Unresolvable, declare_hint, kind_word
from rac.core.diagnostics import Diagnostic, Note, short_count, short_number, warning
from rac.core.source import Span
from rac.ir import expr as ie
from rac.ir import query as iq
from rac.ir.significands import rate_diagnostics
from rac.lang import ast

_M = TypeVar("_M")

#: Most samples a run may have (horizon / period): the exact checks walk every one of them.
MAX_SAMPLES = 1_000_000


class Resolver:
    """Resolve one automaton. Call :meth:`run`; read :attr:`diagnostics`."""

    def __init__(self, automaton: ast.Automaton, values: Mapping[str, Fraction] | None = None):
        """``values`` gives parameters (``param``) their values; a parameter not given takes its low bound."""
        self.node = automaton
        self.values = dict(values or {})
        self.parameters: list[ir.Parameter] = []
        self.diagnostics: list[Diagnostic] = []
        self.symbols: dict[str, Symbol] = {}
        #: The names ``param`` declared: constants to the checker, but named as parameters in its messages.
        self.parameter_names: set[str] = set()
        #: What queries and bindings may name; shares the symbols and the diagnostics.
        self.scope = Scope(automaton.name.name, self.symbols, self.has_model, automaton.name.span,
                           diagnostics=self.diagnostics)
        self.typer = ExpressionTyper(self.scope)
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
            kind = "a parameter" if ident.name in self.parameter_names else kind_word(previous.kind)
            self._error("E0102", f"`{ident.name}` is already declared (as {kind})",
                        ident.span, notes=[Note("first declared here", previous.span)],
                        hints=["rename one of the two, or delete the repeated declaration"])
            return False
        self.symbols[ident.name] = symbol
        return True

    def _unknown(self, name: str, span: Span | None, what: str = "name") -> None:
        self.scope.unknown(name, span, what)

    # ------------------------------------------------------------ declarations
    def run(self) -> ir.Automaton | None:
        node = self.node
        singles = self._singletons()
        self._declare_all()
        period = self._time_value(_single(singles, ast.SampleDecl), "sample every", "period")
        horizon = self._time_value(_single(singles, ast.HorizonDecl), "horizon", "length")
        if period is not None and horizon is not None and (horizon / period).denominator != 1:
            span = singles[ast.HorizonDecl].span
            self._error("E0206", f"the horizon ({_num(horizon)} s) is not a whole number of sample "
                        f"periods ({_num(period)} s)", span,
                        hints=[f"use a horizon of {_num(period * int(horizon / period))} or "
                               f"{_num(period * (int(horizon / period) + 1))}" if horizon > period
                               else f"use a horizon of {_num(period)} (one sample) or more"])
        elif period is not None and horizon is not None and horizon / period > MAX_SAMPLES:
            self._error("E0206", f"the horizon has too many samples ({short_count(int(horizon / period))}; at most "
                        f"{MAX_SAMPLES:,})", singles[ast.HorizonDecl].span,
                        hints=["the exact checks follow every sample of a run: shorten the horizon "
                               "or sample less often"])
        inputs = self._inputs()
        rewards = tuple(n.name for d in node.of(ast.RewardDecl) for n in d.names)
        self._index(inputs, rewards)
        context = ModelContext(self.scope, self.node, self.typer.constant, self.model_spans)
        model = resolve_model(context, inputs, period, horizon)
        self.scope.settings = model_settings(model) if model is not None else None
        locations, initial = self._locations(rewards)
        edges = self._edges(locations, rewards)
        ends = tuple(self._end(d, rewards) for d in node.of(ast.EndDecl))
        assumptions = self._assumptions()
        objective = self._objective(_single(singles, ast.ObjectiveDecl), rewards)
        priority, strict = self._priority(_single(singles, ast.PriorityDecl), rewards)
        episode_ends = self._outcome(_single(singles, ast.EpisodeEndsDecl), "episode ends when")
        goal = self._outcome(_single(singles, ast.GoalDecl), "goal when")
        collision = self._outcome(_single(singles, ast.CollisionDecl), "collision when")
        requirements = self._requirements(singles)
        queries = self._check_queries(horizon)
        if any(d.is_error for d in self.diagnostics):
            # Expressions with errors were not fully read: an "unused" input may be used there.
            return None
        self._unused_inputs(inputs, queries)
        self._unused_parameters()
        assert period is not None and horizon is not None and objective is not None
        automaton = ir.Automaton(
            name=node.name.name,
            inputs=inputs,
            rewards=rewards,
            locations=locations,
            initial=initial,
            edges=edges,
            end_clauses=ends,
            assumptions=assumptions,
            objective=objective,
            priority=priority,
            strict=strict,
            period=period,
            horizon=horizon,
            constants=tuple((n, s.value) for n, s in self.symbols.items()
                            if s.kind == "const" and s.value is not None),
            parameters=tuple(self.parameters),
            episode_ends=episode_ends,
            goal=goal,
            collision=collision,
            requirements=requirements,
            model=model,
            queries=queries,
            source=node,
            spans=self._spans(singles),
        )
        if model is None:
            return automaton
        # the model block fixes the number representation: a rate it cannot hold fails `rac check`, not
        # only `rac compile --target uppaal` (the engine holds the same significands)
        unheld = rate_diagnostics(automaton)
        if unheld:
            self.diagnostics.extend(unheld)
            return None
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
                          (ast.SampleDecl, "sample"), (ast.HorizonDecl, "horizon"),
                          (ast.EpisodeEndsDecl, "episode_ends"), (ast.GoalDecl, "goal"),
                          (ast.CollisionDecl, "collision")):
            member = singles.get(kind)
            if member is not None and member.span is not None:
                spans[f"decl:{key}"] = member.span
        spans.update(self.model_spans)
        return spans

    def _objective_example(self) -> str:
        """An objective over the file's own rewards, the first weighted most (`sa`, `pr`, `co` of the
        paper's automaton named rewards that a file of `safe, fast` does not have)."""
        names = [ident.name for member in self.node.of(ast.RewardDecl) for ident in member.names]
        if not names:
            return "objective 10 * sa + 5 * pr + co"
        terms = [f"{10 ** (len(names) - 1 - k)} * {name}" for k, name in enumerate(names[:-1])]
        return "objective " + " + ".join([*terms, names[-1]])

    def _singletons(self) -> dict[type, ast.Member]:
        words = {ast.SampleDecl: "sample every", ast.HorizonDecl: "horizon",
                 ast.ObjectiveDecl: "objective", ast.PriorityDecl: "priority",
                 ast.EpisodeEndsDecl: "episode ends when", ast.GoalDecl: "goal when",
                 ast.CollisionDecl: "collision when"}
        found: dict[type, ast.Member] = {}
        for kind, word in words.items():
            members = self.node.of(kind)
            for extra in members[1:]:
                self._error("E0106", f"`{word}` is declared more than once", extra.span,
                            notes=[Note("first declared here", members[0].span)],
                            hints=[f"an automaton has one `{word}`: keep one and delete the others"])
            if members:
                found[kind] = members[0]
            elif kind not in _OPTIONAL:
                example = {"sample every": "sample every 0.1", "horizon": "horizon 30",
                           "objective": self._objective_example()}[word]
                self._error("E0105", f"automaton `{self.node.name.name}` has no `{word}` declaration",
                            self.node.name.span, hints=[f"add e.g. `{example}`"])
        return found

    def _declare_all(self) -> None:
        below = self.scope.declared_below
        for member in self.node.members:
            names = [member.name] if isinstance(member, ast.ConstDecl) else \
                member.names if isinstance(member, ast.ParamDecl) else []
            below.update((name.name, name.span) for name in names if name.name not in below)
        try:
            self._declare_in_order()
        finally:
            below.clear()

    def _declare_in_order(self) -> None:
        below = self.scope.declared_below
        for member in self.node.members:
            if isinstance(member, ast.ConstDecl):
                below.pop(member.name.name, None)
            elif isinstance(member, ast.ParamDecl):
                for name in member.names:
                    below.pop(name.name, None)
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
                    typed = self.typer.expr(member.expr, CONSTANT)
                    if isinstance(typed, Bool):
                        if not isinstance(typed.value, ir.BConst):
                            raise Unresolvable
                        symbol.type, symbol.value = "bool", typed.value.value
                    else:
                        symbol.value = typed.value.const
                except Unresolvable:
                    pass
                self._declare(member.name, symbol)
            elif isinstance(member, ast.ParamDecl):
                for name, symbol in zip(member.names, self._parameters(member)):
                    if self._declare(name, symbol):
                        self.parameter_names.add(name.name)

    def _parameters(self, member: ast.ParamDecl) -> list[Symbol]:
        """Parameters are constants whose values the caller chose (by default their low bound)."""
        symbols = [Symbol("const", "num", name.span) for name in member.names]
        first = member.names[0].name
        try:
            low = self.typer.constant(member.low, f"the low bound of `{first}`")
            high = self.typer.constant(member.high, f"the high bound of `{first}`")
        except Unresolvable:
            return symbols
        if low > high:
            self._error("E0409", f"the bounds of parameter `{first}` are reversed: "
                        f"{_num(low)} > {_num(high)}", member.span,
                        hints=[f"write `param {', '.join(n.name for n in member.names)} in "
                               f"[{_num(high)}, {_num(low)}]`"])
            return symbols
        for name, symbol in zip(member.names, symbols):
            symbol.value = self.values.get(name.name, low)
            # One name: the declaration is the parameter's place; several: each its own name.
            span = member.span if len(member.names) == 1 else name.span
            self.parameters.append(ir.Parameter(name.name, low, high, symbol.value, span))
        return symbols

    def _unused_parameters(self) -> None:
        used = {n.id for n in ast.names_in(self.node)}
        for parameter in self.parameters:
            if parameter.name not in used:
                self.diagnostics.append(warning(
                    "W0408", f"parameter `{parameter.name}` is never used", parameter.span,
                    hints=["remove it, or use it in an update, a rate or the objective"]))

    def _time_value(self, member: ast.SampleDecl | ast.HorizonDecl | None, word: str, what: str) -> Fraction | None:
        if member is None:
            return None
        expr = member.period if isinstance(member, ast.SampleDecl) else member.length
        try:
            value = self.typer.constant(expr, f"the {what} of `{word}`")
        except Unresolvable:
            return None
        if value <= 0:
            self._error("E0206", f"`{word}` must be positive (found {_num(value)})", expr.span,
                        hints=[f"write a positive number of seconds, e.g. `{word} "
                               f"{'0.1' if word == 'sample every' else '30'}`"])
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
                    low = self.typer.constant(numeric.low, "an input bound")
                    high = self.typer.constant(numeric.high, "an input bound")
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
                    self._error("E0103", f"`{name}` is {kind_word(symbol.kind)}, not a reward: "
                                "only rewards have flows", flow.reward.span,
                                hints=[f"declare the reward (`reward NAME`) and give it the rate, or delete `{name}'`"])
                    continue
                if name in rates:
                    self._error("E0209", f"location `{decl.name.name}` gives `{name}` two rates", flow.span,
                                notes=[Note("first rate here", spans[name])],
                                hints=[f"a reward has one rate in a location: keep one `{name}' == ...`"])
                    continue
                try:
                    rates[name] = self.typer.linear(flow.rate, RATE)
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
                        notes=[Note("the first initial location", decls[initial[0]].span)],
                        hints=["a run starts in one location: keep `initial` on one of them"])
        return tuple(locations), (initial[0] if initial else 0)

    def _location_index(self, ident: ast.Ident) -> int | None:
        names = [d.name.name for d in self.node.of(ast.LocationDecl)]
        if ident.name in names:
            return names.index(ident.name)
        symbol = self.symbols.get(ident.name)
        if symbol is not None:
            self._error("E0103", f"`{ident.name}` is {kind_word(symbol.kind)}, not a location", ident.span,
                        hints=["an edge goes from a location to a location: name one of the `location`s"])
        else:
            candidates = difflib.get_close_matches(ident.name, names, n=1)
            self._error("E0101", f"unknown location `{ident.name}`", ident.span,
                        hints=[f"did you mean `{candidates[0]}`?"] if candidates else [declare_hint(ident.name,
                                                                                                  "location")])
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
                self._error("E0210", f"cannot assign to {kind_word(symbol.kind)} `{name}`", update.target.span,
                            hints=["updates change rewards only"])
                continue
            try:
                value = self.typer.linear(update.expr, UPDATE)
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
            excluded = self._excluded(decl, target)
            if target is None or (decl.source is not None and source is None) or excluded is None:
                continue
            try:
                guard = self.typer.guard(decl.guard)
            except Unresolvable:
                continue
            updates = self._updates(decl.updates, rewards)
            if source is not None:
                sources = [source]
            else:
                sources = [i for i in range(len(locations)) if i != target and i not in excluded]
                if not sources and decl.excluded:
                    self.diagnostics.append(warning(
                        "W0109", "this edge leaves out every location: it never applies", decl.span,
                        notes=["`*` stands for every location except the target, and `except` names all "
                               "the others"],
                        hints=["remove the edge, or exclude fewer locations; a self-loop is written out: "
                               f"`edge {decl.target.name} -> {decl.target.name}`"]))
            for s in sources:
                grouped[s].append(ir.Edge(s, target, guard, updates, decl.span))
        return tuple(tuple(g) for g in grouped)

    def _excluded(self, decl: ast.EdgeDecl, target: int | None) -> set[int] | None:
        """The locations after ``except`` (each name resolved here, once), or None when one is not a
        location. A name excluded twice, or the target (which ``*`` leaves out anyway), is W0108."""
        found: dict[int, Span | None] = {}
        ok = True
        for ident in decl.excluded:
            index = self._location_index(ident)
            if index is None:
                ok = False
            elif index in found:
                self.diagnostics.append(warning(
                    "W0108", f"`{ident.name}` is excluded twice", ident.span,
                    notes=[Note("first excluded here", found[index])], hints=["remove one of the two"]))
            else:
                if index == target:
                    self.diagnostics.append(warning(
                        "W0108", f"`{ident.name}` is the edge's target, which `*` leaves out already", ident.span,
                        notes=["`*` never includes the target: a self-loop has to be written out"],
                        hints=[f"remove `{ident.name}` from the `except` list"]))
                found[index] = ident.span
        return set(found) if ok else None

    def _end(self, decl: ast.EndDecl, rewards: tuple[str, ...]) -> ir.EndClause:
        try:
            guard = self.typer.guard(decl.guard)
        except Unresolvable:
            guard = ir.TRUE
        return ir.EndClause(guard, self._updates(decl.updates, rewards), decl.span)

    def _assumptions(self) -> tuple[ir.Assumption, ...]:
        parts = []
        for decl in self.node.of(ast.AssumeDecl):
            try:
                guard = self.typer.guard(decl.expr, Context("`assume`", condition=True))
                parts.append(ir.Assumption(guard, decl.text, decl.span))
            except Unresolvable:
                pass
        return tuple(parts)

    def _objective(self, member: ast.ObjectiveDecl | None, rewards: tuple[str, ...]) -> ir.Linear | None:
        if member is None:
            return None
        try:
            return self.typer.linear(member.expr, OBJECTIVE).ordered(rewards)
        except Unresolvable:
            return None

    def _priority(self, member: ast.PriorityDecl | None, rewards: tuple[str, ...]) -> tuple[tuple[str, ...], bool]:
        if member is None:
            return (), False
        seen: dict[str, Span | None] = {}
        for ident in member.names:
            symbol = self.symbols.get(ident.name)
            if symbol is None:
                self._unknown(ident.name, ident.span, "reward")
            elif symbol.kind != "reward":
                self._error("E0103", f"`{ident.name}` is {kind_word(symbol.kind)}, not a reward: "
                            "priorities order rewards", ident.span,
                            hints=["name only rewards (`reward NAME`) in `priority`, highest first"])
            elif ident.name in seen:
                self._error("E0102", f"`{ident.name}` appears twice in the priority order", ident.span,
                            notes=[Note("first here", seen[ident.name])],
                            hints=[f"name each reward once: delete one `{ident.name}`"])
            else:
                seen[ident.name] = ident.span
        missing = [r for r in rewards if r not in seen]
        if missing and len(seen) == len(member.names):
            names = ", ".join(f"`{m}`" for m in missing)
            self._error("E0404", f"the priority order does not rank {names}", member.span,
                        hints=["list every reward, highest priority first: "
                               f"`priority {' > '.join(list(seen) + missing)}`"])
        return tuple(seen), member.strict

    def _outcome(self, member: ast.EpisodeEndsDecl | ast.GoalDecl | ast.CollisionDecl | None,
                 word: str) -> ir.Guard | None:
        """``episode ends when``, ``goal when`` or ``collision when``: a condition typed like an edge's guard."""
        if member is None:
            return None
        try:
            return self.typer.guard(member.condition, Context(f"`{word}`", condition=True))
        except Unresolvable:
            return None

    def _requirements(self, singles: dict[type, ast.Member]) -> tuple[ir.Requirement, ...]:
        """The ``require`` declarations: each names a known check once, with a bound for ``risk`` only,
        and the declarations its check reads (E1009, E1010, E0106)."""
        result = []
        seen: dict[str, Span | None] = {}
        for decl in self.node.of(ast.RequireDecl):
            name = decl.check.name
            if name not in ir.REQUIREMENT_CHECKS:
                close = difflib.get_close_matches(name, ir.REQUIREMENT_CHECKS, n=1)
                self._error("E1010", f"unknown requirement `{name}`", decl.check.span,
                            notes=["`require` takes one of: "
                                   + ", ".join(f"`{c}`" for c in ir.REQUIREMENT_CHECKS)],
                            hints=[f"did you mean `{close[0]}`?"] if close else [])
                continue
            if name in seen:
                self._error("E0106", f"`require {name}` is declared more than once", decl.span,
                            notes=[Note("first declared here", seen[name])],
                            hints=["keep one and delete the others"])
                continue
            seen[name] = decl.span
            bound = self._requirement_bound(decl)
            missing = [word for kind, word in _READS[name] if kind not in singles]
            if missing:
                words = " and ".join(f"`{w}`" for w in missing)
                article = "an" if missing[0][0] in "aeiou" else "a"
                what = f"{words} declarations" if len(missing) > 1 else f"{article} {words} declaration"
                self._error("E1009", f"`require {name}` needs {what}", decl.span,
                            notes=[_WHY_READS[name]],
                            hints=[f"declare {' and '.join(_EXAMPLES[w] for w in missing)}"])
            elif bound is not None or name != "risk":  # `risk` without a readable bound was reported
                result.append(ir.Requirement(name, bound, decl.span))
        return tuple(result)

    def _requirement_bound(self, decl: ast.RequireDecl) -> Fraction | None:
        """``risk``'s bound, a constant in [0, 1] (E1010 without one, or out of range); the others take none."""
        name = decl.check.name
        if name != "risk":
            if decl.bound is not None:
                self._error("E1010", f"`require {name}` takes no bound", decl.bound.span,
                            hints=[f"write `require {name}`; only `risk` has a bound"])
            return None
        if decl.bound is None:
            self._error("E1010", "`require risk` needs a bound: the largest risk tolerance p* allowed",
                        decl.span, hints=["write e.g. `require risk <= 1e-4`"])
            return None
        try:
            value = self.typer.constant(decl.bound, "the bound of `require risk`")
        except Unresolvable:
            return None
        if not 0 <= value <= 1:
            self._error("E1010", f"the bound of `require risk` must lie in [0, 1] (found {_num(value)})",
                        decl.bound.span,
                        notes=["p* is a probability: the chance of a collision at which reaching the goal "
                               "and not trying pay the same"],
                        hints=["write a probability, e.g. `require risk <= 1e-4`"])
            return None
        return value

    def _unused_inputs(self, inputs: tuple[ir.Input, ...], queries: tuple[iq.QueryDecl, ...]) -> None:
        # A query reads an input too: removing it, as W0303 suggests, would break the query.
        used = set(self.typer.used_inputs) | {
            ref.name for decl in queries for e in iq.query_exprs(decl.query) for ref in ie.refs(e)
            if ref.kind is ie.RefKind.INPUT}
        for item in inputs:
            if item.name not in used:
                self.diagnostics.append(warning(
                    "W0303", f"input `{item.name}` is never used", item.span,
                    hints=["remove it, or use it in a guard, a rate or an update"]))

    # ------------------------------------------------------------ queries
    def _check_queries(self, horizon: Fraction | None) -> tuple[iq.QueryDecl, ...]:
        strategies: set[str] = set()
        #: Reachability strategies (``control: E<> p``) by name, with their query's span.
        reaching: dict[str, Span | None] = {}
        names: dict[str, Span | None] = {}
        lowered = []
        for decl in self.node.of(ast.QueryDecl):
            if decl.name.name in names:
                self._error("E0102", f"query `{decl.name.name}` is declared twice", decl.name.span,
                            notes=[Note("first declared here", names[decl.name.name])],
                            hints=["rename one of the two queries, or delete one"])
            names[decl.name.name] = decl.name.span
            query = Lowering(self.scope).query(decl, strategies)
            if query is not None:
                lowered.append(query)
                self._bound_past_horizon(decl, query.query, horizon)
                self._under_reachability(decl, reaching)
                self._probability_equality(decl, query.query)
            if isinstance(decl.query, (ast.ControlStrategy, ast.LearnStrategy)):
                strategies.add(decl.query.name)
                # a later strategy of the same name replaces it
                reaching.pop(decl.query.name, None)
                if isinstance(decl.query, ast.ControlStrategy) and decl.query.goal != "A[]":
                    reaching[decl.query.name] = decl.query.span
        return tuple(lowered)

    def _probability_equality(self, decl: ast.QueryDecl, query: iq.Query) -> None:
        """W0606: ``Pr[...](...) == θ`` (or ``!=``), which rac verify's sequential test cannot decide."""
        if not isinstance(query, iq.ProbabilityQuery) or query.compare is None or query.compare[0] not in ("==", "!="):
            return
        op, threshold = query.compare
        self.diagnostics.append(warning(
            "W0606", f"`Pr[...] {op} {short_number(threshold)}` compares a probability for equality, which "
            "`rac verify` does not answer", decl.query.span,
            notes=["rac verify tests a probability against a threshold sequentially (as UPPAAL does): the test "
                   "tells a probability above the threshold from one below it, never one equal to it; the UPPAAL "
                   "target emits the query as written"],
            hints=[f"ask for the probability itself (drop `{op} {short_number(threshold)}`), or compare with "
                   "`>=` or `<=`"]))

    def _under_reachability(self, decl: ast.QueryDecl, reaching: dict[str, Span | None]) -> None:
        """W0605: a query ``under`` a reachability strategy, which rac verify decides but does not keep."""
        under = getattr(decl.query, "under", None)
        if under not in reaching:
            return
        self.diagnostics.append(warning(
            "W0605", f"`under {under}` names a reachability strategy (`control: E<> ...`), which `rac verify` "
            "does not keep", decl.query.span,
            notes=[Note(f"`{under}` is defined here", reaching[under]),
                   "rac verify decides whether a reachability strategy exists but keeps no strategy to follow, "
                   "so it does not answer this query; UPPAAL does"],
            hints=[f"to ask rac verify, define `{under}` as a safety strategy (`control: A[] p`)"]))

    def _bound_past_horizon(self, decl: ast.QueryDecl, query: iq.Query, horizon: Fraction | None) -> None:
        """W0604: a time bound past the horizon asks about runs the model does not have."""
        bound = getattr(query, "bound", None)
        if horizon is None or not isinstance(bound, iq.Bound) or bound.kind != "time" or bound.limit <= horizon:
            return
        node = getattr(decl.query, "bound", None)
        span = node.limit.span if isinstance(node, ast.Bound) else decl.span
        self.diagnostics.append(warning(
            "W0604", f"the time bound ({short_number(bound.limit)} s) is past the horizon "
            f"({short_number(horizon)} s)", span,
            notes=["the model takes no sample after the horizon: in the emitted UPPAAL model nothing happens "
                   "after it while its clocks flow on, so `rac verify` does not answer this query"],
            hints=[f"bound the query by the horizon (`[<={short_number(horizon)}]`), or lengthen the horizon"]))


#: Single declarations an automaton may leave out.
_OPTIONAL = (ast.PriorityDecl, ast.EpisodeEndsDecl, ast.GoalDecl, ast.CollisionDecl)

#: The declarations each requirement's check reads.
_READS: dict[str, tuple[tuple[type, str], ...]] = {
    "risk": ((ast.GoalDecl, "goal when"), (ast.CollisionDecl, "collision when")),
    "ending_early_never_pays": ((ast.EpisodeEndsDecl, "episode ends when"),),
    "goal_earlier_never_pays_less": ((ast.GoalDecl, "goal when"),),
    "stalling_never_pays": ((ast.GoalDecl, "goal when"),),
}
_WHY_READS = {
    "risk": "the risk tolerance p* compares the return of reaching the goal with that of a collision",
    "ending_early_never_pays": "the check compares runs the condition ends early with runs that go on",
    "goal_earlier_never_pays_less": "the check compares runs that reach the goal at different samples",
    "stalling_never_pays": "the check compares runs that stall with runs that reach the goal",
}
_EXAMPLES = {"goal when": "what reaching the goal means, e.g. `goal when dgoal < 2`",
             "collision when": "what a collision means, e.g. `collision when collide`",
             "episode ends when": "when a run ends, e.g. `episode ends when collide || dgoal < 2`"}


def _single(singles: dict[type, ast.Member], kind: type[_M]) -> _M | None:
    """The declaration of ``kind`` among :meth:`Resolver._singletons`, if the automaton has one."""
    member = singles.get(kind)
    return member if isinstance(member, kind) else None


def _num(value: Fraction) -> str:
    """A rational as a short decimal for messages."""
    return short_number(value)
