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
from engine_files import QUERIES, write_engine_file

import rac
import rac.cli.tune
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
        product.MirrorArithmetic(broken, fine.model.base ** fine.model.exponent)
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


@pytest.mark.parametrize(("raised", "status"), [(RuntimeError("boom"), 3), (RacValueError("nobody handled this"), 3),
                                               (KeyboardInterrupt(), 130)])
@pytest.mark.parametrize("command", [["check"], ["compile", "--target", "python"], ["tune"]])
def test_json_after_an_internal_error_or_ctrl_c_is_still_one_document(
        monkeypatch, capsys, tmp_path, raised: BaseException, status: int, command: list[str]) -> None:
    """`--format json` promises a JSON document on standard output; an internal error or Ctrl-C before the
    command printed one left standard output empty (`json.loads` of it failed), the message on standard
    error only."""
    import rac.cli.files

    def failing(path: object, *args: object, **kwargs: object) -> None:
        raise raised

    monkeypatch.setattr(rac.cli.files, "compile_file", failing)
    monkeypatch.setattr(rac.cli.tune, "compile_source", failing)
    monkeypatch.delenv("RAC_DEBUG", raising=False)
    path = tmp_path / "x.ra"
    path.write_text(MODEL_RATE.read_text(encoding="utf-8").replace("0.00001", "1"), encoding="utf-8")
    text = path.read_text(encoding="utf-8").replace("do sa = sa - 100", "do sa = sa - P").replace(
        "reward sa, pr", "param P in [0, 1000]\n    reward sa, pr")
    path.write_text(text, encoding="utf-8")
    assert main([*command, "--format", "json", str(path)]) == status
    out, err = capsys.readouterr()
    document = json.loads(out)
    expected: object = {"command": command[0], "ok": False, "exit_code": status, "interrupted": status == 130,
                        "error": None if status == 130 else f"internal error: {type(raised).__name__}: {raised}"}
    if command == ["check"] and status == 130:  # rac check's own array: the file it was on, marked interrupted
        expected = [{"file": str(path), "ok": False, "diagnostics": [], "proved": [], "facts": [], "undecided": True,
                     "interrupted": True}]
    assert document == expected
    assert ("internal error" in err) == (status == 3) and ("interrupted" in err) == (status == 130)
    # without the option, standard output stays empty: the message is on standard error
    assert main([*command, str(path)]) == status
    assert capsys.readouterr().out == ""


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


# ---------------------------------------------------------------- --format json: every error as JSON
#: A checked automaton without a `model` block (nor `param`): 8 samples of 0.5 s.
PLAIN = ("automaton Plain {\n    input near : bool\n    reward sa\n    objective sa\n    sample every 0.5\n"
         "    horizon 4\n    initial location N { sa' == 1 }\n    edge N -> N when near\n    query Q: E<> N\n}\n")


def json_run(capsys: pytest.CaptureFixture[str], *args: str | Path) -> tuple[int, object]:
    """``rac ARGS`` in-process: the exit code and standard output parsed as JSON (standard error must be
    empty: nothing of the error is left as text)."""
    status = main([str(a) for a in args])
    out, err = capsys.readouterr()
    assert err == "", err
    return status, json.loads(out)


def codes(found: object) -> list[str]:
    assert isinstance(found, list)
    return [d["code"] for d in found]


@pytest.mark.parametrize("command", ["verify", "preanalyse", "experiment"])
def test_a_file_without_a_model_block_is_json(command: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = tmp_path / "plain.ra"
    path.write_text(PLAIN, encoding="utf-8")
    status, found = json_run(capsys, command, path, "--format", "json", "-o", tmp_path / "out")
    assert status == 1 and codes(found) == ["E0015"]
    assert isinstance(found, list) and "has no `model` block" in found[0]["message"]


@pytest.mark.parametrize(("args", "message"), [
    (["verify", "--query", "Nope"], "--query: no query named Nope"),
    (["verify", "--horizon", "0.3"], "--horizon"),
    (["preanalyse", "--exponent", "x"], "--exponent: 'x' is not a number"),
    (["experiment", "--seed", "1", "--seeds", "1,2"], "not both"),
    (["experiment", "--replay", "-1"], "--replay must be 0 or more"),
    (["experiment", "--bins", "a,b"], "--bins: not a list of numbers"),
])
def test_an_option_the_command_cannot_use_is_json(args: list[str], message: str, tmp_path: Path,
                                                   capsys: pytest.CaptureFixture[str]) -> None:
    path = write_engine_file(tmp_path, "goal_ahead", {"Stays": QUERIES["Stays"]})
    status, found = json_run(capsys, args[0], path, *args[1:], "--format", "json", "-q", "-o", tmp_path / "out")
    assert status == 2 and codes(found) == ["E0014"]
    assert isinstance(found, list) and message in found[0]["message"]


@pytest.mark.parametrize(("args", "message"), [
    (["check", "--bogus"], "unrecognized arguments: --bogus"),
    (["compile", "--target", "java"], "argument --target: invalid choice: 'java'"),
    (["tune", "--horizon", "x"], "argument --horizon"),
    (["verify", "--max-states", "x"], "argument --max-states: not a whole number: 'x'"),
    (["simulate", "--runs"], "argument --runs: expected one argument"),
    (["render", "--shield", "--strategy", "s"], "not allowed with argument --shield"),
    (["preanalyse", "--max-memory", "lots"], "argument --max-memory: `lots` is not a size"),
    (["experiment", "--form=json", "--episodes", "0"], "argument --episodes"),
    (["sweep"], "the following arguments are required: SCENARIOS"),
])
def test_a_command_line_the_parser_refuses_is_json_when_it_asks_for_json(
        args: list[str], message: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """`rac COMMAND --format json` with an unknown option or a bad value: standard output is one JSON array of
    an E0014, as for the command's other usage errors (it was empty: the usage message was only text on standard
    error), with the same exit status 2; standard error keeps argparse's usage message."""
    path = write_engine_file(tmp_path, "goal_ahead", {"Stays": QUERIES["Stays"]})
    status = main([args[0], str(path), *args[1:], *([] if "--form=json" in args else ["--format", "json"])])
    out, err = capsys.readouterr()
    found = json.loads(out)
    assert status == 2 and codes(found) == ["E0014"]
    assert isinstance(found, list) and message in found[0]["message"] and found[0]["span"] is None
    assert f"`rac {args[0]} --help`" in found[0]["hints"][0]
    assert f"usage: rac {args[0]}" in err and f"rac {args[0]}: error: {found[0]['message']}" in err
    # without --format json (or with the last --format text) it stays text alone, exit 2 as well
    assert main([args[0], str(path), *args[1:], "--format", "json", "--format", "text"]) == 2
    assert capsys.readouterr().out == ""


def test_an_output_folder_that_cannot_be_written_is_json(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = write_engine_file(tmp_path, "goal_ahead", {})
    (tmp_path / "afile").write_text("mine\n", encoding="utf-8")
    status, found = json_run(capsys, "preanalyse", path, "--format", "json", "-q", "--runs", "2", "--seed", "1",
                             "-o", tmp_path / "afile")
    assert status == 2 and codes(found) == ["E0009"]


def test_tune_usage_errors_are_its_json_document(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = tmp_path / "plain.ra"
    path.write_text(PLAIN, encoding="utf-8")
    status, found = json_run(capsys, "tune", path, "--format", "json")
    assert isinstance(found, dict)
    assert status == 2 and found["ok"] is False and found["written"] is None
    assert [d["code"] for d in found["diagnostics"]] == ["E0014"]
    assert "declares no `param`" in found["diagnostics"][0]["message"]
    penalty = ROOT / "examples" / "tune" / "driving_penalty.ra"  # sample every 0.1 s
    status, found = json_run(capsys, "tune", penalty, "--format", "json", "--horizon", "10,25.05")
    assert isinstance(found, dict)
    assert status == 2 and [d["code"] for d in found["diagnostics"]] == ["E0014"]
    assert "not a whole number of sample periods" in found["diagnostics"][0]["message"]


@pytest.mark.parametrize(("args", "message"), [
    (["{scenarios}", "--set", "bogus=1"], "unknown setting `bogus`"),
    (["{missing}"], "no scenario file matched"),
    (["{scenarios}", "--scheduler", "tcp://127.0.0.1:1", "--workers", "2"], "--workers sizes the local cluster"),
    (["{scenarios}", "--scheduler", "notaurl"], "--scheduler: the scheduler address"),
])
def test_sweep_usage_errors_are_json(args: list[str], message: str, tmp_path: Path,
                                     capsys: pytest.CaptureFixture[str]) -> None:
    path = write_engine_file(tmp_path, "goal_ahead", {})
    names = {"{scenarios}": str(tmp_path / "goal_ahead.xml"), "{missing}": str(tmp_path / "none*.xml")}
    status, found = json_run(capsys, "sweep", path, *[names.get(a, a) for a in args], "--format", "json", "-q",
                             "-o", tmp_path / "sweep")
    assert status == 2 and codes(found) == ["E0014"]
    assert isinstance(found, list) and message in found[0]["message"]
    status, found = json_run(capsys, "sweep", tmp_path / "missing.ra", tmp_path / "goal_ahead.xml", "--format",
                             "json", "-q", "-o", tmp_path / "sweep")
    assert status == 2 and codes(found) == ["E0008"]


@pytest.mark.parametrize("form", ["text", "json"])
def test_a_sweep_template_that_does_not_parse_gives_its_own_diagnostic(
        form: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """Regression: `rac sweep` on a template with a syntax error printed one E0014 whose message held the E0001
    rendered as text (no code, no span a script could read); it now gives the E0014 and the file's E0001 with its
    span, as `rac check` reports it, and still exits 2 (nothing ran)."""
    path = write_engine_file(tmp_path, "goal_ahead", {})
    path.write_text(path.read_text(encoding="utf-8").replace("reward sa", "reward sa oops("), encoding="utf-8")
    status = main(["sweep", str(path), str(tmp_path / "goal_ahead.xml"), "--task", "check", "-q", "--format", form,
                   "-o", str(tmp_path / "sweep")])
    out, err = capsys.readouterr()
    assert status == 2
    if form == "text":
        assert out == "" and err.startswith(f"error[E0014]: the template {path} does not parse\n")
        assert f"{path}:5:15: error[E0001]: unexpected `oops`" in err
        return
    found = json.loads(out)
    assert err == "" and codes(found) == ["E0014", "E0001"]
    assert isinstance(found, list) and found[0]["message"] == f"the template {path} does not parse"
    assert found[1]["span"]["file"] == str(path) and (found[1]["span"]["line"], found[1]["span"]["column"]) == (5, 15)


def test_a_scenario_beyond_max_memory_is_json(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = write_engine_file(tmp_path, "goal_ahead", {})
    for args in (["check"], ["verify", "-o", str(tmp_path / "out")], ["compile", "--target", "python"]):
        status, found = json_run(capsys, args[0], path, *args[1:], "--format", "json", "--max-memory", "1K")
        assert status == 2 and codes(found) == ["E0016"], args
        assert isinstance(found, list) and found[0]["message"].startswith("resource limit: the scenario")
    tuned = tmp_path / "tuned.ra"  # a `param` in the engine file: rac tune loads its scenario
    tuned.write_text(path.read_text(encoding="utf-8").replace("horizon", "param UNUSED in [0, 1]\n    horizon", 1),
                     encoding="utf-8")
    status, found = json_run(capsys, "tune", tuned, "--format", "json", "--max-memory", "1K")
    assert status == 2 and isinstance(found, dict) and [d["code"] for d in found["diagnostics"]] == ["E0016"]


def test_compile_json_summarises_what_it_wrote(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = tmp_path / "plain.ra"
    path.write_text(PLAIN.replace("edge N -> N when near", "edge N -> N when near\n    location M { sa' == 0 }"),
                    encoding="utf-8")  # M is unreachable: a warning (W0302)
    status, found = json_run(capsys, "compile", path, "--target", "python", "--format", "json", "-o",
                             tmp_path / "plain.py")
    assert isinstance(found, dict) and status == 0
    assert found["ok"] is True and found["target"] == "python" and found["output"] is None
    assert found["written"] == [str(tmp_path / "plain.py")] and (tmp_path / "plain.py").exists()
    assert [d["code"] for d in found["diagnostics"]] == ["W0302"]
    status, found = json_run(capsys, "compile", path, "--target", "uppaal", "--format", "json", "-o",
                             tmp_path / "plain.xml")
    assert isinstance(found, dict) and status == 0
    assert found["written"] == [str(tmp_path / "plain.xml"), str(tmp_path / "plain.q")]
    status, found = json_run(capsys, "compile", path, "--target", "python", "--format", "json")
    assert isinstance(found, dict) and status == 0 and found["written"] == []
    assert isinstance(found["output"], str) and "generated by rac" in found["output"].lower()


@pytest.mark.parametrize(("output", "code"), [("{dir}", "E0009"), ("{source}", "E0009"), ("{mine}", "E0009")])
def test_compile_write_errors_are_json(output: str, code: str, tmp_path: Path,
                                       capsys: pytest.CaptureFixture[str]) -> None:
    path = tmp_path / "plain.ra"
    path.write_text(PLAIN, encoding="utf-8")
    (tmp_path / "mine.py").write_text("print('mine')\n", encoding="utf-8")
    target = {"{dir}": tmp_path, "{source}": path, "{mine}": tmp_path / "mine.py"}[output]
    status, found = json_run(capsys, "compile", path, "--target", "python", "--format", "json", "-o", target)
    assert status == 2 and codes(found) == [code]


def test_control_characters_in_a_message_are_escaped(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """A message, note or hint quoting the user's text (a scenario's file name with an escape character)
    printed the character raw, and a terminal would act on it; the source line showed it as U+FFFD."""
    path = write_engine_file(tmp_path, "goal_ahead")
    text = path.read_text(encoding="utf-8")
    path.write_text(text.replace('scenario "goal_ahead.xml"', 'scenario "scene\x1b[2J.xml"'), encoding="utf-8")
    assert main(["check", str(path)]) == 1
    out = capsys.readouterr().out
    assert "\x1b" not in out
    assert "scene\\x1b[2J.xml: does not exist" in out
    assert "put `scene\\x1b[2J.xml` there" in out


@pytest.mark.parametrize("command", ["check", "simulate"])
def test_a_scenario_given_for_the_automaton_gets_a_hint(command: str, tmp_path: Path,
                                                        capsys: pytest.CaptureFixture[str]) -> None:
    """`rac simulate scenario.xml` said only "unexpected `<`, expected `automaton`", without a hint."""
    path = write_engine_file(tmp_path, "goal_ahead")
    scenario = path.with_suffix(".xml")
    assert scenario.read_bytes().startswith(b"<?xml")
    assert main([command, str(scenario)]) == 1
    captured = capsys.readouterr()
    out = captured.out + captured.err  # the engine commands print diagnostics on standard error
    assert f"{scenario}:1:1: error[E0001]: unexpected `<`" in out
    assert ("hint: this looks like an XML file (a CommonRoad scenario?): rac reads a `.ra` file, whose `model` block "
            "names the scenario with `scenario \"FILE.xml\"`") in out
