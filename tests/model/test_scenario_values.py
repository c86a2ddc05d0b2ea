"""Numbers of a scenario file that are not finite, and orientations too large to normalise.

``load_scenario`` refuses each with a :class:`~rac.model.commonroad.ScenarioError` naming the file,
the element and the value (E0712 in ``rac check``, exit 1), never with shapely's or math's error (a
goal rectangle of NaN width was a GEOSException, an obstacle's infinite orientation a "math domain
error": ``rac`` exit 3) and never with a hang: commonroad-io brings an orientation into [-2π, 2π] by
subtracting 2π one turn at a time, which at inf or 1e300 never ends, so such orientations are refused
before commonroad-io reads the file. Each broken file is the left-turn example of
:mod:`rac.model.intersection` with one number changed in its XML text.
"""

from __future__ import annotations

import math
import re
import time
from pathlib import Path

import pytest

pytest.importorskip("commonroad")

from conftest import REPOSITORY, run_rac  # noqa: E402

from rac.cli.common import EXIT_ERRORS  # noqa: E402
from rac.cli.main import main  # noqa: E402
from rac.model.commonroad import MAX_ORIENTATION, ScenarioError, load_scenario  # noqa: E402
from rac.model.intersection import write_left_turn  # noqa: E402

#: The parts of the example's XML a test changes: the opening of a regular expression (DOTALL) whose
#: first group ends just before the number.
GOAL_RECTANGLE = r"(<goalState>.*?<rectangle>.*?"
OBSTACLE = r'(<dynamicObstacle id="51">.*?'
EGO = r'(<planningProblem id="100">\s*<initialState>.*?'
INITIAL_ORIENTATION = OBSTACLE + r"<initialState>.*?<orientation>\s*<exact>)[^<]*(</exact>)"
TRAJECTORY_ORIENTATION = OBSTACLE + r"<trajectory>.*?<orientation>\s*<exact>)[^<]*(</exact>)"


@pytest.fixture(scope="module")
def example_xml(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return write_left_turn(tmp_path_factory.mktemp("values") / "left_turn.xml")


def edited(example_xml: Path, target: Path, pattern: str, replacement: str) -> Path:
    """The example with the first match of ``pattern`` (DOTALL) replaced, written to ``target``."""
    text, made = re.subn(pattern, replacement, example_xml.read_text(encoding="utf-8"), count=1, flags=re.S)
    assert made, f"the pattern {pattern!r} is not in the example"
    target.write_text(text, encoding="utf-8")
    return target


def number(example_xml: Path, target: Path, pattern: str, value: str) -> Path:
    """The example with the number between ``pattern``'s two groups replaced by ``value``."""
    return edited(example_xml, target, pattern, rf"\g<1>{value}\g<2>")


def refused(path: Path) -> ScenarioError:
    """The ScenarioError of loading ``path``: it names the file first, and leaks no foreign error."""
    with pytest.raises(ScenarioError) as caught:
        load_scenario(path)
    error = caught.value
    assert error.path == str(path) and str(error).startswith(f"{path}: "), str(error)
    assert not any(word in str(error) for word in ("GEOS", "Assertion", "domain error", "Traceback")), str(error)
    return error


@pytest.fixture
def no_reader(monkeypatch: pytest.MonkeyPatch) -> None:
    """commonroad-io's reader fails the test when it runs: the value must be refused before it."""
    from commonroad.common import file_reader

    class Untouchable:
        def __init__(self, *args: object, **kwargs: object) -> None:
            # pytest.fail's exception is no Exception: the loader's handler of reader failures lets it through
            pytest.fail("commonroad-io's reader ran on a file rac should have refused before it")

    monkeypatch.setattr(file_reader, "CommonRoadFileReader", Untouchable)


# ---------------------------------------------------------------- the goal region
@pytest.mark.parametrize(("pattern", "value", "problem"), [
    (GOAL_RECTANGLE + r"<length>)[^<]*(</length>)", "nan", "has a length that is not finite (nan) in its rectangle"),
    (GOAL_RECTANGLE + r"<width>)[^<]*(</width>)", "nan", "has a width that is not finite (nan) in its rectangle"),
    (GOAL_RECTANGLE + r"<width>)[^<]*(</width>)", "inf", "has a width that is not finite (inf) in its rectangle"),
    (GOAL_RECTANGLE + r"<center>\s*<x>)[^<]*(</x>)", "nan",
     "has a centre x that is not finite (nan) in its rectangle"),
    (GOAL_RECTANGLE + r"<center>.*?<y>)[^<]*(</y>)", "-inf",
     "has a centre y that is not finite (-inf) in its rectangle"),
])
def test_a_goal_rectangle_that_is_not_finite_is_refused(example_xml: Path, tmp_path: Path, pattern: str,
                                                         value: str, problem: str) -> None:
    """goallen_nan, goalw_nan, goalw_inf, goalcx_nan of the fuzz sweep: shapely's GEOSException (exit 3)."""
    error = refused(number(example_xml, tmp_path / "goal.xml", pattern, value))
    assert (error.element, error.problem) == ("goal of planning problem 100", problem)


@pytest.mark.parametrize(("shape", "problem"), [
    ("<circle><radius>nan</radius><center><x>-22</x><y>1.75</y></center></circle>",
     "has a radius that is not finite (nan) in its circle"),
    ("<circle><radius>2</radius><center><x>inf</x><y>1.75</y></center></circle>",
     "has a centre x that is not finite (inf) in its circle"),
    ("<polygon><point><x>0</x><y>0</y></point><point><x>nan</x><y>0</y></point><point><x>1</x><y>1</y></point>"
     "</polygon>", "has a point that is not finite (nan, 0.0) in its polygon"),
])
def test_a_goal_circle_or_polygon_that_is_not_finite_is_refused(example_xml: Path, tmp_path: Path, shape: str,
                                                                problem: str) -> None:
    path = edited(example_xml, tmp_path / "goal.xml", r"(<goalState>.*?<position>\s*)<rectangle>.*?</rectangle>",
                  rf"\g<1>{shape}")
    assert refused(path).problem == problem


def test_a_goal_velocity_interval_that_is_not_finite_is_refused(example_xml: Path, tmp_path: Path) -> None:
    """NaN fails commonroad-io's own check (start <= end) and inf passes it: both are refused in rac's words."""
    interval = r"\g<1><velocity><intervalStart>{}</intervalStart><intervalEnd>{}</intervalEnd></velocity>\g<2>"
    pattern = r"(<goalState>.*?</position>)(\s*</goalState>)"
    nan = refused(edited(example_xml, tmp_path / "nan.xml", pattern, interval.format("nan", "5")))
    assert (nan.element, nan.problem) == (
        "planning problem 100's <velocity>", "has the interval [nan, 5], whose bounds are not both finite")
    inf = refused(edited(example_xml, tmp_path / "inf.xml", pattern, interval.format("0", "inf")))
    assert (inf.element, inf.problem) == (
        "goal of planning problem 100", "has a velocity interval that is not finite ([0.0, inf])")


# ---------------------------------------------------------------- obstacles and the ego
@pytest.mark.parametrize(("pattern", "value", "element", "problem"), [
    (OBSTACLE + r"<shape>.*?<width>)[^<]*(</width>)", "inf", "dynamic obstacle 51",
     "has a width that is not finite (inf) in its shape"),
    (OBSTACLE + r"<shape>.*?<length>)[^<]*(</length>)", "nan", "dynamic obstacle 51",
     "has a length that is not finite (nan) in its shape"),
    (OBSTACLE + r"<originXShift>)[^<]*(</originXShift>)", "nan", "dynamic obstacle 51",
     "has an originXShift that is not finite (nan) in its shape"),
    (OBSTACLE + r"<trajectory>.*?<velocity>\s*<exact>)[^<]*(</exact>)", "nan", "dynamic obstacle 51",
     "has a velocity that is not finite (nan) in the state at time step 1"),
    (OBSTACLE + r"<trajectory>.*?<point>\s*<x>)[^<]*(</x>)", "-inf", "dynamic obstacle 51",
     "has a position that is not finite (-inf, -1.75) in the state at time step 1"),
    (EGO + r"<velocity>\s*<exact>)[^<]*(</exact>)", "nan", "planning problem 100",
     "has a velocity that is not finite (nan) in its initial state"),
    (EGO + r"<acceleration>\s*<exact>)[^<]*(</exact>)", "-inf", "planning problem 100",
     "has an acceleration that is not finite (-inf) in its initial state"),
    (EGO + r"<point>.*?<y>)[^<]*(</y>)", "inf", "planning problem 100",
     "has a position that is not finite (1.75, inf) in its initial state"),
])
def test_a_state_or_shape_that_is_not_finite_is_refused(example_xml: Path, tmp_path: Path, pattern: str, value: str,
                                                        element: str, problem: str) -> None:
    error = refused(number(example_xml, tmp_path / "state.xml", pattern, value))
    assert (error.element, error.problem) == (element, problem)


@pytest.mark.parametrize("bound", ["leftBound", "rightBound"])
def test_a_lanelet_point_that_is_not_finite_is_refused(example_xml: Path, tmp_path: Path, bound: str) -> None:
    """A NaN in a right bound failed inside commonroad-io's reader (GEOS); in a left bound it was read."""
    path = number(example_xml, tmp_path / "road.xml", rf'(<lanelet id="1">.*?<{bound}>\s*<point>\s*<x>)[^<]*(</x>)',
                  "nan")
    error = refused(path)
    assert error.element == "lanelet 1" and re.fullmatch(rf"has a point that is not finite \(nan, -?[\d.]+\) "
                                                         rf"in its <{bound}>", error.problem), error.problem


# ---------------------------------------------------------------- orientations, before commonroad-io reads them
@pytest.mark.usefixtures("no_reader")
@pytest.mark.parametrize(("pattern", "value", "element", "problem"), [
    (INITIAL_ORIENTATION, "inf", "dynamic obstacle 51",
     "has an orientation that is not finite (inf) in its initial state"),
    (INITIAL_ORIENTATION, "1e300", "dynamic obstacle 51",
     "has an orientation of 1e300 rad in its initial state"),
    (INITIAL_ORIENTATION, "nan", "dynamic obstacle 51",
     "has an orientation that is not finite (nan) in its initial state"),
    (TRAJECTORY_ORIENTATION, "inf", "dynamic obstacle 51",
     "has an orientation that is not finite (inf) in the state at time step 1"),
    (EGO + r"<orientation>\s*<exact>)[^<]*(</exact>)", "-1e300", "planning problem 100",
     "has an orientation of -1e300 rad in its initial state"),
    (GOAL_RECTANGLE + r"<orientation>)[^<]*(</orientation>)", "inf", "goal of planning problem 100",
     "has an orientation that is not finite (inf) in its <rectangle>"),
])
def test_an_orientation_commonroad_io_cannot_normalise_is_refused_before_it_reads(
        example_xml: Path, tmp_path: Path, pattern: str, value: str, element: str, problem: str) -> None:
    """obsinitori_inf and obsinitori_1e300 hung rac check in commonroad-io's make_valid_orientation;
    obstrajori_inf was a math domain error. The message gives the line of the <orientation>."""
    path = number(example_xml, tmp_path / "orientation.xml", pattern, value)
    error = refused(path)
    assert error.element == element and error.problem.startswith(problem), error.problem
    lines = path.read_text(encoding="utf-8").splitlines()
    found = re.search(r"\(line (\d+)\)", error.problem)
    assert found is not None, error.problem
    line = int(found.group(1))
    assert lines[line - 1].strip() == "<orientation>" or f"<orientation>{value}" in lines[line - 1]
    if math.isfinite(float(value)):
        assert f"beyond the ±{MAX_ORIENTATION:g} rad rac accepts" in error.problem


@pytest.mark.usefixtures("no_reader")
@pytest.mark.parametrize(("where", "bounds"), [
    ("goalState", ("0", "1e300")),  # commonroad-io's AngleInterval subtracts 2π from both until the end is small
    ("goalState", ("-inf", "0")),
    ("initialState", ("0", "inf")),  # an obstacle's uncertain orientation: an AngleInterval as well
])
def test_an_orientation_interval_commonroad_io_cannot_normalise_is_refused(example_xml: Path, tmp_path: Path,
                                                                         where: str, bounds: tuple[str, str]) -> None:
    interval = f"<orientation><intervalStart>{bounds[0]}</intervalStart><intervalEnd>{bounds[1]}</intervalEnd>" \
               "</orientation>"
    if where == "goalState":
        path = edited(example_xml, tmp_path / "interval.xml", r"(<goalState>.*?</position>)(\s*</goalState>)",
                      rf"\g<1>{interval}\g<2>")
        element = "goal of planning problem 100"
    else:
        path = edited(example_xml, tmp_path / "interval.xml", OBSTACLE + r"<initialState>.*?)<orientation>.*?"
                      r"</orientation>", rf"\g<1>{interval}")
        element = "dynamic obstacle 51"
    error = refused(path)
    assert error.element == element
    assert error.problem.startswith(f"has an orientation {'that is not finite' if 'inf' in ''.join(bounds) else 'of'}")
    assert f"in its {'goal' if where == 'goalState' else 'initial'} state (line " in error.problem


def test_orientations_up_to_the_bound_are_read_as_written(example_xml: Path, tmp_path: Path) -> None:
    """The bound refuses only what normalising cannot mean: headings of a few turns, or at the bound, load
    (commonroad-io normalises the bound in about 1,600 steps) and keep their value."""
    for value in (100.0, -MAX_ORIENTATION):
        path = number(example_xml, tmp_path / "turns.xml", INITIAL_ORIENTATION, repr(value))
        started = time.perf_counter()
        scenario = load_scenario(path)
        assert time.perf_counter() - started < 30
        (obstacle,) = [o for o in scenario.obstacles if o.id == 51]
        assert obstacle.waypoints[0].heading == value
    beyond = number(example_xml, tmp_path / "beyond.xml", INITIAL_ORIENTATION, repr(MAX_ORIENTATION * 1.5))
    assert "beyond the" in refused(beyond).problem


# ---------------------------------------------------------------- rac check
def test_rac_check_reports_it_as_E0712_with_exit_1(example_xml: Path, tmp_path: Path,
                                                   capsys: pytest.CaptureFixture[str]) -> None:
    model = tmp_path / "model.ra"
    model.write_text((REPOSITORY / "examples" / "left_turn" / "model.ra").read_text(encoding="utf-8"), encoding="utf-8")
    number(example_xml, tmp_path / "left_turn.xml", GOAL_RECTANGLE + r"<width>)[^<]*(</width>)", "nan")
    assert main(["check", "-q", str(model)]) == EXIT_ERRORS
    err = capsys.readouterr()
    text = err.out + err.err
    assert "E0712" in text and "internal error" not in text
    assert "left_turn.xml: goal of planning problem 100 has a width that is not finite (nan) in its rectangle" in text


def test_rac_check_does_not_hang_on_a_huge_orientation(example_xml: Path, tmp_path: Path) -> None:
    """In a child process with a time limit: before the fix, this one never ended."""
    model = tmp_path / "model.ra"
    model.write_text((REPOSITORY / "examples" / "left_turn" / "model.ra").read_text(encoding="utf-8"), encoding="utf-8")
    number(example_xml, tmp_path / "left_turn.xml", INITIAL_ORIENTATION, "1e300")
    result = run_rac("check", "-q", model, timeout=120)
    assert result.returncode == EXIT_ERRORS, result.stderr
    assert "dynamic obstacle 51 has an orientation of 1e300 rad in its initial state" in result.stdout + result.stderr
