"""Running a sweep's tasks on Dask (``dask.distributed``).

:func:`connect` yields a :class:`distributed.Client`: of a ``LocalCluster`` that rac starts and stops
(one single-threaded worker process per core) or, given a scheduler address (``--scheduler``, or Dask's
own ``scheduler-address`` configuration), of an existing cluster. :func:`run_tasks` submits one Dask task
per :class:`~rac.sweep.task.TaskSpec` not already in the :class:`~rac.sweep.store.Store`, and stores each
row as it arrives. A task that raises, or whose worker died twice (Dask's ``KilledWorker``: the scheduler
allows one failure, so a task whose worker dies is retried once on another worker), becomes an error row;
Ctrl-C cancels what is left and returns what is done.

Dask is imported by these functions, never when this module is imported: ``import rac`` stays light.
"""

from __future__ import annotations

import contextlib
import logging
import os
import signal
import time
import uuid
import warnings
from collections.abc import Callable, Iterator, Sequence
from concurrent.futures import CancelledError  # what Dask's FutureCancelledError is
from dataclasses import dataclass, field
from importlib.util import find_spec
from multiprocessing import resource_tracker
from typing import TYPE_CHECKING, Any

import rac
from rac.core.diagnostics import RacError
from rac.engine.budget import machine_memory
from rac.output.progress import Heartbeat, Progress
from rac.sweep.store import Store
from rac.sweep.task import NOT_FAILED, run_task, source_digest

if TYPE_CHECKING:
    from distributed import Client

    from rac.sweep.task import TaskSpec

__all__ = ["ALLOWED_FAILURES", "BadSchedulerAddress", "Outcome", "connect", "error_row", "run_tasks", "task_function",
           "usable_cores", "workers_of"]

#: Dask's ``distributed.scheduler.allowed-failures`` for the clusters rac starts: a task whose worker dies
#: is retried once on another worker, then reported as an error row (``KilledWorker``).
ALLOWED_FAILURES = 1
#: What a row's ``error`` says when its task's worker died twice (``KilledWorker``).
KILLED = ("its worker died twice while running it (Dask's KilledWorker: a crash in native code, the operating "
          "system's out-of-memory killer or the worker's memory limit)")


class BadSchedulerAddress(RacError, ValueError):
    """A scheduler address Dask cannot use at all (no port, an unknown scheme, ``tls://`` without Dask's
    TLS settings): the user's to fix, not a cluster that could not be reached; ``address`` names it."""

    def __init__(self, address: str, reason: str) -> None:
        super().__init__(f"the scheduler address {address!r} is not one Dask can use ({reason}); give "
                         "tcp://HOST:PORT")
        self.address = address


#: A row: the result of one task (:func:`rac.sweep.task.run_task`).
Row = dict[str, object]


def task_function() -> Callable[[TaskSpec], Row]:
    """The function each Dask task runs on its spec: :func:`rac.sweep.task.run_task` (tests replace it)."""

    return run_task


def error_row(spec: TaskSpec, key: str, status: str, message: str, *, retry: bool = False) -> Row:
    """The row of a task that produced none itself (its worker died, it raised, it could not be sent):
    ``status`` and ``message``, whether a resumed sweep runs it again (``retry``), every other measurement None."""
    return {"key": key, **spec.names(),
            "settings": dict(spec.settings), "task": spec.task, "status": status, "error": message,
            "retry": retry, "seconds": 0.0, "peak_memory": None, "states": None, "scenario_size": None, "verdicts": {},
            "diagnostics": [], "details": None, **spec.limits(), "rac_version": rac.__version__,
            "rac_source": source_digest()}


@dataclass
class Outcome:
    """What :func:`run_tasks` did: the row of every task that has one (stored before or now) by task
    key, each spec's key, how many ran now and how many were skipped (stored before), how many stored
    rows are run again (their process was killed; other failures with ``retry_failed``), and whether
    Ctrl-C stopped it."""

    rows: dict[str, Row] = field(default_factory=dict)
    keys: list[str] = field(default_factory=list)  #: the key of each spec, in the order given
    ran: int = 0
    skipped: int = 0
    #: of those skipped, the rows not ok (an error of an environment since fixed among them): --retry-failed reruns
    skipped_not_ok: int = 0
    rerun_killed: int = 0  #: stored rows marked ``retry`` (the task's process was killed), run again
    rerun_failed: int = 0  #: other stored rows not ok, run again under ``retry_failed``
    #: stored ``timeout`` (``memory``) rows of another task timeout (memory limit) than this run's, run again
    rerun_limits: int = 0
    #: stored rows of another version of rac than this one (``rac_version``), run again
    rerun_version: int = 0
    #: the versions those rows name (``unknown``: a row of before rows held it)
    other_versions: set[str] = field(default_factory=set)
    #: stored rows of this version of rac but of other source files (``rac_source``: a development checkout
    #: changed since), run again
    rerun_source: int = 0
    interrupted: bool = False
    #: tasks the cluster cancelled before they gave a row, and Dask's reason (its scheduler gone:
    #: ``scheduler-connection-lost``): they never ran, so they have no row and the same command runs them again
    cancelled: int = 0
    cancelled_why: str = ""
    #: why a file of the output folder could not be written (a full disk, a read-only folder): a row (the sweep
    #: stopped there, as after Ctrl-C; the rows stored before stand) or results.* and the plots
    write_error: OSError | None = None


@contextlib.contextmanager
def connect(scheduler: str | None = None, workers: int | None = None, *,
            announce: Callable[[str], None] | None = None) -> Iterator[Client]:
    """A Dask client: of the cluster at ``scheduler`` (or Dask's ``scheduler-address`` configuration) when
    given, else of a ``LocalCluster`` of ``workers`` processes (default: one per core) with one thread
    each, closed on exit. ``announce`` receives the dashboard's address. Raises ``OSError`` when the
    scheduler cannot be reached, :class:`BadSchedulerAddress` when its address is not one Dask can use."""
    import dask  # dask: only when a sweep runs; `import rac.sweep` never loads it

    # distributed: only when a sweep runs; `import rac.sweep` never loads it
    from distributed import Client, LocalCluster

    address = scheduler or dask.config.get("scheduler-address", None)
    say = announce or (lambda _: None)
    with dask.config.set({"distributed.scheduler.allowed-failures": ALLOWED_FAILURES}):
        if address:
            try:
                client = Client(address, timeout="10s")
            except (OSError, TimeoutError) as exc:
                raise OSError(f"cannot connect to the Dask scheduler at {address}: {exc}") from exc
            except (ValueError, TypeError) as exc:  # Dask's parse of the address (ValueError: no port,
                # an unknown scheme; TypeError: tls:// without an SSL context): nothing was connected
                raise BadSchedulerAddress(str(address), str(exc)) from exc
            with client:
                workers = len(client.scheduler_info().get("workers", {}))
                say(f"dashboard: {client.dashboard_link} (the cluster at {address}, {_workers(workers)}{_bokeh()})")
                if not workers:  # Dask holds the tasks until a worker joins: without a word, the sweep seemed hung
                    say(f"the cluster at {address} has no worker yet: the tasks wait until one joins "
                        f"(dask worker {address})")
                yield client
            return
        n_workers = workers or usable_cores()
        with _held_signals() as held, warnings.catch_warnings():
            # another cluster holds the dashboard's usual port 8787: Dask takes another and says so
            warnings.filterwarnings("ignore", message=".*already in use.*")
            # each worker's memory limit its share of the machine: the tasks' budgets are half of it
            # (rac.sweep.task.worker_budget), so that side by side they stay within the machine together
            cluster = LocalCluster(n_workers=n_workers, threads_per_worker=1, processes=True,
                                   silence_logs=logging.ERROR, memory_limit=machine_memory() // n_workers)
        local: Client | None = None
        try:
            for number in held:  # a signal held back while the cluster started: now it can be closed
                signal.raise_signal(number)
            local = Client(cluster)
            say(f"dashboard: {local.dashboard_link} (a local cluster, {_workers(n_workers)}{_bokeh()})")
            yield local
        finally:
            # held while they close too: a second Ctrl-C in there left the cluster half closed, and Dask's exit
            # hook then waited some 10 s on it before the process could end
            with _held_signals() as held:
                if local is not None:
                    local.close()
                cluster.close()
            for number in held:  # the process was stopped meanwhile: as if just after
                signal.raise_signal(number)


def workers_of(client: Client) -> int | None:
    """How many workers the client's cluster has now; None when its scheduler does not answer within 5 s
    (or the client is closed): asked from the progress's thread, which must not hang on it."""
    try:
        identity = client.sync(client.scheduler.identity, n_workers=0, callback_timeout=5)
    except (AttributeError, OSError, RuntimeError, CancelledError):  # closed (no scheduler: AttributeError; its
        # loop closing: RuntimeError, CancelledError), the scheduler gone (CommClosedError) or slow (TimeoutError):
        # nothing is said of workers
        return None
    count = identity.get("n_workers") if isinstance(identity, dict) else None
    return count if isinstance(count, int) else None


def usable_cores() -> int:
    """The cores this process may run on (its CPU affinity: a batch system's allocation, ``taskset``), not
    the machine's: on 4 cores of a 64-core node, 4 workers, not 64."""
    try:
        return len(os.sched_getaffinity(0)) or 1
    except (AttributeError, OSError):  # no affinity on this platform (macOS, Windows)
        return os.cpu_count() or 1


def _workers(n: int) -> str:
    """``1 worker``, ``2 workers``."""
    return f"{n} worker{'s' * (n != 1)}"


def _bokeh() -> str:
    """What the dashboard line adds when the dashboard cannot show its pages."""
    return "" if find_spec("bokeh") is not None else "; its pages need bokeh: pip install bokeh"


@contextlib.contextmanager
def _held_signals() -> Iterator[list[int]]:
    """SIGINT and SIGTERM that reach rac in here are held back (the list yielded receives their numbers), for
    the caller to raise once a local cluster is up, or closed: raised in the middle of ``LocalCluster``'s start
    (or close), a ``KeyboardInterrupt`` left a half-started cluster, which Dask's exit hook then failed to
    close, with a traceback. And worker processes started in here never see SIGINT: Ctrl-C on a terminal
    reaches the whole process group, and rac (not each worker) is the one that stops the sweep and closes
    the cluster. SIGINT is blocked in this thread, so the threads the cluster starts here and the workers
    they spawn (also those Dask starts later in place of a dead one) inherit the blocked signal. (Ignoring
    SIGINT instead, as rac did, lost a Ctrl-C pressed during the start: the sweep went on.)"""
    held: list[int] = []

    def hold(number: int, frame: object) -> None:
        held.append(number)

    try:
        interrupt = signal.signal(signal.SIGINT, hold)
    except ValueError:  # not the main thread: signals cannot be changed, nor can Ctrl-C arrive here
        yield held
        return
    terminate = signal.getsignal(signal.SIGTERM)
    if callable(terminate):  # a handler of rac's (or the caller's): it runs once the cluster is up
        signal.signal(signal.SIGTERM, hold)
    # multiprocessing's resource tracker, started with a worker's first spawn, unblocks SIGINT in the thread
    # that starts it, which would then spawn that worker: started here first, it never starts in there
    resource_tracker.ensure_running()
    mask = signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT})
    try:
        yield held
    finally:
        signal.pthread_sigmask(signal.SIG_SETMASK, mask)  # a SIGINT that came meanwhile reaches hold() here
        signal.signal(signal.SIGINT, interrupt)
        if callable(terminate):
            signal.signal(signal.SIGTERM, terminate)


def pending(specs: Sequence[TaskSpec], store: Store, *, force: bool = False,
            retry_failed: bool = False) -> tuple[Outcome, dict[str, TaskSpec]]:
    """What is done and what is left: an :class:`Outcome` holding each spec's key and the rows ``store``
    has (none with ``force``), and the specs to run by key (specs with equal keys, the same scenario file
    under two paths, run once). A stored row marked ``retry`` (its task's process was killed: no verdict)
    is run again, and so is a row of another version of rac or of other source files of rac
    (:func:`rac.sweep.task.source_digest`) and a ``timeout`` or ``memory`` row of another
    limit than the spec's; with
    ``retry_failed`` every stored row that is not ok is."""
    outcome = Outcome()
    todo: dict[str, TaskSpec] = {}
    for spec in specs:
        key = spec.key()
        outcome.keys.append(key)
        if key in todo or key in outcome.rows:  # the same scenario file under another path: decided once
            continue
        stored = None if force else store.get(key)
        if stored is not None and stored.get("rac_version") != rac.__version__:
            # the version is not part of the key: a row of another rac answers that rac, not this one
            outcome.rerun_version += 1
            outcome.other_versions.add(str(stored.get("rac_version") or "unknown"))
            stored = None
        elif stored is not None and stored.get("rac_source") != source_digest():
            # nor is the code: a development checkout keeps its version from commit to commit
            outcome.rerun_source += 1
            stored = None
        elif stored is not None and stored.get("retry") is True:
            outcome.rerun_killed += 1
            stored = None
        elif stored is not None and _other_limit(stored, spec):
            outcome.rerun_limits += 1
            stored = None
        elif stored is not None and retry_failed and stored.get("status") != "ok":
            outcome.rerun_failed += 1
            stored = None
        if stored is not None:
            outcome.rows[key] = stored
        else:
            todo[key] = spec
    outcome.skipped = sum(1 for key in outcome.keys if key in outcome.rows)
    outcome.skipped_not_ok = sum(1 for key in outcome.keys if key in outcome.rows
                                 and outcome.rows[key].get("status") != "ok")
    return outcome, todo


def _other_limit(row: Row, spec: TaskSpec) -> bool:
    """Whether ``row`` is a ``timeout`` or ``memory`` row of a limit other than ``spec``'s: the limit is not
    part of the key, and the row answers the old limit, not the task (a row stored before rows held their
    limits counts as of no limit)."""
    limits = spec.limits()
    field = {"timeout": "task_timeout", "memory": "task_memory"}.get(str(row.get("status")))
    return field is not None and row.get(field) != limits[field]


def run_tasks(client: Client, specs: Sequence[TaskSpec], todo: dict[str, TaskSpec], outcome: Outcome,
              store: Store, *, on_row: Callable[[TaskSpec, Row], None] | None = None) -> Outcome:
    """Run each spec of ``todo`` (by key, from :func:`pending`) as one Dask task and store its row as it
    arrives, adding it to ``outcome``; ``on_row(spec, row)`` is called for each spec of ``specs`` with that
    key. Ctrl-C (``KeyboardInterrupt``) cancels the tasks not finished and returns what is done, with
    :attr:`Outcome.interrupted` set. A row that cannot be stored (a full disk) stops it the same way, with
    :attr:`Outcome.write_error` set."""
    from distributed import as_completed  # distributed: only when a sweep runs; `import rac.sweep` never loads it

    # distributed: only when a sweep runs; `import rac.sweep` never loads it
    from distributed.scheduler import KilledWorker

    function = task_function()
    sharing: dict[str, list[TaskSpec]] = {}  # the specs of each key, found once: not a walk of them all per row
    for other, other_key in zip(specs, outcome.keys):
        sharing.setdefault(other_key, []).append(other)
    token = uuid.uuid4().hex[:8]  # a key of this run only: a shared scheduler may still hold an earlier run's
    futures: dict[Any, tuple[TaskSpec, str]] = {}
    try:
        for key, spec in todo.items():
            future = client.submit(function, spec, key=f"rac-{spec.task}-{key}-{token}", pure=False, retries=0)
            futures[future] = (spec, key)
        for future in as_completed(list(futures)):
            spec, key = futures.pop(future)
            try:
                row = dict(future.result())
            except KilledWorker:
                row = error_row(spec, key, "error", KILLED, retry=True)  # killed, most likely from outside
            except CancelledError as exc:  # the scheduler went away (or someone cancelled it): the task never
                # ran, and an error row stored for it was reused by every later run as if it were the task's
                outcome.cancelled += 1
                outcome.cancelled_why = outcome.cancelled_why or str(getattr(exc, "reason", "") or "unknown")
                continue
            except Exception as exc:  # run_task never raises; a stand-in may, and so may unpickling
                row = error_row(spec, key, "error", f"{type(exc).__name__}: {exc}")
            row["key"] = key
            outcome.rows[key] = row  # first: a Ctrl-C while it is being stored still merges it
            outcome.ran += 1
            try:
                store.put(key, row)
            except OSError as exc:  # a full disk: the tasks left would be lost too, so the sweep stops here,
                # and the rows stored so far stand (the error escaped, and the summary of them with it)
                del outcome.rows[key]  # not stored: the same command runs it again
                outcome.ran -= 1
                outcome.write_error = exc
                with contextlib.suppress(Exception):
                    client.cancel(list(futures), force=True)
                return outcome
            if on_row is not None:
                for other in sharing.get(key, ()):
                    on_row(other, row)
    except KeyboardInterrupt:
        outcome.interrupted = True
        with contextlib.suppress(Exception):  # the cluster may already be going away
            client.cancel(list(futures), force=True)
    return outcome


def rows_in_order(specs: Sequence[TaskSpec], outcome: Outcome) -> list[Row]:
    """One row per spec that has one, in the order of ``specs`` (those :func:`run_tasks` ran); a spec
    sharing its key with another (the same scenario file under two paths) gets that row with its own path, also
    where its ``error`` and ``diagnostics`` quote the other's path."""
    rows: list[Row] = []
    for spec, key in zip(specs, outcome.keys):
        row = outcome.rows.get(key)
        if row is not None:
            rows.append(row if row.get("scenario") == spec.scenario else _renamed(row, spec))
    return rows


def _renamed(row: Row, spec: TaskSpec) -> Row:
    """``row`` (of the same scenario file under another path) as the row of ``spec``: its names, and its path
    in the texts that quote the other's (a load error names the file it read)."""
    other = row.get("scenario")

    def said(text: object) -> object:
        return text.replace(other, spec.scenario) if isinstance(text, str) and isinstance(other, str) else text

    diagnostics = row.get("diagnostics")
    return {**row, **spec.names(), "error": said(row.get("error")),
            "diagnostics": [said(d) for d in diagnostics] if isinstance(diagnostics, list) else diagnostics}


def _duration(seconds: float) -> str:
    """``75`` -> ``75 s``, ``4000`` -> ``67 min``."""
    return f"{seconds:.0f} s" if seconds < 120 else f"{seconds / 60:.0f} min"


class Tracker:
    """The sweep's progress on stderr: on a terminal a bar (tasks done, rate, ETA, failed so far), off one
    a plain line every few seconds (a :class:`rac.output.progress.Heartbeat`, every ``RAC_PROGRESS_INTERVAL``
    seconds); nothing when ``quiet``. Use as a context manager: :meth:`start` once, then :meth:`row` per row
    (:func:`run_tasks`' ``on_row``)."""

    def __init__(self, *, quiet: bool = False) -> None:
        self.quiet = quiet
        self.total = self.done = self.failed = 0
        self._beat = _Lines(self, enabled=False if quiet else None)
        self._bar: Progress | None = None
        self._started = time.monotonic()
        #: the cluster's worker count now (:func:`workers_of`), when known: a line of tasks left and no worker says so
        self.workers: Callable[[], int | None] | None = None

    def __enter__(self) -> Tracker:
        self._beat.__enter__()
        return self

    def __exit__(self, *exc: object) -> None:
        if self._bar is not None:
            self._bar.close()
        self._beat.__exit__(None, None, None)

    def start(self, to_run: int, skipped: int) -> None:
        """``to_run`` tasks are about to be sent, ``skipped`` were done by an earlier run."""
        self.total, self._started = to_run, time.monotonic()
        self._bar = Progress(total=to_run, desc="sweep", unit="tasks", enabled=False if self.quiet else None)

    def row(self, spec: TaskSpec, row: Row) -> None:
        """A task's row arrived."""
        self.done += 1
        self.failed += row.get("status") not in NOT_FAILED  # as the summary counts them: undecided is no failure
        if self._bar is not None:
            self._bar.set_postfix(failed=self.failed)
            self._bar.update()

    def line(self) -> str:
        """The progress in words: ``12 of 40 tasks done, 1 failed, 9.5 tasks/min, ETA 3 min``; before
        :meth:`start`, that the cluster is awaited."""
        elapsed = time.monotonic() - self._started
        if self._bar is None:  # no cluster yet (it starts, or its scheduler does not answer): no task was sent
            return f"waiting for the Dask cluster, no task sent yet; {_duration(elapsed)}"
        text = f"{self.done} of {self.total} tasks done, {self.failed} failed"
        if self.done:
            rate = self.done / max(elapsed, 1e-9)
            per_minute = rate * 60
            text += f", {per_minute:.{1 if per_minute < 100 else 0}f} tasks/min, " \
                    f"ETA {_duration((self.total - self.done) / rate)}"
        if self.done < self.total and self.workers is not None and self.workers() == 0:
            # every worker gone (or none joined): Dask holds the tasks, and "0 of 40 tasks done" alone looked hung
            text += "; the cluster has no worker: the tasks wait until one joins"
        return f"{text}; {_duration(elapsed)}"


class _Lines(Heartbeat):
    """The heartbeat of a sweep: its line is the :class:`Tracker`'s."""

    def __init__(self, tracker: Tracker, *, enabled: bool | None) -> None:
        super().__init__("rac sweep", enabled=enabled)
        self.tracker = tracker

    def line(self) -> str:
        return f"{self.command}: {self.tracker.line()}"
