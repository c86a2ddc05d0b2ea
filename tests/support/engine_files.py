"""Shared helper for the engine tests (tests/verify/test_verify.py, tests/cli/test_engine_cli.py): a ``.ra`` file with a
``model`` block for one of the tiny scenarios of :mod:`tiny_scenarios`, written into a test's folder.

The automaton reads one input, ``near``, bound to ``mindist() < 3 * collision_distance``, keeps one
reward ``sa`` and asks queries of every form (:data:`QUERIES`)::

    path = write_engine_file(tmp_path, "goal_ahead")            # tmp_path/goal_ahead.ra + goal_ahead.xml
    path = write_engine_file(tmp_path, "narrow_road", queries={"Safe": "E[] !offroad()"})
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path

from tiny_scenarios import TINY_SCENARIOS, Block, EgoStart, GoalBox, StraightRoad, TinyScenario

#: The queries of the engine test file, by name, in the order written (every form of the language).
QUERIES: dict[str, str] = {
    "Stays": "E[] !collide() && !offroad()",  # Qb
    "Reaches": "E<> !collide() && !offroad() && goal()",  # Qc, UPPAAL's literal reading
    "safe": "strategy safe = control: A[] !collide() && !offroad()",  # Qd: the shield
    "Shielded": "A[] !collide() under safe",
    "Product": "A[] Close imply sa <= 0",  # reads a location and a reward: the product
    "Somewhere": "E<> Close",
    "LeadsTo": "goal() --> goal()",
    "Eventually": "A<> time >= 1",
    "Prob": "Pr[<=2](<> v >= 6)",
    "ProbRuns": "Pr[<=2; 30](<> collide())",
    "Certain": "Pr[<=1](<> v >= 0) >= 0.99",
    "Impossible": "Pr[<=1](<> v < 0) >= 0.01",
    "Speed": "E[<=2; 20](max: v)",
    "Sim": "simulate[<=2; 4]{mindist(), 3 * collision_distance}",
    "Learn": "strategy fast = maxE(sa)[<=4]{Tiny.location}->{x}: <> time >= 4 under safe",
}

#: The automaton around the model block; ``{model}`` and ``{queries}`` are filled in.
TEMPLATE = """\
// A tiny engine test file: one input from the model, one reward, queries of every form.
automaton Tiny {{
    input near : bool                 // an obstacle is nearer than 3 * TD

    reward sa
    objective sa

    sample every {period}
    horizon {horizon}

    initial location Normal {{ sa' == 1 }}
    location Close          {{ sa' == -1 }}

    edge Normal -> Close when near  do sa -= 10
    edge Close -> Normal when !near

{model}
{queries}}}
"""


#: A line for an engine file's model block: no heading beyond 0.25 rad (turning on is forbidden there).
ALLOW_WHEN = "        allow when fabs(head) <= 0.25\n"

def engine_source(tiny: TinyScenario, queries: Mapping[str, str] | None = None, *,
                  scenario_file: str | None = None) -> str:
    """The text of the engine test file for ``tiny`` (its default settings) with ``queries``
    (default :data:`QUERIES`; ``{}`` for none)."""
    settings = tiny.settings
    block = settings.model_block(scenario_file or f"{tiny.name}.xml", ["near = mindist() < 3 * collision_distance"])
    queries = QUERIES if queries is None else queries
    return TEMPLATE.format(period=_decimal(settings.sense_period), horizon=_decimal(settings.horizon),
                           model="".join(f"    {line}\n" for line in block.splitlines()),
                           queries="".join(f"    query {name}: {text}\n" for name, text in queries.items()))


def write_short_traffic(folder: Path, horizon: str, period: str = "0.5", seconds: float = 2.0) -> Path:
    """``folder/drive.ra`` (the engine test file's automaton, ``horizon`` s, a sample every ``period`` s) over
    ``folder/road.xml``: one lane 300 m long, the ego at x = 10 at 10 m/s, a car ahead at x = 40 driving at 8 m/s
    whose trajectory is recorded for ``seconds`` s (W0728 past it); return the ``.ra`` file's path."""
    road = StraightRoad(300.0, EgoStart(10.0, 1.75, 0.0, 10.0), GoalBox(250.0, 290.0, 0.0, 40.0),
                        obstacles=(Block(11, x=40.0, y=1.75, velocity=8.0),), steps=round(seconds * 10))
    (folder / "road.xml").write_bytes(road.xml("road"))
    model = '    model {\n        scenario "road.xml"\n        bind near = mindist() < 3 * collision_distance\n    }'
    path = folder / "drive.ra"
    path.write_text(TEMPLATE.format(period=period, horizon=horizon, model=model, queries=""), encoding="utf-8")
    return path


def write_engine_file(folder: Path, name: str, queries: Mapping[str, str] | None = None, *,
                      ra_name: str | None = None) -> Path:
    """Write the tiny scenario ``name`` (``folder/<name>.xml``) and the engine test file for it
    (``folder/<ra_name or name>.ra``); return the ``.ra`` file's path."""
    tiny = TINY_SCENARIOS[name]()
    tiny.write(folder / f"{tiny.name}.xml")
    path = folder / f"{ra_name or name}.ra"
    path.write_text(engine_source(tiny, queries), encoding="utf-8")
    return path


def _decimal(value: object) -> str:
    """A Fraction with a finite decimal as the decimal literal ``.ra`` reads (``1/2`` -> ``0.5``)."""
    return format(float(value), "g")  # type: ignore[arg-type]


#: A one-input automaton for model tests: ``close`` (bound in the model block) sends it to ``Unsafe``,
#: where ``sa`` falls. ``{name}``, ``{horizon}``, ``{model}`` (the block's items, one per line,
#: indented by 8) and ``{queries}`` (lines indented by 4) are filled in by :func:`safety_source`.
SAFETY = """\
automaton {name} {{
    input close : bool
    reward sa
    priority sa
    objective sa
    sample every 0.1
    horizon {horizon}
    initial location Safe {{ sa' == 1 }}
    location Unsafe {{ sa' == -1 }}
    edge * -> Unsafe when close do sa = sa - 1000
    edge * -> Safe when !close
    model {{
{model}
    }}
{queries}
}}
"""


def safety_source(name: str, horizon: float, model: str, queries: Mapping[str, str]) -> str:
    """:data:`SAFETY` with ``model`` (newline-separated items) and ``queries`` (name -> text)."""
    items = "\n".join(f"        {line.strip()}" for line in model.strip().splitlines())
    lines = "\n".join(f"    query {key}: {text}" for key, text in queries.items())
    return SAFETY.format(name=name, horizon=f"{horizon:g}", model=items, queries=lines)

