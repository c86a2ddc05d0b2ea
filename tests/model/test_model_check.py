"""`rac check` loads the `model` block's scenario and checks it against the model (E0712, E0713).

- a missing scenario file and a broken one are E0712 at the `scenario` item, with the loader's
  message (file and element) and a hint; what else the loader raises is no E0712 (a bug: it propagates);
- a scenario whose coordinates overflow int32 at the block's exponent is E0713 at the `exponent`
  setting (or the block), naming the value and the largest exponent that fits;
- on success a fact sums the scenario up, and the result carries the Scenario and the ModelData;
- the check runs only when the file has no other error.
"""

from __future__ import annotations

import errno
import os
import re
from pathlib import Path

import pytest

from rac.cli.main import main
from rac.compiler import compile_file
from rac.model import checks as scenario_check
from rac.model.commonroad import Scenario
from rac.model.data import ModelData, build_model_data

REPO = Path(__file__).resolve().parents[2]
LEFT_TURN = REPO / "examples" / "left_turn" / "left_turn.xml"


def source(scenario: str = "left_turn.xml", items: str = "", horizon: str = "30") -> str:
    return f"""\
automaton Driving {{
    input isClose : bool
    input prog    : bool

    reward sa, pr
    priority sa > pr
    objective 10*sa + pr

    sample every 0.1
    horizon {horizon}

    initial location Normal {{ sa' == 1;  pr' == 1 }}
    location Stalled        {{ sa' == 1;  pr' == -1 }}
    location Unsafe         {{ sa' == -1; pr' == 0 }}

    edge * -> Unsafe  when isClose           do sa = sa - 100
    edge * -> Stalled when !isClose && !prog
    edge * -> Normal  when !isClose && prog

    model {{
        scenario "{scenario}"
{items}        bind isClose = mindist() < 3 * collision_distance
        bind prog    = dist_goal() < prev(dist_goal())
    }}
}}
"""


def shifted(dx: float, dy: float = 0.0) -> bytes:
    """left_turn.xml with every ``<x>``/``<y>`` moved by ``(dx, dy)``."""
    import re

    text = LEFT_TURN.read_text(encoding="utf-8")
    for tag, delta in (("x", dx), ("y", dy)):
        text = re.sub(rf"<{tag}>([^<]+)</{tag}>", lambda m, t=tag, d=delta: f"<{t}>{float(m.group(1)) + d!r}</{t}>",
                      text)
    return text.encode("utf-8")


def write(folder: Path, text: str, xml: bytes | None = None, name: str = "left_turn.xml") -> Path:
    path = folder / "driving.ra"
    path.write_text(text, encoding="utf-8")
    if xml is not None:
        (folder / name).write_bytes(xml)
    return path


def line_of(text: str, needle: str) -> int:
    return next(i for i, line in enumerate(text.splitlines(), 1) if needle in line)


def errors(result) -> list:
    return [d for d in result.diagnostics if d.is_error]


# ---------------------------------------------------------------- success
def test_left_turn_loads_and_is_summed_up(tmp_path: Path) -> None:
    text = source()
    result = compile_file(write(tmp_path, text, LEFT_TURN.read_bytes()))
    assert result.ok, [d.message for d in result.diagnostics]
    fact = result.proved[-1]
    assert fact.startswith("scenario left_turn.xml: 20 lanelets, 3 obstacles, goal at scenario time t in [0, 10] s; "
                           "every significand fits int32 at base 10, exponent 4")
    assert isinstance(result.scenario, Scenario) and len(result.scenario.road) == 20
    assert isinstance(result.model_data, ModelData)
    assert result.automaton is not None and result.automaton.model is not None
    assert result.model_data == build_model_data(result.scenario, result.automaton.model)
    assert (result.model_data.base, result.model_data.exponent) == (10, 4)


def test_the_scenario_is_loaded_once(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    path = write(tmp_path, source(), LEFT_TURN.read_bytes())
    calls = []
    real = scenario_check.load_file

    def counting(name: str, *args: object, **kwargs: object):
        calls.append(name)
        return real(name, *args, **kwargs)  # type: ignore[arg-type]

    monkeypatch.setattr(scenario_check, "load_file", counting)
    result = compile_file(path)
    assert result.ok and len(calls) == 1
    again = compile_file(path)  # unchanged file: the cached Scenario
    assert again.scenario is result.scenario


def test_no_model_block_no_scenario(tmp_path: Path) -> None:
    path = tmp_path / "plain.ra"
    path.write_text((REPO / "stdlib" / "driving.ra").read_text(encoding="utf-8"), encoding="utf-8")
    result = compile_file(path)
    assert result.ok and result.scenario is None and result.model_data is None
    assert not any(f.startswith("scenario ") for f in result.proved)


# ---------------------------------------------------------------- E0712
def test_missing_scenario(tmp_path: Path) -> None:
    text = source()
    result = compile_file(write(tmp_path, text))
    (diagnostic,) = errors(result)
    assert diagnostic.code == "E0712"
    assert diagnostic.message == f"cannot load the scenario: {tmp_path / 'left_turn.xml'}: does not exist"
    assert diagnostic.span is not None and diagnostic.span.line == line_of(text, 'scenario "left_turn.xml"')
    assert "relative to the folder of this `.ra` file" in diagnostic.hints[0]
    assert result.scenario is None and result.model_data is None and result.automaton is None


def test_a_dangling_link_as_scenario_says_so(tmp_path: Path) -> None:
    # "does not exist" with the hint "put `left_turn.xml` there": it is there, a link to a moved file
    (tmp_path / "left_turn.xml").symlink_to(tmp_path / "maps" / "left_turn.xml")
    result = compile_file(write(tmp_path, source()))
    (diagnostic,) = errors(result)
    assert diagnostic.code == "E0712"
    assert diagnostic.message.endswith(f"left_turn.xml: is a symbolic link to {tmp_path / 'maps' / 'left_turn.xml'}, "
                                       "which does not exist")
    assert diagnostic.hints == ("restore the file the link points to, or name the scenario file itself",)



def test_a_scenario_that_is_a_pipe_or_unreadable_gets_a_hint_of_its_own(tmp_path: Path,
                                                                         monkeypatch: pytest.MonkeyPatch) -> None:
    """Found by fuzzing scenario files: a FIFO and a file without read permission were E0712 with the
    generic hint about CommonRoad's formats, which sent users to docs/scenario.md for a file that is fine."""
    os.mkfifo(tmp_path / "left_turn.xml")
    (diagnostic,) = errors(compile_file(write(tmp_path, source())))
    assert diagnostic.message.endswith("left_turn.xml: is not a regular file (a pipe or a device?), not a "
                                       "CommonRoad XML file")
    assert diagnostic.hints == ("name a CommonRoad XML file saved on disk: rac reads the scenario whole, not from "
                                "a pipe or a device",)
    (tmp_path / "left_turn.xml").unlink()
    (tmp_path / "left_turn.xml").write_bytes(LEFT_TURN.read_bytes())
    real = Path.read_bytes

    def refused(self: Path) -> bytes:  # chmod 000 stops no root user (CI containers): refuse as EACCES would
        if self.name == "left_turn.xml":
            raise PermissionError(errno.EACCES, "Permission denied", str(self))
        return real(self)

    monkeypatch.setattr(Path, "read_bytes", refused)
    (diagnostic,) = errors(compile_file(write(tmp_path, source())))
    assert diagnostic.message.endswith("left_turn.xml: cannot be read (Permission denied)")
    assert diagnostic.hints == ("make the file readable for you (`chmod +r`, or ask its owner), or copy it next to "
                                "this `.ra` file",)

def test_missing_scenario_in_a_subfolder_names_the_resolved_path(tmp_path: Path) -> None:
    result = compile_file(write(tmp_path, source("maps/left_turn.xml")))
    (diagnostic,) = errors(result)
    assert diagnostic.code == "E0712" and "maps" in diagnostic.message
    assert any("`scenario \"maps/left_turn.xml\"` is the file" in n.message for n in diagnostic.notes)


def test_a_missing_scenario_from_a_relative_ra_path_names_where_it_led(tmp_path: Path,
                                                                       monkeypatch: pytest.MonkeyPatch) -> None:
    # `rac check rel.ra` with `scenario "../shared/x.xml"`: the resolved path is relative as written,
    # so nothing said where rac looked (a user guessing the folder the path is relative to)
    (tmp_path / "work").mkdir()
    write(tmp_path / "work", source("../shared/left_turn.xml"))
    monkeypatch.chdir(tmp_path / "work")
    ra = next((tmp_path / "work").glob("*.ra")).name
    (diagnostic,) = errors(compile_file(Path(ra)))
    assert diagnostic.code == "E0712"
    where = str(tmp_path / "shared" / "left_turn.xml")
    assert [n.message for n in diagnostic.notes] == [
        f"`scenario \"../shared/left_turn.xml\"` is the file `{where}` (relative to the folder of this file)"]


@pytest.mark.parametrize(("xml", "message"), [
    # expat's "no element found" for a file cut short: it is said to be truncated, and where it ends
    (b"<commonRoad", "ends at line 1 before its elements are closed: is it truncated (a download or copy cut "
                     "short)?"),
    (b"<scenario/>", "is not a CommonRoad file (its root element is <scenario>"),
    (LEFT_TURN.read_bytes()[:5000], "before its elements are closed: is it truncated"),
    (b"<?xml version='1.0'?>\n", "is empty: it holds no XML element, not a CommonRoad scenario"),
    (b"<commonRoad><lanelet id='1'/></commonroad>", "is not XML (line 1, column"),
    (LEFT_TURN.read_bytes().replace(b"<trajectory>", b"<trajectory_>", 1).replace(b"</trajectory>",
                                                                                   b"</trajectory_>", 1),
     "dynamic obstacle"),
])
def test_broken_scenario(xml: bytes, message: str, tmp_path: Path) -> None:
    text = source()
    result = compile_file(write(tmp_path, text, xml))
    (diagnostic,) = errors(result)
    assert diagnostic.code == "E0712", diagnostic.message
    assert diagnostic.message.startswith(f"cannot load the scenario: {tmp_path / 'left_turn.xml'}: ")
    assert message in diagnostic.message
    assert diagnostic.span is not None and diagnostic.span.line == line_of(text, "scenario ")
    assert diagnostic.hints


def test_a_value_that_is_no_number_says_so_and_how_to_fix_it(tmp_path: Path) -> None:
    import re

    xml = re.sub(rb"(<dynamicObstacle .*?<length>)[^<]*", rb"\1long", LEFT_TURN.read_bytes(), count=1, flags=re.S)
    (diagnostic,) = errors(compile_file(write(tmp_path, source(), xml)))
    assert diagnostic.code == "E0712" and re.search(r"cannot be read: `long` is not a number \(line \d+\)$",
                                                    diagnostic.message), diagnostic.message
    assert diagnostic.hints[0].startswith("correct that value in the file: CommonRoad's values are plain decimal")


def test_a_directory_is_not_a_scenario(tmp_path: Path) -> None:
    (tmp_path / "left_turn.xml").mkdir()
    (diagnostic,) = errors(compile_file(write(tmp_path, source())))
    assert diagnostic.code == "E0712" and "is a directory" in diagnostic.message


def test_unexpected_exceptions_are_not_renamed_e0712(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    # the loader reports a broken file as a ScenarioError: anything else is a bug, not the file's fault
    def boom(path: str, *args: object, **kwargs: object):
        raise RuntimeError("the reader broke")

    monkeypatch.setattr(scenario_check, "load_file", boom)
    with pytest.raises(RuntimeError, match="the reader broke"):
        compile_file(write(tmp_path, source(), LEFT_TURN.read_bytes()))


def test_builder_errors_become_e0712(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    import rac.model.data

    def broken(scenario, spec):
        raise rac.model.data.ModelDataError("obstacle 51: waypoint times must not decrease")

    monkeypatch.setattr(rac.model.data, "build_model_data_and_largest", broken)  # what the checker calls
    (diagnostic,) = errors(compile_file(write(tmp_path, source(), LEFT_TURN.read_bytes())))
    assert diagnostic.code == "E0712" and "waypoint times must not decrease" in diagnostic.message


# ---------------------------------------------------------------- E0713
def test_overflow_names_the_value_and_the_largest_exponent(tmp_path: Path) -> None:
    text = source(items="        exponent 6\n", horizon="2")  # the rewards fit at exponent 6 over 2 s
    result = compile_file(write(tmp_path, text, shifted(3000)))  # x from about 2930 m to 3070 m
    (diagnostic,) = errors(result)
    assert diagnostic.code == "E0713"
    assert diagnostic.message.startswith("the scenario's road polygon 0 vertex 0 x = 3003.5 overflows int32 at "
                                         "base 10, exponent 6")
    assert diagnostic.span is not None and diagnostic.span.line == line_of(text, "exponent 6")
    assert "3003500000" in diagnostic.notes[0].message and "±2147.483647" in diagnostic.notes[0].message
    assert diagnostic.hints[0].startswith("set `exponent 5` in the `model` block (the largest")
    assert result.scenario is not None and result.model_data is None
    fixed = compile_file(write(tmp_path, source(items="        exponent 5\n", horizon="2")))
    assert fixed.ok and "exponent 5" in fixed.proved[-1]


def test_overflow_at_the_default_exponent_points_at_the_block(tmp_path: Path) -> None:
    text = source()
    (diagnostic,) = errors(compile_file(write(tmp_path, text, shifted(500_000, 5_400_000))))
    assert diagnostic.code == "E0713" and "exponent 4" in diagnostic.message
    assert diagnostic.span is not None and diagnostic.span.line == line_of(text, "model {")
    assert diagnostic.hints[0].startswith("set `exponent 2`")


def test_overflow_at_base_two(tmp_path: Path) -> None:
    text = source(items="        base 2\n        exponent 6\n        action turn in [-0.5, 0.5] step 0.25\n",
                  horizon="2")
    # rates of ±10 per second: ±1 per sample of 0.1 s has a significand at base 2 (±0.1 has none: E0801)
    text = re.sub(r"== (-?)1\b", r"== \g<1>10", text)
    (diagnostic,) = errors(compile_file(write(tmp_path, text, shifted(40_000_000))))
    assert diagnostic.code == "E0713" and "base 2, exponent 6" in diagnostic.message
    assert diagnostic.span is not None and diagnostic.span.line == line_of(text, "exponent 6")
    # 40,000,070 · 2^5 = 1,280,002,240 fits, · 2^6 does not
    assert diagnostic.hints[0].startswith("set `exponent 5`")


def test_no_exponent_fits(tmp_path: Path) -> None:
    (diagnostic,) = errors(compile_file(write(tmp_path, source(items="        exponent 2\n"), shifted(5e8))))
    assert diagnostic.code == "E0713" and diagnostic.hints[0].startswith("no exponent from 1 to 1 fits")


@pytest.mark.parametrize(("item", "message", "hint"), [
    ("width 1e30", "`width` 1e30 m overflows int32 at base 10, exponent 4", "write a `width` within ±214748.3647 m"),
    ("start_x 300000", "`start_x` 300000 m overflows int32 at base 10, exponent 4",
     "write a `start_x` within ±214748.3647 m, or set `exponent 3` in the `model` block"),
])
def test_an_overflowing_setting_of_the_block_is_pointed_at(tmp_path: Path, item: str, message: str,
                                                           hint: str) -> None:
    """The block's own number overflows, not the scenario's: E0713 said "the scenario's vehicle width" at
    the `model` line, with a hint to use a scenario whose coordinates are smaller."""
    text = source(items=f"        {item}\n")
    (diagnostic,) = errors(compile_file(write(tmp_path, text, LEFT_TURN.read_bytes())))
    assert diagnostic.code == "E0713" and diagnostic.message == message
    assert diagnostic.span is not None and diagnostic.span.line == line_of(text, item)
    assert list(diagnostic.hints) == [hint] and "scenario" not in " ".join(n.message for n in diagnostic.notes)


# ---------------------------------------------------------------- order
def test_other_errors_come_first(tmp_path: Path) -> None:
    """The scenario is checked only when the file has no other error (the missing file is not reported)."""
    result = compile_file(write(tmp_path, source(horizon="600", items="        exponent 6\n")))
    codes = [d.code for d in errors(result)]
    assert "E0501" in codes and "E0712" not in codes


def test_rac_check_prints_the_fact(tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                   capsys: pytest.CaptureFixture[str]) -> None:
    write(tmp_path, source(), LEFT_TURN.read_bytes())
    monkeypatch.chdir(tmp_path)
    assert main(["check", "driving.ra"]) == 0
    out = capsys.readouterr().out
    assert "driving.ra: ok" in out and "proved: scenario left_turn.xml: 20 lanelets, 3 obstacles" in out
