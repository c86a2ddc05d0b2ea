"""``rac sweep`` on Dask (issue 13): the orchestration half — a real ``LocalCluster`` of 2 workers, the
store and its skip on re-run, a worker killed mid-task, the timeout row, Ctrl-C, a separate ``dask
scheduler`` and ``dask worker`` driven through ``--scheduler``, the merged results (Parquet, or CSV
without pyarrow), the summary, the plots and the exit codes.

The scenarios are built with commonroad-io (:mod:`tiny_scenarios`, :mod:`rac.model.scenes`): four tiny
roads, the highway scene (its ego starts at 20 m/s, above the template's ``max_speed 10``: its check fails)
and a broken XML file. The template asks one query, ``Stays`` (Qb), whose answers the tiny roads know by
construction: it fails only on the narrow road. Stand-in tasks (:mod:`sweep_helpers`) kill their worker,
sleep or raise where the real :func:`rac.sweep.task.run_task` cannot be made to.
"""

from __future__ import annotations

import _thread
import contextlib
import dataclasses
import json
import os
import re
import shutil
import signal
import socket
import subprocess
import sys
import threading
import time
import types
from collections.abc import Iterator
from pathlib import Path

import pandas as pd
import psutil
import pytest
import sweep_helpers
from conftest import rac_env
from engine_files import engine_source
from PIL import Image
from tiny_scenarios import TINY_SCENARIOS

import rac
from rac.cli.common import EXIT_ERRORS, EXIT_INTERRUPTED, EXIT_OK, EXIT_UNDECIDED, EXIT_USAGE, output_folder
from rac.cli.main import main
from rac.cli.sweep import exit_status
from rac.model.scenes import write_scene
from rac.sweep import Plan, SweepResult, execute, plan, sweep
from rac.sweep.report import render_summary, summarise, write_plots
from rac.sweep.run import KILLED, Outcome, Tracker, connect, pending, rows_in_order, run_tasks, workers_of
from rac.sweep.store import Store
from rac.sweep.task import TaskSpec, source_digest

#: The scenarios of the sweep and the status each task ends in (the template's query is Qb).
EXPECTED = {"avoidable_obstacle": "ok", "broken": "error", "goal_ahead": "ok", "goal_behind_wall": "ok",
            "highway": "failed", "narrow_road": "failed"}
OPTIONS = {"horizon": "2"}  # half the tiny roads' horizon: their Qb answers hold, and each task is quick


@pytest.fixture(scope="module")
def world(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """``sweep.ra`` (its own scenario is never used) and ``scenarios/`` (:data:`EXPECTED`)."""
    root = tmp_path_factory.mktemp("sweep_dask")
    queries = {"Stays": "E[] !collide() && !offroad()"}
    (root / "sweep.ra").write_text(engine_source(TINY_SCENARIOS["goal_ahead"](), queries,
                                                 scenario_file="placeholder.xml"), encoding="utf-8")
    scenarios = root / "scenarios"
    scenarios.mkdir()
    for name in ("avoidable_obstacle", "goal_ahead", "goal_behind_wall", "narrow_road"):
        TINY_SCENARIOS[name]().write(scenarios / f"{name}.xml")
    write_scene("highway", scenarios / "highway.xml")
    (scenarios / "broken.xml").write_text("<commonRoad><lanelet id='1'>", encoding="utf-8")
    return root


@pytest.fixture(scope="module")
def swept(world: Path) -> tuple[SweepResult, list[str]]:
    """The sweep of every scenario on a local cluster of 2 workers, and what it announced."""
    said: list[str] = []
    planned = plan(world / "sweep.ra", [str(world / "scenarios")], options=OPTIONS)
    return execute(planned, workers=2, quiet=True, announce=said.append), said


@pytest.fixture(scope="module")
def client() -> Iterator[object]:
    """A local cluster of 2 workers, as rac starts it, for the stand-in tasks."""
    with connect(workers=2) as dask_client:
        yield dask_client


def by_scenario(rows: list[dict[str, object]]) -> dict[str, dict[str, object]]:
    return {str(row["scenario_name"]): row for row in rows}


def is_png(path: Path) -> bool:
    with Image.open(path) as image:
        image.verify()
        return image.format == "PNG"


def no_cluster(*args: object, **kwargs: object) -> None:
    raise AssertionError("a cluster was started")


def stand_in(monkeypatch: pytest.MonkeyPatch, function: object) -> None:
    """Dask tasks run ``function`` instead of run_task (it is sent to the workers by reference)."""
    monkeypatch.setattr("rac.sweep.run.task_function", lambda: function)


def specs_for(folder: Path, template: Path, names: list[str], **kw: object) -> list[TaskSpec]:
    """Stand-in specs: one small file per name (a key hashes the file's bytes)."""
    specs = []
    text = template.read_text(encoding="utf-8")
    for name in names:
        (folder / name).write_text(name, encoding="utf-8")
        specs.append(TaskSpec(str(template), text, str(folder / name), (), "verify", **kw))  # type: ignore[arg-type]
    return specs


# ---------------------------------------------------------------- the rows, on a local cluster
def test_every_scenario_gives_its_row(swept: tuple[SweepResult, list[str]], world: Path) -> None:
    result, said = swept
    rows = by_scenario(result.rows)
    assert {name: row["status"] for name, row in rows.items()} == EXPECTED
    assert result.outcome.ran == 6 and result.outcome.skipped == 0 and not result.outcome.interrupted
    for name in ("avoidable_obstacle", "goal_ahead", "goal_behind_wall"):
        assert rows[name]["verdicts"] == {"Stays": "satisfied"}, rows[name]
    assert rows["narrow_road"]["verdicts"] == {"Stays": "not satisfied"}  # every state is off its road
    assert any(str(d).startswith("E0714 ") for d in rows["highway"]["diagnostics"])  # type: ignore[attr-defined]
    assert "broken.xml" in str(rows["broken"]["error"])
    assert rows["goal_ahead"]["settings"] == {} and rows["goal_ahead"]["task"] == "verify"
    assert any(line.startswith("dashboard: http://") and "local cluster, 2 workers" in line for line in said), said
    # one stored file per task, each holding its row
    store = Store(result.plan.out)
    assert sorted(p.stem for p in store.folder.glob("*.json")) == sorted(str(r["key"]) for r in result.rows)
    assert store.get(str(rows["narrow_road"]["key"])) == rows["narrow_road"]


def test_the_results_are_merged_summarised_and_plotted(swept: tuple[SweepResult, list[str]]) -> None:
    result, _ = swept
    out = result.plan.out
    assert out == output_folder(result.plan.template, "sweep")  # the output convention: sweep.out/sweep/
    table = pd.read_parquet(out / "results.parquet")
    assert dict(zip(table["scenario_name"], table["status"])) == EXPECTED
    verdicts = table.set_index("scenario_name")["verdicts.Stays"].dropna().to_dict()
    assert verdicts == {"avoidable_obstacle": "satisfied", "goal_ahead": "satisfied", "goal_behind_wall": "satisfied",
                        "narrow_road": "not satisfied"}  # no verdict where the file could not be checked
    assert set(table["grid_point"]) == {"template settings"}
    assert json.loads((out / "results.json").read_text(encoding="utf-8")) == result.rows
    assert is_png(out / "verdicts.png") and is_png(out / "time_vs_size.png")
    summary = result.summary
    assert (summary.tasks, summary.ok, summary.failed, summary.skipped, summary.not_run) == (6, 3, 3, 0, 0)
    assert summary.queries == {"Stays": {"satisfied": 3, "not satisfied": 1, "unknown": 0, "unsupported": 0,
                                            "not_applicable": 0}}
    assert summary.seconds["p50"] <= summary.seconds["p90"] <= summary.seconds["max"]
    text = render_summary(summary)
    assert text.splitlines()[:3] == ["tasks  ok  failed  undecided  skipped  not run",
                                     "    6   3       3          0        0        0",
                                     "failed: 1 with a query not satisfied, 1 with errors in the file, "
                                     "1 that rac could not run"]
    assert "error: broken [template settings]: " in text and "failed: highway [template settings]: E0714" in text
    assert exit_status(result.rows) == EXIT_ERRORS  # a query not satisfied, a file with errors


def test_the_verdict_plot_of_a_large_grid_stays_drawable(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """verdicts.png drew a bar 0.8 inch wide per grid point: a grid of 1,000 points took 20 s to draw a PNG
    88,000 pixels wide. It draws the first 40 points now, and its title says so."""
    from rac.sweep import report

    titles: list[str] = []
    save = report.save_figure
    monkeypatch.setattr(report, "save_figure", lambda figure, path: titles.append(figure.axes[0].get_title())
                        or save(figure, path))
    rows = [{"settings": {"exponent": str(i)}, "status": "ok", "verdicts": {"Stays": "satisfied"}, "seconds": 0.1,
             "scenario_size": 3} for i in range(300)]
    verdicts, _ = write_plots(rows, tmp_path)
    assert " ".join(titles[0].split()) == ("verdicts per grid point (300 tasks; the first 40 of 300 grid points, "
                                           "results.* hold all)")
    with Image.open(verdicts) as image:
        assert image.size[0] < 5000, image.size
    with Image.open(write_plots(rows[:3], tmp_path / "small")[0]) as image:  # a small grid as before
        assert image.size[0] < 1000


def test_whole_number_columns_stay_whole_beside_an_empty_cell(tmp_path: Path) -> None:
    """results.parquet gave a failed task's empty states beside an ok task's 94468 as float64: 94468.0, and
    peak_memory and scenario_size alike. Those columns are pandas' nullable Int64; seconds stay floats."""
    pytest.importorskip("pyarrow", reason="Parquet needs pyarrow")
    from rac.sweep.report import frame, write_results

    rows = [{"scenario": "a.xml", "settings": {}, "task": "experiment", "status": "ok", "seconds": 1.5,
             "states": 94468, "scenario_size": 6, "peak_memory": 135507968},
            {"scenario": "b.xml", "settings": {}, "task": "experiment", "status": "failed", "seconds": 0.25,
             "states": None, "scenario_size": None, "peak_memory": 110960640}]
    write_results(rows, tmp_path)
    for data in (pd.read_parquet(tmp_path / "results.parquet"), frame(rows)):
        assert {str(data[name].dtype) for name in ("states", "scenario_size", "peak_memory")} == {"Int64"}
        assert data["states"].tolist()[0] == 94468 and data["states"].isna().tolist() == [False, True]
        assert str(data["seconds"].dtype) == "float64"


def test_the_verdict_plot_counts_a_task_without_verdicts_per_query(tmp_path: Path,
                                                                   monkeypatch: pytest.MonkeyPatch) -> None:
    """A preanalyse sweep of four tasks answering Qb-Qd and one whose file failed the check drew a bar of 13 "queries
    × scenarios": the failed task counted once beside the others' three. It counts once per query (15)."""
    from rac.sweep import report

    heights: list[float] = []
    save = report.save_figure
    monkeypatch.setattr(report, "save_figure", lambda figure, path: heights.extend(
        patch.get_height() for patch in figure.axes[0].patches) or save(figure, path))
    answered = {"Qb": "satisfied", "Qc": "satisfied", "Qd": "not satisfied"}
    rows = [*({"settings": {}, "status": "ok", "verdicts": answered, "seconds": 0.1, "scenario_size": 3}
              for _ in range(4)),
            {"settings": {}, "status": "failed", "verdicts": {}, "seconds": 0.1, "scenario_size": 3}]
    write_plots(rows, tmp_path)
    assert sorted(heights) == [3, 4, 8]  # task failed: 3 queries; not satisfied: 4; satisfied: 8
    heights.clear()
    write_plots([{**row, "verdicts": {}} for row in rows], tmp_path)  # no verdicts at all (experiment): tasks
    assert sorted(heights) == [1, 4]


def test_the_verdict_bars_differ_by_more_than_colour(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """verdicts.png told satisfied, not satisfied and a failed task apart by green, red and orange alone, which a
    colour-blind reader cannot: each segment has a hatching of its own now, shown in the legend too."""
    from rac.sweep import report

    figures: list = []
    monkeypatch.setattr(report, "save_figure", lambda figure, path: figures.append(figure) or Path(path))
    rows = [{"settings": {}, "status": status, "verdicts": verdicts, "seconds": 0.1, "scenario_size": 3}
            for status, verdicts in (("ok", {"Q": "satisfied"}), ("failed", {"Q": "not satisfied"}),
                                     ("failed", {}), ("error", {}), ("timeout", {}))]
    write_plots(rows, tmp_path)
    ax = figures[0].axes[0]
    labels = [container.get_label() for container in ax.containers]
    hatches = {label: container[0].get_hatch() or "" for label, container in zip(labels, ax.containers)}
    assert sorted(hatches) == ["not satisfied", "satisfied", "task error", "task failed", "task timeout"]
    assert len(set(hatches.values())) == len(hatches), hatches
    assert [handle.get_hatch() or "" for handle in ax.get_legend().legend_handles] == \
        [hatches[text.get_text()] for text in ax.get_legend().get_texts()]


def test_the_verdict_legend_lists_the_segments_as_they_stack(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """verdicts.png's legend read satisfied, not satisfied, task failed from the top while the bars stacked them
    from the bottom: the legend's first entry stood beside the top segment, which was another."""
    from rac.sweep import report

    figures: list = []
    monkeypatch.setattr(report, "save_figure", lambda figure, path: figures.append(figure) or Path(path))
    rows = [{"settings": {}, "status": status, "verdicts": verdicts, "seconds": 0.1, "scenario_size": 3}
            for status, verdicts in (("ok", {"Q": "satisfied"}), ("failed", {"Q": "not satisfied"}), ("failed", {}))]
    write_plots(rows, tmp_path)
    ax = figures[0].axes[0]
    from_top = sorted(ax.containers, key=lambda bars: -bars[0].get_y())
    assert [text.get_text() for text in ax.get_legend().get_texts()] == [bars.get_label() for bars in from_top]
    assert from_top[0].get_label() == "task failed"


def test_the_time_plot_without_sizes_says_so(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """A sweep whose scenario files all failed to load drew time_vs_size.png as an empty axes from 0 to 1, as if
    the plot had failed; it says there is nothing to draw now (and draws nothing else)."""
    from rac.sweep import report

    figures: list = []
    monkeypatch.setattr(report, "save_figure", lambda figure, path: figures.append(figure) or Path(path))
    rows = [{"settings": {}, "status": "error", "verdicts": {}, "seconds": 0.1, "scenario_size": None}] * 2
    sized = [{"settings": {}, "status": "ok", "verdicts": {}, "seconds": 0.1, "scenario_size": 3}]
    write_plots(rows, tmp_path)
    write_plots(sized, tmp_path)
    empty, drawn = figures[1].axes[0], figures[3].axes[0]
    assert [text.get_text() for text in empty.texts] == ["no task has a scenario size and a time: nothing to draw"]
    assert "2 tasks without a size not shown" in empty.get_title()
    assert not drawn.texts and drawn.collections


def test_the_time_plot_ticks_sizes_as_whole_numbers(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """time_vs_size.png of scenarios all of one size (3) had size ticks at 2.96, 2.98, 3.00, ..."""
    from rac.sweep import report

    figures: list = []
    monkeypatch.setattr(report, "save_figure", lambda figure, path: figures.append(figure) or Path(path))
    write_plots([{"settings": {}, "status": "ok", "verdicts": {}, "seconds": s, "scenario_size": 3}
                 for s in (0.1, 0.2)], tmp_path)
    ax = figures[1].axes[0]
    figures[1].draw_without_rendering()
    low, high = ax.get_xlim()
    ticks = [tick for tick in ax.get_xticks() if low <= tick <= high]
    assert ticks and all(float(tick).is_integer() for tick in ticks), ticks


def test_a_sweep_without_rows_leaves_no_plots_of_an_earlier_one(tmp_path: Path) -> None:
    """A sweep stopped before any row (Ctrl-C at once, nothing stored) wrote empty results.* but left the plots
    of the earlier sweep in the folder, which then showed rows the results did not hold."""
    rows = [{"settings": {}, "status": "ok", "verdicts": {"Stays": "satisfied"}, "seconds": 0.1, "scenario_size": 3}]
    assert all(path.is_file() for path in write_plots(rows, tmp_path))
    (tmp_path / "mine.png").write_bytes(b"")  # not the sweep's: stays
    assert write_plots([], tmp_path) == []
    assert sorted(path.name for path in tmp_path.iterdir()) == ["mine.png"]


def test_a_rerun_skips_the_stored_tasks_without_a_cluster(swept: tuple[SweepResult, list[str]], world: Path,
                                                          monkeypatch: pytest.MonkeyPatch) -> None:
    first, _ = swept
    monkeypatch.setattr("rac.sweep.run.connect", no_cluster)
    again = execute(plan(world / "sweep.ra", [str(world / "scenarios")], options=OPTIONS), workers=2, quiet=True)
    assert again.outcome.ran == 0 and again.outcome.skipped == 6
    assert again.rows == first.rows
    # the stored rows not ok are shown as they were (an error of a worker's environment since fixed among them):
    # the summary said only "skipped: 6", and a user who fixed the cause saw the same errors without a word
    assert render_summary(again.summary).splitlines()[1:3] == [
        "    6   3       3          0        6        0",
        "skipped: 6 stored by an earlier run (--force runs them again); 3 of them not ok, shown as stored "
        "(--retry-failed runs those again)"]
    assert again.summary.to_json()["skipped_not_ok"] == 3
    # --force: every task again; a task whose file is gone: that one only
    store = Store(first.plan.out)
    assert len(pending(first.plan.specs, store, force=True)[1]) == 6
    goal = next(row for row in first.rows if row["scenario_name"] == "goal_ahead")
    store.path(str(goal["key"])).rename(store.folder / "elsewhere")
    try:
        outcome, todo = pending(first.plan.specs, store)
        assert list(todo) == [goal["key"]] and outcome.skipped == 5
    finally:
        (store.folder / "elsewhere").rename(store.path(str(goal["key"])))
    # a different grid point is a different task: nothing stored yet
    other = plan(world / "sweep.ra", [str(world / "scenarios")], sets=["exponent=1"], options=OPTIONS)
    assert len(pending(other.specs, store)[1]) == 6


def test_the_python_api_returns_a_dataframe_or_dicts(swept: tuple[SweepResult, list[str]], world: Path,
                                                     monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr("rac.sweep.run.connect", no_cluster)  # every row is stored
    frame = sweep(world / "sweep.ra", world / "scenarios", options=OPTIONS, quiet=True)
    assert isinstance(frame, pd.DataFrame) and len(frame) == 6
    assert frame.set_index("scenario_name").loc["narrow_road", "verdicts.Stays"] == "not satisfied"
    with monkeypatch.context() as without:
        without.setitem(sys.modules, "pandas", None)  # pandas not installed
        rows = sweep(world / "sweep.ra", world / "scenarios", options=OPTIONS, quiet=True)
    assert rows == swept[0].rows
    sweep(world / "sweep.ra", world / "scenarios", options=OPTIONS, quiet=True)  # results.parquet again


def test_without_pyarrow_the_results_are_csv(swept: tuple[SweepResult, list[str]], world: Path,
                                             monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
                                             ) -> None:
    out = swept[0].plan.out
    command = ["sweep", str(world / "sweep.ra"), str(world / "scenarios"), "--horizon", "2", "-q"]
    monkeypatch.setattr("rac.sweep.run.connect", no_cluster)
    with monkeypatch.context() as without:
        without.setitem(sys.modules, "pyarrow", None)  # pyarrow not installed
        assert main(command) == EXIT_ERRORS
    captured = capsys.readouterr()
    assert "note: wrote results.csv, not results.parquet: Parquet needs pandas and pyarrow" in captured.err
    assert f"wrote {out / 'results.csv'}" in captured.out
    assert not (out / "results.parquet").exists()  # the earlier run's: it would not be this run's results
    table = pd.read_csv(out / "results.csv")
    assert dict(zip(table["scenario_name"], table["status"])) == EXPECTED
    assert main(command) == EXIT_ERRORS  # with pyarrow: results.parquet again, and no stale CSV
    assert (out / "results.parquet").exists() and not (out / "results.csv").exists()


# ---------------------------------------------------------------- workers that die, tasks that raise or time out
def test_a_killed_worker_is_replaced_and_its_task_retried(client, tmp_path: Path, world: Path,
                                                          monkeypatch: pytest.MonkeyPatch) -> None:
    stand_in(monkeypatch, sweep_helpers.kill_once)
    specs = specs_for(tmp_path, world / "sweep.ra", ["kill_me.xml", "calm.xml"])
    store = Store(tmp_path / "out")
    outcome, todo = pending(specs, store)
    run_tasks(client, specs, todo, outcome, store)
    killed, calm = (outcome.rows[key] for key in outcome.keys)
    assert killed["status"] == "ok", killed
    assert killed["details"]["attempts"] == 2  # type: ignore[index]  # killed once, then retried
    assert calm["status"] == "ok" and calm["details"]["attempts"] == 1  # type: ignore[index]
    client.wait_for_workers(2, timeout=60)  # type: ignore[attr-defined]  # Dask replaced the dead worker
    assert store.get(str(killed["key"])) == killed


def test_a_worker_that_dies_twice_or_a_task_that_raises_is_an_error_row(client, tmp_path: Path, world: Path,
                                                                        monkeypatch: pytest.MonkeyPatch) -> None:
    specs = specs_for(tmp_path, world / "sweep.ra", ["doomed.xml"])
    store = Store(tmp_path / "out")
    stand_in(monkeypatch, sweep_helpers.kill_always)
    outcome, todo = pending(specs, store)
    run_tasks(client, specs, todo, outcome, store)
    doomed = outcome.rows[outcome.keys[0]]
    assert (doomed["status"], doomed["error"], doomed["scenario_name"]) == ("error", KILLED, "doomed")
    assert exit_status([doomed]) == EXIT_UNDECIDED

    stand_in(monkeypatch, sweep_helpers.raises)
    specs = specs_for(tmp_path, world / "sweep.ra", ["raising.xml"])
    outcome, todo = pending(specs, store)
    run_tasks(client, specs, todo, outcome, store)
    row = outcome.rows[outcome.keys[0]]
    assert (row["status"], row["error"]) == ("error", "RuntimeError: no row for raising.xml")
    assert store.get(outcome.keys[0]) == row  # stored: a re-run does not try again (--force does)
    client.wait_for_workers(2, timeout=60)  # type: ignore[attr-defined]


def test_a_task_the_cluster_cancelled_has_no_row_and_runs_again(client, tmp_path: Path, world: Path,
                                                                 monkeypatch: pytest.MonkeyPatch) -> None:
    """When the scheduler of a cluster at --scheduler went away, Dask cancelled every task left
    ("scheduler-connection-lost"), and each became a stored error row, FutureCancelledError: a row no later run
    ran again, for a task that never ran. Now a cancelled task has no row, is counted, and runs next time."""
    from distributed import Future

    specs = specs_for(tmp_path, world / "sweep.ra", ["fast0.xml", "wait1.xml", "wait2.xml", "wait3.xml"])
    stand_in(monkeypatch, sweep_helpers.waits)
    store = Store(tmp_path / "out")
    outcome, todo = pending(specs, store)

    def cancel_the_rest(spec: TaskSpec, row: dict[str, object]) -> None:  # as a scheduler gone cancels them
        left = [key for key in list(client.futures) if any(f"-{other}-" in str(key) for other in outcome.keys[1:])]
        client.cancel([Future(key, client) for key in left])

    run_tasks(client, specs, todo, outcome, store, on_row=cancel_the_rest)
    assert [path.stem for path in store.folder.glob("*.json")] == [outcome.keys[0]]
    assert list(pending(specs, store)[1]) == outcome.keys[1:]  # the same command runs them
    assert set(outcome.rows) == {outcome.keys[0]} and outcome.cancelled == 3 and outcome.ran == 1


def test_a_sweep_with_tasks_the_cluster_cancelled_says_so_and_is_not_ok(world: Path, tmp_path: Path,
                                                                        monkeypatch: pytest.MonkeyPatch,
                                                                        capsys: pytest.CaptureFixture[str]) -> None:
    """Every row there ok, one task cancelled by the cluster: not exit 0 as if the sweep were complete."""
    scenarios = [str(world / "scenarios" / f"{name}.xml") for name in ("goal_ahead", "avoidable_obstacle")]
    planned = plan(world / "sweep.ra", scenarios, options=OPTIONS, out=tmp_path / "out")
    Store(planned.out).put(planned.specs[1].key(), sweep_helpers.row(planned.specs[1]))

    @contextlib.contextmanager
    def no_client(*args: object, **kwargs: object) -> Iterator[None]:
        yield None

    def cancelled(client: object, specs: object, todo: object, outcome: Outcome, *args: object,
                  **kwargs: object) -> Outcome:
        outcome.cancelled, outcome.cancelled_why = 1, "scheduler-connection-lost"
        return outcome

    monkeypatch.setattr("rac.sweep.run.connect", no_client)
    monkeypatch.setattr("rac.sweep.run.run_tasks", cancelled)
    code = main(["sweep", str(world / "sweep.ra"), *scenarios, "--horizon", "2", "-o", str(planned.out), "-q"])
    captured = capsys.readouterr()
    assert code == EXIT_UNDECIDED, captured.err
    assert "rac sweep: the Dask cluster cancelled 1 task before it ran (Dask's reason: scheduler-connection-lost); " \
           "no row is stored for it: run the same command again, once the cluster is back, to run only those" \
           in captured.err
    with pytest.warns(RuntimeWarning, match="cancelled 1 task before running it"):
        assert len(sweep(world / "sweep.ra", scenarios, options=OPTIONS, out=planned.out, quiet=True)) == 1


def test_rows_reach_on_row_without_a_walk_of_every_spec_each(client, tmp_path: Path, world: Path,
                                                            monkeypatch: pytest.MonkeyPatch) -> None:
    """Each row arriving walked every spec of the sweep to find those of its key: quadratic in the tasks, minutes
    of rac's own time on a sweep of 100,000. The specs are walked once now; each still reaches on_row, a
    key shared by two specs (one file under two names) for both."""

    class Walked(list):  # type: ignore[type-arg]
        walks = 0

        def __iter__(self):  # type: ignore[no-untyped-def]
            Walked.walks += 1
            return super().__iter__()

    stand_in(monkeypatch, sweep_helpers.row)  # a row at once
    specs = specs_for(tmp_path, world / "sweep.ra", [f"s{i}.xml" for i in range(6)])
    twin = tmp_path / "twin.xml"
    twin.write_text("s0.xml", encoding="utf-8")  # s0.xml's bytes: its key
    specs.append(dataclasses.replace(specs[0], scenario=str(twin)))
    store = Store(tmp_path / "out")
    outcome, todo = pending(specs, store)
    heard: list[str] = []
    run_tasks(client, Walked(specs), todo, outcome, store, on_row=lambda spec, row: heard.append(spec.scenario))
    assert sorted(heard) == sorted(spec.scenario for spec in specs) and outcome.ran == 6
    assert Walked.walks == 1


def test_a_file_under_two_names_gets_its_own_name_in_the_error_too(world: Path, tmp_path: Path) -> None:
    """Two copies of a broken scenario are one task; the second's row said "E0712 cannot load the scenario:
    .../first.xml", naming the other file."""
    specs = specs_for(tmp_path, world / "sweep.ra", ["first.xml"])
    (tmp_path / "second.xml").write_text("first.xml", encoding="utf-8")
    specs.append(dataclasses.replace(specs[0], scenario=str(tmp_path / "second.xml")))
    first = specs[0].scenario
    outcome = Outcome(keys=[spec.key() for spec in specs])
    outcome.rows[outcome.keys[0]] = sweep_helpers.row(specs[0], "error", error=f"E0712 cannot load {first}: broken",
                                                      diagnostics=[f"E0712 cannot load {first}: broken"])
    one, two = rows_in_order(specs, outcome)
    assert (one["scenario"], one["error"]) == (first, f"E0712 cannot load {first}: broken")
    assert (two["scenario"], two["scenario_name"]) == (specs[1].scenario, "second")
    assert two["error"] == f"E0712 cannot load {specs[1].scenario}: broken"
    assert two["diagnostics"] == [f"E0712 cannot load {specs[1].scenario}: broken"]


def test_a_full_disk_mid_sweep_keeps_the_rows_stored_and_says_so(client, tmp_path: Path, world: Path,
                                                                   monkeypatch: pytest.MonkeyPatch,
                                                                   capsys: pytest.CaptureFixture[str]) -> None:
    """The disk filled while the third row was stored: the sweep ended with E0009 "...; nothing was written"
    and no summary, while two rows stood in tasks/ (and a re-run reused them). Now it stops there as after
    Ctrl-C, summarises the rows stored, and says what stands and that the same command runs only the rest."""
    scenarios = tmp_path / "scenarios"
    scenarios.mkdir()
    for i in range(4):
        (scenarios / f"fast{i}.xml").write_text(f"<commonRoad>{i}</commonRoad>", encoding="utf-8")
    stand_in(monkeypatch, sweep_helpers.slow)

    @contextlib.contextmanager
    def the_client(*args: object, **kwargs: object) -> Iterator[object]:
        yield client

    monkeypatch.setattr("rac.sweep.run.connect", the_client)
    put = Store.put
    puts: list[str] = []

    def fills_the_disk(store: Store, key: str, row: dict[str, object]) -> Path:
        puts.append(key)
        if len(puts) == 3:
            raise OSError(28, "No space left on device", str(store.path(key)))
        return put(store, key, row)

    monkeypatch.setattr(Store, "put", fills_the_disk)
    out = tmp_path / "out"
    code = main(["sweep", str(world / "sweep.ra"), str(scenarios), "-o", str(out), "-q"])
    captured = capsys.readouterr()
    assert code == EXIT_USAGE, captured.err
    assert re.search(r"^\s+4\s+2\s+0\s+0\s+0\s+2$", captured.out, re.MULTILINE), captured.out  # 2 done, 2 not run
    assert f"error[E0009]: cannot write `{out / 'tasks' / puts[2]}.json`: No space left on device" in captured.err
    assert f"the rows of 2 tasks are stored in {out / 'tasks'}: the same command, once it can write there, runs " \
           "only the 2 tasks left" in captured.err
    assert "nothing was written" not in captured.err
    assert len(list((out / "tasks").glob("*.json"))) == 2
    monkeypatch.setattr(Store, "put", put)
    planned = plan(world / "sweep.ra", [str(scenarios)], out=out)
    assert len(pending(planned.specs, Store(out))[1]) == 2  # the re-run runs the two left only


def test_results_that_cannot_be_written_leave_the_summary_and_the_rows(world: Path, tmp_path: Path,
                                                                       monkeypatch: pytest.MonkeyPatch,
                                                                       capsys: pytest.CaptureFixture[str]) -> None:
    """Every row stored, then the disk full at results.parquet: E0009 said "nothing was written" and the
    summary was lost; now the summary is printed (and in --format json's document, with the error) and the
    hint says the rows stand."""
    planned = plan(world / "sweep.ra", [str(world / "scenarios" / "goal_ahead.xml")], options=OPTIONS,
                   out=tmp_path / "out")
    (spec,) = planned.specs
    Store(planned.out).put(spec.key(), sweep_helpers.row(spec))

    def full(rows: object, folder: Path) -> object:
        raise OSError(28, "No space left on device", str(folder / "results.parquet"))

    monkeypatch.setattr("rac.sweep.report.write_results", full)
    monkeypatch.setattr("rac.sweep.run.connect", no_cluster)
    args = ["sweep", str(world / "sweep.ra"), str(world / "scenarios" / "goal_ahead.xml"), "--horizon", "2",
            "-o", str(tmp_path / "out")]
    assert main([*args, "-q"]) == EXIT_USAGE
    captured = capsys.readouterr()
    assert "query  satisfied" in captured.out and "Stays          1" in captured.out
    assert f"the rows of 1 task are stored in {tmp_path / 'out' / 'tasks'}: the same command, once it can write " \
           "there, writes results.* and the plots" in captured.err
    assert main([*args, "--format", "json"]) == EXIT_USAGE
    document = json.loads(capsys.readouterr().out)
    assert document["exit_code"] == EXIT_USAGE and document["written"] is False and document["ok"] is False
    assert document["summary"]["finished"] == 1 and document["error"]["code"] == "E0009"


def test_the_progress_counts_a_file_under_two_names_as_two_tasks(client, tmp_path: Path, world: Path,
                                                                 monkeypatch: pytest.MonkeyPatch) -> None:
    """The progress's total counted keys, its done count specs: a scenario file under two names (one task,
    two rows) made it say "3 of 2 tasks done" and an ETA below zero."""
    stand_in(monkeypatch, sweep_helpers.row)
    monkeypatch.setattr("rac.sweep.run.connect", lambda *args, **kwargs: contextlib.nullcontext(client))
    trackers: list[Tracker] = []

    class Kept(Tracker):
        def __enter__(self) -> Tracker:
            trackers.append(self)
            return super().__enter__()

    monkeypatch.setattr("rac.sweep.run.Tracker", Kept)
    specs = specs_for(tmp_path, world / "sweep.ra", ["one.xml", "two.xml"])
    (tmp_path / "again.xml").write_text("one.xml", encoding="utf-8")
    specs.append(dataclasses.replace(specs[0], scenario=str(tmp_path / "again.xml")))
    result = execute(Plan(world / "sweep.ra", tmp_path / "out", tuple(specs), 3, 1), quiet=True)
    assert len(result.rows) == 3 and result.outcome.ran == 2
    [tracker] = trackers
    assert (tracker.done, tracker.total) == (3, 3)
    assert tracker.line().startswith("3 of 3 tasks done, 0 failed")


def test_a_task_whose_process_was_killed_runs_again_on_resume(client, world: Path, tmp_path: Path,
                                                              monkeypatch: pytest.MonkeyPatch) -> None:
    """A SIGKILLed task process (the out-of-memory killer) is not a verdict: the resumed sweep runs it again."""
    stand_in(monkeypatch, sweep_helpers.kill_task_process_once)  # the real task; its process killed the first time
    monkeypatch.setattr("rac.sweep.run.connect", lambda *args, **kwargs: contextlib.nullcontext(client))
    scenarios = tmp_path / "scenarios"
    scenarios.mkdir()
    shutil.copy(world / "scenarios" / "goal_ahead.xml", scenarios / "goal_ahead.xml")
    planned = plan(world / "sweep.ra", [str(scenarios)], options=OPTIONS, out=tmp_path / "out")
    first = execute(planned, quiet=True)
    killed = first.rows[0]
    assert (killed["status"], killed["retry"]) == ("error", True), killed
    assert "died of signal SIGKILL" in str(killed["error"])
    said: list[str] = []
    again = execute(planned, quiet=True, announce=said.append)
    assert "rerunning 1 task whose process was killed" in said
    assert (again.outcome.ran, again.outcome.skipped, again.outcome.rerun_killed) == (1, 0, 1)
    assert (again.rows[0]["status"], again.rows[0]["retry"]) == ("ok", False), again.rows[0]
    monkeypatch.setattr("rac.sweep.run.connect", no_cluster)  # an ok row is a result: stored, not rerun
    assert execute(planned, quiet=True).outcome.skipped == 1


def test_retry_failed_reruns_the_stored_rows_that_are_not_ok(world: Path, tmp_path: Path) -> None:
    specs = specs_for(tmp_path, world / "sweep.ra", ["fine.xml", "failed.xml", "killed.xml"])
    store = Store(tmp_path / "out")
    fine, failed, killed = (spec.key() for spec in specs)
    store.put(fine, sweep_helpers.row(specs[0]))
    store.put(failed, sweep_helpers.row(specs[1], "timeout", error="ran past the task timeout of 1 s", retry=False))
    store.put(killed, sweep_helpers.row(specs[2], "error", error="the task's process died of signal SIGKILL",
                                        retry=True))
    outcome, todo = pending(specs, store)
    assert list(todo) == [killed] and (outcome.skipped, outcome.rerun_killed, outcome.rerun_failed) == (2, 1, 0)
    outcome, todo = pending(specs, store, retry_failed=True)
    assert list(todo) == [failed, killed] and (outcome.skipped, outcome.rerun_killed, outcome.rerun_failed) == (1, 1, 1)
    assert len(pending(specs + specs, store)[1]) == 1  # a key given twice runs once


def test_retry_failed_says_which_rows_it_reruns(world: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """--retry-failed announced "rerunning 1 task that failed" for an undecided row, which the summary counts as
    no failure."""
    (spec,) = specs_for(tmp_path, world / "sweep.ra", ["undecided.xml"])
    Store(tmp_path / "out").put(spec.key(), sweep_helpers.row(spec, "undecided", error="not decided: Stays"))
    monkeypatch.setattr("rac.sweep.run.connect", lambda *args, **kwargs: contextlib.nullcontext(None))
    monkeypatch.setattr("rac.sweep.run.run_tasks", lambda *args, **kwargs: None)
    said: list[str] = []
    execute(Plan(world / "sweep.ra", tmp_path / "out", (spec,), 1, 1), retry_failed=True, quiet=True,
            announce=said.append)
    assert said == ["rerunning 1 task stored as not ok (--retry-failed)"]


def test_a_timeout_or_memory_row_of_another_limit_runs_again(world: Path, tmp_path: Path) -> None:
    """The limits are not part of the key: a re-run with a larger --task-timeout reused the stored timeout
    row, "ran past the task timeout of 0.3 s", as the answer of the new command."""
    specs = specs_for(tmp_path, world / "sweep.ra", ["slow.xml", "same.xml", "fine.xml", "big.xml"],
                      timeout=60.0, memory=2**30)
    store = Store(tmp_path / "out")
    slow, same, fine, big = (spec.key() for spec in specs)
    store.put(slow, sweep_helpers.row(specs[0], "timeout", task_timeout=0.3, task_memory=2**30))
    store.put(same, sweep_helpers.row(specs[1], "timeout", task_timeout=60.0, task_memory=2**30))
    store.put(fine, sweep_helpers.row(specs[2], "ok", task_timeout=0.3, task_memory=None))  # a result
    store.put(big, sweep_helpers.row(specs[3], "memory", task_timeout=60.0, task_memory=2**20))
    outcome, todo = pending(specs, store)
    assert list(todo) == [slow, big] and (outcome.skipped, outcome.rerun_limits) == (2, 2)


def test_a_row_of_another_rac_version_runs_again(swept: tuple[SweepResult, list[str]], world: Path,
                                                tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """rac's version was not part of a task's key: after an upgrade a sweep silently reused the rows the old
    rac had computed. Each row holds the version that made it now, and a row of another (or no) version runs
    again, with a line that says so."""
    assert {row["rac_version"] for row in swept[0].rows} == {rac.__version__}  # the real task's rows hold it
    specs = specs_for(tmp_path, world / "sweep.ra", ["same.xml", "older.xml", "unrecorded.xml"])
    store = Store(tmp_path / "out")
    same, older, unrecorded = (spec.key() for spec in specs)
    store.put(same, sweep_helpers.row(specs[0]))
    store.put(older, sweep_helpers.row(specs[1], rac_version="0.0.1"))
    store.put(unrecorded, {k: v for k, v in sweep_helpers.row(specs[2]).items() if k != "rac_version"})
    ran: list[str] = []
    monkeypatch.setattr("rac.sweep.run.connect", lambda *args, **kwargs: contextlib.nullcontext(None))
    monkeypatch.setattr("rac.sweep.run.run_tasks", lambda client, specs, todo, *args, **kwargs: ran.extend(todo))
    said: list[str] = []
    result = execute(Plan(world / "sweep.ra", tmp_path / "out", tuple(specs), 3, 1), quiet=True, announce=said.append)
    assert ran == [older, unrecorded]
    assert (result.outcome.skipped, result.outcome.rerun_version) == (1, 2)
    assert f"rerunning 2 tasks stored by another version of rac (0.0.1, unknown; this is {rac.__version__})" in said


def test_a_row_of_other_rac_source_files_runs_again(swept: tuple[SweepResult, list[str]], world: Path,
                                                   tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """rac's version stays 0.1.0 from commit to commit of a development checkout: a sweep reused the rows that
    older code had computed. Each row holds the digest of rac's source files that made it, and a row of other
    (or no) source files runs again, with a line that says so."""
    assert {row["rac_source"] for row in swept[0].rows} == {source_digest()}  # the real task's rows hold it
    specs = specs_for(tmp_path, world / "sweep.ra", ["same.xml", "older.xml", "unrecorded.xml"])
    store = Store(tmp_path / "out")
    same, older, unrecorded = (spec.key() for spec in specs)
    store.put(same, sweep_helpers.row(specs[0]))
    store.put(older, sweep_helpers.row(specs[1], rac_source="0123456789abcdef"))
    store.put(unrecorded, {k: v for k, v in sweep_helpers.row(specs[2]).items() if k != "rac_source"})
    ran: list[str] = []
    monkeypatch.setattr("rac.sweep.run.connect", lambda *args, **kwargs: contextlib.nullcontext(None))
    monkeypatch.setattr("rac.sweep.run.run_tasks", lambda client, specs, todo, *args, **kwargs: ran.extend(todo))
    said: list[str] = []
    result = execute(Plan(world / "sweep.ra", tmp_path / "out", tuple(specs), 3, 1), quiet=True, announce=said.append)
    assert ran == [older, unrecorded]
    assert (result.outcome.skipped, result.outcome.rerun_source) == (1, 2)
    assert f"rerunning 2 tasks stored by rac {rac.__version__} of other source files (rac's files changed since)" \
        in said


def test_a_task_past_its_timeout_is_a_timeout_row(client, world: Path, tmp_path: Path) -> None:
    # the real run_task: its child process takes longer than 0.2 s only to start
    planned = plan(world / "sweep.ra", [str(world / "scenarios" / "goal_ahead.xml")], options=OPTIONS,
                   task_timeout=0.2, out=tmp_path / "out")
    store = Store(planned.out)
    outcome, todo = pending(planned.specs, store)
    run_tasks(client, planned.specs, todo, outcome, store)
    row = outcome.rows[outcome.keys[0]]
    assert row["status"] == "timeout" and "0.2 s" in str(row["error"]), row
    assert (row["task_timeout"], row["task_memory"]) == (0.2, None)  # the limit it met, for a resumed sweep
    assert exit_status([row]) == EXIT_UNDECIDED


# ---------------------------------------------------------------- Ctrl-C
def interrupted_sweep(world: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch, stop: str,
                      *options: str) -> tuple[int, Path]:
    """``rac sweep`` of one fast and two slow stand-in tasks, stopped by ``stop`` (``ctrl-c`` or ``sigterm``)
    as soon as the fast task's row is stored: the exit code and the output folder."""
    stand_in(monkeypatch, sweep_helpers.slow)
    files = []
    for name in ("fast.xml", "slow_1.xml", "slow_2.xml"):
        (tmp_path / name).write_text(name, encoding="utf-8")
        files.append(str(tmp_path / name))
    out = tmp_path / "out"

    def press_ctrl_c() -> None:  # as soon as the fast task's row is stored
        deadline = time.monotonic() + 60
        while not list((out / "tasks").glob("*.json")) and time.monotonic() < deadline:
            time.sleep(0.05)
        if stop == "ctrl-c":
            _thread.interrupt_main()
        elif signal.getsignal(signal.SIGTERM) == before:  # no handler: SIGTERM would end pytest itself
            unhandled.append(stop)
            _thread.interrupt_main()
        else:
            os.kill(os.getpid(), signal.SIGTERM)

    before = signal.getsignal(signal.SIGTERM)
    unhandled: list[str] = []
    watcher = threading.Thread(target=press_ctrl_c, daemon=True)
    watcher.start()
    start = time.monotonic()
    code = main(["sweep", str(world / "sweep.ra"), *files, "--workers", "2", "-o", str(out), "-q", *options])
    watcher.join()
    assert not unhandled, "SIGTERM is not handled while the sweep runs"
    assert time.monotonic() - start < 25  # the slow tasks (30 s each) were cancelled
    assert signal.getsignal(signal.SIGTERM) == before  # the handler lasts the sweep only
    return code, out


@pytest.mark.parametrize(("stop", "code_after", "said"), [
    ("ctrl-c", 130, "rac sweep: interrupted: 2 tasks not run"),
    # a batch system's time limit, `kill PID`: Python's default ended the process on the spot, with no
    # summary, no results.* merged and a leaked-semaphore warning
    ("sigterm", 143, "rac sweep: terminated (SIGTERM): 2 tasks not run"),
])
def test_ctrl_c_merges_what_is_done_and_exits_130(world: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                                  capsys: pytest.CaptureFixture[str], stop: str, code_after: int,
                                                  said: str) -> None:
    code, out = interrupted_sweep(world, tmp_path, monkeypatch, stop)
    captured = capsys.readouterr()
    assert code == code_after, captured.err
    rows = json.loads((out / "results.json").read_text(encoding="utf-8"))
    assert [row["scenario_name"] for row in rows] == ["fast"]
    assert captured.out.splitlines()[1] == "    3   1       0          0        0        2"
    assert said in captured.err
    assert "run the same command again to run only those" in captured.err


def test_an_interrupted_json_sweep_says_the_exit_code_it_ends_with(world: Path, tmp_path: Path,
                                                                   monkeypatch: pytest.MonkeyPatch,
                                                                   capsys: pytest.CaptureFixture[str]) -> None:
    """The document's ``exit_code`` was the rows' (4: tasks not run) while the process exited 130; and under
    --force "run the same command again to run only those" is untrue: it runs every task again."""
    code, _ = interrupted_sweep(world, tmp_path, monkeypatch, "ctrl-c", "--format", "json", "--force")
    captured = capsys.readouterr()
    document = json.loads(captured.out)
    assert code == 130 and document["interrupted"] is True
    assert document["exit_code"] == code and document["ok"] is False
    assert "with --force the same command runs every task again" in captured.err
    assert "to run only those" not in captured.err


# ---------------------------------------------------------------- an existing cluster
def free_port() -> int:
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        return int(probe.getsockname()[1])


def test_the_cli_on_a_separate_dask_scheduler_and_worker(world: Path, tmp_path: Path,
                                                         capsys: pytest.CaptureFixture[str]) -> None:
    port = free_port()
    address = f"tcp://127.0.0.1:{port}"
    dask = [sys.executable, "-m", "dask"]
    processes = [subprocess.Popen([*dask, "scheduler", "--host", "127.0.0.1", "--port", str(port),
                                   "--no-dashboard"], env=rac_env(), cwd=tmp_path,
                                  stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)]
    try:
        deadline = time.monotonic() + 60
        while True:  # until the scheduler listens
            try:
                socket.create_connection(("127.0.0.1", port), timeout=1).close()
                break
            except OSError:
                assert time.monotonic() < deadline and processes[0].poll() is None, "the scheduler did not start"
                time.sleep(0.2)
        processes.append(subprocess.Popen([*dask, "worker", address, "--nworkers", "1", "--nthreads", "1",
                                           "--no-dashboard"], env=rac_env(), cwd=tmp_path,
                                          stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL))
        scenarios = [str(world / "scenarios" / f"{name}.xml") for name in ("goal_ahead", "narrow_road")]
        out = tmp_path / "out"
        args = ["sweep", str(world / "sweep.ra"), *scenarios, "--scheduler", address, "--horizon", "2",
                "--set", "exponent=2", "-o", str(out)]
        assert main([*args, "--format", "json"]) == EXIT_ERRORS  # the narrow road fails
        captured = capsys.readouterr()
        report = json.loads(captured.out)
        assert report["summary"]["tasks"] == 2 and report["summary"]["ok"] == 1 and report["exit_code"] == 1
        assert report["ok"] is False  # true exactly when the exit status is 0, as every command's document
        assert f"(the cluster at {address}, " in captured.err
        rows = by_scenario(json.loads((out / "results.json").read_text(encoding="utf-8")))
        assert {name: (row["status"], row["settings"]) for name, row in rows.items()} == {
            "goal_ahead": ("ok", {"exponent": "2"}), "narrow_road": ("failed", {"exponent": "2"})}
        assert main([*args, "-q"]) == EXIT_ERRORS  # the same command again: both rows are stored
        assert "skipped: 2 stored by an earlier run" in capsys.readouterr().out
    finally:
        for process in reversed(processes):
            process.terminate()
        for process in processes:
            try:
                process.wait(timeout=20)
            except subprocess.TimeoutExpired:
                process.kill()


# ---------------------------------------------------------------- usage, exit codes, import time
@pytest.mark.parametrize(("args", "message"), [
    (["{scenarios}/nothing*.xml"], "no scenario file matched `{scenarios}/nothing*.xml`"),
    (["{scenarios}", "--set", "exponnt=1,2"], "unknown setting `exponnt` of the `model` block; did you mean"),
    (["{scenarios}", "--set", "exponent"], "`--set exponent`: write NAME=V1,V2,..."),
    # every task of exponent 7 failed (exit 1) after the cluster started: no scenario takes it
    (["{scenarios}", "--set", "exponent=1,7"], "`--set exponent=7`: `exponent` must be a whole number from 1 to 6"),
    (["{scenarios}", "--scheduler", "tcp://127.0.0.1:1", "--workers", "2"], "--workers sizes the local cluster"),
    (["{scenarios}", "--task-memory", "lots"], "`lots` is not a size"),
    # an infinite timeout was stored as `Infinity` in tasks/*.json and results.json, which no JSON reader takes
    (["{scenarios}", "--task-timeout", "inf"], "--task-timeout: not a positive number of seconds: 'inf'"),
    (["{scenarios}", "--task-timeout", "1e400"], "--task-timeout: not a positive number of seconds: '1e400'"),
    # every task failed with the same syntax error (exit 1) after the cluster started
    (["{scenarios}", "--task", "experiment", "--reward-function", "sa +"],
     "--reward-function: `sa +`: the expression is incomplete"),
    # an option the task would run without, as if it had not been given
    (["{scenarios}", "--runs", "5"], "--task verify does not use the option `runs` (its options: horizon, seed, "
                                     "max_states, episodes)"),
    (["{scenarios}", "--explore", "goal"], "--task verify does not use the option `explore`"),
    (["{scenarios}", "--task", "check", "--horizon", "2", "--seed", "1"],
     "--task check does not use the options `horizon`, `seed` (its options: none)"),
    # the same: every task failed with "pass --reward-function EXPR" after the cluster started
    (["{scenarios}", "--task", "experiment"], "--task experiment: the default reward function (the paper's Eq. 9) "
                                              "reads the inputs isClose, prog and comf; pass --reward-function EXPR"),
])
def test_bad_arguments_exit_2_before_any_cluster(world: Path, monkeypatch: pytest.MonkeyPatch,
                                                 capsys: pytest.CaptureFixture[str], args: list[str],
                                                 message: str) -> None:
    monkeypatch.setattr("rac.sweep.run.connect", no_cluster)
    scenarios = str(world / "scenarios")
    given = [arg.format(scenarios=scenarios) for arg in args]
    assert main(["sweep", str(world / "sweep.ra"), *given]) == EXIT_USAGE
    assert message.format(scenarios=scenarios) in capsys.readouterr().err


def test_a_second_sweep_into_a_busy_folder_is_refused_naming_the_first(world: Path, tmp_path: Path,
                                                                        monkeypatch: pytest.MonkeyPatch,
                                                                        capsys: pytest.CaptureFixture[str]) -> None:
    """Two sweeps into one output folder at once ran side by side and interleaved their results.* (each removes
    and rewrites them, from its own rows): the second is refused now, before any cluster starts, saying which
    folder and which process holds it; the first's folder is left as it was."""
    out = tmp_path / "out"
    code = "import sys, time; from pathlib import Path; from rac.sweep.store import holding\n" \
           "with holding(Path(sys.argv[1])):\n    print('held', flush=True)\n    time.sleep(120)\n"
    first = subprocess.Popen([sys.executable, "-c", code, str(out)], stdout=subprocess.PIPE, text=True, env=rac_env())
    try:
        assert first.stdout is not None and first.stdout.readline() == "held\n"
        monkeypatch.setattr("rac.sweep.run.connect", no_cluster)
        scenario = str(world / "scenarios" / "goal_ahead.xml")
        for form in ("text", "json"):
            assert main(["sweep", str(world / "sweep.ra"), scenario, "-o", str(out), "-q", "--format", form]) \
                == EXIT_USAGE
            said = capsys.readouterr()
            text = said.err if form == "text" else said.out
            assert (f"another rac sweep (process {first.pid}) is running into the output folder {out}: two sweeps "
                    "there at once would interleave their results.*") in text, text
        assert sorted(p.name for p in out.iterdir()) == [".rac-sweep.lock"]  # nothing of the second one's
    finally:
        first.kill()
        first.wait()


def test_a_folder_whose_sweep_was_killed_is_taken_over(tmp_path: Path) -> None:
    """A sweep killed (SIGKILL, the machine's reboot) leaves its lock file, naming a process that is gone: the next
    sweep takes the folder, and removes the file when it ends."""
    from rac.sweep.store import LOCK_FILE, holding

    out = tmp_path / "out"
    code = "import os, sys; from pathlib import Path; from rac.sweep.store import holding\n" \
           "with holding(Path(sys.argv[1])):\n    os._exit(9)\n"
    gone = subprocess.Popen([sys.executable, "-c", code, str(out)], env=rac_env())
    assert gone.wait(timeout=60) == 9 and (out / LOCK_FILE).read_text().split()[0] == str(gone.pid)
    with holding(out):
        assert (out / LOCK_FILE).read_text().split()[0] == str(os.getpid())
    assert not (out / LOCK_FILE).exists()


def test_the_api_takes_any_iterable_of_values_as_a_grid_axis(world: Path) -> None:
    """sets={"exponent": range(1, 3)} (or a numpy array) was refused: its text `range(1, 3)` is no value."""
    import numpy as np

    scenario = [str(world / "scenarios" / "goal_ahead.xml")]
    for values in (range(1, 3), np.array([1, 2]), (v for v in (1, 2)), [1, 2]):
        planned = plan(world / "sweep.ra", scenario, sets={"exponent": values, "max_speed": 10})
        assert [spec.settings for spec in planned.specs] == [(("exponent", "1"), ("max_speed", "10")),
                                                             (("exponent", "2"), ("max_speed", "10"))]
    assert plan(world / "sweep.ra", scenario, sets={"dynamics": "increments"}).specs[0].settings == (
        ("dynamics", "increments"),)  # a word is one value, not its letters


@pytest.mark.parametrize("workers", [0, -1, 1.5, True])
def test_the_api_refuses_a_local_cluster_without_workers(world: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                                         workers: object) -> None:
    """sweep(..., workers=-1) started a local cluster of no workers and waited for ever; workers=0 meant one
    per core. Both are refused before anything runs, as --workers refuses them."""
    monkeypatch.setattr("rac.sweep.run.connect", no_cluster)
    planned = plan(world / "sweep.ra", [str(world / "scenarios" / "goal_ahead.xml")], out=tmp_path / "out")
    with pytest.raises(ValueError, match="workers must be a whole number of at least 1, not "):
        execute(planned, workers=workers, quiet=True)  # type: ignore[arg-type]


def test_the_api_refuses_an_infinite_task_timeout(world: Path) -> None:
    with pytest.raises(ValueError, match="the task timeout must be a finite number of seconds more than 0, not inf"):
        plan(world / "sweep.ra", [str(world / "scenarios")], task_timeout=float("inf"))


def test_workers_with_a_configured_scheduler_is_bad_usage(world: Path, monkeypatch: pytest.MonkeyPatch,
                                                          capsys: pytest.CaptureFixture[str]) -> None:
    """With Dask's scheduler-address configuration (DASK_SCHEDULER_ADDRESS) the sweep goes to that cluster:
    --workers was silently ignored there, where --scheduler with --workers is refused."""
    import dask

    monkeypatch.setattr("rac.sweep.run.connect", no_cluster)
    with dask.config.set({"scheduler-address": "tcp://127.0.0.1:1"}):
        assert main(["sweep", str(world / "sweep.ra"), str(world / "scenarios"), "--workers", "2"]) == EXIT_USAGE
    assert ("--workers sizes the local cluster; the cluster at Dask's scheduler-address configuration has its "
            "own workers") in capsys.readouterr().err


def test_a_template_that_cannot_be_read_exits_2(world: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["sweep", str(world / "missing.ra"), str(world / "scenarios")]) == EXIT_USAGE
    assert f"error[E0008]: cannot read `{world / 'missing.ra'}`: No such file or directory" in capsys.readouterr().err


def test_the_exit_code_follows_the_worst_row() -> None:
    def row(status: str, **verdicts: str) -> dict[str, object]:
        return {"status": status, "verdicts": verdicts}

    assert exit_status([row("ok", A="satisfied")]) == EXIT_OK
    assert exit_status([row("ok", A="unknown")]) == EXIT_UNDECIDED
    assert exit_status([row("ok"), row("timeout")]) == EXIT_UNDECIDED
    assert exit_status([row("memory"), row("failed", A="not satisfied")]) == EXIT_ERRORS
    assert summarise([row("ok"), row("error")], tasks=3).not_run == 1


def test_the_summary_tells_apart_files_of_one_name_in_other_folders(world: Path, tmp_path: Path) -> None:
    # a database keeps a scenario per folder under one file name: the summary named both `s`
    template = world / "sweep.ra"
    folders = [tmp_path / "db" / "a", tmp_path / "db" / "b", tmp_path / "other" / "a"]
    specs = []
    for folder in folders:
        folder.mkdir(parents=True)
        specs += specs_for(folder, template, ["s.xml"])
    specs += specs_for(tmp_path / "db" / "b", template, ["t.xml"])
    rows = [sweep_helpers.row(spec, "failed", error="not satisfied: Stays") for spec in specs]
    text = render_summary(summarise(rows, tasks=len(rows)))
    assert "failed: db/a/s [template settings]: not satisfied: Stays" in text
    assert "failed: db/b/s [template settings]" in text
    assert "failed: other/a/s [template settings]" in text
    assert "failed: t [template settings]" in text  # a name no other file has stays the stem
    assert [p["scenario"] for p in summarise(rows, tasks=4).to_json()["problems"]] == [  # type: ignore[index]
        "db/a/s", "db/b/s", "other/a/s", "t"]


def test_off_a_terminal_the_progress_is_plain_lines(monkeypatch: pytest.MonkeyPatch,
                                                    capsys: pytest.CaptureFixture[str]) -> None:
    monkeypatch.setenv("RAC_PROGRESS_INTERVAL", "0.05")  # captured stderr is not a terminal
    with Tracker() as tracker:
        tracker.start(4, 0)
        tracker.row(None, {"status": "ok"})  # type: ignore[arg-type]
        tracker.row(None, {"status": "timeout"})  # type: ignore[arg-type]
        time.sleep(0.3)
    lines = capsys.readouterr().err.splitlines()
    assert lines and all(re.fullmatch(r"rac sweep: 2 of 4 tasks done, 1 failed, [\d.]+ tasks/min, ETA \d+ s; \d+ s",
                                      line) for line in lines), lines
    with Tracker(quiet=True) as tracker:
        tracker.start(4, 0)
        time.sleep(0.2)
    assert capsys.readouterr().err == ""


class QuietCluster:
    """A stand-in for Dask's ``LocalCluster`` and ``Client`` that starts nothing."""

    dashboard_link = "http://127.0.0.1:8787/status"

    def __init__(self, *args: object, **kw: object) -> None:
        pass

    def close(self) -> None:
        pass

    def __enter__(self) -> QuietCluster:
        return self

    def __exit__(self, *exc: object) -> None:  # the close, as `with cluster:` calls it
        self.close()


def test_the_dashboard_line_counts_one_worker(monkeypatch: pytest.MonkeyPatch) -> None:
    """`--workers 1` announced "a local cluster, 1 workers"."""
    import distributed

    monkeypatch.setattr(distributed, "LocalCluster", QuietCluster)
    monkeypatch.setattr(distributed, "Client", QuietCluster)
    said: list[str] = []
    for workers in (1, 2):
        with connect(workers=workers, announce=said.append):
            pass
    assert [line.split("(")[1].split(";")[0].rstrip(")") for line in said] == ["a local cluster, 1 worker",
                                                                               "a local cluster, 2 workers"]


def test_the_progress_counts_failed_tasks_as_the_summary_does() -> None:
    """The progress counted every task not ok as failed: a sweep of undecided tasks said "4 of 4 tasks done,
    4 failed", then its summary "failed 0, undecided 4"."""
    rows = [{"status": status} for status in ("ok", "undecided", "timeout", "failed")]
    with Tracker(quiet=True) as tracker:
        tracker.start(len(rows), 0)
        for row in rows:
            tracker.row(None, row)  # type: ignore[arg-type]
    assert tracker.line().startswith("4 of 4 tasks done, 2 failed")
    assert summarise(rows, tasks=len(rows)).failed == tracker.failed == 2


def test_the_local_cluster_has_a_worker_per_core_rac_may_use(monkeypatch: pytest.MonkeyPatch) -> None:
    """The default was os.cpu_count(), the machine's cores: on 1 core of a 64-core node (a batch system's
    allocation, `taskset`) rac started 64 workers."""
    import distributed

    started: list[object] = []

    class Counted(QuietCluster):
        def __init__(self, *args: object, **kw: object) -> None:
            started.append(kw["n_workers"])

    monkeypatch.setattr(distributed, "LocalCluster", Counted)
    monkeypatch.setattr(distributed, "Client", QuietCluster)
    monkeypatch.setattr(os, "cpu_count", lambda: 64)
    monkeypatch.setattr(os, "sched_getaffinity", lambda pid: {0}, raising=False)
    with connect():
        pass
    assert started == [1]


def test_the_progress_before_the_cluster_answers_says_so() -> None:
    """While the cluster started (or an unreachable --scheduler was tried for 10 s) the line said "0 of 0 tasks
    done, 0 failed", as if the sweep had nothing to do."""
    assert re.fullmatch(r"waiting for the Dask cluster, no task sent yet; \d+ s", Tracker(quiet=True).line())


def test_a_cluster_without_workers_is_said_not_waited_on_in_silence() -> None:
    """A scheduler whose workers were never started (or all died) holds the tasks: the sweep printed "0 of 3
    tasks done" every 10 s, as if a task were slow, and the user waited. Now the start says the cluster has
    no worker yet, and so does each progress line while it has none."""
    from distributed import LocalCluster

    with LocalCluster(n_workers=0, processes=False, dashboard_address=":0") as cluster:
        said: list[str] = []
        with connect(cluster.scheduler_address, announce=said.append) as client:
            assert f"the cluster at {cluster.scheduler_address} has no worker yet: the tasks wait until one joins " \
                   f"(dask worker {cluster.scheduler_address})" in said
            tracker = Tracker(quiet=True)
            tracker.start(3, 0)
            tracker.workers = lambda: workers_of(client)
            assert "0 of 3 tasks done, 0 failed; the cluster has no worker: the tasks wait until one joins; " \
                   in tracker.line()
            cluster.scale(1)
            client.wait_for_workers(1, timeout=30)
            assert workers_of(client) == 1 and "no worker" not in tracker.line()
        assert workers_of(client) is None  # closed: the progress's thread is not stopped by it


def test_the_worker_count_of_a_closing_client_is_none_not_an_error() -> None:
    """The progress's thread asks the worker count every 10 s; a client whose loop is closing answers with
    concurrent.futures' CancelledError, which ended that thread with a traceback on standard error."""
    from concurrent.futures import CancelledError

    class Closing:
        scheduler = types.SimpleNamespace(identity=None)  # there, until its loop answers

        def sync(self, *args: object, **kwargs: object) -> object:
            raise CancelledError

    assert workers_of(Closing()) is None  # type: ignore[arg-type]


def test_import_rac_does_not_import_dask() -> None:
    heavy = ("dask", "distributed", "pandas", "pyarrow")
    code = ("import sys, rac, rac.sweep, rac.cli.arguments; rac.cli.arguments.build_parser(); "
            f"print(sorted(m for m in sys.modules if m.split('.')[0] in {heavy!r}))")
    done = subprocess.run([sys.executable, "-c", code], env=rac_env(), capture_output=True, text=True, check=True)
    assert done.stdout.strip() == "[]"


class TermWhileStarting:
    """A stand-in for Dask's ``LocalCluster`` that receives SIGTERM in the middle of its start (as a batch
    system's `kill` may send it while rac's cluster starts), and records that it was started and closed."""

    events: list[str] = []

    def __init__(self, **kw: object) -> None:
        os.kill(os.getpid(), signal.SIGTERM)
        time.sleep(0.2)  # a Python handler runs here, in the middle of the start
        self.events.append("started")

    def close(self) -> None:
        self.events.append("closed")


def test_sigterm_while_the_cluster_starts_closes_it_and_exits_143(world: Path, tmp_path: Path,
                                                                  monkeypatch: pytest.MonkeyPatch,
                                                                  capsys: pytest.CaptureFixture[str]) -> None:
    """The handler's KeyboardInterrupt came out of LocalCluster's start: a half-started cluster (Dask's exit
    hook then failed to close it, with a traceback), and exit 130 "rac: interrupted" with nothing merged. Now
    SIGTERM is held back until the cluster is up, which is then closed, and the sweep ends as after SIGTERM."""
    import distributed

    monkeypatch.setattr(distributed, "LocalCluster", TermWhileStarting)
    TermWhileStarting.events = []
    before = signal.getsignal(signal.SIGTERM)
    out = tmp_path / "out"
    code = main(["sweep", str(world / "sweep.ra"), str(world / "scenarios" / "goal_ahead.xml"), "--workers", "1",
                 "-o", str(out), "-q"])
    captured = capsys.readouterr()
    assert code == 143, captured.err
    assert TermWhileStarting.events == ["started", "closed"]
    assert "rac sweep: terminated (SIGTERM): 1 task not run" in captured.err
    assert json.loads((out / "results.json").read_text(encoding="utf-8")) == []
    assert signal.getsignal(signal.SIGTERM) == before


def spawned_workers(rac: psutil.Process) -> list[psutil.Process]:
    """The Dask worker processes ``rac`` has spawned so far (multiprocessing's spawn children)."""
    found = []
    for child in rac.children():
        with contextlib.suppress(psutil.Error):  # gone, or not yet readable
            if "spawn_main" in " ".join(child.cmdline()):
                found.append(child)
    return found


def test_ctrl_c_while_the_cluster_starts_stops_the_sweep(world: Path, tmp_path: Path) -> None:
    """Ctrl-C (SIGINT to the whole process group, as a terminal sends it) while the local cluster started was
    lost: rac ignored SIGINT then, so that the workers it spawned would ignore it too, and the sweep went on to
    its end. Now the workers still never see it, rac holds it back until the cluster is up, then closes the
    cluster, merges what is done and exits 130."""
    out = tmp_path / "out"
    process = subprocess.Popen([sys.executable, "-m", "rac", "sweep", str(world / "sweep.ra"),
                                str(world / "scenarios" / "goal_ahead.xml"), "--horizon", "2", "--workers", "1",
                                "-o", str(out)], env=rac_env(), stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                               text=True, start_new_session=True)
    try:
        rac = psutil.Process(process.pid)
        deadline = time.monotonic() + 60
        while not (workers := spawned_workers(rac)) and process.poll() is None and time.monotonic() < deadline:
            time.sleep(0.01)
        assert workers, "no worker process was spawned"
        os.killpg(process.pid, signal.SIGINT)  # the worker is starting: the cluster is not up yet
        _, err = process.communicate(timeout=60)
    finally:
        with contextlib.suppress(ProcessLookupError):
            os.killpg(process.pid, signal.SIGKILL)
    assert process.returncode == 130, err
    assert "rac sweep: interrupted: 1 task not run" in err
    assert "Traceback" not in err and "KeyboardInterrupt" not in err, err  # the workers did not see it
    assert json.loads((out / "results.json").read_text(encoding="utf-8")) == []
    assert not psutil.wait_procs(workers, timeout=10)[1], "a worker outlived the sweep"


class IntWhileClosing(QuietCluster):
    """A stand-in for Dask's ``LocalCluster`` that receives SIGINT in the middle of its close (a second Ctrl-C,
    or one as the sweep ends), and records that it was closed."""

    events: list[str] = []

    def close(self) -> None:
        os.kill(os.getpid(), signal.SIGINT)
        time.sleep(0.2)  # Python's handler runs here, in the middle of the close
        self.events.append("closed")


def test_ctrl_c_while_the_cluster_closes_closes_it_all_the_same(world: Path, tmp_path: Path,
                                                                monkeypatch: pytest.MonkeyPatch,
                                                                capsys: pytest.CaptureFixture[str]) -> None:
    """A second Ctrl-C (or one as the sweep ended) while the local cluster closed left it half closed: Dask's
    exit hook then waited some 10 s on it before the process ended. Now the signal is held until the cluster
    is closed, and the sweep ends as after Ctrl-C."""
    import distributed

    monkeypatch.setattr(distributed, "LocalCluster", IntWhileClosing)
    monkeypatch.setattr(distributed, "Client", QuietCluster)
    monkeypatch.setattr("rac.sweep.run.run_tasks", lambda *args, **kwargs: None)  # no task runs: none needs to
    IntWhileClosing.events = []
    code = main(["sweep", str(world / "sweep.ra"), str(world / "scenarios" / "goal_ahead.xml"), "--workers", "1",
                 "-o", str(tmp_path / "out"), "-q"])
    captured = capsys.readouterr()
    assert IntWhileClosing.events == ["closed"]
    assert code == 130, captured.err
    assert "rac sweep: interrupted: 1 task not run" in captured.err


def test_the_cli_runs_an_experiment_with_its_reward_function(world: Path, tmp_path: Path,
                                                             capsys: pytest.CaptureFixture[str]) -> None:
    """`rac sweep --task experiment` on an automaton without the paper's inputs failed every task with "pass
    --reward-function EXPR", an option rac sweep did not have (nor --episodes and --runs, which the Python
    API's options have)."""
    out = tmp_path / "out"
    code = main(["sweep", str(world / "sweep.ra"), str(world / "scenarios" / "goal_ahead.xml"), "--task",
                 "experiment", "--reward-function=-sa", "--episodes", "3", "--runs", "2", "--seed", "1",
                 "--workers", "1", "-o", str(out), "-q"])  # the file's horizon: within 2 s no safe run reaches the goal
    assert code == EXIT_OK, capsys.readouterr()
    (row,) = json.loads((out / "results.json").read_text(encoding="utf-8"))
    assert row["status"] == "ok" and row["details"]
    assert {entry["episodes"][0] for entry in row["details"]} == {3}


def test_sigterm_while_the_results_are_written_exits_143(world: Path, tmp_path: Path,
                                                         monkeypatch: pytest.MonkeyPatch,
                                                         capsys: pytest.CaptureFixture[str]) -> None:
    """SIGTERM while the rows were merged and plotted (after the tasks) ended as Ctrl-C does: exit 130 and
    "rac: interrupted". The task's row is stored, so no cluster starts here."""
    planned = plan(world / "sweep.ra", [str(world / "scenarios" / "goal_ahead.xml")], options=OPTIONS,
                   out=tmp_path / "out")
    (spec,) = planned.specs
    Store(planned.out).put(spec.key(), sweep_helpers.row(spec))

    def terminated_meanwhile(rows: object, folder: Path) -> list[Path]:
        os.kill(os.getpid(), signal.SIGTERM)
        time.sleep(1)  # the handler runs here
        return []

    monkeypatch.setattr("rac.sweep.report.write_plots", terminated_meanwhile)
    monkeypatch.setattr("rac.sweep.run.connect", no_cluster)
    before = signal.getsignal(signal.SIGTERM)
    code = main(["sweep", str(world / "sweep.ra"), str(world / "scenarios" / "goal_ahead.xml"), "--horizon", "2",
                 "-o", str(tmp_path / "out"), "-q"])
    assert code == 143, capsys.readouterr().err
    assert "rac sweep: terminated (SIGTERM) while writing results.*" in capsys.readouterr().err
    assert signal.getsignal(signal.SIGTERM) == before


@pytest.mark.parametrize("where", ["plots", "pending"])
@pytest.mark.parametrize(("number", "exit_code"), [(signal.SIGINT, 130), (signal.SIGTERM, 143)])
def test_an_interrupt_outside_the_run_still_prints_the_json_document(world: Path, tmp_path: Path,
                                                                     monkeypatch: pytest.MonkeyPatch,
                                                                     capsys: pytest.CaptureFixture[str],
                                                                     where: str, number: int,
                                                                     exit_code: int) -> None:
    """Under --format json, Ctrl-C or SIGTERM while results.* and the plots were written (or before the tasks
    ran) printed no JSON at all, only a line on standard error. Now standard output is the document still:
    interrupted, the exit code the process ends with, what was kept (the summary of the stored rows, the
    files written), and that not all files were written."""
    planned = plan(world / "sweep.ra", [str(world / "scenarios" / "goal_ahead.xml")], options=OPTIONS,
                   out=tmp_path / "out")
    (spec,) = planned.specs
    Store(planned.out).put(spec.key(), sweep_helpers.row(spec))

    def signalled(*args: object, **kwargs: object) -> list[Path]:
        os.kill(os.getpid(), number)
        time.sleep(1)  # the handler runs here
        return []

    monkeypatch.setattr("rac.sweep.report.write_plots" if where == "plots" else "rac.sweep.run.pending", signalled)
    monkeypatch.setattr("rac.sweep.run.connect", no_cluster)
    code = main(["sweep", str(world / "sweep.ra"), str(world / "scenarios" / "goal_ahead.xml"), "--horizon", "2",
                 "-o", str(tmp_path / "out"), "--format", "json"])
    captured = capsys.readouterr()
    document = json.loads(captured.out)
    assert code == exit_code == document["exit_code"], captured.err
    assert document["interrupted"] is True and document["written"] is False
    if where == "plots":  # the rows were merged into results.*; the plots were not drawn
        assert document["summary"]["finished"] == 1
        assert document["files"] == [str(tmp_path / "out" / name) for name in ("results.parquet", "results.json")]
        assert "while writing results.* and the plots" in captured.err
    else:
        assert document["summary"] is None and document["files"] == []
        assert f"results.* not written (run the same command again: the rows of the tasks that ran are stored in " \
               f"{tmp_path / 'out' / 'tasks'})" in captured.err


def test_results_cut_short_leave_no_earlier_sweeps_file_beside_them(world: Path, tmp_path: Path,
                                                                    monkeypatch: pytest.MonkeyPatch,
                                                                    capsys: pytest.CaptureFixture[str]) -> None:
    """The disk filled at results.json after this sweep's results.parquet was written: the earlier sweep's
    results.json and plots stayed beside it, two runs' rows read as one. Now they are removed first."""
    out = tmp_path / "out"
    planned = plan(world / "sweep.ra", [str(world / "scenarios" / "goal_ahead.xml")], options=OPTIONS, out=out)
    (spec,) = planned.specs
    Store(planned.out).put(spec.key(), sweep_helpers.row(spec))
    for name in ("results.json", "results.csv", "verdicts.png", "time_vs_size.png"):  # an earlier sweep's
        (out / name).write_text("earlier", encoding="utf-8")
    from rac.sweep import report

    write_text = report.write_text

    def full_at_json(path: Path, text: str) -> object:
        if path.name == "results.json":
            raise OSError(28, "No space left on device", str(path))
        return write_text(path, text)

    monkeypatch.setattr("rac.sweep.report.write_text", full_at_json)
    monkeypatch.setattr("rac.sweep.run.connect", no_cluster)
    args = ["sweep", str(world / "sweep.ra"), str(world / "scenarios" / "goal_ahead.xml"), "--horizon", "2",
            "-o", str(out), "-q"]
    assert main(args) == EXIT_USAGE
    assert f"cannot write `{out / 'results.json'}`" in capsys.readouterr().err
    assert (out / "results.parquet").exists() or (out / "results.csv").exists()  # this sweep's
    left = sorted(p.name for p in out.iterdir() if p.is_file() and p.read_bytes() == b"earlier")
    assert left == []  # none of the earlier sweep's files beside this one's
    monkeypatch.setattr("rac.sweep.report.write_text", write_text)
    assert main(args) == EXIT_OK  # the same command writes them all
    assert {p.name for p in out.iterdir()} >= {"results.json", "verdicts.png", "time_vs_size.png"}


def test_ctrl_c_while_the_scenarios_are_read_gives_the_sweeps_json_document(world: Path, tmp_path: Path,
                                                                            monkeypatch: pytest.MonkeyPatch,
                                                                            capsys: pytest.CaptureFixture[str]) -> None:
    """Ctrl-C while the plan read and hashed the scenarios (seconds for thousands of files) gave main's bare
    document, without the `summary`, `files` and `written` docs/sweep.md promises a script."""
    def interrupted(*args: object, **kwargs: object) -> None:
        raise KeyboardInterrupt

    monkeypatch.setattr("rac.cli.sweep.plan", interrupted)
    code = main(["sweep", str(world / "sweep.ra"), str(world / "scenarios"), "-o", str(tmp_path / "out"),
                 "--format", "json"])
    captured = capsys.readouterr()
    assert code == EXIT_INTERRUPTED
    document = json.loads(captured.out)
    assert document["interrupted"] is True and document["exit_code"] == EXIT_INTERRUPTED
    assert document["summary"] is None and document["files"] == [] and document["written"] is False
    assert document["out"] == str(tmp_path / "out")
    assert "no task ran, nothing was written" in captured.err


def test_the_tasks_of_a_local_cluster_share_the_machines_memory(client, world: Path) -> None:
    """Each task's command took half the machine's memory as its budget (rac verify's default), so two workers'
    tasks side by side could take all of it, four twice it, and the machine swapped before a budget spoke; a local
    cluster gives each worker its share of the machine, and a task half of its worker's."""
    from rac.engine.budget import DEFAULT_FRACTION, machine_memory
    from rac.sweep import work
    from rac.sweep.task import worker_budget

    workers = list(client.scheduler_info()["workers"])  # type: ignore[attr-defined]
    budgets = [client.submit(worker_budget, workers=[w], pure=False).result() for w in workers]  # type: ignore[attr-defined]
    assert budgets == [int(machine_memory() // 2 * DEFAULT_FRACTION)] * 2
    assert worker_budget() is None  # in this process, no worker: the command's own default
    # the budget reaches the task's command: a preanalyse task's runs stop within it
    spec = TaskSpec(str(world / "sweep.ra"), (world / "sweep.ra").read_text(encoding="utf-8"),
                    str(world / "scenarios" / "goal_ahead.xml"), (), "preanalyse", (("runs", "5"), ("seed", "3")),
                    budget=1000)
    assert "more than the memory budget of 1000 B" in json.dumps(work.execute(spec))


def test_the_time_plot_tells_statuses_apart_without_colour(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """time_vs_size.png told the statuses apart by colour only (ok, failed, timeout look alike to a colour-blind
    reader) and its legend, placed automatically inside the axes, could cover points: each status has a marker of
    its own now, shown in the legend, which lies beside the axes."""
    from rac.sweep import report

    figures: list = []
    monkeypatch.setattr(report, "save_figure", lambda figure, path: figures.append(figure) or Path(path))
    rows = [{"settings": {}, "status": status, "verdicts": {}, "seconds": 0.1 * i, "scenario_size": i}
            for i, status in enumerate(("ok", "failed", "error", "timeout", "memory", "undecided"), start=1)]
    write_plots(rows, tmp_path)
    figure = figures[1]
    ax = figure.axes[0]
    paths = [collection.get_paths()[0].vertices.round(6).tobytes() for collection in ax.collections]
    assert len(ax.collections) == 6 and len(set(paths)) == 6  # six statuses, six shapes
    legend = ax.get_legend()
    shown = [handle.get_paths()[0].vertices.round(6).tobytes() for handle in legend.legend_handles]
    assert shown == paths
    figure.draw_without_rendering()
    assert not legend.get_window_extent().overlaps(ax.get_window_extent())
