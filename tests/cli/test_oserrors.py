"""Ordinary OS conditions are the user's or the environment's, never rac's bug (issue 22): a full or
closed standard output, a name too long for the file system, an output folder that cannot be written
all exit 2 with a message naming what failed; ``fmt`` and ``tune`` do not lose each other's work;
failed writes leave no temporary or partial files; ``fmt --check`` agrees byte for byte with
``fmt --stdout``; ``rac new`` refuses a name that is no file name.

A read-only folder is played by a path *under a regular file* (``file.txt/out.xml``): the tests may
run as root, for whom ``chmod`` does not stop writes, and this fails alike for every user.
"""

from __future__ import annotations

import os
import subprocess
import sys
import time
from collections.abc import Callable
from pathlib import Path

import pytest
from conftest import rac_env, run_rac
from engine_files import write_engine_file

from rac.cli.common import write_atomically
from rac.cli.main import main
from rac.lang.resources import stdlib_dir

DRIVING = (stdlib_dir() / "driving.ra").read_text(encoding="utf-8")
LONG = "a" * 300
EXAMPLES = Path(__file__).resolve().parents[2] / "examples"


@pytest.fixture
def clean(tmp_path: Path) -> Path:
    path = tmp_path / "driving.ra"
    path.write_text(DRIVING, encoding="utf-8")
    return path


def run_with_stdout(stdout: object, *args: str | Path) -> subprocess.CompletedProcess[str]:
    """``python -m rac ARGS`` with its standard output opened on ``stdout`` (a file, or None: closed)."""
    if stdout is None:  # the child starts with file descriptor 1 closed, as `rac check x.ra >&-`
        code = "import os, runpy, sys; os.close(1); sys.argv = ['rac', *sys.argv[1:]]; " \
               "sys.stdout = None; runpy.run_module('rac', run_name='__main__')"
        return subprocess.run([sys.executable, "-c", code, *map(str, args)], env=rac_env(),
                              stderr=subprocess.PIPE, text=True, timeout=120, check=False)
    return subprocess.run([sys.executable, "-m", "rac", *map(str, args)], env=rac_env(), stdout=stdout,
                          stderr=subprocess.PIPE, text=True, timeout=120, check=False)


# ---------------------------------------------------------------- standard output
@pytest.mark.skipif(not Path("/dev/full").exists(), reason="needs /dev/full")
@pytest.mark.parametrize("command", [["check"], ["check", "--format", "json"], ["fmt", "--stdout"],
                                     ["compile", "--target", "python"], ["verify"]])
def test_a_full_standard_output_is_exit_2_with_a_message(
        clean: Path, tmp_path: Path, command: list[str]) -> None:
    if command == ["verify"]:  # the engine needs a model block
        command = ["verify", "--out", str(tmp_path / "out"), str(EXAMPLES / "left_turn" / "model.ra")]
    else:
        command = [*command, str(clean)]
    with open("/dev/full", "w", encoding="utf-8") as full:
        done = run_with_stdout(full, *command)
    assert done.returncode == 2, done.stderr
    assert "internal error" not in done.stderr and "Traceback" not in done.stderr
    assert "error[E0009]: cannot write `<standard output>`: No space left on device" in done.stderr
    assert "Exception ignored" not in done.stderr


def test_a_closed_standard_output_is_exit_2_with_a_message(clean: Path) -> None:
    done = run_with_stdout(None, "check", clean)
    assert done.returncode == 2, done.stderr
    assert "internal error" not in done.stderr
    assert "cannot write `<standard output>`: it is closed" in done.stderr


def test_a_closed_standard_output_does_not_matter_to_a_command_that_prints_nothing(tmp_path: Path) -> None:
    path = tmp_path / "x.ra"
    path.write_text(DRIVING.replace("  ", " "), encoding="utf-8")
    done = run_with_stdout(None, "fmt", path)
    assert done.returncode == 0, done.stderr


# ---------------------------------------------------------------- names and folders
def test_a_too_long_name_for_uppaal_is_e0009(clean: Path) -> None:
    done = run_rac("compile", clean, "--target", "uppaal", "-o", clean.parent / f"{LONG}.xml")
    assert done.returncode == 2, done.stderr
    assert "error[E0009]: cannot write" in done.stderr and "File name too long" in done.stderr
    assert "hint: use a shorter name" in done.stderr


def test_a_too_long_name_for_new_is_e0009(tmp_path: Path) -> None:
    done = run_rac("new", tmp_path / LONG)
    assert done.returncode == 2, done.stderr
    assert "error[E0009]: cannot write" in done.stderr and "File name too long" in done.stderr


@pytest.mark.parametrize("target", ["python", "uppaal"])
def test_an_output_folder_that_cannot_be_written_is_e0009(clean: Path, target: str) -> None:
    blocker = clean.parent / "file.txt"  # a folder under a regular file: unwritable even for root
    blocker.write_text("", encoding="utf-8")
    done = run_rac("compile", clean, "--target", target, "-o", blocker / "out.xml")
    assert done.returncode == 2, done.stderr
    assert "error[E0009]: cannot write" in done.stderr and "Not a directory" in done.stderr
    assert "a part of the path is a file, not a folder" in done.stderr


def test_an_engine_output_folder_that_is_a_file_is_e0009(tmp_path: Path) -> None:
    """`rac simulate -o runs.txt` over an existing file said "File exists" and sent the user to check that
    the folder is writable."""
    path = write_engine_file(tmp_path, "goal_ahead", {})
    blocker = tmp_path / "runs.txt"
    blocker.write_text("keep", encoding="utf-8")
    done = run_rac("simulate", "--runs", "1", "-o", blocker, path)
    assert done.returncode == 2, done.stderr
    assert f"error[E0009]: cannot write `{blocker}`: File exists" in done.stderr
    assert "hint: a file stands where a folder is needed (an engine command's -o names a folder, not a file)" \
        in done.stderr
    assert "check that the folder exists" not in done.stderr
    assert blocker.read_text(encoding="utf-8") == "keep"


def test_new_under_a_regular_file_is_e0009(tmp_path: Path) -> None:
    blocker = tmp_path / "file.txt"
    blocker.write_text("", encoding="utf-8")
    done = run_rac("new", blocker / "mine")
    assert done.returncode == 2, done.stderr
    assert "error[E0009]: cannot write" in done.stderr


@pytest.mark.parametrize("name", ["", ".", "..", ".ra", "sub/"])
def test_new_refuses_a_name_that_names_no_file(tmp_path: Path, name: str) -> None:
    done = run_rac("new", name, cwd=tmp_path)
    assert done.returncode == 2, done.stderr
    assert "rac new: NAME" in done.stderr and "names no file" in done.stderr
    assert list(tmp_path.iterdir()) == []


# ---------------------------------------------------------------- fmt --check agrees with --stdout
@pytest.mark.parametrize("variant", ["cr", "bom"])
def test_fmt_check_fails_when_stdout_would_differ_byte_for_byte(
        clean: Path, capsys: pytest.CaptureFixture[str], variant: str) -> None:
    assert main(["fmt", str(clean)]) == 0
    formatted = clean.read_bytes()
    data = formatted.replace(b"\n", b"\r") if variant == "cr" else b"\xef\xbb\xbf" + formatted
    clean.write_bytes(data)
    capsys.readouterr()
    assert main(["fmt", "--stdout", str(clean)]) == 0
    assert capsys.readouterr().out.encode() == formatted
    assert main(["fmt", "--check", str(clean)]) == 1
    assert "would be reformatted" in capsys.readouterr().err
    assert clean.read_bytes() == data
    assert main(["fmt", str(clean)]) == 0
    assert clean.read_bytes() == formatted


# ---------------------------------------------------------------- leftovers
def test_stale_temporary_files_are_removed_and_fresh_ones_kept(tmp_path: Path) -> None:
    path = tmp_path / "x.ra"
    stale, fresh = tmp_path / ".x.ra.abc123.tmp", tmp_path / ".x.ra.def456.tmp"
    stale.write_text("left by a killed writer", encoding="utf-8")
    fresh.write_text("another writer's, now", encoding="utf-8")
    old = time.time() - 2 * 3600
    os.utime(stale, (old, old))
    write_atomically(path, "text\n")
    assert path.read_text(encoding="utf-8") == "text\n"
    assert not stale.exists() and fresh.exists()


def test_a_failed_csv_write_leaves_no_partial_file(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    import numpy as np

    from rac.verify import report

    def fail(*args: object, **kwargs: object) -> None:
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(report.csv, "writer", lambda handle: type("W", (), {"writerow": fail})())
    with pytest.raises(OSError):
        report.write_csv(tmp_path / "runs.csv", np.zeros(2), ["x"], [np.zeros((1, 2))])
    assert list(tmp_path.iterdir()) == []


def test_fmt_keeps_a_hard_link(tmp_path: Path) -> None:
    path, other = tmp_path / "x.ra", tmp_path / "same.ra"
    path.write_text(DRIVING.replace("  ", " "), encoding="utf-8")
    os.link(path, other)
    assert main(["fmt", str(path)]) == 0
    assert os.path.samefile(path, other)
    assert other.read_text(encoding="utf-8") == path.read_text(encoding="utf-8") != DRIVING.replace("  ", " ")
    assert [p.name for p in tmp_path.iterdir() if p.name.endswith(".tmp")] == []


# ---------------------------------------------------------------- fmt and tune on one file
PARAM_TEXT = DRIVING.replace("const PENALTY = 100", "param PENALTY in [0, 1000]")


def test_tune_refuses_when_the_file_changed_while_it_worked(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]) -> None:
    """The deterministic interleaving: ``fmt`` rewrites the file after tune read it."""
    from rac.cli import tune

    path = tmp_path / "x.ra"
    path.write_text(PARAM_TEXT, encoding="utf-8")
    real = tune.compile_source

    def compile_then_fmt(*args: object, **kwargs: object) -> object:
        result = real(*args, **kwargs)
        assert main(["fmt", str(path)]) == 0  # another rac, between tune's read and its write
        return result

    monkeypatch.setattr(tune, "compile_source", compile_then_fmt)
    capsys.readouterr()
    assert main(["tune", str(path)]) == 2
    err = capsys.readouterr().err
    assert f"error[E0009]: cannot write `{path}`: it changed since rac tune read it" in err
    assert "nothing was written" in err
    assert "param PENALTY in [0, 1000]" in path.read_text(encoding="utf-8")  # fmt's work is kept, not overwritten


def test_concurrent_fmt_and_tune_never_both_succeed_while_losing_work(tmp_path: Path) -> None:
    """Real processes: either both succeed and the file is tuned and formatted, or tune says it lost."""
    path = tmp_path / "x.ra"
    for _ in range(3):
        path.write_text(PARAM_TEXT.replace("  ", " "), encoding="utf-8")
        command = [sys.executable, "-m", "rac"]
        tune = subprocess.Popen([*command, "tune", str(path)], env=rac_env(), stdout=subprocess.PIPE,
                                stderr=subprocess.PIPE, text=True)
        fmt = subprocess.Popen([*command, "fmt", str(path)], env=rac_env(), stdout=subprocess.PIPE,
                               stderr=subprocess.PIPE, text=True)
        tune_err, fmt_err = tune.communicate(timeout=120)[1], fmt.communicate(timeout=120)[1]
        assert fmt.returncode == 0, fmt_err
        text = path.read_text(encoding="utf-8")
        tuned = "const PENALTY = 98" in text
        if tune.returncode == 0:  # fmt ran first (tune keeps fmt's layout) or tune did (fmt formatted it)
            assert tuned, "tune exited 0 but its work was lost"
            assert main(["fmt", "--check", str(path)]) == 0, "fmt exited 0 but its work was lost"
        else:
            assert tune.returncode == 2 and "changed since rac tune read it" in tune_err, tune_err
            assert not tuned


def test_a_hard_link_that_cannot_be_rewritten_in_place_still_gets_a_whole_file(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    import builtins

    from rac.cli import common

    path, other = tmp_path / "x.ra", tmp_path / "same.ra"
    path.write_text("old\n", encoding="utf-8")
    os.link(path, other)
    real_open = builtins.open

    def full_disk(file: object, mode: str = "r", *args: object, **kwargs: object) -> object:
        if Path(str(file)) == path and "w" in mode:
            raise OSError(28, "No space left on device")
        return real_open(file, mode, *args, **kwargs)

    monkeypatch.setattr(builtins, "open", full_disk)
    with pytest.raises(OSError, match="has all of the new text"):
        common.write_atomically(path, "new\n")
    monkeypatch.undo()
    assert path.read_text(encoding="utf-8") == "new\n"
    assert [p.name for p in tmp_path.iterdir() if p.name.endswith(".tmp")] == []


# ---------------------------------------------------------------- standard error closed or full
def run_with_stderr(how: str, *args: str | Path) -> subprocess.CompletedProcess[str]:
    """``python -m rac ARGS 2>&-`` (``how`` "closed": a shell closes descriptor 2 before Python starts) or
    ``2>/dev/full`` ("full"); standard output captured."""
    redirect = "2>&-" if how == "closed" else "2>/dev/full"
    return subprocess.run(["sh", "-c", f'"$0" -m rac "$@" {redirect}', sys.executable, *map(str, args)],
                          env=rac_env(), stdout=subprocess.PIPE, text=True, timeout=120, check=False)


@pytest.mark.skipif(not Path("/dev/full").exists() or os.name != "posix", reason="needs sh and /dev/full")
@pytest.mark.parametrize("how", ["closed", "full"])
def test_a_closed_or_full_standard_error_keeps_the_exit_code(tmp_path: Path, how: str) -> None:
    """The messages are lost (there is nowhere to report that), but not the exit code: a missing file is
    still 2, a file with errors 1, a clean one 0; no traceback or internal error (exit 3), and no
    message strays onto standard output."""
    bad = tmp_path / "bad.ra"
    bad.write_text("automaton A {\n", encoding="utf-8")
    clean = tmp_path / "clean.ra"
    clean.write_text(DRIVING, encoding="utf-8")
    missing = run_with_stderr(how, "check", tmp_path / "missing.ra")
    assert missing.returncode == 2 and missing.stdout == ""
    compiled = run_with_stderr(how, "compile", "--target", "python", bad, "-o", tmp_path / "bad.py")
    assert compiled.returncode == 1 and compiled.stdout == "" and not (tmp_path / "bad.py").exists()
    assert run_with_stderr(how, "check", bad).returncode == 1
    assert run_with_stderr(how, "fmt", "--check", bad).returncode == 1
    done = run_with_stderr(how, "compile", "--target", "python", clean, "-o", tmp_path / "clean.py")
    assert done.returncode == 0 and (tmp_path / "clean.py").exists()
    assert run_with_stderr(how, "check").returncode == 2  # usage: argparse's message is lost too


@pytest.mark.parametrize("command", [["fmt"], ["compile", "--target", "python", "-o", "{out}"]])
def test_a_read_only_file_is_not_replaced(command: list[str], tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                          capsys: pytest.CaptureFixture[str]) -> None:
    """A rename needs only the folder's permission: `rac fmt` replaced a `chmod a-w` file that open()
    (every editor and formatter) refuses to write. The tests run as root, for whom every file is
    writable: `os.access` answers as it does for a user who may not write the file."""
    source = tmp_path / "x.ra"
    source.write_text((stdlib_dir() / "driving.ra").read_text(encoding="utf-8").replace("\n", "\n\n"),
                      encoding="utf-8")
    out = tmp_path / "x.py"
    main(["compile", "--target", "python", "-o", str(out), str(source)])
    target = source if command == ["fmt"] else out
    before = target.read_bytes()
    writable = os.access
    monkeypatch.setattr(os, "access", lambda path, mode, **kw: (
        False if Path(path) == target and mode == os.W_OK else writable(path, mode, **kw)))
    capsys.readouterr()
    assert main([*(part.format(out=out) for part in command), str(source)]) == 2
    err = capsys.readouterr().err
    assert f"error[E0009]: cannot write `{target}`: the file is read-only" in err
    assert "chmod u+w" in err
    assert target.read_bytes() == before


# ---------------------------------------------------------------- two writers of one output folder
def second_writer_at_first_rename(monkeypatch: pytest.MonkeyPatch, second: Callable[[], object]) -> None:
    """``os.replace`` that, when the first writer renames its finished temporary file, runs ``second`` (another
    rac writing the same file: two ``rac verify`` of one file, or `make -j`) to its end first."""
    real, calls = os.replace, []

    def replace(source: object, target: object) -> None:
        if not calls:
            calls.append(source)
            second()
        real(source, target)  # type: ignore[arg-type]

    monkeypatch.setattr(os, "replace", replace)


def _csv(path: Path, run: int) -> None:
    import numpy as np

    from rac.verify.report import write_csv

    write_csv(path, np.arange(3.0), ["x"], [np.full((run, 3), float(run))])


def _shield(path: Path, run: int) -> None:
    import numpy as np

    from rac.engine import shield

    shield.save(shield.ShieldTable(("k",), np.arange(run, dtype=np.int32).reshape(run, 1),
                                   np.ones((run, 4), dtype=bool)), path)


def _strategy(path: Path, run: int) -> None:
    import numpy as np

    from rac.learning.strategy import LearnedStrategy

    LearnedStrategy((), ("x",), (1.0,), "max", np.zeros((run, 1)), np.full((run, 2), float(run))).save(path)


def _read(writer: Callable[[Path, int], None], path: Path) -> int:
    """Which run's version ``path`` holds (an error when it is no whole one)."""
    if writer is _csv:
        return int(float(path.read_text(encoding="utf-8").splitlines()[-1].split(",")[-1]))
    if writer is _shield:
        from rac.engine import shield

        return len(shield.load(path).states)
    from rac.learning.strategy import LearnedStrategy

    return LearnedStrategy.load(path).n_states


@pytest.mark.parametrize("writer", [_csv, _shield, _strategy], ids=["runs.csv", "shield", "strategy"])
def test_two_writers_of_one_file_both_finish_and_leave_a_whole_one(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch, writer: Callable[[Path, int], None]) -> None:
    # every writer used one temporary name, `NAME.partial`: the second truncated and renamed the first's
    # temporary file, so the first failed (FileNotFoundError, an exit 3 or E0009 for a write that was fine)
    # and its unflushed rest could go into the file the second had just put in place
    path = tmp_path / "out.bin"
    second_writer_at_first_rename(monkeypatch, lambda: writer(path, 500))
    writer(path, 2)
    assert _read(writer, path) == 2  # the last rename wins, whole
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out.bin"]


def test_a_full_disk_while_writing_names_the_file(tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                                  capsys: pytest.CaptureFixture[str]) -> None:
    # a write's ENOSPC carries no file name: E0009 named the output folder ("cannot write `out`: No space left
    # on device"), which sent the user looking for a folder at fault, not at the file that failed
    import errno

    from rac.verify import report

    def full(*args: object, **kwargs: object) -> None:
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(report.csv, "writer", lambda handle: type("W", (), {"writerow": full})())
    path = write_engine_file(tmp_path, "goal_ahead", {})
    assert main(["simulate", str(path), "--runs", "2", "--seed", "1", "-q", "-o", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err
    assert f"error[E0009]: cannot write `{tmp_path / 'out' / 'runs.csv'}`: No space left on device" in err
    assert "free some space on the disk" in err
    assert [p.name for p in (tmp_path / "out").iterdir()] == []
