"""UPPAAL's own parser accepts every model and query file rac emits.

The validator is ``utap_validate`` (tests/support/utap.py): UTAP, the parser and type checker inside
UPPAAL, built by ``../shared/tools/uppaal-parser``. Each test writes the emitted ``.xml`` and
``.q``, runs it, and fails with its output (and the lines it points at) unless UPPAAL would accept
the model, the queries in its ``<queries>`` section and every line of the ``.q`` file:

* the golden files ``tests/golden/driving.xml`` + ``driving.q`` (the automaton alone) and
  ``left_turn_model.xml`` + ``left_turn_model.q`` (the whole model of the left turn);
* every ``.ra`` file under ``examples/`` and ``stdlib/``, compiled exactly as
  ``rac compile --target uppaal FILE -o OUT.xml`` does (OUT.xml with OUT.q): the automaton alone,
  or the whole vehicle-and-scenario model for a file with a ``model`` block.
  ``examples/naive_driving.ra`` fails ``rac check`` on purpose (E0402), so rac compile writes
  nothing for it; the model :func:`rac.targets.uppaal.automaton.generate_uppaal` emits for it is validated;
* every query form of the language (docs/language.md, "Queries"), one test each, as queries of
  stdlib/driving.ra's automaton alone compiled by ``rac compile``: ``A[]``, ``E<>``, ``E[]``,
  ``A<>``, ``-->``, ``Pr`` (time and step bounds, runs, ``<>`` and ``[]``, ``>= θ``), ``E[..](max:
  / min:)``, ``simulate``, ``strategy = control: A[]`` / ``E<>``, learning with ``maxE`` / ``minE``
  and ``under``, the functions, ``deadlock``, constants and qualified names; and time in
  symbolic queries with a time unit (1.5 s) that is not a whole fraction of a second. The two
  forms UPPAAL has no counterpart for (``Pr[<=T; N](..) >= θ``, learning over ``[]``) are refused
  by rac with E0802 on the query, and nothing is written; ``control: E<> p`` is written as UPPAAL
  5's ``control: A<> p``;
* the whole model of each tiny scenario (``tiny_scenarios``: narrow_road, avoidable_obstacle,
  goal_behind_wall, goal_ahead) with stdlib/driving.ra's automaton, bound as in
  examples/left_turn/model.ra, once with queries of every form over the automaton's names and
  the model's functions ``collide()``, ``offroad()``, ``goal()``, ``dist_goal()``, and once with
  queries over the model's vocabulary (the ego state ``x y v acc head``, settings such as
  ``collision_distance``, ``mindist()``, the true state ``true_x``);
* the whole model of each shared scenario (``../shared/scenarios/*.xml``, skipped when absent)
  with examples/left_turn/model.ra's settings, as tests/targets/test_uppaal_model.py compiles them;
* random reward automata (hypothesis; the strategy of tests/runtime/test_agreement.py, some with
  ``episode ends when``) emitted alone by ``generate_uppaal``, with queries of several forms over their names;
* stdlib/driving.ra's automaton with ``episode ends when collide || dgoal < 2``, alone and as the
  whole model of each tiny scenario.
* what ``rac check`` accepts, ``rac compile`` writes: a table of query forms (:data:`AGREEMENT`), alone
  and in a tiny scenario's whole model, each either refused by ``rac check``, or written and accepted
  by the parser, or one of the forms docs/uppaal.md lists as having no UPPAAL counterpart (E0802).

Without the validator these tests skip (under ``RAC_REQUIRE_UTAP=1``, as in CI, they fail);
the end of the session prints how many models and query files it accepted.
"""

from __future__ import annotations

import dataclasses
import functools
import re
from fractions import Fraction
from pathlib import Path

import pytest
from hypothesis import HealthCheck, assume, given, settings
from test_agreement import automata
from tiny_scenarios import TINY_SCENARIOS
from utap import Utap

from rac import ir
from rac.cli.main import main
from rac.compiler import compile_file, compile_text
from rac.targets.uppaal.automaton import UppaalError, generate_uppaal
from rac.targets.uppaal.model import generate_uppaal_model

ROOT = Path(__file__).resolve().parents[2]
GOLDEN = Path(__file__).parents[1] / "golden"
DRIVING_RA = ROOT / "stdlib" / "driving.ra"
MODEL_RA = ROOT / "examples" / "left_turn" / "model.ra"
SCENARIOS = ROOT.parent / "shared" / "scenarios"
SHARED_SCENARIOS = ("DEU_Muc-3_1_T-1.xml", "ZAM_Ramp-1_1-T-1.xml", "ZAM_Tutorial-1_2_T-1.xml")
RA_FILES = sorted([*ROOT.glob("examples/**/*.ra"), *ROOT.glob("stdlib/**/*.ra")])
#: Files that `rac check` rejects on purpose (so `rac compile` writes nothing), with the expected code.
REJECTED_BY_CHECK = {"examples/naive_driving.ra": "E0402"}


def compile_cli(source: Path, out: Path, capsys: pytest.CaptureFixture[str]) -> tuple[Path, Path]:
    """``rac compile --target uppaal SOURCE -o OUT`` in process; returns OUT and OUT.q."""
    code = main(["compile", "--target", "uppaal", str(source), "-o", str(out)])
    captured = capsys.readouterr()
    assert code == 0, f"rac compile --target uppaal {source} exited with {code}:\n{captured.err}{captured.out}"
    return out, out.with_suffix(".q")


def driving_without_queries() -> str:
    """stdlib/driving.ra up to its queries (the closing brace left off)."""
    text = DRIVING_RA.read_text(encoding="utf-8")
    return text[:text.index("    query ")]


def with_queries(head: str, queries: list[str] | tuple[str, ...]) -> str:
    return head + "".join(f"    query Q{i}: {query}\n" for i, query in enumerate(queries)) + "}\n"


# ---------------------------------------------------------------- golden files
@pytest.mark.parametrize("stem", ["driving", "left_turn_model"])
def test_golden_files(utap: Utap, stem: str) -> None:
    utap.validate_files(GOLDEN / f"{stem}.xml", GOLDEN / f"{stem}.q")


# ---------------------------------------------------------------- examples/ and stdlib/
@pytest.mark.parametrize("path", RA_FILES, ids=[str(p.relative_to(ROOT)) for p in RA_FILES])
def test_every_example_compiles_to_a_valid_model(utap: Utap, path: Path, tmp_path: Path,
                                                 capsys: pytest.CaptureFixture[str]) -> None:
    relative = path.relative_to(ROOT).as_posix()
    out = tmp_path / f"{path.stem}.xml"
    if relative in REJECTED_BY_CHECK:
        code = main(["compile", "--target", "uppaal", str(path), "-o", str(out)])
        err = capsys.readouterr().err
        assert code == 1 and REJECTED_BY_CHECK[relative] in err, err
        assert not out.exists() and not out.with_suffix(".q").exists()
        result = compile_file(path, analyse=False)  # the model rac would emit if the check passed
        assert result.automaton is not None and result.automaton.model is None, result.diagnostics
        model = generate_uppaal(result.automaton, source_name=path.name, model_name=out.name)
        utap.validate(model.xml, model.queries, path.stem)
        return
    utap.validate_files(*compile_cli(path, out, capsys))


# ---------------------------------------------------------------- every query form, automaton alone
#: One case per form of docs/language.md's query table (several queries where one needs another).
QUERY_FORMS: dict[str, tuple[str, ...]] = {
    "A[]": ("A[] isClose imply Unsafe",),
    "E<>": ("E<> Unsafe && sa < 0",),
    "E[]": ("E[] !Unsafe",),
    "A<>": ("A<> time >= 30",),
    "leads-to": ("isClose --> Unsafe",),
    "Pr<>": ("Pr[<=30](<> Unsafe)",),
    "Pr[]": ("Pr[<=30]([] !Unsafe)",),
    "Pr-runs": ("Pr[<=30; 1000](<> Unsafe)",),
    "Pr-steps": ("Pr[#<=300](<> Unsafe)",),
    "Pr>=theta": ("Pr[<=30](<> Unsafe) >= 0.9",),
    "Pr-runs>=theta": ("Pr[<=30; 1000](<> Unsafe) >= 0.9",),  # docs/language.md's example
    "E-max": ("E[<=30; 100](max: 10*sa + 5*pr + co)",),
    "E-min": ("E[<=30; 100](min: sa)",),
    "simulate": ("simulate[<=30; 10]{sa, pr, co, Unsafe}",),
    "simulate-one-run": ("simulate[<=30]{10*sa + 5*pr + co}",),
    "control-A[]": ("strategy safe = control: A[] !Unsafe",),
    "control-E<>": ("strategy arrive = control: E<> Normal && time >= 30",),
    "learning-under": ("strategy safe = control: A[] !Unsafe",
                       "strategy fast = maxE(pr)[<=30]{Driving.location}->{dgoal}: <> time >= 30 under safe",
                       "A[] !Unsafe under fast", "E<> Unsafe under fast", "Pr[<=30](<> Unsafe) under fast",
                       "E[<=30; 100](max: pr) under fast", "simulate[<=30; 5]{sa, pr} under fast"),
    "learning-minE": ("strategy slow = minE(co)[<=30]{Driving.location}->{sa, pr}: <> time >= 30",),
    "learning-steps": ("strategy k = maxE(sa)[#<=900]{Driving.location}->{}: <> time >= 30",),
    "learning-[]": ("strategy calm = minE(co)[<=30]{}->{}: [] !Unsafe",),
    "functions": ("Pr[<=30](<> fabs(sa) > 10 || abs(pr) > 10 || sqrt(fmax(co, 0)) > 3 || fmin(sa, pr) < -5 "
                  "|| floor(co) != ceil(co) || round(sa) > trunc(pr))",),
    "deadlock": ("A[] !deadlock",),
    "constants-and-qualified": ("A[] Driving.Unsafe imply sa <= PENALTY && 10*sa + 5*pr + co <= 0",),
    "numeric-input": ("E<> dgoal < 2 && Normal",),
    # a condition computed in doubles (10 * sa could leave int32) that reads the location index: the
    # function receives it as a parameter
    "location-in-doubles": ("A[] 10 * sa - Driving.location >= dgoal / 4", "E<> sqrt(Driving.location) > 1"),
    "word-operators": ("A[] not isClose or Unsafe and true",),
}


#: Forms the language parses but UPPAAL has no counterpart for (a number of runs in a hypothesis
#: test, a learning query over ``[]``): rac refuses them with E0802 on the query.
UPPAAL_HAS_NO_SUCH_FORM = {"Pr-runs>=theta", "learning-[]"}


@pytest.mark.parametrize("form", QUERY_FORMS)
def test_every_query_form_alone(utap: Utap, form: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    source = tmp_path / "forms.ra"
    source.write_text(with_queries(driving_without_queries(), QUERY_FORMS[form]), encoding="utf-8")
    out = tmp_path / "forms.xml"
    if form in UPPAAL_HAS_NO_SUCH_FORM:
        code = main(["compile", "--target", "uppaal", str(source), "-o", str(out)])
        err = capsys.readouterr().err
        assert code == 1 and re.search(r"error\[E0802\]: query `Q0` cannot be written", err), err
        assert not out.exists()
        return
    utap.validate_files(*compile_cli(source, out, capsys))


#: A declaration of stdlib/driving.ra whose name the automaton takes (found by tests/support/fuzz.py's generator).
NAMESAKES = {"const": "PENALTY", "bool input": "isClose", "numeric input": "dgoal", "reward": "sa",
             "location": "Unsafe"}


@pytest.mark.parametrize("whole_model", [False, True], ids=["alone", "whole-model"])
@pytest.mark.parametrize("kind", NAMESAKES)
def test_an_automaton_named_like_one_of_its_names(utap: Utap, kind: str, whole_model: bool, tmp_path: Path,
                                                  capsys: pytest.CaptureFixture[str]) -> None:
    """The automaton's name is not in the namespace of its inputs, constants, rewards and
    locations, but in UPPAAL the template's name is as global as the constants and variables:
    `automaton PENALTY { const PENALTY = 100 ... }` once declared both as `PENALTY`."""
    name = NAMESAKES[kind]
    text = (MODEL_RA if whole_model else DRIVING_RA).read_text(encoding="utf-8")
    source = tmp_path / "namesake.ra"
    source.write_text(text.replace("automaton Driving {", f"automaton {name} {{"), encoding="utf-8")
    if whole_model:
        (tmp_path / "left_turn.xml").write_bytes((MODEL_RA.parent / "left_turn.xml").read_bytes())
    utap.validate_files(*compile_cli(source, tmp_path / "namesake.xml", capsys))


def test_inputs_named_like_the_actions_select_variables(utap: Utap, tmp_path: Path,
                                                        capsys: pytest.CaptureFixture[str]) -> None:
    """Inputs `j` and `u`: the Action's select variables (the jerk's and the turn's index) were always
    `j` and `u`, which then shadowed the inputs (UTAP: `j $shadows_a_variable`); they are fresh names
    now, like every name the target adds, also in the guard `allow when` puts on them."""
    text = MODEL_RA.read_text(encoding="utf-8")
    text = text.replace("    input collide : bool", "    input collide : bool\n    input j : bool\n    input u : bool")
    text = text.replace("edge Unsafe -> Unsafe   when collide ", "edge Unsafe -> Unsafe   when collide && j && u ")
    text = text.replace("        bind collide = collide()", "        bind collide = collide()\n        bind j = v > 1\n"
                        "        bind u = acc > 0\n        allow when v < 15")
    assert text.count("input j") == text.count("bind u") == text.count("&& j && u") == 1
    source = tmp_path / "indices.ra"
    source.write_text(text, encoding="utf-8")
    (tmp_path / "left_turn.xml").write_bytes((MODEL_RA.parent / "left_turn.xml").read_bytes())
    xml, queries = compile_cli(source, tmp_path / "indices.xml", capsys)
    emitted = xml.read_text(encoding="utf-8")
    assert ">j_ : int[0,JERK_COUNT-1], u_ : int[0,TURN_COUNT-1]<" in emitted
    assert ">ALLOWED[j_ * TURN_COUNT + u_]<" in emitted
    output = utap.validate_files(xml, queries)
    assert "shadows" not in output, output


def test_names_of_the_obstacle_processes(utap: Utap, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """An input `Obstacle0` and an automaton `Obstacle1`: the whole model's obstacle processes were always
    `Obstacle0 = Obstacle(0);` ..., which then defined those names twice (UTAP: `$Duplicate_definition_of
    Obstacle0`, and `$Not_a_template: Obstacle1` in the `system` line); they are fresh names now, like
    every name the target adds."""
    text = MODEL_RA.read_text(encoding="utf-8").replace("automaton Driving {", "automaton Obstacle1 {")
    text = text.replace("    input collide : bool", "    input collide : bool\n    input Obstacle0 : bool")
    text = text.replace("edge Unsafe -> Unsafe   when collide ", "edge Unsafe -> Unsafe   when collide && Obstacle0 ")
    text = text.replace("        bind collide = collide()",
                        "        bind collide = collide()\n        bind Obstacle0 = v > 1")
    assert text.count("Obstacle0") == 3 and text.count("Obstacle1") == 1
    source = tmp_path / "obstacles.ra"
    source.write_text(text, encoding="utf-8")
    (tmp_path / "left_turn.xml").write_bytes((MODEL_RA.parent / "left_turn.xml").read_bytes())
    xml, queries = compile_cli(source, tmp_path / "obstacles.xml", capsys)
    emitted = xml.read_text(encoding="utf-8")
    assert "Obstacle0_ = Obstacle(0);" in emitted and "Obstacle1_ = Obstacle(1);" in emitted
    assert "Obstacle2 = Obstacle(2);" in emitted
    assert "system Timer, Controller, Action, Dynamics, Obstacle0_, Obstacle1_, Obstacle2, Obstacle1;" in emitted
    utap.validate_files(xml, queries)


def test_time_in_queries_with_a_coarse_period(utap: Utap, tmp_path: Path,
                                              capsys: pytest.CaptureFixture[str]) -> None:
    """A time unit (here the period, 1.5 s) that is not a whole fraction of a second."""
    head = driving_without_queries().replace("sample every 0.1", "sample every 1.5")
    source = tmp_path / "coarse.ra"
    source.write_text(with_queries(head, ("A<> time >= 30", "E<> time >= 4.5 && Unsafe", "A[] time <= 30 || Unsafe",
                                          "Pr[<=30](<> Unsafe)", "simulate[<=30; 5]{sa, pr, co}")), encoding="utf-8")
    utap.validate_files(*compile_cli(source, tmp_path / "coarse.xml", capsys))


def test_updates_whose_values_in_between_fit(utap: Utap, tmp_path: Path,
                                             capsys: pytest.CaptureFixture[str]) -> None:
    """An edge and `at end` clauses whose updates go up and back down, with every value in between
    within int32 at exponent 4 (200003 at most): `rac check` passes it, and the model it compiles to
    is one UPPAAL accepts, the assignments in the order written (UPPAAL stores each of them)."""
    source = tmp_path / "in_between.ra"
    source.write_text("""\
automaton InBetween {
    input a : bool
    reward p
    objective p
    sample every 1
    horizon 3
    initial location L { p' == 1 }
    edge L -> L when a do p = p + 100000, p = p + 100000, p = p - 100000, p = p - 100000
    at end when a do p += 100000
    at end do p -= 100000
}
""", encoding="utf-8")
    assert main(["check", str(source)]) == 0
    assert "rewards stay within [-100000, 200003]" in capsys.readouterr().out
    xml, queries = compile_cli(source, tmp_path / "in_between.xml", capsys)
    model = xml.read_text(encoding="utf-8")
    # the mirror's assignments, in the order written: up by 10^9 (100000 at exponent 4) twice, then down
    assert model.count(" + 1000000000") == 3 and model.count(" - 1000000000") == 3
    assert model.index(" + 1000000000") < model.index(" - 1000000000")
    utap.validate_files(xml, queries)


# ---------------------------------------------------------------- the tiny scenarios' whole models
#: The bindings of examples/left_turn/model.ra.
BINDINGS = ("isClose = mindist() < 3 * collision_distance",
            "prog    = dist_goal() < prev(dist_goal())",
            "comf    = fabs(acc) < comfort_acceleration * max_acceleration && fabs(turn) < comfort_turn * max_turn",
            "collide = collide()",
            "dgoal   = dist_goal()")
#: Queries over the automaton's names and the model's conditions (a tiny scenario's horizon is 4 s).
AUTOMATON_QUERIES = (
    "A[] isClose imply Unsafe", "E<> Unsafe", "E[] !Unsafe", "A<> time >= 4", "isClose --> Unsafe",
    "Pr[<=4](<> Unsafe)", "Pr[<=4]([] !Unsafe) >= 0.5", "Pr[#<=40](<> Unsafe)",
    "E[<=4; 100](max: 10*sa + 5*pr + co)", "simulate[<=4; 10]{sa, pr, co, Unsafe, dgoal}",
    "strategy calm = control: A[] !Unsafe",
    "strategy fast = maxE(10*sa + 5*pr + co)[<=4]{Driving.location}->{dgoal}: <> time >= 4 under calm",
    "A[] !Unsafe under fast", "simulate[<=4; 5]{sa, pr, co} under fast",
    "A[] collide() imply isClose", "E<> goal() && !collide() && !offroad()", "E[] !collide() && !offroad()",
    "A<> goal()", "collide() --> Unsafe", "Pr[<=4](<> collide() || offroad())",
    "strategy shield = control: A[] !collide() && !offroad()",
    "strategy near = minE(dist_goal())[<=4]{Driving.location}->{dgoal}: <> goal() under shield",
    "E<> goal() under near")
#: Queries over the model's vocabulary: ego state, settings, mindist(), the true state.
MODEL_QUERIES = (
    "Pr[<=4](<> mindist() < 3 * collision_distance)", "Pr[<=4](<> fabs(true_x - x) >= 0.5) >= 0.1",
    "E[<=4; 100](max: v)", "E[<=4; 100](min: dist_goal() + fabs(head))", "E[<=2; 100](max: jerk + fabs(turn))",
    "simulate[<=4; 10]{x, y, v, acc, head, true_x, mindist()}",
    "Pr[<=4](<> v > max_speed - 1 || fabs(acc) > comfort_acceleration * max_acceleration)",
    "strategy shield = control: A[] !collide() && !offroad()",
    "strategy reach = maxE(10*sa + 5*pr + co)[<=4]{Driving.location}->{x, y, v, head}: <> goal() under shield",
    "simulate[<=4; 1]{x, y, v, head, true_x} under reach", "A[] !collide() && !offroad() under reach")


def tiny_source(folder: Path, name: str, queries: tuple[str, ...]) -> Path:
    """stdlib/driving.ra's automaton in the tiny scenario ``name`` (written into ``folder``), with the
    scenario's settings as its model block, the bindings of the left turn and ``queries``."""
    tiny = TINY_SCENARIOS[name]()
    tiny.write(folder)
    head = driving_without_queries()
    head = head.replace("sample every 0.1", f"sample every {float(tiny.settings.sense_period):g}")
    head = head.replace("horizon 30", f"horizon {float(tiny.settings.horizon):g}")
    assert f"horizon {float(tiny.settings.horizon):g}" in head and "sample every 0.1" not in head
    block = tiny.settings.model_block(f"{tiny.name}.xml", BINDINGS)
    head += "\n" + "".join(f"    {line}\n" for line in block.splitlines()) + "\n"
    source = folder / f"{name}.ra"
    source.write_text(with_queries(head, queries), encoding="utf-8")
    return source


@pytest.mark.parametrize("name", sorted(TINY_SCENARIOS))
def test_tiny_scenario_whole_model(utap: Utap, name: str, tmp_path: Path,
                                   capsys: pytest.CaptureFixture[str]) -> None:
    source = tiny_source(tmp_path, name, AUTOMATON_QUERIES)
    utap.validate_files(*compile_cli(source, tmp_path / f"{name}_model.xml", capsys))


@pytest.mark.parametrize("name", sorted(TINY_SCENARIOS))
def test_tiny_scenario_model_vocabulary(utap: Utap, name: str, tmp_path: Path,
                                        capsys: pytest.CaptureFixture[str]) -> None:
    source = tiny_source(tmp_path, name, MODEL_QUERIES)
    utap.validate_files(*compile_cli(source, tmp_path / f"{name}_vocabulary.xml", capsys))


# ---------------------------------------------------------------- the shared scenarios
@pytest.mark.parametrize("name", SHARED_SCENARIOS)
def test_shared_scenario_whole_model(utap: Utap, name: str, tmp_path: Path,
                                     capsys: pytest.CaptureFixture[str]) -> None:
    scenario = SCENARIOS / name
    if not scenario.exists():
        pytest.skip(f"{scenario} is absent (../shared/scenarios beside this checkout)")
    source = tmp_path / "model.ra"
    # ZAM_Tutorial's ego starts at 22 m/s: faster than the default `max_speed` 20 (E0714)
    source.write_text(MODEL_RA.read_text(encoding="utf-8").replace('"left_turn.xml"', f'"{scenario}" max_speed 25'),
                      encoding="utf-8")
    utap.validate_files(*compile_cli(source, tmp_path / f"{scenario.stem}.xml", capsys))


def test_zam_ramp_benchmark_model(utap: Utap, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """benchmarks/zam_ramp.ra: CommonUppRoad's ZAM_Ramp model as rac's modelling choices (dynamics
    increments, allow when, the start settings, offroad_from)."""
    source = ROOT / "benchmarks" / "zam_ramp.ra"
    if not (SCENARIOS / "ZAM_Ramp-1_1-T-1.xml").exists():
        pytest.skip("../shared/scenarios/ZAM_Ramp-1_1-T-1.xml is absent (../shared beside this checkout)")
    xml, queries = compile_cli(source, tmp_path / "zam_ramp.xml", capsys)
    assert "allow_actions()" in xml.read_text(encoding="utf-8")
    utap.validate_files(xml, queries)


# ---------------------------------------------------------------- random automata, alone
#: Over the names every automaton of test_agreement's `automata()` has: L0, r0, inputs b c x m.
RANDOM_QUERIES = (
    "A[] L0 imply r0 <= 1000", "E<> L0 && b", "E[] r0 >= -1000", "A<> time >= 30", "b --> L0",
    "Pr[<=30](<> L0 && x > 1)", "Pr[<=30]([] r0 < 100) >= 0.5", "E[<=30; 10](max: r0 + x)",
    "simulate[<=30; 5]{r0, x, m, L0}", "strategy s = control: A[] r0 > -1000",
    "strategy t = maxE(r0)[<=30]{Random.location}->{x, m}: <> time >= 30 under s", "A[] r0 > -1000 under t")


@functools.cache
def random_queries() -> tuple[object, ...]:
    """:data:`RANDOM_QUERIES` checked, as rac's compiler attaches them to an automaton: compiled
    with an automaton that declares the same names in the same order as test_agreement's."""
    head = ("automaton Random {\n    input b : bool\n    input c : bool\n    input x : real in [-5, 5]\n"
            "    input m : int in [0, 3]\n    reward r0\n    objective r0\n    sample every 1\n    horizon 30\n"
            "    initial location L0 { r0' == 1 }\n")
    result = compile_text(with_queries(head, RANDOM_QUERIES), "random.ra", analyse=False)
    assert result.automaton is not None, result.diagnostics
    assert len(result.automaton.queries) == len(RANDOM_QUERIES)
    return tuple(result.automaton.queries)


@settings(max_examples=30, deadline=None, suppress_health_check=[HealthCheck.too_slow, HealthCheck.filter_too_much])
@given(automaton=automata())
def test_random_automata_alone(utap: Utap, automaton: ir.Automaton) -> None:
    automaton = dataclasses.replace(automaton, queries=random_queries())
    try:
        model = generate_uppaal(automaton, source_name="random.ra", model_name="random.xml")
    except UppaalError as failure:  # E0801: a number the significands cannot represent
        assume(not re.search(r"\bE0801\b", str(failure)))
        raise
    utap.validate(model.xml, model.queries, "random")


@pytest.mark.parametrize("length", [3900, 3901])
def test_the_longest_name_reaches_uppaal(length: int, utap: Utap, tmp_path: Path,
                                          capsys: pytest.CaptureFixture[str]) -> None:
    """A name of MAX_NAME characters compiles into a model UPPAAL's parser accepts (the target's
    derived names included); one character more is E0012 at the name."""
    name = "a" * length
    source = tmp_path / "long.ra"
    source.write_text(f"""automaton A {{
    input {name} : bool
    input d : real in [0, 2]
    reward r
    priority r
    objective r
    sample every 0.1
    horizon 1
    initial location L {{ r' == 1 }}
    location M {{ r' == d }}
    edge L -> M when {name}
    edge M -> L when d > 1
    query Q: A[] r >= -1
}}
""", encoding="utf-8")
    if length == 3901:
        assert main(["check", str(source)]) == 1
        assert "error[E0012]: a name of 3,901 characters: at most 3,900" in capsys.readouterr().out
        return
    utap.validate_files(*compile_cli(source, tmp_path / "long.xml", capsys))


# ---------------------------------------------------------------- episode ends when
#: `episode ends when collide || dgoal < 2` over stdlib/driving.ra's inputs.
ENDS = ir.BOr((ir.BInput("collide"), ir.BAtom("dgoal", "<", Fraction(2))))


@pytest.mark.parametrize("name", [None, *sorted(TINY_SCENARIOS)])
def test_episode_ends_reaches_uppaal(utap: Utap, name: str | None, tmp_path: Path,
                                    capsys: pytest.CaptureFixture[str]) -> None:
    """An automaton whose run ends at a sample (`episode ends when collide || dgoal < 2` in its file),
    compiled by `rac compile --target uppaal` alone and as the whole model of each tiny scenario: the
    Timer's `sense!` edges are guarded by the condition (the one into the ending sets `ended`), every
    non-zero rate stops once `ended` is set, and UPPAAL accepts model and queries."""
    if name is None:
        source = tmp_path / "ends.ra"
        queries = [query for form in ("A[]", "E-max", "simulate", "learning-under") for query in QUERY_FORMS[form]]
        source.write_text(with_queries(driving_without_queries(), queries), encoding="utf-8")
    else:
        source = tiny_source(tmp_path, name, AUTOMATON_QUERIES)
    text = source.read_text(encoding="utf-8")
    source.write_text(text.replace("    at end when", "    episode ends when collide || dgoal < 2\n\n    at end when"),
                      encoding="utf-8")
    assert compile_file(source).raise_for_errors().episode_ends == ENDS
    xml_path, queries_path = compile_cli(source, tmp_path / f"ends_{name or 'alone'}.xml", capsys)
    xml = xml_path.read_text(encoding="utf-8")
    assert "bool ended;" in xml
    condition = r"\(collide_? \|\| dgoal &lt; \d+\)"  # the model's collide() makes the input `collide_`
    assert re.search(rf"count == STEPS \|\| {condition}<", xml)
    assert len(re.findall(rf"count &lt; STEPS &amp;&amp; [^<]*!{condition}<", xml)) == (1 if name is None else 2)
    assert "settled = true, ended = true" in xml
    assert re.search(r"sa&#39; == \(ended \? 0\.0 : 0\.\d\)", xml) and "co&#39; == 0" in xml
    utap.validate_files(xml_path, queries_path)


# ---------------------------------------------------------------- what rac check accepts, rac compile writes
#: Query forms over stdlib/driving.ra's automaton, alone and as the whole model of a tiny scenario, and
#: what each gets: "ok" (`rac check` accepts it, `rac compile --target uppaal` writes it, UPPAAL's parser
#: accepts it), "check CODE" (`rac check` refuses it) or "target CODE: words" (`rac check` accepts it and the
#: UPPAAL target refuses it: only the forms docs/uppaal.md's table lists as UPPAAL having no counterpart,
#: where `rac verify` may still answer). A query `rac check` accepts that the target refuses for any other
#: reason is a defect: the location index in a condition computed with doubles was one (E0802), a discrete
#: observation holding a number beyond int32 another (E0801 in the target only).
AGREEMENT: dict[str, tuple[str, str]] = {  # name: (query, outcome alone and in the whole model)
    "location-in-a-wide-sum": ("A[] 10 * sa - Driving.location >= dgoal / 4", "ok"),
    "location-sqrt": ("E<> sqrt(Driving.location) > 1", "ok"),
    "location-leads-to": ("-Driving.location * 1000 + pr * 7 < 2 * co --> Unsafe", "ok"),
    "location-control": ("strategy T = control: A[] Driving.location / 3 + 3 * sa - 2 * pr > -0.5", "ok"),
    "location-statistical": ("Pr[<=4](<> Driving.location * 1000000000000 > sa)", "ok"),
    "location-simulate": ("simulate[<=4; 1]{-Driving.location, Driving.location / 2, Unsafe}", "ok"),
    "location-observed": ("strategy S = maxE(sa)[<=4]{Driving.location, 2 * Driving.location + 1}->{dgoal}: "
                          "<> time >= 4", "ok"),
    "wide-sum": ("A[] Unsafe imply 10 * sa + 5 * pr + co <= 0", "ok"),
    "constant-truth": ("E<> sa > 4503599627370497", "ok"),
    "fine-threshold": ("E<> dgoal - 0.00001 == 0 || sa == 0.00001", "ok"),
    "time": ("A<> time >= 4 || fabs(time - 2) < 0.5 || time * time > 3", "ok"),
    "bool-compare": ("E<> (sa > 1) == (pr > 1) && Unsafe != isClose", "ok"),
    "functions-symbolic": ("E<> round(sa) > 0.5 && floor(pr * 0.1) > 0.5 && fmin(sa, pr) > fmax(dgoal, co)", "ok"),
    "deadlock": ("A[] !deadlock", "ok"),
    "deadlock-E<>": ("E<> deadlock", "ok"),
    "observed-half": ("strategy S = maxE(sa)[<=4]{0.5, sa / 3 + pr / 7, isClose}->{}: <> Unsafe", "ok"),
    "observed-beyond-int32": ("strategy S = maxE(sa)[<=4]{4503599627370497}->{}: <> Unsafe", "check E0801"),
    "observed-sum-beyond-int32": ("strategy S = maxE(sa)[<=4]{sa + 4503599627370497}->{}: <> Unsafe", "check E0801"),
    "E-max-deadline": ("E[<=4; 10](max: Driving.location + sa)", "ok"),
    "Pr-equality": ("Pr[<=4](<> Unsafe) == 0.5", "target E0802: `>=` or `<=` only"),
    "Pr-strict": ("Pr[<=4](<> Unsafe) > 0.5", "target E0802: `>=` or `<=` only"),
    "Pr-runs-threshold": ("Pr[<=4; 100](<> Unsafe) >= 0.5", "target E0802: choosing the number of runs itself"),
    "learning-[]": ("strategy S = maxE(sa)[<=4]{}->{}: [] !Unsafe", "target E0802: reachability goals only"),
    "deadlock-E[]": ("E[] !deadlock", "target E0802: `deadlock` only in"),
    "deadlock-Pr": ("Pr[<=4](<> deadlock)", "target E0802: `deadlock` only in"),
    "observed-non-linear": ("strategy S = maxE(sa)[<=4]{sa * sa}->{}: <> Unsafe",
                            "target E0802: a discrete observation must be linear"),
    "fine-time-bound": ("Pr[<=0.123456789](<> Unsafe)", "target E0802: a time unit so fine"),
}
#: In the whole model only: the model's vocabulary.
AGREEMENT_MODEL: dict[str, tuple[str, str]] = {
    "model-symbolic": ("A[] mindist() < 3 * collision_distance imply isClose", "ok"),
    "model-location": ("E<> mindist() + Driving.location > sa * 1000000", "ok"),
    "ego-observed": ("strategy S = maxE(sa)[<=4]{x + 3, v / 2}->{x}: <> goal()", "ok"),
    "ego-observed-beyond-int32": ("strategy S = maxE(sa)[<=4]{x + 4503599627370497}->{}: <> goal()", "check E0801"),
    "truth-statistical": ("Pr[<=4]([] true_v >= 0 && !Unsafe)", "ok"),
    "truth-symbolic": ("E<> true_x > 20", "target E0802: the ground truth"),
    "prev": ("Pr[<=4](<> prev(v) > v)", "target E0802: `prev(...)` cannot be read"),
    "jerk": ("E<> jerk > 0 && acc == 0", "ok"),
    # decided by constants in rac verify (docs/verify.md, "A formula that reads no state"), written as they are
    "constant-control": ("strategy T = control: A[] true", "ok"),
    "constant-reach-control": ("strategy T = control: E<> 1 > 2", "ok"),
    "constant-leads-to": ("Unsafe --> true", "ok"),
    "constant-leads-from": ("false --> Unsafe", "ok"),
}


def _agreement(source: Path, whole: bool, utap: Utap, name: str) -> str:
    """What `rac check` and the UPPAAL target make of ``source``: "ok" after UPPAAL's parser accepted
    the model, "check CODE" or "target CODE: message"."""
    result = compile_file(source)
    errors = [d for d in result.diagnostics if d.severity.name == "ERROR"]
    if errors:
        return "check " + " ".join(sorted({d.code for d in errors}))
    automaton = result.raise_for_errors()
    try:
        model = (generate_uppaal_model(automaton, data=result.model_data) if whole else
                 generate_uppaal(automaton, source_name="agreement.ra", model_name="agreement.xml"))
    except UppaalError as refused:
        return "target " + str(refused)
    utap.validate(model.xml, model.queries, name)
    return "ok"


@pytest.mark.parametrize(("row", "whole"), [
    *((row, whole) for row in AGREEMENT for whole in (False, True)), *((row, True) for row in AGREEMENT_MODEL)],
    ids=lambda value: ("whole-model" if value else "alone") if isinstance(value, bool) else value)
def test_what_check_accepts_compiles(utap: Utap, row: str, whole: bool, tmp_path: Path) -> None:
    """Each query `rac check` accepts compiles, and UPPAAL's parser accepts the model, or it is one of
    the forms UPPAAL has no counterpart for (:data:`AGREEMENT`)."""
    query, expected = {**AGREEMENT, **AGREEMENT_MODEL}[row]
    if whole:
        source = tiny_source(tmp_path, "avoidable_obstacle", (query,))
    else:
        source = tmp_path / "agreement.ra"
        source.write_text(with_queries(driving_without_queries().replace("horizon 30", "horizon 4"), (query,)),
                          encoding="utf-8")
    got = _agreement(source, whole, utap, f"agreement-{row}")
    if expected.startswith("target "):
        code, words = expected.removeprefix("target ").split(": ", 1)
        assert got.startswith(f"target {code}: query `Q0`") and words in got, got
    else:
        assert got == expected, got


@pytest.mark.parametrize("update", ["r0 = r0 - r1", "r0 = r1 - r0", "r1 = -r0 + 2", "r0 = r0 - r1 - r1"])
def test_an_update_less_another_reward_is_a_double_uppaal_assigns(update: str, utap: Utap) -> None:
    """`r0 = r0 - r1` was emitted as the hybrid clocks' `r0 = r0 - r1`, a clock difference that UPPAAL refuses to
    assign to a clock ($Incompatible_types): a random automaton of test_random_automata_alone found it."""
    text = f"""automaton Less {{
    input b : bool
    reward r0, r1
    priority r0 > r1
    objective 2*r0 + r1
    sample every 1
    horizon 10
    initial location L0 {{ r0' == 1; r1' == 1 }}
    edge L0 -> L0 when b do {update}
}}
"""
    result = compile_text(text, "less.ra", analyse=False)
    assert result.automaton is not None, result.diagnostics
    model = generate_uppaal(result.automaton, source_name="less.ra", model_name="less.xml")
    assert "r0 = r0 - r1," not in model.xml and "r0 = r1 - r0," not in model.xml
    utap.validate(model.xml, model.queries, "less")
