"""One owner for the scenario model (issue 24): :class:`rac.model.program.CheckedProgram`.

- the checker loads a `model` block's scenario once, through :func:`rac.model.checks.load`; ``rac
  check``, ``rac verify`` and ``rac compile --target uppaal`` in one process read the file once, and
  every stage reads the program the checker made (the same model's data, not a rebuilt one);
- a file with two planning problems and no `planning_problem` setting never gets a silently chosen
  scenario: the engine's and the UPPAAL target's entry points raise what E0715 reports;
- ``rac verify --standard`` at another horizon does not lower the standard queries again: their
  bounds are replaced (:func:`rac.check.standard.at_horizon`), the same queries as lowered anew.
"""

from __future__ import annotations

from fractions import Fraction
from pathlib import Path

import pytest
from engine_files import TEMPLATE, write_engine_file
from tiny_scenarios import junction_with_two_problems

import rac.model.commonroad
from rac.check.standard import at_horizon
from rac.check.standard import standard_queries as lowered_anew
from rac.cli.main import main
from rac.compiler import compile_file
from rac.core.diagnostics import CheckError
from rac.engine.product import decide_in_model
from rac.model import checks
from rac.model.commonroad import PlanningProblemError
from rac.model.program import CheckedProgram, program_of
from rac.targets.uppaal.model import generate_uppaal_model, model_vocabulary
from rac.verify.context import Context, VerifyOptions
from rac.verify.runner import standard_queries, verify


@pytest.fixture
def loads(monkeypatch: pytest.MonkeyPatch) -> list[str]:
    """The paths commonroad-io's loader (rac's wrapper of it) is called with, from an empty cache on."""
    calls: list[str] = []
    real = rac.model.commonroad.load_scenario

    def counted(path, *args, **kwargs):  # type: ignore[no-untyped-def]
        calls.append(str(path))
        return real(path, *args, **kwargs)

    monkeypatch.setattr(rac.model.commonroad, "load_scenario", counted)
    monkeypatch.setattr(checks, "_CACHE", {})
    return calls


def test_check_verify_and_compile_load_the_scenario_once(tmp_path: Path, loads: list[str]) -> None:
    path = write_engine_file(tmp_path, "goal_ahead", queries={"Stays": "E[] !collide() && !offroad()"})
    assert main(["check", str(path)]) == 0
    assert main(["verify", str(path), "--query", "Stays", "--out", str(tmp_path / "out")]) in (0, 1)
    assert main(["compile", str(path), "--target", "uppaal", "-o", str(tmp_path / "model.xml")]) == 0
    assert (tmp_path / "model.xml").is_file()
    assert len(loads) == 1, loads


def test_the_program_is_the_checkers(tmp_path: Path, loads: list[str]) -> None:
    path = write_engine_file(tmp_path, "goal_ahead", queries={"Stays": "E[] !collide() && !offroad()"})
    result = compile_file(path)
    program = result.checked()
    assert isinstance(program, CheckedProgram)
    assert program.automaton is result.automaton and program.model_data is result.model_data
    assert program.scenario is result.scenario and program.data is result.model_data
    assert program_of(result).model_data is result.model_data and program_of(program) is program
    context = Context(result, VerifyOptions())
    assert context.program.model_data is result.model_data and context.data is result.model_data
    assert context.automaton is result.automaton and context.evaluator is context.evaluator  # made once
    # every stage takes the program; none of them loads the scenario again
    (answer,) = verify(program, VerifyOptions(only=("Stays",), out_dir=tmp_path / "out"))
    assert answer.status in ("satisfied", "not satisfied")
    assert decide_in_model(result, None, "Stays").holds == decide_in_model(program, None, "Stays").holds
    assert generate_uppaal_model(program).xml == generate_uppaal_model(result.raise_for_errors(),
                                                                       data=result.model_data).xml
    assert model_vocabulary(program) == model_vocabulary(program.automaton, data=program.model_data)
    assert len(loads) == 1, loads
    # an automaton alone asks the same owner, whose cache has the scenario
    alone = CheckedProgram.of(program.automaton)
    assert alone.scenario is result.scenario and len(loads) == 1
    # a file checked without the analyses has loaded nothing: its program asks the owner
    unchecked = compile_file(path, analyse=False)
    assert unchecked.model_data is None and unchecked.checked().scenario is result.scenario
    assert len(loads) == 1


def test_a_file_with_errors_has_no_program(tmp_path: Path) -> None:
    path = tmp_path / "broken.ra"
    path.write_text("automaton Broken { reward r objective q }\n", encoding="utf-8")
    result = compile_file(path)
    with pytest.raises(CheckError):
        result.checked()
    with pytest.raises(CheckError):
        decide_in_model(result, None, "Q")


def test_an_automaton_without_a_model_block(tmp_path: Path) -> None:
    path = tmp_path / "plain.ra"
    path.write_text(TEMPLATE.format(period="0.1", horizon="1", model="", queries=""), encoding="utf-8")
    program = compile_file(path).checked()
    assert program.model_data is None and program.scenario is None
    with pytest.raises(ValueError, match="no `model` block"):
        program.data  # noqa: B018 - the property raises
    with pytest.raises(ValueError, match="no `model` block"):
        decide_in_model(program, None, "Q")
    with pytest.raises(ValueError, match="needs a `model` block"):
        Context(program, VerifyOptions())


# ---------------------------------------------------------------- two planning problems, none chosen
MODEL = """\
    model {
        scenario "junction.xml"
        bind near = mindist() < 3 * collision_distance
    }"""


def test_two_planning_problems_are_never_chosen_silently(tmp_path: Path, loads: list[str]) -> None:
    (tmp_path / "junction.xml").write_bytes(junction_with_two_problems())
    path = tmp_path / "drive.ra"
    path.write_text(TEMPLATE.format(period="0.1", horizon="10", model=MODEL,
                                    queries="    query Stays: E[] !collide() && !offroad()\n"), encoding="utf-8")
    checked = compile_file(path)
    assert [d.code for d in checked.diagnostics if d.is_error] == ["E0715"]
    with pytest.raises(CheckError, match="E0715"):
        checked.checked()
    # without the checks, the automaton alone: every entry point asks the owner, which refuses to choose
    result = compile_file(path, analyse=False)
    automaton = result.raise_for_errors()
    entry_points = {
        "CompileResult.checked": result.checked,
        "CheckedProgram.of": lambda: CheckedProgram.of(automaton),
        "decide_in_model(result)": lambda: decide_in_model(result, None, "Stays"),
        "decide_in_model(automaton)": lambda: decide_in_model(automaton, None, "Stays"),
        "generate_uppaal_model": lambda: generate_uppaal_model(automaton),
        "model_vocabulary": lambda: model_vocabulary(automaton),
        "Context": lambda: Context(result, VerifyOptions()),
        "verify": lambda: verify(result, VerifyOptions(only=("Stays",))),
        "checks.load": lambda: checks.load(automaton.model),  # type: ignore[arg-type]
    }
    for name, call in entry_points.items():
        with pytest.raises(PlanningProblemError) as raised:
            call()
        assert raised.value.chosen is None and raised.value.ids == (100, 101), name
        assert "has 2 planning problems (100, 101) and none was chosen" in str(raised.value), name
    assert result.scenario is None and result.model_data is None


# ---------------------------------------------------------------- the standard queries at another horizon
def test_standard_queries_at_another_horizon_are_not_lowered_again(tmp_path: Path) -> None:
    path = write_engine_file(tmp_path, "goal_ahead", queries={})
    result = compile_file(path)
    automaton = result.raise_for_errors()
    for horizon in (Fraction(3, 2), Fraction(4), automaton.horizon):
        assert standard_queries(result, horizon) == lowered_anew(automaton, horizon, verify_only=True)
        assert standard_queries(result.checked(), horizon) == standard_queries(result, horizon)
    assert standard_queries(result, Fraction(3, 2))[0].text.startswith("Pr[<=1.5](<> ")
    learning = [d for d in automaton.standard_queries if d.name == "reach"]
    with pytest.raises(ValueError, match="MAXT"):
        at_horizon(learning, Fraction(1))
