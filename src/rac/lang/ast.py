"""The typed syntax tree of a `.ra` file: frozen dataclasses carrying spans.

Spans never take part in equality, so a tree parsed from pretty-printed text
compares equal to the original (the round-trip property the tests check).
Surface variants are normalised here: ``and``/``or``/``not`` become
``&&``/``||``/``!``; the printer emits the canonical form.
"""

from __future__ import annotations

import bisect
import dataclasses
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from fractions import Fraction
from typing import TypeVar, Union

from rac.core.source import Span

T = TypeVar("T")


def _span() -> Span | None:
    return field(default=None, compare=False, repr=False)


# ---------------------------------------------------------------- expressions
@dataclass(frozen=True)
class Number:
    value: Fraction
    span: Span | None = _span()


@dataclass(frozen=True)
class BoolLit:
    value: bool
    span: Span | None = _span()


@dataclass(frozen=True)
class Name:
    id: str
    span: Span | None = _span()


@dataclass(frozen=True)
class Qualified:
    """``Process.member`` — e.g. ``Driving.Unsafe`` in a query."""

    scope: str
    id: str
    span: Span | None = _span()


@dataclass(frozen=True)
class Call:
    func: str
    args: tuple[Expr, ...]
    span: Span | None = _span()


@dataclass(frozen=True)
class Unary:
    op: str  # "-" or "!"
    operand: Expr
    span: Span | None = _span()


@dataclass(frozen=True)
class Binary:
    op: str  # + - * /  < <= > >= == !=  && ||  imply
    left: Expr
    right: Expr
    span: Span | None = _span()
    #: ``right`` is the rest of a long chain that :func:`fold_chain` split (``a + b + c`` written without
    #: parentheses around ``b + c``), not an operand in parentheses: the formatter prints none.
    flat: bool = False


Expr = Union[Number, BoolLit, Name, Qualified, Call, Unary, Binary]

ARITHMETIC_OPS = ("+", "-", "*", "/")
COMPARISON_OPS = ("<", "<=", ">", ">=", "==", "!=")
LOGICAL_OPS = ("&&", "||", "imply")

#: A chain of one level's operators (``a + b - c``, ``p && q && r``) of at most this many operands nests to the
#: left, as it reads; a longer one is split (:func:`fold_chain`).
CHAIN_BLOCK = 32
#: The operators a chain may be split at: ``x op (y ...)`` is ``x op y ...`` (exactly; with doubles, up to
#: rounding), also when the rest mixes in ``-`` after ``+`` or ``/`` after ``*``.
ASSOCIATIVE_OPS = ("+", "*", "&&", "||")


#: The operators of each level a chain is made of.
_CHAIN_LEVEL = {"+": "sum", "-": "sum", "*": "product", "/": "product", "&&": "and", "||": "or"}


def same_level(operand: Expr, op: str) -> bool:
    """Whether ``operand`` is a chain of ``op``'s level (``(b + c)`` in ``a - (b + c)``): in a chain it stands in
    parentheses, so a part of the chain cannot start with it (:func:`fold_chain`'s ``starts``)."""
    return isinstance(operand, Binary) and _CHAIN_LEVEL.get(operand.op, operand.op) == _CHAIN_LEVEL.get(op, op)


def fold_chain(operands: Sequence[T], operators: Sequence[str], join: Callable[[str, T, T, bool], T],
               starts: Callable[[int], bool] | None = None) -> T:
    """The chain ``x0 op1 x1 op2 x2 ...`` (``operators[i]`` between ``operands[i]`` and ``operands[i + 1]``,
    all of one level) as binary nodes, each built by ``join(op, left, right, flat)``.

    Up to :data:`CHAIN_BLOCK` operands nest to the left, ``((x0 op1 x1) op2 x2) ...``. A longer chain is split
    at the operator of :data:`ASSOCIATIVE_OPS` nearest its middle, each side in turn, so that its depth grows
    with the logarithm of its length: every later stage walks expressions recursively, and a generated sum
    of 300 terms is not 300 levels of nesting (E0006). ``a - b + c - d`` splits as ``(a - b) + (c - d)``, which
    is the same value; a chain with no such operator (``a - b - c ...``) nests to the left whatever its length.
    ``flat`` is true when ``right`` is such a part of two or more operands, which prints without parentheses.
    ``starts(i)`` says whether such a part may begin with ``operands[i]``: not when that operand is a chain of the
    same level in parentheses (:func:`same_level`), which printed first in the part would lose them.
    """
    splits = [i + 1 for i, op in enumerate(operators)  # operands[i + 1] begins a right part
              if op in ASSOCIATIVE_OPS and (starts is None or starts(i + 1))]

    def left_fold(low: int, high: int) -> T:
        result = operands[low]
        for i in range(low + 1, high):
            result = join(operators[i - 1], result, operands[i], False)
        return result

    def fold(low: int, high: int) -> T:  # operands[low:high]; recursion as deep as log2(len / CHAIN_BLOCK)
        if high - low <= CHAIN_BLOCK:
            return left_fold(low, high)
        middle = (low + high) // 2
        at = bisect.bisect_left(splits, middle)
        candidates = [splits[j] for j in (at - 1, at) if 0 <= j < len(splits) and low < splits[j] < high]
        if not candidates:
            return left_fold(low, high)
        split = min(candidates, key=lambda i: abs(i - middle))
        return join(operators[split - 1], fold(low, split), fold(split, high), high - split >= 2)

    return fold(0, len(operands))


# ---------------------------------------------------------------- declarations
@dataclass(frozen=True)
class BoolType:
    span: Span | None = _span()


@dataclass(frozen=True)
class NumericType:
    kind: str  # "real" or "int"
    low: Expr | None
    high: Expr | None
    span: Span | None = _span()


InputType = Union[BoolType, NumericType]


@dataclass(frozen=True)
class Ident:
    """A declared or referenced name with its own span."""

    name: str
    span: Span | None = _span()


@dataclass(frozen=True)
class InputDecl:
    names: tuple[Ident, ...]
    type: InputType
    span: Span | None = _span()


@dataclass(frozen=True)
class AssumeDecl:
    expr: Expr
    span: Span | None = _span()
    #: The condition as written (comments dropped, whitespace runs as one space): runtime errors quote it.
    text: str = field(default="", compare=False, repr=False)


@dataclass(frozen=True)
class ConstDecl:
    name: Ident
    expr: Expr
    span: Span | None = _span()


@dataclass(frozen=True)
class ParamDecl:
    """``param NAME, ... in [low, high]``: constants whose values the checker synthesises."""

    names: tuple[Ident, ...]
    low: Expr
    high: Expr
    span: Span | None = _span()


@dataclass(frozen=True)
class RewardDecl:
    names: tuple[Ident, ...]
    span: Span | None = _span()


@dataclass(frozen=True)
class PriorityDecl:
    strict: bool
    names: tuple[Ident, ...]
    span: Span | None = _span()


@dataclass(frozen=True)
class ObjectiveDecl:
    expr: Expr
    span: Span | None = _span()


@dataclass(frozen=True)
class SampleDecl:
    period: Expr
    span: Span | None = _span()


@dataclass(frozen=True)
class HorizonDecl:
    length: Expr
    span: Span | None = _span()


@dataclass(frozen=True)
class Flow:
    """``reward' == rate`` inside a location."""

    reward: Ident
    rate: Expr
    span: Span | None = _span()


@dataclass(frozen=True)
class LocationDecl:
    name: Ident
    initial: bool
    flows: tuple[Flow, ...]
    span: Span | None = _span()


@dataclass(frozen=True)
class Update:
    target: Ident
    op: str  # "=", "+=", "-="
    expr: Expr
    span: Span | None = _span()


@dataclass(frozen=True)
class EdgeDecl:
    """``edge SOURCE -> TARGET when g do u``; ``edge * except A, B -> TARGET ...`` leaves A and B out."""

    source: Ident | None  # None is ``*``: every location except the target (and ``excluded``)
    target: Ident
    guard: Expr | None
    updates: tuple[Update, ...]
    #: The names after ``except``, as written (the checker resolves them); only with ``*``.
    excluded: tuple[Ident, ...] = ()
    span: Span | None = _span()

    def __post_init__(self) -> None:
        if self.excluded and self.source is not None:
            raise ValueError("only a `*` edge can exclude locations")


@dataclass(frozen=True)
class EndDecl:
    """``at end when g do u``: applied once when a run ends."""

    guard: Expr | None
    updates: tuple[Update, ...]
    span: Span | None = _span()


@dataclass(frozen=True)
class EpisodeEndsDecl:
    """``episode ends when COND``: the run ends after a sample whose inputs satisfy COND."""

    condition: Expr
    span: Span | None = _span()


@dataclass(frozen=True)
class GoalDecl:
    """``goal when COND``: what reaching the goal means, at a sample."""

    condition: Expr
    span: Span | None = _span()


@dataclass(frozen=True)
class CollisionDecl:
    """``collision when COND``: what a collision means, at a sample."""

    condition: Expr
    span: Span | None = _span()


@dataclass(frozen=True)
class RequireDecl:
    """``require CHECK`` or ``require CHECK <= BOUND``: the check's failure is an error.

    The check's name is kept as written; the checker knows which exist and which take a bound.
    """

    check: Ident
    bound: Expr | None = None
    span: Span | None = _span()


# ---------------------------------------------------------------- queries
@dataclass(frozen=True)
class Bound:
    kind: str  # "time" (``<=T``) or "steps" (``#<=K``)
    limit: Expr
    span: Span | None = _span()


@dataclass(frozen=True)
class PathQuery:
    """``A[] p``, ``E<> p``, ``E[] p``, ``A<> p``."""

    quantifier: str
    expr: Expr
    under: str | None = None
    span: Span | None = _span()


@dataclass(frozen=True)
class LeadsToQuery:
    left: Expr
    right: Expr
    under: str | None = None
    span: Span | None = _span()


@dataclass(frozen=True)
class ProbabilityQuery:
    """``Pr[<=T;N](<> p) >= θ``."""

    bound: Bound
    runs: Expr | None
    path: str  # "<>" or "[]"
    expr: Expr
    compare: tuple[str, Expr] | None = None
    under: str | None = None
    span: Span | None = _span()


@dataclass(frozen=True)
class ExpectationQuery:
    """``E[<=T;N](max: e)``."""

    bound: Bound
    runs: Expr
    aggregate: str  # "max" or "min"
    expr: Expr
    under: str | None = None
    span: Span | None = _span()


@dataclass(frozen=True)
class SimulateQuery:
    bound: Bound
    runs: Expr | None
    exprs: tuple[Expr, ...]
    under: str | None = None
    span: Span | None = _span()


@dataclass(frozen=True)
class ControlStrategy:
    """``strategy S = control: A[] p``."""

    name: str
    goal: str  # "A[]" or "E<>"
    expr: Expr
    under: str | None = None
    span: Span | None = _span()


@dataclass(frozen=True)
class LearnStrategy:
    """``strategy S = maxE(e)[<=T]{d...}->{c...}: <> p under S0``."""

    name: str
    optimise: str  # "maxE" or "minE"
    objective: Expr
    bound: Bound
    discrete: tuple[Expr, ...]
    continuous: tuple[Expr, ...]
    path: str
    expr: Expr
    under: str | None = None
    span: Span | None = _span()


Query = Union[PathQuery, LeadsToQuery, ProbabilityQuery, ExpectationQuery, SimulateQuery,
              ControlStrategy, LearnStrategy]


@dataclass(frozen=True)
class QueryDecl:
    name: Ident
    query: Query
    span: Span | None = _span()


# ---------------------------------------------------------------- the scenario model
@dataclass(frozen=True)
class ModelScenario:
    """``scenario "file.xml"``: the CommonRoad file, as written (without the quotes)."""

    path: str
    span: Span | None = _span()


@dataclass(frozen=True)
class ModelAction:
    """``action jerk in [low, high] step s``."""

    name: Ident
    low: Expr
    high: Expr
    step: Expr
    span: Span | None = _span()


@dataclass(frozen=True)
class ModelBinding:
    """``bind input = expr``: the model expression that drives one input."""

    input: Ident
    expr: Expr
    span: Span | None = _span()


@dataclass(frozen=True)
class ModelAllow:
    """``allow when expr``: an action is allowed only where ``expr`` holds one sense period later."""

    expr: Expr
    span: Span | None = _span()


@dataclass(frozen=True)
class ModelSetting:
    """``name value``, e.g. ``exponent 4`` (the resolver knows which names exist)."""

    name: Ident
    value: Expr
    span: Span | None = _span()


ModelItem = Union[ModelScenario, ModelAction, ModelBinding, ModelAllow, ModelSetting]


@dataclass(frozen=True)
class ModelDecl:
    """``model { ... }``: the scenario model the automaton is checked against."""

    items: tuple[ModelItem, ...]
    span: Span | None = _span()

    def of(self, kind: type) -> list:
        """All items of one kind, in source order."""
        return [i for i in self.items if isinstance(i, kind)]


Member = Union[InputDecl, AssumeDecl, ConstDecl, ParamDecl, RewardDecl, PriorityDecl, ObjectiveDecl,
               SampleDecl, HorizonDecl, LocationDecl, EdgeDecl, EndDecl, EpisodeEndsDecl, GoalDecl, CollisionDecl,
               RequireDecl, QueryDecl, ModelDecl]


@dataclass(frozen=True)
class Automaton:
    name: Ident
    members: tuple[Member, ...]
    span: Span | None = _span()

    def of(self, kind: type) -> list:
        """All members of one declaration kind, in source order."""
        return [m for m in self.members if isinstance(m, kind)]


@dataclass(frozen=True)
class Comment:
    text: str
    span: Span | None = _span()


@dataclass(frozen=True)
class Module:
    """One parsed file: its automata and (for the formatter) its comments."""

    automata: tuple[Automaton, ...]
    comments: tuple[Comment, ...] = field(default=(), compare=False)
    span: Span | None = _span()


def nodes_in(node: object, kind: type[T]) -> list[T]:
    """Every node of ``kind`` in an AST node, in field order (a walk over the frozen dataclasses'
    fields; a node of ``kind`` is not looked into)."""
    if isinstance(node, kind):
        return [node]
    if isinstance(node, (tuple, list)):
        return [n for item in node for n in nodes_in(item, kind)]
    if dataclasses.is_dataclass(node) and not isinstance(node, type):
        return [n for f in dataclasses.fields(node) for n in nodes_in(getattr(node, f.name), kind)]
    return []


def names_in(node: object) -> list[Name]:
    """Every name an AST node mentions."""
    return nodes_in(node, Name)
