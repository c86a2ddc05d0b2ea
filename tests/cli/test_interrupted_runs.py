"""Long commands stopped midway (Ctrl-C, memory that runs out) keep the work done before: `rac verify`
shows the queries it answered, `rac preanalyse` the settings it finished, with the exit code that says
they were stopped, never a bare "interrupted" that drops minutes of answers."""

from __future__ import annotations

import errno
import json
import os
import signal
import subprocess
import sys
from pathlib import Path

import pytest
from conftest import rac_env
from engine_files import write_engine_file

from rac.cli.common import EXIT_INTERRUPTED, EXIT_TERMINATED, EXIT_UNDECIDED, EXIT_USAGE
from rac.cli.main import main
from rac.verify.statistical import StatisticalAnswerer

QUERIES = {"Stays": "E[] !collide() && !offroad()", "Sim": "simulate[<=2; 4]{mindist(), 3 * collision_distance}",
           "Later": "E<> !collide() && !offroad() && goal()"}


def run(capsys: pytest.CaptureFixture[str], *args: str | Path) -> tuple[int, str, str]:
    capsys.readouterr()
    code = main([str(a) for a in args])
    out, err = capsys.readouterr()
    return code, out, err


def _raises(exc: BaseException):
    def answer(self: object, query: object, base: object) -> object:
        raise exc

    return answer


@pytest.mark.parametrize("form", ["text", "json"])
def test_verify_interrupted_shows_the_queries_answered(capsys: pytest.CaptureFixture[str], tmp_path: Path,
                                                      monkeypatch: pytest.MonkeyPatch, form: str) -> None:
    path = write_engine_file(tmp_path, "goal_ahead", QUERIES)
    monkeypatch.setattr(StatisticalAnswerer, "simulate", _raises(KeyboardInterrupt()))  # Ctrl-C during Sim
    code, out, err = run(capsys, "verify", path, "-q", "--seed", "1", "-o", tmp_path / "o", "--format", form)
    assert code == EXIT_INTERRUPTED
    assert "rac verify: interrupted during Sim: simulate[<=2;4]" in err
    # under JSON the answers are in the document, not above (it said "above" there too)
    assert f"1 query answered before it is {'above' if form == 'text' else 'in the JSON document'}" in err
    if form == "json":
        document = json.loads(out)  # standard output stays one JSON document
        assert [r["name"] for r in document["results"]] == ["Stays"] and document["interrupted"].startswith("Sim: ")
    else:
        assert "Verifying Stays" in out and "Formula is satisfied" in out and "Later" not in out


@pytest.mark.parametrize("form", ["text", "json"])
def test_verify_with_a_full_disk_shows_the_queries_answered(capsys: pytest.CaptureFixture[str], tmp_path: Path,
                                                           monkeypatch: pytest.MonkeyPatch, form: str) -> None:
    # the disk filled up at Sim's CSV: only E0009 was printed, and the answers of the queries before it (minutes,
    # on a real scene) were dropped with it, where Ctrl-C at the same moment shows them
    path = write_engine_file(tmp_path, "goal_ahead", QUERIES)
    csv = tmp_path / "o" / "Sim.csv"
    monkeypatch.setattr(StatisticalAnswerer, "simulate",
                        _raises(OSError(errno.ENOSPC, "No space left on device", str(csv))))
    code, out, err = run(capsys, "verify", path, "-q", "--seed", "1", "-o", tmp_path / "o", "--format", form)
    assert code == EXIT_USAGE
    where = "above" if form == "text" else "in the JSON document"
    assert "rac verify: stopped during Sim: simulate[<=2;4]" in err and f"by the error {where}; " in err
    assert f"1 query answered before it is {where}" in err
    if form == "json":
        document = json.loads(out)  # one document: the answers and the error
        assert [r["name"] for r in document["results"]] == ["Stays"] and document["interrupted"].startswith("Sim: ")
        assert document["error"]["code"] == "E0009" and str(csv) in document["error"]["message"]
    else:
        assert "Verifying Stays" in out and "Formula is satisfied" in out and "Later" not in out
        assert f"error[E0009]: cannot write `{csv}`: No space left on device" in err


def test_verify_out_of_memory_in_one_query_keeps_the_others(capsys: pytest.CaptureFixture[str], tmp_path: Path,
                                                            monkeypatch: pytest.MonkeyPatch) -> None:
    # the machine's memory (or `ulimit -v`) ran out in Sim before any budget said so: Sim is undecided, the
    # queries before and after it are answered; before, the whole command ended in E0016 and showed none
    path = write_engine_file(tmp_path, "goal_ahead", QUERIES)
    monkeypatch.setattr(StatisticalAnswerer, "simulate", _raises(MemoryError("std::bad_alloc")))
    code, out, _ = run(capsys, "verify", path, "-q", "--seed", "1", "-o", tmp_path / "o", "--format", "json")
    assert code == EXIT_UNDECIDED
    results = {r["name"]: r for r in json.loads(out)["results"]}
    assert list(results) == ["Stays", "Sim", "Later"]
    assert results["Sim"]["status"] == "unknown" and "out of memory (std::bad_alloc)" in results["Sim"]["message"]
    assert results["Stays"]["status"] == "satisfied" and results["Later"]["status"] in ("satisfied", "not satisfied")


@pytest.mark.parametrize("form", ["text", "json"])
def test_verify_out_of_memory_after_the_queries_shows_their_answers(capsys: pytest.CaptureFixture[str],
                                                                    tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                                                    form: str) -> None:
    # the penalty check after the queries explores a product of its own while their graphs are still held: the
    # memory that ran out there ended the command in E0016 alone, every answer (minutes of them) dropped
    from rac.verify import penalties

    def exhausted(context: object) -> object:
        raise MemoryError("Unable to allocate 1.00 GiB for an array with shape (134217728,) and data type int64")

    monkeypatch.setattr(penalties, "check_penalties", exhausted)
    path = write_engine_file(tmp_path, "goal_ahead", QUERIES)
    code, out, err = run(capsys, "verify", path, "-q", "--seed", "1", "-o", tmp_path / "o", "--format", form)
    assert code == EXIT_USAGE
    where = "above" if form == "text" else "in the JSON document"
    assert f"rac verify: stopped during penalties that no action avoids by the error {where}; 3 queries answered" in err
    if form == "json":
        document = json.loads(out)  # one document: the answers and the error
        assert [r["name"] for r in document["results"]] == ["Stays", "Sim", "Later"]
        assert document["error"]["code"] == "E0016" and "out of memory (Unable to allocate" in \
            document["error"]["message"]
    else:
        assert "Verifying Stays" in out and "Verifying Later" in out
        assert "error[E0016]: out of memory (Unable to allocate" in err and "a lower --max-memory" in err


def _row_failing_on_the_second(monkeypatch: pytest.MonkeyPatch, exc: BaseException) -> None:
    """``rac.studies.preanalysis._row`` raising ``exc`` on its second setting (the first is answered)."""
    from rac.studies import preanalysis

    calls = []
    real = preanalysis._row

    def row(*args: object, **kwargs: object) -> object:
        calls.append(1)
        if len(calls) == 2:
            raise exc
        return real(*args, **kwargs)

    monkeypatch.setattr(preanalysis, "_row", row)


@pytest.mark.parametrize("form", ["text", "json"])
def test_preanalyse_interrupted_shows_the_settings_finished(capsys: pytest.CaptureFixture[str], tmp_path: Path,
                                                            monkeypatch: pytest.MonkeyPatch, form: str) -> None:
    path = write_engine_file(tmp_path, "goal_ahead", {})
    _row_failing_on_the_second(monkeypatch, KeyboardInterrupt())
    code, out, err = run(capsys, "preanalyse", path, "-q", "--exponent", "1,2,3", "--runs", "2", "--seed", "1",
                         "-o", tmp_path / "pre", "--format", form)
    assert code == EXIT_INTERRUPTED
    # under JSON the rows are in the document, not above (it said "above" there too)
    where = "above" if form == "text" else "in the JSON document"
    assert f"rac preanalyse: interrupted; 1 setting finished before it ({where})" in err
    if form == "json":
        document = json.loads(out)
        assert [s["exponent"] for s in document["settings"]] == [1] and document["interrupted"] is True
    else:
        assert "| 1 | " in out and "| 2 | " not in out


@pytest.mark.parametrize("stop", ["interrupt", "full disk"])
def test_preanalyse_stopped_removes_an_earlier_sweeps_plot(capsys: pytest.CaptureFixture[str], tmp_path: Path,
                                                           monkeypatch: pytest.MonkeyPatch, stop: str) -> None:
    # an earlier run's sweep.png (of its own settings and runs) stayed beside this run's Fig. 7 plots, as if it
    # were this run's; the plot of a run that finishes replaces it, one that stops before its plot removes it
    path = write_engine_file(tmp_path, "goal_ahead", {})
    old = tmp_path / "pre" / "sweep.png"
    old.parent.mkdir()
    old.write_bytes(b"an earlier sweep")
    os.utime(old, (1_600_000_000, 1_600_000_000))
    kept = tmp_path / "pre" / "notes.png"  # not the sweep's: left alone
    kept.write_bytes(b"mine")
    os.utime(kept, (1_600_000_000, 1_600_000_000))
    failure = KeyboardInterrupt() if stop == "interrupt" else OSError(errno.ENOSPC, "No space left on device", "x")
    _row_failing_on_the_second(monkeypatch, failure)
    code, _, err = run(capsys, "preanalyse", path, "-q", "--exponent", "1,2,3", "--runs", "2", "--seed", "1",
                       "-o", tmp_path / "pre")
    assert code == (EXIT_INTERRUPTED if stop == "interrupt" else EXIT_USAGE)
    assert not old.exists() and kept.read_bytes() == b"mine"
    assert f"rac preanalyse: removed {old}, an earlier run's plot of settings or runs this run did not draw" in err
    assert list((tmp_path / "pre").glob("fig7_e1_*.png"))  # the finished setting's own plot stays


@pytest.mark.parametrize("form", ["text", "json"])
def test_preanalyse_with_a_full_disk_shows_the_settings_finished(capsys: pytest.CaptureFixture[str], tmp_path: Path,
                                                                monkeypatch: pytest.MonkeyPatch, form: str) -> None:
    # the disk filled up at the second setting's plot: only E0009 was printed, the first setting's answers
    # (written, with its plot) were dropped with it, where Ctrl-C at the same moment shows them
    path = write_engine_file(tmp_path, "goal_ahead", {})
    plot = tmp_path / "pre" / "exponent_2.png"
    _row_failing_on_the_second(monkeypatch, OSError(errno.ENOSPC, "No space left on device", str(plot)))
    code, out, err = run(capsys, "preanalyse", path, "-q", "--exponent", "1,2,3", "--runs", "2", "--seed", "1",
                         "-o", tmp_path / "pre", "--format", form)
    assert code == EXIT_USAGE
    where = "above" if form == "text" else "in the JSON document"
    assert f"rac preanalyse: stopped by the error {where}; 1 setting finished before it ({where})" in err
    if form == "json":
        document = json.loads(out)
        assert [s["exponent"] for s in document["settings"]] == [1] and document["error"]["code"] == "E0009"
    else:
        assert "| 1 | " in out and "| 2 | " not in out
        assert f"error[E0009]: cannot write `{plot}`: No space left on device" in err


def test_preanalyse_out_of_memory_in_one_setting_keeps_the_others(capsys: pytest.CaptureFixture[str],
                                                                  tmp_path: Path,
                                                                  monkeypatch: pytest.MonkeyPatch) -> None:
    # before, the machine's MemoryError in one setting ended the command in E0016 with no row shown
    path = write_engine_file(tmp_path, "goal_ahead", {})
    _row_failing_on_the_second(monkeypatch, MemoryError("std::bad_alloc"))
    code, out, err = run(capsys, "preanalyse", path, "-q", "--exponent", "1,2,3", "--runs", "2", "--seed", "1",
                         "-o", tmp_path / "pre", "--format", "json")
    assert code == EXIT_UNDECIDED
    settings = {s["exponent"]: s for s in json.loads(out)["settings"] if "exponent" in s}
    assert settings[1]["qb"] is True and settings[3]["qb"] is True
    assert settings[2]["error"].startswith("out of memory (std::bad_alloc): this setting needed more memory")
    # three settings, not four: the sweep plot's entry is no setting
    assert "rac preanalyse: 1 of 3 settings were not answered" in err


#: A child rac whose statistical answerer sends the process SIGTERM (`timeout`, a batch system's limit, `kill`),
#: as it would arrive in the middle of a long query.
TERMINATED_CHILD = """
import os, signal, sys, time
from rac.verify.statistical import StatisticalAnswerer
def simulate(self, query, base):
    os.kill(os.getpid(), signal.SIGTERM)
    time.sleep(30)  # the signal arrives in here
StatisticalAnswerer.simulate = simulate
from rac.cli.main import main
sys.exit(main(sys.argv[1:]))
"""


@pytest.mark.parametrize("form", ["text", "json"])
def test_verify_terminated_shows_the_queries_answered(tmp_path: Path, form: str) -> None:
    # SIGTERM ended the process on the spot: `timeout 600 rac verify ...` printed nothing of the queries it
    # had answered (Ctrl-C showed them), and a --format json reader got no document at all
    path = write_engine_file(tmp_path, "goal_ahead", QUERIES)
    done = subprocess.run([sys.executable, "-c", TERMINATED_CHILD, "verify", str(path), "-q", "--seed", "1",
                           "-o", str(tmp_path / "o"), "--format", form], env=rac_env(), capture_output=True,
                          text=True, timeout=120, check=False)
    assert done.returncode == EXIT_TERMINATED == 128 + signal.SIGTERM, done.stderr
    assert "rac verify: terminated (SIGTERM) during Sim: simulate[<=2;4]" in done.stderr
    assert f"1 query answered before it is {'above' if form == 'text' else 'in the JSON document'}" in done.stderr
    assert "Traceback" not in done.stderr
    if form == "json":
        document = json.loads(done.stdout)
        assert [r["name"] for r in document["results"]] == ["Stays"] and document["interrupted"].startswith("Sim: ")
    else:
        assert "Verifying Stays" in done.stdout and "Formula is satisfied" in done.stdout


def _check_stopped_at(monkeypatch: pytest.MonkeyPatch, name: str, exc: BaseException) -> None:
    """``rac check``'s ``compile_file`` raising ``exc`` on the file called ``name`` (the others are checked)."""
    import rac.cli.files

    real = rac.cli.files.compile_file

    def compile_file(path: Path, *args: object, **kwargs: object) -> object:
        if Path(path).name == name:
            raise exc
        return real(path, *args, **kwargs)

    monkeypatch.setattr(rac.cli.files, "compile_file", compile_file)


def _three_files(tmp_path: Path) -> list[Path]:
    from rac.lang.resources import stdlib_file

    text = stdlib_file("driving.ra").read_text(encoding="utf-8")
    paths = [tmp_path / f"{name}.ra" for name in ("a", "b", "c")]
    for path in paths:
        path.write_text(text, encoding="utf-8")
    return paths


def test_check_interrupted_keeps_the_files_checked(capsys: pytest.CaptureFixture[str], tmp_path: Path,
                                                   monkeypatch: pytest.MonkeyPatch) -> None:
    # Ctrl-C in the second file printed only {"command": "check", "ok": false, ...}: the first file's results
    # (minutes of checks on a large scenario) were dropped
    a, b, c = _three_files(tmp_path)
    _check_stopped_at(monkeypatch, "b.ra", KeyboardInterrupt())
    code, out, err = run(capsys, "check", "--format", "json", a, b, c)
    assert code == EXIT_INTERRUPTED and "rac: interrupted" in err
    document = json.loads(out)  # one document, rac check's own: an entry per file
    assert [entry["file"] for entry in document] == [str(a), str(b)]
    assert document[0]["ok"] is True and document[0]["proved"] and "interrupted" not in document[0]
    assert document[1] == {"file": str(b), "ok": False, "diagnostics": [], "proved": [], "facts": [],
                           "undecided": True, "interrupted": True}
    # as text the first file's summary was printed before
    code, out, _ = run(capsys, "check", a, b, c)
    assert code == EXIT_INTERRUPTED and f"{a}: ok" in out and str(b) not in out


#: A child ``rac check`` that sends itself SIGTERM while it checks the file ``b.ra``.
TERMINATED_CHECK = """
import os, signal, sys, time
from pathlib import Path
import rac.cli.files
real = rac.cli.files.compile_file
def compile_file(path, *args, **kwargs):
    if Path(path).name == "b.ra":
        os.kill(os.getpid(), signal.SIGTERM)
        time.sleep(30)  # the signal arrives in here
    return real(path, *args, **kwargs)
rac.cli.files.compile_file = compile_file
from rac.cli.main import main
sys.exit(main(sys.argv[1:]))
"""


def test_check_terminated_keeps_the_files_checked(tmp_path: Path) -> None:
    a, b, c = _three_files(tmp_path)
    done = subprocess.run([sys.executable, "-c", TERMINATED_CHECK, "check", "--format", "json", str(a), str(b),
                           str(c)], env=rac_env(), capture_output=True, text=True, timeout=120, check=False)
    assert done.returncode == EXIT_TERMINATED, done.stderr
    document = json.loads(done.stdout)
    assert [(entry["file"], entry["ok"], entry.get("interrupted")) for entry in document] == [
        (str(a), True, None), (str(b), False, True)]


def _import_stopped() -> ImportError:
    """What Ctrl-C raises when it stops the import of a pybind11 extension (stormpy, matplotlib's): an
    ``ImportError`` from the ``KeyboardInterrupt``, not the ``KeyboardInterrupt`` itself."""
    exc = ImportError("initialization failed")
    exc.__cause__ = KeyboardInterrupt()
    return exc


@pytest.mark.parametrize("form", ["text", "json"])
def test_verify_interrupted_in_an_import_shows_the_queries_answered(capsys: pytest.CaptureFixture[str],
                                                                    tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                                                    form: str) -> None:
    # Ctrl-C while matplotlib's extensions loaded for Sim's plot (or stormpy's): "rac: internal error: ImportError:
    # initialization failed ... This is a bug in rac", exit 3, and the answers before it were dropped
    path = write_engine_file(tmp_path, "goal_ahead", QUERIES)
    monkeypatch.setattr(StatisticalAnswerer, "simulate", _raises(_import_stopped()))
    code, out, err = run(capsys, "verify", path, "-q", "--seed", "1", "-o", tmp_path / "o", "--format", form)
    assert code == EXIT_INTERRUPTED, err
    assert "internal error" not in err and "rac verify: interrupted during Sim: simulate[<=2;4]" in err
    assert f"1 query answered before it is {'above' if form == 'text' else 'in the JSON document'}" in err
    if form == "json":
        document = json.loads(out)
        assert [r["name"] for r in document["results"]] == ["Stays"] and document["interrupted"].startswith("Sim: ")
    else:
        assert "Verifying Stays" in out and "Later" not in out


@pytest.mark.parametrize("form", ["text", "json"])
def test_a_command_interrupted_in_an_import_exits_as_interrupted(capsys: pytest.CaptureFixture[str], tmp_path: Path,
                                                                 monkeypatch: pytest.MonkeyPatch, form: str) -> None:
    # the same at the start of the command (verify imports stormpy first): exit 3 and "a bug in rac"
    import rac.cli.engine

    def stopped(args: object) -> int:
        raise _import_stopped()

    monkeypatch.setattr(rac.cli.engine, "simulate_command", stopped)
    path = write_engine_file(tmp_path, "goal_ahead", {})
    code, out, err = run(capsys, "simulate", path, "-q", "--runs", "2", "-o", tmp_path / "o", "--format", form)
    assert code == EXIT_INTERRUPTED, err
    assert "internal error" not in err and "rac: interrupted" in err
    if form == "json":
        document = json.loads(out)
        assert document["interrupted"] is True and document["exit_code"] == EXIT_INTERRUPTED
        assert document["error"] is None


def test_preanalyse_interrupted_in_an_import_shows_the_settings_finished(capsys: pytest.CaptureFixture[str],
                                                                         tmp_path: Path,
                                                                         monkeypatch: pytest.MonkeyPatch) -> None:
    path = write_engine_file(tmp_path, "goal_ahead", {})
    _row_failing_on_the_second(monkeypatch, _import_stopped())
    code, out, err = run(capsys, "preanalyse", path, "-q", "--exponent", "1,2,3", "--runs", "2", "--seed", "1",
                         "-o", tmp_path / "pre")
    assert code == EXIT_INTERRUPTED, err
    assert "rac preanalyse: interrupted; 1 setting finished before it (above)" in err and "| 1 | " in out


def test_an_error_that_ctrl_c_did_not_cause_is_still_a_bug() -> None:
    from rac.cli.common import interrupted_by

    plain = ImportError("initialization failed")
    looped = ValueError("x")
    looped.__context__ = ValueError("y")
    looped.__context__.__context__ = looped  # a chain that loops back must not hang the check
    assert interrupted_by(_import_stopped()) and interrupted_by(KeyboardInterrupt())
    assert not interrupted_by(plain) and not interrupted_by(looped)


def test_simulate_interrupted_while_plotting_keeps_the_previous_pair(capsys: pytest.CaptureFixture[str],
                                                                     tmp_path: Path,
                                                                     monkeypatch: pytest.MonkeyPatch) -> None:
    # runs.csv was renamed into place before the plot was drawn (a second): Ctrl-C then left the new runs' CSV
    # beside the previous run's plot, a pair that disagrees with nothing to say so
    from rac.verify import report

    path = write_engine_file(tmp_path, "goal_ahead", {})
    out = tmp_path / "o"
    code, _, err = run(capsys, "simulate", path, "-q", "--runs", "3", "--seed", "1", "-o", out)
    assert code == 0, err
    before = {name: (out / name).read_bytes() for name in ("runs.csv", "runs.png")}
    monkeypatch.setattr(report, "plot_series", _raises_any(KeyboardInterrupt()))
    code, _, err = run(capsys, "simulate", path, "-q", "--runs", "5", "--seed", "2", "-o", out)
    assert code == EXIT_INTERRUPTED, err
    assert {name: (out / name).read_bytes() for name in before} == before
    assert sorted(p.name for p in out.iterdir()) == ["runs.csv", "runs.png"]  # no temporary left


def test_verify_interrupted_while_plotting_keeps_the_previous_pair(capsys: pytest.CaptureFixture[str],
                                                                   tmp_path: Path,
                                                                   monkeypatch: pytest.MonkeyPatch) -> None:
    from rac.verify import statistical

    path = write_engine_file(tmp_path, "goal_ahead", {"Sim": QUERIES["Sim"]})
    out = tmp_path / "o"
    code, _, err = run(capsys, "verify", path, "-q", "--seed", "1", "-o", out, "--query", "Sim")
    assert code == 0, err
    before = {name: (out / name).read_bytes() for name in ("Sim.csv", "Sim.png")}
    monkeypatch.setattr(statistical, "plot_series", _raises_any(KeyboardInterrupt()))
    path = write_engine_file(tmp_path, "goal_ahead", {"Sim": QUERIES["Sim"].replace("4]", "6]")})  # other runs
    code, _, err = run(capsys, "verify", path, "-q", "--seed", "2", "-o", out, "--query", "Sim")
    assert code == EXIT_INTERRUPTED, err
    assert {name: (out / name).read_bytes() for name in before} == before
    assert sorted(p.name for p in out.iterdir()) == ["Sim.csv", "Sim.png"]


def _raises_any(exc: BaseException):
    def raiser(*args: object, **kwargs: object) -> object:
        raise exc

    return raiser


def test_render_interrupted_while_drawing_the_gif_keeps_the_previous_pair(capsys: pytest.CaptureFixture[str],
                                                                          tmp_path: Path,
                                                                          monkeypatch: pytest.MonkeyPatch) -> None:
    # run.png was written before the GIF's frames were drawn (seconds): Ctrl-C there left the new run's picture
    # beside the previous run's animation
    from rac.output import render

    path = write_engine_file(tmp_path, "goal_ahead", {})
    out = tmp_path / "o"
    code, _, err = run(capsys, "render", path, "-q", "--gif", "--seed", "1", "-o", out)
    assert code == 0, err
    before = {name: (out / name).read_bytes() for name in ("run.png", "run.gif")}
    monkeypatch.setattr(render.Image, "fromarray", _raises_any(KeyboardInterrupt()))  # in the GIF's frames
    code, _, err = run(capsys, "render", path, "-q", "--gif", "--seed", "2", "-o", out)
    assert code == EXIT_INTERRUPTED, err
    assert {name: (out / name).read_bytes() for name in before} == before
    assert sorted(p.name for p in out.iterdir()) == ["run.gif", "run.png"]


def test_check_interrupted_in_an_import_keeps_the_files_checked(capsys: pytest.CaptureFixture[str], tmp_path: Path,
                                                                monkeypatch: pytest.MonkeyPatch) -> None:
    # Ctrl-C in numpy's import while the second file was checked: the JSON document of the first was dropped
    a, b, c = _three_files(tmp_path)
    _check_stopped_at(monkeypatch, "b.ra", _import_stopped())
    code, out, err = run(capsys, "check", "--format", "json", a, b, c)
    assert code == EXIT_INTERRUPTED and "rac: interrupted" in err
    assert [entry["file"] for entry in json.loads(out)] == [str(a), str(b)]
