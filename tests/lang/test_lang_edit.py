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
