"""The engine's benchmark (issue 4): ``python benchmarks/engine.py [--quick] [--horizons 10,15] [--shield-only]
[--shield-horizons 10,60] [--output FILE]``.

Explores the discrete state space (``rac.engine.explore.explore``) and computes the most permissive
safety shield (``rac.engine.storm.safety_shield(graph, "safe")``, a backward pass over the layers) at
horizons of 10, 15, 20, 25 and 30 time steps, and prints a markdown table: states, time (explore, shield, total),
exploration throughput in states/s, peak memory, and the speed-up over the published CommonUppRoad
run of UPPAAL on ZAM_Ramp. The same table goes to ``benchmarks/results/engine.md`` (or ``--output``).
``docs/benchmarks.md`` explains the settings and the columns.

Cases (each horizon of each case runs in a child process of its own, so that its peak memory is
its own; ``ru_maxrss`` of the child):

  left turn        examples/left_turn/model.ra at the benchmark's settings, ``prune_unsafe=True``.
  ZAM_Ramp as CommonUppRoad ran it
                   benchmarks/zam_ramp.ra over ../shared/scenarios/ZAM_Ramp-1_1-T-1.xml (``--ramp``):
                   CommonUppRoad's experiments/exp2 model written as rac's modelling choices (SCALE
                   100, a decision every 0.1 s, constant speed 30 m/s, turn -0.1/0/+0.1 rad per step
                   allowed only while the next heading stays within 0.2 rad and the ego on the road,
                   integer increments, the start at the centre of lane 0, off-road not checked at the
                   start), ``prune_unsafe=False`` as UPPAAL's control synthesis explores the whole
                   game. Next to UPPAAL's published states and times; the notes give the growth per
                   decision of both and compare the counts per step of UPPAAL's Decisions cycle.
  left turn, model.ra's settings   examples/left_turn/model.ra as written (exponent 4, a decision
                   every 0.2 s among 81 (jerk, turn) pairs) at horizon 6, pruned: almost no states
                   merge there (81 ** 3 leaves), so the horizons above are out of reach.

The shield against the exploration (issue 20): a second table, on ZAM_Ramp at horizons of 10, 20,
30, 60, 80, 100, 150 and 200 samples (``--shield-horizons``; ``--quick``: 10 and 20), each in a child
process: the CPU time of ``explore`` and of ``safety_shield`` (the backward pass over the layers) and
their ratio; the peak memory of each (``tracemalloc``, in a second, traced run: the exploration's
peak, and the shield's own allocations beyond the graph it is given) and their ratio; up to
horizon 30 also Storm's shield (``safety_shield_storm``), checked to give the same winning states and
allowed choices. Two cases: the graph as UPPAAL explores it (not pruned), and as
``rac.engine.shield.synthesise`` does (unsafe states pruned, the action that led to a state merged
away). The goal: both ratios at most 0.25 at every horizon.

The ZAM_Ramp cases are skipped, with a message, when the shared scenario is absent (a fresh clone
has no ../shared). The left-turn ``.ra`` model is generated into a temporary folder from
examples/left_turn/model.ra (the driving automaton and its bindings), with the benchmark's settings
in the ``model`` block and the scenario given by its absolute path.
"""

from __future__ import annotations

import argparse
import datetime
import gc
import json
import os
import platform
import re
import sys
import tempfile
import time
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

HERE = Path(__file__).resolve().parent
REPOSITORY = HERE.parent
DEFAULT_OUTPUT = HERE / "results" / "engine.md"
LEFT_TURN = REPOSITORY / "examples" / "left_turn" / "model.ra"
DEFAULT_RAMP = REPOSITORY.parent / "shared" / "scenarios" / "ZAM_Ramp-1_1-T-1.xml"
ZAM_RAMP_RA = HERE / "zam_ramp.ra"

try:  # benchmark the installed rac; in a checkout without it, the checkout's src/
    import rac
except ImportError:
    sys.path.insert(0, str(REPOSITORY / "src"))
    import rac

import children  # noqa: E402 - benchmarks/, on sys.path as the script's folder
from children import peak_rss_mb, seconds  # noqa: E402

RAC_PATH = Path(rac.__file__).resolve().parent.parent

HORIZONS = (10, 15, 20, 25, 30)
QUICK_HORIZONS = (10, 15, 20)
#: The shield against the exploration: ZAM_Ramp's horizons (samples of 0.1 s).
SHIELD_HORIZONS = (10, 20, 30, 60, 80, 100, 150, 200)
QUICK_SHIELD_HORIZONS = (10, 20)
#: Storm's shield, the oracle, is timed and compared up to this horizon (beyond, it costs minutes).
ORACLE_HORIZON = 30
#: Repeats (the best time kept) only below this horizon; one run each beyond.
REPEAT_BELOW = 60
#: The goal: the shield's CPU time and peak memory at most this fraction of the exploration's.
GOAL_SHIELD_RATIO = 0.25
MB = 2**20
#: The published CommonUppRoad run of UPPAAL on ZAM_Ramp-1_1-T-1: horizon (time steps) -> (states, seconds).
REFERENCE: dict[int, tuple[int, float]] = {
    10: (7_692, 3.1), 15: (42_772, 13.1), 20: (147_280, 52.5), 25: (380_679, 136.7), 30: (796_534, 290.2),
}
GOAL_SPEEDUP = 100.0
#: The benchmark's model settings: written into the generated `model` blocks (see docs/benchmarks.md).
SETTINGS = (
    "exponent 2",
    "decide_period 0.5",
    "action jerk in [-2, 2] step 2",
    "action turn in [-0.4, 0.4] step 0.4",
)
#: The locations UPPAAL stores per step of CommonUppRoad's Decisions cycle (Idle, EgoGo, ObsGo, Done;
#: the Controller's committed Choose is not kept under its conservative space optimisation): its
#: stored states per state of rac's, one per sample.
UPPAAL_STATES_PER_STEP = 4
#: The goal: rac's states within this factor of UPPAAL's (per step of its cycle).
GOAL_STATES_FACTOR = 2.0
AS_WRITTEN_HORIZON = 6
MAX_STATES = 30_000_000  # a child gives up (MemoryError) beyond this many states
CHILD_TIMEOUT = 900  # seconds


# ---------------------------------------------------------------- the models
def ra_text(scenario: Path, settings: Sequence[str], source: Path = LEFT_TURN) -> str:
    """``source`` (examples/left_turn/model.ra) with ``scenario`` (absolute) and ``settings`` in its model block."""
    text = source.read_text(encoding="utf-8")
    path = str(scenario.resolve())
    if '"' in path or "\\" in path:
        raise SystemExit(f"benchmarks/engine.py: cannot write the path {path!r} as a .ra string")
    lines = "".join(f"\n        {setting}" for setting in settings)
    changed, count = re.subn(r'(?m)^(\s*)scenario\s+"[^"]*"', lambda m: f'{m.group(1)}scenario "{path}"{lines}', text)
    if count != 1:
        raise SystemExit(f"benchmarks/engine.py: cannot find the `scenario` line in {source}")
    return changed


@dataclass(frozen=True)
class Case:
    """One row group of the table: a model, whether unsafe states are pruned, and its horizons."""

    name: str
    model: Path
    prune: bool
    horizons: tuple[int, ...]
    reference: bool  # compare with the UPPAAL ZAM_Ramp run
    forget: bool = False  # explore(..., forget_actions=True): the action that led to a state merged away


# ---------------------------------------------------------------- one measurement (child process)


def measure(model: str, horizon: int, prune: bool, repeat: int, forget: bool = False) -> dict[str, Any]:
    """Explore and shield ``model`` ``repeat`` times; the repeat with the best total time."""
    from rac.compiler import compile_file
    from rac.engine.explore import explore
    from rac.engine.storm import safety_shield

    result = compile_file(model)
    if result.model_data is None:
        messages = "; ".join(d.message for d in result.diagnostics if d.is_error)
        return {"error": f"{model} does not check: {messages}"}
    data = result.model_data
    gc.collect()
    before = peak_rss_mb()
    best: dict[str, Any] | None = None
    for _ in range(repeat):
        start = time.perf_counter()
        try:
            graph = explore(data, horizon_samples=horizon, prune_unsafe=prune, max_states=MAX_STATES,
                            forget_actions=forget)
        except MemoryError:
            return {"error": f"more than {MAX_STATES:,} states"}
        explored = time.perf_counter()
        shield = safety_shield(graph, "safe")
        done = time.perf_counter()
        row = {
            "states": graph.n_states, "choices": graph.n_choices,
            "explore": explored - start, "shield": done - explored, "total": done - start,
            "winning_start": shield.shield_exists, "winning": int(shield.winning.sum()),
            "start_offroad": bool(graph.labels["offroad"][graph.initial]),
            "start_collide": bool(graph.labels["collide"][graph.initial]),
        }
        if best is None or row["total"] < best["total"]:
            best = row
        del graph, shield
        gc.collect()
    assert best is not None
    best.update(rss_before=before, rss_peak=peak_rss_mb())
    return best


def measure_shield(model: str, horizon: int, prune: bool, repeat: int, forget: bool) -> dict[str, Any]:
    """The shield against the exploration on ``model``: CPU times (the best of ``repeat`` untraced runs),
    then peak memories from one run under ``tracemalloc``; Storm's shield up to :data:`ORACLE_HORIZON`."""
    import tracemalloc

    from rac.compiler import compile_file
    from rac.engine.explore import explore
    from rac.engine.storm import safety_shield, safety_shield_storm

    data = compile_file(model).model_data
    if data is None:
        return {"error": f"{model} does not check"}

    def run() -> Any:
        return explore(data, horizon_samples=horizon, prune_unsafe=prune, max_states=MAX_STATES,
                       forget_actions=forget)

    row: dict[str, Any] = {}
    try:
        for _ in range(repeat):
            gc.collect()
            start = time.process_time()
            graph = run()
            explored = time.process_time()
            shield = safety_shield(graph, "safe")
            done = time.process_time()
            if not row or explored - start + done - explored < row["explore"] + row["shield"]:
                row.update(explore=explored - start, shield=done - explored)
            row.update(states=graph.n_states, choices=graph.n_choices, winning_start=shield.shield_exists)
            if horizon <= ORACLE_HORIZON and "storm" not in row:
                before = time.process_time()
                oracle = safety_shield_storm(graph, "safe")
                row["storm"] = time.process_time() - before
                row["same"] = bool(np.array_equal(oracle.winning, shield.winning)
                                   and np.array_equal(oracle.allowed_choices, shield.allowed_choices))
                del oracle
            del graph, shield
        gc.collect()
        tracemalloc.start()
        graph = run()
        graph_bytes, explore_peak = tracemalloc.get_traced_memory()
        tracemalloc.reset_peak()
        shield = safety_shield(graph, "safe")  # its result stays alive: counted in its peak
        shield_peak = tracemalloc.get_traced_memory()[1] - graph_bytes  # beyond the graph it is given
        tracemalloc.stop()
        row["winning"] = int(shield.winning.sum())
    except MemoryError:
        return {"error": f"more than {MAX_STATES:,} states"}
    row.update(explore_peak=explore_peak / MB, graph=graph_bytes / MB, shield_peak=shield_peak / MB)
    return row


def child_main(spec: str) -> int:
    """The child's side of :func:`run_child`: one JSON line with :func:`measure`'s (or
    :func:`measure_shield`'s) result."""
    args = json.loads(spec)
    how = measure_shield if args.get("shield") else measure
    print(json.dumps(how(args["model"], args["horizon"], args["prune"], args["repeat"], args["forget"])))
    return 0


def run_child(model: Path, horizon: int, prune: bool, repeat: int, forget: bool = False,
              shield: bool = False) -> dict[str, Any]:
    """:func:`measure` (``shield``: :func:`measure_shield`) in a fresh Python process (the same rac), so
    that ``ru_maxrss`` is this case's."""
    spec = {"model": str(model), "horizon": horizon, "prune": prune, "repeat": repeat, "forget": forget,
            "shield": shield}
    return children.run_child(Path(__file__).resolve(), spec, CHILD_TIMEOUT, RAC_PATH)


# ---------------------------------------------------------------- the table


def rate(value: float) -> str:
    """States per second: ``2.41 M/s`` or ``304 k/s``."""
    return f"{value / 1e6:.2f} M/s" if value >= 1e6 else f"{value / 1e3:.0f} k/s"


COLUMNS = ("case", "pruned", "horizon", "states", "choices", "explore", "shield", "total", "explore rate",
           "peak RSS (+growth)", "start winning", "UPPAAL states", "UPPAAL time", "speed-up")


def table_row(case: Case, horizon: int, m: dict[str, Any]) -> list[str]:
    """The cells of one row (:data:`COLUMNS`) for a measurement ``m`` of :func:`measure`."""
    reference = REFERENCE.get(horizon) if case.reference else None
    head = [case.name, "yes" if case.prune else "no", str(horizon)]
    uppaal = [f"{reference[0]:,}", f"{reference[1]:.1f} s"] if reference else ["—", "—"]
    if "error" in m:
        return head + [m["error"]] + ["—"] * (len(COLUMNS) - len(head) - 4) + uppaal + ["—"]
    start = "yes" if m["winning_start"] else ("no (off-road)" if m["start_offroad"] else "no")
    speedup = f"{reference[1] / m['total']:,.0f}x" if reference else "—"
    return head + [
        f"{m['states']:,}", f"{m['choices']:,}", seconds(m["explore"]), seconds(m["shield"]), seconds(m["total"]),
        rate(m["states"] / m["explore"]), f"{m['rss_peak']:.0f} MB (+{m['rss_peak'] - m['rss_before']:.0f})",
        start, *uppaal, speedup,
    ]


def markdown(rows: list[list[str]], columns: Sequence[str] = COLUMNS) -> str:
    """The table in markdown, numbers right-aligned."""
    text = {"case", "pruned", "start winning", "same as Storm's"}
    lines = ["| " + " | ".join(columns) + " |",
             "|" + "|".join("---" if c in text else "---:" for c in columns) + "|"]
    lines += ["| " + " | ".join(row) + " |" for row in rows]
    return "\n".join(lines)


SHIELD_COLUMNS = ("case", "horizon", "states", "choices", "explore CPU", "shield CPU", "shield / explore",
                  "explore peak", "shield peak", "shield / explore (memory)", "Storm's shield CPU", "same as Storm's")


def shield_row(case: str, horizon: int, m: dict[str, Any]) -> list[str]:
    """The cells of one row of the shield table (:data:`SHIELD_COLUMNS`) for :func:`measure_shield`'s ``m``."""
    head = [case, str(horizon)]
    if "error" in m:
        return head + [m["error"]] + ["—"] * (len(SHIELD_COLUMNS) - len(head) - 1)
    storm = (seconds(m["storm"]), "yes" if m["same"] else "NO") if "storm" in m else ("—", "—")
    return head + [
        f"{m['states']:,}", f"{m['choices']:,}", seconds(m["explore"]), seconds(m["shield"]),
        f"{m['shield'] / m['explore']:.3f}", f"{m['explore_peak']:,.0f} MB", f"{m['shield_peak']:,.1f} MB",
        f"{m['shield_peak'] / m['explore_peak']:.3f}", *storm,
    ]


def shield_notes(results: dict[tuple[str, int], dict[str, Any]]) -> list[str]:
    """The goal (both ratios at most :data:`GOAL_SHIELD_RATIO` at every horizon) and the worst ratios."""
    measured = [(name, h, m) for (name, h), m in results.items() if "error" not in m]
    if not measured:
        return []
    time_ratio = max((m["shield"] / m["explore"], name, h) for name, h, m in measured)
    memory_ratio = max((m["shield_peak"] / m["explore_peak"], name, h) for name, h, m in measured)
    verdict = "ok" if max(time_ratio[0], memory_ratio[0]) <= GOAL_SHIELD_RATIO else "MISS"
    differ = [f"{name}, horizon {h}" for name, h, m in measured if m.get("same") is False]
    notes = [f"goal: the shield at most {GOAL_SHIELD_RATIO:g} of the exploration in CPU time and in peak memory "
             f"at every horizon: {verdict} (highest: time {time_ratio[0]:.3f} at {time_ratio[1]}, horizon "
             f"{time_ratio[2]}; memory {memory_ratio[0]:.3f} at {memory_ratio[1]}, horizon {memory_ratio[2]})"]
    if differ:
        notes.append("the shield differs from Storm's: " + "; ".join(differ))
    return notes


def environment(quick: bool, repeat: int) -> list[str]:
    """The header lines: date, mode, machine, versions, settings and how memory is measured."""
    cpu = platform.processor() or platform.machine()
    memory = ""
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
        for line in Path("/proc/meminfo").read_text().splitlines():
            if line.startswith("MemTotal"):
                memory = f", {int(line.split()[1]) / 2**20:.0f} GB RAM"
                break
    except OSError:
        pass
    try:
        import stormpy

        storm = f", stormpy {stormpy.__version__}"
    except Exception:  # noqa: BLE001 - only for the header
        storm = ""
    return [
        f"date: {datetime.datetime.now().astimezone().isoformat(timespec='seconds')}",
        f"mode: {'--quick' if quick else 'full'}; best of {repeat} per case (total time), each case in a child process",
        f"machine: {platform.system()} {platform.release()}, {cpu}, {os.cpu_count()} CPUs{memory}",
        f"python {platform.python_version()} ({platform.python_implementation()}), numpy {np.__version__}{storm}",
        f"rac {rac.__version__} from {Path(rac.__file__).resolve().parent}",
        "settings (model block): " + "; ".join(SETTINGS) + " — sense_period 0.1 s (one CommonRoad time step), "
        "granularity 0.25, the rest model.ra's; 3 x 3 = 9 (jerk, turn) pairs per decision (left turn); "
        "benchmarks/zam_ramp.ra as written (ZAM_Ramp)",
        "memory: peak RSS = ru_maxrss of the child (Python, numpy, stormpy, the compiled model, the graph and "
        "the shield); (+growth) = its growth over the peak before the first exploration",
    ]


SHIELD_WHOLE = "ZAM_Ramp, not pruned"
SHIELD_SYNTHESISE = "ZAM_Ramp as synthesise explores it (pruned, merged)"
ZAM_CASE = "ZAM_Ramp as CommonUppRoad ran it"
ZAM_MERGED = "ZAM_Ramp, the action that led to a state merged away"


def states_notes(states: dict[int, int], merged: dict[int, int]) -> list[str]:
    """The ZAM_Ramp state counts against UPPAAL's: the goal (within 2x per step of its cycle) and the
    growth per decision between consecutive horizons: rac's before and after merging (``merged``:
    ``forget_actions``), and UPPAAL's."""
    compared = {h: (n, REFERENCE[h][0]) for h, n in sorted(states.items()) if h in REFERENCE}
    if not compared:
        return []
    ratios = {h: n * UPPAAL_STATES_PER_STEP / uppaal for h, (n, uppaal) in compared.items()}
    worst = max(ratios.values(), key=lambda r: max(r, 1 / r))
    verdict = "ok" if max(worst, 1 / worst) <= GOAL_STATES_FACTOR else "MISS"
    lines = [f"goal: ZAM_Ramp's states within {GOAL_STATES_FACTOR:g}x of UPPAAL's at every horizon, counted per "
             f"step of its Decisions cycle (UPPAAL stores {UPPAAL_STATES_PER_STEP} locations per step — Idle, "
             f"EgoGo, ObsGo, Done — for each of rac's states, one per sample): {verdict} (rac x "
             f"{UPPAAL_STATES_PER_STEP} / UPPAAL: " + ", ".join(f"{r:.2f} at {h}" for h, r in ratios.items()) + ")"]
    rows = ["| horizons | rac | rac, merged | UPPAAL |", "|---|---:|---:|---:|"]
    horizons = list(compared)
    for low, high in zip(horizons, horizons[1:]):
        steps = high - low
        ours = (compared[high][0] / compared[low][0]) ** (1 / steps)
        theirs = (compared[high][1] / compared[low][1]) ** (1 / steps)
        after = (f"{(merged[high] / merged[low]) ** (1 / steps):.3f}x" if low in merged and high in merged else "—")
        rows.append(f"| {low} -> {high} | {ours:.3f}x | {after} | {theirs:.3f}x |")
    if len(horizons) > 1:
        lines.append("growth per decision (states(h2) / states(h1)) ** (1 / (h2 - h1)):\n\n" + "\n".join(rows) + "\n")
    return lines


# ---------------------------------------------------------------- main
def main(argv: Sequence[str] | None = None) -> int:
    """Run every case, print the table and notes, write them to ``--output``; 1 if a case failed."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--quick", action="store_true", help=f"horizons {QUICK_HORIZONS}, one run each (a smoke run)")
    parser.add_argument("--horizons", help="comma-separated horizons in time steps (default: 10,15,20,25,30)")
    parser.add_argument("--repeat", type=int, help="runs per case, the best total kept (default 3; --quick: 1)")
    parser.add_argument("--shield-horizons",
                        help="comma-separated ZAM_Ramp horizons of the shield table (default: "
                             f"{','.join(map(str, SHIELD_HORIZONS))}; --quick: "
                             f"{','.join(map(str, QUICK_SHIELD_HORIZONS))}; 0 or an empty list: no shield table)")
    parser.add_argument("--shield-only", action="store_true",
                        help="only the table of the shield against the exploration")
    parser.add_argument("--ramp", type=Path, default=DEFAULT_RAMP, help="the ZAM_Ramp-1_1-T-1 CommonRoad file")
    parser.add_argument("--output", type=Path, default=DEFAULT_OUTPUT,
                        help=f"markdown file to write (default: {DEFAULT_OUTPUT.relative_to(REPOSITORY)})")
    parser.add_argument("--child", help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    if args.child:
        return child_main(args.child)

    def parse(option: str, text: str) -> tuple[int, ...]:
        try:
            found = tuple(int(h) for h in text.split(",") if h.strip())
        except ValueError:
            parser.error(f"{option}: expected whole numbers separated by commas, not {text!r}")
        if found and min(found) < 0:
            parser.error(f"{option}: horizons are >= 0")
        return found

    if args.horizons:
        horizons = parse("--horizons", args.horizons)
        if not horizons:
            parser.error("--horizons: give at least one horizon >= 0")
    else:
        horizons = QUICK_HORIZONS if args.quick else HORIZONS
    if args.shield_horizons is not None:
        shield_horizons = tuple(h for h in parse("--shield-horizons", args.shield_horizons) if h > 0)
    else:
        shield_horizons = QUICK_SHIELD_HORIZONS if args.quick else SHIELD_HORIZONS
    if args.shield_only and not shield_horizons:
        parser.error("--shield-only needs shield horizons")
    repeat = args.repeat or (1 if args.quick else 3)

    notes: list[str] = []
    rows: list[list[str]] = []
    results: dict[tuple[str, int], dict[str, Any]] = {}
    with tempfile.TemporaryDirectory(prefix="rac-engine-bench-") as folder:
        tmp = Path(folder)
        left_turn = tmp / "left_turn.ra"
        left_turn.write_text(ra_text(LEFT_TURN.parent / "left_turn.xml", SETTINGS), encoding="utf-8")
        cases = [Case("left turn", left_turn, True, horizons, False)]
        shield_cases: list[Case] = []
        ramp = args.ramp
        if ramp.is_file():
            ramp_model = tmp / "zam_ramp.ra"
            ramp_model.write_text(ra_text(ramp, (), ZAM_RAMP_RA), encoding="utf-8")
            cases += [Case(ZAM_CASE, ramp_model, False, horizons, True),
                      Case(ZAM_MERGED, ramp_model, False, horizons, True, forget=True)]
            shield_cases = [Case(SHIELD_WHOLE, ramp_model, False, shield_horizons, False),
                            Case(SHIELD_SYNTHESISE, ramp_model, True, shield_horizons, False, forget=True)]
        else:
            message = f"skipped the ZAM_Ramp cases: {ramp} not found (a fresh clone has no ../shared; see --ramp)"
            print(message, file=sys.stderr)
            notes.append(message)
        if not args.quick:
            cases.append(Case("left turn, model.ra's settings (exponent 4, 81 pairs every 0.2 s)", LEFT_TURN, True,
                              (AS_WRITTEN_HORIZON,), False))
        if args.shield_only:
            cases = []

        for case in cases:
            for horizon in case.horizons:
                print(f"... {case.name}, horizon {horizon}", file=sys.stderr, flush=True)
                measured = run_child(case.model, horizon, case.prune, repeat, case.forget)
                results[case.name, horizon] = measured
                rows.append(table_row(case, horizon, measured))
        shield_results: dict[tuple[str, int], dict[str, Any]] = {}
        shield_rows: list[list[str]] = []
        for case in shield_cases:
            for horizon in case.horizons:
                print(f"... the shield against the exploration: {case.name}, horizon {horizon}", file=sys.stderr,
                      flush=True)
                measured = run_child(case.model, horizon, case.prune, repeat if horizon < REPEAT_BELOW else 1,
                                     case.forget, shield=True)
                shield_results[case.name, horizon] = measured
                shield_rows.append(shield_row(case.name, horizon, measured))
    speedups = [(REFERENCE[h][1] / m["total"], name, h) for (name, h), m in results.items()
                if name == ZAM_CASE and h in REFERENCE and "error" not in m]
    if speedups:
        worst = min(speedups)
        verdict = "ok" if worst[0] >= GOAL_SPEEDUP else "MISS"
        notes.insert(0, f"goal: >= {GOAL_SPEEDUP:.0f}x faster than UPPAAL on ZAM_Ramp at every horizon: {verdict} "
                        f"(lowest {worst[0]:,.0f}x: {worst[1]}, horizon {worst[2]})")
    zam = {h: m["states"] for (name, h), m in results.items() if name == ZAM_CASE and "error" not in m}
    merged = {h: m["states"] for (name, h), m in results.items() if name == ZAM_MERGED and "error" not in m}
    if zam:
        notes[1:1] = states_notes(zam, merged)
    largest = max((m for m in results.values() if "error" not in m), key=lambda m: m["states"], default=None)
    if largest is not None:
        notes.append(f"exploration throughput, largest case: {largest['states']:,} states in "
                     f"{seconds(largest['explore'])} = {rate(largest['states'] / largest['explore'])}")

    env = environment(args.quick, repeat)
    tables = [markdown(rows)] if rows else []
    if shield_rows:
        tables.append("the shield against the exploration (CPU seconds; peak memory by tracemalloc):\n\n"
                      + markdown(shield_rows, SHIELD_COLUMNS))
        notes += shield_notes(shield_results)
    children.report("rac engine benchmark", env, "\n\n".join(tables), notes, args.output)
    failed = [name for (name, _), m in [*results.items(), *shield_results.items()] if "error" in m]
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
