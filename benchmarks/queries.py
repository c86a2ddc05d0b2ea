"""Every query on every kind of scene: ``python benchmarks/queries.py [--ramp PATH] [--output FILE]``.

For each scene class — the left-turn intersection, CommonUppRoad's ZAM_Ramp, and generated scenes
of a highway, a T-junction and an overtaking (:mod:`rac.model.scenes`) — a file shaped like
``examples/paper/model.ra`` (the paper's reward automaton, its bindings and its four queries: the
shield Qd, the learned ``reachSafe`` and the two checks under it) is verified with the paper's
standard queries too (``rac verify --standard``: Qa-Qd, the Fig. 7 simulations). The table gives
each query's verdict, states, time and the file's peak memory; the goal is every query decided (no
UNKNOWN) in under 10 s on this machine. ``docs/benchmarks.md`` explains the settings.

Files:
  left turn    examples/paper/model.ra as it is (its left_turn_15s.xml).
  ZAM_Ramp     benchmarks/zam_ramp.ra over ../shared/scenarios/ZAM_Ramp-1_1-T-1.xml (``--ramp``);
               skipped, with a message, when the file is absent (a fresh clone has no ../shared).
  highway, T-junction, overtaking
               examples/paper/model.ra's automaton over the scene (written by rac.model.scenes into a
               temporary folder), with the `model` block of :data:`SCENES` and a 10 s horizon.

Each file runs in a child process of its own (its peak RSS is the file's), seed 1.
"""

from __future__ import annotations

import argparse
import datetime
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

HERE = Path(__file__).resolve().parent
REPOSITORY = HERE.parent
DEFAULT_OUTPUT = HERE / "results" / "queries.md"
PAPER = REPOSITORY / "examples" / "paper" / "model.ra"
ZAM_RAMP_RA = HERE / "zam_ramp.ra"
DEFAULT_RAMP = REPOSITORY.parent / "shared" / "scenarios" / "ZAM_Ramp-1_1-T-1.xml"

try:  # benchmark the installed rac; in a checkout without it, the checkout's src/
    import rac
except ImportError:
    sys.path.insert(0, str(REPOSITORY / "src"))
    import rac

import children  # noqa: E402 - benchmarks/, on sys.path as the script's folder
from children import peak_rss_mb, seconds  # noqa: E402

from rac.model.scenes import TUTORIAL_45  # noqa: E402

RAC_PATH = Path(rac.__file__).resolve().parent.parent

GOAL_SECONDS = 10.0
#: Issue 20's goal for the scenes where exploring everything first fails: each file under a minute.
FILE_GOAL_SECONDS = 60.0
HORIZON = 10  # s, the generated scenes' horizon (unless HORIZONS says otherwise)
CHILD_TIMEOUT = 600  # seconds
#: The paper's settings (examples/paper/model.ra's `model` block), for scenes it was not written for.
PAPER_SETTINGS = ("exponent 2", "decide_period 2", "granularity 0.05", "action jerk in [-2, 2] step 2",
                  "action turn in [0, 0.4] step 0.2")
#: The generated scenes' `model` blocks (besides the scenario and the bindings of examples/paper/model.ra).
SCENES: dict[str, tuple[str, ...]] = {
    "highway": ("exponent 2", "decide_period 2", "granularity 0.25", "max_speed 30",
                "action jerk in [-2, 2] step 2", "action turn in [-0.2, 0.2] step 0.2"),
    "t_junction": ("exponent 2", "decide_period 2", "granularity 0.25",
                   "action jerk in [-2, 2] step 2", "action turn in [0, 0.4] step 0.2"),
    "overtaking": ("exponent 2", "decide_period 2", "granularity 0.25", "max_speed 25",
                   "action jerk in [-2, 2] step 2", "action turn in [-0.2, 0.2] step 0.2"),
    # issue 20: an obstacle-free street over 14 s and a car driving head-on in the ego's lane over 21 s,
    # with the paper's settings; the tutorial road with 45 actions every 0.2 s over a 4 s episode
    "urban": PAPER_SETTINGS,
    "urban_head_on": PAPER_SETTINGS,
    "tutorial": TUTORIAL_45,
}
#: Horizons (s) other than HORIZON: the scenes' own goal windows.
HORIZONS = {"urban": 14, "urban_head_on": 21, "tutorial": 4}
NAMES = {"highway": "highway", "t_junction": "T-junction", "overtaking": "overtaking", "urban": "urban (14 s)",
         "urban_head_on": "urban head-on (21 s)", "tutorial": "tutorial, 45 actions (4 s)"}


# ---------------------------------------------------------------- the files
def scene_source(scene: str) -> str:
    """examples/paper/model.ra's automaton over ``scene``.xml: its `model` block's bindings with
    :data:`SCENES`' settings, and the scene's horizon (:data:`HORIZONS`, else :data:`HORIZON` s; its
    queries' bounds too)."""
    horizon = HORIZONS.get(scene, HORIZON)
    text = PAPER.read_text(encoding="utf-8")
    first = re.search(r"(?m)^automaton ", text)
    if first is None:
        raise SystemExit("benchmarks/queries.py: examples/paper/model.ra has no automaton")
    text = text[first.start():]
    text, count = re.subn(r"(?m)^(\s*)horizon\s+\d+.*$", rf"\g<1>horizon {horizon}", text)
    if count != 1:
        raise SystemExit("benchmarks/queries.py: cannot find the `horizon` line of examples/paper/model.ra")
    text = text.replace("[<=14]", f"[<={horizon}]")
    block = re.search(r"(?ms)^    model \{\n(.*?)^    \}\n", text)
    if block is None:
        raise SystemExit("benchmarks/queries.py: cannot find the `model` block of examples/paper/model.ra")
    binds = [line for line in block.group(1).splitlines() if line.strip().startswith("bind ")]
    items = [f'        scenario "{scene}.xml"', *(f"        {setting}" for setting in SCENES[scene]), *binds]
    model = "    model {\n" + "\n".join(items) + "\n    }\n"
    header = f"// {NAMES[scene]}: benchmarks/queries.py (examples/paper/model.ra's automaton)\n"
    return header + text[:block.start()] + model + text[block.end():]


def ramp_source(ramp: Path) -> str:
    """benchmarks/zam_ramp.ra with the scenario's absolute path."""
    path = str(ramp.resolve())
    if '"' in path or "\\" in path:
        raise SystemExit(f"benchmarks/queries.py: cannot write the path {path!r} as a .ra string")
    text, count = re.subn(r'scenario\s+"[^"]*"', lambda _: f'scenario "{path}"',
                          ZAM_RAMP_RA.read_text(encoding="utf-8"))
    if count != 1:
        raise SystemExit("benchmarks/queries.py: cannot find the `scenario` line of benchmarks/zam_ramp.ra")
    return text


@dataclass(frozen=True)
class Case:
    name: str
    model: Path


# ---------------------------------------------------------------- one file (child process)


def measure(model: str, out_dir: str) -> dict[str, Any]:
    """Every query of ``model`` (with the standard ones): name, verdict, states, seconds."""
    from rac.compiler import compile_file
    from rac.verify.context import VerifyOptions
    from rac.verify.runner import run_queries

    result = compile_file(model)
    if result.automaton is None or result.model_data is None:
        return {"error": "; ".join(d.message for d in result.diagnostics if d.is_error) or "no model"}
    start = time.perf_counter()
    _, answers = run_queries(result, VerifyOptions(standard=True, seed=1, out_dir=Path(out_dir), plots=False))
    total = time.perf_counter() - start
    rows = [{"name": a.name, "status": a.status, "states": a.states, "seconds": a.seconds, "message": a.message,
             "method": a.method} for a in answers]
    return {"queries": rows, "total": total, "rss_peak": peak_rss_mb()}


def run_child(model: Path, out_dir: Path) -> dict[str, Any]:
    """:func:`measure` in a fresh Python process (the same rac), so that ``ru_maxrss`` is this file's."""
    spec = {"model": str(model), "out": str(out_dir)}
    return children.run_child(Path(__file__).resolve(), spec, CHILD_TIMEOUT, RAC_PATH)


# ---------------------------------------------------------------- the table


VERDICTS = {"satisfied": "satisfied", "not satisfied": "NOT satisfied", "value": "value", "unknown": "UNKNOWN",
            "unsupported": "unsupported", "not_applicable": "not applicable"}


def table(results: dict[str, dict[str, Any]]) -> tuple[str, list[str]]:
    """The markdown table (one row per query) and the notes (the goal's verdict first)."""
    lines = ["| scene | query | verdict | decided | states | time | peak RSS (file) |",
             "|---|---|---|---|---:|---:|---:|"]
    slow: list[str] = []
    undecided: list[str] = []
    notes: list[str] = []
    for scene, m in results.items():
        if "error" in m:
            lines.append(f"| {scene} | — | {m['error']} | — | — | — | — |")
            undecided.append(f"{scene}: {m['error']}")
            continue
        for i, q in enumerate(m["queries"]):
            states = f"{q['states']:,}" if q["states"] else "—"
            rss = f"{m['rss_peak']:.0f} MB" if i == 0 else ""
            lines.append(f"| {scene if i == 0 else ''} | {q['name']} | {VERDICTS.get(q['status'], q['status'])} | "
                         f"{q.get('method') or '—'} | {states} | {seconds(q['seconds'])} | {rss} |")
            if q["status"] in ("unknown", "unsupported"):
                undecided.append(f"{scene} {q['name']}: {q['message']}")
            if q["seconds"] >= GOAL_SECONDS:
                slow.append(f"{scene} {q['name']} ({seconds(q['seconds'])})")
        if m["total"] >= FILE_GOAL_SECONDS:
            slow.append(f"{scene} as a whole ({seconds(m['total'])}, goal {FILE_GOAL_SECONDS:g} s)")
        notes.append(f"{scene}: {len(m['queries'])} queries in {seconds(m['total'])}")
    verdict = "ok" if not slow and not undecided else "MISS"
    goal = f"goal: every query decided in under {GOAL_SECONDS:g} s: {verdict}"
    if undecided:
        goal += "; undecided: " + "; ".join(undecided)
    if slow:
        goal += "; slower: " + ", ".join(slow)
    return "\n".join(lines), [goal, *notes]


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--ramp", type=Path, default=DEFAULT_RAMP, help="the ZAM_Ramp-1_1-T-1 CommonRoad file")
    parser.add_argument("--output", type=Path, default=DEFAULT_OUTPUT,
                        help=f"markdown file to write (default: {DEFAULT_OUTPUT.relative_to(REPOSITORY)})")
    parser.add_argument("--only", action="append", choices=["left turn", "ZAM_Ramp", *SCENES],
                        help="only this file (repeatable; default: every one)")
    parser.add_argument("--quick", action="store_true",
                        help="the left turn only (what the tests run)")
    parser.add_argument("--child", help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    if args.child:
        spec = json.loads(args.child)
        print(json.dumps(measure(spec["model"], spec["out"])))
        return 0

    from rac.model.scenes import write_scene

    notes: list[str] = []
    results: dict[str, dict[str, Any]] = {}
    with tempfile.TemporaryDirectory(prefix="rac-queries-bench-") as folder:
        tmp = Path(folder)
        cases = [Case("left turn", PAPER)]
        if args.ramp.is_file():
            ramp = tmp / "zam_ramp.ra"
            ramp.write_text(ramp_source(args.ramp), encoding="utf-8")
            cases.append(Case("ZAM_Ramp", ramp))
        else:
            message = f"skipped ZAM_Ramp: {args.ramp} not found (a fresh clone has no ../shared; see --ramp)"
            print(message, file=sys.stderr)
            notes.append(message)
        only = set(args.only or (["left turn"] if args.quick else ["left turn", "ZAM_Ramp", *SCENES]))
        cases = [case for case in cases if case.name in only]
        for scene in SCENES:
            if scene not in only:
                continue
            write_scene(scene, tmp / f"{scene}.xml")
            source = tmp / f"{scene}.ra"
            source.write_text(scene_source(scene), encoding="utf-8")
            cases.append(Case(NAMES[scene], source))
        for case in cases:
            print(f"... {case.name}", file=sys.stderr, flush=True)
            results[case.name] = run_child(case.model, tmp / f"{case.name.replace(' ', '_')}.out")
    text, more = table(results)
    notes = more + notes
    header = [f"date: {datetime.datetime.now().astimezone().isoformat(timespec='seconds')}",
              f"machine: {platform.system()} {platform.release()}, {os.cpu_count()} CPUs; python "
              f"{platform.python_version()}; rac {rac.__version__}",
              "each file: `rac verify --standard --seed 1` (the paper's Qa-Qd and Fig. 7 simulations, then the "
              "file's own queries) in a child process; peak RSS is the child's ru_maxrss"]
    children.report("rac: every query on every kind of scene", header, text, notes, args.output)
    return 1 if any("error" in m for m in results.values()) else 0


if __name__ == "__main__":
    sys.exit(main())
