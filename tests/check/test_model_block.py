"""The `model` block: parsing, formatting, defaults, every diagnostic, and what it changes elsewhere.

- the block of the issue parses to the expected items, formats canonically, keeps its comments;
- `scenario`, `action`, `bind` and `step` stay ordinary names outside the block;
- omitted settings and actions take the defaults of ``rac.check.model_block``; the scenario path is
  resolved against the `.ra` file's folder; constants in bindings are replaced by their values;
- every new code (E0701-E0711) and the generic ones the block reuses (E0101-E0106, E0201);
- with a model, queries may use the model's vocabulary (E0601 without one);
- the int32 range check uses the block's base and exponent and points at the `exponent` setting.
"""

from __future__ import annotations

import os
import re
from fractions import Fraction
from pathlib import Path

import pytest

from rac import ir
from rac.check.queries import MODEL_FUNCTIONS as QUERY_MODEL_FUNCTIONS
from rac.compiler import compile_file, compile_text
from rac.ir import expr as ie
from rac.ir.vocabulary import ACTIONS, BINDING_MATH, MODEL_FUNCTIONS, MODELLING, SETTINGS, WORD_SETTINGS
from rac.lang import ast
from rac.lang.format import format_module, format_source
from rac.lang.parser import ParseFailure, parse_text

REPO = Path(__file__).resolve().parents[2]
DRIVING = (REPO / "stdlib" / "driving.ra").read_text(encoding="utf-8")
LEFT_TURN = REPO / "examples" / "left_turn" / "left_turn.xml"


@pytest.fixture(scope="module")
def scenario_folder(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A folder with `left_turn.xml` (and `dir/left_turn.xml`): `rac check` loads the scenario."""
    folder = tmp_path_factory.mktemp("model_block")
    (folder / "dir").mkdir()
    for target in (folder / "left_turn.xml", folder / "dir" / "left_turn.xml"):
        target.write_bytes(LEFT_TURN.read_bytes())
    return folder


@pytest.fixture(autouse=True)
def _in_scenario_folder(scenario_folder: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """Text without a file names its scenario relative to the working folder: run in one that has it."""
    monkeypatch.chdir(scenario_folder)

# The block of the issue (issue 3, item 3), verbatim.
BLOCK = """\
    model {
        scenario "left_turn.xml"            // CommonRoad file, relative to the .ra file's folder
        base 10                              // number representation: significand = trunc(v * base^exponent)
        exponent 4                           // 1..6
        sense_period 0.1                     // C1 (s); defaults to the automaton's `sample every`, must equal it
        decide_period 0.2                    // C2 (s), a whole multiple of C1
        granularity 0.25                     // G: sense() takes 1/G Euler sub-steps; 1/G must be a whole number
        action jerk in [-2, 2] step 0.5      // exactly two actions: jerk and turn
        action turn in [-0.4, 0.4] step 0.1
        length 4.5                           // ego vehicle size (m)
        width 1.8
        max_acceleration 3                   // MA
        max_turn 0.4                         // MT
        min_speed 0
        max_speed 20
        collision_distance 0.5               // TD
        comfort_acceleration 0.8             // p1
        comfort_turn 0.8                     // p2
        bind isClose = mindist() < 3 * collision_distance
        bind prog    = dist_goal() < prev(dist_goal())
        bind comf    = fabs(acc) < comfort_acceleration * max_acceleration && fabs(turn) < comfort_turn * max_turn
        bind collide = collide()
        bind dgoal   = dist_goal()
    }
"""

MINIMAL_BINDINGS = """\
        bind isClose = mindist() < 3 * collision_distance
        bind prog    = dist_goal() < prev(dist_goal())
"""


def with_model(block: str, driving: str = DRIVING) -> str:
    """The driving automaton with ``block`` added before its closing brace."""
    at = driving.rindex("}")
    return driving[:at] + block + driving[at:]


def small(items: str, bindings: str = MINIMAL_BINDINGS, extra: str = "", sample: str = "0.1",
          scenario: str = '        scenario "left_turn.xml"\n') -> str:
    """A two-input automaton with a model block of ``items`` (and the usual scenario and bindings)."""
    return f"""automaton Small {{
    input isClose : bool
    input prog    : bool
    const K = 3
    reward sa, pr
    priority sa > pr
    objective 10*sa + pr
    sample every {sample}
    horizon 30
    initial location Normal {{ sa' == 1; pr' == 1 }}
    location Stalled        {{ sa' == 1; pr' == -1 }}
    location Unsafe         {{ sa' == -1 }}
    edge * -> Unsafe  when isClose          do sa -= 100
    edge * -> Stalled when !isClose && !prog
    edge * -> Normal  when !isClose && prog
{extra}    model {{
{scenario}{items}{bindings}    }}
}}
"""


def check(text: str, name: str = "small.ra"):
    return compile_text(text, name)


def codes(text: str) -> list[str]:
    return [d.code for d in check(text).diagnostics]


def only(text: str, code: str):
    """The one diagnostic of ``text``, which must have ``code``; besides it, a `base 2` warns that the
    defaults are truncated (W0725, tested on its own below), and the 30 s horizon runs past left_turn.xml's
    10 s of traffic (W0728, tested in tests/model/test_scenario_traffic.py)."""
    found = [d for d in check(text).diagnostics if d.code not in ("W0725", "W0728") or code == d.code]
    assert [d.code for d in found] == [code], [(d.code, d.message) for d in found]
    return found[0]


def line_of(text: str, needle: str) -> int:
    return next(i for i, line in enumerate(text.splitlines(), 1) if needle in line)


# ---------------------------------------------------------------- parsing and formatting
def test_the_issue_block_parses() -> None:
    module = parse_text(with_model(BLOCK))
    (block,) = module.automata[0].of(ast.ModelDecl)
    kinds = [type(i).__name__ for i in block.items]
    assert kinds == (["ModelScenario"] + ["ModelSetting"] * 5 + ["ModelAction"] * 2 + ["ModelSetting"] * 9
                     + ["ModelBinding"] * 5)
    assert block.items[0] == ast.ModelScenario("left_turn.xml")
    assert block.items[2] == ast.ModelSetting(ast.Ident("exponent"), ast.Number(Fraction(4)))
    jerk = block.items[6]
    assert isinstance(jerk, ast.ModelAction) and jerk.name.name == "jerk"
    assert jerk.low == ast.Unary("-", ast.Number(Fraction(2))) and jerk.step == ast.Number(Fraction(1, 2))
    collide = block.items[-2]
    assert collide == ast.ModelBinding(ast.Ident("collide"), ast.Call("collide", ()))
    assert block.span is not None and block.items[0].span is not None
    assert block.items[0].span.line == block.span.line + 1


def test_the_issue_block_formats_canonically_and_keeps_its_comments() -> None:
    text = with_model("\n" + BLOCK)
    formatted = format_source(text)
    assert parse_text(formatted) == parse_text(text)
    assert format_source(formatted) == formatted
    for comment in parse_text(text).comments:
        assert formatted.count(comment.text.rstrip()) == 1, comment.text
    block = formatted[formatted.index("    model {"):]
    assert block.splitlines()[:3] == [
        "    model {",
        '        scenario "left_turn.xml"         // CommonRoad file, relative to the .ra file\'s folder',
        "        base 10                          // number representation: significand = trunc(v * base^exponent)",
    ]
    # the bindings align their `=`
    assert "        bind prog    = dist_goal() < prev(dist_goal())\n" in block
    assert "        bind comf    = fabs(acc) < comfort_acceleration * max_acceleration && fabs(turn) < " in block
    assert block.endswith("        bind dgoal   = dist_goal()\n    }\n}\n")


def test_format_layout() -> None:
    source = ('automaton M { horizon 3 model { /* a */ scenario "s.xml" base 2*K\n'
              ' // own line\n bind a = x and y or not z } // after\n model { } }')
    assert format_source(source) == (
        "automaton M {\n"
        "    horizon 3\n"
        "\n"
        "    model {  /* a */\n"
        '        scenario "s.xml"\n'
        "        base 2 * K\n"
        "        // own line\n"
        "        bind a = (x && y) || !z\n"
        "    }  // after\n"
        "    model { }\n"
        "}\n")


@pytest.mark.parametrize("word", ["scenario", "action", "bind", "step", "model"])
def test_block_keywords_are_names_elsewhere(word: str) -> None:
    text = f"""automaton M {{
    input {word} : bool
    reward r
    objective r
    sample every 1
    horizon 2
    initial location A {{ r' == 1 }}
    location B {{ }}
    edge A -> B when {word}
    edge B -> A when !{word}
    query Q: A[] {word} imply B
}}
"""
    result = check(text)
    assert result.ok, [d.message for d in result.diagnostics]


def test_word_operators_inside_the_block() -> None:
    """`and`/`or` after a value are operators, not the name of the next setting."""
    (block,) = parse_text(small("", "        bind isClose = collide() and goal() or offroad()\n"
                                    "        bind prog = not goal()\n")).automata[0].of(ast.ModelDecl)
    binding = block.items[1]
    assert isinstance(binding, ast.ModelBinding) and isinstance(binding.expr, ast.Binary)
    assert binding.expr.op == "||" and binding.expr.left.op == "&&"  # type: ignore[union-attr]
    assert block.items[2].expr == ast.Unary("!", ast.Call("goal", ()))  # type: ignore[union-attr]


def test_scenario_strings_hold_no_comments() -> None:
    text = small("", scenario='        scenario "maps//a/*b*/.xml"  // the map\n')
    module = parse_text(text)
    assert [c.text for c in module.comments] == ["// the map"]
    assert module.automata[0].of(ast.ModelDecl)[0].items[0] == ast.ModelScenario("maps//a/*b*/.xml")
    assert format_source(format_source(text)) == format_source(text)


@pytest.mark.parametrize(("text", "message"), [
    ('automaton M { model { scenario "a.xml } }', "unexpected character `\"`"),
    ("automaton M { model { scenario a.xml } }", "unexpected `a`"),
    ("automaton M { model { action jerk [-2, 2] step 1 } }", "unexpected `[`"),
    ("automaton M { model { action jerk in [-2, 2] } }", "unexpected `}`"),
    ("automaton M { model { base } }", "unexpected `}`"),
    ("automaton M { model { 3 } }", "unexpected `3`"),
])
def test_syntax_errors(text: str, message: str) -> None:
    with pytest.raises(ParseFailure) as failure:
        parse_text(text)
    assert failure.value.diagnostic.code in ("E0001", "E0002")
    assert failure.value.diagnostic.message == message


def test_syntax_error_in_the_block_lists_its_items() -> None:
    with pytest.raises(ParseFailure) as failure:
        parse_text("automaton M { model { 3 } }")
    assert failure.value.diagnostic.notes[0].message == "expected `action`, `allow`, `bind`, `scenario`, `}` or a name"


# ---------------------------------------------------------------- the IR
def test_the_issue_block_resolves() -> None:
    result = check(with_model(BLOCK), "dir/driving.ra")
    assert result.ok, [d.message for d in result.diagnostics]
    model = result.automaton.model  # type: ignore[union-attr]
    assert model is not None
    assert model.scenario == "left_turn.xml"
    assert model.scenario_path == os.path.join("dir", "left_turn.xml")
    assert (model.base, model.exponent, model.scale) == (10, 4, 10_000)
    assert (model.sense_period, model.decide_period, model.granularity, model.substeps) == (
        Fraction(1, 10), Fraction(1, 5), Fraction(1, 4), 4)
    assert model.actions == (ir.Action("jerk", Fraction(-2), Fraction(2), Fraction(1, 2)),
                             ir.Action("turn", Fraction(-2, 5), Fraction(2, 5), Fraction(1, 10)))
    assert len(model.action("jerk").values) == 9 and len(model.action("turn").values) == 9
    assert [b.input for b in model.bindings] == ["isClose", "prog", "comf", "collide", "dgoal"]
    assert model.bindings[3].expr == ie.call("collide")


def test_defaults() -> None:
    result = check(small("", sample="0.05"))
    assert result.ok, [d.message for d in result.diagnostics]
    model = result.automaton.model  # type: ignore[union-attr]
    assert model is not None
    assert model.sense_period == Fraction(1, 20) and model.decide_period == Fraction(1, 10)
    for name, setting in SETTINGS.items():
        if setting.default is not None:
            assert getattr(model, name) == setting.default, name
    assert (model.base, model.exponent, model.granularity) == (10, 4, Fraction(1, 4))
    assert (model.length, model.width, model.max_acceleration, model.max_turn) == (
        Fraction(9, 2), Fraction(9, 5), Fraction(3), Fraction(2, 5))
    assert (model.min_speed, model.max_speed, model.collision_distance) == (Fraction(0), Fraction(20), Fraction(1, 2))
    assert model.comfort_acceleration == model.comfort_turn == Fraction(4, 5)
    assert model.actions == tuple(ir.Action(n, lo, hi, st) for n, (lo, hi, st, _) in ACTIONS.items())


def test_settings_table_matches_the_contract() -> None:
    fields = set(ir.ModelSpec.__dataclass_fields__)
    assert set(SETTINGS) <= fields
    # the modelling choices are settings too, but not values an expression reads
    assert fields - set(SETTINGS) == {"scenario", "scenario_path", "actions", "bindings", "span", "allow",
                                      *MODELLING, *WORD_SETTINGS}
    assert set(QUERY_MODEL_FUNCTIONS) == set(MODEL_FUNCTIONS)
    assert not set(MODEL_FUNCTIONS) & set(BINDING_MATH)


def test_an_omitted_action_keeps_its_default() -> None:
    model = check(small("        action turn in [-1, 1] step 0.25\n")).automaton.model  # type: ignore[union-attr]
    assert model is not None
    assert model.action("turn") == ir.Action("turn", Fraction(-1), Fraction(1), Fraction(1, 4))
    assert model.action("jerk") == ir.Action("jerk", Fraction(-2), Fraction(2), Fraction(1, 2))


def test_constants_in_settings_and_bindings() -> None:
    text = small("        max_turn K / 10\n        decide_period K * 0.1\n",
                 "        bind isClose = mindist() < K * collision_distance\n        bind prog = goal()\n")
    model = check(text).automaton.model  # type: ignore[union-attr]
    assert model is not None
    assert model.max_turn == Fraction(3, 10) and model.decide_period == Fraction(3, 10)
    # Constants become their values; the model's own names stay names (a setting with its value).
    assert model.bindings[0].expr == ie.Compare("<", ie.call("mindist"),
                                                ie.Binary("*", ie.Const(Fraction(3)),
                                                          ie.model_ref("collision_distance", Fraction(1, 2))))


def test_model_names_hide_constants_in_bindings() -> None:
    text = small("", "        bind isClose = x > 2\n        bind prog = goal()\n",
                 extra="    const x = 1\n")
    model = check(text).automaton.model  # type: ignore[union-attr]
    x, two = ie.model_ref("x"), ie.Const(Fraction(2))
    assert model is not None and model.bindings[0].expr == ie.Compare(">", x, two, ie.difference(x, two))


def test_scenario_path_is_relative_to_the_file(tmp_path: Path) -> None:
    folder = tmp_path / "scenarios" / "ra"
    folder.mkdir(parents=True)
    (folder / "a.ra").write_text(small("", scenario='        scenario "../maps/left_turn.xml"\n'))
    # Without the analyses the scenario is not loaded (the check reports a missing one, see
    # tests/model/test_model_check.py): only the path is resolved here.
    model = compile_file(folder / "a.ra", analyse=False).automaton.model  # type: ignore[union-attr]
    assert model is not None and model.scenario == "../maps/left_turn.xml"
    assert Path(model.scenario_path) == tmp_path / "scenarios" / "maps" / "left_turn.xml"
    absolute = str(tmp_path / "elsewhere.xml")
    (folder / "b.ra").write_text(small("", scenario=f'        scenario "{absolute}"\n'))
    assert compile_file(folder / "b.ra", analyse=False).automaton.model.scenario_path == absolute  # type: ignore[union-attr]
    # Text without a file: relative to the working folder.
    assert check(small("")).automaton.model.scenario_path == "left_turn.xml"  # type: ignore[union-attr]


def test_no_model_block() -> None:
    result = check(DRIVING)
    assert result.ok and result.automaton.model is None  # type: ignore[union-attr]


def test_the_documented_block_checks() -> None:
    """docs/language.md's model block, attached to the driving automaton, passes `rac check`."""
    doc = (REPO / "docs" / "language.md").read_text(encoding="utf-8")
    section = doc[doc.index("## The `model` block"):]
    block = re.search(r"```ra\n(model \{.*?\n\})\n```", section, re.DOTALL)
    assert block is not None
    result = check(with_model("\n" + block.group(1) + "\n"))
    assert result.ok, [d.message for d in result.diagnostics]
    assert result.automaton.model == check(with_model(BLOCK)).automaton.model  # type: ignore[union-attr]


def test_model_does_not_change_the_checks_or_runtime() -> None:
    import rac

    plain = check(DRIVING)
    modelled = check(with_model(BLOCK))
    # The automaton's facts are the same; the model adds the scenario's (tests/model/test_model_check.py).
    assert plain.proved == modelled.proved[:-1]
    assert modelled.proved[-1].startswith("scenario left_turn.xml: ")
    ra = rac.loads(with_model(BLOCK))
    ra.reset()
    assert ra.step({"isClose": False, "prog": True, "comf": True, "collide": False, "dgoal": 40.0}) > 0


# ---------------------------------------------------------------- diagnostics
@pytest.mark.parametrize(("items", "code", "message", "hint"), [
    ("        max_accel 3\n", "E0701", "unknown setting `max_accel` in the `model` block",
     "did you mean `max_acceleration`?"),
    ("        jerk 2\n", "E0701", "unknown setting `jerk` in the `model` block",
     "an action is declared with its range: `action jerk in [-2, 2] step 0.5`"),
    ("        isClose mindist() < 1\n", "E0701", "unknown setting `isClose` in the `model` block",
     "an input is bound with `bind`: `bind isClose = ...`"),
    ("        zzzz 1\n", "E0701", "unknown setting `zzzz` in the `model` block", "the settings are `base`, "),
    ("        exponent 8\n", "E0702", "`exponent` must be a whole number from 1 to 6 (found 8)",
     "use a whole number from 1 to 6; the default is `exponent 4`"),
    ("        exponent 0\n", "E0702", "`exponent` must be a whole number from 1 to 6 (found 0)", None),
    ("        exponent 2.5\n", "E0702", "`exponent` must be a whole number from 1 to 6 (found 2.5)", None),
    ("        base 1\n", "E0702", "`base` must be a whole number >= 2 (found 1)", None),
    # a scale beyond int32 (the number 1 has no significand) was accepted, and left to later overflows
    ("        exponent 6\n        base 36\n", "E0702", "base 36 at exponent 6 is beyond the 32-bit integer range: "
     "the model holds a real v as the 32-bit significand trunc(v · base^exponent), and even v = 1 would not fit",
     "`exponent 5` is the largest that fits at this base"),
    ("        base 1e300\n", "E0702", "base 1e300 at exponent 4 is beyond the 32-bit integer range: the model "
     "holds a real v as the 32-bit significand trunc(v · base^exponent), and even v = 1 would not fit",
     "use a smaller base (the default is `base 10`)"),
    ("        decide_period 0\n", "E0702", "`decide_period` must be a number > 0 (found 0 s)",
     "use a number > 0; without it, `decide_period` is 2 × `sense_period`"),
    ("        sense_period -0.1\n", "E0702", "`sense_period` must be a number > 0 (found -0.1 s)", None),
    ("        granularity 2\n", "E0702", "`granularity` must be a number from 0.001 to 1 (found 2)", None),
    ("        granularity 0.0001\n", "E0702", "`granularity` must be a number from 0.001 to 1 (found 0.0001)",
     "use a number from 0.001 to 1; the default is `granularity 0.25`"),
    ("        length 0\n", "E0702", "`length` must be a number > 0 (found 0 m)", None),
    ("        min_speed -1\n", "E0702", "`min_speed` must be a number >= 0 (found -1 m/s)", None),
    ("        comfort_turn 1.2\n", "E0702", "`comfort_turn` must be a number in (0, 1] (found 1.2)", None),
    ("        min_speed 25\n", "E0702", "`max_speed` (20 m/s) must be more than `min_speed` (25 m/s)", None),
    ("        min_speed 5\n        max_speed 5\n", "E0702",
     "`max_speed` (5 m/s) must be more than `min_speed` (5 m/s)", None),
    ("        decide_period 0.25\n", "E0703",
     "`decide_period` (0.25 s) is not a whole multiple of `sense_period` (0.1 s)",
     "the controller decides at sensing instants only: use `decide_period 0.2` or `decide_period 0.3`"),
    ("        decide_period 0.05\n", "E0703",
     "`decide_period` (0.05 s) is not a whole multiple of `sense_period` (0.1 s)",
     "the controller decides at sensing instants only: use `decide_period 0.1`"),
    ("        sense_period 0.2\n", "E0704", "`sense_period` (0.2 s) differs from `sample every` (0.1 s)", None),
    ("        granularity 0.3\n", "E0705",
     "`granularity` 0.3 does not divide the sensing period into whole sub-steps (1/G = 3.33333…)",
     "`sense()` takes 1/G Euler sub-steps: use `granularity 1/3` or `granularity 0.25`"),
    ("        granularity 0.4\n", "E0705",
     "`granularity` 0.4 does not divide the sensing period into whole sub-steps (1/G = 2.5)",
     "`sense()` takes 1/G Euler sub-steps: use `granularity 0.5` or `granularity 1/3`"),
    ("        action jerk in [-2, 2] step 0.3\n", "E0706",
     "the range [-2, 2] of action `jerk` is not a whole number of steps of 0.3",
     "end the range at 1.9 or 2.2, or choose a step that divides its width"),
    ("        action jerk in [2, -2] step 0.5\n", "E0706", "empty range [2, -2] for action `jerk`", None),
    ("        exponent 2\n        action jerk in [-20000000, 20000000] step 0.01\n", "E0901",
     "action `jerk` in [-20000000, 20000000] step 0.01 offers 4,000,000,001 values, more than the limit of 1,000",
     "choose a coarser step or a narrower range"),
    ("        action jerk in [-2, 2] step 0.02\n        action turn in [-0.4, 0.4] step 0.01\n", "E0901",
     "the actions offer 16,281 (jerk, turn) pairs (201 × 81), more than the limit of 10,000",
     "choose coarser steps or narrower ranges"),
    ("        action turn in [-1, 1] step 0\n", "E0706", "the step of action `turn` must be positive (found 0)",
     None),
    ("        exponent 1\n        action turn in [-0.4, 0.4] step 0.05\n", "E0706",
     "action `turn` in [-0.4, 0.4] step 0.05 does not fall on whole significands at base 10, exponent 1",
     "use a range and step that are multiples of 0.1, or raise the exponent"),
    ("        base 2\n", "E0706",
     "the default action `turn` in [-0.4, 0.4] step 0.1 does not fall on whole significands at base 2, "
     "exponent 4", "use a range and step that are multiples of 0.0625, or raise the exponent"),
    # a sample number beyond int32: `rac compile --target uppaal` stopped with an internal error
    ("        offroad_from 99999999999999999999\n", "E0702",
     "`offroad_from` must be a whole number from 0 to 2147483647 (found 1e20… samples)",
     "use a whole number from 0 to 2147483647; the default is `offroad_from 0`"),
    # a positive setting whose significand truncates to 0: the model would use 0, not the value written
    ("        width 0.00001\n", "E0702",
     "`width` 0.00001 m truncates to 0 at base 10, exponent 4: the model would use 0, and `width` must be positive",
     "the smallest positive `width` at base 10, exponent 4 is 0.0001 m: set `width` to at least that, or raise "
     "the exponent (`exponent 5` holds 0.00001)"),
    ("        collision_distance 1e-9\n", "E0702",
     "`collision_distance` 0.000000001 m truncates to 0 at base 10, exponent 4: the model would use 0, and "
     "`collision_distance` must be positive",
     "the smallest positive `collision_distance` at base 10, exponent 4 is 0.0001 m: set `collision_distance` to "
     "at least that"),
    ("        base 2\n        action turn in [-0.5, 0.5] step 0.5\n        exponent 1\n", "E0702",
     "the default `max_turn` 0.4 rad/s truncates to 0 at base 2, exponent 1: the model would use 0, and `max_turn` "
     "must be positive", "the smallest positive `max_turn` at base 2, exponent 1 is 0.5 rad/s"),
    ("        action steer in [0, 1] step 1\n", "E0707", "unknown action `steer`",
     "the vehicle has two actions, `jerk` (m/s³) and `turn` (rad/s)"),
    ("        action trun in [0, 1] step 1\n", "E0707", "unknown action `trun`", "did you mean `turn`?"),
    ("        base 10\n        base 12\n", "E0102", "`base` is set twice in the `model` block", None),
    ('        scenario "b.xml"\n', "E0102", "`scenario` is set twice in the `model` block", None),
    ("        action jerk in [-1, 1] step 1\n        action jerk in [-2, 2] step 1\n", "E0102",
     "action `jerk` is declared twice in the `model` block", None),
    ("        base isClose\n", "E0103", "input `isClose` cannot appear in the value of `base`", None),
    ("        base unknown\n", "E0101", "unknown name `unknown`", None),
    ("        width true\n", "E0201", "the value of `width` needs a number, found a boolean", None),
])
def test_setting_errors(items: str, code: str, message: str, hint: str | None) -> None:
    text = small(items)
    diagnostic = only(text, code)
    assert diagnostic.message == message
    if hint is not None:
        assert diagnostic.hints[0].startswith(hint), diagnostic.hints
    assert diagnostic.span is not None
    assert diagnostic.span.line == line_of(text, items.splitlines()[-1].strip())


def test_empty_scenario_name() -> None:
    diagnostic = only(small("", scenario='        scenario ""\n'), "E0702")
    assert diagnostic.message == "the `scenario` file name is empty"


def test_missing_scenario() -> None:
    text = small("        exponent 3\n", scenario="")
    diagnostic = only(text, "E0105")
    assert diagnostic.message == "the `model` block has no `scenario`"
    assert diagnostic.span is not None and diagnostic.span.line == line_of(text, "model {")


def test_two_model_blocks() -> None:
    text = with_model('    model { scenario "x.xml" }\n', small(""))
    diagnostic = only(text, "E0106")
    assert diagnostic.message == "`model` is declared more than once"
    assert diagnostic.span is not None and diagnostic.span.line == line_of(text, 'model { scenario')
    assert diagnostic.notes[0].span is not None and diagnostic.notes[0].span.line == line_of(text, "model {")


def test_sense_period_defaults_to_the_sample_period_and_may_repeat_it() -> None:
    assert check(small("        sense_period 0.1\n        decide_period 0.3\n")).ok
    diagnostic = only(small("        sense_period 0.2\n"), "E0704")
    assert diagnostic.notes[0].span is not None and diagnostic.notes[0].message == "the automaton samples here"
    # A sense period that differs also shifts the default decision period: no second error.
    assert codes(small("        sense_period 0.3\n")) == ["E0704"]


def test_errors_do_not_cascade() -> None:
    """A rejected value is not compared with others; every independent error is reported."""
    assert codes(small("        sense_period -1\n        decide_period 0.25\n")) == ["E0702"]
    assert codes(small("        exponent 9\n        action turn in [-0.4, 0.4] step 0.05\n")) == ["E0702"]
    assert sorted(codes(small("        exponent 9\n        granularity 0.3\n        zz 1\n"))) == [
        "E0701", "E0702", "E0705"]


@pytest.mark.parametrize(("bindings", "code", "message", "line_text"), [
    ("        bind isclose = goal()\n        bind prog = goal()\n", "E0708",
     "`bind` names unknown input `isclose`", "bind isclose"),
    ("        bind isClose = goal()\n        bind prog = goal()\n        bind sa = 1\n", "E0708",
     "`bind` names `sa`, which is a reward, not an input", "bind sa"),
    ("        bind isClose = goal()\n        bind prog = goal()\n        bind K = 1\n", "E0708",
     "`bind` names `K`, which is a constant, not an input", "bind K"),
    ("        bind isClose = goal()\n", "E0709", "input `prog` has no binding in the `model` block",
     "input prog"),
    ("        bind isClose = mindist()\n        bind prog = goal()\n", "E0710",
     "input `isClose` is a boolean, but its binding is a number", "bind isClose"),
    ("        bind isClose = goal()\n        bind prog = goal()\n        bind prog = offroad()\n", "E0102",
     "input `prog` is bound twice in the `model` block", "bind prog = offroad"),
    ("        bind isClose = distance() < 1\n        bind prog = goal()\n", "E0711",
     "unknown function `distance()` in a binding", "bind isClose"),
    ("        bind isClose = mindst() < 1\n        bind prog = goal()\n", "E0711",
     "unknown function `mindst()` in a binding", "bind isClose"),
    ("        bind isClose = fabs(1, 2) < 1\n        bind prog = goal()\n", "E0711",
     "`fabs()` takes 1 argument, found 2", "bind isClose"),
    ("        bind isClose = collide(1)\n        bind prog = goal()\n", "E0711",
     "`collide()` takes no arguments, found 1", "bind isClose"),
    ("        bind isClose = prev(prev(goal()))\n        bind prog = goal()\n", "E0711",
     "`prev()` cannot be nested", "bind isClose"),
    ("        bind isClose = prog\n        bind prog = goal()\n", "E0103",
     "input `prog` cannot appear in a binding", "bind isClose"),
    ("        bind isClose = Unsafe\n        bind prog = goal()\n", "E0103",
     "location `Unsafe` cannot appear in a binding", "bind isClose"),
    ("        bind isClose = true_x > 1\n        bind prog = goal()\n", "E0103",
     "`true_x` (the true state) cannot appear in a binding", "bind isClose"),
    ("        bind isClose = Small.Unsafe\n        bind prog = goal()\n", "E0103",
     "`Small.Unsafe` is not available in a binding", "bind isClose"),
    ("        bind isClose = speed > 1\n        bind prog = goal()\n", "E0101", "unknown name `speed`",
     "bind isClose"),
    ("        bind isClose = !mindist()\n        bind prog = goal()\n", "E0201",
     "expected a boolean, found a number", "bind isClose"),
])
def test_binding_errors(bindings: str, code: str, message: str, line_text: str) -> None:
    text = small("", bindings)
    diagnostic = only(text, code)
    assert diagnostic.message == message
    assert diagnostic.span is not None and diagnostic.span.line == line_of(text, line_text)


def test_the_arguments_of_a_refused_call_are_checked_too() -> None:
    """A call with the wrong number of arguments, or a nested `prev()`, still reports the errors
    inside its arguments (they were skipped): every finding of one expression, in source order."""
    cases = [
        ("        bind isClose = fabs(spd, 2) < 1\n        bind prog = goal()\n", ["E0711", "E0101"]),
        ("        bind isClose = prev(prev(spd > 1))\n        bind prog = goal()\n", ["E0711", "E0101"]),
        ("        bind isClose = distnce(spd) < 1\n        bind prog = goal()\n", ["E0711", "E0101"]),
    ]
    for bindings, expected in cases:
        assert codes(small("", bindings)) == expected, bindings
    assert codes(small("", extra="    query Q: A[] mindist(spd) > 0\n")) == ["E0711", "E0101"]


def test_binding_hints() -> None:
    unknown = only(small("", "        bind isClose = distance() < 1\n        bind prog = goal()\n"), "E0711")
    assert "`collide()`" in unknown.hints[-1] and "`fmax(a, b)`" in unknown.hints[-1]
    close = only(small("", "        bind isClose = mindst() < 1\n        bind prog = goal()\n"), "E0711")
    assert close.hints[0] == "did you mean `mindist()`?"
    misspelt = only(small("", "        bind isclose = goal()\n        bind prog = goal()\n"), "E0708")
    assert misspelt.hints == ("did you mean `isClose`?",)  # and `isClose` is not reported unbound
    name = only(small("", "        bind isClose = collision_distanc > 1\n        bind prog = goal()\n"), "E0101")
    assert name.hints == ("did you mean `collision_distance`?",)


def test_numeric_inputs_take_numeric_bindings() -> None:
    text = with_model(BLOCK.replace("bind dgoal   = dist_goal()", "bind dgoal   = dist_goal() < 3"))
    diagnostic = only(text, "E0710")
    assert diagnostic.message == "input `dgoal` is a number (real), but its binding is a boolean"
    assert diagnostic.notes[0].span is not None and diagnostic.notes[0].span.line == line_of(text, "input dgoal")


def test_every_input_needs_a_binding() -> None:
    text = with_model(BLOCK.replace("        bind comf    = fabs(acc) < comfort_acceleration * max_acceleration && "
                                    "fabs(turn) < comfort_turn * max_turn\n", "")
                      .replace("        bind dgoal   = dist_goal()\n", ""))
    diagnostics = check(text).diagnostics
    assert [(d.code, d.span.line) for d in diagnostics] == [  # type: ignore[union-attr]
        ("E0709", line_of(text, "input comf")), ("E0709", line_of(text, "input dgoal"))]


def test_bindings_may_be_nonlinear_and_read_the_vocabulary() -> None:
    bindings = ("        bind isClose = v * v / (2 * max_acceleration) > mindist() || collide() || offroad()\n"
                "        bind prog = dist_goal() < prev(dist_goal()) && time > 0 && fmin(x, y) < fmax(head, 1)"
                " && sqrt(abs(acc)) >= 0 && prev(goal()) == goal() && jerk + turn > -10\n")
    assert check(small("", bindings)).ok


# ---------------------------------------------------------------- queries
QUERIES = """\
    query Qa: Pr[<=30](<> fabs(true_x - x) >= 0.5)
    query Qb: E[] !collide() && !offroad()
    query Qd: strategy safe = control: A[] !collide() && !offroad()
    query Qr: strategy reach = maxE(10*sa + pr)[<=30]{x, y}->{v}: <> goal() under safe
    query Qm: A[] mindist() >= 3 * collision_distance imply !isClose
    query Qp: E<> prev(collide()) && dist_goal() < 1
"""


def test_model_vocabulary_in_queries() -> None:
    result = check(small("", extra=QUERIES))
    assert result.ok, [(d.code, d.message) for d in result.diagnostics]


def test_model_functions_need_a_model() -> None:
    text = small("", extra=QUERIES)
    without = text[:text.index("    model {")] + "}\n"
    result = check(without)
    assert {d.code for d in result.diagnostics} == {"E0601", "E0101"}  # `x`, `true_x`, ... unknown too
    assert sum(d.code == "E0601" for d in result.diagnostics) == 9


def test_model_function_arity_and_types_in_queries() -> None:
    diagnostic = only(small("", extra="    query Q: A[] mindist(1) > 0\n"), "E0711")
    assert diagnostic.message == "`mindist()` takes no arguments, found 1"
    assert only(small("", extra="    query Q: A[] mindist()\n"), "E0201")
    assert only(small("", extra="    query Q: A[] collide() + 1 > 0\n"), "E0201")


@pytest.mark.parametrize(("extra", "bindings", "divisor"), [
    ("    query Q: A[] mindist() / 0 > 1\n", MINIMAL_BINDINGS, "0"),
    ("    query Q: Pr[<=30 / (K - 3)](<> goal())\n", MINIMAL_BINDINGS, "K - 3"),
    ("    query Q: E[<=30; 10](max: 0 * (sa / (x - x)))\n", MINIMAL_BINDINGS, "x - x"),
    ("", "        bind isClose = mindist() / (2 * collision_distance - 2 * collision_distance) < 1\n"
         "        bind prog = goal()\n", "2 * collision_distance - 2 * collision_distance"),
])
def test_a_divisor_of_zero_in_a_query_or_binding_is_E0207(extra: str, bindings: str, divisor: str) -> None:
    """The fuzzer: `A[] speed > 1/0` checked clean, and `rac verify` answered it (the engine divides by zero
    as floats do); a constant divisor of zero is E0207 in a query or binding as in the automaton itself."""
    text = small("", bindings, extra=extra)
    diagnostic = only(text, "E0207")
    assert diagnostic.message == "division by zero"
    assert diagnostic.span is not None and text[diagnostic.span.start:diagnostic.span.end] == divisor


def test_automaton_names_come_first_in_queries() -> None:
    text = small("", extra="    const v = true\n    query Q: A[] v\n")
    assert check(text).ok  # `v` is the boolean constant here, not the ego speed


# ---------------------------------------------------------------- the int32 range check
LONG = """automaton Long {
    input isClose : bool
    input collide : bool
    assume collide imply isClose
    reward sa
    objective sa
    sample every 0.1
    horizon 600
    initial location Normal { sa' == 1 }
    location Unsafe         { sa' == -1 }
    edge * -> Unsafe      when isClose  do sa = sa - 100
    edge * -> Normal      when !isClose
    edge Unsafe -> Unsafe when collide  do sa = sa - 100
    model {
        scenario "left_turn.xml"
%s        bind isClose = mindist() < 3 * collision_distance
        bind collide = collide()
    }
}
"""


def test_range_check_uses_the_model_exponent() -> None:
    ok = check(LONG % "        exponent 3\n")
    assert ok.ok
    assert "int32 range holds at base 10, exponent 3: rewards stay within [-600599.8, 600]" in ok.proved
    text = LONG % "        exponent 6\n"
    diagnostic = only(text, "E0501")
    assert diagnostic.message == "reward `sa` overflows int32 at base 10, exponent 6: it can reach -600599.8"
    assert diagnostic.span is not None and diagnostic.span.line == line_of(text, "exponent 6")
    assert diagnostic.notes[0].message == "`sa` is declared here"
    assert diagnostic.notes[0].span is not None and diagnostic.notes[0].span.line == line_of(text, "reward sa")
    assert diagnostic.hints[0].startswith("set `exponent 3` in the `model` block (the largest that fits)")
    assert diagnostic.data["exponent"] == 6


def test_range_check_points_at_base_or_the_reward() -> None:
    text = LONG % "        base 100\n"  # exponent 4 by default: 100^4 = 10^8
    diagnostic = only(text, "E0501")
    assert "base 100, exponent 4" in diagnostic.message
    assert diagnostic.span is not None and diagnostic.span.line == line_of(text, "base 100")
    assert diagnostic.hints[0].startswith("set `exponent 1`")
    text = LONG % ""  # default representation, not written: the reward is the place
    diagnostic = only(text, "E0501")
    assert diagnostic.span is not None and diagnostic.span.line == line_of(text, "reward sa")
    assert diagnostic.hints[0].startswith("set `exponent 3`")


def test_formatted_examples_still_check() -> None:
    """`rac fmt` output of a file with a model block checks to the same IR."""
    text = with_model(BLOCK)
    formatted = format_module(parse_text(text))
    assert check(formatted).automaton == check(text).automaton


def test_memory_error_while_loading_is_not_a_broken_scenario(monkeypatch: pytest.MonkeyPatch, capsys) -> None:
    """Issue 22: a MemoryError while the scenario loads (a process limit, a machine too small) was
    reported as E0712, "cannot load the scenario", about a file that is fine; it is a resource error."""
    from rac.cli.main import main
    from rac.model import checks

    def out_of_memory(*args: object, **kwargs: object) -> None:
        raise MemoryError

    monkeypatch.setattr(checks, "load", out_of_memory)
    folder = Path(__file__).parents[1] / "diagnostics"
    monkeypatch.chdir(folder)
    status = main(["check", "E0712_missing_scenario.ra"])
    err = capsys.readouterr().err
    assert status == 2
    assert "E0712" not in err and "internal error" not in err
    assert "out of memory" in err and "ulimit -v" in err


def test_a_large_scenario_load_is_announced(monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> None:
    """Issue 22: a 50 MB scenario loaded for 15 minutes without a word. A file expected to take more than
    a few seconds is announced through the caller's callback, with its size and the expected time."""
    from rac.compiler import compile_file
    from rac.model import checks

    folder = Path(__file__).parents[1] / "diagnostics"
    source = (folder / "E0712_missing_scenario.ra").read_text(encoding="utf-8")
    scenario = re.search(r'scenario "([^"]+)"', source)
    assert scenario is not None
    (tmp_path / scenario.group(1)).write_bytes(b"<x/>" + b" " * (checks.LOAD_NOTICE_BYTES + 1))
    (tmp_path / "big.ra").write_text(source, encoding="utf-8")
    said: list[str] = []
    compile_file(tmp_path / "big.ra", progress=said.append)
    assert len(said) == 1 and "loading the scenario" in said[0] and "MB" in said[0], said
    said.clear()
    (tmp_path / scenario.group(1)).write_bytes(b"<x/>")
    compile_file(tmp_path / "big.ra", progress=said.append)
    assert said == []


# ---------------------------------------------------------------- truncated settings (W0725)
def test_a_setting_truncated_to_a_nonzero_significand_warns_with_the_value_used() -> None:
    """`width 4.55555` at exponent 2 became 4.55 silently: the model, and every check, used 4.55."""
    text = small("        exponent 2\n        width 2.55555\n")
    diagnostic = only(text, "W0725")
    assert diagnostic.severity == "warning"
    assert diagnostic.message == ("`width` 2.55555 m is truncated to whole significands at base 10, exponent 2: "
                                  "the model uses 2.55 m")
    assert diagnostic.span is not None and diagnostic.span.line == line_of(text, "width 2.55555")
    assert diagnostic.hints == ("write `width 2.55` to say what the model uses, or raise the exponent "
                                "(`exponent 5` holds 2.55555)",)
    assert check(text).ok  # a warning: the file still checks
    # a value the representation holds exactly, or that E0702 rejects (truncated to 0), does not warn
    assert "W0725" not in codes(small("        exponent 2\n        width 2.55\n"))
    assert codes(small("        exponent 2\n        width 0.001\n")) == ["E0702"]
    # a setting that may be 0 and truncates to it warns too: the model's lowest speed is 0, not 0.00001
    assert only(small("        min_speed 0.00001\n"), "W0725").message == (
        "`min_speed` 0.00001 m/s is truncated to whole significands at base 10, exponent 4: the model uses 0 m/s")


def test_defaults_truncated_at_another_base_warn_once() -> None:
    text = small("        base 2\n        action turn in [-0.5, 0.5] step 0.5\n"
                 "        action jerk in [-2, 2] step 0.5\n")
    found = [d for d in check(text).diagnostics if d.code == "W0725"]
    assert len(found) == 1
    diagnostic = found[0]
    assert diagnostic.span is not None and diagnostic.span.line == line_of(text, "base 2")
    assert diagnostic.message.startswith("at base 2, exponent 4 the model holds default settings truncated to "
                                         "whole significands: `width` 1.8 m as 1.75 m, ")
    assert "`max_turn` 0.4 rad/s as 0.375 rad/s" in diagnostic.message



# ---------------------------------------------------------------- int inputs bound to numbers (W0726)
def int_bound(binding: str, sample: str = "0.1") -> str:
    """:func:`small` with an ``int`` input ``n`` in [0, 20] bound to ``binding``, read by one edge."""
    text = small("", MINIMAL_BINDINGS + f"        bind n = {binding}\n", sample=sample)
    return text.replace("    input prog    : bool\n", "    input prog    : bool\n    input n : int in [0, 20]\n") \
        .replace("when !isClose && prog\n", "when !isClose && prog && n > 8\n")


def test_an_int_input_bound_to_a_number_that_need_not_be_whole_warns() -> None:
    """`input n : int` with `bind n = v` checked silently: the model fed `n` 8.1562 (bindings cannot round),
    `rac verify` and the UPPAAL model read it so, while `rac check` took `n` to be whole (W0304 said
    `n > 8 && n < 9` never fires) and the Python runtime refuses it."""
    text = int_bound("v")
    diagnostic = only(text, "W0726")
    assert diagnostic.severity == "warning" and check(text).ok
    assert diagnostic.message == "input `n` is an `int`, but its binding need not be a whole number"
    assert diagnostic.span is not None and diagnostic.span.line == line_of(text, "bind n = v")
    assert diagnostic.hints == ("declare the input `real`: `input n : real in [0, 20]`",)
    for binding in ("fmin(3.5, v / 2)", "dist_goal()", "mindist()", "sqrt(4)", "4 / 2", "time", "x + 1",
                    "prev(v)", "collision_distance"):
        assert "W0726" in codes(int_bound(binding)), binding


def test_an_int_input_bound_to_a_whole_number_does_not_warn() -> None:
    for binding in ("2", "K", "fmin(K, fmax(0, -3 * K + 20))", "fabs(-K)", "max_speed - 10", "prev(K)"):
        assert "W0726" not in codes(int_bound(binding)), binding
    assert "W0726" not in codes(int_bound("time", sample="1"))
    # a real input bound to the same number is what the hint asks for
    assert "W0726" not in codes(int_bound("v").replace("input n : int", "input n : real"))


# ---------------------------------------------------------------- a horizon of no whole number of decisions (W0731)
def at_horizon(items: str, horizon: str, sample: str = "0.1") -> str:
    """:func:`small` with the model block's ``items`` and ``horizon`` s."""
    return small(items, sample=sample).replace("    horizon 30\n", f"    horizon {horizon}\n")


def test_a_horizon_of_no_whole_number_of_decisions_warns() -> None:
    """A file's horizon of 30.1 s with decisions of 0.2 s: every engine command's last decision held for 0.1 s,
    shorter than the others, and rac check said nothing (ScenarioEnv warned of its own `horizon=` only)."""
    text = at_horizon("", "30.1")
    diagnostic = only(text, "W0731")
    assert diagnostic.severity == "warning" and check(text).ok
    assert diagnostic.message == ("the horizon (30.1 s) is not a whole multiple of `decide_period` (0.2 s): the "
                                  "last decision is shorter than the others")
    assert diagnostic.span is not None and diagnostic.span.line == line_of(text, "horizon 30.1")
    assert diagnostic.notes[1].message == "`decide_period` defaults to 2 × `sense_period` = 0.2 s"
    assert diagnostic.hints == ("for decisions of one length use `horizon 30` or `horizon 30.2`",)
    written = only(at_horizon("        decide_period 0.5\n", "30.2"), "W0731")
    assert "holds for 0.2 s (2 of the 5 sensing periods of a decision)" in written.notes[0].message
    assert len(written.notes) == 1 and written.hints == (
        "for decisions of one length use `horizon 30` or `horizon 30.5`, or a `decide_period` that divides the "
        "horizon",)
    # a horizon shorter than one decision: the one multiple above it
    assert only(at_horizon("        decide_period 1\n", "0.5"), "W0731").hints == (
        "for decisions of one length use `horizon 1`, or a `decide_period` that divides the horizon",)


@pytest.mark.parametrize(("items", "horizon", "expected"), [
    ("", "30", []),  # a whole number of decisions
    ("        decide_period 0.1\n", "30.1", []),  # a decision at every sample
    ("        decide_period 0.25\n", "30.1", ["E0703"]),  # the decision period is the error, said once
    ("", "30.05", ["E0206"]),  # no whole number of samples: the horizon's error, said once
])
def test_no_w0731_where_the_decisions_fit_or_another_error_says_it(items: str, horizon: str,
                                                                   expected: list[str]) -> None:
    assert [c for c in codes(at_horizon(items, horizon)) if c not in ("W0725", "W0728")] == expected


@pytest.mark.parametrize(("guard", "code", "said"), [
    ("isClose && time > 3", "E0101", "`time`"), ("isClose && v > 3", "E0101", "`v`"),
    ("mindist() < 3", "E0103", "`mindist()`")])
def test_the_model_in_a_guard_says_to_read_it_through_an_input(guard: str, code: str, said: str) -> None:
    """`time`, the ego state and the model's functions exist in queries and bindings; in a guard a
    newcomer got "unknown name `time`" with no hint, and for `mindist()` "function calls are allowed in
    queries only", which hid the binding that does it."""
    text = DRIVING.replace("edge * -> Unsafe        when isClose ", f"edge * -> Unsafe        when {guard} ")
    assert text != DRIVING
    found = [d for d in compile_text(text, "t.ra").diagnostics if d.code == code]
    assert len(found) == 1, found
    assert list(found[0].hints) == [f"the automaton reads only its inputs: declare an input, compute it from {said} "
                                    "with a binding of the `model` block (`bind INPUT = ...`) or in your environment, "
                                    "and read the input here"]


@pytest.mark.parametrize(("where", "old", "new", "name"), [
    ("binding", "bind isClose = mindist() <", "bind isClose = mindist <", "mindist"),
    ("query", "query Qe: A[] isClose imply Unsafe", "query Qe: A[] dist_goal > 1", "dist_goal")])
def test_a_function_without_its_parentheses_is_named(where: str, old: str, new: str, name: str,
                                                     scenario_folder: Path) -> None:
    """`bind near = mindist < 3` said "unknown name `mindist`" and listed the ego state and settings:
    the function was right there, only its `()` missing."""
    source = (REPO / "examples" / "left_turn" / "model.ra").read_text(encoding="utf-8")
    assert old in source
    path = scenario_folder / f"parentheses_{where}.ra"
    path.write_text(source.replace(old, new), encoding="utf-8")
    found = [d for d in compile_file(path).diagnostics if d.code == "E0101"]
    assert len(found) == 1, found
    assert list(found[0].hints) == [f"`{name}` is a function: write `{name}()`"]


@pytest.mark.parametrize(("declaration", "example"), [
    ("input collide : bool", "bind collide = collide()"),
    ("input atGoal : bool", "bind atGoal = goal()"),
    ("input off_road : bool", "bind off_road = offroad()"),
    ("input dgoal : real in [0, 500]", "bind dgoal = dist_goal()"),
    ("input mindist : real in [0, 500]", "bind mindist = mindist()"),
    ("input gap : real in [0, 500]", "bind gap = dist_goal()"),
    ("input fast : bool", "bind fast = mindist() < 3 * collision_distance"),
])
def test_an_unbound_input_named_after_a_model_function_is_shown_that_function(declaration: str,
                                                                            example: str) -> None:
    """E0709's example binding is the predicate or distance the input's name says (a user who wrote
    `input collide` means `collide()`, not a distance comparison), else the usual example."""
    text = small("").replace("    input prog    : bool\n", f"    input prog    : bool\n    {declaration}\n")
    diagnostic = only(text, "E0709")
    assert diagnostic.hints[-1].endswith(f"e.g. `{example}`"), diagnostic.hints
