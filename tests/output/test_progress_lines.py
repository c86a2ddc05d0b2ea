"""Progress off a terminal (issue 11): a long command is never silent. Where stderr is not a TTY
(CI logs, pipes) a heartbeat prints the phase, what was counted, its rate and the time elapsed
every few seconds; ``-q`` silences it; on a terminal the tqdm bars do the job instead."""

from __future__ import annotations

import io
import re
import time
from pathlib import Path

import pytest
from engine_files import QUERIES, write_engine_file

from rac.cli.main import main
from rac.output.progress import Heartbeat, Progress

LINE = re.compile(r"^rac verify: (?P<phase>.+?); (?:(?P<count>[\d.]+(?: [kMG])?) states \([\d.]+(?: [kMG])?/s\); )?"
                  r"(?P<elapsed>\d+) s$")


def test_a_heartbeat_prints_the_phase_the_count_and_the_time() -> None:
    stream = io.StringIO()
    with Heartbeat("rac test", interval=0.02, file=stream) as beat:
        assert Heartbeat.active is beat
        beat.phase("exploring")
        with Progress(desc="exploring", unit="states", enabled=False) as bar:
            bar.update(1500)
            time.sleep(0.1)
    assert Heartbeat.active is None
    lines = stream.getvalue().splitlines()
    assert lines, "no heartbeat line"
    assert re.fullmatch(r"rac test: exploring; 1.5 k states \([\d.]+ [kMG]?/s\); 0 s", lines[-1]), lines[-1]


def test_a_heartbeat_is_silent_on_a_terminal_and_when_disabled() -> None:
    class Terminal(io.StringIO):
        def isatty(self) -> bool:
            return True

    for stream, enabled in ((Terminal(), None), (io.StringIO(), False)):
        with Heartbeat("rac test", interval=0.01, file=stream, enabled=enabled):
            time.sleep(0.05)
        assert stream.getvalue() == ""


def test_verify_off_a_terminal_says_what_it_does(tmp_path: Path, capsys: pytest.CaptureFixture[str],
                                                  monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("RAC_PROGRESS_INTERVAL", "0.001")
    path = write_engine_file(tmp_path, "avoidable_obstacle", {"Stays": QUERIES["Stays"], "safe": QUERIES["safe"]})
    assert main(["verify", str(path), "--out", str(tmp_path / "o")]) == 0
    lines = [line for line in capsys.readouterr().err.splitlines() if line.startswith("rac verify:")]
    assert lines, "no progress line on stderr"
    assert all(LINE.match(line) for line in lines), lines
    assert any("safe: strategy safe = control" in line for line in lines) or any("Stays" in line for line in lines)
    assert main(["verify", str(path), "-q", "--out", str(tmp_path / "o")]) == 0
    assert "rac verify:" not in capsys.readouterr().err


@pytest.mark.parametrize("value", ["abc", "inf", "0", "nan", "-1", "1e9"])
def test_a_bad_progress_interval_is_said_and_the_default_used(value: str, monkeypatch: pytest.MonkeyPatch,
                                                              capsys: pytest.CaptureFixture[str]) -> None:
    # `abc` was an internal error in every command, `inf` a thread's traceback, `0` a flood of lines
    from rac.output import progress

    monkeypatch.setenv("RAC_PROGRESS_INTERVAL", value)
    monkeypatch.setattr(progress, "_SAID_INTERVAL", False)
    assert progress.Heartbeat("rac check").interval == progress.DEFAULT_INTERVAL
    assert f"RAC_PROGRESS_INTERVAL={value!r} is not a positive number of seconds" in capsys.readouterr().err
    progress.Heartbeat("rac check")
    assert capsys.readouterr().err == ""  # said once


@pytest.fixture
def slow_simulation(monkeypatch: pytest.MonkeyPatch) -> None:
    """Every simulated sample takes 3 ms more, and the heartbeat speaks every millisecond: a long run in brief.
    The model's sensing step is what every sample does (the truth's integration, slowed before, runs only for
    expressions that read the truth: `E[..](max: v)` then simulated too fast for the heartbeat, now and then)."""
    from rac.model.batch import BatchModel

    sense = BatchModel.sense

    def slow(self, *args, **kwargs):
        time.sleep(0.003)
        return sense(self, *args, **kwargs)

    monkeypatch.setattr(BatchModel, "sense", slow)
    monkeypatch.setenv("RAC_PROGRESS_INTERVAL", "0.001")


@pytest.mark.parametrize("command", ["simulate", "render"])
def test_simulate_and_render_count_the_samples_they_simulate(command: str, tmp_path: Path,
                                                              capsys: pytest.CaptureFixture[str],
                                                              slow_simulation: None) -> None:
    # One run of a long horizon takes minutes (900,000 samples of 1 ms: over 3 minutes); the
    # heartbeat said only "working; 200 s", without how far the run had come.
    path = write_engine_file(tmp_path, "avoidable_obstacle", {})
    assert main([command, str(path), "--seed", "1", "--out", str(tmp_path / "o")]) == 0
    lines = [line for line in capsys.readouterr().err.splitlines() if line.startswith(f"rac {command}:")]
    counted = [line for line in lines
               if re.fullmatch(rf"rac {command}: simulating; [\d.]+(?: [kMG])? samples \([\d.]+(?: [kMG])?/s\); \d+ s",
                               line)]
    assert counted, lines
    assert main([command, str(path), "-q", "--seed", "1", "--out", str(tmp_path / "o")]) == 0
    assert f"rac {command}: simulating" not in capsys.readouterr().err


@pytest.mark.parametrize("query", ["Prob", "ProbRuns", "Speed", "Sim"])
def test_verify_counts_the_samples_its_statistical_queries_simulate(query: str, tmp_path: Path,
                                                                    capsys: pytest.CaptureFixture[str],
                                                                    slow_simulation: None) -> None:
    # `Pr[<=100000](<> collide())` at 0.1 s simulated for over five minutes with the heartbeat saying
    # only "rac verify: P: Pr[<=100000](<> collide()); 270 s", and no bar on a terminal either
    path = write_engine_file(tmp_path, "avoidable_obstacle", {query: QUERIES[query]})
    assert main(["verify", str(path), "--seed", "1", "--no-plots", "--query", query,
                 "--out", str(tmp_path / "o")]) == 0
    lines = [line for line in capsys.readouterr().err.splitlines() if line.startswith("rac verify:")]
    pattern = rf"rac verify: {query}: .+; [\d.]+(?: [kMG])? samples \([\d.]+(?: [kMG])?/s\); \d+ s"
    assert any(re.fullmatch(pattern, line) for line in lines), lines


def test_a_count_that_starts_again_has_a_rate_of_its_own() -> None:
    """A query simulates its runs in batches, each counting its samples from 0: the rate of a later batch
    was its count over the time since the first batch began."""

    def rate(line: str) -> float:
        match = re.search(r"\(([\d.]+)(?: ([kMG]))?/s\)", line)
        assert match is not None, line
        return float(match.group(1)) * {None: 1, "k": 1e3, "M": 1e6, "G": 1e9}[match.group(2)]

    beat = Heartbeat("rac test", enabled=False)
    beat.phase("P")
    beat.count(0, "samples")
    time.sleep(0.5)
    beat.count(1000, "samples")
    assert rate(beat.line()) < 2100  # 1,000 samples in 0.5 s
    beat.count(0, "samples")  # the next batch, just begun
    beat.count(1000, "samples")
    assert rate(beat.line()) > 10_000, beat.line()  # 1,000 samples in no time, not in 0.5 s


def test_a_bar_of_a_few_counts_whole_numbers() -> None:
    """tqdm's scaled counts ("13.3k states") showed the 3rd of a sweep's 8 tasks as "3.00/8.00 tasks"."""
    few, many = io.StringIO(), io.StringIO()
    with Progress(total=8, desc="sweep", unit="tasks", enabled=True, file=few) as bar, \
            Progress(desc="exploring", unit="states", enabled=True, file=many) as states:
        time.sleep(0.2)  # past tqdm's least interval between two refreshes
        bar.update(3)
        states.update(13300)
    assert "3/8" in few.getvalue() and ".00" not in few.getvalue(), few.getvalue()
    assert "13.3k states" in many.getvalue(), many.getvalue()
