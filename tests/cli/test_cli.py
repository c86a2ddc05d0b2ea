"""End to end: the ``rac`` command, as a child process (``python -m rac``) and in process (``rac.cli.main``)."""

from __future__ import annotations

import ast
import json
import os
import re
import shutil
import subprocess
import sys
import types
from pathlib import Path

import pytest
from conftest import REPOSITORY, rac_env, run_rac

from rac import __version__
from rac.cli.main import main
from rac.compiler import compile_file
from rac.lang.resources import stdlib_file
from rac.targets.python import generate_python

DRIVING = stdlib_file("driving.ra")
DRIVING_TEXT = DRIVING.read_text(encoding="utf-8")
#: stdlib/driving.ra is in rac fmt's layout (tests/project/test_stdlib.py), so it is its own golden file.
GOLDEN_FMT = DRIVING
#: stdlib/driving.ra (in rac fmt's layout) with its alignment collapsed to single spaces; the
#: comments keep their columns, so the continuation comment stays a continuation.
UNFORMATTED = re.sub(r"(?<=\S) {2,}(?=[^ /])", " ", DRIVING_TEXT)
VALID = {"isClose": False, "prog": True, "comf": True, "collide": False, "dgoal": 40.0}


@pytest.fixture
def clean(tmp_path: Path) -> Path:
    path = tmp_path / "driving.ra"
    path.write_text(DRIVING_TEXT, encoding="utf-8")
    return path


@pytest.fixture
def unformatted(tmp_path: Path) -> Path:
    assert UNFORMATTED != DRIVING_TEXT
    path = tmp_path / "driving.ra"
    path.write_text(UNFORMATTED, encoding="utf-8")
    return path


@pytest.fixture
def p2_fails(tmp_path: Path) -> Path:
    """The design's counter-example: with PENALTY = 90 progress can compensate an unsafe moment."""
    path = tmp_path / "weak_penalty.ra"
    text = DRIVING_TEXT.replace("const PENALTY = 100", "const PENALTY = 90")
    assert text != DRIVING_TEXT
    path.write_text(text, encoding="utf-8")
    return path


@pytest.fixture
def syntax_error(tmp_path: Path) -> Path:
    path = tmp_path / "broken.ra"
    path.write_text("automaton Broken {\n    input x : bool\n    reward r\n    edge -> when x\n}\n", encoding="utf-8")
    return path


def folder_listing(folder: Path) -> list[str]:
    return sorted(p.name for p in folder.iterdir())


# ---------------------------------------------------------------- check
def test_check_clean_file_proves_the_priorities() -> None:
    done = run_rac("check", DRIVING)
    assert done.returncode == 0, done.stderr
    proved = [line.strip() for line in done.stdout.splitlines() if line.strip().startswith("proved:")]
    assert proved, done.stdout
    p2 = [line for line in proved if "P2 holds" in line]
    assert p2 and "-20" in p2[0], done.stdout
    assert f"{DRIVING}: ok" in done.stdout
    assert done.stderr == ""


def test_check_quiet_prints_no_facts(capsys: pytest.CaptureFixture[str], clean: Path) -> None:
    assert main(["check", "-q", str(clean)]) == 0
    out = capsys.readouterr().out
    assert "proved:" not in out and f"{clean}: ok" in out


def test_check_file_with_errors_exits_1(p2_fails: Path) -> None:
    done = run_rac("check", p2_fails)
    assert done.returncode == 1, done.stdout + done.stderr
    assert "E0402" in done.stdout and "P2" in done.stdout
    assert f"{p2_fails}: 1 error" in done.stdout


def test_check_syntax_error_exits_1(capsys: pytest.CaptureFixture[str], syntax_error: Path) -> None:
    assert main(["check", str(syntax_error)]) == 1
    out = capsys.readouterr().out
    assert f"{syntax_error.name}:4:" in out  # the error points at line 4
    assert "error" in out


def test_check_json(capsys: pytest.CaptureFixture[str], clean: Path, p2_fails: Path) -> None:
    assert main(["check", "--format", "json", str(clean), str(p2_fails)]) == 1
    report = json.loads(capsys.readouterr().out)  # nothing but the JSON on stdout
    assert [entry["file"] for entry in report] == [str(clean), str(p2_fails)]
    for entry in report:
        assert set(entry) >= {"file", "ok", "diagnostics", "proved"}
    good, bad = report
    assert good["ok"] is True and good["diagnostics"] == []
    assert any("P2 holds" in fact and "-20" in fact for fact in good["proved"])
    assert bad["ok"] is False
    assert [d["code"] for d in bad["diagnostics"]] == ["E0402"]
    assert bad["diagnostics"][0]["severity"] == "error"
    assert bad["diagnostics"][0]["span"]["line"] >= 1


def test_check_json_entries_have_the_same_fields_whatever_the_outcome(capsys: pytest.CaptureFixture[str], clean: Path,
                                                                      p2_fails: Path, tmp_path: Path) -> None:
    """Regression: an unreadable file's entry had only `file`, `ok`, `diagnostics` and `proved`: a script reading
    every entry's `facts` or `undecided` failed on it. Every entry now has the same fields."""
    missing = tmp_path / "nope.ra"
    assert main(["check", "--format", "json", str(clean), str(missing), str(p2_fails)]) == 2
    report = json.loads(capsys.readouterr().out)
    assert [list(entry) for entry in report] == [["file", "ok", "diagnostics", "proved", "facts", "undecided"]] * 3
    unread = report[1]
    assert unread["file"] == str(missing) and unread["ok"] is False and [d["code"] for d in unread["diagnostics"]] == [
        "E0008"]
    assert unread["proved"] == [] and unread["facts"] == [] and unread["undecided"] is False


def test_check_json_as_a_command(clean: Path) -> None:
    done = run_rac("check", "--format", "json", clean)
    assert done.returncode == 0, done.stderr
    [entry] = json.loads(done.stdout)
    assert entry["ok"] is True and entry["file"] == str(clean)


def test_check_multiple_files(capsys: pytest.CaptureFixture[str], clean: Path, p2_fails: Path,
                              syntax_error: Path) -> None:
    assert main(["check", str(clean), str(p2_fails), str(syntax_error)]) == 1
    out = capsys.readouterr().out
    assert f"{clean}: ok" in out
    assert f"{p2_fails}: 1 error" in out
    assert f"{syntax_error}: 1 error" in out
    assert out.index(f"{clean}: ok") < out.index(f"{p2_fails}: 1 error") < out.index(f"{syntax_error}: 1 error")


def test_check_multiple_clean_files(capsys: pytest.CaptureFixture[str], clean: Path) -> None:
    assert main(["check", str(clean), str(DRIVING)]) == 0
    assert capsys.readouterr().out.count(": ok") == 2


def test_check_that_stopped_at_its_limit_is_undecided(capsys: pytest.CaptureFixture[str], clean: Path,
                                                      p2_fails: Path) -> None:
    """A check that stopped at its limit (W0405) proved nothing: exit 4 (undecided), as rac verify for
    an undecided query, unless another file has an error (exit 1)."""
    unfinished = REPOSITORY / "tests" / "diagnostics" / "W0405_too_many_samples.ra"
    assert main(["check", str(clean), str(unfinished)]) == 4
    out = capsys.readouterr().out
    assert f"{clean}: ok" in out
    assert f"{unfinished}: undecided, 2 warnings (2 of them: a check stopped at its limit" in out
    assert main(["check", "--format", "json", str(unfinished), str(clean)]) == 4
    report = json.loads(capsys.readouterr().out)
    assert [entry["undecided"] for entry in report] == [True, False]
    assert [entry["ok"] for entry in report] == [True, True]
    assert main(["check", str(unfinished), str(p2_fails)]) == 1  # an error outranks an undecided check
    capsys.readouterr()


REQUIRED_NOT_MADE = """automaton Req {
    input g : bool
    reward p
    objective p
    sample every 1
    horizon 5
    initial location L0 { p' == 1 }
    edge L0 -> L0 when g do p = p / 2
    goal when g
    REQUIRE
}
"""


@pytest.mark.parametrize("require", ["require stalling_never_pays", "collision when !g\n    require risk <= 0.5"])
def test_a_required_check_that_cannot_be_made_is_undecided(capsys: pytest.CaptureFixture[str], tmp_path: Path,
                                                           require: str) -> None:
    """A `require`d incentive check left undone (W1008: an update that scales a reward) is neither proved
    nor refuted: exit 4 and `undecided`, never 0 and `ok`; without the `require`, W1008 stays a warning."""
    path = tmp_path / "req.ra"
    path.write_text(REQUIRED_NOT_MADE.replace("REQUIRE", require), encoding="utf-8")
    assert main(["check", str(path)]) == 4
    out = capsys.readouterr().out
    assert f"{path}: undecided, 1 warning (1 of them: a required check not made" in out
    assert f"`require {'risk' if 'risk' in require else 'stalling_never_pays'}` is neither proved nor refuted" in out
    assert main(["check", "--format", "json", str(path)]) == 4
    [entry] = json.loads(capsys.readouterr().out)
    assert entry["undecided"] is True and entry["ok"] is True
    path.write_text(REQUIRED_NOT_MADE.replace("REQUIRE", ""), encoding="utf-8")
    assert main(["check", str(path)]) == 0
    assert f"{path}: ok, 1 warning" in capsys.readouterr().out


@pytest.mark.parametrize("target", ["python", "uppaal"])
def test_compile_of_an_undecided_file_exits_as_check_does(capsys: pytest.CaptureFixture[str], tmp_path: Path,
                                                          clean: Path, target: str) -> None:
    """`rac check` exits 4 on a file whose check stopped at its limit (W0405) or whose required check was not
    made (W1008); `rac compile` made the same checks and exited 0, as for a file that passed. It writes the
    code and exits 4, saying why; JSON has "undecided"."""
    unfinished = REPOSITORY / "tests" / "diagnostics" / "W0405_too_many_samples.ra"
    required = tmp_path / "req.ra"
    required.write_text(REQUIRED_NOT_MADE.replace("REQUIRE", "require stalling_never_pays"), encoding="utf-8")
    output = tmp_path / ("out.py" if target == "python" else "out.xml")
    for path in (unfinished, required):
        assert main(["check", str(path)]) == 4
        output.unlink(missing_ok=True)
        capsys.readouterr()
        assert main(["compile", "--target", target, str(path), "-o", str(output)]) == 4
        err = capsys.readouterr().err
        assert output.exists() and f"wrote {output}" in err
        assert f"note: `{path}` is undecided: a check was not made (the warnings above say which)" in err
        assert main(["compile", "--target", target, "--format", "json", str(path), "-o", str(output)]) == 4
        summary = json.loads(capsys.readouterr().out)
        assert summary["ok"] is True and summary["undecided"] is True
        assert main(["compile", "--target", target, str(path)]) == 4  # to standard output: the same
        capsys.readouterr()
    assert main(["compile", "--target", target, "--format", "json", str(clean), "-o", str(output)]) == 0
    assert json.loads(capsys.readouterr().out)["undecided"] is False


def test_check_missing_file_exits_2(tmp_path: Path) -> None:
    missing = tmp_path / "nope.ra"
    done = run_rac("check", missing)
    assert done.returncode == 2
    assert "E0008" in done.stderr and str(missing) in done.stderr
    assert "Traceback" not in done.stderr


def test_check_directory_exits_2(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    assert main(["check", str(tmp_path)]) == 2
    err = capsys.readouterr().err
    assert "E0008" in err and "directory" in err


@pytest.mark.skipif(not hasattr(os, "geteuid") or os.geteuid() == 0, reason="root can read any file")
def test_check_unreadable_file_exits_2(capsys: pytest.CaptureFixture[str], clean: Path) -> None:
    clean.chmod(0)
    try:
        assert main(["check", str(clean)]) == 2
    finally:
        clean.chmod(0o644)
    assert "E0008" in capsys.readouterr().err


def test_check_unreadable_wins_over_errors(capsys: pytest.CaptureFixture[str], tmp_path: Path,
                                           p2_fails: Path) -> None:
    missing = tmp_path / "missing.ra"
    assert main(["check", str(p2_fails), str(missing)]) == 2
    capsys.readouterr()
    assert main(["check", "--format", "json", str(missing), str(p2_fails)]) == 2
    missing_entry, bad_entry = json.loads(capsys.readouterr().out)
    assert missing_entry["ok"] is False and missing_entry["diagnostics"][0]["code"] == "E0008"
    assert bad_entry["ok"] is False and bad_entry["diagnostics"][0]["code"] == "E0402"


# ---------------------------------------------------------------- compile
def test_compile_writes_a_module_that_imports_and_runs(tmp_path: Path) -> None:
    out = tmp_path / "driving_ra.py"
    done = run_rac("compile", DRIVING, "--target", "python", "-o", out)
    assert done.returncode == 0, done.stderr
    assert done.stdout == ""
    assert f"wrote {out}" in done.stderr
    script = (
        "import json, sys\n"
        "from driving_ra import Driving\n"
        "ra = Driving()\n"
        f"x = {VALID!r}\n"
        "total = sum(ra.step(x) for _ in range(300))\n"
        "total += ra.end(dict(x, dgoal=1.0))\n"
        "print(json.dumps([ra.location, ra.samples, total, sorted(sys.modules)]))\n"
    )
    # a child interpreter in the output folder, without rac on its path: the module needs only the stdlib
    env = {k: v for k, v in os.environ.items() if k != "PYTHONPATH"}
    ran = subprocess.run([sys.executable, "-c", script], cwd=tmp_path, env=env, capture_output=True,
                         text=True, timeout=60, check=False)
    assert ran.returncode == 0, ran.stderr
    location, samples, total, modules = json.loads(ran.stdout)
    assert (location, samples) == ("Normal", 300)
    assert total == pytest.approx(10 * 30 + 5 * (30 + 100) + 30)  # the objective's value at the end
    assert "rac" not in modules and "numpy" not in modules


def test_compile_to_stdout(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["compile", str(DRIVING), "--target", "python"]) == 0
    captured = capsys.readouterr()
    expected = generate_python(compile_file(DRIVING).raise_for_errors(), source_name=DRIVING.name)
    assert captured.out == expected
    ast.parse(captured.out)
    assert "class Driving" in captured.out


def test_compiled_module_steps_and_validates(tmp_path: Path) -> None:
    out = tmp_path / "driving_ra.py"
    assert main(["compile", str(DRIVING), "--target", "python", "-o", str(out)]) == 0
    module = types.ModuleType("driving_ra")
    exec(compile(out.read_text(encoding="utf-8"), str(out), "exec"), module.__dict__)  # noqa: S102
    ra = module.Driving()
    assert ra.step(VALID) == pytest.approx(1.6)  # 10*0.1 + 5*0.1 + 0.1
    with pytest.raises(ValueError, match="assume"):
        ra.step(dict(VALID, collide=True))


def test_compile_with_errors_leaves_the_output_alone(tmp_path: Path, p2_fails: Path, syntax_error: Path) -> None:
    out_dir = tmp_path / "out"
    out_dir.mkdir()
    out = out_dir / "driving_ra.py"
    original = b"# an earlier, good build\r\nkeep = 'me'\n\x00\xff"
    out.write_bytes(original)
    before = folder_listing(out_dir)
    for bad in (p2_fails, syntax_error):
        done = run_rac("compile", bad, "--target", "python", "-o", out)
        assert done.returncode == 1, done.stderr
        assert "error" in done.stderr and done.stdout == ""
        assert out.read_bytes() == original
        assert folder_listing(out_dir) == before  # no temporary file left behind


@pytest.mark.parametrize("target", ["python", "uppaal"])
def test_compile_replaces_only_what_rac_wrote(capsys: pytest.CaptureFixture[str], tmp_path: Path, target: str) -> None:
    # `rac compile ... -o reward.py` replaced a hand-written reward.py without a word
    source = DRIVING
    out = tmp_path / ("reward.py" if target == "python" else "model.xml")
    assert main(["compile", str(source), "--target", target, "-o", str(out)]) == 0
    assert main(["compile", str(source), "--target", target, "-o", str(out)]) == 0  # its own output: replaced
    capsys.readouterr()
    mine = out.with_suffix(".q") if target == "uppaal" else out
    mine.write_text("# my own reward, by hand\n", encoding="utf-8")
    assert main(["compile", str(source), "--target", target, "-o", str(out)]) == 2
    err = capsys.readouterr().err
    assert f"error[E0009]: cannot write `{mine}`: it exists and rac did not write it" in err
    assert mine.read_text(encoding="utf-8") == "# my own reward, by hand\n"


def test_compile_missing_input_exits_2_and_leaves_the_output_alone(capsys: pytest.CaptureFixture[str],
                                                                    tmp_path: Path) -> None:
    out = tmp_path / "out.py"
    out.write_text("old\n", encoding="utf-8")
    assert main(["compile", str(tmp_path / "missing.ra"), "--target", "python", "-o", str(out)]) == 2
    assert out.read_text(encoding="utf-8") == "old\n"
    assert folder_listing(tmp_path) == ["out.py"]
    assert "E0008" in capsys.readouterr().err


def test_compile_replaces_an_existing_output(tmp_path: Path) -> None:
    out = tmp_path / "driving_ra.py"
    out.write_text("# Generated by rac from an older driving.ra\nold\n", encoding="utf-8")  # an earlier build
    out.chmod(0o640)
    assert main(["compile", str(DRIVING), "--target", "python", "-o", str(out)]) == 0
    assert "class Driving" in out.read_text(encoding="utf-8")
    assert out.stat().st_mode & 0o777 == 0o640  # the file's permissions are kept
    assert folder_listing(tmp_path) == ["driving_ra.py"]


def test_compile_json_diagnostics(capsys: pytest.CaptureFixture[str], p2_fails: Path) -> None:
    assert main(["compile", str(p2_fails), "--target", "python", "--format", "json"]) == 1
    diagnostics = json.loads(capsys.readouterr().out)
    assert [d["code"] for d in diagnostics] == ["E0402"]


def test_compile_to_a_missing_folder_is_a_usage_error(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    code = main(["compile", str(DRIVING), "--target", "python", "-o", str(tmp_path / "no" / "such" / "out.py")])
    err = capsys.readouterr().err
    assert code == 2
    assert "internal error" not in err
    assert "error[E0009]: cannot write" in err


# ---------------------------------------------------------------- fmt
def test_fmt_rewrites_in_place_keeping_comments(unformatted: Path) -> None:
    done = run_rac("fmt", unformatted)
    assert done.returncode == 0, done.stderr
    assert f"{unformatted}: reformatted" in done.stderr
    formatted = unformatted.read_text(encoding="utf-8")
    assert formatted == GOLDEN_FMT.read_text(encoding="utf-8")
    original_comments = [line.split("//", 1)[1].strip() for line in DRIVING_TEXT.splitlines() if "//" in line]
    assert original_comments
    for comment in original_comments:
        assert f"// {comment}" in formatted
    assert folder_listing(unformatted.parent) == [unformatted.name]
    assert compile_file(unformatted).ok


def test_fmt_is_idempotent(capsys: pytest.CaptureFixture[str], unformatted: Path) -> None:
    assert main(["fmt", str(unformatted)]) == 0
    first = unformatted.read_bytes()
    capsys.readouterr()
    assert main(["fmt", str(unformatted)]) == 0
    assert unformatted.read_bytes() == first
    assert capsys.readouterr().err == ""  # nothing to say: already formatted


def test_fmt_check(capsys: pytest.CaptureFixture[str], unformatted: Path, tmp_path: Path) -> None:
    assert main(["fmt", "--check", str(unformatted)]) == 1
    assert f"{unformatted}: would be reformatted" in capsys.readouterr().err
    assert unformatted.read_text(encoding="utf-8") == UNFORMATTED  # --check never writes
    formatted = tmp_path / "formatted.ra"
    shutil.copy(GOLDEN_FMT, formatted)
    assert main(["fmt", "--check", str(formatted)]) == 0
    assert main(["fmt", "--check", str(formatted), str(unformatted)]) == 1


def test_fmt_check_as_a_command(unformatted: Path) -> None:
    assert run_rac("fmt", "--check", unformatted).returncode == 1
    assert run_rac("fmt", "--check", GOLDEN_FMT).returncode == 0


def test_fmt_stdout(capsys: pytest.CaptureFixture[str], unformatted: Path) -> None:
    assert main(["fmt", "--stdout", str(unformatted)]) == 0
    assert capsys.readouterr().out == GOLDEN_FMT.read_text(encoding="utf-8")
    assert unformatted.read_text(encoding="utf-8") == UNFORMATTED  # untouched


def test_fmt_check_with_stdout_keeps_the_checks_verdict(capsys: pytest.CaptureFixture[str], unformatted: Path) -> None:
    # `--check --stdout` printed the result and exited 0, the check forgotten
    assert main(["fmt", "--check", "--stdout", str(unformatted)]) == 1
    captured = capsys.readouterr()
    assert captured.out == GOLDEN_FMT.read_text(encoding="utf-8")
    assert captured.err == f"{unformatted}: would be reformatted\n"
    assert unformatted.read_text(encoding="utf-8") == UNFORMATTED
    assert main(["fmt", "--check", "--stdout", str(DRIVING)]) == 0  # in the layout already


def test_fmt_syntax_error_exits_1_and_leaves_the_file(capsys: pytest.CaptureFixture[str], syntax_error: Path) -> None:
    before = syntax_error.read_bytes()
    assert main(["fmt", str(syntax_error)]) == 1
    assert syntax_error.read_bytes() == before
    assert "error" in capsys.readouterr().err


def test_fmt_missing_file_exits_2(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    assert main(["fmt", str(tmp_path / "missing.ra")]) == 2
    assert main(["fmt", str(tmp_path)]) == 2


def test_fmt_never_writes_a_file_too_large_to_read_back(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    """A 138 KB file whose runs the layout pads to one 400-character name grew to 1.2 MB: `rac fmt`
    wrote it, and then `rac check` and `rac fmt` itself refused it (E0005). Now it is left as it is."""
    count, long = 2600, "M" * 400
    lines = ["automaton Big {", "input a : bool", "reward r", "objective r", "sample every 1", "horizon 10",
             "initial location L0 { r' == 1 }", f"location {long} {{ r' == 1 }}",
             *(f"location L{i} {{ r' == 1 }}" for i in range(1, count)),
             *(f"edge L{i} -> L{(i + 1) % count} when a" for i in range(count)), "}"]
    path = tmp_path / "big.ra"
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")
    before = path.read_bytes()
    for options in ([], ["--check"], ["--stdout"]):
        assert main(["fmt", *options, str(path)]) == 1
        captured = capsys.readouterr()
        assert captured.out == ""
        assert f"error[E0005]: `{path}` formatted is too large (1,188,730 bytes; at most 1,000,000)" in captured.err
    assert path.read_bytes() == before


# ---------------------------------------------------------------- usage
def test_version() -> None:
    done = run_rac("--version")
    assert done.returncode == 0
    assert done.stdout.strip() == f"rac {__version__}"


@pytest.mark.parametrize("argv", [
    [],
    ["frobnicate"],
    ["check"],
    ["check", "--format", "yaml", "x.ra"],
    ["compile", "x.ra"],
    ["compile", "x.ra", "--target", "c"],
    ["fmt"],
    ["--no-such-option"],
])
def test_bad_usage_exits_2(capsys: pytest.CaptureFixture[str], argv: list[str]) -> None:
    assert main(argv) == 2
    assert "usage:" in capsys.readouterr().err


@pytest.mark.parametrize("argv", [["--bogus"], ["-x"], ["--bogus", "--other"]])
def test_an_unknown_option_without_a_command_is_named(capsys: pytest.CaptureFixture[str], argv: list[str]) -> None:
    # it said "the following arguments are required: COMMAND" and never named the option
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert err.rstrip().endswith(f"rac: error: unrecognized arguments: {' '.join(argv)}") and "COMMAND" in err


def test_no_command_still_asks_for_one(capsys: pytest.CaptureFixture[str]) -> None:
    assert main([]) == 2
    assert capsys.readouterr().err.rstrip().endswith("rac: error: the following arguments are required: COMMAND")


@pytest.mark.parametrize(("argv", "option", "last"), [
    (["compile", "--target", "uppaal", "--target", "python"], "--target", "python"),
    (["compile", "--target", "python", "-o", "a.py", "--output", "b.py"], "-o/--output", "b.py"),
    (["check", "--format", "text", "--format", "json"], "--format", "json"),
])
def test_an_option_of_one_value_given_twice_is_said(capsys: pytest.CaptureFixture[str], clean: Path,
                                                   tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                                   argv: list[str], option: str, last: str) -> None:
    # the last one won silently: `--target python --target uppaal` wrote UPPAAL, `-o a.py -o b.py` wrote b.py
    # only. The last still counts (a script appends its override to its defaults), and the warning says so.
    monkeypatch.chdir(tmp_path)  # where the relative a.py and b.py go
    assert main([*argv, str(clean)]) == 0
    out, err = capsys.readouterr()
    assert f"warning: argument {option}: given twice with different values" in err
    assert f"`{last}`: the last one counts" in err
    if option == "--format":
        assert json.loads(out)[0]["ok"] is True
    if option == "-o/--output":
        assert not (tmp_path / "a.py").exists() and (tmp_path / "b.py").exists()
    if option == "--target":
        assert out.startswith("# Generated by rac")


def test_an_option_given_twice_with_one_value_and_a_repeatable_one_are_fine(capsys: pytest.CaptureFixture[str],
                                                                           clean: Path) -> None:
    assert main(["check", "-q", "--format", "json", "--format", "json", str(clean)]) == 0
    assert json.loads(capsys.readouterr().out)[0]["ok"] is True
    from rac.cli.arguments import build_parser

    args = build_parser().parse_args(["verify", "x.ra", "--query", "a", "--query", "b", "--horizon", "30",
                                      "--horizon", "30.0"])
    assert args.query == ["a", "b"] and args.horizon == 30  # the same number twice is that number


def test_bad_usage_as_a_command() -> None:
    done = run_rac("check")
    assert done.returncode == 2
    assert "usage:" in done.stderr and "Traceback" not in done.stderr


# ---------------------------------------------------------------- benchmarks
RUN_BENCHMARKS = REPOSITORY / "benchmarks" / "run.py"


@pytest.mark.skipif(not RUN_BENCHMARKS.exists(), reason="benchmarks/ is not in this tree")
def test_benchmarks_quick_smoke(tmp_path: Path) -> None:
    output = tmp_path / "latest.md"
    done = subprocess.run([sys.executable, str(RUN_BENCHMARKS), "--quick", "--output", str(output)],
                          env=rac_env(), capture_output=True, text=True, timeout=300, check=False)
    assert done.returncode == 0, done.stdout + done.stderr
    assert "benchmark" in done.stdout and "verdict" in done.stdout
    table = output.read_text(encoding="utf-8")
    assert "| benchmark | value | target | verdict |" in table
    for row in ("horizon 30 s", "horizon 3600 s", "fitted exponent", "generated / hand-written", "step_batch",
                "parse only", "agreement"):
        assert row in table, row
    assert "FAIL" not in table


# ---------------------------------------------------------------- a reader that leaves early
def test_a_failed_check_fails_whoever_reads_its_first_line(tmp_path: Path) -> None:
    """`rac check bad.ra | head -1`: the reader leaves after one line (the output is 400 kB, far more
    than a pipe holds); rac still exits 1, and prints no "Exception ignored" on the way out."""
    import subprocess
    import sys

    from conftest import rac_env

    lines = ["automaton A {", "    input d : bool", "    reward r", "    priority r", "    objective r",
             "    sample every 0.1", "    horizon 1", "    initial location L { r' == 1 }",
             *(f"    edge L -> L when nope{i}" for i in range(3000)), "}"]
    source = tmp_path / "many.ra"
    source.write_text("\n".join(lines) + "\n", encoding="utf-8")
    for _ in range(3):
        child = subprocess.Popen([sys.executable, "-m", "rac", "check", str(source)], env=rac_env(),
                                 stdout=subprocess.PIPE, stderr=subprocess.PIPE)
        assert child.stdout is not None and child.stderr is not None
        assert child.stdout.readline()  # head -1
        child.stdout.close()
        err = child.stderr.read().decode()
        assert child.wait(timeout=120) == 1
        assert "Exception ignored" not in err and "BrokenPipe" not in err


# ---------------------------------------------------------------- the files rac writes
def test_written_files_get_the_usual_mode_links_stay_links_and_the_source_is_never_overwritten(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    import os

    from rac.cli.main import main

    source = tmp_path / "driving.ra"
    source.write_text((REPOSITORY / "stdlib" / "driving.ra").read_text(encoding="utf-8"), encoding="utf-8")
    old = os.umask(0o022)
    try:
        assert main(["compile", "--target", "python", str(source), "-o", str(tmp_path / "out.py")]) == 0
    finally:
        os.umask(old)
    assert (tmp_path / "out.py").stat().st_mode & 0o777 == 0o644  # as any new file, not mkstemp's 0600
    # rac fmt through a symbolic link rewrites its target and keeps the link
    messy = tmp_path / "messy.ra"
    messy.write_text(source.read_text(encoding="utf-8").replace("horizon 30", "horizon    30"), encoding="utf-8")
    link = tmp_path / "link.ra"
    link.symlink_to(messy.name)
    assert main(["fmt", str(link)]) == 0
    assert link.is_symlink() and "horizon    30" not in messy.read_text(encoding="utf-8")
    # -o naming the input file (directly or through the link) is refused, nothing written
    before = messy.read_bytes()
    capsys.readouterr()
    for output in (messy, link):
        assert main(["compile", "--target", "python", str(messy), "-o", str(output)]) == 2
        assert "error[E0009]: cannot write" in capsys.readouterr().err
    assert main(["compile", "--target", "uppaal", str(messy), "-o", str(messy)]) == 2
    assert "error[E0009]: cannot write" in capsys.readouterr().err
    assert messy.read_bytes() == before


@pytest.mark.parametrize("command", [["check"], ["verify"], ["compile", "--target", "python"], ["tune"]])
def test_an_unknown_option_is_refused_with_the_commands_usage(capsys: pytest.CaptureFixture[str], clean: Path,
                                                              command: list[str]) -> None:
    # it was `rac`'s usage, "usage: rac [-h] [--version] COMMAND ...", which shows none of the command's options,
    # where a missing value or a bad choice shows the command's
    assert main([*command, str(clean), "--bogus"]) == 2
    err = capsys.readouterr().err
    assert err.startswith(f"usage: rac {command[0]} [-h]")
    assert err.rstrip().endswith(f"rac {command[0]}: error: unrecognized arguments: --bogus")
    assert clean.read_text(encoding="utf-8") == DRIVING_TEXT


# ---------------------------------------------------------------- file names that are not UTF-8
@pytest.fixture
def not_utf8(tmp_path: Path) -> Path:
    """driving.ra under a name whose byte 0xff is no UTF-8 (Python holds it as the surrogate escape U+DCFF)."""
    path = tmp_path / os.fsdecode(b"bad\xffname.ra")
    try:
        path.write_text(DRIVING_TEXT, encoding="utf-8")
    except (OSError, UnicodeEncodeError):  # a file system that takes only UTF-8 names
        pytest.skip("this file system refuses a name that is not UTF-8")
    return path


def test_a_name_its_output_cannot_encode_is_escaped_not_an_internal_error(tmp_path: Path) -> None:
    # PYTHONIOENCODING=ascii (a C locale, a Windows code page): `rac check ü.ra` ended in an internal error
    # (exit 3, UnicodeEncodeError) after its diagnostics were computed
    source = tmp_path / "ü.ra"
    source.write_text(DRIVING_TEXT, encoding="utf-8")
    env = {**rac_env(), "PYTHONIOENCODING": "ascii"}
    done = subprocess.run([sys.executable, "-m", "rac", "check", "-q", str(source)], env=env, capture_output=True,
                          check=False)
    assert done.returncode == 0 and done.stdout == f"{tmp_path}/\\xfc.ra: ok\n".encode("ascii"), done.stderr
    done = subprocess.run([sys.executable, "-m", "rac", "check", str(tmp_path / "gone-ü.ra")], env=env,
                          capture_output=True, check=False)
    assert done.returncode == 2 and b"gone-\\xfc.ra" in done.stderr and b"internal error" not in done.stderr


def test_a_file_name_not_utf8_is_shown_with_its_byte_escaped(not_utf8: Path, tmp_path: Path) -> None:
    # the text summary died of a UnicodeEncodeError on a UTF-8 standard output (exit 3), JSON held the lone
    # surrogate "bad\udcffname.ra", which strict UTF-8 and JSON readers reject, and rac compile -o could not
    # write the module's header naming the file (exit 3)
    shown = str(tmp_path / "bad\\xffname.ra")
    done = run_rac("check", "-q", not_utf8)  # rac_env: PYTHONIOENCODING=utf-8, strict
    assert done.returncode == 0 and done.stdout == f"{shown}: ok\n", done.stderr
    done = run_rac("check", "-q", "--format", "json", not_utf8, tmp_path / os.fsdecode(b"gone\xfe.ra"))
    assert done.returncode == 2 and "\\ud" not in done.stdout
    document = json.loads(done.stdout)
    assert [entry["file"] for entry in document] == [shown, str(tmp_path / "gone\\xfe.ra")]
    assert document[1]["diagnostics"][0]["message"].startswith(f"cannot read `{tmp_path / 'gone'}\\xfe.ra`")
    done = run_rac("check", tmp_path / os.fsdecode(b"gone\xfe.ra"))
    assert done.returncode == 2 and f"error[E0008]: cannot read `{tmp_path / 'gone'}\\xfe.ra`" in done.stderr
    output = tmp_path / "module.py"
    done = run_rac("compile", "--target", "python", not_utf8, "-o", output)
    assert done.returncode == 0, done.stderr
    assert output.read_text(encoding="utf-8").startswith("# Generated by rac from bad\\xffname.ra.")
