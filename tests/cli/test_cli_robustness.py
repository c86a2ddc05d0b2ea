"""The command line refuses what it cannot do with a message and exit 2, never an internal error (exit 3)
nor a silent loss: negative seeds, out-of-range pre-analysis settings, output folders and files that
cannot be written (a FIFO stays a FIFO), a ``--from`` file that is no UTF-8 text or no regular file, a
scheduler address Dask cannot use, and an output folder holding the input file (never overwritten).

FIFOs are made with ``os.mkfifo`` in ``tmp_path``; nothing here opens one (that would block).
"""

from __future__ import annotations

import fcntl
import os
import stat
from pathlib import Path

import pytest
from engine_files import write_engine_file

from rac.cli.arguments import MIN_SEED, build_parser
from rac.cli.common import (
    EXIT_ERRORS,
    EXIT_OK,
    EXIT_UNDECIDED,
    EXIT_USAGE,
    NotRegularFile,
    locked,
    write_atomically,
)
from rac.cli.main import main
from rac.lang.resources import stdlib_dir

DRIVING = (stdlib_dir() / "driving.ra").read_text(encoding="utf-8")
SEED_RULE = f"a seed must be a whole number of at least {MIN_SEED}"


@pytest.fixture
def engine_file(tmp_path: Path) -> Path:
    """A small engine file (sample period 0.5 s, no obstacle) beside its scenario, in ``tmp_path``."""
    return write_engine_file(tmp_path, "goal_ahead", {})


@pytest.fixture
def clean(tmp_path: Path) -> Path:
    """driving.ra (no model block) in ``tmp_path``."""
    path = tmp_path / "driving.ra"
    path.write_text(DRIVING, encoding="utf-8")
    return path


def run(capsys: pytest.CaptureFixture[str], *args: str | Path) -> tuple[int, str, str]:
    """``rac ARGS`` in this process: the exit code, standard output and standard error."""
    capsys.readouterr()
    code = main([str(a) for a in args])
    out, err = capsys.readouterr()
    assert "internal error" not in err and "Traceback" not in err, err
    return code, out, err


def is_fifo(path: Path) -> bool:
    return stat.S_ISFIFO(os.lstat(path).st_mode)


# ---------------------------------------------------------------- 1. seeds
@pytest.mark.parametrize("command", [
    ["simulate", "--runs", "2", "--seed", "-1"],
    ["verify", "--query", "safe", "--seed", "-1"],
    ["render", "--seed", "-1"],
    ["preanalyse", "--runs", "2", "--seed", "-1"],
    ["experiment", "--seeds", "-1", "--episodes", "2", "--runs", "1", "--combination", "RA"],
    ["experiment", "--seeds", "1,-2", "--episodes", "2", "--runs", "1", "--combination", "RA"],
    ["experiment", "--seed", "-5", "--episodes", "2", "--runs", "1", "--combination", "RA"],
], ids=["simulate", "verify", "render", "preanalyse", "experiment-seeds", "experiment-list", "experiment-seed"])
def test_a_negative_seed_is_usage(capsys: pytest.CaptureFixture[str], engine_file: Path, tmp_path: Path,
                                  command: list[str]) -> None:
    out = tmp_path / "o"
    code, stdout, err = run(capsys, command[0], engine_file, "-q", "-o", out, *command[1:])
    assert code == EXIT_USAGE
    assert f"rac {command[0]}: error: argument --seed" in err and SEED_RULE in err
    assert stdout == "" and not out.exists()


def test_sweep_has_the_same_seed_rule(capsys: pytest.CaptureFixture[str], engine_file: Path, tmp_path: Path) -> None:
    out = tmp_path / "sweep"
    code, _, err = run(capsys, "sweep", engine_file, tmp_path / "goal_ahead.xml", "-q", "-o", out, "--seed", "-1")
    assert code == EXIT_USAGE
    assert "rac sweep: error: argument --seed" in err and SEED_RULE in err
    assert not out.exists()


@pytest.mark.parametrize("command", ["simulate", "verify", "render", "preanalyse", "experiment", "sweep"])
def test_the_least_seed_and_a_huge_one_are_seeds(command: str) -> None:
    parser = build_parser()
    extra = ["x.xml"] if command == "sweep" else []
    for seed in (MIN_SEED, 10**30):
        args = parser.parse_args([command, "x.ra", *extra, "--seed", str(seed)])
        assert int(args.seed) == seed


def test_experiment_seeds_are_a_list_of_seeds() -> None:
    assert build_parser().parse_args(["experiment", "x.ra", "--seeds", "0,2,3"]).seeds == (0, 2, 3)


def test_a_seed_given_twice_is_refused(capsys: pytest.CaptureFixture[str]) -> None:
    # it was learned twice and counted twice in the table's means and spreads
    with pytest.raises(SystemExit) as stop:
        build_parser().parse_args(["experiment", "x.ra", "--seeds", "1,2,1,2,3"])
    assert stop.value.code == 2
    assert "argument --seeds: seed 1, 2 given twice in '1,2,1,2,3'" in capsys.readouterr().err


# ---------------------------------------------------------------- 2. preanalyse: a folder it cannot write
def blocked_folders(tmp_path: Path) -> dict[str, Path]:
    afile = tmp_path / "afile"
    afile.write_text("mine\n", encoding="utf-8")
    return {"a-file": afile, "under-a-file": afile / "sub", "too-long": tmp_path / ("a" * 300)}


@pytest.mark.parametrize("which", ["a-file", "under-a-file", "too-long"])
def test_preanalyse_cannot_write_its_folder(capsys: pytest.CaptureFixture[str], engine_file: Path, tmp_path: Path,
                                           which: str) -> None:
    out = blocked_folders(tmp_path)[which]
    code, _, err = run(capsys, "preanalyse", engine_file, "-q", "--seed", "1", "--runs", "2", "-o", out)
    assert code == EXIT_USAGE
    assert err.startswith(f"error[E0009]: cannot write `{out}`: "), err
    assert (tmp_path / "afile").read_text(encoding="utf-8") == "mine\n"


def test_preanalyse_default_folder_blocked_by_a_file(capsys: pytest.CaptureFixture[str], engine_file: Path,
                                                     tmp_path: Path) -> None:
    blocker = tmp_path / "goal_ahead.out"
    blocker.write_text("mine\n", encoding="utf-8")
    code, _, err = run(capsys, "preanalyse", engine_file, "-q", "--seed", "1", "--runs", "2")
    assert code == EXIT_USAGE
    assert err == (f"error[E0009]: cannot write `{blocker / 'preanalyse'}`: Not a directory\n"
                   " = hint: a part of the path is a file, not a folder: choose another path; nothing was written\n")
    assert blocker.read_text(encoding="utf-8") == "mine\n"


def test_a_folder_where_an_output_file_goes_is_named(capsys: pytest.CaptureFixture[str], engine_file: Path,
                                                     tmp_path: Path) -> None:
    """The message named the -o folder ("cannot write `out`: Is a directory", hint "name a file, not a
    folder"), which is a folder as it should be; the folder in the way is the file's."""
    out = tmp_path / "out"
    (out / "runs.csv").mkdir(parents=True)
    code, _, err = run(capsys, "simulate", engine_file, "--seed", "1", "--runs", "2", "-o", out)
    assert code == EXIT_USAGE
    assert err.startswith(f"error[E0009]: cannot write `{out / 'runs.csv'}`: "), err


# ---------------------------------------------------------------- 3. preanalyse: values out of range
@pytest.mark.parametrize(("option", "message"), [
    (["--sense", "1e400"], "--sense: '1e400' must be at most the horizon, 4 s"),
    (["--decide", "1e400"], "--decide: '1e400' must be at most the horizon, 4 s"),
    (["--exponent", "1e400"], "--exponent: '1e400' must be at most 6 (the model's `exponent` lies in 1..6)"),
    (["--exponent", "7"], "--exponent: '7' must be at most 6 (the model's `exponent` lies in 1..6)"),
    (["--horizon", "1e-9"], "--horizon 1e-09 is not a whole number of samples of C1 = 0.5 s"),
    (["--horizon", "0.15"], "--horizon 0.15 is not a whole number of samples of C1 = 0.5 s"),
    (["--horizon", "1", "--sense", "0.5,0.3"], "--horizon 1 is not a whole number of samples of C1 = 0.3 s"),
    (["--horizon", "1e400"], "--horizon 1e400 is 2e400 samples of C1 = 0.5 s: more than 2,147,483,647"),
])
def test_preanalyse_refuses_values_out_of_range(capsys: pytest.CaptureFixture[str], engine_file: Path,
                                               tmp_path: Path, option: list[str], message: str) -> None:
    out = tmp_path / "pre"
    code, stdout, err = run(capsys, "preanalyse", engine_file, "-q", "--seed", "1", "--runs", "2", "-o", out,
                            *option)
    assert code == EXIT_USAGE
    assert stdout == "" and err == f"error[E0014]: {message}\n"
    assert not out.exists()


def test_preanalyse_takes_a_horizon_of_whole_samples(capsys: pytest.CaptureFixture[str], engine_file: Path,
                                                     tmp_path: Path) -> None:
    out = tmp_path / "pre"
    code, stdout, _ = run(capsys, "preanalyse", engine_file, "-q", "--seed", "1", "--runs", "2", "-o", out,
                          "--horizon", "1", "--sense", "0.5", "--decide", "1")
    assert code == EXIT_OK and "| 2 | 0.5 | 1 |" in stdout


@pytest.mark.parametrize("command", [["simulate", "--runs", "1"], ["render"], ["verify", "--query", "safe"]])
def test_a_horizon_of_too_many_samples_is_usage(capsys: pytest.CaptureFixture[str], engine_file: Path,
                                                tmp_path: Path, command: list[str]) -> None:
    code, _, err = run(capsys, command[0], engine_file, "-q", "--seed", "1", "-o", tmp_path / "o", "--horizon",
                       "1e400", *command[1:])
    assert code == EXIT_USAGE
    assert err == "error[E0014]: --horizon 1e400 is 2e400 samples of 0.5 s: more than 2,147,483,647\n"


# ---------------------------------------------------------------- 4. compile: a folder as the output
@pytest.mark.parametrize("target", ["uppaal", "python"])
@pytest.mark.parametrize("output", ["./", "", "/"])
def test_compile_to_a_folder_is_e0009(capsys: pytest.CaptureFixture[str], clean: Path, tmp_path: Path,
                                      monkeypatch: pytest.MonkeyPatch, target: str, output: str) -> None:
    monkeypatch.chdir(tmp_path)
    before = sorted(os.listdir(tmp_path))
    code, _, err = run(capsys, "compile", "--target", target, clean, "-o", output)
    assert code == EXIT_USAGE
    shown = "/" if output == "/" else "."
    assert err == (f"error[E0009]: cannot write `{shown}`: it is a directory\n"
                   " = hint: name a file, not a folder; nothing was written\n")
    assert sorted(os.listdir(tmp_path)) == before


# ---------------------------------------------------------------- 5. new --from: what check, fmt and tune refuse
def test_new_from_a_file_that_is_not_utf8(capsys: pytest.CaptureFixture[str], tmp_path: Path,
                                          monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.chdir(tmp_path)
    (tmp_path / "badutf.ra").write_bytes(b"\xff\xfe\x00bad")
    code, _, err = run(capsys, "new", "x", "--from", "badutf.ra")
    assert code == EXIT_ERRORS
    assert "badutf.ra:1:1: error[E0004]: file is not UTF-8 text (invalid byte 0xff at offset 0)" in err
    assert not (tmp_path / "x.ra").exists()


def test_new_from_a_fifo_is_e0008_and_reads_nothing(capsys: pytest.CaptureFixture[str], tmp_path: Path,
                                                    monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.chdir(tmp_path)
    os.mkfifo(tmp_path / "pipe.ra")
    code, _, err = run(capsys, "new", "x", "--from", "pipe.ra")  # reading it would block: it is refused first
    assert code == EXIT_USAGE
    assert err == ("error[E0008]: cannot read `pipe.ra`: not a regular file (a pipe or a device?)\n"
                   " = hint: pass the path of a .ra file\n")
    assert not (tmp_path / "x.ra").exists() and is_fifo(tmp_path / "pipe.ra")


def test_new_from_a_file_keeps_its_text(capsys: pytest.CaptureFixture[str], tmp_path: Path,
                                        monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.chdir(tmp_path)
    (tmp_path / "mine.ra").write_bytes(DRIVING.replace("\n", "\r\n").encode("utf-8"))
    code, out, _ = run(capsys, "new", "copy", "--from", "mine.ra")
    assert code == EXIT_OK and out.startswith("wrote copy.ra (from mine.ra, automaton Copy)")
    text = (tmp_path / "copy.ra").read_text(encoding="utf-8")
    assert "\r" not in text and "automaton Copy" in text


# ---------------------------------------------------------------- 6. sweep --scheduler
@pytest.mark.parametrize("address", ["notaurl", "tcp://", "tcp://127.0.0.1", "tcp://127.0.0.1:abc", "tcp://[::1:1",
                                     "bogus://h:1", "inproc://x", "tls://127.0.0.1:1"])
def test_a_scheduler_address_dask_cannot_use_is_usage(capsys: pytest.CaptureFixture[str], engine_file: Path,
                                                      tmp_path: Path, address: str) -> None:
    code, _, err = run(capsys, "sweep", engine_file, tmp_path / "goal_ahead.xml", "-q", "-o", tmp_path / "sweep",
                       "--scheduler", address)
    assert code == EXIT_USAGE
    said = f"error[E0014]: --scheduler: the scheduler address {address!r} is not one Dask can use ("
    assert err.startswith(said), err
    assert err.endswith("); give tcp://HOST:PORT\n")


def test_connect_raises_bad_scheduler_address() -> None:
    from rac.sweep.run import BadSchedulerAddress, connect

    with pytest.raises(BadSchedulerAddress, match="missing port number") as caught, connect("tcp://127.0.0.1"):
        pass
    assert caught.value.address == "tcp://127.0.0.1" and isinstance(caught.value, ValueError)


# ---------------------------------------------------------------- 7. a FIFO or a link to one as the output
@pytest.mark.parametrize("target", ["python", "uppaal"])
@pytest.mark.parametrize("link", [False, True], ids=["fifo", "link-to-fifo"])
def test_compile_never_replaces_a_fifo(capsys: pytest.CaptureFixture[str], clean: Path, tmp_path: Path,
                                       target: str, link: bool) -> None:
    fifo = tmp_path / "fifo"
    os.mkfifo(fifo)
    output = fifo
    if link:
        output = tmp_path / "link.xml"
        output.symlink_to(fifo)
    code, _, err = run(capsys, "compile", "--target", target, clean, "-o", output)
    assert code == EXIT_USAGE
    assert err == (f"error[E0009]: cannot write `{output}`: it is not a regular file (a pipe or a device?)\n"
                   " = hint: rac replaces only regular files: choose the path of a file, or a new one; "
                   "nothing was written\n")
    assert is_fifo(fifo) and sorted(p.name for p in tmp_path.iterdir()) == sorted(
        ["driving.ra", "fifo", *(["link.xml"] if link else [])])


def test_compile_uppaal_never_replaces_a_fifo_queries_file(capsys: pytest.CaptureFixture[str], clean: Path,
                                                           tmp_path: Path) -> None:
    os.mkfifo(tmp_path / "model.q")
    code, _, err = run(capsys, "compile", "--target", "uppaal", clean, "-o", tmp_path / "model.xml")
    assert code == EXIT_USAGE
    assert f"error[E0009]: cannot write `{tmp_path / 'model.q'}`: it is not a regular file" in err
    assert is_fifo(tmp_path / "model.q") and not (tmp_path / "model.xml").exists()


@pytest.mark.parametrize("name", ["model", "model.XML", "model.txt"])
def test_compile_uppaal_says_when_the_name_is_not_read_as_xml(capsys: pytest.CaptureFixture[str], clean: Path,
                                                              tmp_path: Path, name: str) -> None:
    # UPPAAL's tools read a model as XML only by the `.xml` ending: any other name is parsed as XTA text
    code, _, err = run(capsys, "compile", "--target", "uppaal", clean, "-o", tmp_path / name)
    assert code == EXIT_OK
    assert (tmp_path / name).read_text().startswith("<?xml")
    assert (f"note: `{tmp_path / name}` holds an XML model, but UPPAAL reads a file as XML only when its name ends "
            f"in `.xml`") in err and f"name it `{name}.xml`" in err
    code, _, err = run(capsys, "compile", "--target", "uppaal", clean, "-o", tmp_path / "model.xml")
    assert code == EXIT_OK and "note:" not in err


def test_write_atomically_refuses_a_fifo(tmp_path: Path) -> None:
    os.mkfifo(tmp_path / "fifo")
    with pytest.raises(NotRegularFile):
        write_atomically(tmp_path / "fifo", "text\n")
    assert is_fifo(tmp_path / "fifo") and [p.name for p in tmp_path.iterdir()] == ["fifo"]


# ---------------------------------------------------------------- 8. an output folder holding the input
@pytest.mark.parametrize(("command", "name"), [
    (["simulate", "--runs", "1"], "runs.csv"),
    (["render"], "run.png"),
    (["verify", "--query", "safe"], "safe.shield.npz"),
    (["preanalyse", "--runs", "1"], "sweep.png"),
    (["experiment", "--episodes", "2", "--runs", "1", "--combination", "RA"], "results.json"),
])
def test_an_engine_command_never_overwrites_its_input(capsys: pytest.CaptureFixture[str], tmp_path: Path,
                                                      command: list[str], name: str) -> None:
    folder = tmp_path / "ow"
    folder.mkdir()
    source = write_engine_file(folder, "goal_ahead", {"safe": "strategy safe = control: A[] !collide()"})
    text = source.read_bytes()
    source.rename(folder / name)
    code, _, err = run(capsys, command[0], folder / name, "-q", "--seed", "1", "-o", folder, *command[1:])
    assert code == EXIT_USAGE
    assert err.startswith(f"error[E0009]: cannot write into `{folder}`: it holds the input file "
                          f"`{folder / name}`, which an output may replace\n"), err
    assert "rac never overwrites the `.ra` file it reads" in err
    assert (folder / name).read_bytes() == text
    assert sorted(p.name for p in folder.iterdir()) == sorted(["goal_ahead.xml", name])


def test_the_input_reached_by_a_link_in_a_subfolder_is_refused_too(capsys: pytest.CaptureFixture[str],
                                                                   tmp_path: Path) -> None:
    """verify --standard writes into standard/ of the folder: an input there, behind a link, is safe too."""
    (tmp_path / "ow" / "standard").mkdir(parents=True)
    source = write_engine_file(tmp_path / "ow" / "standard", "goal_ahead", {})
    real = source.rename(source.with_name("Fig7.csv"))
    link = tmp_path / "model.ra"
    link.symlink_to(real)
    code, out, err = run(capsys, "verify", link, "--format", "json", "-o", tmp_path / "ow", "--standard")
    assert code == EXIT_USAGE and err == ""
    assert '"code": "E0009"' in out and f"(as `{real}`)" in out


def test_a_ra_input_in_the_output_folder_is_fine(capsys: pytest.CaptureFixture[str], engine_file: Path,
                                                 tmp_path: Path) -> None:
    """No output's name ends in .ra: `rac simulate model.ra -o .` beside the file is allowed."""
    text = engine_file.read_bytes()
    code, _, _ = run(capsys, "simulate", engine_file, "-q", "--seed", "1", "--runs", "1", "--horizon", "1",
                     "-o", tmp_path)
    assert code == EXIT_OK and (tmp_path / "runs.csv").is_file()
    assert engine_file.read_bytes() == text


# ---------------------------------------------------------------- 9. messages
def test_render_an_unknown_strategy_says_so_once(capsys: pytest.CaptureFixture[str], engine_file: Path,
                                                 tmp_path: Path) -> None:
    code, _, err = run(capsys, "render", engine_file, "-q", "--seed", "1", "-o", tmp_path / "o",
                       "--strategy", "nosuch")
    assert code == EXIT_USAGE
    assert err.startswith(f"error[E0014]: no learned strategy `nosuch` in {engine_file} (learning queries: none)\n")
    assert err.count("error[") == 1 and "= hint: name a `strategy NAME" in err


def test_render_an_empty_strategy_name_says_so(capsys: pytest.CaptureFixture[str], engine_file: Path,
                                               tmp_path: Path) -> None:
    # `--strategy ""` rendered a random run, exit 0
    code, _, err = run(capsys, "render", engine_file, "-q", "--seed", "1", "-o", tmp_path / "o", "--strategy", "")
    assert code == EXIT_USAGE
    assert err.startswith(f"error[E0014]: no learned strategy `` in {engine_file} (learning queries: none)\n")


@pytest.mark.parametrize("command", ["simulate", "render", "preanalyse"])
def test_runs_beyond_the_memory_budget_are_refused_before_anything_is_allocated(
        capsys: pytest.CaptureFixture[str], engine_file: Path, tmp_path: Path, command: str) -> None:
    # `rac simulate --runs 100000000000000000000` was an internal error (numpy: maximum allowed
    # dimension exceeded); a large but possible count would have filled the machine's memory
    runs = ["--runs", "100000000"] if command != "render" else []
    horizon = ["--horizon", "100000000"] if command == "render" else []
    extra = ["--exponent", "2", "--sense", "0.5", "--decide", "1"] if command == "preanalyse" else []
    out = tmp_path / "out"
    code, stdout, err = run(capsys, command, engine_file, "--seed", "1", "-q", "--max-memory", "512M", "-o", out,
                            *runs, *horizon, *extra)
    said = stdout + err
    assert "would need about" in said and "more than the memory budget of 512 MB" in said
    assert "out of memory" not in said  # refused by the estimate, not by the machine
    # preanalyse: the row says it, and a setting without answers is undecided (exit 4)
    assert code == (EXIT_UNDECIDED if command == "preanalyse" else EXIT_USAGE)


def test_the_lock_of_a_linked_file_is_its_targets_folder(tmp_path: Path) -> None:
    """`rac fmt link.ra` locked the link's folder while it rewrote the target elsewhere: `rac tune` on
    the target itself (which locks the target's folder) did not wait for it."""
    real = tmp_path / "real"
    real.mkdir()
    (real / "a.ra").write_text("automaton A { }\n", encoding="utf-8")
    links = tmp_path / "links"
    links.mkdir()
    (links / "a.ra").symlink_to(real / "a.ra")
    with locked(links / "a.ra"):
        fd = os.open(real, os.O_RDONLY)
        try:
            with pytest.raises(BlockingIOError):
                fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        finally:
            os.close(fd)


def test_a_huge_file_is_refused_without_being_read(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """A file of gigabytes named .ra (a log, a disk image) was read whole into memory before E0005 said it is too
    large: 5 GB of resident memory for `rac check`, swapping a small machine. At most one byte past the limit
    is read now; the message still gives the file's whole size."""
    import tracemalloc

    from rac.core.source import MAX_SOURCE_BYTES

    path = tmp_path / "huge.ra"
    with path.open("wb") as handle:  # sparse: no disk space taken
        handle.truncate(60 * MAX_SOURCE_BYTES)
    tracemalloc.start()
    try:
        assert main(["check", str(path)]) == 1
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    assert f"error[E0005]: file is too large ({60 * MAX_SOURCE_BYTES:,} bytes" in capsys.readouterr().out
    assert peak < 10 * MAX_SOURCE_BYTES  # the file is 60 times the limit
