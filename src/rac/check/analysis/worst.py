"""The worst run: the supremum of a linear functional of the rewards over a bounded horizon.

Both P2 (priority soundness) and the int32 range check ask the same question:
over every run of at most ``steps`` samples, with inputs free at each sample
(subject to ``assume``), and every instant at which the automaton is in a
*watched* location, how large can ``w·r + w0`` become?

Between samples rewards change linearly, so only instants at samples matter:
just before an edge (the first sample's; later ones equal the previous
"before next"), just after it, just before the next sample, and just after the
``at end`` updates of a run that ends there. A run may end after any sample or
before the first, with inputs of its own (``end(inputs)``), so the end's inputs
range freely over what ``assume`` allows. A sample whose inputs satisfy ``episode
ends when`` ends the run: no run continues from it (its instant "just before the
next sample" is not one either), no ``end(inputs)`` follows it, and its ``at end``
clauses are those whose guards hold on that sample's inputs, reading those same
inputs (:attr:`~rac.check.analysis.affine.Outcome.ending`, one map per outcome).

The search is a backward dynamic programme over sets of affine functionals of
the reward vector (exact for any affine updates, rational arithmetic). When
every update is a translation (``r = r + c``) the set collapses to one
functional and a vectorised max-plus recurrence in scaled integers answers in
one pass over the horizon.

A target with :attr:`Target.intermediates` also watches the values inside a sequence of updates: after
each assignment of an edge's updates but the last (``mid-edge``), and of the ``at end`` clauses'
(``mid-end``). No instant of the semantics sees them, but the UPPAAL model stores each assignment in
a reward's 32-bit mirror, so the int32 range check must bound them (:attr:`Worst.applied` says how
many assignments of the sequence the run's value is taken after).
"""

from __future__ import annotations

import dataclasses
import functools
import math
import typing
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from fractions import Fraction

import numpy as np

from rac import ir
from rac.check.analysis.affine import (
    Affine,
    EndOutcome,
    Moves,
    Outcome,
    accrual,
    end_assignments,
    stored_prefixes,
    sup_linear,
    sup_weighted,
)
from rac.check.analysis.behaviour import ById
from rac.core.diagnostics import RacError

ZERO = Fraction(0)
#: Instants of one sample, in time order; START is t = 0 before any sample.
BEFORE_EDGE, AFTER_EDGE, AFTER_END, BEFORE_NEXT, CONTINUE, START = (
    "before-edge", "after-edge", "after-end", "before-next", "continue", "start")
#: Inside a sequence of updates (only for a target with :attr:`Target.intermediates`): after some of
#: the edge's assignments (MID_EDGE, in the sample's edge) or of the ``at end`` clauses' (MID_END).
MID_EDGE, MID_END = "mid-edge", "mid-end"


#: The most samples the worst-run search goes through. Beyond it the search goes on only while the
#: values still change (the translation engine: once two consecutive samples give the same values,
#: every earlier sample does too), and a run to show may not be longer; otherwise it stops with
#: :class:`Unfinished`, which the checks report as a warning (W0405), never as a proof.
MAX_SAMPLES = 100_000


class Unfinished(RacError):
    """The worst-run search stopped at :data:`MAX_SAMPLES`; ``reason`` says why, for the warning."""

    def __init__(self, reason: str) -> None:
        super().__init__(reason)
        self.reason = reason


@dataclass(frozen=True)
class Target:
    """Maximise ``weights·r + constant`` over instants spent in ``watched`` locations."""

    weights: tuple[Fraction, ...]
    constant: Fraction
    watched: tuple[bool, ...]
    #: Also the values inside a sequence of updates, after each of its assignments (MID_EDGE,
    #: MID_END; counted where the edge's target is watched): what UPPAAL stores, which the int32
    #: range check bounds. No instant of the semantics sees them, so other checks leave this off.
    intermediates: bool = False


@dataclass(frozen=True)
class Step:
    """One sample of the worst run: where it was, what the inputs did, and which instant ends it."""

    sample: int  # 1-based
    outcome: Outcome
    inputs: dict[str, Fraction]  # values of the numeric inputs the arithmetic reads
    instant: str  # CONTINUE, or the instant at which the run reaches the supremum


@dataclass
class Worst:
    """The supremum and a run reaching it (``end`` is set when the run ends with ``at end``)."""

    value: Fraction
    steps: list[Step] = field(default_factory=list)
    instant: str = START
    end: EndOutcome | None = None
    end_inputs: dict[str, Fraction] = field(default_factory=dict)
    #: At MID_EDGE or MID_END: after how many assignments of the sequence (the last step's edge's
    #: updates, or the enabled ``at end`` clauses' in order, :func:`end_assignments`) the value is taken.
    applied: int | None = None


def maximise(automaton: ir.Automaton, moves: Moves, target: Target,
             run: bool | Callable[[Fraction], bool] = True) -> Worst | None:
    """The worst run for ``target`` (None when no watched instant is reachable).

    ``run`` says whether the run itself is wanted, or for which values (a proof needs the value
    only, and a run can be as long as the horizon); when not, its steps are left empty.
    Raises :class:`Unfinished` beyond :data:`MAX_SAMPLES` (see there).
    """
    if moves.translations_only and not _scales_inside(automaton, moves, target):
        return maximise_translations(automaton, moves, target, run)
    if automaton.steps > MAX_SAMPLES:
        raise Unfinished(f"the horizon has {automaton.steps:,} samples, more than the {MAX_SAMPLES:,} the "
                         "search goes through when updates scale rewards")
    return maximise_generic(automaton, moves, target)


def _scales_inside(automaton: ir.Automaton, moves: Moves, target: Target) -> bool:
    """Whether a value the target watches inside a sequence of updates comes from a map that is not a
    translation, although the whole sequence is one (``p = c - p, p = c - p``): the translation engine
    reads only a map's offsets, so it would take ``c - p`` for ``p + c``."""
    if not target.intermediates:
        return False
    prefixes = _Prefixes(automaton, target)
    inside = [m for os in moves.samples for o in os
              for _, m in (*prefixes.edge(o.edge), *prefixes.end(o.ending))]
    inside += [m for end in moves.ends for _, m in prefixes.end(end)]
    return not all(m.is_translation for m in inside)


def within_limit(automaton: ir.Automaton) -> ir.Automaton:
    """``automaton`` with its horizon cut to :data:`MAX_SAMPLES` samples, for a search that stopped there.

    A run of the cut automaton is a run of ``automaton`` (runs of at most that many samples, ending
    after any of them), so the supremum over it is a lower bound of ``automaton``'s: a violation
    found there refutes the check over the whole horizon, while a bound found there proves nothing.
    """
    return dataclasses.replace(automaton, horizon=automaton.period * MAX_SAMPLES)


# ---------------------------------------------------------------- generic engine
_Func = tuple[tuple[Fraction, ...], Fraction, dict[str, Fraction]]
#: The link of an AFTER_END entry whose run ``episode ends when`` ended: the end is the outcome's own.
_EPISODE = "episode"


class _Puller:
    """Pull functionals back through affine maps, memoised (runs repeat the same maps)."""

    def __init__(self) -> None:
        self.cache: dict[tuple[tuple[Fraction, ...], int], tuple[tuple[Fraction, ...], Fraction, dict]] = {}
        self.keep: list[Affine] = []  # keeps ids in the cache keys alive

    def __call__(self, func: _Func, affine: Affine) -> _Func:
        c, d, g = func
        key = (c, id(affine))
        hit = self.cache.get(key)
        if hit is None:
            self.keep.append(affine)
            size = len(c)
            if affine.matrix is None:
                c2 = c
            else:
                m = affine.matrix
                c2 = tuple(sum((c[k] * m[k][j] for k in range(size)), ZERO) for j in range(size))
            d_add = sum((c[k] * affine.offset[k].const for k in range(size) if c[k]), ZERO)
            g_add: dict[str, Fraction] = {}
            for k in range(size):
                if c[k]:
                    for name, coefficient in affine.offset[k].terms:
                        g_add[name] = g_add.get(name, ZERO) + c[k] * coefficient
            hit = (c2, d_add, g_add)
            self.cache[key] = hit
        c2, d_add, g_add = hit
        if g_add:
            g = dict(g)
            for name, value in g_add.items():
                g[name] = g.get(name, ZERO) + value
        return (c2, d + d_add, g)


class _Prefixes:
    """The values inside the update sequences a target watches (:attr:`Target.intermediates`): per edge
    and per set of enabled ``at end`` clauses, :func:`stored_prefixes` (none without intermediates)."""

    def __init__(self, automaton: ir.Automaton, target: Target) -> None:
        self.automaton, self.target = automaton, target
        self.edges: dict[int, tuple[tuple[int, Affine], ...]] = {}
        self.ends: dict[tuple[int, ...], tuple[tuple[int, Affine], ...]] = {}

    def edge(self, edge: ir.Edge | None) -> tuple[tuple[int, Affine], ...]:
        if edge is None or not self.target.intermediates:
            return ()
        found = self.edges.get(id(edge))
        if found is None:
            found = self.edges[id(edge)] = stored_prefixes(edge.updates, self.automaton.rewards, self.target.weights)
        return found

    def end(self, end: EndOutcome | None) -> tuple[tuple[int, Affine], ...]:
        if end is None or not self.target.intermediates:
            return ()
        found = self.ends.get(end.ends)
        if found is None:
            found = self.ends[end.ends] = stored_prefixes(end_assignments(self.automaton, end.ends),
                                                          self.automaton.rewards, self.target.weights)
        return found


def _end_functionals(moves: Moves, base: _Func, pull: _Puller, prefixes: _Prefixes
                     ) -> dict[tuple[Fraction, ...], tuple]:
    """The target after ``at end`` (and inside its updates, with intermediates), maximised over the
    end's own inputs: coefficients -> (d, end, point, applied), applied None after every update."""
    best: dict[tuple[Fraction, ...], tuple] = {}
    for end in moves.ends:
        for applied, end_map in ((None, end.end_map), *prefixes.end(end)):
            c, d, g = pull(base, end_map)
            bonus, point = sup_linear(g, end.box)
            if c not in best or d + bonus > best[c][0]:
                best[c] = (d + bonus, end, point, applied)
    return best


_Box = list[tuple[Fraction, Fraction]]


def _image(affine: Affine, box: _Box, inputs: tuple) -> _Box:
    """Interval image of a box of reward vectors (inputs within their pieces' closures)."""
    pieces = dict(inputs)
    result = []
    for i, offset in enumerate(affine.offset):
        lo = hi = offset.const
        for name, coefficient in offset.terms:
            piece = pieces.get(name)
            a, b = (coefficient * piece.low, coefficient * piece.high) if piece else (ZERO, ZERO)
            lo, hi = lo + min(a, b), hi + max(a, b)
        if affine.matrix is None:
            lo, hi = lo + box[i][0], hi + box[i][1]
        else:
            for j, m in enumerate(affine.matrix[i]):
                if m:
                    a, b = m * box[j][0], m * box[j][1]
                    lo, hi = lo + min(a, b), hi + max(a, b)
        result.append((lo, hi))
    return result


def _groups(outs: tuple[Outcome, ...]) -> list[list[int]]:
    """The outcomes of one location grouped by what a functional pulled back through them depends on
    (target, edge map, whether the run ends and with which ``at end`` clauses): they differ only in
    their input boxes. Groups and the outcomes within them keep the order of their first outcome."""
    by_key: dict[tuple[int, int, tuple[int, ...] | None], list[int]] = {}
    for oi, o in enumerate(outs):
        by_key.setdefault((o.target, id(o.edge_map), o.ending.ends if o.ending else None), []).append(oi)
    return list(by_key.values())


def _boxes_over(maps: Sequence[Affine], outs: tuple[Outcome, ...], group: list[int]) -> list[tuple]:
    """The group's input boxes restricted to the inputs ``maps`` read, without repeats (their images
    under the maps are then the same)."""
    read = {name for affine in maps for offset in affine.offset for name, _ in offset.terms}
    seen: dict[tuple, None] = {}
    for oi in group:
        seen.setdefault(tuple(item for item in outs[oi].box if item[0] in read), None)
    return list(seen)


def _reachable_boxes(automaton: ir.Automaton, moves: Moves) -> list[dict[int, _Box]]:
    """boxes[k][l]: an interval hull of the rewards "before the edge" of sample k in location l.

    For k = 1 it is the start (r = 0): the first accrual belongs to sample 1's functionals.
    Independent of the target, so computed once per automaton and moves (the range check asks for
    two targets per reward).
    """
    return _cached_boxes(ById(automaton), ById(moves))


@functools.lru_cache(maxsize=8)
def _cached_boxes(automaton_key: ById, moves_key: ById) -> list[dict[int, _Box]]:
    automaton = typing.cast(ir.Automaton, automaton_key.value)
    moves = typing.cast(Moves, moves_key.value)
    accruals = [accrual(loc, automaton.period) for loc in automaton.locations]
    size = len(automaton.rewards)
    boxes: list[dict[int, _Box]] = [{} for _ in range(automaton.steps + 2)]
    boxes[1] = {automaton.initial: [(ZERO, ZERO)] * size}
    # Per location and group: the maps of a sample (after the first, and the first's) and the
    # distinct input boxes those maps read.
    plans: dict[int, list[tuple[int, Affine, Affine, list[tuple], list[tuple]]]] = {}
    for here, outs in enumerate(moves.samples):
        plans[here] = []
        for group in _groups(outs):
            o = outs[group[0]]
            later = (o.edge_map, accruals[o.target])
            plans[here].append((o.target, o.edge_map, accruals[o.target],
                                _boxes_over(later, outs, group),
                                _boxes_over((accruals[here], *later), outs, group)))
    for k in range(1, automaton.steps):
        following = boxes[k + 1]
        for here, box in boxes[k].items():
            for target, edge_map, arrive, later_boxes, first_boxes in plans[here]:
                for inputs in (first_boxes if k == 1 else later_boxes):
                    start = _image(accruals[here], box, inputs) if k == 1 else box
                    after = _image(arrive, _image(edge_map, start, inputs), inputs)
                    old = following.get(target)
                    following[target] = after if old is None else [
                        (min(a[0], b[0]), max(a[1], b[1])) for a, b in zip(old, after)]
    return boxes


def _prune(table: dict, box: _Box) -> None:
    """Drop functionals that another one beats everywhere on the box (they can never be the max)."""
    if len(table) < 2:
        return
    order = sorted(table, key=lambda c: table[c][0], reverse=True)
    kept: list[tuple[Fraction, ...]] = []
    for c in order:
        d = table[c][0]
        for other in kept:
            gap = d - table[other][0]
            for j, (lo, hi) in enumerate(box):
                delta = c[j] - other[j]
                gap += delta * (hi if delta > 0 else lo)
            if gap <= 0:
                del table[c]
                break
        else:
            kept.append(c)


def maximise_generic(automaton: ir.Automaton, moves: Moves, target: Target) -> Worst | None:
    """:func:`maximise` for any updates (the general search; the tests compare the fast engine with it)."""
    steps = automaton.steps
    outs = moves.samples
    accruals = [accrual(loc, automaton.period) for loc in automaton.locations]
    boxes = _reachable_boxes(automaton, moves)
    groups = [_groups(os) for os in outs]
    inputs = [[dict((name, (piece.low, piece.high)) for name, piece in o.box) for o in os] for os in outs]
    pull = _Puller()
    base: _Func = (target.weights, target.constant, {})
    prefixes = _Prefixes(automaton, target)
    ends = _end_functionals(moves, base, pull, prefixes)
    l0 = automaton.initial
    # tables[k][l]: coefficients -> (d, outcome index, instant, link, x point), where link is the
    # next sample's coefficients (CONTINUE), (end outcome, its x point, applied) (AFTER_END, MID_END),
    # (_EPISODE, applied) for the outcome's own end, or applied (MID_EDGE).
    tables: list[list[dict]] = [[] for _ in range(steps + 2)]
    tables[steps + 1] = [{} for _ in automaton.locations]
    for k in range(steps, 0, -1):
        layer: list[dict] = [{} for _ in automaton.locations]
        for here in boxes[k]:  # only locations a run can be in at sample k
            # coefficients -> (value, (outcome, candidate) rank, entry): the first outcome in order
            # wins a tie, and within it the first candidate, as offering them one by one would do.
            best: dict[tuple[Fraction, ...], tuple] = {}
            for group in groups[here]:
                o = outs[here][group[0]]
                t = o.target
                candidates: list[tuple[_Func, str, object]] = []
                goes_on = k < steps and not o.ends_episode
                if target.watched[t]:
                    candidates.append((base, AFTER_EDGE, None))
                    if o.ending is not None:
                        # The run ends here: its end clauses read this sample's inputs, not inputs of
                        # their own (the functional keeps their input terms for the sample's box).
                        if o.ending.ends:
                            candidates.append((pull(base, o.ending.end_map), AFTER_END, (_EPISODE, None)))
                        for applied, end_map in prefixes.end(o.ending):
                            candidates.append((pull(base, end_map), MID_END, (_EPISODE, applied)))
                    else:
                        for c_end, (d_end, end, point, applied) in ends.items():
                            candidates.append(((c_end, d_end, {}), AFTER_END if applied is None else MID_END,
                                               (end, point, applied)))
                    if goes_on:
                        candidates.append((pull(base, accruals[t]), BEFORE_NEXT, None))
                if goes_on:
                    for c_next, entry in tables[k + 1][t].items():
                        candidates.append((pull((c_next, entry[0], {}), accruals[t]), CONTINUE, c_next))
                pulled = []
                for func, instant, link in candidates:
                    func = pull(func, o.edge_map)
                    if k == 1:
                        func = pull(func, accruals[l0])
                    pulled.append((func, instant, link))
                if k == 1 and target.watched[l0]:
                    pulled.append((pull(base, accruals[l0]), BEFORE_EDGE, None))
                if target.watched[t]:  # inside the edge's updates, after the first `applied` of them
                    for applied, prefix in prefixes.edge(o.edge):
                        func = pull(base, prefix)
                        pulled.append((pull(func, accruals[l0]) if k == 1 else func, MID_EDGE, applied))
                for ci, ((c, d, g), instant, link) in enumerate(pulled):
                    top, top_oi = None, -1
                    for oi in (group if g else group[:1]):  # without input terms every box gives d
                        total = d + _sup_value(g, inputs[here][oi])
                        if top is None or total > top:
                            top, top_oi = total, oi
                    held = best.get(c)
                    if held is None or top > held[0] or (top == held[0] and (top_oi, ci) < held[1]):
                        best[c] = (top, (top_oi, ci), (top_oi, instant, link, g))
            table = layer[here]
            for c, (total, _, (oi, instant, link, g)) in best.items():
                table[c] = (total, oi, instant, link, sup_linear(g, outs[here][oi].box)[1])
            _prune(table, boxes[k][here])
        tables[k] = layer
    start = _start(target, l0, ends)
    first = tables[1][l0]
    if not first:
        return start
    c_best = max(first, key=lambda c: first[c][0])
    if start is not None and start.value >= first[c_best][0]:
        return start
    result = Worst(first[c_best][0])
    k, here, c = 1, l0, c_best
    while True:
        _, oi, instant, link, point = tables[k][here][c]
        o = outs[here][oi]
        result.steps.append(Step(k, o, point, instant))
        if instant != CONTINUE:
            result.instant = instant
            if instant == MID_EDGE:
                result.applied = link
            elif instant in (AFTER_END, MID_END):
                if link[0] is _EPISODE:  # the end clauses of the sample that ended the run, on its inputs
                    result.end, result.end_inputs, result.applied = o.ending, point, link[1]
                else:
                    result.end, result.end_inputs, result.applied = link
            return result
        k, here, c = k + 1, o.target, link


def _sup_value(form: dict[str, Fraction], box: dict[str, tuple[Fraction, Fraction]]) -> Fraction:
    """:func:`sup_linear`'s value alone (the search's inner loop; the point is found once, for the winner)."""
    total = ZERO
    for name, g in form.items():
        if g:
            low, high = box[name]
            total += g * (high if g > 0 else low)
    return total


def _start(target: Target, l0: int, ends: dict[tuple[Fraction, ...], tuple]) -> Worst | None:
    """The best instant at t = 0: before any sample, or after ending there (r = 0)."""
    if not target.watched[l0]:
        return None
    best = Worst(target.constant)
    for d_end, end, point, applied in ends.values():
        if d_end > best.value:
            best = Worst(d_end, [], AFTER_END if applied is None else MID_END, end, point, applied)
    return best


# ---------------------------------------------------------------- fast engine
def maximise_translations(automaton: ir.Automaton, moves: Moves, target: Target,
                          run: bool | Callable[[Fraction], bool] = True) -> Worst | None:
    """Every map is a translation: the functional stays ``w``; a max-plus recurrence on scalars.

    V_k(l) = max over outcomes o of l of
             max(watched(t)·(w0 + K_edge + max(0, K_end, K_next)), V_{k+1}(t) + K_next)
    where K_edge, K_next are sups over the outcome's input box of the weighted offsets of
    one sample, and K_end the best weighted ``at end`` offset over the end's own inputs. An
    outcome where ``episode ends when`` holds stops there with watched(t)·(w0 + max(K_edge,
    K_edge+end)), K_edge+end the sup over its box of the edge's and its own end clauses' offsets
    together (they read the same inputs). With :attr:`Target.intermediates`, a stop may also be
    inside the edge's updates (K_mid, the best of their prefixes), K_end and K_edge+end include the
    prefixes of the end clauses' updates.
    """
    steps = automaton.steps
    l0 = automaton.initial
    w = target.weights
    outs = moves.samples
    accruals = [accrual(loc, automaton.period) for loc in automaton.locations]
    prefixes = _Prefixes(automaton, target)
    # Each way to end on inputs of its own: (value, end, applied, the map up to there).
    end_options = [(sup_weighted(w, (end_map,), e.box)[0], e, applied, end_map)
                   for e in moves.ends for applied, end_map in ((None, e.end_map), *prefixes.end(e))]
    k_end, best_end, end_applied, best_end_map = (max(end_options, key=lambda item: item[0]) if end_options
                                                  else (None, None, None, None))
    start = _start(target, l0, {} if k_end is None or best_end is None or best_end_map is None else
                   {(): (target.constant + k_end, best_end, sup_weighted(w, (best_end_map,), best_end.box)[1],
                         end_applied)})
    if not any(outs):  # `assume` excludes every input: no sample ever happens
        return start

    def ended(first: tuple[Affine, ...], o: Outcome) -> Fraction | None:
        """With ``episode ends when`` holding: the sup of the sample's offsets and its end clauses'
        (and of those inside the clauses' updates, with intermediates)."""
        if o.ending is None:
            return None
        maps = ([o.ending.end_map] if o.ending.ends else []) + [m for _, m in prefixes.end(o.ending)]
        return max((sup_weighted(w, (*first, o.edge_map, m), o.box)[0] for m in maps), default=None)

    def inside(first: tuple[Affine, ...], o: Outcome) -> Fraction | None:
        """With intermediates: the sup of the values inside the edge's updates (None: none watched)."""
        return max((sup_weighted(w, (*first, m), o.box)[0] for _, m in prefixes.edge(o.edge)), default=None)

    # per (l, o): (l, oi, t, K_edge, K_next, whether the run ends there, K_edge+end or None, K_mid or None)
    rows = []
    for here, os in enumerate(outs):
        for oi, o in enumerate(os):
            t = o.target
            rows.append((here, oi, t, sup_weighted(w, (o.edge_map,), o.box)[0],
                         sup_weighted(w, (o.edge_map, accruals[t]), o.box)[0], o.ends_episode, ended((), o),
                         inside((), o)))
    first_rows = []  # sample 1 from l0: the accrual before the edge uses the same inputs
    for oi, o in enumerate(outs[l0]):
        t = o.target
        first_rows.append((oi, t,
                           sup_weighted(w, (accruals[l0], o.edge_map), o.box)[0],
                           sup_weighted(w, (accruals[l0], o.edge_map, accruals[t]), o.box)[0],
                           sup_weighted(w, (accruals[l0],), o.box)[0], o.ends_episode,
                           ended((accruals[l0],), o), inside((accruals[l0],), o)))
    values = ([v for r in rows for v in (*r[3:5], *r[6:]) if v is not None]
              + [v for r in first_rows for v in (*r[2:5], *r[6:]) if v is not None]
              + [target.constant] + ([k_end] if k_end is not None else []))
    scale = math.lcm(*(v.denominator for v in values))
    n_loc = len(automaton.locations)
    width = max(len(os) for os in outs)
    # Every reachable value lies within ±magnitude; "minus infinity" must lie well below, and
    # padding added to it must stay below neg_inf // 2 (the "reachable" test).
    magnitude = int(max(abs(v) for v in values) * scale * (steps + 3))
    if magnitude < (1 << 60):
        dtype: type | str = np.int64
        neg_inf = -(1 << 62)
    else:  # exact Python integers
        dtype = object
        neg_inf = -4 * (magnitude + 1)
    w0 = int(target.constant * scale)
    end_bonus = max(0, int(k_end * scale)) if k_end is not None else 0
    targets = np.zeros((n_loc, width), dtype=np.int64)
    stop = np.full((n_loc, width), neg_inf, dtype=dtype)
    stop_last = np.full((n_loc, width), neg_inf, dtype=dtype)

    def episode_stop(edge_value: int, kee: Fraction | None) -> int:
        """The stop value where ``episode ends when`` ends the run: after the edge, or after its own end clauses."""
        return edge_value if kee is None else max(edge_value, w0 + int(kee * scale))

    k_next = np.full((n_loc, width), neg_inf, dtype=dtype)
    goes_on = np.zeros((n_loc, width), dtype=bool)  # the run may continue after this outcome
    for here, oi, t, ke, kn, ending, kee, kmid in rows:
        targets[here, oi] = t
        k_next[here, oi] = int(kn * scale)
        goes_on[here, oi] = not ending
        if target.watched[t]:
            edge_value = w0 + int(ke * scale)
            mid = neg_inf if kmid is None else w0 + int(kmid * scale)
            if ending:  # the run ends here, with this sample's own end clauses (no end of its own)
                stop[here, oi] = stop_last[here, oi] = max(episode_stop(edge_value, kee), mid)
            else:
                stop[here, oi] = max(edge_value + end_bonus, w0 + int(kn * scale), mid)
                stop_last[here, oi] = max(edge_value + end_bonus, mid)
    value = np.full(n_loc, neg_inf, dtype=dtype)
    # choice[k], stopped[k] for k = steps down to `settled`; below it they equal those at `settled`.
    choice: dict[int, np.ndarray] = {}
    stopped: dict[int, np.ndarray] = {}
    settled = 2
    rows_idx = np.arange(n_loc)
    for k in range(steps, 1, -1):
        if k == steps:
            cont = np.full((n_loc, width), neg_inf, dtype=dtype)
            s = stop_last
        else:
            cont = np.where((value[targets] > neg_inf // 2) & goes_on, value[targets] + k_next, neg_inf)
            s = stop
        cand = np.maximum(s, cont)
        best = cand.argmax(axis=1)
        choice[k] = best
        stopped[k] = s[rows_idx, best] >= cont[rows_idx, best]
        previous, value = value, cand[rows_idx, best]
        if k < steps and np.array_equal(previous, value):
            # V_k = V_{k+1}, and V_{k-1} = F(V_k) with the same F: every earlier sample repeats sample k.
            settled = k
            break
        if steps - k + 1 >= MAX_SAMPLES:
            raise Unfinished(f"the horizon has {steps:,} samples and the worst value still changes after "
                             f"{MAX_SAMPLES:,} of them")
    # Sample 1, from the initial location only.
    best_value, best_choice = None, None
    for oi, t, ke, kn, kb, ending, kee, kmid in first_rows:
        options = []
        if target.watched[t]:
            if ending:
                options.append((episode_stop(w0 + int(ke * scale), kee), "stop"))
            else:
                options.append((w0 + int(ke * scale) + end_bonus, "stop"))
            if kmid is not None:
                options.append((w0 + int(kmid * scale), "stop"))
            if steps > 1 and not ending:
                options.append((w0 + int(kn * scale), BEFORE_NEXT))
        if target.watched[l0]:
            options.append((w0 + int(kb * scale), BEFORE_EDGE))
        if steps > 1 and not ending and value[t] > neg_inf // 2:
            options.append((int(value[t]) + int(kn * scale), CONTINUE))
        for v, instant in options:
            if best_value is None or v > best_value:
                best_value, best_choice = v, (oi, instant)
    if best_value is None:
        return start
    if start is not None and start.value * scale >= best_value:
        return start
    result = Worst(Fraction(best_value, scale))
    assert best_choice is not None  # set together with best_value
    if not (run(result.value) if callable(run) else run):
        return result
    oi, instant = best_choice
    here, k = l0, 1
    # a run repeats its samples: weigh each once
    points: dict[tuple[int, str, int | None, bool], dict[str, Fraction]] = {}
    stops: dict[tuple[int, bool, bool], tuple[str, int | None]] = {}
    while True:
        if k > MAX_SAMPLES:
            raise Unfinished(f"the worst run is longer than {MAX_SAMPLES:,} samples")
        o = outs[here][oi]
        applied = None
        if instant == "stop":
            last = k == steps or o.ends_episode
            if (id(o), last, k == 1) not in stops:
                stops[id(o), last, k == 1] = _which_stop(w, o, accruals, (k_end, end_applied), prefixes,
                                                         last=last, first=k == 1, l0=l0)
            instant, applied = stops[id(o), last, k == 1]
        key = (id(o), instant, applied, k == 1)
        point = points.get(key)
        if point is None:
            maps = _maps_for(instant, o, accruals, _prefix(prefixes, instant, o, applied), first=k == 1, l0=l0)
            point = points[key] = sup_weighted(w, maps, o.box)[1]
        if instant in (AFTER_END, MID_END) and o.ending is not None:  # the run's own end, on the sample's inputs
            result.end, result.end_inputs = o.ending, point
        elif instant in (AFTER_END, MID_END):
            assert best_end is not None and best_end_map is not None
            result.end = best_end
            result.end_inputs = sup_weighted(w, (best_end_map,), best_end.box)[1]
        if instant in (MID_EDGE, MID_END):
            result.applied = applied
        result.steps.append(Step(k, o, point, instant))
        if instant != CONTINUE:
            result.instant = instant
            return result
        here, k = o.target, k + 1
        at = max(k, settled)
        oi = int(choice[at][here])
        instant = "stop" if stopped[at][here] else CONTINUE


def _prefix(prefixes: _Prefixes, instant: str, o: Outcome, applied: int | None) -> Affine | None:
    """The map inside a sequence of updates that a MID_EDGE or MID_END instant of ``o`` stops at
    (None at any other instant, and at the end of a run on inputs of its own: :func:`_maps_for`)."""
    if applied is None:
        return None
    if instant == MID_EDGE:
        return dict(prefixes.edge(o.edge))[applied]
    if instant == MID_END and o.ending is not None:
        return dict(prefixes.end(o.ending))[applied]
    return None


def _maps_for(instant: str, o: Outcome, accruals: list[Affine], inside: Affine | None, *, first: bool,
              l0: int) -> tuple[Affine, ...]:
    """The maps of one sample up to ``instant`` (their weighted offsets pick the inputs); ``inside``:
    the map of the edge's or the end clauses' first updates a MID_EDGE or MID_END instant stops at."""
    maps: tuple[Affine, ...] = (accruals[l0],) if first else ()
    if instant == BEFORE_EDGE:
        return maps
    if instant == MID_EDGE:
        assert inside is not None
        return maps + (inside,)
    maps += (o.edge_map,)
    if instant in (BEFORE_NEXT, CONTINUE):
        return maps + (accruals[o.target],)
    if instant in (AFTER_END, MID_END) and o.ending is not None:  # the end clauses read the sample's inputs
        return maps + (inside if instant == MID_END and inside is not None else o.ending.end_map,)
    return maps


def _which_stop(w: tuple[Fraction, ...], o: Outcome, accruals: list[Affine],
                end: tuple[Fraction | None, int | None], prefixes: _Prefixes,
                last: bool, first: bool, l0: int) -> tuple[str, int | None]:
    """Which instant of a sample attains the stop value found by the recurrence (the first of them),
    and after how many updates of its sequence for MID_EDGE and MID_END; ``end``: the best end on
    inputs of its own (K_end) and where in its updates it is."""
    k_end, end_applied = end
    before: tuple[Affine, ...] = (accruals[l0],) if first else ()
    edge = sup_weighted(w, (*before, o.edge_map), o.box)[0]
    options: list[tuple[Fraction, str, int | None]] = [(edge, AFTER_EDGE, None)]
    inside: list[tuple[Fraction, str, int | None]] = [
        (sup_weighted(w, (*before, m), o.box)[0], MID_EDGE, applied) for applied, m in prefixes.edge(o.edge)]
    if o.ending is not None:  # the run ends here: its own end clauses, nothing after
        if o.ending.ends:
            options.append((sup_weighted(w, (*before, o.edge_map, o.ending.end_map), o.box)[0], AFTER_END, None))
        options += [(sup_weighted(w, (*before, o.edge_map, m), o.box)[0], MID_END, applied)
                    for applied, m in prefixes.end(o.ending)]
    else:
        if k_end is not None and k_end > 0:
            options.append((edge + k_end, AFTER_END if end_applied is None else MID_END, end_applied))
        if not last:
            options.append((sup_weighted(w, (*before, o.edge_map, accruals[o.target]), o.box)[0], BEFORE_NEXT, None))
    _, instant, applied = max(options + inside, key=lambda item: item[0])
    return instant, applied
