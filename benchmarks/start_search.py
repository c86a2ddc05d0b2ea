"""Qd's search from the start at its worst, its memory: ``python benchmarks/start_search.py [--quick]``.

Where the model is too large to explore, ``rac verify`` decides ``control: A[] !collide() && !offroad()``
by the runtime shield searching the whole horizon from the start (:mod:`rac.verify.symbolic`), within a
budget of work (:data:`rac.verify.symbolic.START_WORK`) and ``--max-memory``. Its worst is a scene where
no fixed continuation carries an action, so that every layer is expanded until the budget is spent: here
the tutorial road with 45 actions every 0.2 s (:data:`rac.model.scenes.TUTORIAL_45`, 4 s), its fixed
continuations switched off. Each case runs in a child process of its own (``benchmarks/children.py``) and
reports the search's nodes, its time, the largest memory the search estimated before allocating
(:data:`rac.engine.lookahead.SUCCESSOR_BYTES`, :data:`~rac.engine.lookahead.LAYER_BYTES`) and the child's
peak RSS growth over its peak before the search (after a one-node search that loads the model's tables).

Targets: the peak RSS growth stays within the memory limit where one is given (the search stops before it
allocates past it), and within the whole budget's search at most :data:`GOAL_MB` (it was about 900 MB before
the layers were merged in place). ``--quick``: a tenth of the work budget (under 10 s).
"""

from __future__ import annotations

import argparse
import datetime
import json
import platform
import sys
import tempfile
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

HERE = Path(__file__).resolve().parent
REPOSITORY = HERE.parent
DEFAULT_OUTPUT = HERE / "results" / "start_search.md"

try:  # benchmark the installed rac; in a checkout without it, the checkout's src/
    import rac
except ImportError:
    sys.path.insert(0, str(REPOSITORY / "src"))
    import rac

import children  # noqa: E402 - benchmarks/, on sys.path as the script's folder
from children import peak_rss_mb, seconds  # noqa: E402

RAC_PATH = Path(rac.__file__).resolve().parent.parent
#: (share of START_WORK, memory limit in MB or None): the full run's cases, and --quick's.
CASES: tuple[tuple[float, int | None], ...] = ((1.0, None), (1.0, 200), (1.0, 50))
QUICK_CASES: tuple[tuple[float, int | None], ...] = ((0.1, None), (0.1, 20))
#: The most peak RSS growth the whole budget's search may have without a limit (MB).
GOAL_MB = 600
CHILD_TIMEOUT = 600  # seconds
HORIZON_SECONDS = 4
COLUMNS = ("work", "memory limit", "nodes spent", "stopped by", "largest estimate", "peak RSS growth", "time")
MB = 2**20
SETTINGS = ("exponent 2", "decide_period 0.2", "granularity 0.25", "max_speed 20",
            "action jerk in [-2, 2] step 0.5", "action turn in [-0.4, 0.4] step 0.2")


def tutorial(folder: Path) -> Path:
    """A file over the tutorial road with :data:`SETTINGS` (those of ``TUTORIAL_45``), in ``folder``."""
    from rac.model.scenes import TUTORIAL_45, write_scene

    assert SETTINGS == TUTORIAL_45, "benchmarks/start_search.py: TUTORIAL_45 changed; update SETTINGS"
    write_scene("tutorial", folder / "tutorial.xml")
    model = "\n".join(f"        {line}" for line in ('scenario "tutorial.xml"', *SETTINGS, "bind near = false"))
    path = folder / "tutorial.ra"
    path.write_text(f"""automaton Start {{
    input near : bool
    reward sa
    objective sa
    sample every 0.1
    horizon {HORIZON_SECONDS}
    initial location Normal {{ sa' == 1 }}
    model {{
{model}
    }}
}}
""", encoding="utf-8")
    return path


def measure(share: float, limit_mb: int | None) -> dict[str, Any]:
    """The start search over the tutorial road at ``share`` of its work budget and a memory limit of
    ``limit_mb`` MB (None: none), every layer expanded; its nodes, time, estimate and peak RSS growth."""
    import numpy as np

    from rac.compiler import compile_file
    from rac.engine.lookahead import Lookahead, LookaheadSettings
    from rac.model.native import NativeModel
    from rac.verify import symbolic

    with tempfile.TemporaryDirectory() as folder:
        data = compile_file(tutorial(Path(folder))).model_data
    assert data is not None
    horizon = round(HORIZON_SECONDS / float(data.period))
    start = NativeModel(data).initial_state()
    row = np.array([0, *list(start)[:7]], dtype=np.int64)
    # the worst: no fixed continuation carries an action, so the budget is spent expanding layers
    Lookahead._fixed = lambda self, states, k, held, remaining: np.zeros(states.shape[0],  # type: ignore[method-assign]
                                                                         dtype=np.int64)
    estimates = [0]
    spend = Lookahead._spend

    def spy(self: Lookahead, nodes: int = 1, needed_bytes: int = 0) -> None:
        estimates.append(needed_bytes)
        spend(self, nodes, needed_bytes)

    Lookahead._spend = spy  # type: ignore[method-assign]
    Lookahead(data, horizon, LookaheadSettings(depth=2, seconds=None, nodes=2)).decide(row)  # the model's tables
    estimates[:] = [0]
    before = peak_rss_mb()
    nodes = max(1, round(symbolic.start_nodes(data) * share))
    settings = LookaheadSettings(depth=horizon + 1, seconds=None, nodes=nodes,
                                 max_bytes=None if limit_mb is None else limit_mb * MB)
    t0 = time.perf_counter()
    found = Lookahead(data, horizon, settings).decide(row)
    elapsed = time.perf_counter() - t0
    # the estimate a limit refused is not allocated: the largest one the search went on with
    allowed = [e for e in estimates if settings.max_bytes is None or e <= settings.max_bytes]
    return {"nodes": found.nodes, "budget": nodes, "memory": found.memory, "complete": found.complete,
            "seconds": elapsed, "estimate": max(allowed), "growth": (peak_rss_mb() - before) * MB}


def child_main(spec: str) -> int:
    """The child's side of :func:`run_child`: one JSON line with :func:`measure`'s result."""
    args = json.loads(spec)
    print(json.dumps(measure(args["share"], args["limit_mb"])))
    return 0


def run_child(share: float, limit_mb: int | None) -> dict[str, Any]:
    """:func:`measure` in a fresh Python process (the same rac), so that its peak RSS is this case's."""
    return children.run_child(Path(__file__).resolve(), {"share": share, "limit_mb": limit_mb}, CHILD_TIMEOUT,
                              RAC_PATH)


def row(case: tuple[float, int | None], m: dict[str, Any]) -> list[str]:
    """One line of the table (an error in the nodes' column)."""
    share, limit = case
    head = [f"{share:g} x START_WORK", "none" if limit is None else f"{limit} MB"]
    if "error" in m:
        return [*head, m["error"], "", "", "", ""]
    stopped = "memory limit" if m["memory"] else "work budget" if not m["complete"] else "(complete)"
    return [*head, f"{m['nodes']:,} of {m['budget']:,}", stopped, f"{m['estimate'] / MB:.0f} MB",
            f"{m['growth'] / MB:.0f} MB", seconds(m["seconds"])]


def markdown(rows: list[list[str]]) -> str:
    """The rows as a markdown table under :data:`COLUMNS`."""
    lines = ["| " + " | ".join(COLUMNS) + " |", "|" + " --- |" * len(COLUMNS)]
    return "\n".join([*lines, *("| " + " | ".join(r) + " |" for r in rows)])


def verdicts(cases: Sequence[tuple[float, int | None]], results: Sequence[dict[str, Any]]) -> list[str]:
    """Per case, whether its peak RSS growth stays within its limit (or :data:`GOAL_MB` without one)."""
    notes = []
    for (share, limit), m in zip(cases, results):
        if "error" in m:
            continue
        goal = limit if limit is not None else GOAL_MB
        ok = "ok" if m["growth"] <= goal * MB else "MISS"
        notes.append(f"{share:g} x START_WORK, limit {limit or 'none'}: peak RSS growth {m['growth'] / MB:.0f} MB, "
                     f"goal {goal} MB: {ok}")
    return notes


def main(argv: Sequence[str] | None = None) -> int:
    """Measure every case in a child process, print and write the table."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--quick", action="store_true", help="a tenth of the work budget (under 10 s)")
    parser.add_argument("--output", type=Path, default=DEFAULT_OUTPUT, help="where the markdown table goes")
    parser.add_argument("--child", help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    if args.child is not None:
        return child_main(args.child)
    cases = QUICK_CASES if args.quick else CASES
    results = [run_child(*case) for case in cases]
    header = [f"date: {datetime.datetime.now().astimezone().isoformat(timespec='seconds')}",
              f"mode: {'--quick' if args.quick else 'full'}; each case in a child process",
              f"python {platform.python_version()}, rac {rac.__version__} from {RAC_PATH / 'rac'}",
              f"scene: the tutorial road, 45 actions every 0.2 s, {HORIZON_SECONDS} s; fixed continuations off",
              "peak RSS growth: the child's ru_maxrss after the search minus before (after a one-node search)"]
    notes = verdicts(cases, results)
    children.report("Qd's search from the start: memory", header,
                    markdown([row(c, m) for c, m in zip(cases, results)]), notes, args.output)
    return 1 if any("error" in m for m in results) or any(note.endswith("MISS") for note in notes) else 0


if __name__ == "__main__":
    sys.exit(main())
