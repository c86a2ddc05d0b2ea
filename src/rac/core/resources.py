"""What a stage may refuse to spend before it starts: the memory and time of loading a scenario
(:func:`estimate_load`) and the refusal, :class:`ScenarioTooLarge`; and the option every memory refusal names
as the one that sets the budget (:func:`memory_option`).

Here, in ``core``, and not beside the loader (:mod:`rac.model.checks`, which uses them): the ``rac``
command catches :class:`ScenarioTooLarge` around every sub-command, and must not load the model (or
numpy) to do so.
"""

from __future__ import annotations

import contextlib
from collections.abc import Iterator
from contextvars import ContextVar
from dataclasses import dataclass

from rac.core.diagnostics import RacError
from rac.core.numbers import format_bytes, size_option

__all__ = ["LOAD_BASE_BYTES", "LOAD_BYTES_PER_FILE_BYTE", "LOAD_BYTES_PER_SECOND", "LOAD_NOTICE_BYTES",
           "MEMORY_OPTION", "LoadEstimate", "ScenarioTooLarge", "estimate_load", "memory_option",
           "memory_option_limits", "memory_option_named"]

#: The option that sets the memory budget, as the engine commands name it (``rac verify --max-memory``).
MEMORY_OPTION = "--max-memory"
#: The option that sets the memory budget of the work running now, as its refusals name it: a context variable,
#: not an argument, because the budget's errors are raised deep in the explorations, learning and simulation,
#: which every command shares; ``rac sweep``'s tasks set their own (:func:`memory_option_named`).
# With it, whether that option is also the process's hard limit (``rac sweep``'s ``--task-memory`` sets RLIMIT_AS).
_memory_option: ContextVar[tuple[str, bool]] = ContextVar("memory_option", default=(MEMORY_OPTION, False))


def memory_option() -> str:
    """The option a refusal names as the one that sets the memory budget: :data:`MEMORY_OPTION`, or the one the
    caller said with :func:`memory_option_named`."""
    return _memory_option.get()[0]


def memory_option_limits() -> bool:
    """Whether :func:`memory_option` also sets the process's hard memory limit (``rac sweep --task-memory``): then a
    lower value lowers the limit with the budget, and running out of memory before the budget spoke is not
    prevented by lowering it (:func:`rac.engine.budget.out_of_memory` advises accordingly)."""
    return _memory_option.get()[1]


@contextlib.contextmanager
def memory_option_named(option: str, *, limits: bool = False) -> Iterator[None]:
    """Within the block, the budget's refusals name ``option`` (e.g. ``rac sweep``'s ``--task-memory``) as what
    sets the memory budget: a sweep's rows named ``--max-memory``, an option ``rac sweep`` does not have.
    ``limits``: the option's value is also the process's hard memory limit (:func:`memory_option_limits`)."""
    token = _memory_option.set((option, limits))
    try:
        yield
    finally:
        _memory_option.reset(token)

#: A scenario file larger than this is announced before it loads (``check_scenario``'s ``progress``):
#: at :data:`LOAD_BYTES_PER_SECOND` it takes a few seconds or more.
LOAD_NOTICE_BYTES = 4 * 2**20
#: How fast a scenario loads and its model's data is built, per byte of the file, for the announced time
#: only: a little below the slowest rate ``benchmarks/scenario_load.py`` measures (docs/benchmarks.md: 1.66 MB/s
#: idle; 1.24 MB/s for 10,000 lanelets and 2.0-2.4 MB/s for 400-1,500 obstacles with the 2 cores shared), so
#: the time said is an upper "about". It was 0.375 MB/s, measured on a loaded machine partly before issue 22's
#: load was made linear: some 54 s announced for a 20 MB scene of 400 obstacles that loads in 9-16 s.
LOAD_BYTES_PER_SECOND = 2**20
#: The peak memory of loading a scenario and building its model's data, beyond what the process held
#: before, per byte of the file: an upper estimate over what ``benchmarks/scenario_load.py`` measured
#: (docs/history.md, "Loading a large scenario (issue 22)"): lanelets cost about 43 bytes per file byte, 500
#: obstacles of 40 time steps 64 (549 MB for 8.6 MB), 1,500 of them 30. The file is held three times
#: over while it loads (its bytes, rac's XML tree, commonroad-io's) besides commonroad-io's objects
#: and rac's own.
LOAD_BYTES_PER_FILE_BYTE = 64
#: What any load costs besides: importing commonroad-io (and shapely, lxml) the first time, the
#: model's fixed tables.
LOAD_BASE_BYTES = 128 * 2**20


@dataclass(frozen=True)
class LoadEstimate:
    """What loading a scenario file of ``file_bytes`` and building its model's data is expected to
    cost: ``peak_bytes`` of memory at most (:data:`LOAD_BYTES_PER_FILE_BYTE`, :data:`LOAD_BASE_BYTES`)
    and about ``seconds`` (:data:`LOAD_BYTES_PER_SECOND`)."""

    file_bytes: int
    peak_bytes: int
    seconds: float


def estimate_load(file_bytes: int) -> LoadEstimate:
    """The :class:`LoadEstimate` of a scenario file of ``file_bytes`` bytes."""
    return LoadEstimate(file_bytes, LOAD_BASE_BYTES + LOAD_BYTES_PER_FILE_BYTE * file_bytes,
                        file_bytes / LOAD_BYTES_PER_SECOND)


class ScenarioTooLarge(RacError, MemoryError):
    """A scenario refused before it loads: its :class:`LoadEstimate` ``estimate`` exceeds the memory
    budget ``limit`` (bytes; ``--max-memory``, :func:`memory_option`). A ``MemoryError`` like the engine's
    budget errors: the file is not at fault, the budget is too small for it; ``rac`` reports it as a resource error."""

    def __init__(self, path: str, estimate: LoadEstimate, limit: int) -> None:
        self.path, self.estimate, self.limit = path, estimate, limit
        option = memory_option()
        super().__init__(
            f"the scenario {path} ({format_bytes(estimate.file_bytes)}) would need about "
            f"{format_bytes(estimate.peak_bytes)} of memory to load, more than the memory budget of "
            f"{format_bytes(limit)} ({option}); nothing was loaded: give rac more with "
            f"`{option} {size_option(estimate.peak_bytes)}` (on a machine that has it), or use a smaller "
            "scenario")
