"""One task of ``rac sweep`` (issue 13): the template instantiated per scenario and grid point
(:mod:`rac.sweep.template`), the grid and scenario expansion (:mod:`rac.sweep.grid`), and
:func:`rac.sweep.task.run_task`, which runs one task in a child process and returns its row.

The scenarios are built here with commonroad-io (:mod:`tiny_scenarios`, :mod:`rac.model.scenes`);
the template is the engine test file of :mod:`engine_files` with two queries. The rows of one batch
of tasks are computed once (two at a time, as two Dask workers would) and checked by several tests.
"""

from __future__ import annotations

import dataclasses
import json
import os
import subprocess
import sys
import time
from concurrent.futures import ThreadPoolExecutor
from fractions import Fraction
from pathlib import Path

import pytest
import sweep_helpers
from conftest import rac_env
from engine_files import engine_source
from tiny_scenarios import TINY_SCENARIOS

import rac
from rac.compiler import compile_file, compile_text
from rac.core.numbers import MIN_SEED
from rac.model.scenes import write_scene
from rac.sweep.api import plan
from rac.sweep.grid import grid_points, parse_set, scenario_files
from rac.sweep.run import pending
from rac.sweep.store import Store
from rac.sweep.task import TASKS, TaskSpec, run_task, source_digest
from rac.sweep.template import check_template, instantiate

QUERIES = {"Stays": "E[] !collide() && !offroad()", "Reaches": "E<> !collide() && !offroad() && goal()"}
#: Every key a row has, whatever happened (the interface with the Dask half).
ROW_KEYS = {"key", "scenario", "scenario_name", "planning_problem", "settings", "task", "status", "error", "seconds",
            "peak_memory", "states", "scenario_size", "verdicts", "diagnostics", "details"}


@pytest.fixture(scope="module")
def folder(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """``template/sweep.ra`` (its own scenario file is never used) and ``scenarios/``: three tiny roads,
    the highway scene (its ego starts at 20 m/s, above the template's `max_speed 10`: the check fails)
    and a broken XML file."""
    root = tmp_path_factory.mktemp("sweep")
    (root / "template").mkdir()
    (root / "template" / "sweep.ra").write_text(engine_source(TINY_SCENARIOS["goal_ahead"](), QUERIES,
                                                              scenario_file="placeholder.xml"), encoding="utf-8")
    scenarios = root / "scenarios"
    (scenarios / "more").mkdir(parents=True)
    for name in ("goal_ahead", "narrow_road"):
        TINY_SCENARIOS[name]().write(scenarios / f"{name}.xml")
    TINY_SCENARIOS["avoidable_obstacle"]().write(scenarios / "more" / "avoidable_obstacle.xml")
    # also at the top, for preanalyse (a path of its own); written here, not by the `rows` fixture, so that
    # what the folder holds does not depend on which tests ran before in this process (it did under -n 2)
    TINY_SCENARIOS["avoidable_obstacle"]().write(scenarios / "avoidable_obstacle.xml")
    write_scene("highway", scenarios / "highway.xml")
    (scenarios / "broken.xml").write_text("<commonRoad><lanelet id='1'>", encoding="utf-8")
    (scenarios / "notes.txt").write_text("not a scenario", encoding="utf-8")
    return root


def spec(folder: Path, scenario: str, task: str = "verify", settings: tuple[tuple[str, str], ...] = (),
         **kw) -> TaskSpec:
    template = folder / "template" / "sweep.ra"
    return TaskSpec(str(template), template.read_text(encoding="utf-8"), str(folder / "scenarios" / scenario),
                    settings, task, **kw)


#: The batch whose rows the tests below read: name -> the task.
BATCH = {
    "check": ("goal_ahead.xml", "check", ()),
    "ok": ("goal_ahead.xml", "verify", ()),
    "unsafe": ("narrow_road.xml", "verify", ()),
    "nested": ("more/avoidable_obstacle.xml", "verify", ()),
    "highway": ("highway.xml", "verify", ()),
    "highway_check": ("highway.xml", "check", ()),
    "broken": ("broken.xml", "verify", ()),
    "missing": ("no_such_file.xml", "verify", ()),
    "decide": ("goal_ahead.xml", "verify", (("decide_period", "0.75"),)),
    "exponent7": ("goal_ahead.xml", "check", (("exponent", "7"),)),
    "exponent1": ("goal_ahead.xml", "verify", (("exponent", "1"), ("dynamics", "increments"))),
    "preanalyse": ("avoidable_obstacle.xml", "preanalyse", ()),
    "experiment": ("goal_ahead.xml", "experiment", ()),
}
OPTIONS = {"preanalyse": (("runs", "5"), ("seed", "3")),
           "experiment": (("seeds", "1"), ("episodes", "20"), ("runs", "5"), ("reward_function", "goal()"))}


@pytest.fixture(scope="module")
def rows(folder: Path) -> dict[str, dict[str, object]]:
    specs = {name: spec(folder, scenario, task, settings, options=OPTIONS.get(task, ()), timeout=120)
             for name, (scenario, task, settings) in BATCH.items()}
    with ThreadPoolExecutor(2) as pool:  # two at a time, as two Dask workers would
        results = dict(zip(specs, pool.map(run_task, specs.values())))
    for name, row in results.items():
        assert set(row) >= ROW_KEYS, name
        json.dumps(row)  # JSON-serialisable
        assert row["key"] == specs[name].key()
    return results


# ---------------------------------------------------------------- the rows
def test_check_row(rows: dict[str, dict[str, object]], folder: Path) -> None:
    row = rows["check"]
    assert row["status"] == "ok", row
    assert row["error"] is None and row["verdicts"] == {} and row["details"] is None
    assert row["task"] == "check" and row["settings"] == {}
    assert row["scenario"] == str(folder / "scenarios" / "goal_ahead.xml") and row["scenario_name"] == "goal_ahead"
    assert row["scenario_size"] == 1  # one lanelet, no obstacle
    assert isinstance(row["seconds"], float) and row["seconds"] > 0
    assert isinstance(row["peak_memory"], int) and row["peak_memory"] > 10 * 2**20


def test_verify_rows_give_each_query_its_verdict(rows: dict[str, dict[str, object]]) -> None:
    ok, unsafe, nested = rows["ok"], rows["unsafe"], rows["nested"]
    assert ok["status"] == "ok" and ok["error"] is None, ok
    assert ok["verdicts"] == {"Stays": "satisfied", "Reaches": "satisfied"}
    assert isinstance(ok["states"], int) and ok["states"] > 100
    # the narrow road: every state is off the road (tiny_scenarios.narrow_road)
    assert unsafe["status"] == "failed", unsafe
    assert unsafe["verdicts"] == {"Stays": "not satisfied", "Reaches": "not satisfied"}
    assert "Stays" in str(unsafe["error"])
    # the parked van: it stays safe by braking (tiny_scenarios.avoidable_obstacle); read literally, a run
    # that collides with it and then stands in the goal satisfies Reaches
    assert nested["status"] == "ok" and nested["verdicts"] == {"Stays": "satisfied", "Reaches": "satisfied"}
    assert nested["scenario_size"] == 2 and nested["scenario_name"] == "avoidable_obstacle"


def test_a_scenario_the_check_refuses_fails_with_its_diagnostics(rows: dict[str, dict[str, object]]) -> None:
    for name in ("highway", "highway_check"):
        row = rows[name]
        assert row["status"] == "failed", row
        assert any(d.startswith("E0714 ") for d in row["diagnostics"]), row["diagnostics"]  # type: ignore[union-attr]
        assert str(row["error"]).startswith("E0714 ")
        assert row["verdicts"] == {}
        assert row["scenario_size"] == 3 + 3  # three lanes, three cars: the scenario was read


def test_broken_and_missing_scenarios_are_error_rows(rows: dict[str, dict[str, object]]) -> None:
    broken, missing = rows["broken"], rows["missing"]
    assert broken["status"] == "error" and "cannot load the scenario" in str(broken["error"]), broken
    assert broken["scenario_size"] is None and broken["verdicts"] == {}
    assert missing["status"] == "error" and "no_such_file.xml" in str(missing["error"]), missing
    assert missing["key"] and missing["scenario_name"] == "no_such_file"


def test_a_setting_the_check_refuses_fails_that_task_only(rows: dict[str, dict[str, object]]) -> None:
    decide = rows["decide"]
    assert decide["status"] == "failed" and decide["settings"] == {"decide_period": "0.75"}
    assert any(d.startswith("E0703 ") for d in decide["diagnostics"]), decide  # type: ignore[union-attr]
    exponent = rows["exponent7"]
    assert exponent["status"] == "failed"
    assert any(d.startswith("E0702 ") and "found 7" in d for d in exponent["diagnostics"]), exponent  # type: ignore
    assert rows["exponent1"]["status"] == "ok", rows["exponent1"]
    assert rows["exponent1"]["settings"] == {"exponent": "1", "dynamics": "increments"}


def test_preanalyse_row_holds_the_preanalysis_row(rows: dict[str, dict[str, object]]) -> None:
    row = rows["preanalyse"]
    assert row["status"] == "ok", row
    details = row["details"]
    assert isinstance(details, list) and len(details) == 1
    assert details[0]["exponent"] == 2 and details[0]["qb"] is True and details[0]["qc"] is False
    assert details[0]["seed"] == 3
    assert row["verdicts"] == {"Qb": "satisfied", "Qc": "not satisfied", "Qd": "satisfied"}
    assert row["states"] == details[0]["states"]


def test_a_preanalyse_setting_beyond_the_state_budget_is_undecided(folder: Path) -> None:
    # `rac preanalyse` exits 4 on it (no answer, none failed); the sweep's row said "failed" (exit 1)
    row = run_task(spec(folder, "goal_ahead.xml", "preanalyse",
                        options=(("runs", "2"), ("seed", "1"), ("max_states", "10")), timeout=60))
    assert row["status"] == "undecided", row
    assert "more than 10 states" in str(row["error"])
    # and what to change: it said how far it got, not which option to raise
    assert str(row["error"]).endswith(": shorten the horizon (--horizon), coarsen the model (exponent, action steps, "
                                      "decide_period) or raise --max-states if the machine has the memory"), row


def test_an_experiment_row_without_a_safe_strategy_holds_the_shields_states(folder: Path) -> None:
    """On the narrow road (every state off the road) the experiment stops at "no safe strategy" after computing the
    shield: the row's states was empty though its size was known; it is the shield's, as an ok row's."""
    options = (("seed", "1"), ("episodes", "4"), ("runs", "2"), ("reward_function", "goal()"))
    row = run_task(spec(folder, "narrow_road.xml", "experiment", options=options, timeout=60))
    assert row["status"] == "failed" and str(row["error"]).startswith("no safe strategy exists from the start"), row
    assert isinstance(row["states"], int) and row["states"] > 0, row


def test_an_experiment_row_whose_goal_no_shielded_run_reaches_fails(folder: Path) -> None:
    """Behind the obstacle no run the shield allows reaches the goal: the row was "ok", though every shielded row of
    its table must fail (rac experiment exits 1 on it). It is "failed", with the table kept in its details."""
    options = (("seed", "1"), ("episodes", "4"), ("runs", "2"), ("reward_function", "goal()"))
    row = run_task(spec(folder, "avoidable_obstacle.xml", "experiment", options=options, timeout=60))
    assert row["status"] == "failed", row
    assert str(row["error"]).startswith("no run the shield allows reaches the goal safely within the horizon"), row
    assert isinstance(row["details"], list) and len(row["details"]) == 4 and row["states"], row


def test_an_experiment_row_explores_as_its_option_says(folder: Path) -> None:
    """The option explore is rac experiment's --explore: goal steers the exploring choices (the experiment's
    own tests check how); a value it does not know is refused by the plan, before any task runs."""
    options = (("seeds", "1"), ("episodes", "8"), ("runs", "2"), ("reward_function", "goal()"), ("explore", "goal"))
    row = run_task(spec(folder, "goal_ahead.xml", "experiment", options=options, timeout=120))
    assert row["status"] == "ok", row
    with pytest.raises(ValueError, match="--explore: one of uniform, goal, not 'best'"):
        plan(folder / "template" / "sweep.ra", [str(folder / "scenarios" / "goal_ahead.xml")], task="experiment",
             options={"explore": "best", "reward_function": "goal()"}, out=folder / "plan-out")


def test_experiment_row_holds_the_summary_table(rows: dict[str, dict[str, object]]) -> None:
    row = rows["experiment"]
    assert row["status"] == "ok", row
    details = row["details"]
    assert isinstance(details, list)
    assert [d["combination"] for d in details] == ["SS&RA", "SS&RF", "RA", "RF"]
    assert all(d["seeds"] == 1 and d["episodes"] == [20] for d in details)


def test_tasks_write_no_files(rows: dict[str, dict[str, object]], folder: Path) -> None:
    assert not list(folder.rglob("*.out")), "a task wrote beside the template or a scenario"
    assert sorted(p.name for p in (folder / "template").iterdir()) == ["sweep.ra"]


# ---------------------------------------------------------------- limits
def _marked(mark: str) -> list[int]:
    """The processes whose environment holds ``mark``."""
    found = []
    for entry in Path("/proc").iterdir():
        try:
            if entry.name.isdigit() and mark.encode() in (entry / "environ").read_bytes():
                found.append(int(entry.name))
        except OSError:  # gone, or not ours
            pass
    return found


def test_a_task_past_its_timeout_is_a_timeout_row(folder: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    mark = f"RAC_SWEEP_TEST_MARK_{os.getpid()}"
    monkeypatch.setenv(mark, "1")  # the child inherits it: what is left of the task can be found
    row = run_task(spec(folder, "goal_ahead.xml", timeout=0.3))
    assert row["status"] == "timeout", row
    assert "0.3 s" in str(row["error"])
    assert 0.3 <= row["seconds"] < 10  # type: ignore[operator]
    assert row["verdicts"] == {} and set(row) >= ROW_KEYS
    assert _marked(mark) == [], "the task's process outlived its timeout"


def test_a_preanalyse_task_killed_at_its_timeout_keeps_the_answers_found(folder: Path, tmp_path: Path,
                                                                         monkeypatch: pytest.MonkeyPatch) -> None:
    """A preanalyse task killed at its --task-timeout dropped what its setting had found (Qa, in seconds, before an
    exploration that ran past the timeout): the row said only the timeout. The task keeps its answers as it finds
    them, and the timeout row holds them, the setting saying why it has no more."""
    hook = tmp_path / "hook"  # the child's sitecustomize: its exploration runs past any timeout
    hook.mkdir()
    (hook / "sitecustomize.py").write_text("import time\nimport rac.studies.preanalysis as p\n"
                                           "p.synthesise = lambda *args, **kw: time.sleep(600)\n", encoding="utf-8")
    monkeypatch.setenv("PYTHONPATH", os.pathsep.join([str(hook), os.environ.get("PYTHONPATH", "")]))
    row = run_task(spec(folder, "goal_ahead.xml", "preanalyse", options=(("runs", "2"), ("seed", "1")), timeout=8))
    assert row["status"] == "timeout", row
    said = "ran past the task timeout of 8 s"
    assert row["error"] == f"{said}; kept the answers found before it (Qa) in its details"
    [setting] = row["details"]  # type: ignore[misc]
    assert setting["qa"] is not None and "qb" not in setting and setting["error"] == said
    assert row["verdicts"] == {} and row["states"] is None
    assert row["scenario_size"] == 1  # the road's one lanelet: the task's time is drawn against it in time_vs_size.png


def test_a_task_killed_at_its_timeout_keeps_its_scenarios_size(folder: Path, tmp_path: Path,
                                                               monkeypatch: pytest.MonkeyPatch) -> None:
    """A task killed at its --task-timeout had no scenario_size, though its check had loaded the scenario:
    time_vs_size.png left out exactly the slow tasks ("1 tasks without a size not shown"). An experiment task, which
    keeps no answers, keeps the size."""
    from rac.sweep.report import write_plots

    hook = tmp_path / "hook"  # the child's sitecustomize: the shield runs past any timeout
    hook.mkdir()
    (hook / "sitecustomize.py").write_text("import time\nimport rac.engine.shield as s\n"
                                           "s.synthesise = lambda *args, **kw: time.sleep(600)\n", encoding="utf-8")
    monkeypatch.setenv("PYTHONPATH", os.pathsep.join([str(hook), os.environ.get("PYTHONPATH", "")]))
    row = run_task(spec(folder, "goal_ahead.xml", "experiment", options=OPTIONS["experiment"], timeout=8))
    assert row["status"] == "timeout" and row["error"] == "ran past the task timeout of 8 s", row
    assert row["scenario_size"] == 1, row
    from rac.sweep import report

    titles: list[str] = []
    save = report.save_figure
    monkeypatch.setattr(report, "save_figure", lambda figure, path: titles.append(figure.axes[0].get_title())
                        or save(figure, path))
    write_plots([row, {**row, "scenario_size": None}], tmp_path)
    assert titles[-1] == "task time against scenario size (1 task without a size not shown)"


def test_a_verify_task_killed_at_its_timeout_keeps_the_verdicts_found(folder: Path, tmp_path: Path,
                                                                      monkeypatch: pytest.MonkeyPatch) -> None:
    """A verify task killed at its --task-timeout dropped the verdicts of the queries it had answered before the
    one that ran past it: the row keeps them now, and says which query was running."""
    hook = tmp_path / "hook"  # the child's sitecustomize: a simulate query runs past any timeout
    hook.mkdir()
    (hook / "sitecustomize.py").write_text("import time\nfrom rac.verify.statistical import StatisticalAnswerer\n"
                                           "StatisticalAnswerer.simulate = lambda *args, **kw: time.sleep(600)\n",
                                           encoding="utf-8")
    monkeypatch.setenv("PYTHONPATH", os.pathsep.join([str(hook), os.environ.get("PYTHONPATH", "")]))
    template = tmp_path / "two.ra"
    template.write_text(engine_source(TINY_SCENARIOS["goal_ahead"](), {"Stays": QUERIES["Stays"],
                                                                       "Sim": "simulate[<=2; 4]{mindist()}"},
                                      scenario_file="placeholder.xml"), encoding="utf-8")
    row = run_task(TaskSpec(str(template), template.read_text(encoding="utf-8"),
                            str(folder / "scenarios" / "goal_ahead.xml"), (), "verify", (("seed", "1"),), timeout=8))
    assert row["status"] == "timeout", row
    assert row["error"] == ("ran past the task timeout of 8 s; kept the answers of the queries before it (Stays); "
                            "it was answering Sim: simulate[<=2;4]{mindist()}"), row["error"]
    assert row["verdicts"] == {"Stays": "satisfied"} and row["states"] > 0  # type: ignore[operator]


def test_the_task_leaves_with_its_worker(folder: Path) -> None:
    """A worker that dies (Dask reruns its task elsewhere) takes its task's process along."""
    mark = f"RAC_SWEEP_WORKER_MARK_{os.getpid()}"
    long = spec(folder, "goal_ahead.xml", "experiment",
                options=(("episodes", "1000000"), ("reward_function", "goal()"), ("seeds", "1")))
    code = ("import json, sys; from rac.sweep.task import TaskSpec, run_task; "
            "run_task(TaskSpec.from_json(json.load(sys.stdin)))")
    worker = subprocess.Popen([sys.executable, "-c", code], stdin=subprocess.PIPE, text=True,
                              env={**rac_env(), mark: "1"})
    try:
        worker.stdin.write(json.dumps(long.to_json()))  # type: ignore[union-attr]
        worker.stdin.close()  # type: ignore[union-attr]
        deadline = time.monotonic() + 30
        while len(_marked(mark)) < 2 and time.monotonic() < deadline:  # the worker and its task
            time.sleep(0.1)
        assert len(_marked(mark)) == 2
    finally:
        worker.kill()
        worker.wait()
    deadline = time.monotonic() + 5
    while _marked(mark) and time.monotonic() < deadline:
        time.sleep(0.1)
    assert _marked(mark) == [], "the task's process outlived its worker"


def test_a_task_past_its_memory_limit_is_a_memory_row(folder: Path) -> None:
    row = run_task(spec(folder, "goal_ahead.xml", memory=64 * 2**20, timeout=60))
    assert row["status"] == "memory", row
    assert "64 MB" in str(row["error"])


def test_the_memory_limit_leaves_out_the_modules_the_task_loaded(folder: Path) -> None:
    """RLIMIT_AS counted the address space of rac's loaded modules (about 280 MB, a third of it resident):
    under 200 MB a task of a tiny road was a `memory` row at 90 MB resident, and under 300 MB so was every
    task of a real scenario. The limit is now what the task maps beyond them."""
    row = run_task(spec(folder, "goal_ahead.xml", memory=200 * 2**20, timeout=60))
    assert row["status"] == "ok", row


@pytest.mark.parametrize(("option", "value", "said"), [
    ("seed", "-1", f"option seed: must be at least {MIN_SEED}: '-1'"),  # it said "at least 1", and took 0
    ("seeds", "2,-1", f"option seed: must be at least {MIN_SEED}: '-1'"),
    ("runs", "0", "option runs: must be at least 1: '0'"),
])
def test_an_option_below_its_least_value_is_an_error_row_naming_it(folder: Path, option: str, value: str,
                                                                    said: str) -> None:
    row = run_task(spec(folder, "goal_ahead.xml", options=((option, value),)))
    assert row["status"] == "error" and said in str(row["error"]), row


@pytest.mark.parametrize(("value", "said"), [
    ("0.15", "horizon 0.15 is not a whole number of samples of 0.5 s"),
    ("1e12", "samples of 0.5 s: more than 2,147,483,647"),  # the command line's rule: beyond int32 samples
])
def test_a_horizon_that_is_not_a_number_of_samples_is_an_error_row(folder: Path, value: str, said: str) -> None:
    row = run_task(spec(folder, "goal_ahead.xml", options=(("horizon", value),)))
    assert row["status"] == "error" and said in str(row["error"]), row


def test_an_unknown_option_is_an_error_row(folder: Path) -> None:
    row = run_task(spec(folder, "goal_ahead.xml", options=(("horizn", "2"),)))
    assert row["status"] == "error" and "horizn" in str(row["error"]), row


def test_task_names() -> None:
    assert TASKS == ("check", "verify", "preanalyse", "experiment")
    with pytest.raises(ValueError, match="simulate"):
        TaskSpec("t.ra", "", "s.xml", (), "simulate")


# ---------------------------------------------------------------- the key
def test_the_key_depends_on_the_inputs_only(folder: Path, tmp_path: Path) -> None:
    base = spec(folder, "goal_ahead.xml")
    assert len(base.key()) == 16 and int(base.key(), 16) >= 0
    assert base.key() == spec(folder, "goal_ahead.xml").key()
    # stable across processes (no hash randomisation)
    code = ("import sys; from rac.sweep.task import TaskSpec; "
            "print(TaskSpec(*sys.argv[1:3], sys.argv[3], (), 'verify').key())")
    other = subprocess.run([sys.executable, "-c", code, base.template, base.template_text, base.scenario],
                           env={**rac_env(), "PYTHONHASHSEED": "7"}, capture_output=True, text=True, check=True)
    assert other.stdout.strip() == base.key()
    # the limits do not change what a task computes
    assert spec(folder, "goal_ahead.xml", timeout=5, memory=2**30).key() == base.key()
    different = [spec(folder, "narrow_road.xml"), spec(folder, "goal_ahead.xml", task="check"),
                 spec(folder, "goal_ahead.xml", settings=(("exponent", "1"),)),
                 spec(folder, "goal_ahead.xml", settings=(("exponent", "3"),)),
                 spec(folder, "goal_ahead.xml", options=(("horizon", "2"),)),
                 TaskSpec(base.template, base.template_text + "\n", base.scenario, (), "verify")]
    keys = {base.key(), *(s.key() for s in different)}
    assert len(keys) == len(different) + 1
    # the scenario's bytes, not its path: a copy has the same key, a changed file another
    copy = tmp_path / "copy.xml"
    copy.write_bytes(Path(base.scenario).read_bytes())
    moved = TaskSpec(base.template, base.template_text, str(copy), (), "verify")
    assert moved.key() == base.key()
    write_scene("overtaking", copy)
    assert moved.key() != base.key()
    # an unreadable scenario still has a key (its row is an error row)
    assert spec(folder, "no_such_file.xml").key() != spec(folder, "other_missing.xml").key()


@pytest.mark.skipif(not hasattr(os, "mkfifo"), reason="FIFOs are POSIX")
def test_a_fifo_among_the_scenarios_is_an_error_row_not_a_hang(folder: Path, tmp_path: Path) -> None:
    """A FIFO named *.xml in a scenario folder hung the sweep before any task ran (its key read it, waiting for
    a writer for ever), and its task's process until the task timeout. It is keyed by its path now, and its
    row says what it is."""
    fifo = tmp_path / "pipe.xml"
    os.mkfifo(fifo)
    code = ("import sys; from rac.sweep.api import plan; "
            "print(plan(sys.argv[1], [sys.argv[2]], task='check').specs[0].key())")
    keyed = subprocess.run([sys.executable, "-c", code, str(folder / "template" / "sweep.ra"), str(tmp_path)],
                           env=rac_env(), capture_output=True, text=True, timeout=20)
    assert keyed.returncode == 0 and len(keyed.stdout.strip()) == 16, keyed.stderr
    started = time.perf_counter()
    row = run_task(dataclasses.replace(spec(folder, "goal_ahead.xml", task="check"), scenario=str(fifo), timeout=8))
    assert row["status"] == "error" and "is not a regular file" in str(row["error"]), row
    assert time.perf_counter() - started < 8


def test_a_sweep_reads_each_scenario_once_for_its_keys(folder: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """The keys of a sweep read each scenario file once per grid point (a sweep of 1000 points over a large
    scenario read it 1000 times before any task ran); now once per sweep, with the same keys as before."""
    reads: list[Path] = []
    read_bytes = Path.read_bytes

    def counted(self: Path) -> bytes:
        reads.append(self)
        return read_bytes(self)

    scenario = folder / "scenarios" / "goal_ahead.xml"
    monkeypatch.setattr(Path, "read_bytes", counted)
    planned = plan(folder / "template" / "sweep.ra", [str(scenario)], sets=["exponent=1,2,3"])
    outcome, todo = pending(planned.specs, Store(folder / "unused"))
    assert len(todo) == 3 and reads.count(scenario) == 1
    # the key is the same as that of a spec that reads the file itself
    assert TaskSpec.from_json(planned.specs[0].to_json()).key() == outcome.keys[0] == dataclasses.replace(
        planned.specs[0], scenario_digest=None).key()


def test_the_source_digest_changes_with_any_file_of_rac(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """The digest a row records: the same for the same files, another after an edit, a new file or a rename;
    compiled files (``__pycache__``) aside."""
    package = tmp_path / "rac"
    (package / "sub").mkdir(parents=True)
    (package / "__init__.py").write_text("x = 1\n", encoding="utf-8")
    (package / "sub" / "a.py").write_text("y = 2\n", encoding="utf-8")
    monkeypatch.setattr(rac, "__file__", str(package / "__init__.py"))

    def digest() -> str:
        source_digest.cache_clear()
        return source_digest()

    first = digest()
    assert len(first) == 16 and digest() == first
    (package / "__pycache__").mkdir()
    (package / "__pycache__" / "x.pyc").write_bytes(b"compiled")
    assert digest() == first
    seen = {first}
    for change in (lambda: (package / "sub" / "a.py").write_text("y = 3\n", encoding="utf-8"),
                   lambda: (package / "sub" / "b.py").write_text("", encoding="utf-8"),
                   lambda: (package / "sub" / "b.py").rename(package / "sub" / "c.py")):
        change()
        seen.add(digest())
    assert len(seen) == 4
    monkeypatch.undo()
    source_digest.cache_clear()
    assert source_digest() != first  # rac's own files again


# ---------------------------------------------------------------- the template
def test_instantiate_applies_the_scenario_and_the_settings(folder: Path) -> None:
    template = folder / "template" / "sweep.ra"
    scenario = folder / "scenarios" / "goal_ahead.xml"
    text = instantiate(check_template(template), template, scenario,
                       (("exponent", "1"), ("sensor_error", "0.25"), ("dynamics", "increments"),
                        ("start_x", "-2")))
    result = compile_text(text, name=str(template))
    assert result.ok, result.diagnostics
    model = result.automaton.model  # type: ignore[union-attr]
    assert model.scenario_path == str(scenario)
    assert model.exponent == 1 and result.model_data.scale == 10  # type: ignore[union-attr]
    assert model.sensor_error == Fraction(1, 4)  # absent from the template: added
    assert model.dynamics == "increments" and model.start_x == -2
    assert text.count("exponent") == 1  # replaced, not written twice
    # without settings: only the scenario changes
    plain = compile_text(instantiate(check_template(template), template, scenario, ()), name=str(template))
    assert plain.ok and plain.model_data.scale == 100  # type: ignore[union-attr]


@pytest.mark.parametrize("example", ["paper/model.ra", "left_turn/model.ra", "left_turn/preanalysis.ra"])
def test_instantiate_keeps_everything_but_the_scenario(example: str) -> None:
    """The shipped files, instantiated with their own scenario and no settings, check to the same
    automaton: the edit changes the scenario item alone."""
    path = Path(__file__).resolve().parents[2] / "examples" / example
    before = compile_file(path)
    assert before.ok and before.automaton is not None and before.automaton.model is not None
    scenario = before.automaton.model.scenario_path
    after = compile_text(instantiate(check_template(path), path, scenario, ()), name=str(path))
    assert after.ok and after.automaton is not None and after.automaton.model is not None
    assert after.automaton.model.scenario_path == os.path.abspath(scenario)
    same = dataclasses.replace(after.automaton.model, scenario=before.automaton.model.scenario,
                               scenario_path=scenario)
    assert same == before.automaton.model
    assert dataclasses.replace(after.automaton, model=same, source=before.automaton.source) == before.automaton


def test_a_scenario_path_a_ra_file_cannot_hold_is_an_error_row_that_says_so(folder: Path, tmp_path: Path) -> None:
    """A scenario named `a"b.xml` gave the error "the template a scenario path cannot hold a quote ...": the
    words of the path's rule, garbled behind "the template"."""
    weird = tmp_path / 'a"b.xml'
    weird.write_bytes((folder / "scenarios" / "goal_ahead.xml").read_bytes())
    row = run_task(dataclasses.replace(spec(folder, "goal_ahead.xml", task="check"), scenario=str(weird)))
    assert row["status"] == "error"
    assert row["error"] == (f"cannot instantiate the template {folder / 'template' / 'sweep.ra'} with the scenario "
                            f"{weird}: a scenario path cannot hold a quote or a line break: {str(weird)!r}")


def test_check_template_refuses_a_template_without_a_model_block(tmp_path: Path) -> None:
    bare = tmp_path / "bare.ra"
    bare.write_text("automaton Bare {\n    reward r\n    objective r\n    sample every 1\n    horizon 2\n"
                    "    initial location A { r' == 1 }\n}\n", encoding="utf-8")
    with pytest.raises(ValueError, match="no `model` block"):
        check_template(bare)
    broken = tmp_path / "broken.ra"
    broken.write_text("automaton {", encoding="utf-8")
    with pytest.raises(ValueError, match="E0"):
        check_template(broken)
    with pytest.raises(OSError):
        check_template(tmp_path / "missing.ra")


def test_check_template_reads_the_template_as_rac_check_does(tmp_path: Path) -> None:
    """A byte-order mark (which `rac check` drops) was an `unexpected character` and refused the template;
    a Latin-1 file was Python's bare codec message, not E0004; a FIFO blocked the sweep for ever."""
    text = (Path(__file__).resolve().parents[2] / "examples" / "left_turn" / "model.ra").read_text(encoding="utf-8")
    marked = tmp_path / "marked.ra"
    marked.write_bytes(b"\xef\xbb\xbf" + text.replace("\n", "\r\n").encode("utf-8"))
    assert check_template(marked) == text  # the mark dropped, the line ends as \n (the task keys stay)
    latin = tmp_path / "latin.ra"
    latin.write_bytes(text.encode("utf-8") + b"// caf\xe9\n")
    with pytest.raises(ValueError, match="E0004"):
        check_template(latin)
    fifo = tmp_path / "fifo.ra"
    os.mkfifo(fifo)
    with pytest.raises(OSError, match="not a regular file"):
        check_template(fifo)


# ---------------------------------------------------------------- grid and scenarios
def test_scenario_files_expand_folders_and_globs(folder: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    scenarios = folder / "scenarios"
    every = sorted(p for p in scenarios.rglob("*.xml"))
    assert len(every) == 6
    assert scenario_files([str(scenarios)]) == every  # recursively, *.xml only
    # a file named twice, or inside a folder named too, counts once
    assert scenario_files([str(scenarios / "highway.xml"), str(scenarios), str(scenarios / "highway.xml")]) == every
    assert scenario_files([str(scenarios / "g*.xml")]) == [scenarios / "goal_ahead.xml"]
    assert scenario_files([str(scenarios / "**" / "avoid*.xml")]) == [scenarios / "avoidable_obstacle.xml",
                                                                      scenarios / "more" / "avoidable_obstacle.xml"]
    monkeypatch.chdir(scenarios)
    assert scenario_files(["highway.xml", "more"]) == [scenarios / "highway.xml",
                                                       scenarios / "more" / "avoidable_obstacle.xml"]
    with pytest.raises(ValueError, match=r"nothing\*\.xml.*missing\.xml"):
        scenario_files(["nothing*.xml", "highway.xml", "missing.xml"])
    (scenarios / "empty").mkdir()
    with pytest.raises(ValueError, match="empty"):
        scenario_files(["empty"])
    # rac's own outputs (a UPPAAL model rac compile wrote into TEMPLATE.out/) are no scenarios to a search
    (scenarios / "driving.out").mkdir()
    (scenarios / "driving.out" / "model.xml").write_text("<?xml version='1.0'?>\n<nta><declaration>// Generated by "
                                                         "rac from driving.ra</declaration></nta>\n")
    assert scenario_files([str(scenarios)]) == every
    assert scenario_files([str(scenarios / "**" / "*.xml")]) == every
    with pytest.raises(ValueError, match="driving.out"):
        scenario_files([str(scenarios / "driving.out")])
    named = scenarios / "driving.out" / "model.xml"
    assert scenario_files([str(named)]) == [named]  # named outright: taken, and its task says what it is
    with pytest.raises(ValueError):
        scenario_files([])


def test_parse_set_and_grid_points() -> None:
    sets = parse_set(["exponent=1,2", "decide_period = 0.5, 1", "dynamics=integrated,increments,integrated"])
    assert sets == [("exponent", ["1", "2"]), ("decide_period", ["0.5", "1"]),
                    ("dynamics", ["integrated", "increments"])]
    points = grid_points(sets)
    assert len(points) == 8
    assert points[0] == (("exponent", "1"), ("decide_period", "0.5"), ("dynamics", "integrated"))
    assert points[1] == (("exponent", "1"), ("decide_period", "0.5"), ("dynamics", "increments"))
    assert points[-1] == (("exponent", "2"), ("decide_period", "1"), ("dynamics", "increments"))
    assert grid_points([]) == [()]
    assert parse_set(["start_x=-2"]) == [("start_x", ["-2"])]
    # what only the template can give a value (a constant of its own) is left to each task's check
    assert parse_set(["exponent=DIGITS", "max_speed=2*TOP"]) == [("exponent", ["DIGITS"]), ("max_speed", ["2*TOP"])]


def test_a_value_written_twice_another_way_is_one_grid_point() -> None:
    """`--set exponent=1,1.0` made two grid points, two tasks with one answer (the repeated text was kept once,
    the same value written another way was not)."""
    assert parse_set(["exponent=1,1.0,2", "max_speed=0.5,0.50,1/2"]) == [("exponent", ["1", "2"]),
                                                                         ("max_speed", ["0.5", "1/2"])]


@pytest.mark.parametrize("text, message", [
    ("exponent", "NAME=V1,V2"), ("exponent=", "no value"), ("=1,2", "NAME=V1,V2"), ("exponent=1,,2", "empty"),
    ("exponent=1 2", "exponent"), ("expnent=1", "did you mean `exponent`"), ("scenario=a.xml", "SCENARIOS"),
    ("jerk=1", "action"), ("exponent=1;exponent=2", "exponent"),
    # a value outside the setting's own range failed every task of it, one failed row per scenario, exit 1:
    # it is said up front now, in rac check's words (E0702)
    ("exponent=1,7", r"`--set exponent=7`: `exponent` must be a whole number from 1 to 6 \(found 7\)"),
    ("exponent=2.5", r"`exponent` must be a whole number from 1 to 6 \(found 2.5\)"),
    ("max_speed=10,-1", r"`--set max_speed=-1`: `max_speed` must be a number > 0 \(found -1 m/s\)"),
    ("sense_period=1-1", r"`sense_period` must be a number > 0 \(found 0 s\)"),
    ("dynamics=fast", r"`dynamics` must be one of the words `integrated`, `increments` \(found `fast`\)"),
])
def test_parse_set_refuses(text: str, message: str) -> None:
    with pytest.raises(ValueError, match=message):
        parse_set([text])


def test_parse_set_refuses_a_setting_twice() -> None:
    with pytest.raises(ValueError, match="twice"):
        parse_set(["exponent=1", "exponent=2"])


def test_the_child_reads_the_spec_on_stdin(folder: Path) -> None:
    """``python -m rac.sweep.child`` (what run_task starts) prints the row's task part as JSON."""
    task = spec(folder, "goal_ahead.xml", task="check")
    done = subprocess.run([sys.executable, "-m", "rac.sweep.child"], input=json.dumps(task.to_json()), text=True,
                          env=rac_env(), capture_output=True, check=True, timeout=60, cwd=os.getcwd())
    assert json.loads(done.stdout)["status"] == "ok"


def test_a_task_whose_process_is_killed_is_an_error_row_to_retry(folder: Path) -> None:
    """SIGKILL from outside (the out-of-memory killer) is no verdict on the task: the row says so."""
    row = sweep_helpers.run_task_killed(spec(folder, "goal_ahead.xml"))
    assert row["status"] == "error", row
    assert "died of signal SIGKILL" in str(row["error"]) and row["retry"] is True
    assert run_task(spec(folder, "goal_ahead.xml", "check"))["retry"] is False


def test_an_inconsistent_scenario_is_an_error_row(folder: Path, tmp_path: Path) -> None:
    """E0718-E0721 say the input is unusable, as E0712 does: no verdict on the template ("error")."""
    text = (folder / "scenarios" / "goal_ahead.xml").read_text(encoding="utf-8")
    assert 'timeStepSize="0.1"' in text
    step = tmp_path / "step.xml"  # outside the module's folder: other tests count its scenarios
    step.write_text(text.replace('timeStepSize="0.1"', 'timeStepSize="1e-308"'), encoding="utf-8")
    row = run_task(spec(folder, str(step), "check"))
    assert row["status"] == "error" and str(row["error"]).startswith("E0718 inconsistent scenario: "), row


def test_an_undecided_query_makes_an_undecided_row(folder: Path, tmp_path: Path) -> None:
    # it was an "error" row ("rac could not run it") and counted as failed; nothing failed, no answer came
    from rac.cli.sweep import exit_status
    from rac.sweep.report import render_summary, summarise

    template = tmp_path / "late.ra"  # a bound past the horizon: not answered (unsupported)
    template.write_text(engine_source(TINY_SCENARIOS["goal_ahead"](), {"Late": "Pr[<=5](<> v >= 6)"},
                                      scenario_file="placeholder.xml"), encoding="utf-8")
    row = run_task(TaskSpec(str(template), template.read_text(encoding="utf-8"),
                            str(folder / "scenarios" / "goal_ahead.xml"), (), "verify"))
    assert row["status"] == "undecided" and str(row["error"]).startswith("not decided: "), row
    summary = summarise([row], tasks=1)
    assert (summary.ok, summary.failed, summary.undecided) == (0, 0, 1)
    assert render_summary(summary).splitlines()[:2] == ["tasks  ok  failed  undecided  skipped  not run",
                                                        "    1   0       0          1        0        0"]
    assert exit_status([row]) == 4


def test_a_scenario_copied_under_another_name_keeps_its_own_name_in_the_rows(folder: Path, tmp_path: Path) -> None:
    # the two files share a key (the same bytes) and were run once; the copy's row kept the other's name
    from rac.sweep.run import Outcome, rows_in_order

    original = folder / "scenarios" / "goal_ahead.xml"
    copy = tmp_path / "copy.xml"
    copy.write_bytes(original.read_bytes())
    specs = [spec(folder, "goal_ahead.xml", "check"),
             TaskSpec(spec(folder, "goal_ahead.xml").template, spec(folder, "goal_ahead.xml").template_text,
                      str(copy), (), "check")]
    assert specs[0].key() == specs[1].key()
    row = run_task(specs[0])
    outcome = Outcome(keys=[s.key() for s in specs], rows={row["key"]: row})
    first, second = rows_in_order(specs, outcome)
    assert (first["scenario"], first["scenario_name"]) == (str(original), "goal_ahead")
    assert (second["scenario"], second["scenario_name"]) == (str(copy), "copy")


def test_the_source_digest_is_the_same_installed_or_checked_out(tmp_path: Path, monkeypatch: pytest.MonkeyPatch
                                                                ) -> None:
    """A wheel carries the grammar and the standard library inside the package, a checkout keeps them beside
    it: the same code gives the same digest either way (a Dask worker may import the other copy: CI's test
    process ran the installed rac while its workers imported the checkout's, and every stored row was
    rerun as 'of other source files')."""
    package = tmp_path / "rac"
    package.mkdir()
    (package / "__init__.py").write_text("x = 1\n", encoding="utf-8")
    monkeypatch.setattr(rac, "__file__", str(package / "__init__.py"))
    source_digest.cache_clear()
    checked_out = source_digest()
    for folder, name in (("grammar", "rac.lark"), ("stdlib", "driving.ra")):  # where a wheel puts them
        (package / folder).mkdir()
        (package / folder / name).write_text("copied by the wheel\n", encoding="utf-8")
    source_digest.cache_clear()
    assert source_digest() == checked_out
    monkeypatch.undo()
    source_digest.cache_clear()


def test_a_verify_task_whose_queries_draw_runs_says_its_seed(tmp_path: Path) -> None:
    """Without --seed each task drew a fresh seed and the row kept none: a statistical query's verdict that no
    one could reproduce, nor check with `rac verify --seed N` on the file. The row now says the seed, and the
    task given it answers alike; a task whose queries draw nothing has no seed."""
    from rac.sweep import work  # the task's own half, run here in process

    tiny = TINY_SCENARIOS["avoidable_obstacle"]()
    tiny.write(tmp_path / "road.xml")
    queries = {"Stays": "E[] !collide() && !offroad()", "Near": "Pr[<=2](<> mindist() < 14) >= 0.5"}
    template = tmp_path / "sweep.ra"
    template.write_text(engine_source(tiny, queries, scenario_file="placeholder.xml"), encoding="utf-8")
    drawn = TaskSpec(str(template), template.read_text(encoding="utf-8"), str(tmp_path / "road.xml"), (), "verify",
                     (("horizon", "2"),))
    row = work.execute(drawn)
    assert row["status"] in ("ok", "failed") and set(row["verdicts"]) == {"Stays", "Near"}, row
    assert isinstance(row["seed"], int) and row["seed"] >= MIN_SEED
    again = work.execute(dataclasses.replace(drawn, options=(("horizon", "2"), ("seed", str(row["seed"])))))
    assert (again["seed"], again["verdicts"]) == (row["seed"], row["verdicts"])
    plain = dataclasses.replace(drawn, template_text=engine_source(tiny, {"Stays": queries["Stays"]},
                                                                   scenario_file="placeholder.xml"))
    assert "seed" not in work.execute(plain)


def test_a_file_with_several_planning_problems_is_a_task_per_problem(folder: Path, tmp_path: Path) -> None:
    # a file with several planning problems was one task, an E0715 error row ("choose one in the model block"),
    # though a sweep's template cannot choose one for every file: real datasets number them per file
    from tiny_scenarios import SECOND_PROBLEM_ID, junction_with_two_problems

    from rac.sweep import plan
    from rac.sweep.report import summarise

    scenes = tmp_path / "scenes"
    scenes.mkdir()
    (scenes / "junction.xml").write_bytes(junction_with_two_problems())
    TINY_SCENARIOS["goal_ahead"]().write(scenes / "goal_ahead.xml")
    template = folder / "template" / "sweep.ra"
    planned = plan(template, [str(scenes)], task="check", sets=["exponent=1,2"])
    assert [(Path(s.scenario).name, s.planning_problem, s.settings) for s in planned.specs] == [
        ("goal_ahead.xml", None, (("exponent", "1"),)), ("goal_ahead.xml", None, (("exponent", "2"),)),
        ("junction.xml", 100, (("exponent", "1"),)), ("junction.xml", 100, (("exponent", "2"),)),
        ("junction.xml", SECOND_PROBLEM_ID, (("exponent", "1"),)),
        ("junction.xml", SECOND_PROBLEM_ID, (("exponent", "2"),))]
    assert (planned.scenarios, planned.problems, planned.points) == (2, 3, 2)
    assert len({s.key() for s in planned.specs}) == 6
    # a spec without a chosen problem keeps the key it had before the field existed (stored rows are reused)
    plain = planned.specs[0]
    assert plain.key() == dataclasses.replace(plain, planning_problem=None).key()
    assert TaskSpec.from_json(planned.specs[-1].to_json()) == planned.specs[-1]
    rows = [run_task(dataclasses.replace(s, timeout=120)) for s in planned.specs[2::3]]  # 100 at 1, 101 at 2
    assert [(r["planning_problem"], r["status"]) for r in rows] == [(100, "ok"), (SECOND_PROBLEM_ID, "ok")], rows
    assert all("E0715" not in json.dumps(r["diagnostics"]) for r in rows)
    failed = [{**rows[1], "status": "failed", "error": "x"}]
    assert summarise(failed, tasks=1).problems == [("failed", "junction (planning problem 101)", "exponent=2", "x")]
    # the template's (or the grid's) choice applies to every file: no task per problem
    assert [s.planning_problem for s in plan(template, [str(scenes)], task="check",
                                             sets=["planning_problem=100"]).specs] == [None, None]


@pytest.mark.parametrize("task", ["preanalyse", "experiment"])
def test_every_task_keeps_within_the_memory_budget(folder: Path, task: str, monkeypatch: pytest.MonkeyPatch) -> None:
    """A preanalyse or experiment task ran without a memory budget (`rac preanalyse` and `rac experiment` have
    half the memory available): a large model grew past a GB unchecked, or under --task-memory ran into it as an
    allocation that failed midway. Every task now has the budget of its command (the task's limit, if any), and
    stops within it, saying how far it got."""
    from rac.sweep import work

    monkeypatch.setattr(work, "default_max_bytes", lambda: 1000)  # the budget a task without --task-memory has
    row = work.execute(spec(folder, "goal_ahead.xml", task, options=OPTIONS[task]))
    assert "more than the memory budget of 1000 B" in str(row["error"]), row
    assert row["status"] in ("undecided", "failed"), row


@pytest.mark.parametrize("task", ["preanalyse", "experiment"])
def test_a_tasks_budget_refusal_names_the_sweeps_option(folder: Path, task: str,
                                                        monkeypatch: pytest.MonkeyPatch) -> None:
    """A task's budget refusal said `(--max-memory)` and `raise --max-memory`, an option `rac sweep` does not have
    (the engine's words, shared by every command); it names --task-memory, and rac verify's own stay."""
    from rac.sweep import work

    monkeypatch.setattr(work, "default_max_bytes", lambda: 1000)
    row = work.execute(spec(folder, "goal_ahead.xml", task, options=OPTIONS[task]))
    assert "(--task-memory)" in str(row["error"]) and "--max-memory" not in str(row["error"]), row
    from rac.core.resources import memory_option

    assert memory_option() == "--max-memory"  # the task's option ends with it


def test_an_experiment_tasks_shield_refusal_names_what_to_raise(folder: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """The shield's budget refusal in an experiment task named --task-memory only as the budget, and advised only
    "coarsen the model (actions, decide_period) or shorten the horizon", while a verify task's says what to raise
    (--task-memory, --max-states): it says so now, as rac verify's (verify.context.over_budget)."""
    from rac.engine import shield
    from rac.engine.budget import BudgetExceeded
    from rac.sweep import work

    def refused(*args: object, **kwargs: object) -> object:  # the budget's own refusal, in the task's option
        raise BudgetExceeded(what="the model", kind="memory", limit=2**20, states=500, sample=4, seconds=0.4,
                             needed_bytes=2**21)

    monkeypatch.setattr(shield, "synthesise", refused)
    options = (("seed", "1"), ("episodes", "20"), ("reward_function", "goal()"))
    row = work.execute(spec(folder, "goal_ahead.xml", "experiment", options=options, memory=2**30))
    assert row["status"] == "undecided", row
    assert ("the safety shield cannot be computed: the model would need about 2 MB by t = 0.4 s (sample 4), more "
            "than the memory budget of 1 MB (--task-memory); 500 states so far: shorten the horizon (--horizon), "
            "coarsen the model (exponent, action steps, decide_period) or raise --task-memory only if the machine has "
            "that much memory free") == row["error"], row


@pytest.mark.parametrize(("options", "seeds"), [
    ((("episodes", "20"), ("reward_function", "goal()")), "the seeds (--seed N runs one seed instead of 5)"),
    ((("episodes", "20"), ("seed", "4"), ("reward_function", "goal()")), None)])
def test_an_experiment_tasks_budget_refusal_advises_only_what_the_sweep_can_change(
        folder: Path, monkeypatch: pytest.MonkeyPatch, options: tuple[tuple[str, str], ...], seeds: str | None) -> None:
    """An experiment task refused by its memory budget advised lowering "the seeds or the combinations", rac
    experiment's --seeds and --combination: `rac sweep` has neither. It names --seed N (one seed) while the task
    runs five, nothing about the seeds when it runs one, and never the combinations."""
    from rac.sweep import work

    monkeypatch.setattr(work, "default_max_bytes", lambda: 1000)
    row = work.execute(spec(folder, "goal_ahead.xml", "experiment", options=options))
    error = str(row["error"])
    assert "more than the memory budget of 1000 B (--task-memory): lower the episodes per run (20, --episodes)" in error
    assert "combinations" not in error, row
    assert (seeds in error) if seeds else ("seed" not in error), row


def test_an_experiment_task_stopped_by_its_budget_is_undecided_not_failed(folder: Path,
                                                                         monkeypatch: pytest.MonkeyPatch) -> None:
    """Every ExperimentError made the row "failed" (exit 1, "with errors in the file"): a refusal by the memory
    budget too, which docs/sweep.md calls an undecided row (as a verify task's budget, exit 4), and a reward function
    that does not parse, which rac could not run (an error row, as rac experiment's exit 2 for both says)."""
    from rac.sweep import work

    monkeypatch.setattr(work, "default_max_bytes", lambda: 1000)
    options = (("seed", "1"), ("episodes", "20"), ("reward_function", "goal()"))
    row = work.execute(spec(folder, "goal_ahead.xml", "experiment", options=options))
    assert row["status"] == "undecided" and "more than the memory budget" in str(row["error"]), row
    monkeypatch.undo()
    row = work.execute(spec(folder, "goal_ahead.xml", "experiment", options=(("reward_function", "goal() +"),)))
    assert row["status"] == "error" and str(row["error"]).startswith("--reward-function:"), row


@pytest.mark.parametrize(("memory", "advice"), [(2**30, "raise --task-memory"), (None, "a lower --task-memory")])
def test_running_out_of_memory_before_the_budget_advises_what_helps_in_a_sweep(
        folder: Path, monkeypatch: pytest.MonkeyPatch, memory: int | None, advice: str) -> None:
    """A task that ran out of memory before its budget spoke advised "a lower --task-memory stops the exploration":
    rac verify's advice, where --max-memory is the budget alone; a sweep's --task-memory is the budget and the task's
    memory limit (RLIMIT_AS), so lowering it lowers both and stops no sooner. Without --task-memory the advice
    stands: the option then sets a budget below the machine's memory."""
    from rac.engine import shield
    from rac.sweep import work

    def exhausted(*args: object, **kwargs: object) -> object:
        raise MemoryError("Unable to allocate 80.0 MiB for an array with shape (10485241,) and data type int64")

    monkeypatch.setattr(shield, "synthesise", exhausted)
    row = work.execute(spec(folder, "goal_ahead.xml", "experiment", options=OPTIONS["experiment"], memory=memory))
    error = str(row["error"])
    assert "out of memory (Unable to allocate 80.0 MiB" in error and advice in error, row
    if memory is not None:
        assert "a lower --task-memory stops" not in error, row


@pytest.mark.parametrize("memory", [16, 64])
def test_a_small_task_memory_is_a_memory_row_not_a_numpy_import_error(folder: Path, memory: int) -> None:
    # numpy (its OpenBLAS), shapely and commonroad-io's reader were first imported under the limit: a task of
    # --task-memory 16M was an `error` row quoting numpy's "bad install" advice (a shared object it could not
    # map), one of 64M "the task's process exited with status 1: OpenBLAS error: Memory allocation still failed"
    row = run_task(spec(folder, "highway.xml", "check", memory=memory * 2**20, timeout=60))
    assert row["status"] in ("memory", "ok", "failed"), row
    assert "ImportError" not in str(row["error"]) and "exited with status" not in str(row["error"]), row["error"]


def test_the_summary_says_why_tasks_failed() -> None:
    """The "failed:" line said "2 failed, 1 error": the status alone, repeating the column above and not
    telling a query not satisfied from a file that does not check. It says why, in a fixed order."""
    from rac.sweep.report import render_summary, summarise

    def row(status: str, **verdicts: str) -> dict[str, object]:
        return {"status": status, "scenario": f"s{status}.xml", "settings": {}, "verdicts": verdicts, "error": "x"}

    # an experiment with no safe strategy from the start, on a file that checks (a warning only), was counted "with
    # errors in the file"
    unsafe = {**row("failed"), "diagnostics": ["W0728 the horizon runs past the recorded traffic"],
              "error": "no safe strategy exists from the start: the shielded combinations cannot run"}
    rows = [row("memory"), row("failed", Q="not satisfied", P="satisfied"),
            {**row("failed"), "diagnostics": ["E0714 the ego starts at 22 m/s"]}, row("timeout"),
            row("failed", Q="satisfied", P="not satisfied"), row("ok", Q="satisfied"),
            row("undecided", Q="unknown"), row("error"), unsafe]
    summary = summarise(rows, tasks=len(rows))
    assert summary.failed == 7
    assert summary.failures == {"not satisfied": 2, "file": 1, "run": 1, "error": 1, "timeout": 1, "memory": 1}
    assert render_summary(summary).splitlines()[2] == (
        "failed: 2 with a query not satisfied, 1 with errors in the file, 1 that failed when run (e.g. an experiment "
        "with no safe strategy), 1 that rac could not run, 1 timed out, 1 out of memory")
    assert summarise(rows[5:7], tasks=2).failures == {}
    assert "failed:" not in render_summary(summarise(rows[5:7], tasks=2))
