"""The fuzzer (tests/support/fuzz.py) in the suite: bounded runs over mutants of the shipped `.ra` files and
over generated programs (tests/support/fuzzgen.py) must find no internal error, no hang, no misbehaving
`rac fmt`, no Python target that fails to import or steps unlike the runtime and, when UPPAAL's
parser is available, no compiled model it rejects; bounded, seeded runs of the classes of issue 22
(huge action grids, Python builtins and keywords as names, stdout full or closed, concurrent
writers); long runs are `python tests/support/fuzz.py --minutes N` (docs/fuzzing.md)."""

from __future__ import annotations

import random
import tempfile
from collections.abc import Callable, Iterator
from pathlib import Path

import fuzz
import fuzzgen
import pytest
import utap
from fuzz import Report, fuzz_one, generated_share
from hypothesis import HealthCheck, given, settings

from rac.cli.main import main

ROOT = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="module")
def utap_binary() -> Path | None:
    """UPPAAL's parser, or None when it is unavailable (the fuzz tests then run without it, and
    fail under ``RAC_REQUIRE_UTAP=1``)."""
    located = utap.locate()
    if located.path is None and utap.required():
        pytest.fail(f"{located.reason} ({utap.ENV_REQUIRE}=1)", pytrace=False)
    return located.path


@pytest.fixture(scope="module")
def folder() -> Iterator[Path]:
    """A folder with the scenario files the inputs name (a module fixture: hypothesis runs many
    examples in one test)."""
    with tempfile.TemporaryDirectory(prefix="rac-fuzz-test-") as name:
        yield fuzz.scenario_folder(Path(name))


def first_failure(report: Report) -> str:
    what, text, detail = report.failures[0]
    return f"{what}: {detail}\n--- input ---\n{text}"


@pytest.mark.parametrize("seed", [1, 2])
def test_mutants_of_the_shipped_files_never_fail_internally(seed: int, utap_binary: Path | None) -> None:
    # (stdout conditions and concurrent writers start subprocesses: their own tests below)
    report = fuzz.fuzz(seed, inputs=300, utap_binary=utap_binary, os_every=0, writers_every=0)
    assert report.counts["inputs"] == 300
    assert not report.failures, first_failure(report)
    assert report.counts["check exit 0"] > 0  # some mutants still check, and went through fmt and both targets
    assert report.counts["json checked"] >= 50  # and --format json's document checked against the text's verdict


def test_generated_programs_check_compile_and_satisfy_uppaal(utap_binary: Path | None) -> None:
    """The seeded generator, as the long runs use it: no failure, and most of what it writes
    checks (so fmt, both targets and UPPAAL's parser see it), near misses included."""
    report = fuzz.fuzz(3, inputs=60, source="generate", utap_binary=utap_binary)
    assert not report.failures, first_failure(report)
    passed, generated = generated_share(report)
    assert generated == 60 and passed >= 0.3 * generated, fuzz.summary(report)
    assert report.counts["generated valid check ok"] == report.counts["generated valid"] > 0
    assert report.counts["generated near miss"] > report.counts["generated near miss check ok"]
    assert report.counts["compile python exit 0"] == passed
    assert report.counts["compile uppaal exit 0"] > 0
    if utap_binary is not None:
        assert report.counts["utap accepted"] == report.counts["compile uppaal exit 0"]


@settings(max_examples=60, deadline=None, derandomize=True, database=None,
          suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])
@given(program=fuzzgen.programs())
def test_generated_programs_never_fail(program: fuzzgen.Generated, folder: Path, utap_binary: Path | None) -> None:
    """The same generator drawn by hypothesis: a failing program shrinks to a small one."""
    report = Report()
    fuzz_one(program.text, folder, report, utap_binary)
    assert not report.failures, first_failure(report)


def test_the_generator_is_reproducible_from_its_seed() -> None:
    def texts(seed: int) -> list[str]:
        choices = fuzzgen.RandomChoices(random.Random(seed))
        return [fuzzgen.generate(choices).text for _ in range(5)]

    assert texts(4) == texts(4) != texts(5)


def test_a_model_uppaal_rejects_is_a_finding(tmp_path: Path, utap_binary: Path | None) -> None:
    """The UTAP oracle is not vacuous: a compiled model with an undeclared name is reported, with
    UPPAAL's message."""
    if utap_binary is None:
        utap.unavailable(utap.locate().reason)
    source = tmp_path / "fuzz.ra"
    source.write_text((ROOT / "stdlib" / "driving.ra").read_text(encoding="utf-8"), encoding="utf-8")
    assert main(["compile", "--target", "uppaal", str(source), "-o", str(tmp_path / "out.xml")]) == 0
    assert fuzz.utap_problem(utap_binary, tmp_path) is None
    xml = tmp_path / "out.xml"
    xml.write_text(xml.read_text(encoding="utf-8").replace("</declaration>", "int broken = undeclared;</declaration>",
                                                           1), encoding="utf-8")
    complaint = fuzz.utap_problem(utap_binary, tmp_path)
    assert complaint is not None and "undeclared" in complaint


def test_a_json_document_unlike_the_text_is_a_finding(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """The --format json oracle is not vacuous: a document that is no JSON, a diagnostic without a code or
    with a span outside the file, and a verdict unlike the text format's are each reported."""
    source = tmp_path / "fuzz.ra"
    text = (ROOT / "examples" / "naive_driving.ra").read_text(encoding="utf-8")
    source.write_text(text, encoding="utf-8")
    assert fuzz.json_problem(source, text, 1) is None  # E0402: an error, exit 1, in both formats
    assert "exits 0, with --format json 1" in str(fuzz.json_problem(source, text, 0))
    honest = fuzz.run_apart(["check", "--format", "json", str(source)])
    for broken, said in [(honest[1][:-20], "is not JSON"),
                         (honest[1].replace('"E0402"', '"oops"'), "without a code"),
                         (honest[1].replace('"line": 28', '"line": 2800', 1), "has span"),
                         (honest[1].replace('"severity": "error"', '"severity": "warning"', 1), "severity")]:
        monkeypatch.setattr(fuzz, "run_apart", lambda argv, out=broken: (1, out, ""))
        assert said in str(fuzz.json_problem(source, text, 1))


def test_fmt_changing_the_meaning_or_losing_a_comment_is_a_finding(monkeypatch: pytest.MonkeyPatch) -> None:
    text = (ROOT / "stdlib" / "driving.ra").read_text(encoding="utf-8")
    assert fuzz.fmt_problem(text) is None
    real = fuzz.format_module
    monkeypatch.setattr(fuzz, "format_module", lambda module: real(module, comments=False))
    assert "comments" in (fuzz.fmt_problem(text) or "")
    monkeypatch.setattr(fuzz, "format_module", lambda module: real(module).replace("sa - 100", "sa - 10"))
    assert fuzz.fmt_problem(text) == "the formatted text parses to a different tree"


def test_a_penalty_whose_sum_no_float_holds_is_reported(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """The fuzzer's first find: `sa = sa - 1e308` checks each number, but P2's worst objective over
    the horizon is about 3e310, and printing it crashed the check (OverflowError)."""
    text = (ROOT / "stdlib" / "driving.ra").read_text(encoding="utf-8").replace("sa = sa - 100", "sa = sa - 1e308")
    source = tmp_path / "huge.ra"
    source.write_text(text, encoding="utf-8")
    assert main(["check", str(source)]) == 1
    out = capsys.readouterr()
    assert "internal error" not in out.err and "error[E0" in out.out


def generated(seed: int, count: int, keep: Callable[[fuzzgen.Generated], bool]) -> list[fuzzgen.Generated]:
    """The first ``count`` programs of the seeded generator that ``keep`` takes."""
    choices, found = fuzzgen.RandomChoices(random.Random(seed)), []
    for _ in range(2000):
        program = fuzzgen.generate(choices)
        if keep(program):
            found.append(program)
            if len(found) == count:
                return found
    raise AssertionError(f"the generator wrote only {len(found)} such programs")


def test_huge_action_grids_are_refused_with_a_diagnostic(folder: Path) -> None:
    """Issue 22: a grid past the limit is E0901 at once (the time limit would catch a hang)."""
    refused = 0
    for program in generated(22, 5, lambda p: "huge grid" in p.defects):
        report = Report()
        assert fuzz_one(program.text, folder, report) is not None, first_failure(report)
        assert not report.failures, first_failure(report)
        status, output = fuzz.run(["check", str(folder / "fuzz.ra")])
        refused += status == 1 and "E0901" in output
    assert refused > 0


PYTHON_NAMED = """automaton float {
    input None, len : bool
    input class : real in [1, 5]
    reward ValueError, math
    priority ValueError > math
    objective 10 * ValueError + math
    sample every 1
    horizon 5
    initial location def { math' == 1 }
    location type { ValueError' == -1 }
    edge * -> type when len do ValueError -= 100
    edge * -> def when !len && class < 3
    edge def -> def when !len && class >= 3 do math += 1
}
"""


def test_python_builtins_and_keywords_as_names_compile_import_and_step(folder: Path) -> None:
    """Issue 22: the Python target renames what would shadow a builtin (`float_`); its module
    imports and steps as rac.load's runtime does."""
    programs = [PYTHON_NAMED] + [p.text for p in generated(
        23, 5, lambda p: p.kind != "near miss" and any(f" {n} " in p.text for n in fuzzgen.PYTHON_NAMES[:12]))]
    report = Report()
    for text in programs:
        assert fuzz_one(text, folder, report, os_every=0, writers_every=0) == 0, text
    assert not report.failures, first_failure(report)
    assert report.counts["python stepped"] == len(programs)


def test_a_python_module_stepping_unlike_the_runtime_is_a_finding(tmp_path: Path) -> None:
    source = tmp_path / "fuzz.ra"
    source.write_text(PYTHON_NAMED, encoding="utf-8")
    assert main(["compile", "--target", "python", str(source), "-o", str(tmp_path / "out.py")]) == 0
    assert fuzz.python_problem(tmp_path / "out.py", source) is None
    module = tmp_path / "out.py"
    module.write_text(module.read_text(encoding="utf-8") + "\nfloat_.step = lambda self, inputs: 7.0\n",
                      encoding="utf-8")
    assert "7.0" in (fuzz.python_problem(module, source) or "")


def test_stdout_full_or_closed_is_e0009_exit_2(folder: Path) -> None:
    """Issue 22: `rac check`, `rac fmt --stdout` and `rac compile --target python` with stdout
    on /dev/full and closed exit 2 with E0009, never 3."""
    programs = [(ROOT / "stdlib" / "driving.ra").read_text(encoding="utf-8")] + [
        p.text for p in generated(24, 2, lambda p: p.kind == "valid")]
    report = Report()
    for text in programs:
        assert fuzz_one(text, folder, report, os_every=1, writers_every=0) == 0
    assert not report.failures, first_failure(report)
    assert report.counts["stdout conditions"] == 2 * len(fuzz.STDOUT_COMMANDS) * len(programs)


def test_concurrent_fmt_and_tune_leave_a_formatted_file(folder: Path) -> None:
    """Issue 22: `rac fmt` with `rac tune` (a file with `param`) or a second `rac fmt`, started
    together: exit 0 or 2 each, and the file formatted afterwards."""
    programs = [(ROOT / "examples" / "tune" / "driving_weights.ra").read_text(encoding="utf-8")] + [
        p.text for p in generated(25, 3, lambda p: p.kind == "valid" and "param " in p.text)] + [
        p.text for p in generated(26, 1, lambda p: p.kind == "valid" and "param " not in p.text)]
    report = Report()
    for text in programs:
        assert fuzz_one(text, folder, report, os_every=0, writers_every=1) == 0
    assert not report.failures, first_failure(report)
    assert report.counts["concurrent writers"] == len(programs)
