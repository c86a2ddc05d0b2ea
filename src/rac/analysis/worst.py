"""The worst run: the supremum of a linear functional of the rewards over a bounded horizon.

Both P2 (priority soundness) and the int32 range check ask the same question:
over every run of at most ``steps`` samples, with inputs free at each sample
(subject to ``assume``), and every instant at which the automaton is in a
*watched* location, how large can ``w·r + w0`` become?

Between samples rewards change linearly, so only instants at samples matter:
just before an edge, just after it, and just after ``at end`` updates. The
search is a backward dynamic programme over sets of affine functionals of the
reward vector (exact for any affine updates, rational arithmetic). When every
update is a translation (``r = r + c``), the set collapses to one functional and
a vectorised max-plus recurrence in scaled integers answers in one pass.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from fractions import Fraction

import numpy as np

from rac import ir
from rac.analysis.affine import Affine, Outcome, accrual, sup_linear

ZERO = Fraction(0)
#: Instants of one sample, in time order.
BEFORE_EDGE, AFTER_EDGE, AFTER_END, BEFORE_NEXT, CONTINUE, START = (
    "before-edge", "after-edge", "after-end", "before-next", "continue", "start")


@dataclass(frozen=True)
class Target:
    """Maximise ``weights·r + constant`` over instants spent in ``watched`` locations."""

    weights: tuple[Fraction, ...]
    constant: Fraction
    watched: tuple[bool, ...]


@dataclass(frozen=True)
class Step:
    """One sample of the worst run: where it was, what the inputs did, and which instant ends it."""

    sample: int  # 1-based
    outcome: Outcome
    inputs: dict[str, Fraction]  # values of the numeric inputs the arithmetic reads
    instant: str  # CONTINUE, or the instant at which the run reaches the supremum


@dataclass
class Worst:
    value: Fraction
    steps: list[Step] = field(default_factory=list)
    instant: str = START


# ---------------------------------------------------------------- generic engine
_Func = tuple[tuple[Fraction, ...], Fraction, dict[str, Fraction]]


class _Puller:
    """Pull functionals back through affine maps, memoised (runs repeat the same maps)."""

    def __init__(self) -> None:
        self.cache: dict[tuple[tuple[Fraction, ...], int], tuple[tuple[Fraction, ...], Fraction, dict]] = {}
        self.keep: list[Affine] = []

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


def maximise(automaton: ir.Automaton, outs: list[list[Outcome]], target: Target) -> Worst | None:
    """The worst run for ``target`` (None when no watched instant is reachable)."""
    translations = all(o.edge_map.is_translation and o.end_map.is_translation for os in outs for o in os)
    if translations:
        return _maximise_translations(automaton, outs, target)
    return _maximise_generic(automaton, outs, target)


def _maximise_generic(automaton: ir.Automaton, outs: list[list[Outcome]], target: Target) -> Worst | None:
    steps = automaton.steps
    accruals = [accrual(loc, automaton.period) for loc in automaton.locations]
    pull = _Puller()
    base: _Func = (target.weights, target.constant, {})
    l0 = automaton.initial
    # tables[k][l]: functional coefficients -> (d, outcome index, instant, next coefficients, x point)
    tables: list[list[dict]] = [[] for _ in range(steps + 2)]
    tables[steps + 1] = [{} for _ in automaton.locations]
    for k in range(steps, 0, -1):
        layer: list[dict] = [{} for _ in automaton.locations]
        for here in (range(len(automaton.locations)) if k > 1 else [l0]):
            best = layer[here]
            for oi, o in enumerate(outs[here]):
                t = o.target
                candidates: list[tuple[_Func, str, tuple | None]] = []
                if target.watched[t]:
                    candidates.append((base, AFTER_EDGE, None))
                    candidates.append((pull(base, o.end_map), AFTER_END, None))
                    if k < steps:
                        candidates.append((pull(base, accruals[t]), BEFORE_NEXT, None))
                if k < steps:
                    for c_next, entry in tables[k + 1][t].items():
                        candidates.append((pull((c_next, entry[0], {}), accruals[t]), CONTINUE, c_next))
                for func, instant, c_next in candidates:
                    func = pull(func, o.edge_map)
                    if k == 1:
                        func = pull(func, accruals[l0])
                    _offer(best, func, o, oi, instant, c_next)
                if k == 1 and target.watched[l0]:
                    _offer(best, pull(base, accruals[l0]), o, oi, BEFORE_EDGE, None)
        tables[k] = layer
    first = tables[1][l0]
    start = target.constant if target.watched[l0] else None
    if not first:
        return None if start is None else Worst(start)
    c_best = max(first, key=lambda c: first[c][0])
    value = first[c_best][0]
    if start is not None and start >= value:
        return Worst(start)
    result = Worst(value)
    k, here, c = 1, l0, c_best
    while True:
        d, oi, instant, c_next, point = tables[k][here][c]
        o = outs[here][oi]
        result.steps.append(Step(k, o, point, instant))
        if instant != CONTINUE:
            result.instant = instant
            return result
        k, here, c = k + 1, o.target, c_next


def _offer(best: dict, func: _Func, o: Outcome, oi: int, instant: str, c_next) -> None:
    c, d, g = func
    bonus, point = sup_linear(g, o.box)
    total = d + bonus
    entry = best.get(c)
    if entry is None or total > entry[0]:
        best[c] = (total, oi, instant, c_next, point)


# ---------------------------------------------------------------- fast engine
def _maximise_translations(automaton: ir.Automaton, outs: list[list[Outcome]], target: Target) -> Worst | None:
    """Every map is a translation: the functional stays ``w``; a max-plus recurrence on scalars.

    V_k(l) = max over outcomes o of l of
             max(watched(t)·(w0 + max(K_edge, K_end, K_next)), V_{k+1}(t) + K_next)
    where K_* are the sup over the outcome's input box of the weighted offsets of one sample.
    """
    steps = automaton.steps
    l0 = automaton.initial
    w = target.weights
    if not any(outs):  # `assume` excludes every input: no sample ever happens
        return Worst(target.constant) if target.watched[l0] else None
    accruals = [accrual(loc, automaton.period) for loc in automaton.locations]

    def weighted(*maps: Affine) -> dict[str, Fraction] | Fraction:
        return _weigh(w, maps)

    rows = []  # per (l, o): (l, t, K_edge, K_end, K_next, points)
    for here, os in enumerate(outs):
        for oi, o in enumerate(os):
            t = o.target
            k_edge = _sup(weighted(o.edge_map), o)
            k_end = _sup(weighted(o.edge_map, o.end_map), o)
            k_next = _sup(weighted(o.edge_map, accruals[t]), o)
            rows.append((here, oi, t, k_edge, k_end, k_next))
    first_rows = []  # sample 1 from l0, with the accrual before the edge in the same x
    for oi, o in enumerate(outs[l0]):
        t = o.target
        first_rows.append((oi, t,
                           _sup(weighted(accruals[l0], o.edge_map), o),
                           _sup(weighted(accruals[l0], o.edge_map, o.end_map), o),
                           _sup(weighted(accruals[l0], o.edge_map, accruals[t]), o),
                           _sup(weighted(accruals[l0]), o)))
    values = [v for r in rows for v in r[3:]] + [v for r in first_rows for v in r[2:]] + [target.constant]
    scale = math.lcm(*(v.denominator for v in values))
    n_loc = len(automaton.locations)
    width = max(len(os) for os in outs)
    # Dense [location, outcome] tables; padding rows can never win.
    # Every reachable value lies within ±magnitude; "minus infinity" must lie well below, and
    # padding added to it must stay below neg_inf // 2 (the "reachable" test).
    magnitude = int(max(abs(v) for v in values) * scale * (steps + 2))
    if magnitude < (1 << 60):
        dtype: type | str = np.int64
        neg_inf = -(1 << 62)
    else:  # exact Python integers
        dtype = object
        neg_inf = -4 * (magnitude + 1)
    targets = np.zeros((n_loc, width), dtype=np.int64)
    stop = np.full((n_loc, width), neg_inf, dtype=dtype)
    stop_last = np.full((n_loc, width), neg_inf, dtype=dtype)
    k_next = np.full((n_loc, width), neg_inf, dtype=dtype)
    w0 = int(target.constant * scale)
    for here, oi, t, ke, kd, kn in rows:
        targets[here, oi] = t
        k_next[here, oi] = int(kn * scale)
        if target.watched[t]:
            stop[here, oi] = w0 + int(max(ke, kd, kn) * scale)
            stop_last[here, oi] = w0 + int(max(ke, kd) * scale)
    value = np.full(n_loc, neg_inf, dtype=dtype)
    choice = np.zeros((steps + 1, n_loc), dtype=np.int32)
    stopped = np.zeros((steps + 1, n_loc), dtype=bool)
    for k in range(steps, 1, -1):
        if k == steps:
            cont = np.full((n_loc, width), neg_inf, dtype=dtype)
            s = stop_last
        else:
            cont = np.where(value[targets] > neg_inf // 2, value[targets] + k_next, neg_inf)
            s = stop
        cand = np.maximum(s, cont)
        best = cand.argmax(axis=1)
        rows_idx = np.arange(n_loc)
        choice[k] = best
        stopped[k] = s[rows_idx, best] >= cont[rows_idx, best]
        value = cand[rows_idx, best]
    # Sample 1, from the initial location only.
    best_value, best_choice = None, None
    for oi, t, ke, kd, kn, kb in first_rows:
        options = []
        if target.watched[t]:
            options += [(w0 + int(ke * scale), AFTER_EDGE), (w0 + int(kd * scale), AFTER_END)]
            if steps > 1:
                options.append((w0 + int(kn * scale), BEFORE_NEXT))
        if target.watched[l0]:
            options.append((w0 + int(kb * scale), BEFORE_EDGE))
        if steps > 1 and value[t] > neg_inf // 2:
            options.append((int(value[t]) + int(kn * scale), CONTINUE))
        for v, instant in options:
            if best_value is None or v > best_value:
                best_value, best_choice = v, (oi, instant)
    start = target.constant if target.watched[l0] else None
    if best_value is None:
        return None if start is None else Worst(start)
    if start is not None and start * scale >= best_value:
        return Worst(start)
    result = Worst(Fraction(best_value, scale))
    oi, instant = best_choice  # type: ignore[misc]
    here, k = l0, 1
    while True:
        o = outs[here][oi]
        if instant != CONTINUE and k > 1:
            instant = _which_stop(target, o, w, accruals, k == steps)
        point = _point(_weigh(w, _maps_for(instant, o, accruals, first=k == 1, l0=l0)), o)
        result.steps.append(Step(k, o, point, instant))
        if instant != CONTINUE:
            result.instant = instant
            return result
        here, k = o.target, k + 1
        oi = int(choice[k, here])
        instant = CONTINUE if not stopped[k, here] else "stop"


def _maps_for(instant: str, o: Outcome, accruals: list[Affine], *, first: bool, l0: int) -> tuple[Affine, ...]:
    maps: tuple[Affine, ...] = (accruals[l0],) if first else ()
    if instant == BEFORE_EDGE:
        return maps
    maps += (o.edge_map,)
    if instant == AFTER_END:
        return maps + (o.end_map,)
    if instant in (BEFORE_NEXT, CONTINUE):
        return maps + (accruals[o.target],)
    return maps


def _which_stop(target: Target, o: Outcome, w, accruals: list[Affine], last: bool) -> str:
    options = [(_sup(_weigh(w, (o.edge_map,)), o), AFTER_EDGE),
               (_sup(_weigh(w, (o.edge_map, o.end_map)), o), AFTER_END)]
    if not last:
        options.append((_sup(_weigh(w, (o.edge_map, accruals[o.target])), o), BEFORE_NEXT))
    return max(options, key=lambda item: item[0])[1]


def _weigh(w: tuple[Fraction, ...], maps: tuple[Affine, ...]) -> dict[str, Fraction]:
    """``w·(sum of the maps' offsets)`` as {"": constant, input: coefficient} (translations only)."""
    form: dict[str, Fraction] = {"": ZERO}
    for affine in maps:
        for k, offset in enumerate(affine.offset):
            if w[k]:
                form[""] += w[k] * offset.const
                for name, coefficient in offset.terms:
                    form[name] = form.get(name, ZERO) + w[k] * coefficient
    return form


def _sup(form: dict[str, Fraction] | Fraction, o: Outcome) -> Fraction:
    assert isinstance(form, dict)
    linear = {k: v for k, v in form.items() if k}
    bonus, _ = sup_linear(linear, o.box)
    return form[""] + bonus


def _point(form: dict[str, Fraction], o: Outcome) -> dict[str, Fraction]:
    return sup_linear({k: v for k, v in form.items() if k}, o.box)[1]
