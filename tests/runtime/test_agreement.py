"""The three implementations agree to the bit: interpreter, generated module, batch stepping.

Each test runs ``n`` columns; a column is a sequence of samples with episode ends (``end`` then
``reset``) scheduled before some samples and a final ``end``. Every column runs on its own
interpreter and generated instance; all columns run at once on a batch (both edge-selection
strategies), ended columns restarted with ``reset(mask)``. After every operation the returned
reward, the location, every reward value, the objective, the sample count and whether the run
ended and was terminated must be identical. With ``episode ends when``, a column whose sample ends
its run is then ended again (``end``: 0.0, nothing changes) and reset before its next sample.
The fuzzer's compiled programs run on the generated module and the interpreter with values of every
kind, and on the batch against one interpreter per row (masks, ``clip``, refused inputs).
"""

from __future__ import annotations

import copy
import functools
import math
import pickle
import struct
import sys
import types
from dataclasses import dataclass, replace
from fractions import Fraction
from typing import Any

import fuzzgen
import numpy as np
import pytest
from driving_ir import driving_automaton
from hypothesis import HealthCheck, assume, given, settings
from hypothesis import strategies as st

from rac import ir
from rac.runtime.batch import BatchRewardAutomaton
from rac.runtime.interpreter import RewardAutomaton
from rac.runtime.semantics import InputSpec, input_specs
from rac.targets.python import generate_python

Values = dict[str, object]
Record = tuple[Any, ...]


def bits(value: float) -> bytes:
    return struct.pack("<d", value)


@dataclass
class Column:
    steps: list[Values]
    ends: dict[int, Values]  # an episode ends (end, then reset) before the sample with this index
    final: Values


def record(reward: float, location: str, rewards: dict[str, float], objective: float, samples: int,
           ended: bool, terminated: bool) -> Record:
    return (bits(reward), location, tuple((k, bits(v)) for k, v in rewards.items()), bits(objective), samples,
            bool(ended), bool(terminated))


def run_single(ra: Any, column: Column) -> list[Record]:
    out = []

    def note(reward: float) -> None:
        out.append(record(reward, ra.location, ra.rewards, ra.objective, ra.samples, ra.ended, ra.terminated))

    ra.reset()
    for t, values in enumerate(column.steps):
        if t in column.ends:
            note(ra.end(column.ends[t]))
            ra.reset()
        note(ra.step(values))
        if ra.terminated:
            note(ra.end(column.final))
            ra.reset()
    note(ra.end(column.final))
    return out


def stack(values: list[Values]) -> dict[str, np.ndarray]:
    return {name: np.array([v[name] for v in values]) for name in values[0]}


def run_batch(automaton: ir.Automaton, columns: list[Column], strategy: str) -> list[list[Record]]:
    batch = BatchRewardAutomaton(automaton, len(columns), strategy=strategy)
    out: list[list[Record]] = [[] for _ in columns]
    names = automaton.location_names

    def note(rewards: np.ndarray, mask: np.ndarray) -> None:
        locations, values, objective, samples = batch.locations, batch.rewards, batch.objective, batch.samples
        ended, terminated = batch.ended, batch.terminated
        for j in np.flatnonzero(mask):
            current = {k: float(v[j]) for k, v in values.items()}
            out[j].append(record(float(rewards[j]), names[locations[j]], current, float(objective[j]),
                                 int(samples[j]), ended[j], terminated[j]))

    everyone = np.ones(len(columns), dtype=bool)
    for t in range(len(columns[0].steps)):
        mask = np.array([t in c.ends for c in columns])
        if mask.any():
            rewards = batch.end_batch(stack([c.ends.get(t, c.steps[t]) for c in columns]), mask=mask)
            assert not rewards[~mask].any()
            note(rewards, mask)
            batch.reset(mask=mask)
        note(batch.step_batch(stack([c.steps[t] for c in columns])), everyone)
        terminated = batch.terminated
        if terminated.any():
            with pytest.raises(RuntimeError, match="the run has ended"):
                batch.step_batch(stack([c.steps[t] for c in columns]))
            rewards = batch.end_batch(stack([c.final for c in columns]), mask=terminated)
            assert not rewards.any()
            note(rewards, terminated)
            batch.reset(mask=terminated)
    note(batch.end_batch(stack([c.final for c in columns])), everyone)
    return out


def load_class(automaton: ir.Automaton) -> type:
    module = types.ModuleType("generated_ra")
    exec(compile(generate_python(automaton), "<generated>", "exec"), module.__dict__)  # noqa: S102
    return getattr(module, module.__all__[0])


def check_agreement(automaton: ir.Automaton, columns: list[Column]) -> None:
    generated = load_class(automaton)
    expected = [run_single(RewardAutomaton(automaton), c) for c in columns]
    for j, column in enumerate(columns):
        assert run_single(generated(), column) == expected[j], f"generated module, column {j}"
    for strategy in ("table", "direct"):
        assert run_batch(automaton, columns, strategy) == expected, f"batch ({strategy})"


@st.composite
def columns_of(draw: st.DrawFn, values: st.SearchStrategy[Values]) -> list[Column]:
    n = draw(st.integers(1, 4))
    length = draw(st.integers(0, 25))
    out = []
    for _ in range(n):
        steps = [draw(values) for _ in range(length)]
        ticks = draw(st.sets(st.integers(0, length - 1), max_size=3)) if length else set()
        out.append(Column(steps, {t: draw(values) for t in sorted(ticks)}, draw(values)))
    return out


# ---------------------------------------------------------------- the driving automaton
@st.composite
def driving_values(draw: st.DrawFn) -> Values:
    close = draw(st.booleans())
    dgoal = draw(st.one_of(st.floats(0, 500), st.sampled_from([0.0, 2.0, math.nextafter(2.0, 0.0), 500.0])))
    return {"isClose": close, "prog": draw(st.booleans()), "comf": draw(st.booleans()),
            "collide": close and draw(st.booleans()), "dgoal": dgoal}


DRIVING = driving_automaton()


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(columns_of(driving_values()))
def test_driving_agrees(columns: list[Column]) -> None:
    check_agreement(DRIVING, columns)


#: The driving automaton whose run ends at a collision or near the goal (its end clause applied there).
DRIVING_ENDS = replace(DRIVING, episode_ends=ir.BOr((ir.BInput("collide"), ir.BAtom("dgoal", "<", Fraction(2)))))


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(columns_of(driving_values()))
def test_driving_with_episode_ends_agrees(columns: list[Column]) -> None:
    check_agreement(DRIVING_ENDS, columns)


# ---------------------------------------------------------------- random small automata
FRACTIONS = st.builds(Fraction, st.integers(-12, 12), st.sampled_from([1, 1, 2, 3, 4, 10]))
B, C = ir.BInput("b"), ir.BInput("c")
INPUTS = (ir.Input("b", "bool"), ir.Input("c", "bool"), ir.Input("x", "real", Fraction(-5), Fraction(5)),
          ir.Input("m", "int", Fraction(0), Fraction(3)))
LIMITED = ir.Assumption(ir.BNot(ir.BAnd((B, ir.BAtom("x", ">", Fraction(3))))), "b imply x <= 3")


@st.composite
def linear(draw: st.DrawFn, names: tuple[str, ...], max_terms: int = 3) -> ir.Linear:
    const = draw(st.one_of(st.just(Fraction(0)), FRACTIONS))
    chosen = draw(st.lists(st.sampled_from(names), unique=True, max_size=max_terms)) if names else []
    return ir.Linear(const, tuple((name, draw(FRACTIONS)) for name in chosen))


@st.composite
def partition(draw: st.DrawFn) -> list[ir.Guard]:
    """Mutually exclusive guards (one per cell of a partition of the input space).

    Now and then overlapping ones: the checker would refuse them, but all three implementations
    define the outcome the same way (the first enabled edge in source order is taken).
    """
    kind = draw(st.sampled_from(["bool", "x", "mixed", "int", "true"] * 2 + ["overlap"]))
    if kind == "overlap":
        return [B, ir.BAtom("x", "<", draw(FRACTIONS) / 2), ir.TRUE]
    if kind == "bool":
        return [B, ir.BNot(B)]
    if kind == "true":
        return [ir.TRUE]
    t1, t2 = sorted((draw(FRACTIONS) / 2, draw(FRACTIONS) / 2))
    if kind == "x":
        return [ir.BAtom("x", "<", t1), ir.BAnd((ir.BAtom("x", ">=", t1), ir.BAtom("x", "<", t2))),
                ir.BAtom("x", ">=", t2)]
    if kind == "mixed":
        low = ir.BAtom("x", "<=", t1)
        return [ir.BAnd((B, low)), ir.BAnd((B, ir.BNot(low))), ir.BNot(B)]
    zero = ir.BAtom("m", "==", Fraction(0))
    return [zero, ir.BAnd((ir.BAtom("m", "!=", Fraction(0)), C)), ir.BNot(ir.BOr((zero, C)))]


@st.composite
def updates(draw: st.DrawFn, rewards: tuple[str, ...]) -> tuple[ir.Assignment, ...]:
    targets = draw(st.lists(st.sampled_from(rewards), max_size=2))
    return tuple(ir.Assignment(r, draw(linear(rewards + ("x", "m")))) for r in targets)


@st.composite
def automata(draw: st.DrawFn) -> ir.Automaton:
    n_loc = draw(st.integers(1, 4))
    rewards = tuple(f"r{i}" for i in range(draw(st.integers(1, 3))))
    constant_rates = st.builds(ir.Linear, FRACTIONS)
    locations = tuple(
        ir.Location(f"L{i}", tuple(draw(st.one_of(constant_rates, constant_rates, linear(("x", "m"), 2)))
                                   for _ in rewards))
        for i in range(n_loc))
    edges = []
    for source in range(n_loc):
        cells = draw(st.permutations(draw(partition())))
        cells = cells[:draw(st.integers(0, len(cells)))]
        edges.append(tuple(ir.Edge(source, draw(st.integers(0, n_loc - 1)), guard, draw(updates(rewards)))
                           for guard in cells))
    end_clauses = tuple(ir.EndClause(draw(st.sampled_from(draw(partition()))), draw(updates(rewards)))
                        for _ in range(draw(st.integers(0, 2))))
    # `episode ends when`: absent, or one cell of a partition (sometimes true: every first sample ends)
    episode_ends = draw(st.one_of(st.none(), st.sampled_from(draw(partition()))))
    return ir.Automaton(
        name="Random", inputs=INPUTS, rewards=rewards, locations=locations,
        initial=draw(st.integers(0, n_loc - 1)),
        edges=tuple(edges), end_clauses=end_clauses, episode_ends=episode_ends,
        assumptions=draw(st.sampled_from([(), (LIMITED,)])),
        objective=draw(linear(rewards)), priority=rewards, strict=False,
        period=draw(st.sampled_from([Fraction(1, 10), Fraction(1, 4), Fraction(1), Fraction(1, 3),
                                     Fraction(3, 2)])),
        horizon=Fraction(30))


@st.composite
def random_values(draw: st.DrawFn, limited: bool) -> Values:
    b = draw(st.booleans())
    # -0.0 often: 0.0 + c*x and c*x differ exactly there
    special = st.sampled_from([0.0, -2.5, 0.5, 1.5, 3.0, -5.0, 5.0])
    x = draw(st.one_of(st.just(-0.0), st.floats(-5, 5), special))
    if limited and b:
        x = min(x, 3.0)
    m = draw(st.one_of(st.integers(0, 3), st.sampled_from([0.0, 1.0, 3.0])))
    return {"b": b, "c": draw(st.booleans()), "x": x, "m": m}


@st.composite
def automaton_and_columns(draw: st.DrawFn) -> tuple[ir.Automaton, list[Column]]:
    automaton = draw(automata())
    return automaton, draw(columns_of(random_values(automaton.assumptions == (LIMITED,))))


@settings(max_examples=200, deadline=None,
          suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])
@given(automaton_and_columns())
def test_random_automata_agree(case: tuple[ir.Automaton, list[Column]]) -> None:
    automaton, columns = case
    check_agreement(automaton, columns)


# ---------------------------------------------------------------- assume violations: one message everywhere
#: Three assumptions over every kind of input; the second is written over two lines.
ASSUMING = """\
automaton Assuming {
    input b : bool
    input c : bool
    input x : real in [-5, 5]
    input m : int in [0, 3]
    assume b imply x <= 3
    assume m != 2 ||
           c
    assume !(c && x < -4.5) && (m == 0 || m >= 1)
    reward r
    objective r
    sample every 1
    horizon 10
    initial location L { r' == 1 }
}
"""


def _compiled_assuming() -> ir.Automaton:
    from rac.compiler import compile_text

    return compile_text(ASSUMING, "assuming.ra").raise_for_errors()


ASSUMING_IR = _compiled_assuming()
ASSUMING_CLASS = load_class(ASSUMING_IR)
OK: Values = {"b": False, "c": True, "x": 0.0, "m": 0}


def message(call: Any, values: Any) -> str:
    """The message of the ValueError ``call(values)`` raises."""
    try:
        call(values)
    except ValueError as exc:
        return str(exc)
    raise AssertionError(f"{values} was accepted")


@st.composite
def violations(draw: st.DrawFn) -> Values:
    """Valuations within the bounds that break at least one assumption (often several)."""
    x = draw(st.one_of(st.floats(-5, 5), st.sampled_from([3.0, math.nextafter(3.0, 4.0), -4.5, -5.0, -0.0])))
    values = {"b": draw(st.booleans()), "c": draw(st.booleans()), "x": x,
              "m": draw(st.sampled_from([0, 1, 2, 3, 2.0, True]))}
    broken = draw(st.sampled_from(["first", "second", "third"]))
    if broken == "first":
        values.update(b=True, x=draw(st.floats(math.nextafter(3.0, 4.0), 5)))
    elif broken == "second":
        values.update(m=2, c=False)
    else:
        values.update(c=True, x=draw(st.floats(-5, math.nextafter(-4.5, -5))))
    return values


@settings(max_examples=150, deadline=None)
@given(violations(), st.integers(0, 3))
def test_assume_violations_read_the_same_everywhere(values: Values, column: int) -> None:
    """Issue 12: every runtime names the first violated assumption (as written, with its line) and the
    values of the inputs it reads, in the same words; the batch adds which automata broke it."""
    expected = message(RewardAutomaton(ASSUMING_IR).step, values)
    assert expected.startswith("inputs violate `assume ")
    assert "(assuming.ra:" in expected
    for ra in (RewardAutomaton(ASSUMING_IR), ASSUMING_CLASS()):
        assert message(ra.step, values) == expected
        assert message(ra.end, values) == expected
    rows = [values if j == column else OK for j in range(4)]
    for strategy in ("table", "direct"):
        batch = BatchRewardAutomaton(ASSUMING_IR, 4, strategy=strategy)
        assert message(batch.step_batch, stack(rows)) == f"{expected} (automata [{column}])"
        assert message(batch.end_batch, stack(rows)) == f"{expected} (automata [{column}])"


# ---------------------------------------------------------------- compiled `.ra` programs, as users write them
def _compiled(program: Any) -> ir.Automaton | None:
    """The generated program checked in process (``rac.compile_text``), or None when it has errors."""
    import warnings

    from rac.compiler import compile_text

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        result = compile_text(program.text, "fuzz.ra")
    return result.raise_for_errors() if result.ok else None


@st.composite
def typed_value(draw: st.DrawFn, spec: InputSpec) -> object:
    """A value as environments hand it over: Python's and numpy's bools, ints and floats (float32
    inside the range, or at a bound rounded to float32), at the bounds, at 0 and -0.0, in between;
    now and then outside the range or of another kind, which both must refuse alike."""
    if draw(st.integers(0, 19)) == 0:
        return draw(st.sampled_from([None, "1", 2, 0.5, math.nan, math.inf, spec.high + 1, spec.low - 0.5]))
    if spec.is_bool:
        return draw(st.sampled_from([True, False, np.True_, np.False_, 0, 1, np.int8(1)]))
    special = [spec.low, spec.high, (spec.low + spec.high) / 2]
    if spec.low <= 0 <= spec.high:
        special += [0.0, -0.0]
    value = draw(st.one_of(st.sampled_from(special), st.floats(spec.low, spec.high)))
    if spec.kind == "int":
        whole = float(round(value))
        return draw(st.sampled_from([whole, int(whole), np.int64(int(whole)), np.float32(whole)]))
    narrow = [np.float32(value)] if spec.low <= float(np.float32(value)) <= spec.high else []
    at_bound = [np.float32(spec.low), np.float32(spec.high)]
    return draw(st.sampled_from([value, np.float64(value), *narrow, *at_bound]))


def _outcome(call: Any, values: Values) -> tuple[str, object]:
    try:
        return "ok", bits(call(values))
    except (ValueError, RuntimeError) as exc:  # both must refuse alike, in the same words
        return type(exc).__name__, str(exc)


def _state(ra: Any) -> Record:
    return (ra.location, tuple((k, bits(v)) for k, v in ra.rewards.items()), bits(ra.objective), ra.samples,
            bits(ra.time), ra.ended, ra.terminated)


@settings(max_examples=80, deadline=None, derandomize=True, database=None,
          suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large, HealthCheck.filter_too_much])
@given(program=fuzzgen.programs(), data=st.data())
def test_compiled_programs_agree(program: Any, data: st.DataObject) -> None:
    """Programs from the fuzzer's generator (tests/support/fuzzgen.py: inputs of each kind with ranges,
    `assume`, rates reading inputs, translations and resets, `at end`, `episode ends when`, several
    rewards and a weighted objective, names Python reserves) compiled by the checker, then run by the
    generated module and the interpreter on the same random operations: steps, ends (with and without
    ``clip``, whose counts must agree too), resets mid-run,
    and copies and pickles (a vector environment's workers) that go on from where the original was.
    Every outcome (a reward's bits, or the error's type and words) and the state after it must agree."""
    automaton = _compiled(program)
    assume(automaton is not None)
    assert automaton is not None
    module = types.ModuleType("rac_agreement_generated")  # importable while it runs: pickle finds the class
    exec(compile(generate_python(automaton), "<generated>", "exec"), module.__dict__)  # noqa: S102
    sys.modules[module.__name__] = module
    try:
        _run_operations(getattr(module, module.__all__[0])(), automaton, data)
    finally:
        del sys.modules[module.__name__]


def _run_operations(generated: Any, automaton: ir.Automaton, data: st.DataObject) -> None:
    interpreted = RewardAutomaton(automaton)
    specs = input_specs(automaton)
    for _ in range(data.draw(st.integers(1, 40), label="operations")):
        operation = data.draw(st.sampled_from(["step"] * 6 + ["end", "reset", "copy", "pickle"]))
        if operation == "reset" or (operation == "step" and generated.ended and data.draw(st.booleans())):
            generated.reset(), interpreted.reset()
        elif operation == "copy":
            generated, interpreted = copy.deepcopy(generated), copy.copy(interpreted)
        elif operation == "pickle":
            protocol = data.draw(st.integers(0, pickle.HIGHEST_PROTOCOL), label="protocol")
            generated = pickle.loads(pickle.dumps(generated, protocol))  # noqa: S301 - our own object
            interpreted = pickle.loads(pickle.dumps(interpreted, protocol))  # noqa: S301
        else:
            values = {spec.name: data.draw(typed_value(spec), label=spec.name) for spec in specs}
            clip = data.draw(st.booleans(), label="clip")
            ours = _outcome(functools.partial(getattr(generated, operation), clip=clip), values)
            theirs = _outcome(functools.partial(getattr(interpreted, operation), clip=clip), values)
            assert ours == theirs, (operation, clip, values)
        assert _state(generated) == _state(interpreted), operation
        assert generated.clipped == interpreted.clipped, operation


def _column(values: list[object]) -> object:
    """One input's values for a batch as an environment hands them over: an array of their own dtype when
    they share one (a float32 column keeps its float32 bounds), else an object column read row by row."""
    kinds = {np.asarray(v).dtype for v in values}
    return np.array(values, dtype=kinds.pop() if len(kinds) == 1 else object)


def _batch_row(batch: BatchRewardAutomaton, j: int) -> Record:
    return (batch.location_names()[j], tuple((k, bits(float(v[j]))) for k, v in batch.rewards.items()),
            bits(float(batch.objective[j])), int(batch.samples[j]), bits(float(batch.time[j])), bool(batch.ended[j]),
            bool(batch.terminated[j]))


@settings(max_examples=60, deadline=None, derandomize=True, database=None,
          suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large, HealthCheck.filter_too_much])
@given(program=fuzzgen.programs(), data=st.data())
def test_compiled_programs_agree_in_a_batch(program: Any, data: st.DataObject) -> None:
    """The batch on the fuzzer's compiled programs, against one interpreter per row: values of every kind an
    environment hands over (numpy's and Python's, float32 columns at the bounds, now and then one outside its
    range or of another kind), with and without ``clip``, under random masks, with ends and masked resets. A
    call the interpreters take on every masked row gives their rewards to the bit; one that any masked row
    refuses is refused by the batch with the same kind of error, and changes nothing."""
    automaton = _compiled(program)
    assume(automaton is not None)
    assert automaton is not None
    specs, n = input_specs(automaton), 3
    rows = [RewardAutomaton(automaton) for _ in range(n)]
    batch = BatchRewardAutomaton(automaton, n, strategy=data.draw(st.sampled_from(["table", "direct"])))
    for _ in range(data.draw(st.integers(1, 25), label="operations")):
        operation = data.draw(st.sampled_from(["step"] * 5 + ["end", "reset"]))
        mask = np.array(data.draw(st.lists(st.booleans(), min_size=n, max_size=n), label="mask"))
        if operation == "reset":
            for j in np.flatnonzero(mask):
                rows[j].reset()
            batch.reset(mask=mask)
        else:
            mask &= ~batch.ended if operation == "step" else ~batch.ended | batch.terminated
            if not mask.any():  # nothing read: a column no row could hold (strings) is still refused by its dtype
                continue
            clip = data.draw(st.booleans(), label="clip")
            values = [{spec.name: data.draw(typed_value(spec), label=spec.name) for spec in specs} for _ in rows]
            trial = [copy.copy(ra) for ra in rows]
            outcomes = [_outcome(functools.partial(getattr(ra, operation), clip=clip), values[j]) if mask[j]
                        else ("ok", bits(0.0)) for j, ra in enumerate(trial)]
            call = batch.step_batch if operation == "step" else batch.end_batch
            columns = {spec.name: _column([v[spec.name] for v in values]) for spec in specs}
            refused = [kind for kind, _ in outcomes if kind != "ok"]
            if refused:
                with pytest.raises((ValueError, RuntimeError)) as error:
                    call(columns, mask=mask, clip=clip)
                assert type(error.value).__name__ in refused, (operation, values, outcomes, error.value)
            else:
                got = call(columns, mask=mask, clip=clip)
                assert [("ok", bits(float(r))) for r in got] == outcomes, (operation, values)
                rows = trial
        for j, ra in enumerate(rows):
            assert _batch_row(batch, j) == _state(ra), (operation, j)


@settings(max_examples=100, deadline=None,
          suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])
@given(automata(), st.data())
def test_atom_codes_are_the_atoms_bits(automaton: ir.Automaton, data: st.DataObject) -> None:
    """The table strategy's index of each row's atoms (one product of the atoms with their weights
    2**i) is ``Σ atom_i << i``, every atom shifted and or-ed in."""
    rows = data.draw(st.lists(random_values(automaton.assumptions == (LIMITED,)), min_size=1, max_size=40))
    batch = BatchRewardAutomaton(automaton, len(rows), strategy="table")
    x = batch._read({name: [row[name] for row in rows] for name in rows[0]}, None)
    expected = np.zeros(len(rows), dtype=np.int64)
    for bit, (name, op, threshold) in enumerate(batch._atom_list):
        truth = x[name] if op is None else op(x[name], threshold)
        expected |= truth.astype(np.int64) << bit
    code = batch._atom_code(x, len(rows))
    assert code.dtype == batch._code_dtype and code.tolist() == expected.tolist()
