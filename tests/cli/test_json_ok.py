"""Every command's ``--format json`` document has ``ok``, and it is true exactly when the command exits 0:
a script reads one field whatever the command. ``verify``, ``simulate``, ``render``, ``preanalyse`` and
``experiment`` had none."""

from __future__ import annotations

import json
from collections.abc import Callable
from pathlib import Path

import pytest
from engine_files import engine_source, write_engine_file
from tiny_scenarios import EgoStart, GoalBox, StraightRoad, TinySettings, straight_road

from rac.cli.main import main

#: A learning query (on `goal_ahead` some run reaches the goal under the shield, on `avoidable_obstacle` none does).
LEARN = {"safe": "strategy safe = control: A[] !collide() && !offroad()",
         "reach": "strategy reach = maxE(sa)[<=4]{Tiny.location}->{x, v}: <> goal() under safe"}
REWARD_FUNCTION = "10 * !near + 100 * goal()"

#: A file with a `param` to tune; the penalty `{change}` is 1 + P (P >= 4.5 is synthesised) or 1 (no value of P
#: passes, E0406).
TUNED = """automaton Small {{
    input bad : bool
    param P in [0, 100]
    reward sa, pr
    priority sa > pr
    objective 10 * sa + pr
    sample every 1
    horizon 5
    initial location Ok {{ sa' == 1; pr' == 1 }}
    location Bad {{ sa' == 0; pr' == 1 }}
    edge * -> Bad when bad do sa = sa - ({change})
    edge * -> Ok when !bad
}}
"""


def tuned(folder: Path, change: str) -> Path:
    path = folder / "small.ra"
    path.write_text(TUNED.format(change=change), encoding="utf-8")
    return path


def far_road(folder: Path) -> Path:
    """A road that ends just below int32 at exponent 6: the runs stop where the sensed state leaves it (exit 1),
    as tests/cli/test_int32_runs.py builds it."""
    road = StraightRoad(2145.0, EgoStart(2140.0, 1.75, 0.0, 10.0), GoalBox(2143.0, 2145.0, 0.0, 4.0))
    tiny = straight_road("far_road", road, settings=TinySettings(exponent=6))
    tiny.write(folder / "far_road.xml")
    path = folder / "far_road.ra"
    path.write_text(engine_source(tiny, {}), encoding="utf-8")
    return path


def engine(name: str, queries: dict[str, str] | None = None) -> Callable[[Path], Path]:
    return lambda folder: write_engine_file(folder, name, {} if queries is None else queries)


def broken(folder: Path) -> Path:
    path = folder / "broken.ra"
    path.write_text(TUNED.format(change="1 + P").replace("priority sa > pr", "priority sa > nosuch"), encoding="utf-8")
    return path


EXPERIMENT = ["--seeds", "1", "--episodes", "8", "--runs", "2", "--reward-function", REWARD_FUNCTION, "-q"]

#: (command and options, the file, its exit code): a success and a failure of each command that prints a document.
CASES = [
    (["check"], lambda folder: tuned(folder, "1 + P"), 0),
    (["check"], broken, 1),
    (["compile", "--target", "python"], lambda folder: tuned(folder, "1 + P"), 0),
    (["tune", "--print"], lambda folder: tuned(folder, "1 + P"), 0),
    (["tune", "--print"], lambda folder: tuned(folder, "1"), 1),
    (["verify", "--query", "safe"], engine("goal_ahead", {"safe": LEARN["safe"]}), 0),
    (["verify", "--query", "Stays"], engine("narrow_road", {"Stays": "E[] !collide() && !offroad()"}), 1),
    (["simulate", "--runs", "2", "--seed", "1"], engine("goal_ahead"), 0),
    (["simulate", "--runs", "2", "--seed", "1"], far_road, 1),
    (["render", "--seed", "1"], engine("goal_ahead"), 0),
    (["render", "--seed", "1"], far_road, 1),
    (["preanalyse", "--exponent", "2", "--runs", "2", "--seed", "1"], engine("goal_ahead"), 0),
    (["preanalyse", "--exponent", "2", "--runs", "2", "--max-seconds", "1e-9"], engine("goal_ahead"), 4),
    (["experiment", *EXPERIMENT, "--combination", "RF"], engine("goal_ahead", LEARN), 0),
    (["experiment", *EXPERIMENT, "--combination", "SS&RA"], engine("avoidable_obstacle", LEARN), 1),
]


@pytest.mark.parametrize(("argv", "make", "status"), CASES, ids=[f"{argv[0]}-{status}" for argv, _, status in CASES])
def test_ok_is_true_exactly_when_the_command_exits_0(argv: list[str], make: Callable[[Path], Path], status: int,
                                                     tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = make(tmp_path)
    outputs = [] if argv[0] in ("check", "tune", "compile") else ["--out", str(tmp_path / "out")]
    code = main([argv[0], str(path), *argv[1:], *outputs, "--format", "json"])
    printed = capsys.readouterr().out
    assert code == status, printed
    document = json.loads(printed)
    if argv[0] == "check":  # an array of one entry per file
        [document] = document
    assert document["ok"] is (code == 0), document
