"""``rac.verify.runner``: the driver that answers a file's queries with the native engine.

On the tiny scenarios of :mod:`tiny_scenarios` (known answers by construction): Qb, Qc and the
safety shield (Qd) equal the known answers, witness traces start at the ego's start and advance
one period per row, the saved shield reads back with :func:`rac.engine.shield.load` and allows exactly
the known actions at the start, queries ``under`` it, product queries over the automaton's
location and reward, the statistical queries (intervals, run counts, sequential tests, means,
simulated CSV files), seeds, the state budget, query selection and the renderers.
"""

from __future__ import annotations

import csv
import dataclasses
import itertools
import json
import math
import time
from collections.abc import Callable, Sequence
from fractions import Fraction
from pathlib import Path

import numpy as np
import pytest
from engine_files import QUERIES, engine_source, write_engine_file
from tiny_scenarios import TINY_SCENARIOS, TinyScenario

from rac.compiler import CompileResult, compile_file
from rac.core.diagnostics import CheckError
from rac.engine import shield
from rac.engine.budget import TimeExceeded, TimeLimit, runs_within, simulation_bytes
from rac.engine.explore import action_pairs
from rac.engine.witness import Bounds
from rac.model import NativeModel
from rac.verify import reach
from rac.verify.context import Context, UnknownVerdict
from rac.verify.runner import (
    QueryResult,
    UnknownQuery,
    VerifyOptions,
    render_json,
    render_text,
    run_queries,
    standard_queries,
    verify,
)
from rac.verify.statistical import StatisticalAnswerer
from rac.verify.symbolic import SymbolicAnswerer

NAMES = tuple(TINY_SCENARIOS)
#: Qc as `rac verify` reads it (UPPAAL's literal reading: a collision does not end a run, so a run
#: may pass through the wall or the van and still reach the goal).
LITERAL_QC = {"narrow_road": "not satisfied", "avoidable_obstacle": "satisfied", "goal_behind_wall": "satisfied",
              "goal_ahead": "satisfied"}


@dataclasses.dataclass(frozen=True)
class Compiled:
    """A tiny scenario's engine test file, compiled, with its folder."""

    tiny: TinyScenario
    result: CompileResult
    folder: Path


@pytest.fixture(scope="module")
def compiled(tmp_path_factory: pytest.TempPathFactory) -> Callable[[str], Compiled]:
    """``compiled(name)``: the engine test file (tests/support/engine_files.py) for a tiny scenario, compiled
    (cached)."""
    cache: dict[str, Compiled] = {}

    def get(name: str) -> Compiled:
        if name not in cache:
            folder = tmp_path_factory.mktemp(name)
            path = write_engine_file(folder, name)
            result = compile_file(path)
            assert result.ok and result.model_data is not None, result.diagnostics
            cache[name] = Compiled(TINY_SCENARIOS[name](), result, folder)
        return cache[name]

    return get


def run(item: Compiled, *names: str, out: Path | None = None, **options: object) -> dict[str, QueryResult]:
    """The named queries verified (plots off, seed 1 unless given), by name."""
    settings: dict[str, object] = {"seed": 1, "plots": False, "out_dir": out, "only": names or None, **options}
    results = verify(item.result, VerifyOptions(**settings))  # type: ignore[arg-type]
    return {r.name: r for r in results}


def assert_trace_is_a_run(item: Compiled, trace: Sequence[dict[str, object]], *, product: bool = False) -> None:
    """The trace starts at the ego's start at time 0 and advances by one period per (sampled) row."""
    data = item.result.model_data
    assert data is not None
    scale, period = data.scale, float(item.tiny.settings.sense_period)
    start = NativeModel(data).initial_state()
    first = trace[0]
    assert first["time"] == 0
    assert (first["x"], first["y"], first["v"], first["head"]) == (start.x / scale, start.y / scale,
                                                                  start.v / scale, start.head / scale)
    rows = [row for row in trace if row.get("phase", "sampled") == "sampled"] if product else list(trace)
    assert [row["time"] for row in rows] == pytest.approx([k * period for k in range(len(rows))])
    if product:  # an `accrued` row comes just before the sampled row of the same time
        for before, after in zip(trace, trace[1:]):
            if after.get("phase") == "sampled" and after["time"] != 0:
                assert before["phase"] == "accrued" and before["time"] == after["time"]


# ---------------------------------------------------------------- known answers
@pytest.mark.parametrize("name", NAMES)
def test_qb_qc_and_the_shield_are_the_known_answers(name: str, compiled: Callable[[str], Compiled],
                                                    tmp_path: Path) -> None:
    item = compiled(name)
    tiny, horizon = item.tiny, item.tiny.settings.horizon_samples
    results = run(item, "Stays", "Reaches", "safe", "Shielded", out=tmp_path)
    assert list(results) == ["Stays", "Reaches", "safe", "Shielded"]  # file order

    qb = results["Stays"]
    assert qb.kind == "symbolic" and qb.horizon_samples == horizon
    assert qb.status == ("satisfied" if tiny.stays_safe else "not satisfied")
    if tiny.stays_safe:  # a witness: a whole run to the horizon, never unsafe
        assert qb.trace is not None and len(qb.trace) == horizon + 1
        assert_trace_is_a_run(item, qb.trace)
        assert not any(row["collide"] or row["offroad"] for row in qb.trace)
    else:
        assert qb.trace is None

    qc = results["Reaches"]
    assert qc.status == LITERAL_QC[name]
    if tiny.reaches_goal:  # a safe run reaches the goal: found on the pruned model, and said so
        assert qc.message is not None and "a run that stays safe until it gets there exists" in qc.message
    elif qc.status == "satisfied":  # only through a collision: verify says so
        assert qc.message is not None and "a collision does not end a run" in qc.message
        assert "NO run that stays safe until it gets there exists" in qc.message
        assert qc.trace is not None and any(row["collide"] or row["offroad"] for row in qc.trace[:-1])
    if qc.trace is not None:
        assert_trace_is_a_run(item, qc.trace)
        last = qc.trace[-1]
        assert last["goal"] and not last["collide"] and not last["offroad"]

    qd = results["safe"]
    assert qd.kind == "strategy" and qd.status == ("satisfied" if tiny.stays_safe else "not satisfied")
    if tiny.stays_safe:
        assert qd.files == (str(tmp_path / "safe.shield.npz"),)
        table = shield.load(tmp_path / "safe.shield.npz")
        data = item.result.model_data
        assert data is not None
        start = [0, *NativeModel(data).initial_state()]
        pairs = action_pairs(data).tolist()
        allowed = {tuple(pairs[a]) for a in table.allowed(start)}
        expected = {(math.trunc(jerk * data.scale), math.trunc(turn * data.scale))
                    for jerk, turn in tiny.start_actions}
        assert allowed == expected
        assert table.knows(start)
    else:  # no strategy exists: nothing is saved (UPPAAL defines no strategy either)
        assert qd.files == () and not (tmp_path / "safe.shield.npz").exists()

    shielded = results["Shielded"]
    if tiny.stays_safe:
        assert shielded.status == "satisfied"
    else:  # no strategy to follow: as in UPPAAL, the query cannot use it
        assert shielded.status == "not_applicable" and "does not exist" in (shielded.message or "")


def test_a_query_under_a_strategy_is_answered_on_the_shielded_graph(compiled: Callable[[str], Compiled]) -> None:
    """Unshielded, the ego can hit the van; under the shield it cannot (and `only` keeps the strategy)."""
    item = compiled("avoidable_obstacle")
    tiny = item.tiny
    path = item.folder / "under.ra"
    path.write_text(engine_source(tiny, {"Free": "A[] !collide()", "safe": QUERIES["safe"],
                                         "Kept": "A[] !collide() && !offroad() under safe",
                                         "Stuck": "A[] v > 0 under safe"}, scenario_file="avoidable_obstacle.xml"))
    result = compile_file(path)
    results = verify(result, VerifyOptions(only=("Free", "Kept", "Stuck")))
    assert [r.name for r in results] == ["Free", "safe", "Kept", "Stuck"]
    status = {r.name: r.status for r in results}
    assert status == {"Free": "not satisfied", "safe": "satisfied", "Kept": "satisfied", "Stuck": "not satisfied"}
    stuck = results[-1]  # the shield brakes to a stop: a counter-example ending at v = 0
    assert stuck.trace is not None and stuck.trace[-1]["v"] == 0


def test_leads_to_and_control_under_a_shield(compiled: Callable[[str], Compiled]) -> None:
    """`-->` and `control:` under a shield are answered on the graph the shield allows (not ignored):
    unshielded, the ego can hit the van and stay on the road; under the shield it never collides, so
    `collide() --> offroad()` holds vacuously, and the strategy within the shield is the shield."""
    item = compiled("avoidable_obstacle")
    path = item.folder / "under_more.ra"
    path.write_text(engine_source(item.tiny, {"safe": QUERIES["safe"], "Hit": "collide() --> offroad()",
                                              "HitUnder": "collide() --> offroad() under safe",
                                              "inner": "strategy inner = control: A[] !collide() under safe"},
                                  scenario_file="avoidable_obstacle.xml"))
    results = {r.name: r for r in verify(compile_file(path), VerifyOptions(seed=1, plots=False))}
    assert results["Hit"].status == "not satisfied" and results["HitUnder"].status == "satisfied"
    assert results["inner"].status == "satisfied"
    assert results["inner"].states is not None and results["inner"].states < results["Hit"].states  # type: ignore


def test_forms_uppaal_reads_otherwise_are_not_answered(compiled: Callable[[str], Compiled]) -> None:
    """What UPPAAL would answer differently (a step bound counts its transitions) or not at all is
    "unsupported", with the reason, never answered with another meaning."""
    item = compiled("goal_ahead")
    path = item.folder / "forms.ra"
    queries = {"Steps": "Pr[#<=8](<> goal())", "Fixed": "Pr[<=2; 30](<> goal()) >= 0.5",
               "Always": "strategy calm = maxE(sa)[<=2]{Tiny.location}->{x}: [] !collide()",
               "Timed": "Pr[<=2](<> goal())"}
    path.write_text(engine_source(item.tiny, queries, scenario_file="goal_ahead.xml"))
    results = {r.name: r for r in verify(compile_file(path), VerifyOptions(seed=1, plots=False))}
    assert {name: r.status for name, r in results.items()} == {
        "Steps": "unsupported", "Fixed": "unsupported", "Always": "unsupported", "Timed": "value"}
    assert "counts UPPAAL's transitions" in (results["Steps"].message or "")
    assert "drop `;N`" in (results["Fixed"].message or "")
    assert "only reachability goals" in (results["Always"].message or "")


def test_a_strategy_without_an_output_folder_is_still_usable(compiled: Callable[[str], Compiled]) -> None:
    results = run(compiled("goal_ahead"), "safe", "Shielded", out=None)
    assert results["safe"].files == () and results["Shielded"].status == "satisfied"


# ---------------------------------------------------------------- the product with the automaton
def test_product_queries_read_the_location_and_the_reward(compiled: Callable[[str], Compiled]) -> None:
    item = compiled("avoidable_obstacle")
    path = item.folder / "product.ra"
    path.write_text(engine_source(item.tiny, {"Product": QUERIES["Product"], "Somewhere": QUERIES["Somewhere"],
                                              "Positive": "A[] sa >= 0"}, scenario_file="avoidable_obstacle.xml"))
    item = dataclasses.replace(item, result=compile_file(path))
    results = run(item)
    product, somewhere, positive = results["Product"], results["Somewhere"], results["Positive"]
    # decided on the automaton alone (near = mindist() < 3 TD needs no assume); the others on the product,
    # stopped at the first witness or counterexample
    assert product.status == "satisfied" and product.method == "compositional" and product.states is None
    assert somewhere.status == "satisfied" and somewhere.trace is not None and somewhere.method == "product search"
    assert_trace_is_a_run(item, somewhere.trace, product=True)
    assert somewhere.trace[0]["location"] == "Normal" and somewhere.trace[-1]["location"] == "Close"
    # Entering Close costs 10, more than the 4 s of `sa' == 1` can have earned: sa < 0 there.
    assert positive.status == "not satisfied" and positive.trace is not None
    assert positive.trace[-1]["location"] == "Close" and positive.trace[-1]["sa"] < 0
    assert all(row["sa"] >= 0 for row in positive.trace[:-1])
    text = render_text([positive])
    assert "Close sa=" in text and "(accrued)" in text


def test_product_on_an_empty_road_never_comes_close(compiled: Callable[[str], Compiled]) -> None:
    results = run(compiled("goal_ahead"), "Product", "Somewhere")
    assert results["Product"].status == "satisfied"
    assert results["Somewhere"].status == "not satisfied" and results["Somewhere"].trace is None


def test_leads_to_and_eventually(compiled: Callable[[str], Compiled]) -> None:
    results = run(compiled("narrow_road"), "LeadsTo", "Eventually")
    assert results["LeadsTo"].status == "satisfied" and results["Eventually"].status == "satisfied"
    item = compiled("narrow_road")
    path = item.folder / "eventually.ra"
    path.write_text(engine_source(item.tiny, {"Goal": "A<> goal()", "Off": "A[] offroad()",
                                              "Never": "!offroad() --> goal()"}, scenario_file="narrow_road.xml"))
    results = {r.name: r for r in verify(compile_file(path))}
    assert results["Goal"].status == "not satisfied"  # no run of the 1 m road gets anywhere near the goal
    assert results["Off"].status == "satisfied"  # by construction: every state is off the road
    assert results["Never"].status == "satisfied"  # vacuous: no state is on the road


# ---------------------------------------------------------------- statistics
def test_probability_interval_meets_epsilon(compiled: Callable[[str], Compiled]) -> None:
    item = compiled("avoidable_obstacle")
    for epsilon in (0.1, 0.05):
        prob = run(item, "Prob", epsilon=epsilon)["Prob"]
        assert prob.kind == "probability" and prob.status == "value"
        assert prob.interval is not None and prob.estimate is not None and prob.runs is not None
        lo, hi = prob.interval
        assert (hi - lo) / 2 <= epsilon + 1e-12
        assert lo <= prob.estimate <= hi and 0 < prob.estimate < 1  # v >= 6 from 5 m/s: sometimes
        assert prob.horizon_samples == 4 and prob.confidence == 0.95
    coarse = run(item, "Prob", epsilon=0.1)["Prob"]
    assert coarse.runs is not None and prob.runs > coarse.runs  # a narrower interval needs more runs


def test_probability_with_runs_and_sequential_tests(compiled: Callable[[str], Compiled]) -> None:
    results = run(compiled("avoidable_obstacle"), "ProbRuns", "Certain", "Impossible", confidence=0.9)
    runs = results["ProbRuns"]
    assert runs.runs == 30 and runs.confidence == 0.9
    assert runs.interval is not None and runs.estimate is not None
    assert runs.interval[0] <= runs.estimate <= runs.interval[1]
    assert runs.estimate > 0  # full speed into the parked van: some uniform runs collide
    certain, impossible = results["Certain"], results["Impossible"]
    assert certain.status == "satisfied" and certain.estimate == 1
    assert impossible.status == "not satisfied" and impossible.estimate == 0  # the speed never drops below 0
    # a statistical verdict says so, with its error bound and the region where it has none: "Formula is satisfied"
    # with "estimated by simulation" read as a proof
    assert certain.message == ("decided by Wald's sequential test: wrong with probability at most 0.05 if the "
                               "probability lies outside [0.98, 1] (within it either answer may come)")
    assert impossible.message == ("decided by Wald's sequential test: wrong with probability at most 0.05 if the "
                                  "probability lies outside [0, 0.02] (within it either answer may come)")
    assert f"    {certain.message}\n" in render_text([certain])
    assert certain.runs is not None and certain.runs >= 1 and impossible.runs is not None


def test_expectation_mean_within_the_speed_range(compiled: Callable[[str], Compiled]) -> None:
    item = compiled("avoidable_obstacle")
    speed = run(item, "Speed")["Speed"]
    settings = item.tiny.settings
    assert speed.kind == "expectation" and speed.runs == 20 and speed.estimate is not None
    assert float(settings.min_speed) <= speed.estimate <= float(settings.max_speed)
    assert speed.estimate >= 5  # the largest speed of a run is at least the start's 5 m/s
    assert speed.interval is not None and speed.interval[0] < speed.estimate < speed.interval[1]


def test_simulate_writes_one_csv_row_per_run_and_sample(compiled: Callable[[str], Compiled], tmp_path: Path) -> None:
    sim = run(compiled("avoidable_obstacle"), "Sim", out=tmp_path)["Sim"]
    assert sim.kind == "simulate" and sim.runs == 4 and sim.horizon_samples == 4
    assert sim.files == (str(tmp_path / "Sim.csv"),)  # plots off
    with open(tmp_path / "Sim.csv", newline="", encoding="utf-8") as handle:
        rows = list(csv.reader(handle))
    assert rows[0] == ["run", "time", "mindist()", "3 * collision_distance"]
    body = rows[1:]
    assert len(body) == 4 * (4 + 1)
    assert [(int(r[0]), float(r[1])) for r in body] == [(n, k * 0.5) for n in range(4) for k in range(5)]
    assert {float(r[3]) for r in body} == {1.5}
    distances = np.array([float(r[2]) for r in body])
    assert sim.estimate == pytest.approx(distances.min())
    below = sum(any(float(r[2]) < 1.5 for r in body if int(r[0]) == n) for n in range(4))
    assert sim.message == f"4 runs of 4 samples; {below} of 4 runs go below 3 * collision_distance = 1.5"


def test_same_seed_same_numbers(compiled: Callable[[str], Compiled]) -> None:
    item = compiled("avoidable_obstacle")
    names = ("Prob", "ProbRuns", "Certain", "Speed", "Sim")

    def numbers(seed: int) -> list[dict[str, object]]:
        return [{k: v for k, v in r.items() if k != "seconds"}
                for r in render_json(list(run(item, *names, seed=seed).values()))]

    first = numbers(7)
    assert first == numbers(7)
    assert [r["seed"] for r in first] == [r["seed"] for r in numbers(7)]
    other = numbers(8)
    assert [r["estimate"] for r in other] != [r["estimate"] for r in first]


# ---------------------------------------------------------------- budget, selection, errors
def test_state_budget_gives_unknown_not_a_crash(compiled: Callable[[str], Compiled]) -> None:
    results = run(compiled("goal_ahead"), "Stays", "safe", "Shielded", "Product", "LeadsTo", max_states=10)
    # the automaton alone decides Product: no state of the model is needed
    product = results.pop("Product")
    assert product.status == "satisfied" and product.method == "compositional"
    stays = results.pop("Stays")  # a run safe to the horizon is found within the budget (a run is 9 states)
    assert (stays.status, stays.method) == ("satisfied", "witness search")
    assert stays.states is not None and stays.states <= 2 * 10  # the random runs', then the beam's
    safe = results.pop("safe")  # beyond the budget the shield is computed state by state
    assert (safe.status, safe.method) == ("satisfied", "on demand") and "more than 10 states" in (safe.message or "")
    assert {r.status for r in results.values()} == {"unknown"}
    assert "state by state" in (results["Shielded"].message or "")
    assert "more than 10 states" in (results["LeadsTo"].message or "")
    assert "--max-states" in (results["LeadsTo"].message or "")
    assert "--horizon" in (results["LeadsTo"].message or "")
    assert "UNKNOWN" in render_text(list(results.values()))


def test_only_names_that_exist(compiled: Callable[[str], Compiled]) -> None:
    with pytest.raises(UnknownQuery) as caught:
        run(compiled("goal_ahead"), "Stays", "Nope", "Neither")
    assert caught.value.args[0] == "Nope, Neither"


def test_learning_strategies_are_learned(compiled: Callable[[str], Compiled]) -> None:
    learn = run(compiled("goal_ahead"), "Learn")
    assert list(learn) == ["safe", "Learn"]  # `under safe` pulls in the strategy
    result = learn["Learn"]  # rac.learning.qlearning (tests/learning/test_learn.py has the details)
    assert result.kind == "learning" and result.status == "value" and result.runs is not None and result.runs > 0
    assert "learned in" in (result.message or "") and "collided: 0" in (result.message or "")


def test_horizon_option_overrides_the_automaton(compiled: Callable[[str], Compiled]) -> None:
    stays = run(compiled("goal_ahead"), "Stays", horizon=Fraction(1))["Stays"]
    assert stays.status == "satisfied" and stays.horizon_samples == 2
    assert stays.trace is not None and [row["time"] for row in stays.trace] == [0, 0.5, 1]


def test_a_file_without_a_model_block_or_with_errors(tmp_path: Path) -> None:
    path = tmp_path / "plain.ra"
    path.write_text("automaton Plain {\n    input near : bool\n    reward sa\n    objective sa\n    sample every 0.5\n"
                    "    horizon 4\n    initial location N { sa' == 1 }\n    edge N -> N when near\n"
                    "    query Q: E<> N\n}\n")
    with pytest.raises(ValueError, match="needs a `model` block"):
        verify(compile_file(path))
    broken = write_engine_file(tmp_path, "goal_ahead", {"Q": "E<> goal()"})
    broken.write_text(broken.read_text().replace("3 * collision_distance", "3 * colision_distance"))
    with pytest.raises(CheckError) as caught:
        verify(compile_file(broken))
    assert [d.code for d in caught.value.diagnostics] == ["E0101"]


def test_standard_queries(compiled: Callable[[str], Compiled], tmp_path: Path) -> None:
    item = compiled("goal_behind_wall")
    decls = standard_queries(item.result)
    assert [d.name for d in decls] == ["Qa", "Qb", "Qc", "Qd", "Fig7", "Fig7_safe", "Unsafe_safe"]
    results = run(item, "Qb", "Qc", "Qd", standard=True, out=tmp_path)
    assert [r.name for r in results.values()] == ["Qb", "Qc", "Qd"]
    assert results["Qb"].status == "satisfied" and results["Qd"].status == "satisfied"
    assert results["Qb"].title == "a run that is never unsafe exists"
    assert "NO run that stays safe until it gets there exists" in (results["Qc"].message or "")
    # the file defines a strategy `safe` of its own: the standard one is `safe_` (nothing is overwritten)
    assert decls[3].text == "strategy safe_ = control: A[] !collide() && !offroad()"
    assert (tmp_path / "standard" / "safe_.shield.npz").is_file() and not (tmp_path / "safe.shield.npz").exists()
    assert standard_queries(item.result, Fraction(3, 2))[0].text.startswith("Pr[<=1.5](<> ")


# ---------------------------------------------------------------- rendering
def _row(k: int, x: float) -> dict[str, float | int | str]:
    return {"time": k * 0.5, "x": x, "y": 1.5, "v": 5.0, "acc": 0.0, "head": 0.0, "jerk": 0.0, "turn": 0.0,
            "collide": False, "offroad": False, "goal": k == 7}


def test_render_text_layout() -> None:
    trace = tuple(_row(k, 10 + 2.5 * k) for k in range(8))
    results = [
        QueryResult("Qc", "E<> goal()", "symbolic", "satisfied", states=1234, horizon_samples=8, seconds=0.25,
                    trace=trace),
        QueryResult("P", "Pr[<=2](<> v >= 6)", "probability", "value", interval=(0.25, 0.35), estimate=0.3, runs=300,
                    horizon_samples=4, seconds=1.5, seed=42, confidence=0.9),
        QueryResult("E", "E[<=2;20](max: v)", "expectation", "value", interval=(7.5, 8.5), estimate=8.0, runs=20,
                    horizon_samples=4, seconds=0.0, seed=3, confidence=0.95),
        QueryResult("U", "A[] !collide()", "symbolic", "unknown", message="too many states"),
    ]
    assert render_text(results) == """\
Verifying Qc: E<> goal()
 -- Formula is satisfied.
    1,234 states, horizon 8 samples, 0.25 s
    trace (8 states, first and last 3; --trace shows all):
      t=0s x=10 y=1.5 v=5 acc=0 head=0 jerk=0 turn=0
      t=0.5s x=12.5 y=1.5 v=5 acc=0 head=0 jerk=0 turn=0
      t=1s x=15 y=1.5 v=5 acc=0 head=0 jerk=0 turn=0
      t=2.5s x=22.5 y=1.5 v=5 acc=0 head=0 jerk=0 turn=0
      t=3s x=25 y=1.5 v=5 acc=0 head=0 jerk=0 turn=0
      t=3.5s x=27.5 y=1.5 v=5 acc=0 head=0 jerk=0 turn=0 [goal]
Verifying P: Pr[<=2](<> v >= 6)
 -- Pr in [0.2500, 0.3500] (300 runs, 90% CI)
    horizon 4 samples, 1.50 s, seed 42
Verifying E: E[<=2;20](max: v)
 -- (20 runs) E = 8 ± 0.5 (95% CI)
    horizon 4 samples, 0.00 s, seed 3
Verifying U: A[] !collide()
 -- Formula is UNKNOWN: too many states
    0.00 s"""
    assert render_text(results[:1], traces=True).count("\n      t=") == 8


def test_render_text_says_why_a_query_is_not_answered_once() -> None:
    """`E<> prev(v) > v` printed its reason after "Not answered:" and again under the timing line."""
    why = "`prev(...)` in an exhaustive query is not supported: a merged state has no single previous sample"
    result = QueryResult("T", "E<> prev(v) > v", "symbolic", "unsupported", message=why)
    assert render_text([result]) == f"Verifying T: E<> prev(v) > v\n -- Not answered: {why}\n    0.00 s"


def test_render_json_is_strict_json(compiled: Callable[[str], Compiled], tmp_path: Path) -> None:
    item = compiled("avoidable_obstacle")
    path = item.folder / "one.ra"
    path.write_text(engine_source(item.tiny, {"One": "E[<=2;1](max: v)", "Sim": QUERIES["Sim"]},
                                  scenario_file="avoidable_obstacle.xml"))
    results = verify(compile_file(path), VerifyOptions(seed=1, out_dir=tmp_path, plots=False))
    text = json.dumps(render_json(results), allow_nan=False)  # one run: no interval, but no Infinity either
    one, sim = json.loads(text)
    assert one["interval"] == [None, None] and one["runs"] == 1 and one["estimate"] >= 5
    assert sim["files"] == [str(tmp_path / "Sim.csv")]
    assert sim["location"] == {"file": str(path), "line": one["location"]["line"] + 1, "column": 5}
    expected = {"name", "formula", "kind", "status", "title", "interval", "estimate", "runs", "states", "seconds",
                "horizon_samples", "trace", "files", "message", "seed", "confidence", "exact", "method", "optimum",
                "location"}
    assert set(one) == expected


# ---------------------------------------------------------------- Pr: the interval covers Storm's exact value
@pytest.mark.parametrize("event", ["v > 8", "x > 20", "mindist() < 2"])
def test_probability_interval_covers_the_exact_value(tmp_path: Path, event: str) -> None:
    """SMC draws actions uniformly; Storm computes the same probability exactly on the explored
    model (a DTMC with uniform choices). The interval must cover it (fixed seed: not flaky)."""
    path = write_engine_file(tmp_path, "avoidable_obstacle", {"P": f"Pr[<=4](<> {event})"})
    result = compile_file(path)
    (answer,) = verify(result, VerifyOptions(seed=3, only=("P",), out_dir=tmp_path / "out"))
    assert answer.exact is not None and 0.0 < answer.exact <= 1.0
    assert answer.interval is not None
    assert answer.interval[0] <= answer.exact <= answer.interval[1]
    assert "exact (Storm" in render_text([answer])


# ---------------------------------------------------------------- statistical queries within --max-memory (issue 22)
def test_expectation_runs_in_chunks_within_the_memory_budget(tmp_path: Path) -> None:
    """`E[...]` with many runs and a small budget is answered in chunks, with the same mean as one batch
    would give for a deterministic per-run value (the chunks aggregate the statistic incrementally)."""
    path = write_engine_file(tmp_path, "avoidable_obstacle", {"E": "E[<=2;3000](max: time)"})
    (answer,) = verify(compile_file(path), VerifyOptions(seed=1, only=("E",), out_dir=tmp_path / "out",
                                                         max_bytes=2 * 2**20))
    assert answer.status == "value" and answer.runs == 3000
    assert answer.estimate == pytest.approx(2.0) and answer.interval == (pytest.approx(2.0), pytest.approx(2.0))


def test_simulate_beyond_the_memory_budget_stops_before_allocating(tmp_path: Path) -> None:
    """`simulate` must hold every trace: beyond --max-memory it stops at once, naming the estimate."""
    path = write_engine_file(tmp_path, "avoidable_obstacle", {"S": "simulate[<=3;1000000]{mindist()}"})
    (answer,) = verify(compile_file(path), VerifyOptions(seed=1, only=("S",), out_dir=tmp_path / "out",
                                                         max_bytes=300 * 2**20))
    assert answer.status == "unknown"
    assert answer.message is not None and "--max-memory" in answer.message and "1,000,000 runs" in answer.message


def test_a_query_has_its_seed_whichever_queries_are_selected(compiled: Callable[[str], Compiled]) -> None:
    """`--query Learn` (and `rac render --strategy`, which runs the learning query alone) learns with the
    seed the whole file gives it: the k-th statistical or learning query of the file gets the k-th seed
    derived from --seed, whether or not the queries before it run. Before, the seed was the k-th of those
    *run*, so `rac verify --seed 1 --query Learn` learned another strategy than `rac verify --seed 1`
    (and `A<> p under Learn` could get another verdict)."""
    item = compiled("avoidable_obstacle")
    seeded = ("Prob", "ProbRuns", "Certain", "Impossible", "Speed", "Sim", "Learn")  # in the file's order
    together = run(item, *seeded, learn_episodes=64)
    alone = run(item, "Learn", learn_episodes=64)
    expected = [int(np.random.SeedSequence(1).spawn(len(seeded))[k].generate_state(1)[0]) for k in range(len(seeded))]
    assert [together[name].seed for name in seeded] == expected  # the whole file's seeds are what they were
    assert alone["Learn"].seed == together["Learn"].seed
    assert alone["Learn"].estimate == together["Learn"].estimate
    assert run(item, "Sim", "Speed")["Speed"].seed == together["Speed"].seed


def test_a_trace_shows_the_values_the_model_holds() -> None:
    """Regression: trace rows printed numbers with `:g` (6 significant digits), so a mirror at the int32
    limit, sa = -214748.3648, read `sa=-214748`, and a position at exponent 6 lost its last digits."""
    row = {"time": 0.5, "x": 2140.123456, "y": 1.75, "v": 8.1562, "acc": 0.0, "head": 0.0, "jerk": 0.0,
           "turn": 0.0, "location": "B", "sa": -214748.3648}
    text = render_text([QueryResult("Q", "E<> B", "symbolic", "satisfied", trace=(row,))], traces=True)
    assert "t=0.5s x=2140.123456 y=1.75 v=8.1562 acc=0 head=0 jerk=0 turn=0 B sa=-214748.3648" in text


def least_limit(result: CompileResult, *, prune: bool) -> int:
    """The least --max-memory the model's graph (pruned or not) fits alone (bisection: the budget checks
    estimates, not measures)."""

    def fits(limit: int) -> bool:
        try:
            Context(result, VerifyOptions(seed=1, max_bytes=limit)).graph(prune)
        except UnknownVerdict:
            return False
        return True

    low, high = 1, 2**30
    while low < high:
        middle = (low + high) // 2
        low, high = (low, middle) if fits(middle) else (middle + 1, high)
    return low


def test_a_graph_kept_for_later_queries_counts_against_the_memory_limit(tmp_path: Path) -> None:
    """Each exploration was held to --max-memory alone while the graphs of earlier queries stayed in memory
    for later ones, so two graphs within the limit each could together fill the machine: the unpruned
    graph that fits the limit alone is refused beside the pruned one, saying what holds the rest."""
    path = write_engine_file(tmp_path, "avoidable_obstacle")
    result = compile_file(path)
    low = least_limit(result, prune=False)  # the unpruned graph fits it alone
    ctx = Context(result, VerifyOptions(seed=1, max_bytes=low))
    kept = ctx.graph(True)  # the pruned graph, smaller, fits
    assert 0 < kept.nbytes < low and ctx.memory_left() == low - kept.nbytes
    with pytest.raises(UnknownVerdict, match="holds the model explored for earlier queries"):
        ctx.graph(False)
    roomy = Context(result, VerifyOptions(seed=1, max_bytes=low + kept.nbytes))  # room for both: both explored
    assert roomy.graph(True).nbytes == kept.nbytes and roomy.graph(False).n_states > kept.n_states


def test_simulated_runs_fit_beside_the_kept_graphs(tmp_path: Path) -> None:
    """Regression: the statistical queries (and learning, the optimum, the penalty check) were held to
    --max-memory alone while an earlier query's graph stayed in memory: runs that fit the limit alone are
    now refused beside the graph, and the refusal says what holds the rest."""
    result = compile_file(write_engine_file(tmp_path, "avoidable_obstacle"))
    low = least_limit(result, prune=True)
    kept = Context(result, VerifyOptions(seed=1, max_bytes=low)).graph(True).nbytes
    samples = 1
    while simulation_bytes(1, samples, 1) < low:  # one run as large as the graph's whole limit
        samples *= 2
    limit = simulation_bytes(1, samples, 1) + kept // 2  # one run fits the whole limit, not what the graph leaves
    assert runs_within(limit, samples, 1) >= 1 and runs_within(limit - kept, samples, 1) == 0
    ctx = Context(result, VerifyOptions(seed=1, max_bytes=limit))
    assert StatisticalAnswerer(ctx).chunk(1, samples, "`Q`") >= 1  # nothing kept yet: the whole limit
    ctx.graph(True)
    with pytest.raises(UnknownVerdict, match="what --max-memory leaves beside the kept graphs.*holds the model "
                                             "explored for earlier queries"):
        StatisticalAnswerer(ctx).chunk(1, samples, "`Q`")


def test_learning_fits_beside_the_kept_graphs(compiled: Callable[[str], Compiled],
                                              monkeypatch: pytest.MonkeyPatch) -> None:
    """Regression: learning and the optimum beside it were held to --max-memory alone, not to what the
    graphs kept for later queries leave of it (:meth:`Context.memory_left`), and a refusal did not say
    what holds the rest."""
    item = compiled("avoidable_obstacle")
    roomy = run(item, "Learn")["Learn"]
    assert roomy.status == "value", roomy.message
    # the shield it learns under is computed first, unlimited (a search under 1 byte would not prove it)
    monkeypatch.setattr(Context, "memory_left", lambda self: 1 if self.strategy_exists("safe") else None)
    monkeypatch.setattr(Context, "kept_note", lambda self: " (KEPT GRAPHS)")
    refused = run(item, "Learn")["Learn"]
    assert refused.status == "unknown" and "(KEPT GRAPHS); the episode budget is --learn-episodes" in refused.message


@pytest.mark.parametrize(("formula", "holds"), [
    ("A[] true", True), ("A[] !deadlock", True), ("E<> false", False), ("E<> deadlock", False),
    ("A<> collision_distance > 1000", False), ("E[] fabs(-2) > 0", True), ("A[] 1 > 2", False),
])
def test_a_formula_that_reads_no_state_is_decided_without_exploring(tmp_path: Path, formula: str,
                                                                    holds: bool) -> None:
    """Regression: `A[] true` and UPPAAL's usual `A[] !deadlock` searched for a state where they fail, found
    none, and then needed the complete graph to prove it: on examples/paper UNKNOWN after 5,000,000 states.
    A formula that reads no state has one value in every state; the same formula made to read the state
    (`|| time < 0`, never true) and decided on the complete graph gives the same verdict."""
    quantifier, body = formula.split(" ", 1)
    path = write_engine_file(tmp_path, "avoidable_obstacle",
                             {"Alone": formula, "Read": f"{quantifier} ({body}) || time < 0"})
    result = compile_file(path)
    alone = {r.name: r for r in verify(result, VerifyOptions(seed=1, plots=False, max_states=1))}["Alone"]
    assert alone.status == ("satisfied" if holds else "not satisfied") and alone.method == "constant"
    read = {r.name: r for r in verify(result, VerifyOptions(seed=1, plots=False, only=["Read"]))}["Read"]
    assert read.status == alone.status and read.method != "constant"


@pytest.mark.parametrize(("formula", "holds"), [
    ("A<> !offroad()", True), ("A<> time <= 0", True), ("A<> !collide() && !goal()", True),
    ("E[] offroad()", False), ("E[] time > 0", False), ("E[] goal()", False),
])
def test_a_formula_the_start_decides_needs_no_exploring(tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                                        formula: str, holds: bool) -> None:
    """Regression: `A<> p` with `p` true at the start and `E[] p` with `p` false there searched for a run that
    never meets `p` (or keeps it), found none, and needed the complete graph to say so: UNKNOWN beyond the state
    budget. Every run begins in the start, which decides them; the same query decided on the complete graph
    (the shortcut switched off) gives the same verdict. The other cases are still explored."""
    path = write_engine_file(tmp_path, "avoidable_obstacle", {"Start": formula, "Other": "A<> goal()"})
    result = compile_file(path)
    tight = {r.name: r for r in verify(result, VerifyOptions(seed=1, plots=False, max_states=1))}
    assert tight["Start"].status == ("satisfied" if holds else "not satisfied")
    assert tight["Start"].method == "initial state" and tight["Start"].states == 1
    assert tight["Other"].method != "initial state"  # goal() is false at the start: the start does not decide it
    monkeypatch.setattr(SymbolicAnswerer, "_at_start", lambda self, query, base: None)
    explored = {r.name: r for r in verify(result, VerifyOptions(seed=1, plots=False, only=["Start"]))}["Start"]
    assert explored.status == tight["Start"].status and explored.method != "initial state"


def test_a_query_past_max_seconds_is_unknown_and_the_next_is_answered(tmp_path: Path) -> None:
    """`--max-seconds`: `E[<=4;100000000](max: v)` (memory allows tens of millions of runs at once) ran 5 minutes
    with no limit but Ctrl-C. Each query now has the limit, checked per explored layer, simulated sample and chunk
    of runs: past it the query is UNKNOWN saying so; the queries after it have their own time, and one decided
    without exploring is decided; `v` reads the sensed state, so no truth is integrated for it."""
    path = write_engine_file(tmp_path, "avoidable_obstacle", {
        "Long": "E[<=4;100000000](max: v)", "Explore": "E<> goal() && v > 100", "Constant": "A[] true",
        "Quick": "E[<=4;20](max: v)"})
    result = compile_file(path)
    answers = {r.name: r for r in verify(result, VerifyOptions(seed=1, plots=False, max_seconds=1e-9))}
    for name in ("Long", "Explore", "Quick"):
        assert answers[name].status == "unknown"
        assert answers[name].message.startswith(f"query {name}: given up after ")
        assert answers[name].message.endswith("past the time limit of 1e-09 s (--max-seconds)")
    assert answers["Constant"].status == "satisfied"
    roomy = {r.name: r for r in verify(result, VerifyOptions(seed=1, plots=False, max_seconds=600,
                                                             only=("Explore", "Quick")))}
    unlimited = {r.name: r for r in verify(result, VerifyOptions(seed=1, plots=False, only=("Explore", "Quick")))}
    assert roomy["Explore"].status == unlimited["Explore"].status == "not satisfied"
    assert roomy["Quick"].estimate == unlimited["Quick"].estimate  # the limit changes no answer it lets through


def test_the_witness_search_keeps_within_max_seconds(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """The witness search has its own safety time limit (300 s): under `--max-seconds` it gets at most what is left
    of the query's time, or a query given 1 s could search for 300."""
    seen: list[float] = []
    real = reach.search

    def spy(*args: object, **kwargs: object) -> object:
        seen.append(kwargs["bounds"].safety_seconds)  # type: ignore[attr-defined]
        return real(*args, **kwargs)  # type: ignore[arg-type]

    monkeypatch.setattr(reach, "search", spy)
    result = compile_file(write_engine_file(tmp_path, "avoidable_obstacle", {"Explore": "E<> goal() && v > 100"}))
    verify(result, VerifyOptions(seed=1, plots=False, max_seconds=1.5))
    limited = list(seen)
    seen.clear()
    verify(result, VerifyOptions(seed=1, plots=False))
    assert limited and all(0 <= seconds <= 1.5 for seconds in limited)
    assert seen and all(seconds == Bounds().safety_seconds for seconds in seen)


def test_the_guided_product_search_keeps_within_max_seconds(tmp_path: Path) -> None:
    """The product search (a beam of up to 2 million states toward where the automaton reaches the query) read
    no clock: a query over the automaton's names ran it to the end past `--max-seconds` and was answered.
    It checks the query's limit per sample, as every exploration does."""
    path = write_engine_file(tmp_path, "avoidable_obstacle", {"Somewhere": QUERIES["Somewhere"]})
    result = compile_file(path)
    [free] = verify(result, VerifyOptions(seed=1, plots=False))
    assert free.status == "satisfied" and free.method == "product search"
    [limited] = verify(result, VerifyOptions(seed=1, plots=False, max_seconds=1e-9))
    assert limited.status == "unknown", limited
    assert (limited.message or "").endswith("past the time limit of 1e-09 s (--max-seconds)"), limited.message


def _limit_passing_in_explorations(query: str) -> type:
    """A :class:`TimeLimit` that is past only when ``query``'s explorations check it (the per-layer progress
    ``(layer, frontier, total)``), never between steps or samples: what reads it there is what it reaches."""

    class Passing(TimeLimit):
        def check(self, *progress: int) -> None:
            if len(progress) == 3 and self.what == f"query {query}":
                raise TimeExceeded(what=self.what, limit=1.0, seconds=1.5)

    return Passing


def test_the_exact_probability_beside_a_simulation_keeps_within_max_seconds(tmp_path: Path,
                                                                           monkeypatch: pytest.MonkeyPatch) -> None:
    """`Pr[<=T](<> p)` also computes its exact value by exploring the model (up to 2 million states) with no
    look at --max-seconds: past the limit that value is left out, as beyond the memory budget, and the
    simulated answer stands."""
    from rac.verify import runner

    result = compile_file(write_engine_file(tmp_path, "avoidable_obstacle", {"Prob": QUERIES["Prob"]}))
    [free] = verify(result, VerifyOptions(seed=1, plots=False))
    assert free.status == "value" and free.exact is not None
    monkeypatch.setattr(runner, "TimeLimit", _limit_passing_in_explorations("Prob"))
    [limited] = verify(result, VerifyOptions(seed=1, plots=False, max_seconds=1.0))
    assert limited.status == "value" and limited.exact is None and limited.interval == free.interval


def test_the_optimum_beside_a_learned_strategy_keeps_within_max_seconds(tmp_path: Path,
                                                                         monkeypatch: pytest.MonkeyPatch) -> None:
    """The exact optimum reported beside a learned strategy (and emitted by --exact) explored its decision
    graph with no look at --max-seconds (minutes on a large scene): past the limit it is out of reach, saying
    so, and the learned strategy stands; under --exact the query is UNKNOWN."""
    from rac.verify import runner

    queries = {"safe": QUERIES["safe"], "Learn": QUERIES["Learn"]}
    result = compile_file(write_engine_file(tmp_path, "avoidable_obstacle", queries))
    monkeypatch.setattr(runner, "TimeLimit", _limit_passing_in_explorations("Learn"))
    learned = {r.name: r for r in verify(result, VerifyOptions(seed=1, plots=False, max_seconds=1.0))}["Learn"]
    assert learned.status == "value", learned.message
    assert ("optimum out of reach (query Learn: given up after 1.5 s, past the time limit of 1 s (--max-seconds))"
            in (learned.message or "")), learned.message
    exact = {r.name: r for r in verify(result, VerifyOptions(seed=1, plots=False, max_seconds=1.0, exact=True))}
    assert exact["Learn"].status == "unknown"
    assert exact["Learn"].message == ("the exact optimum is out of reach: query Learn: given up after 1.5 s, past the "
                                      "time limit of 1 s (--max-seconds)")


def test_a_slow_machine_answers_as_a_fast_one(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """15 s between two readings of the clock (a machine far slower than this one): the witness search ran
    past its 20 s and the answers came from the layered search instead (another method, another trace) or
    were UNKNOWN beyond its budget. Its work budget decides now: the same answers, found the same way."""
    queries = {"Reaches": QUERIES["Reaches"], "Stays": QUERIES["Stays"]}
    result = compile_file(write_engine_file(tmp_path, "avoidable_obstacle", queries))

    def answers() -> dict[str, tuple[object, ...]]:
        # no random runs: the beam, which reads the clock once per sample, finds them
        return {r.name: (r.status, r.method, r.states, r.message, r.trace)
                for r in verify(result, VerifyOptions(seed=3, plots=False, witness=Bounds(runs=0)))}

    steady = answers()
    assert {name: found[1] for name, found in steady.items()} == {"Reaches": "witness search",
                                                                  "Stays": "witness search"}
    readings = itertools.count(0.0, 15.0)
    monkeypatch.setattr(time, "perf_counter", lambda: next(readings))
    assert answers() == steady


def test_a_witness_search_cut_by_its_safety_net_says_the_answer_depends_on_the_machine(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """The witness search's time limit decided what it found, unsaid in the answer. Now its work budget does,
    and where the safety net (300 s) cuts it on a machine far slower than expected, the answer (decided by the
    layered search then) says that it depends on the machine's speed."""
    result = compile_file(write_engine_file(tmp_path, "avoidable_obstacle", {"Explore": "E<> goal() && v > 100",
                                                                              "Somewhere": "E<> Close"}))
    steady = {r.name: r for r in verify(result, VerifyOptions(seed=1, plots=False, only=("Explore",)))}
    readings = itertools.count(0.0, 2 * Bounds().safety_seconds)  # type: ignore[operator]
    monkeypatch.setattr(time, "perf_counter", lambda: next(readings))
    crawled = {r.name: r for r in verify(result, VerifyOptions(seed=1, plots=False, only=("Explore",)))}
    assert crawled["Explore"].status == steady["Explore"].status == "not satisfied"
    assert "safety time limit" not in (steady["Explore"].message or "")
    # the pruned model's search, then the whole model's (E<> goal() && v > 100 is reached on neither)
    assert ("2 witness searches ran into the safety time limit (300 s) before spending their work budget, so this "
            "answer (its method, its trace, whether it is known) depends on the machine's speed and load"
            ) in (crawled["Explore"].message or "")


def test_no_plots_removes_the_plot_of_an_earlier_run(tmp_path: Path) -> None:
    """`--no-plots` wrote a new `NAME.csv` and left the earlier run's `NAME.png` beside it: a plot of other runs
    read as this run's. The stale plot is removed as the new CSV takes the old one's place."""
    result = compile_file(write_engine_file(tmp_path, "avoidable_obstacle", {"Sim": "simulate[<=2;5]{v}"}))
    out = tmp_path / "out"
    verify(result, VerifyOptions(seed=1, out_dir=out))
    assert (out / "Sim.csv").exists() and (out / "Sim.png").exists()
    first = (out / "Sim.csv").read_text()
    verify(result, VerifyOptions(seed=2, plots=False, out_dir=out))
    assert (out / "Sim.csv").read_text() != first and not (out / "Sim.png").exists()


@pytest.mark.parametrize(("alone", "read", "holds"), [
    ("strategy s = control: A[] true", "strategy r = control: A[] true || time < 0", True),
    ("strategy s = control: A[] !deadlock", "strategy r = control: A[] !deadlock || time < 0", True),
    ("strategy s = control: A[] 1 > 2", "strategy r = control: A[] 1 > 2 || time < 0", False),
    ("strategy s = control: E<> true", "strategy r = control: E<> true || time < 0", True),
    ("strategy s = control: E<> collision_distance > 1000", "strategy r = control: E<> false || time < 0", False),
    ("goal() --> true", "goal() --> true || time < 0", True),
    ("false --> goal()", "false || time < 0 --> goal()", True),
    ("true --> 1 > 2", "true || time < 0 --> false || time < 0", False),
])
def test_a_strategy_or_leads_to_decided_by_constants_needs_no_exploring(tmp_path: Path, alone: str, read: str,
                                                                          holds: bool) -> None:
    """Regression: `control: A[] true` (or `false`, `E<> false`) and `p --> true`, `false --> q`, `true -->
    false` explored the whole model to find what their constants decide: UNKNOWN beyond the state budget.
    Each is now decided at once, as the same formula made to read the state (`|| time < 0`, never true) is
    on the complete graph. (`true --> q` with `q` reading the state is not constant, and is still explored.)"""
    path = write_engine_file(tmp_path, "avoidable_obstacle", {"Alone": alone, "Read": read,
                                                               "Explored": "true --> goal()"})
    result = compile_file(path)
    answers = {r.name: r for r in verify(result, VerifyOptions(seed=1, plots=False, max_states=1,
                                                               only=["Alone", "Explored"]))}
    assert answers["Alone"].status == ("satisfied" if holds else "not satisfied")
    assert answers["Alone"].method == "constant"
    assert answers["Explored"].status == "unknown"  # reads goal() in every reachable state: not decided by constants
    read_answer = {r.name: r for r in verify(result, VerifyOptions(seed=1, plots=False, only=["Read"]))}["Read"]
    assert read_answer.status == answers["Alone"].status and read_answer.method != "constant"


def test_a_strategy_of_every_action_is_computed_when_a_query_under_it_needs_it(tmp_path: Path) -> None:
    """`control: A[] true` is decided without exploring, and its table (every action) is computed only for a
    query under it: the same table as the same goal made to read the state, and the same verdicts under it.
    Beyond the budget a query under it is unknown and says why; under `control: A[] false` not applicable."""
    queries = {"Every": "strategy every = control: A[] true", "Under": "A[] !collide() under every",
               "Read": "strategy read = control: A[] true || time < 0", "UnderRead": "A[] !collide() under read",
               "Sim": "Pr[<=2](<> collide()) under every", "SimRead": "Pr[<=2](<> collide()) under read",
               "Never": "strategy never = control: A[] false", "UnderNever": "A[] !collide() under never"}
    result = compile_file(write_engine_file(tmp_path, "avoidable_obstacle", queries))
    tight = {r.name: r for r in verify(result, VerifyOptions(seed=1, plots=False, max_states=1))}
    assert tight["Every"].status == "satisfied" and tight["Every"].method == "constant"
    assert tight["Under"].status == "unknown"
    assert tight["Under"].message.startswith("the strategy `every` allows every action (its goal reads no state), "
                                             "but a query under it needs its table")
    assert tight["Never"].status == "not satisfied" and tight["Never"].method == "constant"
    assert tight["UnderNever"].status == "not_applicable"
    context, results = run_queries(result, VerifyOptions(seed=1, plots=False))
    answers = {r.name: r for r in results}
    assert answers["Under"].status == answers["UnderRead"].status and answers["Under"].method == "exhaustive"
    assert answers["Sim"].status == answers["SimRead"].status == "value"  # runs under the table computed for them
    every, read = context.strategy("every"), context.strategy("read")
    assert np.array_equal(every[0].allowed_choices, read[0].allowed_choices)
    assert np.array_equal(every[0].winning, read[0].winning)
