"""The finite alphabet of input valuations that the exact checks range over.

Guards compare each numeric input with constants only, so the truth of every
guard is constant on each *piece* of a numeric input's range: the thresholds
themselves and the open intervals between them. A *class* is one valuation of
the boolean inputs plus one piece per numeric input; enumerating the classes
that satisfy ``assume`` covers every input valuation exactly.
"""

from __future__ import annotations

import bisect
import itertools
import math
from collections.abc import Mapping
from dataclasses import dataclass
from fractions import Fraction

import numpy as np

from rac import ir
from rac.core.diagnostics import RacError, short_number

#: Above this many classes the exact checks refuse (reported as a diagnostic).
MAX_CLASSES = 1 << 20
#: Bytes of guard truth tables :meth:`InputSpace.evaluate` keeps; beyond, tables are recomputed
#: (a file with hundreds of guards over a large space would otherwise hold gigabytes).
MAX_CACHED_BYTES = 1 << 27


@dataclass(frozen=True)
class Piece:
    """A point or an interval of one numeric input's range, with its closure."""

    low: Fraction
    high: Fraction
    low_closed: bool
    high_closed: bool

    @property
    def is_point(self) -> bool:
        return self.low == self.high

    def representative(self, integral: bool) -> Fraction:
        if self.is_point:
            return self.low
        if integral:
            return Fraction(math.floor(self.low) + 1) if not self.low_closed else self.low
        return (self.low + self.high) / 2

    def describe(self, name: str) -> str:
        if self.is_point:
            return f"{name} = {_num(self.low)}"
        left = "[" if self.low_closed else "("
        right = "]" if self.high_closed else ")"
        return f"{name} in {left}{_num(self.low)}, {_num(self.high)}{right}"


class TooManyClasses(RacError):
    def __init__(self, count: int):
        super().__init__(f"{count} input classes")
        self.count = count


def _num(value: Fraction) -> str:
    return short_number(value)


def guard_inputs(guard: ir.Guard) -> set[str]:
    """Names of the inputs a guard reads."""
    return {leaf.name if isinstance(leaf, ir.BInput) else leaf.input for leaf in ir.guard_leaves(guard)}


def all_guards(automaton: ir.Automaton) -> list[ir.Guard]:
    """Every guard of the automaton: ``assume``, the edges', the ``at end`` clauses', and the
    ``episode ends``/``goal``/``collision`` conditions (their thresholds cut the pieces too)."""
    named = (automaton.episode_ends, automaton.goal, automaton.collision)
    return [automaton.assume, *(e.guard for e in automaton.all_edges()),
            *(c.guard for c in automaton.end_clauses), *(g for g in named if g is not None)]


def pieces_of(item: ir.Input, thresholds: set[Fraction]) -> list[Piece]:
    """The pieces of numeric input ``item``'s range that comparisons with ``thresholds`` cut it into, in
    increasing order: each threshold within the range and the intervals between (an ``int`` input's
    whole values only: a point per whole threshold and the runs of integers between)."""
    assert item.low is not None and item.high is not None
    points = sorted({item.low, item.high} | {t for t in thresholds if item.low < t < item.high})
    if item.kind == "int":
        # Integer inputs: keep thresholds that are integers as points, and the integer runs between.
        pieces: list[Piece] = []
        cuts = sorted({item.low, item.high} | {t for t in thresholds if item.low <= t <= item.high})
        for i, point in enumerate(cuts):
            if point.denominator == 1:
                pieces.append(Piece(point, point, True, True))
            if i + 1 < len(cuts):
                lo = Fraction(math.floor(point) + 1)
                hi = Fraction(math.ceil(cuts[i + 1]) - 1)
                if lo <= hi:
                    pieces.append(Piece(lo, hi, True, True))
        return pieces
    pieces = []
    for i, point in enumerate(points):
        pieces.append(Piece(point, point, True, True))
        if i + 1 < len(points):
            pieces.append(Piece(point, points[i + 1], False, False))
    return pieces


class InputSpace:
    """All input classes of an automaton, as numpy columns, with guard evaluation."""

    def __init__(self, automaton: ir.Automaton, extra_guards: list[ir.Guard] | None = None):
        self.automaton = automaton
        atoms = {leaf for guard in all_guards(automaton) + (extra_guards or [])
                 for leaf in ir.guard_leaves(guard) if isinstance(leaf, ir.BAtom)}
        self.bools = [i.name for i in automaton.bool_inputs]
        self.numerics = list(automaton.numeric_inputs)
        self.pieces = {i.name: pieces_of(i, {a.threshold for a in atoms if a.input == i.name})
                       for i in self.numerics}
        self._guards = [*all_guards(automaton), *(extra_guards or [])]
        sizes = [2] * len(self.bools) + [len(self.pieces[i.name]) for i in self.numerics]
        # A class's index is its pieces' indices in row-major order (itertools.product): each column's stride.
        self._strides = {item.name: math.prod(sizes[len(self.bools) + k + 1:])
                         for k, item in enumerate(self.numerics)}
        count = math.prod(sizes)
        if count > MAX_CLASSES:
            raise TooManyClasses(count)
        grid = np.array(list(itertools.product(*(range(s) for s in sizes))), dtype=np.int32)
        grid = grid.reshape(count, len(sizes))
        self.count = count
        # Column per input: bool value, or piece index for numeric inputs.
        self.columns: dict[str, np.ndarray] = {}
        for k, name in enumerate(self.bools):
            # False before True, so witnesses prefer "false" valuations.
            self.columns[name] = grid[:, k].astype(bool)
        for k, item in enumerate(self.numerics):
            self.columns[item.name] = grid[:, len(self.bools) + k]
        # Each piece's representative, in increasing order: an atom's truth table is a bisection.
        self._representatives = {item.name: [p.representative(item.kind == "int") for p in self.pieces[item.name]]
                                 for item in self.numerics}
        self._cache: dict[ir.Guard, np.ndarray] = {}
        self._cached_bytes = 0
        self._satisfiable: dict[ir.Guard, bool] = {}
        self.valid = self.evaluate(automaton.assume)

    def _atom_table(self, atom: ir.BAtom) -> np.ndarray:
        """The atom's truth on each piece of its input (pieces are ordered, so a prefix, suffix or point)."""
        values = self._representatives[atom.input]
        below = bisect.bisect_left(values, atom.threshold)  # pieces [0, below) lie below the threshold
        upto = bisect.bisect_right(values, atom.threshold)  # pieces [below, upto) equal it
        table = np.zeros(len(values), dtype=bool)
        if atom.op in ("<", "<=", "!="):
            table[:below] = True
        if atom.op in (">", ">=", "!="):
            table[upto:] = True
        if atom.op in ("<=", ">=", "=="):
            table[below:upto] = True
        return table

    def satisfiable(self, guard: ir.Guard) -> bool:
        """Does some class allowed by ``assume`` satisfy the guard? (Decided once per guard.)"""
        known = self._satisfiable.get(guard)
        if known is None:
            known = self._satisfiable[guard] = bool((self.evaluate(guard) & self.valid).any())
        return known

    def evaluate(self, guard: ir.Guard) -> np.ndarray:
        """Truth of a guard in every class (ignoring ``assume``)."""
        cached = self._cache.get(guard)
        if cached is not None:
            return cached
        if isinstance(guard, ir.BConst):
            result = np.full(self.count, guard.value, dtype=bool)
        elif isinstance(guard, ir.BInput):
            result = self.columns[guard.name]
        elif isinstance(guard, ir.BAtom):
            result = self._atom_table(guard)[self.columns[guard.input]]
        elif isinstance(guard, ir.BNot):
            result = ~self.evaluate(guard.operand)
        elif isinstance(guard, ir.BAnd):
            result = np.logical_and.reduce([self.evaluate(g) for g in guard.operands])
        else:
            result = np.logical_or.reduce([self.evaluate(g) for g in guard.operands])
        if self._cached_bytes + result.nbytes <= MAX_CACHED_BYTES:
            self._cache[guard] = result
            self._cached_bytes += result.nbytes
        return result

    def piece(self, cls: int, name: str) -> Piece:
        return self.pieces[name][int(self.columns[name][cls])]

    def valuation(self, cls: int) -> dict[str, bool | Fraction]:
        """A concrete input valuation inside a class."""
        values: dict[str, bool | Fraction] = {n: bool(self.columns[n][cls]) for n in self.bools}
        for item in self.numerics:
            values[item.name] = self.piece(cls, item.name).representative(item.kind == "int")
        return values

    def describe(self, cls: int, only: set[str] | None = None,
                 values: Mapping[str, Fraction] | None = None, none: str = "(no inputs)") -> str:
        """``isClose=true, prog=false, dgoal in [0, 2)`` for messages.

        ``values`` are numeric inputs' values within the class's pieces' closures (those a worst run's
        rates and updates read): each is shown as ``d = 10``, and named even when ``only`` leaves it out.
        ``none`` is the text where nothing is shown.
        """
        values = values or {}
        parts = []
        for name in self.bools:
            if only is None or name in only:
                parts.append(f"{name}={'true' if self.columns[name][cls] else 'false'}")
        for item in self.numerics:
            if item.name in values:
                parts.append(self._value_text(cls, item.name, values[item.name]))
            elif only is None or item.name in only:
                parts.append(self.piece(cls, item.name).describe(item.name))
        return ", ".join(parts) if parts else none

    def attains(self, cls: int, name: str, value: Fraction) -> bool:
        """Whether a run in class ``cls`` can give the numeric input ``name`` the value ``value`` (a worst
        run's value, within the closure of the class's piece).

        A supremum over an open piece sits at its end (a threshold or a bound, itself a point piece):
        the run takes it when every guard and ``assume`` read the same there as in the piece.
        """
        piece = self.piece(cls, name)
        if (piece.low < value < piece.high or (value == piece.low and piece.low_closed)
                or (value == piece.high and piece.high_closed)):
            return True
        index = int(self.columns[name][cls])
        point = next((j for j, q in enumerate(self.pieces[name]) if q.is_point and q.low == value), None)
        other = None if point is None else cls + (point - index) * self._strides[name]
        return other is not None and bool(self.valid[other]) and all(
            self.evaluate(g)[cls] == self.evaluate(g)[other] for g in self._guards)

    def _value_text(self, cls: int, name: str, value: Fraction) -> str:
        """``d = 10`` for a value a run can take with the class's guards; else the piece and the value
        approached (:meth:`attains`)."""
        if self.attains(cls, name, value):
            return f"{name} = {_num(value)}"
        return f"{self.piece(cls, name).describe(name)}, tending to {_num(value)}"
