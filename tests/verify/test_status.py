"""rac.verify.status and rac.cli.engine.verdict_status: the verdict table and the exit codes agree."""

from __future__ import annotations

import itertools

import pytest

from rac.cli.common import EXIT_ERRORS, EXIT_OK, EXIT_UNDECIDED
from rac.cli.engine import verdict_status
from rac.verify.report import QueryResult
from rac.verify.status import (
    METHODS,
    NOT_APPLICABLE,
    NOT_SATISFIED,
    SATISFIED,
    STATUSES,
    UNDECIDED,
    UNKNOWN,
    UNSUPPORTED,
    VALUE,
    VERDICTS,
)


def test_the_tables_nest() -> None:
    assert len(set(STATUSES)) == len(STATUSES) == 6
    assert set(VERDICTS) == set(STATUSES) - {VALUE}
    assert set(UNDECIDED) == {UNKNOWN, UNSUPPORTED} and set(UNDECIDED) <= set(VERDICTS)
    assert SATISFIED not in UNDECIDED and NOT_SATISFIED not in UNDECIDED
    assert all(isinstance(words, str) and words for words in METHODS.values())


def result(status: str) -> QueryResult:
    return QueryResult("Q", "E<> p", "reach", status)


def expected_code(statuses: tuple[str, ...]) -> int:
    """The rule in words: a query that does not hold wins, then one not decided, else success."""
    if NOT_SATISFIED in statuses:
        return EXIT_ERRORS
    if any(s in UNDECIDED for s in statuses):
        return EXIT_UNDECIDED
    return EXIT_OK


@pytest.mark.parametrize("size", [0, 1, 2, 3])
def test_exit_code_of_every_combination_of_statuses(size: int) -> None:
    """Brute force over every multiset of up to three statuses."""
    for statuses in itertools.combinations_with_replacement(STATUSES, size):
        assert verdict_status([result(s) for s in statuses]) == expected_code(statuses), statuses


def test_not_applicable_and_values_never_fail_on_their_own() -> None:
    assert verdict_status([result(NOT_APPLICABLE), result(VALUE), result(SATISFIED)]) == EXIT_OK
    assert verdict_status([result(UNKNOWN), result(NOT_SATISFIED)]) == EXIT_ERRORS
    assert verdict_status([result(UNSUPPORTED)]) == EXIT_UNDECIDED
