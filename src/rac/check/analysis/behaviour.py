"""Determinism (with a witness valuation), dead edges and unreachable locations."""

from __future__ import annotations

import dataclasses
import functools
import math
import typing
from collections import deque
from fractions import Fraction

import numpy as np

from rac import ir
from rac.core.diagnostics import Diagnostic, Note, error, warning
from rac.core.source import Span
from rac.ir.inputs import InputSpace, TooManyClasses, guard_inputs


class ById:
    """A cache key that hashes and compares an object by identity (the IR is immutable, and hashing
    it deeply costs more than the work a cache saves)."""

    def __init__(self, value: object) -> None:
        self.value = value

    def __hash__(self) -> int:
        return id(self.value)

    def __eq__(self, other: object) -> bool:
        return isinstance(other, ById) and other.value is self.value


def allowed_boxes(automaton: ir.Automaton, names: tuple[str, ...], guard: ir.Guard | None = None
                  ) -> list[dict[str, tuple[Fraction, Fraction]]] | None:
    """The input classes ``assume`` allows (and ``guard`` holds in), as boxes over the numeric inputs
    ``names``: each input's closed bounds within the class (an ``int`` input's whole values), without
    repeats. A linear form's infimum over the allowed inputs is its least minimum over these boxes
    (a real interval's open end is a limit of values inside it). None when the classes are too many
    to list (E0306): callers then use the declared bounds."""
    return _allowed_boxes(ById(automaton), names, ById(guard))


@functools.lru_cache(maxsize=64)
def _allowed_boxes(automaton_key: ById, names: tuple[str, ...], guard_key: ById
                   ) -> list[dict[str, tuple[Fraction, Fraction]]] | None:
    automaton = typing.cast(ir.Automaton, automaton_key.value)
    guard = typing.cast("ir.Guard | None", guard_key.value)
    space, _ = input_space(automaton)
    if space is None:
        return None
    chosen = space.valid if guard is None else space.valid & space.evaluate(guard)
    if not names:
        return [{}] if chosen.any() else []
    columns = np.stack([space.columns[name][chosen] for name in names], axis=1)
    integral = {item.name for item in automaton.numeric_inputs if item.kind == "int"}
    boxes = []
    for row in np.unique(columns, axis=0):
        box = {}
        for name, index in zip(names, row):
            piece = space.pieces[name][int(index)]
            low, high = piece.low, piece.high
            if name in integral:  # the whole values inside the piece
                low = Fraction(math.ceil(low)) if piece.low_closed else Fraction(math.floor(low) + 1)
                high = Fraction(math.floor(high)) if piece.high_closed else Fraction(math.ceil(high) - 1)
            box[name] = (low, high)
        if all(low <= high for low, high in box.values()):  # an int piece without a whole value holds none
            boxes.append(box)
    return boxes


@functools.lru_cache(maxsize=2)  # a space holds up to MAX_CACHED_BYTES of guard tables: keep few
def _classes(automaton_key: ById) -> InputSpace | TooManyClasses:
    """The automaton's input classes, built once (every analysis of one check and
    :func:`allowed_boxes` share them), or why they cannot be."""
    try:
        return InputSpace(typing.cast(ir.Automaton, automaton_key.value))
    except TooManyClasses as exc:
        return exc


def input_space(automaton: ir.Automaton) -> tuple[InputSpace | None, list[Diagnostic]]:
    """The input classes, or a diagnostic explaining why the exact checks cannot run."""
    classes = _classes(ById(automaton))
    if isinstance(classes, InputSpace):
        return classes, []
    return None, [error(
        "E0306", f"too many input combinations for the exact checks ({classes.count:,} classes)",
        automaton.source.name.span if automaton.source else None,
        hints=["use fewer inputs, or fewer distinct thresholds on numeric inputs"])]


def check_behaviour(automaton: ir.Automaton, space: InputSpace | None = None) -> list[Diagnostic]:
    """Assume satisfiable, determinism, edges that never fire, reachability within the horizon.

    ``space`` is the automaton's :class:`InputSpace` when the caller has built it already.
    """
    diagnostics: list[Diagnostic] = []
    if space is None:
        space, diagnostics = input_space(automaton)
        if space is None:
            return diagnostics
    valid = space.valid
    if not valid.any():
        span, notes = _unsatisfiable_assume(automaton, space)
        return [error("E0305", "`assume` excludes every input valuation", span, notes=notes,
                      hints=["no run is possible; weaken the assumptions"])]
    reported_dead: set[object] = set()
    reported_pairs: set[tuple[object, object]] = set()
    for location, edges in zip(automaton.locations, automaton.edges):
        for edge in edges:
            if not space.satisfiable(edge.guard) and edge.span not in reported_dead:
                reported_dead.add(edge.span)
                diagnostics.append(warning(
                    "W0304", "this edge can never fire: its guard is false for every input allowed by "
                    "`assume`", edge.span, hints=["remove the edge or correct its guard"]))
        diagnostics += _overlaps(automaton, space, location, edges, reported_pairs)
    diagnostics += _reachability(automaton, space)
    return diagnostics


def _overlaps(automaton: ir.Automaton, space: InputSpace, location: ir.Location, edges: tuple[ir.Edge, ...],
              reported_pairs: set[tuple[object, object]]) -> list[Diagnostic]:
    """E0301 for every pair of the location's edges enabled together in some allowed class."""
    live = [k for k, edge in enumerate(edges) if space.satisfiable(edge.guard)]
    if len(live) < 2:
        return []
    count = np.zeros(space.count, dtype=np.int32)
    for k in live:
        count += space.evaluate(edges[k].guard)
    # Only classes that enable two edges or more can witness a pair: look at those alone
    # (a location with n edges would otherwise cost n^2 passes over every class).
    crowded = np.flatnonzero((count > 1) & space.valid)
    if not len(crowded):
        return []
    enabled = {k: space.evaluate(edges[k].guard)[crowded] for k in live}
    result = []
    for a, i in enumerate(live):
        for j in live[a + 1:]:
            both = enabled[i] & enabled[j]
            key = (edges[i].span, edges[j].span)
            if not both.any() or key in reported_pairs:
                continue
            reported_pairs.add(key)
            cls = int(crowded[np.argmax(both)])
            names = automaton.location_names
            result.append(error(
                "E0301",
                f"nondeterminism: two edges leave `{location.name}` on the same inputs",
                edges[j].span,
                notes=[Note(f"the other edge (to `{names[edges[i].target]}`)", edges[i].span),
                       "witness: " + space.describe(
                           cls, guard_inputs(edges[i].guard) | guard_inputs(edges[j].guard))],
                hints=["make the guards exclusive, e.g. add `&& !(...)` of the other guard"],
                data={"location": location.name, "witness": _json_valuation(space, cls)}))
    return result


def distances(automaton: ir.Automaton, space: InputSpace) -> dict[int, int]:
    """Samples needed to reach each reachable location (breadth-first over edges that can fire).

    An edge that fires only where `episode ends when` holds reaches its target, but no run goes on
    from there: only a location entered on inputs that let the run continue has its edges followed.
    """
    ends = automaton.episode_ends
    distance = {automaton.initial: 0}
    going_on = {automaton.initial: 0}  # samples needed to be there with the run still going
    queue = deque([automaton.initial])
    while queue:
        here = queue.popleft()
        for edge in automaton.edges[here]:
            if not space.satisfiable(edge.guard):
                continue
            distance.setdefault(edge.target, going_on[here] + 1)
            continues = ends is None or space.satisfiable(ir.BAnd((edge.guard, ir.BNot(ends))))
            if continues and edge.target not in going_on:
                going_on[edge.target] = going_on[here] + 1
                queue.append(edge.target)
    return distance


def _reachability(automaton: ir.Automaton, space: InputSpace) -> list[Diagnostic]:
    distance = distances(automaton, space)
    result = []
    for index, location in enumerate(automaton.locations):
        if index not in distance:
            lead = ("no sequence of edges from the initial location leads here"
                    if automaton.episode_ends is None or index not in distances(
                        dataclasses.replace(automaton, episode_ends=None), space)
                    else "every sequence of edges that leads here passes a sample where `episode ends when` "
                         "holds, and the run ends there")
            result.append(warning("W0302", f"location `{location.name}` is unreachable", location.span,
                                  hints=[lead]))
        elif distance[index] > automaton.steps:
            result.append(warning(
                "W0302", f"location `{location.name}` cannot be reached within the horizon",
                location.span, notes=[f"it needs {distance[index]} samples; the horizon has {automaton.steps}"]))
    return result


def _unsatisfiable_assume(automaton: ir.Automaton, space: InputSpace) -> tuple[Span | None, list[Note]]:
    """The first `assume` that, with the ones before it, excludes every valuation (and those)."""
    assumptions = automaton.assumptions
    if not assumptions:
        return (None if automaton.source is None else automaton.source.name.span), []
    allowed = np.ones(space.count, dtype=bool)
    for k, assumption in enumerate(assumptions):
        allowed = allowed & space.evaluate(assumption.guard)
        if not allowed.any():
            earlier = [Note("together with this assumption", a.span) for a in assumptions[:k]]
            return assumption.span, earlier
    return assumptions[0].span, []


def _json_valuation(space: InputSpace, cls: int) -> dict[str, object]:
    values: dict[str, object] = {}
    for name, value in space.valuation(cls).items():
        values[name] = value if isinstance(value, bool) else float(value)
    return values
