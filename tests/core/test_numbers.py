"""rac.core.numbers: sizes for people, also where an estimate is beyond any float."""

from __future__ import annotations

from fractions import Fraction

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from rac.core.numbers import format_bytes, seconds_at, size_option
from rac.engine.budget import parse_size


@pytest.mark.parametrize(("size", "text", "option"), [
    (10, "10 B", "1M"), (3000, "2.93 kB", "1M"), (5 * 2**30, "5 GB", "5G"), (int(1.55 * 2**30), "1.55 GB", "1.6G"),
    # an estimate for a horizon of 1e400 s: an int beyond float's range (was an OverflowError, exit 3)
    (10**400, "9.09e+387 TB", "9.31e+390G"),
])
def test_sizes_read_as_people_write_them(size: int, text: str, option: str) -> None:
    assert (format_bytes(size), size_option(size)) == (text, option)


@given(st.integers(1, 2**60))
def test_the_suggested_budget_holds_the_size(size: int) -> None:
    assert parse_size(size_option(size)) >= size


@given(st.integers(0, 2**31 - 1), st.fractions(Fraction(1, 1000), Fraction(10)).filter(lambda f: f.denominator <= 1000))
def test_seconds_at_is_the_exact_time_rounded_once(samples: int, period: Fraction) -> None:
    # the float nearest to samples * period: info["time"] of 71 samples of 0.1 s reads 7.1
    assert seconds_at(samples, period) == float(samples * period)
    assert (seconds_at(np.array([samples]), period) == float(samples * period)).all()
    assert seconds_at(71, Fraction(1, 10)) == 7.1 != 71 * 0.1
