"""Random bindings and queries, as a user writes them, in the emitted C and in the engine: one meaning.

tests/targets/test_emitted_c.py compiles the ``read_inputs()`` of the emitted whole model as C and
compares every input it computes with the engine's :class:`rac.engine.bindings.Bindings` on a few
hundred (previous, current) state pairs, for the bindings of fixed files. Here hypothesis writes the
bindings: ``.ra`` text of nested arithmetic (``+ - * /``, unary minus, negative and fractional
literals, parentheses), ``fabs``, ``abs``, ``sqrt``, ``fmin``, ``fmax``, ``prev(...)`` of numbers
and of conditions, the ego state, ``time``, the settings, ``mindist()`` and ``dist_goal()``, and
conditions over them (comparisons, ``&&``, ``||``, ``!``, ``imply``, ``==`` of two conditions,
``collide()``, ``offroad()``, ``goal()``). Each file is checked by ``rac check``'s compiler, emitted
by ``generate_uppaal_model`` (and validated with UPPAAL's parser when it is available), and its
inputs compared: the same bit for every boolean input, the same significand for every numeric one.

The queries likewise: random conditions and numbers over the automaton's names (inputs, rewards,
locations, ``Probe.location``) mixed with the model's, written as ``E<>``, ``A[]``, ``E[]``, ``A<>``,
``-->`` (symbolic: integer mirrors and significands, doubles hoisted into functions), ``Pr``,
``E[..](max:/min:)``, ``simulate`` and learning objectives (statistical: rewards as hybrid clocks) and
discrete observations (integers), printed by the UPPAAL target's query printer as C and compared with the
engine's :class:`rac.engine.evaluate.Evaluator` on random states, bit for bit
(test_emitted_c's :func:`compare_expressions`, whose states put comparisons next to their thresholds).
"""

from __future__ import annotations

import random
import re
import shutil
import tempfile
import warnings
from pathlib import Path

import numpy as np
import pytest
import utap as utap_module
from hypothesis import HealthCheck, assume, given, settings
from hypothesis import strategies as st
from test_emitted_c import Case, compare_expressions, compile_reader, load, print_expressions, run_binary, state_pairs
from tiny_scenarios import avoidable_obstacle

from rac.compiler import compile_text
from rac.engine.bindings import Bindings
from rac.engine.evaluate import EvaluationError, Evaluator, Frame
from rac.model.data import ModelRangeError
from rac.targets.uppaal.model import generate_uppaal_model, model_vocabulary

COMPILER = shutil.which("cc") or shutil.which("gcc")
pytestmark = pytest.mark.skipif(COMPILER is None, reason="no C compiler (cc or gcc) on PATH")

EGO = ("x", "y", "v", "acc", "head", "jerk", "turn")
SETTINGS = ("collision_distance", "length", "width", "max_speed", "max_acceleration", "comfort_turn", "max_turn")
LITERALS = ("0", "1", "2", "3", "0.5", "0.25", "1.5", "10", "0.1", "7", "0.003")


def _numbers(prev: bool) -> st.SearchStrategy[str]:
    leaves = st.one_of(st.sampled_from(EGO), st.sampled_from(LITERALS), st.just("time"), st.sampled_from(SETTINGS),
                       st.sampled_from(("mindist()", "dist_goal()")))

    def extend(inner: st.SearchStrategy[str]) -> st.SearchStrategy[str]:
        options = [
            st.builds(lambda op, a, b: f"({a} {op} {b})", st.sampled_from("+-*"), inner, inner),
            # division by a constant, or by a value kept away from 0
            st.builds(lambda a, b: f"{a} / {b}", inner, st.sampled_from(("3", "-7", "0.5", "-0.25", "10"))),
            st.builds(lambda a, b: f"{a} / (1 + fabs({b}))", inner, inner),
            inner.map(lambda a: f"-{a}" if not a.startswith("-") else f"-({a})"),
            st.builds(lambda f, a: f"{f}({a})", st.sampled_from(("fabs", "abs")), inner),
            inner.map(lambda a: f"sqrt(fabs({a}))"),
            st.builds(lambda f, a, b: f"{f}({a}, {b})", st.sampled_from(("fmin", "fmax")), inner, inner),
        ]
        return st.one_of(*options)

    numbers = st.recursive(leaves, extend, max_leaves=5)
    if not prev:
        return numbers
    return st.one_of(numbers, st.builds(lambda a, op, b: f"({a} {op} prev({b}))", numbers, st.sampled_from("+-"),
                                        _numbers(False)))


def _conditions() -> st.SearchStrategy[str]:
    numbers = _numbers(False)
    compare = st.builds(lambda a, op, b: f"{a} {op} {b}", numbers, st.sampled_from(["<", "<=", ">", ">=", "==", "!="]),
                        numbers)
    leaves = st.one_of(compare, compare, st.sampled_from(("collide()", "offroad()", "goal()", "true", "false")))

    def extend(inner: st.SearchStrategy[str]) -> st.SearchStrategy[str]:
        return st.one_of(
            st.builds(lambda a, op, b: f"({a} {op} {b})", inner, st.sampled_from(["&&", "||", "imply", "=="]), inner),
            inner.map(lambda a: f"!({a})"),
        )

    conditions = st.recursive(leaves, extend, max_leaves=4)
    return st.one_of(conditions, conditions.map(lambda a: f"prev({a})"),
                     st.builds(lambda a, b: f"({a} || prev({b}))", conditions, conditions))


AUTOMATON = """\
automaton Bound {{
    input b0, b1 : bool
    input n0, n1 : real in [-1000, 1000]
    reward r
    objective r
    sample every 0.5
    horizon 4
    initial location A {{ r' == 1 }}
    location B {{ r' == n0 / 1000 }}
    edge A -> B when b0 && n1 < 5
    edge B -> A when !b0 || b1
{block}}}
"""


@st.composite
def bindings(draw: st.DrawFn) -> tuple[str, ...]:
    return (f"b0 = {draw(_conditions())}", f"b1 = {draw(_conditions())}",
            f"n0 = {draw(_numbers(True))}", f"n1 = {draw(_numbers(True))}")


def _block(folder: Path, lines: tuple[str, ...]) -> str:
    tiny = avoidable_obstacle()
    if not (folder / f"{tiny.name}.xml").exists():
        tiny.write(folder)
    block = tiny.settings.model_block(f"{tiny.name}.xml", lines)
    return "".join(f"    {line}\n" for line in block.splitlines())


def compare(lines: tuple[str, ...], folder: Path, seed: int) -> int:
    """The emitted ``read_inputs()`` against the engine on state pairs; how many pairs were compared
    (0 where the file does not check, e.g. a warning-free value out of int32, or the engine refuses)."""
    text = AUTOMATON.format(block=_block(folder, lines))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        result = compile_text(text, str(folder / "bound.ra"))
    if not result.ok:
        errors = [d for d in result.diagnostics if d.severity.name == "ERROR"]
        # the only refusal the generator may meet: a setting-only binding beyond int32 (E0010, E0714, ...)
        assert all(d.code.startswith(("E07", "E00")) for d in errors), "\n".join(map(str, errors))
        return 0
    automaton = result.raise_for_errors()
    data = result.model_data
    model = generate_uppaal_model(automaton, data=data)
    located = utap_module.locate()
    if located.path is not None:
        utap_module.Utap(located.path, folder / "utap").validate(model.xml, model.queries, "bound")
    before, now, k = state_pairs(data, random.Random(seed), 60)
    frame = Frame(k=k, ego=now, prev=Frame(k=k - 1, ego=before))
    try:
        with np.errstate(all="ignore"):
            engine = Bindings(Evaluator(data, automaton), automaton, "the test").read(frame)
    except (EvaluationError, ModelRangeError):
        return 0  # a significand beyond int32: UPPAAL aborts there, the engine refuses
    binary = compile_reader(model.xml, automaton, folder, model_vocabulary(automaton, data=data))
    stdin = "".join(" ".join(map(str, [*b, kk - 1, *c, kk])) + "\n" for b, c, kk in zip(before, now, k))
    emitted = np.asarray([[int(v) for v in line.split()] for line in run_binary(binary, stdin)], dtype=np.int64)
    assert emitted.shape == engine.shape
    for column, item in enumerate(automaton.inputs):
        differ = np.flatnonzero(emitted[:, column] != engine[:, column])
        assert differ.size == 0, (
            f"input `{item.name}` ({lines[column]}): the emitted model reads {emitted[differ[0], column]}, the "
            f"engine {engine[differ[0], column]} (previous state {before[differ[0]].tolist()}, state "
            f"{now[differ[0]].tolist()}, k={k[differ[0]]}); {differ.size} of {len(k)} states differ")
    return len(k)


@settings(max_examples=25, deadline=None, derandomize=True, database=None,
          suppress_health_check=[HealthCheck.too_slow, HealthCheck.filter_too_much, HealthCheck.data_too_large])
@given(lines=bindings(), seed=st.integers(0, 2**16))
def test_random_bindings_read_alike_in_the_emitted_model_and_the_engine(lines: tuple[str, ...], seed: int) -> None:
    with tempfile.TemporaryDirectory(prefix="rac-bindings-") as folder:
        assume(compare(lines, Path(folder), seed) > 0)


# ---------------------------------------------------------------- queries
QUERY_LITERALS = ("0", "1", "2", "0.5", "0.0015", "20.0005", "3", "-4", "1000", "0.25", "-2.5", "0.49999999999999994",
                  "4503599627370497")


def _query_numbers(integers: bool, truth: bool = False) -> st.SearchStrategy[str]:
    """Numbers of a query; ``integers``: only values the model holds as integers (inputs' significands,
    mirrors, the ego, ``time``) and constants, so that symbolic comparisons stay exact; ``truth``: the
    true state too (statistical queries only)."""
    held = ("d", "gap", "r", "s", "x", "v", "acc", "head", "time", "Probe.location")
    doubles = ("mindist()", "dist_goal()", "collision_distance", "length", "sensor_error", "max_speed",
               *(("true_x", "true_v", "true_head") if truth else ()))
    leaves = st.one_of(st.sampled_from(held), st.sampled_from(QUERY_LITERALS),
                       *(() if integers else (st.sampled_from(doubles),)))

    def extend(inner: st.SearchStrategy[str]) -> st.SearchStrategy[str]:
        linear = [
            st.builds(lambda op, a, b: f"({a} {op} {b})", st.sampled_from("+-"), inner, inner),
            st.builds(lambda a, c: f"{a} * {c}", inner, st.sampled_from(("3", "-2", "0.5", "-0.25"))),
            st.builds(lambda a, c: f"{a} / {c}", inner, st.sampled_from(("3", "-7", "0.5", "10"))),
            inner.map(lambda a: f"-({a})"),
        ]
        if integers:
            return st.one_of(*linear)
        return st.one_of(*linear,
                         st.builds(lambda a, b: f"({a} * {b})", inner, inner),
                         st.builds(lambda f, a: f"{f}({a})", st.sampled_from(("fabs", "abs", "floor", "ceil", "round",
                                                                              "trunc")), inner),
                         inner.map(lambda a: f"sqrt(fabs({a}))"),
                         st.builds(lambda f, a, b: f"{f}({a}, {b})", st.sampled_from(("fmin", "fmax")), inner, inner))

    return st.recursive(leaves, extend, max_leaves=4)


def _query_conditions(truth: bool = False) -> st.SearchStrategy[str]:
    def compare(integers: bool) -> st.SearchStrategy[str]:
        numbers = _query_numbers(integers, truth and not integers)
        return st.builds(lambda a, op, b: f"{a} {op} {b}", numbers,
                         st.sampled_from(["<", "<=", ">", ">=", "==", "!="]), numbers)

    leaves = st.one_of(compare(True), compare(True), compare(False),
                       st.sampled_from(("near", "fast", "A", "B", "Probe.B", "collide()", "goal()", "true")))

    def extend(inner: st.SearchStrategy[str]) -> st.SearchStrategy[str]:
        return st.one_of(
            st.builds(lambda a, op, b: f"({a} {op} {b})", inner, st.sampled_from(["&&", "||", "imply"]), inner),
            inner.map(lambda a: f"!({a})"))

    return st.recursive(leaves, extend, max_leaves=4)


PROBE = """\
automaton Probe {{{{
    input near : bool
    input fast : bool
    input d    : real in [0, 1000]
    input gap  : real in [-50, 1000000]
    reward r, s
    objective r + 2 * s
    sample every 0.5
    horizon 4
    initial location A {{{{ r' == 1; s' == 0 }}}}
    location B {{{{ r' == -1; s' == 0.5 }}}}
    edge A -> B when near do r = r - 10
    edge B -> A when !near && d > 20
    model {{{{
        scenario "{{scenario}}"
        exponent 3
        decide_period 1
        action jerk in [-2, 2] step 2
        action turn in [-0.2, 0.2] step 0.2
        bind near = mindist() < 3 * collision_distance
        bind fast = v > prev(v)
        bind d    = dist_goal()
        bind gap  = fmin(mindist(), 1000000) - 0.0015
    }}}}
{queries}}}}}
"""


@st.composite
def queries(draw: st.DrawFn) -> tuple[str, ...]:
    lines = []
    forms = ["E<>", "A[]", "E[]", "A<>", "-->", "Pr<>", "Pr[]", "simulate", "max", "min", "learn"]
    for i, form in enumerate(draw(st.lists(st.sampled_from(forms), min_size=1, max_size=4))):
        if form in ("E<>", "A[]", "E[]", "A<>"):
            lines.append(f"query Q{i}: {form} {draw(_query_conditions())}")
        elif form == "-->":
            lines.append(f"query Q{i}: {draw(_query_conditions())} --> {draw(_query_conditions())}")
        elif form.startswith("Pr"):
            lines.append(f"query Q{i}: Pr[<=4]({form[2:]} {draw(_query_conditions(truth=True))})")
        elif form in ("max", "min"):
            lines.append(f"query Q{i}: E[<=4; 10]({form}: {draw(_query_numbers(False, truth=True))})")
        elif form == "learn":  # discrete observations: integers (linear in values held as integers)
            discrete = draw(st.lists(_query_numbers(True), min_size=1, max_size=2))
            lines.append(f"query Q{i}: strategy S{i} = maxE({draw(_query_numbers(False))})[<=4]"
                         f"{{{{{', '.join(discrete)}}}}}->{{{{x, v}}}}: <> {draw(_query_conditions())}")
        else:
            lines.append(f"query Q{i}: simulate[<=4; 1]{{{{{draw(_query_numbers(False, truth=True))}}}}}")
    return tuple(lines)


def compare_queries(lines: tuple[str, ...], folder: Path, seed: int) -> int:
    """The query expressions printed as C against the engine; how many were compared (0 where the file
    does not check)."""
    text = PROBE.format(queries="".join(f"    {line}\n" for line in lines))

    def write(target: Path) -> Path:
        scenario = avoidable_obstacle().write(target)
        path = target / "probe.ra"
        path.write_text(text.format(scenario=scenario.name), encoding="utf-8")
        return path

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        result = compile_text(write(folder).read_text(encoding="utf-8"), str(folder / "probe.ra"))
    if not result.ok:
        return 0
    # every query `rac check` accepts compiles (a discrete observation beyond int32 is refused by both)
    loaded = load(Case("random", write), folder)
    printed, _, printer = print_expressions(loaded.automaton, loaded.vocabulary)
    printed = [p for p in printed if re.fullmatch(r"Q\d+", p.query.name)]  # the file's, not the standard queries
    if not printed:
        return 0
    located = utap_module.locate()
    if located.path is not None:
        model = generate_uppaal_model(loaded.emitted, data=loaded.data)
        utap_module.Utap(located.path, folder / "utap").validate(model.xml, model.queries, "probe")
    with np.errstate(all="ignore"):
        mismatches, _ = compare_expressions(loaded, printed, printer, folder, random.Random(seed), set(), count=120)
    assert not mismatches, (f"{len(mismatches)} of {len(printed)} expressions differ:\n" + "\n".join(mismatches))
    return len(printed)


@settings(max_examples=25, deadline=None, derandomize=True, database=None,
          suppress_health_check=[HealthCheck.too_slow, HealthCheck.filter_too_much, HealthCheck.data_too_large])
@given(lines=queries(), seed=st.integers(0, 2**16))
def test_random_queries_read_alike_in_the_emitted_model_and_the_engine(lines: tuple[str, ...], seed: int) -> None:
    with tempfile.TemporaryDirectory(prefix="rac-queries-") as folder:
        assume(compare_queries(lines, Path(folder), seed) > 0)


def test_a_negated_location_index_is_the_engines_double(tmp_path: Path) -> None:
    """Found by the random queries: the printer wrote the location index as UPPAAL's integer, so
    `-Probe.location` in location 0 was the integer 0 (0.0 as a double) where the engine, which reads
    the index as a double, computes -0.0: `E[<=4; 10](max: 1 / -Probe.location)` was inf in the
    emitted model and -inf in rac's engine. The index is now printed as a double."""
    lines = ("query Q0: E[<=4; 10](max: 1 / -Probe.location)",
             "query Q1: simulate[<=4; 1]{{-Probe.location, -(Probe.location) * -1, Probe.location / 2}}")
    assert compare_queries(lines, tmp_path, seed=3) == 4
    text = PROBE.format(queries="".join(f"    {line}\n" for line in lines)).format(scenario="unused.xml")
    assert "1 / -Probe.location" in text


def test_round_is_cs_round(tmp_path: Path) -> None:
    """Found by the random queries' neighbourhood: the engine's `round()` was ``sign(x) * floor(|x| + 0.5)``,
    not C's (the emitted model's): 0.49999999999999994 became 1 (``|x| + 0.5`` rounds up to 1.0), 2**52 + 1
    became 2**52 + 2, and a negative zero lost its sign. The C functions and the engine now agree."""
    lines = ("query Q0: simulate[<=4; 1]{{round(time * 0 + 0.49999999999999994), round(-r * 0), "
             "round(time * 0 + 4503599627370497), round(-(time * 0 + 0.49999999999999994))}}",)
    assert compare_queries(lines, tmp_path, seed=3) == 4


def test_a_location_index_in_a_sum_beyond_int32_reaches_the_condition(tmp_path: Path) -> None:
    """`rac check` accepted these symbolic queries, but `rac compile --target uppaal` refused them with
    E0802 ("a location cannot be read in a condition computed with doubles"): a sum of mirrors that could
    leave int32 (`3 * r`) is computed in doubles, in a function of the declarations, which cannot name
    `Probe.location`. The function now receives the location index as a parameter (`cond0(Probe.location)`),
    UPPAAL's parser accepts the model, and the condition computes what rac's engine computes."""
    lines = ("query Q0: A[] 3 * r - Probe.location >= d / 4",
             "query Q1: E<> sqrt(Probe.location) > 0.5 && Probe.location * 2 - 5 * s < r",
             "query Q2: -Probe.location * 1000 + s * 7 < 2 * x --> B",
             "query Q3: strategy T = control: A[] Probe.location / 3 + 3 * r - 2 * s > -0.5")
    assert compare_queries(lines, tmp_path, seed=5) == 5  # Q2 has two state formulas
    text = PROBE.format(queries="".join(f"    {line}\n" for line in lines)).format(
        scenario=avoidable_obstacle().write(tmp_path).name)
    source = tmp_path / "located.ra"
    source.write_text(text, encoding="utf-8")
    result = compile_text(text, str(source))
    model = generate_uppaal_model(result.raise_for_errors(), data=result.model_data)
    assert "A[] settled imply cond0(Probe.location)" in model.queries
    assert "bool cond0(int32_t loc) {" in model.xml
