"""The one table of the scenario model's names (rac.ir.vocabulary) holds together, and docs/model.md shows it.

- every name the emitted UPPAAL model reads it by (a global, a constant, a Dynamics clock) is
  declared there, and every ModelData field the engine reads a setting from exists;
- a setting the model holds as a significand reads as the model holds it (truncated at the block's
  exponent), in the checked IR, in rac's engine and in the emitted declarations alike;
- the table in docs/model.md ("The vocabulary of bindings and queries") is the table rendered from
  the code (rerun with ``RAC_UPDATE_DOCS=1`` after changing the vocabulary).
"""

from __future__ import annotations

import dataclasses
import os
import re
from fractions import Fraction
from pathlib import Path

import numpy as np
import pytest

from rac.check.queries import lower_expression
from rac.compiler import compile_file
from rac.engine.evaluate import Evaluator, Frame
from rac.engine.simulate import TRUTH_COLUMNS
from rac.ir import expr as ie
from rac.ir.vocabulary import EGO_STATE, MODEL_NAMES, SETTINGS, TRUE_STATE, Holding, ModelName
from rac.model.data import ModelData
from rac.model.native import State
from rac.targets.uppaal.declarations import declared_names
from rac.targets.uppaal.model import generate_uppaal_model

ROOT = Path(__file__).resolve().parents[2]
DOC = ROOT / "docs" / "model.md"
MODEL_RA = ROOT / "examples" / "left_turn" / "model.ra"
BEGIN, END = "<!-- vocabulary table -->", "<!-- end vocabulary table -->"


def _engine(entry: ModelName) -> str:
    if entry.kind == "ego":
        return "the state's significand / `SCALE_D`"
    if entry.holding is Holding.TRUTH:
        return "the finely integrated truth"
    if entry.holding is Holding.TIME:
        return "`k * C1`"
    if entry.holding is Holding.SIGNIFICAND:
        return f"`ModelData.{entry.engine}` / `SCALE_D`"
    return "the nearest double"


def _uppaal(entry: ModelName) -> str:
    if entry.holding is Holding.SIGNIFICAND:
        return f"`{entry.uppaal}` (as a number `i2d({entry.uppaal})`)"
    if entry.holding is Holding.TRUTH:
        return f"`Dynamics.{entry.uppaal}` (a hybrid clock; queries only)"
    if entry.holding is Holding.TIME:
        return "`count` (the sample counter) in queries, `count * C1` as a number and in bindings"
    return f"`{entry.uppaal}`" if entry.uppaal else "a double literal"


def rendered() -> str:
    """The vocabulary as the markdown table docs/model.md shows."""
    rows = ["| name | what | unit | held as | rac's engine reads | the UPPAAL model reads |",
            "| --- | --- | --- | --- | --- | --- |"]
    for name, entry in MODEL_NAMES.items():
        rows.append(f"| `{name}` | {entry.description} | {entry.unit or '—'} | {entry.holding.value} | "
                    f"{_engine(entry)} | {_uppaal(entry)} |")
    return "\n".join(rows)


def test_docs_show_the_table() -> None:
    text = DOC.read_text(encoding="utf-8")
    if os.environ.get("RAC_UPDATE_DOCS"):
        before, _, rest = text.partition(BEGIN)
        _, _, after = rest.partition(END)
        text = f"{before}{BEGIN}\n{rendered()}\n{END}{after}"
        DOC.write_text(text, encoding="utf-8")
    assert f"{BEGIN}\n{rendered()}\n{END}" in text, "docs/model.md's vocabulary table differs: RAC_UPDATE_DOCS=1"


@pytest.fixture(scope="module")
def left_turn():
    result = compile_file(MODEL_RA)
    assert result.ok and result.model_data is not None
    return result


def test_every_uppaal_name_is_declared(left_turn) -> None:
    declared = set(declared_names(left_turn.model_data))
    xml = generate_uppaal_model(left_turn.automaton, data=left_turn.model_data).xml
    for name, entry in MODEL_NAMES.items():
        if entry.holding is Holding.TRUTH:
            assert re.search(rf"hybrid clock [^;]*\b{entry.uppaal}\b", xml), name
        elif entry.holding is Holding.TIME:
            assert "clock time;" in xml and "count" in declared
        elif entry.uppaal:
            assert entry.uppaal in declared or f"const double {entry.uppaal} =" in xml, name
    fields = {f.name for f in dataclasses.fields(ModelData)}
    assert {e.engine for e in MODEL_NAMES.values() if e.kind == "setting" and e.engine} <= fields
    assert {n for n, e in MODEL_NAMES.items() if e.kind == "setting"} == set(SETTINGS)


def test_settings_read_as_the_model_holds_them(left_turn, tmp_path: Path) -> None:
    """`length 4.55555` is held as 45555 at exponent 4: the IR, the engine and the declarations say 4.5555."""
    text = MODEL_RA.read_text(encoding="utf-8").replace(
        'scenario "left_turn.xml"', f'scenario "{MODEL_RA.parent / "left_turn.xml"}"\n        length 4.55555')
    path = tmp_path / "long.ra"
    path.write_text(text, encoding="utf-8")
    result = compile_file(path)
    assert result.ok, result.diagnostics
    automaton, data = result.automaton, result.model_data
    length = lower_expression(automaton, "length")
    assert isinstance(length, ie.Ref) and length.value == Fraction(45555, 10_000)
    frame = Frame(k=np.zeros(1, dtype=np.int64), ego=np.zeros((1, 7), dtype=np.int64))
    assert Evaluator(data, automaton).evaluate(length, frame)[0] == 45555 / 10_000.0
    assert data.length == 45555 and "const int32_t LENGTH = 45555;" in generate_uppaal_model(automaton, data=data).xml
    # an exact setting keeps its value
    assert lower_expression(automaton, "sensor_error").value == Fraction(1, 2)


def test_the_native_state_is_the_ego_state() -> None:
    """rac.model.native.State names its fields statically; they must be the vocabulary's."""
    assert State._fields == EGO_STATE
    assert TRUTH_COLUMNS == TRUE_STATE
