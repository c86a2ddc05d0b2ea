"""The emitted automaton-alone UPPAAL model, run as C, against the engine's mirrors and the Python target.

``rac compile --target uppaal`` writes, for a file without a ``model`` block, the network
``Timer, AUTOMATON, Environment`` (docs/uppaal.md, "The model"). tests/targets/test_emitted_network.py
runs the whole model of a few fixed automata against the engine's product; here random automata
run alone, sample by sample, in three implementations that must agree:

- the emitted network, every guard, update, invariant and select compiled as C and played by
  test_emitted_network's :class:`Network` (broadcasts, committed locations, time to the Timer's
  deadline, hybrid clocks at their rates). The Environment's ``select`` is the one thing the model
  leaves open: its edge is made controllable here, so that the test chooses the inputs (one tuple
  per sample, among those its ``assume`` guard allows);
- the engine's integer side, :class:`rac.engine.product.MirrorArithmetic` (what ``rac verify``'s
  product computes), stepped in the emitted order: accrual with the held inputs (at the first
  sample with the new ones when a rate reads an input), the edge, ``episode ends when``, ``at end``;
- the Python target's module (``rac compile --target python``), stepped with the same inputs
  (numbers as the significand's exact value), ``end()`` with the last inputs at the horizon.

After every sample and after the run's end: the same location in all three, the same sample
count, the network's mirrors equal to the engine's, its hybrid clocks equal to the module's
rewards (within rounding), and where no mirror truncates the mirrors equal to the rewards times
the scale; the run ends at the same sample in all three. Every model is also validated with
UPPAAL's parser when it is available (tests/support/utap.py; without it the comparison still runs).

Automata: test_agreement's IR strategy (``automata()``: up to four locations, rates reading a real
and an int input, updates with rational coefficients over rewards and inputs, negative ones among
them, guards over partitions of the inputs, ``at end`` clauses, ``episode ends when``, ``assume``),
at periods whose rates the significands can represent and at other representations than 10^4 (a `model`
block's base and exponent: 10^2, 10^6, 2^12, 3^5), and the fuzzer's generated programs
(tests/support/fuzzgen.py: ``*`` edges, constants, several ``at end`` clauses, extreme names), and automata
without inputs (their Environment reads nothing: ``read!`` without a ``select``).
"""

from __future__ import annotations

import dataclasses
import functools
import itertools
import random
import re
import shutil
import tempfile
import warnings
from fractions import Fraction
from pathlib import Path
from typing import Any

import fuzzgen
import numpy as np
import pytest
import utap as utap_module
from hypothesis import HealthCheck, assume, given, settings
from hypothesis import strategies as st
from lxml import etree
from test_agreement import automata, load_class
from test_emitted_network import CLOCKWORK as CLOCKWORK_MODEL
from test_emitted_network import Network, c_compatible, truncates

from rac import ir
from rac.compiler import compile_file, compile_text
from rac.engine.evaluate import EvaluationError
from rac.engine.product import MirrorArithmetic
from rac.ir.significands import Unrepresentable
from rac.model.data import ModelRangeError
from rac.runtime.semantics import first_sample_reads
from rac.targets.uppaal.automaton import UppaalError, generate_uppaal, vocabulary

COMPILER = shutil.which("cc") or shutil.which("gcc")
pytestmark = pytest.mark.skipif(COMPILER is None, reason="no C compiler (cc or gcc) on PATH")

#: Periods whose rates (test_agreement's fractions, denominators up to 10) mostly stay whole significands.
PERIODS = (Fraction(1, 10), Fraction(1, 2), Fraction(1), Fraction(2), Fraction(1, 4))


@dataclasses.dataclass
class Sample:
    """What one implementation shows after a sample (or after the run's end, ``k`` then the last sample)."""

    k: int
    location: str
    ended: bool
    mirrors: tuple[int, ...] = ()
    rewards: tuple[float, ...] = ()


def controllable_environment(xml: str) -> str:
    """``xml`` with the Environment's choosing edge (the one with a ``select``) controllable, so that
    :class:`Network` takes its values from the test's choices instead of enumerating them. An
    automaton without inputs has no such edge: its Environment's ``read!`` chooses nothing."""
    root = etree.fromstring(xml.encode("utf-8"))
    found = sends = 0
    environment = root.findall("template")[-1]  # `system Timer, AUTOMATON, Environment;`
    for transition in environment.iter("transition"):
        kinds = {label.get("kind"): label.text for label in transition.findall("label")}
        sends += (kinds.get("synchronisation") or "").endswith("!")  # read! (`read_!` where an input is `read`)
        if kinds.get("select"):
            transition.set("controllable", "true")
            found += 1
    others = [label for template in root.findall("template")[:-1] for label in template.iter("label")]
    assert sends == 1 and found <= 1 and not any(label.get("kind") == "select" for label in others), (sends, found)
    # the declarations in the C subset test_emitted_network's interpreter reads: a bounded integer
    # (`int[0,STEPS] count`, UPPAAL checks its range) and UPPAAL's `int` (32 bits) as int32_t
    declaration = root.find("declaration")
    declaration.text = re.sub(r"\bint\s*\[[^\]]*\]", "int32_t", declaration.text)
    declaration.text = re.sub(r"\bint\b", "int32_t", declaration.text)
    return etree.tostring(root, encoding="unicode")


def validator(folder: Path) -> utap_module.Utap | None:
    located = utap_module.locate()
    return None if located.path is None else utap_module.Utap(located.path, folder)


class Alone:
    """One automaton's emitted model, compiled, with the engine's and the module's sides."""

    def __init__(self, automaton: ir.Automaton, folder: Path):
        self.a = automaton
        model = generate_uppaal(automaton, source_name="random.ra", model_name="random.xml")
        self.xml = model.xml
        self.queries = model.queries
        self.names = vocabulary(automaton)
        self.net = Network(controllable_environment(model.xml), folder)
        self.process = self.net.index[self.names.process]
        # `system Timer, AUTOMATON, Environment;` (each renamed where a .ra name takes its name)
        assert len(self.net.processes) == 3
        self.timer = 0
        #: the Timer's last location (`Done`, renamed where the automaton has one): only a silent self-loop
        self.done = {loc for loc, edges in self.net.processes[0].edges.items()
                     if edges and all(e.target == loc and e.sync is None for e in edges)}
        assert len(self.done) == 1, self.done
        environment = [e for es in self.net.processes[2].edges.values() for e in es
                       if e.sync is not None and e.sync.endswith("!")]  # its read! (renamed where an input is `read`)
        assert len(environment) == 1
        edge = environment[0]
        assert bool(edge.selects) == bool(automaton.inputs), "the Environment selects exactly when there are inputs"
        #: every select tuple the Environment's `assume` guard allows, with the inputs its update writes
        #: (without inputs, the one empty tuple: nothing to choose)
        self.valuations: dict[tuple[int, ...], dict[str, object]] = {}
        for chosen in itertools.product(*[range(lo, hi + 1) for lo, hi in edge.bounds]):
            if edge.guard is None or edge.guard(*chosen):
                if edge.assign is not None:
                    edge.assign(*chosen)
                self.valuations[chosen] = self.read_inputs()
        self.net.restore(self.net.initial())
        assert self.valuations, "the emitted Environment allows no input"
        #: the significands' scale: 10^4, or a `model` block's base^exponent
        self.scale = self.names.scale
        self.arithmetic = MirrorArithmetic(automaton, self.scale)
        self.module = load_class(automaton)
        self.location_of = {uppaal: name for name, uppaal in self.names.locations.items()}

    # ------------------------------------------------------------ the network
    def read_inputs(self) -> dict[str, object]:
        """The input globals of the network: booleans, numbers as significands."""
        v = self.net.value
        return {item.name: bool(v(self.names.bools[item.name])) if item.is_bool
                else int(v(self.names.significands[item.name])) for item in self.a.inputs}

    def network(self, choices: list[tuple[int, ...]]) -> tuple[list[Sample], list[dict[str, object]]]:
        """The network's samples along ``choices``, and the inputs it read at each."""
        net, v = self.net, self.net.value
        state = net.initial()
        net.restore(state)
        state = net.instant(state, choices, lambda *_: None)
        samples, inputs = [], []
        for _ in range(len(choices) + 2):
            if state[0][self.timer] in self.done:
                break
            state = net.delay(state)
            state = net.instant(state, choices, lambda *_: None)
            inputs.append(self.read_inputs())
            samples.append(Sample(int(v(self.names.count)), self.location_of[state[0][self.process]],
                                  state[0][self.timer] in self.done,
                                  tuple(int(v(self.names.mirrors[r])) for r in self.a.rewards),
                                  tuple(float(v(self.names.hybrids[r])) for r in self.a.rewards)))
        else:
            raise AssertionError("the network's run did not end")
        # (without inputs the Environment's read! selects nothing: no choice is taken)
        assert state[2] == (len(samples) if self.a.inputs else 0), "the Environment chose once per sample"
        return samples, inputs

    # ------------------------------------------------------------ the engine
    def engine(self, inputs: list[dict[str, object]]) -> list[Sample]:
        a, arithmetic = self.a, self.arithmetic
        loc = np.array([a.initial], dtype=np.int64)
        mirrors = np.zeros((1, len(a.rewards)), dtype=np.int64)
        held = np.zeros((1, len(a.inputs)), dtype=np.int64)
        first_reads = first_sample_reads(a)
        out = []
        for k, values in enumerate(inputs, start=1):
            new = np.array([[int(values[item.name]) for item in a.inputs]], dtype=np.int64)
            if k > 1 or not first_reads:
                mirrors = arithmetic.accrue(loc, held, mirrors)
            else:
                mirrors = arithmetic.accrue(loc, new, mirrors)
            loc, mirrors = arithmetic.edges(loc, new, mirrors)
            ends = k == a.steps or (a.ending is not None and bool(arithmetic.guard(a.ending, new)[0]))
            if ends:
                mirrors = arithmetic.end(new, mirrors)
            out.append(Sample(k, a.location_names[int(loc[0])], ends, tuple(int(m) for m in mirrors[0])))
            held = new
            if ends:
                break
        return out

    # ------------------------------------------------------------ the Python target
    def python(self, inputs: list[dict[str, object]]) -> list[Sample]:
        ra = self.module()
        ra.reset()
        out = []
        for k, read in enumerate(inputs, start=1):
            values = {item.name: read[item.name] if item.is_bool else self.number(item, int(read[item.name]))
                      for item in self.a.inputs}
            ra.step(values)
            ends = bool(ra.terminated)
            if k == self.a.steps and not ends:
                ra.end(values)
                ends = True
            out.append(Sample(ra.samples, ra.location, ends, (),
                              tuple(float(ra.rewards[r]) for r in self.a.rewards)))
            if ends:
                break
        return out

    def number(self, item: ir.Input, significand: int) -> float | int:
        value = Fraction(significand, self.scale)
        return int(value) if item.kind == "int" else float(value)

    # ------------------------------------------------------------ one run
    def compare(self, seed: int) -> list[Sample]:
        rng = random.Random(seed)
        choices = [rng.choice(sorted(self.valuations)) for _ in range(self.a.steps)]
        inputs = [self.valuations[chosen] for chosen in choices]
        engine = self.engine(inputs)  # first: it refuses where two edges are enabled at once
        python = self.python(inputs)
        network, read = self.network(choices)
        assert read == inputs[:len(read)]
        assert len(network) == len(engine) == len(python), (len(network), len(engine), len(python))
        exact = not truncates(self.a, self.scale)
        for n, e, p in zip(network, engine, python):
            where = f"sample {n.k} (inputs {inputs[n.k - 1]})"
            assert (n.k, n.location, n.ended) == (e.k, e.location, e.ended) == (p.k, p.location, p.ended), where
            assert n.mirrors == e.mirrors, f"{where}: mirrors emitted {n.mirrors} / engine {e.mirrors}"
            for reward, hybrid, value, mirror in zip(self.a.rewards, n.rewards, p.rewards, n.mirrors):
                assert hybrid == pytest.approx(value, rel=1e-9, abs=1e-9), \
                    f"{where}: `{reward}` hybrid clock {hybrid} / Python target {value}"
                if exact:
                    assert mirror == pytest.approx(value * self.scale, rel=1e-9, abs=1e-6), \
                        f"{where}: `{reward}` mirror {mirror} / Python target {value} * {self.scale}"
        return network


def build(automaton: ir.Automaton, folder: Path) -> Alone | None:
    """The compiled comparison of ``automaton`` (its files in ``folder``), None where the emitted model
    does not exist (E0801)."""
    try:
        alone = Alone(automaton, folder)
    except UppaalError as failure:
        assert re.search(r"\bE0801\b", str(failure)), str(failure)
        return None
    except Unrepresentable:
        return None
    check = validator(folder)
    if check is not None:
        check.validate(alone.xml, alone.queries, automaton.name)
    return alone


def run(automaton: ir.Automaton, seeds: list[int]) -> int:
    """Every seed's run compared; how many samples were compared (0 where the model does not exist,
    or where the engine refuses: two edges enabled at once, an int32 overflow)."""
    with tempfile.TemporaryDirectory(prefix="rac-alone-") as folder:
        alone = build(automaton, Path(folder))
        if alone is None:
            return 0
        compared = 0
        for seed in seeds:
            try:
                compared += len(alone.compare(seed))
            except (EvaluationError, ModelRangeError):
                continue
        return compared


def shortened(automaton: ir.Automaton, period: Fraction, samples: int,
              representation: tuple[int, int] | None = None) -> ir.Automaton:
    """``automaton`` over ``samples`` samples of ``period``; with ``representation``, its significands at
    that (base, exponent), as a `model` block would set them (the automaton alone reads nothing else of it)."""
    shorter = dataclasses.replace(automaton, period=period, horizon=period * samples)
    if representation is None:
        return shorter
    base, exponent = representation
    return dataclasses.replace(shorter, model=dataclasses.replace(model_spec(), base=base, exponent=exponent))


@functools.cache
def model_spec() -> ir.ModelSpec:
    """A checked `model` block (examples/paper/model.ra's)."""
    paper = Path(__file__).resolve().parents[2] / "examples" / "paper" / "model.ra"
    spec = compile_file(paper).raise_for_errors().model
    assert spec is not None
    return spec


# ---------------------------------------------------------------- tests
@settings(max_examples=40, deadline=None, derandomize=True, database=None,
          suppress_health_check=[HealthCheck.too_slow, HealthCheck.filter_too_much, HealthCheck.data_too_large])
@given(automaton=automata(), period=st.sampled_from(PERIODS), samples=st.integers(1, 8),
       representation=st.sampled_from([None, None, (10, 2), (10, 6), (2, 12), (3, 5)]),
       seeds=st.lists(st.integers(0, 2**16), min_size=1, max_size=3))
def test_random_automata_run_alike_in_uppaal_engine_and_python(automaton: ir.Automaton, period: Fraction,
                                                               samples: int, representation: tuple[int, int] | None,
                                                               seeds: list[int]) -> None:
    assume(run(shortened(automaton, period, samples, representation), seeds) > 0)


def _checked(program: Any) -> ir.Automaton | None:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        result = compile_text(program.text, "fuzz.ra")
    return result.raise_for_errors() if result.ok else None


@settings(max_examples=25, deadline=None, derandomize=True, database=None,
          suppress_health_check=[HealthCheck.too_slow, HealthCheck.filter_too_much, HealthCheck.data_too_large])
@given(program=fuzzgen.programs(), seed=st.integers(0, 2**16))
def test_generated_programs_run_alike_in_uppaal_engine_and_python(program: Any, seed: int) -> None:
    automaton = _checked(program)
    assume(automaton is not None and automaton.steps <= 40)
    assert automaton is not None
    assume(c_compatible(automaton))
    assume(run(automaton, [seed]) > 0)


#: What the random automata rarely combine: a rate reading a real input (the first sample accrues on
#: read?), an update reading a reward updated before it, fractional updates of negative rewards
#: (C's division truncates towards zero), an int input with a negative range, `assume`, two `at end`
#: clauses, `episode ends when`, and locations named like the Timer's (`Done`, `Timer`: renamed).
METER = """\
automaton Meter {
    input near : bool
    input gain : bool
    input d    : real in [0, 1000]
    input m    : int in [-3, 3]
    assume near imply m >= 0
    reward dist, pen
    objective dist + pen
    sample every 0.5
    horizon 4
    initial location Done { dist' == 2*d;    pen' == 0 }
    location Timer        { dist' == 20 - d; pen' == -1 }
    edge Done -> Timer when near && d < 29 do pen = pen - d, dist = dist + 3*pen
    edge Timer -> Done when !near          do dist = dist - 2, pen = pen/3 - dist/7
    at end when gain do pen = pen + 10
    at end when d < 10 do dist = dist * 2
    episode ends when m == -3 && !gain
}
"""


@pytest.mark.parametrize("seed", range(6))
def test_a_meter_runs_alike_in_uppaal_engine_and_python(seed: int, tmp_path: Path) -> None:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        automaton = compile_text(METER, "meter.ra").raise_for_errors()
    alone = build(automaton, tmp_path)
    assert alone is not None
    assert len(alone.compare(seed)) >= 1


#: An int input read by a rate `n / 3`: at 1 s a sample gains `n * 10000 / 3` significand units, whole
#: only for multiples of 3. The Environment gave each run of integers between two compared numbers its
#: least integer (1, 7), and the target refused the rate (E0801); it now gives the run's least multiple
#: of 3 (3, 9), so an automaton whose bounds and compared numbers are multiples of 3 is emitted.
THIRDS = """\
automaton Thirds {
    input n : int in [0, 12]
    input b : bool
    reward r, s
    objective r + s
    sample every 1
    horizon 6
    initial location A { r' == n / 3; s' == 1 }
    location B { r' == 1; s' == -n / 3 }
    edge A -> B when b && n < 6 do s = s + n / 3
    edge B -> A when !b
}
"""


@pytest.mark.parametrize("seed", range(4))
def test_an_int_input_read_in_thirds_runs_alike_in_uppaal_engine_and_python(seed: int, tmp_path: Path) -> None:
    automaton = compile_text(THIRDS, "thirds.ra").raise_for_errors()
    alone = build(automaton, tmp_path)
    assert alone is not None
    assert sorted({int(v["n"]) for v in alone.valuations.values()}) == [0, 30000, 60000, 90000, 120000]
    assert len(alone.compare(seed)) == automaton.steps


# ---------------------------------------------------------------- automata without inputs
@st.composite
def inputless(draw: st.DrawFn) -> ir.Automaton:
    """``automata()`` without its inputs: constant rates, guards that are constants (one edge at most
    per location, so that the automaton stays deterministic), updates over rewards only."""
    automaton = draw(automata())

    def rewards_only(linear: ir.Linear) -> ir.Linear:
        return ir.Linear(linear.const, tuple((n, c) for n, c in linear.terms if n in automaton.rewards))

    def assignments(updates: tuple[ir.Assignment, ...]) -> tuple[ir.Assignment, ...]:
        return tuple(ir.Assignment(u.reward, rewards_only(u.value)) for u in updates)

    constant = st.sampled_from([ir.TRUE, ir.BConst(False)])
    locations = tuple(dataclasses.replace(loc, rates=tuple(ir.Linear(r.const) for r in loc.rates))
                      for loc in automaton.locations)
    edges = tuple(tuple(ir.Edge(e.source, e.target, draw(constant), assignments(e.updates)) for e in group[:1])
                  for group in automaton.edges)
    end_clauses = tuple(ir.EndClause(draw(constant), assignments(c.updates)) for c in automaton.end_clauses)
    episode_ends = draw(st.one_of(st.none(), st.none(), constant))
    return dataclasses.replace(automaton, inputs=(), locations=locations, edges=edges, end_clauses=end_clauses,
                               episode_ends=episode_ends, assumptions=())


@settings(max_examples=30, deadline=None, derandomize=True, database=None,
          suppress_health_check=[HealthCheck.too_slow, HealthCheck.filter_too_much, HealthCheck.data_too_large])
@given(automaton=inputless(), period=st.sampled_from(PERIODS), samples=st.integers(1, 8),
       representation=st.sampled_from([None, None, (10, 2), (2, 12)]))
def test_automata_without_inputs_run_alike_in_uppaal_engine_and_python(automaton: ir.Automaton, period: Fraction,
                                                                     samples: int,
                                                                     representation: tuple[int, int] | None) -> None:
    # the harness asserted one Environment edge with a `select`, which an automaton without inputs
    # does not have: no such automaton was ever run
    assume(run(shortened(automaton, period, samples, representation), [0]) > 0)


#: test_emitted_network's automaton that reads nothing, alone.
CLOCKWORK = CLOCKWORK_MODEL.format(block="")


def test_an_automaton_without_inputs_runs_alike_in_uppaal_engine_and_python(tmp_path: Path) -> None:
    automaton = compile_text(CLOCKWORK, "clockwork.ra").raise_for_errors()
    assert automaton.inputs == ()
    alone = build(automaton, tmp_path)
    assert alone is not None
    assert alone.valuations == {(): {}}
    samples = alone.compare(0)
    assert [s.location for s in samples] == ["Tock", "Tick"] * 3
    assert samples[-1].ended


def test_an_input_named_like_the_read_channel_runs_alike(tmp_path: Path) -> None:
    """An input named `read` makes the emitted channel `read_`: the harness found the Environment's edge by
    the name `read!` and failed such a model (the generated programs name inputs so)."""
    text = CLOCKWORK.replace("    reward up, down", "    input read : bool\n    reward up, down")
    text = text.replace("Tick -> Tock do", "Tick -> Tock when read do")
    text = text.replace("Tock -> Tick do", "Tock -> Tick when !read do")
    automaton = compile_text(text, "read.ra").raise_for_errors()
    alone = build(automaton, tmp_path)
    assert alone is not None and "read_!" in alone.xml
    assert all(len(alone.compare(seed)) == automaton.steps for seed in range(3))
