"""Reachability on the fly in ``rac verify`` (issue 20, rac.verify.reach): the run that decides a query
— the witness of ``E<>`` and ``E[]``, the counterexample of ``A[]`` and ``A<>`` — is looked for before
anything is built in full, and said so (``method``).

- On the obstacle-free boulevard (rac.model.scenes ``urban``, 14 s) the layered search finds Qc's
  witness at sample 70 after some 24,000 states; the whole pruned model has millions.
- On the head-on street (``urban_head_on``, 21 s, goal window at samples 194-204) breadth-first is
  beyond any budget; the beam nearest the goal finds a witness.
- On every tiny scenario and query form, the verdicts of the cheap searches, of the layered search
  and of Storm on the complete graph agree; on the examples, the engine's searches agree with Storm.
- A witness that does not replay with the scalar model is an internal error; "not satisfied" (for
  ``E<>``; "satisfied" for ``A[]``) comes only from a complete graph; JSON says the method.
"""

from __future__ import annotations

import dataclasses
import json
import re
import time
from collections.abc import Callable
from fractions import Fraction
from pathlib import Path

import numpy as np
import pytest
from engine_files import QUERIES, safety_source, write_engine_file
from tiny_scenarios import TINY_SCENARIOS

import rac.verify.reach as reach_module
from rac.cli.common import EXIT_INTERNAL
from rac.cli.main import main
from rac.compiler import CompileResult, compile_file
from rac.engine import storm
from rac.engine.budget import BudgetExceeded
from rac.engine.explore import explore
from rac.engine.witness import Bounds, Found, search
from rac.model.batch import batch_model
from rac.model.sample import EGO
from rac.model.scenes import write_scene
from rac.verify.context import Context, VerifyOptions
from rac.verify.runner import run_queries

REPO = Path(__file__).resolve().parents[2]
#: examples/paper/model.ra's model settings (a decision every 2 s, 3 x 3 actions, left turns only).
PAPER_MODEL = """\
exponent 2
decide_period 2
granularity 0.05
action jerk in [-2, 2] step 2
action turn in [0, 0.4] step 0.2
bind close = mindist() < 3 * collision_distance
"""
QC = "E<> !collide() && !offroad() && goal()"
#: No cheap search: only the layered search and the complete graph.
NO_SEARCH = Bounds(runs=0, width=0)


def scene_file(folder: Path, scene: str, horizon: int, queries: dict[str, str]) -> CompileResult:
    write_scene(scene, folder / f"{scene}.xml")
    path = folder / f"{scene}.ra"
    path.write_text(safety_source("Scene", horizon, f'scenario "{scene}.xml"\n' + PAPER_MODEL, queries),
                    encoding="utf-8")
    result = compile_file(path)
    assert result.ok, result.diagnostics
    return result


def answers(result: CompileResult, **options: object) -> dict[str, object]:
    settings: dict[str, object] = {"seed": 1, "plots": False, **options}
    return {r.name: r for r in run_queries(result, VerifyOptions(**settings))[1]}  # type: ignore[arg-type]


# ---------------------------------------------------------------- the scenes of the issue
def test_qc_is_found_on_the_fly_long_before_the_whole_model_is_built(tmp_path: Path) -> None:
    result = scene_file(tmp_path, "urban", 14, {"Qc": QC})
    assert result.model_data is not None
    with pytest.raises(BudgetExceeded):  # the whole pruned model: beyond 200,000 states (5 million in all)
        explore(result.model_data, horizon_samples=140, prune_unsafe=True, max_states=200_000)
    layered = answers(result, witness=NO_SEARCH, max_states=200_000)["Qc"]
    assert (layered.status, layered.method) == ("satisfied", "on the fly")  # type: ignore[attr-defined]
    assert layered.states < 30_000  # type: ignore[attr-defined]
    trace = layered.trace  # type: ignore[attr-defined]
    assert len(trace) == 71 and trace[-1]["goal"] and trace[-1]["time"] == 7.0  # the first layer with a witness
    assert not any(row["collide"] or row["offroad"] for row in trace)
    cheap = answers(result, max_states=200_000)["Qc"]
    assert (cheap.status, cheap.method) == ("satisfied", "witness search")  # type: ignore[attr-defined]
    assert "a run that stays safe until it gets there exists" in cheap.message  # type: ignore[attr-defined]


def test_the_beam_finds_the_head_on_witness_breadth_first_cannot(tmp_path: Path) -> None:
    result = scene_file(tmp_path, "urban_head_on", 21, {"Qc": QC})
    found = answers(result, max_states=1_000_000)["Qc"]
    assert (found.status, found.method) == ("satisfied", "witness search")  # type: ignore[attr-defined]
    last = found.trace[-1]  # type: ignore[attr-defined]
    assert last["goal"] and 19.4 <= last["time"] <= 20.4
    assert not any(row["collide"] or row["offroad"] for row in found.trace)  # type: ignore[attr-defined]
    layered = answers(result, witness=NO_SEARCH, max_states=1_000_000)["Qc"]
    assert layered.status == "unknown"  # type: ignore[attr-defined]
    assert "more than 1,000,000 states" in layered.message  # type: ignore[attr-defined]
    assert "no witness was found by 0 random runs" in layered.message  # type: ignore[attr-defined]


# ---------------------------------------------------------------- agreement
#: Model-level queries of every form the searches decide (and their negations' forms).
FORMS = {
    "Qc": QC, "Crash": "E<> collide()", "Off": "E<> offroad()", "Fast": "E<> v >= 9", "Never": "E<> v >= 99",
    "NoCrash": "A[] !collide()", "Safe": "A[] !collide() && !offroad()", "Slow": "A[] v <= 9",
    "Qb": "E[] !collide() && !offroad()", "Keeps": "E[] v > 7", "Goal": "A<> goal()", "Brakes": "A<> v < 7",
    "Reach": "strategy r = control: E<> goal()",
}


def oracle(result: CompileResult, text: str) -> bool:
    """Storm on the complete, unpruned graph: the verdict by brute force."""
    context = Context(result, VerifyOptions(seed=1))
    graph = explore(context.data, horizon_samples=context.horizon_samples)
    query = result.raise_for_errors().queries[[d.text for d in result.raise_for_errors().queries].index(text)].query
    kind = "E<>" if text.startswith("strategy") else query.quantifier  # type: ignore[attr-defined]
    labelled = dataclasses.replace(graph, labels={**graph.labels, "q": context.label(graph, query.expr)})  # type: ignore[attr-defined]
    return storm.decide(labelled, kind, "q").holds


@pytest.mark.parametrize("name", sorted(TINY_SCENARIOS))
def test_the_searches_agree_with_storm_on_the_complete_graph(name: str, tmp_path: Path) -> None:
    result = compile_file(write_engine_file(tmp_path, name, FORMS))
    assert result.ok, result.diagnostics
    cheap = answers(result)
    layered = answers(result, witness=NO_SEARCH)
    narrow = answers(result, witness=Bounds(runs=1, width=1))
    for query, text in FORMS.items():
        expected = "satisfied" if oracle(result, text) else "not satisfied"
        for how, got in (("cheap", cheap), ("layered", layered), ("narrow", narrow)):
            answer = got[query]
            assert answer.status == expected, (query, how, answer.message)  # type: ignore[attr-defined]
            assert answer.method in ("witness search", "on the fly", "exhaustive", "initial state"), (query, how)  # type: ignore[attr-defined]
            if how == "layered":
                assert answer.method != "witness search"  # type: ignore[attr-defined]
            if answer.trace:  # type: ignore[attr-defined]
                assert answer.trace[0]["time"] == 0  # type: ignore[attr-defined]


EXAMPLES = sorted(REPO.glob("examples/**/model.ra"))


@pytest.mark.parametrize("path", EXAMPLES, ids=[str(p.relative_to(REPO)) for p in EXAMPLES])
def test_the_searches_agree_with_storm_on_the_examples(path: Path) -> None:
    """Each example's model over two decisions: a safe run into the goal, a collision, leaving the road,
    a run safe to the end — found by the cheap search exactly when Storm finds it on the complete graph,
    and without a witness proved absent only by a complete beam."""
    result = compile_file(path)
    data = result.model_data
    assert data is not None
    horizon = 2 * data.decide_every
    model = batch_model(data)
    graph = explore(data, horizon_samples=horizon)

    def safe(k: int, rows: np.ndarray) -> np.ndarray:
        return ~model.collide(rows[:, :7], k) & ~model.offroad(rows[:, :7], k)

    targets: dict[str, tuple[Callable[[int, np.ndarray], np.ndarray], bool]] = {
        "goal": (lambda k, rows: safe(k, rows) & model.goal(rows[:, :7], k), True),
        "collide": (lambda k, rows: model.collide(rows[:, :7], k), False),
        "offroad": (lambda k, rows: model.offroad(rows[:, :7], k), False),
        "fast": (lambda k, rows: rows[:, 2] >= data.ego_v + data.scale, False),
    }
    for name, (target, prune) in targets.items():
        pruned = explore(data, horizon_samples=horizon, prune_unsafe=True) if prune else graph
        labelled = dataclasses.replace(pruned, labels={**pruned.labels, "t": reach_module.in_graph(pruned, target)})
        expected = storm.decide(labelled, "E<>", "t").holds
        found = search(data, target, horizon_samples=horizon, seed=3, prune_unsafe=prune,
                       bounds=Bounds(runs=50, width=200))
        if found.witness is not None:
            assert expected, name
        elif found.proves_absence:
            assert not expected, name
        else:  # the beam was cut: nothing proved; the layered search decides
            layered = reach_module.layered_search(data, target, horizon_samples=horizon, prune_unsafe=prune)
            assert (layered.witness is not None) == expected, name


# ---------------------------------------------------------------- what a verdict rests on
def test_a_witness_that_does_not_replay_is_an_internal_error(tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                                             capsys: pytest.CaptureFixture[str]) -> None:
    path = write_engine_file(tmp_path, "goal_ahead", {"Reaches": QUERIES["Reaches"]})
    real = reach_module.search

    def tampered(*args: object, **kwargs: object) -> Found:
        found = real(*args, **kwargs)  # type: ignore[arg-type]
        assert found.witness is not None
        states = found.witness.states.copy()
        states[3, 2] += 1  # y off by a centimetre at sample 3
        return dataclasses.replace(found, witness=dataclasses.replace(found.witness, states=states))

    monkeypatch.setattr(reach_module, "search", tampered)
    assert main(["verify", str(path), "-q"]) == EXIT_INTERNAL
    err = capsys.readouterr().err
    assert "rac: internal error: ReplayMismatch: the witness found by" in err
    assert "does not replay with the scalar model (rac.model.native) at sample 3: the search has" in err


def test_no_witness_is_a_verdict_only_on_a_complete_graph(tmp_path: Path) -> None:
    """``E<> v >= 99`` cannot hold (speeds end at 10 m/s) and ``A[] v < 99`` holds: a narrow beam that
    finds nothing proves neither; beyond the budget both are unknown, within it both are decided."""
    path = write_engine_file(tmp_path, "goal_ahead", {"Never": "E<> v >= 99", "Always": "A[] v < 99"})
    result = compile_file(path)
    small = answers(result, witness=Bounds(runs=1, width=1), max_states=20)
    for query in ("Never", "Always"):
        assert small[query].status == "unknown", small[query]  # type: ignore[attr-defined]
        assert "no witness was found" in small[query].message  # type: ignore[attr-defined]
    decided = answers(result, witness=Bounds(runs=1, width=1))
    assert {q: (r.status, r.method) for q, r in decided.items()} == {  # type: ignore[attr-defined]
        "Never": ("not satisfied", "exhaustive"), "Always": ("satisfied", "exhaustive")}
    # the answerer refuses to decide on an incomplete graph
    from rac.verify.symbolic import SymbolicAnswerer

    context = Context(result, VerifyOptions(seed=1))
    cut = explore(context.data, horizon_samples=context.horizon_samples, beam=lambda k, rows: np.arange(1))
    assert not cut.complete
    query = result.raise_for_errors().queries[0]
    with pytest.raises(AssertionError, match="complete graph"):
        SymbolicAnswerer(context)._decided(query.query, None, cut)  # type: ignore[arg-type]


def test_json_says_how_each_verdict_was_reached(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = write_engine_file(tmp_path, "goal_ahead", {"Reaches": QUERIES["Reaches"], "Never": "E<> v >= 99",
                                                      "safe": QUERIES["safe"], "LeadsTo": QUERIES["LeadsTo"]})
    main(["verify", str(path), "--format", "json", "--seed", "1", "-o", str(tmp_path / "o")])
    methods = {r["name"]: r["method"] for r in json.loads(capsys.readouterr().out)["results"]}
    assert methods == {"Reaches": "witness search", "Never": "exhaustive", "safe": "exhaustive",
                       "LeadsTo": "exhaustive"}
    main(["verify", str(path), "--seed", "1", "-o", str(tmp_path / "o"), "--query", "Reaches"])
    assert "    found by a bounded witness search and replayed\n" in capsys.readouterr().out


def test_a_search_does_not_change_the_seeds_of_later_queries(tmp_path: Path) -> None:
    queries = {"Prob": QUERIES["Prob"]}
    alone = compile_file(write_engine_file(tmp_path, "goal_ahead", queries, ra_name="alone"))
    after = compile_file(write_engine_file(tmp_path, "goal_ahead", {"Reaches": QUERIES["Reaches"], **queries},
                                           ra_name="after"))
    assert answers(alone)["Prob"].seed == answers(after)["Prob"].seed  # type: ignore[attr-defined]


def test_the_horizon_option_reaches_the_searches(tmp_path: Path) -> None:
    path = write_engine_file(tmp_path, "goal_ahead", {"Reaches": QUERIES["Reaches"]})
    short = answers(compile_file(path), horizon=Fraction(1))["Reaches"]
    assert (short.status, short.method) == ("not satisfied", "exhaustive")  # type: ignore[attr-defined]


def test_the_witness_search_keeps_within_max_memory(tmp_path: Path) -> None:
    """The beam's graph was bounded by its work budget alone (some 150 MB at 2 million states), never by
    --max-memory: a limit below that was exceeded. Now the beam stops at the limit, the verdict stays
    unknown, and the message says which limit cut the search (not an error)."""
    result = compile_file(write_engine_file(tmp_path, "goal_ahead", {"Never": "E<> v >= 99"}))
    unbounded = answers(result, witness=Bounds(runs=0))["Never"]
    assert (unbounded.status, unbounded.method) == ("not satisfied", "exhaustive")  # type: ignore[attr-defined]
    cut = answers(result, witness=Bounds(runs=0), max_bytes=20_000)["Never"]
    assert cut.status == "unknown"  # type: ignore[attr-defined]
    assert "a beam search (73 states, cut short by --max-memory)" in cut.message  # type: ignore[attr-defined]
    context = Context(result, VerifyOptions(seed=1))
    found = search(context.data, lambda k, rows: rows[:, 0] < -1, horizon_samples=context.horizon_samples, seed=1,
                   bounds=Bounds(runs=0, max_bytes=20_000))
    assert found.out_of_memory and found.witness is None and not found.proves_absence and found.states > 0


def test_an_unknown_verdict_counts_the_random_runs_made_not_those_asked_for(tmp_path: Path) -> None:
    """An unknown verdict's message said "no witness was found by 2,000 random runs" (the option's count)
    even where --max-memory left room for none, the search's time was up after a batch, or its budget
    of states left room for two: it now says how many were made, of how many, and what stopped them."""
    from rac.engine.witness import random_runs

    result = compile_file(write_engine_file(tmp_path, "goal_ahead", {"Never": "E<> v >= 99"}))
    context = Context(result, VerifyOptions(seed=1))
    horizon = context.horizon_samples
    per_run = (horizon + 1) * (7 * 4 + 8)  # a run's states (goal_ahead's 7 ego columns) and choices

    def never(k: int, rows: np.ndarray) -> np.ndarray:
        return np.zeros(rows.shape[0], dtype=bool)

    assert random_runs(context.data, never, horizon_samples=horizon, runs=10, seed=1, max_bytes=3 * per_run).runs == 10
    assert random_runs(context.data, never, horizon_samples=horizon, runs=10, seed=1, max_bytes=per_run - 1).runs == 0
    cut = random_runs(context.data, never, horizon_samples=horizon, runs=10, seed=1, max_bytes=3 * per_run,
                      deadline=time.perf_counter())  # past after the first batch: no other
    assert cut.timed_out and cut.runs == 3
    none = answers(result, max_bytes=per_run - 1)["Never"]
    assert none.status == "unknown"  # type: ignore[attr-defined]
    assert "; no random run fitted in --max-memory and a beam search (" in none.message  # type: ignore[attr-defined]
    assert "random runs" not in none.message  # type: ignore[attr-defined]
    timed = answers(result, witness=Bounds(safety_seconds=0), max_bytes=30 * per_run)["Never"]
    assert timed.status == "unknown"  # type: ignore[attr-defined]
    made = re.search(r"no witness was found by (\d+) of 2,000 random runs \(cut short by a time limit\) and a beam",
                     timed.message)  # type: ignore[attr-defined]
    assert made is not None and 0 < int(made[1]) <= 30, timed.message  # type: ignore[attr-defined]
    capped = answers(result, max_states=20)["Never"]
    assert capped.status == "unknown"  # type: ignore[attr-defined]
    assert ("no witness was found by 2 of 2,000 random runs (as many as a budget of 20 states leaves room for) "
            "and a beam search (") in capped.message  # type: ignore[attr-defined]
    whole = answers(result, witness=Bounds(runs=30), max_bytes=30 * per_run)["Never"]  # all made: as before
    assert "no witness was found by 30 random runs and a beam search (" in whole.message  # type: ignore[attr-defined]


def test_the_continuation_of_a_witness_honours_the_time_limit(tmp_path: Path) -> None:
    """Whether a safe run to the goal also stays safe to the horizon is looked for by random runs (two
    batches of 2,000, about a second) that never read --max-seconds. They now stop at the query's limit,
    and the note says that the limit, not the runs, left it open."""
    from rac.engine.budget import TimeLimit
    from rac.verify.reach import Reacher
    from rac.verify.symbolic import SymbolicAnswerer

    result = compile_file(write_engine_file(tmp_path, "goal_ahead", {"Qc": QC}))
    context = Context(result, VerifyOptions(seed=1))
    goal = batch_model(context.data)

    def target(k: int, rows: np.ndarray) -> np.ndarray:
        return np.asarray(goal.goal(rows[:, EGO], k), dtype=bool)

    reached = Reacher(context).find(target, prune=True, exhaustive=False)
    assert reached is not None and reached.witness is not None
    free = Reacher(context).continues_safely(reached.witness, target)
    assert free.witness is not None and not free.timed_out
    context.limit = TimeLimit(1.0, started=time.perf_counter() - 2.0)  # the query's time is up
    late = Reacher(context).continues_safely(reached.witness, target)
    assert late.witness is None and late.timed_out and late.states == 0
    meaning = SymbolicAnswerer(context)._safe_meaning(target, reached.witness)
    assert "is not known: the random runs that look for one were cut short by --max-seconds" in meaning


def test_random_runs_hold_no_more_runs_at_once_than_max_memory_leaves_room_for(tmp_path: Path) -> None:
    """The random runs keep a batch's runs whole (1,000 runs x every sample to the horizon): the
    continuation of a witness, not capped by the searches' 2 million states, would hold 1,000 runs of a
    300,000-sample horizon (some 12 GB) whatever --max-memory said. A batch now holds what fits; where
    not one run fits none is made, and the note says so."""
    from rac.engine.witness import random_runs
    from rac.verify.reach import Reacher
    from rac.verify.symbolic import SymbolicAnswerer

    result = compile_file(write_engine_file(tmp_path, "goal_ahead", {"Qc": QC}))
    context = Context(result, VerifyOptions(seed=1))
    data, horizon = context.data, context.horizon_samples
    model = batch_model(data)

    def target(k: int, rows: np.ndarray) -> np.ndarray:
        return np.asarray(model.goal(rows[:, EGO], k), dtype=bool)

    def never(k: int, rows: np.ndarray) -> np.ndarray:
        return np.zeros(rows.shape[0], dtype=bool)

    per_run = (horizon + 1) * (7 * 4 + 8)  # goal_ahead's rows: the 7 ego columns
    whole = random_runs(data, never, horizon_samples=horizon, runs=10, seed=1)
    small = random_runs(data, never, horizon_samples=horizon, runs=10, seed=1, max_bytes=3 * per_run)
    assert not whole.out_of_memory and not small.out_of_memory and small.states == whole.states
    none = random_runs(data, never, horizon_samples=horizon, runs=10, seed=1, max_bytes=per_run - 1)
    assert none.out_of_memory and none.states == 0 and none.witness is None and none.runs == 0
    reached = Reacher(context).find(target, prune=True, exhaustive=False)
    assert reached is not None and reached.witness is not None
    context.options = dataclasses.replace(context.options, max_bytes=20)  # not one sample's state and choice
    assert Reacher(context).continues_safely(reached.witness, target).out_of_memory
    meaning = SymbolicAnswerer(context)._safe_meaning(target, reached.witness)
    assert "is not known: not one random run to the horizon fits in --max-memory" in meaning
