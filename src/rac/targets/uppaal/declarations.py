"""UPPAAL global declarations of the scenario model: its data and its functions.

:func:`emit_declarations` prints :class:`rac.model.ModelData` as ``const`` scalars and arrays, the
controller's state variables and the functions ``sense_state()``, ``mindist()``, ``collide()``,
``offroad()``, ``goal()``, ``dist_goal()`` (with helpers ``i2d``, ``d2i``, ``obs_wp``,
``obs_present``, ``obs_x``, ``obs_y``, ``obs_head``, ``in_road``, ``in_goal``).
:func:`declared_names` lists every global name the text declares, so that the rest of the UPPAAL
model can avoid them.

The text is in the subset that is valid both in UPPAAL and in C99 (tests/test_model_c.py compiles
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

__all__ = ["C_PRELUDE", "declared_names", "emit_declarations"]

#: What a C compiler needs before the declarations (UPPAAL predeclares all of it).
C_PRELUDE = """\
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


def _scalar(name: str, value: int, comment: str = "") -> str:
    return f"const int32_t {name} = {_int(value)};" + (f"  // {comment}" if comment else "")


def _comment_text(text: str) -> str:
    return re.sub(r"[^\x20-\x7e]", "?", text).replace("*/", "* /")


def action_name(name: str) -> str:
    cleaned = re.sub(r"[^A-Za-z0-9_]", "_", name).upper()
    return cleaned if cleaned[:1].isalpha() else "A_" + cleaned


def _polygon_function(name: str, prefix: str) -> str:
    return f"""\
bool {name}(double px, double py) {{
    int32_t p;
    int32_t i;
    int32_t j;
    double xi;
    double yi;
    double xj;
    double yj;
    bool inside;
    bool found;
    found = false;
    for (p = 0; p < {prefix}_N; p++) {{
        inside = false;
        j = {prefix}_START[p + 1] - 1;
        for (i = {prefix}_START[p]; i < {prefix}_START[p + 1]; i++) {{
            xi = i2d({prefix}_X[i]);
            yi = i2d({prefix}_Y[i]);
            xj = i2d({prefix}_X[j]);
            yj = i2d({prefix}_Y[j]);
            if (((yi > py) != (yj > py)) && (px < (xj - xi) * (py - yi) / (yj - yi) + xi)) {{
                inside = !inside;
            }}
            j = i;
        }}
        if (inside) {{
            found = true;
        }}
    }}
    return found;
}}
"""


_FUNCTIONS = """\
// ---- conversions (Eq. (1)): a significand s stands for s / SCALE
double i2d(int32_t s) {
    return s / SCALE_D;
}

int32_t d2i(double d) {
    return fint(d * SCALE_D);
}

// ---- the ground truth's saturation (template Dynamics): the rate of a value kept in [low, high],
// 0 where the value is at a bound and the rate points outward
double saturated(double value, double rate, double low, double high) {
    double r;
    r = rate;
    if ((value >= high && rate > 0.0) || (value <= low && rate < 0.0)) {
        r = 0.0;
    }
    return r;
}

// ---- sense_state(): Algorithm 1, SUBSTEPS Euler sub-steps of SENSE_UNIT = C1 * G seconds
void sense_state() {
    int32_t i;
    double fx;
    double fy;
    double fv;
    double fa;
    double fh;
    double fj;
    double ft;
    double ma;
    double vmin;
    double vmax;
    fx = i2d(x);
    fy = i2d(y);
    fv = i2d(v);
    fa = i2d(acc);
    fh = i2d(head);
    fj = i2d(jerk);
    ft = i2d(turn);
    ma = i2d(MAX_ACC);
    vmin = i2d(MIN_SPEED);
    vmax = i2d(MAX_SPEED);
    for (i = 0; i < SUBSTEPS; i++) {
        fa = fa + fj * SENSE_UNIT;
        if (fa > ma) {
            fa = ma;
        }
        if (fa < -ma) {
            fa = -ma;
        }
        fh = fh + ft * SENSE_UNIT;
        fv = fv + fa * SENSE_UNIT;
        if (fv > vmax) {
            fv = vmax;
        }
        if (fv < vmin) {
            fv = vmin;
        }
        fx = fx + fv * cos(fh) * SENSE_UNIT;
        fy = fy + fv * sin(fh) * SENSE_UNIT;
    }
    x = d2i(fx);
    y = d2i(fy);
    v = d2i(fv);
    acc = d2i(fa);
    head = d2i(fh);
}

// ---- obstacles at sample count: the last waypoint at or before it, straight motion since
int32_t obs_wp(int32_t i) {
    int32_t j;
    int32_t m;
    j = -1;
    if (count >= OBS_FROM[i] && count <= OBS_UNTIL[i]) {
        j = WP_START[i];
        for (m = WP_START[i] + 1; m < WP_START[i + 1]; m++) {
            if (WP_T[m] <= count) {
                j = m;
            }
        }
    }
    return j;
}

bool obs_present(int32_t i) {
    return obs_wp(i) >= 0;
}

double obs_head(int32_t i) {
    int32_t j;
    double h;
    h = 0.0;
    j = obs_wp(i);
    if (j >= 0) {
        h = i2d(WP_HEAD[j]);
    }
    return h;
}

double obs_x(int32_t i) {
    int32_t j;
    double h;
    double dt;
    double r;
    r = 0.0;
    j = obs_wp(i);
    if (j >= 0) {
        dt = (count - WP_T[j]) * SENSE_PERIOD_S;
        h = i2d(WP_HEAD[j]);
        r = i2d(WP_X[j]) + i2d(WP_VEL[j]) * cos(h) * dt;
    }
    return r;
}

double obs_y(int32_t i) {
    int32_t j;
    double h;
    double dt;
    double r;
    r = 0.0;
    j = obs_wp(i);
    if (j >= 0) {
        dt = (count - WP_T[j]) * SENSE_PERIOD_S;
        h = i2d(WP_HEAD[j]);
        r = i2d(WP_Y[j]) + i2d(WP_VEL[j]) * sin(h) * dt;
    }
    return r;
}

// ---- mindist(): each L x W rectangle as 3 discs of radius sqrt((L/6)^2 + (W/2)^2) at -L/3, 0, +L/3
double mindist() {
    int32_t i;
    int32_t a;
    int32_t b;
    double ex;
    double ey;
    double eh;
    double ec;
    double es;
    double el;
    double ew;
    double er;
    double eoff;
    double ox;
    double oy;
    double oh;
    double oc;
    double osn;
    double ol;
    double ow;
    double orad;
    double ooff;
    double ax;
    double ay;
    double bx;
    double by;
    double dx;
    double dy;
    double d;
    double best;
    ex = i2d(x);
    ey = i2d(y);
    eh = i2d(head);
    ec = cos(eh);
    es = sin(eh);
    el = i2d(LENGTH);
    ew = i2d(WIDTH);
    er = sqrt((el / 6.0) * (el / 6.0) + (ew / 2.0) * (ew / 2.0));
    eoff = el / 3.0;
    best = NO_OBSTACLE;
    for (i = 0; i < OBS_N; i++) {
        if (obs_wp(i) >= 0) {
            ox = obs_x(i);
            oy = obs_y(i);
            oh = obs_head(i);
            oc = cos(oh);
            osn = sin(oh);
            ol = i2d(OBS_LENGTH[i]);
            ow = i2d(OBS_WIDTH[i]);
            orad = sqrt((ol / 6.0) * (ol / 6.0) + (ow / 2.0) * (ow / 2.0));
            ooff = ol / 3.0;
            for (a = 0; a < 3; a++) {
                ax = ex + (a - 1) * eoff * ec;
                ay = ey + (a - 1) * eoff * es;
                for (b = 0; b < 3; b++) {
                    bx = ox + (b - 1) * ooff * oc;
                    by = oy + (b - 1) * ooff * osn;
                    dx = ax - bx;
                    dy = ay - by;
                    d = sqrt(dx * dx + dy * dy) - er - orad;
                    if (d < best) {
                        best = d;
                    }
                }
            }
        }
    }
    return best;
}

bool collide() {
    return mindist() < i2d(TD);
}

// ---- point in polygons (ray casting)
{in_road}
{in_goal}
// ---- offroad(): a corner of the ego rectangle outside every road polygon
bool offroad() {
    int32_t j;
    double ex;
    double ey;
    double eh;
    double c;
    double s;
    double hl;
    double hw;
    double px;
    double py;
    bool off;
    ex = i2d(x);
    ey = i2d(y);
    eh = i2d(head);
    c = cos(eh);
    s = sin(eh);
    hl = i2d(LENGTH) / 2.0;
    hw = i2d(WIDTH) / 2.0;
    off = false;
    for (j = 0; j < 4; j++) {
        px = ex + CORNER_A[j] * hl * c - CORNER_B[j] * hw * s;
        py = ey + CORNER_A[j] * hl * s + CORNER_B[j] * hw * c;
        if (!in_road(px, py)) {
            off = true;
        }
    }
    return off;
}

// ---- goal(): the centre inside a goal polygon while GOAL_LOW <= count <= GOAL_HIGH
bool goal() {
    bool reached;
    reached = false;
    if (count >= GOAL_LOW && count <= GOAL_HIGH) {
        reached = in_goal(i2d(x), i2d(y));
    }
    return reached;
}

double dist_goal() {
    double dx;
    double dy;
    dx = i2d(x) - i2d(GOAL_CX);
    dy = i2d(y) - i2d(GOAL_CY);
    return sqrt(dx * dx + dy * dy);
}
"""


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
        _scalar("DECIDE_EVERY", data.decide_every, "C2 / C1"),
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
        _array("OBS_ID", data.obs_id, "CommonRoad ids"),
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
        "",
        _FUNCTIONS.replace("{in_road}", _polygon_function("in_road", "ROAD"))
        .replace("{in_goal}", _polygon_function("in_goal", "GOAL")),
    ]
    return "\n".join(out)


_GLOBAL = re.compile(r"^(?:const )?(?:int32_t|double|bool|void) ([A-Za-z_][A-Za-z0-9_]*)", re.MULTILINE)


def declared_names(data: ModelData) -> tuple[str, ...]:
    """Every global name (constant, variable, function) :func:`emit_declarations` declares, in order."""
    return tuple(_GLOBAL.findall(emit_declarations(data)))
