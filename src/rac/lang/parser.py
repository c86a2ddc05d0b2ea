"""Text → AST: the lark parser, an explicit Transformer, and syntax errors in user terms."""

from __future__ import annotations

import re
from fractions import Fraction
from functools import lru_cache
from pathlib import Path

from lark import Lark, Token, Transformer, Tree, v_args
from lark.exceptions import UnexpectedCharacters, UnexpectedEOF, UnexpectedInput, UnexpectedToken, VisitError

from rac.core.diagnostics import Diagnostic, error
from rac.core.source import MAX_SOURCE_BYTES, SourceFile, Span
from rac.lang import ast
from rac.lang.resources import grammar_path


class ParseFailure(Exception):
    """Internal: carries the diagnostic of the first syntax error."""

    def __init__(self, diagnostic: Diagnostic, source: SourceFile | None = None):
        super().__init__(diagnostic.message)
        self.diagnostic = diagnostic
        #: The text the diagnostic points into, when there is one to show.
        self.source = source


@lru_cache(maxsize=1)
def _lark() -> Lark:
    return Lark(
        grammar_path().read_text(encoding="utf-8"),
        parser="lalr",
        lexer="contextual",
        propagate_positions=True,
        maybe_placeholders=True,
        # The parse table is cached in the temp folder: saves ~0.1 s per `rac` start.
        cache=True,
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
    "OR_WORD": "`||`",
    "AND_OP": "`&&`",
    "AND_WORD": "`&&`",
    "NUMERIC_TYPE": "`real` or `int`",
    "OPTIMISE": "`maxE` or `minE`",
    "MAXMIN": "`max` or `min`",
    "A_BOX": "`A[]`",
    "E_BOX": "`E[]`",
    "A_DIAMOND": "`A<>`",
    "E_DIAMOND": "`E<>`",
    "PR_OPEN": "`Pr[`",
    "E_OPEN": "`E[`",
    "STRING": 'a file name in quotes (`"..."`)',
    "$END": "end of file",
}
_DECLARATION_WORDS = ("input", "assume", "const", "reward", "priority", "objective", "sample",
                      "horizon", "initial", "location", "edge", "at", "query", "model")
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


#: Comments, strings (whose text may hold ``//`` or ``/*``) and an unclosed ``/*``, lexed like the grammar.
_COMMENT_SCAN = re.compile(r'(?P<line>//[^\n]*)|(?P<block>/\*.*?\*/)|(?P<string>"[^"\n]*")|(?P<open>/\*)', re.DOTALL)


def _unterminated_comment(text: str) -> int | None:
    """Offset of the first ``/*`` that is never closed (lexed like the grammar does), if any."""
    for match in _COMMENT_SCAN.finditer(text):
        if match.lastgroup == "open":
            return match.start()
    return None


def _acceptable(exc: UnexpectedInput) -> set[str]:
    """The terminals the parser really accepts at the error (LALR tables over-approximate)."""
    parser = getattr(exc, "interactive_parser", None)
    accepted: set[str] = set()
    if parser is not None:
        try:
            accepted = set(parser.accepts())
        except UnexpectedInput:
            accepted = set()
    return accepted or set(getattr(exc, "expected", None) or getattr(exc, "allowed", None) or ())


def _end_of_text(source: SourceFile) -> Span:
    """Where "unexpected end of file" points: just after the last non-blank character."""
    end = len(source.text.rstrip())
    return source.span(end, end)


_CHARACTER_HINTS = {
    "&": "logical and is written `&&` (or `and`)",
    "|": "logical or is written `||` (or `or`)",
    '"': 'a file name is written in double quotes on one line: `scenario "left_turn.xml"`',
}


def _syntax_error(exc: UnexpectedInput, source: SourceFile) -> Diagnostic:
    at_end = isinstance(exc, UnexpectedEOF) or (isinstance(exc, UnexpectedToken) and exc.token.type == "$END")
    if at_end:
        where = len(source.text)
    elif isinstance(exc, UnexpectedToken) and exc.token.start_pos is not None:
        where = exc.token.start_pos
    else:
        where = getattr(exc, "pos_in_stream", None) or 0
    comment = _unterminated_comment(source.text)
    if comment is not None and comment <= where:
        # Without its `*/` the lexer reads `/*` as a division and a product: say what happened.
        return error("E0003", "unterminated block comment", source.span(comment, comment + 2),
                     hints=["close the comment with `*/`"])
    expected = _acceptable(exc)
    notes = [f"expected {_describe_expected(expected)}"] if expected else []
    if isinstance(exc, UnexpectedCharacters):
        start = exc.pos_in_stream
        char = source.text[start]
        shown = repr(char)[1:-1] if not char.isprintable() or char == " " else char
        hints = [_CHARACTER_HINTS[char]] if char in _CHARACTER_HINTS else []
        return error("E0002", f"unexpected character `{shown}`", source.span(start, start + 1),
                     notes=notes, hints=hints)
    if at_end:
        hints = ["check that every `{` has a matching `}`"] if "RBRACE" in expected else []
        return error("E0001", "unexpected end of file", _end_of_text(source), notes=notes, hints=hints)
    if isinstance(exc, UnexpectedToken):
        start = where
        span = source.span(start, exc.token.end_pos or start + len(exc.token.value))
        return error("E0001", f"unexpected {_token_text(exc.token)}", span, notes=notes,
                     hints=_syntax_hints(str(exc.token.value), expected))
    return error("E0001", "syntax error", _end_of_text(source))


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

    # ---- the model block
    def model_block(self, meta, items):
        return ast.ModelDecl(tuple(items), self._sp(meta))

    def model_scenario(self, meta, items):
        return ast.ModelScenario(str(items[0])[1:-1], self._sp(meta))

    def model_action(self, meta, items):
        name, low, high, step = items
        return ast.ModelAction(self._ident(name), low, high, step, self._sp(meta))

    def model_binding(self, meta, items):
        return ast.ModelBinding(self._ident(items[0]), items[1], self._sp(meta))

    def model_setting(self, meta, items):
        return ast.ModelSetting(self._ident(items[0]), items[1], self._sp(meta))

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
            "E0005", f"file is too large ({len(data):,} bytes; at most {MAX_SOURCE_BYTES:,})",
            empty.span(0, 0), hints=["a reward automaton is a few kilobytes: is this the right file?"]))
    return decode_source(name, data)


def _looks_like_utf16(data: bytes) -> bool:
    """A byte-order mark, or ASCII text with every other byte NUL."""
    if data.startswith((b"\xff\xfe", b"\xfe\xff")):
        return True
    head = data[:200]
    return len(head) >= 8 and (not any(head[1::2]) or not any(head[0::2]))


def decode_source(name: str, data: bytes) -> SourceFile:
    """Decode bytes as a `.ra` file's text, rejecting binary content with a diagnostic."""
    utf16 = "it looks like UTF-16: save it as UTF-8"
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError as exc:
        partial = SourceFile(name, data[: exc.start].decode("utf-8", "replace"))
        raise ParseFailure(error(
            "E0004", f"file is not UTF-8 text (invalid byte 0x{data[exc.start]:02x} at offset {exc.start})",
            partial.end_span, hints=[f"`.ra` files are UTF-8 text; {utf16}" if _looks_like_utf16(data) else
                                     "`.ra` files are UTF-8 text: save it as UTF-8 (it may be in Latin-1 or "
                                     "another legacy encoding), or check that this is the right file"]),
            partial) from None
    if "\x00" in text:
        offset = text.index("\x00")
        source = SourceFile(name, text)
        raise ParseFailure(error("E0004", "file contains a NUL byte: it is not a text file",
                                 source.span(offset, offset + 1),
                                 hints=[f"`.ra` files are UTF-8 text; {utf16}" if _looks_like_utf16(data) else
                                        "`.ra` files are UTF-8 text; is this a binary file?"]))
    return SourceFile(name, text.removeprefix("\ufeff"))


#: Deepest expression accepted: operators nested in one another, each link of a chain like
#: ``a + b + c`` counting as one level (the AST nests chains to the left). Every later stage
#: (types, analyses, formatter, targets) walks expressions recursively; this bound keeps
#: them far from Python's recursion limit.
MAX_NESTING = 100

_FOLDED = {"or_", "and_", "sum", "product"}
#: Expression rules that nest their operands one level deeper (atoms count as level 0).
_NESTING = _FOLDED | {"imply", "cmp", "not_word", "not_bang", "neg", "call"}


def _nesting_depths(tree: Tree) -> dict[int, int]:
    """Depth of every expression node (by id), as the AST will nest it; computed without recursion."""
    depths: dict[int, int] = {}
    stack: list[tuple[Tree, bool]] = [(tree, False)]
    while stack:
        node, done = stack.pop()
        children = [c for c in node.children if isinstance(c, Tree)]
        if not done:
            stack.append((node, True))
            stack.extend((c, False) for c in children)
            continue
        if node.data in _FOLDED:
            # ``x0 op x1 op x2`` becomes ((x0 op x1) op x2): x0 sits deepest.
            operands = [depths[id(c)] if isinstance(c, Tree) else 0 for c in node.children[::2]]
            links = len(operands) - 1
            depth = max(d + links - max(0, i - 1) for i, d in enumerate(operands))
        else:
            inner = max((depths[id(c)] for c in children), default=0)
            depth = inner + 1 if node.data in _NESTING else inner
        depths[id(node)] = depth
    return depths


def _check_nesting(tree: Tree, source: SourceFile) -> None:
    """Raise E0006 at the outermost expression nested deeper than :data:`MAX_NESTING`."""
    depths = _nesting_depths(tree)
    stack = [tree]
    while stack:
        node = stack.pop()
        if depths[id(node)] <= MAX_NESTING:
            continue
        if node.data in _NESTING and not getattr(node.meta, "empty", True):
            raise ParseFailure(error(
                "E0006", f"expression nested too deeply ({depths[id(node)]} levels; at most {MAX_NESTING})",
                source.span(node.meta.start_pos, node.meta.end_pos),
                hints=["simplify the expression; in a chain such as `a && b && c` every operator "
                       "counts as one level"]))
        stack.extend(reversed([c for c in node.children if isinstance(c, Tree)]))


def parse_source(source: SourceFile) -> ast.Module:
    """Parse text into an AST; raise :class:`ParseFailure` on the first syntax error."""
    comments: list[ast.Comment] = []
    try:
        tree = _lark().parse(source.text)
    except UnexpectedInput as exc:
        raise ParseFailure(_syntax_error(exc, source)) from None
    except RecursionError:
        raise ParseFailure(error("E0006", "expression nested too deeply", source.end_span)) from None
    _check_nesting(tree, source)
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
    """Comments with their spans, for the formatter (the parser ignores them).

    Strings are matched too, and skipped: ``scenario "maps//a.xml"`` holds no comment.
    """
    comments = []
    terminals = {t.name: t for t in _lark().lexer_conf.terminals}
    pattern = re.compile("|".join(f"(?P<{name}>{terminals[name].pattern.to_regexp()})"
                                  for name in ("LINE_COMMENT", "BLOCK_COMMENT", "STRING")), re.DOTALL)
    for match in pattern.finditer(source.text):
        if match.lastgroup != "STRING":
            comments.append(ast.Comment(match.group(0), source.span(match.start(), match.end())))
    return comments


def parse_text(text: str, name: str = "<string>") -> ast.Module:
    """Parse a string; convenience for tests and tools."""
    return parse_source(SourceFile(name, text))


def parse_tree(text: str) -> Tree:
    """The raw lark tree (for debugging the grammar)."""
    return _lark().parse(text)


class ExpressionError(ValueError):
    """:func:`parse_expression`'s error; ``incomplete`` when the text stops mid-expression and
    ``count`` (how many expressions) when it holds a comma-separated list instead of one."""

    def __init__(self, message: str, *, incomplete: bool = False, count: int = 1) -> None:
        super().__init__(message)
        self.incomplete = incomplete
        self.count = count


def parse_expression(text: str, name: str = "<expr>") -> ast.Expr:
    """One expression of the query language (e.g. ``"10*!isClose + comf"``), parsed, not checked:
    names are resolved when the expression is evaluated. :class:`ExpressionError` (a
    ``ValueError``) when the text is not one expression; its message starts with the text."""
    # A `simulate` query holds a list of expressions: the grammar's way in for a bare one.
    prefix = "automaton X {\nquery E: simulate[<=1;1]{"
    try:
        module = parse_source(SourceFile(name, f"{prefix}{text}\n}}\n}}\n"))
    except ParseFailure as failure:
        span = failure.diagnostic.span
        if span is not None and span.start >= len(prefix) + len(text.rstrip()):
            # the error is at the wrapper's `}`, after the text: say so, not "unexpected `}`"
            raise ExpressionError(f"`{text}`: the expression is incomplete", incomplete=True) from None
        raise ExpressionError(f"`{text}`: {failure.diagnostic.message}") from None
    exprs = module.automata[0].members[0].query.exprs  # type: ignore[union-attr]
    if len(exprs) != 1:
        raise ExpressionError(f"`{text}`: expected one expression, not {len(exprs)}", count=len(exprs))
    return exprs[0]
