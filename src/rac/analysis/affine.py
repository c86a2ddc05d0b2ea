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
from rac.analysis.inputs import InputSpace, Piece

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
    ends: tuple[int, ...]  # indices of enabled end clauses
    box: tuple[tuple[str, Piece], ...]  # pieces of the inputs the arithmetic reads
    edge_map: Affine
    end_map: Affine  # applied after the edge when the run ends here


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
    """Distinct outcomes per location, over the classes allowed by ``assume``."""
    relevant = arithmetic_inputs(automaton)
    rewards = automaton.rewards
    end_enabled = [space.evaluate(c.guard) for c in automaton.end_clauses]
    valid = space.valid
    result: list[list[Outcome]] = []
    for index, edges in enumerate(automaton.edges):
        enabled = [space.evaluate(e.guard) for e in edges]
        seen: dict[tuple, Outcome] = {}
        for cls in map(int, valid.nonzero()[0]):
            taken = next((e for e, mask in zip(edges, enabled) if mask[cls]), None)
            ends = tuple(i for i, mask in enumerate(end_enabled) if mask[cls])
            box = tuple((name, space.piece(cls, name)) for name in relevant)
            key = (id(taken), ends, box)
            if key in seen:
                continue
            edge_map = from_assignments(taken.updates, rewards) if taken else identity(len(rewards))
            end_map = identity(len(rewards))
            for i in ends:
                end_map = then(end_map, from_assignments(automaton.end_clauses[i].updates, rewards))
            seen[key] = Outcome(index, cls, taken, taken.target if taken else index, ends, box,
                                edge_map, end_map)
        result.append(list(seen.values()))
    return result


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
