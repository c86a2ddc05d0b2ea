"""The Environment of the automaton-alone UPPAAL model offers every outcome the file's queries can tell.

The emitted model gives a numeric input one value per piece of its range (docs/uppaal.md, "Numbers").
The pieces once came from the guards alone, so a query comparing the input with a number of its own
could never see a value the automaton can: for `input n : int in [0, 10]` the model offered 0, 1
and 10, and `E<> n == 7` was not satisfied in UPPAAL while rac (rac.check.analysis.invariant, every
input sequence) finds the run. Here, on random inputs, guards and queries, the set of truth-vectors of
every comparison (the guards' and the queries') over the values the Environment offers must be the
set over every significand of the range: the UPPAAL model compares significands, exactly (a number
without a whole significand rounded so that every integer keeps its truth), so that is what it can tell.
"""

from __future__ import annotations

import re
from fractions import Fraction

import numpy as np
from hypothesis import HealthCheck, assume, given, reject, settings
from hypothesis import strategies as st

from rac.check.analysis.invariant import REFUTED, decide_invariant
from rac.compiler import compile_text
from rac.ir import expr as ie
from rac.targets.uppaal.automaton import UppaalError, generate_uppaal

SCALE = 10**4  # base 10, exponent 4: the automaton alone
OPS = ("<", "<=", ">", ">=", "==", "!=")
TEXT = """automaton R {{
    input x : {kind} in [{low}, {high}]
    reward s
    objective s
    sample every 1
    horizon 2
    initial location A {{ s' == 1 }}
    location B {{ s' == 1 }}
{edges}
{queries}
}}
"""


def num(value: Fraction) -> str:
    return str(value.numerator) if value.denominator == 1 else f"{value.numerator}/{value.denominator}"


def holds(op: str, value: np.ndarray, threshold: Fraction) -> np.ndarray:
    """``value / SCALE op threshold`` exactly, on integer significands."""
    left, right = value * threshold.denominator, threshold.numerator * SCALE
    return {"<": left < right, "<=": left <= right, ">": left > right, ">=": left >= right,
            "==": left == right, "!=": left != right}[op]


def outcomes(values: np.ndarray, atoms: list[tuple[str, Fraction]]) -> set[tuple[bool, ...]]:
    table = np.stack([holds(op, values, t) for op, t in atoms], axis=1)
    return {tuple(bool(b) for b in row) for row in np.unique(table, axis=0)}


def offered(xml: str) -> list[int]:
    (values,) = re.findall(r"const int32_t x_values\[\d+\] = \{([^}]*)\};", xml)
    return [int(v) for v in values.split(",")]


thresholds = st.sampled_from([Fraction(v) for v in (-3, -1, 0, 1, 2, 3, 5, 7)]
                             + [Fraction(1, 2), Fraction(1, 3), Fraction(-5, 4), Fraction(3, 20000), Fraction(7, 3)])
comparisons = st.tuples(st.sampled_from(OPS), thresholds)


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(kind=st.sampled_from(["real", "int"]), low=st.integers(-3, 1), width=st.integers(0, 8),
       guards=st.lists(comparisons, max_size=2), queries=st.lists(comparisons, min_size=1, max_size=3),
       scaled=st.booleans())
def test_the_environment_offers_every_outcome_of_the_guards_and_the_queries(
        kind: str, low: int, width: int, guards: list[tuple[str, Fraction]],
        queries: list[tuple[str, Fraction]], scaled: bool) -> None:
    high = low + width
    edges = "\n".join(f"    edge {'A -> B' if k == 0 else 'B -> A'} when x {op} {num(t)}"
                      for k, (op, t) in enumerate(guards))
    # a query may compare a scaled input (`2 * x + 1 < 2 t + 1`): the same threshold
    written = [f"2 * x + 1 {op} {num(2 * t + 1)}" if scaled else f"x {op} {num(t)}" for op, t in queries]
    text = TEXT.format(kind=kind, low=low, high=high, edges=edges,
                       queries="\n".join(f"    query Q{k}: E<> {q}" for k, q in enumerate(written)))
    result = compile_text(text, "r.ra")
    assume(result.ok)
    try:
        model = generate_uppaal(result.automaton)  # type: ignore[arg-type]
    except UppaalError:  # a guard's threshold without a significand (E0801): nothing emitted
        reject()
    values = offered(model.xml)
    step = SCALE if kind == "int" else 1
    every = np.arange(low * SCALE, high * SCALE + 1, step, dtype=np.int64)
    assert all(low * SCALE <= v <= high * SCALE and v % step == 0 for v in values), (text, values)
    atoms = [*guards, *queries]
    assert outcomes(np.array(values, dtype=np.int64), atoms) == outcomes(every, atoms), (text, values)


def test_a_query_on_a_value_no_guard_tells_apart_is_reachable_in_the_emitted_model() -> None:
    """`E<> n == 7`: rac finds the run; the model once offered n in {0, 1, 10} only."""
    text = TEXT.format(kind="int", low=0, high=10, edges="    edge A -> B when x < 1",
                       queries="    query Q: E<> x == 7\n    query P: E<> x > 3 && x < 5")
    result = compile_text(text, "r.ra")
    automaton = result.raise_for_errors()
    for decl in automaton.queries:  # rac: a run of the automaton reaches it
        assert decide_invariant(automaton, ie.Unary("!", decl.query.expr), automaton.steps).status == REFUTED
    values = offered(generate_uppaal(automaton).xml)
    assert 70000 in values and any(30000 < v < 50000 for v in values), values
