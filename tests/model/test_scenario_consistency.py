"""Scenario files that read but contradict themselves (issue 22): a time step that makes the model's
times meaningless (E0718), an obstacle's trajectory whose time steps repeat or skip (E0719), a lanelet
pointing at a lanelet the file lacks (E0720), a lanelet without width (E0721), a lanelet whose bounds run
in opposite directions (E0729). Each is a written
scenario (the left-turn junction of :mod:`rac.model.intersection`, or a tiny road) edited as text; the
loader's error names the code, the element, the attribute and the file with line:column, and
``rac check`` reports it as a diagnostic at the `scenario` item.
"""

from __future__ import annotations

import re
from pathlib import Path

import pytest

pytest.importorskip("commonroad")

from engine_files import engine_source  # noqa: E402
from tiny_scenarios import TINY_SCENARIOS  # noqa: E402

from rac.compiler import compile_file  # noqa: E402
from rac.model.commonroad import InconsistentScenarioError, load_scenario  # noqa: E402
from rac.model.intersection import write_left_turn  # noqa: E402


@pytest.fixture(scope="module")
def junction(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return write_left_turn(tmp_path_factory.mktemp("junction") / "left_turn.xml")


def edited(source: Path, target: Path, pattern: str, replacement: str, count: int = 1) -> Path:
    """``source`` with ``pattern`` (a regular expression, DOTALL) replaced ``count`` times, written to ``target``."""
    text, made = re.subn(pattern, replacement, source.read_text(encoding="utf-8"), count=count, flags=re.S)
    assert made, f"the pattern {pattern!r} is not in {source.name}"
    target.write_text(text, encoding="utf-8")
    return target


def line_of(path: Path, text: str) -> int:
    """The 1-based line of the first occurrence of ``text`` in ``path``."""
    return next(n for n, line in enumerate(path.read_text(encoding="utf-8").splitlines(), 1) if text in line)


def inconsistency(path: Path) -> InconsistentScenarioError:
    with pytest.raises(InconsistentScenarioError) as caught:
        load_scenario(path)
    return caught.value


@pytest.mark.parametrize("step", ["1e-308", "1e-7", "1e7"])
def test_a_time_step_that_makes_times_meaningless_is_E0718(junction: Path, tmp_path: Path, step: str) -> None:
    path = edited(junction, tmp_path / "step.xml", r'timeStepSize="0\.1"', f'timeStepSize="{step}"')
    error = inconsistency(path)
    assert (error.code, error.attribute, error.element) == ("E0718", "timeStepSize", None)
    assert (error.line, error.column) == (line_of(path, "<commonRoad"), 1)
    assert str(error).startswith(f"{path}:{error.line}:1: has timeStepSize=\"{step}\" s")
    assert "0.1 s" in error.hint


def test_repeated_gapped_or_backward_trajectory_times_are_E0719(junction: Path, tmp_path: Path) -> None:
    first = line_of(junction, "<dynamicObstacle")
    state = r"<state>\s*<time>\s*<exact>{}</exact>.*?</state>\s*"
    gapped = edited(junction, tmp_path / "gap.xml", state.format(5), "")  # the first obstacle loses step 5
    error = inconsistency(gapped)
    assert (error.code, error.attribute) == ("E0719", "time") and error.element.startswith("dynamic obstacle")
    assert "skips time step 5 (its trajectory goes from step 4 to 6)" in str(error)
    assert error.line == first and f"{gapped}:{first}:3: " in str(error)
    repeated = edited(junction, tmp_path / "twice.xml", r"(<time>\s*<exact>)6(</exact>)", r"\g<1>5\g<2>")
    assert "has two states at time step 5" in str(inconsistency(repeated))
    backwards = edited(junction, tmp_path / "back.xml", r"(<time>\s*<exact>)5(</exact>)", r"\g<1>3\g<2>")
    assert "has time steps out of order (4 then 3)" in str(inconsistency(backwards))


@pytest.mark.parametrize("kind", ["successor", "predecessor", "adjacentLeft"])
def test_a_lanelet_pointing_at_a_missing_lanelet_is_E0720(junction: Path, tmp_path: Path, kind: str) -> None:
    found = re.search(rf'<{kind} ref="(\d+)"', junction.read_text(encoding="utf-8"))
    assert found is not None
    path = edited(junction, tmp_path / "ref.xml", rf'<{kind} ref="{found.group(1)}"', f'<{kind} ref="999"')
    error = inconsistency(path)
    assert (error.code, error.attribute) == ("E0720", kind)
    assert error.line == line_of(path, f'<{kind} ref="999"') and error.column == 5
    assert re.fullmatch(r'lanelet \d+', str(error.element))
    assert f'has <{kind} ref="999">, but the file defines no lanelet 999' in str(error)


def test_a_lanelet_without_width_is_E0721(tmp_path: Path) -> None:
    road = TINY_SCENARIOS["avoidable_obstacle"]().write(tmp_path / "road.xml")  # one lanelet, y in [0, 3]
    path = edited(road, tmp_path / "flat.xml", r"<y>3\.0</y>", "<y>0.0</y>", count=0)
    error = inconsistency(path)
    assert (error.code, error.attribute, error.element) == ("E0721", "leftBound", "lanelet 1")
    assert error.line == line_of(path, '<lanelet id="1"') and error.column == 3
    assert "coincide at every point" in str(error)


#: The left bound of the one lanelet of ``avoidable_obstacle`` (y = 3, from x = 0 to 100), and the same points
#: the other way round: the bound written from the lane's end to its start.
FORWARD = r"<x>0\.0</x>(\s*)<y>3\.0</y>(.*?)<x>100\.0</x>(\s*)<y>3\.0</y>"
BACKWARD = r"<x>100.0</x>\1<y>3.0</y>\2<x>0.0</x>\3<y>3.0</y>"


def test_a_lanelet_whose_bounds_run_opposite_ways_is_E0729(junction: Path, tmp_path: Path) -> None:
    """A left bound written from the lane's end to its start made the lanelet's outline cross itself (a bow
    tie): `offroad()` held across most of the lane, and `rac check` blamed the ego's start (W0716) or, with a
    start elsewhere, said nothing. A lane whose bounds run alike, straight or round a bend, is read."""
    road = TINY_SCENARIOS["avoidable_obstacle"]().write(tmp_path / "road.xml")  # one lanelet, y in [0, 3]
    path = edited(road, tmp_path / "reversed.xml", FORWARD, BACKWARD)
    error = inconsistency(path)
    assert (error.code, error.attribute, error.element) == ("E0729", "leftBound", "lanelet 1")
    assert error.line == line_of(path, '<lanelet id="1"') and error.column == 3
    assert ("has its <leftBound> and <rightBound> running in opposite directions: the left one from (100, 3) to "
            "(0, 3), the right one from (0, 0) to (100, 0)") in str(error)
    ra = tmp_path / "driving.ra"
    ra.write_text(engine_source(TINY_SCENARIOS["goal_ahead"](), {}, scenario_file=path.name), encoding="utf-8")
    assert [d.code for d in compile_file(str(ra)).diagnostics if d.is_error] == ["E0729"]
    load_scenario(road)
    load_scenario(junction)  # lanelets that turn left and right, lanes towards -x and -y


def test_rac_check_reports_each_at_the_scenario_item(junction: Path, tmp_path: Path) -> None:
    path = edited(junction, tmp_path / "left_turn.xml", r'<successor ref="(\d+)"', '<successor ref="999"')
    ra = tmp_path / "driving.ra"
    ra.write_text(engine_source(TINY_SCENARIOS["goal_ahead"](), {}, scenario_file=path.name), encoding="utf-8")
    result = compile_file(str(ra))
    errors = [d for d in result.diagnostics if d.is_error]
    assert [d.code for d in errors] == ["E0720"]
    assert errors[0].message.startswith(f"inconsistent scenario: {path}:")
    assert errors[0].hints and "ref" in errors[0].hints[0]
