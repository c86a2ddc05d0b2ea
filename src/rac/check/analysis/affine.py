"""Affine maps on reward vectors, and the per-location outcomes of one sample.

Everything that can happen at one sample is an affine map of the reward
vector whose offset may depend linearly on numeric inputs: an edge's updates,
the ``at end`` updates, and the accrual ``r += period·rate`` of a location.
An *outcome* groups the input classes that behave identically in a location
(same edge, same end clauses, same pieces of the inputs the arithmetic reads).
"""

from __future__ import annotations

from collections.abc import Collection, Sequence
from dataclasses import dataclass
from fractions import Fraction

import numpy as np

from rac import ir
from rac.check.analysis.behaviour import distances
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


def stored_prefixes(assignments: Sequence[ir.Assignment], rewards: tuple[str, ...],
                    weights: Sequence[Fraction]) -> tuple[tuple[int, Affine], ...]:
    """The values a sequence of assignments leaves *inside* it: ``(i, map after its first i
    assignments)`` for each ``i`` short of the whole sequence (the whole one is the edge's, or the
    end's, own instant), where assignment ``i`` sets a reward that ``weights`` weighs, or is the first
    (any other leaves ``weights·r`` as the previous prefix did; the first one's value is the one in
    between, which the value before the sequence need not stand for: it may be watched elsewhere).
    UPPAAL runs an edge's assignments in order and stores each one in the reward's 32-bit mirror, so
    the int32 range check must bound these too."""
    index = {r: i for i, r in enumerate(rewards)}
    return tuple((i, from_assignments(tuple(assignments[:i]), rewards))
                 for i in range(1, len(assignments)) if i == 1 or weights[index[assignments[i - 1].reward]])


def end_assignments(automaton: ir.Automaton, ends: Sequence[int]) -> tuple[ir.Assignment, ...]:
    """The assignments the ``at end`` clauses ``ends`` (indices, enabled ones) run, in order: one
    sequence, as the UPPAAL model's ``finish?`` edge runs it (a disabled clause's assignments keep
    their values)."""
    return tuple(u for i in ends for u in automaton.end_clauses[i].updates)


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
    #: The truth of each guard of the ``split`` the outcomes were grouped by (:func:`outcomes`), in order.
    flags: tuple[bool, ...] = ()
    #: ``episode ends when`` holds (declared and true for this outcome's inputs): the run ends at this
    #: sample, so no run continues from it (:func:`outcomes` always tells these apart).
    ends_episode: bool = False
    #: With :attr:`ends_episode`: how the run ends here, the ``at end`` clauses whose guards hold on
    #: this outcome's own inputs (:func:`outcomes` tells them apart), as one map over those same inputs
    #: (its class and box are the outcome's). None when the run does not end here.
    ending: EndOutcome | None = None


@dataclass(frozen=True)
class EndOutcome:
    """What one group of input classes does when a run ends (``at end`` clauses).

    A run may end right after any sample (or before the first), and ``end(inputs)`` takes
    inputs of its own, so the end's inputs range over every valuation ``assume`` allows
    (:attr:`Moves.ends`). A sample where ``episode ends when`` holds is different: the run ends
    there, its clauses read that sample's inputs (:attr:`Outcome.ending`), and no ``end`` follows.
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


def outcomes(automaton: ir.Automaton, space: InputSpace,
             reachable: Collection[int] | None = None, split: Sequence[ir.Guard] = ()) -> list[list[Outcome]]:
    """Distinct outcomes of a sample per location, over the classes allowed by ``assume``.

    Locations outside ``reachable`` (when given) get none: no run is ever there. Within a location
    the outcomes come in the order of their first class; each one's representative class is the one
    that leaves the most numeric inputs as intervals (the first such), as witnesses read better so.
    ``split``: guards whose truth also tells outcomes apart (``episode ends when``, ``goal when``, the
    ``at end`` clauses of a sample that ends the run); each outcome's :attr:`Outcome.flags` holds it.
    ``episode ends when`` always tells them apart (:attr:`Outcome.ends_episode`), and so does, among
    the classes where it holds, each ``at end`` guard: the clauses applied when the run ends there
    read that sample's inputs (:attr:`Outcome.ending`).
    """
    groups = _Grouping(automaton, space)
    rewards = automaton.rewards
    ends = automaton.ending
    grouping = list(split)
    if ends is not None and ends not in grouping:
        grouping.append(ends)
    ends_at = grouping.index(ends) if ends is not None else -1
    bits = np.zeros(groups.size, dtype=np.int64)  # the guards' truths, the first guard the highest bit
    for guard in grouping:
        bits = bits * 2 + space.evaluate(guard)[groups.classes]
    clauses = automaton.end_clauses if ends is not None else ()
    if ends is not None and clauses:
        # Where the run ends at the sample, which end clauses apply (on the same inputs); elsewhere
        # no end follows the sample, so the clauses' guards tell nothing apart.
        ending = space.evaluate(ends)[groups.classes]
        for clause in clauses:
            bits = bits * 2 + (space.evaluate(clause.guard)[groups.classes] & ending)
    width = len(grouping) + len(clauses)
    endings: dict[tuple[int, ...], Affine] = {}  # per set of enabled clauses: their map (shared)
    maps: dict[int, Affine] = {}  # per edge: its updates as one map (shared by the edge's outcomes)
    stay = identity(len(rewards))  # no edge fires: one map for all such outcomes (searches key on it)
    result: list[list[Outcome]] = []
    for index, edges in enumerate(automaton.edges):
        if reachable is not None and index not in reachable:
            result.append([])
            continue
        taken = np.full(groups.size, len(edges), dtype=np.int64)  # len(edges): no edge fires
        for k in range(len(edges) - 1, -1, -1):  # the first enabled edge wins (the last write)
            taken[space.evaluate(edges[k].guard)[groups.classes]] = k
        found = []
        for label, cls in groups.representatives(taken * (1 << width) + bits, (len(edges) + 1) << width):
            k = label >> width
            edge = edges[k] if k < len(edges) else None
            if edge is None:
                edge_map = stay
            else:
                edge_map = maps.get(id(edge)) or maps.setdefault(id(edge), from_assignments(edge.updates, rewards))
            truths = tuple(bool(label >> (width - 1 - j) & 1) for j in range(width))
            box = groups.box(cls)
            end = None
            if ends_at >= 0 and truths[ends_at]:
                enabled = tuple(i for i, on in enumerate(truths[len(grouping):]) if on)
                end_map = endings.get(enabled)
                if end_map is None:
                    end_map = endings[enabled] = _end_map(automaton, enabled)
                end = EndOutcome(cls, enabled, box, end_map)
            found.append(Outcome(index, cls, edge, edge.target if edge else index, box, edge_map,
                                 truths[:len(split)], end is not None, end))
        result.append(found)
    return result


class _Grouping:
    """Groups the classes allowed by ``assume`` by a per-class label and the pieces the arithmetic reads.

    Vectorised (a file with hundreds of locations and ~10^5 classes would otherwise spend minutes in a
    Python loop per location and class); it picks the same representatives, in the same order, as
    going through the classes one by one would.
    """

    def __init__(self, automaton: ir.Automaton, space: InputSpace) -> None:
        self.space = space
        self.relevant = arithmetic_inputs(automaton)
        self.classes = np.flatnonzero(space.valid)
        self.size = len(self.classes)
        columns = [space.columns[name][self.classes].astype(np.int64) for name in self.relevant]
        if columns:
            _, self.boxes = np.unique(np.stack(columns, axis=1), axis=0, return_inverse=True)
            self.boxes = self.boxes.reshape(-1)
        else:
            self.boxes = np.zeros(self.size, dtype=np.int64)
        self.box_count = int(self.boxes.max()) + 1 if self.size else 1
        intervals = np.zeros(self.size, dtype=np.int64)
        for item in space.numerics:
            is_interval = np.array([not p.is_point for p in space.pieces[item.name]], dtype=bool)
            intervals += is_interval[space.columns[item.name][self.classes]]
        # Preference among the classes of one group: more intervals first, then the earlier class.
        self.by_preference = np.lexsort((-np.arange(self.size), intervals))  # least preferred first
        self.rank = np.empty(self.size, dtype=np.int64)
        self.rank[self.by_preference] = np.arange(self.size)

    def representatives(self, labels: np.ndarray, label_count: int) -> list[tuple[int, int]]:
        """(label, representative class) per group of equal (label, box), in the order of first classes."""
        keys = labels * self.box_count + self.boxes
        if label_count * self.box_count > 4 * self.size + 1024:  # sparse keys: number them densely first
            _, keys = np.unique(keys, return_inverse=True)
            keys = keys.reshape(-1)
        span = int(keys.max()) + 1 if self.size else 0
        first = np.full(span, self.size, dtype=np.int64)
        np.minimum.at(first, keys, np.arange(self.size))
        best = np.full(span, -1, dtype=np.int64)
        np.maximum.at(best, keys, self.rank)
        present = np.flatnonzero(first < self.size)
        present = present[np.argsort(first[present])]
        chosen = self.by_preference[best[present]]
        return [(int(labels[i]), int(self.classes[i])) for i in chosen]

    def box(self, cls: int) -> tuple[tuple[str, Piece], ...]:
        return tuple((name, self.space.piece(cls, name)) for name in self.relevant)


def end_outcomes(automaton: ir.Automaton, space: InputSpace) -> list[EndOutcome]:
    """Distinct ways a run can end, over the classes allowed by ``assume``."""
    groups = _Grouping(automaton, space)
    enabled = [space.evaluate(c.guard)[groups.classes] for c in automaton.end_clauses]
    # Each class's set of enabled clauses, numbered densely in the order of first classes.
    if enabled:
        _, labels = np.unique(np.stack(enabled, axis=1), axis=0, return_inverse=True)
        labels = labels.reshape(-1)
    else:
        labels = np.zeros(groups.size, dtype=np.int64)
    result = []
    for _, cls in groups.representatives(labels, int(labels.max()) + 1 if groups.size else 1):
        ends = tuple(i for i, clause in enumerate(automaton.end_clauses) if space.evaluate(clause.guard)[cls])
        result.append(EndOutcome(cls, ends, groups.box(cls), _end_map(automaton, ends)))
    return result


def _end_map(automaton: ir.Automaton, enabled: tuple[int, ...]) -> Affine:
    """The ``at end`` clauses ``enabled`` (indices), applied in order, as one map."""
    end_map = identity(len(automaton.rewards))
    for i in enabled:
        end_map = then(end_map, from_assignments(automaton.end_clauses[i].updates, automaton.rewards))
    return end_map


@dataclass(frozen=True)
class Moves:
    """Everything a run can do: per location the outcomes of a sample, and the ways to end."""

    samples: tuple[tuple[Outcome, ...], ...]
    ends: tuple[EndOutcome, ...]
    #: The guards the sample outcomes were also told apart by (their :attr:`Outcome.flags`).
    split: tuple[ir.Guard, ...] = ()

    @property
    def translations_only(self) -> bool:
        return (all(o.edge_map.is_translation and (o.ending is None or o.ending.end_map.is_translation)
                    for os in self.samples for o in os)
                and all(e.end_map.is_translation for e in self.ends))


def moves(automaton: ir.Automaton, space: InputSpace, split: Sequence[ir.Guard] = ()) -> Moves:
    """Sample outcomes and end outcomes of an automaton over its input classes (sample outcomes also
    told apart by the truth of each guard of ``split``, see :func:`outcomes`).

    Locations no run can reach have no outcomes (no analysis of runs looks at them).
    """
    reachable = distances(automaton, space)
    return Moves(tuple(tuple(os) for os in outcomes(automaton, space, reachable, split)),
                 tuple(end_outcomes(automaton, space)), tuple(split))


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


def sup_weighted(w: tuple[Fraction, ...], maps: Collection[Affine],
                 box: tuple[tuple[str, Piece], ...], factors: Sequence[Fraction] | None = None
                 ) -> tuple[Fraction, dict[str, Fraction]]:
    """Supremum of ``w·(sum of the maps' offsets)`` over the closure of ``box``, and a point attaining
    it (translations only: what a sample adds to a weighted sum of the rewards). ``factors``: one per
    map, each map's offsets weighed by it (a discount: a sample's edge and the accrual after it read the
    same inputs but count in different steps)."""
    const = ZERO
    form: dict[str, Fraction] = {}
    for i, affine in enumerate(maps):
        for k, offset in enumerate(affine.offset):
            if w[k]:
                weight = w[k] if factors is None else factors[i] * w[k]
                const += weight * offset.const
                for name, coefficient in offset.terms:
                    form[name] = form.get(name, ZERO) + weight * coefficient
    bonus, point = sup_linear(form, box)
    return const + bonus, point
