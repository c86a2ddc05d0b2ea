"""``A[] p`` over the automaton alone (rac.check.analysis.invariant) against brute force.

The oracle enumerates every input sequence of exactly the horizon's length, or shorter where ``episode
ends when`` ends it (the product's runs),
with the valuations of ``tests/support/reference.py`` and evaluates ``p`` at every instant the product of
model and automaton shows (rac.engine.product: the start, ``read``/``accrued`` of the first sample,
``sampled``, ``accrued``, ``ended``), counting a formula that reads an input only where the inputs
are settled. A proof must agree with it everywhere; a refutation of a query without reward
comparisons is exact, so it must agree too.
"""

from __future__ import annotations

from fractions import Fraction
from pathlib import Path

from hypothesis import HealthCheck, event, given, settings
from hypothesis import strategies as st
from reference import ZERO, accrue, assign, edge_for, valuations
from test_worst import cases, num

from rac import ir
from rac.check.analysis.invariant import PROVED, REFUTED, UNDECIDED, decide_invariant, over_automaton
from rac.compiler import compile_text
from rac.ir import expr as ie
from rac.ir import query as iq
from rac.runtime.semantics import first_sample_reads

ROOT = Path(__file__).resolve().parents[2]


def value(node: ie.Expr, location: int, inputs: dict[str, object], rewards: tuple[Fraction, ...]) -> object:
    """``node`` at one instant, exactly."""
    if isinstance(node, ie.Const):
        return node.value
    if isinstance(node, ie.Ref):
        if node.kind is ie.RefKind.LOCATION:
            return location == node.index
        if node.kind is ie.RefKind.INPUT:
            return inputs[node.name]
        return rewards[node.index]
    if isinstance(node, ie.Unary):
        inner = value(node.operand, location, inputs, rewards)
        return (not inner) if node.op == "!" else -inner  # type: ignore[operator]
    if isinstance(node, ie.Compare):
        return ir.compare(value(node.left, location, inputs, rewards), node.op,
                          value(node.right, location, inputs, rewards))
    assert isinstance(node, ie.Binary)
    a, b = value(node.left, location, inputs, rewards), value(node.right, location, inputs, rewards)
    if node.op == "&&":
        return bool(a) and bool(b)
    if node.op == "||":
        return bool(a) or bool(b)
    if node.op == "imply":
        return (not a) or bool(b)
    return {"+": lambda: a + b, "-": lambda: a - b, "*": lambda: a * b, "/": lambda: a / b}[node.op]()  # type: ignore[operator]


def compared_constants(node: ie.Expr) -> set[Fraction]:
    """The constants ``node`` compares an input with (``x < 0``: 0): the oracle tries the input there too."""
    if isinstance(node, ie.Compare):
        sides = (node.left, node.right)
        if any(isinstance(s, ie.Ref) and s.kind is ie.RefKind.INPUT for s in sides):
            constant = [s for s in sides if not ie.refs(s)]  # `1 / 2` is a division of constants
            return {Fraction(value(s, 0, {}, ())) for s in constant}  # type: ignore[arg-type]
        return set()
    if isinstance(node, ie.Unary):
        return compared_constants(node.operand)
    if isinstance(node, ie.Binary):
        return compared_constants(node.left) | compared_constants(node.right)
    return set()


def violated(automaton: ir.Automaton, expr: ie.Expr) -> bool:
    """Whether some instant of some run of exactly the horizon's samples (or fewer, ended by ``episode
    ends when``) violates ``expr``."""
    settled_only = any(r.kind is ie.RefKind.INPUT for r in ie.refs(expr))
    zero_inputs: dict[str, object] = {i.name: False if i.is_bool else ZERO for i in automaton.inputs}
    xs = valuations(automaton, compared_constants(expr))
    steps = automaton.steps
    l0, r0 = automaton.initial, tuple(ZERO for _ in automaton.rewards)

    def bad(location: int, x: dict[str, object], r: tuple[Fraction, ...], settled: bool) -> bool:
        return (settled or not settled_only) and not value(expr, location, x, r)

    if bad(l0, zero_inputs, r0, False):
        return True
    if steps == 0:
        return False
    # (location, rewards, inputs held) before each sample's edge
    frontier: set[tuple[int, tuple[Fraction, ...], tuple[object, ...]]] = set()
    reads = first_sample_reads(automaton)
    for v in xs:
        if reads:  # accrues on read with this sample's inputs
            r = accrue(automaton, l0, r0, v.values)
            if bad(l0, v.guards, r, False):
                return True
        else:
            r = accrue(automaton, l0, r0, zero_inputs)
            if bad(l0, zero_inputs, r, False):
                return True
        frontier.add((l0, r, tuple(sorted(v.guards.items())) + tuple(sorted(v.values.items()))))
    names = [i.name for i in automaton.inputs]
    for k in range(1, steps + 1):
        following = set()
        for location, r, key in frontier:
            n = len(names)
            guards = dict(key[:n])
            values = dict(key[n:])
            edge = edge_for(automaton, location, guards)
            if edge is not None:
                r = assign(automaton, edge.updates, r, values)
                location = edge.target
            if bad(location, guards, r, True):
                return True
            if k == steps or (automaton.episode_ends is not None
                              and ir.evaluate_guard(automaton.episode_ends, guards)):  # the run ends here
                ended = r
                for clause in automaton.end_clauses:
                    if ir.evaluate_guard(clause.guard, guards):
                        ended = assign(automaton, clause.updates, ended, values)
                if automaton.end_clauses and bad(location, guards, ended, True):
                    return True
                continue
            after = accrue(automaton, location, r, values)
            if bad(location, guards, after, True):
                return True
            for v in xs:
                following.add((location, after, tuple(sorted(v.guards.items())) + tuple(sorted(v.values.items()))))
        frontier = following
    return False


@st.composite
def queries(draw, automaton: ir.Automaton, thresholds: list[Fraction]):
    """A random state formula over the automaton's locations, inputs and rewards."""
    def literal() -> str:
        kinds = ["location", "bool", "reward"] + (["number"] if automaton.numeric_inputs else [])
        kind = draw(st.sampled_from(kinds))
        if kind == "location":
            return draw(st.sampled_from(list(automaton.location_names)))
        if kind == "bool":
            return draw(st.sampled_from([i.name for i in automaton.bool_inputs]))
        if kind == "number":
            op = draw(st.sampled_from(["<", "<=", ">", ">="]))
            return f"x {op} {num(draw(st.sampled_from(thresholds)))}"
        terms = " + ".join(f"{draw(st.sampled_from(['1', '2', '-1']))} * {r}" for r in automaton.rewards)
        op = draw(st.sampled_from(["<", "<=", ">", ">="]))
        return f"{terms} {op} {num(Fraction(draw(st.integers(-4, 4)), draw(st.sampled_from([1, 2]))))}"

    def formula(depth: int) -> str:
        if depth == 0 or draw(st.booleans()):
            text = literal()
            return f"!{text}" if draw(st.booleans()) and " " not in text else text
        op = draw(st.sampled_from(["&&", "||", "imply"]))
        return f"({formula(depth - 1)} {op} {formula(depth - 1)})"

    return formula(2)


def with_query(text: str, formula: str) -> tuple[ir.Automaton, ie.Expr]:
    source = text.rstrip().removesuffix("}") + f"    query Q: A[] {formula}\n}}\n"
    result = compile_text(source, "random.ra", analyse=False)
    assert result.automaton is not None, (source, result.diagnostics)
    query = next(d.query for d in result.automaton.queries if d.name == "Q")
    assert isinstance(query, iq.PathQuery)
    return result.automaton, query.expr


@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.data())
def test_invariant_agrees_with_brute_force(data: st.DataObject) -> None:
    case = data.draw(cases())
    thresholds = sorted({Fraction(t) for t in (-2, 0, Fraction(1, 2), 1, 2, 3)})
    formula = data.draw(queries(case.automaton, thresholds))
    automaton, expr = with_query(case.text, formula)
    verdict = decide_invariant(automaton, expr)
    truth = violated(automaton, expr)
    if verdict.status == PROVED:
        assert not truth, (case.text, formula)
    has_reward = any(r.kind is ie.RefKind.REWARD for r in ie.refs(expr))
    if verdict.status == REFUTED and not has_reward:
        assert truth, (case.text, formula, verdict.reason)
    assert verdict.status != UNDECIDED or has_reward, (formula, verdict.reason)
    event(f"{verdict.status}, violated={truth}")


def test_the_driving_queries_are_proved_and_a_wrong_one_refuted() -> None:
    text = open(ROOT / "stdlib/driving.ra").read()
    for formula, expected in [("isClose imply Unsafe", PROVED), ("Unsafe imply 10 * sa + 5 * pr + co <= 0", PROVED),
                              ("isClose imply Normal", REFUTED), ("Unsafe imply sa <= -200", REFUTED)]:
        automaton, expr = with_query(text.replace("horizon 30", "horizon 2"), formula)
        assert decide_invariant(automaton, expr).status == expected, formula


def test_queries_reading_the_model_are_left_to_the_model() -> None:
    result = compile_text(open(ROOT / "examples/left_turn/model.ra").read().replace(
        "query Qe:", "query Q: A[] Unsafe imply mindist() < 10\n    query Qe:"), "examples/left_turn/model.ra",
        analyse=False)
    assert result.automaton is not None
    query = next(d.query for d in result.automaton.queries if d.name == "Q")
    assert isinstance(query, iq.PathQuery) and not over_automaton(query.expr)
    assert decide_invariant(result.automaton, query.expr).status == UNDECIDED
