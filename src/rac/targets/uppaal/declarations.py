"""UPPAAL global declarations of the scenario model: its data and its functions.

:func:`emit_declarations` prints :class:`rac.model.ModelData` as ``const`` scalars and arrays, the
controller's state variables and the functions ``sense_state()``, ``mindist()``, ``collide()``,
``offroad()``, ``goal()``, ``dist_goal()`` (with helpers ``i2d``, ``d2i``, ``obs_wp``,
``obs_present``, ``obs_x``, ``obs_y``, ``obs_head``, ``in_road``, ``in_goal``).
:func:`declared_names` lists every global name the text declares, so that the rest of the UPPAAL
model can avoid them. The functions' text is a template, ``templates/model_functions.c.j2``;
this module prints the data in front of it.

The text is in the subset that is valid both in UPPAAL and in C99 (tests/targets/test_model_c.py compiles
it with a four-line prelude and checks it against :mod:`rac.model.native` bit for bit):

- integers are ``int32_t`` (UPPAAL's ``int`` is 16-bit); no ``int[a,b]``, ``meta``, pointers,
  references or ``&&=``; every array has at least one element (a dummy ``0`` pads an empty one;
  a separate ``*_N`` constant holds the real count); array sizes and initial values are literals
  (C wants constant expressions there);
- every local is declared at the top of its function, without an initialiser; loops are
  ``for (i = 0; i < N; i++)``; every function has one ``return``, at its end;
- ``fint(d)`` truncates a double (the C prelude defines it as ``((int32_t)(d))``); double
  literals have digits on both sides of the point; no ``(double)`` casts: ``int32_t / double``
  promotes in both languages;
- names avoid UPPAAL keywords and C library names (``y0``, ``j1``, ``time`` ...).

The global ``int32_t count`` is the sample index ``k``: the Timer's ``sense`` edge must increment it
(``count++``) — UPPAAL runs the sender's update before the receivers', so ``sense_state()`` (which does not
read it) and every later reader see the new sample. A channel cannot share a function's name, so
the function is ``sense_state()`` and the target's broadcast channel can be ``sense``.

Example::

    text = emit_declarations(build_model_data(scenario, spec))   # the <declaration> of the nta
"""

from __future__ import annotations

import re
from collections.abc import Sequence

from rac.core.numbers import INT32_LOW, INT32_MAX
from rac.model.data import ModelData
from rac.targets.uppaal.expr import double_literal
from rac.targets.uppaal.layout import environment

__all__ = ["C_PRELUDE", "declared_names", "emit_declarations"]

#: What a C compiler needs before the declarations (UPPAAL predeclares all of it).
C_PRELUDE = """\
#include <float.h>
#include <math.h>
#include <stdbool.h>
#include <stdint.h>
#define fint(d) ((int32_t)(d))
"""

_WIDTH = 100


def _int(value: int) -> str:
    if not INT32_LOW <= value <= INT32_MAX:
        raise ValueError(f"{value} does not fit int32")
    return str(value)


def _array(name: str, values: Sequence[int], comment: str = "") -> str:
    """``const int32_t NAME[n] = {...};`` — one dummy 0 when empty."""
    items = [_int(v) for v in values] or ["0"]
    head = f"const int32_t {name}[{len(items)}] = {{"
    lines: list[str] = []
    line = head
    for index, item in enumerate(items):
        piece = item + ("," if index < len(items) - 1 else "")
        if len(line) + 1 + len(piece) > _WIDTH and line != head:
            lines.append(line)
            line = "    " + piece
        else:
            line = line + piece if line == head else line + " " + piece
    lines.append(line + "};" + (f"  // {comment}" if comment else ""))
    return "\n".join(lines)


#: What ``OBS_ID`` holds for a CommonRoad id beyond int32 (no function of the model reads the ids).
UNREPRESENTED_ID = -1


def _obstacle_ids(ids: Sequence[int]) -> str:
    """``OBS_ID``: the obstacles' CommonRoad ids, labels that no function of the model reads. CommonRoad ids
    are whole numbers of any size (a converted dataset's may pass 2^31): one beyond int32 is
    :data:`UNREPRESENTED_ID` there, and the comment gives it (the compile failed with an internal error)."""
    beyond = [i for i in ids if not INT32_LOW <= i <= INT32_MAX]
    comment = "CommonRoad ids"
    if beyond:
        comment += f" ({UNREPRESENTED_ID}: {', '.join(map(str, beyond))}, beyond int32)"
    return _array("OBS_ID", [i if INT32_LOW <= i <= INT32_MAX else UNREPRESENTED_ID for i in ids], comment)


def _scalar(name: str, value: int, comment: str = "") -> str:
    return f"const int32_t {name} = {_int(value)};" + (f"  // {comment}" if comment else "")


def _comment_text(text: str) -> str:
    return re.sub(r"[^\x20-\x7e]", "?", text).replace("*/", "* /")


#: The constant holding the samples between two decisions (C2 / C1): declared here, read by the
#: Timer's guards and by a query's guard on ``jerk``/``turn`` (through ``ModelNames.decide_every``).
DECIDE_EVERY = "DECIDE_EVERY"


def action_name(name: str) -> str:
    cleaned = re.sub(r"[^A-Za-z0-9_]", "_", name).upper()
    return cleaned if cleaned[:1].isalpha() else "A_" + cleaned


def emit_declarations(data: ModelData) -> str:
    """The UPPAAL global declarations of the model (deterministic; see the module docstring)."""
    out: list[str] = [
        f"// Scenario model of {_comment_text(data.name)}, generated by rac: significands at scale "
        f"{data.base}^{data.exponent}.",
        "// ---- number representation and periods",
        _scalar("SCALE", data.scale),
        f"const double SCALE_D = {double_literal(float(data.scale))};",
        _scalar("SUBSTEPS", data.substeps, "1/G Euler sub-steps per sense"),
        f"const double SENSE_UNIT = {double_literal(data.unit)};  // C1 * G seconds",
        f"const double SENSE_PERIOD_S = {double_literal(data.period)};  // C1 seconds",
        _scalar("SENSE_PERIOD", data.sense_period, "C1"),
        _scalar("DECIDE_PERIOD", data.decide_period, "C2"),
        _scalar("OFFROAD_FROM", data.offroad_from, "offroad() is false before this sample"),
        _scalar(DECIDE_EVERY, data.decide_every, "C2 / C1"),
        f"const double NO_OBSTACLE = {double_literal(1.0e9)};  // mindist() without obstacles",
        "// ---- vehicle",
        _scalar("LENGTH", data.length),
        _scalar("WIDTH", data.width),
        _scalar("MAX_ACC", data.max_acc, "MA"),
        _scalar("MAX_TURN", data.max_turn, "MT"),
        _scalar("MIN_SPEED", data.min_speed),
        _scalar("MAX_SPEED", data.max_speed),
        _scalar("TD", data.td, "collision distance"),
        _scalar("P1", data.p1, "comfort fraction of MA"),
        _scalar("P2", data.p2, "comfort fraction of MT"),
        "// ---- actions: the value with index i is NAME_VALUES[i], 0 <= i < NAME_COUNT",
    ]
    for action in data.actions:
        name = action_name(action.name)
        out += [
            _scalar(f"{name}_LOW", action.low),
            _scalar(f"{name}_HIGH", action.high),
            _scalar(f"{name}_STEP", action.step),
            _scalar(f"{name}_COUNT", action.count),
            _array(f"{name}_VALUES", action.values),
        ]
    out += [
        "// ---- ego start",
        _scalar("EGO_X0", data.ego_x),
        _scalar("EGO_Y0", data.ego_y),
        _scalar("EGO_V0", data.ego_v),
        _scalar("EGO_ACC0", data.ego_acc),
        _scalar("EGO_HEAD0", data.ego_head),
        "// ---- road: polygon p has the vertices ROAD_START[p] .. ROAD_START[p + 1] - 1",
        _scalar("ROAD_N", data.road_count),
        _array("ROAD_START", data.road_start),
        _array("ROAD_X", data.road_x),
        _array("ROAD_Y", data.road_y),
        "// ---- obstacles: obstacle i exists at OBS_FROM[i] <= count <= OBS_UNTIL[i];",
        "//      its waypoints are WP_START[i] .. WP_START[i + 1] - 1, times WP_T in sense periods",
        _scalar("OBS_N", data.obstacle_count),
        _obstacle_ids(data.obs_id),
        _array("OBS_LENGTH", data.obs_length),
        _array("OBS_WIDTH", data.obs_width),
        _array("OBS_FROM", data.obs_from),
        _array("OBS_UNTIL", data.obs_until),
        _array("WP_START", data.wp_start),
        _array("WP_T", data.wp_time),
        _array("WP_X", data.wp_x),
        _array("WP_Y", data.wp_y),
        _array("WP_HEAD", data.wp_head),
        _array("WP_VEL", data.wp_vel),
        "// ---- goal: polygons like the road's, times in sense periods",
        _scalar("GOAL_N", data.goal_count),
        _array("GOAL_START", data.goal_start),
        _array("GOAL_X", data.goal_x),
        _array("GOAL_Y", data.goal_y),
        _scalar("GOAL_LOW", data.goal_low),
        _scalar("GOAL_HIGH", data.goal_high),
        _scalar("GOAL_CX", data.goal_cx),
        _scalar("GOAL_CY", data.goal_cy),
        "// a goal of time alone (a goal state without a position): goal() reads the window only",
        f"const bool GOAL_ANYWHERE = {'true' if data.goal_anywhere else 'false'};",
        "// ---- the ego rectangle's corners as (along, across) signs",
        _array("CORNER_A", (1, 1, -1, -1)),
        _array("CORNER_B", (1, -1, -1, 1)),
        "// ---- state: the sample index (the Timer increments it at each sense) and the sensed ego",
        "int32_t count = 0;",
        f"int32_t x = {_int(data.ego_x)};",
        f"int32_t y = {_int(data.ego_y)};",
        f"int32_t v = {_int(data.ego_v)};",
        f"int32_t acc = {_int(data.ego_acc)};",
        f"int32_t head = {_int(data.ego_head)};",
        "int32_t jerk = 0;",
        "int32_t turn = 0;",
        "// collision sticky: a collision at this sample or an earlier one (keep_collision() sets it)",
        f"const bool STICKY_COLLISION = {'true' if data.sticky else 'false'};",
        "bool crashed = false;",
        "",
        environment().get_template("model_functions.c.j2").render(increments=data.increments),
    ]
    return "\n".join(out)


_GLOBAL = re.compile(r"^(?:const )?(?:int32_t|double|bool|void) ([A-Za-z_][A-Za-z0-9_]*)", re.MULTILINE)


def declared_names(data: ModelData) -> tuple[str, ...]:
    """Every global name (constant, variable, function) :func:`emit_declarations` declares, in order."""
    return tuple(_GLOBAL.findall(emit_declarations(data)))
