"""A run whose sensed state leaves int32 (the car drives off a road that ends just below the range
at the file's exponent): every engine command says so as the model's limit, never as a crash.

At exponent 6 the model's positions are micrometres, so int32 ends at x = 2147.48 m. The road
ends at 2145 m; the ego starts at 2140 m at 10 m/s and passes the range within a second.
"""

from __future__ import annotations

import csv
import json
from fractions import Fraction
from pathlib import Path

import pytest
from engine_files import engine_source
from tiny_scenarios import EgoStart, GoalBox, StraightRoad, TinySettings, straight_road

from rac.cli.main import main

QUERIES = {"Reach": "Pr[<=2](<> offroad())", "Stays": "E[] !collide() && !offroad()"}


def write_far_road(folder: Path, queries: dict[str, str] | None = None) -> Path:
    road = StraightRoad(2145.0, EgoStart(2140.0, 1.75, 0.0, 10.0), GoalBox(2143.0, 2145.0, 0.0, 4.0))
    tiny = straight_road("far_road", road, settings=TinySettings(exponent=6))
    tiny.write(folder / "far_road.xml")
    path = folder / "far_road.ra"
    path.write_text(engine_source(tiny, QUERIES if queries is None else queries), encoding="utf-8")
    return path


@pytest.mark.parametrize("command", [["simulate", "--runs", "3"], ["render"]])
def test_a_run_beyond_int32_is_the_models_limit(command: list[str], capsys: pytest.CaptureFixture[str],
                                                tmp_path: Path) -> None:
    path = write_far_road(tmp_path)
    assert main([command[0], str(path), *command[1:], "--seed", "1", "-o", str(tmp_path / "out")]) == 1
    err = capsys.readouterr().err
    assert "error[E0015]: a sensed value left the int32 range: sense(): x = 21" in err
    assert "UPPAAL's model aborts there too" in err and "coarser `exponent`" in err
    assert "internal error" not in err
    # where in the file: the model block's number representation (the E0015 had no place, nor a source line)
    line = next(n for n, text in enumerate(path.read_text().splitlines(), 1) if text.strip() == "exponent 6")
    assert f"{path}:{line}:9: error[E0015]" in err and f"{line} |         exponent 6" in err


def test_simulate_keeps_the_runs_an_overflow_leaves(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    """One run leaving int32 dropped all of them: `rac simulate --runs 8` wrote nothing, though each run is
    independent and the others go on to the horizon. Each run now stops at its own overflow (UPPAAL's model aborts
    there), the files hold every run up to its stop, and the E0015 says which stopped where (exit 1)."""
    road = StraightRoad(2145.0, EgoStart(2138.0, 1.75, 0.0, 3.0), GoalBox(2143.0, 2145.0, 0.0, 4.0))
    tiny = straight_road("mixed", road, settings=TinySettings(exponent=6))  # the fast runs pass x = 2147.48 m
    tiny.write(tmp_path / "mixed.xml")
    path = tmp_path / "mixed.ra"
    path.write_text(engine_source(tiny, {}), encoding="utf-8")
    out = tmp_path / "out"
    assert main(["simulate", str(path), "--runs", "8", "--seed", "1", "-o", str(out)]) == 1
    err = capsys.readouterr().err
    with (out / "runs.csv").open(encoding="utf-8") as file:
        rows = [row["run"] for row in csv.DictReader(file)]
    lengths = [rows.count(str(run)) for run in range(8)]
    stopped = [run for run in range(8) if lengths[run] < 9]  # samples 0..8 for a run that went on
    assert 0 < len(stopped) < 8, lengths
    assert f"{path}:" in err and "error[E0015]: a sensed value left the int32 range: sense(): x = " in err
    first = f"run {stopped[0]} at sample {lengths[stopped[0]]} (t = {lengths[stopped[0]] / 2:g} s)"
    assert (f"{len(stopped)} of 8 runs stopped there: {first}") in err
    assert f"runs.csv and runs.png hold each up to its stop; the other {8 - len(stopped)} runs went on" in err
    assert (out / "runs.png").is_file()


def test_render_draws_the_run_up_to_its_overflow(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    path = write_far_road(tmp_path)
    assert main(["render", str(path), "--seed", "1", "-o", str(tmp_path / "out")]) == 1
    captured = capsys.readouterr()
    assert "rendered one run: 1 of 8 samples (seed 1)" in captured.out and (tmp_path / "out" / "run.png").is_file()
    assert "1 of 1 run stopped there: run 0 at sample 2 (t = 1 s); the picture shows the run up to there" \
        in captured.err


def test_a_probability_decided_before_int32_ends_is_answered(capsys: pytest.CaptureFixture[str],
                                                              tmp_path: Path) -> None:
    """Regression: every run leaves the road (sample 1) before its x leaves int32 (sample 2), and UPPAAL
    stops checking `<> offroad()` at the first state that satisfies it; the whole batch raised at the
    overflow, so `Pr[<=2](<> offroad())` and its `>= 0.9` were UNKNOWN (exit 4). `[] !offroad()` is
    decided (false) there too. Where the overflow comes first (`<> collide()`: no obstacle) the query
    stays unknown, and says that the overflow came before the formula was decided."""
    queries = {"Reach": "Pr[<=2](<> offroad())", "Likely": "Pr[<=2](<> offroad()) >= 0.9",
               "Kept": "Pr[<=2]([] !offroad())", "Hit": "Pr[<=2](<> collide())"}
    path = write_far_road(tmp_path, queries)
    assert main(["verify", str(path), "--seed", "1", "--format", "json", "-o", str(tmp_path / "out")]) == 4
    results = {result["name"]: result for result in json.loads(capsys.readouterr().out)["results"]}
    assert results["Reach"]["status"] == "value" and results["Reach"]["estimate"] == 1.0
    assert results["Reach"]["interval"][0] > 0.9
    assert results["Likely"]["status"] == "satisfied"
    assert results["Kept"]["status"] == "value" and results["Kept"]["estimate"] == 0.0
    assert results["Hit"]["status"] == "unknown"
    assert results["Hit"]["message"].startswith("a sensed value left the int32 range: sense(): x = 21")
    assert "came before `<> collide()` was decided" in results["Hit"]["message"]


def test_preanalyse_reports_the_row_and_never_exits_0_with_one_unanswered(
        capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    path = write_far_road(tmp_path)
    assert main(["preanalyse", str(path), "--exponent", "2,6", "--runs", "5", "--seed", "1", "-q",
                 "--format", "json", "-o", str(tmp_path / "out")]) == 4
    captured = capsys.readouterr()
    rows = {row["exponent"]: row for row in json.loads(captured.out)["settings"]}
    assert "error" not in rows[2] and rows[2]["qb"] is False  # centimetres: the car leaves the road, in range
    assert rows[6]["error"].startswith("a sensed value left the int32 range at this exponent")
    # the overflowing setting keeps Qb-Qd (the exploration ends a run at its first unsafe state): answered in part,
    # which said "were not answered" as if it had none
    assert "rac preanalyse: 1 of 2 settings were answered only in part (their rows say why)" in captured.err
    assert json.loads(captured.out)["answered"] == {"fully": 1, "partly": 1, "not": 0}
    assert Fraction(rows[6]["sense"]) == Fraction(1, 2)


def test_preanalyse_answers_what_the_overflow_leaves_answerable(capsys: pytest.CaptureFixture[str],
                                                                 tmp_path: Path) -> None:
    """Qa's runs leaving int32 at exponent 6 dropped the whole setting: Qb-Qd went unanswered, though the
    exploration ends each run at its first unsafe state (off the road at sample 1, before x leaves int32 at sample
    2) and never overflows. The row now says Qa's overflow and holds Qb-Qd."""
    path = write_far_road(tmp_path)
    assert main(["preanalyse", str(path), "--exponent", "6", "--runs", "3", "--seed", "1", "-q", "--format", "json",
                 "-o", str(tmp_path / "out")]) == 4
    [row] = [row for row in json.loads(capsys.readouterr().out)["settings"] if "exponent" in row]
    assert row["error"].startswith("a sensed value left the int32 range at this exponent in Qa's runs: sense(): x = ")
    assert "qa" not in row and (row["qb"], row["qc"], row["qd"]) == (False, False, False) and row["states"] > 0


def test_preanalyse_counts_settings_answered_in_part_apart(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    """A setting answered in part (Qa's runs left int32, Qb-Qd answered) and one not answered at all (a decision
    period that is no multiple of the sensing period) were both "not answered": the message, and the JSON,
    count them apart; exit 4 either way (something left undecided)."""
    path = write_far_road(tmp_path)
    assert main(["preanalyse", str(path), "--exponent", "2,6", "--decide", "0.5,0.75", "--runs", "3", "--seed", "1",
                 "-q", "--format", "json", "-o", str(tmp_path / "out")]) == 4
    captured = capsys.readouterr()
    assert captured.err == ("rac preanalyse: 3 of 4 settings were not answered in full (1 in part, 2 not at all) "
                            "(their rows say why)\n")
    assert json.loads(captured.out)["answered"] == {"fully": 1, "partly": 1, "not": 2}
