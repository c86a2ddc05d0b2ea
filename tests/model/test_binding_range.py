"""A numeric binding that reads `mindist()` where no obstacle exists: `rac check` refuses it (E0801).

There `mindist()` reads 1e9, its value without an obstacle, and `bind d = mindist()` needs the
significand 1e9 · 10^4, beyond int32. rac's engine refused to read it (every verdict unknown), the
emitted UPPAAL model's `d2i()` truncated it out of int32 (compiled as C: -2147483648, so the guard
`d < 5` held with no obstacle anywhere), and `rac check` said nothing. Scenes built with
commonroad-io (tests/support/tiny_scenarios.py).
"""

from __future__ import annotations

import json
import re
from pathlib import Path

import pytest
from tiny_scenarios import WALL_EGO, WALL_GOAL, Block, StraightRoad

from rac.cli.main import main
from rac.compiler import compile_file

AUTOMATON = """\
automaton Far {{
    input d : real in [0, 100]

    reward r
    objective r

    sample every 0.5
    horizon 4

    initial location Clear {{ r' == 1 }}
    location Near          {{ r' == -1 }}

    edge * -> Near  when d < 5 do r = r - 100
    edge * -> Clear when d >= 5

    model {{
        scenario "road.xml"
        exponent {exponent}
        action jerk in [-2, 2] step 2
        action turn in [0, 0] step 1
        bind d = {binding}
    }}

    query Seen: E<> Near
}}
"""


def write(folder: Path, binding: str, obstacles: tuple[Block, ...] = (), steps: int | None = None,
          exponent: int = 4) -> tuple[Path, str]:
    """``folder/far.ra`` over a straight road with ``obstacles`` (driving for ``steps`` time steps of 0.1 s)."""
    (folder / "road.xml").write_bytes(StraightRoad(80.0, WALL_EGO, WALL_GOAL, obstacles=obstacles, steps=steps)
                                      .xml("road"))
    text = AUTOMATON.format(binding=binding, exponent=exponent)
    path = folder / "far.ra"
    path.write_text(text, encoding="utf-8")
    return path, text


def e0801(path: Path) -> list:
    return [d for d in compile_file(path).diagnostics if d.is_error and d.code == "E0801"]


def test_a_distance_bound_to_an_input_without_obstacles_is_refused(tmp_path: Path) -> None:
    path, text = write(tmp_path, "mindist()")
    (diagnostic,) = e0801(path)
    line = next(i for i, row in enumerate(text.splitlines(), 1) if "bind d = mindist()" in row)
    assert diagnostic.span is not None and (diagnostic.span.line, diagnostic.span.column) == (line, 9)
    assert diagnostic.message == ("binding `d = mindist()` leaves int32 at base 10, exponent 4 where no "
                                  "obstacle exists")
    assert diagnostic.notes[0].message.startswith("the scenario has no obstacle; there `mindist()` reads 1e9")
    assert "at least 1e13, beyond int32" in diagnostic.notes[0].message
    assert list(diagnostic.hints) == ["bound the distance, e.g. `bind d = fmin(mindist(), 100)` (the upper bound "
                                      "of `d`)"]


@pytest.mark.parametrize("binding", ["mindist() - 3 * collision_distance", "fabs(mindist()) * 2", "-mindist()",
                                     "prev(mindist())", "mindist() / 2 + v"])
def test_every_binding_that_must_leave_int32_is_refused(tmp_path: Path, binding: str) -> None:
    path, _ = write(tmp_path, binding)
    assert len(e0801(path)) == 1, binding


@pytest.mark.parametrize("binding", ["fmin(mindist(), 100)", "fmin(mindist(), dist_goal())", "sqrt(mindist())",
                                     "mindist() / 1000000", "fmax(fmin(mindist(), 100), -mindist())"])
def test_a_binding_that_may_fit_is_left_to_the_engine(tmp_path: Path, binding: str) -> None:
    path, _ = write(tmp_path, binding)
    result = compile_file(path)
    assert result.ok, [d.message for d in result.diagnostics]


def test_the_sample_at_which_an_obstacle_is_gone_is_named(tmp_path: Path) -> None:
    """A car that drives for 2 s (20 time steps): from sample 5 (2.5 s) on no obstacle exists."""
    car = Block(11, x=40.0, y=1.75, velocity=5.0)
    path, _ = write(tmp_path, "mindist()", (car,), steps=20)
    (diagnostic,) = e0801(path)
    assert diagnostic.notes[0].message.startswith("no obstacle exists at t = 2.5 s (sample 5); there `mindist()`")
    assert diagnostic.data == {"base": 10, "exponent": 4, "input": "d", "sample": 5}
    # a car that stays for the whole horizon: the distance fits, whatever the ego does
    path, _ = write(tmp_path, "mindist()", (car,))
    assert compile_file(path).ok
    # a coarser representation holds 1e9 (exponent 1: 1e10 does not fit, there is no exponent 0)
    path, _ = write(tmp_path, "mindist() / 100", exponent=1)
    assert compile_file(path).ok


def test_compile_and_verify_refuse_it(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """The UPPAAL model is not written, and `rac verify` does not exit 0."""
    path, _ = write(tmp_path, "mindist()")
    assert main(["compile", "--target", "uppaal", str(path), "-o", str(tmp_path / "far.xml")]) == 1
    assert not (tmp_path / "far.xml").exists()
    assert main(["verify", str(path), "-o", str(tmp_path / "out")]) == 1
    assert "error[E0801]" in capsys.readouterr().err


def test_an_input_bound_without_a_significand_is_refused_before_its_binding(tmp_path: Path) -> None:
    """An input whose upper bound has no significand itself (1e6 at exponent 4: 1e10). `rac check` checked only
    its binding (and hinted at another bound, 1000), passing files whose bound `rac compile --target uppaal`
    then refused; the bound itself is E0801 now, as in the target."""
    path, text = write(tmp_path, "fmin(mindist(), 1000000)")
    path.write_text(text.replace("input d : real in [0, 100]", "input d : real in [0, 1000000]"), encoding="utf-8")
    (diagnostic,) = e0801(path)
    assert diagnostic.message == ("the bound 1000000 of input `d` is not representable as a 32-bit significand at "
                                  "base 10, exponent 4")


def test_a_binding_beyond_int32_in_a_run_leaves_the_verdict_unknown(tmp_path: Path,
                                                                     capsys: pytest.CaptureFixture[str]) -> None:
    """What the check cannot settle (`dist_goal()` is unbounded) the engine checks at every sample: the
    verdict is unknown (exit 4), and the message says which value, not "a sensed value"."""
    path, _ = write(tmp_path, "dist_goal() * 100", exponent=6)  # about 39 m from the goal: 3.9e9 micrometres
    assert compile_file(path).ok
    assert main(["verify", str(path), "--format", "json", "-o", str(tmp_path / "out")]) == 4
    (result,) = json.loads(capsys.readouterr().out)["results"]
    assert result["status"] == "unknown"
    assert result["message"].startswith("a value of a run left the int32 range: the binding of `d` = ")


def test_a_learning_run_beyond_int32_names_the_binding(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """`rac experiment` stops where a binding leaves int32 (exit 1) and says which value and how to bound
    it, not "a sensed value" with a hint about the ego's state only."""
    path, _ = write(tmp_path, "dist_goal() * 100", exponent=6)
    assert main(["experiment", str(path), "--seeds", "1", "--episodes", "5", "--runs", "1", "-q",
                 "--reward-function", "r", "-o", str(tmp_path / "out")]) == 1
    err = capsys.readouterr().err
    assert "error[E0015]: a value of a run left the int32 range: the binding of `d` = " in err
    assert "bound the binding (`fmin(e, 1000)`, `fmax(e, -1000)`)" in err
    # at the binding's line, shown (the E0015 had no place in the file)
    line = next(n for n, text in enumerate(path.read_text().splitlines(), 1) if "bind d = " in text)
    assert f"{path}:{line}:" in err and f"{line} | " in err and "dist_goal() * 100" in err


def write_late_car(path: Path) -> None:
    """The road of :func:`write` with a car that enters at 0.5 s (sample 1) and stays, at x = 40."""
    road = StraightRoad(80.0, WALL_EGO, WALL_GOAL, obstacles=(Block(11, x=40.0, y=1.75, velocity=0.5),), steps=60)
    text = road.xml("road").decode("utf-8")
    # the initial state at time step 5, its trajectory from 6: the car exists from sample 1 (0.5 s) on
    text, made = re.subn(r"(<initialState>\s*<time>\s*<exact>)0(</exact>)", r"\g<1>5\2", text, count=1)
    assert made == 1
    text, dropped = re.subn(r"<state>\s*<time>\s*<exact>[1-5]</exact>.*?</state>\s*", "", text, flags=re.S)
    assert dropped == 5
    path.write_text(text, encoding="utf-8")


def test_prev_reads_the_start_without_an_obstacle(tmp_path: Path) -> None:
    """A car that enters at 0.5 s (sample 1) and stays: `mindist()` is a distance at every sample the
    bindings read, but `prev(mindist())` at the first sample reads the start, where no obstacle exists.
    (CommonRoad's schema wants an obstacle's initial state at time step 0, so the file is edited after it.)"""
    path, source = write(tmp_path, "prev(mindist())")
    write_late_car(tmp_path / "road.xml")
    (diagnostic,) = e0801(path)
    assert diagnostic.notes[0].message.startswith("no obstacle exists at the start (t = 0 s), which `prev(...)` "
                                                  "reads at the first sample; there `mindist()` reads 1e9")
    assert diagnostic.data["sample"] == 1
    path.write_text(source.replace("bind d = prev(mindist())", "bind d = mindist()"), encoding="utf-8")
    result = compile_file(path)
    assert result.ok, [d.message for d in result.diagnostics]  # the car exists at every sample read


def test_learning_shows_the_start_without_refusing_it(tmp_path: Path) -> None:
    """Regression: the learning episodes read every binding at the start (sample 0) to show it, where the
    emitted model and the product read none; with no obstacle there, `bind d = mindist()` (a distance at
    every sample read) made ScenarioEnv and every learning query fail with "needs the significand 1e13".
    The value shown at the start is clipped to the input's range like any other; the run goes on."""
    from rac.learning.scenario_env import ScenarioEnv

    path, _ = write(tmp_path, "mindist()")
    write_late_car(tmp_path / "road.xml")
    assert compile_file(path).ok
    env = ScenarioEnv(path)
    _, info = env.reset(seed=0)
    assert info["inputs"] == {"d": 100.0}  # 1e9, clipped to `d`'s upper bound
    _, _, _, _, info = env.step(0)
    assert 0 <= info["inputs"]["d"] < 100  # the car at x = 40 from sample 1 on
