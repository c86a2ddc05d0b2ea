"""Text → AST: the lark parser, an explicit Transformer, and syntax errors in user terms."""

from __future__ import annotations

from fractions import Fraction
from functools import lru_cache
from pathlib import Path

from lark import Lark, Token, Transformer, Tree, v_args
from lark.exceptions import UnexpectedCharacters, UnexpectedEOF, UnexpectedInput, UnexpectedToken, VisitError

from rac import ast
from rac.diagnostics import Diagnostic, error
from rac.resources import grammar_path
from rac.source import MAX_SOURCE_BYTES, SourceFile, Span


class ParseFailure(Exception):
    """Internal: carries the diagnostic of the first syntax error."""

    def __init__(self, diagnostic: Diagnostic):
        super().__init__(diagnostic.message)
        self.diagnostic = diagnostic


@lru_cache(maxsize=1)
def _lark() -> Lark:
    return Lark(
        grammar_path().read_text(encoding="utf-8"),
        parser="lalr",
        lexer="contextual",
        propagate_positions=True,
        maybe_placeholders=True,
    )


# How terminals are named in messages. Literal terminals are shown as their text.
_TERMINAL_WORDS = {
    "NAME": "a name",
    "NUMBER": "a number",
    "CMP_OP": "a comparison (`<`, `<=`, `==`, ...)",
    "ADD_OP": "`+` or `-`",
    "MUL_OP": "`*` or `/`",
    "ASSIGN_OP": "`=`, `+=` or `-=`",
    "OR_OP": "`||`",
    "AND_OP": "`&&`",
    "NUMERIC_TYPE": "`real` or `int`",
    "OPTIMISE": "`maxE` or `minE`",
    "MAXMIN": "`max` or `min`",
    "A_BOX": "`A[]`",
    "E_BOX": "`E[]`",
    "A_DIAMOND": "`A<>`",
    "E_DIAMOND": "`E<>`",
    "PR_OPEN": "`Pr[`",
    "E_OPEN": "`E[`",
    "$END": "end of file",
}
_DECLARATION_WORDS = ("input", "assume", "const", "reward", "priority", "objective", "sample",
                      "horizon", "initial", "location", "edge", "at", "query")
_EXPRESSION_START = {"a name", "a number", "`true`", "`false`", "`(`", "`-`", "`!`", "`not`"}


def _describe_terminal(name: str) -> str:
    if name in _TERMINAL_WORDS:
        return _TERMINAL_WORDS[name]
    for terminal in _lark().terminals:
        if terminal.name == name and terminal.pattern.type == "str":
            return f"`{terminal.pattern.value}`"
    return name.lower()


def _describe_expected(expected: set[str]) -> str:
    words = {_describe_terminal(t) for t in expected}
    declaration_words = {f"`{w}`" for w in _DECLARATION_WORDS}
    parts: list[str] = []
    if len(words & declaration_words) >= 5:
        words -= declaration_words
        parts.append("a declaration (`input`, `reward`, `location`, `edge`, `query`, ...)")
    if len(words & _EXPRESSION_START) >= 4:
        words -= _EXPRESSION_START
        parts.append("an expression")
    operators = {w for w in words if w.startswith("`") and any(c in w for c in "+-*/<>=&|")}
    if len(operators) >= 4:
        words -= operators
        parts.append("an operator")
    parts.extend(sorted(words))
    if len(parts) == 1:
        return parts[0]
    return ", ".join(parts[:-1]) + " or " + parts[-1]


def _token_text(token: Token) -> str:
    if token.type == "$END":
        return "end of file"
    return f"`{token.value}`"


def _syntax_hints(found: str, expected: set[str]) -> list[str]:
    hints = []
    words = {_describe_terminal(t) for t in expected}
    if found == "=" and "`==`" in words:
        hints.append("a flow is written `reward' == rate`, with `==`")
    if found == ":=":
        hints.append("assignments are written `reward = expr` (UPPAAL's `:=` is old syntax)")
    if found in ("{", "}") and "RBRACE" in expected:
        hints.append("check that every `{` has a matching `}`")
    if found == ";" and "RBRACE" not in expected:
        hints.append("`;` only separates flows inside a location; declarations need no terminator")
    return hints


def _syntax_error(exc: UnexpectedInput, source: SourceFile) -> Diagnostic:
    pos = getattr(exc, "pos_in_stream", None)
    if isinstance(exc, UnexpectedToken) and exc.token.type == "$END":
        pos = None
    if isinstance(exc, UnexpectedCharacters):
        start = exc.pos_in_stream
        char = source.text[start]
        if source.text.startswith("/*", start):
            return error("E0003", "unterminated block comment", source.span(start, start + 2),
                         hints=["close the comment with `*/`"])
        shown = repr(char)[1:-1] if not char.isprintable() or char == " " else char
        return error("E0002", f"unexpected character `{shown}`", source.span(start, start + 1),
                     notes=[f"expected {_describe_expected(set(exc.allowed or ()))}"]
                     if exc.allowed else [])
    if isinstance(exc, UnexpectedToken):
        expected = set(exc.expected)
        start = exc.token.start_pos
        if start is not None and source.text.startswith("/*", start):
            return error("E0003", "unterminated block comment", source.span(start, start + 2),
                         hints=["close the comment with `*/`"])
        if exc.token.type == "$END":
            span = source.end_span
            message = "unexpected end of file"
        else:
            start = exc.token.start_pos if exc.token.start_pos is not None else pos or 0
            span = source.span(start, exc.token.end_pos or start + len(exc.token.value))
            message = f"unexpected {_token_text(exc.token)}"
        return error("E0001", message, span, notes=[f"expected {_describe_expected(expected)}"],
                     hints=_syntax_hints(str(exc.token.value), expected))
    if isinstance(exc, UnexpectedEOF):
        return error("E0001", "unexpected end of file", source.end_span,
                     notes=[f"expected {_describe_expected(set(exc.expected))}"])
    return error("E0001", "syntax error", source.end_span)


def _fold(items: list, meta_span: Span | None, build) -> ast.Expr:
    """Left-fold ``a op b op c`` into nested binary nodes."""
    result = items[0]
    for i in range(1, len(items), 2):
        result = build(items[i], result, items[i + 1])
    return result


_CANONICAL_OP = {"and": "&&", "or": "||"}


@v_args(meta=True)
class _ToAst(Transformer):
    """Builds AST nodes; one method per grammar rule, named as the rule."""

    def __init__(self, source: SourceFile):
        super().__init__()
        self.source = source

    def _sp(self, item) -> Span | None:
        if isinstance(item, Token):
            return self.source.span(item.start_pos or 0, item.end_pos or 0)
        if getattr(item, "empty", True):
            return None
        return self.source.span(item.start_pos, item.end_pos)

    def _join(self, left, right) -> Span | None:
        a = getattr(left, "span", None)
        b = getattr(right, "span", None)
        if a is None or b is None:
            return a or b
        return self.source.span(a.start, b.end)

    def _ident(self, token: Token) -> ast.Ident:
        return ast.Ident(str(token), self._sp(token))

    def _binary(self, op: Token, left: ast.Expr, right: ast.Expr) -> ast.Binary:
        name = _CANONICAL_OP.get(str(op), str(op))
        return ast.Binary(name, left, right, self._join(left, right))

    # ---- file structure
    def start(self, meta, automata):
        return ast.Module(tuple(automata), span=self._sp(meta))

    def automaton(self, meta, items):
        name, *members = items
        return ast.Automaton(self._ident(name), tuple(members), self._sp(meta))

    def name_list(self, meta, names):
        return tuple(self._ident(n) for n in names)

    def input_decl(self, meta, items):
        return ast.InputDecl(items[0], items[1], self._sp(meta))

    def bool_type(self, meta, items):
        return ast.BoolType(self._sp(meta))

    def numeric_type(self, meta, items):
        kind, low, high = items
        return ast.NumericType(str(kind), low, high, self._sp(meta))

    def assume_decl(self, meta, items):
        return ast.AssumeDecl(items[0], self._sp(meta))

    def const_decl(self, meta, items):
        return ast.ConstDecl(self._ident(items[0]), items[1], self._sp(meta))

    def reward_decl(self, meta, items):
        return ast.RewardDecl(items[0], self._sp(meta))

    def priority_decl(self, meta, items):
        strict = items[0] is not None
        return ast.PriorityDecl(strict, tuple(self._ident(n) for n in items[1:]), self._sp(meta))

    def objective_decl(self, meta, items):
        return ast.ObjectiveDecl(items[0], self._sp(meta))

    def sample_decl(self, meta, items):
        return ast.SampleDecl(items[0], self._sp(meta))

    def horizon_decl(self, meta, items):
        return ast.HorizonDecl(items[0], self._sp(meta))

    def location_decl(self, meta, items):
        initial, name, flows = items
        return ast.LocationDecl(self._ident(name), initial is not None, flows or (), self._sp(meta))

    def flows(self, meta, items):
        return tuple(items)

    def flow(self, meta, items):
        return ast.Flow(self._ident(items[0]), items[1], self._sp(meta))

    def edge_decl(self, meta, items):
        source, target, guard, updates = items
        return ast.EdgeDecl(source, self._ident(target), guard, updates or (), self._sp(meta))

    def edge_source(self, meta, items):
        token = items[0]
        return None if token.type == "STAR" else self._ident(token)

    def guard(self, meta, items):
        return items[0]

    def updates(self, meta, items):
        return tuple(items)

    def update(self, meta, items):
        target, op, expr = items
        return ast.Update(self._ident(target), str(op), expr, self._sp(meta))

    def end_decl(self, meta, items):
        guard, updates = items
        return ast.EndDecl(guard, updates, self._sp(meta))

    # ---- queries
    def query_decl(self, meta, items):
        return ast.QueryDecl(self._ident(items[0]), items[1], self._sp(meta))

    def plain_query(self, meta, items):
        query, under = items
        from dataclasses import replace

        return replace(query, under=under, span=self._sp(meta))

    def under(self, meta, items):
        return str(items[0])

    def _path(self, meta, items, quantifier):
        return ast.PathQuery(quantifier, items[1], span=self._sp(meta))

    def q_always(self, meta, items):
        return self._path(meta, items, "A[]")

    def q_possibly(self, meta, items):
        return self._path(meta, items, "E<>")

    def q_potentially_always(self, meta, items):
        return self._path(meta, items, "E[]")

    def q_eventually(self, meta, items):
        return self._path(meta, items, "A<>")

    def q_leads_to(self, meta, items):
        return ast.LeadsToQuery(items[0], items[2], span=self._sp(meta))

    def q_probability(self, meta, items):
        _, bound, runs, (path, expr), compare = items
        return ast.ProbabilityQuery(bound, runs, path, expr, compare, span=self._sp(meta))

    def q_expectation(self, meta, items):
        _, bound, runs, aggregate, expr = items
        return ast.ExpectationQuery(bound, runs, str(aggregate), expr, span=self._sp(meta))

    def q_simulate(self, meta, items):
        bound, runs, *exprs = items
        return ast.SimulateQuery(bound, runs, tuple(exprs), span=self._sp(meta))

    def strategy_query(self, meta, items):
        name, body, under = items
        from dataclasses import replace

        return replace(body, name=str(name), under=under, span=self._sp(meta))

    def s_control(self, meta, items):
        goal, expr = items[0]
        return ast.ControlStrategy("", goal, expr)

    def goal_always(self, meta, items):
        return ("A[]", items[1])

    def goal_reach(self, meta, items):
        return ("E<>", items[1])

    def s_learn(self, meta, items):
        optimise, objective, bound, discrete, continuous, (path, expr) = items
        return ast.LearnStrategy("", str(optimise), objective, bound, discrete, continuous, path, expr)

    def observations(self, meta, items):
        return tuple(i for i in items if i is not None)

    def bound_time(self, meta, items):
        return ast.Bound("time", items[0], self._sp(meta))

    def bound_steps(self, meta, items):
        return ast.Bound("steps", items[1], self._sp(meta))

    def runs(self, meta, items):
        return items[0]

    def path_eventually(self, meta, items):
        return ("<>", items[1])

    def path_always(self, meta, items):
        return ("[]", items[1])

    def prob_cmp(self, meta, items):
        return (str(items[0]), items[1])

    # ---- expressions
    def imply(self, meta, items):
        return self._binary(items[1], items[0], items[2])

    def or_(self, meta, items):
        return _fold(items, None, self._binary)

    and_ = or_
    sum = or_
    product = or_

    def cmp(self, meta, items):
        return self._binary(items[1], items[0], items[2])

    def not_word(self, meta, items):
        return ast.Unary("!", items[1], self._sp(meta))

    def not_bang(self, meta, items):
        return ast.Unary("!", items[0], self._sp(meta))

    def neg(self, meta, items):
        return ast.Unary("-", items[0], self._sp(meta))

    def number(self, meta, items):
        return ast.Number(Fraction(str(items[0])), self._sp(items[0]))

    def true(self, meta, items):
        return ast.BoolLit(True, self._sp(items[0]))

    def false(self, meta, items):
        return ast.BoolLit(False, self._sp(items[0]))

    def name(self, meta, items):
        return ast.Name(str(items[0]), self._sp(items[0]))

    def qualified(self, meta, items):
        return ast.Qualified(str(items[0]), str(items[1]), self._sp(meta))

    def call(self, meta, items):
        func, *args = items
        return ast.Call(str(func), tuple(a for a in args if a is not None), self._sp(meta))


def read_source(path: str | Path) -> SourceFile:
    """Read a file as UTF-8 text; raise :class:`ParseFailure` for anything that is not one.

    Unreadable files (missing, a directory, no permission) raise ``OSError`` so the
    CLI can exit with status 2; content problems become diagnostics.
    """
    path = Path(path)
    name = str(path)
    if path.is_dir():
        raise IsADirectoryError(f"{name} is a directory, not a .ra file")
    data = path.read_bytes()
    empty = SourceFile(name, "")
    if len(data) > MAX_SOURCE_BYTES:
        raise ParseFailure(error(
            "E0005", f"file is too large ({len(data) / 1e6:.1f} MB; at most {MAX_SOURCE_BYTES // 1000} kB)",
            empty.span(0, 0), hints=["a reward automaton is a few kilobytes: is this the right file?"]))
    return decode_source(name, data)


def decode_source(name: str, data: bytes) -> SourceFile:
    """Decode bytes as a `.ra` file's text, rejecting binary content with a diagnostic."""
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError as exc:
        partial = SourceFile(name, data[: exc.start].decode("utf-8", "replace"))
        raise ParseFailure(error(
            "E0004", f"file is not UTF-8 text (invalid byte 0x{data[exc.start]:02x} at offset {exc.start})",
            partial.end_span, hints=["`.ra` files are UTF-8 text; is this a binary file?"])) from None
    if "\x00" in text:
        offset = text.index("\x00")
        source = SourceFile(name, text)
        raise ParseFailure(error("E0004", "file contains a NUL byte: it is not a text file",
                                 source.span(offset, offset + 1)))
    return SourceFile(name, text.removeprefix("\ufeff"))


def parse_source(source: SourceFile) -> ast.Module:
    """Parse text into an AST; raise :class:`ParseFailure` on the first syntax error."""
    comments: list[ast.Comment] = []
    try:
        tree = _lark().parse(source.text)
    except UnexpectedInput as exc:
        raise ParseFailure(_syntax_error(exc, source)) from None
    except RecursionError:
        raise ParseFailure(error("E0006", "expression nested too deeply", source.end_span)) from None
    try:
        module = _ToAst(source).transform(tree)
    except RecursionError:
        raise ParseFailure(error("E0006", "expression nested too deeply", source.end_span)) from None
    except VisitError as exc:
        if isinstance(exc.orig_exc, RecursionError):
            raise ParseFailure(error("E0006", "expression nested too deeply", source.end_span)) from None
        raise exc.orig_exc from None
    comments = _collect_comments(source)
    if not module.automata:
        raise ParseFailure(error("E0007", "the file declares no automaton", source.span(0, 0),
                                 hints=["start with `automaton Name { ... }`"]))
    from dataclasses import replace

    return replace(module, comments=tuple(comments))


def _collect_comments(source: SourceFile) -> list[ast.Comment]:
    """Comments with their spans, for the formatter (the parser ignores them)."""
    comments = []
    lexer_conf = _lark().lexer_conf
    terminals = {t.name: t for t in lexer_conf.terminals}
    import re

    pattern = re.compile(
        "|".join(f"(?P<{name}>{terminals[name].pattern.to_regexp()})"
                 for name in ("LINE_COMMENT", "BLOCK_COMMENT"))
        + r"|(?P<string>\"(?:[^\"\\\n]|\\.)*\")", re.DOTALL)
    for match in pattern.finditer(source.text):
        if match.lastgroup == "string":
            continue
        comments.append(ast.Comment(match.group(0), source.span(match.start(), match.end())))
    return comments


def parse_text(text: str, name: str = "<string>") -> ast.Module:
    """Parse a string; convenience for tests and tools."""
    return parse_source(SourceFile(name, text))


def parse_tree(text: str) -> Tree:
    """The raw lark tree (for debugging the grammar)."""
    return _lark().parse(text)
