"""Stand-ins for :func:`rac.sweep.task.run_task` in tests/sweep/test_sweep_dask.py: small functions a Dask worker
process can import (by this module's name) to kill itself, sleep or answer at once.

A stand-in's behaviour is chosen by its scenario's file name, and it remembers across worker processes
with marker files beside the scenario (a killed worker forgets everything else)::

    monkeypatch.setattr("rac.sweep.run.task_function", lambda: sweep_helpers.kill_once)
"""

from __future__ import annotations

import os
import signal
import threading
import time
from pathlib import Path

import psutil

import rac
from rac.sweep.task import TaskSpec, run_task, source_digest


def row(spec: TaskSpec, status: str = "ok", **fields: object) -> dict[str, object]:
    """A row as :func:`rac.sweep.task.run_task` returns it, with ``fields`` replaced; ``details`` says
    which process made it."""
    return {"key": spec.key(), "scenario": spec.scenario, "scenario_name": Path(spec.scenario).stem,
            "settings": dict(spec.settings), "task": spec.task, "status": status, "error": None, "seconds": 0.01,
            "peak_memory": None, "states": 1, "scenario_size": 2, "verdicts": {"Stays": "satisfied"},
            "diagnostics": [], "details": {"pid": os.getpid()}, "rac_version": rac.__version__,
            "rac_source": source_digest(), **fields}


def marker(spec: TaskSpec, what: str) -> Path:
    """The marker file ``SCENARIO.WHAT`` beside the scenario."""
    return Path(spec.scenario).with_suffix(f".{what}")


def kill_once(spec: TaskSpec) -> dict[str, object]:
    """Kill the worker process running it (SIGKILL: no goodbye to the scheduler) the first time it runs
    on a scenario named ``kill*``; a row otherwise, which says how many attempts there were."""
    attempts = marker(spec, "attempts")
    count = int(attempts.read_text()) + 1 if attempts.exists() else 1
    attempts.write_text(str(count))
    if Path(spec.scenario).name.startswith("kill") and count == 1:
        os.kill(os.getpid(), signal.SIGKILL)
    return row(spec, details={"pid": os.getpid(), "attempts": count})


def kill_always(spec: TaskSpec) -> dict[str, object]:
    """Kill the worker process running it, every time."""
    os.kill(os.getpid(), signal.SIGKILL)
    return row(spec)  # never reached


def slow(spec: TaskSpec) -> dict[str, object]:
    """A row after 0.1 s on a scenario named ``fast*``, after 30 s on any other (a sweep to interrupt)."""
    time.sleep(0.1 if Path(spec.scenario).name.startswith("fast") else 30)
    return row(spec)


def waits(spec: TaskSpec) -> dict[str, object]:
    """A row at once on a scenario named ``fast*``, after 3 s on any other (a task still to come when the
    first row arrives, yet one that does not hold a worker for long)."""
    time.sleep(0 if Path(spec.scenario).name.startswith("fast") else 3)
    return row(spec)


def raises(spec: TaskSpec) -> dict[str, object]:
    """A stand-in that breaks the promise of :func:`rac.sweep.task.run_task` never to raise."""
    raise RuntimeError(f"no row for {Path(spec.scenario).name}")


def run_task_killed(spec: TaskSpec) -> dict[str, object]:
    """The real :func:`rac.sweep.task.run_task`, whose task process (the child of this process) is killed
    with SIGKILL as soon as it starts, as the out-of-memory killer would."""
    me = psutil.Process()
    done = threading.Event()

    def kill_the_child() -> None:
        while not done.is_set():
            for child in me.children():
                try:
                    if "rac.sweep.child" in " ".join(child.cmdline()):
                        child.send_signal(signal.SIGKILL)
                        return
                except psutil.Error:  # gone, or not yet readable: look again
                    pass
            time.sleep(0.01)

    killer = threading.Thread(target=kill_the_child, daemon=True)
    killer.start()
    try:
        return run_task(spec)
    finally:
        done.set()
        killer.join()


def kill_task_process_once(spec: TaskSpec) -> dict[str, object]:
    """:func:`run_task_killed` the first time it runs on a scenario, the real task after that."""
    attempts = marker(spec, "attempts")
    count = int(attempts.read_text()) + 1 if attempts.exists() else 1
    attempts.write_text(str(count))
    return run_task_killed(spec) if count == 1 else run_task(spec)
