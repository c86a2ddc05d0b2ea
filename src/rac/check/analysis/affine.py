"""Affine maps on reward vectors, and the per-location outcomes of one sample.

Everything that can happen at one sample is an affine map of the reward
vector whose offset may depend linearly on numeric inputs: an edge's updates,
the ``at end`` updates, and the accrual ``r += period·rate`` of a location.
An *outcome* groups the input classes that behave identically in a location
(same edge, same end clauses, same pieces of the inputs the arithmetic reads).
"""

from __future__ import annotations

from dataclasses import dataclass
from fractions import Fraction

from rac import ir
from rac.ir.inputs import InputSpace, Piece

ZERO = Fraction(0)


@dataclass(frozen=True)
class Affine:
    """``r' = M r + offset(x)``; ``matrix is None`` means the identity."""

    matrix: tuple[tuple[Fraction, ...], ...] | None
    offset: tuple[ir.Linear, ...]  # per reward, linear in numeric inputs

    @property
    def is_translation(self) -> bool:
        return self.matrix is None


def identity(size: int) -> Affine:
    return Affine(None, tuple(ir.Linear() for _ in range(size)))


def from_assignments(assignments: tuple[ir.Assignment, ...], rewards: tuple[str, ...]) -> Affine:
    """Compose sequential assignments (each sees the values left by the previous ones)."""
    current = [ir.Linear.variable(r) for r in rewards]  # over original rewards + inputs
    index = {r: i for i, r in enumerate(rewards)}
    for assignment in assignments:
        value = ir.Linear(assignment.value.const)
        for name, coefficient in assignment.value.terms:
            term = current[index[name]] if name in index else ir.Linear.variable(name)
            value = value + term.scaled(coefficient)
        current[index[assignment.reward]] = value
    matrix = tuple(tuple(current[k].coefficient(r) for r in rewards) for k in range(len(rewards)))
    offsets = tuple(ir.Linear(c.const, tuple((n, v) for n, v in c.terms if n not in index)) for c in current)
    is_identity = all(matrix[k][j] == (1 if k == j else 0) for k in range(len(rewards)) for j in range(len(rewards)))
    return Affine(None if is_identity else matrix, offsets)


def accrual(location: ir.Location, period: Fraction) -> Affine:
    return Affine(None, tuple(rate.scaled(period) for rate in location.rates))


def then(first: Affine, second: Affine) -> Affine:
    """The map ``second ∘ first`` (apply ``first``, then ``second``)."""
    size = len(first.offset)
    if second.matrix is None:
        offset = tuple(a + b for a, b in zip(first.offset, second.offset))
        return Affine(first.matrix, offset)
    m2 = second.matrix
    offset = tuple(
        sum((first.offset[j].scaled(m2[k][j]) for j in range(size)), ir.Linear()) + second.offset[k]
        for k in range(size))
    if first.matrix is None:
        return Affine(m2, offset)
    m1 = first.matrix
    matrix = tuple(tuple(sum((m2[k][j] * m1[j][i] for j in range(size)), ZERO) for i in range(size))
                   for k in range(size))
    return Affine(matrix, offset)


@dataclass(frozen=True)
class Outcome:
    """What one group of input classes does in one location at a sample."""

    source: int
    cls: int  # a representative class (for witnesses)
    edge: ir.Edge | None
    target: int
    box: tuple[tuple[str, Piece], ...]  # pieces of the inputs the arithmetic reads
    edge_map: Affine


@dataclass(frozen=True)
class EndOutcome:
    """What one group of input classes does when a run ends (``at end`` clauses).

    A run may end right after any sample (or before the first), and ``end(inputs)`` takes
    inputs of its own, so the end's inputs range over every valuation ``assume`` allows.
    """

    cls: int
    ends: tuple[int, ...]  # indices of enabled end clauses, applied in order
    box: tuple[tuple[str, Piece], ...]
    end_map: Affine


def arithmetic_inputs(automaton: ir.Automaton) -> tuple[str, ...]:
    """Numeric inputs that rates or updates read (their values, not only their pieces, matter)."""
    names: set[str] = set()
    for location in automaton.locations:
        for rate in location.rates:
            names.update(rate.variables())
    updates = [u for e in automaton.all_edges() for u in e.updates]
    updates += [u for c in automaton.end_clauses for u in c.updates]
    rewards = set(automaton.rewards)
    for update in updates:
        names.update(n for n in update.value.variables() if n not in rewards)
    return tuple(i.name for i in automaton.numeric_inputs if i.name in names)


def outcomes(automaton: ir.Automaton, space: InputSpace) -> list[list[Outcome]]:
    """Distinct outcomes of a sample per location, over the classes allowed by ``assume``."""
    relevant = arithmetic_inputs(automaton)
    rewards = automaton.rewards
    valid = space.valid
    result: list[list[Outcome]] = []
    for index, edges in enumerate(automaton.edges):
        enabled = [space.evaluate(e.guard) for e in edges]
        seen: dict[tuple, Outcome] = {}
        for cls in map(int, valid.nonzero()[0]):
            taken = next((e for e, mask in zip(edges, enabled) if mask[cls]), None)
            box = tuple((name, space.piece(cls, name)) for name in relevant)
            key = (id(taken), box)
            if key in seen and _intervals(space, seen[key].cls) >= _intervals(space, cls):
                continue
            edge_map = from_assignments(taken.updates, rewards) if taken else identity(len(rewards))
            seen[key] = Outcome(index, cls, taken, taken.target if taken else index, box, edge_map)
        result.append(list(seen.values()))
    return result


def _intervals(space: InputSpace, cls: int) -> int:
    """How many numeric inputs a class leaves as intervals: such witnesses read better than points."""
    return sum(not space.piece(cls, item.name).is_point for item in space.numerics)


def end_outcomes(automaton: ir.Automaton, space: InputSpace) -> list[EndOutcome]:
    """Distinct ways a run can end, over the classes allowed by ``assume``."""
    relevant = arithmetic_inputs(automaton)
    rewards = automaton.rewards
    enabled = [space.evaluate(c.guard) for c in automaton.end_clauses]
    seen: dict[tuple, EndOutcome] = {}
    for cls in map(int, space.valid.nonzero()[0]):
        ends = tuple(i for i, mask in enumerate(enabled) if mask[cls])
        box = tuple((name, space.piece(cls, name)) for name in relevant)
        if (ends, box) in seen and _intervals(space, seen[(ends, box)].cls) >= _intervals(space, cls):
            continue
        end_map = identity(len(rewards))
        for i in ends:
            end_map = then(end_map, from_assignments(automaton.end_clauses[i].updates, rewards))
        seen[(ends, box)] = EndOutcome(cls, ends, box, end_map)
    return list(seen.values())


@dataclass(frozen=True)
class Moves:
    """Everything a run can do: per location the outcomes of a sample, and the ways to end."""

    samples: tuple[tuple[Outcome, ...], ...]
    ends: tuple[EndOutcome, ...]

    @property
    def translations_only(self) -> bool:
        return (all(o.edge_map.is_translation for os in self.samples for o in os)
                and all(e.end_map.is_translation for e in self.ends))


def moves(automaton: ir.Automaton, space: InputSpace) -> Moves:
    """Sample outcomes and end outcomes of an automaton over its input classes."""
    return Moves(tuple(tuple(os) for os in outcomes(automaton, space)), tuple(end_outcomes(automaton, space)))


def sup_linear(form: dict[str, Fraction], box: tuple[tuple[str, Piece], ...]) -> tuple[Fraction, dict[str, Fraction]]:
    """Supremum of ``Σ g_i·x_i`` over the closure of a box, and a point attaining it."""
    total = ZERO
    point: dict[str, Fraction] = {}
    for name, piece in box:
        g = form.get(name, ZERO)
        value = piece.high if g > 0 else piece.low
        point[name] = value
        total += g * value
    return total, point
