"""Every verdict `rac check` gives on P1, P2 and the int32 range, against a brute force of every input
sequence, on random small `.ra` programs; and every P2 counterexample it prints, replayed by the runtime.

The programs come from the whole language the checks read: bool, real and int inputs (thresholds
between whole values, scaled comparisons such as `2 * x + 1 < 2`), `assume`, one to four locations,
`*` edges, rates and updates that read inputs, updates that scale, reset or reflect rewards and
sequences of them, `at end` clauses, `episode ends when`, objective weights that are zero, negative or
fractions with a constant term, and `priority strict`. Determinism holds by construction: every
location partitions the input *cells* among its edges.

The oracle is written here from docs/language.md's semantics, not from the analyses: it simulates
every run over every input sequence exactly (Fractions), with each numeric input at every threshold,
inside every interval between them for the guards, and at the interval's two ends for the arithmetic
(a value at an instant is affine in each sample's inputs, so its supremum over an interval is at an
end of its closure). It reads only the IR. Which locations penalise a reward is rac's (`p2_target`)
for the value; the oracle's own reading of the docs (a rate that can be negative, or an edge whose
updates together can lower the reward) must be a subset of it, and must refute wherever rac refutes.
"""

from __future__ import annotations

import dataclasses
import itertools
import math
import os
import random
from fractions import Fraction

from hypothesis import HealthCheck, assume, given, reject, settings
from hypothesis import strategies as st

from rac import ir
from rac.check.analysis.priority import p2_target
from rac.compiler import compile_text
from rac.runtime.interpreter import RewardAutomaton

SETTINGS = settings(max_examples=int(os.environ.get("RAC_EXAMPLES", "15")), deadline=None,
                    derandomize=not os.environ.get("RAC_EXAMPLES"),
                    suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])
ZERO = Fraction(0)
INT32_MAX, INT32_MIN = 2**31 - 1, -(2**31)
SCALE = 10**4  # the default number representation: base 10, exponent 4
#: Cases whose brute force would go through more (state, valuation) pairs at a sample are dropped (they
#: make the test slow, not wrong).
MAX_STATES = 20_000


def num(value: Fraction | int) -> str:
    value = Fraction(value)
    return str(value.numerator) if value.denominator == 1 else f"{value.numerator}/{value.denominator}"


# ---------------------------------------------------------------- programs
def program(rng: random.Random) -> str:
    """A random deterministic automaton, as `.ra` text."""
    bools = ["a", "b"][: rng.randint(0, 2)]
    numeric: list[tuple[str, str, int, int, list[Fraction]]] = []
    if rng.random() < 0.7:
        low, high = rng.choice([-2, -1, 0]), rng.choice([1, 2, 3])
        cuts = sorted({rng.choice([Fraction(low), Fraction(high), Fraction(1), Fraction(1, 2), Fraction(0),
                                   Fraction(-1, 2)]) for _ in range(rng.randint(1, 2))})
        numeric.append(("x", rng.choice(["real", "real", "int"]), low, high, [c for c in cuts if low <= c <= high]))
        if rng.random() < 0.3:
            numeric.append(("y", rng.choice(["real", "int"]), -1, 1, [ZERO]))
    rewards = ["p", "q", "s"][: rng.randint(1, 3)]
    locations = [f"L{i}" for i in range(rng.randint(1, 4))]
    period = rng.choice([Fraction(1), Fraction(1, 2), Fraction(1, 10)])

    literal_sets = [[b, f"!{b}"] for b in bools]
    for name, _, low, _, cuts in numeric:
        t = cuts[0] if cuts else Fraction(low)
        op, negated = rng.choice([("<", ">="), ("<=", ">"), ("==", "!=")])
        if len(cuts) > 1 and op in ("<", "<="):
            literal_sets.append([f"{name} {op} {num(t)}", f"{name} {negated} {num(t)} && {name} < {num(cuts[1])}",
                                 f"{name} >= {num(cuts[1])}"])
        elif rng.random() < 0.5:
            literal_sets.append([f"{name} {op} {num(t)}", f"{name} {negated} {num(t)}"])
        else:
            literal_sets.append([f"2 * {name} + 1 {op} {num(2 * t + 1)}", f"2 * {name} + 1 {negated} {num(2 * t + 1)}"])
    cells = [" && ".join(f"({c})" for c in combo) for combo in itertools.product(*literal_sets)] or ["true"]

    def guard(chosen: list[int]) -> str:
        return "true" if len(chosen) == len(cells) else " || ".join(f"({cells[i]})" for i in sorted(chosen))

    def some_cells() -> list[int]:
        return rng.sample(range(len(cells)), rng.randint(1, len(cells)))

    def inputs() -> str:
        return "".join(f" + {rng.choice(['1', '-1', '1/2', '-2'])} * {name}"
                       for name, *_ in numeric if rng.random() < 0.4)

    def constant() -> str:
        return num(Fraction(rng.randint(-3, 3), rng.choice([1, 2])))

    def update() -> str:
        r, other, c = rng.choice(rewards), rng.choice(rewards), constant()
        return rng.choice([f"{r} = {r} + {c}", f"{r} += {c}", f"{r} -= {c}", f"{r} = {r} + {c}{inputs()}",
                           f"{r} = 0", f"{r} = {r} / 2", f"{r} = {c} - {r}", f"{r} = 2 * {r} + {c}",
                           f"{other} = {r} + 1"])

    def updates() -> str:
        items = [update() for _ in range(rng.choice([0, 0, 1, 1, 2, 3]))]
        return f" do {', '.join(items)}" if items else ""

    lines = ["automaton Random {"]
    lines += [f"    input {b} : bool" for b in bools]
    lines += [f"    input {name} : {kind} in [{low}, {high}]" for name, kind, low, high, _ in numeric]
    if len(cells) > 1 and rng.random() < 0.4:
        lines.append(f"    assume !({guard(rng.sample(range(len(cells)), rng.randint(1, len(cells) - 1)))})")
    order = rng.sample(rewards, len(rewards))
    lines.append(f"    reward {', '.join(rewards)}")
    lines.append(f"    priority {'strict ' if rng.random() < 0.4 else ''}{' > '.join(order)}")
    weights = " + ".join(f"{num(rng.choice([1, 2, 3, 10, -1, 0, Fraction(1, 2)]))} * {r}" for r in rewards)
    term = rng.choice([None, None, Fraction(1), Fraction(-1), Fraction(-1, 2)])
    lines.append(f"    objective {weights}{'' if term is None else ' + ' + num(term)}")
    lines.append(f"    sample every {num(period)}")
    lines.append(f"    horizon {num(rng.randint(1, 4) * period)}")
    initial = rng.randrange(len(locations))
    for i, name in enumerate(locations):
        flows = "; ".join(f"{r}' == {constant()}{inputs()}" for r in rewards if rng.random() < 0.8)
        lines.append(f"    {'initial ' if i == initial else ''}location {name} {{ {flows} }}")
    star: tuple[int, set[int]] | None = None
    if len(locations) > 1 and rng.random() < 0.4:
        star = (rng.randrange(len(locations)), set(some_cells()))
        lines.append(f"    edge * -> {locations[star[0]]} when {guard(sorted(star[1]))}{updates()}")
    for i, name in enumerate(locations):
        free = [c for c in range(len(cells)) if star is None or star[0] == i or c not in star[1]]
        choice = {c: rng.choice([None, *range(len(locations))]) for c in free}
        for target in range(len(locations)):
            chosen = [c for c in free if choice[c] == target]
            if chosen:
                lines.append(f"    edge {name} -> {locations[target]} when {guard(chosen)}{updates()}")
    for _ in range(rng.choice([0, 0, 1, 2])):
        chosen = some_cells()
        when = "" if len(chosen) == len(cells) else f" when {guard(chosen)}"
        lines.append(f"    at end{when} do {', '.join(update() for _ in range(rng.randint(1, 2)))}")
    if rng.random() < 0.35:
        lines.append(f"    episode ends when {guard(some_cells())}")
    lines.append("}")
    return "\n".join(lines) + "\n"


# ---------------------------------------------------------------- the brute force
def holds(guard: ir.Guard, x: dict[str, object]) -> bool:
    if isinstance(guard, ir.BConst):
        return guard.value
    if isinstance(guard, ir.BInput):
        return bool(x[guard.name])
    if isinstance(guard, ir.BAtom):
        value, t = x[guard.input], guard.threshold
        return {"<": value < t, "<=": value <= t, ">": value > t, ">=": value >= t,  # type: ignore[operator]
                "==": value == t, "!=": value != t}[guard.op]
    if isinstance(guard, ir.BNot):
        return not holds(guard.operand, x)
    if isinstance(guard, ir.BAnd):
        return all(holds(g, x) for g in guard.operands)
    assert isinstance(guard, ir.BOr)
    return any(holds(g, x) for g in guard.operands)


def thresholds(guard: ir.Guard, name: str) -> set[Fraction]:
    if isinstance(guard, ir.BAtom):
        return {guard.threshold} if guard.input == name else set()
    if isinstance(guard, ir.BNot):
        return thresholds(guard.operand, name)
    if isinstance(guard, (ir.BAnd, ir.BOr)):
        return set().union(*(thresholds(g, name) for g in guard.operands))
    return set()


@dataclasses.dataclass(frozen=True)
class Valuation:
    guards: dict[str, object]  # decides the guards
    values: dict[str, object]  # feeds the arithmetic


def valuations(a: ir.Automaton, inside: int = 0) -> list[Valuation]:
    """Per class of the guards: its representative, and the arithmetic at the closure's ends (or, with
    ``inside``, at that many points strictly inside an open interval)."""
    guards = [a.assume, *(e.guard for e in a.all_edges()), *(c.guard for c in a.end_clauses)]
    guards += [g for g in (a.episode_ends, a.goal, a.collision) if g is not None]
    names, options = [], []
    for item in a.inputs:
        names.append(item.name)
        if item.is_bool:
            options.append([(False, [False]), (True, [True])])
            continue
        assert item.low is not None and item.high is not None
        if item.kind == "int":
            options.append([(Fraction(v), [Fraction(v)]) for v in range(int(item.low), int(item.high) + 1)])
            continue
        cuts = {item.low, item.high}.union(*(thresholds(g, item.name) for g in guards))
        points = sorted(c for c in cuts if item.low <= c <= item.high)
        choices: list[tuple[object, list[object]]] = [(p, [p]) for p in points]
        for lo, hi in zip(points, points[1:]):
            within = [lo + (hi - lo) * Fraction(k, inside + 1) for k in range(1, inside + 1)]
            choices.append(((lo + hi) / 2, within if inside else [lo, hi]))
        options.append(choices)
    result = []
    for combo in itertools.product(*options):
        chosen = {n: c[0] for n, c in zip(names, combo)}
        if holds(a.assume, chosen):
            arithmetic = itertools.product(*(c[1] for c in combo))
            result += [Valuation(chosen, dict(zip(names, values))) for values in arithmetic]
    return result


def value(linear: ir.Linear, env: dict[str, object]) -> Fraction:
    return linear.const + sum((c * env[n] for n, c in linear.terms), ZERO)  # type: ignore[misc]


def assign(a: ir.Automaton, updates: tuple[ir.Assignment, ...], r: tuple[Fraction, ...], x: dict[str, object],
           between: list[tuple[Fraction, ...]]) -> tuple[Fraction, ...]:
    env = {**x, **dict(zip(a.rewards, r))}
    for i, update in enumerate(updates, start=1):
        env[update.reward] = value(update.value, env)
        if i < len(updates):
            between.append(tuple(env[n] for n in a.rewards))  # type: ignore[misc]
    return tuple(env[n] for n in a.rewards)  # type: ignore[misc]


def accrue(a: ir.Automaton, location: int, r: tuple[Fraction, ...], x: dict[str, object]) -> tuple[Fraction, ...]:
    return tuple(v + a.period * value(rate, x) for v, rate in zip(r, a.locations[location].rates))


class TooLarge(Exception):
    """The program has too many valuations or runs for the oracle to enumerate (the example is skipped)."""


def observations(a: ir.Automaton) -> tuple[set[tuple[int, tuple[Fraction, ...]]], set[tuple[Fraction, ...]]]:
    """Every (location, rewards) at an instant of some run (t = 0, before and after a sample's edge,
    after the `at end` updates of a run that ends there), and the values in between a sequence of
    updates (what the UPPAAL model stores)."""
    xs = valuations(a)
    seen: set[tuple[int, tuple[Fraction, ...]]] = set()
    between: list[tuple[Fraction, ...]] = []
    # what each valuation does, decided once: the edge it takes from each location, whether it ends
    # the episode, and the `at end` updates it enables
    edges: list[list[ir.Edge | None]] = []
    for location in range(len(a.locations)):
        row: list[ir.Edge | None] = []
        for v in xs:
            enabled = [e for e in a.edges[location] if holds(e.guard, v.guards)]
            assert len(enabled) <= 1
            row.append(enabled[0] if enabled else None)
        edges.append(row)
    stops = [a.episode_ends is not None and holds(a.episode_ends, v.guards) for v in xs]
    finals = [tuple(u for c in a.end_clauses if holds(c.guard, v.guards) for u in c.updates) for v in xs]

    def end(location: int, r: tuple[Fraction, ...], i: int) -> None:
        seen.add((location, assign(a, finals[i], r, xs[i].values, between)))

    zero = tuple(ZERO for _ in a.rewards)
    seen.add((a.initial, zero))
    for i in range(len(xs)):  # a run may end before its first sample, with inputs of its own
        end(a.initial, zero, i)
    frontier, ended = {(a.initial, zero)}, set()
    for k in range(1, a.steps + 1):
        following = set()
        for location, r in frontier:
            for i, v in enumerate(xs):
                if k == 1:
                    r1 = accrue(a, location, r, v.values)
                    seen.add((location, r1))
                else:
                    r1 = r
                edge = edges[location][i]
                here, r2 = location, r1
                if edge is not None:
                    here, r2 = edge.target, assign(a, edge.updates, r1, v.values, between)
                seen.add((here, r2))
                if stops[i]:
                    end(here, r2, i)  # the run ends here, its `at end` clauses on this sample's inputs
                    continue
                if (here, r2) not in ended:  # or it ends here with inputs of its own
                    ended.add((here, r2))
                    for j in range(len(xs)):
                        end(here, r2, j)
                if k < a.steps:
                    after = accrue(a, here, r2, v.values)
                    seen.add((here, after))
                    following.add((here, after))
        if len(following) * len(xs) > MAX_STATES:
            raise TooLarge
        frontier = following
    return seen, set(between)


def penalised(a: ir.Automaton, reward: str, xs: list[Valuation]) -> tuple[bool, ...]:
    """docs/checks.md: a rate that some allowed input makes negative, or an edge into the location whose
    updates, taken together, lower the reward for some allowed input its guard lets through (or read a
    reward, which may lower it)."""
    k = a.rewards.index(reward)
    marks = [any(value(loc.rates[k], v.values) < 0 for v in xs) for loc in a.locations]
    for edge in a.all_edges():
        env = {r: ir.Linear.variable(r) for r in a.rewards}
        for update in edge.updates:
            total = ir.Linear(update.value.const)
            for n, c in update.value.terms:
                total = total + (env[n] if n in env else ir.Linear.variable(n)).scaled(c)
            env[update.reward] = total
        delta = env[reward] - ir.Linear.variable(reward)
        if any(n in a.rewards for n in delta.variables()) or any(
                holds(edge.guard, v.guards) and value(delta, v.values) < 0 for v in xs):
            marks[edge.target] = True
    return tuple(marks)


def weighted(a: ir.Automaton, level: int) -> tuple[dict[str, Fraction], Fraction]:
    ranked = set(a.priority[level:])
    weights = {r: a.objective.coefficient(r) if r in ranked else ZERO for r in a.rewards}
    return weights, a.objective.const if level == 0 else ZERO


def worst(a: ir.Automaton, seen, level: int, watched: tuple[bool, ...]) -> Fraction | None:
    weights, constant = weighted(a, level)
    values = [constant + sum((weights[n] * v for n, v in zip(a.rewards, r)), ZERO)
              for location, r in seen if watched[location]]
    return max(values, default=None)


def p1_conflicts(a: ir.Automaton) -> set[tuple[str, str, str]]:
    index = {r: i for i, r in enumerate(a.rewards)}
    numeric = [item.name for item in a.numeric_inputs]
    # the points alone (the boolean inputs' values do not enter a rate)
    xs = [dict(point) for point in {tuple((n, v.values[n]) for n in numeric) for v in valuations(a, inside=97)}]
    found = set()
    for location in a.locations:
        for i, high in enumerate(a.priority):
            for low in a.priority[i + 1:]:
                f, g = location.rates[index[high]], location.rates[index[low]].scaled(a.objective.coefficient(low))
                if any(value(f, x) < 0 < value(g, x) for x in xs):
                    found.add((location.name, high, low))
    return found


# ---------------------------------------------------------------- a counterexample replayed
def replayed(a: ir.Automaton, data: dict, level: int) -> tuple[float, str]:
    """The E0402 run of ``data`` fed to the runtime: the weighted sum at its violating instant, and the
    location there."""
    # right after the edge of a sample that ends the episode comes before its `at end` updates, which
    # the runtime's step applies too: replay without them unless the run ends with them
    automaton = a if data["end"] is not None else dataclasses.replace(a, end_clauses=())
    runtime = RewardAutomaton(automaton)
    weights, constant = weighted(a, level)

    def total(rewards: dict[str, float]) -> float:
        return float(constant) + sum(float(weights[r]) * rewards[r] for r in a.rewards)

    def accrued(location: int, x: dict[str, object]) -> dict[str, float]:
        rates = a.locations[location].rates
        return {r: runtime.rewards[r] + float(a.period * value(rates[i], x)) for i, r in enumerate(a.rewards)}

    samples = [(entry, s) for entry in data["run"] for s in range(entry["sample"], entry["last_sample"] + 1)]
    for entry, sample in samples:
        x = {k: v if isinstance(v, bool) else Fraction(v) for k, v in entry["inputs"].items()}
        if sample == 1 and entry["instant"] == "before-edge":
            return total(accrued(a.initial, x)), runtime.location
        runtime.step({k: v if isinstance(v, bool) else float(v) for k, v in x.items()})
        if entry["instant"] == "before-next":
            return total(accrued(a.location_names.index(runtime.location), x)), runtime.location
    if data["end"] is not None:
        runtime.end({k: v if isinstance(v, bool) else float(Fraction(v)) for k, v in data["end"]["inputs"].items()})
    return total(runtime.rewards), runtime.location


# ---------------------------------------------------------------- the property
def check_verdicts(text: str) -> None:
    result = compile_text(text, "random.ra")
    a = compile_text(text, "random.ra", analyse=False).automaton
    assert a is not None, text
    codes = {d.code for d in result.diagnostics}
    # a program the oracle has nothing to compare on (nondeterministic, undecided) or cannot enumerate is
    # rejected, not passed: hypothesis counts it and draws another
    assume(not codes & {"E0301", "E0305", "E0306", "W0405"})
    try:
        seen, between = observations(a)
    except TooLarge:
        reject()
    xs = valuations(a)
    # P1: exactly the conflicts a grid of allowed inputs finds
    p1 = {(d.data["location"], d.data["decreasing"], d.data["increasing"]) for d in result.diagnostics
          if d.code == "E0401"}
    assert p1 == p1_conflicts(a), text
    # P2: the proved bound is the brute force's worst value (<= 0); a refutation's value too (> 0)
    errors = {d.data["level"]: d for d in result.diagnostics if d.code == "E0402"}
    bounds = {f.data["reward"]: f for f in result.facts if f.check == "P2"}
    for level in range(len(a.priority)) if a.strict else range(1):
        watched = p2_target(a, level).watched
        documented = penalised(a, a.priority[level], xs)
        assert all(w or not d for w, d in zip(watched, documented)), (level, watched, documented, text)
        expected = worst(a, seen, level, watched)
        if level in errors:
            data = errors[level].data
            assert expected is not None and Fraction(data["value"]) == expected > 0, (level, expected, text)
            refuted = worst(a, seen, level, documented)
            assert refuted is not None and refuted > 0, (level, "a location the docs do not call penalised", text)
            got, where = replayed(a, data, level)
            assert watched[a.location_names.index(where)], text
            if not any(e["approached"] for e in data["run"]) and not (data["end"] or {}).get("approached"):
                assert math.isclose(got, float(expected), rel_tol=1e-9, abs_tol=1e-9), (got, expected, text)
            else:  # a supremum: the inputs are a run near enough it to violate all the same
                assert got > 0, (got, expected, text)
        else:
            fact = bounds[a.priority[level]]
            assert expected is None or expected <= 0, (level, expected, text)
            proved = fact.data.get("bound")
            assert proved == (None if expected is None else str(expected)), (fact.message, expected, text)
    # the int32 range: the proved extremes are the brute force's, values in between updates included
    values = [v for _, r in seen for v in r] + [v for r in between for v in r] + [ZERO]
    low, high = min(values), max(values)
    overflows = high * SCALE >= INT32_MAX + 1 or low * SCALE <= INT32_MIN - 1
    (fact,) = [f for f in result.facts if f.check == "range"] or [None]
    if fact is not None:
        assert not overflows and (Fraction(fact.data["low"]), Fraction(fact.data["high"])) == (low, high), text
    elif "E0501" in codes:
        assert overflows, text
    else:  # what the UPPAAL model computes on the way to an update's value leaves int32 (E0801)
        assert "E0801" in codes, text


@SETTINGS
@given(st.randoms(use_true_random=False))
def test_verdicts_agree_with_a_brute_force_of_every_input_sequence(rng: random.Random) -> None:
    check_verdicts(program(rng))


@SETTINGS
@given(st.randoms(use_true_random=False))
def test_the_range_verdict_at_int32_scale_agrees_with_the_brute_force(rng: random.Random) -> None:
    """The same programs with one constant in the hundreds of thousands: rewards near and past the int32
    range at base 10, exponent 4 (214748.3647), in between a sequence of updates too."""
    text = program(rng)
    big = rng.choice(["100000", "-100000", "214748.3647", "-214748.3648", "150000", "107374.1824"])
    lines = text.splitlines()
    chosen = [i for i, line in enumerate(lines) if " = " in line or "' == " in line]
    if chosen:
        i = rng.choice(chosen)
        lines[i] = lines[i].replace(" + 1", f" + {big}", 1).replace("== 1", f"== {big}", 1).replace(
            "= 0", f"= {big}", 1)
    check_verdicts("\n".join(lines) + "\n")
