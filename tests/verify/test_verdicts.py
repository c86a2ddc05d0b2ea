"""Honest verdicts and budgets (issue 11): what ``rac verify`` answers on models that outgrow the
machine, and what its verdicts mean.

- A query ``under`` a shield is answered on what the shield allows, from the start: the unpruned
  model is never explored for it, and a shield that does not exist is reported as such before any
  exploration (not as "more than N states").
- ``E<>`` queries are tried on the pruned graph first: a run found there is a run of the model.
- An undecided query (*unknown*, *unsupported*) never exits 0: its own exit code, and a message in
  the user's terms (no internal function names) that says what to change.
- Exploration stops before it exceeds its budgets (``--max-states``, ``--max-memory``), also
  inside a layer: a layer is expanded in chunks, never allocated whole beyond the budget.
"""

from __future__ import annotations

import json
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from engine_files import QUERIES, write_engine_file

import rac.engine.explore as explore_module
from rac.cli.common import EXIT_ERRORS, EXIT_UNDECIDED
from rac.cli.main import main
from rac.compiler import compile_file
from rac.engine.budget import (
    BudgetExceeded,
    cgroup_limit,
    default_max_bytes,
    machine_memory,
    parse_size,
    projected_states,
)
from rac.engine.explore import explore
from rac.model.batch import BatchModel
from rac.model.data import ModelData
from rac.verify.runner import VerifyOptions, run_queries

LEFT_TURN = Path(__file__).resolve().parents[2] / "examples" / "left_turn" / "model.ra"


def sizes(data: ModelData, horizon: int) -> tuple[int, int]:
    """(pruned, unpruned) state counts of the model up to ``horizon`` samples."""
    return (explore(data, horizon_samples=horizon, prune_unsafe=True).n_states,
            explore(data, horizon_samples=horizon).n_states)


def between(data: ModelData, horizon: int) -> int:
    """A state budget the pruned model fits in and the unpruned one does not."""
    pruned, unpruned = sizes(data, horizon)
    assert pruned < unpruned, (pruned, unpruned)
    return (pruned + unpruned) // 2


# ---------------------------------------------------------------- strategies and pruning
def test_a_query_under_a_shield_never_explores_the_unpruned_model(tmp_path: Path) -> None:
    path = write_engine_file(tmp_path, "avoidable_obstacle", {"safe": QUERIES["safe"],
                                                              "Shielded": QUERIES["Shielded"]})
    result = compile_file(path)
    assert result.model_data is not None
    horizon = result.automaton.steps  # type: ignore[union-attr]
    budget = between(result.model_data, horizon)
    context, results = run_queries(result, VerifyOptions(seed=1, plots=False, max_states=budget))
    by_name = {r.name: r for r in results}
    assert by_name["Shielded"].status == "satisfied", by_name["Shielded"].message
    assert False not in context.graphs  # only the pruned model (the shield's) was explored


def test_a_shield_that_does_not_exist_is_said_before_any_exploration(tmp_path: Path) -> None:
    path = write_engine_file(tmp_path, "narrow_road", {"safe": QUERIES["safe"], "Shielded": QUERIES["Shielded"]})
    result = compile_file(path)
    assert result.model_data is not None
    budget = between(result.model_data, result.automaton.steps)  # type: ignore[union-attr]
    _, results = run_queries(result, VerifyOptions(seed=1, plots=False, max_states=budget))
    shielded = {r.name: r for r in results}["Shielded"]
    assert shielded.status == "not_applicable"
    assert shielded.message == ("the strategy `safe` does not exist: its defining query safe is not satisfied (no "
                                "strategy keeps `!collide() && !offroad()` from the start: it is false at the start)")


def test_reachability_is_tried_on_the_pruned_model_first(tmp_path: Path) -> None:
    """Qc (UPPAAL's literal reading) holds on a scene where a safe run reaches the goal: the pruned
    model shows it, so a budget the unpruned model exceeds still decides it."""
    path = write_engine_file(tmp_path, "goal_ahead", {"Reaches": QUERIES["Reaches"]})
    result = compile_file(path)
    assert result.model_data is not None
    budget = between(result.model_data, result.automaton.steps)  # type: ignore[union-attr]
    context, results = run_queries(result, VerifyOptions(seed=1, plots=False, max_states=budget))
    assert results[0].status == "satisfied", results[0].message
    assert False not in context.graphs


# ---------------------------------------------------------------- exit codes and messages
def test_an_undecided_query_has_its_own_exit_code(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = write_engine_file(tmp_path, "goal_ahead")  # `-->` needs the whole model: beyond 10 states
    assert main(["verify", str(path), "--query", "LeadsTo", "--max-states", "10"]) == EXIT_UNDECIDED
    assert EXIT_UNDECIDED not in (0, EXIT_ERRORS)
    out = capsys.readouterr().out
    assert "UNKNOWN" in out
    # a query that does not hold (Qb on the narrow road: decided within 10 states) outweighs one that
    # is undecided (E<> Close, in the product)
    path = write_engine_file(tmp_path, "narrow_road", {"Stays": QUERIES["Stays"], "Somewhere": QUERIES["Somewhere"]})
    assert main(["verify", str(path), "--query", "Somewhere", "--max-states", "10"]) == EXIT_UNDECIDED
    assert main(["verify", str(path), "--max-states", "10"]) == EXIT_ERRORS
    out = capsys.readouterr().out
    assert "Verifying Stays" in out and "Formula is NOT satisfied" in out


def test_an_unknown_verdict_speaks_the_users_language(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = write_engine_file(tmp_path, "goal_ahead")
    main(["verify", str(path), "--query", "LeadsTo", "--query", "Somewhere", "--max-states", "10"])
    out = capsys.readouterr().out
    assert not re.search(r"\b\w+\(\):", out), out  # no internal function names
    assert "the model has more than 10 states by t = 1 s (sample 2)" in out
    assert "the product of model and automaton has more than 10 states by t = 0.5 s (sample 1)" in out
    assert "--max-states" in out and "--horizon" in out
    main(["verify", str(path), "--query", "LeadsTo", "--max-states", "10", "--format", "json"])
    (result,) = json.loads(capsys.readouterr().out)["results"]
    assert result["status"] == "unknown"
    assert result["message"].startswith("the model has more than 10 states by t = 1 s (sample 2)")


# ---------------------------------------------------------------- budgets
def left_turn() -> ModelData:
    result = compile_file(LEFT_TURN)
    assert result.model_data is not None
    return result.model_data


def test_a_chunked_layer_is_the_same_graph(monkeypatch: pytest.MonkeyPatch) -> None:
    data = left_turn()  # 81 action pairs per decision
    whole = explore(data, horizon_samples=3)
    monkeypatch.setattr(explore_module, "CHUNK_ROWS", 97)
    chunked = explore(data, horizon_samples=3)
    assert whole.n_states == chunked.n_states
    for name in ("states", "choice_offsets", "choice_action", "choice_target"):
        assert np.array_equal(getattr(whole, name), getattr(chunked, name)), name
    for name, mask in whole.labels.items():
        assert np.array_equal(mask, chunked.labels[name]), name


def test_a_layer_beyond_the_state_budget_is_never_allocated(monkeypatch: pytest.MonkeyPatch) -> None:
    data = left_turn()
    rows: list[int] = []
    sense = BatchModel.sense

    def recording(self: BatchModel, states: np.ndarray) -> np.ndarray:
        rows.append(states.shape[0])
        return sense(self, states)

    monkeypatch.setattr(BatchModel, "sense", recording)
    monkeypatch.setattr(explore_module, "CHUNK_ROWS", 500)
    full = explore(data, horizon_samples=3).n_states
    rows.clear()
    with pytest.raises(BudgetExceeded) as raised:
        explore(data, horizon_samples=3, max_states=full // 3)
    assert max(rows) <= 500  # the layer was expanded chunk by chunk
    assert sum(rows) < 81 * 81 * 81  # and stopped before the last layer was whole
    assert raised.value.kind == "states" and raised.value.limit == full // 3
    assert f"more than {full // 3:,} states" in str(raised.value)


def test_the_message_says_how_far_the_horizon_is() -> None:
    # nine successors per decision, a decision every 2 samples: the layers stay constant in between
    nine = [1, *(9 ** ((k + 1) // 2) for k in range(1, 11))]
    assert nine[:5] == [1, 9, 9, 81, 81]
    assert projected_states(nine[:5], 2, 10) == (sum(nine), 9.0)
    assert projected_states(nine[:2], 2, 10) == (sum(nine), 9.0)  # from the first decision's successors on
    assert projected_states([1, 1, 1], 1, 5) == (6, 1.0)
    assert projected_states([1], 2, 10) is None  # no decision's successors yet
    with pytest.raises(BudgetExceeded) as raised:
        explore(left_turn(), horizon_samples=6, max_states=5000)
    assert raised.value.projected_states is not None and raised.value.projected_states > 5000
    assert "per decision, the horizon (sample 6) would have about" in str(raised.value)


def test_the_memory_budget_stops_before_it_is_exceeded() -> None:
    data = left_turn()
    with pytest.raises(BudgetExceeded) as raised:
        explore(data, horizon_samples=4, max_bytes=2 * 2**20)
    assert raised.value.kind == "memory"
    assert raised.value.needed_bytes > 2 * 2**20
    message = str(raised.value)
    assert "--max-memory" in message and "2 MB" in message


def test_the_default_memory_budget_is_a_safe_fraction_of_the_machine() -> None:
    total = machine_memory()
    assert total > 0
    assert 0 < default_max_bytes() <= total // 2


@pytest.mark.parametrize(("text", "size"), [("512M", 512 * 2**20), ("4G", 4 * 2**30), ("1.5G", 3 * 2**29),
                                            ("2048", 2048), ("64k", 64 * 2**10)])
def test_sizes_read_as_people_write_them(text: str, size: int) -> None:
    assert parse_size(text) == size


@pytest.mark.parametrize("text", ["", "G", "-1G", "4X", "1e3"])
def test_a_size_that_is_not_one_is_refused(text: str) -> None:
    with pytest.raises(ValueError, match="size"):
        parse_size(text)


# ---------------------------------------------------------------- statistics
def test_probability_intervals_cover_the_exact_value() -> None:
    """Calibration: over 400 seeds, the 95% Clopper-Pearson interval of ``Pr[<=2; 100](<> collide())``
    covers Storm's exact probability (uniform choices on the explored model) at least 93% of the time,
    and so does the sequential estimate (``Pr[<=2](...)``, stopping at half-width 0.1) over 200 seeds.
    A simulation whose semantics differed from the explored model's would miss far more often."""
    import tempfile

    folder = Path(tempfile.mkdtemp())
    for query, seeds, options in (("Pr[<=2; 100](<> collide())", 400, {}),
                                  ("Pr[<=2](<> collide())", 200, {"epsilon": 0.1})):
        path = write_engine_file(folder, "avoidable_obstacle", {"P": query})
        result = compile_file(path)
        covered = 0
        for seed in range(seeds):
            (answer,) = run_queries(result, VerifyOptions(seed=seed, plots=False, out_dir=folder / "o",
                                                          **options))[1]  # type: ignore[arg-type]
            assert answer.exact is not None and answer.interval is not None
            covered += answer.interval[0] <= answer.exact <= answer.interval[1]
        assert 0 < answer.exact < 1  # a probability worth estimating (0.62 here)
        assert covered >= 0.93 * seeds, (query, covered, seeds)


def test_every_probability_query_draws_its_own_seed(tmp_path: Path) -> None:
    """Two identical queries in one file are independent estimates (their own seeds), and the whole
    file is reproducible from --seed."""
    path = write_engine_file(tmp_path, "avoidable_obstacle", {"A": "Pr[<=2; 50](<> collide())",
                                                              "B": "Pr[<=2; 50](<> collide())"})
    result = compile_file(path)
    first = run_queries(result, VerifyOptions(seed=7, plots=False, out_dir=tmp_path / "o"))[1]
    again = run_queries(result, VerifyOptions(seed=7, plots=False, out_dir=tmp_path / "o"))[1]
    assert first[0].seed != first[1].seed
    assert [(r.seed, r.estimate) for r in first] == [(r.seed, r.estimate) for r in again]
    # the seed a command reports is the one that reproduces it (`rac render --seed 1` said "seed 164...")
    context, drawn = run_queries(result, VerifyOptions(plots=False, out_dir=tmp_path / "o"))
    assert run_queries(result, VerifyOptions(seed=7, plots=False, out_dir=tmp_path / "o"))[0].seed == 7
    replay = run_queries(result, VerifyOptions(seed=context.seed, plots=False, out_dir=tmp_path / "o"))[1]
    assert [(r.seed, r.estimate) for r in replay] == [(r.seed, r.estimate) for r in drawn]


def test_a_simulation_without_obstacles_says_so(tmp_path: Path) -> None:
    """On an empty road `mindist()` reads 1e9 at every sample: the result says there is no obstacle
    instead of leaving "1000000000" to be read as a distance."""
    path = write_engine_file(tmp_path, "goal_ahead", {"Sim": QUERIES["Sim"]})
    result = compile_file(path)
    assert result.model_data is not None and result.model_data.obstacle_count == 0
    (answer,) = run_queries(result, VerifyOptions(seed=1, plots=False, out_dir=tmp_path / "o"))[1]
    assert answer.message is not None
    assert "no obstacle at any sample (the scenario has none): `mindist()` reads 1e9" in answer.message


# ---------------------------------------------------------------- what Qc means, everywhere
def dead_end(folder: Path, queries: dict[str, str] | None = None) -> Path:
    """A road that ends 3 m after the goal (x in [20, 30]); the ego at 10 m/s cannot stop before
    the end within the 4 s horizon: a run reaches the goal safely, and every run then leaves the road.
    ``queries``: the file's (default Qb, then Qc)."""
    from engine_files import engine_source
    from tiny_scenarios import EgoStart, GoalBox, StraightRoad, straight_road

    tiny = straight_road("dead_end", StraightRoad(33.0, EgoStart(10.0, 1.75, 0.0, 10.0), GoalBox(20.0, 30.0)))
    tiny.write(folder / "dead_end.xml")
    path = folder / "dead_end.ra"
    queries = queries or {"Stays": QUERIES["Stays"], "Reaches": QUERIES["Reaches"]}
    path.write_text(engine_source(tiny, queries), encoding="utf-8")
    return path


def test_qc_means_the_same_in_verify_and_preanalyse(tmp_path: Path) -> None:
    from rac.studies.preanalysis import render_table, sweep

    result = compile_file(dead_end(tmp_path))
    answers = {r.name: r for r in run_queries(result, VerifyOptions(seed=1, plots=False, out_dir=tmp_path / "o"))[1]}
    assert answers["Stays"].status == "not satisfied"  # no run stays safe to the horizon
    assert answers["Reaches"].status == "satisfied"
    assert answers["Reaches"].message == ("a run that stays safe until it gets there exists (the trace); "
                                          "NONE of them stays safe to the horizon (4 s)")
    (row,) = sweep(result, runs=5, seed=1)
    assert (row["qb"], row["qc"], row["qc_horizon"]) == (False, True, False)
    assert "| true (safe until the goal only) |" in render_table([row])


def test_qc_left_open_is_decided_by_the_complete_graph_a_later_query_explores(tmp_path: Path) -> None:
    """Qc before the shield: its witness is found by the search, no random run continues it to the horizon
    (every run leaves the dead end's road), and the shield's query explores the complete pruned graph
    afterwards. Qc's "safe to the horizon?" is then decided on that graph, as when it comes first (before:
    "not known", beside a learning query that proves no shielded run reaches the goal)."""
    path = dead_end(tmp_path, {"Reaches": QUERIES["Reaches"], "safe": QUERIES["safe"]})
    answers = {r.name: r for r in run_queries(compile_file(path), VerifyOptions(seed=1, plots=False))[1]}
    assert answers["Reaches"].status == "satisfied" and answers["Reaches"].method == "witness search"
    assert answers["Reaches"].message == ("a run that stays safe until it gets there exists (the trace); NONE of "
                                          "them stays safe to the horizon (4 s) (decided on the complete pruned "
                                          "model, which a later query explored)")


def test_the_experiment_counts_a_goal_only_when_the_run_can_stay_safe_to_the_horizon(tmp_path: Path) -> None:
    """On the dead end every run that reaches the goal leaves the road before the horizon: no greedy
    run, learning episode or evaluation run is "safe at the goal" (before: all of them were)."""
    from rac.studies.experiment import render_markdown, run_experiment

    result = compile_file(dead_end(tmp_path))
    report = run_experiment(result, seeds=(1, 2), episodes=40, evaluation_runs=5, parallel=8,
                            combinations=("RA", "RF"), reward_function="10 * !near + 100 * goal()")
    records = report["records"]
    assert records and all(r.greedy_success is False and r.first_success_episode is None for r in records)
    assert all(r.evaluation_successes == 0 and not r.succeeded.any() for r in records)
    assert "safe at the goal and to the horizon" in render_markdown(report)


@pytest.mark.parametrize(("files", "membership", "limit"), [
    ({"memory.max": "max\n"}, "0::/\n", None),                                  # cgroup v2, no limit
    ({"job/memory.max": "2147483648\n"}, "0::/job\n", 2 * 2**30),             # v2, the process's own cgroup
    ({"memory/memory.limit_in_bytes": "9223372036854771712\n"}, "4:memory:/x\n", None),  # v1, no limit
    ({"memory/memory.limit_in_bytes": "1073741824\n"}, "4:memory:/docker/abc\n", 2**30),  # v1 at the mount
    ({}, "", None),                                                                # no cgroup file at all
])
def test_a_containers_memory_limit_is_read(files: dict[str, str], membership: str, limit: int | None,
                                           tmp_path: Path) -> None:
    # a container is killed at its limit, never swapping first: half the host's memory would be no budget
    for name, text in files.items():
        (tmp_path / name).parent.mkdir(parents=True, exist_ok=True)
        (tmp_path / name).write_text(text, encoding="ascii")
    assert cgroup_limit(tmp_path, membership) == limit


def test_the_default_budget_keeps_within_ulimit_v() -> None:
    # `ulimit -v 3G` in the shell: the default budget is half of that, not half the machine's memory
    script = ("import resource; resource.setrlimit(resource.RLIMIT_AS, (3 * 2**30, resource.RLIM_INFINITY)); "
              "from rac.engine.budget import default_max_bytes, physical_memory; "
              "print(default_max_bytes(), physical_memory())")
    out = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, check=True).stdout.split()
    budget, physical = int(out[0]), int(out[1])
    assert budget == min(3 * 2**30, physical) // 2
