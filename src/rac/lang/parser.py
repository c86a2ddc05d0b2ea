"""Text → AST: the lark parser's tree turned into :mod:`rac.lang.ast` nodes by an explicit Transformer.

Three ways in, one per start rule of the grammar (:mod:`rac.lang.grammar`): a file
(:func:`parse_source`), expressions (:func:`parse_expression`, :func:`parse_expressions`) and
query declarations (:func:`parse_queries`). Syntax errors are put in user terms by
:mod:`rac.lang.syntax_errors`.
"""

from __future__ import annotations

import errno
import os
import re
from dataclasses import replace
from fractions import Fraction
from functools import lru_cache
from pathlib import Path

from lark import Token, Transformer, Tree, v_args
from lark.exceptions import UnexpectedInput, UnexpectedToken, VisitError

from rac.core.diagnostics import Diagnostic, RacError, error
from rac.core.source import MAX_SOURCE_BYTES, SourceFile, Span
from rac.lang import ast
from rac.lang.grammar import EXPRESSIONS, MODULE, QUERIES, lark_parser, terminal_regexp
from rac.lang.syntax_errors import syntax_error

#: A number literal's magnitude must lie within what a double holds (the targets compute with doubles)...
MAX_MAGNITUDE = 1e308
#: ... and, when it is not zero, not below the smallest normal double.
MIN_MAGNITUDE = 1e-307
#: ... with at most this many digits (more cannot matter to a double, and cost time to hold exactly).
MAX_DIGITS = 100
#: A computed value's numerator and denominator have at most this many digits: each product of constants
#: may double them (``const G2 = G1 * G1``), so that a chain of twenty such constants held millions of
#: digits and the check ran for minutes; a double holds 17.
MAX_EXACT_DIGITS = 1000
#: The longest name: UPPAAL's parser refuses identifiers of 4,000 characters, and the UPPAAL target
#: derives names from the user's (a select variable, a mirror) a few characters longer.
MAX_NAME = 3900
#: The words that are operators or literals inside expressions (grammar/rac.lark's IMPLY, NOT_WORD,
#: OR_WORD, AND_WORD, TRUE, FALSE): the contextual lexer would accept them as a declared name, but an
#: expression would read the word, never the name (E0013).
EXPRESSION_WORDS = ("and", "or", "not", "imply", "true", "false")
_NUMBER_PARTS = re.compile(r"(\d+)(?:\.(\d+))?(?:[eE]([+-]?\d+))?")


def number_problem(text: str) -> str | None:
    """Why the literal ``text`` (the grammar's NUMBER) is out of range, or None when it is not:
    decided on the text, before anything large is built (``1e10000000`` is refused at once)."""
    match = _NUMBER_PARTS.fullmatch(text)
    if match is None:
        return None
    whole, fraction, exponent = match.group(1), match.group(2) or "", match.group(3) or "0"
    digits = (whole + fraction).lstrip("0")
    if len(whole) + len(fraction) > MAX_DIGITS:
        return f"written with more than {MAX_DIGITS} digits"
    if len(exponent.lstrip("+-").lstrip("0")) > 6:  # even 0e... would build 10**exponent
        return "out of range (its exponent has more than 6 digits)"
    if not digits:
        return None  # zero
    # the decimal exponent of the leading digit: 10**magnitude <= value < 10**(magnitude + 1)
    magnitude = int(exponent) + len(whole.lstrip("0")) - 1 if whole.lstrip("0") else \
        int(exponent) - (len(fraction) - len(fraction.lstrip("0"))) - 1
    if magnitude > 308 or (magnitude == 308 and float(text) == float("inf")):
        return "too large (beyond 1e308)"
    if magnitude < -307:
        return "too small (below 1e-307, but not 0)"
    return None


def _abbreviated(text: str) -> str:
    return text if len(text) <= 40 else f"{text[:20]}…{text[-12:]}"


class ParseFailure(RacError):
    """Internal: carries the diagnostic of the first syntax error."""

    diagnostic: Diagnostic  # always set, unlike RacError's

    def __init__(self, diagnostic: Diagnostic, source: SourceFile | None = None):
        super().__init__(diagnostic.message)
        self.diagnostic = diagnostic
        #: The text the diagnostic points into, when there is one to show.
        self.source = source


_CANONICAL_OP = {"and": "&&", "or": "||"}


def _operators(items: list) -> list[str]:
    """The operators of a chain's items ``[x0, op1, x1, ...]`` (tokens), ``and``/``or`` as ``&&``/``||``."""
    return [_CANONICAL_OP.get(str(op), str(op)) for op in items[1::2]]


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
        return ast.Ident(self._name_text(token), self._sp(token))

    def _name_text(self, token: Token) -> str:
        """A name's text; E0012 when it is longer than UPPAAL accepts (the target would be refused), E0013
        when it is a word expressions read as an operator or a literal."""
        text = str(token)
        if len(text) > MAX_NAME:
            raise ParseFailure(error(
                "E0012", f"a name of {len(text):,} characters: at most {MAX_NAME:,}", self._sp(token),
                notes=["UPPAAL's parser refuses names of 4,000 characters, and the UPPAAL target derives "
                       "longer names from yours: the emitted model could not be loaded"],
                hints=["use a shorter name"]))
        if text in EXPRESSION_WORDS:
            raise ParseFailure(error(
                "E0013", f"`{text}` is a word of the language: it cannot name anything", self._sp(token),
                notes=[f"in an expression `{text}` is always the "
                       f"{'literal' if text in ('true', 'false') else 'operator'}, so the name could never be read"],
                hints=[f"choose another name, e.g. `{text}_`"]))
        return text

    def _binary(self, op: Token, left: ast.Expr, right: ast.Expr) -> ast.Binary:
        name = _CANONICAL_OP.get(str(op), str(op))
        return ast.Binary(name, left, right, self._join(left, right))

    # ---- file structure
    def start(self, meta, automata):
        return ast.Module(tuple(automata), span=self._sp(meta))

    def expr_list(self, meta, exprs):
        return tuple(exprs)

    def query_list(self, meta, decls):
        return tuple(decls)

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
        span = self._sp(meta)
        written = self.source.text[span.start:span.end] if span is not None else ""
        text = " ".join(_comments().sub(" ", written).split()[1:])  # without the keyword `assume`
        return ast.AssumeDecl(items[0], span, text)

    def const_decl(self, meta, items):
        return ast.ConstDecl(self._ident(items[0]), items[1], self._sp(meta))

    def param_decl(self, meta, items):
        return ast.ParamDecl(items[0], items[1], items[2], self._sp(meta))

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
        (source, excluded), target, guard, updates = items
        return ast.EdgeDecl(source, self._ident(target), guard, updates or (), excluded, self._sp(meta))

    def edge_source(self, meta, items):
        """(the source, or None for ``*``; the names after ``except``)."""
        token = items[0]
        if token.type == "STAR":
            return None, items[1] or ()
        return self._ident(token), ()

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

    def episode_decl(self, meta, items):
        return ast.EpisodeEndsDecl(items[0], self._sp(meta))

    def goal_decl(self, meta, items):
        return ast.GoalDecl(items[0], self._sp(meta))

    def collision_decl(self, meta, items):
        return ast.CollisionDecl(items[0], self._sp(meta))

    def require_decl(self, meta, items):
        name, bound = items
        return ast.RequireDecl(self._ident(name), bound, self._sp(meta))

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

    def model_allow(self, meta, items):
        return ast.ModelAllow(items[0], self._sp(meta))

    def model_setting(self, meta, items):
        return ast.ModelSetting(self._ident(items[0]), items[1], self._sp(meta))

    # ---- queries
    def query_decl(self, meta, items):
        return ast.QueryDecl(self._ident(items[0]), items[1], self._sp(meta))

    def plain_query(self, meta, items):
        query, under = items
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
        operands, operators = items[::2], _operators(items)
        return ast.fold_chain(operands, operators, lambda op, left, right, flat: ast.Binary(
            op, left, right, self._join(left, right), flat),
            lambda i: not ast.same_level(operands[i], operators[i - 1]))

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
        text = str(items[0])
        span = self._sp(items[0])
        problem = number_problem(text)
        if problem is not None:
            raise ParseFailure(error(
                "E0010", f"the number `{_abbreviated(text)}` is {problem}", span,
                notes=["numbers are held exactly, and every target computes with doubles: a number is 0 or "
                       f"between 1e-307 and 1e308 in size, written with at most {MAX_DIGITS} digits"],
                hints=["use a smaller unit or a smaller value"]))
        return ast.Number(Fraction(text), span)

    def true(self, meta, items):
        return ast.BoolLit(True, self._sp(items[0]))

    def false(self, meta, items):
        return ast.BoolLit(False, self._sp(items[0]))

    def name(self, meta, items):
        return ast.Name(self._name_text(items[0]), self._sp(items[0]))

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
    if os.fspath(path) == "":  # Path("") is ".", the working folder: say what was given
        raise FileNotFoundError(errno.ENOENT, "the path is empty, not a .ra file", "")
    path = Path(path)
    name = str(path)
    if path.is_dir():
        raise IsADirectoryError(f"{name} is a directory, not a .ra file")
    if path.exists() and not path.is_file():  # a FIFO or a device: reading it would block
        raise OSError(errno.EINVAL, "not a regular file (a pipe or a device?)", name)
    # at most one byte past the limit: a file of gigabytes (a log, a disk image named .ra) is refused
    # without being read into memory, which swapped the machine before E0005 could say so
    with path.open("rb") as handle:
        data = handle.read(MAX_SOURCE_BYTES + 1)
        size = max(len(data), os.fstat(handle.fileno()).st_size)
    _check_size(name, size, "file")
    return decode_source(name, data)


def _check_size(name: str, size: int, what: str) -> None:
    """E0005 for a source over :data:`MAX_SOURCE_BYTES` (``size`` in UTF-8 bytes)."""
    if size > MAX_SOURCE_BYTES:
        raise ParseFailure(error(
            "E0005", f"{what} is too large ({size:,} bytes; at most {MAX_SOURCE_BYTES:,})",
            SourceFile(name, "").span(0, 0),
            hints=[f"a reward automaton is a few kilobytes: is this the right {what.split()[-1]}?"]))


def text_source(text: str, name: str | os.PathLike[str]) -> SourceFile:
    """Source text given as a string, with the checks of a file's: a ``TypeError`` naming the argument
    that is not a ``str``, E0005 (:class:`ParseFailure`) over :data:`MAX_SOURCE_BYTES` UTF-8 bytes, and
    E0004 for a NUL character."""
    if not isinstance(text, str):
        raise TypeError(f"text must be a str, not {type(text).__name__}")
    if isinstance(name, os.PathLike):  # a file's path names its text as well
        name = os.fspath(name)
    if not isinstance(name, str):
        raise TypeError(f"name must be a str, not {type(name).__name__}")
    if len(text) > MAX_SOURCE_BYTES // 4:  # only then can it be too large: a character is 1 to 4 bytes
        _check_size(name, len(text.encode("utf-8", "surrogatepass")), "source text")
    source = _as_source(name, text)
    _reject_nul(source, "source text", "`.ra` source is text; is this binary data?")
    return source


def _as_source(name: str, text: str) -> SourceFile:
    """``text`` as the source rac reads, whether it came from a file or a string: a leading byte-order
    mark dropped (Python's ``utf-8`` codec keeps it, so a file saved with one read by
    ``Path.read_text`` starts with it) and a lone CR (old Mac line endings) a line break, as LF, one
    character for one, so that lines and columns are an editor's (they were all on line 1)."""
    return SourceFile(name, re.sub(r"\r(?!\n)", "\n", text.removeprefix("\ufeff")))


def _reject_nul(source: SourceFile, what: str, hint: str, show: bool = True) -> None:
    """E0004 (:class:`ParseFailure`) at the first NUL character of ``source``: a file's or a string's
    source alike is text, never binary data. ``show``: with its line, the NUL shown as U+FFFD (not for a
    file that looks like UTF-16, whose every other character is a NUL)."""
    if "\x00" in source.text:
        offset = source.text.index("\x00")
        raise ParseFailure(error("E0004", f"{what} contains a NUL byte: it is not a text file" if what == "file"
                                 else f"{what} contains a NUL byte: it is not text", source.span(offset, offset + 1),
                                 hints=[hint]), source if show else None)


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
        partial = _as_source(name, data[: exc.start].decode("utf-8", "replace"))
        raise ParseFailure(error(
            "E0004", f"file is not UTF-8 text (invalid byte 0x{data[exc.start]:02x} at offset {exc.start})",
            partial.end_span, hints=[f"`.ra` files are UTF-8 text; {utf16}" if _looks_like_utf16(data) else
                                     "`.ra` files are UTF-8 text: save it as UTF-8 (it may be in Latin-1 or "
                                     "another legacy encoding), or check that this is the right file"]),
            partial) from None
    source = _as_source(name, text)
    wide = _looks_like_utf16(data)
    _reject_nul(source, "file", f"`.ra` files are UTF-8 text; {utf16}" if wide else
                "`.ra` files are UTF-8 text; is this a binary file?", show=not wide)
    return source


#: Deepest expression accepted: operators nested in one another, each link of a chain like
#: ``a + b + c`` counting as one level as the AST nests it (:func:`rac.lang.ast.fold_chain`: a long chain
#: of ``+``, ``*``, ``&&`` or ``||`` is split, so it nests about 31 levels plus the logarithm of its length).
#: Every later stage (types, analyses, formatter, targets) walks expressions recursively; this bound keeps
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
        if node.data in _FOLDED:  # nested as the AST will be
            operands = [depths[id(c)] if isinstance(c, Tree) else 0 for c in node.children[::2]]
            # an operand that is a chain of the same rule is one in parentheses (ast.same_level)
            starts = [not (isinstance(c, Tree) and c.data == node.data) for c in node.children[::2]]
            depth = ast.fold_chain(operands, _operators(node.children),
                                   lambda op, left, right, flat: max(left, right) + 1, starts.__getitem__)
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
                hints=["simplify the expression: each operator nested in another counts as one level (a long "
                       "chain of `+`, `*`, `&&` or `||` counts as a few: it is split)"]))
        stack.extend(reversed([c for c in node.children if isinstance(c, Tree)]))


#: Words that are keywords only where a declaration starts (grammar/rac.lark, issue 25). LALR merges
#: the parse states after an expression inside and outside a ``model`` block, so the contextual lexer
#: reads ``collision sticky`` after a setting as the keyword: where the keyword cannot go on but a name
#: can, :func:`_as_name` reads it as the name it is.
CONTEXTUAL_WORDS = ("episode", "ends", "goal", "collision", "require")


def _as_name(exc: UnexpectedInput) -> bool:
    """Lark's error handler: an unexpected contextual keyword is fed again as a name when a name may
    stand there (parsing resumes); False (the syntax error stands) otherwise."""
    if not isinstance(exc, UnexpectedToken) or str(exc.token) not in CONTEXTUAL_WORDS:
        return False
    parser = exc.interactive_parser
    if "NAME" not in parser.accepts():
        return False
    parser.feed_token(Token.new_borrow_pos("NAME", str(exc.token), exc.token))
    return True


def _parse(source: SourceFile, start: str) -> object:
    """``source`` parsed from the start rule ``start`` and transformed into AST nodes;
    :class:`ParseFailure` on the first syntax error or on nesting beyond :data:`MAX_NESTING`."""
    try:
        tree = lark_parser().parse(source.text, start=start, on_error=_as_name)
    except UnexpectedInput as exc:
        raise ParseFailure(syntax_error(exc, source, start)) from None
    except RecursionError:
        raise ParseFailure(error("E0006", "expression nested too deeply", source.end_span)) from None
    _check_nesting(tree, source)
    try:
        return _ToAst(source).transform(tree)
    except RecursionError:
        raise ParseFailure(error("E0006", "expression nested too deeply", source.end_span)) from None
    except VisitError as exc:
        if isinstance(exc.orig_exc, RecursionError):
            raise ParseFailure(error("E0006", "expression nested too deeply", source.end_span)) from None
        raise exc.orig_exc from None


def parse_source(source: SourceFile) -> ast.Module:
    """Parse text into an AST; raise :class:`ParseFailure` on the first syntax error."""
    module = _parse(source, MODULE)
    assert isinstance(module, ast.Module)
    if not module.automata:
        raise ParseFailure(error("E0007", "the file declares no automaton", source.span(0, 0),
                                 hints=["start with `automaton Name { ... }`"]))
    return replace(module, comments=tuple(_collect_comments(source)))


@lru_cache(maxsize=1)
def _comments() -> re.Pattern[str]:
    """The grammar's comments (an expression holds no string a comment marker could be part of)."""
    return re.compile("|".join(terminal_regexp(name) for name in ("LINE_COMMENT", "BLOCK_COMMENT")), re.DOTALL)


def _collect_comments(source: SourceFile) -> list[ast.Comment]:
    """Comments with their spans, for the formatter (the parser ignores them).

    Strings are matched too, and skipped: ``scenario "maps//a.xml"`` holds no comment.
    """
    comments = []
    pattern = re.compile("|".join(f"(?P<{name}>{terminal_regexp(name)})"
                                  for name in ("LINE_COMMENT", "BLOCK_COMMENT", "STRING")), re.DOTALL)
    for match in pattern.finditer(source.text):
        if match.lastgroup != "STRING":
            comments.append(ast.Comment(match.group(0), source.span(match.start(), match.end())))
    return comments


def parse_text(text: str, name: str = "<string>") -> ast.Module:
    """Parse a string; convenience for tests and tools."""
    return parse_source(SourceFile(name, text))


def parse_expressions(source: SourceFile) -> tuple[ast.Expr, ...]:
    """Expressions separated by commas (``mindist(), 3 * collision_distance``), parsed, not checked;
    :class:`ParseFailure` when the text is not such a list."""
    exprs = _parse(source, EXPRESSIONS)
    assert isinstance(exprs, tuple)
    return exprs


def parse_queries(source: SourceFile) -> tuple[ast.QueryDecl, ...]:
    """Query declarations one after another (``query Qb: E[] !collide()``), as inside an
    automaton, parsed, not checked; :class:`ParseFailure` on a syntax error."""
    decls = _parse(source, QUERIES)
    assert isinstance(decls, tuple)
    return decls


class ExpressionError(RacError, ValueError):
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
    try:
        exprs = parse_expressions(SourceFile(name, text))
    except ParseFailure as failure:
        span = failure.diagnostic.span
        if span is not None and span.start >= len(text.rstrip()):
            # the text ends where more was expected: say so, not "unexpected end of file"
            raise ExpressionError(f"`{text}`: the expression is incomplete", incomplete=True) from None
        raise ExpressionError(f"`{text}`: {failure.diagnostic.message}") from None
    if len(exprs) != 1:
        raise ExpressionError(f"`{text}`: expected one expression, not {len(exprs)}", count=len(exprs))
    return exprs[0]
