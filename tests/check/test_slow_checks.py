"""rac check on inputs that used to be slow: the faster paths give the same answers, and limits are honest.

The outcomes of a sample are grouped with numpy now (they were grouped class by class); the
reference below is that earlier loop, and random small automata must give the same outcomes, in
the same order, with the same representative classes. The worst-run search stops at
``MAX_SAMPLES`` unless its values settle: then it must say so (W0405), and when it does finish it
must give exactly the answer of a search without the limit.
"""

from __future__ import annotations

from fractions import Fraction

import pytest
from hypothesis import given
from test_worst import SETTINGS, Case, cases

from rac import ir
from rac.check.analysis import worst as worst_module
from rac.check.analysis.affine import arithmetic_inputs, end_outcomes, from_assignments, identity, moves, outcomes, then
from rac.check.analysis.behaviour import distances
from rac.check.analysis.priority import check_priorities, check_ranges
from rac.check.analysis.worst import Target, Unfinished, maximise
from rac.compiler import compile_text
from rac.core.diagnostics import Fact
from rac.ir.inputs import InputSpace


# ---------------------------------------------------------------- the earlier, class-by-class grouping
def _intervals(space: InputSpace, cls: int) -> int:
    return sum(not space.piece(cls, item.name).is_point for item in space.numerics)


def reference_outcomes(automaton: ir.Automaton, space: InputSpace) -> list[list[tuple]]:
    relevant = arithmetic_inputs(automaton)
    result = []
    for index, edges in enumerate(automaton.edges):
        enabled = [space.evaluate(e.guard) for e in edges]
        ending = (space.evaluate(automaton.episode_ends) if automaton.episode_ends is not None
                  else [False] * space.count)
        clauses = [space.evaluate(c.guard) for c in automaton.end_clauses]
        seen: dict[tuple, tuple] = {}
        for cls in map(int, space.valid.nonzero()[0]):
            taken = next((e for e, mask in zip(edges, enabled) if mask[cls]), None)
            box = tuple((name, space.piece(cls, name)) for name in relevant)
            # A sample that ends the run is an outcome of its own, one per set of end clauses its inputs enable.
            ends = tuple(i for i, mask in enumerate(clauses) if mask[cls]) if ending[cls] else None
            key = (id(taken), box, bool(ending[cls]), ends)
            if key in seen and _intervals(space, seen[key][1]) >= _intervals(space, cls):
                continue
            edge_map = from_assignments(taken.updates, automaton.rewards) if taken else identity(len(automaton.rewards))
            end = None
            if ends is not None:
                end_map = identity(len(automaton.rewards))
                for i in ends:
                    end_map = then(end_map, from_assignments(automaton.end_clauses[i].updates, automaton.rewards))
                end = (cls, ends, box, end_map)
            seen[key] = (index, cls, taken, taken.target if taken else index, box, edge_map, bool(ending[cls]), end)
        result.append(list(seen.values()))
    return result


def reference_end_outcomes(automaton: ir.Automaton, space: InputSpace) -> list[tuple]:
    relevant = arithmetic_inputs(automaton)
    enabled = [space.evaluate(c.guard) for c in automaton.end_clauses]
    seen: dict[tuple, tuple] = {}
    for cls in map(int, space.valid.nonzero()[0]):
        ends = tuple(i for i, mask in enumerate(enabled) if mask[cls])
        box = tuple((name, space.piece(cls, name)) for name in relevant)
        if (ends, box) in seen and _intervals(space, seen[(ends, box)][0]) >= _intervals(space, cls):
            continue
        end_map = identity(len(automaton.rewards))
        for i in ends:
            end_map = then(end_map, from_assignments(automaton.end_clauses[i].updates, automaton.rewards))
        seen[(ends, box)] = (cls, ends, box, end_map)
    return list(seen.values())


@SETTINGS
@given(cases(general=True))
def test_grouped_outcomes_match_the_class_by_class_loop(case: Case) -> None:
    automaton = case.automaton
    space = InputSpace(automaton)
    reachable = distances(automaton, space)
    expected = reference_outcomes(automaton, space)
    found = outcomes(automaton, space, reachable)
    for index, (want, got) in enumerate(zip(expected, found)):
        if index not in reachable:
            assert got == []  # no run is there: nothing to analyse
            continue
        assert [(o.source, o.cls, o.edge, o.target, o.box, o.edge_map, o.ends_episode,
                 o.ending and (o.ending.cls, o.ending.ends, o.ending.box, o.ending.end_map)) for o in got] == want
    assert [(e.cls, e.ends, e.box, e.end_map) for e in end_outcomes(automaton, space)] == \
        reference_end_outcomes(automaton, space)


@SETTINGS
@given(cases())
def test_atom_tables_by_bisection_match_each_piece(case: Case) -> None:
    space = InputSpace(case.automaton)
    for guard in [e.guard for e in case.automaton.all_edges()]:
        for atom in ir.guard_leaves(guard):
            if isinstance(atom, ir.BAtom):
                integral = case.automaton.input(atom.input).kind == "int"
                expected = [ir.compare(p.representative(integral), atom.op, atom.threshold)
                            for p in space.pieces[atom.input]]
                assert space._atom_table(atom).tolist() == expected


# ---------------------------------------------------------------- the sample limit
@SETTINGS
@given(cases())
def test_a_limited_search_finishes_with_the_same_answer_or_says_it_did_not(case: Case) -> None:
    automaton = case.automaton
    outs = moves(automaton, InputSpace(automaton))
    full = maximise(automaton, outs, case.target)
    limit = worst_module.MAX_SAMPLES
    try:
        worst_module.MAX_SAMPLES = 2  # the generated horizons have 1 to 5 samples
        try:
            limited = maximise(automaton, outs, case.target)
        except Unfinished:
            assert automaton.steps > 2 or (full is not None and len(full.steps) > 2)
            return
    finally:
        worst_module.MAX_SAMPLES = limit
    assert (limited is None) == (full is None)
    if full is not None and limited is not None:
        assert limited.value == full.value
        assert [(s.sample, s.outcome, s.inputs, s.instant) for s in limited.steps] == \
            [(s.sample, s.outcome, s.inputs, s.instant) for s in full.steps]
        assert (limited.instant, limited.end, limited.end_inputs) == (full.instant, full.end, full.end_inputs)


GROWING = """\
automaton Driving {
    input isClose : bool
    reward sa, pr
    priority sa > pr
    objective 10*sa + pr
    sample every 0.1
    horizon 30
    initial location Normal { sa' == 1;  pr' == 1 }
    location Unsafe         { sa' == -1; pr' == 0 }
    edge Normal -> Unsafe when isClose  do sa = sa - 100
    edge Unsafe -> Normal when !isClose
}
"""


def compiled(text: str) -> ir.Automaton:
    result = compile_text(text, "test.ra", analyse=False)
    assert result.automaton is not None, result.diagnostics
    return result.automaton


def test_past_the_limit_p2_and_the_range_are_reported_unchecked(monkeypatch: pytest.MonkeyPatch) -> None:
    automaton = compiled(GROWING)  # 300 samples; the objective grows with every sample in Normal
    assert check_priorities(automaton) == []  # P2 holds at 30 s
    monkeypatch.setattr(worst_module, "MAX_SAMPLES", 100)
    facts: list[Fact] = []
    (p2,) = check_priorities(automaton, facts)
    assert (p2.code, p2.severity.value, p2.message) == (
        "W0405", "warning", "P2 for `sa` not checked: the horizon has 300 samples and the worst value "
        "still changes after 100 of them")
    assert not any(f.message.startswith("P2 holds") for f in facts)  # not a proof
    (rng,) = check_ranges(automaton, facts=facts)
    assert rng.code == "W0405" and "int32 range" in rng.message
    assert not any(f.message.startswith("int32 range holds") for f in facts)


def test_settled_values_are_checked_beyond_the_limit(monkeypatch: pytest.MonkeyPatch) -> None:
    # Normal accrues nothing, so the worst values settle after a few samples: P2 is proved at
    # 300 samples with a limit of 100, with the same bound as without the limit.
    text = GROWING.replace("initial location Normal { sa' == 1;  pr' == 1 }",
                           "initial location Normal { sa' == 0;  pr' == 0 }")
    automaton = compiled(text)
    facts: list[Fact] = []
    assert check_priorities(automaton, facts) == []
    monkeypatch.setattr(worst_module, "MAX_SAMPLES", 100)
    limited: list[Fact] = []
    assert check_priorities(automaton, limited) == []
    assert limited == facts and any(f.message.startswith("P2 holds for `sa`") for f in facts)


def test_a_refutation_within_the_limit_is_unchanged(monkeypatch: pytest.MonkeyPatch) -> None:
    text = GROWING.replace("sa = sa - 100", "sa = sa - 30")  # P2 fails: 30 s of progress outweigh 30
    automaton = compiled(text)
    (before,) = check_priorities(automaton)
    monkeypatch.setattr(worst_module, "MAX_SAMPLES", 1000)
    (after,) = check_priorities(automaton)
    assert before.code == "E0402" and after == before


def test_unreachable_locations_have_no_outcomes() -> None:
    # 50 locations behind contradictory guards: none is analysed (this used to cost a pass over
    # every input class per location, twice).
    lines = ["automaton Many {", "    input d : real in [0, 100]", "    reward sa", "    objective sa",
             "    sample every 0.1", "    horizon 30", "    initial location Start { sa' == 1 }"]
    lines += [f"    location L{i} {{ sa' == -1 }}" for i in range(50)]
    lines += [f"    edge Start -> L{i} when d < 10 && d > {20 + i}" for i in range(50)]
    lines += [f"    edge L{i} -> Start when d > {i}" for i in range(50)]
    automaton = compiled("\n".join(lines) + "\n}\n")
    outs = moves(automaton, InputSpace(automaton))
    assert len(outs.samples[0]) == 1 and all(not os for os in outs.samples[1:])
    everywhere = tuple(True for _ in automaton.locations)
    worst = maximise(automaton, outs, Target((Fraction(1),), Fraction(0), everywhere))
    assert worst is not None and worst.value == 30


def test_a_violation_within_the_limit_is_reported_past_it(monkeypatch: pytest.MonkeyPatch) -> None:
    # With the limit at 100 samples and a horizon of 300, the searches stop (the worst values keep
    # changing), but a run of 100 samples is a run of the horizon: a violation among them is an
    # error, with a note saying where it was found, never "not checked" (W0405).
    monkeypatch.setattr(worst_module, "MAX_SAMPLES", 100)
    facts: list[Fact] = []
    # P2: 10 s of progress (110) outweigh a penalty of 5 (50).
    (p2,) = check_priorities(compiled(GROWING.replace("sa = sa - 100", "sa = sa - 5")), facts)
    assert p2.code == "E0402" and p2.severity.value == "error"
    assert any("first 100 samples (of 300)" in note.message for note in p2.notes)
    # int32: re-entering Unsafe costs 10,000 every other sample, beyond ±214,748 within 100 samples.
    (rng,) = check_ranges(compiled(GROWING.replace("sa = sa - 100", "sa = sa - 10000")), facts=facts)
    assert rng.code == "E0501" and "`sa` overflows int32" in rng.message
    assert any("first 100 samples (of 300)" in note.message for note in rng.notes)
    assert not any(f.message.startswith(("P2 holds", "int32 range holds")) for f in facts)


def test_past_the_limit_a_range_that_holds_there_stays_unchecked(monkeypatch: pytest.MonkeyPatch) -> None:
    # Rewards grow by 1 a second: nothing overflows within the first 100 samples, so the range
    # check past the limit stays W0405 (one warning, however many rewards stopped).
    automaton = compiled(GROWING)
    monkeypatch.setattr(worst_module, "MAX_SAMPLES", 100)
    facts: list[Fact] = []
    assert [d.code for d in check_ranges(automaton, facts=facts)] == ["W0405"]
    assert not any(f.message.startswith("int32 range holds") for f in facts)
