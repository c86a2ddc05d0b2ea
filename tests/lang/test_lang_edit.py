"""rac.lang.edit: a .ra file's model block with another scenario and settings, the one owner of the
edit shared by rac sweep's templates and ScenarioEnv's scene sets."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

from rac.lang.edit import with_model
from rac.lang.parser import parse_text

TEXT = """\
automaton A {
    reward r
    objective r
    sample every 1
    horizon 2
    initial location L { r' == 1 }
    model {
        scenario "old.xml"  // a comment
        exponent 2
    }
}
"""


def items(text: str) -> list[str]:
    block = next(m for m in parse_text(text, "x.ra").automata[0].members if type(m).__name__ == "ModelDecl")
    return [type(item).__name__ for item in block.items]  # type: ignore[attr-defined]


def test_with_model_swaps_the_scenario_and_keeps_the_rest() -> None:
    text = with_model(TEXT, "x.ra", "scenes/new.xml")
    assert f'"{os.path.abspath("scenes/new.xml")}"' in text and "old.xml" not in text
    assert "exponent 2" in text and items(text) == items(TEXT)
    set_text = with_model(TEXT, "x.ra", "new.xml", [("exponent", "1"), ("max_speed", "20")])
    assert "exponent 1" in set_text and "exponent 2" not in set_text and "max_speed 20" in set_text


def test_with_model_says_which_file_is_wrong(tmp_path: Path) -> None:
    with pytest.raises(ValueError, match=r"bare\.ra has no `model` block"):
        with_model(TEXT.replace('model {\n        scenario "old.xml"  // a comment\n        exponent 2\n    }\n', ""),
                   "bare.ra", "new.xml")
    with pytest.raises(ValueError, match=r"broken\.ra does not parse"):
        with_model("automaton {", "broken.ra", "new.xml")
    with pytest.raises(ValueError, match=r"`exponent=1 \+`"):
        with_model(TEXT, "x.ra", "new.xml", [("exponent", "1 +")])


def test_sweep_uses_the_one_edit() -> None:
    from rac.sweep import template

    assert template.setting_value is __import__("rac.lang.edit", fromlist=["setting_value"]).setting_value
    assert template.instantiate(TEXT, "x.ra", "new.xml", ()) == with_model(TEXT, "x.ra", "new.xml")


def test_with_model_keeps_every_other_line_and_comment_where_the_file_has_them() -> None:
    """The whole file was printed again without comments: a scene's diagnostic then named a line and showed a
    source line of a text the user never saw."""
    text = TEXT.replace("    horizon 2\n", "    horizon 2   // two seconds\n\n    // the start\n")
    edited = with_model(text, "x.ra", "new.xml", [("exponent", "1"), ("max_speed", "20"), ("sensor_error", "0.5")])
    before, after = text.splitlines(), edited.splitlines()
    assert len(after) == len(before)
    changed = [i for i, (a, b) in enumerate(zip(before, after, strict=True)) if a != b]
    assert [before[i].strip() for i in changed] == ['scenario "old.xml"  // a comment', "exponent 2"]
    assert after[changed[0]] == f'        scenario "{os.path.abspath("new.xml")}"  // a comment'
    assert after[changed[1]] == "        exponent 1 max_speed 20 sensor_error 0.5"  # the new ones in the order given
    block = next(m for m in parse_text(edited, "x.ra").automata[0].members if type(m).__name__ == "ModelDecl")
    assert [getattr(i, "name", None) and i.name.name for i in block.items] == [  # type: ignore[attr-defined]
        None, "exponent", "max_speed", "sensor_error"]
    # a block that writes neither: both join the line of its `{`
    bare = TEXT.replace('        scenario "old.xml"  // a comment\n        exponent 2\n', "        bind b = v > 1\n")
    edited = with_model(bare, "x.ra", "new.xml", [("exponent", "3")])
    assert edited.splitlines()[6] == f'    model {{ scenario "{os.path.abspath("new.xml")}" exponent 3'
    assert len(edited.splitlines()) == len(bare.splitlines())


def test_a_scene_of_a_set_that_does_not_check_points_at_the_line_the_user_wrote(tmp_path: Path) -> None:
    from engine_files import write_engine_file
    from tiny_scenarios import highway

    from rac.core.diagnostics import CheckError
    from rac.learning.gym import ScenarioEnv

    model = write_engine_file(tmp_path, "goal_ahead", {})
    text = model.read_text(encoding="utf-8")
    # comments above the model block: the reprinted text had lost them, and every line number after them
    text = text.replace("    reward sa\n", "    reward sa\n    // one\n    // two\n    // three\n")
    model.write_text(text, encoding="utf-8")
    (tmp_path / "fast.xml").write_bytes(highway(33.0))  # 33 m/s against max_speed: E0714 at `scenario`
    with pytest.raises(CheckError) as raised:
        ScenarioEnv(model, scenarios=[tmp_path / "fast.xml"])
    (diagnostic,) = [d for d in raised.value.diagnostics if d.code == "E0714"]
    span = diagnostic.span
    assert span is not None  # at the written `max_speed`, in the file as the user has it
    assert text.splitlines()[span.line - 1][span.column - 1:].startswith("max_speed 10")
