"""W0303 (an input nothing reads): a query reads its inputs too, so an input only a query reads is used."""

from __future__ import annotations

import pytest

from rac.compiler import compile_text

SOURCE = """\
automaton Reader {{
    input near  : bool
    input dgoal : real in [0, 500]
    input lane  : int in [0, 3]

    reward sa
    objective sa

    sample every 1
    horizon 10

    initial location Go {{ sa' == 1 }}
    location Near       {{ sa' == -1 }}

    edge Go -> Near when near

    {query}
}}
"""


def _unused(query: str) -> list[str]:
    result = compile_text(SOURCE.format(query=query), "reader.ra", analyse=False)
    assert result.ok, [d.message for d in result.diagnostics]
    return sorted(d.message for d in result.diagnostics if d.code == "W0303")


@pytest.mark.parametrize("query", [
    "query Q: E<> dgoal > 30 && lane == 3",
    "query Q: Pr[<=10](<> dgoal < 2 && lane >= 1)",
    "query Q: E[<=10; 100](max: sa + dgoal + lane)",
    "query Q: simulate[<=10; 5]{sa, dgoal, lane}",
    "query Q: dgoal < 2 --> lane == 0",
    "query Q: strategy S = maxE(sa)[<=10]{lane}->{dgoal}: <> time >= 10",
])
def test_an_input_read_only_by_a_query_is_used(query: str) -> None:
    assert _unused(query) == []


def test_an_input_nothing_reads_is_still_reported() -> None:
    assert _unused("query Q: E<> lane == 3") == ["input `dgoal` is never used"]
