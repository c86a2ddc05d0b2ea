"""Loaded automata as values: copies are independent, pickles cross process boundaries, ``rac.loads``
checks its arguments and the size of its text like a file's."""

from __future__ import annotations

import copy
import multiprocessing
import pickle
import struct
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np
import pytest
from driving_ir import inputs

import rac
from rac.core.source import MAX_SOURCE_BYTES
from rac.runtime.batch import BatchRewardAutomaton
from rac.runtime.interpreter import RewardAutomaton

DRIVING = Path(__file__).parents[2] / "stdlib" / "driving.ra"
#: Unsafe (PENALTY), a held numeric input, an end bonus: every kind of state a run carries.
#: spawn: the worker starts from nothing, so the automaton must arrive whole in the pickle
#: (fork would let it inherit the parent's memory).
SPAWN = multiprocessing.get_context("spawn")
TRACE = [inputs(), inputs(comf=False), inputs(is_close=True), inputs(prog=False, dgoal=1.0), inputs()]


def bits(value: float) -> bytes:
    return struct.pack("<d", value)


def state(ra: RewardAutomaton) -> tuple[object, ...]:
    return (ra.location, list(map(bits, ra.rewards.values())), bits(ra.objective), ra.samples, ra.ended)


def run(ra: RewardAutomaton, trace: list[dict[str, object]]) -> list[bytes]:
    return [bits(ra.step(x)) for x in trace] + [bits(ra.end(inputs(dgoal=1.0)))]


@pytest.mark.parametrize("duplicate", [copy.copy, copy.deepcopy, lambda ra: pickle.loads(pickle.dumps(ra))])
def test_a_copy_mid_run_is_independent_and_continues_alike(duplicate: object) -> None:
    original = rac.load(DRIVING)
    for x in TRACE[:3]:
        original.step(x)
    twin = duplicate(original)  # type: ignore[operator]
    assert type(twin) is RewardAutomaton and state(twin) == state(original)
    reference = rac.load(DRIVING)
    for x in TRACE[:3]:
        reference.step(x)
    # the copy runs on; the original must not see it, and both continue exactly as an uncopied run
    assert run(twin, TRACE[3:]) == run(reference, TRACE[3:])
    fresh = rac.load(DRIVING)
    for x in TRACE[:3]:
        fresh.step(x)
    assert state(original) == state(fresh)
    assert run(original, TRACE[3:]) == run(fresh, TRACE[3:])


def test_a_copy_keeps_its_own_clip_counts() -> None:
    original = rac.load(DRIVING)
    original.step(inputs(dgoal=600.0), clip=True)
    twin = copy.copy(original)
    twin.step(inputs(), clip=True)
    assert original.clipped == {"dgoal": 1} and twin.clipped == {"dgoal": 0}


def _step_in_worker(ra: RewardAutomaton) -> tuple[list[bytes], RewardAutomaton]:
    return run(ra, TRACE[3:]), ra


def test_a_pickled_automaton_steps_in_another_process() -> None:
    ra = rac.load(DRIVING)
    for x in TRACE[:3]:
        ra.step(x)
    expected = run(copy.copy(ra), TRACE[3:])
    with ProcessPoolExecutor(max_workers=1, mp_context=SPAWN) as pool:
        rewards, back = pool.submit(_step_in_worker, ra).result(timeout=120)
    assert rewards == expected
    assert back.ended and back.samples == len(TRACE) and not ra.ended


class Counting(RewardAutomaton):
    """A user's subclass with an attribute of its own (module level: pickle finds the class by name)."""

    def __init__(self, automaton: object) -> None:
        super().__init__(automaton)  # type: ignore[arg-type]
        self.episodes = 0

    def reset(self) -> None:
        super().reset()
        if hasattr(self, "episodes"):
            self.episodes += 1


def test_a_subclass_keeps_its_own_attributes_through_pickle_and_copies() -> None:
    # pickle rebuilt the automaton with RewardAutomaton.__init__ and its run state alone, so a SubprocVecEnv
    # worker's copy of a subclass had no `episodes` (AttributeError at its next reset)
    ra = Counting(rac.load(DRIVING).ir)
    ra.reset()
    ra.step(TRACE[0])
    ra.note = "mine"
    for twin in (pickle.loads(pickle.dumps(ra)), copy.copy(ra), copy.deepcopy(ra)):
        assert type(twin) is Counting and twin.episodes == 1 and twin.note == "mine"
        assert repr(twin).startswith("<Counting Driving at ")  # its own class's name
        assert state(twin) == state(ra)
        twin.reset()
        assert twin.episodes == 2
    assert RewardAutomaton(rac.load(DRIVING).ir).__getstate__()["own"] == {}  # nothing built travels


def _batch_in_worker(batch: BatchRewardAutomaton) -> np.ndarray:
    return batch.step_batch({k: np.full(len(batch), v) for k, v in inputs(is_close=True).items()})


def test_a_batch_pickles_copies_and_steps_in_another_process() -> None:
    batch = rac.load(DRIVING).batch(3)
    batch.step_batch({k: np.full(3, v) for k, v in inputs().items()})
    twin = copy.copy(batch)
    twin.step_batch({k: np.full(3, v) for k, v in inputs(is_close=True).items()})
    assert (batch.samples == 1).all() and (twin.samples == 2).all()  # the copy has its own arrays
    with ProcessPoolExecutor(max_workers=1, mp_context=SPAWN) as pool:
        remote = pool.submit(_batch_in_worker, pickle.loads(pickle.dumps(batch))).result(timeout=120)
    local = batch.step_batch({k: np.full(3, v) for k, v in inputs(is_close=True).items()})
    assert remote.tobytes() == local.tobytes()


def test_a_check_error_pickles_and_crosses_processes() -> None:
    """CheckError's ``args`` hold the rendered text only, so pickle rebuilt it as ``CheckError(text)`` and
    failed (AttributeError: 'str' object has no attribute 'span'); copy.copy too. A file that fails its
    checks in a worker (a wrapper given a path in SubprocVecEnv, a process pool) broke the pool instead
    of raising the error there. It is rebuilt from its diagnostics and sources now."""
    naive = DRIVING.parents[1] / "examples" / "naive_driving.ra"
    with pytest.raises(rac.CheckError) as raised:
        rac.load(naive)
    for twin in (pickle.loads(pickle.dumps(raised.value)), copy.copy(raised.value)):  # noqa: S301 - our own
        assert isinstance(twin, rac.CheckError) and str(twin) == str(raised.value)
        assert [d.code for d in twin.diagnostics] == ["E0402"]
    with ProcessPoolExecutor(max_workers=1, mp_context=SPAWN) as pool:
        with pytest.raises(rac.CheckError, match="E0402") as remote:
            pool.submit(rac.load, naive).result(timeout=120)
    assert str(remote.value) == str(raised.value)


@pytest.mark.parametrize(("args", "message"), [
    ((DRIVING.read_text(encoding="utf-8"), None), r"name must be a str, not NoneType"),
    ((None,), r"text must be a str, not NoneType"),
    ((b"automaton A {}",), r"text must be a str, not bytes"),
])
def test_loads_refuses_arguments_that_are_not_text(args: tuple[object, ...], message: str) -> None:
    with pytest.raises(TypeError, match=message):
        rac.loads(*args)  # type: ignore[arg-type]


def test_loads_has_the_size_limit_of_files() -> None:
    text = DRIVING.read_text(encoding="utf-8")
    room = MAX_SOURCE_BYTES - len(text.encode("utf-8")) - len("//")
    big = text + "//" + "x" * (room + 1)  # one byte over
    with pytest.raises(rac.CheckError) as caught:
        rac.loads(big)
    (diagnostic,) = caught.value.diagnostics
    assert diagnostic.code == "E0005"
    assert diagnostic.message == f"source text is too large ({MAX_SOURCE_BYTES + 1:,} bytes; at most 1,000,000)"
    wide = text + "//" + "é" * (room // 2 + 1)  # fewer characters than the limit, more bytes
    assert [d.code for d in rac.compile_text(wide).diagnostics] == ["E0005"]
    assert rac.compile_text(text, DRIVING).sources.keys() == {str(DRIVING)}  # a path names text too
    at_limit = text + "//" + "é" * (room // 2)  # two bytes each: at most the limit in bytes
    assert rac.loads(at_limit).name == "Driving"


@pytest.mark.parametrize("where", ["in a comment", "between tokens", "at the end"])
def test_loads_refuses_a_nul_byte_as_a_file_does(tmp_path: Path, where: str) -> None:
    """A NUL character is E0004 in a string as in a file (not a syntax error, nor anything else),
    at the NUL's position."""
    text = DRIVING.read_text(encoding="utf-8")
    at = {"in a comment": text.index("//") + 2, "between tokens": text.index("{") + 1, "at the end": len(text)}[where]
    bad = text[:at] + "\x00" + text[at:]
    with pytest.raises(rac.CheckError) as caught:
        rac.loads(bad)
    (diagnostic,) = caught.value.diagnostics
    assert diagnostic.code == "E0004" and "NUL" in diagnostic.message
    assert diagnostic.span is not None and diagnostic.span.start == at
    path = tmp_path / "nul.ra"
    path.write_text(bad, encoding="utf-8")
    (from_file,) = rac.compile_file(path).diagnostics
    assert from_file.span is not None and (from_file.code, from_file.span.start) == ("E0004", at)


def test_load_says_the_files_warnings() -> None:
    # rac.load printed nothing: a user who only trains never learned that the reward leaves a
    # loophole open (W1002) or reads an input never (W0303)
    import warnings as python_warnings

    from rac.core.diagnostics import RacCheckWarning

    folder = Path(__file__).resolve().parents[1] / "diagnostics"
    with pytest.warns(RacCheckWarning) as caught:
        rac.load(folder / "W1002_ending_early.ra")
    (message,) = [str(w.message) for w in caught]
    assert message.startswith("rac check found 1 warning (`rac check FILE` prints them with their notes and hints):")
    assert "W1002_ending_early.ra:18: W1002 ending early pays" in message
    with pytest.warns(RacCheckWarning, match="W0303 input `comf` is never used"):
        rac.loads((folder / "W0303_unused_input.ra").read_text(encoding="utf-8"), "unused.ra")
    with python_warnings.catch_warnings():
        python_warnings.simplefilter("error")  # a file without warnings loads silently
        rac.load(Path(__file__).resolve().parents[2] / "stdlib" / "driving.ra")


def test_the_check_warning_names_the_line_that_loaded_the_file() -> None:
    # a fixed stacklevel named rac.load's caller, but for RewardAutomatonWrapper given a path a line of rac's own
    # (wrappers.py, in its _load), which no user acts on
    import gymnasium

    from rac.core.diagnostics import RacCheckWarning
    from rac.learning.wrappers import RewardAutomatonWrapper

    path = Path(__file__).resolve().parents[1] / "diagnostics" / "W1002_ending_early.ra"
    with pytest.warns(RacCheckWarning) as loaded:
        rac.load(path)
    with pytest.warns(RacCheckWarning) as wrapped:
        RewardAutomatonWrapper(gymnasium.make("CartPole-v1"), path, lambda obs, info: {})
    assert [w.filename for w in (*loaded, *wrapped)] == [__file__, __file__]


def test_the_type_load_returns_is_public() -> None:
    """``rac.load`` is annotated as returning ``rac.RewardAutomaton`` (a name type checkers see), but the
    name was missing at run time: ``isinstance(ra, rac.RewardAutomaton)`` raised AttributeError."""
    assert "RewardAutomaton" in rac.__all__ and "RewardAutomaton" in dir(rac)
    assert rac.RewardAutomaton is RewardAutomaton and isinstance(rac.load(DRIVING), rac.RewardAutomaton)
