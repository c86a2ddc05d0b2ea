"""``rac experiment``: the paper's four combinations on a tiny scenario (rac.studies.experiment, rac.cli.main)."""

from __future__ import annotations

import argparse
import dataclasses
import json
from pathlib import Path

import numpy as np
import pytest
from engine_files import write_engine_file
from PIL import Image
from tiny_scenarios import goal_anywhere

from rac.cli.arguments import build_parser
from rac.cli.main import main
from rac.compiler import compile_file
from rac.studies.experiment import (
    COMBINATIONS,
    EXPLORE,
    ExperimentError,
    render_markdown,
    results_json,
    run_experiment,
    summary,
)

#: Episodes reach the goal region of `goal_ahead` by speeding up; the learning query's goal.
LEARN = {"safe": "strategy safe = control: A[] !collide() && !offroad()",
         "reach": "strategy reach = maxE(sa)[<=4]{Tiny.location}->{x, v}: <> goal() under safe"}
REWARD_FUNCTION = "10 * !near + 100 * goal()"


@pytest.fixture(scope="module")
def report(tmp_path_factory: pytest.TempPathFactory) -> dict[str, object]:
    folder = tmp_path_factory.mktemp("experiment")
    path = write_engine_file(folder, "avoidable_obstacle", LEARN)
    return run_experiment(compile_file(path), seeds=(1, 2), episodes=64, evaluation_runs=20,
                          reward_function=REWARD_FUNCTION, parallel=8)


def test_every_combination_runs_for_every_seed(report: dict[str, object]) -> None:
    records = report["records"]
    assert [(r.combination, r.seed) for r in records] == [(c, s) for c, _, _ in COMBINATIONS for s in (1, 2)]
    assert report["observation"] == {"discrete": ["Tiny.location", "time"], "continuous": ["x", "v"], "query": "reach"}
    assert report["shield_states"] > 0


def test_the_shield_keeps_learning_free_of_collisions(report: dict[str, object]) -> None:
    records = report["records"]
    for r in records:
        shielded = r.combination.startswith("SS&")
        if shielded:
            assert r.collisions_during_learning == 0 and r.offroad_during_learning == 0
        assert 1 <= r.episodes <= 64 and r.seconds > 0
        assert len(r.returns) == r.episodes == len(r.succeeded)
        assert 0 <= r.evaluation_successes <= r.evaluation_runs == 20
    unshielded = [r for r in records if not r.combination.startswith("SS&")]
    assert sum(r.collisions_during_learning + r.offroad_during_learning for r in unshielded) > 0


def test_the_table_reports_mean_and_spread(report: dict[str, object]) -> None:
    table = render_markdown(report)
    lines = table.splitlines()
    assert lines[0].startswith("| combination | learning time (s) |")
    assert [line.split(" | ")[0] for line in lines[2:6]] == ["| SS&RA", "| SS&RF", "| RA", "| RF"]
    assert "±" in lines[2]
    assert f"reward function `{REWARD_FUNCTION}`" in table
    rows = summary(report)
    assert [row["seeds"] for row in rows] == [2, 2, 2, 2]
    # only the query's observation is taken: said, with what is learned instead of its maxE(sa)[<=4]
    assert "{Tiny.location, time}->{x, v}" in table and "the lists of query `reach`, and only those" in table
    assert "`rac verify --query reach` answers it as written" in table


def test_the_shielded_rows_say_what_uniform_exploration_can_expect(report: dict[str, object]) -> None:
    optima = report["optima"]
    assert set(optima) == {"SS&RA", "SS&RF"}
    table = render_markdown(report)
    for label, optimum in optima.items():
        chance = optimum["uniform_success"]
        line = next(line for line in table.splitlines() if line.startswith(f"Exact optimum of {label} "))
        if chance == 0:  # the tiny road's goal lies behind the obstacle: no allowed run reaches it safely
            assert not optimum["reaches_goal_safely"]
            assert "under the shield no uniformly random episode reaches the goal safely" in line
        else:
            assert 0 < chance <= 1, optimum
            assert f"uniformly random episode reaches the goal safely with probability {100 * chance:.3g} %" in line
            assert f"{1 / chance:.3g} episodes on average until the first" in line


def test_a_goal_no_shielded_run_reaches_is_said_plainly(report: dict[str, object]) -> None:
    """On the tiny road the goal lies behind the obstacle: no run the shield allows reaches it safely, and
    the optimum's run does not. The note said only that no *uniformly random* episode does, "what a
    learner exploring at epsilon near 1 can expect", beside an optimum cell "4.0 (0 % below; 2 of 2 within
    5 %)", as if learning could do better and the optimum reached the goal (rac verify says both)."""
    table = render_markdown(report)
    for label, optimum in report["optima"].items():
        assert optimum["uniform_success"] == 0 and not optimum["reaches_goal_safely"]
        line = next(line for line in table.splitlines() if line.startswith(f"Exact optimum of {label} "))
        assert "a run that does not reach the goal safely" in line
        assert ("nor does any run the shield allows (exact, over all of them within the horizon): no episode "
                "can succeed, whatever the learner") in line
        assert "what a learner exploring at epsilon near 1 can expect" not in line


def test_a_goal_no_shielded_run_reaches_exits_1_with_the_table_written(tmp_path: Path,
                                                                        capsys: pytest.CaptureFixture[str]) -> None:
    """rac experiment exited 0 on the tiny road whose goal no run the shield allows reaches: a table every shielded
    row of which must fail read as a measurement. It is written all the same, and the exit status (1) and standard
    error say why, as for a file without a safe strategy."""
    path = write_engine_file(tmp_path, "avoidable_obstacle", LEARN)
    out = tmp_path / "out"
    code = main(["experiment", str(path), "--seeds", "1", "--episodes", "8", "--runs", "2", "--reward-function",
                 REWARD_FUNCTION, "--combination", "SS&RA", "--out", str(out), "-q"])
    captured = capsys.readouterr()
    assert code == 1, captured.err
    assert "| SS&RA |" in captured.out and (out / "results.json").exists() and (out / "experiment.md").exists()
    assert captured.err.startswith("rac experiment: no run the shield allows reaches the goal safely within the "
                                   "horizon (8 samples; exact, over all of them, the optimum of SS&RA): no episode "
                                   "of SS&RA can succeed, whatever the learner"), captured.err
    assert captured.err.rstrip().endswith("the results above are written all the same"), captured.err
    # a reachable goal still exits 0 (test_cli_writes_table_json_and_curves), and so does a table without a shield
    assert main(["experiment", str(path), "--seeds", "1", "--episodes", "8", "--runs", "2", "--reward-function",
                 REWARD_FUNCTION, "--combination", "RF", "--out", str(out), "-q"]) == 0


def test_cli_writes_table_json_and_curves(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = write_engine_file(tmp_path, "goal_ahead", LEARN)
    out = tmp_path / "out"
    code = main(["experiment", str(path), "--seeds", "1", "--episodes", "16", "--runs", "5", "--reward-function",
                 REWARD_FUNCTION, "--combination", "SS&RA", "--combination", "RF", "--out", str(out), "-q"])
    assert code == 0
    printed = capsys.readouterr().out
    assert "| SS&RA |" in printed and "| RF |" in printed and "| RA |" not in printed
    data = json.loads((out / "results.json").read_text())
    assert [run["combination"] for run in data["runs"]] == ["SS&RA", "RF"]
    assert "(computed once, used by SS&RA)." in printed  # it said "used by SS&RA and SS&RF"
    assert (out / "experiment.md").read_text().startswith("| combination |")
    for name in ("returns.png", "first_success.png"):
        with Image.open(out / name) as image:
            assert image.format == "PNG" and image.size[0] > 300


def test_the_default_reward_function_needs_the_papers_inputs(tmp_path: Path,
                                                             capsys: pytest.CaptureFixture[str]) -> None:
    path = write_engine_file(tmp_path, "goal_ahead", LEARN)
    with pytest.raises(ExperimentError, match="isClose, prog and comf"):
        run_experiment(compile_file(path), seeds=(1,), episodes=4)
    # an option to give or to change: a usage error (2), not a failure of the file (1)
    assert main(["experiment", str(path), "--seeds", "1", "--episodes", "4", "--out", str(tmp_path / "o")]) == 2
    assert "--reward-function" in capsys.readouterr().err
    assert main(["experiment", str(path), "--seeds", "x"]) == 2
    assert main(["experiment", str(path), "--reward-function", "10 *", "--out", str(tmp_path / "o")]) == 2


@pytest.mark.parametrize(("option", "value", "said"), [
    ("--bins", "1", "--bins: 2 positive widths, one per continuous observation (x, v), not 1"),
    ("--bins", "1,-2", "not 1,-2"),
    ("--bins", "nan,1", "not nan,1"),
    ("--bins", "", "--bins: not a list of numbers: ''"),  # it learned with the derived bins, without a word
    ("--reward-function", "foo", "--reward-function: `foo`: unknown name `foo`"),
])
def test_bad_bins_and_reward_functions_are_refused_before_anything_is_computed(
        tmp_path: Path, capsys: pytest.CaptureFixture[str], option: str, value: str, said: str) -> None:
    # they were internal errors: the bins met only by the learning, the reward function's names
    # only by the checker, after the shield and the optimum had been computed
    path = write_engine_file(tmp_path, "goal_ahead", LEARN)
    out = tmp_path / "o"
    assert main(["experiment", str(path), "--seeds", "1", "--episodes", "4", "--reward-function", REWARD_FUNCTION,
                 option, value, "--out", str(out)]) == 2  # an option to change: a usage error
    err = capsys.readouterr().err
    assert said in err and "internal error" not in err and "computing" not in err
    assert not out.exists()


@pytest.mark.filterwarnings("ignore::RuntimeWarning")  # numpy's, on dividing by zero
def test_a_reward_function_that_is_not_a_number_stops_learning_with_a_message(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    # a NaN reward poisoned the table and the greedy choice crashed (numpy: high <= 0): exit 3
    path = write_engine_file(tmp_path, "goal_ahead", LEARN)
    assert main(["experiment", str(path), "--seeds", "1", "--episodes", "4", "--runs", "2", "--reward-function",
                 "sqrt(-1 - v)", "--combination", "RF", "--out", str(tmp_path / "o"), "-q"]) == 1
    err = capsys.readouterr().err
    assert "not a finite number" in err and "`sqrt(-1 - v)`" in err and "internal error" not in err
    # a constant division by zero is refused before learning, as an option the command cannot use
    assert main(["experiment", str(path), "--seeds", "1", "--episodes", "4", "--reward-function", "0/0",
                 "--combination", "RF", "--out", str(tmp_path / "o"), "-q"]) == 2
    assert "error[E0014]: --reward-function: `0/0`: division by zero" in capsys.readouterr().err


def test_seed_is_one_seed_and_not_ignored(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """`rac experiment --seed 3` ran seeds 1..5 (its --seed was ignored next to --seeds, issue 12)."""
    path = write_engine_file(tmp_path, "goal_ahead", LEARN)
    out = tmp_path / "out"
    assert main(["experiment", str(path), "--seed", "3", "--episodes", "8", "--runs", "2", "--reward-function",
                 REWARD_FUNCTION, "--combination", "RF", "--out", str(out), "-q"]) == 0
    assert json.loads((out / "results.json").read_text())["seeds"] == [3]
    capsys.readouterr()
    assert main(["experiment", str(path), "--seed", "3", "--seeds", "1,2", "-q"]) == 2
    assert "not both" in capsys.readouterr().err


def test_the_learning_curves_say_mean_and_sd_once(report: dict[str, object], tmp_path: Path,
                                                  monkeypatch: pytest.MonkeyPatch) -> None:
    """The review read "(mean ± sd over seeds)" twice in the title of returns.png."""
    import rac.output.plots as plots
    from rac.studies.experiment import write_outputs

    figures = []
    monkeypatch.setattr(plots, "save_figure", lambda figure, path, **options: figures.append(figure) or Path(path))
    write_outputs(report, tmp_path)
    title = figures[0].get_suptitle()
    assert title.count("over seeds") == 1 and "mean ± sd" in title and "10-episode moving average" in title
    styles = [(line.get_linestyle(), line.get_marker()) for ax in figures[0].axes for line in ax.get_lines()]
    assert len(set(styles)) == len(styles) == 4


def test_each_combination_has_its_own_returns_panel(report: dict[str, object], tmp_path: Path,
                                                    monkeypatch: pytest.MonkeyPatch) -> None:
    """returns.png drew the four combinations on one axes: RA's returns (about -12,000 on examples/paper)
    squashed SS&RA's and SS&RF's into flat lines near 0. Each combination has a panel of its own now, on a
    shared episode axis, each with its own value range."""
    import rac.output.plots as plots
    from rac.studies.experiment import write_outputs

    figures = []
    monkeypatch.setattr(plots, "save_figure", lambda figure, path, **options: figures.append(figure) or Path(path))
    records = report["records"]
    assert isinstance(records, list)
    scale = {"RA": -12_000.0, "RF": 50.0, "SS&RA": -300.0, "SS&RF": 1.0}  # returns of very different sizes
    report = {**report, "records": [dataclasses.replace(r, returns=np.linspace(0, 1, 30) * scale[r.combination])
                                    for r in records]}
    write_outputs(report, tmp_path)
    panels = figures[0].axes
    assert [ax.get_title(loc="left").split(" (")[0] for ax in panels] == ["SS&RA", "SS&RF", "RA", "RF"]
    for ax in panels:
        low, high = ax.get_ylim()
        (line,) = ax.get_lines()
        values = line.get_ydata()
        assert low <= min(values) and max(values) <= high
        assert high - low < 2 * (max(values) - min(values))  # each panel scaled to its own curve
        assert ax.get_shared_x_axes().joined(ax, panels[0])


def test_the_ablation_learns_every_row(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = write_engine_file(tmp_path, "goal_ahead", LEARN)
    out = tmp_path / "out"
    code = main(["experiment", str(path), "--seeds", "1", "--episodes", "16", "--runs", "5", "--reward-function",
                 REWARD_FUNCTION, "--combination", "SS&RA", "--ablation", "--out", str(out), "-q"])
    assert code == 0
    printed = capsys.readouterr().out
    assert "(derived from the model's action grid and goal)" in printed
    assert "| SS&RA |" in printed and printed.splitlines()[2].endswith("| yes |")  # counterfactuals
    ablation = (out / "ablation.md").read_text().splitlines()
    assert [line.split(" | ")[0] for line in ablation[2:10]] == [
        "| as the experiment", "| other bins", "| counterfactuals switched", "| replay switched",
        "| all three switched", "| time not observed", "| untried actions at 0", "| best episode not replayed"]
    data = json.loads((out / "results.json").read_text())
    assert [len(variant["records"]) for variant in data["ablation"]] == [1] * 8
    assert [variant["counterfactuals"] for variant in data["ablation"]] == [True, True, False, True, False, True, True,
                                                                           True]
    assert [variant["time"] for variant in data["ablation"]] == [True] * 5 + [False, True, True]
    assert [variant["pessimistic"] for variant in data["ablation"]] == [True] * 6 + [False, True]
    # the earlier learner has no best-episode replay; the last row switches it off alone
    assert [variant["replay_best"] for variant in data["ablation"]] == [True] * 6 + [False, False]
    assert ablation[9].split(" | ")[6] == "no" and ablation[2].split(" | ")[6] == "yes"
    assert data["observation"]["discrete"][-1] == "time" and data["learner"]["alpha"] == 1.0


def test_a_shield_beyond_the_state_budget_is_a_resource_limit(tmp_path: Path,
                                                               capsys: pytest.CaptureFixture[str]) -> None:
    # it exited 1, as if the file had failed; simulate and render say a resource limit with 2
    path = write_engine_file(tmp_path, "goal_ahead", LEARN)
    assert main(["experiment", str(path), "--seeds", "1", "--episodes", "4", "--reward-function", REWARD_FUNCTION,
                 "--max-states", "10", "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err
    assert "error[E0016]: resource limit: the safety shield cannot be computed" in err
    # and what to raise: it named only what to coarsen ("coarsen the model (actions, decide_period) or shorten the
    # horizon"), not the option that stopped it
    assert "or raise --max-states if the machine has the memory" in " ".join(err.split()), err


def test_a_shield_out_of_the_process_memory_says_which_limit(tmp_path: Path, capsys: pytest.CaptureFixture[str],
                                                             monkeypatch: pytest.MonkeyPatch) -> None:
    # under `prlimit --as=4G` with --max-memory 100G the shield's exploration ran out of the process's memory
    # first, and the error said only numpy's "Unable to allocate 80.0 MiB ...; coarsen the model": no word
    # of the process's limit, nor of the lower --max-memory that stops rac within it
    from rac.engine import shield

    def exhausted(*args: object, **kwargs: object) -> object:
        raise MemoryError("Unable to allocate 80.0 MiB for an array with shape (10485241,) and data type int64")

    monkeypatch.setattr(shield, "synthesise", exhausted)
    path = write_engine_file(tmp_path, "goal_ahead", LEARN)
    assert main(["experiment", str(path), "--seeds", "1", "--episodes", "4", "--reward-function", REWARD_FUNCTION,
                 "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err
    assert ("error[E0016]: resource limit: the safety shield cannot be computed: out of memory (Unable to "
            "allocate") in err
    assert "more memory than this process may use" in err and "a lower --max-memory" in err


# SIGTERM (`timeout`, a batch system's limit): its handler's KeyboardInterrupt came in the middle of a learning
# step, which run_together did not defer as it defers Ctrl-C: "rac: terminated (SIGTERM)" and nothing kept
@pytest.mark.parametrize(("stop", "status"), [("SIGINT", 130), ("SIGTERM", 143)])
def test_ctrl_c_while_learning_keeps_what_was_learned(tmp_path: Path, stop: str, status: int) -> None:
    """Ctrl-C (or SIGTERM) during the learning: every run's best evaluated strategy is shown and written
    (the table, results.json with "interrupted"), the note says so, and the exit code is 130 (143)."""
    import os
    import signal
    import subprocess
    import sys
    import threading
    import time

    repository = Path(__file__).resolve().parents[2]
    command = [sys.executable, "-m", "rac", "experiment", str(repository / "examples" / "paper" / "model.ra"),
               "--episodes", "100000", "--seeds", "1", "--runs", "5", "-o", str(tmp_path / "out")]
    child = subprocess.Popen(command, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                             env=dict(os.environ, PYTHONUNBUFFERED="1", RAC_PROGRESS_INTERVAL="0.5"))
    assert child.stderr is not None
    seen = ""
    while "runs together" not in seen:  # the learning has begun: the heartbeat (off a terminal) says so
        line = child.stderr.readline()
        assert line, f"the experiment ended before learning: {seen}"
        seen += line
    time.sleep(3.0)  # a few batches learned and evaluated
    rest: list[str] = []
    reader = threading.Thread(target=lambda: rest.append(child.stderr.read() if child.stderr else ""), daemon=True)
    reader.start()  # the heartbeat goes on: its pipe is read to the end
    child.send_signal(getattr(signal, stop))
    try:
        out = child.stdout.read() if child.stdout is not None else ""
        child.wait(timeout=120)
    finally:
        child.kill()
    reader.join(timeout=10)
    assert child.returncode == status, out
    # the note said "Interrupted (Ctrl-C)" after SIGTERM too
    said = "Interrupted (Ctrl-C)" if stop == "SIGINT" else "Terminated (SIGTERM)"
    assert f"{said} while learning" in out and "| SS&RA |" in out
    assert f"{said} while learning" in (tmp_path / "out" / "experiment.md").read_text(encoding="utf-8")
    assert rest and "Traceback" not in seen + rest[0]
    results = json.loads((tmp_path / "out" / "results.json").read_text(encoding="utf-8"))
    assert results["interrupted"] == "learning"
    assert all(0 < run["episodes"] < 100_000 and run["evaluation_runs"] == 0 for run in results["runs"])


@pytest.mark.parametrize(("observation", "column", "said"), [
    ("{}->{x}", 5, "add `Tiny.location` to its discrete list, or pass --no-counterfactuals"),
    ("{near}->{x}", 5, "add `Tiny.location` to its discrete list"),
    ("{Tiny.location}->{sa, x}", 66, "leave `sa` out of its lists"),
])
def test_an_observation_counterfactuals_cannot_use_is_the_querys_fault_said_at_once(
        tmp_path: Path, capsys: pytest.CaptureFixture[str], observation: str, column: int, said: str) -> None:
    """The RA combinations learn from counterfactual experiences, which need the automaton's location
    among the query's discrete observations. A query without it went through the shield and the optimum,
    then stopped with "learning stopped: ... (the reward function `...` or the automaton's objective)",
    blaming the reward, with no line of the file and no way out."""
    path = write_engine_file(tmp_path, "goal_ahead", {
        "safe": LEARN["safe"], "reach": f"strategy reach = maxE(sa)[<=4]{observation}: <> goal() under safe"})
    out = tmp_path / "o"
    assert main(["experiment", str(path), "--seeds", "1", "--episodes", "4", "--runs", "2", "--reward-function",
                 REWARD_FUNCTION, "--out", str(out)]) == 1
    err = capsys.readouterr().err
    assert f"{path.name}:" in err and f":{column}: error[E0015]: the observation of query `reach`" in err
    assert said in err and "reward function" not in err and "computing" not in err
    assert not out.exists()
    # without counterfactual experiences (or with the reward function's combinations alone) it learns
    assert main(["experiment", str(path), "--seeds", "1", "--episodes", "4", "--runs", "2", "--reward-function",
                 REWARD_FUNCTION, "--no-counterfactuals", "--combination", "SS&RA", "--out", str(out), "-q"]) == 0


def test_the_ablation_is_measured_against_the_optimum_whichever_combinations_the_table_shows(
        tmp_path: Path) -> None:
    """--ablation learns SS&RA's variants; with --combination RF the SS&RA optimum was not computed, so
    every ablation row said "—" for "within 5 % of the optimum" and results.json had no optimum for them."""
    path = write_engine_file(tmp_path, "goal_ahead", LEARN)
    out = tmp_path / "out"
    assert main(["experiment", str(path), "--seeds", "1", "--episodes", "4", "--runs", "2", "--reward-function",
                 REWARD_FUNCTION, "--combination", "RF", "--ablation", "--out", str(out), "-q"]) == 0
    data = json.loads((out / "results.json").read_text())
    assert [run["combination"] for run in data["runs"]] == ["RF"] and data["runs"][0]["optimum"] is None
    assert "(computed once, used only to judge whether a run can stay safe from the goal to the horizon)." in \
        (out / "experiment.md").read_text()
    optimum = data["optima"]["SS&RA"]["value"]
    assert all(r["optimum"] == optimum for variant in data["ablation"] for r in variant["records"])
    rows = (out / "ablation.md").read_text().splitlines()[2:10]
    assert all(row.endswith(" of 1 seeds |") for row in rows), rows


def test_a_reward_function_that_is_not_a_number_is_said_without_numpys_warnings(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """The shielded combinations' exact optimum is computed before learning: a reward function that
    divides by zero (`1 / near`, near false: its increase inf - inf) was summed into the backward pass, and numpy's
    RuntimeWarnings ("invalid value encountered in subtract", in optimum.py, qlearning.py, _methods.py)
    came before the message; the optimum's search now refuses the step as learning does."""
    import warnings

    path = write_engine_file(tmp_path, "goal_ahead", LEARN)
    with warnings.catch_warnings():
        warnings.simplefilter("error", RuntimeWarning)
        assert main(["experiment", str(path), "--seeds", "1", "--episodes", "4", "--runs", "2", "--reward-function",
                     "1 / near", "--combination", "SS&RF", "--out", str(tmp_path / "o"), "-q"]) == 1
    err = capsys.readouterr().err
    assert err.startswith("error[E0015]: learning stopped: a step's reward is nan, not a finite number"), err
    assert "Warning" not in err


def test_the_evaluation_runs_are_held_to_the_memory_budget_before_anything_is_computed(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """--max-memory bounded the learning only: `--runs 3000000` learned, then evaluated every strategy's
    runs together until an allocation failed ("out of memory ... lower --max-memory so that rac stops
    before it", which it did not), or the machine ran out of memory."""
    path = write_engine_file(tmp_path, "goal_ahead", LEARN)
    out = tmp_path / "o"
    assert main(["experiment", str(path), "--seeds", "1", "--episodes", "4", "--runs", "100000", "--max-memory",
                 "400M", "--reward-function", REWARD_FUNCTION, "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert "error[E0016]: resource limit: evaluating 4 strategies over 100,000 runs each together would need" in err
    assert "lower the evaluation runs (100,000, --runs)" in err and "computing" not in err
    assert not out.exists()


def test_a_folder_in_the_way_of_an_output_leaves_the_others_as_they_were(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """A folder named returns.png in the output folder: experiment.md and results.json were replaced
    before the plot failed, beside the previous run's first_success.png, under "nothing was written"."""
    path = write_engine_file(tmp_path, "goal_ahead", LEARN)
    out = tmp_path / "out"
    (out / "returns.png").mkdir(parents=True)
    assert main(["experiment", str(path), "--seeds", "1", "--episodes", "2", "--runs", "1", "--reward-function",
                 REWARD_FUNCTION, "--combination", "RF", "--out", str(out), "-q"]) == 2
    err = capsys.readouterr().err
    assert f"error[E0009]: cannot write `{out / 'returns.png'}`" in err and "nothing was written" in err
    assert sorted(p.name for p in out.iterdir()) == ["returns.png"]


def test_an_interrupted_run_is_said_to_show_the_best_strategy_it_evaluated(report: dict[str, object]) -> None:
    """Every combination keeps its best evaluated strategy (LEARNER: learning to the budget), also when
    Ctrl-C stops it; the note said "the strategy of its last evaluation", which may be a worse one."""
    note = next(line for line in render_markdown(dict(report, interrupted="learning")).splitlines()
                if line.startswith("Interrupted (Ctrl-C) while learning"))
    assert "each run shows the best strategy it had evaluated" in note and "last evaluation" not in note


def test_two_experiments_writing_one_folder_both_finish(report: dict[str, object], tmp_path: Path,
                                                       monkeypatch: pytest.MonkeyPatch) -> None:
    """experiment.md and results.json went through one temporary name each (`NAME.partial`): a second
    `rac experiment` into the same folder truncated and renamed the first's, which then failed with
    FileNotFoundError (an internal error) and could leave the second's file overwritten in part."""
    import os

    from rac.studies.experiment import write_outputs

    real, calls = os.replace, []

    def replace(source: object, target: object) -> None:
        if not calls:  # the first rename of the first writer: the second runs to its end before it
            calls.append(source)
            write_outputs(report, tmp_path)
        real(source, target)  # type: ignore[arg-type]

    monkeypatch.setattr(os, "replace", replace)
    write_outputs(report, tmp_path)
    assert json.loads((tmp_path / "results.json").read_text(encoding="utf-8"))["seeds"] == [1, 2]
    assert (tmp_path / "experiment.md").read_text(encoding="utf-8") == render_markdown(report) + "\n"
    assert not [p.name for p in tmp_path.iterdir() if p.name.startswith(".") or p.suffix in (".partial", ".tmp")]


@pytest.mark.parametrize("form", ["text", "json"])
def test_a_full_disk_at_the_plots_still_shows_what_was_learned(tmp_path: Path, capsys: pytest.CaptureFixture[str],
                                                               monkeypatch: pytest.MonkeyPatch, form: str) -> None:
    """The learning (minutes to hours) is done when the outputs are written: a full disk there printed only
    E0009 and the table and the results were never shown."""
    import errno

    import rac.output.plots as plots

    out = tmp_path / "out"

    def full(figure: object, path: object, **options: object) -> Path:
        raise OSError(errno.ENOSPC, "No space left on device", str(path))

    monkeypatch.setattr(plots, "save_figure", full)
    path = write_engine_file(tmp_path, "goal_ahead", LEARN)
    code = main(["experiment", str(path), "--seeds", "1", "--episodes", "8", "--runs", "2", "--reward-function",
                 REWARD_FUNCTION, "--combination", "RF", "--out", str(out), "-q", "--format", form])
    assert code == 2
    printed, err = capsys.readouterr()
    if form == "json":
        document = json.loads(printed)  # one document: the results, and the error in it
        assert [run["combination"] for run in document["runs"]] == ["RF"] and document["error"]["code"] == "E0009"
    else:
        assert "| RF |" in printed
        assert f"error[E0009]: cannot write `{out / 'returns.png'}`: No space left on device" in err
    assert "the results above were not all written" in err


def test_results_json_is_strict_json_whatever_the_file_name() -> None:
    """Regression: results.json (and `rac experiment --format json`) wrote a file name's undecodable byte
    as the lone surrogate `\\udce9`, which strict JSON readers (jq, serde) refuse; every string is now shown
    as the other commands' JSON shows it (`\\xe9`)."""
    text = results_json({"file": "caf\udce9.ra", "records": [], "reward_function": "10 * !isClose"})
    assert "udce9" not in text and json.loads(text)["file"] == "caf\\xe9.ra"
    text.encode("utf-8")  # strict UTF-8: no lone surrogate


@pytest.mark.parametrize("form", ["text", "json"])
def test_ctrl_c_while_writing_keeps_the_previous_files_and_shows_what_was_learned(
        tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch, form: str) -> None:
    """experiment.md and results.json were renamed into place before the plots were drawn (seconds): Ctrl-C there
    left the new table beside the previous run's plots, printed a bare "rac: interrupted" and dropped what was
    learned."""
    import rac.output.plots as plots

    path = write_engine_file(tmp_path, "goal_ahead", LEARN)
    out = tmp_path / "out"
    args = ["experiment", str(path), "--episodes", "8", "--runs", "2", "--reward-function", REWARD_FUNCTION,
            "--combination", "RF", "--out", str(out), "-q"]
    assert main([*args, "--seeds", "1"]) == 0
    before = {p.name: p.read_bytes() for p in out.iterdir()}
    assert sorted(before) == ["experiment.md", "first_success.png", "results.json", "returns.png"]
    capsys.readouterr()

    def stopped(figure: object, path: object, **options: object) -> Path:
        raise KeyboardInterrupt

    monkeypatch.setattr(plots, "save_figure", stopped)
    assert main([*args, "--seeds", "2", "--format", form]) == 130
    assert {p.name: p.read_bytes() for p in out.iterdir()} == before  # no new file beside an old one, no temporary
    printed, err = capsys.readouterr()
    assert f"rac experiment: interrupted while writing the results above; none of the files in {out} changed" in err
    if form == "json":
        document = json.loads(printed)
        assert document["seeds"] == [2] and document["interrupted"] == "writing"
    else:
        assert "| RF |" in printed


def test_json_keeps_the_files_warnings_and_names_the_files_written(tmp_path: Path,
                                                                  capsys: pytest.CaptureFixture[str]) -> None:
    """Regression: `rac experiment --format json` printed results.json alone: the file's warnings, which text prints
    on standard error and JSON leaves out of it, were nowhere (simulate, render, verify have them in the
    document's `warnings`), nor the files written (text's `wrote PATH` lines; simulate's `wrote`)."""
    path = write_engine_file(tmp_path, "goal_ahead", LEARN)
    text = path.read_text(encoding="utf-8")
    path.write_text(text.replace("    input near : bool", "    input unused : bool\n    input near : bool").replace(
        "        bind near =", "        bind unused = mindist() < 1\n        bind near ="), encoding="utf-8")
    out = tmp_path / "out"
    args = ["experiment", str(path), "--episodes", "4", "--runs", "2", "--reward-function", REWARD_FUNCTION,
            "--combination", "RF", "--seeds", "1", "--out", str(out), "-q"]
    assert main(args) == 0
    assert "warning[W0303]: input `unused` is never used" in capsys.readouterr().err
    assert main([*args, "--format", "json"]) == 0
    printed, err = capsys.readouterr()
    document = json.loads(printed)
    assert "W0303" not in err
    assert [(w["code"], w["span"]["line"]) for w in document["warnings"]] == [("W0303", 3)]
    assert document["wrote"] == [str(out / name) for name in
                                 ("experiment.md", "results.json", "returns.png", "first_success.png")]
    assert document["ok"] is True  # exit 0 (every command's document has it)
    # the rest is results.json as written
    written = json.loads((out / "results.json").read_text(encoding="utf-8"))
    assert {k: v for k, v in document.items() if k not in ("warnings", "wrote", "ok")} == written


def test_the_shields_exploration_counts_its_states(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """rac experiment's shield exploration (minutes on a big scene) showed its phase and no count: no bar on a
    terminal, and off one the heartbeat's lines said no states and no rate, as rac verify's explorations do."""
    from rac.output.progress import Heartbeat

    heard: list[tuple[str, object]] = []
    monkeypatch.setattr(Heartbeat, "phase", lambda self, text: heard.append(("phase", text)))
    monkeypatch.setattr(Heartbeat, "count", lambda self, n, unit, what="": heard.append((unit, n)))
    path = write_engine_file(tmp_path, "goal_ahead", LEARN)
    assert main(["experiment", str(path), "--seeds", "1", "--episodes", "4", "--runs", "2", "--reward-function",
                 REWARD_FUNCTION, "--combination", "SS&RA", "--out", str(tmp_path / "out")]) == 0
    start = heard.index(("phase", "computing the safety shield"))
    end = next(i for i in range(start + 1, len(heard)) if heard[i][0] == "phase")
    states = [n for unit, n in heard[start:end] if unit == "states"]
    assert len(states) > 1 and states == sorted(states) and states[-1] > 1, heard


def test_explore_goal_steers_every_combination_and_says_so(tmp_path: Path,
                                                          capsys: pytest.CaptureFixture[str]) -> None:
    """``--explore goal``: the table's notes say how the episodes explored, what such an episode can expect
    (exact, beside the uniform one) and the model steps the lookahead took; results.json keeps it all."""
    path = write_engine_file(tmp_path, "goal_ahead", LEARN)
    out = tmp_path / "out"
    code = main(["experiment", str(path), "--seeds", "1", "--episodes", "16", "--runs", "5", "--reward-function",
                 REWARD_FUNCTION, "--explore", "goal", "--out", str(out), "-q"])
    assert code == 0
    printed = capsys.readouterr().out
    assert "exploring choices (--explore goal) half towards the goal" in printed
    assert "an episode exploring as --explore does reaches it safely with probability" in printed
    assert "to look one decision ahead for the exploring choices (--explore)" in printed
    data = json.loads((out / "results.json").read_text())
    assert data["explore"] == "goal" and data["model_steps"]["ahead"] > 0
    for label in ("SS&RA", "SS&RF"):
        assert 0 < data["optima"][label]["uniform_success"] < data["optima"][label]["steered_success"] <= 1
    # the default explores uniformly, and says so; it looks nothing up ahead
    default = run_experiment(compile_file(path), seeds=(1,), episodes=16, evaluation_runs=5,
                             reward_function=REWARD_FUNCTION, combinations=["SS&RA"])
    assert default["explore"] == "uniform" and default["model_steps"]["ahead"] == 0
    assert "steered_success" not in default["optima"]["SS&RA"]
    assert "exploring choices uniform among the allowed actions" in render_markdown(default)


def test_explore_goal_is_refused_for_a_goal_without_a_position(tmp_path: Path,
                                                             capsys: pytest.CaptureFixture[str]) -> None:
    """A goal of time alone has no distance to head for (``dist_goal()`` reads 0): refused before anything
    is computed, as an option to change (exit 2)."""
    path = write_engine_file(tmp_path, "goal_ahead", LEARN)
    (tmp_path / "goal_ahead.xml").write_bytes(goal_anywhere())
    code = main(["experiment", str(path), "--seeds", "1", "--episodes", "4", "--reward-function", REWARD_FUNCTION,
                 "--explore", "goal", "--out", str(tmp_path / "out"), "-q"])
    assert code == 2
    err = capsys.readouterr().err
    assert "--explore goal: the goal has no position" in err and "explore uniformly" in err
    assert not (tmp_path / "out").exists()


def test_the_command_lines_explore_choices_are_the_experiments() -> None:
    """``rac experiment --explore`` and ``rac sweep --explore`` offer exactly :data:`EXPLORE`'s names (the
    parser does not import the experiment, which loads numpy)."""
    parser = build_parser()
    commands = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    for name in ("experiment", "sweep"):
        option = next(a for a in commands.choices[name]._actions if "--explore" in a.option_strings)
        assert tuple(option.choices) == tuple(EXPLORE), name
