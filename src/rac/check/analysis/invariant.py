"""``A[] p`` over the automaton alone: for every input sequence within ``assume``, does ``p`` hold at
every instant of every run within the horizon?

``p`` reads the automaton's own state only: its locations, its inputs and its rewards (a query of
the kind of Qe-Qh). The negation of ``p`` is put in disjunctive normal form; each disjunct is a
conjunction of literals of three kinds (the automaton is in a location; a guard over the inputs;
a linear comparison over the rewards), and ``p`` holds iff no disjunct can be true at an instant.

The instants are those at which the product of model and automaton shows a state
(:mod:`rac.engine.product`): the start (the initial location, every input false or 0, every reward
0); after each sample's edge (the location it enters and the sample's inputs); before the next
sample's edge (the same location and inputs, the rewards accrued); after the ``at end`` updates;
and, when a rate reads an input, the first sample before its edge (the initial location, that
sample's inputs). A sample whose inputs satisfy ``episode ends when`` is the run's last. A
disjunct without reward literals is decided on the pairs (location, input class) that these
instants show, exactly; one with a single reward comparison and no input
literals by the worst-run search of :mod:`rac.check.analysis.worst` (the supremum of that
comparison's linear form over the instants spent in the disjunct's locations). Anything else is
*undecided* here, and the caller falls back to the model.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from fractions import Fraction

import numpy as np

from rac import ir
from rac.check.analysis.affine import moves
from rac.check.analysis.worst import Target, Unfinished, maximise
from rac.core.diagnostics import RacError, short_number
from rac.ir import expr as ie
from rac.ir.inputs import InputSpace, TooManyClasses

__all__ = ["PROVED", "REFUTED", "UNDECIDED", "Invariant", "decide_invariant", "over_automaton"]

PROVED, REFUTED, UNDECIDED = "proved", "refuted", "undecided"

_FLIP = {"<": ">", "<=": ">=", ">": "<", ">=": "<=", "==": "==", "!=": "!="}
_NEGATE = {"<": ">=", "<=": ">", ">": "<=", ">=": "<", "==": "!=", "!=": "=="}


@dataclass(frozen=True)
class Invariant:
    """The verdict on ``A[] p`` over the automaton: :data:`PROVED`, :data:`REFUTED` (``reason`` says
    at which abstract instant) or :data:`UNDECIDED` (``reason`` says why not)."""

    status: str
    reason: str


@dataclass(frozen=True)
class _Literal:
    """One literal of a disjunct of ``!p``: a location set, an input guard, or a reward comparison."""

    locations: frozenset[int] | None = None  # the automaton is in one of these
    guard: ir.Guard | None = None  # over the inputs
    reward: tuple[ie.LinearForm, str] | None = None  # form op 0, the form over rewards


class _Unsupported(RacError):
    pass


def over_automaton(expr: ie.Expr) -> bool:
    """Whether ``expr`` reads the automaton's own state only (locations, inputs, rewards, constants)."""
    for node in ie.walk(expr):
        if isinstance(node, ie.Ref) and node.kind not in (ie.RefKind.INPUT, ie.RefKind.REWARD, ie.RefKind.LOCATION):
            return False
        if isinstance(node, (ie.Call, ie.Prev)):
            return False
    return True


def _literal(automaton: ir.Automaton, node: ie.Expr, positive: bool) -> _Literal:
    """``node`` (or its negation) as a literal; raises :class:`_Unsupported`."""
    if isinstance(node, ie.Ref) and node.kind is ie.RefKind.LOCATION:
        here = frozenset({node.index})
        return _Literal(locations=here if positive else frozenset(range(len(automaton.locations))) - here)
    if isinstance(node, ie.Ref) and node.kind is ie.RefKind.INPUT and node.type == ie.BOOL:
        guard: ir.Guard = ir.BInput(node.name)
        return _Literal(guard=guard if positive else ir.BNot(guard))
    if isinstance(node, ie.Const) and isinstance(node.value, bool):
        return _Literal(guard=ir.BConst(node.value == positive))
    if isinstance(node, ie.Compare) and node.linear is not None:
        op = node.op if positive else _NEGATE[node.op]
        form = node.linear
        kinds = {ref.kind for ref, _ in form.terms}
        if not form.terms:
            return _Literal(guard=ir.BConst(_holds(form.const, op)))
        if kinds == {ie.RefKind.REWARD}:
            if op in ("==", "!="):
                raise _Unsupported("an equality over the rewards")
            return _Literal(reward=(form, op))
        if kinds == {ie.RefKind.INPUT} and len(form.terms) == 1:
            (ref, coefficient), = form.terms
            threshold = -form.const / coefficient
            return _Literal(guard=ir.BAtom(ref.name, op if coefficient > 0 else _FLIP[op], threshold))
        raise _Unsupported("a comparison mixing inputs and rewards, or of several inputs")
    raise _Unsupported(f"`{type(node).__name__}` in the query")


def _holds(value: Fraction, op: str) -> bool:
    return {"<": value < 0, "<=": value <= 0, ">": value > 0, ">=": value >= 0, "==": value == 0,
            "!=": value != 0}[op]


def _dnf(automaton: ir.Automaton, node: ie.Expr, positive: bool) -> list[list[_Literal]]:
    """``node`` (negated unless ``positive``) in disjunctive normal form."""
    if isinstance(node, ie.Unary) and node.op == "!":
        return _dnf(automaton, node.operand, not positive)
    if isinstance(node, ie.Binary) and node.op in ("&&", "||", "imply"):
        # a imply b == !a || b
        left = _dnf(automaton, node.left, positive if node.op != "imply" else not positive)
        right = _dnf(automaton, node.right, positive)
        if (node.op == "&&") == positive and not (node.op == "imply" and positive):
            product = [a + b for a in left for b in right]
            if len(product) > 4096:
                raise _Unsupported("the query's normal form is too large")
            return product
        return left + right
    return [[_literal(automaton, node, positive)]]


def decide_invariant(automaton: ir.Automaton, expr: ie.Expr, horizon_samples: int | None = None) -> Invariant:
    """``A[] expr`` for every input sequence within ``assume``, over ``horizon_samples`` samples (the
    automaton's horizon by default)."""
    if not over_automaton(expr):
        return Invariant(UNDECIDED, "the query reads more than the automaton's locations, inputs and rewards")
    if horizon_samples is not None:
        automaton = dataclasses.replace(automaton, horizon=horizon_samples * automaton.period)
    try:
        disjuncts = _dnf(automaton, expr, False)
        guards = [lit.guard for d in disjuncts for lit in d if lit.guard is not None]
        space = InputSpace(automaton, guards)
    except _Unsupported as why:
        return Invariant(UNDECIDED, f"not decided on the automaton alone: {why}")
    except TooManyClasses as exc:
        return Invariant(UNDECIDED, f"too many input classes for the automaton-level check ({exc.count:,})")
    # A formula that reads an input counts only where the inputs are those the location reacted to
    # (UPPAAL's `settled`, engine.product's ProductGraph.label): not at the start, not before the
    # first sample's edge.
    settled_only = any(r.kind is ie.RefKind.INPUT for r in ie.refs(expr))
    pairs = _Pairs(automaton, space, settled_only)
    undecided: list[str] = []
    for disjunct in disjuncts:
        verdict = _disjunct(automaton, space, pairs, disjunct, settled_only)
        if verdict.status == REFUTED:
            return verdict
        if verdict.status == UNDECIDED:
            undecided.append(verdict.reason)
    if undecided:
        return Invariant(UNDECIDED, undecided[0])
    return Invariant(PROVED, f"holds for every input sequence within the assumptions, over every run of "
                             f"{short_number(automaton.horizon)} s")


class _Pairs:
    """The (location, input class) pairs the instants of runs within the horizon show."""

    def __init__(self, automaton: ir.Automaton, space: InputSpace, settled_only: bool) -> None:
        self.automaton = automaton
        self.space = space
        count = len(automaton.locations)
        valid = space.valid
        steps = automaton.steps
        # Locations reachable at some sample before the last (the sources of every shown edge). A
        # sample whose inputs satisfy `episode ends when` ends the run: no sample follows it.
        going = valid & ~space.evaluate(automaton.ending) if automaton.ending is not None else valid
        reach = {automaton.initial: 0}
        frontier = [automaton.initial]
        targets: dict[int, np.ndarray] = {}
        while frontier:
            following = []
            for here in frontier:
                target = self._targets(here)
                targets[here] = target
                for there in np.unique(target[going]).tolist():
                    if there not in reach and reach[here] + 1 <= steps - 1:
                        reach[there] = reach[here] + 1
                        following.append(there)
            frontier = following
        self.shown = np.zeros((count, space.count), dtype=bool)  # [location, class]
        if steps >= 1:
            for here in reach:
                target = targets[here]
                self.shown[target[valid], np.flatnonzero(valid)] = True
            if automaton.rates_read_inputs and not settled_only:
                self.shown[automaton.initial, valid] = True

    def _targets(self, here: int) -> np.ndarray:
        """The location entered from ``here`` in each class (the enabled edge's target, else ``here``)."""
        target = np.full(self.space.count, here, dtype=np.int64)
        taken = np.zeros(self.space.count, dtype=bool)
        for edge in self.automaton.edges[here]:
            enabled = self.space.evaluate(edge.guard) & ~taken
            target[enabled] = edge.target
            taken |= enabled
        return target


def _start_holds(automaton: ir.Automaton, disjunct: list[_Literal]) -> bool:
    """Whether ``disjunct`` is true at the start: the initial location, inputs false or 0, rewards 0."""
    zero: dict[str, bool | Fraction] = {i.name: False if i.kind == "bool" else Fraction(0) for i in automaton.inputs}
    for lit in disjunct:
        if lit.locations is not None and automaton.initial not in lit.locations:
            return False
        if lit.guard is not None and not ir.evaluate_guard(lit.guard, dict(zero)):
            return False
        if lit.reward is not None and not _holds(lit.reward[0].const, lit.reward[1]):
            return False
    return True


def _disjunct(automaton: ir.Automaton, space: InputSpace, pairs: _Pairs, disjunct: list[_Literal],
              settled_only: bool) -> Invariant:
    names = automaton.location_names
    if not settled_only and _start_holds(automaton, disjunct):
        return Invariant(REFUTED, "the query is false at the start (t = 0), where every input is false or 0")
    where = frozenset(range(len(automaton.locations)))
    classes = np.ones(space.count, dtype=bool)
    rewards = []
    for lit in disjunct:
        if lit.locations is not None:
            where &= lit.locations
        if lit.guard is not None:
            classes &= space.evaluate(lit.guard)
        if lit.reward is not None:
            rewards.append(lit.reward)
    classes &= space.valid
    if not where or not classes.any():
        return Invariant(PROVED, "")
    if not rewards:
        shown = pairs.shown[sorted(where)][:, classes]
        if not shown.any():
            return Invariant(PROVED, "")
        row, column = np.argwhere(shown)[0]
        location = sorted(where)[int(row)]
        cls = int(np.flatnonzero(classes)[int(column)])
        return Invariant(REFUTED, f"a run of the automaton reaches `{names[location]}` with inputs "
                                  f"{space.describe(cls)}")
    if len(rewards) > 1 or any(lit.guard is not None for lit in disjunct):
        return Invariant(UNDECIDED, "not decided on the automaton alone: a disjunct combines a reward comparison "
                                    "with other comparisons or with inputs")
    form, op = rewards[0]
    sign = 1 if op in (">", ">=") else -1
    coefficients = {ref.name: c for ref, c in form.terms}
    target = Target(tuple(sign * coefficients.get(r, Fraction(0)) for r in automaton.rewards), sign * form.const,
                    tuple(k in where for k in range(len(automaton.locations))))
    plain = InputSpace(automaton)
    try:
        worst = maximise(automaton, moves(automaton, plain), target, run=False)
    except Unfinished as stop:
        return Invariant(UNDECIDED, f"the worst-run search stopped: {stop.reason}")
    if worst is None:
        return Invariant(PROVED, "")
    strict = op in (">", "<")
    if worst.value < 0 or (strict and worst.value == 0):
        return Invariant(PROVED, "")
    if worst.value > 0:
        return Invariant(REFUTED, "a run of the automaton makes the reward comparison true (left side minus "
                                  f"right side = {short_number(sign * worst.value)})")
    return Invariant(UNDECIDED, "the compared sum reaches 0 at best; whether it attains it is not decided here")
