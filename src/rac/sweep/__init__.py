"""``rac sweep``: one template ``.ra`` file with a ``model`` block, run over many CommonRoad scenarios
and a grid of model settings, one Dask task per (scenario, grid point) — docs/sweep.md.

The halves: :mod:`rac.sweep.grid` and :mod:`rac.sweep.task` say what the tasks are and run one;
:mod:`rac.sweep.run` sends them to Dask, :mod:`rac.sweep.store` keeps each row as it arrives,
:mod:`rac.sweep.report` merges, summarises and plots them. Dask is imported only when a sweep runs.

Example (in a script, under ``if __name__ == "__main__":``: the local cluster starts worker processes)::

    from rac.sweep import sweep

    frame = sweep("driving.ra", ["scenarios/"], sets={"exponent": [1, 2]}, task="verify",
                  options={"horizon": 2})
    frame.groupby("settings.exponent")["verdicts.Qb"].value_counts()

May import: rac, rac.compiler, core, lang, ir, check, model, runtime, engine, output, learning, verify, studies.
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from rac.sweep.api import Plan, SweepResult, default_folder, execute, plan, sweep

__all__ = ["Plan", "SweepResult", "default_folder", "execute", "plan", "sweep"]


def __getattr__(name: str) -> Any:
    # PEP 562: `rac.sweep.kinds` (the task list rac's parser reads) is a submodule, and importing it
    # runs this file: the API's imports (the grid, the templates, the checker) wait for first use.
    if name not in __all__:
        raise AttributeError(f"module 'rac.sweep' has no attribute {name!r}")
    value = getattr(importlib.import_module("rac.sweep.api"), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted({*globals(), *__all__})
