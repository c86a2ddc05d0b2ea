"""Clipping inputs to their declared ranges (runtime.semantics.clip_inputs), in both runtimes."""

from __future__ import annotations

import math

import numpy as np
import pytest
from driving_ir import driving_automaton, inputs

from rac.runtime.interpreter import RewardAutomaton
from rac.runtime.semantics import clip_inputs, input_specs


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


def test_clip_inputs_leaves_what_is_not_a_number_to_validation() -> None:
    specs = input_specs(driving_automaton())
    raw = {**inputs(), "dgoal": "far", "isClose": 2}
    assert clip_inputs(specs, raw) == (raw, {})
