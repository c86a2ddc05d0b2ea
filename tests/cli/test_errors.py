"""One error root (issue 24): every exception of rac is a :class:`RacError`, keeping its builtin base;
a RacError carrying a :class:`Diagnostic` is rendered by the ``rac`` command like the checker's
findings; E0801 of a reward rate is found by ``rac check`` when the automaton has a ``model`` block,
and the engine raises the same diagnostic; an unknown failure is an internal error (exit 3), not E0712.
"""

from __future__ import annotations

import dataclasses
import json
from fractions import Fraction
from pathlib import Path

import pytest

import rac
from rac.cli.main import main
from rac.compiler import compile_file, compile_text
from rac.core.diagnostics import CheckError, RacError, RacValueError, error
from rac.core.resources import ScenarioTooLarge
from rac.engine.budget import BudgetExceeded
from rac.engine.shield import UnseenState
from rac.ir.significands import Unrepresentable, rate_diagnostics
from rac.model.commonroad import ScenarioError
from rac.model.data import ModelDataError, ModelRangeError

ROOT = Path(__file__).resolve().parents[2]
DIAGNOSTICS = ROOT / "tests" / "diagnostics"
MODEL_RATE = DIAGNOSTICS / "E0801_model_rate.ra"


def test_the_root_keeps_the_builtin_bases() -> None:
    assert rac.RacError is RacError
    for cls, builtin in [(CheckError, Exception), (ScenarioError, Exception), (ModelRangeError, ValueError),
                         (ModelDataError, ValueError), (BudgetExceeded, MemoryError), (ScenarioTooLarge, MemoryError),
                         (UnseenState, KeyError), (RacValueError, ValueError), (Unrepresentable, ValueError)]:
        assert issubclass(cls, RacError) and issubclass(cls, builtin), cls


def test_a_rac_error_carries_its_diagnostic() -> None:
    found = error("E0801", "a number", None, hints=["a hint"])
    failure = RacError(diagnostic=found)
    assert failure.diagnostic is found and str(failure) == "a number"
    assert RacError("plain").diagnostic is None


def test_rac_check_reports_e0801_with_a_model_block() -> None:
    result = compile_file(MODEL_RATE)
    codes = [d.code for d in result.diagnostics if d.is_error]
    assert codes == ["E0801"] and result.automaton is None


def test_the_check_and_the_uppaal_target_say_the_same() -> None:
    # the rate of the model-less E0801 example, whose diagnostic `rac compile --target uppaal` prints
    text = MODEL_RATE.read_text(encoding="utf-8")
    checked = next(d for d in compile_text(text, "x.ra").diagnostics if d.code == "E0801")
    expected = (DIAGNOSTICS / "E0801_rate_not_representable.expected").read_text(encoding="utf-8")
    assert checked.message in expected
    assert all(hint in expected for hint in checked.hints) and all(n.message in expected for n in checked.notes)


def test_the_product_raises_the_checkers_diagnostic() -> None:
    # an automaton the checker did not see (built by hand): the engine raises the check's E0801
    from rac.engine import product

    fine = compile_file(ROOT / "examples" / "left_turn" / "model.ra", analyse=False).automaton
    assert fine is not None and fine.model is not None
    location = fine.locations[0]
    rate = dataclasses.replace(location.rates[0], const=location.rates[0].const + Fraction("0.00001"))
    broken = dataclasses.replace(fine, locations=(dataclasses.replace(location, rates=(rate, *location.rates[1:])),
                                                  *fine.locations[1:]))
    (expected,) = rate_diagnostics(broken)
    with pytest.raises(ValueError) as caught:  # a ValueError as before
        product._Arithmetic(broken, fine.model.base ** fine.model.exponent)
    assert isinstance(caught.value, Unrepresentable) and caught.value.diagnostic == expected


def test_the_cli_renders_a_rac_error_with_a_diagnostic(monkeypatch, capsys, tmp_path) -> None:
    import rac.cli.files

    found = error("E0801", "a number the representation cannot hold", None, hints=["raise the exponent"])

    def failing(args):
        raise RacValueError(diagnostic=found)

    monkeypatch.setattr(rac.cli.files, "check_command", failing)
    status = main(["check", str(tmp_path / "x.ra")])
    err = capsys.readouterr().err
    assert status == 1 and "error[E0801]: a number the representation cannot hold" in err
    assert "hint: raise the exponent" in err and "internal error" not in err
    status = main(["check", "--format", "json", str(tmp_path / "x.ra")])
    out = capsys.readouterr().out
    assert status == 1 and json.loads(out)[0]["code"] == "E0801"


def test_a_rac_error_without_a_diagnostic_is_an_internal_error(monkeypatch, capsys, tmp_path) -> None:
    import rac.cli.files

    def failing(args):
        raise RacValueError("nobody handled this")

    monkeypatch.setattr(rac.cli.files, "check_command", failing)
    monkeypatch.delenv("RAC_DEBUG", raising=False)
    status = main(["check", str(tmp_path / "x.ra")])
    assert status == 3 and "internal error: RacValueError: nobody handled this" in capsys.readouterr().err


def test_an_unknown_loader_failure_is_an_internal_error(monkeypatch, capsys, tmp_path) -> None:
    import rac.model.checks

    def boom(path: str, *args: object, **kwargs: object):
        raise RuntimeError("the reader broke")

    monkeypatch.setattr(rac.model.checks, "load_file", boom)
    monkeypatch.delenv("RAC_DEBUG", raising=False)
    text = (DIAGNOSTICS / "E0712_missing_scenario.ra").read_text(encoding="utf-8")
    (tmp_path / "m.ra").write_text(text, encoding="utf-8")
    status = main(["check", str(tmp_path / "m.ra")])
    err = capsys.readouterr().err
    assert status == 3 and "internal error: RuntimeError: the reader broke" in err and "E0712" not in err


@pytest.mark.parametrize("command", ["verify", "preanalyse", "experiment", "tune"])
def test_engine_commands_print_load_errors_as_json_when_asked(command: str, tmp_path: Path,
                                                              capsys: pytest.CaptureFixture[str]) -> None:
    # a script reading --format json parses standard output: a file rac cannot read or check is JSON
    # there too (it was text on standard error, standard output empty)
    broken = tmp_path / "broken.ra"
    broken.write_text("automaton A {\n  bogus\n}\n", encoding="utf-8")
    for path, code, status in [(tmp_path / "missing.ra", "E0008", 2), (broken, "E0001", 1)]:
        extra = [] if command == "tune" else ["-o", str(tmp_path / "out")]
        assert main([command, str(path), "--format", "json", *extra]) == status
        out, err = capsys.readouterr()
        found = json.loads(out)
        diagnostics = found["diagnostics"] if command == "tune" else found
        assert [d["code"] for d in diagnostics] == [code] and err == ""
