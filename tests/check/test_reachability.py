"""W0302 against the runs themselves: a location is reported unreachable exactly when no run within the
horizon is ever there, `episode ends when` included (a run that enters a location on inputs that end the
episode goes no further)."""

from __future__ import annotations

import itertools

from rac.compiler import compile_text
from rac.runtime.interpreter import RewardAutomaton

ENDS = """automaton R {
    input e : bool
    input f : bool
    reward s
    priority s
    objective s
    sample every 1
    horizon 4
    initial location A { s' == 1 }
    location B { s' == 1 }
    location C { s' == -1 }
    location D { s' == 1 }
    edge A -> B when e
    edge B -> C
    edge A -> D when !e && f
    episode ends when e
}
"""


def visited(text: str) -> set[str]:
    """Every location some run is in, over every input sequence of the horizon (the runtime ends a run
    where `episode ends when` holds)."""
    automaton = compile_text(text, "r.ra", analyse=False).raise_for_errors()
    names = [i.name for i in automaton.inputs]
    seen = {automaton.location_names[automaton.initial]}
    for sequence in itertools.product(itertools.product([False, True], repeat=len(names)), repeat=automaton.steps):
        runtime = RewardAutomaton(automaton)
        for values in sequence:
            if runtime.ended:
                break
            runtime.step(dict(zip(names, values)))
            seen.add(runtime.location)
    return seen


def test_a_location_behind_the_end_of_every_episode_is_unreachable() -> None:
    """`B` is entered only where `e` holds, which ends the episode: no run is ever in `C`. W0302 said
    nothing (its search followed every edge as if the run went on)."""
    result = compile_text(ENDS, "r.ra")
    unreachable = {d.message for d in result.diagnostics if d.code == "W0302"}
    assert visited(ENDS) == {"A", "B", "D"}
    assert unreachable == {"location `C` is unreachable"}
    (warning,) = [d for d in result.diagnostics if d.code == "W0302"]
    assert "episode ends when" in warning.hints[0]
    # where entering `B` need not end the episode, `C` is reached and not reported
    going_on = ENDS.replace("episode ends when e", "episode ends when e && f")
    assert visited(going_on) == {"A", "B", "C", "D"}
    assert not [d for d in compile_text(going_on, "r.ra").diagnostics if d.code == "W0302"]
