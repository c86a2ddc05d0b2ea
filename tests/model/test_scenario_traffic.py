"""W0728: a horizon that runs past the recorded traffic. CommonRoad regards a moving obstacle as gone after its
last time step and so does the model, so once the last one ends the road holds no moving traffic and whatever
rac proves, shields or learns after it is about an empty road; `rac check` said nothing of it (the shipped
left_turn example verified 30 s over 10 s of traffic)."""

from __future__ import annotations

import re
from pathlib import Path

from engine_files import TEMPLATE
from tiny_scenarios import Block, EgoStart, GoalBox, StraightRoad

from rac.compiler import compile_file

MODEL = """\
    model {
        scenario "road.xml"
        bind near = mindist() < 3 * collision_distance
    }"""


def check(folder: Path, horizon: str, *, steps: int, start: float = 0.0, velocity: float = 8.0) -> list:
    """The W0728 warnings of an automaton of ``horizon`` s over a lane whose car ahead (``velocity`` m/s; 0:
    parked) is recorded for ``steps`` time steps of 0.1 s, the ego starting at ``start`` s."""
    road = StraightRoad(300.0, EgoStart(10.0, 1.75, 0.0, 10.0), GoalBox(250.0, 290.0, 0.0, 40.0),
                        obstacles=(Block(11, x=40.0, y=1.75, velocity=velocity),), steps=steps)
    text = road.xml("road").decode("utf-8")
    if start:  # the schema wants a planning problem to start at step 0: the step is moved afterwards
        text, made = re.subn(r"(<planningProblem .*?<initialState>.*?<time>\s*<exact>)0(</exact>)",
                             rf"\g<1>{round(start * 10)}\2", text, count=1, flags=re.S)
        assert made == 1
    (folder / "road.xml").write_text(text, encoding="utf-8")
    path = folder / "drive.ra"
    path.write_text(TEMPLATE.format(period="0.1", horizon=horizon, model=MODEL, queries=""), encoding="utf-8")
    result = compile_file(path)
    assert result.ok, [d.message for d in result.diagnostics]
    return [d for d in result.diagnostics if d.code == "W0728"]


def test_a_horizon_past_the_traffic_is_said_with_both_times(tmp_path: Path) -> None:
    (warning,) = check(tmp_path, "12", steps=80)
    assert warning.severity == "warning"
    assert warning.message == ("the horizon runs past the recorded traffic of `road.xml`: its 1 moving obstacle is "
                               "gone after scenario time t = 8 s, the horizon ends at t = 12 s")
    assert "from t = 8 s the road holds no moving obstacle" in warning.notes[0].message
    assert warning.hints[0].startswith("shorten the horizon to 8 s")
    assert warning.span is not None and warning.span.line > 1


def test_traffic_that_reaches_the_horizon_is_not_warned_of(tmp_path: Path) -> None:
    assert not check(tmp_path, "8", steps=80)
    assert not check(tmp_path, "7.9", steps=80)


def test_parked_cars_stay_and_are_not_warned_of(tmp_path: Path) -> None:
    assert not check(tmp_path, "20", steps=10, velocity=0.0)


def test_the_horizon_counts_from_the_egos_start(tmp_path: Path) -> None:
    # the ego starts at 3 s: a 6 s horizon ends at scenario time 9 s, past the traffic's 8 s
    (warning,) = check(tmp_path, "6", steps=80, start=3.0)
    assert "the horizon ends at t = 9 s" in warning.message and "shorten the horizon to 5 s" in warning.hints[0]
    assert not check(tmp_path, "5", steps=80, start=3.0)
