"""One task of ``rac sweep``: a template instantiated with one scenario and one grid point, checked
and run as one command (``check``, ``verify``, ``preanalyse`` or ``experiment``), giving one result row.

:func:`run_task` runs the task in a child process, ``python -m rac.sweep.child`` reading the
:class:`TaskSpec` as JSON on its standard input: a Dask worker is a daemonic process, which cannot
have ``multiprocessing`` children, but can start a subprocess. The child runs in a process group
of its own, killed whole when the task passes its ``timeout``; its address space is limited to
``memory`` bytes more than its imported modules map (``RLIMIT_AS``, set once they are imported), so that a task that
needs more fails with ``MemoryError`` in the child instead of taking the worker down. The child
writes its part of the row as JSON on its standard output (anything the task prints goes to its
standard error) and leaves when its parent does. What it has found so far it keeps in a partial file
(:attr:`TaskSpec.partial`: a ``verify`` task's verdicts, a ``preanalyse`` task's answers): a task killed at its
timeout keeps them in its row.
What the child runs is :mod:`rac.sweep.work`.

The row (:func:`run_task`'s docstring lists its keys) never carries an exception: whatever
happens becomes its ``status`` and ``error``.
"""

from __future__ import annotations

import dataclasses
import functools
import hashlib
import json
import os
import signal
import subprocess
import sys
import tempfile
import time
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import rac
from rac.engine.budget import DEFAULT_FRACTION, format_bytes
from rac.lang.resources import grammar_path, stdlib_dir
from rac.sweep.kinds import TASKS
from rac.verify.status import VERDICTS as report_verdicts

__all__ = ["KILLING_SIGNALS", "NOT_FAILED", "OPTIONS", "OUT_OF_MEMORY", "PARTIAL_FIELDS", "STATUSES", "TASKS",
           "TASK_OPTIONS", "VERDICTS",
           "TaskSpec", "digest_of", "memory_error", "run_task", "scenario_bytes", "scenario_digest", "source_digest"]

#: What a task runs: the command of the same name on one file.
#: A row's ``status``: "ok" (no errors; every query decided), "failed" (errors in the file, a query
#: not satisfied), "undecided" (a query unknown beyond a budget, or unsupported: no failure, no
#: answer), "error" (rac could not run it), "timeout" and "memory" (the task's limits).
STATUSES = ("ok", "failed", "undecided", "error", "timeout", "memory")
#: The statuses that are no failure: the tasks "failed" so far (the progress) and in all (the summary) are the
#: others.
NOT_FAILED = ("ok", "undecided")
#: The verdicts a row's ``verdicts`` holds (a query whose answer is a value, ``Pr[<=T](<> p)`` or
#: ``simulate``, has none and is not listed): rac verify's own (:data:`rac.verify.report.VERDICTS`).
VERDICTS = report_verdicts
#: The options a task takes (:attr:`TaskSpec.options`), as the commands' options of the same names.
OPTIONS: dict[str, str] = {
    "horizon": "horizon in seconds (default: the automaton's)",
    "seed": "seed of simulations and learning (default: fresh)",
    "max_states": "give up (verdict unknown) beyond this many states (default 5,000,000)",
    "episodes": "episode budget of learning (experiment: per run, default 500; verify: learning queries)",
    "seeds": "experiment: the seeds, e.g. 1,2,3 (default 1..5)",
    "runs": "preanalyse: simulated runs per setting (default 100); experiment: evaluation runs (default 100)",
    "reward_function": "experiment: the reward function of the RF combinations (default: the paper's Eq. 9)",
    "explore": "experiment: how learning episodes explore, uniform (default) or goal (rac experiment --explore)",
}
#: The options each task uses (:mod:`rac.sweep.work`): another is refused by :func:`rac.sweep.api.plan`, where it
#: was ignored, silently.
TASK_OPTIONS: dict[str, tuple[str, ...]] = {
    "check": (),
    "verify": ("horizon", "seed", "max_states", "episodes"),
    "preanalyse": ("horizon", "seed", "max_states", "runs"),
    "experiment": ("horizon", "seed", "max_states", "episodes", "seeds", "runs", "reward_function", "explore"),
}
#: What an error says when the task ran out of memory under its limit (Python, numpy, C++, the loader;
#: CPython's SystemError "returned NULL without setting an exception" when even the MemoryError failed).
OUT_OF_MEMORY = ("MemoryError", "Unable to allocate", "Cannot allocate memory", "bad_alloc", "out of memory",
                  "SystemError", "failed to map segment from shared object", "Memory allocation still failed")
#: The signals that end a task's process from outside (the out-of-memory killer's SIGKILL, a shutdown's
#: SIGTERM): such a death says nothing about the task, so its row is marked ``retry`` and a resumed sweep
#: runs it again. A crash (SIGSEGV, SIGABRT) is the task's own doing and stays a plain error.
KILLING_SIGNALS = frozenset({signal.SIGKILL, signal.SIGTERM})
#: What a task's partial file (:attr:`TaskSpec.partial`) may give the row of a task killed at its timeout; besides,
#: ``kept`` (what it holds, in words) goes into the row's error, and ``running`` (the index in ``details`` of the part
#: that was running, or null) says which part of the details gets that error.
PARTIAL_FIELDS = ("details", "verdicts", "states", "seed", "scenario_size")
#: The last characters of the child's standard error an error row quotes.
_STDERR_TAIL = 2000


@dataclass(frozen=True)
class TaskSpec:
    """One task: the template, one scenario, one grid point, the command and its options, and the
    limits (which do not change what the task computes, so they are not part of :meth:`key`)."""

    template: str  #: path of the template .ra (relative scenario paths resolve from its folder)
    template_text: str  #: its text, read once by the caller
    scenario: str  #: path of one CommonRoad XML file
    settings: tuple[tuple[str, str], ...]  #: one point of the --set grid: (model setting name, value text)
    task: str  #: one of TASKS
    options: tuple[tuple[str, str], ...] = ()  #: e.g. ("horizon", "2"), ("seed", "1"); see OPTIONS
    timeout: float | None = None  #: seconds; past it the task is a "timeout" row
    memory: int | None = None  #: bytes of address space; past it the task is a "memory" row
    #: :func:`scenario_digest` of the scenario, when the caller hashed it already (:func:`rac.sweep.api.plan`
    #: hashes each file once, not once per grid point); None: :meth:`key` reads the file
    scenario_digest: str | None = None
    #: the id of the scenario's planning problem this task runs (the model block's ``planning_problem``), chosen
    #: by :func:`rac.sweep.api.plan` for a file with several; None: the template's choice
    planning_problem: int | None = None
    #: the memory budget of the task's command (``rac verify``'s ``--max-memory``) when ``memory`` is None: its
    #: share of the Dask worker's memory (:func:`worker_budget`; set where the task runs, not part of the key);
    #: None: the command's own default, half the machine's memory, which tasks side by side would each take
    budget: int | None = None
    #: a file the task keeps what it has found so far in, as part of its row (:data:`PARTIAL_FIELDS`; set by
    #: :func:`run_task`, not part of the key): the row of a task killed at its timeout keeps it; None: none
    partial: str | None = None

    def __post_init__(self) -> None:
        if self.task not in TASKS:
            raise ValueError(f"unknown task `{self.task}`: the tasks are {', '.join(TASKS)}")

    def names(self) -> dict[str, str | int | None]:
        """The row fields that name the task's scenario: its path, the file's stem, and the planning problem
        the sweep chose (None: the template's choice)."""
        return {"scenario": self.scenario, "scenario_name": Path(self.scenario).stem,
                "planning_problem": self.planning_problem}

    def key(self) -> str:
        """16 hex digits of the SHA-256 of the scenario file's bytes, the template's text, the settings,
        the task and its options (settings and options in name order): equal inputs, equal key, in
        any process. A scenario that cannot be read is keyed by its absolute path."""
        scenario = self.scenario_digest or scenario_digest(self.scenario)
        inputs: list[object] = [scenario, self.template_text, sorted(map(list, self.settings)), self.task,
                                sorted(map(list, self.options))]
        if self.planning_problem is not None:  # only then: the rows stored before it existed keep their keys
            inputs.append(self.planning_problem)
        payload = json.dumps(inputs, ensure_ascii=True)
        return hashlib.sha256(payload.encode("ascii")).hexdigest()[:16]

    def limits(self) -> dict[str, Any]:
        """The task's limits as its row holds them (``task_timeout`` in seconds, ``task_memory`` in bytes;
        None: none): not part of the key, so a stored ``timeout`` or ``memory`` row says which limit it met."""
        return {"task_timeout": self.timeout, "task_memory": self.memory}

    def to_json(self) -> dict[str, Any]:
        """The spec as JSON data (what :func:`run_task` sends the child)."""
        return asdict(self)

    @classmethod
    def from_json(cls, data: dict[str, Any]) -> TaskSpec:
        """The spec :meth:`to_json` gave."""
        pairs = {name: tuple((str(a), str(b)) for a, b in data.get(name, ())) for name in ("settings", "options")}
        return cls(data["template"], data["template_text"], data["scenario"], pairs["settings"], data["task"],
                   pairs["options"], data.get("timeout"), data.get("memory"), data.get("scenario_digest"),
                   data.get("planning_problem"), data.get("budget"), data.get("partial"))


def scenario_digest(path: str | os.PathLike[str]) -> str:
    """What a task's key holds of its scenario file: the SHA-256 of its bytes, or ``unreadable:`` and its absolute
    path when it cannot be read or is no regular file (a FIFO's read would wait for a writer for ever, a
    device's never end; the task's check then says what it is)."""
    try:
        return digest_of(scenario_bytes(path))
    except OSError:
        return "unreadable:" + os.path.abspath(path)


def scenario_bytes(path: str | os.PathLike[str]) -> bytes:
    """The scenario file's bytes; ``OSError`` when it cannot be read or is no regular file (see
    :func:`scenario_digest`)."""
    if not Path(path).is_file():
        raise OSError(f"not a regular file: {path}")
    return Path(path).read_bytes()


def digest_of(data: bytes) -> str:
    """:func:`scenario_digest` of a readable file whose bytes are ``data``."""
    return hashlib.sha256(data).hexdigest()


@functools.cache
def source_digest() -> str:
    """16 hex digits of the SHA-256 of rac's own files as this process imports them (each file's path below the
    package and its bytes; ``__pycache__`` aside), with the grammar and the standard library wherever rac reads
    them (:mod:`rac.lang.resources`: inside an installed wheel, at the top of a checkout), computed once per
    process. rac's version stays the same between the commits of a development checkout: this changes with
    every edit, so a row computed by other code (its ``rac_source``) is not reused; the same code installed
    or checked out gives the same digest (a Dask worker may import the other copy)."""
    package = Path(rac.__file__).resolve().parent
    shipped = {"grammar": grammar_path().parent, "stdlib": stdlib_dir()}
    files = [(path.relative_to(package).as_posix(), path) for path in package.rglob("*")
             if path.is_file() and "__pycache__" not in path.parts
             and path.relative_to(package).parts[0] not in shipped]
    files += [(f"{name}/{path.relative_to(folder).as_posix()}", path) for name, folder in shipped.items()
              for path in folder.rglob("*") if path.is_file() and "__pycache__" not in path.parts]
    digest = hashlib.sha256()
    for name, path in sorted(files):
        digest.update(name.encode("utf-8") + b"\0")
        digest.update(hashlib.sha256(path.read_bytes()).digest())
    return digest.hexdigest()[:16]


def _row(spec: TaskSpec) -> dict[str, Any]:
    """The row before the task ran: what the spec says, and an error nothing replaced yet."""
    return {"key": spec.key(), **spec.names(),
            "settings": dict(spec.settings), "task": spec.task, "status": "error",
            "error": "the task gave no result", "retry": False, "seconds": 0.0, "peak_memory": None, "states": None,
            "scenario_size": None, "verdicts": {}, "diagnostics": [], "details": None, **spec.limits(),
            "rac_version": rac.__version__, "rac_source": source_digest()}


def run_task(spec: TaskSpec) -> dict[str, object]:
    """One result row; never raises (an exception, a timeout, the memory limit, an unreadable or broken
    scenario, a template that fails ``rac check`` all become a row with status "error"/"failed" and an
    ``error`` text).

    Keys (always present, JSON-serialisable): key, scenario (path), scenario_name (the file's stem),
    planning_problem (the id the sweep chose for a file with several; None: the template's choice), settings
    (dict name -> value text), task, status (:data:`STATUSES`), error (str or None), retry (bool:
    the task's process was killed from outside, :data:`KILLING_SIGNALS`, so the row is no verdict and a
    resumed sweep runs the task again), task_timeout and task_memory (the limits it ran under,
    :meth:`TaskSpec.limits`), rac_version (the version of rac that ran it: a resumed sweep runs a row of another
    version again), rac_source (:func:`source_digest` of the rac that ran it: the same, for a row of other code
    under the same version), seconds
    (the task's own time in the child; the whole time when the child gave no result), peak_memory
    (bytes, the child's largest resident size, or None), states (int or None), scenario_size (int:
    lanelets + obstacles, or None), verdicts (dict query name -> :data:`VERDICTS`; {} for check),
    diagnostics (list of "CODE message" of the check's errors and warnings), details (the preanalysis
    row(s), or the experiment's summary table, as a list of dicts; None otherwise); and wall_seconds
    (the time of the whole task, the child's start included)."""
    start = time.perf_counter()
    row = _row(spec)
    if spec.memory is None and spec.budget is None:
        spec = dataclasses.replace(spec, budget=worker_budget())
    try:
        row.update(_in_child(spec))
    except Exception as exc:  # a row, never an exception: the sweep goes on
        row.update(status="error", error=f"rac could not run the task: {type(exc).__name__}: {exc}")
    row["wall_seconds"] = time.perf_counter() - start
    if not row["seconds"]:
        row["seconds"] = row["wall_seconds"]
    return row


def worker_budget() -> int | None:
    """The memory budget of a task run by a Dask worker: :data:`~rac.engine.budget.DEFAULT_FRACTION` of the
    worker's memory limit (a local cluster gives each worker its share of the machine), so that the tasks
    running side by side stay within the machine's memory together, where each took half of it (two workers:
    all of it; four: twice it, and the machine swapped before any budget spoke); None outside a worker or
    for a worker without a limit (the command's own default then)."""
    try:
        # distributed: only a task run by a Dask worker asks it; importing rac.sweep.task stays light
        from distributed import get_worker

        limit = get_worker().memory_manager.memory_limit
    except (ImportError, ValueError):  # not in a worker (the task runs in this process)
        return None
    return int(limit * DEFAULT_FRACTION) if limit else None


def _environment() -> dict[str, str]:
    """The child's environment: it imports the same rac as this process; one thread for numerical
    libraries (a sweep runs tasks side by side, one per core)."""
    env = dict(os.environ)
    parent = str(Path(rac.__file__).resolve().parent.parent)
    env["PYTHONPATH"] = os.pathsep.join([parent, *filter(None, env.get("PYTHONPATH", "").split(os.pathsep))])
    for name in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
        env.setdefault(name, "1")
    env["PYTHONIOENCODING"] = "utf-8"
    return env


def _kill(process: subprocess.Popen[bytes]) -> None:
    """Kill the child's whole process group (what it started too)."""
    try:
        os.killpg(process.pid, signal.SIGKILL)
    except (ProcessLookupError, PermissionError):  # gone already
        pass


def _in_child(spec: TaskSpec) -> dict[str, Any]:
    """Run ``spec`` in ``python -m rac.sweep.child``; its part of the row."""
    with tempfile.TemporaryDirectory(prefix="rac-task-") as folder:  # the task's partial file, removed with it
        partial = os.path.join(folder, "partial.json")
        absolute = TaskSpec(**{**asdict(spec), "template": os.path.abspath(spec.template),
                               "scenario": os.path.abspath(spec.scenario), "settings": spec.settings,
                               "options": spec.options, "partial": partial})
        process = subprocess.Popen([sys.executable, "-m", "rac.sweep.child", str(os.getpid())],
                                   stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                                   env=_environment(), start_new_session=True)
        start = time.perf_counter()
        try:
            out, err = process.communicate(json.dumps(absolute.to_json()).encode("utf-8"), timeout=spec.timeout)
        except subprocess.TimeoutExpired:
            _kill(process)
            process.communicate()
            return {"status": "timeout", "seconds": time.perf_counter() - start,
                    **_kept(partial, f"ran past the task timeout of {spec.timeout:g} s")}
        finally:
            _kill(process)  # on any exit: nothing of the task outlives it
    seconds = time.perf_counter() - start
    try:
        result: dict[str, Any] = json.loads(out.decode("utf-8"))
        return result
    except ValueError:
        pass
    stderr = err.decode("utf-8", "replace")
    code = process.returncode
    how = f"died of signal {signal.Signals(-code).name}" if code < 0 else f"exited with status {code}"
    tail = stderr[-_STDERR_TAIL:].strip()
    if spec.memory is not None and any(sign in stderr for sign in OUT_OF_MEMORY):
        return {"status": "memory", "error": memory_error(spec.memory, f"the task's process {how}"),
                "seconds": seconds}
    killed = code < 0 and -code in KILLING_SIGNALS
    return {"status": "error", "error": f"the task's process {how}" + (f":\n{tail}" if tail else ""),
            "retry": killed, "seconds": seconds}


def _kept(partial: str, error: str) -> dict[str, Any]:
    """The row fields a killed task keeps from its partial file ``partial`` (:data:`PARTIAL_FIELDS`), with
    ``error`` saying what they are; ``error`` alone when the task had written none (or it cannot be read)."""
    try:
        with open(partial, encoding="utf-8") as file:
            found = json.load(file)
    except (OSError, ValueError):  # nothing found yet: the file was never written
        return {"error": error}
    if not isinstance(found, dict):
        return {"error": error}
    kept = {name: found[name] for name in PARTIAL_FIELDS if name in found}
    if not found.get("kept"):  # no answers yet: what the task knew of its scenario (its size) alone
        return {"error": error, **({"scenario_size": kept["scenario_size"]} if "scenario_size" in kept else {})}
    running, details = found.get("running"), kept.get("details")
    if isinstance(running, int) and isinstance(details, list) and 0 <= running < len(details) \
            and isinstance(details[running], dict):  # the part cut short says why it has no more answers
        details[running].setdefault("error", error)
    return {"error": f"{error}; {found['kept']}", **kept}


def memory_error(limit: int, what: str) -> str:
    return f"{what}: out of memory under the task memory limit of {format_bytes(limit)}"
