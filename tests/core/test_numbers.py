"""rac.core.numbers: sizes for people, also where an estimate is beyond any float."""

from __future__ import annotations

import pytest
from hypothesis import given
from hypothesis import strategies as st

from rac.core.numbers import format_bytes, size_option
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
