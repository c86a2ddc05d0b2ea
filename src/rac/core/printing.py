"""The printer base every target's expression printer builds on (the sympy/pysmt printer idea).

A target describes its syntax as data, an :class:`OperatorTable`: for each operator its spelling,
its :class:`Level` and its :class:`Associativity`. :class:`Printer` walks an expression tree
(``print_<NodeClass>`` methods, :meth:`Printer.print`) and puts the parentheses where the table
says the target's grammar needs them, so the four printers — the ``.ra`` formatter, the Python
target, UPPAAL guards and UPPAAL queries — differ in their tables and in the few nodes a target
really prints its own way.

Each print returns a :class:`Printed`: the text and the level of its outermost operator. An operand
stands in parentheses when its level is below the one its place needs::

    class Arithmetic(Printer):
        table = OperatorTable(binary={"+": Operator(" + ", Level.ADD), "*": Operator(" * ", Level.MUL)})

    Arithmetic().infix("*", Printed("a + b", Level.ADD), Printed("c", Level.ATOM))
    # Printed(text='(a + b) * c', level=<Level.MUL: 6>)

May import: nothing of rac.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from enum import Enum, IntEnum
from typing import ClassVar, NamedTuple

__all__ = [
    "COMPARISONS",
    "C_BINARY",
    "Associativity",
    "Level",
    "Operator",
    "OperatorTable",
    "Printed",
    "Printer",
    "number",
    "signed_sum",
]


class Level(IntEnum):
    """How tightly an operator binds, loosest first; one ladder for every target.

    A target uses the levels its grammar has: Python's ``not`` (looser than comparisons) has
    :attr:`NOT`, which the C-like languages leave out, their ``!`` being :attr:`PREFIX`.
    """

    #: ``imply`` in `.ra`; also the level a top-level expression needs: nothing there is parenthesised.
    TOP = 0
    IMPLY = 0
    OR = 1
    AND = 2
    #: A prefix ``not`` that binds looser than comparisons (Python).
    NOT = 3
    COMPARE = 4
    ADD = 5
    MUL = 6
    #: Unary minus, ``!``; a negative number literal.
    PREFIX = 7
    #: Names, literals, calls, anything in parentheses.
    ATOM = 8


class Associativity(Enum):
    """Which operands of an operator may stand at its own level without parentheses."""

    LEFT = "left"  # a - b - c is (a - b) - c: the first operand only
    RIGHT = "right"  # a imply b imply c is a imply (b imply c); !!a: the last operand only
    NONE = "none"  # comparisons: no operand (a < b < c is refused or means something else)
    #: The operation is associative (Python's ``and``): every operand; (a and b) and c prints a and b and c.
    ASSOCIATIVE = "associative"


@dataclass(frozen=True)
class Operator:
    """One operator of a target: its spelling (with the spaces printed around it: ``" && "``, or
    before a prefix operand: ``"!"``, ``"not "``), level and associativity."""

    spelling: str
    level: Level
    associativity: Associativity = Associativity.LEFT


@dataclass(frozen=True)
class OperatorTable:
    """A target's operators, keyed by their `.ra` spelling (``"&&"``, ``"imply"``, ``"-"``), and its
    boolean literals. Binary and prefix operators are separate tables: ``-`` is both."""

    binary: Mapping[str, Operator]
    prefix: Mapping[str, Operator] = field(default_factory=dict)
    true: str = "true"
    false: str = "false"


#: ``<``, ``<=``, ``>``, ``>=``, ``==``, ``!=`` as C, Python, `.ra` and UPPAAL write them; printed as not
#: associative, since each language reads ``a < b < c`` its own way.
COMPARISONS: Mapping[str, Operator] = {
    op: Operator(f" {op} ", Level.COMPARE, Associativity.NONE) for op in ("<", "<=", ">", ">=", "==", "!=")
}

#: C's binary operators, which `.ra` and UPPAAL share: a table starts from these and adds its own.
C_BINARY: Mapping[str, Operator] = {
    "||": Operator(" || ", Level.OR),
    "&&": Operator(" && ", Level.AND),
    **COMPARISONS,
    "+": Operator(" + ", Level.ADD),
    "-": Operator(" - ", Level.ADD),
    "*": Operator(" * ", Level.MUL),
    "/": Operator(" / ", Level.MUL),
}


class Printed(NamedTuple):
    """A printed expression and the level of its outermost operator (:class:`Level`)."""

    text: str
    level: int


class Printer:
    """Walks an expression tree and parenthesises by the table of the target.

    :meth:`print` calls the method ``print_<class name of the node>``, which a subclass defines
    for each node of its tree and builds from :meth:`infix`, :meth:`prefix` and :meth:`literal`;
    a node without such a method is refused (:meth:`print_default`).
    """

    table: ClassVar[OperatorTable]

    def print(self, node: object) -> Printed:
        """``node`` printed by the method for its class."""
        method = getattr(self, "print_" + type(node).__name__, None)
        if method is None:
            return self.print_default(node)
        result: Printed = method(node)
        return result

    def print_default(self, node: object) -> Printed:
        """What :meth:`print` does with a node it has no method for: :class:`TypeError`."""
        raise TypeError(f"not an expression: {node!r}")

    def binary(self, op: str) -> Operator:
        """The binary operator ``op`` of the table; :class:`ValueError` when the target has none."""
        try:
            return self.table.binary[op]
        except KeyError:
            raise ValueError(f"unknown binary operator {op!r}") from None

    def unary(self, op: str) -> Operator:
        """The prefix operator ``op`` of the table; :class:`ValueError` when the target has none."""
        try:
            return self.table.prefix[op]
        except KeyError:
            raise ValueError(f"unknown unary operator {op!r}") from None

    def needs_parentheses(self, op: str, operand: Printed, need: int) -> bool:
        """Whether ``operand`` of the operator ``op`` stands in parentheses where the grammar needs
        ``need``; a target that parenthesises more for its readers overrides this."""
        return operand.level < need

    def operand(self, operand: Printed, need: int, op: str = "") -> str:
        """The text of ``operand`` (of the operator ``op``, if any), in parentheses when it binds less
        tightly than ``need``."""
        return f"({operand.text})" if self.needs_parentheses(op, operand, need) else operand.text

    def infix(self, op: str, *operands: Printed) -> Printed:
        """``a op b`` (or ``a op b op c``: a chain of one operator), parenthesised by associativity."""
        operator = self.binary(op)
        level, kind = operator.level, operator.associativity
        last = len(operands) - 1
        texts = []
        for index, operand in enumerate(operands):
            at_own_level = (kind is Associativity.ASSOCIATIVE
                            or (kind is Associativity.LEFT and index == 0)
                            or (kind is Associativity.RIGHT and index == last))
            texts.append(self.operand(operand, level if at_own_level else level + 1, op))
        return Printed(operator.spelling.join(texts), level)

    def prefix(self, op: str, operand: Printed) -> Printed:
        """``op operand``; a prefix operator that is not right-associative refuses its own level
        (``-(-a)``, not ``--a``)."""
        operator = self.unary(op)
        level = operator.level
        need = level if operator.associativity in (Associativity.RIGHT, Associativity.ASSOCIATIVE) else level + 1
        return Printed(operator.spelling + self.operand(operand, need, op), level)

    def literal(self, value: bool) -> Printed:
        """The target's ``true`` or ``false``."""
        return Printed(self.table.true if value else self.table.false, Level.ATOM)


def number(text: str) -> Printed:
    """A number literal: a leading minus binds like the prefix operator (``-(-1)``, ``2 * -1``)."""
    return Printed(text, Level.PREFIX if text.startswith("-") else Level.ATOM)


def signed_sum(parts: Iterable[tuple[bool, str]]) -> str:
    """``a - b + c`` from ``(negative, magnitude)`` parts: the first part's sign is a ``-`` before it,
    the others' are the operators between them; no parts print as ``""``."""
    text = ""
    for index, (negative, part) in enumerate(parts):
        if index == 0:
            text = ("-" if negative else "") + part
        else:
            text += f" {'-' if negative else '+'} {part}"
    return text
