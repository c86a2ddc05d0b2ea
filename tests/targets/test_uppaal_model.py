"""The UPPAAL target with a `model` block: the whole model of the automaton in its scenario.

* ``tests/golden/left_turn_model.xml`` and ``.q`` are the exact output for
  ``examples/left_turn/model.ra`` (the driving automaton in the left-turn scenario);
* the model has the shape UPPAAL's reader needs (as tests/targets/test_uppaal.py checks for the automaton
  alone): element order, unique ids, broadcast channels only, controllable edges only in Action,
  one-line formulas, every name a query reads declared, symbolic queries over integers only;
* the scenario part of the declarations is :func:`emit_declarations` verbatim and compiles as C,
  with the Obstacle template's function;
* ``rac compile --target uppaal`` emits it for the file with a model block, and the three shared
  scenarios (``../shared/scenarios``, skipped when absent) compile in under 2 s each.
"""

from __future__ import annotations

import dataclasses
import re
import shutil
import subprocess
from fractions import Fraction
from pathlib import Path

import pytest
from golden_files import assert_golden
from test_uppaal import QUERY_WORDS, Parsed, identifiers, is_symbolic

from rac.cli.main import main
from rac.compiler import compile_file, compile_text
from rac.engine.product import MirrorArithmetic
from rac.ir import expr as ie
from rac.model import build_model_data
from rac.model.commonroad import load_scenario
from rac.targets.uppaal.automaton import UppaalError
from rac.targets.uppaal.declarations import C_PRELUDE, emit_declarations
from rac.targets.uppaal.model import generate_uppaal_model

ROOT = Path(__file__).resolve().parents[2]
GOLDEN = Path(__file__).parents[1] / "golden"
MODEL_RA = ROOT / "examples" / "left_turn" / "model.ra"
SCENARIOS = Path(__file__).resolve().parents[3] / "shared" / "scenarios"
COMPILER = shutil.which("cc") or shutil.which("gcc")
REGENERATE = ("regenerate them with:  RAC_UPDATE_GOLDEN=1 PYTHONPATH=src python -m pytest "
              "tests/targets/test_uppaal_model.py  (then read the diff against docs/uppaal.md before committing)")


def automaton():
    return compile_file(MODEL_RA).raise_for_errors()


@pytest.fixture(scope="module")
def model():
    return generate_uppaal_model(automaton(), source_name="examples/left_turn/model.ra",
                                 model_name="left_turn_model.xml")


@pytest.fixture(scope="module")
def parsed(model) -> Parsed:
    return Parsed(model.xml)


def template_names(parsed: Parsed, template: str) -> set[str]:
    """The names a template declares locally (its parameter included)."""
    element = parsed.templates[template]
    code = re.sub(r"//[^\n]*", "", (element.findtext("declaration") or "") + ";" + (element.findtext("parameter")
                                                                                    or ""))
    found = set()
    for match in re.finditer(r"(?:hybrid clock|clock|double|int32_t|bool|void)\s+([^;=(]+)", code):
        found |= set(re.findall(r"\w+", match.group(1)))
    return found


def instance_template(parsed: Parsed, process: str) -> str:
    if process in parsed.templates:
        return process
    match = re.search(rf"\b{process}\s*=\s*(\w+)\(", parsed.root.findtext("system"))
    assert match, process
    return match.group(1)


# ---------------------------------------------------------------- golden
def test_golden_files(model) -> None:
    files = {GOLDEN / "left_turn_model.xml": model.xml, GOLDEN / "left_turn_model.q": model.queries}
    assert_golden(files, REGENERATE)


def test_generation_is_deterministic(model) -> None:
    assert generate_uppaal_model(automaton(), source_name="examples/left_turn/model.ra",
                                 model_name="left_turn_model.xml") == model


# ---------------------------------------------------------------- shape
def test_processes_and_system_order(parsed: Parsed) -> None:
    assert set(parsed.templates) == {"Timer", "Controller", "Action", "Dynamics", "Obstacle", "Driving"}
    assert parsed.processes == ["Timer", "Controller", "Action", "Dynamics", "Obstacle0", "Obstacle1", "Obstacle2",
                                "Driving"]
    system = parsed.root.findtext("system")
    assert "Obstacle0 = Obstacle(0);" in system and "Obstacle2 = Obstacle(2);" in system
    assert parsed.templates["Obstacle"].findtext("parameter") == "const int32_t i"


def test_element_order_and_ids(parsed: Parsed) -> None:
    tags = [child.tag for child in parsed.root]
    assert re.fullmatch(r"declaration,(template,)+system,queries", ",".join(tags)), tags
    order = ["name", "parameter", "declaration", "location", "branchpoint", "init", "transition"]
    for template in parsed.templates.values():
        kinds = [child.tag for child in template]
        assert kinds == sorted(kinds, key=order.index), kinds
        locations = {loc.get("id") for loc in template.findall("location")}
        assert template.find("init").get("ref") in locations
        for transition in template.findall("transition"):
            assert transition.find("source").get("ref") in locations
            assert transition.find("target").get("ref") in locations
        names = [loc.findtext("name") for loc in template.findall("location")]
        assert len(names) == len(set(names))
    ids = [element.get("id") for element in parsed.root.iter("location", "transition")]
    assert len(ids) == len(set(ids)) and all(ids)


def test_controllable_edges_only_in_action(parsed: Parsed) -> None:
    for name, template in parsed.templates.items():
        for transition in template.findall("transition"):
            labels = {label.get("kind"): label.text for label in transition.findall("label")}
            controllable = transition.get("controllable") == "true"
            assert transition.get("controllable") in ("true", "false")
            assert controllable == (name == "Action" and "select" in labels), (name, labels)
    chooser = next(t for t in parsed.templates["Action"].findall("transition") if t.get("controllable") == "true")
    labels = {label.get("kind"): label.text for label in chooser.findall("label")}
    assert labels == {"select": "j : int[0,JERK_COUNT-1], u : int[0,TURN_COUNT-1]",
                      "assignment": "jerk = JERK_VALUES[j], turn = TURN_VALUES[u]"}


def test_only_broadcast_channels(parsed: Parsed) -> None:
    code = re.sub(r"//[^\n]*", "", parsed.declaration)
    declarations = re.findall(r"[^;]*\bchan\b[^;]*;", code)
    assert [d.strip() for d in declarations] == ["broadcast chan accrue, read, sense, decide, finish;"]
    syncs = {label.text for label in parsed.root.iter("label") if label.get("kind") == "synchronisation"}
    assert {s[:-1] for s in syncs} <= {"accrue", "read", "sense", "decide", "finish"}
    senders = {name: {label.text for label in t.iter("label") if label.get("kind") == "synchronisation"
                      and label.text.endswith("!")} for name, t in parsed.templates.items()}
    assert senders["Timer"] == {"accrue!", "sense!", "decide!", "finish!"} and senders["Controller"] == {"read!"}
    assert not senders["Action"] and not senders["Dynamics"] and not senders["Obstacle"] and not senders["Driving"]


def test_formulas_are_single_lines_and_named(parsed: Parsed) -> None:
    names = [name for name, _ in parsed.queries]
    assert names[:2] == ["Qe", "Qh"] and all(names)
    for _, formula in parsed.queries:
        assert "\n" not in formula and formula == formula.strip()


def test_the_papers_queries(model) -> None:
    queries = re.findall(r"// [^\n]*\n([^\n]*)", model.queries.split("\n", 3)[3])
    assert queries == [
        "A[] settled imply (isClose imply Driving.Unsafe)",
        "A[] Driving.Unsafe imply cond0()",  # 10.0 * iSa + 5.0 * iPr + iCo <= 0.0: 10*iSa may leave int32
        "Pr[<=MAXT](<> Dynamics.Running && fabs(Dynamics.true_x - i2d(x)) >= THD)",
        "E[] !collide() && !offroad()",
        "E<> !collide() && !offroad() && goal()",
        "strategy safe = control: A[] !collide() && !offroad()",
        "simulate[<=MAXT;100]{mindist(), 3.0 * i2d(TD)}",
        "simulate[<=MAXT;100]{mindist(), 3.0 * i2d(TD)} under safe",
        "Pr[<=MAXT](<> mindist() <= 3.0 * i2d(TD)) under safe",
        "strategy reachSafe = maxE(10.0 * sa + 5.0 * pr + co)[<=MAXT]{Driving.location}->{i2d(x), i2d(y), i2d(v), "
        "i2d(head)}: <> goal() under safe",
        "simulate[<=MAXT;1]{i2d(x), i2d(y), i2d(v), i2d(head)} under reachSafe",
        "strategy reach = maxE(10.0 * sa + 5.0 * pr + co)[<=MAXT]{Driving.location}->{i2d(x), i2d(y), i2d(v), "
        "i2d(head)}: <> count >= STEPS",
        "A[] !collide() && !offroad() under reach",
        "A<> goal() under reach",
    ]


def test_symbolic_queries_read_integers_only(parsed: Parsed) -> None:
    functions = {"collide", "offroad", "goal"}  # bool functions of the integer state
    for _, formula in parsed.queries:
        if not is_symbolic(formula):
            continue
        names = {name.split(".")[0] for name in identifiers(formula)}
        assert not names & ((parsed.hybrids | parsed.doubles) - functions), formula
        assert not re.search(r"\d\.\d", formula), formula


def test_every_name_is_declared(parsed: Parsed) -> None:
    strategies = set()
    for _, formula in parsed.queries:
        defined = re.match(r"strategy (\w+) =", formula)
        for name in identifiers(formula):
            if defined and name == defined.group(1):
                continue
            if "." in name:
                process, member = name.split(".")
                assert process in parsed.processes, formula
                template = instance_template(parsed, process)
                assert (member == "location" or member in parsed.locations[template]
                        or member in template_names(parsed, template)), formula
            elif name not in QUERY_WORDS and name not in strategies:
                assert name in parsed.globals, (name, formula)
        if defined:
            strategies.add(defined.group(1))
    # every name the labels of the Controller, Dynamics, Action and Timer read
    functions = set(re.findall(r"^(?:void|bool|double|int32_t)\s+(\w+)\(", parsed.declaration, re.MULTILINE))
    for template in ("Controller", "Dynamics", "Action", "Timer"):
        local = template_names(parsed, template)
        for label in parsed.templates[template].iter("label"):
            if label.get("kind") == "select":
                local |= set(re.findall(r"(\w+) :", label.text))
        for label in parsed.templates[template].iter("label"):
            if label.get("kind") == "synchronisation":
                continue
            for name in re.findall(r"(?<![\w.])[A-Za-z_]\w*", re.sub(r"\d+\.\d+(?:e-?\d+)?", "", label.text)):
                assert name in parsed.globals | functions | local | {"int", "cos", "sin", "fabs", "true", "false"}, (
                    name, label.text)


def test_bindings_and_prev(parsed: Parsed) -> None:
    """The bindings are functions of the declarations (valid C: tests/targets/test_emitted_c.py runs them);
    prev(e) is e evaluated on the previous sample's state, kept in integers, not a double variable."""
    edges = parsed.templates["Controller"].findall("transition")
    labels = [{label.get("kind"): label.text for label in t.findall("label")} for t in edges]
    assert labels == [{}, {"synchronisation": "accrue?", "assignment": "sense_state()"},
                      {"synchronisation": "read!", "assignment": "read_inputs()"}]
    # the Timer keeps the start's sample as the sender of the first decide!, before any action is chosen
    start = parsed.templates["Timer"].findall("transition")[0]
    assert {label.get("kind"): label.text for label in start.findall("label")} == {
        "synchronisation": "decide!", "assignment": "keep_sample()"}
    assert parsed.templates["Controller"].findtext("declaration") is None
    declaration = parsed.declaration
    assert "int32_t prev_x, prev_y, prev_v, prev_acc, prev_head;" in declaration
    assert ("void keep_sample() {\n    prev_x = x;\n    prev_y = y;\n    prev_v = v;\n    prev_acc = acc;\n"
            "    prev_head = head;\n}") in declaration
    assert ("    count = count - 1;\n"
            "    prev0 = dist_goal();\n") in declaration
    assert ("    count = count + 1;\n"
            "    isClose = mindist() < 3.0 * i2d(TD);\n"
            "    prog = dist_goal() < prev0;\n"
            "    comf = fabs(i2d(acc)) < i2d(P1) * i2d(MAX_ACC) && fabs(i2d(turn)) < i2d(P2) * i2d(MAX_TURN);\n"
            "    collide_ = collide();\n"
            "    dgoal = d2i(dist_goal());\n"
            "    keep_sample();\n"
            "}") in declaration
    assert not re.search(r"^double ", declaration[declaration.index("// ---- end scenario model"):], re.MULTILINE)


def test_edges_compare_and_assign_no_double(parsed: Parsed) -> None:
    """Doubles on an edge exclude the model from symbolic analysis: the model's edges only call
    functions, compare integers, and assign integers, bools or hybrid clocks (reference §2)."""
    for name, template in parsed.templates.items():
        for label in template.iter("label"):
            if label.get("kind") in ("guard", "assignment"):
                assert "i2d(" not in label.text or name == "Dynamics", (name, label.text)
                assert not re.search(r"mindist|dist_goal|prev\d", label.text), (name, label.text)


def test_timer_decides_every_decide_period(parsed: Parsed) -> None:
    guards = [label.text for label in parsed.templates["Timer"].iter("label") if label.get("kind") == "guard"]
    assert "count < STEPS && count % DECIDE_EVERY == 0" in guards
    assert "count < STEPS && count % DECIDE_EVERY != 0" in guards
    assert "const int32_t DECIDE_EVERY = 2;" in parsed.declaration
    assert parsed.declaration.count("int32_t count") == 1 and "int[0,STEPS]" not in parsed.declaration


def test_dynamics_ode(parsed: Parsed) -> None:
    invariants = [label.text for label in parsed.templates["Dynamics"].iter("label")
                  if label.get("kind") == "invariant"]
    assert invariants == ["true_x' == UNIT_S * true_v * cos(true_head) && true_y' == UNIT_S * true_v * sin(true_head)"
                          " && true_v' == UNIT_S * saturated(true_v, true_acc, i2d(MIN_SPEED), i2d(MAX_SPEED))"
                          " && true_acc' == UNIT_S * saturated(true_acc, i2d(jerk), -i2d(MAX_ACC), i2d(MAX_ACC))"
                          " && true_head' == UNIT_S * i2d(turn)"]


def test_file_queries_may_use_the_models_conditions(tmp_path: Path) -> None:
    source = MODEL_RA.read_text(encoding="utf-8").replace(
        "    query Qe:", "    query Qg: E<> goal() && Normal\n    query Qe:")
    ra = tmp_path / "model.ra"
    ra.write_text(source.replace('"left_turn.xml"', f'"{MODEL_RA.parent / "left_turn.xml"}"'), encoding="utf-8")
    model = generate_uppaal_model(compile_file(ra).raise_for_errors())
    assert "// Qg\nE<> goal() && Driving.Normal\n" in model.queries


def test_a_query_reading_the_action_skips_the_period_after_a_decision(tmp_path: Path) -> None:
    """After `decide!` the Timer waits with jerk and turn already the new choice beside the decision
    sample's state; rac's engine has no such state (it shows the choice from the next sample on), so
    `E<> acc == 0 && jerk > 0` held at the start in UPPAAL only, and `E[<=2](max: jerk)` counted the
    choice of the decision at 2 s. A query reading them leaves that period out."""
    source = MODEL_RA.read_text(encoding="utf-8").replace(
        "    query Qe:", "    query J1: E<> acc == 0 && jerk > 0\n    query J2: A[] turn >= 0 || isClose\n"
        "    query J3: E<> x > 0\n    query J4: E[<=2; 10](max: jerk)\n    query J5: E[<=2; 10](min: fabs(turn) - v)\n"
        "    query J6: E[<=2; 10](max: v)\n    query Qe:")
    ra = tmp_path / "model.ra"
    ra.write_text(source.replace('"left_turn.xml"', f'"{MODEL_RA.parent / "left_turn.xml"}"'), encoding="utf-8")
    model = generate_uppaal_model(compile_file(ra).raise_for_errors())
    assert "// J1\nE<> !(Timer.Wait && count % DECIDE_EVERY == 0) && (acc == 0 && jerk > 0)\n" in model.queries
    assert ("// J2\nA[] settled && !(Timer.Wait && count % DECIDE_EVERY == 0) imply (turn >= 0 || isClose)\n"
            in model.queries)
    assert "// J3\nE<> x > 0\n" in model.queries  # the ego state is the same before and after the choice
    # E[..](max: e) over the run: a decision at the bound's last sample (here at 2 s) would bring its
    # choice in, which rac's engine shows from the next sample on, past the bound; the period after a
    # decision counts as -DBL_MAX (DBL_MAX for min), the replaced action still counted before `decide!`
    assert ("// J4\nE[<=20;10](max: (!(Timer.Wait && count % DECIDE_EVERY == 0) ? i2d(jerk) : -DBL_MAX))\n"
            in model.queries)
    assert ("// J5\nE[<=20;10](min: (!(Timer.Wait && count % DECIDE_EVERY == 0) ? fabs(i2d(turn)) - i2d(v) "
            ": DBL_MAX))\n" in model.queries)
    assert "// J6\nE[<=20;10](max: i2d(v))\n" in model.queries
    assert '<location id="' in model.xml and ">Wait</name>" in model.xml


# ---------------------------------------------------------------- C
def c_declarations(parsed: Parsed) -> str:
    text = parsed.declaration
    start = text.index("// ---- begin scenario model")
    end = text.index("// ---- end scenario model")
    return text[text.index("\n", start) + 1:end]


def test_scenario_declarations_are_emitted_verbatim(parsed: Parsed) -> None:
    spec = automaton().model
    data = build_model_data(load_scenario(spec.scenario_path), spec)
    assert c_declarations(parsed) == emit_declarations(data) + "\n"


def test_an_obstacle_id_beyond_int32_is_no_internal_error() -> None:
    """CommonRoad ids are whole numbers of any size; OBS_ID is int32_t and no function reads it. An id past
    2^31 (a converted dataset's) ended `rac compile --target uppaal` in "internal error: ... does not fit int32"."""
    import dataclasses

    spec = automaton().model
    data = build_model_data(load_scenario(spec.scenario_path), spec)
    huge = dataclasses.replace(data, obs_id=(5_000_000_000, *data.obs_id[1:]))
    line = next(line for line in emit_declarations(huge).splitlines() if line.startswith("const int32_t OBS_ID["))
    rest = ", ".join(map(str, data.obs_id[1:]))
    assert line == f"const int32_t OBS_ID[{len(data.obs_id)}] = {{-1, {rest}}};  // CommonRoad ids (-1: 5000000000, " \
                   "beyond int32)"


@pytest.mark.skipif(COMPILER is None, reason="no C compiler (cc or gcc) on PATH")
def test_declarations_compile_as_c(parsed: Parsed, tmp_path: Path) -> None:
    """The whole declaration section (channels left out, clocks as doubles: C has neither) and
    the Obstacle template's functions, as one C file."""
    lines = [re.sub(r"^(hybrid )?clock ", "double ", line) for line in parsed.declaration.splitlines()
             if not re.match(r"broadcast chan ", line)]
    obstacle = parsed.templates["Obstacle"].findtext("declaration")
    obstacle = obstacle.replace("hybrid clock ox, oy;", "const int32_t i = 0;\ndouble ox;\ndouble oy;")
    source = tmp_path / "model.c"
    source.write_text(C_PRELUDE + "\n".join(lines) + "\n" + obstacle
                      + "\n\nint main(void) {\n    keep_sample();\n    sense_state();\n    read_inputs();\n"
                      "    follow();\n    return speed() > 0.0 ? 1 : 0;\n}\n", encoding="utf-8")
    result = subprocess.run([COMPILER, "-O2", "-std=c99", "-Wall", "-Werror", "-o", str(tmp_path / "model"),
                             str(source), "-lm"], capture_output=True, text=True, check=False)
    assert result.returncode == 0, result.stderr


# ---------------------------------------------------------------- command line
def test_cli_emits_the_whole_model(tmp_path: Path) -> None:
    out = tmp_path / "out.xml"
    assert main(["compile", "--target", "uppaal", str(MODEL_RA), "-o", str(out)]) == 0
    xml, queries = out.read_text(encoding="utf-8"), (tmp_path / "out.q").read_text(encoding="utf-8")
    assert "system Timer, Controller, Action, Dynamics, Obstacle0, Obstacle1, Obstacle2, Driving;" in xml
    assert "strategy safe = control: A[] !collide() &amp;&amp; !offroad()" in xml
    assert "//   verifyta out.xml out.q" in queries


@pytest.mark.parametrize("name", ["DEU_Muc-3_1_T-1.xml", "ZAM_Ramp-1_1-T-1.xml", "ZAM_Tutorial-1_2_T-1.xml"])
def test_shared_scenarios_compile(name: str, tmp_path: Path) -> None:
    scenario = SCENARIOS / name
    if not scenario.exists():
        pytest.skip(f"{scenario} is absent")
    # ZAM_Tutorial's ego starts at 22 m/s: faster than the default `max_speed` 20 (E0714)
    source = MODEL_RA.read_text(encoding="utf-8").replace('"left_turn.xml"', f'"{scenario}" max_speed 25')
    ra = tmp_path / "model.ra"
    ra.write_text(source, encoding="utf-8")
    out = tmp_path / "model.xml"
    assert main(["compile", "--target", "uppaal", str(ra), "-o", str(out)]) == 0
    parsed = Parsed(out.read_text(encoding="utf-8"))
    assert parsed.processes[:4] == ["Timer", "Controller", "Action", "Dynamics"] and parsed.processes[-1] == "Driving"
    assert len(parsed.queries) == 14


def test_automaton_without_model_block_is_emitted_alone(tmp_path: Path) -> None:
    text = MODEL_RA.read_text(encoding="utf-8")
    alone = re.sub(r"    model \{.*?\n    \}\n", "", text, flags=re.DOTALL)
    automaton_alone = compile_text(alone, "alone.ra").raise_for_errors()
    with pytest.raises(ValueError):
        generate_uppaal_model(automaton_alone)


def test_standard_queries_read_the_models_names(tmp_path: Path) -> None:
    """An automaton whose names clash with the model's (an input `x`, a reward `v`) keeps the standard
    queries about the model: they read the ego's x, the objective reads the reward v."""
    source = MODEL_RA.read_text(encoding="utf-8").replace(
        "reward sa, pr, co", "reward sa, pr, co, v").replace(
        "input dgoal   : real in [0, 500]", "input dgoal   : real in [0, 500]\n    input x : real in [0, 10]").replace(
        "objective 10 * sa + 5 * pr + co", "objective 10 * sa + 5 * pr + co + v").replace(
        "priority sa > pr > co ", "priority sa > pr > co > v ").replace(
        "bind dgoal   = dist_goal()", "bind dgoal   = dist_goal()\n        bind x = fmin(v, 10)").replace(
        '"left_turn.xml"', f'"{MODEL_RA.parent / "left_turn.xml"}"')
    source = re.sub(r"location (\w+) *\{ sa' == (-?1); *pr' == (-?\d); *co' == (-?\d) \}",
                    r"location \1 { sa' == \2; pr' == \3; co' == \4; v' == 0 }", source)
    ra = tmp_path / "clash.ra"
    ra.write_text(source, encoding="utf-8")
    result = compile_file(ra, analyse=False)
    automaton = result.raise_for_errors()
    found = {d.name: d for d in automaton.standard_queries}
    reach = found["reachSafe"].query
    assert reach.continuous[0] == ie.model_ref("x")  # the ego's x, not the input
    assert found["reachSafe"].text.startswith("strategy reachSafe = maxE(10 * sa + 5 * pr + co + v)")
    assert ie.Ref(ie.RefKind.REWARD, "v", "num", 3) in ie.refs(reach.objective)
    queries = generate_uppaal_model(automaton).queries
    assert "maxE(10.0 * sa + 5.0 * pr + co + v_)" in queries and "->{i2d(x_), " not in queries


def test_sensor_error_sets_thd(tmp_path: Path) -> None:
    assert automaton().model.sensor_error == Fraction(1, 2)  # the default
    source = MODEL_RA.read_text(encoding="utf-8").replace(
        '        bind isClose', '        sensor_error 0.3\n        bind isClose')
    ra = tmp_path / "model.ra"
    ra.write_text(source.replace('"left_turn.xml"', f'"{MODEL_RA.parent / "left_turn.xml"}"'), encoding="utf-8")
    spec = compile_file(ra).raise_for_errors().model
    assert spec.sensor_error == Fraction(3, 10)
    assert "const double THD = 0.3;" in generate_uppaal_model(compile_file(ra).raise_for_errors()).xml


def test_a_rate_reading_an_input_is_checked_as_the_engine_checks_it(tmp_path: Path) -> None:
    """In the whole model the Controller computes the inputs (any significand): the automaton-alone
    Environment's values, one per piece of an input's range, are not part of it. A rate reading
    `dgoal` was still checked at those values (at exponent 2 the threshold 2 is the significand 200,
    of which `co' == dgoal / 800` at 0.1 s gains 200/8000: not whole), and the file that `rac verify`
    runs was refused with E0801."""
    source = MODEL_RA.read_text(encoding="utf-8").replace(
        "initial location Normal { sa' == 1;  pr' == 1;  co' == 1 }",
        "initial location Normal { sa' == 1;  pr' == 1;  co' == dgoal / 800 }").replace(
        '        scenario "left_turn.xml"', '        scenario "left_turn.xml"\n        exponent 2')
    assert "dgoal / 800" in source and "exponent 2" in source
    ra = tmp_path / "model.ra"
    ra.write_text(source.replace('"left_turn.xml"', f'"{MODEL_RA.parent / "left_turn.xml"}"'), encoding="utf-8")
    automaton = compile_file(ra).raise_for_errors()
    MirrorArithmetic(automaton, 100)  # rac's engine runs it: each accrual truncated, as emitted
    model = generate_uppaal_model(automaton)
    assert "iCo = iCo + dgoal / 8000" in model.xml
    assert "dgoal_values" not in model.xml  # no Environment chooses the inputs
    # the accrual's product stays checked over the input's range: `3*dgoal / 1000` at dgoal = 200000
    # (the significand 2e9 at exponent 4) computes 6e9 in UPPAAL's 32 bits
    wide = source.replace("co' == dgoal / 800", "co' == dgoal * 3 / 100").replace("\n        exponent 2", "")
    wide = wide.replace("real in [0, 500]", "real in [0, 200000]").replace("    priority sa > pr > co", "")
    ra.write_text(wide.replace('"left_turn.xml"', f'"{MODEL_RA.parent / "left_turn.xml"}"'), encoding="utf-8")
    # `rac check` reports it too: it passed the file that `rac compile --target uppaal` then refused, and
    # `rac verify` ran it (its engine reads only the values a run reaches)
    result = compile_file(ra)
    [diagnostic] = [d for d in result.diagnostics if d.code == "E0801"]
    assert re.search(r"reward rate `co' == 0.03\*dgoal`.* 6000000000, beyond", diagnostic.message)
    assert result.automaton is None
    # the target's own check, on the same automaton as the checker would have built it
    ra.write_text(wide.replace("real in [0, 200000]", "real in [0, 500]").replace(
        '"left_turn.xml"', f'"{MODEL_RA.parent / "left_turn.xml"}"'), encoding="utf-8")
    narrow = compile_file(ra).raise_for_errors()
    widened = dataclasses.replace(narrow, inputs=tuple(
        dataclasses.replace(item, high=Fraction(200000)) if item.name == "dgoal" else item for item in narrow.inputs))
    with pytest.raises(UppaalError, match=r"E0801: reward rate `co' == 0.03\*dgoal`.* 6000000000, beyond"):
        generate_uppaal_model(widened)


@pytest.mark.parametrize(("bound", "why"), [
    ("500000", "its significand 5000000000 is beyond the 32-bit integer range"),
    ("500.00005", "is not an integer"),
])
def test_an_input_bound_without_a_significand_fails_rac_check_as_it_fails_the_target(
        bound: str, why: str, tmp_path: Path) -> None:
    """`dgoal` in [0, 500000] at exponent 4 (significand 5e9), or [0, 500.00005]: `rac check` passed the file,
    `rac compile --target uppaal` refused it (E0801 at the bound) and `rac verify` ran it. With a `model`
    block rac check reports the bound as the target does."""
    source = MODEL_RA.read_text(encoding="utf-8").replace("real in [0, 500]", f"real in [0, {bound}]")
    assert f"[0, {bound}]" in source
    ra = tmp_path / "model.ra"
    ra.write_text(source.replace('"left_turn.xml"', f'"{MODEL_RA.parent / "left_turn.xml"}"'), encoding="utf-8")
    result = compile_file(ra)
    [diagnostic] = [d for d in result.diagnostics if d.code == "E0801"]
    assert diagnostic.message == (f"the bound {bound} of input `dgoal` is not representable as a 32-bit significand "
                                  "at base 10, exponent 4")
    assert why in diagnostic.notes[0].message
    assert result.automaton is None  # nothing for the engine or a target to run
