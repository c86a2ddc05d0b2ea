"""The canonical pretty-printer of `.ra` files, used by ``rac fmt`` and the round-trip tests.

Three layers:

* :func:`format_expr` prints an expression with the fewest parentheses the grammar
  needs to read it back as the same tree, and around ``&&`` inside ``||`` (precedence, lowest first: ``imply``
  (right-associative), ``||``, ``&&``, comparisons (non-associative), ``+ -``,
  ``* /`` (both left-associative), unary ``-`` and ``!``: the table :data:`RA` of
  :class:`RaPrinter`, a :class:`rac.core.printing.Printer`);
* :func:`format_query` and :func:`format_member` print one query or declaration
  on one line (a ``model`` block: one item per line, :func:`format_model_item`);
* :func:`format_module` lays out whole files: four-space indentation, one member
  per line, a blank line where the kind of declaration changes, and every comment
  of the source kept, attached by position to the member it belongs to. Runs of
  declarations of one kind are aligned in columns (:mod:`rac.lang.columns`): the ``:``
  of inputs, the ``=`` of constants and bindings, location bodies and their flows,
  the ``when`` and ``do`` of edges and ``at end`` clauses, and trailing comments.

The property the tests check: ``parse_text(format_module(m)) == m`` for every tree
``m`` the parser can produce, and formatting formatted text changes nothing.
"""

from __future__ import annotations

import bisect
from collections.abc import Sequence
from dataclasses import dataclass, field
from fractions import Fraction

from rac.core.numbers import exact_decimal
from rac.core.printing import C_BINARY, Associativity, Level, Operator, OperatorTable, Printed, Printer, number
from rac.lang import ast
from rac.lang.columns import align_cells, comment_column
from rac.lang.parser import parse_text

__all__ = ["RA", "RaPrinter", "format_expr", "format_member", "format_model_item", "format_module", "format_query",
           "format_source"]

INDENT = "    "

#: Trailing comments of consecutive lines are aligned in one column, unless a line is
#: longer than this (its comment then follows two spaces).
_ALIGN_LIMIT = 72

# ---------------------------------------------------------------- expressions
#: The `.ra` operators as grammar/rac.lark parses them: C's, and ``imply``, the loosest, which
#: associates to the right.
RA = OperatorTable(
    binary={**C_BINARY, "imply": Operator(" imply ", Level.IMPLY, Associativity.RIGHT)},
    # `!!a` needs no parentheses; `-(-a)` keeps them, for the reader (RaPrinter.print_Unary)
    prefix={op: Operator(op, Level.PREFIX, Associativity.RIGHT) for op in ("-", "!")},
)


#: An exact decimal longer than this prints with an exponent (``1e308``, not 309 digits).
PLAIN_NUMBER_CHARS = 24


def _format_number(value: Fraction) -> str:
    """Print an exact decimal literal — plain when short, else with an exponent (``1.5e-300``), both
    reading back as the same value; ``(n / d)`` when no finite decimal exists."""
    if value < 0:
        return "-" + _format_number(-value)
    plain = exact_decimal(value)
    if plain is None:  # not a finite decimal: never produced by the parser; print an equal value
        return f"({value.numerator} / {value.denominator})"
    if len(plain) <= PLAIN_NUMBER_CHARS or value == 0:
        return plain
    # value = digits * 10**exponent, digits without trailing zeros
    places = 0
    while (value * 10**places).denominator != 1:
        places += 1
    digits, exponent = (value * 10**places).numerator, -places
    while digits % 10 == 0:
        digits //= 10
        exponent += 1
    text = str(digits)
    mantissa = text[0] + (f".{text[1:]}" if len(text) > 1 else "")
    scientific = f"{mantissa}e{exponent + len(text) - 1}"
    return scientific if len(scientific) < len(plain) else plain


class RaPrinter(Printer):
    """Prints `.ra` syntax trees (:mod:`rac.lang.ast`) with the fewest parentheses that read back
    as the same tree."""

    table = RA

    def print_Number(self, node: ast.Number) -> Printed:
        return number(_format_number(node.value))

    def print_BoolLit(self, node: ast.BoolLit) -> Printed:
        return self.literal(node.value)

    def print_Name(self, node: ast.Name) -> Printed:
        return Printed(node.id, Level.ATOM)

    def print_Qualified(self, node: ast.Qualified) -> Printed:
        return Printed(f"{node.scope}.{node.id}", Level.ATOM)

    def print_Call(self, node: ast.Call) -> Printed:
        return Printed(f"{node.func}({', '.join(self.print(a).text for a in node.args)})", Level.ATOM)

    def print_Unary(self, node: ast.Unary) -> Printed:
        self.unary(node.op)  # an unknown operator is reported before its operand
        operand = self.print(node.operand)
        if node.op == "-" and operand.text.startswith("-"):
            operand = Printed(f"({operand.text})", Level.ATOM)  # `--x` would be hard to read
        return self.prefix(node.op, operand)

    def print_Binary(self, node: ast.Binary) -> Printed:
        self.binary(node.op)  # an unknown operator is reported before its operands
        right = self.print(node.right)
        if node.flat:  # the rest of a long chain, written without parentheses (ast.fold_chain)
            right = Printed(right.text, Level.ATOM)
        return self.infix(node.op, self.print(node.left), right)

    def needs_parentheses(self, op: str, operand: Printed, need: int) -> bool:
        """Also ``a || (b && c)``: the grammar needs no parentheses there, but a reader does (C
        compilers warn without them), and files write them."""
        return (op == "||" and operand.level == Level.AND) or super().needs_parentheses(op, operand, need)


_PRINTER = RaPrinter()


def _expr(expr: ast.Expr) -> str:
    return _PRINTER.print(expr).text


def format_expr(expr: ast.Expr) -> str:
    """Print an expression with minimal parentheses; parsing the result gives back ``expr``.

    Numbers print as integers or exact decimals (``0.1``, ``2.25``); ``and``/``or``/``not``
    are printed in their canonical forms ``&&``/``||``/``!``.
    """
    return _expr(expr)


# ---------------------------------------------------------------- queries
def _bound(bound: ast.Bound, runs: ast.Expr | None = None) -> str:
    prefix = {"time": "<=", "steps": "#<="}.get(bound.kind)
    if prefix is None:
        raise ValueError(f"unknown bound kind {bound.kind!r}")
    text = prefix + _expr(bound.limit)
    if runs is not None:
        text += f";{_expr(runs)}"
    return text


def _under(query: ast.Query) -> str:
    return f" under {query.under}" if query.under is not None else ""


def _exprs(exprs: tuple[ast.Expr, ...]) -> str:
    return ", ".join(_expr(e) for e in exprs)


def format_query(query: ast.Query) -> str:
    """Print one query formula (the part after ``query NAME:``), UPPAAL style."""
    if isinstance(query, ast.PathQuery):
        text = f"{query.quantifier} {_expr(query.expr)}"
    elif isinstance(query, ast.LeadsToQuery):
        text = f"{_expr(query.left)} --> {_expr(query.right)}"
    elif isinstance(query, ast.ProbabilityQuery):
        text = f"Pr[{_bound(query.bound, query.runs)}]({query.path} {_expr(query.expr)})"
        if query.compare is not None:
            op, threshold = query.compare
            text += f" {op} {_expr(threshold)}"
    elif isinstance(query, ast.ExpectationQuery):
        text = f"E[{_bound(query.bound, query.runs)}]({query.aggregate}: {_expr(query.expr)})"
    elif isinstance(query, ast.SimulateQuery):
        text = f"simulate[{_bound(query.bound, query.runs)}]{{{_exprs(query.exprs)}}}"
    elif isinstance(query, ast.ControlStrategy):
        text = f"strategy {query.name} = control: {query.goal} {_expr(query.expr)}"
    elif isinstance(query, ast.LearnStrategy):
        text = (f"strategy {query.name} = {query.optimise}({_expr(query.objective)})[{_bound(query.bound)}]"
                f"{{{_exprs(query.discrete)}}}->{{{_exprs(query.continuous)}}}: "
                f"{query.path} {_expr(query.expr)}")
    else:
        raise TypeError(f"not a query: {query!r}")
    return text + _under(query)


# ---------------------------------------------------------------- declarations
def _names(idents: tuple[ast.Ident, ...], separator: str = ", ") -> str:
    return separator.join(i.name for i in idents)


def _type(kind: ast.InputType) -> str:
    if isinstance(kind, ast.BoolType):
        return "bool"
    if (kind.low is None) != (kind.high is None):
        raise ValueError("a numeric input has both bounds or neither")
    if kind.low is None or kind.high is None:
        return kind.kind
    return f"{kind.kind} in [{_expr(kind.low)}, {_expr(kind.high)}]"


def _updates(updates: tuple[ast.Update, ...]) -> str:
    return "do " + ", ".join(f"{u.target.name} {u.op} {_expr(u.expr)}" for u in updates) if updates else ""


def _guard(guard: ast.Expr | None) -> str:
    return f"when {_expr(guard)}" if guard is not None else ""


def _edge_source(edge: ast.EdgeDecl) -> str:
    """What an edge leaves from: a location's name, ``*`` for every location, or ``* except A, B``."""
    if edge.source is not None:
        return edge.source.name
    return f"* except {_names(edge.excluded)}" if edge.excluded else "*"


#: A line of a printed automaton: a declaration, or an item of its ``model`` block.
_Node = ast.Member | ast.ModelItem


def _cells(node: _Node) -> list[str] | None:
    """The cells of a declaration whose runs are aligned in columns (:func:`align_cells`), or None.

    Locations are not here: the columns of their flows span the run (:func:`_location_lines`).
    """
    if isinstance(node, ast.InputDecl):
        return [f"input {_names(node.names)}", f": {_type(node.type)}"]
    if isinstance(node, ast.ConstDecl):
        return [f"const {node.name.name}", f"= {_expr(node.expr)}"]
    if isinstance(node, ast.ModelBinding):
        return [f"bind {node.input.name}", f"= {_expr(node.expr)}"]
    if isinstance(node, ast.EdgeDecl):
        return [f"edge {_edge_source(node)} -> {node.target.name}", _guard(node.guard), _updates(node.updates)]
    if isinstance(node, ast.EndDecl):
        return ["at end", _guard(node.guard), _updates(node.updates)]
    return None


def _location_lines(locations: Sequence[ast.LocationDecl]) -> list[str]:
    """A run of locations: the bodies start in one column, and so do the i-th flows of the bodies."""
    flows = align_cells([[f"{f.reward.name}' == {_expr(f.rate)}" + (";" if i < len(loc.flows) - 1 else "")
                          for i, f in enumerate(loc.flows)] for loc in locations])
    return align_cells([[f"{'initial ' if loc.initial else ''}location {loc.name.name}",
                         f"{{ {text} }}" if text else "{ }"] for loc, text in zip(locations, flows, strict=True)])


def _run_lines(run: Sequence[_Node]) -> list[str]:
    """The lines of a run of declarations (or model items) of one kind, aligned."""
    locations = [node for node in run if isinstance(node, ast.LocationDecl)]
    if len(locations) == len(run):
        return _location_lines(locations)
    rows = [cells for cells in map(_cells, run) if cells is not None]
    if len(rows) == len(run):
        return align_cells(rows)
    return [_line(node) for node in run]


def _line(node: _Node) -> str:
    """One declaration or model item alone on its line (no alignment applies to its kind)."""
    if isinstance(node, (ast.ModelScenario, ast.ModelAction, ast.ModelBinding, ast.ModelAllow, ast.ModelSetting)):
        return format_model_item(node)
    return format_member(node)


def format_model_item(item: ast.ModelItem) -> str:
    """Print one item of a ``model`` block on one line, without indentation or comments."""
    if isinstance(item, ast.ModelScenario):
        if '"' in item.path or "\n" in item.path:
            raise ValueError(f"a scenario path cannot hold a quote or a line break: {item.path!r}")
        return f'scenario "{item.path}"'
    if isinstance(item, ast.ModelAction):
        return f"action {item.name.name} in [{_expr(item.low)}, {_expr(item.high)}] step {_expr(item.step)}"
    if isinstance(item, ast.ModelBinding):
        return _run_lines([item])[0]
    if isinstance(item, ast.ModelAllow):
        return f"allow when {_expr(item.expr)}"
    if isinstance(item, ast.ModelSetting):
        return f"{item.name.name} {_expr(item.value)}"
    raise TypeError(f"not a model item: {item!r}")


def format_member(member: ast.Member) -> str:
    """Print one declaration of an automaton, without indentation or comments.

    Every declaration fits on one line except a ``model`` block, which prints one item per
    line, indented by four spaces, between ``model {`` and ``}``. A declaration alone in its
    run prints the same in :func:`format_module`.
    """
    if isinstance(member, (ast.InputDecl, ast.ConstDecl, ast.LocationDecl, ast.EdgeDecl, ast.EndDecl)):
        return _run_lines([member])[0]
    if isinstance(member, ast.ParamDecl):
        return f"param {_names(member.names)} in [{_expr(member.low)}, {_expr(member.high)}]"
    if isinstance(member, ast.AssumeDecl):
        return f"assume {_expr(member.expr)}"
    if isinstance(member, ast.RewardDecl):
        return f"reward {_names(member.names)}"
    if isinstance(member, ast.PriorityDecl):
        return f"priority {'strict ' if member.strict else ''}{_names(member.names, ' > ')}"
    if isinstance(member, ast.ObjectiveDecl):
        return f"objective {_expr(member.expr)}"
    if isinstance(member, ast.SampleDecl):
        return f"sample every {_expr(member.period)}"
    if isinstance(member, ast.HorizonDecl):
        return f"horizon {_expr(member.length)}"
    if isinstance(member, ast.EpisodeEndsDecl):
        return f"episode ends when {_expr(member.condition)}"
    if isinstance(member, ast.GoalDecl):
        return f"goal when {_expr(member.condition)}"
    if isinstance(member, ast.CollisionDecl):
        return f"collision when {_expr(member.condition)}"
    if isinstance(member, ast.RequireDecl):
        bound = f" <= {_expr(member.bound)}" if member.bound is not None else ""
        return f"require {member.check.name}{bound}"
    if isinstance(member, ast.QueryDecl):
        return f"query {member.name.name}: {format_query(member.query)}"
    if isinstance(member, ast.ModelDecl):
        if not member.items:
            return "model { }"
        return "\n".join(["model {", *(INDENT + format_model_item(i) for i in member.items), "}"])
    raise TypeError(f"not a declaration: {member!r}")


#: Declarations of one group are printed without blank lines between them.
_GROUP = {
    ast.InputDecl: 0,
    ast.AssumeDecl: 1,
    ast.ConstDecl: 2, ast.ParamDecl: 2,
    ast.RewardDecl: 3, ast.PriorityDecl: 3, ast.ObjectiveDecl: 3,
    ast.SampleDecl: 4, ast.HorizonDecl: 4,
    ast.LocationDecl: 5,
    ast.EdgeDecl: 6,
    ast.EndDecl: 7,
    ast.EpisodeEndsDecl: 8, ast.GoalDecl: 8, ast.CollisionDecl: 8,
    ast.RequireDecl: 9,
    ast.QueryDecl: 10,
    ast.ModelDecl: 11,
}


# ---------------------------------------------------------------- comments
@dataclass
class _Slot:
    """The comments attached to one printed line (a member, a header, a closing brace)."""

    leading: list[ast.Comment] = field(default_factory=list)   # own lines before it
    trailing: list[ast.Comment] = field(default_factory=list)  # after it, on its line
    continued: list[ast.Comment] = field(default_factory=list)  # own lines aligned under `trailing`


@dataclass
class _BlockComments:
    """The comments inside a ``model { ... }`` block (its member slot holds those around it)."""

    header: _Slot                 # trailing: after `model {`
    items: list[_Slot]
    closing: list[ast.Comment]    # own lines before `}`


@dataclass
class _AutomatonComments:
    header: _Slot                 # leading: before `automaton`; trailing: after `automaton X {`
    members: list[_Slot]
    closing: list[ast.Comment]    # own lines before `}`
    after: list[ast.Comment]      # after `}` on its line
    #: For each `model` member (by index): the comments inside its braces.
    blocks: dict[int, _BlockComments] = field(default_factory=dict)


@dataclass
class _Placement:
    automata: list[_AutomatonComments]
    trailer: list[ast.Comment]    # after the last automaton


def _comment_text(comment: ast.Comment) -> str:
    text = comment.text.replace("\r\n", "\n")
    return text.rstrip() if text.startswith("//") else text


def _is_continuation(comment: ast.Comment, slot: _Slot) -> bool:
    """Tell whether an own-line comment sits right under the slot's trailing comment, in its column.

    The column is the first trailing comment's: that is where continuations are printed, so
    formatted text reads back the same way (with ``/* a */ // b`` trailing, a comment under
    ``// b`` is not a continuation).
    """
    if not slot.trailing:
        return False
    anchor = slot.trailing[0]
    last = slot.continued[-1] if slot.continued else slot.trailing[-1]
    if anchor.span is None or last.span is None or comment.span is None:
        return False
    return (last.span.line == last.span.end_line and comment.span.line == last.span.end_line + 1
            and comment.span.column == anchor.span.column)


@dataclass(frozen=True)
class _Order:
    """The nodes of one automaton or ``model`` block that have a span (in source order, none overlapping
    another), for finding where a comment sits by bisection: placing every comment of a large file by a
    scan of every member took time quadratic in its size."""

    indices: list[int]
    starts: list[int]
    ends: list[int]

    @classmethod
    def of(cls, nodes: Sequence[_Node]) -> _Order:
        placed = [(index, node.span) for index, node in enumerate(nodes) if node.span is not None]
        return cls([i for i, _ in placed], [sp.start for _, sp in placed], [sp.end for _, sp in placed])

    def around(self, offset: int) -> tuple[int | None, int | None, int | None]:
        """The index of the node holding ``offset``, else None and those of the last node before it and the
        first after it (None: there is none)."""
        k = bisect.bisect_right(self.starts, offset) - 1
        if k >= 0 and offset < self.ends[k]:
            return self.indices[k], None, None
        return (None, self.indices[k] if k >= 0 else None,
                self.indices[k + 1] if k + 1 < len(self.indices) else None)


def _place_in_automaton(comment: ast.Comment, automaton: ast.Automaton, slots: _AutomatonComments,
                        order: _Order) -> None:
    span = comment.span
    assert span is not None
    name = automaton.name.span
    if name is not None and span.start < name.end:
        slots.header.leading.append(comment)
        return
    inside, previous, following = order.around(span.start)
    if inside is not None:
        member = automaton.members[inside]
        if isinstance(member, ast.ModelDecl):
            _place_in_block(comment, member, slots.blocks[inside])
        else:
            slots.members[inside].leading.append(comment)  # inside a declaration
        return
    if previous is not None:
        slot = slots.members[previous]
        end_line = automaton.members[previous].span.end_line  # type: ignore[union-attr]
    else:
        slot = slots.header
        end_line = name.end_line if name is not None else -1
    if span.line == end_line:
        slot.trailing.append(comment)
    elif _is_continuation(comment, slot):
        slot.continued.append(comment)
    elif following is not None:
        slots.members[following].leading.append(comment)
    else:
        slots.closing.append(comment)


def _place_in_block(comment: ast.Comment, block: ast.ModelDecl, slots: _BlockComments) -> None:
    """Attach a comment inside a ``model`` block to the item it belongs to (as for members)."""
    span = comment.span
    assert span is not None and block.span is not None
    inside, previous, following = _Order.of(block.items).around(span.start)
    if inside is not None:
        slots.items[inside].leading.append(comment)  # inside an item
        return
    if previous is not None:
        slot = slots.items[previous]
        end_line = block.items[previous].span.end_line  # type: ignore[union-attr]
    else:
        slot = slots.header
        end_line = block.span.line
    if span.line == end_line:
        slot.trailing.append(comment)
    elif _is_continuation(comment, slot):
        slot.continued.append(comment)
    elif following is not None:
        slots.items[following].leading.append(comment)
    else:
        slots.closing.append(comment)


def _place_comments(module: ast.Module) -> _Placement:
    """Attach every comment of ``module`` to the line it belongs to, by source position."""
    placement = _empty_placement(module)
    automata = [(i, a) for i, a in enumerate(module.automata) if a.span is not None]
    orders = {i: _Order.of(a.members) for i, a in automata}
    for comment in sorted(module.comments, key=lambda c: c.span.start if c.span is not None else -1):
        span = comment.span
        if span is None or not automata:
            target = placement.automata[0].header.leading if placement.automata else placement.trailer
            target.append(comment)
            continue
        previous: int | None = None
        following: int | None = None
        for index, automaton in automata:
            assert automaton.span is not None
            if automaton.span.start <= span.start < automaton.span.end:
                _place_in_automaton(comment, automaton, placement.automata[index], orders[index])
                break
            if automaton.span.end <= span.start:
                previous = index
            elif following is None:
                following = index
        else:
            before = module.automata[previous].span if previous is not None else None
            if previous is not None and before is not None and span.line == before.end_line:
                placement.automata[previous].after.append(comment)
            elif following is not None:
                placement.automata[following].header.leading.append(comment)
            else:
                placement.trailer.append(comment)
    return placement


def _empty_placement(module: ast.Module) -> _Placement:
    return _Placement([_AutomatonComments(
        _Slot(), [_Slot() for _ in a.members], [], [],
        {i: _BlockComments(_Slot(), [_Slot() for _ in m.items], []) for i, m in enumerate(a.members)
         if isinstance(m, ast.ModelDecl)}) for a in module.automata], [])


def _emit_line(lines: list[str], code: str, slot: _Slot, column: int | None = None) -> None:
    """Append ``code`` with its trailing comments (at ``column`` if given) and their continuations."""
    if not slot.trailing:
        lines.append(code)
        return
    at = max(column if column is not None else 0, len(code) + 2)
    lines.append(code.ljust(at) + " ".join(_comment_text(c) for c in slot.trailing))
    lines.extend(" " * at + _comment_text(c) for c in slot.continued)


def _runs(keys: Sequence[object], slots: Sequence[_Slot]) -> list[range]:
    """Split consecutive lines into runs: a run ends where the key changes (a blank line or
    another kind of declaration follows) or before a line with own-line comments above it."""
    runs: list[range] = []
    start = 0
    for index in range(1, len(keys) + 1):
        if index == len(keys) or keys[index] != keys[start] or slots[index].leading:
            runs.append(range(start, index))
            start = index
    return runs


def _layout(nodes: Sequence[_Node], slots: Sequence[_Slot], groups: Sequence[int],
            indent: str) -> tuple[list[str], list[int | None]]:
    """Each line's code, aligned within its run of one kind of declaration, and the column of its
    trailing comments, shared by its run of consecutive lines (None: two spaces after the code).

    A ``model`` block spans several lines: it has no code here (:func:`_format_block` prints it).
    """
    codes = [""] * len(nodes)
    for run in _runs([type(node) for node in nodes], slots):
        if not isinstance(nodes[run.start], ast.ModelDecl):
            for index, line in zip(run, _run_lines([nodes[i] for i in run]), strict=True):
                codes[index] = indent + line
    columns: list[int | None] = [None] * len(nodes)
    for run in _runs(groups, slots):
        column = comment_column([len(codes[i]) for i in run if slots[i].trailing], _ALIGN_LIMIT)
        for index in run:
            columns[index] = column if len(codes[index]) <= _ALIGN_LIMIT else None
    return codes, columns


def _format_block(block: ast.ModelDecl, comments: _BlockComments, slot: _Slot) -> list[str]:
    """A ``model`` block, one item per line; ``slot`` holds the comments after its ``}``."""
    indent = INDENT * 2
    if not block.items and not comments.header.trailing and not comments.closing:
        lines: list[str] = []
        _emit_line(lines, INDENT + format_member(block), slot)
        return lines
    lines = []
    _emit_line(lines, INDENT + "model {", comments.header)
    codes, columns = _layout(block.items, comments.items, [0] * len(block.items), indent)
    for code, item, column in zip(codes, comments.items, columns, strict=True):
        lines.extend(indent + _comment_text(c) for c in item.leading)
        _emit_line(lines, code, item, column)
    lines.extend(indent + _comment_text(c) for c in comments.closing)
    _emit_line(lines, INDENT + "}", slot)
    return lines


def _format_automaton(automaton: ast.Automaton, comments: _AutomatonComments) -> list[str]:
    lines = [_comment_text(c) for c in comments.header.leading]
    _emit_line(lines, f"automaton {automaton.name.name} {{", comments.header)
    groups = [_GROUP[type(m)] for m in automaton.members]
    codes, columns = _layout(automaton.members, comments.members, groups, INDENT)
    for index, (code, slot) in enumerate(zip(codes, comments.members, strict=True)):
        if index and groups[index] != groups[index - 1]:
            lines.append("")
        lines.extend(INDENT + _comment_text(c) for c in slot.leading)
        member = automaton.members[index]
        if isinstance(member, ast.ModelDecl):
            lines.extend(_format_block(member, comments.blocks[index], slot))
        else:
            _emit_line(lines, code, slot, columns[index])
    lines.extend(INDENT + _comment_text(c) for c in comments.closing)
    closing = "}"
    if comments.after:
        closing += "  " + " ".join(_comment_text(c) for c in comments.after)
    lines.append(closing)
    return lines


def format_module(module: ast.Module, *, comments: bool = True) -> str:
    """Print a whole file in the canonical layout; the result ends with a single newline.

    With ``comments`` (the default), every comment of ``module.comments`` is printed exactly
    once, next to the declaration it was written at: after it on its line (trailing), on
    its own lines before it (leading; comments written inside a declaration move there
    too), before the closing ``}``, or at the top or bottom of the file. Own-line comments
    aligned under a trailing comment stay aligned under it. Line comments lose trailing
    whitespace.
    """
    placement = _place_comments(module) if comments and module.comments else _empty_placement(module)
    lines: list[str] = []
    for index, automaton in enumerate(module.automata):
        if index:
            lines.append("")
        lines.extend(_format_automaton(automaton, placement.automata[index]))
    if placement.trailer:
        if lines:
            lines.append("")
        lines.extend(_comment_text(c) for c in placement.trailer)
    return "\n".join(lines) + "\n" if lines else ""


def format_source(text: str, name: str = "<string>") -> str:
    """Parse ``text`` and print it in the canonical layout, comments included.

    Raises :class:`rac.lang.parser.ParseFailure` when ``text`` is not a valid `.ra` file.
    """
    return format_module(parse_text(text, name))
