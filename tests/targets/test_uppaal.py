"""The UPPAAL target: golden files, the shape UPPAAL's reader needs, the CLI, and the semantics.

* ``tests/golden/driving.xml`` and ``driving.q`` are the exact output for ``stdlib/driving.ra``;
* every emitted model is well-formed, in the element order UPPAAL's streaming reader needs
  (``docs/uppaal.md``), declares broadcast channels only, and its labels and queries keep to the
  lexer's rules (doubles with digits on both sides of the point, integers within int32);
* symbolic queries read no double and no hybrid clock, and every name a query uses is declared;
* ``rac compile --target uppaal`` writes the model and its ``.q`` file, both or neither;
* a small interpreter of the emitted network (broadcast synchronisation, committed locations,
  the Timer's period) runs random input sequences; the automaton's integer mirrors then equal
  ``rac.runtime.interpreter``'s rewards times the scale, its hybrid clocks the rewards, its location the
  runtime's location, sample after sample.
"""

from __future__ import annotations

import dataclasses
import itertools
import json
import random
import re
from fractions import Fraction
from pathlib import Path

import pytest
from conftest import run_rac
from engine_files import write_engine_file
from golden_files import assert_golden
from hypothesis import given, settings
from hypothesis import strategies as st
from lxml import etree

from rac import ir
from rac.cli.main import main
from rac.compiler import compile_file, compile_text
from rac.ir import expr as ie
from rac.ir import query as iq
from rac.lang.resources import stdlib_file
from rac.runtime.interpreter import RewardAutomaton
from rac.targets.uppaal.automaton import UppaalError, generate_uppaal, vocabulary
from rac.targets.uppaal.expr import (
    INT32_MAX,
    NotRepresentable,
    compare_significand,
    double_literal,
    int_literal,
    print_int_linear,
)

GOLDEN = Path(__file__).parents[1] / "golden"
DRIVING = stdlib_file("driving.ra")
REGENERATE = ("regenerate them with:  RAC_UPDATE_GOLDEN=1 PYTHONPATH=src python -m pytest tests/targets/test_uppaal.py"
              "  (then read the diff against docs/uppaal.md before committing)")

#: Exercises what driving.ra does not: names UPPAAL reserves (`E`, `sum`, `location`), an `int`
#: input, a rate that reads an input, fractional update coefficients, two `at end` clauses, and
#: every kind of query.
EDGE_CASES = """\
automaton Sum {
    input E : bool
    input sum : real in [0, 10]
    input lane : int in [0, 3]
    assume E imply sum > 1
    const HALF = 0.5
    const ON = true
    reward sa, pr
    objective 2*sa + pr
    sample every 0.2
    horizon 2
    initial location location { sa' == 1; pr' == sum / 2 - 1 }
    location Bad { sa' == -1; pr' == 0 }
    edge location -> Bad when E && lane == 2 do sa = HALF*sa - 3, pr = pr + sum
    edge Bad -> location when !E do pr = (sa + pr) / 3
    at end when sum < 2.5 do pr += 1
    at end when lane >= 1 do sa -= 2
    query Q1: A[] E imply Bad
    query Q2: A[] Bad imply 2*sa + pr <= 1.5
    query Q3: E<> time >= 1.5 && sum > 2
    query Q4: Pr[<=2](<> Bad && sa < -0.5) >= 0.5
    query Q5: E[<=2; 100](max: 2*sa + pr)
    query Q6: simulate[<=2; 5]{sa, pr, Bad, sum}
    query Q7: strategy S = control: A[] !Bad
    query Q8: strategy L = maxE(2*sa + pr)[<=2]{Sum.location, lane}->{sum, sa}: <> time >= 2 under S
    query Q9: Pr[<=1.9](<> sa * pr > 1)
    query Q10: E<> sa - pr == 0.25 && ON
    query Q11: E --> Bad
}
"""

#: No inputs, no end clause, no query; a zero rate everywhere for one reward.
NO_INPUTS = """\
automaton Clock {
    reward up, flat
    objective up
    sample every 1
    horizon 5
    initial location Only { up' == 2 }
}
"""


#: Names that collide with what the target adds (`count`, `Timer`, `Wait`, `iSa`, `SCALE`, `time`...).
CLASHES = """\
automaton Timer {
    input count : bool
    input time : real in [0, 4]
    input settled : bool
    const SCALE = 3
    reward sa, iSa
    objective sa + iSa
    sample every 0.5
    horizon 3
    initial location Wait { sa' == SCALE; iSa' == time }
    location Done { sa' == -1 }
    edge Wait -> Done when count && time > 1 do iSa = iSa + sa
    edge Done -> Wait when !count || settled
    at end when time >= 2 do sa = sa * 2
    query Q1: A[] count && time > 1 imply Done
    query Q2: E<> Timer.Done && iSa > 0.5
    query Q3: Pr[<=3](<> Done)
}
"""


def driving() -> ir.Automaton:
    return compile_file(DRIVING).raise_for_errors()


def automaton_of(text: str) -> ir.Automaton:
    return compile_text(text, "test.ra").raise_for_errors()


def emitted(automaton: ir.Automaton, name: str = "model.xml"):
    return generate_uppaal(automaton, source_name="test.ra", model_name=name)


ALL = {"driving": driving, "edge_cases": lambda: automaton_of(EDGE_CASES), "no_inputs": lambda: automaton_of(NO_INPUTS),
       "clashes": lambda: automaton_of(CLASHES)}


# ---------------------------------------------------------------- golden
def test_golden_files() -> None:
    model = generate_uppaal(driving(), source_name="stdlib/driving.ra", model_name="driving.xml")
    files = {GOLDEN / "driving.xml": model.xml, GOLDEN / "driving.q": model.queries}
    assert_golden(files, REGENERATE)


def test_generation_is_deterministic() -> None:
    assert emitted(driving()) == emitted(driving())


def test_the_papers_qh_reads_integer_mirrors() -> None:
    """Qh sums weighted mirrors: 10*iSa leaves int32 when sa reaches -30029.8 (rac check's worst case),
    so the sum is computed in doubles, exactly (integers below 2**53), in a condition of the model."""
    model = emitted(driving())
    queries = dict(re.findall(r"// (\w+)\n(.*)", model.queries))
    assert queries["Qh"] == "A[] Driving.Unsafe imply cond0()"
    assert "bool cond0() {\n    return 10.0 * iSa + 5.0 * iPr + iCo &lt;= 0.0;\n}" in model.xml
    assert queries["Qe"] == "A[] settled imply (isClose imply Driving.Unsafe)"


# ---------------------------------------------------------------- the shape UPPAAL reads
class Parsed:
    """An emitted model read back with lxml, with the names it declares."""

    def __init__(self, xml: str):
        self.root = etree.fromstring(xml.encode("utf-8"))
        self.declaration = self.root.findtext("declaration")
        code = re.sub(r"//[^\n]*", "", self.declaration)
        self.hybrids = set(re.findall(r"\w+", " ".join(re.findall(r"hybrid clock ([^;]*);", code))))
        self.doubles = set(re.findall(r"\bdouble\s+(\w+)", code))
        self.clocks = set(re.findall(r"(?<!hybrid )\bclock\s+(\w+)", code))
        self.globals = set()
        for match in re.finditer(r"^\s*(?:const\s+)?(?:broadcast chan|hybrid clock|clock|bool|int32_t|int|double|"
                                 r"int\[[^\]]*\])\s+([^;=\[]+)", code, re.MULTILINE):
            self.globals |= set(re.findall(r"\w+", match.group(1)))
        self.templates = {t.findtext("name"): t for t in self.root.findall("template")}
        self.locations = {name: {loc.findtext("name") for loc in t.findall("location")}
                          for name, t in self.templates.items()}
        system = re.sub(r"//[^\n]*", "", self.root.findtext("system"))
        self.processes = re.search(r"system\s+([^;]*);", system).group(1).replace(" ", "").split(",")
        self.queries = [(q.findtext("comment"), q.findtext("formula")) for q in self.root.iter("query")]

    def texts(self) -> list[str]:
        """Every piece of UPPAAL syntax: declarations, labels, system, formulas."""
        found = [self.declaration, self.root.findtext("system")]
        found += [label.text for label in self.root.iter("label")]
        found += [t.findtext("declaration") or "" for t in self.templates.values()]
        return found + [formula for _, formula in self.queries]


@pytest.fixture(scope="module", params=sorted(ALL))
def parsed(request) -> Parsed:
    return Parsed(emitted(ALL[request.param]()).xml)


def test_header_and_element_order(parsed: Parsed) -> None:
    xml = emitted(driving()).xml
    assert xml.startswith('<?xml version="1.0" encoding="utf-8"?>\n<!DOCTYPE nta PUBLIC '
                          "'-//Uppaal Team//DTD Flat System 1.6//EN' "
                          "'http://www.it.uu.se/research/group/darts/uppaal/flat-1_6.dtd'>\n<nta>")
    assert parsed.root.tag == "nta"
    tags = [child.tag for child in parsed.root]
    assert re.fullmatch(r"declaration,(template,)+system(,queries)?", ",".join(tags)), tags
    order = ["name", "parameter", "declaration", "location", "branchpoint", "init", "transition"]
    for template in parsed.templates.values():
        kinds = [child.tag for child in template]
        assert kinds == sorted(kinds, key=order.index), kinds
        assert kinds.count("name") == 1 and kinds.count("init") == 1
        for location in template.findall("location"):
            inner = [child.tag for child in location]
            assert inner[0] == "name" and inner[-1] in ("name", "label", "committed"), inner
            assert inner.count("committed") <= 1 and "urgent" not in inner


def test_ids_and_references(parsed: Parsed) -> None:
    ids = [element.get("id") for element in parsed.root.iter("location", "transition")]
    assert len(ids) == len(set(ids)) and all(ids)
    for template in parsed.templates.values():
        locations = {loc.get("id") for loc in template.findall("location")}
        assert template.find("init").get("ref") in locations
        for transition in template.findall("transition"):
            assert transition.find("source").get("ref") in locations
            assert transition.find("target").get("ref") in locations
            assert transition.get("controllable") == "false"
        names = [loc.findtext("name") for loc in template.findall("location")]
        assert len(names) == len(set(names))
    assert set(parsed.processes) == set(parsed.templates)


def test_only_broadcast_channels(parsed: Parsed) -> None:
    code = re.sub(r"//[^\n]*", "", parsed.declaration)
    declarations = re.findall(r"[^;]*\bchan\b[^;]*;", code)
    assert declarations and all(d.strip().startswith("broadcast chan") for d in declarations)
    syncs = {label.text[:-1] for label in parsed.root.iter("label") if label.get("kind") == "synchronisation"}
    channels = set(re.findall(r"\w+", declarations[0].replace("broadcast chan", "")))
    assert syncs <= channels


def test_literals_keep_to_the_lexer(parsed: Parsed) -> None:
    for text in parsed.texts():
        code = re.sub(r"//[^\n]*", "", text)
        assert not re.search(r"(?<![\w.])\.\d", code), code  # `.5`
        assert not re.search(r"\d\.(?!\d)", code), code  # `5.`
        for number in re.findall(r"(?<![\w.])\d+(?![\w.])", re.sub(r"\d+\.\d+(?:e-?\d+)?", "", code)):
            assert int(number) <= INT32_MAX, code


def test_no_16_bit_int_holds_a_count_beyond_its_range() -> None:
    """UPPAAL's `int` is int[-32768, 32767]; the automaton-alone model declared `const int STEPS` and
    `const int PERIOD`, so a run of 3600 s at 0.1 s (36,000 samples) or a time unit finer than the
    period by more than 32767 held numbers its type cannot (the whole model declared them `int32_t`)."""
    long = NO_INPUTS.replace("sample every 1\n    horizon 5", "sample every 0.1\n    horizon 3600")
    assert long != NO_INPUTS
    fine = NO_INPUTS[:-2] + "    query Q: Pr[<=0.00001](<> up > 1)\n}\n"
    for text in (long, fine):
        declaration = Parsed(emitted(automaton_of(text)).xml).declaration
        values = {name: int(value) for name, value in re.findall(r"\bint\s+(\w+)\s*=\s*(-?\d+)", declaration)}
        assert all(-32768 <= v <= 32767 for v in values.values()), values
        assert re.search(r"const int32_t (STEPS = 36000|PERIOD = 100000);", declaration), declaration


def test_formulas_are_single_lines(parsed: Parsed) -> None:
    for _, formula in parsed.queries:
        assert "\n" not in formula and formula == formula.strip()


QUERY_WORDS = {"A", "E", "imply", "true", "false", "Pr", "under", "strategy", "control", "maxE", "minE", "max",
               "min", "simulate", "deadlock", "fabs", "location", "and", "or", "not"}


def identifiers(formula: str) -> list[str]:
    without_numbers = re.sub(r"\d+\.\d+(?:e-?\d+)?", "", formula)
    return re.findall(r"(?<![\w.])[A-Za-z_]\w*(?:\.[A-Za-z_]\w*)?", without_numbers)


def is_symbolic(formula: str) -> bool:
    return bool(re.match(r"(A\[\]|E<>|E\[\]|A<>|strategy \w+ = control:)", formula)) or (
        "-->" in formula and not re.match(r"(Pr|E\[|simulate|strategy)", formula))


def test_symbolic_queries_read_no_double(parsed: Parsed) -> None:
    symbolic = [formula for _, formula in parsed.queries if is_symbolic(formula)]
    for formula in symbolic:
        names = {name.split(".")[0] for name in identifiers(formula)}
        assert not names & (parsed.hybrids | parsed.doubles), formula
        assert not re.search(r"\d\.\d", formula), formula  # no double literal either


def test_every_query_name_is_declared(parsed: Parsed) -> None:
    strategies = set()
    for _, formula in parsed.queries:
        defined = re.match(r"strategy (\w+) =", formula)
        names = identifiers(formula)
        for name in names:
            if defined and name == defined.group(1):
                continue
            if "." in name:
                process, member = name.split(".")
                assert process in parsed.processes, formula
                assert member == "location" or member in parsed.locations[process], formula
            elif name not in QUERY_WORDS and name not in strategies:
                assert name in parsed.globals, (name, formula)
        if defined:
            strategies.add(defined.group(1))


def test_the_edge_cases_translate_as_documented() -> None:
    queries = dict(Parsed(emitted(automaton_of(EDGE_CASES)).xml).queries)
    assert queries["Q1"] == "A[] settled imply (E_ imply Sum.Bad)"
    assert queries["Q2"] == "A[] Sum.Bad imply cond0()"  # 2.0 * iSa + iPr <= 15000.0: 2*iSa may leave int32
    # `time` is the sample counter: 1.5 s is sample 7.5, so at least sample 8 (the engine's k * 0.2 >= 1.5)
    assert queries["Q3"] == "E<> settled && (count >= 8 && sum_ > 20000)"
    assert queries["Q4"] == "Pr[<=20](<> Sum.Bad && sa < -0.5) >= 0.5"
    assert queries["Q5"] == "E[<=20;100](max: 2.0 * sa + pr)"  # doubles as the engine computes them
    assert queries["Q6"] == "simulate[<=20;5]{sa, pr, Sum.Bad, sum_ / 10000.0}"
    assert queries["Q7"] == "strategy S = control: A[] !Sum.Bad"
    assert queries["Q8"] == ("strategy L = maxE(2.0 * sa + pr)[<=20]{Sum.location, lane}->{sum_ / 10000.0, sa}: "
                             "<> count >= STEPS under S")  # the last sample
    assert queries["Q9"] == "Pr[<=19](<> sa * pr > 1.0)"
    assert queries["Q10"] == "E<> cond1() && true"  # iSa - iPr == 2500 in doubles: the difference may leave int32
    assert queries["Q11"] == "settled && E_ --> Sum.Bad"


def test_query_constants_round_exactly_on_integers() -> None:
    text = NO_INPUTS[:-2] + ("    query Q1: A[] up <= 0.00015\n    query Q2: E<> up < 0.00015\n"
                             "    query Q3: E<> up == 0.00015\n    query Q4: A[] up / 2 + flat >= 0.5\n}\n")
    queries = dict(Parsed(emitted(automaton_of(text)).xml).queries)
    assert queries == {"Q1": "A[] iUp <= 1", "Q2": "E<> iUp < 2", "Q3": "E<> false", "Q4": "A[] cond0()"}
    assert "return 1.0 * iUp + 2.0 * iFlat &gt;= 10000.0;" in emitted(automaton_of(text)).xml


def test_one_integer_times_a_constant_compares_the_integer_itself() -> None:
    # `2147483647 * up > 1` is `up > 1/2147483647`, on the mirror `iUp > 0`; compared as a product it
    # needed 2147483647 * 2147483647 >= 2**53 and was refused with E0801, though it is exact
    text = NO_INPUTS[:-2] + ("    query Q1: A[] 2147483647 * up > 1\n    query Q2: E<> 3 * up < 7\n"
                             "    query Q3: E<> -2147483647 * up >= 2147483647\n"
                             "    query Q4: E<> 4 * up == 0.0002\n}\n")
    queries = dict(Parsed(emitted(automaton_of(text)).xml).queries)
    assert queries == {"Q1": "A[] iUp > 0", "Q2": "E<> iUp < 23334", "Q3": "E<> iUp <= -10000", "Q4": "E<> false"}


def test_reserved_names_are_renamed() -> None:
    parsed = Parsed(emitted(automaton_of(EDGE_CASES)).xml)
    assert {"E_", "sum_", "lane", "sa", "pr", "iSa", "iPr"} <= parsed.globals
    assert parsed.locations["Sum"] == {"location_", "Bad"}
    assert "sum" not in parsed.globals and "E" not in parsed.globals


def test_time_unit_and_rates() -> None:
    xml = emitted(automaton_of(EDGE_CASES)).xml
    assert "// time unit: 0.1 s. A sample period (0.2 s) is PERIOD = 2 time units;" in xml
    assert "sa&#39; == 0.1 &amp;&amp; pr&#39; == 0.05*sum_ / 10000.0 - 0.1" in xml
    clock = Parsed(emitted(automaton_of(NO_INPUTS)).xml)
    assert "time unit: 1 s" in clock.declaration
    invariant = next(loc.findtext("label") for loc in clock.templates["Clock"].findall("location"))
    assert invariant == "up' == 2 && flat' == 0"


def test_model_block_sets_the_representation() -> None:
    model = _model_spec(base=10, exponent=2)
    automaton = dataclasses.replace(driving(), model=model)
    xml = emitted(automaton).xml
    assert "const int32_t SCALE = 100;" in xml and "(base 10, exponent 2)" in xml
    assert "iSa = iSa - 10000" in xml and "dgoal &lt; 200" in xml
    assert "A[] Driving.Unsafe imply cond0()" in xml and "return 10.0 * iSa + 5.0 * iPr + iCo &lt;= 0.0;" in xml


def _model_spec(base: int, exponent: int) -> ir.ModelSpec:
    return ir.ModelSpec(
        scenario="s.xml", scenario_path="s.xml", base=base, exponent=exponent, sense_period=Fraction(1, 10),
        decide_period=Fraction(1, 10), granularity=Fraction(1), actions=(), length=Fraction(4), width=Fraction(2),
        max_acceleration=Fraction(3), max_turn=Fraction(1), min_speed=Fraction(0), max_speed=Fraction(20),
        collision_distance=Fraction(1), comfort_acceleration=Fraction(1, 2), comfort_turn=Fraction(1, 2),
        bindings=())


def test_time_is_the_sample_counter() -> None:
    """A query reads `time` as the engine does, `k * C1` at sample `k`: the counter, not UPPAAL's clock.

    The clock flows between samples and after the horizon, so `A[] time <= 5` was false in UPPAAL
    (true in the engine), and `E<> time > 4.5` held between two samples where the engine's next
    sample is at 5 s."""
    text = NO_INPUTS.replace("sample every 1", "sample every 0.5")[:-2] + (
        "    query Q1: A[] time <= 5\n    query Q2: E<> time > 4.2\n    query Q3: A[] time + up >= 0\n"
        "    query Q4: E[<=5; 10](max: time)\n}\n")
    model = emitted(automaton_of(text))
    queries = dict(Parsed(model.xml).queries)
    assert queries["Q1"] == "A[] count <= STEPS"  # the counter never passes the last sample
    assert queries["Q2"] == "E<> count > 8"  # the first sample after 4.2 s: 4.5 s
    # mixed with a reward (a clock could not be): 5000 * count + iUp may leave int32, so in doubles
    assert queries["Q3"] == "A[] cond0()"
    assert "return 5000.0 * count + iUp >= 0.0;" in Parsed(model.xml).declaration
    assert queries["Q4"] == "E[<=10;10](max: count * 0.5)"  # the time unit is the period, 0.5 s


# ---------------------------------------------------------------- diagnostics
def codes(automaton: ir.Automaton) -> list[tuple[str, str]]:
    with pytest.raises(UppaalError) as failure:
        emitted(automaton)
    return [(d.code, d.message) for d in failure.value.diagnostics]


def test_a_threshold_beyond_every_held_integer_is_a_constant_truth(tmp_path: Path,
                                                                  capsys: pytest.CaptureFixture[str]) -> None:
    """Regression: `A[] sa < 1000000` compares the mirror with 10^10, which no int32 literal holds, and
    rac compile refused the file (E0801) though no mirror reaches it: the comparison is true, as rac's
    engine (exact on the integers) answers. So is `time > 1e9`, the sample counter against 10^10."""
    queries = ("    query Big: A[] sa < 1000000\n    query In: E<> sum > 300000\n"
               "    query Late: E<> time > 1000000000\n    query Low: A[] pr >= -1000000 && lane >= -1000000000\n")
    text = EDGE_CASES.replace("    query Q11: E --> Bad\n", queries)
    formulas = dict(Parsed(emitted(automaton_of(text)).xml).queries)
    assert formulas["Big"] == "A[] true" and formulas["Late"] == "E<> false"
    assert formulas["In"] == "E<> settled && false" and formulas["Low"] == "A[] settled imply true && true"
    # in a model, rac verify gives the truth the emitted model now states
    path = write_engine_file(tmp_path, "goal_ahead", {"Far": "A[] x < 100000000", "Beyond": "E<> x > 100000000"})
    assert main(["compile", "--target", "uppaal", str(path), "-o", str(tmp_path / "m.xml")]) == 0
    written = (tmp_path / "m.q").read_text(encoding="utf-8")
    assert "A[] true" in written and "E<> false" in written
    assert main(["verify", str(path), "--query", "Far", "--query", "Beyond", "--format", "json",
                 "-o", str(tmp_path / "out")]) == 1
    statuses = {r["name"]: r["status"] for r in json.loads(capsys.readouterr().out)["results"]}
    assert statuses == {"Far": "satisfied", "Beyond": "not satisfied"}


def test_a_mirror_compared_with_the_least_int32() -> None:
    """Regression: a mirror may hold -2147483648 (the int32 range check allows it), but no literal writes
    it, so `A[] sa >= -214748.3648` was E0801. The comparison is now made with its neighbour, exactly on
    integers; a sum of several integers is compared in doubles as before."""
    expected = {"A[] sa >= -214748.3648": "A[] true", "E<> sa < -214748.3648": "E<> false",
                "E<> sa <= -214748.3648": "E<> iSa < -2147483647", "E<> sa == -214748.3648": "E<> iSa < -2147483647",
                "E<> sa > -214748.3648": "E<> iSa >= -2147483647", "E<> sa != -214748.3648": "E<> iSa >= -2147483647",
                "E<> -sa >= 214748.3648": "E<> iSa < -2147483647"}
    for query, formula in expected.items():
        text = EDGE_CASES.replace("    query Q11: E --> Bad\n", f"    query T: {query}\n")
        assert dict(Parsed(emitted(automaton_of(text)).xml).queries)["T"] == formula, query
    text = EDGE_CASES.replace("    query Q11: E --> Bad\n", "    query T: E<> sa + pr == -214748.3648\n")
    model = emitted(automaton_of(text)).xml
    assert "return 1.0 * iSa + iPr == -2147483648.0;" in model  # the sum may be below: not rewritten


def test_rate_not_representable() -> None:
    text = NO_INPUTS.replace("up' == 2", "up' == 0.00001")
    (code, message), = codes(automaton_of(text))
    assert code == "E0801"
    assert message == ("reward rate `up' == 0.00001` in location `Only` is not representable in significands "
                       "at exponent 4")


def test_threshold_and_interval_not_representable() -> None:
    text = DRIVING.read_text(encoding="utf-8").replace("dgoal < 2", "dgoal < 0.00005")
    found = codes(automaton_of(text))
    assert [c for c, _ in found] == ["E0801"]
    assert "has no representable value in (0, 0.00005)" in found[0][1]


def test_a_huge_query_number_prints_short() -> None:
    """`A[] up < 1e300` printed its significand in full, a 305-digit E0801 message (it is `A[] true` now:
    no mirror reaches it); so did a sum too large for doubles and a discrete observation's number."""
    text = NO_INPUTS[:-2] + "    query Q: A[] 1e300 * up + flat < 5\n}\n"
    (code, message), = codes(automaton_of(text))
    assert code == "E0801"
    assert "too large to be computed exactly (2.14748e309… >= 2**53)" in message and len(message) < 200, message
    text = NO_INPUTS[:-2] + "    query Q: strategy S = maxE(up)[<=5]{up + 1e300}->{}: <> time >= 5\n}\n"
    (diagnostic,) = [d for d in compile_text(text, "test.ra").diagnostics if d.is_error]
    assert diagnostic.code == "E0801" and len(diagnostic.message) < 300, diagnostic.message
    assert "as the integer `up + 1e304`" in diagnostic.message and "its number 1e304 is beyond" in diagnostic.message


def test_query_not_expressible() -> None:
    text = NO_INPUTS[:-2] + ("    query Q1: A[] up * up < 4\n    query Q2: Pr[<=5](<> up > 1) > 0.5\n"
                             "    query Q3: A[] up < 1000000\n    query Q4: Pr[<=5; 100](<> up > 1) >= 0.5\n"
                             "    query Q5: A[] time * up < 4\n}\n")
    found = codes(automaton_of(text))
    assert [c for c, _ in found] == ["E0802", "E0802"]  # Q3 is `A[] true`: no mirror reaches 10^10
    assert "`>=` or `<=` only" in found[0][1]
    assert "drop `;N`" in found[1][1]
    # a symbolic query that computes with doubles calls a condition of the declarations
    text = NO_INPUTS[:-2] + "    query Q1: A[] up * up < 4\n    query Q2: A[] time * up < 4\n}\n"
    parsed = Parsed(emitted(automaton_of(text)).xml)
    assert dict(parsed.queries)["Q1"] == "A[] cond0()"
    assert "bool cond0() {\n    return iUp / 10000.0 * (iUp / 10000.0) < 4.0;\n}" in parsed.declaration
    # `time` is the sample counter, an integer, so a condition may read it (UPPAAL's clock it could not)
    assert dict(parsed.queries)["Q2"] == "A[] cond1()"
    assert "return count * 1.0 * (iUp / 10000.0) < 4.0;" in parsed.declaration


def test_a_time_bound_too_fine_for_int32_is_refused() -> None:
    """`Pr[<=0.123456789]` made the time unit 1e-9 s and the period 1e9 units (with a horizon of 5 s,
    5e9 units), past int32 where UPPAAL's lexer says $Overflow. Now the query gets E0802 and the unit
    stays the one the other durations need."""
    queries = "    query Q1: Pr[<=0.5](<> up > 1)\n    query Q2: Pr[<=0.123456789](<> up > 1)\n"
    found = codes(automaton_of(NO_INPUTS[:-2] + queries + "    query Q3: Pr[<=2e9](<> up > 1)\n}\n"))
    assert [c for c, _ in found] == ["E0802", "E0802"], found
    assert "the time bound 0.123456789 s needs a time unit so fine" in found[0][1]
    assert "the time bound 2000000000 s is 4000000000 time units of 0.5 s, beyond the 32-bit" in found[1][1]
    # the unit divides the bounds that fit: 0.5 s, so the period is 2 units
    parsed = Parsed(emitted(automaton_of(NO_INPUTS[:-2] + "    query Q1: Pr[<=0.5](<> up > 1)\n}\n")).xml)
    assert dict(parsed.queries)["Q1"] == "Pr[<=1](<> up > 1.0)"
    assert "const int32_t PERIOD = 2;" in parsed.declaration


@pytest.mark.parametrize("query", ["E[] !deadlock", "A<> deadlock", "deadlock --> Only", "Pr[<=2]([] !deadlock)",
                                   "simulate[<=2; 2]{deadlock}", "strategy S = control: A[] !deadlock",
                                   "strategy S = maxE(up)[<=2]{deadlock}->{}: <> time >= 2"])
def test_deadlock_outside_a_box_or_a_diamond_is_refused(query: str) -> None:
    """UTAP accepts `deadlock` in `A[] p` and `E<> p` only (`$Cannot_handle_this_deadlock_predicate`
    elsewhere); rac emitted such queries, which UPPAAL rejected. Now they get E0802."""
    (code, message), = codes(automaton_of(NO_INPUTS[:-2] + f"    query Q: {query}\n}}\n"))
    assert (code, message) == ("E0802", "query `Q` cannot be written over the UPPAAL model: UPPAAL reads "
                                        "`deadlock` only in `A[] p` and `E<> p` queries")


def test_deadlock_in_a_box_or_a_diamond_is_emitted() -> None:
    text = NO_INPUTS[:-2] + "    query Q1: A[] !deadlock\n    query Q2: E<> deadlock || up > 1\n}\n"
    queries = dict(Parsed(emitted(automaton_of(text)).xml).queries)
    assert queries == {"Q1": "A[] !deadlock", "Q2": "E<> deadlock || iUp > 10000"}, queries


def test_model_functions_need_the_full_model() -> None:
    automaton = dataclasses.replace(driving(), model=_model_spec(10, 4))
    collide = iq.QueryDecl("Qc", iq.PathQuery("E<>", ie.call("collide")), "E<> collide()")
    (code, message), = codes(dataclasses.replace(automaton, queries=(*automaton.queries, collide)))
    assert code == "E0802" and "`collide()` is a function of the scenario model" in message
    # Without such a query, an automaton with a model block is emitted alone.
    assert "system Timer, Driving, Environment;" in emitted(automaton).xml


# ---------------------------------------------------------------- the expression printer
def test_literals() -> None:
    assert [double_literal(Fraction(v)) for v in ("0.5", "100", "0.00001", "-2.25", "1e20")] == [
        "0.5", "100.0", "1.0e-5", "-2.25", "1.0e20"]
    assert int_literal(INT32_MAX) == "2147483647"
    with pytest.raises(NotRepresentable):
        int_literal(INT32_MAX + 1)
    with pytest.raises(NotRepresentable):
        int_literal(Fraction(1, 2))
    assert print_int_linear(Fraction(-1000000), [(Fraction(1), "iSa")]) == "iSa - 1000000"
    assert print_int_linear(Fraction(0), [(Fraction(1, 2), "iSa"), (Fraction(1, 3), "iPr")]) == "(3*iSa + 2*iPr) / 6"


@settings(max_examples=300, deadline=None)
@given(significand=st.integers(-10**6, 10**6), op=st.sampled_from(["<", "<=", ">", ">=", "==", "!="]),
       threshold=st.fractions(min_value=-100, max_value=100, max_denominator=10**6),
       exponent=st.integers(0, 4))
def test_significand_comparisons_are_exact(significand: int, op: str, threshold: Fraction, exponent: int) -> None:
    scale = 10**exponent
    text, _ = compare_significand("x", op, threshold, scale)
    got = eval(text.replace("true", "True").replace("false", "False"), {"x": significand})  # noqa: S307
    assert got == ir.compare(Fraction(significand, scale), op, threshold)


# ---------------------------------------------------------------- the command
def test_cli_writes_model_and_queries(tmp_path: Path) -> None:
    done = run_rac("compile", "--target", "uppaal", DRIVING, "-o", tmp_path / "out.xml")
    assert done.returncode == 0, done.stderr
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out.q", "out.xml"]
    model = generate_uppaal(driving(), source_name="driving.ra", model_name="out.xml")
    assert (tmp_path / "out.xml").read_text(encoding="utf-8") == model.xml
    assert (tmp_path / "out.q").read_text(encoding="utf-8") == model.queries
    assert "verifyta out.xml out.q" in model.queries


def test_cli_without_output_prints_the_model(capsys) -> None:
    assert main(["compile", "--target", "uppaal", str(DRIVING)]) == 0
    assert capsys.readouterr().out == generate_uppaal(driving(), source_name="driving.ra").xml


def test_cli_error_touches_neither_file(tmp_path: Path, capsys) -> None:
    source = tmp_path / "bad.ra"
    source.write_text(NO_INPUTS.replace("up' == 2", "up' == 0.00001"), encoding="utf-8")
    old = "// generated by rac: an earlier build"  # rac replaces only what it wrote (E0009 otherwise)
    for name in ("out.xml", "out.q"):
        (tmp_path / name).write_text(old, encoding="utf-8")
    assert main(["compile", "--target", "uppaal", str(source), "-o", str(tmp_path / "out.xml")]) == 1
    assert "error[E0801]" in capsys.readouterr().err
    assert [(tmp_path / n).read_text(encoding="utf-8") for n in ("out.xml", "out.q")] == [old, old]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["bad.ra", "out.q", "out.xml"]


def test_cli_unwritable_queries_touch_neither_file(tmp_path: Path, capsys) -> None:
    (tmp_path / "out.xml").write_text("old", encoding="utf-8")
    (tmp_path / "out.q").mkdir()
    assert main(["compile", "--target", "uppaal", str(DRIVING), "-o", str(tmp_path / "out.xml")]) == 2
    assert "error[E0009]: cannot write" in capsys.readouterr().err
    assert (tmp_path / "out.xml").read_text(encoding="utf-8") == "old"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out.q", "out.xml"]


def test_cli_refuses_a_q_output(tmp_path: Path, capsys) -> None:
    assert main(["compile", "--target", "uppaal", str(DRIVING), "-o", str(tmp_path / "model.q")]) == 2
    assert not list(tmp_path.iterdir())


def test_cli_json_diagnostics(tmp_path: Path, capsys) -> None:
    source = tmp_path / "bad.ra"
    source.write_text(NO_INPUTS.replace("up' == 2", "up' == 0.00001"), encoding="utf-8")
    assert main(["compile", "--target", "uppaal", "--format", "json", str(source), "-o", str(tmp_path / "o.xml")]) == 1
    assert '"code": "E0801"' in capsys.readouterr().out


# ---------------------------------------------------------------- semantics: run the emitted network
class C(int):
    """An UPPAAL integer: arithmetic stays integral, ``/`` truncates towards zero."""

    def _op(self, other, f):
        if isinstance(other, float):
            return f(float(self), other)
        return C(f(int(self), int(other)))

    def __add__(self, o):
        return self._op(o, lambda a, b: a + b)

    def __radd__(self, o):
        return self._op(o, lambda a, b: b + a)

    def __sub__(self, o):
        return self._op(o, lambda a, b: a - b)

    def __rsub__(self, o):
        return self._op(o, lambda a, b: b - a)

    def __mul__(self, o):
        return self._op(o, lambda a, b: a * b)

    def __rmul__(self, o):
        return self._op(o, lambda a, b: b * a)

    def __truediv__(self, o):
        if isinstance(o, float):
            return float(self) / o
        quotient = abs(int(self)) // abs(int(o))
        return C(quotient if (self >= 0) == (o > 0) else -quotient)

    def __neg__(self):
        return C(-int(self))


def python(expression: str) -> str:
    """An UPPAAL label as Python: literals as :class:`C`, ``&&``/``||``/``!`` as words, ``c ? a : b``."""
    ternary = re.fullmatch(r"\((.*)\) \? (.*) : (.*)", expression)
    if ternary:
        return f"({python(ternary.group(2))}) if ({python(ternary.group(1))}) else ({python(ternary.group(3))})"
    text = re.sub(r"(?<!\w)\d+\.\d+(?:e-?\d+)?|(?<!\w)\d+",
                  lambda m: m.group(0) if "." in m.group(0) else f"C({m.group(0)})", expression)
    text = text.replace("&&", " and ").replace("||", " or ")
    text = re.sub(r"!(?!=)", " not ", text)
    return re.sub(r"\btrue\b", "True", re.sub(r"\bfalse\b", "False", text))


def split_top(text: str) -> list[str]:
    parts, depth, start = [], 0, 0
    for i, ch in enumerate(text):
        depth += ch in "([" and 1 or (-1 if ch in ")]" else 0)
        if ch == "," and depth == 0:
            parts.append(text[start:i].strip())
            start = i + 1
    return [*parts, text[start:].strip()] if text.strip() else []


class Network:
    """A small interpreter of the emitted models: broadcast channels, committed locations, one
    period clock. Enough to run them sample by sample; not a general UPPAAL simulator."""

    def __init__(self, xml: str, rng: random.Random):
        parsed = Parsed(xml)
        self.rng = rng
        self.values: dict[str, object] = {}
        code = re.sub(r"//[^\n]*", "", parsed.declaration)
        for match in re.finditer(r"const \w+ (\w+)\[\d+\] = \{([^}]*)\};", code):
            self.values[match.group(1)] = [C(int(v)) for v in match.group(2).split(",")]
        for match in re.finditer(r"const (\w+) (\w+) = ([^;]*);", code):
            self.values[match.group(2)] = eval(python(match.group(3)), {"C": C})  # noqa: S307
        for match in re.finditer(r"^(bool|int32_t|int\[[^\]]*\]|hybrid clock|clock) ([^;]*);", code, re.MULTILINE):
            for name in re.findall(r"\w+", match.group(2)):
                self.values[name] = {"bool": False, "hybrid clock": 0.0, "clock": 0.0}.get(match.group(1), C(0))
        self.int32 = set(re.findall(r"\w+", " ".join(re.findall(r"int32_t ([^;=]*);", code))))
        declaration = parsed.declaration
        self.period = re.search(r"const int32_t (\w+) = \d+;  // time units per sample", declaration).group(1)
        self.scale = re.search(r"const int32_t (\w+) = \d+;  // the significand", declaration).group(1)
        self.time = re.search(r"clock (\w+);  // global time", declaration).group(1)
        self.processes = []
        for name in parsed.processes:
            template = parsed.templates[name]
            names = {loc.get("id"): loc.findtext("name") for loc in template.findall("location")}
            locations = {loc.findtext("name"): (loc.find("committed") is not None,
                                                loc.findtext("label[@kind='invariant']") or "")
                         for loc in template.findall("location")}
            edges = []
            for t in template.findall("transition"):
                labels = {label.get("kind"): label.text for label in t.findall("label")}
                edges.append((names[t.find("source").get("ref")], names[t.find("target").get("ref")], labels))
            local = (template.findtext("declaration") or "").replace("clock", "").replace(";", "").split()
            for clock in local:
                self.values[clock] = 0.0
                self.clock = clock  # the Timer's, the only template with a local clock
            self.processes.append({"name": name, "at": names[template.find("init").get("ref")],
                                   "locations": locations, "edges": edges})

    def eval(self, expression: str, scope: dict | None = None):
        return eval(python(expression), {"C": C, **self.values, **(scope or {})})  # noqa: S307

    def apply(self, assignment: str | None, scope: dict | None = None) -> None:
        for part in split_top(assignment or ""):
            if part.endswith("++"):
                self.values[part[:-2]] = self.values[part[:-2]] + C(1)
                continue
            target, value = part.split(" = ", 1)
            result = self.eval(value, scope)
            if target in self.int32:
                assert abs(result) <= INT32_MAX, (target, result)
            self.values[target] = result

    def enabled(self, process, sync: str | None):
        """Edges of ``process`` with this synchronisation (``None``: internal or sending) that are enabled,
        each with a select binding chosen at random among those that satisfy the guard."""
        found = []
        for source, target, labels in process["edges"]:
            if source != process["at"]:
                continue
            label = labels.get("synchronisation")
            if sync is None and label is not None and not label.endswith("!"):
                continue
            if sync is not None and label != sync:
                continue
            bindings = [{}]
            if "select" in labels:
                ranges = [re.fullmatch(r"(\w+) : int\[(\d+),(\d+)\]", s.strip()).groups()
                          for s in labels["select"].split(", ")]
                bindings = [dict(zip([r[0] for r in ranges], map(C, values)))
                            for values in itertools.product(*(range(int(r[1]), int(r[2]) + 1) for r in ranges))]
            bindings = [b for b in bindings if "guard" not in labels or self.eval(labels["guard"], b)]
            if bindings:
                found.append((target, labels, self.rng.choice(bindings)))
        return found

    def delay(self) -> None:
        """Let time pass up to the Timer's next deadline (its invariant `t <= PERIOD`)."""
        step = float(self.values[self.period]) - self.values[self.clock]
        for process in self.processes:
            invariant = process["locations"][process["at"]][1]
            for name, rate in re.findall(r"(\w+)' == ([^&]*?)(?: &&|$)", invariant):
                self.values[name] = self.values[name] + float(self.eval(rate)) * step
        self.values[self.clock] = self.values[self.clock] + step
        self.values[self.time] = self.values[self.time] + step

    def step(self) -> str | None:
        """Take one transition (delaying first when no process is committed); return its channel."""
        committed = [p for p in self.processes if p["locations"][p["at"]][0]]
        candidates = [(p, e) for p in (committed or self.processes) for e in self.enabled(p, None)]
        if not candidates:
            self.delay()
            candidates = [(p, e) for p in self.processes for e in self.enabled(p, None)]
        sender, (target, labels, binding) = self.rng.choice(candidates)
        sync = labels.get("synchronisation")
        receivers = []
        if sync is not None:
            for process in self.processes:
                if process is sender:
                    continue
                edges = self.enabled(process, sync[:-1] + "?")
                assert len(edges) <= 1, f"{process['name']} has two enabled edges on {sync}"
                receivers += [(process, edges[0])] if edges else []
        self.apply(labels.get("assignment"), binding)
        sender["at"] = target
        for process, (target, labels, binding) in receivers:
            self.apply(labels.get("assignment"), binding)
            process["at"] = target
        return sync[:-1] if sync else None


def run_network(automaton: ir.Automaton, seed: int) -> None:
    xml = emitted(automaton).xml
    network = Network(xml, random.Random(seed))
    runtime = RewardAutomaton(automaton)
    scale = int(network.values[network.scale])
    ra = network.processes[1]
    names = vocabulary(automaton)
    inputs: dict[str, object] = {}
    truncations = 0
    fractional = any(c.denominator != 1 for e in automaton.all_edges() for u in e.updates for _, c in u.value.terms)

    def compare(when: str) -> None:
        for reward, value in runtime.rewards.items():
            mirror = network.values[names.mirrors[reward]]
            tolerance = 1e-6 * max(1.0, abs(value * scale)) + (truncations if fractional else 0)
            assert abs(mirror - value * scale) <= tolerance, (when, reward, mirror, value)
            assert network.values[names.hybrids[reward]] == pytest.approx(value, abs=1e-9), (when, reward)
        assert ra["at"] == names.locations[runtime.location], when

    for _ in range(100_000):
        channel = network.step()
        if channel == "read":
            for item in automaton.inputs:
                if item.is_bool:
                    inputs[item.name] = bool(network.values[names.bools[item.name]])
                else:
                    inputs[item.name] = float(Fraction(int(network.values[names.significands[item.name]]), scale))
        elif channel == "sense":
            runtime.step(inputs)
            truncations += 1
            compare(f"sample {runtime.samples}")
        elif channel == "finish":
            runtime.end(inputs)
            compare("end")
            break
    else:
        raise AssertionError("the run did not end")
    assert runtime.samples == automaton.steps
    assert network.values[network.time] == pytest.approx(float(automaton.horizon / automaton.period) *
                                                         int(network.values[network.period]))


@pytest.mark.parametrize("seed", range(4))
def test_driving_mirrors_follow_the_runtime(seed: int) -> None:
    run_network(driving(), seed)


@pytest.mark.parametrize("seed", range(4))
def test_edge_case_mirrors_follow_the_runtime(seed: int) -> None:
    run_network(automaton_of(EDGE_CASES), seed)


def test_no_inputs_mirrors_follow_the_runtime() -> None:
    run_network(automaton_of(NO_INPUTS), 0)


@pytest.mark.parametrize("seed", range(2))
def test_clashing_names_mirrors_follow_the_runtime(seed: int) -> None:
    run_network(automaton_of(CLASHES), seed)


def test_clashing_names_are_kept_apart() -> None:
    parsed = Parsed(emitted(automaton_of(CLASHES)).xml)
    assert parsed.processes == ["Timer_", "Timer", "Environment"]
    assert {"count", "count_", "time", "time_", "settled", "settled_", "iSa", "iSa_", "iISa", "SCALE",
            "SCALE_"} <= parsed.globals
    assert parsed.locations["Timer"] == {"Wait", "Done"}
    assert parsed.locations["Timer_"] == {"Wait_", "Accrued", "Reading", "Ending", "Done_"}
    queries = dict(parsed.queries)
    assert queries["Q1"] == "A[] settled_ imply (count && time > 10000 imply Timer.Done)"
    assert queries["Q2"] == "E<> Timer.Done && iISa > 5000"
    assert queries["Q3"] == "Pr[<=6](<> Timer.Done)"
