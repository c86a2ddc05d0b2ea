"""rac.check.model_block directly: :func:`allowed` puts a setting's range in words, and the E0702
message and hint that :func:`resolve_model` writes use those words."""

from __future__ import annotations

from fractions import Fraction
from pathlib import Path

import pytest

from rac.check.model_block import allowed
from rac.compiler import compile_text
from rac.ir.vocabulary import SETTINGS, Setting

LEFT_TURN = Path(__file__).resolve().parents[2] / "examples" / "left_turn" / "left_turn.xml"


@pytest.mark.parametrize(("setting", "words"), [
    (Setting("n", Fraction(2), "", "", Fraction(1), maximum=Fraction(6), whole=True), "a whole number from 1 to 6"),
    (Setting("p", None, "s", "", Fraction(0), exclusive=True), "a number > 0"),
    (Setting("q", None, "", "", Fraction(1, 2)), "a number >= 0.5"),
    (Setting("r", None, "", "", Fraction(0), exclusive=True, maximum=Fraction(1)), "a number in (0, 1]"),
    (Setting("s", None, "", ""), "a number"),
    (Setting("t", None, "", "", whole=True), "a whole number"),
])
def test_allowed_words(setting: Setting, words: str) -> None:
    assert allowed(setting) == words


def test_allowed_of_the_real_settings() -> None:
    assert allowed(SETTINGS["exponent"]) == "a whole number from 1 to 6"
    assert allowed(SETTINGS["sense_period"]) == "a number > 0"
    assert allowed(SETTINGS["base"]) == "a whole number >= 2"


def small(exponent: str) -> str:
    return f"""automaton Small {{
    input isClose : bool
    reward sa
    objective sa
    sample every 0.1
    horizon 30
    initial location Normal {{ sa' == 1 }}
    location Unsafe         {{ sa' == -1 }}
    edge * -> Unsafe when isClose
    edge * -> Normal when !isClose
    model {{
        scenario "left_turn.xml"
        exponent {exponent}
        bind isClose = mindist() < 3 * collision_distance
    }}
}}
"""


@pytest.fixture
def in_scenario_folder(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    (tmp_path / "left_turn.xml").write_bytes(LEFT_TURN.read_bytes())
    monkeypatch.chdir(tmp_path)
    return tmp_path


@pytest.mark.usefixtures("in_scenario_folder")
def test_out_of_range_value_is_reported_in_the_allowed_words() -> None:
    result = compile_text(small("8"), "small.ra")
    [diagnostic] = [d for d in result.diagnostics if d.code == "E0702"]
    words = allowed(SETTINGS["exponent"])
    assert diagnostic.message == f"`exponent` must be {words} (found 8)"
    assert any(hint.startswith(f"use {words}") for hint in diagnostic.hints)


@pytest.mark.usefixtures("in_scenario_folder")
def test_the_block_is_read_into_the_model_spec() -> None:
    result = compile_text(small("3"), "small.ra")
    assert result.automaton is not None, [d.message for d in result.diagnostics]
    spec = result.automaton.model
    assert [b.input for b in spec.bindings] == ["isClose"]
