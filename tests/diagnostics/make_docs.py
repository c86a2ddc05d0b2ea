"""The diagnostic examples: one failing input per check, its expected output, and docs/diagnostics.md.

Every ``<CODE>_<short_name>.ra`` file in this folder is a failing example; its
``.expected`` file is the full output of ``rac check <CODE>_<short_name>.ra`` run in
this folder (standard output, then standard error). Inputs that must not be
committed (not UTF-8, over 1 MB, a directory, a missing file) and examples of other
commands (E0009: ``rac compile`` into a missing folder) are listed in :data:`GENERATED`;
their inputs are made in a scratch folder under the same name.

docs/diagnostics.md, the reference, shows every example once, under its code, in an
``<!-- excerpt: NAME -->`` ... ``<!-- end excerpt -->`` region: the lines of the input around each
line the output names (:data:`CONTEXT` lines before and after, ``...`` where lines are skipped,
the line numbers kept) and the whole output. docs/checks.md, which explains the checks, shows a few
examples whole (``<!-- case: NAME -->`` ... ``<!-- end case -->``: source and output), some outputs
alone (``<!-- output: NAME -->`` ... ``<!-- end output -->``), and the index of the codes
(``<!-- codes -->`` ... ``<!-- end codes -->``: one row per ``## CODE`` heading of
docs/diagnostics.md). Every region is generated from the files here, so the docs cannot drift
from the tests; the prose between the regions is written by hand. A new example gets a region of its
own in its code's section of docs/diagnostics.md.

    python tests/diagnostics/make_docs.py             # rewrite the generated regions of both docs
    python tests/diagnostics/make_docs.py --expected  # also rerun rac and rewrite every .expected file
    python tests/diagnostics/make_docs.py --check     # exit 1 if a doc or an .expected file is stale

After ``--expected``, read the diff: the new output is what the tests will demand.
"""

from __future__ import annotations

import argparse
import contextlib
import importlib.util
import io
import os
import re
import sys
import tempfile
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

HERE = Path(__file__).resolve().parent
ROOT = HERE.parents[1]
DOC = ROOT / "docs" / "checks.md"
REFERENCE = ROOT / "docs" / "diagnostics.md"
#: Lines of the input shown before and after each line an output names.
CONTEXT = 2

# Off a terminal a slow check prints a progress line every RAC_PROGRESS_INTERVAL seconds; the
# expected outputs hold none (tests/conftest.py sets the same), whatever the machine's load
os.environ.setdefault("RAC_PROGRESS_INTERVAL", "3600")

if importlib.util.find_spec("rac") is None:  # run as a script from a checkout
    sys.path.insert(0, str(ROOT / "src"))

from rac.cli.main import main as rac_main  # noqa: E402

#: A small valid automaton that the generated inputs start from.
SMALL = """\
// Safety only: a minimal automaton
automaton Driving {
    input isClose : bool

    reward sa
    objective sa

    sample every 0.1
    horizon 30

    initial location Normal { sa' == 1 }
    location Unsafe         { sa' == -1 }

    edge Normal -> Unsafe when isClose
    edge Unsafe -> Normal when !isClose
}
"""

#: The UPPAAL target's examples (`rac compile --target uppaal`): a rate whose growth per sample is
#: not a whole number of significand units, and a symbolic query that is not linear.
UPPAAL_RATE = SMALL.replace("// Safety only: a minimal automaton",
                            "// A rate too small for the UPPAAL model's significands (10^-4)") \
    .replace("initial location Normal { sa' == 1 }", "initial location Normal { sa' == 0.00001 }")
UPPAAL_QUERY = SMALL.replace("// Safety only: a minimal automaton",
                             "// A probability compared with `>`, which UPPAAL's query language has not") \
    .replace("    edge Unsafe -> Normal when !isClose\n",
             "    edge Unsafe -> Normal when !isClose\n\n    query Qp: Pr[<=10](<> Unsafe) > 0.5\n")
_UPPAAL = ("compile", "--target", "uppaal", "{file}", "-o", "driving.xml")

#: The same automaton with German comments, as an editor set to Latin-1 saves it.
LATIN1 = SMALL.replace("// Safety only: a minimal automaton", "// Nur Sicherheit: ein minimaler Automat") \
    .replace("input isClose : bool", "input isClose : bool  // Hindernis näher als der Sicherheitsabstand")


#: The automaton of the E0712 example (which names a `left_turn.xml` that is missing), with the
#: representation written out: the E0713 example puts a scenario next to it.
SCENARIO_EXPONENT = (HERE / "E0712_missing_scenario.ra").read_text(encoding="utf-8") \
    .replace("// A model whose scenario file is not next to this one",
             "// A model whose scenario lies in UTM coordinates, hundreds of kilometres from the origin") \
    .replace("        bind isClose", "        exponent 4                // significand = trunc(v * 10^4)\n"
             "        bind isClose", 1)
#: examples/left_turn/left_turn.xml moved by (500 km, 5400 km), as a map in UTM coordinates places it.
UTM_SHIFT = (500_000, 5_400_000)


def shifted_scenario(dx: float, dy: float) -> bytes:
    """examples/left_turn/left_turn.xml with every ``<x>`` and ``<y>`` moved by ``(dx, dy)``."""
    text = (ROOT / "examples" / "left_turn" / "left_turn.xml").read_text(encoding="utf-8")
    for tag, delta in (("x", dx), ("y", dy)):
        text = re.sub(rf"<{tag}>([^<]+)</{tag}>", lambda m, t=tag, d=delta: f"<{t}>{float(m.group(1)) + d!r}</{t}>",
                      text)
    return text.encode("utf-8")


def _scenario_exponent(folder: Path) -> None:
    (folder / "E0713_scenario_exponent.ra").write_text(SCENARIO_EXPONENT, encoding="utf-8")
    (folder / "left_turn.xml").write_bytes(shifted_scenario(*UTM_SHIFT))


def _scene(name: str, scenario: str, comment: str, build: str) -> Callable[[Path], None]:
    """The automaton of the E0712 example as ``NAME.ra`` over ``scenario``, which the builder
    ``build`` of tests/support/tiny_scenarios.py (commonroad-io) writes next to it."""
    text = (HERE / "E0712_missing_scenario.ra").read_text(encoding="utf-8") \
        .replace("// A model whose scenario file is not next to this one", f"// A model over {comment}") \
        .replace('scenario "left_turn.xml"  // the CommonRoad file, next to this one',
                 f'scenario "{scenario}"  // the CommonRoad file, next to this one')

    def make(folder: Path) -> None:
        if str(HERE.parent / "support") not in sys.path:  # tests/support/, where tiny_scenarios lives
            sys.path.insert(0, str(HERE.parent / "support"))
        import tiny_scenarios

        (folder / f"{name}.ra").write_text(text, encoding="utf-8")
        (folder / scenario).write_bytes(getattr(tiny_scenarios, build)())
    return make


def _spawn(folder: Path) -> None:
    """The automaton of the E0712 example over ``highway.xml``: the highway of :mod:`rac.model.scenes`
    with its truck 10 m ahead of the ego at the ego's speed, inside the unsafe distance at the start."""
    from rac.model.scenario_xml import scenario_bytes
    from rac.model.scenes import build_highway

    text = (HERE / "E0712_missing_scenario.ra").read_text(encoding="utf-8") \
        .replace("// A model whose scenario file is not next to this one",
                 "// A model whose traffic starts inside the unsafe distance of the ego") \
        .replace('scenario "left_turn.xml"  // the CommonRoad file, next to this one',
                 'scenario "highway.xml"  // the CommonRoad file, next to this one')
    (folder / "W1011_penalty_no_action_avoids.ra").write_text(text, encoding="utf-8")
    (folder / "highway.xml").write_bytes(scenario_bytes(*build_highway(truck=(40.0, 20.0)), tags=(),
                                                        source="generated by rac.model.scenes (highway)"))


#: A distance to the nearest obstacle as a numeric input, on a road without obstacles (E0801).
NO_OBSTACLE = """\
// A distance to the nearest obstacle, on a road without obstacles
automaton Driving {
    input gap : real in [0, 100]  // the distance to the nearest obstacle (m)

    reward sa
    objective sa

    sample every 0.1
    horizon 10

    initial location Normal { sa' == 1 }
    location Unsafe         { sa' == -1 }

    edge Normal -> Unsafe when gap < 1.5  do sa = sa - 100
    edge Unsafe -> Normal when gap >= 1.5

    model {
        scenario "urban.xml"  // the CommonRoad file, next to this one
        bind gap = mindist()
    }
}
"""


def _no_obstacle(folder: Path) -> None:
    """:data:`NO_OBSTACLE` next to ``urban.xml``: the urban boulevard of :mod:`rac.model.scenes`, no road users."""
    from rac.model.scenes import scene_bytes

    (folder / "E0801_binding_no_obstacle.ra").write_text(NO_OBSTACLE, encoding="utf-8")
    (folder / "urban.xml").write_bytes(scene_bytes("urban"))


def _scene_file(name: str) -> Callable[[Path], None]:
    """The automaton of the E0712 example as ``NAME.ra``, next to the scenario it names (examples/left_turn)."""
    def make(folder: Path) -> None:
        (folder / f"{name}.ra").write_text((HERE / "E0712_missing_scenario.ra").read_text(encoding="utf-8"),
                                           encoding="utf-8")
        (folder / "left_turn.xml").write_bytes(_left_turn())
    return make


#: The automaton of the E0712 example with a width its model block's exponent truncates (W0725).
TRUNCATED = (HERE / "E0712_missing_scenario.ra").read_text(encoding="utf-8") \
    .replace("// A model whose scenario file is not next to this one", "// A width finer than the exponent holds") \
    .replace('        scenario "left_turn.xml"  // the CommonRoad file, next to this one\n',
             '        scenario "left_turn.xml"  // the CommonRoad file, next to this one\n'
             '        exponent 2                // significands in hundredths\n'
             '        width 1.855               // the ego\'s width (m)\n')


def _truncated(folder: Path) -> None:
    (folder / "W0725_setting_truncated.ra").write_text(TRUNCATED, encoding="utf-8")
    (folder / "left_turn.xml").write_bytes(_left_turn())


#: The automaton of the E0712 example whose progress is an `int` input bound to the ego's speed (W0726).
INT_SPEED = (HERE / "E0712_missing_scenario.ra").read_text(encoding="utf-8") \
    .replace("// A model whose scenario file is not next to this one", "// An int input bound to the ego's speed") \
    .replace("    input prog    : bool  // the distance to the goal shrank since the last sample\n",
             "    input speed   : int in [0, 20]\n") \
    .replace("    edge * -> Unsafe  when isClose           do sa = sa - 100\n"
             "    edge * -> Stalled when !isClose && !prog\n"
             "    edge * -> Normal  when !isClose && prog\n",
             "    edge * -> Unsafe  when isClose                do sa = sa - 100\n"
             "    edge * -> Stalled when !isClose && speed < 1\n"
             "    edge * -> Normal  when !isClose && speed >= 1\n") \
    .replace("        bind prog    = dist_goal() < prev(dist_goal())\n", "        bind speed   = v\n")


def _int_speed(folder: Path) -> None:
    (folder / "W0726_int_input_not_whole.ra").write_text(INT_SPEED, encoding="utf-8")
    (folder / "left_turn.xml").write_bytes(_left_turn())


#: The automaton of the E0712 example whose horizon, 9.9 s, is no whole number of its 0.2 s decisions (W0731).
DECISIONS = (HERE / "E0712_missing_scenario.ra").read_text(encoding="utf-8") \
    .replace("// A model whose scenario file is not next to this one",
             "// A horizon of no whole number of decisions (decide_period defaults to 0.2 s)") \
    .replace("    horizon 30\n", "    horizon 9.9\n")


def _decisions(folder: Path) -> None:
    (folder / "W0731_horizon_not_whole_decisions.ra").write_text(DECISIONS, encoding="utf-8")
    (folder / "left_turn.xml").write_bytes(_left_turn())


def _left_turn() -> bytes:
    return (ROOT / "examples" / "left_turn" / "left_turn.xml").read_bytes()


def _one_lane() -> bytes:
    """A lane 3 m wide (y in [0, 3]) with a parked van: ``avoidable_obstacle()`` of tests/support/tiny_scenarios.py."""
    if str(HERE.parent) not in sys.path:  # tests/, where tiny_scenarios lives
        sys.path.insert(0, str(HERE.parent))
    import tiny_scenarios

    return tiny_scenarios.avoidable_obstacle().xml


def _edited(name: str, scenario: str, comment: str, source: Callable[[], bytes], pattern: str,
            replacement: str) -> Callable[[Path], None]:
    """The automaton of the E0712 example as ``NAME.ra`` over ``scenario``: the bytes of ``source()`` with
    the regular expression ``pattern`` (DOTALL) replaced everywhere by ``replacement``, next to it."""
    text = (HERE / "E0712_missing_scenario.ra").read_text(encoding="utf-8") \
        .replace("// A model whose scenario file is not next to this one", f"// A model over {comment}") \
        .replace('scenario "left_turn.xml"  // the CommonRoad file, next to this one',
                 f'scenario "{scenario}"  // the CommonRoad file, next to this one')

    def make(folder: Path) -> None:
        edited, made = re.subn(pattern, replacement, source().decode("utf-8"), flags=re.S)
        assert made, f"{name}: the pattern {pattern!r} is not in the scenario"
        (folder / f"{name}.ra").write_text(text, encoding="utf-8")
        (folder / scenario).write_text(edited, encoding="utf-8")
    return make


@dataclass(frozen=True)
class Case:
    """One failing example: committed as ``NAME.ra``, or made by ``make`` in a scratch folder."""

    name: str
    #: The text the doc shows as the example's source (None: no source to show).
    shown: str | None
    #: For generated inputs: a sentence saying what the file is, shown before the example.
    note: str = ""
    make: Callable[[Path], None] | None = None
    #: The command line after ``rac``; ``{file}`` stands for the input.
    argv: tuple[str, ...] = ("check", "{file}")

    @property
    def code(self) -> str:
        return self.name.split("_", 1)[0]

    @property
    def file(self) -> str:
        return f"{self.name}.ra"

    def command(self, *extra: str) -> list[str]:
        """The arguments of ``rac``, with ``extra`` options after the subcommand."""
        first, *rest = (a.replace("{file}", self.file) for a in self.argv)
        return [first, *extra, *rest]

    @property
    def expected_path(self) -> Path:
        return HERE / f"{self.name}.expected"

    @property
    def expected(self) -> str:
        return self.expected_path.read_text(encoding="utf-8")


def _write(name: str, data: bytes) -> Callable[[Path], None]:
    def make(folder: Path) -> None:
        (folder / name).write_bytes(data)
    return make


def _directory(name: str) -> Callable[[Path], None]:
    def make(folder: Path) -> None:
        (folder / name).mkdir()
    return make


def _nothing(folder: Path) -> None:
    """The file is missing on purpose."""


#: P2 holds for the plain return (at worst 10*(3-10) + 3 = -67 when unsafe), not for the return
#: discounted by 0.9 per sample: the safe samples' gains come early, the penalty late.
DISCOUNTED = """\
// Keep a distance: safety first, then progress
automaton Keep {
    input isClose : bool   // another car within the safety distance

    reward sa, pr
    priority sa > pr
    objective 10 * sa + pr

    sample every 0.1
    horizon 3

    initial location Normal { sa' == 1;  pr' == 1 }
    location Close          { sa' == -1; pr' == 0 }

    edge * -> Close  when isClose  do sa = sa - 10
    edge * -> Normal when !isClose
}
"""


GENERATED: tuple[Case, ...] = (
    Case("E0004_latin1_comment", LATIN1,
         "The file below, saved in Latin-1 instead of UTF-8 (`ä` is the single byte 0xE4):",
         _write("E0004_latin1_comment.ra", LATIN1.encode("latin-1"))),
    Case("E0004_utf16_file", SMALL,
         "The file below, saved as UTF-16 (every ASCII character is followed by a NUL byte):",
         _write("E0004_utf16_file.ra", SMALL.encode("utf-16-le"))),
    Case("E0005_too_large", None,
         "A valid automaton followed by a comment of a million characters (1,000,040 bytes in all):",
         _write("E0005_too_large.ra", (SMALL + "// " + "x" * (1_000_040 - len(SMALL) - 4) + "\n").encode())),
    Case("E0012_name_too_long", None,
         "`E0012_name_too_long.ra` is the minimal automaton of the E0004 example with an input whose name is "
         "3,901 characters long (the line is shown as a window around the name):",
         _write("E0012_name_too_long.ra", SMALL.replace("automaton Driving {",
                                                       "automaton Driving {\n    input " + "a" * 3901 + " : bool",
                                                       1).encode())),
    Case("E0008_directory", None,
         "`E0008_directory.ra` is a directory:", _directory("E0008_directory.ra")),
    Case("E0008_missing_file", None,
         "`E0008_missing_file.ra` does not exist:", _nothing),
    Case("E0009_missing_folder", None,
         "`E0009_missing_folder.ra` is a valid automaton, and the folder `build` does not exist:",
         _write("E0009_missing_folder.ra", SMALL.encode()),
         ("compile", "--target", "python", "{file}", "-o", "build/driving.py")),
    # `rac check` accepts these two files (only the UPPAAL target rejects them), so the doc shows
    # no ```ra block for them: tests/project/test_examples.py runs `rac check` on every such block.
    Case("E0014_no_param", None,
         "`E0014_no_param.ra` is the minimal automaton of the E0004 example, which declares no `param`:",
         _write("E0014_no_param.ra", SMALL.encode()), ("tune", "{file}")),
    Case("E0015_no_model", None,
         "`E0015_no_model.ra` is the minimal automaton of the E0004 example, which has no `model` block:",
         _write("E0015_no_model.ra", SMALL.encode()), ("verify", "{file}")),
    Case("E0016_scenario_too_large", None,
         "`E0016_scenario_too_large.ra` is the automaton of the E0712 example next to its `left_turn.xml` (the "
         "scenario of examples/left_turn), checked with a memory budget of 1 MB:",
         _scene_file("E0016_scenario_too_large"), ("check", "--max-memory", "1M", "{file}")),
    Case("E0410_discounted_compensation", DISCOUNTED,
         "`E0410_discounted_compensation.ra`, whose priority order holds for the plain return, checked for a "
         "learner that discounts by 0.9 per step:",
         _write("E0410_discounted_compensation.ra", DISCOUNTED.encode()),
         ("check", "--discount", "0.9", "{file}")),
    Case("E0801_rate_not_representable", None,
         "`E0801_rate_not_representable.ra` is the minimal automaton of the E0004 example, with the "
         "rate `sa' == 0.00001` in `Normal`:",
         _write("E0801_rate_not_representable.ra", UPPAAL_RATE.encode()), _UPPAAL),
    Case("E0801_binding_no_obstacle", None,
         "`E0801_binding_no_obstacle.ra` binds a numeric input to `mindist()` over `urban.xml` (line 19), next to "
         "it: the urban boulevard of `rac.model.scenes`, which has no other road users:",
         _no_obstacle),
    Case("E0802_probability_comparison", None,
         "`E0802_probability_comparison.ra` is the minimal automaton of the E0004 example, with the query "
         "`query Qp: Pr[<=10](<> Unsafe) > 0.5`:",
         _write("E0802_probability_comparison.ra", UPPAAL_QUERY.encode()), _UPPAAL),
    # The scenario must sit next to the file: the doc shows no ```ra block (tests/project/test_examples.py
    # would check it without the scenario, which is E0712).
    Case("E0713_scenario_exponent", None,
         "`E0713_scenario_exponent.ra` is the automaton of the E0712 example with `exponent 4` written "
         "in its `model` block (line 23), next to a `left_turn.xml` that is the left-turn scenario "
         "(examples/left_turn) moved 500 km east and 5,400 km north, as a map in UTM coordinates "
         "places it:",
         _scenario_exponent),
    Case("E0714_ego_too_fast", None,
         "`E0714_ego_too_fast.ra` is the automaton of the E0712 example over `highway.xml` (line 22), "
         "next to it: three lanes, the ego at 33 m/s on the middle one, a truck ahead (`highway()` of "
         "tests/support/tiny_scenarios.py); the `model` block leaves `max_speed` at its default, 20 m/s:",
         _scene("E0714_ego_too_fast", "highway.xml", "a highway whose ego starts at 33 m/s", "highway")),
    Case("E0715_several_planning_problems", None,
         "`E0715_several_planning_problems.ra` is the automaton of the E0712 example over `junction.xml` "
         "(line 22), next to it: the left-turn junction of examples/left_turn with a second planning "
         "problem, 101, from the north arm (`junction_with_two_problems()` of tests/support/tiny_scenarios.py):",
         _scene("E0715_several_planning_problems", "junction.xml", "a junction with two planning problems",
                "junction_with_two_problems")),
    Case("E0718_time_step", None,
         "`E0718_time_step.ra` is the automaton of the E0712 example over `tiny_step.xml` (line 22), next to "
         "it: examples/left_turn/left_turn.xml with `timeStepSize=\"1e-308\"`:",
         _edited("E0718_time_step", "tiny_step.xml", "a scenario whose time step is 1e-308 s", _left_turn,
                 r'timeStepSize="0\.1"', 'timeStepSize="1e-308"')),
    Case("E0719_trajectory_gap", None,
         "`E0719_trajectory_gap.ra` is the automaton of the E0712 example over `gap.xml` (line 22), next to "
         "it: examples/left_turn/left_turn.xml whose obstacles' trajectories lack their state at time step 5:",
         _edited("E0719_trajectory_gap", "gap.xml", "a scenario whose trajectories skip a time step", _left_turn,
                 r"<state>\s*<time>\s*<exact>5</exact>.*?</state>\s*", "")),
    Case("E0720_missing_lanelet", None,
         "`E0720_missing_lanelet.ra` is the automaton of the E0712 example over `dangling.xml` (line 22), "
         "next to it: examples/left_turn/left_turn.xml whose lanelet 1 names lanelet 99, which is not in the "
         "file, as a successor (line 134):",
         _edited("E0720_missing_lanelet", "dangling.xml", "a scenario with a dangling lanelet reference",
                 _left_turn, r'<successor ref="11"/>', '<successor ref="99"/>')),
    Case("E0721_lanelet_without_width", None,
         "`E0721_lanelet_without_width.ra` is the automaton of the E0712 example over `flat.xml` (line 22), "
         "next to it: one straight lanelet (`avoidable_obstacle()` of tests/support/tiny_scenarios.py) whose left "
         "bound lies on its right bound, y = 0:",
         _edited("E0721_lanelet_without_width", "flat.xml", "a road without width", _one_lane,
                 r"<y>3\.0</y>", "<y>0.0</y>")),
    Case("W0722_goal_window_closed", None,
         "`W0722_goal_window_closed.ra` is the automaton of the E0712 example over `late.xml` (line 22), next "
         "to it: one lane, the ego starting at 7 s (time step 70) while the goal's window is [0, 6] s "
         "(`late_start()` of tests/support/tiny_scenarios.py):",
         _scene("W0722_goal_window_closed", "late.xml", "a scenario whose goal window closes before the ego starts",
                "late_start")),
    Case("W0723_goal_direction", None,
         "`W0723_goal_direction.ra` is the automaton of the E0712 example over `direction.xml` (line 22), next "
         "to it: one lane whose goal also asks for a velocity in [0, 1] m/s and an orientation in [2.5, 3.5] rad "
         "(`goal_with_direction()` of tests/support/tiny_scenarios.py):",
         _scene("W0723_goal_direction", "direction.xml", "a goal that also asks for a velocity and a heading",
                "goal_with_direction")),
    Case("W0724_start_in_collision", None,
         "`W0724_start_in_collision.ra` is the automaton of the E0712 example over `blocked.xml` (line 22), next "
         "to it: one lane, the ego at x = 10 and a parked car at x = 13.5 on the same line "
         "(`blocked_start()` of tests/support/tiny_scenarios.py):",
         _scene("W0724_start_in_collision", "blocked.xml", "a start inside a parked car", "blocked_start")),
    Case("W0725_setting_truncated", TRUNCATED,
         "`W0725_setting_truncated.ra` is the automaton of the E0712 example with `exponent 2` and `width 1.855`, "
         "next to its `left_turn.xml` (the scenario of examples/left_turn):",
         _truncated),
    Case("W0726_int_input_not_whole", INT_SPEED,
         "`W0726_int_input_not_whole.ra` is the automaton of the E0712 example whose second input is the ego's "
         "speed as an `int`, next to its `left_turn.xml` (the scenario of examples/left_turn):",
         _int_speed),
    Case("W0727_dist_goal_anywhere", None,
         "`W0727_dist_goal_anywhere.ra` is the automaton of the E0712 example over `survive.xml` (line 22), next "
         "to it: one lane whose goal has no position, only the time window [0, 8] s "
         "(`goal_anywhere()` of tests/support/tiny_scenarios.py):",
         _scene("W0727_dist_goal_anywhere", "survive.xml", "a goal of time alone", "goal_anywhere")),
    Case("W0728_traffic_ends", None,
         "`W0728_traffic_ends.ra` is the automaton of the E0712 example (horizon 30 s) over `short.xml` (line 22), "
         "next to it: one lane with a car ahead whose recorded trajectory ends at 8 s "
         "(`short_traffic()` of tests/support/tiny_scenarios.py):",
         _scene("W0728_traffic_ends", "short.xml", "traffic recorded for 8 s", "short_traffic")),
    Case("E0729_lanelet_bounds_reversed", None,
         "`E0729_lanelet_bounds_reversed.ra` is the automaton of the E0712 example over `reversed.xml` (line 22), "
         "next to it: one straight lanelet (`avoidable_obstacle()` of tests/support/tiny_scenarios.py) whose left "
         "bound is written from x = 100 back to x = 0:",
         _edited("E0729_lanelet_bounds_reversed", "reversed.xml", "a lanelet whose bounds run opposite ways",
                 _one_lane, r"<x>0\.0</x>(\s*)<y>3\.0</y>(.*?)<x>100\.0</x>(\s*)<y>3\.0</y>",
                 r"<x>100.0</x>\1<y>3.0</y>\2<x>0.0</x>\3<y>3.0</y>")),
    Case("W0730_traffic_rules", None,
         "`W0730_traffic_rules.ra` is the automaton of the E0712 example over `lights.xml` (line 22), next to it: "
         "one lane with a traffic light at x = 60 m, a stop sign and their stop line (`traffic_rules()` of "
         "tests/support/tiny_scenarios.py):",
         _scene("W0730_traffic_rules", "lights.xml", "a lane with a traffic light", "traffic_rules")),
    Case("W1011_penalty_no_action_avoids", None,
         "`W1011_penalty_no_action_avoids.ra` is the automaton of the E0712 example over `highway.xml` (line 22), "
         "next to it: the highway of `rac.model.scenes` (`build_highway(truck=(40.0, 20.0))`), whose truck starts "
         "10 m ahead of the ego at the ego's 20 m/s: `mindist()` reads 0.97 m, inside the unsafe distance "
         "`3 * collision_distance` (1.5 m), whatever the ego does:",
         _spawn, ("verify", "{file}")),
    Case("W0731_horizon_not_whole_decisions", DECISIONS,
         "`W0731_horizon_not_whole_decisions.ra` is the automaton of the E0712 example with `horizon 9.9`, next to "
         "its `left_turn.xml` (the scenario of examples/left_turn):",
         _decisions),
    Case("W0716_start_off_road", None,
         "`W0716_start_off_road.ra` is the automaton of the E0712 example over `ramp.xml` (line 22), next "
         "to it: one lane from x = 0, the ego starting at x = 0, half of it before the road, as in "
         "CommonUppRoad's ZAM_Ramp (`ramp()` of tests/support/tiny_scenarios.py):",
         _scene("W0716_start_off_road", "ramp.xml", "a ramp whose ego starts half before the road", "ramp")),
)


def committed() -> list[Case]:
    return [Case(p.stem, p.read_text(encoding="utf-8")) for p in sorted(HERE.glob("*.ra"))]


def cases() -> list[Case]:
    """Every example, in code order."""
    return sorted(committed() + list(GENERATED), key=lambda c: c.name)


def case(name: str) -> Case:
    for c in cases():
        if c.name == name:
            return c
    raise KeyError(name)


def expected_status(output: str) -> int:
    """The exit status an output implies: 2 unreadable or unwritable, an option the command cannot use or a
    resource limit; 1 errors; 4 a check that stopped at its limit (W0405) and no error; 0 warnings only."""
    if any(f"error[{code}]" in output for code in ("E0008", "E0009", "E0014", "E0016")):
        return 2
    if "error[" in output:
        return 1
    return 4 if "warning[W0405]" in output else 0


# ------------------------------------------------------------------ running rac
def run(c: Case, *extra: str) -> tuple[int, str]:
    """``rac [command] [extra] NAME.ra`` in-process, in the folder of the input: (status, stdout + stderr)."""
    with contextlib.ExitStack() as stack:
        folder = HERE
        if c.make is not None:
            folder = Path(stack.enter_context(tempfile.TemporaryDirectory()))
            c.make(folder)
        out, err = io.StringIO(), io.StringIO()
        stack.enter_context(contextlib.chdir(folder))
        stack.enter_context(contextlib.redirect_stdout(out))
        stack.enter_context(contextlib.redirect_stderr(err))
        status = rac_main(c.command(*extra))
    return status, out.getvalue() + err.getvalue()


# ------------------------------------------------------------------ the docs' generated regions
#: ``case`` regions show an example's source and output, ``excerpt`` regions the lines around the
#: lines its output names and the output, ``output`` regions only the output.
CASE_REGION = re.compile(r"<!-- (?P<kind>case|excerpt|output): (?P<name>[A-Za-z0-9_]+) -->\n.*?"
                         r"<!-- end (?P=kind) -->", re.DOTALL)
#: The index of the codes in docs/checks.md.
CODES_REGION = re.compile(r"<!-- codes -->\n.*?<!-- end codes -->", re.DOTALL)
#: A code's heading in docs/diagnostics.md: ``## E0001 — syntax error``.
HEADING = re.compile(r"^## (?P<code>[EW]\d{4}) — (?P<title>.+)$", re.MULTILINE)


def named_lines(c: Case) -> list[int]:
    """The lines of the input that the example's output names: where each diagnostic and each note
    points (``NAME.ra:LINE:COLUMN``), and the lines a counterexample's run names (``line N``)."""
    output = c.expected
    found = {int(m) for m in re.findall(rf"{re.escape(c.file)}:(\d+):\d+", output)}
    found |= {int(m) for m in re.findall(r"\blines? (\d+)\b", output)}
    return sorted(found)


def excerpt(c: Case) -> str:
    """The input's lines around each line :func:`named_lines` gives, numbered as in the output; ``...``
    stands for the lines left out. An input whose output names no line is shown whole."""
    assert c.shown is not None
    lines = c.shown.rstrip("\n").split("\n")
    named = [n for n in named_lines(c) if 1 <= n <= len(lines)]
    keep = set(range(1, len(lines) + 1)) if not named else {
        k for n in named for k in range(max(1, n - CONTEXT), min(len(lines), n + CONTEXT) + 1)}
    width = len(str(max(keep)))
    shown: list[str] = []
    for number in range(1, len(lines) + 1):
        if number in keep:
            shown.append(f"{number:>{width}} | {lines[number - 1]}".rstrip())
        elif not shown or shown[-1] != "...":
            shown.append("...")
    return "\n".join(shown)


def region(c: Case, kind: str = "case") -> str:
    """The doc's text for one example: the source (whole, or the lines around the ones the output
    names, or none), what the file is, and rac's output."""
    parts = [f"<!-- {kind}: {c.name} -->"]
    if kind != "output" and c.note:
        parts += [c.note, ""]
    if kind == "case" and c.shown is not None:
        parts += ["```ra", c.shown.rstrip("\n"), "```", ""]
    if kind == "excerpt" and c.shown is not None:
        if c.make is None:
            total = len(c.shown.rstrip("\n").split("\n"))
            parts += [f"[`{c.file}`](../tests/diagnostics/{c.file}) ({total} lines):", ""]
        parts += ["```text", excerpt(c), "```", ""]
    parts += ["```text", "$ rac " + " ".join(c.command()), c.expected.rstrip("\n"), "```", f"<!-- end {kind} -->"]
    return "\n".join(parts)


def anchor(code: str) -> str:
    """The anchor of a code's section in docs/diagnostics.md (an ``<a id>`` before its heading)."""
    return code.lower()


def codes_index(reference: str) -> str:
    """docs/checks.md's index: a row per code of docs/diagnostics.md, linked to its section."""
    rows = ["<!-- codes -->", "| Code | Meaning |", "| --- | --- |"]
    rows += [f"| [{m['code']}](diagnostics.md#{anchor(m['code'])}) | {m['title']} |"
             for m in HEADING.finditer(reference)]
    return "\n".join(rows + ["<!-- end codes -->"])


def with_new_cases(doc: str) -> str:
    """docs/diagnostics.md with an (empty) excerpt region for every example it does not show yet:
    after the last example of its code's section, else before the section's ``**Fix:**``, else at
    the section's end. An example whose code has no section is left out (the tests name the code)."""
    shown = set(documented_cases(doc))
    for c in cases():
        if c.name in shown:
            continue
        heading = next((m for m in HEADING.finditer(doc) if m["code"] == c.code), None)
        if heading is None:
            continue
        following = next((m for m in HEADING.finditer(doc, heading.end())), None)
        end = doc.rfind("<a id=", heading.end(), following.start()) if following else len(doc)
        section = doc[heading.end():end]
        regions = [m for m in CASE_REGION.finditer(section) if m["kind"] == "excerpt"]
        fix = section.find("**Fix:**")
        at = heading.end() + (regions[-1].end() if regions else fix if fix >= 0 else len(section.rstrip("\n")))
        new = f"<!-- excerpt: {c.name} -->\n<!-- end excerpt -->"
        doc = doc[:at] + ("\n\n" + new if regions or fix < 0 else new + "\n\n") + doc[at:]
    return doc


def render(doc: str, reference: str | None = None) -> str:
    """The doc with every generated region regenerated from the files (the index of the codes from
    ``reference``, the text of docs/diagnostics.md; read from the file when not given). In
    docs/diagnostics.md (the doc with ``## CODE`` headings) a new example gets a region of its own."""
    if HEADING.search(doc):
        doc = with_new_cases(doc)
    doc = CASE_REGION.sub(lambda m: region(case(m.group("name")), m.group("kind")), doc)
    if CODES_REGION.search(doc):
        if reference is None:
            reference = REFERENCE.read_text(encoding="utf-8")
        index = codes_index(reference)
        doc = CODES_REGION.sub(lambda m: index, doc)
    return doc


def documented_cases(doc: str, kind: str = "excerpt") -> list[str]:
    """The examples the doc shows in regions of ``kind``, in order."""
    return [m.group("name") for m in CASE_REGION.finditer(doc) if m.group("kind") == kind]


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n", 1)[0])
    parser.add_argument("--expected", action="store_true", help="rerun rac and rewrite every .expected file")
    parser.add_argument("--check", action="store_true", help="only report stale files (exit 1)")
    args = parser.parse_args(argv)
    stale = []
    for c in cases():
        if not (args.expected or args.check) and c.expected_path.exists():
            continue
        _, output = run(c)
        old = c.expected_path.read_text(encoding="utf-8") if c.expected_path.exists() else None
        if output != old:
            stale.append(c.expected_path.name)
            if not args.check:
                c.expected_path.write_text(output, encoding="utf-8")
    for path in (REFERENCE, DOC):  # the reference first: the index of the codes is made from it
        doc = path.read_text(encoding="utf-8")
        new = render(doc)
        if new != doc:
            stale.append(str(path.relative_to(ROOT)))
            if not args.check:
                path.write_text(new, encoding="utf-8")
    for name in stale:
        print(f"{'stale' if args.check else 'wrote'}: {name}")
    return 1 if args.check and stale else 0


if __name__ == "__main__":
    sys.exit(main())
