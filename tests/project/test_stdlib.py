"""The standard library (stdlib/*.ra): every file checks with its priority proved, is in canonical
layout, compiles to both targets (UPPAAL's parser accepts the model), says in its header what
`rac check` proves, and has a `model` example (examples/stdlib/NAME.ra) that checks on a scene
rac.model.scenes builds (kept beside it). ``rac new`` copies one as a starting point."""

from __future__ import annotations

import re
from pathlib import Path

import pytest
from conftest import REPOSITORY

from rac.cli.main import main
from rac.compiler import compile_file
from rac.lang.resources import stdlib_dir
from rac.model.scenes import scene_bytes
from rac.targets.python import generate_python
from rac.targets.uppaal.automaton import generate_uppaal

STDLIB = sorted((REPOSITORY / "stdlib").glob("*.ra"))
#: The files this part of issue 14 adds; driving.ra (the paper's automaton) was there before.
NEW = ("safe_distance", "speed_limit", "goal_window", "lane_change")
EXAMPLES = REPOSITORY / "examples" / "stdlib"


def _check(path: Path, capsys: pytest.CaptureFixture[str]) -> tuple[int, str]:
    status = main(["check", str(path)])
    return status, capsys.readouterr().out


def test_the_library_has_its_files() -> None:
    assert {p.stem for p in STDLIB} >= {"driving", *NEW}
    # rac's own library (the checkout's, or the installed wheel's copy of it) holds the same files
    installed = {path.name: path.read_bytes() for path in stdlib_dir().glob("*.ra")}
    assert installed == {path.name: path.read_bytes() for path in STDLIB}


@pytest.mark.parametrize("path", STDLIB, ids=lambda p: p.stem)
def test_checks_with_its_priority_proved(path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    status, out = _check(path, capsys)
    assert status == 0, out
    assert f"{path}: ok\n" in out  # no warning either
    facts = re.findall(r"^  proved: (.*)$", out, re.M)
    assert "P1 holds: wherever a reward decreases, no lower-priority reward grows" in facts
    highest = compile_file(path).automaton.priority[0]
    p2 = [f for f in facts if f.startswith(f"P2 holds for `{highest}` (penalised in `")]
    assert len(p2) == 1, facts
    assert re.search(r"the objective stays <= -\d", p2[0]), p2  # strictly negative where penalised
    assert any(f.startswith("deterministic") for f in facts)


@pytest.mark.parametrize("name", NEW)
def test_header_says_what_check_proves(name: str, capsys: pytest.CaptureFixture[str]) -> None:
    path = REPOSITORY / "stdlib" / f"{name}.ra"
    text = path.read_text(encoding="utf-8")
    header = text[:text.index("\nautomaton ")]
    _, out = _check(path, capsys)
    proved = re.findall(r"^  (proved: .*)$", out, re.M)
    assert re.findall(r"^//   (proved: .*)$", header, re.M) == proved
    for part in ("Rewards", "Inputs", "bind ", "Priorities"):
        assert part in header, f"{name}.ra's header does not say its {part}"


@pytest.mark.parametrize("path", STDLIB, ids=lambda p: p.stem)
def test_is_fmt_clean(path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["fmt", "--check", str(path)]) == 0, capsys.readouterr().err


@pytest.mark.parametrize("path", STDLIB, ids=lambda p: p.stem)
def test_compiles_to_both_targets(path: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str], utap) -> None:
    assert main(["compile", "--target", "python", str(path), "-o", str(tmp_path / "reward.py")]) == 0
    namespace: dict[str, object] = {}
    exec(compile((tmp_path / "reward.py").read_text(encoding="utf-8"), "reward.py", "exec"), namespace)
    automaton = compile_file(path).automaton
    assert (tmp_path / "reward.py").read_text(encoding="utf-8") == generate_python(automaton, source_name=path.name)
    assert main(["compile", "--target", "uppaal", str(path), "-o", str(tmp_path / "reward.xml")]) == 0
    capsys.readouterr()
    model = generate_uppaal(automaton, source_name=path.name, model_name="reward.xml")
    assert (tmp_path / "reward.xml").read_text(encoding="utf-8") == model.xml
    utap.validate(model.xml, model.queries, path.stem)


#: The horizon line of a model example: the 12 s of its scene's traffic and goal window.
_SCENE_HORIZON = "\n    horizon 12  // the scene's 12 s of traffic and goal window (the stdlib file: 30 s)\n"


def _without_model_block(text: str) -> str:
    return re.sub(r"\n\n    model \{\n(?:        .*\n)*    \}\n", "\n", text)


@pytest.mark.parametrize("name", NEW)
def test_model_example_checks_on_its_scene(name: str, capsys: pytest.CaptureFixture[str]) -> None:
    path = EXAMPLES / f"{name}.ra"
    example = path.read_text(encoding="utf-8")
    stdlib = (REPOSITORY / "stdlib" / f"{name}.ra").read_text(encoding="utf-8")
    # the example is the stdlib automaton itself, plus its model block, over the scene's 12 s
    body = example[example.index("automaton "):]
    assert "\n    horizon 30\n" in stdlib
    automaton = stdlib[stdlib.index("automaton "):]
    assert _without_model_block(body) == automaton.replace("\n    horizon 30\n", _SCENE_HORIZON)
    scene = re.search(r'scenario "(\w+)\.xml"', example)
    assert scene, f"examples/stdlib/{name}.ra has no scene"
    # the scene beside it is the one rac.model.scenes builds
    assert (EXAMPLES / f"{scene.group(1)}.xml").read_bytes() == scene_bytes(scene.group(1))
    status, out = _check(path, capsys)
    assert status == 0, out
    # the scenes of rac.model.scenes record 12 s of traffic: a horizon of 30 s ran past it (W0728)
    assert f"{path}: ok\n" in out and "warning[" not in out, out
    assert f"proved: scenario {scene.group(1)}.xml: " in out
    # every binding in the stdlib header is the one the example uses
    bindings = re.findall(r"^        (bind \w+ += .*?)(?:\s+//.*)?$", example, re.M)
    header = stdlib[:stdlib.index("\nautomaton ")]
    assert [" ".join(b.split()) for b in bindings] == \
        [" ".join(b.split()) for b in re.findall(r"^//     (bind .*)$", header, re.M)]


# ---------------------------------------------------------------- rac new
def test_new_copies_renames_and_checks(tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                       capsys: pytest.CaptureFixture[str]) -> None:
    monkeypatch.chdir(tmp_path)
    assert main(["new", "rewards/my_limit", "--from", "speed_limit"]) == 0
    out = capsys.readouterr().out
    assert out.splitlines() == [f"wrote rewards/my_limit.ra (from {stdlib_dir() / 'speed_limit.ra'}, "
                                "automaton MyLimit)", "next: rac check rewards/my_limit.ra"]
    written = (tmp_path / "rewards" / "my_limit.ra").read_text(encoding="utf-8")
    original = (REPOSITORY / "stdlib" / "speed_limit.ra").read_text(encoding="utf-8")
    assert written == original.replace("automaton SpeedLimit {", "automaton MyLimit {")
    status, out = _check(Path("rewards/my_limit.ra"), capsys)
    assert status == 0 and "rewards/my_limit.ra: ok" in out
    assert compile_file(tmp_path / "rewards" / "my_limit.ra").automaton.name == "MyLimit"


def test_new_defaults_to_driving_and_takes_a_stdlib_path(tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                                         capsys: pytest.CaptureFixture[str]) -> None:
    monkeypatch.chdir(tmp_path)
    assert main(["new", "cruise"]) == 0
    assert compile_file(tmp_path / "cruise.ra").automaton.name == "Cruise"
    assert "Qh: A[] Unsafe imply" in (tmp_path / "cruise.ra").read_text(encoding="utf-8")
    # `--from stdlib/X.ra` resolves through the library even where no stdlib/ folder is
    assert main(["new", "2nd", "--from", "stdlib/lane_change.ra"]) == 0
    out = capsys.readouterr().out
    assert "wrote 2nd.ra" in out and "next: rac check 2nd.ra" in out
    # not an identifier: the automaton keeps its name
    assert compile_file(tmp_path / "2nd.ra").automaton.name == "LaneChange"


def test_new_renames_qualified_references(tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                          capsys: pytest.CaptureFixture[str]) -> None:
    monkeypatch.chdir(tmp_path)
    source = (REPOSITORY / "stdlib" / "lane_change.ra").read_text(encoding="utf-8")
    (tmp_path / "mine.ra").write_text(source.replace("E<> Done", "E<> LaneChange.Done"), encoding="utf-8")
    assert main(["new", "overtake", "--from", "mine.ra"]) == 0
    written = (tmp_path / "overtake.ra").read_text(encoding="utf-8")
    assert "E<> Overtake.Done" in written and "LaneChange" not in written.split("automaton ", 1)[1]
    assert _check(Path("overtake.ra"), capsys)[0] == 0


def test_new_refuses_to_overwrite(tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                  capsys: pytest.CaptureFixture[str]) -> None:
    monkeypatch.chdir(tmp_path)
    (tmp_path / "mine.ra").write_text("// mine\n", encoding="utf-8")
    assert main(["new", "mine", "--from", "goal_window"]) == 2
    err = capsys.readouterr().err
    assert "error[E0009]: cannot write `mine.ra`: the file exists" in err
    assert (tmp_path / "mine.ra").read_text(encoding="utf-8") == "// mine\n"


def test_new_from_an_unknown_file_lists_the_library(tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                                    capsys: pytest.CaptureFixture[str]) -> None:
    monkeypatch.chdir(tmp_path)
    assert main(["new", "x", "--from", "nothere"]) == 2
    err = capsys.readouterr().err
    assert "error[E0008]" in err and "speed_limit.ra" in err
    assert not (tmp_path / "x.ra").exists()


@pytest.mark.parametrize("name", NEW)
def test_model_example_compiles_to_a_whole_uppaal_model(name: str, tmp_path: Path,
                                                        capsys: pytest.CaptureFixture[str], utap) -> None:
    out = tmp_path / f"{name}.xml"
    assert main(["compile", "--target", "uppaal", str(EXAMPLES / f"{name}.ra"), "-o", str(out)]) == 0, \
        capsys.readouterr().err
    xml = out.read_text(encoding="utf-8")
    assert "mindist" in xml or "dist_goal" in xml or "offroad" in xml  # the bindings' model functions
    utap.validate(xml, out.with_suffix(".q").read_text(encoding="utf-8"), f"{name}_model")
