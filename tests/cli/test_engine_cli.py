"""End to end: ``rac verify``, ``rac simulate``, ``rac render`` and ``rac preanalyse`` through
:func:`rac.cli.main`, on the tiny scenarios of :mod:`tiny_scenarios` (tests/support/engine_files.py).

Exit codes: 0 when everything asked holds, 1 when a query is not satisfied or the file has errors or
no ``model`` block, 2 for bad usage and unreadable files, 4 when a query was not decided (*unknown*).
"""

from __future__ import annotations

import csv
import json
import re
import textwrap
from pathlib import Path

import pytest
from engine_files import QUERIES, TEMPLATE, write_engine_file
from PIL import Image
from tiny_scenarios import Block, GoalBox, StraightRoad, TinySettings

from rac.cli.common import EXIT_ERRORS, EXIT_INTERNAL, EXIT_INTERRUPTED, EXIT_OK, EXIT_UNDECIDED, EXIT_USAGE
from rac.cli.main import main
from rac.engine import shield
from rac.model.commonroad import EgoStart

#: The engine's timings vary: ``0.03 s`` becomes ``T s`` before texts are compared.
SECONDS = re.compile(r"\b\d+\.\d\d s\b")


def normalised(text: str) -> str:
    """``text`` with every timing replaced by ``T s``."""
    return SECONDS.sub("T s", text)


def line_of(path: Path, name: str) -> int:
    """The line of ``query NAME:`` in ``path`` (1-based)."""
    lines = path.read_text(encoding="utf-8").splitlines()
    return next(i for i, line in enumerate(lines, 1) if line.strip().startswith(f"query {name}:"))


def csv_rows(path: Path) -> list[list[str]]:
    with path.open(newline="", encoding="utf-8") as handle:
        return list(csv.reader(handle))


def image_size(path: Path) -> tuple[int, int]:
    """The size of a PNG, after checking that PIL reads it as one."""
    with Image.open(path) as image:
        assert image.format == "PNG"
        image.verify()
        return image.size


# ---------------------------------------------------------------- verify
def test_verify_past_max_seconds_is_undecided(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    """`rac verify --max-seconds S`: a query given up is UNKNOWN (exit 4, never 0), and so is the penalty check
    after the queries, each saying the limit stopped it."""
    path = write_engine_file(tmp_path, "avoidable_obstacle", {"Explore": "E<> goal() && v > 100"})
    assert main(["verify", str(path), "--max-seconds", "1e-9", "--out", str(tmp_path / "out")]) == 4
    out = capsys.readouterr().out
    assert " -- Formula is UNKNOWN: query Explore: given up after " in out
    assert " -- not checked: the penalty check: given up after " in out and out.count("(--max-seconds)") == 2


def test_verify_not_satisfied_exits_1(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    path = write_engine_file(tmp_path, "narrow_road")
    out = tmp_path / "out"
    assert main(["verify", str(path), "--query", "Stays", "--query", "safe", "--out", str(out)]) == 1
    captured = capsys.readouterr()
    assert normalised(captured.out) == f"""\
Verifying Stays: E[] !collide() && !offroad()  ({path}:{line_of(path, "Stays")})
 -- Formula is NOT satisfied.
    1 state, horizon 8 samples, T s
    decided in the initial state, where every run begins
    `!collide() && !offroad()` fails at t = 0
Verifying safe: strategy safe = control: A[] !collide() && !offroad()  ({path}:{line_of(path, "safe")})
 -- Formula is NOT satisfied.
    1 state, horizon 8 samples, T s
    decided on the complete graph up to the horizon
    no strategy keeps `!collide() && !offroad()` from the start: it is false at the start
"""
    # rac check's warning about the file comes first: it says why the query fails
    assert captured.err.startswith(f"{path}:18:9: warning[W0716]: the ego starts off the road")
    assert captured.err.count("warning[") == 1
    assert not (out / "safe.shield.npz").exists()  # no strategy, no file (UPPAAL defines none either)


def test_verify_shield_in_the_default_folder_exits_0(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    path = write_engine_file(tmp_path, "goal_ahead")
    assert main(["verify", str(path), "--query", "Shielded"]) == 0  # pulls in `safe`, which it is under
    out = capsys.readouterr().out
    saved = tmp_path / "goal_ahead.out" / "verify" / "safe.shield.npz"
    assert f"    wrote {saved}\n" in out
    assert out.index("Verifying safe:") < out.index("Verifying Shielded:")
    assert out.count(" -- Formula is satisfied.") == 2
    table = shield.load(saved)
    assert table.columns == ("k", "x", "y", "v", "acc", "head", "jerk", "turn")
    start = [0, 1000, 175, 800, 0, 0, 0, 0]  # x = 10, y = 1.75, v = 8 at exponent 2
    assert table.knows(start) and table.allowed(start).size == 3  # every jerk, straight on


def test_verify_literal_qc_mentions_the_collision(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    path = write_engine_file(tmp_path, "goal_behind_wall")
    assert main(["verify", str(path), "--standard", "--query", "Qb", "--query", "Qc", "--out",
                 str(tmp_path / "out")]) == 0
    out = capsys.readouterr().out
    assert out.startswith("Verifying Qb: E[] !collide() && !offroad()\n    (a run that is never unsafe exists)\n"
                          " -- Formula is satisfied.\n")
    assert "Verifying Qc: E<> !collide() && !offroad() && goal()\n    (a safe state in the goal is reachable)\n" in out
    assert ("    the trace passes through unsafe states (a collision does not end a run); "
            "NO run that stays safe until it gets there exists\n") in out
    assert "[collide]" in out


def test_verify_trace_option_prints_every_state(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    path = write_engine_file(tmp_path, "goal_ahead", {"Reaches": QUERIES["Reaches"]})
    assert main(["verify", str(path), "--out", str(tmp_path / "o")]) == 0
    short = capsys.readouterr().out
    assert "trace (9 states, first and last 3; --trace shows all):" in short
    assert short.count("\n      t=") == 6
    assert main(["verify", str(path), "--trace", "--out", str(tmp_path / "o")]) == 0
    rows = [line.strip() for line in capsys.readouterr().out.splitlines() if line.startswith("      t=")]
    assert [row.split()[0] for row in rows] == [f"t={k * 0.5:g}s" for k in range(9)]
    assert rows[0] == "t=0s x=10 y=1.75 v=8 acc=0 head=0 jerk=0 turn=0"
    assert rows[-1].endswith("[goal]")


def test_verify_unknown_query_exits_2(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    path = write_engine_file(tmp_path, "goal_ahead", {"Stays": QUERIES["Stays"], "Sim": QUERIES["Sim"]})
    assert main(["verify", str(path), "--query", "Stays", "--query", "Nope"]) == 2
    captured = capsys.readouterr()
    assert captured.out == ""
    assert captured.err == (f"error[E0014]: --query: no query named Nope in {path}\n"
                            " = note: its queries: Stays, Sim; --standard adds Qa, Qb, Qc, Qd, Fig7, Fig7_safe, "
                            "Unsafe_safe\n")
    assert not (tmp_path / "goal_ahead.out").exists()


def test_verify_state_budget_is_unknown_with_a_hint(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    path = write_engine_file(tmp_path, "goal_ahead")  # `-->` needs the whole model
    assert main(["verify", str(path), "--query", "LeadsTo", "--query", "Somewhere", "--max-states", "10"]) == 4
    out = normalised(capsys.readouterr().out)
    assert out == f"""\
Verifying Somewhere: E<> Close  ({path}:{line_of(path, "Somewhere")})
 -- Formula is UNKNOWN: the product of model and automaton has more than 10 states by t = 0.5 s (sample 1): \
shorten the horizon (--horizon), coarsen the model (exponent, action steps, decide_period) or raise --max-states \
if the machine has the memory (the automaton alone does not decide it: a run of the automaton reaches `Close` \
with inputs near=true)
    T s
Verifying LeadsTo: goal() --> goal()  ({path}:{line_of(path, "LeadsTo")})
 -- Formula is UNKNOWN: the model has more than 10 states by t = 1 s (sample 2); growing ×9 per decision, the \
horizon (sample 8) would have about 1.5e+04 states: shorten the horizon (--horizon), coarsen the model (exponent, \
action steps, decide_period) or raise --max-states if the machine has the memory
    T s
"""


def test_verify_json_has_the_fields_and_repeats_with_the_seed(capsys: pytest.CaptureFixture[str],
                                                              tmp_path: Path) -> None:
    path = write_engine_file(tmp_path, "avoidable_obstacle")
    out = tmp_path / "out"
    args = ["verify", str(path), "--format", "json", "--seed", "11", "--out", str(out), "--query", "Stays",
            "--query", "ProbRuns", "--query", "Certain", "--query", "Speed", "--query", "Sim"]
    assert main(args) == 0
    captured = capsys.readouterr()
    assert captured.err == ""
    report = json.loads(captured.out)
    assert report["file"] == str(path)
    results = {r["name"]: r for r in report["results"]}
    assert list(results) == ["Stays", "ProbRuns", "Certain", "Speed", "Sim"]
    for r in results.values():
        assert {"name", "formula", "kind", "status", "interval", "estimate", "runs", "seconds", "trace",
                "files", "message", "seed", "location"} <= set(r)
        assert r["location"]["file"] == str(path)
    assert results["Stays"]["status"] == "satisfied" and len(results["Stays"]["trace"]) == 9
    assert results["ProbRuns"]["kind"] == "probability" and results["ProbRuns"]["runs"] == 30
    assert results["Certain"]["status"] == "satisfied"
    assert results["Speed"]["runs"] == 20 and 5 <= results["Speed"]["estimate"] <= 10
    assert results["Sim"]["files"] == [str(out / "Sim.csv"), str(out / "Sim.png")]
    assert len(csv_rows(out / "Sim.csv")) == 1 + 4 * 5
    width, height = image_size(out / "Sim.png")
    assert width > 100 and height > 100

    def numbers(report: dict) -> list[dict]:
        return [{k: v for k, v in r.items() if k != "seconds"} for r in report["results"]]

    assert main(args) == 0
    assert numbers(json.loads(capsys.readouterr().out)) == numbers(report)


def test_verify_statistical_verdicts_and_exit_code(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    path = write_engine_file(tmp_path, "goal_ahead", {"Certain": QUERIES["Certain"],
                                                      "Impossible": QUERIES["Impossible"]})
    assert main(["verify", str(path), "--seed", "1"]) == 1  # Impossible is not satisfied
    out = normalised(capsys.readouterr().out)
    certain, impossible = out.split("Verifying Impossible")
    assert " -- Formula is satisfied.\n" in certain and " satisfied the formula\n" in certain
    assert " -- Formula is NOT satisfied.\n" in impossible and re.search(r" -- \d+ runs, 0 satisfied", impossible)


def test_verify_without_queries_says_so(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    path = write_engine_file(tmp_path, "goal_ahead", {})
    assert main(["verify", str(path)]) == 0
    captured = capsys.readouterr()
    # the check of penalties that no action avoids runs without queries too
    assert captured.out == ("Checking penalties that no action avoids\n -- none: at each of the 820 decision states up "
                            "to the horizon (8 samples) some allowed action avoids every penalty of `sa`\n"
                            "    27,091 states, horizon 8 samples\n")
    assert captured.err == f"{path}: no queries (add `query NAME: ...` lines, or pass --standard)\n"


def test_verify_file_without_model_block_exits_1(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    path = tmp_path / "plain.ra"
    path.write_text("automaton Plain {\n    input near : bool\n    reward sa\n    objective sa\n    sample every 0.5\n"
                    "    horizon 4\n    initial location N { sa' == 1 }\n    edge N -> N when near\n"
                    "    query Q: E<> N\n}\n")
    for command in ("verify", "simulate", "render", "preanalyse"):
        assert main([command, str(path)]) == 1, command
        captured = capsys.readouterr()
        assert captured.out == ""
        assert captured.err == (f"error[E0015]: `{path}` has no `model` block: the engine answers queries on a "
                                "scenario model\n = hint: add a `model` block naming a CommonRoad scenario "
                                "(docs/language.md, 'The model block')\n")


def test_verify_file_with_errors_exits_1(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    path = write_engine_file(tmp_path, "goal_ahead")
    path.write_text(path.read_text().replace("3 * collision_distance\n", "3 * colision_distance\n"))
    assert main(["verify", str(path)]) == 1
    captured = capsys.readouterr()
    assert captured.out == ""
    line = next(i for i, text in enumerate(path.read_text().splitlines(), 1) if "colision" in text)
    assert f"{path.name}:{line}:37: error[E0101]: unknown name `colision_distance`" in captured.err
    assert "did you mean `collision_distance`?" in captured.err
    assert not (tmp_path / "goal_ahead.out").exists()


def test_verify_usage_errors_exit_2(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    path = write_engine_file(tmp_path, "goal_ahead", {"Stays": QUERIES["Stays"]})
    assert main(["verify", str(tmp_path / "missing.ra")]) == 2
    assert "E0008" in capsys.readouterr().err
    for bad in (["--epsilon", "0"], ["--confidence", "1.5"], ["--max-states", "0"], ["--horizon", "-1"],
                ["--format", "xml"]):
        assert main(["verify", str(path), *bad]) == 2, bad
        assert "error: argument" in capsys.readouterr().err
    (tmp_path / "taken").write_text("a file, not a folder")
    assert main(["verify", str(path), "--query", "Stays", "--out", str(tmp_path / "taken")]) == 0
    capsys.readouterr()  # nothing to write for Stays
    strategy = write_engine_file(tmp_path, "goal_ahead", {"safe": QUERIES["safe"]}, ra_name="strategy")
    assert main(["verify", str(strategy), "--out", str(tmp_path / "taken")]) == 2
    assert capsys.readouterr().err.startswith(f"error[E0009]: cannot write `{tmp_path / 'taken'}`: ")


# ---------------------------------------------------------------- simulate
def test_simulate_writes_csv_and_png(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    path = write_engine_file(tmp_path, "goal_ahead", {})
    csv_path, png_path = tmp_path / "chosen" / "runs.csv", tmp_path / "chosen" / "runs.png"
    assert main(["simulate", str(path), "--runs", "3", "--seed", "5", "-o", str(tmp_path / "chosen")]) == 0
    assert capsys.readouterr().out == (f"simulated 3 runs of 8 samples (seed 5)\n"
                                       f"0 of 3 runs go below 3 * collision_distance = 1.5\n"
                                       f"wrote {csv_path}\nwrote {png_path}\n")
    rows = csv_rows(csv_path)
    assert rows[0] == ["run", "time", "mindist()", "3 * collision_distance"]
    assert len(rows) == 1 + 3 * (8 + 1)
    assert [(r[0], float(r[1])) for r in rows[1:10]] == [("0", k * 0.5) for k in range(9)]
    assert {(r[2], r[3]) for r in rows[1:]} == {("1e+09", "1.5")}  # no obstacle on the road
    image_size(png_path)
    first = csv_path.read_text()
    assert main(["simulate", str(path), "--runs", "3", "--seed", "5", "--out", str(csv_path.parent)]) == 0
    assert csv_path.read_text() == first  # same seed, same runs


def test_simulate_says_one_run_in_the_singular(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    path = write_engine_file(tmp_path, "goal_ahead", {})
    assert main(["simulate", str(path), "--runs", "1", "--seed", "5", "-o", str(tmp_path / "one")]) == 0
    out = capsys.readouterr().out.splitlines()
    assert out[:2] == ["simulated 1 run of 8 samples (seed 5)", "0 of 1 run goes below 3 * collision_distance = 1.5"]


def test_the_simulate_plot_counts_the_runs_once(tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                                capsys: pytest.CaptureFixture[str]) -> None:
    """runs.png of `rac simulate --runs 1 --expr v` was titled "model.ra: 1 run (seed 1): 1 run"."""
    import rac.output.plots as plots

    titles: list[str] = []
    monkeypatch.setattr(plots, "save_figure",
                        lambda figure, path, **options: titles.append(figure.axes[0].get_title()) or Path(path))
    path = write_engine_file(tmp_path, "avoidable_obstacle", {})
    for extra in (["--expr", "v"], [], ["--shield"]):
        assert main(["simulate", str(path), "--runs", "2", "--seed", "5", "-q", *extra, "-o", str(tmp_path)]) == 0
    capsys.readouterr()
    assert titles[0] == f"{path.name}, seed 5: 2 runs"
    assert re.fullmatch(rf"{re.escape(path.name)}, seed 5: \d of 2 runs below 3 \* collision_distance", titles[1])
    assert titles[2].startswith(f"{path.name}, under the shield, seed 5: ")
    assert all(title.count("2 runs") == 1 for title in titles)


def test_simulate_default_paths_and_expressions(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    path = write_engine_file(tmp_path, "avoidable_obstacle", {})
    assert main(["simulate", str(path), "--runs", "2", "--horizon", "1", "--expr", "v", "--expr", "prev(x)",
                 "--expr", "collide()"]) == 0
    out = capsys.readouterr().out
    csv_path = tmp_path / "avoidable_obstacle.out" / "simulate" / "runs.csv"
    assert out.endswith(f"wrote {csv_path}\nwrote {csv_path.with_suffix('.png')}\n")
    rows = csv_rows(csv_path)
    assert rows[0] == ["run", "time", "v", "prev(x)", "collide()"]
    assert len(rows) == 1 + 2 * 3
    assert rows[1][2:] == ["5", "10", "0"]  # the start: 5 m/s at x = 10, no collision
    image_size(csv_path.with_suffix(".png"))


def test_simulate_under_the_shield(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    path = write_engine_file(tmp_path, "avoidable_obstacle", {})
    csv_path = tmp_path / "shielded" / "runs.csv"
    assert main(["simulate", str(path), "--shield", "--runs", "20", "--seed", "3", "--expr", "collide()",
                 "--expr", "offroad()", "-o", str(csv_path.parent)]) == 0
    out = capsys.readouterr().out
    assert out.startswith("simulated 20 runs of 8 samples (seed 3) under the shield\n")
    assert "continued unshielded" not in out
    rows = csv_rows(csv_path)[1:]
    assert len(rows) == 20 * 9 and {(r[2], r[3]) for r in rows} == {("0", "0")}  # never unsafe


def test_simulate_shield_without_safe_strategy_exits_1(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    path = write_engine_file(tmp_path, "narrow_road", {})
    assert main(["simulate", str(path), "--shield", "--runs", "2"]) == 1
    captured = capsys.readouterr()
    assert captured.out == ""
    assert "warning[W0716]: the ego starts off the road" in captured.err  # rac check's, first
    # the error names the file and why (it said neither: with several files in a CI log, which one, and what?)
    assert (f"error[E0015]: no safe strategy exists from the start within the horizon of `{path}` (4 s; Qd is not "
            "satisfied): the ego starts off the road\n") in captured.err
    assert not (tmp_path / "narrow_road.out").exists()


@pytest.mark.parametrize("command", ["simulate", "render"])
def test_a_shield_beyond_the_budget_gives_way_to_the_runtime_shield(command: str, capsys: pytest.CaptureFixture[str],
                                                                   tmp_path: Path) -> None:
    # beyond the budget the runs choose under the runtime shield, as training does, and say so with the
    # guarantee they had (it was a resource limit, exit 2, and no runs)
    path = write_engine_file(tmp_path, "avoidable_obstacle", {})
    out = tmp_path / "out"
    assert main([command, str(path), "--shield", "--max-states", "10", "--runs" if command == "simulate" else "--seed",
                 "3", "-o", str(out)]) == 0
    err = capsys.readouterr().err
    assert f"rac {command}: note: the exhaustive shield is beyond the budget (" in err and "10" in err
    assert "the runs choose under the runtime shield instead" in err
    assert re.search(rf"rac {command}: note: the runs' actions, [\d,]+ decisions: [\d,]+ by the runtime shield "
                     r"\(a safe continuation for the next 5 decisions, or to the horizon", err), err
    assert "no action known to be safe" not in err  # the obstacle is avoidable: every decision had a safe one
    if command == "simulate":  # every run kept clear of the obstacle
        rows = list(csv.DictReader((out / "runs.csv").open(encoding="utf-8")))
        assert rows and all(float(r["mindist()"]) >= float(r["3 * collision_distance"]) / 3 for r in rows)


def test_runs_under_the_runtime_shield_do_not_depend_on_the_clock(capsys: pytest.CaptureFixture[str],
                                                                   tmp_path: Path,
                                                                   monkeypatch: pytest.MonkeyPatch) -> None:
    """Beyond the budget the runtime shield searches with a node budget: on a machine so loaded that each
    reading of the clock is 40 ms after the last, the runs at a seed are those of an idle one (its time
    budget, 0.1 s a decision, cut the searches there, and the runs drew from other masks)."""
    from types import SimpleNamespace

    from rac.engine import lookahead

    path = write_engine_file(tmp_path, "goal_behind_wall", {})

    def runs(folder: str) -> tuple[str, str]:
        out = tmp_path / folder
        assert main(["simulate", str(path), "--shield", "--max-states", "10", "--runs", "20", "--seed", "3",
                     "-o", str(out)]) == 0
        return (out / "runs.csv").read_text(encoding="utf-8"), capsys.readouterr().err

    idle, said = runs("idle")
    assert "up to 64 search nodes each" in said and "ran out of" not in said
    ticks = iter(range(10**9))
    monkeypatch.setattr(lookahead, "time", SimpleNamespace(perf_counter=lambda: next(ticks) * 0.04))
    loaded, said = runs("loaded")
    assert loaded == idle and "ran out of" not in said


@pytest.mark.parametrize(("expr", "message"), [
    ("mindist(", "`mindist(`: the expression is incomplete"),
    ("3 *", "`3 *`: the expression is incomplete"),
    ("a b", "`a b`: unexpected `b`"),
    ("x, y", "`x, y`: one expression per --expr (repeat --expr for more)"),
    ("foo()", "`foo()`: unknown function `foo` (did you mean `floor(e)`?)"),
    ("mindst()", "`mindst()`: unknown function `mindst` (did you mean `mindist()`?)"),
    ("zzz()", "`zzz()`: unknown function `zzz` (a query may call `collide()`, `offroad()`, `goal()`, `mindist()`, "
              "`dist_goal()`, `prev(e)`, `fabs(e)`, `abs(e)`, `sqrt(e)`, `fmin(a, b)`, `fmax(a, b)`, `floor(e)`, "
              "`ceil(e)`, `round(e)`, `trunc(e)`)"),
    ("near", "the input `near` is not known here: it needs the product of the model and the automaton"),
])
def test_simulate_bad_expression_exits_2(capsys: pytest.CaptureFixture[str], tmp_path: Path, expr: str,
                                         message: str) -> None:
    path = write_engine_file(tmp_path, "goal_ahead", {})
    assert main(["simulate", str(path), "--runs", "1", "--horizon", "0.5", "--expr", "v", "--expr", expr]) == 2
    captured = capsys.readouterr()
    assert captured.out == ""
    assert captured.err == f"error[E0014]: --expr: {message}\n"
    assert not (tmp_path / "goal_ahead.out").exists()


# ---------------------------------------------------------------- render
def test_render_writes_png_and_gif(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    path = write_engine_file(tmp_path, "goal_behind_wall", {})
    png, gif = tmp_path / "pictures" / "run.png", tmp_path / "pictures" / "run.gif"
    assert main(["render", str(path), "--horizon", "1", "--seed", "4", "-o", str(png.parent), "--gif"]) == 0
    assert capsys.readouterr().out == ("rendered one run: 2 samples (seed 4)\nthe run: first off-road sample at "
                                       f"t = 1 s\nwrote {png}\nwrote {gif}\n")
    image_size(png)
    with Image.open(gif) as image:
        assert image.format == "GIF" and image.n_frames == 3  # one frame per sample: t = 0, 0.5, 1


def test_render_default_path_and_shield(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    path = write_engine_file(tmp_path, "avoidable_obstacle", {})
    assert main(["render", str(path), "--horizon", "1", "--shield"]) == 0
    out = capsys.readouterr().out
    assert re.fullmatch(r"rendered one run under the shield: 2 samples \(seed \d+\)\n"
                        r"the run: no collision, never off the road\nwrote .*\n", out)
    image_size(tmp_path / "avoidable_obstacle.out" / "render" / "run.png")
    narrow = write_engine_file(tmp_path, "narrow_road", {})
    assert main(["render", str(narrow), "--horizon", "1", "--shield"]) == 1
    assert "no safe strategy exists from the start" in capsys.readouterr().err


@pytest.mark.parametrize(("time_step", "noted"), [("0.1", False), ("0.2", True)])
def test_render_says_when_the_obstacles_are_drawn_off_the_sample(time_step: str, noted: bool,
                                                                  capsys: pytest.CaptureFixture[str],
                                                                  tmp_path: Path) -> None:
    """commonroad-io draws an obstacle at a time step only, so where the scenario's time step does not
    divide the sampling period (0.2 s steps, a sample every 0.5 s) the picture showed each obstacle at
    the nearest step, up to 0.1 s from where the model has it (a car at 8 m/s 0.8 m off, more than the
    collision distance), and the title's time was that step's: nothing said so. A note says it now."""
    from engine_files import write_short_traffic

    path = write_short_traffic(tmp_path, horizon="1")
    road = tmp_path / "road.xml"
    road.write_text(road.read_text(encoding="utf-8").replace('timeStepSize="0.1"', f'timeStepSize="{time_step}"'),
                    encoding="utf-8")
    assert main(["render", str(path), "--seed", "1", "--format", "json"]) == 0
    notes = json.loads(capsys.readouterr().out)["notes"]
    expected = ([f"the scenario's time step ({time_step} s) does not divide the sampling period (0.5 s): the picture "
                 "draws the obstacles at the nearest CommonRoad time step, up to 0.1 s from the ego's sample (the "
                 "model moves them on in a straight line between steps: docs/model.md)"] if noted else [])
    assert notes == expected


def test_render_draws_the_model_blocks_vehicle(monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str],
                                               tmp_path: Path) -> None:
    import rac.output.render

    seen: dict[str, object] = {}

    def fake(scenario_path: object, trajectory: object, png_path: Path, **options: object) -> Path:
        seen.update(options, trajectory=trajectory)
        return Path(png_path)

    monkeypatch.setattr(rac.output.render, "render_trajectory", fake)
    path = write_engine_file(tmp_path, "goal_ahead", {})
    path.write_text(path.read_text().replace("length 4.5", "length 4").replace("width 1.8", "width 1.6"))
    assert main(["render", str(path), "--horizon", "1", "--seed", "1"]) == 0
    capsys.readouterr()
    assert (seen["length"], seen["width"], seen["sample_period"]) == (4.0, 1.6, 0.5)
    assert seen["trajectory"].shape == (3, 3)  # type: ignore[attr-defined]


# ---------------------------------------------------------------- preanalyse
def test_preanalyse_table_json_and_plots(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    path = write_engine_file(tmp_path, "avoidable_obstacle", {})
    out = tmp_path / "pre"
    assert main(["preanalyse", str(path), "--exponent", "1,4", "--runs", "5", "--seed", "1", "--out", str(out)]) == 0
    text = capsys.readouterr().out
    lines = text.splitlines()
    assert lines[0].startswith("| exponent | C1 (s) | C2 (s) | Qa: Pr sensor error | Qb | Qc | Qd |")
    rows = [line for line in lines[2:] if line.startswith("| ")]
    assert [row.split(" | ")[:3] for row in rows] == [["| 1", "0.5", "1"], ["| 4", "0.5", "1"]]
    for row in rows:  # the known answers at both exponents: Qb, not Qc, Qd
        assert " | true | false | true | " in row and " of 5 (Pr in [" in row
    assert text.endswith(f"sweep plot: {out / 'sweep.png'}\n\nplots in {out}\n")
    assert sorted(p.name for p in out.iterdir()) == ["fig7_e1_c1_0.5_c2_1.png", "fig7_e4_c1_0.5_c2_1.png",
                                                     "sweep.png"]
    for plot in out.iterdir():
        image_size(plot)

    assert main(["preanalyse", str(path), "--exponent", "1,4", "--runs", "5", "--seed", "1", "--out", str(out),
                 "--format", "json"]) == 0
    report = json.loads(capsys.readouterr().out)
    assert report["file"] == str(path)
    settings = [s for s in report["settings"] if "exponent" in s]
    assert [s["exponent"] for s in settings] == [1, 4]
    for s in settings:
        assert (s["qb"], s["qc"], s["qd"], s["samples"], s["seed"]) == (True, False, True, 8, 1)
        assert len(s["qa"]) == 2 and len(s["true_min"]) == 5 and s["threshold"] == 0.5
        assert Path(s["plot"]).is_file()
    assert report["settings"][-1] == {"sweep_plot": str(out / "sweep.png")}
    assert "removed" not in report  # the same settings again: every plot drawn again, nothing of before left


def test_preanalyse_removes_an_earlier_runs_plots_of_other_settings(capsys: pytest.CaptureFixture[str],
                                                                   tmp_path: Path) -> None:
    """A run's Fig. 7 plot is named by its setting: a run of other settings into the same folder left the earlier
    run's plots beside its own, as if of this run (sweep.png only was replaced). A run removes the plots an
    earlier one wrote as it starts, and says which it did not draw again; files not named as rac's stay."""
    path = write_engine_file(tmp_path, "avoidable_obstacle", {})
    out = tmp_path / "pre"
    assert main(["preanalyse", str(path), "--exponent", "1,4", "--runs", "2", "--seed", "1", "-q", "-o", str(out)]) == 0
    mine = ["fig7_e1_c1_0.5_c2_1.png.bak", "fig7_notes.png", "fig7_e1_c1_0.5_c2_1_mine.png", "my_sweep.png"]
    for name in mine:
        (out / name).write_bytes(b"mine")
    capsys.readouterr()
    for form in ("text", "json"):
        assert main(["preanalyse", str(path), "--exponent", "4", "--runs", "2", "--seed", "1", "-q", "-o", str(out),
                     "--format", form]) == 0
        captured = capsys.readouterr()
        assert sorted(p.name for p in out.iterdir()) == sorted(["fig7_e4_c1_0.5_c2_1.png", "sweep.png", *mine])
        if form == "text":
            assert (f"rac preanalyse: removed {out / 'fig7_e1_c1_0.5_c2_1.png'}, an earlier run's plot of settings or "
                    "runs this run did not draw\n") in captured.err
        else:  # nothing left to remove: said by neither
            assert "removed" not in captured.err and "removed" not in json.loads(captured.out)
    for name in mine:
        assert (out / name).read_bytes() == b"mine"


@pytest.mark.parametrize("periods", [("0.5", "1"), ("0.05", "0.1"), ("1e-5", "2e-5"), ("1500000", "3000000")])
def test_the_plots_an_earlier_run_left_are_exactly_those_rac_names(tmp_path: Path, periods: tuple[str, str]) -> None:
    from rac.studies.preanalysis import earlier_plots

    sense, decide = (float(p) for p in periods)
    name = f"fig7_e12_c1_{sense:g}_c2_{decide:g}.png"  # as rac.studies.preanalysis names a setting's plot
    for file in (name, "sweep.png", f"x{name}", f"{name}.tmp", name.replace("_c2_", "_c3_")):
        (tmp_path / file).write_bytes(b"")
    assert earlier_plots(tmp_path) == sorted([tmp_path / name, tmp_path / "sweep.png"])


def test_preanalyse_reports_a_decide_period_that_is_no_multiple(capsys: pytest.CaptureFixture[str],
                                                                tmp_path: Path) -> None:
    path = write_engine_file(tmp_path, "goal_ahead", {})
    # a setting without answers is undecided: exit 4, never 0
    assert main(["preanalyse", str(path), "--decide", "0.75", "--runs", "2", "--out", str(tmp_path / "pre")]) == 4
    captured = capsys.readouterr()
    assert captured.err == "rac preanalyse: 1 of 1 settings were not answered (their rows say why)\n"
    assert captured.out == (
        "| exponent | C1 (s) | C2 (s) | Qa: Pr sensor error | Qb | Qc | Qd | states | time (s) | "
        "runs below threshold under the shield (true distance) |\n"
        "| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |\n"
        "| 2 | 0.5 | 0.75 | the decision period is not a whole multiple of the sensing period | | | | | | |\n")
    assert not (tmp_path / "pre").exists()  # "plots in DIR" named a folder that was never made
    assert main(["preanalyse", str(path), "--decide", "0.75", "--format", "json"]) == 4
    [row] = json.loads(capsys.readouterr().out)["settings"]
    assert row == {"exponent": 2, "sense": 0.5, "decide": 0.75,
                   "error": "the decision period is not a whole multiple of the sensing period"}


def test_preanalyse_shows_qa_of_a_setting_whose_exploration_stopped(capsys: pytest.CaptureFixture[str],
                                                                     tmp_path: Path) -> None:
    """A setting whose exploration went past --max-states after Qa was answered showed its error alone in the table:
    Qa's interval, in its row of the JSON, was dropped, and the states read 0. The table shows Qa, "—" for the
    rest, and the error in the last column."""
    path = write_engine_file(tmp_path, "goal_ahead", {})
    assert main(["preanalyse", str(path), "--runs", "2", "--seed", "1", "--max-states", "3", "-q",
                 "--out", str(tmp_path / "pre")]) == 4
    captured = capsys.readouterr()
    # the time column is measured (0.00 or 0.01 s under load): every other column exactly
    assert re.fullmatch(re.escape("| 2 | 0.5 | 1 | [0.000, 0.842] | — | — | — | — | ") + r"\d+\.\d\d" + re.escape(
        " | the model has more than 3 states by t = 0.5 s (sample 1): shorten the horizon (--horizon), coarsen the "
        "model (exponent, action steps, decide_period) or raise --max-states if the machine has the memory |"),
        captured.out.splitlines()[-1]), captured.out
    assert captured.err == "rac preanalyse: 1 of 1 settings were answered only in part (their rows say why)\n"


def test_preanalyse_past_max_seconds_exits_4_and_says_so(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    """rac preanalyse had no time limit. --max-seconds gives each setting up past it (here at once: within
    Qa's runs), a row without all its answers: exit 4, and the command says how many rows the limit cut."""
    path = write_engine_file(tmp_path, "goal_ahead", {})
    assert main(["preanalyse", str(path), "--exponent", "1,2", "--runs", "2", "--max-seconds", "1e-9", "--format",
                 "json", "--out", str(tmp_path / "pre")]) == 4
    captured = capsys.readouterr()
    assert captured.err == ("rac preanalyse: 2 of 2 settings were not answered (their rows say why; 2 given up past "
                            "--max-seconds 1e-09)\n")
    for row in json.loads(captured.out)["settings"]:
        assert re.fullmatch(r"this setting: given up after \S+ s, past the time limit of 1e-09 s \(--max-seconds\)",
                            row["error"]), row
        # the limit is checked at every simulated sample too (e0b9173): given up within Qa's runs, not after them
        assert "qa" not in row and "qb" not in row and row["time_limit"] == 1e-9
    assert main(["preanalyse", str(path), "--max-seconds", "0"]) == 2
    assert "--max-seconds: must be positive and finite: '0'" in capsys.readouterr().err


@pytest.mark.parametrize(("option", "message"), [
    (["--exponent", "0"], "--exponent: '0' must be a positive whole number"),
    (["--exponent", "x"], "--exponent: 'x' is not a number"),
    (["--exponent", "1.5"], "--exponent: '1.5' must be a positive whole number"),
    (["--sense", "0.5,"], "--sense: '' is not a number"),
    (["--exponent", "2,3,2.0"], "--exponent: '2.0' is given twice (as 2)"),  # a row run and shown twice
])
def test_preanalyse_bad_lists_exit_2(capsys: pytest.CaptureFixture[str], tmp_path: Path, option: list[str],
                                     message: str) -> None:
    path = write_engine_file(tmp_path, "goal_ahead", {})
    assert main(["preanalyse", str(path), *option]) == 2
    captured = capsys.readouterr()
    assert captured.out == "" and captured.err == f"error[E0014]: {message}\n"


# ---------------------------------------------------------------- where outputs go
def test_help_names_the_output_convention(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["--help"]) == 0
    text = " ".join(capsys.readouterr().out.split())  # argparse wraps the epilog
    assert "one folder per input file and command, FILE.out/COMMAND/ beside FILE.ra" in text
    assert "-o/--out" in text
    assert main(["simulate", "--help"]) == 0
    assert "default: FILE.out/simulate/ beside the file" in " ".join(capsys.readouterr().out.split())


def test_each_command_writes_into_its_own_folder(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    """simulate's plot and render's picture once shared `FILE.png`: now every command has its folder."""
    path = write_engine_file(tmp_path, "avoidable_obstacle", {"Sim": QUERIES["Sim"]})
    assert main(["verify", str(path), "--seed", "1", "-q"]) == 0
    assert main(["simulate", str(path), "--runs", "2", "--horizon", "1", "--seed", "1", "-q"]) == 0
    assert main(["render", str(path), "--horizon", "1", "--seed", "1", "-q"]) == 0
    assert main(["preanalyse", str(path), "--runs", "2", "--seed", "1", "-q"]) == 0
    capsys.readouterr()
    out = tmp_path / "avoidable_obstacle.out"
    written = sorted(str(p.relative_to(out)) for p in out.rglob("*") if p.is_file())
    assert written == ["preanalyse/fig7_e2_c1_0.5_c2_1.png", "preanalyse/sweep.png", "render/run.png",
                       "simulate/runs.csv", "simulate/runs.png", "verify/Sim.csv", "verify/Sim.png"]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["avoidable_obstacle.out", "avoidable_obstacle.ra",
                                                          "avoidable_obstacle.xml"]


def test_the_output_folders_are_git_ignored() -> None:
    import shutil
    import subprocess

    root = Path(__file__).resolve().parents[2]
    if shutil.which("git") is None or not (root / ".git").exists():
        pytest.skip("not a git checkout (the .gitignore rule is tested where one is)")
    for command in ("verify", "simulate", "render", "preanalyse", "experiment"):
        inside = f"examples/left_turn/model.out/{command}/runs.png"
        assert subprocess.run(["git", "-C", str(root), "check-ignore", "-q", inside]).returncode == 0, inside
    assert subprocess.run(["git", "-C", str(root), "check-ignore", "-q", "examples/left_turn/model.ra"]).returncode == 1


def test_verify_standard_keeps_a_query_of_the_same_name(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    """`--standard` adds a Fig7 of its own: a query named Fig7 in the file keeps its files."""
    path = write_engine_file(tmp_path, "goal_ahead", {"Fig7": "simulate[<=1; 2]{v}"})
    out = tmp_path / "o"
    assert main(["verify", str(path), "--standard", "--query", "Fig7", "--seed", "1", "--out", str(out), "-q"]) == 0
    printed = capsys.readouterr().out
    assert f"wrote {out / 'standard' / 'Fig7.png'}" in printed and f"wrote {out / 'Fig7.png'}" in printed
    assert csv_rows(out / "Fig7.csv")[0] == ["run", "time", "v"]  # the file's own query
    assert csv_rows(out / "standard" / "Fig7.csv")[0][2] == "mindist()"  # the paper's Fig. 7


@pytest.mark.parametrize("query", ["Pr[<=5](<> v >= 6)", "E[<=5; 4](max: v)", "simulate[<=5; 2]{v}",
                                   "strategy fast = maxE(sa)[<=5]{Tiny.location}->{x}: <> time >= 4"])
def test_a_time_bound_past_the_horizon_is_not_answered(query: str, capsys: pytest.CaptureFixture[str],
                                                       tmp_path: Path) -> None:
    # the horizon is 4 s: the emitted UPPAAL model takes no sample after it (its clocks flow on), and
    # rac's runs went on sampling, so the two answered differently (W0604 in rac check)
    path = write_engine_file(tmp_path, "goal_ahead", {"Late": query})
    assert main(["check", str(path)]) == 0
    assert "warning[W0604]: the time bound (5 s) is past the horizon (4 s)" in capsys.readouterr().out
    assert main(["verify", str(path), "--seed", "1", "--format", "json", "-o", str(tmp_path / "out")]) == 4
    (result,) = json.loads(capsys.readouterr().out)["results"]
    assert result["status"] == "unsupported"
    assert result["message"].startswith("the time bound (5 s) is past the horizon (4 s)")
    assert main(["verify", str(path), "--seed", "1", "-o", str(tmp_path / "out")]) == 4
    out = capsys.readouterr().out
    assert out.count("the time bound (5 s) is past the horizon") == 1  # said once, also for simulate


def test_a_longer_horizon_asked_for_admits_the_bound(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    # `--horizon 5` lengthens the runs the user asks about (the standard queries' MAXT follows it)
    path = write_engine_file(tmp_path, "goal_ahead", {"Late": "Pr[<=5](<> v >= 6)"})
    assert main(["verify", str(path), "--seed", "1", "--horizon", "5", "--format", "json",
                 "-o", str(tmp_path / "out")]) == 0
    (result,) = json.loads(capsys.readouterr().out)["results"]
    assert result["status"] == "value" and result["horizon_samples"] == 10


def test_runs_that_the_automaton_ends_early_are_answered_as_the_emitted_model_ends_them(
        capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    # `episode ends when` ends a run in the emitted model (its Timer stops); the engines over the
    # scenario model alone went on to the horizon and answered differently
    queries = {"Crash": "E<> collide()", "Safe": "A[] !collide()", "Prob": "Pr[<=2](<> collide())",
               "safe": "strategy safe = control: A[] !collide() && !offroad()"}
    path = write_engine_file(tmp_path, "avoidable_obstacle", queries)
    text = path.read_text(encoding="utf-8")
    path.write_text(text.replace("    edge Close -> Normal when !near\n",
                                 "    edge Close -> Normal when !near\n    episode ends when near\n"), encoding="utf-8")
    assert main(["verify", str(path), "--seed", "1", "--format", "json", "-o", str(tmp_path / "out")]) == 1
    results = {r["name"]: r for r in json.loads(capsys.readouterr().out)["results"]}
    # decided on the product, whose runs end where the automaton ends them (a collision in the sample
    # where the obstacle first comes near is still reached)
    assert (results["Crash"]["status"], results["Safe"]["status"]) == ("satisfied", "not satisfied")
    assert "product" in results["Crash"]["method"] and "product" in results["Safe"]["method"]
    for name in ("Prob", "safe"):
        assert results[name]["status"] == "unsupported"
        assert results[name]["message"].startswith("the automaton ends runs early (`episode ends when`)")


def test_deadlock_with_allow_when_is_not_answered(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    # where `allow when` leaves no action the emitted model deadlocks; `deadlock` read false there
    path = write_engine_file(tmp_path, "goal_ahead", {"Dead": "E<> deadlock"})
    text = path.read_text(encoding="utf-8")
    path.write_text(text.replace("    model {\n", "    model {\n        allow when v < 100\n", 1), encoding="utf-8")
    assert main(["verify", str(path), "--seed", "1", "--format", "json", "-o", str(tmp_path / "out")]) == 4
    (result,) = json.loads(capsys.readouterr().out)["results"]
    assert result["status"] == "unsupported"
    assert result["message"].startswith("`deadlock` is not answered for a model with `allow when` yet")


@pytest.mark.parametrize("query", ["E[<=2; 4](max: sa)", "Close --> Normal",
                                   "strategy keep = control: A[] !Close"])
def test_what_the_engine_does_not_answer_is_unsupported_not_unknown(query: str, capsys: pytest.CaptureFixture[str],
                                                                    tmp_path: Path) -> None:
    # UNKNOWN reads as "raise the budget"; no budget answers these
    path = write_engine_file(tmp_path, "goal_ahead", {"Q": query})
    assert main(["verify", str(path), "--seed", "1", "--format", "json", "-o", str(tmp_path / "out")]) == 4
    (result,) = json.loads(capsys.readouterr().out)["results"]
    assert result["status"] == "unsupported" and "not supported yet" in result["message"]


def test_statistical_runs_that_allow_when_stops_are_not_answered(capsys: pytest.CaptureFixture[str],
                                                                  tmp_path: Path) -> None:
    # where `allow when` leaves no action the emitted model deadlocks and the run ends; rac's runs went
    # on with any action (Pr 0.77 where UPPAAL answers 0)
    path = write_engine_file(tmp_path, "goal_ahead", {"Fast": "Pr[<=4](<> v >= 6)", "Top": "E[<=4; 20](max: v)"})
    text = path.read_text(encoding="utf-8")
    path.write_text(text.replace("    model {\n", "    model {\n        allow when v < 5.5\n", 1), encoding="utf-8")
    assert main(["verify", str(path), "--seed", "1", "--format", "json", "-o", str(tmp_path / "out")]) == 4
    results = json.loads(capsys.readouterr().out)["results"]
    for result in results:
        assert result["status"] == "unsupported"
        assert "runs met a decision where the model's `allow when` allowed no action" in result["message"]


# ---------------------------------------------------------------- --format json
def test_simulate_and_render_json_summaries(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    # a script reads what was simulated and written from standard output, notes included, never text
    path = write_engine_file(tmp_path, "avoidable_obstacle", {})
    out = tmp_path / "out"
    assert main(["simulate", str(path), "--runs", "3", "--seed", "4", "--shield", "--max-states", "10",
                 "-o", str(out), "--format", "json"]) == 0
    captured = capsys.readouterr()
    document = json.loads(captured.out)
    assert document["runs"] == 3 and document["seed"] == 4 and document["shield"] is True
    assert document["wrote"] == [str(out / "runs.csv"), str(out / "runs.png")]
    assert all(Path(p).is_file() for p in document["wrote"])
    rows = list(csv.DictReader((out / "runs.csv").open(encoding="utf-8")))
    below = {r["run"] for r in rows if float(r["mindist()"]) < float(r["3 * collision_distance"])}
    assert document["runs_below"] == len(below) and document["runs_left_policy"] == 0
    # the runtime shield's fallback and the guarantee it gave are notes in the document, not on stderr
    assert any(n.startswith("the exhaustive shield is beyond the budget") for n in document["notes"])
    assert any(n.startswith("the runs' actions, ") for n in document["notes"])
    assert "note:" not in captured.err
    assert main(["render", str(path), "--seed", "4", "-o", str(out), "--format", "json", "-q"]) == 0
    document = json.loads(capsys.readouterr().out)
    assert document["how"] == "one run" and document["seed"] == 4 and document["wrote"] == [str(out / "run.png")]


@pytest.mark.parametrize("argv", [["simulate", "--expr", "mindist("], ["render", "--strategy", "nosuch"]])
def test_simulate_and_render_json_errors(argv: list[str], capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    path = write_engine_file(tmp_path, "goal_ahead", {})
    assert main([argv[0], str(path), *argv[1:], "--horizon", "0.5", "--format", "json", "-q"]) == 2
    captured = capsys.readouterr()
    [diagnostic] = json.loads(captured.out)
    assert diagnostic["code"] == "E0014" and captured.err == ""


def test_verify_without_a_seed_says_the_seed_that_reproduces_it(capsys: pytest.CaptureFixture[str],
                                                                 tmp_path: Path) -> None:
    # each query printed a seed derived from a fresh one that appeared nowhere: nothing reproduced the run
    path = write_engine_file(tmp_path, "goal_ahead", {"Prob": "Pr[<=2](<> v >= 6)"})
    assert main(["verify", str(path), "-q", "--no-plots", "-o", str(tmp_path / "a")]) == 0
    first = capsys.readouterr()
    found = re.search(r"the random queries drew seed (\d+); `--seed \1` reproduces their answers", first.err)
    assert found, first.err
    assert main(["verify", str(path), "-q", "--no-plots", "-o", str(tmp_path / "b"), "--seed", found.group(1)]) == 0
    again = capsys.readouterr()
    def answers(out: str, folder: str) -> str:  # the time each answer took differs
        return re.sub(r"\d+\.\d+ s,", "", out.replace(folder, ""))

    assert answers(again.out, str(tmp_path / "b")) == answers(first.out, str(tmp_path / "a"))
    assert re.search(r"seed \d+", again.out)
    assert "drew seed" not in again.err  # given, not drawn
    assert main(["verify", str(path), "-q", "--no-plots", "-o", str(tmp_path / "c"), "--seed", found.group(1),
                 "--format", "json"]) == 0
    assert json.loads(capsys.readouterr().out)["seed"] == int(found.group(1))


@pytest.mark.parametrize("argv", [["verify", "--query", "safe"], ["simulate", "--runs", "2"], ["render"],
                                  ["preanalyse", "--exponent", "2", "--sense", "0.5", "--decide", "1"]])
def test_json_documents_hold_the_files_warnings(argv: list[str], capsys: pytest.CaptureFixture[str],
                                                tmp_path: Path) -> None:
    """A road narrower than the ego: `rac check` warns that the ego starts off the road (W0716), which is why
    the shield does not exist. Text prints it on standard error; `--format json` dropped it, stderr stayed
    empty and the document said nothing, so a script saw Qd fail without the reason."""
    path = write_engine_file(tmp_path, "narrow_road", {"safe": QUERIES["safe"]})
    main([argv[0], str(path), *argv[1:], "--seed", "1", "-o", str(tmp_path / "out"), "--format", "json", "-q"])
    captured = capsys.readouterr()
    document = json.loads(captured.out)
    assert [w["code"] for w in document["warnings"]] == ["W0716"]
    assert document["warnings"][0]["span"]["file"] == str(path)
    assert "W0716" not in captured.err  # standard output holds it, once


def test_help_names_every_exit_code(capsys: pytest.CaptureFixture[str]) -> None:
    """`rac --help` listed 0-4 but not 130 (Ctrl-C), and 4 as "a query not decided" only, though
    `rac check` exits 4 for a check stopped at its limit (W0405, W1008)."""
    assert main(["--help"]) == 0
    text = " ".join(capsys.readouterr().out.split())  # argparse wraps the epilog
    listed = text.split("Exit codes: ", 1)[1]
    for code in (EXIT_OK, EXIT_ERRORS, EXIT_USAGE, EXIT_INTERNAL, EXIT_UNDECIDED, EXIT_INTERRUPTED):
        assert f" {code} " in f" {listed}"
    assert "a check stopped at its limit" in listed


def test_a_horizon_option_past_the_recorded_traffic_is_warned_of(tmp_path: Path,
                                                                  capsys: pytest.CaptureFixture[str]) -> None:
    # the file's horizon ends with the traffic (no W0728 from rac check), but `--horizon 3` ran a second past it,
    # on a road whose car had vanished, without a word
    from engine_files import write_short_traffic

    path = write_short_traffic(tmp_path, horizon="2")  # 2 s of traffic
    assert main(["simulate", str(path), "--seed", "1", "-q", "--out", str(tmp_path / "a")]) == 0
    assert "W0728" not in capsys.readouterr().err
    assert main(["simulate", str(path), "--seed", "1", "-q", "--horizon", "3", "--out", str(tmp_path / "b")]) == 0
    err = capsys.readouterr().err
    assert ("warning[W0728]: --horizon 3 runs past the recorded traffic of `road.xml`: its 1 moving obstacle is gone "
            "after scenario time t = 2 s, the horizon ends at t = 3 s") in err
    assert "shorten the horizon to 2 s (--horizon)" in err
    assert main(["verify", str(path), "--seed", "1", "--horizon", "3", "--standard", "--query", "Qa", "--format",
                 "json", "--out", str(tmp_path / "c")]) in (0, 1, 4)
    document = json.loads(capsys.readouterr().out)
    assert [w["code"] for w in document["warnings"]] == ["W0728"]


def _late_goal(folder: Path) -> Path:
    """``folder/drive.ra`` (a sample every 0.5 s, horizon 4 s, the tiny scenarios' coarse model) over
    ``folder/late_goal.xml``: one lane, the ego at x = 10 at 10 m/s, a car ahead whose trajectory is recorded for
    4 s, the goal x in [40, 60] in the window [3, 5] s."""
    road = StraightRoad(300.0, EgoStart(10.0, 1.75, 0.0, 10.0), GoalBox(40.0, 60.0, 3.0, 5.0),
                        obstacles=(Block(11, x=40.0, y=1.75, velocity=8.0),), steps=40)
    (folder / "late_goal.xml").write_bytes(road.xml("late_goal"))
    block = TinySettings().model_block("late_goal.xml", ["near = mindist() < 3 * collision_distance"])
    path = folder / "drive.ra"
    path.write_text(TEMPLATE.format(period="0.5", horizon="4", model=textwrap.indent(block, "    "), queries=""),
                    encoding="utf-8")
    return path


def test_a_horizon_option_before_the_goal_window_is_warned_of(tmp_path: Path,
                                                              capsys: pytest.CaptureFixture[str]) -> None:
    """`--horizon 2` ends the runs before the goal's window [3, 5] s opens: no run can reach the goal, and the
    engine commands said nothing of it (the file's own horizon of 4 s holds the window's first samples)."""
    path = _late_goal(tmp_path)
    assert main(["simulate", str(path), "--seed", "1", "-q", "--out", str(tmp_path / "a")]) == 0
    assert "W0722" not in capsys.readouterr().err
    assert main(["simulate", str(path), "--seed", "1", "-q", "--horizon", "2", "--out", str(tmp_path / "b")]) == 0
    err = capsys.readouterr().err
    assert ("warning[W0722]: the goal's time window [3, 5] s opens after --horizon 2 ends (scenario time t = 2 s): "
            "`goal()` never holds") in err
    assert "lengthen the horizon to at least 3 s (--horizon)" in err
    assert main(["verify", str(path), "--seed", "1", "--horizon", "2", "--standard", "--query", "Qc", "--format",
                 "json", "--out", str(tmp_path / "c")]) in (0, 1, 4)
    document = json.loads(capsys.readouterr().out)
    assert [w["code"] for w in document["warnings"]] == ["W0722"]


def test_preanalyse_says_where_its_horizon_leaves_no_goal_or_traffic(tmp_path: Path,
                                                                     capsys: pytest.CaptureFixture[str]) -> None:
    """`rac preanalyse --horizon 6` ran past the 4 s of recorded traffic without W0728 (the other engine
    commands warn of it), and at `--horizon 2` the runs end before the goal's window [3, 5] s opens, yet Qc
    read a bare "false", as if the traffic or the road kept the ego from the goal; the row says why now."""
    path = _late_goal(tmp_path)
    argv = ["preanalyse", str(path), "--seed", "1", "-q", "--runs", "3"]
    assert main([*argv, "--horizon", "6", "--out", str(tmp_path / "a")]) == 0
    assert "warning[W0728]: --horizon 6 runs past the recorded traffic of `late_goal.xml`" in capsys.readouterr().err
    assert main([*argv, "--horizon", "6", "--format", "json", "--out", str(tmp_path / "b")]) == 0
    document = json.loads(capsys.readouterr().out)
    assert [w["code"] for w in document["warnings"]] == ["W0728"]
    assert "goal_never" not in document["settings"][0]

    assert main([*argv, "--horizon", "2", "--format", "json", "--out", str(tmp_path / "c")]) == 0
    row = json.loads(capsys.readouterr().out)["settings"][0]
    assert row["qc"] is False and row["goal_never"] == "the goal's window opens after the horizon"
    assert main([*argv, "--horizon", "2", "--out", str(tmp_path / "d")]) == 0
    table = capsys.readouterr().out
    assert "| false (`goal()` holds at no sample: the goal's window opens after the horizon) |" in table
