"""A float input compared with a rational threshold: every runtime evaluates the comparisons the checker proved.

The checker proves facts of exact values; the runtimes read floats. A float that is the double nearest to
some of its input's numbers (bounds, thresholds) stands for the nearest of them, every other float for
itself (:func:`rac.runtime.semantics.float_atoms`): so every comparison holds of one value in the input's
range. Before, each atom compared with ``float(threshold)`` on its own, and two numbers sharing a double
(``0.3333333333333333`` and ``1/3``) were both "equal" to it: edges the checker proved disjoint both held.
"""

from __future__ import annotations

import math
import types
from fractions import Fraction

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from rac import ir
from rac.compiler import compile_text
from rac.runtime.batch import BatchRewardAutomaton
from rac.runtime.interpreter import RewardAutomaton
from rac.runtime.semantics import float_atoms
from rac.targets.python import generate_python

THIRD = """\
automaton Third {
    input x : real in [0, 1]
    reward r
    objective r
    sample every 1
    horizon 10
    initial location A { r' == 0 }
    location Low { r' == 0 }
    location High { r' == 0 }
    edge A -> Low when x <= 0.3333333333333333 do r = r + 1
    edge A -> High when x >= 1/3 do r = r + 2
}
"""


def generated_class(automaton: ir.Automaton) -> type:
    module = types.ModuleType("thresholds_ra")
    exec(compile(generate_python(automaton), "<generated>", "exec"), module.__dict__)  # noqa: S102 - the code under test
    return getattr(module, module.__all__[0])


def test_two_numbers_of_one_double_are_told_apart_as_the_checker_does() -> None:
    """``x <= 0.3333333333333333`` and ``x >= 1/3`` are disjoint (the checker proves it), and share a double;
    that float (exactly between them) stands for the nearer, 0.3333333333333333: the first edge alone holds
    there, in every runtime (before, both held and the first was taken by its place in the file)."""
    automaton = compile_text(THIRD, "third.ra").raise_for_errors()
    third = 1 / 3
    assert float(Fraction(3333333333333333, 10**16)) == third  # one double for both numbers
    for x, expected in ((third, ("Low", 1.0)), (math.nextafter(third, 0), ("Low", 1.0)),
                        (math.nextafter(third, 1), ("High", 2.0)), (0.0, ("Low", 1.0)), (1.0, ("High", 2.0))):
        for ra in (RewardAutomaton(automaton), generated_class(automaton)()):
            ra.step({"x": x})
            assert (ra.location, ra.rewards["r"]) == expected, (type(ra).__name__, x)
        batch = BatchRewardAutomaton(automaton, 2)
        batch.step_batch({"x": np.array([x, x])})
        assert batch.location_names() == [expected[0]] * 2, x
    # with 1/3 first, the disjoint edges in the other order: at that float x is still 0.3333333333333333
    flipped = compile_text(THIRD.replace("x <= 0.3333333333333333", "x < 0").replace("x >= 1/3", "x > 1/3 && x < 1")
                           .replace("edge A -> High", "edge A -> Low when x == 1/3 do r = r + 1\n    edge A -> High"),
                           "flipped.ra").raise_for_errors()
    for ra in (RewardAutomaton(flipped), generated_class(flipped)()):
        ra.step({"x": third})
        assert ra.location == "Low"  # `x == 1/3` at the double of 1/3, the only number of x there


def test_a_bound_or_threshold_alone_compares_as_its_double() -> None:
    """What users write keeps working: ``x <= 0.1`` holds at the float 0.1 (a hair above 1/10), ``x == 0.1``
    too, and ``x < 0.3`` does not hold at 0.3 (a hair below 3/10): each float stands for the number it
    rounds. Where two numbers share a double, the one nearer to it is the one the double stands for."""
    decimal = Fraction(3333333333333333, 10**16)
    cuts = [(Fraction(1, 10), False), (Fraction(3, 10), True), (decimal, False), (Fraction(1, 3), True)]
    atoms = float_atoms(cells_automaton(partition(cuts)))
    third = 1 / 3
    for op, threshold, expected in (("<=", Fraction(1, 10), ("<=", 0.1)), ("==", Fraction(1, 10), ("==", 0.1)),
                                    ("<", Fraction(3, 10), ("<", 0.3)), ("<=", decimal, ("<=", third))):
        assert atoms(ir.BAtom("x", op, threshold)) == expected
    # 1/3 shares the double of 0.3333333333333333, which is nearer to it: at that double x is not 1/3
    assert [atoms(ir.BAtom("x", op, Fraction(1, 3))) for op in ("<", "<=", ">", ">=", "==", "!=")] == [
        ("<=", third), ("<=", third), (">", third), (">", third), False, True]


# ---------------------------------------------------------------- partitions cut at numbers sharing doubles
BASES = [Fraction(1, 3), Fraction(2, 3), Fraction(1, 10), Fraction(3, 10), Fraction(7, 10), Fraction(1, 7)]


def relatives(base: Fraction) -> list[Fraction]:
    """``base`` and numbers of the same double: the double itself and its shortest decimal."""
    near = float(base)
    return sorted({base, Fraction(near), Fraction(repr(near))})


@st.composite
def cut_points(draw: st.DrawFn) -> list[tuple[Fraction, bool]]:
    """Sorted distinct cuts in (0, 1), each closed to the left (``x < t`` below it) or not (``x <= t``)."""
    chosen = draw(st.lists(st.sampled_from(BASES), min_size=1, max_size=3, unique=True))
    cuts = sorted({t for base in chosen for t in draw(st.lists(st.sampled_from(relatives(base)), min_size=1))})
    return [(t, draw(st.booleans())) for t in cuts]


def partition(cuts: list[tuple[Fraction, bool]]) -> list[ir.Guard]:
    """The cells between consecutive cuts: exactly one holds for every exact value of x."""
    below = [ir.BAtom("x", "<" if strict else "<=", t) for t, strict in cuts]
    cells: list[ir.Guard] = [below[0]]
    cells += [ir.BAnd((ir.BNot(low), high)) for low, high in zip(below, below[1:])]
    return [*cells, ir.BNot(below[-1])]


def cells_automaton(cells: list[ir.Guard]) -> ir.Automaton:
    """One reward per cell, raised by an ``at end`` clause guarded by it: every clause whose guard holds
    applies, so the rewards after ``end`` say which cells held (edges would hide all but the first)."""
    rewards = tuple(f"c{i}" for i in range(len(cells)))
    return ir.Automaton(
        name="Cells", inputs=(ir.Input("x", "real", Fraction(0), Fraction(1)),), rewards=rewards,
        locations=(ir.Location("L", tuple(ir.Linear(Fraction(0)) for _ in rewards)),), initial=0,
        edges=((),), end_clauses=tuple(ir.EndClause(cell, (ir.Assignment(r, ir.Linear(Fraction(1))),))
                                      for cell, r in zip(cells, rewards)),
        objective=ir.Linear(Fraction(0), tuple((r, Fraction(1)) for r in rewards)), priority=rewards,
        strict=False, period=Fraction(1), horizon=Fraction(10), assumptions=())


@settings(max_examples=60, deadline=None, derandomize=True, database=None)
@given(cuts=cut_points(), data=st.data())
def test_exactly_one_cell_of_a_partition_holds_at_every_float(cuts: list[tuple[Fraction, bool]],
                                                              data: st.DataObject) -> None:
    """Cells that partition [0, 1] exactly: at every float (the doubles of the cuts and their neighbours
    above all) exactly one holds, the same one in the interpreter, the generated module and the batch,
    and it is the cell of the float's exact value unless the float is the double of a cut."""
    cells = cells_automaton(partition(cuts))
    doubles = sorted({float(t) for t, _ in cuts})
    special = [y for f in doubles for y in (f, math.nextafter(f, 0), math.nextafter(f, 1))]
    xs = data.draw(st.lists(st.one_of(st.sampled_from(special), st.floats(0, 1)), min_size=1, max_size=6))
    generated = generated_class(cells)
    batch = BatchRewardAutomaton(cells, len(xs))
    batch.end_batch({"x": np.array(xs)})
    for j, x in enumerate(xs):
        held = []
        for ra in (RewardAutomaton(cells), generated()):
            ra.end({"x": x})
            held.append([name for name, value in ra.rewards.items() if value])
        held.append([name for name, value in batch.rewards.items() if value[j]])
        assert held[0] == held[1] == held[2], x
        assert len(held[0]) == 1, (x, held[0])
        if x not in doubles:
            exact = [f"c{i}" for i, cell in enumerate(partition(cuts)) if ir.evaluate_guard(cell, {"x": Fraction(x)})]
            assert held[0] == exact, x
