"""Synthesis of several weights of the objective (``param w1, w2 in [1, 100]`` with
``objective w1 * sa + w2 * pr + co``): the exact set of weights for which every check holds, a
polyhedron, by cutting planes (docs/checks.md, "Parameters").

The parameters may appear only in the objective, affinely (:mod:`rac.check.params` proves the
latter), so the runs and the reward values along them do not depend on them. Each check is then a
maximum over finitely many runs of a function affine in the weights:

- P2 at a level holds at weights θ when ``max over runs r of J_r(θ) <= 0``, where ``J_r(θ)`` is the
  weighted sum at the run's violating instant, linear in θ once the run's reward values are known;
- P1 holds when each weight stays on the side of 0 where a rate conflict does no harm, a linear
  inequality by itself.

With a discount (``rac check --discount``), P2 of the discounted return adds the inequalities of its worst runs:
a run's discounted value is ``Σ_r coefficient_r(θ)·D_r`` (+ the constant), ``D_r`` the discounted sum of reward
r's changes along it, linear in θ as well.

The set is therefore the polyhedron ``{θ in the box : J_r(θ) <= 0 for every run r}``. It is found
by cutting planes: the lexicographically least point of the current outer polytope (the box and the
cuts so far) is the candidate, the exact worst-run oracle finds the most violating run there, its
inequality ``J_r(θ) <= 0`` is added, and so on until the oracle finds no violation. Then every vertex
of the outer polytope is checked the same way: when none violates, the outer polytope is the set
itself, since the set is convex (an intersection of half-spaces) and holds every vertex. Each cut
comes from a run whose inequality the current polytope did not yet imply, and there are finitely
many distinct reward vectors at violating instants (finitely many runs), so the search terminates.

The linear programs involved (the lexicographic minimum, redundancy of a cut, the least integer
point) are over a polytope of a few parameters and a few dozen rows, and are solved exactly by
enumerating its vertices in rational arithmetic. sympy's simplex (``sympy.solvers.simplex``,
1.14) was the first choice; on small degenerate systems like these (repeated rows, cuts through a
vertex) it returned infeasible points as optima and cycled (14 and 1 of 600 random cases for
``linprog``, 1 wrong for ``lpmin``), which an exact answer cannot afford. sympy puts each
inequality in least integer terms (``Poly.primitive``).
"""

from __future__ import annotations

import dataclasses
import itertools
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from fractions import Fraction

from rac import ir
from rac.check.analysis.affine import moves
from rac.check.analysis.behaviour import input_space
from rac.check.analysis.discount import Discount, discounted_value, discounted_worst
from rac.check.analysis.priority import p2_levels, p2_target, rate_conflicts, replay
from rac.check.analysis.worst import Target, Unfinished, maximise
from rac.core.diagnostics import RacError, short_number

Vector = tuple[Fraction, ...]
#: The automaton resolved with the parameters at a point (None when it does not resolve).
ResolveAt = Callable[[Vector], "ir.Automaton | None"]
#: The most vertices the exactness proof enumerates (constraint subsets of the parameters' size).
MAX_SUBSETS = 200_000


@dataclass(frozen=True)
class Inequality:
    """``coefficients · θ <= bound`` over the parameters, in declaration order."""

    coefficients: Vector
    bound: Fraction

    def slack(self, point: Sequence[Fraction]) -> Fraction:
        """``bound - coefficients · point``: negative where the point violates it."""
        return self.bound - sum((a * x for a, x in zip(self.coefficients, point)), Fraction(0))


@dataclass(frozen=True)
class Region:
    """The weights for which every check holds: ``inequalities`` within the declared box (empty when
    ``point`` is None), its ``vertices``, and the point the file is checked with."""

    parameters: tuple[ir.Parameter, ...]
    inequalities: tuple[Inequality, ...]
    vertices: tuple[Vector, ...]
    #: The lexicographically least integer point (highest priority first), else the least point.
    point: Vector | None
    integer: bool
    #: Parameter indices, highest priority first (the order of the lexicographic minimum).
    order: tuple[int, ...]
    #: Each cut, as a sentence.
    cuts: tuple[str, ...]
    #: When empty: the point whose checks show why (the last candidate).
    witness: Vector

    @property
    def empty(self) -> bool:
        return self.point is None

    def describe(self) -> list[str]:
        """The inequalities, each in least integer terms with its leading parameter alone on one side; two
        opposite ones (``v <= 0`` and ``v >= 0``) as one equation (``v == 0``), and a set of one point as
        the parameters' values (``u == 0``, ``v == 0``)."""
        names = [p.name for p in self.parameters]
        if self.inequalities and len(self.vertices) == 1:
            (point,) = self.vertices
            units = [Inequality(tuple(Fraction(j == i) for j in range(len(point))), point[i]) for i in self.order]
            return [_describe(unit, names, self.order, equation=True) for unit in units]
        shown: list[str] = []
        paired: set[int] = set()
        for k, q in enumerate(self.inequalities):
            if k in paired:
                continue
            opposite = next((j for j in range(k + 1, len(self.inequalities))
                             if j not in paired and _opposite(q, self.inequalities[j])), None)
            if opposite is not None:
                paired.add(opposite)
            shown.append(_describe(q, names, self.order, equation=opposite is not None))
        return shown


class Unsupported(RacError):
    """A parameter is somewhere the polyhedron would not be exact: ``name`` and ``where``."""

    def __init__(self, name: str, where: str) -> None:
        super().__init__(f"`{name}` appears in {where}")
        self.name, self.where = name, where


@dataclass(frozen=True)
class Weights:
    """The objective's coefficients (per reward) and constant, each affine in the parameters:
    ``(value at θ = 0, gradient)``."""

    rewards: tuple[tuple[Fraction, Vector], ...]
    constant: tuple[Fraction, Vector]

    @staticmethod
    def measure(resolve: ResolveAt, origin: Vector) -> tuple[Weights, ir.Automaton]:
        """The affine forms, from the objective at ``origin`` and one unit along each parameter
        (exact: the parameters enter affinely). Raises :class:`Unsupported` when a parameter changes
        anything but the objective."""
        base = resolve(origin)
        assert base is not None
        size = len(origin)
        steps = []
        for i in range(size):
            point = tuple(x + (1 if j == i else 0) for j, x in enumerate(origin))
            moved = resolve(point)
            if moved is None:  # a weight of the objective alone resolves anywhere: this one sets more
                raise Unsupported(base.parameters[i].name, "a declaration the file does not check with at "
                                  f"{base.parameters[i].name} = {short_number(point[i])} (a bound, a constant)")
            if _without_objective(moved) != _without_objective(base):
                raise Unsupported(base.parameters[i].name, _where(base, moved))
            steps.append(moved.objective)
        forms = []
        for name in [*base.rewards, None]:
            at = base.objective.const if name is None else base.objective.coefficient(name)
            gradient = tuple((o.const if name is None else o.coefficient(name)) - at for o in steps)
            forms.append((at - sum((g * x for g, x in zip(gradient, origin)), Fraction(0)), gradient))
        return Weights(tuple(forms[:-1]), forms[-1]), base

    def at(self, point: Vector) -> tuple[tuple[Fraction, ...], Fraction]:
        """The coefficients and the constant at ``point``."""
        def value(form: tuple[Fraction, Vector]) -> Fraction:
            return form[0] + sum((g * x for g, x in zip(form[1], point)), Fraction(0))
        return tuple(value(f) for f in self.rewards), value(self.constant)


def _where(a: ir.Automaton, b: ir.Automaton) -> str:
    """What differs between two resolutions of the file besides the objective, in the user's words."""
    if a.locations != b.locations:
        return "a rate"
    if a.edges != b.edges:
        return "an edge (its guard or its updates)"
    if a.end_clauses != b.end_clauses:
        return "an `at end` clause"
    if (a.inputs, a.assumptions) != (b.inputs, b.assumptions):
        return "an input bound or `assume`"
    if a.model != b.model:
        return "the `model` block"
    return "the timing (`sample every` or `horizon`)"


def _without_objective(automaton: ir.Automaton) -> ir.Automaton:
    return dataclasses.replace(automaton, objective=ir.Linear.constant(Fraction(0)), constants=(), parameters=())


def synthesise_region(resolve: ResolveAt, parameters: tuple[ir.Parameter, ...],
                      discount: Discount | None = None) -> Region:
    """The exact polyhedron of parameter values for which P1 and P2 hold (see the module docstring), and P2 of
    the return discounted by ``discount`` when given (a run's discounted value is linear in the weights too).

    Raises :class:`Unsupported` (a parameter outside the objective) or :class:`Unfinished` (the
    worst-run search stopped at its limit, or the discounted one does not go).
    """
    lows = tuple(p.low for p in parameters)
    weights, base = Weights.measure(resolve, lows)
    order = _order(base, weights, len(parameters))
    names = [p.name for p in parameters]
    box = _box(parameters)
    sentences: list[str] = []
    cuts = _p1(base, weights, sentences)
    oracle = _Oracle(base, weights, names, discount)
    # Phase 1: the lexicographically least candidate, until the oracle finds no violation there.
    candidate = lows
    while True:
        found = _least(box + cuts, order)
        if found is None:
            return Region(parameters, (), (), None, False, order, tuple(sentences), candidate)
        candidate = found
        new = oracle.cuts(candidate, sentences)
        if not new:
            break
        # Each cut excludes the point it was found at; were it not so, the loop would not end.
        assert any(c.slack(candidate) < 0 for c in new), "a cut must exclude its candidate"
        cuts += new
    # Phase 2: every vertex of the outer polyhedron, until none violates: then it is the set.
    checked: set[Vector] = {candidate}  # the oracle found no violation there
    while True:
        vertices = _vertices(box + cuts, len(parameters))
        new = []
        for vertex in vertices:
            if vertex not in checked:
                checked.add(vertex)
                found_here = oracle.cuts(vertex, sentences)
                if found_here:
                    new += found_here
                    candidate = vertex  # a point whose checks fail, to show if nothing is left
        if not new:
            break
        cuts += new
        if _least(box + cuts, order) is None:
            return Region(parameters, (), (), None, False, order, tuple(sentences), candidate)
    kept = tuple(_irredundant(box, cuts))
    point = _least_integer(box + list(kept), order)
    integer = point is not None
    if point is None:
        point = _least(box + list(kept), order)
    assert point is not None, "the set has a vertex: it passed the vertex check"
    return Region(parameters, kept, tuple(sorted(vertices)), point, integer, order, tuple(sentences), point)


class _Oracle:
    """The exact worst-run search over the automaton with the weights at a point."""

    def __init__(self, automaton: ir.Automaton, weights: Weights, names: list[str],
                 discount: Discount | None = None) -> None:
        self.automaton, self.weights, self.names, self.discount = automaton, weights, names, discount
        space, _ = input_space(automaton)
        assert space is not None
        self.space, self.moves = space, moves(automaton, space)

    def cuts(self, point: Vector, sentences: list[str]) -> list[Inequality]:
        """An inequality from the worst run of every P2 level violated at ``point`` (of the plain return, and of
        the discounted one with a discount)."""
        found = self._cuts(point, sentences, None)
        return found + (self._cuts(point, sentences, self.discount) if self.discount is not None else [])

    def _cuts(self, point: Vector, sentences: list[str], discount: Discount | None) -> list[Inequality]:
        a = self.automaton
        coefficients, constant = self.weights.at(point)
        found = []
        for level in p2_levels(a):
            watched = p2_target(a, level).watched
            ranked = set(a.priority[level:])
            target = Target(tuple(c if r in ranked else Fraction(0) for r, c in zip(a.rewards, coefficients)),
                            constant if level == 0 else Fraction(0), watched)
            worst = (maximise(a, self.moves, target, run=lambda value: value > 0) if discount is None
                     else discounted_worst(a, self.moves, target, discount))
            if worst is None or worst.value <= 0:
                continue
            if discount is None:
                values, _ = replay(a, self.space, worst)  # the rewards at the violating instant
            else:  # each reward's discounted sum of changes up to it: the discounted value is linear in them
                units = [tuple(Fraction(j == k) for j in range(len(a.rewards))) for k in range(len(a.rewards))]
                values = [discounted_value(a, self.space, worst, Target(unit, Fraction(0), watched), discount)
                          for unit in units]
            # J(θ) = Σ over ranked rewards of coefficient_r(θ)·value_r (+ the constant at level 0) <= 0.
            row = [Fraction(0)] * len(point)
            bound = Fraction(0)
            for (at, gradient), reward, value in zip(self.weights.rewards, a.rewards, values):
                if reward in ranked:
                    bound -= at * value
                    row = [x + g * value for x, g in zip(row, gradient)]
            if level == 0:
                bound -= self.weights.constant[0]
                row = [x + g for x, g in zip(row, self.weights.constant[1])]
            cut = Inequality(tuple(row), bound)
            found.append(cut)
            where = ", ".join(f"{n} = {short_number(x)}" for n, x in zip(self.names, point))
            need = (f"needs {_describe(cut, self.names)}" if any(row)
                    else "fails whatever the parameters are (they do not weigh what it compares)")
            which = "P2" if discount is None else "P2 of the discounted return"
            sentences.append(f"at {where}, {which} for `{a.priority[level]}` {need}")
        return found


def _order(automaton: ir.Automaton, weights: Weights, size: int) -> tuple[int, ...]:
    """Parameter indices by the priority of the reward they weight, highest first; then the rest."""
    rank = {r: k for k, r in enumerate(automaton.priority)}
    def key(i: int) -> tuple[int, int]:
        ranks = [rank.get(r, len(rank)) for r, (_, g) in zip(automaton.rewards, weights.rewards) if g[i] != 0]
        return (min(ranks, default=len(rank) + 1), i)
    return tuple(sorted(range(size), key=key))


def _box(parameters: tuple[ir.Parameter, ...]) -> list[Inequality]:
    size = len(parameters)
    result = []
    for i, p in enumerate(parameters):
        unit = tuple(Fraction(1 if j == i else 0) for j in range(size))
        result.append(Inequality(tuple(-x for x in unit), -p.low))
        result.append(Inequality(unit, p.high))
    return result


def _p1(automaton: ir.Automaton, weights: Weights, sentences: list[str]) -> list[Inequality]:
    """P1 as inequalities: a rate conflict (``high`` falls while ``low`` rises, or while it falls)
    keeps the weight of ``low`` at most 0 (or at least 0)."""
    found: list[Inequality] = []
    index = {r: k for k, r in enumerate(automaton.rewards)}
    for location in automaton.locations:
        for a, first in enumerate(automaton.priority):
            for second in automaton.priority[a + 1:]:
                at, gradient = weights.rewards[index[second]]
                plus, minus = rate_conflicts(automaton, location, first, second)
                for conflict, sign in ((plus, 1), (minus, -1)):
                    if conflict:
                        cut = Inequality(tuple(sign * g for g in gradient), -sign * at)
                        if not any(gradient) and cut.bound >= 0:
                            continue  # a constant weight on the harmless side
                        found.append(cut)
                        names = [p.name for p in automaton.parameters]
                        need = (_describe(cut, names) if any(gradient) else
                                f"the weight of `{second}` {'<=' if sign > 0 else '>='} 0, whatever the parameters are")
                        sentences.append(f"P1 in `{location.name}` ({first} > {second}) needs {need}")
    return found


def _least(rows: list[Inequality], order: tuple[int, ...]) -> Vector | None:
    """The lexicographically least point of the polytope in ``order`` (None when it is empty): a
    lexicographic minimum over a polytope is attained at a vertex."""
    vertices = _vertices(rows, len(order))
    return min(vertices, key=lambda p: tuple(p[i] for i in order)) if vertices else None


def _fix(i: int, size: int, value: Fraction) -> list[Inequality]:
    """``θ_i = value`` as two inequalities."""
    unit = tuple(Fraction(1 if j == i else 0) for j in range(size))
    return [Inequality(unit, value), Inequality(tuple(-x for x in unit), -value)]


def _least_integer(rows: list[Inequality], order: tuple[int, ...]) -> Vector | None:
    """The lexicographically least integer point (None when there is none): the least integer of the
    first parameter for which the rest has an integer completion (recursively the least), and so on."""
    size = len(order)

    def search(fixed: list[Inequality], depth: int) -> dict[int, Fraction] | None:
        vertices = _vertices(fixed, size)
        if not vertices:
            return None
        if depth == size:
            return {}
        i = order[depth]
        low, high = min(p[i] for p in vertices), max(p[i] for p in vertices)
        for v in range(math.ceil(low), math.floor(high) + 1):
            rest = search(fixed + _fix(i, size, Fraction(v)), depth + 1)
            if rest is not None:
                return {i: Fraction(v), **rest}
        return None

    found = search(list(rows), 0)
    return None if found is None else tuple(found[i] for i in range(size))


def _vertices(rows: list[Inequality], size: int) -> list[Vector]:
    """Every vertex of the polytope (bounded by the box, so it has one when it is not empty): the
    solutions of ``size`` of its rows taken as equalities that satisfy every row. Exact, and small
    here (a few parameters, a few dozen rows); the rows are first reduced to distinct half-spaces."""
    distinct: list[Inequality] = []
    for row in rows:
        normal = _normalised(row)
        if normal is None:
            if row.bound < 0:
                return []  # 0 <= negative: nothing satisfies it
        elif normal not in distinct:
            distinct.append(normal)
    if math.comb(len(distinct), size) > MAX_SUBSETS:
        raise Unfinished(f"the polytope has {len(distinct)} inequalities in {size} parameters: more than "
                         f"{MAX_SUBSETS:,} vertex candidates")
    found: set[Vector] = set()
    for subset in itertools.combinations(distinct, size):
        point = _solve([r.coefficients for r in subset], [r.bound for r in subset])
        if point is not None and point not in found and all(r.slack(point) >= 0 for r in distinct):
            found.add(point)
    return sorted(found)


def _solve(matrix: list[Vector], rhs: list[Fraction]) -> Vector | None:
    """The unique solution of a square system (None when it is singular), by exact elimination."""
    size = len(rhs)
    m = [list(row) + [b] for row, b in zip(matrix, rhs)]
    for col in range(size):
        pivot = next((r for r in range(col, size) if m[r][col] != 0), None)
        if pivot is None:
            return None
        m[col], m[pivot] = m[pivot], m[col]
        for r in range(size):
            if r != col and m[r][col] != 0:
                factor = m[r][col] / m[col][col]
                m[r] = [x - factor * y for x, y in zip(m[r], m[col])]
    return tuple(m[i][size] / m[i][i] for i in range(size))


def _irredundant(box: list[Inequality], cuts: list[Inequality]) -> list[Inequality]:
    """The cuts that the box and the other kept cuts do not imply (each checked by an exact LP),
    in least integer terms, without repeats."""
    unique: list[Inequality] = []
    for cut in cuts:
        normal = _normalised(cut)
        if normal is not None and normal not in unique:
            unique.append(normal)
    kept = list(unique)
    size = len(box) // 2
    for cut in unique:
        others = [c for c in kept if c != cut]
        # Implied when its left side stays within its bound at every vertex of what the others leave.
        if all(cut.slack(v) >= 0 for v in _vertices(box + others, size)):
            kept = others
    return kept


def _normalised(cut: Inequality) -> Inequality | None:
    """The same half-space with coprime integer coefficients (None for a row without coefficients)."""
    if not any(cut.coefficients):
        return None
    scale = math.lcm(*(x.denominator for x in (*cut.coefficients, cut.bound)))
    whole = [int(x * scale) for x in cut.coefficients]
    divisor = math.gcd(*whole)
    return Inequality(tuple(Fraction(x, divisor) for x in whole), cut.bound * scale / divisor)


def _opposite(a: Inequality, b: Inequality) -> bool:
    """Whether ``b`` is ``a`` reversed (``v <= 0`` and ``-2 * v <= 0``): together they are an equation."""
    scale = next((-y / x for x, y in zip(a.coefficients, b.coefficients) if x != 0), None)
    return (scale is not None and scale > 0 and all(y == -scale * x for x, y in zip(a.coefficients, b.coefficients))
            and b.bound == -scale * a.bound)


def _describe(cut: Inequality, names: list[str], order: tuple[int, ...] | None = None, *,
              equation: bool = False) -> str:
    """``10 * w1 >= 37 * w2 + 50``: the leading parameter (first in ``order``, else in declaration order)
    alone on the left, with a positive coefficient, the rest on the right, in least integer terms
    (sympy's ``primitive``); with ``equation``, ``==`` for the comparison."""
    # sympy: only when this runs; importing rac.check.analysis.weights stays light
    from sympy import Poly, Rational, symbols

    order = order if order is not None else tuple(range(len(names)))
    xs = symbols(" ".join(f"x{i}" for i in range(len(names))) + " _", seq=True)[:len(names)]
    expr = sum((Rational(a.numerator, a.denominator) * x for a, x in zip(cut.coefficients, xs)), Rational(0)) \
        - Rational(cut.bound.numerator, cut.bound.denominator)
    _, primitive = Poly(expr, *xs).primitive()
    terms = {i: Fraction(int(primitive.coeff_monomial(x))) for i, x in enumerate(xs)}
    constant = Fraction(int(primitive.coeff_monomial(1)))
    lead = next(i for i in order if terms[i] != 0)
    if max(len(str(abs(t.numerator))) for t in (*terms.values(), constant)) > 15:
        # a discounted cut's least integer terms carry gamma's powers (hundreds of digits): the leading
        # parameter alone, the others' coefficients rounded for reading (`…`), as short_number writes them
        scale = abs(terms[lead])
        terms, constant = {i: t / scale for i, t in terms.items()}, constant / scale
    # a·θ_lead + Σ rest + c <= 0  ⇔  sign: θ_lead on the left with a positive coefficient.
    flip = terms[lead] < 0
    left = abs(terms[lead])
    rest = [(-t if not flip else t, names[i]) for i, t in terms.items() if i != lead and t != 0]
    bound = -constant if not flip else constant
    op = "==" if equation else ">=" if flip else "<="
    right = _sum_text(rest, bound)
    return f"{_term(left, names[lead])} {op} {right}"


def _term(coefficient: Fraction, name: str) -> str:
    return name if coefficient == 1 else f"{short_number(coefficient)} * {name}"


def _sum_text(terms: list[tuple[Fraction, str]], constant: Fraction) -> str:
    parts: list[str] = []
    for c, name in terms:
        text = _term(abs(c), name)
        parts.append(text if not parts and c > 0 else (f"- {text}" if c < 0 else f"+ {text}"))
    if constant != 0 or not parts:
        text = short_number(abs(constant))
        parts.append((text if constant >= 0 else f"-{text}") if not parts else
                     (f"+ {text}" if constant > 0 else f"- {text}"))
    if parts[0].startswith("- "):
        parts[0] = "-" + parts[0][2:]
    return " ".join(parts)


__all__ = ["Inequality", "Region", "Unsupported", "Weights", "synthesise_region"]
