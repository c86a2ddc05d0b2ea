"""rac.cli.new: ``rac new NAME --from FILE`` copies a file, renaming its automaton after NAME."""

from __future__ import annotations

import argparse
from pathlib import Path

import pytest

from rac.cli.common import EXIT_OK, EXIT_USAGE
from rac.cli.main import main
from rac.cli.new import camel_case, new_command, renamed, template_path
from rac.compiler import compile_file
from rac.lang.resources import stdlib_file

STDLIB = Path(__file__).resolve().parents[2] / "stdlib"


@pytest.mark.parametrize(("name", "camel"), [
    ("my_reward", "MyReward"), ("speed", "Speed"), ("a__b_", "AB"), ("x2_y", "X2Y"),
    ("_", None), ("2fast", None), ("my-reward", None), ("", None),
])
def test_camel_case(name: str, camel: str | None) -> None:
    assert camel_case(name) == camel


def test_template_path_finds_stdlib_names() -> None:
    for template in ("speed_limit", "speed_limit.ra", "stdlib/speed_limit.ra"):
        assert template_path(template).name == "speed_limit.ra"
        assert template_path(template).read_bytes() == (STDLIB / "speed_limit.ra").read_bytes()
    with pytest.raises(FileNotFoundError):
        template_path("some/where/missing.ra")


def test_renamed_changes_the_declaration_and_qualified_references() -> None:
    text = "automaton Old {\n  input p : bool\n  reward r\n  objective r\n" \
           "  initial location L { r' == 1 }\n  query Q: E<> Old.L\n}\n"
    new = renamed(text, "Fresh")
    assert "automaton Fresh {" in new and "E<> Fresh.L" in new and "Old" not in new
    assert renamed("not a .ra file {", "Fresh") == "not a .ra file {"  # does not parse: unchanged


def test_new_command_writes_a_checked_copy(tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                           capsys: pytest.CaptureFixture[str]) -> None:
    monkeypatch.chdir(tmp_path)
    code = new_command(argparse.Namespace(name="my_limit", template="speed_limit"))
    assert code == EXIT_OK
    written = tmp_path / "my_limit.ra"
    assert "automaton MyLimit" in written.read_text(encoding="utf-8")
    out = capsys.readouterr().out
    assert "wrote my_limit.ra" in out and "automaton MyLimit" in out and "next: rac check my_limit.ra" in out
    original, copy = compile_file(STDLIB / "speed_limit.ra"), compile_file(written)
    assert copy.ok and original.ok
    assert [loc.name for loc in copy.automaton.locations] == [loc.name for loc in original.automaton.locations]
    # never overwrites
    assert new_command(argparse.Namespace(name="my_limit", template="speed_limit")) == EXIT_USAGE
    assert "E0009" in capsys.readouterr().err


@pytest.mark.parametrize(("name", "shown"), [("my limit", "'my limit.ra'"), ("-x", "./-x.ra")])
def test_the_next_command_can_be_pasted(name: str, shown: str, tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                        capsys: pytest.CaptureFixture[str]) -> None:
    """`next: rac check my limit.ra` checks two files; `next: rac check -x.ra` is an unknown option."""
    monkeypatch.chdir(tmp_path)
    assert new_command(argparse.Namespace(name=name, template="speed_limit")) == EXIT_OK
    assert f"next: rac check {shown}\n" in capsys.readouterr().out


def test_new_command_refuses_names_of_no_file(capsys: pytest.CaptureFixture[str]) -> None:
    assert new_command(argparse.Namespace(name="..", template="speed_limit")) == EXIT_USAGE
    assert "names no file" in capsys.readouterr().err


def test_renamed_leaves_strings_and_comments_that_read_alike() -> None:
    """Only the parser's references are renamed: `Old.xml` in a scenario path or a comment is a file's
    name, and `Old . L` with spaces is a reference too."""
    text = ("automaton Old {  // see Old.md\n  input p : bool\n  reward r\n  objective r\n"
            "  initial location L { r' == 1 }\n  query Q: E<> Old . L\n"
            "  model {\n    scenario \"Old.xml\"\n  }\n}\n")
    new = renamed(text, "Fresh")
    assert "automaton Fresh {" in new and "E<> Fresh . L" in new
    assert 'scenario "Old.xml"' in new and "// see Old.md" in new


def test_new_command_repoints_a_relative_scenario(tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                                  capsys: pytest.CaptureFixture[str]) -> None:
    """A copy into another folder names the same scenario file: the checker resolves the path from
    the folder of the file that writes it."""
    scene = STDLIB.parent / "examples" / "left_turn"
    (tmp_path / "left_turn.xml").write_bytes((scene / "left_turn.xml").read_bytes())
    (tmp_path / "model.ra").write_text((scene / "model.ra").read_text(encoding="utf-8"), encoding="utf-8")
    monkeypatch.chdir(tmp_path)
    assert new_command(argparse.Namespace(name="sub/turn", template="model.ra")) == EXIT_OK
    text = (tmp_path / "sub" / "turn.ra").read_text(encoding="utf-8")
    assert 'scenario "../left_turn.xml"  // the paper' in text
    assert compile_file(tmp_path / "sub" / "turn.ra").ok
    capsys.readouterr()
    # in the same folder, nothing to rewrite
    assert new_command(argparse.Namespace(name="turn", template="model.ra")) == EXIT_OK
    assert 'scenario "left_turn.xml"' in (tmp_path / "turn.ra").read_text(encoding="utf-8")


def test_without_from_the_stdlib_file_even_beside_a_file_of_its_name(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]) -> None:
    """`rac new foo` copied the user's own driving.ra of the working folder, not the standard library's."""
    monkeypatch.chdir(tmp_path)
    (tmp_path / "driving.ra").write_text("automaton Mine {\n    reward r\n    objective r\n    sample every 1\n"
                                         "    horizon 2\n    initial location A { r' == 1 }\n}\n", encoding="utf-8")
    assert main(["new", "foo"]) == EXIT_OK
    copied = (tmp_path / "foo.ra").read_text(encoding="utf-8")
    installed = stdlib_file("driving.ra")  # the checkout's stdlib/, or the installed package's copy
    assert copied == renamed(installed.read_text(encoding="utf-8"), "Foo")
    assert f"(from {installed}, automaton Foo)" in capsys.readouterr().out
    # --from names a file: the one in the working folder
    assert main(["new", "bar", "--from", "driving.ra"]) == EXIT_OK
    assert "automaton Bar {\n    reward r\n" in (tmp_path / "bar.ra").read_text(encoding="utf-8")


@pytest.mark.parametrize(("text", "where", "code"), [
    ("automaton Old {\n  input a : bool\n  reward r r\n}\n", "bad.ra:3:12: error[E0001]", "E0001"),
    ("// nothing here\n", "bad.ra:1:1: error[E0007]", "E0007"),
])
def test_a_from_file_that_does_not_parse_is_its_syntax_error_and_writes_nothing(
        text: str, where: str, code: str, tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
        capsys: pytest.CaptureFixture[str]) -> None:
    """`rac new --from` a file with a syntax error: the error as rac check prints it (place, code,
    caret), exit 1, and no NAME.ra: a copy of a broken file is no start (it was copied, exit 0)."""
    monkeypatch.chdir(tmp_path)
    (tmp_path / "bad.ra").write_text(text, encoding="utf-8")
    capsys.readouterr()
    assert main(["new", "fresh", "--from", "bad.ra"]) == 1
    captured = capsys.readouterr()
    assert captured.err.startswith(where) and "^" in captured.err and "Traceback" not in captured.err
    assert captured.out == "" and not (tmp_path / "fresh.ra").exists()
    assert list(tmp_path.iterdir()) == [tmp_path / "bad.ra"]  # no temporary file left either
    main(["check", "bad.ra"])
    assert f"error[{code}]" in capsys.readouterr().out


@pytest.mark.parametrize("name", ["notes/fresh", "notes/deeper/fresh"])
def test_a_file_where_the_folder_goes_is_named_as_such(name: str, tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                                         capsys: pytest.CaptureFixture[str]) -> None:
    """`rac new notes/fresh` with `notes` a file said "cannot write `notes/fresh.ra`: File exists" (a file
    that does not exist) and sent the user to an engine command's -o: now the path's part that is a file."""
    monkeypatch.chdir(tmp_path)
    (tmp_path / "notes").write_text("mine\n", encoding="utf-8")
    assert main(["new", name]) == EXIT_USAGE
    err = capsys.readouterr().err
    assert f"error[E0009]: cannot write `{name}.ra`: Not a directory" in err
    assert "a part of the path is a file, not a folder" in err and "File exists" not in err and "-o" not in err
    assert (tmp_path / "notes").read_text(encoding="utf-8") == "mine\n"


def test_a_file_made_while_new_works_is_never_replaced(tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                                      capsys: pytest.CaptureFixture[str]) -> None:
    # `rac new` looked whether NAME.ra existed, then wrote it by a rename, which replaces whatever was made
    # there in between (a second `rac new x` of a script, an editor saving): the user's file was lost
    import rac.cli.new

    target = tmp_path / "mine.ra"
    real = rac.cli.new.repointed

    def meanwhile(*args: object) -> str:
        target.write_text("// the user's own file\n", encoding="utf-8")
        return real(*args)  # type: ignore[arg-type]

    monkeypatch.setattr(rac.cli.new, "repointed", meanwhile)
    assert main(["new", str(tmp_path / "mine")]) == EXIT_USAGE
    assert f"error[E0009]: cannot write `{target}`: the file exists" in capsys.readouterr().err
    assert target.read_text(encoding="utf-8") == "// the user's own file\n"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["mine.ra"]


def test_a_full_disk_leaves_no_half_new_file(tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                            capsys: pytest.CaptureFixture[str]) -> None:
    import contextlib
    import errno
    import os

    real = os.fdopen

    @contextlib.contextmanager
    def full(fd: int, *args: object, **kwargs: object):  # type: ignore[no-untyped-def]
        with real(fd, *args, **kwargs) as handle:  # type: ignore[call-overload]
            handle.write("// half")
            handle.flush()
            raise OSError(errno.ENOSPC, "No space left on device")
        yield handle

    monkeypatch.setattr(os, "fdopen", full)
    code = main(["new", str(tmp_path / "mine")])
    monkeypatch.undo()
    assert code == EXIT_USAGE
    assert "No space left on device" in capsys.readouterr().err and list(tmp_path.iterdir()) == []
