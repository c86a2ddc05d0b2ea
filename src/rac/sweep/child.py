"""The child process of one ``rac sweep`` task: ``python -m rac.sweep.child [PARENT_PID]``.

:func:`rac.sweep.task.run_task` starts it with the :class:`~rac.sweep.task.TaskSpec` as JSON on
standard input; it runs the task (:mod:`rac.sweep.work`) under the memory limit and writes the
task's part of the row as JSON on standard output. Kept apart from :mod:`rac.sweep.task` so that
the parent's module never imports what the task runs.
"""

from __future__ import annotations

import json
import os
import resource
import sys
import threading
import time

from rac.sweep import work
from rac.sweep.task import OUT_OF_MEMORY, TaskSpec, memory_error


def _leave_with_parent(parent: int) -> None:
    """Exit when the parent ``parent`` (the sweep's worker) is gone, even before this call: a task whose
    worker died is rerun elsewhere."""

    def watch() -> None:
        while os.getppid() == parent:
            time.sleep(0.5)
        os._exit(1)

    threading.Thread(target=watch, name="rac-sweep-parent", daemon=True).start()


def address_space() -> int:
    """The bytes of address space this process maps now (Linux: ``/proc/self/statm``; elsewhere 0)."""
    try:
        with open("/proc/self/statm", encoding="ascii") as statm:
            return int(statm.read().split()[0]) * resource.getpagesize()
    except (OSError, ValueError, IndexError):
        return 0


def _limit_memory(limit: int) -> None:
    """Limit the address space to ``limit`` bytes more than the process maps now, its modules loaded (never
    above the hard limit already set). The modules map about 280 MB of address space of which a third is
    resident (shared libraries, numpy's thread pool): counted against the limit, they left a task of
    ``--task-memory 300M`` 20 MB, and every task of a real scenario was a ``memory`` row at 90 MB resident."""
    limit += address_space()
    _, hard = resource.getrlimit(resource.RLIMIT_AS)
    if hard != resource.RLIM_INFINITY:
        limit = min(limit, hard)
    resource.setrlimit(resource.RLIMIT_AS, (limit, hard))


def main(argv: list[str] | None = None) -> int:
    """``python -m rac.sweep.child [PARENT_PID]``: read a :class:`TaskSpec` as JSON on standard input, run
    it, write the task's part of the row as JSON on standard output; leave when the process
    ``PARENT_PID`` (default: the parent at the start) is no longer the parent."""
    argv = sys.argv[1:] if argv is None else argv
    _leave_with_parent(int(argv[0]) if argv else os.getppid())
    spec = TaskSpec.from_json(json.load(sys.stdin))
    sys.stdout.flush()
    result = os.fdopen(os.dup(1), "w", encoding="utf-8")
    os.dup2(2, 1)  # whatever the task prints goes to standard error, not into the result
    work.load(spec.task)  # the task's modules, before the memory limit: it limits the task, not them
    if spec.memory is not None:
        _limit_memory(spec.memory)
    row = work.execute(spec)
    if spec.memory is not None and (row["status"] == "memory" or row["status"] in ("failed", "error", "undecided") and
                                    any(sign in str(row["error"]) for sign in OUT_OF_MEMORY)):
        row.update(status="memory", error=memory_error(spec.memory, str(row["error"])))
    row["peak_memory"] = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024  # kB on Linux
    with result:
        json.dump(row, result)
    return 0



if __name__ == "__main__":
    sys.exit(main())
