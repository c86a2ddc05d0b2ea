"""Clipping inputs to their declared ranges (runtime.semantics.clip_inputs), in both runtimes."""

from __future__ import annotations

import math

import numpy as np
import pytest
from driving_ir import driving_automaton, inputs

from rac.runtime.interpreter import RewardAutomaton
from rac.runtime.semantics import clip_column, clip_inputs, clip_rows, input_specs


def test_out_of_range_values_are_refused_without_clip_and_clipped_with_it() -> None:
    ra = RewardAutomaton(driving_automaton())
    with pytest.raises(ValueError, match=r"input 'dgoal' = 600.0 is outside \[0.0, 500.0\]"):
        ra.step(inputs(dgoal=600.0))
    reference = RewardAutomaton(driving_automaton())
    assert ra.step(inputs(dgoal=600.0), clip=True) == reference.step(inputs(dgoal=500.0))
    assert ra.clipped == {"dgoal": 1}
    ra.step(inputs(dgoal=-math.inf), clip=True)
    assert ra.clipped == {"dgoal": 1}
    ra.step(inputs(dgoal=3.0), clip=True)
    assert ra.clipped == {"dgoal": 0}
    assert ra.end(inputs(dgoal=-1.0), clip=True) == reference.end(inputs(dgoal=0.0)) > 0  # the end bonus


def test_nan_is_never_clipped() -> None:
    ra = RewardAutomaton(driving_automaton())
    with pytest.raises(ValueError, match="input 'dgoal' is NaN, which is never clipped"):
        ra.step(inputs(dgoal=math.nan), clip=True)
    assert ra.samples == 0
    batch = RewardAutomaton(driving_automaton()).batch(3)
    values = {k: np.array([v] * 3) for k, v in inputs().items()}
    values["dgoal"] = np.array([1.0, math.nan, 2.0])
    with pytest.raises(ValueError, match=r"input 'dgoal'\[1\] is NaN"):
        batch.step_batch(values, clip=True)
    # a row outside the mask is not read, NaN or not
    batch.step_batch(values, mask=np.array([True, False, True]), clip=True)
    assert batch.clipped == {"dgoal": 0}


def test_the_batch_clips_like_the_interpreter() -> None:
    batch = RewardAutomaton(driving_automaton()).batch(4)
    values = {k: np.array([v] * 4) for k, v in inputs().items()}
    values["dgoal"] = np.array([-5.0, 10.0, 900.0, np.inf])
    assert batch.step_batch(values, clip=True).tolist() == [RewardAutomaton(driving_automaton()).step(inputs())] * 4
    assert batch.clipped == {"dgoal": 3}
    values["dgoal"] = np.array([1.0, 700.0, 1.0, 1.0])
    rewards = batch.end_batch(values, mask=np.array([False, True, True, False]), clip=True)
    assert batch.clipped == {"dgoal": 1}
    assert rewards[0] == rewards[3] == 0.0 and rewards[2] > 0 == rewards[1]  # the bonus needs dgoal < 2


def test_a_masked_batch_names_a_column_of_the_wrong_shape_under_clip() -> None:
    # with a mask, clipping broadcast a (3, 1) column against the (3,) mask: numpy's "non-broadcastable
    # output operand" instead of the shape the batch names without clip
    batch = RewardAutomaton(driving_automaton()).batch(3)
    values = {k: np.array([v] * 3) for k, v in inputs().items()}
    values["dgoal"] = np.array([[1.0], [700.0], [2.0]])
    for mask in (None, np.array([True, False, True])):
        with pytest.raises(ValueError, match=r"input 'dgoal' must have shape \(3,\), not \(3, 1\)"):
            batch.step_batch(values, mask=mask, clip=True)
    assert batch.samples.tolist() == [0, 0, 0]


@pytest.mark.parametrize("dgoal", [3.0, 700.0])
def test_one_run_reads_a_0d_array_as_its_value_with_clip_as_without(dgoal: float) -> None:
    # a 0-d array (np.where(c, a, b) of scalars) is the one value it holds, as step_batch broadcasts it: it was
    # refused ("an array of shape ()"), while with clip=True one out of range was clipped to a float and taken
    ra, twin = RewardAutomaton(driving_automaton()), RewardAutomaton(driving_automaton())
    assert ra.step(inputs(dgoal=np.array(dgoal)), clip=True) == twin.step(inputs(dgoal=dgoal), clip=True)
    assert ra.clipped == twin.clipped == {"dgoal": int(dgoal > 500.0)}
    if dgoal <= 500.0:
        assert ra.step(inputs(dgoal=np.array(dgoal))) == twin.step(inputs(dgoal=dgoal))
    else:
        with pytest.raises(ValueError, match=r"input 'dgoal' = 700.0 is outside"):
            ra.step(inputs(dgoal=np.array(dgoal)))
    assert ra.rewards == twin.rewards and ra.location == twin.location


def test_clip_inputs_leaves_what_is_not_a_number_to_validation() -> None:
    specs = input_specs(driving_automaton())
    raw = {**inputs(), "dgoal": "far", "isClose": 2}
    assert clip_inputs(specs, raw) == (raw, {})


def test_clip_rows_counts_each_row_by_the_rule_of_clip_inputs() -> None:
    """The vector wrapper's per-environment counts: one per clipped row, summing to clip_inputs' count
    for a column; a scalar standing for every row counts in every row it is read in (``rows``)."""
    specs = input_specs(driving_automaton())
    column = np.array([600.0, 3.0, -1.0, 500.0, -0.0])
    rows = np.array([True, True, False, True, True])
    values, per_row = clip_rows(specs, {**inputs(), "dgoal": column}, 5, rows)
    assert per_row["dgoal"].tolist() == [1, 0, 0, 0, 0] and per_row["dgoal"].dtype == np.int64
    same, counts = clip_inputs(specs, {**inputs(), "dgoal": column}, rows)
    assert counts["dgoal"] == per_row["dgoal"].sum() and np.array_equal(same["dgoal"], values["dgoal"])  # type: ignore[arg-type]
    assert set(per_row) == {spec.name for spec in specs if not spec.is_bool}
    scalar, per_row = clip_rows(specs, {**inputs(), "dgoal": 600.0}, 5, rows)
    assert per_row["dgoal"].tolist() == [1, 1, 0, 1, 1]
    assert np.asarray(scalar["dgoal"]).tolist() == [500.0, 500.0, 600.0, 500.0, 500.0]
    with pytest.raises(ValueError, match=r"input 'dgoal'\[1\] is NaN"):
        clip_column(next(s for s in specs if s.name == "dgoal"), np.array([1.0, math.nan]))


def test_a_step_that_raises_leaves_the_counts_of_the_last_one() -> None:
    # "the automaton is left untouched" by a refused step: its clip counts too (they were the refused step's)
    ra = RewardAutomaton(driving_automaton())
    ra.step(inputs(dgoal=3.0), clip=True)
    assert ra.clipped == {"dgoal": 0}
    with pytest.raises(ValueError, match="isClose"):
        ra.step({**inputs(dgoal=900.0), "isClose": "yes"}, clip=True)
    assert ra.clipped == {"dgoal": 0} and ra.samples == 1
    batch = RewardAutomaton(driving_automaton()).batch(2)
    values = {k: np.array([v] * 2) for k, v in inputs().items()}
    batch.step_batch(values, clip=True)
    values["dgoal"] = np.array([900.0, 1.0])
    values["isClose"] = np.array([0.5, 1.0])
    with pytest.raises(ValueError, match="isClose"):
        batch.step_batch(values, clip=True)
    assert batch.clipped == {"dgoal": 0} and batch.samples.tolist() == [1, 1]


def test_a_float32_at_a_bound_rounded_to_float32_is_that_bound() -> None:
    """MountainCar observes its position as float32: at the left wall np.float32(-1.2), which is
    -1.2000000476837158 as a float and was refused for `real in [-1.2, 0.6]` by every runtime."""
    import types

    from rac.compiler import compile_text
    from rac.targets.python import generate_python

    source = ("automaton Car {\n    input pos : real in [-1.2, 0.6]\n    reward r\n    objective r\n"
              "    sample every 1\n    horizon 10\n    initial location A { r' == pos }\n}\n")
    automaton = compile_text(source, "car.ra").raise_for_errors()
    module = types.ModuleType("car_generated")
    exec(compile(generate_python(automaton), "<generated>", "exec"), module.__dict__)  # noqa: S102
    for value, read in [(np.float32(-1.2), -1.2), (np.float32(0.6), 0.6), (np.float16(0.6), 0.6),
                        (np.float32(0.25), 0.25)]:
        ra, generated = RewardAutomaton(automaton), module.Car()
        assert ra.step({"pos": value}) == generated.step({"pos": value}) == read
        batch = RewardAutomaton(automaton).batch(2)
        assert batch.step_batch({"pos": np.array([value, value])}).tolist() == [read, read]
    for outside in (np.float32(-1.3), -1.2000000476837158, np.float64(np.float32(-1.2))):  # not a float32 at the bound
        for runtime in (RewardAutomaton(automaton), module.Car()):
            with pytest.raises(ValueError, match=r"input 'pos' = -1.\d+ is outside \[-1.2, 0.6\]"):
                runtime.step({"pos": outside})
        with pytest.raises(ValueError, match=r"is outside \[-1.2, 0.6\]"):
            RewardAutomaton(automaton).batch(1).step_batch({"pos": np.array([outside])})
    # the float32 bound widened to a Python float: still refused, and the message says what happened
    hint = r"is outside \[-1.2, 0.6\]: -1.2000000476837158 is the float32 nearest a bound.*numpy float32.*clip=True"
    with pytest.raises(ValueError, match=hint):
        RewardAutomaton(automaton).step({"pos": float(np.float32(-1.2))})
    with pytest.raises(ValueError, match=hint):
        RewardAutomaton(automaton).batch(1).step_batch({"pos": np.array([np.float32(-1.2)], dtype=np.float64)})
    with pytest.raises(ValueError, match=r"is outside \[-1.2, 0.6\]$"):  # another value: no float32 hint
        RewardAutomaton(automaton).step({"pos": -1.25})


def test_clipping_leaves_a_float32_at_a_bound_uncounted() -> None:
    # it is the bound (test above): clip=True neither moves nor counts it, in either runtime
    from rac.compiler import compile_text

    source = ("automaton Car {\n    input pos : real in [-1.2, 0.6]\n    reward r\n    objective r\n"
              "    sample every 1\n    horizon 10\n    initial location A { r' == pos }\n}\n")
    automaton = compile_text(source, "car.ra").raise_for_errors()
    ra = RewardAutomaton(automaton)
    assert ra.step({"pos": np.float32(-1.2)}, clip=True) == -1.2 and ra.clipped == {"pos": 0}
    assert ra.step({"pos": np.float32(-1.3)}, clip=True) == -1.2 and ra.clipped == {"pos": 1}
    batch = RewardAutomaton(automaton).batch(2)
    assert batch.step_batch({"pos": np.array([-1.2, -1.3], dtype=np.float32)}, clip=True).tolist() == [-1.2, -1.2]
    assert batch.clipped == {"pos": 1}


def test_an_object_column_is_clipped_as_the_batch_reads_it() -> None:
    """A vector info's object column (numbers of types gymnasium does not batch, None where a sub-environment
    did not report): the batch reads it row by row, and clip=True left it unclipped, so a value out of
    range was refused as if clip had not been asked for."""
    from fractions import Fraction

    batch = RewardAutomaton(driving_automaton()).batch(3)
    column = np.array([Fraction(1001, 2), np.float32(600.0), None], dtype=object)
    rows = np.array([True, True, False])
    got = batch.step_batch({**inputs(), "dgoal": column}, mask=rows, clip=True)
    assert got.tolist() == [RewardAutomaton(driving_automaton()).step(inputs(dgoal=500.0))] * 2 + [0.0]
    assert batch.clipped == {"dgoal": 2}
    _, per_row = clip_rows(input_specs(driving_automaton()), {**inputs(), "dgoal": column}, 3, rows)
    assert per_row["dgoal"].tolist() == [1, 1, 0]
    with pytest.raises(ValueError, match=r"input 'dgoal'\[2\] = None is not a number"):
        batch.step_batch({**inputs(), "dgoal": column}, clip=True)  # every row read: None is refused by name


def test_clip_leaves_an_array_for_one_value_as_given() -> None:
    """``step(x, clip=True)`` with an array (or a list) for one input refuses it as it was given: it clipped the
    array first and then named the clipped value (``array([500.])`` for a given ``array([700.])``), and a list
    holding NaN was "input 'dgoal'[0] is NaN" (an index into a value that is no column)."""
    ra = RewardAutomaton(driving_automaton())
    with pytest.raises(ValueError, match=r"input 'dgoal' = array\(\[700\.\]\) is not a number: an array of shape"):
        ra.step(inputs(dgoal=np.array([700.0])), clip=True)  # type: ignore[arg-type]
    with pytest.raises(ValueError, match=r"input 'dgoal' = \[nan\] is not a number"):
        ra.step(inputs(dgoal=[math.nan]), clip=True)  # type: ignore[arg-type]
    assert ra.samples == 0 and ra.clipped == {}
