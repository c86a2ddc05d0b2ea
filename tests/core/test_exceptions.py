"""rac's exceptions cross process boundaries: pickle, and gymnasium's AsyncVectorEnv re-raising one."""

from __future__ import annotations

import pickle

import pytest

import rac
from rac.core.diagnostics import CheckError, RacError, RacValueError
from rac.model.commonroad import ScenarioError
from rac.model.data import ModelRangeError


def failures() -> list[RacError]:
    with pytest.raises(CheckError) as raised:
        rac.loads("automaton A {", "broken.ra")
    return [raised.value, ModelRangeError("sensed v", 1e12, None, 1000),
            ScenarioError("scene.xml", "lanelet", "broken"), RacValueError("plain")]


@pytest.mark.parametrize("index", range(4), ids=["check", "model-range", "scenario", "value"])
def test_an_error_is_the_same_failure_after_pickle_and_when_rebuilt_from_itself(index: int) -> None:
    # gymnasium's AsyncVectorEnv sends a worker's exception to the parent and raises type(e)(e) there: a
    # CheckError said "TypeError: 'CheckError' object is not iterable", and an error whose __init__ takes
    # its parts (ModelRangeError, ScenarioError) neither pickled nor rebuilt (TypeError: missing arguments)
    error = failures()[index]
    for again in (pickle.loads(pickle.dumps(error)), type(error)(error)):
        assert type(again) is type(error) and str(again) == str(error) and again.args == error.args
        assert again.__dict__ == error.__dict__
    if isinstance(error, CheckError):
        assert type(error)(error).diagnostics == error.diagnostics
