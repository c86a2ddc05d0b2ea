"""The compiler as a list of stages (issue 24): rac.compiler.STAGES, typed facts (rac.core.diagnostics.Fact)
structured in ``rac check --format json``, and the parameter stage's one outcome (rac.check.params)."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from rac.check.params import ParameterOutcome, synthesise_parameters
from rac.cli.main import main
from rac.compiler import STAGES, Compilation, Settings, compile_file, compile_text
from rac.core.diagnostics import FACT_CHECKS, Fact
from rac.lang.parser import parse_text

ROOT = Path(__file__).resolve().parents[2]
DRIVING = ROOT / "stdlib" / "driving.ra"


def test_the_stages_run_in_order_and_stop_at_an_error() -> None:
    assert [name for name, _ in STAGES] == ["resolve", "parameters", "analysis", "scenario"]
    module = parse_text(DRIVING.read_text(encoding="utf-8"), "driving.ra")
    state = Compilation(module)
    checks = []
    for _, stage in STAGES:
        state = stage(state, Settings())
        checks.append({fact.check for fact in state.facts})
    assert checks[0] == set() and "determinism" in checks[2] and not state.failed
    # a type error: resolve reports it, and no later stage adds anything
    broken = parse_text(DRIVING.read_text(encoding="utf-8").replace("sa' == -1", "sa' == true", 1), "broken.ra")
    state = Compilation(broken)
    for _, stage in STAGES:
        state = stage(state, Settings())
    assert state.failed and state.facts == ()


def test_facts_are_typed_and_print_as_before() -> None:
    result = compile_file(DRIVING)
    assert result.ok and all(isinstance(fact, Fact) and fact.check in FACT_CHECKS for fact in result.facts)
    assert result.proved == tuple(str(fact) for fact in result.facts)
    p2 = [fact for fact in result.facts if fact.check == "P2"]
    assert p2 and all(fact.data["reward"] in ("sa", "pr") for fact in p2)
    with pytest.raises(ValueError, match="unknown check"):
        Fact("P3", "no such check")


def test_check_json_lists_the_facts_structured(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["check", str(DRIVING), "--format", "json"]) == 0
    (report,) = json.loads(capsys.readouterr().out)
    assert report["proved"] == [fact["message"] for fact in report["facts"]]
    assert {fact["check"] for fact in report["facts"]} >= {"determinism", "P1", "P2", "range"}
    assert next(f for f in report["facts"] if f["check"] == "range")["data"]["exponent"] is not None


def test_the_parameter_stage_has_one_outcome() -> None:
    text = DRIVING.read_text(encoding="utf-8").replace("const PENALTY = 100", "param PENALTY in [0, 1000]", 1)
    assert text != DRIVING.read_text(encoding="utf-8")
    node = parse_text(text, "driving.ra").automata[0]
    parameters = compile_text(text, "driving.ra", analyse=False).raise_for_errors().parameters
    outcome = synthesise_parameters(node, parameters)
    assert isinstance(outcome, ParameterOutcome) and outcome.automaton is not None and not outcome.diagnostics
    assert outcome.synthesised is not None and [f.check for f in outcome.facts] == ["synthesis"]
    assert outcome.facts[0].message == compile_text(text, "driving.ra").facts[0].message
