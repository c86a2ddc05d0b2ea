"""Determinism (E0301 and its witness), dead edges (W0304), an `assume` that excludes everything (E0305)
and unreachable locations (W0302), against a brute force over concrete input valuations, on random
small automata whose guards may overlap.

The oracle is written from docs/language.md, not from rac.check.analysis.behaviour: it evaluates every
guard on concrete values (both values of a bool; every whole value of an `int` input; a real input's
bounds, every constant a guard compares it with, and a point inside each interval between them), so a
valuation it finds is one a user can feed the runtime. E0301 is reported for a location exactly when
some allowed valuation enables two of its edges, and the printed witness must enable both edges named;
W0304 exactly for the edges no allowed valuation enables; E0305 exactly when no valuation is allowed;
and, for a deterministic automaton, W0302 exactly for the locations no run within the horizon visits
(the runtime steps every input sequence).
"""

from __future__ import annotations

import itertools
import os
import random
from fractions import Fraction

from hypothesis import HealthCheck, assume, given, settings
from hypothesis import strategies as st

from rac import ir
from rac.compiler import compile_text

SETTINGS = settings(max_examples=int(os.environ.get("RAC_EXAMPLES", "60")), deadline=None,
                    derandomize=not os.environ.get("RAC_EXAMPLES"),
                    suppress_health_check=[HealthCheck.too_slow])


def num(value: Fraction) -> str:
    return str(value.numerator) if value.denominator == 1 else f"{value.numerator}/{value.denominator}"


def program(rng: random.Random) -> str:
    """A random automaton as `.ra` text: guards are random conditions, so edges may overlap."""
    bools = ["a", "b"][: rng.randint(0, 2)]
    numeric = []
    for name in ("x", "y")[: rng.choice([0, 1, 1, 2])]:
        low = Fraction(rng.choice([-3, -2, -1, 0, 1]))
        high = low + rng.choice([0, 1, 2, 3])
        numeric.append((name, rng.choice(["real", "int"]), low, high))

    def atom() -> str:
        if bools and (not numeric or rng.random() < 0.4):
            b = rng.choice(bools)
            return rng.choice([b, f"!{b}"])
        name, _, low, high = rng.choice(numeric)
        t = rng.choice([low, high, (low + high) / 2, low - 1, high + Fraction(1, 2), Fraction(1, 3), Fraction(0)])
        op = rng.choice(["<", "<=", ">", ">=", "==", "!="])
        if rng.random() < 0.3:  # a scaled comparison: 2 * x + 1 op 2t + 1
            return f"2 * {name} + 1 {op} {num(2 * t + 1)}"
        if rng.random() < 0.2:  # the constant on the left
            return f"{num(t)} {op} {name}"
        return f"{name} {op} {num(t)}"

    def condition(depth: int = 0) -> str:
        if depth > 1 or rng.random() < 0.5:
            return atom()
        op = rng.choice([" && ", " || ", " imply "])
        return f"({condition(depth + 1)}{op}{condition(depth + 1)})" if op != " imply " else \
            f"({condition(depth + 1)} imply {condition(depth + 1)})"

    if not bools and not numeric:
        bools = ["a"]
    locations = [f"L{i}" for i in range(rng.randint(1, 4))]
    lines = ["automaton Random {"]
    lines += [f"    input {b} : bool" for b in bools]
    lines += [f"    input {n} : {k} in [{num(lo)}, {num(hi)}]" for n, k, lo, hi in numeric]
    if rng.random() < 0.4:
        lines.append(f"    assume {condition()}")
    lines += ["    reward s", "    priority s", "    objective s", "    sample every 1",
              f"    horizon {rng.randint(1, 3)}"]
    for i, name in enumerate(locations):
        lines.append(f"    {'initial ' if i == 0 else ''}location {name} {{ s' == 1 }}")
    for _ in range(rng.randint(1, 6)):
        source = rng.choice([*locations, "*"] if len(locations) > 1 else locations)
        target = rng.choice(locations)
        when = "" if rng.random() < 0.1 else f" when {condition()}"
        lines.append(f"    edge {source} -> {target}{when}")
    lines.append("}")
    return "\n".join(lines) + "\n"


def thresholds(guard: ir.Guard, name: str) -> set[Fraction]:
    return {leaf.threshold for leaf in ir.guard_leaves(guard) if isinstance(leaf, ir.BAtom) and leaf.input == name}


def concrete_valuations(a: ir.Automaton) -> list[dict[str, object]]:
    """Every valuation the oracle tries (allowed by `assume` or not)."""
    guards = [a.assume, *(e.guard for e in a.all_edges())]
    options = []
    for item in a.inputs:
        if item.is_bool:
            options.append([False, True])
            continue
        assert item.low is not None and item.high is not None
        if item.kind == "int":
            options.append([Fraction(v) for v in range(int(item.low), int(item.high) + 1)])
            continue
        cuts = sorted({item.low, item.high}.union(*(thresholds(g, item.name) for g in guards)))
        points = [c for c in cuts if item.low <= c <= item.high]
        options.append(points + [(p + q) / 2 for p, q in zip(points, points[1:])])
    names = [item.name for item in a.inputs]
    return [dict(zip(names, combo)) for combo in itertools.product(*options)]


def check_behaviour(text: str) -> None:
    result = compile_text(text, "random.ra")
    a = compile_text(text, "random.ra", analyse=False).automaton
    assert a is not None, text
    codes = [d.code for d in result.diagnostics]
    assume("E0306" not in codes)
    xs = concrete_valuations(a)
    allowed = [x for x in xs if ir.evaluate_guard(a.assume, x)]
    assert ("E0305" in codes) == (not allowed), text
    if not allowed:
        return
    # W0304: the edges no allowed valuation enables (a `*` edge is one edge per source: reported once)
    dead = {e.span for e in a.all_edges() if not any(ir.evaluate_guard(e.guard, x) for x in allowed)}
    live = {e.span for e in a.all_edges()} - dead
    reported_dead = {d.span for d in result.diagnostics if d.code == "W0304"}
    assert reported_dead == dead - live, (text, reported_dead, dead)
    # E0301: every pair of edges some allowed valuation enables together out of one location, once (the
    # copies of two `*` edges are one pair), and the witness enables both
    pairs = {frozenset((e.span, f.span)) for edges in a.edges for e, f in itertools.combinations(edges, 2)
             if any(ir.evaluate_guard(e.guard, x) and ir.evaluate_guard(f.guard, x) for x in allowed)}
    errors = [d for d in result.diagnostics if d.code == "E0301"]
    assert {frozenset((d.span, d.notes[0].span)) for d in errors} == pairs, (text, [d.message for d in errors])
    for d in errors:
        # the JSON holds doubles: 1/3 as 0.333...; every number here has a small denominator
        witness = {k: v if isinstance(v, bool) else Fraction(v).limit_denominator(1000)
                   for k, v in d.data["witness"].items()}
        assert set(witness) == {i.name for i in a.inputs}, (text, witness)
        assert ir.evaluate_guard(a.assume, witness), (text, witness, "the witness breaks `assume`")
        for item in a.numeric_inputs:
            value = witness[item.name]
            assert item.low <= value <= item.high, (text, witness, "the witness is out of range")
            assert item.kind != "int" or value.denominator == 1, (text, witness, "an int input not whole")
        location = a.location_names.index(d.data["location"])
        enabled = [e for e in a.edges[location] if ir.evaluate_guard(e.guard, witness)]
        assert len(enabled) >= 2, (text, witness, "the witness enables fewer than two edges")
        assert {e.span for e in enabled} >= {d.span, d.notes[0].span}, (text, witness, "not the edges named")
    if pairs:
        return
    # W0302: the locations no run visits within the horizon (every allowed valuation at every sample)
    seen = frontier = {a.initial}
    for _ in range(a.steps):
        frontier = {next((e.target for e in a.edges[here] if ir.evaluate_guard(e.guard, x)), here)
                    for here in frontier for x in allowed}
        seen = seen | frontier
    unreachable = {d.message.split("`")[1] for d in result.diagnostics if d.code == "W0302"}
    assert unreachable == {a.location_names[i] for i in range(len(a.locations)) if i not in seen}, (text, unreachable)


@SETTINGS
@given(st.randoms(use_true_random=False))
def test_behaviour_verdicts_agree_with_a_brute_force_of_concrete_valuations(rng: random.Random) -> None:
    check_behaviour(program(rng))
