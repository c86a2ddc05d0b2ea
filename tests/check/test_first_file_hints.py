"""The hints a first `.ra` file meets name that file's own declarations, not the paper's automaton's."""

from __future__ import annotations

import pytest

from rac.compiler import compile_text

_BODY = ("automaton M {\n    input near : bool\n    REWARDS\n    sample every 1\n    horizon 5\n"
         "    initial location Go { }\n    location Near { }\n    edge Go -> Near when near\n}\n")


@pytest.mark.parametrize(("rewards", "example"), [
    ("reward safe, fast", "objective 10 * safe + fast"),
    ("reward a, b, c", "objective 100 * a + 10 * b + c"),
    ("reward only", "objective only"),
    ("", "objective 10 * sa + 5 * pr + co")])
def test_a_missing_objective_is_shown_over_the_files_rewards(rewards: str, example: str) -> None:
    """A file of `reward safe, fast` without an objective was told to add `objective 10 * sa + 5 * pr + co`:
    three rewards it does not have, and pasting it gave three E0101."""
    result = compile_text(_BODY.replace("REWARDS", rewards), "t.ra")
    found = [d for d in result.diagnostics if d.code == "E0105"]
    assert len(found) == 1 and "has no `objective` declaration" in found[0].message, found
    assert list(found[0].hints) == [f"add e.g. `{example}`"]
    if rewards:  # the example, pasted in, resolves
        fixed = compile_text(_BODY.replace("REWARDS", f"{rewards}\n    {example}"), "t.ra")
        assert not [d for d in fixed.diagnostics if d.code in ("E0101", "E0105")], fixed.diagnostics
