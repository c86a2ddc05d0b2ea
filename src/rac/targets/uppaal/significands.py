"""Numbers of the UPPAAL target as significands, and E0801 when one does not fit.

A real value ``v`` is held in an ``int32`` as its significand ``v * base**exponent`` (base 10,
exponent 4, or the ``model`` block's). :class:`Significands` owns that representation for one
emitted model: the value the Environment chooses for each piece of a numeric input's range
(:class:`NumericInput`), what each integer mirror gains per sample in each location (an
:data:`Accrual`), and the E0801 diagnostic, with its notes and hints, for every number that has no
significand — an input's bound or compared value, a rate times the period, or (reported through
:meth:`Significands.unrepresentable` by the other modules) a threshold or an update.
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from dataclasses import dataclass
from fractions import Fraction

from rac import ir
from rac.core.diagnostics import Diagnostic
from rac.ir import expr as ie
from rac.ir import query as iq
from rac.ir.significands import bound_diagnostic, input_extremes, rate_diagnostic, unrepresentable
from rac.ir.significands import decimal_text as _decimal
from rac.ir.vocabulary import DEFAULT_BASE, DEFAULT_EXPONENT
from rac.runtime.semantics import mirror_accrual
from rac.targets.uppaal.expr import int_literal
from rac.targets.uppaal.names import Names

__all__ = ["Accrual", "NumericInput", "Significands"]

#: What a reward's mirror gains per sample in one location: a constant and ``(coefficient,
#: significand name)`` terms, in significand units (``None`` where it is not representable).
Accrual = tuple[Fraction, list[tuple[Fraction, str]]]


@dataclass
class NumericInput:
    """A numeric input as the emitted model declares it: its UPPAAL name, bounds (as text) and the
    array of significands the Environment chooses from, one per piece of its range."""

    source: str
    name: str
    low: str
    high: str
    array: str
    values: list[int]
    pieces: str
    select: str

    @property
    def count(self) -> int:
        """How many values the Environment chooses from."""
        return len(self.values)

    @property
    def initializer(self) -> str:
        """The value array's initialiser, ``{v0, v1, ...}``."""
        return "{" + ", ".join(int_literal(v) for v in self.values) + "}"


class Significands:
    """The number representation of one emitted model of ``automaton``; the E0801 diagnostics of the
    numbers it cannot hold are appended to ``diagnostics``."""

    def __init__(self, automaton: ir.Automaton, diagnostics: list[Diagnostic]):
        self.a = automaton
        model = automaton.model
        self.base = model.base if model is not None else DEFAULT_BASE
        self.exponent = model.exponent if model is not None else DEFAULT_EXPONENT
        self.scale = self.base ** self.exponent
        self.diagnostics = diagnostics

    # ------------------------------------------------------------ diagnostics
    def span(self, span):
        """Where a diagnostic points: ``span``, else the automaton's name."""
        if span is not None:
            return span
        return self.a.source.name.span if self.a.source is not None else None

    def unrepresentable(self, message: str, span, notes: Iterable[str] = (), hints: Iterable[str] | None = None):
        """Report E0801 at ``span``; without ``hints``, the hint to enlarge the exponent or round the number."""
        self.diagnostics.append(unrepresentable(self.a, message, self.span(span), notes, hints))

    # ------------------------------------------------------------ inputs
    def inputs(self, names: Names, arrays: dict[str, str], selects: dict[str, str],
               chosen: bool = True) -> list[NumericInput]:
        """The numeric inputs with the significands the Environment chooses from (``arrays`` and
        ``selects``: the names of each input's value array and select variable). ``chosen=False``:
        no Environment chooses them (the whole model's Controller computes them from the bindings),
        so they have no values, and no piece of their ranges needs a significand."""
        # Imported here: InputSpace needs numpy, which `import rac.targets.uppaal.automaton` does not load.
        from rac.ir.inputs import InputSpace, all_guards, pieces_of

        space = InputSpace(self.a)
        queried = self._query_thresholds()
        result = []
        for item in self.a.numeric_inputs:
            values: list[int] = []
            pieces = space.pieces[item.name]
            grid = self._grid(item.name)
            for piece in pieces if chosen else ():
                value = self._representative(item, piece, grid)
                if value is None:
                    break  # one diagnostic per input: its first unrepresentable piece
                values.append(value)
            else:
                if chosen and queried.get(item.name):
                    # A query that compares the input with a number of its own tells apart values that
                    # no guard does (`E<> n == 7`): the Environment offers a value on each side of it too.
                    # A piece between such cuts without a significand holds no value the model could give.
                    guards = {leaf.threshold for guard in all_guards(self.a) for leaf in ir.guard_leaves(guard)
                              if isinstance(leaf, ir.BAtom) and leaf.input == item.name}
                    pieces = [p for p in pieces_of(item, guards | queried[item.name])
                              if p.is_point or self._representative(item, p, grid, report=False) is not None]
                    values = [v for p in pieces if (v := self._representative(item, p, grid)) is not None]
            problem = bound_diagnostic(self.a, item)
            if problem is not None:
                self.diagnostics.append(problem)
            result.append(NumericInput(
                item.name, names[item.name], _decimal(item.low), _decimal(item.high),  # type: ignore[arg-type]
                arrays[item.name], values,
                ", ".join(p.describe(item.name) for p in pieces), selects[item.name]))
        return result

    def _query_thresholds(self) -> dict[str, set[Fraction]]:
        """Per numeric input, the numbers the file's queries compare it with alone (`d < 2`, `2 * d + 1 >= 3`),
        as the significands the emitted comparison tells apart: a number without a whole significand
        is compared on the integers around it (docs/uppaal.md, "Queries"), so both of them."""
        kinds = {item.name: item.kind for item in self.a.numeric_inputs}
        found: dict[str, set[Fraction]] = {}
        for decl in self.a.queries:
            for expr in iq.query_exprs(decl.query):
                for node in ie.walk(expr):
                    if not isinstance(node, ie.Compare) or node.linear is None or len(node.linear.terms) != 1:
                        continue
                    ((ref, coefficient),) = node.linear.terms
                    if ref.kind is not ie.RefKind.INPUT or ref.name not in kinds:
                        continue
                    threshold = -node.linear.const / coefficient
                    if kinds[ref.name] == "int":
                        cuts = {threshold}
                    else:
                        scaled = threshold * self.scale
                        cuts = {Fraction(math.floor(scaled), self.scale), Fraction(math.ceil(scaled), self.scale)}
                    found.setdefault(ref.name, set()).update(cuts)
        return found

    def _grid(self, name: str) -> int:
        """The least whole number whose multiples, as the significand of input ``name``, make every
        rate that reads it gain whole significand units per sample (``coefficient * period *
        significand`` whole): the values the Environment prefers inside an open piece."""
        period = Fraction(self.a.period)
        return math.lcm(1, *((coef * period).denominator for location in self.a.locations
                             for rate in location.rates for term, coef in rate.terms if term == name))

    def _representative(self, item: ir.Input, piece, grid: int = 1, report: bool = True) -> int | None:
        """The significand the Environment chooses for one piece of a numeric input's range: inside an
        open piece the one nearest its middle, on ``grid`` (:meth:`_grid`) where the piece holds such a
        value, so that the rates reading the input stay whole (any value of the piece is as good for
        the guards: they cannot tell its values apart). None where it has none (E0801 unless not
        ``report``)."""
        scale = self.scale
        if item.kind == "int" and not piece.is_point:
            return self._whole_representative(piece, grid)
        if piece.is_point:
            value = piece.representative(item.kind == "int") * scale
            if value.denominator == 1:
                return value.numerator
            self.unrepresentable(
                f"input `{item.name}` compares with {_decimal(piece.low)}, which is not representable as a "
                f"significand at base {self.base}, exponent {self.exponent}", item.span,
                notes=[f"{_decimal(piece.low)} * {scale} = {_decimal(value)} is not an integer, "
                       "so the model cannot give the input that value"])
            return None
        low = math.floor(piece.low * scale) + 1
        high = math.ceil(piece.high * scale) - 1
        if low > high and not report:
            return None
        if low > high:
            self.unrepresentable(
                f"input `{item.name}` has no representable value in ({_decimal(piece.low)}, {_decimal(piece.high)}) "
                f"at base {self.base}, exponent {self.exponent}", item.span,
                notes=["the interval between two thresholds of its guards is narrower than one significand unit "
                       f"(1/{scale})"])
            return None
        middle = (piece.low + piece.high) / 2 * scale
        on_grid = min(max(round(middle / grid) * grid, math.ceil(Fraction(low, grid)) * grid),
                      math.floor(Fraction(high, grid)) * grid)
        if low <= on_grid <= high:
            return on_grid
        return min(max(round(middle), low), high)

    def _whole_representative(self, piece, grid: int) -> int:
        """The significand the Environment chooses for a run of integers ``[low, high]`` of an ``int``
        input: its least integer, or, where that is off ``grid`` (:meth:`_grid`), the least integer of
        the run whose significand is on it (``n / 3`` at 1 s gains ``n * 10000 / 3`` units, whole for
        multiples of 3), else the least integer (the rate is then refused: E0801)."""
        low, high = int(piece.low), int(piece.high)
        step = grid // math.gcd(grid, self.scale)  # the integers whose significand is a multiple of grid
        first = -(-low // step) * step
        return (first if first <= high else low) * self.scale

    # ------------------------------------------------------------ rates
    def accruals(self, inputs: list[NumericInput], names: Names) -> list[list[Accrual | None]]:
        """Per location and reward: (constant, [(coefficient, significand)]) that the mirror gains per sample."""
        period = Fraction(self.a.period)
        values = {i.source: i.values for i in inputs}
        # the bounds, where no Environment chooses the values (the whole model): the accrual's products
        # p*input must stay within int32 over the input's range there too (as `rac check` checks them)
        extremes = input_extremes(self.a)
        result: list[list[Accrual | None]] = []
        for location in self.a.locations:
            row: list[Accrual | None] = []
            for reward, rate in zip(self.a.rewards, location.rates):
                problem = rate_diagnostic(self.a, location, reward, rate, values, extremes)
                if problem is not None:
                    self.diagnostics.append(problem)
                    row.append(None)
                    continue
                const, terms = mirror_accrual(rate, period, self.scale)
                row.append((const, [(c, names[name]) for c, name in terms]))
            result.append(row)
        return result

