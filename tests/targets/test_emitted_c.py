"""The emitted whole model, compiled as C, against the engine: one model, one meaning.

The global declarations of the model that ``rac compile --target uppaal`` writes for a file with a
``model`` block are in the subset that is valid both in UPPAAL and in C (tests/targets/test_model_c.py checks
the scenario part against :mod:`rac.model.native`). These tests compile the whole declaration
section (channels, which C has no use for, left out; clocks and hybrid clocks as doubles) with the
system C compiler and compare what it computes with the engine. They run on every ``.ra`` file with
a ``model`` block under ``examples/`` and ``stdlib/`` (globbed, so new files are covered), the engine
test files of the tiny scenarios (tests/support/engine_files.py) and three files of this module:
:data:`SETTINGS_AUTOMATON` (bindings over settings held as significands), :data:`PROBE_AUTOMATON`
(queries over most of the query printer's branches, three of which it must refuse) and
:data:`TIME_UNIT_AUTOMATON` (a time unit finer than the sensing period).

- **Bindings.** The C program plays the Controller — ``keep_sample()`` on the previous sample's
  state, then ``read_inputs()`` on the current one — and prints every input, which must equal the
  value the engine's product (:mod:`rac.engine.product`) reads, on a few hundred (previous, current)
  state pairs per file: random states near the road, next to obstacles, around the goal and along
  runs, half of the pairs one ``sense_state()`` apart. ``test_bindings_of_the_emitted_model_are_the_engines``
  is the failing-first test of ``length 4.55555`` at exponent 4 (read as 4.5555 by both).
- **Query expressions.** Every expression of the file's queries and of the standard ones — state
  formulas of ``A[]``/``E<>``/``E[]``/``A<>``/``-->``/``control:`` (symbolic, with their ``settled``
  guard), formulas of ``Pr`` and of learning goals, numbers of ``E``, learning objectives,
  ``simulate`` and continuous observations (statistical), discrete observations (integers) — is
  printed over the emitted model's names (:func:`rac.targets.uppaal.model.model_vocabulary`) by
  :class:`rac.targets.uppaal.query.UppaalPrinter` with ``c_syntax=True`` and compiled as one C
  function, beside the conditions the printer hoisted into functions and shims for the
  process-qualified names (``Driving.Unsafe``, ``Driving.location``, ``Dynamics.true_x``). Random
  states set every global (sample, ego, location, inputs, mirrors, hybrid clocks, true state,
  ``time`` in time units, ``settled``), with the integer comparisons' operands put next to their
  thresholds, and each value is compared bit for bit with :class:`rac.engine.evaluate.Evaluator` on the
  same state: symbolic expressions over the integer mirrors and significands, statistical ones
  over the rewards as doubles (the hybrid clocks, set to mirror / SCALE). Every condition must take
  both values over the states, unless it reads ``deadlock`` or a model function the scenario pins
  (``collide()`` without obstacles, ``offroad()`` on a road narrower than the ego). The queries the
  printer refuses (:class:`QueryError`) must be exactly the expected ones (none in a real file); the
  model is emitted without them.
- **The ground truth.** The ODE of the emitted ``Dynamics`` template (its invariant) and its start
  (its edge's assignment), extracted from the XML, are compiled as C and integrated finely with RK4,
  period by period from the engine's truth, over action sequences that drive the speed and the
  acceleration into their bounds; the result must match the engine's truth
  (:func:`rac.engine.simulate.simulate`) within the error bound of two integrations of the same
  saturated ODE (:func:`truth_tolerances`), and the start exactly.
"""

from __future__ import annotations

import dataclasses
import html
import inspect
import itertools
import math
import random
import re
import shutil
import subprocess
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from fractions import Fraction
from pathlib import Path

import numpy as np
import pytest
from engine_files import write_engine_file
from test_model_c import random_states, simulated_states
from tiny_scenarios import TINY_SCENARIOS, avoidable_obstacle

from rac import ir
from rac.compiler import compile_file, compile_text
from rac.engine.bindings import Bindings
from rac.engine.evaluate import Evaluator, Frame
from rac.engine.explore import action_pairs
from rac.engine.simulate import simulate
from rac.ir import expr as ie
from rac.ir import query as iq
from rac.ir.query import query_exprs
from rac.ir.vocabulary import MODEL_NAMES, TRUE_STATE
from rac.lang import ast
from rac.lang.parser import parse_source, read_source
from rac.model import NativeModel, State
from rac.model.data import ModelData
from rac.targets.uppaal.declarations import C_PRELUDE
from rac.targets.uppaal.expr import QueryError
from rac.targets.uppaal.model import generate_uppaal_model, model_vocabulary
from rac.targets.uppaal.query import STATISTICAL, SYMBOLIC, UppaalPrinter, Vocabulary

COMPILER = shutil.which("cc") or shutil.which("gcc")
needs_cc = pytest.mark.skipif(COMPILER is None, reason="no C compiler (cc or gcc) on PATH")
CFLAGS = ("-O2", "-ffp-contract=off", "-fno-builtin", "-std=c99")

ROOT = Path(__file__).resolve().parents[2]

#: Bindings that read settings the model holds as significands (``length`` at exponent 4 is
#: 4.5555, not 4.55555), ``time``, ``prev`` of a number and of a condition, and model functions.
SETTINGS_AUTOMATON = """\
automaton Reader {{
    input near  : bool
    input gain  : bool
    input d     : real in [0, 1000]
    input len10 : real in [0, 1000]
    input late  : bool
    reward r
    objective r
    sample every 0.5
    horizon 4
    initial location A {{ r' == 1 }}
    location B {{ r' == 0 }}
    edge A -> B when near || late
    edge B -> A when !near && gain && d < 20 && len10 > 1
    model {{
        scenario "{scenario}"
        length 4.55555
        exponent 4
        decide_period 1
        granularity 0.25
        action jerk in [-2, 2] step 2
        action turn in [-0.2, 0.2] step 0.2
        bind near  = mindist() < 3 * collision_distance
        bind gain  = v > prev(v) || prev(acc > 0)
        bind d     = dist_goal()
        bind len10 = length * 10
        bind late  = time > 2.5 && fabs(turn) < comfort_turn * max_turn
    }}
}}
"""

#: Queries over most branches of the query printer: conditions computed with doubles in
#: symbolic queries (hoisted into functions), exact comparisons of significands and mirrors with
#: thresholds that are not whole significands, negative leading coefficients, the location index,
#: ``deadlock``, ``time`` (the sample counter) compared, as a number and mixed with a reward,
#: ``settled`` under ``[]`` and ``<>``, the true state, every math function, discrete observations
#: of mirrors, significands, `time` and constants, the location index in conditions computed with
#: doubles (passed to them as a parameter).
#: The last two are refused by the printer (:data:`PROBE_REFUSED`); the model is emitted without them.
PROBE_AUTOMATON = """\
automaton Probe {{
    input near : bool
    input fast : bool
    input d    : real in [0, 1000]
    input gap  : real in [-50, 1000000]
    reward r, s
    objective r + 2 * s
    sample every 0.5
    horizon 4
    initial location A {{ r' == 1; s' == 0 }}
    location B {{ r' == -1; s' == 0.5 }}
    edge A -> B when near do r = r - 10
    edge B -> A when !near && d > 20
    model {{
        scenario "{scenario}"
        exponent 3
        decide_period 1
        action jerk in [-2, 2] step 2
        action turn in [-0.2, 0.2] step 0.2
        bind near = mindist() < 3 * collision_distance
        bind fast = v > prev(v) || prev(acc > 0)
        bind d    = dist_goal()
        bind gap  = fmin(mindist(), 1000000) - 0.0015
    }}
    query Hoisted: A[] mindist() < 3 * collision_distance imply B
    query Inputs: E<> near && d <= 20.0005 && gap > -0.0015
    query Mixed: A[] r / 2 + s >= 0.5 || -r / 3 + s < 0.0015 || x > 30 || Probe.location == 1
    query Ego: E<> 2 * v - acc >= 1.0005 && head < 0.0005
    query Dead: A[] !deadlock
    query Lead: fast --> B && d > 20
    query Time: A<> time >= 2
    query TimeMixed: A[] time + r > 1
    query Chosen: A[] jerk > 0 imply turn >= 0 && acc > -1
    query TimeFn: E<> fmax(time, 1) > 2 && sqrt(fabs(v)) < 2
    query Abs: E[] abs(v - 5) < 3 && dist_goal() > length
    query Ctl: strategy T = control: E<> goal() && near
    query P1: Pr[<=4](<> fabs(true_x - x) + fabs(true_y - y) >= sensor_error && time + r > 1)
    query P2: Pr[<=4]([] r >= -10 && (near imply B) && d < 20.0005)
    query Exp: E[<=4; 10](min: sqrt(true_v * true_v + 1) - floor(r) + ceil(s) * round(d) - trunc(gap))
    query Exp2: E[<=4; 10](max: fmin(x, y) + fmax(time, dist_goal()))
    query Exp3: E[<=2; 10](max: jerk * v - fabs(turn))
    query Sim: simulate[<=4; 2]{{near, d, r, Probe.location, B, true_head - head, time, -gap / 3, true_acc * true_v}}
    query L: strategy S = minE(r - s)[<=4]{{B, Probe.location, x + 1.5}}->{{x, v}}: <> goal() && d <= 30
    query L2: strategy S2 = maxE(r)[<=4]{{r / 2 + s, -d, near, time}}->{{true_v, mindist()}}: <> time >= 4
    query LocationDouble: E<> sqrt(Probe.location) > 0.5
    query LocationSum: A[] 3 * r - Probe.location >= d / 4 || -Probe.location * 1000 + s * 7 < 2 * x
    query Prev: A[] prev(v) <= v
    query Truth: E<> true_x > 20
}}
"""
#: The probe's queries the printer refuses, and a word of the reason it gives.
PROBE_REFUSED = {"Prev": "prev(...)", "Truth": "ground truth"}

#: A time unit finer than the sensing period: the bound ``[<=2.9]`` makes the unit 0.1 s, so a sample
#: period of 0.3 s is PERIOD = 3 time units in the emitted model. The queries read ``time`` as the
#: sample counter whatever the unit: the engine reads it at sample ``k`` as ``k * C1`` (``k * 0.3``),
#: the statistical queries' ``count * 0.3`` must be the same double, and ``time >= 0.1`` is
#: ``count >= 1``.
TIME_UNIT_AUTOMATON = """\
automaton Slow {{
    input near : bool
    reward r
    objective r
    sample every 0.3
    horizon 3
    initial location A {{ r' == 1 }}
    location B {{ r' == -1 }}
    edge A -> B when near
    edge B -> A when !near
    model {{
        scenario "{scenario}"
        exponent 2
        decide_period 0.6
        action jerk in [-2, 2] step 2
        action turn in [-0.2, 0.2] step 0.2
        bind near = mindist() < 3 * collision_distance || time > 1.2
    }}
    query Early: A<> time >= 0.1
    query Clock: simulate[<=3; 1]{{time, r + time}}
    query Late: Pr[<=2.9](<> time + r > 2.5)
}}
"""


# ---------------------------------------------------------------- the files
def _has_model_block(path: Path) -> bool:
    return any(automaton.of(ast.ModelDecl) for automaton in parse_source(read_source(path)).automata)


#: Every `.ra` file with a `model` block under examples/ and stdlib/ (new files are covered).
MODEL_FILES = sorted(p for p in [*ROOT.glob("examples/**/*.ra"), *ROOT.glob("stdlib/**/*.ra")]
                     if _has_model_block(p))


@dataclass(frozen=True)
class Case:
    """One `.ra` file with a `model` block: ``write(folder)`` writes what it needs there and returns its path."""

    id: str
    write: Callable[[Path], Path]
    #: The queries whose expressions the printer refuses (QueryError), with a word of the reason;
    #: the model is emitted without them.
    refused: Mapping[str, str] = dataclasses.field(default_factory=dict)
    #: Model functions that are constant in the scenario by construction (beside ``collide()`` and
    #: ``mindist()`` without obstacles): conditions reading them may keep one value.
    pinned: frozenset[str] = frozenset()


def _in_scenario(text: str) -> Callable[[Path], Path]:
    def write(folder: Path) -> Path:
        scenario = avoidable_obstacle().write(folder)
        path = folder / "file.ra"
        path.write_text(text.format(scenario=scenario.name), encoding="utf-8")
        return path
    return write


CASES = (
    [Case(p.relative_to(ROOT).as_posix(), lambda folder, p=p: p) for p in MODEL_FILES]
    + [Case(f"tiny/{name}", lambda folder, name=name: write_engine_file(folder, name),
            pinned=frozenset({"offroad"}) if name == "narrow_road" else frozenset())  # narrower than the ego
       for name in TINY_SCENARIOS]
    + [Case("settings", _in_scenario(SETTINGS_AUTOMATON)),
       Case("probe", _in_scenario(PROBE_AUTOMATON), refused=PROBE_REFUSED),
       Case("time-unit", _in_scenario(TIME_UNIT_AUTOMATON))]
)
CASE_IDS = [case.id for case in CASES]


@dataclass
class Loaded:
    """A checked file, its model data and the emitted model (of the queries the printer accepts)."""

    automaton: ir.Automaton
    data: ModelData
    xml: str
    vocabulary: Vocabulary
    #: The automaton the model was emitted from: without the refused queries.
    emitted: ir.Automaton


def load(case: Case, folder: Path) -> Loaded:
    result = compile_file(case.write(folder))
    automaton = result.raise_for_errors()
    data = result.model_data
    emitted = dataclasses.replace(automaton, queries=tuple(q for q in automaton.queries if q.name not in case.refused))
    vocabulary = model_vocabulary(emitted, data=data)
    if case.refused:  # the refused queries must not change the names (e.g. the time unit)
        assert vocabulary == model_vocabulary(automaton, data=data)
    xml = generate_uppaal_model(emitted, data=data).xml
    return Loaded(automaton, data, xml, vocabulary, emitted)


# ---------------------------------------------------------------- C
def _declaration(xml: str) -> str:
    """The global declaration section, as text."""
    return html.unescape(re.search(r"<declaration>(.*?)</declaration>", xml, re.DOTALL).group(1))


def _as_c(declaration: str) -> str:
    """UPPAAL declarations as C: channels dropped, clocks and hybrid clocks as doubles."""
    lines = []
    for line in declaration.splitlines():
        if re.match(r"\s*(urgent\s+)?(broadcast\s+)?chan\b", line):
            continue
        line = re.sub(r"^(\s*)(hybrid\s+)?clock\b", r"\1double", line)
        lines.append(line)
    return "\n".join(lines)


def _compile(source_text: str, folder: Path, name: str) -> Path:
    source = folder / f"{name}.c"
    source.write_text(source_text, encoding="utf-8")
    binary = folder / name
    result = subprocess.run([COMPILER, *CFLAGS, "-o", str(binary), str(source), "-lm"], capture_output=True,
                            text=True, check=False)
    assert result.returncode == 0, result.stderr
    return binary


def run_binary(binary: Path, stdin: str) -> list[str]:
    return subprocess.run([str(binary)], input=stdin, capture_output=True, text=True, check=True,
                          timeout=60).stdout.splitlines()


# ---------------------------------------------------------------- states
def _near_goal(model: NativeModel, rng: random.Random, count: int) -> list[tuple[State, int]]:
    """States around the goal's centre during the goal interval (so that ``goal()`` holds in some)."""
    data = model.data
    if data.goal_count == 0:
        return []
    scale = data.scale
    low, high = max(data.goal_low, 0), min(data.goal_high, max(data.goal_low, 0) + 200)
    jerks, turns = data.action("jerk").values, data.action("turn").values
    states = []
    for i in range(count):
        # a third along the x axis, the straight road of the tiny scenarios, so that some are on the road
        along = i % 3 == 0
        values = (data.goal_cx / scale + rng.uniform(-4, 4),
                  data.goal_cy / scale + (rng.uniform(-0.5, 0.5) if along else rng.uniform(-4, 4)),
                  rng.uniform(0, model.max_speed_d), rng.uniform(-1, 1),
                  rng.uniform(-0.05, 0.05) if along else rng.uniform(-math.pi, math.pi))
        states.append((State(*(int(value * scale) for value in values), rng.choice(jerks), rng.choice(turns)),
                       rng.randrange(low, high + 1)))
    return states


def sample_states(data: ModelData, rng: random.Random, count: int) -> tuple[np.ndarray, np.ndarray]:
    """``count`` realistic (ego significands (n, 7), sample index (n,)) pairs: random states near the
    road, half of them next to an obstacle (tests/targets/test_model_c.py), states around the goal, and
    states along runs from the start."""
    model = NativeModel(data)
    states = (random_states(model, rng, count * 6 // 10) + _near_goal(model, rng, count // 5)
              + simulated_states(model, rng, runs=2, steps=count // 10))
    rng.shuffle(states)
    ego = np.asarray([list(state) for state, _ in states], dtype=np.int64)
    return ego, np.asarray([k for _, k in states], dtype=np.int64)


def state_pairs(data: ModelData, rng: random.Random, count: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(previous ego, current ego, current k): the current state is ``sense_state()`` of the previous one
    (its actions kept or changed) in half of the pairs, an unrelated state in the others."""
    model = NativeModel(data)
    before, k = sample_states(data, rng, count)
    k = np.maximum(k, 0) + 1
    now, _ = sample_states(data, rng, len(k))
    jerks, turns = data.action("jerk").values, data.action("turn").values
    for row in range(len(k)):
        if row % 2 == 0:
            sensed = model.sense(State(*(int(v) for v in before[row])))
            now[row] = [*sensed[:5], rng.choice(jerks), rng.choice(turns)] if row % 4 == 0 else list(sensed)
    return before, now, k


def _pinned(case: Case, data: ModelData) -> set[str]:
    """The model functions that are constant in this scenario by construction."""
    return set(case.pinned) | ({"collide", "mindist"} if data.obstacle_count == 0 else set())


def _may_be_constant(expr: ie.Expr, pinned: set[str]) -> bool:
    """Whether a condition may keep one value: it reads ``deadlock`` or a pinned model function."""
    return any((isinstance(node, ie.Call) and node.name in pinned)
               or (isinstance(node, ie.Ref) and node.kind is ie.RefKind.DEADLOCK) for node in ie.walk(expr))


def _reads_state(expr: ie.Expr) -> bool:
    """Whether a number depends on the state (not only on settings and constants)."""
    def varies(node: ie.Expr) -> bool:
        if isinstance(node, ie.Call):
            return True
        return isinstance(node, ie.Ref) and (not node.is_model or node.model.kind != "setting")
    return any(varies(node) for node in ie.walk(expr))


# ---------------------------------------------------------------- 1. the bindings
MAIN = r"""
#include <stdio.h>

int main(void) {
    long long in[16];
    while (scanf("%lld %lld %lld %lld %lld %lld %lld %lld %lld %lld %lld %lld %lld %lld %lld %lld",
                 &in[0], &in[1], &in[2], &in[3], &in[4], &in[5], &in[6], &in[7],
                 &in[8], &in[9], &in[10], &in[11], &in[12], &in[13], &in[14], &in[15]) == 16) {
        x = (int32_t)in[0]; y = (int32_t)in[1]; v = (int32_t)in[2]; acc = (int32_t)in[3];
        head = (int32_t)in[4]; jerk = (int32_t)in[5]; turn = (int32_t)in[6]; count = (int32_t)in[7];
        KEEP_SAMPLE
        x = (int32_t)in[8]; y = (int32_t)in[9]; v = (int32_t)in[10]; acc = (int32_t)in[11];
        head = (int32_t)in[12]; jerk = (int32_t)in[13]; turn = (int32_t)in[14]; count = (int32_t)in[15];
        READ_INPUTS();
        PRINT_INPUTS();
    }
    return 0;
}
"""


def compile_reader(xml: str, automaton, folder: Path, vocabulary: Vocabulary | None = None) -> Path:
    """A C program: per line, a previous and a current state; it prints every input after reading.
    ``vocabulary`` (default: :func:`model_vocabulary` of ``automaton``) names the inputs in the model."""
    vocabulary = vocabulary or model_vocabulary(automaton)
    declaration = _declaration(xml)
    inputs = [item.name for item in automaton.inputs]
    functions = re.findall(r"^void (\w+)\(\)", declaration, re.MULTILINE)
    keep = [f"{f}();" for f in functions if f.startswith("keep_sample")]
    read = next(f for f in functions if f.startswith("read_inputs"))
    names = {**vocabulary.bools, **vocabulary.significands}  # `collide` is `collide_` in the model
    prints = " ".join(f'printf("%lld ", (long long){names[name]});' for name in inputs) + ' printf("\\n");'
    main = (MAIN.replace("KEEP_SAMPLE", " ".join(keep)).replace("READ_INPUTS", read)
            .replace("PRINT_INPUTS();", prints))
    return _compile(C_PRELUDE + _as_c(declaration) + "\n" + main, folder, "reader")


def check_bindings(automaton, data: ModelData, xml: str, folder: Path, before: np.ndarray, now: np.ndarray,
                   k: np.ndarray, pinned: set[str]) -> None:
    """The inputs ``read_inputs()`` computes on (``before``, ``now``) equal the engine's; every condition
    took both values (unless it reads a function the scenario pins)."""
    binary = compile_reader(xml, automaton, folder, model_vocabulary(automaton, data=data))
    lines = "".join(" ".join(map(str, [*b, kk - 1, *c, kk])) + "\n" for b, c, kk in zip(before, now, k))
    emitted = np.asarray([[int(v) for v in line.split()] for line in run_binary(binary, lines)], dtype=np.int64)
    frame = Frame(k=k, ego=now, prev=Frame(k=k - 1, ego=before))
    engine = Bindings(Evaluator(data, automaton), automaton, "the test").read(frame)
    assert emitted.shape == engine.shape
    bindings = {b.input: b.expr for b in automaton.model.bindings}
    for column, item in enumerate(automaton.inputs):
        differ = np.flatnonzero(emitted[:, column] != engine[:, column])
        assert differ.size == 0, (
            f"input `{item.name}` (bind {item.name} = {bindings[item.name]}): the emitted model reads "
            f"{emitted[differ[0], column]}, the engine {engine[differ[0], column]} (previous state "
            f"{before[differ[0]].tolist()}, state {now[differ[0]].tolist()}, k={k[differ[0]]}); "
            f"{differ.size} of {len(k)} states differ")
        # the sample exercised both outcomes of every condition the scenario lets vary
        if item.is_bool and not _may_be_constant(bindings[item.name], pinned):
            assert set(engine[:, column]) == {0, 1}, item.name
        if not item.is_bool and _reads_state(bindings[item.name]):
            assert len(set(engine[:, column])) > len(k) // 4, item.name


def random_pairs(data, rng: np.random.Generator, n: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``n`` (previous ego, current ego, k) triples near the road, with actions from the grid."""
    start = np.asarray([data.ego_x, data.ego_y, data.ego_v, data.ego_acc, data.ego_head, 0, 0],
                       dtype=np.int64)
    scale = data.scale
    jerks, turns = np.asarray(data.action("jerk").values), np.asarray(data.action("turn").values)

    def states() -> np.ndarray:
        ego = np.tile(start, (n, 1))
        ego[:, 0] += rng.integers(-5 * scale, 60 * scale, n)
        ego[:, 1] += rng.integers(-3 * scale, 3 * scale, n)
        ego[:, 2] = rng.integers(0, 12 * scale, n)
        ego[:, 3] = rng.integers(-3 * scale, 3 * scale, n)
        ego[:, 4] = rng.integers(-scale // 2, scale // 2, n)
        ego[:, 5] = rng.choice(jerks, n)
        ego[:, 6] = rng.choice(turns, n)
        return ego

    k = rng.integers(1, 9, n)
    return states(), states(), k


@needs_cc
def test_bindings_of_the_emitted_model_are_the_engines(tmp_path: Path) -> None:
    """The failing-first test of issue 9: ``len10 = length * 10`` with ``length 4.55555`` at exponent 4."""
    tiny = avoidable_obstacle()
    scenario = tiny.write(tmp_path)
    result = compile_text(SETTINGS_AUTOMATON.format(scenario=scenario.name), str(tmp_path / "reader.ra"))
    automaton = result.raise_for_errors()
    data = result.model_data
    model = generate_uppaal_model(automaton, data=data)
    before, now, k = random_pairs(data, np.random.default_rng(7), 400)
    check_bindings(automaton, data, model.xml, tmp_path, before, now, k, set())


@needs_cc
@pytest.mark.parametrize("case", CASES, ids=CASE_IDS)
def test_every_binding_of_every_file(case: Case, tmp_path: Path) -> None:
    loaded = load(case, tmp_path)
    before, now, k = state_pairs(loaded.data, random.Random(f"bindings {case.id}"), 300)
    check_bindings(loaded.automaton, loaded.data, loaded.xml, tmp_path, before, now, k,
                   _pinned(case, loaded.data))


# ---------------------------------------------------------------- 2. the query expressions
@dataclass(frozen=True)
class Printed:
    """One expression of a query, printed as C over the emitted model's names."""

    query: iq.QueryDecl
    role: str  # where it stands in the query: "A[]", "Pr", "max", "simulate", "discrete", ...
    expr: ie.Expr
    dialect: str  # SYMBOLIC (integers: mirrors and significands) or STATISTICAL (rewards as hybrid clocks)
    box: bool | None  # a state formula under [] (None: not a state formula)
    c: str
    kind: str  # the C type of its value: "bool", "double" or "int"

    @property
    def settled(self) -> bool:
        """A state formula reading an input is guarded by ``settled`` (docs/uppaal.md)."""
        return self.box is not None and any(r.kind is ie.RefKind.INPUT for r in ie.refs(self.expr))


def _roles(query: iq.Query) -> list[tuple[str, ie.Expr, str, str, bool | None]]:
    """Every expression of a query: (role, expression, how it is printed, dialect, box)."""
    if isinstance(query, iq.PathQuery):
        return [(query.quantifier, query.expr, "state", SYMBOLIC, query.quantifier in ("A[]", "E[]"))]
    if isinstance(query, iq.LeadsToQuery):
        return [("-->", query.left, "state", SYMBOLIC, False), ("-->", query.right, "state", SYMBOLIC, False)]
    if isinstance(query, iq.ControlStrategy):
        return [(f"control: {query.goal}", query.expr, "state", SYMBOLIC, query.goal == "A[]")]
    if isinstance(query, iq.ProbabilityQuery):
        return [(f"Pr {query.path}", query.expr, "state", STATISTICAL, query.path == "[]")]
    if isinstance(query, iq.ExpectationQuery):
        return [(query.aggregate, query.expr, "extreme", STATISTICAL, None)]
    if isinstance(query, iq.SimulateQuery):
        return [("simulate", e, "any", STATISTICAL, None) for e in query.exprs]
    assert isinstance(query, iq.LearnStrategy), query
    return [(query.optimise, query.objective, "number", STATISTICAL, None),
            *(("discrete", e, "discrete", SYMBOLIC, None) for e in query.discrete),
            *(("continuous", e, "any", STATISTICAL, None) for e in query.continuous),
            (f"{query.optimise} {query.path}", query.expr, "state", STATISTICAL, query.path == "[]")]


def print_expressions(automaton: ir.Automaton, vocabulary: Vocabulary
                      ) -> tuple[list[Printed], dict[str, list[str]], UppaalPrinter]:
    """Every expression of the file's and the standard queries printed as C, the refused ones (query
    name -> the printer's reason for each of its refused expressions), and the printer (its hoisted
    conditions)."""
    counter = itertools.count()
    printer = UppaalPrinter(vocabulary, fresh=lambda base: f"rac_test_{base}{next(counter)}", c_syntax=True)
    printed: list[Printed] = []
    refused: dict[str, list[str]] = {}
    for decl in automaton.queries + automaton.standard_queries:
        roles = _roles(decl.query)
        assert len(roles) == len(query_exprs(decl.query)), decl.text  # no expression left out
        for role, expr, how, dialect, box in roles:
            try:
                if how == "state":
                    text = printer.state(expr, dialect, box)[0]
                elif how == "number":
                    text = printer.number(expr, STATISTICAL)[0]
                elif how == "extreme":  # E[..](max: e): the period after a decision left out
                    text = printer.extreme(expr, role)[0]
                elif how == "any":
                    text = printer.any(expr)
                else:
                    text = printer.discrete(expr)
            except QueryError as exc:
                refused.setdefault(decl.name, []).append(str(exc))
                continue
            kind = "bool" if expr.type == ie.BOOL else "int" if how == "discrete" else "double"
            printed.append(Printed(decl, role, expr, dialect, box, text, kind))
    return printed, refused, printer


QUERY_MAIN = r"""
#include <stdio.h>
#include <stdlib.h>

static long long read_int(void) {
    long long value;
    if (scanf("%lld", &value) != 1) {
        exit(0);
    }
    return value;
}

static double read_double(void) {
    double value;
    if (scanf("%lf", &value) != 1) {
        exit(1);
    }
    return value;
}

int main(void) {
    int32_t location;
    for (;;) {
READ
PRINT
        printf("\n");
    }
    return 0;
}
"""


def compile_expressions(loaded: Loaded, printed: list[Printed], printer: UppaalPrinter, folder: Path) -> Path:
    """One C program: the emitted declarations, shims for the process-qualified names, the hoisted
    conditions and one function per expression; ``main`` reads states (:func:`_state_lines`) and
    prints every expression's value per state."""
    v, automaton = loaded.vocabulary, loaded.emitted
    model = v.model
    locations = [v.locations[loc.name] for loc in automaton.locations]
    true_names = [MODEL_NAMES[name].uppaal for name in TRUE_STATE]
    parts = [C_PRELUDE, _as_c(_declaration(loaded.xml)), "",
             "// ---- the processes' names that queries read",
             f"struct {{ {' '.join(f'bool {name};' for name in locations)} int32_t location; }} {v.process};",
             # the engine's states are never the model's initial state, before the Dynamics sets the truth
             f"struct {{ double {', '.join(true_names)}; bool {model.running}; }} {model.dynamics}"
             f" = {{ .{model.running} = true }};",
             # the engine's states are never the period after a decision (the Timer waiting at a decision
             # sample, where jerk and turn already show the new choice): its guard must let them all through
             f"struct {{ bool {model.wait}; }} {model.timer} = {{ false }};"]
    if any(re.search(r"\bdeadlock\b", p.c) for p in printed):
        parts.append("bool deadlock = false;  // the model never deadlocks")
    parts.append("// ---- the conditions the printer hoisted")
    parts += [f"bool {c.name}({c.signature or 'void'}) {{ return {c.body}; }}" for c in printer.conditions.values()]
    parts.append("// ---- one function per expression")
    ctype = {"bool": "bool", "double": "double", "int": "long long"}
    for i, p in enumerate(printed):
        parts.append(f"// {p.query.name} ({p.role}): {p.query.text}")
        parts.append(f"static {ctype[p.kind]} e{i}(void) {{ return {p.c}; }}")
    read = ["count = (int32_t)read_int();",
            *(f"{name} = (int32_t)read_int();" for name in ("x", "y", "v", "acc", "head", "jerk", "turn")),
            "location = (int32_t)read_int();",
            f"{v.process}.location = location;",
            *(f"{v.process}.{name} = location == {i};" for i, name in enumerate(locations))]
    for item in automaton.inputs:
        read.append(f"{v.bools[item.name]} = read_int() != 0;" if item.is_bool
                    else f"{v.significands[item.name]} = (int32_t)read_int();")
    for reward in automaton.rewards:
        read += [f"{v.mirrors[reward]} = (int32_t)read_int();", f"{v.hybrids[reward]} = read_double();"]
    read += [f"{model.dynamics}.{name} = read_double();" for name in true_names]
    read += ["time = read_double();", f"{v.settled} = read_int() != 0;"]  # the clock: no query reads it
    formats = {"bool": ('"%d "', "(int)"), "double": ('"%.17e "', ""), "int": ('"%lld "', "")}
    prints = [f"printf({formats[p.kind][0]}, {formats[p.kind][1]}e{i}());" for i, p in enumerate(printed)]
    main = (QUERY_MAIN.replace("READ", "\n".join(f"        {line}" for line in read))
            .replace("PRINT", "\n".join(f"        {line}" for line in prints)))
    return _compile("\n".join(parts) + "\n" + main, folder, "expressions")


@dataclass
class QueryStates:
    """Random states of the product: everything a query expression reads."""

    k: np.ndarray
    ego: np.ndarray
    location: np.ndarray
    inputs: dict[str, np.ndarray]  # bool, or int significands
    mirrors: dict[str, np.ndarray]
    truth: np.ndarray  # (n, 5)
    settled: np.ndarray

    @property
    def n(self) -> int:
        return len(self.k)


#: A comparison over values held as integers: ``Σ a·h + b op 0`` with integer ``a`` (by the value's
#: key: ("input", name), ("reward", name), ("ego", column) or ("time", "") for the sample index) and ``b``.
Boundary = tuple[tuple[tuple[tuple[str, str], int], ...], int]


def _settable(ref: ie.Ref, scale: int, period: Fraction) -> tuple[tuple[str, str], Fraction] | None:
    """The key of the integer a state holds ``ref`` in, and the value of one unit (None: not settable)."""
    if ref.kind is ie.RefKind.INPUT:
        return ("input", ref.name), Fraction(1, scale)
    if ref.kind is ie.RefKind.REWARD:
        return ("reward", ref.name), Fraction(1, scale)
    if ref.is_model and ref.model.kind == "ego":
        return ("ego", str(ref.index)), Fraction(1, scale)
    if ref.is_model and ref.model.kind == "time":
        return ("time", ""), period
    return None


def boundaries(printed: list[Printed], scale: int, period: Fraction) -> list[Boundary]:
    """Every comparison of the expressions that is linear in values a state holds as integers."""
    found: list[Boundary] = []
    for p in printed:
        for node in ie.walk(p.expr):
            if not isinstance(node, ie.Compare) or node.linear is None or node.linear.is_constant:
                continue
            held = [(_settable(ref, scale, period), coefficient) for ref, coefficient in node.linear.terms]
            if any(h is None for h, _ in held):
                continue
            terms = [(key, coefficient * unit) for (key, unit), coefficient in held]
            multiple = math.lcm(node.linear.const.denominator, *(c.denominator for _, c in terms))
            boundary = (tuple((key, int(c * multiple)) for key, c in terms), int(node.linear.const * multiple))
            if boundary not in found:
                found.append(boundary)
    return found


def query_states(loaded: Loaded, printed: list[Printed], rng: random.Random, count: int) -> QueryStates:
    """Realistic ego states (:func:`sample_states`) with random locations, inputs, rewards, true states
    near the sensed ones and ``settled`` mostly true. In most states, about half the comparisons of
    values held as integers (:func:`boundaries`) are put next to their thresholds (on both sides, and
    on them), in random order (a later one may move an earlier one's value again)."""
    data, automaton = loaded.data, loaded.emitted
    scale = data.scale
    ego, k = sample_states(data, rng, count)
    n = len(k)
    location = np.asarray([rng.randrange(len(automaton.locations)) for _ in range(n)], dtype=np.int64)
    inputs = {}
    for item in automaton.inputs:
        if item.is_bool:
            inputs[item.name] = np.asarray([rng.random() < 0.5 for _ in range(n)])
        else:
            low, high = math.ceil(item.low * scale), math.floor(item.high * scale)
            high = min(high, low + 200 * scale)
            inputs[item.name] = np.asarray([rng.randrange(low, high + 1) for _ in range(n)], dtype=np.int64)
    # rewards of the order of the rates times the horizon, plus penalties
    bound = int(40 * automaton.horizon * scale)
    mirrors = {r: np.asarray([rng.randrange(-bound, bound + 1) for _ in range(n)], dtype=np.int64)
               for r in automaton.rewards}
    truth = ego[:, :5] / float(scale) + np.asarray([[rng.uniform(-1, 1) for _ in range(5)] for _ in range(n)])
    settled = np.asarray([rng.random() < 0.8 for _ in range(n)])
    columns = {("time", ""): k, **{("input", name): inputs[name] for name in inputs},
               **{("reward", r): mirrors[r] for r in mirrors}, **{("ego", str(c)): ego[:, c] for c in range(7)}}
    found = boundaries(printed, scale, Fraction(automaton.period))
    for row in range(n):  # comparisons next to their thresholds, each solved for its last term
        if rng.random() < 0.2:
            continue
        for terms, const in rng.sample(found, len(found)):
            if rng.random() < 0.5:
                continue
            rest = const + sum(a * int(columns[key][row]) for key, a in terms[:-1])
            key, a = terms[-1]
            value = -rest // a + rng.choice((-1, 0, 0, 1))
            if abs(value) < 2**31 - 1 and (key[0] != "time" or value >= 0):
                columns[key][row] = value
    k = np.maximum(k, 0)
    return QueryStates(k, ego, location, inputs, mirrors, truth, settled)


def _state_lines(states: QueryStates, automaton: ir.Automaton, scale: int, period_units: int) -> str:
    """The states as :func:`compile_expressions`'s ``main`` reads them (doubles as ``repr``, read back exactly)."""
    lines = []
    for row in range(states.n):
        fields = [states.k[row], *states.ego[row], states.location[row]]
        fields += [int(states.inputs[item.name][row]) for item in automaton.inputs]
        for reward in automaton.rewards:
            mirror = int(states.mirrors[reward][row])
            fields += [mirror, repr(mirror / float(scale))]  # the hybrid clock equals the mirror at a sample
        fields += [repr(float(value)) for value in states.truth[row]]
        fields += [repr(float(states.k[row] * period_units)), int(states.settled[row])]
        lines.append(" ".join(map(str, fields)))
    return "\n".join(lines) + "\n"


def engine_frames(loaded: Loaded, states: QueryStates) -> dict[str, Frame]:
    """The engine's frame per dialect: symbolic expressions read the integer mirrors and significands,
    statistical ones the rewards as doubles (UPPAAL's hybrid clocks: no ``mirrors``)."""
    automaton, scale = loaded.emitted, float(loaded.data.scale)
    inputs = {item.name: (states.inputs[item.name] if item.is_bool else states.inputs[item.name] / scale)
              for item in automaton.inputs}
    significands = {item.name: states.inputs[item.name] for item in automaton.numeric_inputs}
    rewards = {r: states.mirrors[r] / scale for r in automaton.rewards}
    common = dict(k=states.k, ego=states.ego, truth=states.truth, location=states.location, rewards=rewards,
                  inputs=inputs, significands=significands)
    return {SYMBOLIC: Frame(**common, mirrors=states.mirrors), STATISTICAL: Frame(**common)}


def _held(ref: ie.Ref, frame: Frame, scale: int, period: Fraction) -> tuple[np.ndarray, Fraction]:
    """The integers holding ``ref`` in a discrete observation and the value of one unit (``time``: the
    sample counter, one unit a period)."""
    if ref.kind is ie.RefKind.INPUT:
        return frame.significands[ref.name], Fraction(1, scale)
    if ref.kind is ie.RefKind.REWARD:
        return frame.mirrors[ref.name], Fraction(1, scale)
    if ref.kind is ie.RefKind.LOCATION_INDEX:
        return frame.location, Fraction(1)
    if ref.is_model and ref.model.kind == "time":
        return frame.k, period
    assert ref.is_model and ref.model.kind == "ego", ref
    return frame.ego[:, ref.index], Fraction(1, scale)


def discrete_value(expr: ie.Expr, frame: Frame, scale: int, period: Fraction) -> tuple[np.ndarray, int]:
    """A numeric discrete observation as UPPAAL observes it: the smallest whole multiple of the
    expression's exact value over the integers that hold it (docs/uppaal.md: ``x`` is the significand),
    and that multiple."""
    form = ie.linear_form(expr)
    assert form is not None, expr
    terms = [(coefficient * unit, column) for ref, coefficient in form.terms
             for column, unit in [_held(ref, frame, scale, period)]]
    multiple = math.lcm(form.const.denominator, *(c.denominator for c, _ in terms))
    total = np.full(frame.n, int(form.const * multiple), dtype=np.int64)
    for c, column in terms:
        total = total + int(c * multiple) * column.astype(np.int64)
    return total, multiple


def _same_doubles(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Bit for bit (any NaN equals any NaN)."""
    a, b = np.asarray(a, dtype=np.float64), np.asarray(b, dtype=np.float64)
    return (a.view(np.int64) == b.view(np.int64)) | (np.isnan(a) & np.isnan(b))


def compare_expressions(loaded: Loaded, printed: list[Printed], printer: UppaalPrinter, folder: Path,
                        rng: random.Random, pinned: set[str], count: int = 300) -> tuple[list[str], list[str]]:
    """``printed`` compiled as C and evaluated on ``count`` random states (:func:`query_states`) against
    the engine: the expressions that differ (with the first state where they do) and the conditions
    that kept one value over the states (unless they may: a pinned function, ``deadlock``)."""
    binary = compile_expressions(loaded, printed, printer, folder)
    data, automaton = loaded.data, loaded.emitted
    states = query_states(loaded, printed, rng, count)
    period_units = loaded.vocabulary.period / loaded.vocabulary.unit
    assert period_units.denominator == 1
    lines = run_binary(binary, _state_lines(states, automaton, data.scale, int(period_units)))
    rows = [line.split() for line in lines]
    assert len(rows) == states.n and all(len(row) == len(printed) for row in rows)
    frames = engine_frames(loaded, states)
    evaluator = Evaluator(data, automaton)
    mismatches, constant = [], []
    for column, p in enumerate(printed):
        tokens = [row[column] for row in rows]
        frame = frames[p.dialect]
        where = f"{p.query.name}: {p.query.text} ({p.role}) printed as `{p.c}`"
        if p.kind == "int":  # a numeric discrete observation: an integer in UPPAAL, the number in the engine
            emitted = np.asarray([int(t) for t in tokens], dtype=np.int64)
            expected, multiple = discrete_value(p.expr, frame, data.scale, loaded.vocabulary.period)
            differ = np.flatnonzero(emitted != expected)
            # the engine observes the number itself (a double): the same partition of the states
            engine = evaluator.evaluate(p.expr, frame)
            if not np.allclose(engine, expected / multiple, rtol=1e-12, atol=1e-12):
                mismatches.append(f"{where}: the engine observes {engine.tolist()[:5]}..., not the integers "
                                  f"{expected.tolist()[:5]}... / {multiple}")
        elif p.kind == "bool":
            emitted = np.asarray([int(t) for t in tokens], dtype=bool)
            engine = evaluator.evaluate_bool(p.expr, frame)
            if p.settled:
                engine = (~states.settled | engine) if p.box else (states.settled & engine)
            differ = np.flatnonzero(emitted != engine)
            if not _may_be_constant(p.expr, pinned) and len(set(engine.tolist())) < 2:
                constant.append(where)
        else:
            emitted = np.asarray([float(t) for t in tokens])
            engine = np.asarray(evaluator.evaluate(p.expr, frame), dtype=np.float64)
            differ = np.flatnonzero(~_same_doubles(emitted, engine))
        if differ.size:
            row = int(differ[0])
            engine_value = (expected if p.kind == "int" else engine)[row]
            state = dict(k=int(states.k[row]), ego=states.ego[row].tolist(), location=int(states.location[row]),
                         inputs={n: states.inputs[n][row].item() for n in states.inputs},
                         mirrors={n: int(states.mirrors[n][row]) for n in states.mirrors},
                         truth=states.truth[row].tolist(), settled=bool(states.settled[row]))
            mismatches.append(f"{where}: the emitted model computes {tokens[row]}, the engine "
                              f"{engine_value.item()!r} in {differ.size} of {states.n} states; first: {state}")
    return mismatches, constant


@needs_cc
@pytest.mark.parametrize("case", CASES, ids=CASE_IDS)
def test_every_query_expression_of_every_file(case: Case, tmp_path: Path) -> None:
    """Every expression of the file's and the standard queries, printed as C, equals the engine's value."""
    loaded = load(case, tmp_path)
    printed, refused, printer = print_expressions(loaded.automaton, loaded.vocabulary)
    # the printer refuses exactly what it should, for the reason it should (one expression each)
    assert set(refused) == set(case.refused), refused
    assert all(len(reasons) == 1 and case.refused[name] in reasons[0] for name, reasons in refused.items()), refused
    assert printed
    mismatches, constant = compare_expressions(loaded, printed, printer, tmp_path, random.Random(f"queries {case.id}"),
                                               _pinned(case, loaded.data))
    assert not mismatches, (f"{len(mismatches)} of {len(printed)} expressions differ:\n" + "\n".join(mismatches))
    # the states exercised both outcomes of every condition the scenario lets vary
    assert not constant, "conditions that kept one value over the states:\n" + "\n".join(constant)


#: Statistical queries over the true state, whose hybrid clocks are 0 in the emitted model's initial state.
TRUTH_QUERIES_AUTOMATON = """\
automaton Truth {{
    input near : bool
    reward r
    objective r
    sample every 0.5
    horizon 4
    initial location A {{ r' == 1 }}
    location B {{ r' == -1 }}
    edge A -> B when near
    edge B -> A when !near
    model {{
        scenario "{scenario}"
        exponent 3
        decide_period 1
        action jerk in [-2, 2] step 2
        action turn in [-0.2, 0.2] step 0.2
        bind near = mindist() < 3 * collision_distance
    }}
    query Drift: Pr[<=4](<> fabs(true_x - x) >= sensor_error)
    query Close: Pr[<=4]([] fabs(true_x - x) + fabs(true_v - v) < sensor_error)
    query Slowest: E[<=4; 10](min: true_v)
    query Widest: E[<=4; 10](max: fabs(true_head - head) - true_x)
}}
"""


@needs_cc
def test_the_true_state_counts_from_the_start_the_engine_has(tmp_path: Path) -> None:
    """The emitted model's initial state, before the Dynamics' first (committed) edge sets the true state
    to the ego's start, holds every true-state clock at 0, while the ego is already at its start: the
    paper's Qa, `Pr[<=T](<> fabs(true_x - x) >= sensor_error)`, held there in every run (1.75 m apart in
    the left turn), and `E[..](min: true_v)` read 0. rac's engine starts the truth at the ego's start. At
    time 0 the emitted formulas, over both states (the initial one and the one after the Dynamics' edge),
    must give what the engine gives at sample 0: `<>` their disjunction, `[]` their conjunction, `max:`
    and `min:` their extreme."""
    loaded = load(Case("truth", _in_scenario(TRUTH_QUERIES_AUTOMATON)), tmp_path)
    v, data = loaded.vocabulary, loaded.data
    counter = itertools.count()
    printer = UppaalPrinter(v, fresh=lambda base: f"rac_test_{base}{next(counter)}", c_syntax=True)
    printed: list[tuple[str, str, ie.Expr, str]] = []  # (query name, how a run combines states, expr, C)
    for decl in loaded.automaton.queries:
        query = decl.query
        if isinstance(query, iq.ProbabilityQuery):
            printed.append((decl.name, query.path, query.expr, printer.state(query.expr, STATISTICAL,
                                                                             query.path == "[]").text))
        else:
            assert isinstance(query, iq.ExpectationQuery)
            printed.append((decl.name, query.aggregate, query.expr, printer.extreme(query.expr, query.aggregate).text))
    _, start = dynamics_of(loaded.xml, v.model.dynamics)
    import xml.etree.ElementTree as ElementTree  # as in dynamics_of: `xml` names a string in this module

    dynamics = next(t for t in ElementTree.fromstring(loaded.xml).iter("template")
                    if t.findtext("name") == v.model.dynamics)
    first = dynamics.find("init").get("ref")
    assert [loc.find("committed") is not None for loc in dynamics.iter("location") if loc.get("id") == first] == [True]
    # the location the Dynamics' first edge enters, from which on the true state is the engine's
    (running,) = [loc.findtext("name") for loc in dynamics.iter("location") if loc.get("id") != first]
    names = [MODEL_NAMES[name].uppaal for name in TRUE_STATE]
    locations = [v.locations[loc.name] for loc in loaded.automaton.locations]
    program = [C_PRELUDE, _as_c(_declaration(loaded.xml)), "#include <stdio.h>",
               f"struct {{ {' '.join(f'bool {name};' for name in locations)} int32_t location; }} {v.process};",
               # the initial state: every clock 0, every process in its initial location
               f"struct {{ double {', '.join(names)}; bool {running}; }} {v.model.dynamics};",
               f"struct {{ bool {v.model.wait}; }} {v.model.timer};",
               "static void print_all(void) {",
               *(f'    printf("%.17e ", (double)({c}));' for _, _, _, c in printed),
               '    printf("\\n");', "}",
               "int main(void) {",
               f"    {v.process}.{locations[0]} = true;",
               "    print_all();",
               *(f"    {v.model.dynamics}.{name} = {start[name]};" for name in names),  # the Dynamics' first edge
               f"    {v.model.dynamics}.{running} = true;",
               "    print_all();", "    return 0;", "}"]
    binary = _compile("\n".join(program) + "\n", tmp_path, "start")
    initial, started = ([float(t) for t in line.split()] for line in run_binary(binary, ""))
    runs = simulate(data, runs=1, horizon_samples=1, seed=0)
    frame = Frame(k=np.zeros(1, dtype=np.int64), ego=np.ascontiguousarray(runs.states[:, 0]),
                  truth=np.ascontiguousarray(runs.truth[:, 0]))
    evaluator = Evaluator(data, loaded.automaton)
    combine = {"<>": any, "[]": all, "max": max, "min": min}
    for (name, how, expr, text), first, second in zip(printed, initial, started, strict=True):
        engine = float(np.asarray(evaluator.evaluate(expr, frame), dtype=np.float64)[0])
        emitted = float(combine[how]([first, second]))
        assert emitted == engine, (f"{name} ({text}) at time 0: the emitted model gives {first!r} in its initial "
                                   f"state and {second!r} once the Dynamics started, {emitted!r} in all; the engine "
                                   f"{engine!r} at sample 0")


# ---------------------------------------------------------------- 3. the ground truth
TRUTH_MAIN = r"""
#include <stdio.h>

// the right-hand sides of the Dynamics template's invariant (per time unit)
static void rac_derivative(const double s[5], double d[5]) {
DERIVATIVE
}

// The start (the first edge's assignment), then, per line ``x y v acc head jerk turn`` (the true state
// at a sample and the actions of the period), the true state one period later: RK4 over the emitted ODE.
int main(void) {
    double s[5], k1[5], k2[5], k3[5], k4[5], w[5];
    double h;
    long long steps, n, j, u;
    int i;
    double true_x, true_y, true_v, true_acc, true_head;
START
    printf("%.17e %.17e %.17e %.17e %.17e\n", true_x, true_y, true_v, true_acc, true_head);
    if (scanf("%lld", &steps) != 1) {
        return 1;
    }
    h = (double)PERIOD / (double)steps;  // time units
    while (scanf("%lf %lf %lf %lf %lf %lld %lld", &s[0], &s[1], &s[2], &s[3], &s[4], &j, &u) == 7) {
        jerk = (int32_t)j;
        turn = (int32_t)u;
        for (n = 0; n < steps; n++) {
            rac_derivative(s, k1);
            for (i = 0; i < 5; i++) w[i] = s[i] + h / 2.0 * k1[i];
            rac_derivative(w, k2);
            for (i = 0; i < 5; i++) w[i] = s[i] + h / 2.0 * k2[i];
            rac_derivative(w, k3);
            for (i = 0; i < 5; i++) w[i] = s[i] + h * k3[i];
            rac_derivative(w, k4);
            for (i = 0; i < 5; i++) s[i] = s[i] + h / 6.0 * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i]);
        }
        printf("%.17e %.17e %.17e %.17e %.17e\n", s[0], s[1], s[2], s[3], s[4]);
    }
    return 0;
}
"""

#: RK4 steps per sensing period in C: the step bounds how far the C integration overshoots a bound
#: of the saturated ODE (see :func:`truth_tolerances`).
TRUTH_STEPS = 2000


def _split_top(text: str, separator: str) -> list[str]:
    """``text`` split at ``separator`` outside parentheses."""
    parts, depth, start, i = [], 0, 0, 0
    while i < len(text):
        if text[i] in "([":
            depth += 1
        elif text[i] in ")]":
            depth -= 1
        elif depth == 0 and text.startswith(separator, i):
            parts.append(text[start:i].strip())
            start = i = i + len(separator)
            continue
        i += 1
    return [*parts, text[start:].strip()]


def dynamics_of(xml: str, process: str) -> tuple[dict[str, str], dict[str, str]]:
    """The ``Dynamics`` template's ODE (clock -> right-hand side, from its invariant) and its start
    (clock -> value, from the assignment of its first edge), as UPPAAL/C expressions."""
    import xml.etree.ElementTree as ElementTree

    template = next(t for t in ElementTree.fromstring(xml).iter("template") if t.findtext("name") == process)
    clocks = re.fullmatch(r"hybrid clock ([\w, ]+);", template.findtext("declaration").strip()).group(1)
    assert [c.strip() for c in clocks.split(",")] == [MODEL_NAMES[n].uppaal for n in TRUE_STATE]
    invariants = [label.text for label in template.iter("label") if label.get("kind") == "invariant"]
    assert len(invariants) == 1, invariants
    ode = {}
    for part in _split_top(invariants[0], "&&"):
        match = re.fullmatch(r"(\w+)' == (.+)", part)
        assert match, part
        ode[match.group(1)] = match.group(2)
    assignments = [label.text for label in template.iter("label") if label.get("kind") == "assignment"]
    assert len(assignments) == 1, assignments
    start = {}
    for part in _split_top(assignments[0], ","):
        name, value = part.split(" = ", 1)
        start[name.strip()] = value
    return ode, start


def compile_truth(xml: str, vocabulary: Vocabulary, folder: Path) -> Path:
    ode, start = dynamics_of(xml, vocabulary.model.dynamics)
    names = [MODEL_NAMES[n].uppaal for n in TRUE_STATE]
    assert set(ode) == set(names) == set(start)
    derivative = [f"    double {name} = s[{i}];" for i, name in enumerate(names)]
    derivative += [f"    d[{i}] = {ode[name]};" for i, name in enumerate(names)]
    main = (TRUTH_MAIN.replace("DERIVATIVE", "\n".join(derivative))
            .replace("START", "\n".join(f"    {name} = {start[name]};" for name in names)))
    return _compile(C_PRELUDE + _as_c(_declaration(xml)) + "\n" + main, folder, "truth")


def action_plans(data: ModelData, rng: random.Random, decisions: int) -> np.ndarray:
    """``(runs, decisions)`` indices into :func:`action_pairs`: full jerk throughout (acceleration to
    +MA, speed to its maximum), full braking (to -MA and the minimum speed), full jerk then full
    braking, alternating with the largest turn, and two random sequences."""
    jerks, turns = list(data.action("jerk").values), list(data.action("turn").values)
    pairs = [tuple(p) for p in action_pairs(data).tolist()]

    def index(jerk: int, turn: int) -> int:
        return pairs.index((jerk, turn))

    up, down, straight = max(jerks), min(jerks), min(turns, key=abs)
    plans = [[index(up, straight)] * decisions, [index(down, straight)] * decisions,
             [index(up if d < decisions // 2 else down, straight) for d in range(decisions)],
             [index(up if d % 2 == 0 else down, max(turns)) for d in range(decisions)]]
    plans += [[rng.randrange(len(pairs)) for _ in range(decisions)] for _ in range(2)]
    return np.asarray(plans, dtype=np.int64)


def truth_tolerances(data: ModelData, engine_substeps: int) -> np.ndarray:
    """How far two integrations of the same saturated ODE over one sensing period (``P`` s), from the
    same state, may differ, per truth column (x, y, v, acc, head).

    Away from the saturation switches both are RK4 on a smooth right-hand side with steps of at most
    ``P / 100`` s: errors ~1e-12. Where the acceleration or the speed reaches its bound the
    right-hand side is discontinuous, and each integration errs by at most one step's increment
    there: the engine clips back onto the bound after a step (and undershoots when only its last
    stage sees the bound), the C integration of the ODE as emitted overshoots and keeps the offset.
    With ``h`` the two step lengths added (s), ``J`` the largest jerk and ``A`` the largest
    acceleration, a period (the actions are constant in it, so the acceleration switches at most
    once) bounds the differences by: acceleration ``h*J``; speed ``h*A`` plus the acceleration's
    offset over the period, ``h*J*P``; positions the speed's bound over the period; the heading
    has no switch (rounding only). 1e-9 covers the smooth error and the rounding."""
    period = float(data.period)
    h = period / TRUTH_STEPS + period / engine_substeps
    jerk = max(abs(j) for j in data.action("jerk").values) / data.scale
    acc = data.max_acc / data.scale
    speed = h * (acc + jerk * period)
    return np.asarray([speed * period, speed * period, speed, h * jerk, 0.0]) + 1e-9


@needs_cc
@pytest.mark.parametrize("case", [c for c in CASES if c.id in (*(p.relative_to(ROOT).as_posix() for p in MODEL_FILES),
                                                                "tiny/goal_ahead")],
                         ids=lambda c: c.id)
def test_the_ground_truth_is_the_emitted_ode(case: Case, tmp_path: Path) -> None:
    """The engine's truth, period by period, is the emitted ``Dynamics`` ODE integrated finely in C."""
    loaded = load(case, tmp_path)
    data = loaded.data
    binary = compile_truth(loaded.xml, loaded.vocabulary, tmp_path)
    samples = math.ceil(12 / data.period)  # 12 s: long enough to reach every bound from the start
    decisions = math.ceil(samples / data.decide_every)
    plans = action_plans(data, random.Random(f"truth {case.id}"), decisions)
    runs = len(plans)

    def policy(k: int, states: np.ndarray) -> np.ndarray:
        allowed = np.zeros((runs, len(action_pairs(data))), dtype=bool)
        allowed[np.arange(runs), plans[:, k // data.decide_every]] = True
        return allowed

    engine = simulate(data, runs=runs, horizon_samples=samples, seed=1, policy=policy)
    truth = engine.truth  # (runs, samples + 1, 5)
    before = truth[:, :-1].reshape(-1, 5)
    actions = engine.states[:, 1:, 5:7].reshape(-1, 2)  # the jerk and turn in force over each period
    stdin = f"{TRUTH_STEPS}\n" + "".join(f"{' '.join(map(repr, state.tolist()))} {j} {u}\n"
                                         for state, (j, u) in zip(before, actions))
    lines = run_binary(binary, stdin)
    start = np.asarray([float(v) for v in lines[0].split()])
    assert (start == truth[:, 0]).all(), (start, truth[0, 0])  # the same doubles: i2d(EGO_X0) ...
    emitted = np.asarray([[float(v) for v in line.split()] for line in lines[1:]])
    after = truth[:, 1:].reshape(-1, 5)
    difference = np.abs(emitted - after)
    tolerance = truth_tolerances(data, inspect.signature(simulate).parameters["truth_substeps"].default)
    worst = np.unravel_index(np.argmax((difference / tolerance).max(axis=1)), (runs, samples))
    assert np.all(difference <= tolerance), (
        f"over a period, the emitted ODE integrated in C differs from the engine's truth by up to "
        f"{difference.max(axis=0).tolist()} (x, y, v, acc, head; tolerance {tolerance.tolist()}); worst: run "
        f"{worst[0]}, sample {worst[1]}, from {truth[worst].tolist()} with (jerk, turn) "
        f"{engine.states[worst[0], worst[1] + 1, 5:7].tolist()}")
    # the runs drove the speed and the acceleration into every bound, where the ODE saturates
    scale = float(data.scale)
    v, acc = truth[:, :, 2], truth[:, :, 3]
    assert (v == data.max_speed / scale).any() and (v == data.min_speed / scale).any()
    assert (acc == data.max_acc / scale).any() and (acc == -data.max_acc / scale).any()
    moved = np.abs(after[:, :2] - before[:, :2]).max()
    assert moved > 100 * tolerance[0], moved
