"""Compiled expressions (rac.engine.compiled, issue 23) against the evaluator's walk, their reference.

Random checked expressions over the bindings' and queries' vocabulary (ego names, ``time``,
settings, the true state, the model's and the math functions, ``prev``, inputs, rewards and
locations) on random frames — with and without what a name needs (the error must be the
evaluator's), with and without the integers exact comparisons are decided on — must give the same
array, bit for bit, and the same dtype. Then the bindings, the episodes and the product with
compiled code against the same with the walk (``compiled=False``).
"""

from __future__ import annotations

import math
from fractions import Fraction
from functools import cache
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from rac import ir
from rac.compiler import compile_file
from rac.engine.bindings import Bindings
from rac.engine.compiled import compile_expressions
from rac.engine.evaluate import Evaluator, Frame, c_round
from rac.ir import expr as ie
from rac.ir.vocabulary import EGO_STATE, MODEL_FUNCTIONS, TRUE_STATE

PAPER = Path(__file__).resolve().parents[2] / "examples" / "paper" / "model.ra"


@cache
def paper() -> tuple[ir.Automaton, Evaluator]:
    result = compile_file(PAPER)
    assert result.automaton is not None and result.model_data is not None
    return result.automaton, Evaluator(result.model_data, result.automaton)


# ---------------------------------------------------------------- random expressions
def _fraction() -> st.SearchStrategy[Fraction]:
    return st.one_of(st.integers(-50, 50).map(Fraction),
                     st.builds(Fraction, st.integers(-500, 500), st.sampled_from([2, 3, 4, 7, 10, 100, 1000])))


def _numbers() -> st.SearchStrategy[ie.Expr]:
    automaton, _ = paper()
    leaves = st.one_of(
        _fraction().map(lambda value: ie.Const(value)),
        st.sampled_from(EGO_STATE).map(ie.model_ref),
        st.just(ie.model_ref("time")),
        st.sampled_from(TRUE_STATE).map(ie.model_ref),
        st.tuples(st.sampled_from(["collision_distance", "length", "comfort_acceleration", "sensor_error"]),
                  _fraction()).map(lambda pair: ie.model_ref(pair[0], pair[1])),
        st.sampled_from(["mindist", "dist_goal"]).map(ie.call),
        st.sampled_from(list(automaton.rewards)).map(lambda name: ie.Ref(ie.RefKind.REWARD, name, ie.NUM)),
        st.just(ie.Ref(ie.RefKind.LOCATION_INDEX, "Driving.location", ie.NUM)),
        st.just(ie.Ref(ie.RefKind.INPUT, "gap", ie.NUM)),  # a numeric input (the frames make one up)
    )

    def extend(inner: st.SearchStrategy[ie.Expr]) -> st.SearchStrategy[ie.Expr]:
        return st.one_of(
            st.builds(lambda op, a, b: ie.Binary(op, a, b), st.sampled_from("+-*/"), inner, inner),
            inner.map(lambda a: ie.Unary("-", a)),
            inner.map(ie.Prev),
            st.builds(lambda name, a: ie.call(name, a),
                      st.sampled_from(["fabs", "abs", "sqrt", "floor", "ceil", "round", "trunc"]), inner),
            st.builds(lambda name, a, b: ie.call(name, a, b), st.sampled_from(["fmin", "fmax"]), inner, inner),
        )

    return st.recursive(leaves, extend, max_leaves=6)


def _compare(op: str, left: ie.Expr, right: ie.Expr) -> ie.Compare:
    return ie.Compare(op, left, right, ie.difference(left, right))  # the linear form, as the checker gives it


def expressions() -> st.SearchStrategy[ie.Expr]:
    automaton, _ = paper()
    numbers = _numbers()
    leaves = st.one_of(
        st.booleans().map(lambda value: ie.Const(value)),
        st.sampled_from([name for name in MODEL_FUNCTIONS if name not in ("mindist", "dist_goal")]).map(ie.call),
        st.builds(_compare, st.sampled_from(["<", "<=", ">", ">=", "==", "!="]), numbers, numbers),
        st.sampled_from(automaton.inputs).map(lambda item: ie.Ref(ie.RefKind.INPUT, item.name, ie.BOOL)),
        st.sampled_from(range(len(automaton.location_names))).map(
            lambda index: ie.Ref(ie.RefKind.LOCATION, automaton.location_names[index], ie.BOOL, index)),
        st.just(ie.Ref(ie.RefKind.DEADLOCK, "deadlock", ie.BOOL)),
    )

    def extend(inner: st.SearchStrategy[ie.Expr]) -> st.SearchStrategy[ie.Expr]:
        return st.one_of(
            st.builds(lambda op, a, b: ie.Binary(op, a, b), st.sampled_from(["&&", "||", "imply"]), inner, inner),
            inner.map(lambda a: ie.Unary("!", a)),
            inner.map(ie.Prev),
        )

    return st.one_of(st.recursive(leaves, extend, max_leaves=5), numbers)


# ---------------------------------------------------------------- random frames
@st.composite
def frames(draw: st.DrawFn) -> Frame:
    automaton, evaluator = paper()
    n = draw(st.integers(1, 6))
    start = np.asarray(evaluator.model.native.initial_state(), dtype=np.int64)
    seed = draw(st.integers(0, 2**32 - 1))
    rng = np.random.default_rng(seed)

    def one(prev: Frame | None) -> Frame:
        ego = np.tile(start, (n, 1))
        ego[:, :2] += rng.integers(-3000, 3000, (n, 2))  # within 30 m of the start (scale 100)
        ego[:, 2] = rng.integers(0, 1500, n)
        ego[:, 3:5] = rng.integers(-300, 300, (n, 2))
        ego[:, 5:7] = rng.integers(-200, 200, (n, 2))
        k = rng.integers(0, 150, n)
        holds = rng.random(6) < 0.7
        inputs = {item.name: (rng.random(n) < 0.5) for item in automaton.inputs}
        inputs["gap"] = rng.integers(-500, 500, n) / 100.0
        rewards = {name: rng.integers(-10**6, 10**6, n) / 100.0 for name in automaton.rewards}
        return Frame(
            k=k, ego=ego.astype(np.int32 if holds[0] else np.int64),
            truth=rng.normal(0, 20, (n, 5)) if holds[1] else None,
            location=rng.integers(0, len(automaton.location_names), n) if holds[2] else None,
            rewards=rewards if holds[3] else None,
            inputs=inputs if holds[4] else None,
            mirrors={name: np.round(values * 100).astype(np.int64) for name, values in rewards.items()}
            if holds[5] else None,
            significands={"gap": np.round(inputs["gap"] * 100).astype(np.int64)} if rng.random() < 0.5 else None,
            crashed=rng.random(n) < 0.2, prev=prev)

    depth = draw(st.integers(0, 2))
    frame = None
    for _ in range(depth + 1):
        frame = one(frame)
    assert frame is not None
    return frame


def _outcome(run):
    with np.errstate(over="ignore"):  # overflow warnings are the same in both; not what is compared
        try:
            return "value", run()
        except Exception as exc:  # noqa: BLE001 - the same error is the point
            return "error", (type(exc), str(exc))


def _fresh(frame: Frame | None) -> Frame | None:
    """``frame`` without the model values already kept on it (so each side computes its own)."""
    if frame is None:
        return None
    return Frame(frame.k, frame.ego, frame.truth, frame.location, frame.rewards, frame.inputs, _fresh(frame.prev),
                 frame.mirrors, frame.significands, frame.crashed)


def _same(a: np.ndarray, b: np.ndarray) -> bool:
    a, b = np.asarray(a), np.asarray(b)
    if a.dtype == object or b.dtype == object:
        return a.dtype == b.dtype and a.shape == b.shape and all(x == y for x, y in zip(a.tolist(), b.tolist()))
    return a.dtype == b.dtype and a.shape == b.shape and a.tobytes() == b.tobytes()


@settings(max_examples=400, deadline=None, suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])
@given(st.lists(expressions(), min_size=1, max_size=3), frames())
def test_compiled_expressions_are_the_evaluators_bit_for_bit(exprs: list[ie.Expr], frame: Frame) -> None:
    _, evaluator = paper()
    compiled = compile_expressions(evaluator, exprs)
    for index, expr in enumerate(exprs):
        expected = _outcome(lambda expr=expr: evaluator.evaluate(expr, _fresh(frame)))
        got = _outcome(lambda index=index: compiled(_fresh(frame))[index])
        if expected[0] == "error":  # the compiled function stops at the first error of any of its expressions
            assert got[0] == "error" or any(_outcome(lambda e=e: evaluator.evaluate(e, _fresh(frame)))[0] == "error"
                                            for e in exprs), (expr, expected, got)
            if len(exprs) == 1:
                assert got == expected, compiled.source
            continue
        if got[0] == "error":  # another expression of the list failed
            assert any(_outcome(lambda e=e: evaluator.evaluate(e, _fresh(frame)))[0] == "error" for e in exprs)
            continue
        assert _same(got[1], expected[1]), (compiled.source, got[1], expected[1])
        booleans = compiled.booleans(_fresh(frame))[index]
        assert _same(booleans, evaluator.evaluate_bool(expr, _fresh(frame))), compiled.source


def test_constant_subexpressions_are_folded_and_shared_ones_computed_once() -> None:
    automaton, evaluator = paper()
    bindings = [b.expr for b in automaton.model.bindings]  # type: ignore[union-attr]
    compiled = compile_expressions(evaluator, bindings + bindings)
    source = compiled.source
    assert "ev.value" not in source  # everything the paper's bindings say is compiled
    assert source.count("ev.function('mindist', f0)") == 1
    assert "np.multiply(K" not in source  # 3 * collision_distance folded into one constant


def test_the_bindings_compiled_and_walked_read_the_same_inputs() -> None:
    automaton, evaluator = paper()
    compiled = Bindings(evaluator, automaton, "a test")
    walked = Bindings(evaluator, automaton, "a test", compiled=False)
    rng = np.random.default_rng(3)
    for _ in range(20):
        n = 64
        start = np.asarray(evaluator.model.native.initial_state(), dtype=np.int64)
        ego = np.tile(start, (n, 1))
        ego[:, :2] += rng.integers(-3000, 3000, (n, 2))
        ego[:, 2:5] = rng.integers(-300, 1500, (n, 3))
        k = rng.integers(1, 140, n)
        frame = Frame(k, ego, prev=Frame(k - 1, ego[::-1].copy()), crashed=rng.random(n) < 0.1)
        assert np.array_equal(compiled.read(_fresh(frame)), walked.read(_fresh(frame)))  # type: ignore[arg-type]
        assert _same(compiled.prevs(_fresh(frame)), walked.prevs(_fresh(frame)))  # type: ignore[arg-type]


@pytest.mark.parametrize("reward", ["automaton", "10 * !isClose + (5 + 100 * goal()) * prog + comf"])
def test_episodes_compiled_and_walked_agree(reward: str) -> None:
    from rac.learning.episodes import EpisodeBatch

    result = compile_file(PAPER)
    batches = [EpisodeBatch(result, reward=reward, compiled=compiled) for compiled in (True, False)]
    observed = ["x", "v", "Driving.location", "prev(dist_goal()) - dist_goal()"]
    rng = np.random.default_rng(5)
    for batch in batches:
        batch.reset(24)
    while not batches[0].done.all():
        actions = rng.integers(0, batches[0].n_actions, 24)
        steps = [batch.step(actions) for batch in batches]
        for name in ("reward", "terminated", "truncated", "collided", "offroad"):
            assert _same(getattr(steps[0], name), getattr(steps[1], name)), name
        assert _same(batches[0].observe(observed), batches[1].observe(observed))
        for name, values in batches[0].inputs.items():
            assert _same(values, batches[1].inputs[name]), name
    assert batches[1].done.all()


def test_a_sample_calls_each_model_function_once(monkeypatch: pytest.MonkeyPatch) -> None:
    """The bindings (mindist, collide, dist_goal and prev(dist_goal()), goal), the labels (collide,
    offroad) and the goal share one call of each model function per step (its samples taken together);
    prev() reads the samples' own, and the last step's last (structural: counts, not time)."""
    from rac.learning.episodes import EpisodeBatch

    result = compile_file(PAPER)
    batch = EpisodeBatch(result)
    model = batch.evaluator.model
    calls: dict[str, int] = {}

    def counting(name: str):  # type: ignore[no-untyped-def]
        method = getattr(model, name)

        def counted(*args):  # type: ignore[no-untyped-def]
            calls[name] = calls.get(name, 0) + 1
            return method(*args)
        return counted

    for name in ("sense", "mindist", "offroad", "goal", "dist_goal"):
        monkeypatch.setattr(model, name, counting(name))
    batch.reset(8)
    assert calls == {"mindist": 1, "goal": 1, "dist_goal": 1}  # the start: collide(), atGoal, prog
    calls.clear()
    rng = np.random.default_rng(2)
    samples = 0
    while not batch.done.all():
        before = int(batch.k.max())
        batch.step(rng.integers(0, batch.n_actions, 8))
        samples += int(batch.k.max()) - before
    assert samples > 0
    # a step's samples are taken together (EpisodeBatch._together: every step computes here, the memo
    # being empty): the ego moves once per sample, every other function is called once per step
    steps = batch.steps_computed // 8
    assert 0 < steps < samples
    assert calls == {"sense": samples, **dict.fromkeys(("mindist", "offroad", "goal", "dist_goal"), steps)}


def test_round_is_cs_round_in_the_walk_and_the_compiled_code() -> None:
    """C's round(), which the emitted model calls: half away from zero, exact just below a half and
    beyond 2**52, the sign of zero kept (the engine computed ``sign(x) * floor(|x| + 0.5)``)."""
    _, evaluator = paper()
    values = [0.5, -0.5, 2.5, -2.5, 0.49999999999999994, -0.49999999999999994, 2.0**52 + 1, -(2.0**52 + 1), -0.0,
              -0.3, 0.3, 1.5, float("inf"), -float("inf")]
    expected = [1.0, -1.0, 3.0, -3.0, 0.0, -0.0, 2.0**52 + 1, -(2.0**52 + 1), -0.0, -0.0, 0.0, 2.0, float("inf"),
                -float("inf")]
    exprs = [ie.call("round", ie.Const(Fraction(value) if math.isfinite(value) else Fraction(0))) for value in values]
    frame = Frame(k=np.array([1]), ego=np.zeros((1, 7), dtype=np.int64))
    finite = [i for i, value in enumerate(values) if math.isfinite(value) and value != 0]
    compiled = compile_expressions(evaluator, [exprs[i] for i in finite])(frame)
    for j, i in enumerate(finite):
        walked = np.asarray(evaluator.evaluate(exprs[i], frame), dtype=np.float64)
        assert walked.tobytes() == np.float64(expected[i]).tobytes(), (values[i], walked)
        assert np.asarray(compiled[j], dtype=np.float64).reshape(-1)[:1].tobytes() == \
            np.float64(expected[i]).tobytes(), (values[i], compiled[j])
    assert np.asarray(c_round(np.array(values))).tobytes() == np.array(expected).tobytes()
