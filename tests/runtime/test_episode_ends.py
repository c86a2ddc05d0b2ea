"""`episode ends when COND` in the Python runtimes: the sample that satisfies COND ends the run there.

The interpreter, the batch and the generated module agree on every run (tests/runtime/test_agreement.py);
these tests pin down what the run is: the end clauses applied at that sample with its inputs and counted
in its reward, ``terminated``, ``end`` giving 0.0 afterwards and ``step`` refused until ``reset``.
"""

from __future__ import annotations

import copy
import pickle
import types
from dataclasses import replace
from fractions import Fraction
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from driving_ir import driving_automaton

from rac import ir
from rac.compiler import compile_text
from rac.runtime.batch import BatchRewardAutomaton
from rac.runtime.interpreter import RewardAutomaton
from rac.runtime.semantics import ENDED_MESSAGE
from rac.targets.python import generate_python

ENDS = ir.BOr((ir.BInput("collide"), ir.BAtom("dgoal", "<", Fraction(2))))
DRIVING = replace(driving_automaton(), episode_ends=ENDS)


def inputs(**changes: object) -> dict[str, object]:
    return {"isClose": False, "prog": True, "comf": True, "collide": False, "dgoal": 40.0, **changes}


def generated() -> Any:
    module = types.ModuleType("generated_ends")
    exec(compile(generate_python(DRIVING), "<generated>", "exec"), module.__dict__)  # noqa: S102
    return module.Driving()


@pytest.mark.parametrize("make", [lambda: RewardAutomaton(DRIVING), generated], ids=["interpreter", "generated"])
def test_the_goal_ends_the_run_with_its_bonus(make: Any) -> None:
    ra = make()
    assert ra.step(inputs()) == pytest.approx(1.6)  # 0.1 per reward, weights 10 + 5 + 1
    assert not ra.terminated and not ra.ended
    reward = ra.step(inputs(dgoal=1.0))
    assert reward == pytest.approx(1.6 + 5 * 100)  # the end clause `pr = pr + 100` in this sample's reward
    assert ra.terminated and ra.ended and ra.samples == 2
    assert ra.end(inputs(dgoal=300.0)) == 0.0  # already ended: nothing applied again, nothing read
    assert ra.end({"nonsense": 1}) == 0.0
    assert ra.rewards["pr"] == pytest.approx(100.2)
    with pytest.raises(RuntimeError, match=ENDED_MESSAGE.split(";")[0]):
        ra.step(inputs())
    ra.reset()
    assert not ra.terminated and not ra.ended and ra.objective == 0.0


def test_a_collision_ends_the_run_without_the_goal_bonus() -> None:
    ra = RewardAutomaton(DRIVING)
    reward = ra.step(inputs(isClose=True, collide=True))
    assert ra.terminated and ra.location == "Unsafe"  # the edge is taken first, then the run ends
    assert reward == pytest.approx(10 * (0.1 - 100) + 5 * 0.1 + 0.1)


def test_end_after_a_plain_end_still_refuses() -> None:
    ra = RewardAutomaton(DRIVING)
    ra.end(inputs())
    assert ra.ended and not ra.terminated
    with pytest.raises(RuntimeError):
        ra.end(inputs())


def test_without_the_declaration_nothing_terminates() -> None:
    plain = driving_automaton()
    assert plain.ending is None and replace(plain, episode_ends=ir.BConst(False)).ending is None
    ra = RewardAutomaton(plain)
    ra.step(inputs(dgoal=1.0, isClose=True, collide=True))
    assert not ra.terminated and not ra.ended


def test_copies_and_pickles_keep_terminated() -> None:
    ra = RewardAutomaton(DRIVING)
    ra.step(inputs(dgoal=0.5))
    for twin in (copy.copy(ra), copy.deepcopy(ra), pickle.loads(pickle.dumps(ra))):
        assert twin.terminated and twin.end(inputs()) == 0.0
    assert "terminated" in repr(ra)


def test_the_batch_terminates_rows_and_refuses_their_steps() -> None:
    batch = BatchRewardAutomaton(DRIVING, 3)
    columns = {name: np.array([value] * 3) for name, value in inputs().items()}
    columns["dgoal"] = np.array([40.0, 1.0, 40.0])
    rewards = batch.step_batch(columns)
    assert batch.terminated.tolist() == [False, True, False] and batch.ended.tolist() == [False, True, False]
    assert rewards[1] == pytest.approx(1.6 + 500) and rewards[0] == pytest.approx(1.6)
    with pytest.raises(RuntimeError, match=r"automata \[1\]"):
        batch.step_batch(columns)
    live = ~batch.terminated
    batch.step_batch(columns | {"dgoal": np.array([40.0, 40.0, 40.0])}, mask=live)
    ended = batch.end_batch(columns, mask=np.ones(3, dtype=bool))  # the terminated row: 0.0, unchanged
    assert ended[1] == 0.0 and batch.ended.all() and batch.terminated.tolist() == [False, True, False]
    assert batch.take([1, 1]).terminated.all() and copy.copy(batch).terminated[1]
    batch.reset(mask=np.array([False, True, False]))
    assert not batch.terminated.any()


def test_run_samples_skips_a_terminated_row() -> None:
    """A transition of several samples: a row whose episode ended inside it takes no later sample."""
    batch = BatchRewardAutomaton(DRIVING, 2)
    first = {name: np.array([value] * 2) for name, value in inputs().items()} | {"dgoal": np.array([1.0, 40.0])}
    second = {name: np.array([value] * 2) for name, value in inputs().items()}
    both, none = np.ones(2, dtype=bool), np.zeros(2, dtype=bool)
    total = batch.run_samples([(first, both, none), (second, both, both)])
    assert batch.samples.tolist() == [1, 2] and batch.terminated.tolist() == [True, False]
    assert total[0] == pytest.approx(1.6 + 500) and total[1] == pytest.approx(3.2)


def test_the_declaration_in_a_file_runs_alike() -> None:
    """`episode ends when` written in the language compiles to the guard these tests build by hand, and the
    interpreter, the batch and the module `rac compile --target python` writes end the run at the same sample."""
    text = (Path(__file__).resolve().parents[2] / "stdlib" / "driving.ra").read_text(encoding="utf-8")
    text = text.replace("    at end when", "    episode ends when collide || dgoal < 2\n\n    at end when")
    automaton = compile_text(text, "driving.ra").raise_for_errors()
    assert automaton.episode_ends == ENDS
    module = types.ModuleType("generated_from_text")
    exec(compile(generate_python(automaton), "<generated>", "exec"), module.__dict__)  # noqa: S102
    runs = [RewardAutomaton(automaton), module.Driving()]
    batch = BatchRewardAutomaton(automaton, 1)
    for values in (inputs(), inputs(dgoal=10.0), inputs(dgoal=1.9)):
        rewards = {ra.step(values) for ra in runs}
        rewards.add(float(batch.step_batch({k: np.array([v]) for k, v in values.items()})[0]))
        assert len(rewards) == 1
    assert all(ra.terminated for ra in runs) and batch.terminated[0]
