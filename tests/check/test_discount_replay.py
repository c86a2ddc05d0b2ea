"""Every E0410 counterexample `rac check --discount` prints, replayed by the runtime: on random programs
(test_check_brute_force's generator) and discounts, the run of the diagnostic's data, fed to
rac.runtime.interpreter sample by sample, must end in a penalised location with the discounted sum of
the weighted changes equal to the value the check reports (> 0). Only test_discount.py's driving case
replayed the printed run before; the search's internal run is checked there against a brute force.
"""

from __future__ import annotations

import dataclasses
import math
import os
import random
from fractions import Fraction

from hypothesis import HealthCheck, assume, given, settings
from hypothesis import strategies as st
from test_check_brute_force import program, value, weighted

from rac import ir
from rac.check.analysis.discount import DISCOUNTED_P2, Discount, check_discounted
from rac.check.analysis.priority import p2_target
from rac.compiler import compile_text
from rac.runtime.interpreter import RewardAutomaton

SETTINGS = settings(max_examples=int(os.environ.get("RAC_EXAMPLES", "15")), deadline=None,
                    derandomize=not os.environ.get("RAC_EXAMPLES"),
                    suppress_health_check=[HealthCheck.too_slow, HealthCheck.filter_too_much])


def inputs_of(entry: dict) -> dict[str, object]:
    return {k: v if isinstance(v, bool) else float(Fraction(v)) for k, v in entry.items()}


def replay(a: ir.Automaton, data: dict, discount: Discount) -> tuple[float, str]:
    """The discounted weighted sum at the run's violating instant, and the location there."""
    level = data["level"]
    weights, constant = weighted(a, level)
    # the edge of a sample that ends the episode comes before its `at end` updates, which step() applies
    # too: replay without them unless the run ends with them (as test_check_brute_force's replay)
    automaton = a if data["end"] is not None else dataclasses.replace(a, end_clauses=())
    runtime = RewardAutomaton(automaton)

    def f(rewards: dict[str, float]) -> float:
        return sum(float(weights[r]) * rewards[r] for r in a.rewards)

    def accrued(location: str, x: dict[str, object]) -> dict[str, float]:
        rates = a.locations[a.location_names.index(location)].rates
        exact = {k: v if isinstance(v, bool) else Fraction(v) for k, v in x.items()}
        return {r: runtime.rewards[r] + float(a.period * value(rates[i], exact)) for i, r in enumerate(a.rewards)}

    total = float(constant)
    last = 0
    for entry in data["run"]:
        x = inputs_of(entry["inputs"])
        for k in range(entry["sample"], entry["last_sample"] + 1):
            w = float(discount.weight(k))
            if k == 1 and entry["instant"] == "before-edge":
                return total + w * (f(accrued(a.location_names[a.initial], x)) - f(runtime.rewards)), \
                    a.location_names[a.initial]
            before = f(runtime.rewards)
            runtime.step(x)
            total += w * (f(runtime.rewards) - before)
            last = k
            if k == entry["last_sample"] and entry["instant"] == "before-next":
                after = f(accrued(runtime.location, x))
                return total + float(discount.weight(k + 1)) * (after - f(runtime.rewards)), runtime.location
    if data["end"] is not None:
        before = f(runtime.rewards)
        runtime.end(inputs_of(data["end"]["inputs"]))
        total += float(discount.weight(max(last, 1))) * (f(runtime.rewards) - before)
    return total, runtime.location


@SETTINGS
@given(rng=st.randoms(use_true_random=False),
       gamma=st.sampled_from([Fraction(1, 2), Fraction(3, 4), Fraction(9, 10), Fraction(99, 100)]),
       samples_per_step=st.sampled_from([1, 1, 2, 3]))
def test_every_discounted_counterexample_replays_to_its_value(rng: random.Random, gamma: Fraction,
                                                              samples_per_step: int) -> None:
    text = program(rng)
    codes = {d.code for d in compile_text(text, "random.ra").diagnostics}
    # a program with no runs to replay, or none the exact checks decide (P1, P2 or the range may fail: the
    # discounted search runs all the same)
    assume(not codes & {"E0301", "E0305", "E0306", "W0405", "E0801"})
    a = compile_text(text, "random.ra", analyse=False).automaton
    assert a is not None
    discount = Discount(gamma, samples_per_step)
    found = [d for d in check_discounted(a, discount) if d.code == DISCOUNTED_P2]
    assume(found)
    for d in found:
        data = d.data
        approached = any(e["approached"] for e in data["run"]) or (data["end"] or {}).get("approached")
        got, where = replay(a, data, discount)
        assert p2_target(a, data["level"]).watched[a.location_names.index(where)], (text, where)
        if not approached:
            assert math.isclose(got, float(Fraction(data["value"])), rel_tol=1e-9, abs_tol=1e-9), \
                (got, data["value"], discount, text)
        else:  # a supremum: the inputs are a run near enough it to violate all the same
            assert got > 0, (got, data["value"], discount, text)


APPROACHED = """automaton Random {
    input x : real in [-2, 2]
    reward p, q
    priority strict q > p
    objective 1/2 * p + 1 * q
    sample every 1/10
    horizon 2/5
    initial location L0 { p' == 1/2 + -2 * x; q' == 1/2 }
    edge L0 -> L0 when ((2 * x + 1 <= 0))
    episode ends when ((2 * x + 1 <= 0))
}
"""


def test_an_approached_counterexample_replays_to_a_violation() -> None:
    """P2 at `p`'s level is a supremum, 0.3, approached as x tends to -0.5 from above (x = -0.5 would end
    the episode). The JSON's inputs once gave x the class's middle, 0.75, whose run ends at -0.2, no
    violation; they now give a value near enough -0.5 that the replayed run violates, for the plain
    return and the discounted one."""
    a = compile_text(APPROACHED, "approached.ra", analyse=False).automaton
    assert a is not None
    (error,) = [d for d in compile_text(APPROACHED, "approached.ra").diagnostics if d.code == "E0402"]
    assert error.data["value"] == "3/10" and error.data["run"][0]["approached"] == {"x": "-1/2"}
    assert -0.5 < float(Fraction(error.data["run"][0]["inputs"]["x"])) < 0.75  # nearer -0.5 than the middle
    got, _ = replay(a, error.data, Discount(Fraction(1)))
    assert 0 < got < 0.3
    (discounted,) = check_discounted(a, Discount(Fraction(9, 10)))
    got, _ = replay(a, discounted.data, Discount(Fraction(9, 10)))
    assert discounted.data["run"][0]["approached"] == {"x": "-1/2"}
    assert 0 < got < float(Fraction(discounted.data["value"]))
