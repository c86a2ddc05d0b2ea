"""rac.targets.uppaal.significands: the values the Environment chooses (one per piece of a numeric
input's range), what the mirrors gain per sample, and E0801 when a number has no significand."""

from __future__ import annotations

from fractions import Fraction

from rac.compiler import compile_text
from rac.targets.uppaal.automaton import AutomatonGenerator
from rac.targets.uppaal.significands import NumericInput, Significands

#: A small automaton with a bool and a real input, two rewards (the tests of labels and processes share it).
TINY = """automaton Tiny {
    input near : bool
    input d : real in [0, 10]
    reward sa, pr
    objective 10*sa + pr
    sample every 0.5
    horizon 2
    initial location Go { sa' == 1; pr' == 2 }
    location Slow { sa' == -1; pr' == 0 }
    edge * -> Slow when near || d < 2.5 do sa = sa - 3
    edge * -> Go when !near && d >= 2.5
}
"""


def generator(text: str = TINY) -> AutomatonGenerator:
    """The UPPAAL generator of a checked ``text`` (its parts: numbers, labels, processes)."""
    result = compile_text(text, "tiny.ra")
    assert result.automaton is not None, [d.message for d in result.diagnostics]
    return AutomatonGenerator(result.automaton, "tiny.ra", "tiny")


def test_one_significand_per_piece_of_the_range() -> None:
    g = generator()
    numbers: Significands = g.numbers
    assert numbers.scale == 10 ** 4  # base 10, exponent 4 without a model block
    [d] = numbers.inputs(g.n, g.array, g.select)
    assert isinstance(d, NumericInput)
    assert d.pieces == "d = 0, d in (0, 2.5), d = 2.5, d in (2.5, 10), d = 10"
    # points exactly, open pieces at their middle; each value falls in its own piece
    assert d.values == [0, 12500, 25000, 62500, 100000]
    assert (d.low, d.high, d.count) == ("0", "10", 5)
    assert d.initializer == "{0, 12500, 25000, 62500, 100000}"
    assert g.diagnostics == []


def test_accrual_is_rate_times_period_in_significand_units() -> None:
    g = generator()
    inputs = g.numbers.inputs(g.n, g.array, g.select)
    accruals = g.numbers.accruals(inputs, g.n)
    # per location (Go, Slow) and reward (sa, pr): rate * 0.5 s * 10^4
    assert accruals == [[(Fraction(5000), []), (Fraction(10000), [])],
                        [(Fraction(-5000), []), (Fraction(0), [])]]


def test_a_threshold_finer_than_one_unit_is_e0801() -> None:
    g = generator(TINY.replace("d < 2.5", "d < 2.50001").replace("d >= 2.5", "d >= 2.50001"))
    g.numbers.inputs(g.n, g.array, g.select)
    assert [d.code for d in g.diagnostics] == ["E0801"]
    assert "2.50001" in g.diagnostics[0].message and "exponent 4" in g.diagnostics[0].message


def test_a_rate_term_whose_product_overflows_int32_is_e0801() -> None:
    # the accrual `iP = iP + 3*x / 10`: 3 times x's significand (10^9 at x = 100000) is 3e9, beyond int32,
    # though each sample's gain (3e8) and the reward's range fit: UPPAAL computes the product in 32 bits
    text = ("automaton Ov {\n    input x : real in [0, 100000]\n    reward p\n    objective p\n"
            "    sample every 0.1\n    horizon 0.2\n    initial location A { p' == 3 * x }\n}\n")
    g = generator(text)
    assert g.diagnostics == []
    g.numbers.accruals(g.numbers.inputs(g.n, g.array, g.select), g.n)
    [diagnostic] = g.diagnostics
    assert diagnostic.code == "E0801"
    assert "computes 3*x / 10 per sample, and 3 times the significand of `x` = 100000 is 3000000000" \
        in diagnostic.message
    # within the range: the same rate over x in [0, 10000] (3e8) is emitted
    g = generator(text.replace("100000]", "10000]"))
    g.numbers.accruals(g.numbers.inputs(g.n, g.array, g.select), g.n)
    assert g.diagnostics == []


def test_a_rate_reading_an_input_gets_whole_values_inside_each_open_piece() -> None:
    # `pr' == d / 20` at 0.5 s gains d/40 per sample, a whole number of units at a significand that is
    # a multiple of 40: the points 0, 2.5 and 10 are, the middles of (0, 2.5) and (2.5, 10), 12500 and
    # 62500, are not. rac chose the middles anyway and refused the rate (E0801), though every piece
    # holds values that make it whole.
    text = TINY.replace("pr' == 2", "pr' == d / 20")
    g = generator(text)
    inputs = g.numbers.inputs(g.n, g.array, g.select)
    g.numbers.accruals(inputs, g.n)
    assert g.diagnostics == []
    [d] = inputs
    assert d.values == [0, 12480, 25000, 62480, 100000]
    assert all(v % 40 == 0 for v in d.values)
    # each open piece keeps a value inside it, nearest its middle on that grid
    assert 0 < d.values[1] < 25000 and 25000 < d.values[3] < 100000
    # a piece too narrow for any multiple keeps its middle, and the rate is refused as before
    g = generator(text.replace("d < 2.5", "d < 2.5001").replace("d >= 2.5", "d >= 2.5001")
                  .replace("[0, 10]", "[2.5, 10]").replace("d / 40", "d / 4000"))
    g.numbers.accruals(g.numbers.inputs(g.n, g.array, g.select), g.n)
    assert [d.code for d in g.diagnostics] == ["E0801"]


def test_a_bound_at_int32_min_is_refused_for_what_it_is() -> None:
    # -214748.3648 has the significand -2147483648, an int32 (the range check lets a mirror reach it),
    # but UPPAAL has no literal for it; the note said it "is not a 32-bit integer"
    g = generator(TINY.replace("[0, 10]", "[-214748.3648, 10]"))
    g.numbers.inputs(g.n, g.array, g.select)
    [diagnostic] = g.diagnostics
    assert diagnostic.code == "E0801" and "the bound -214748.3648 of input `d`" in diagnostic.message
    [note] = [n.message for n in diagnostic.notes]
    assert "not a 32-bit integer" not in note
    assert note == ("its significand -2147483648 is a 32-bit integer, but UPPAAL writes no literal for it: "
                    "its literals reach 2147483647 in magnitude")


def test_an_int_input_in_thirds_gets_multiples_of_three_or_a_refusal_that_says_why() -> None:
    # `r' == n / 3` at 0.5 s gains n * 10000 / 6 units: whole for multiples of 3. The runs between the
    # compared numbers got their least integers (1, 7) and the rate was refused, with a hint to enlarge
    # the exponent, which never makes a third whole.
    text = ("automaton T {\n    input n : int in [0, 12]\n    input b : bool\n    reward r\n    objective r\n"
            "    sample every 0.5\n    horizon 2\n    initial location A { r' == n / 3 }\n    location B { r' == 1 }\n"
            "    edge A -> B when b && n < 6\n}\n")
    g = generator(text)
    inputs = g.numbers.inputs(g.n, g.array, g.select)
    g.numbers.accruals(inputs, g.n)
    assert g.diagnostics == []
    [n] = inputs
    assert n.values == [0, 30000, 60000, 90000, 120000]
    # the bound 10 is given as it is: no multiple of 3 replaces it, and the message says which value fails
    g = generator(text.replace("[0, 12]", "[0, 10]"))
    g.numbers.accruals(g.numbers.inputs(g.n, g.array, g.select), g.n)
    [diagnostic] = g.diagnostics
    assert diagnostic.code == "E0801"
    assert "at `n` = 10 one sample's gain is no whole number of significand units" in diagnostic.message
    notes = [note.message for note in diagnostic.notes]
    assert "one sample adds 1.66667… to `r`, 16666.7… significand units" in notes[0]
    assert notes[1] == "the gain is whole only where `n` is a multiple of 3 (no exponent of base 10 helps: 3 divides " \
                       "no power of 10)"
    [hint] = diagnostic.hints
    assert "larger `exponent`" not in hint
    assert hint.startswith("give `n` bounds and compared numbers that are multiples of 3") and "`0.3334*n`" in hint
