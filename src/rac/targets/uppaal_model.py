"""The UPPAAL target with a ``model`` block: the whole model of the automaton in its scenario.

``rac compile --target uppaal FILE.ra -o out.xml`` on a file with a ``model`` block writes the
paper's model (Sections 3-5, Fig. 3 and Fig. 5) for the scenario the block names, instead of the
automaton alone (:mod:`rac.targets.uppaal`). Its processes, in the order of the ``system`` line:

- ``Timer`` — as in the automaton-alone model (``accrue!``, waits for ``read``, ``sense!``,
  ``finish!`` after the last sample), plus ``decide!`` at time 0 and after ``sense!`` every
  ``DECIDE_EVERY`` samples (C2 / C1). It increments the scenario declarations' ``count``;
- ``Controller`` — on ``accrue?`` it calls ``sense_state()`` (Algorithm 1: the ego over the last
  period, with the current actions), then, from a committed location, sends ``read!`` assigning
  every bound input from its binding (a numeric input gets the significand ``d2i(e)``);
  ``prev(e)`` is a variable per distinct ``e``, set to ``e`` at the start and after each reading;
- ``Action`` — on ``decide?`` it moves to a committed location whose one outgoing edge is
  controllable: ``select j : int[0,JERK_COUNT-1], u : int[0,TURN_COUNT-1]`` assigns
  ``jerk = JERK_VALUES[j], turn = TURN_VALUES[u]``;
- ``Dynamics`` — the ground truth: hybrid clocks ``true_x, true_y, true_v, true_acc, true_head``
  with the ODEs of the kinematic model (unclamped), from the ego's start;
- one ``Obstacle`` process per dynamic obstacle (``Obstacle(i)``): hybrid clocks ``ox, oy`` moving
  with the velocity and heading of the current waypoint, set from ``obs_x(i), obs_y(i)`` at every
  ``accrue?`` (so they are exact at samples, and the rates change when a waypoint is reached);
- the reward automaton, exactly as in the automaton-alone model.

The queries are the file's own, then the paper's standard set (Qa-Qd, Fig. 7's simulations with
and without the shield, the unsafe-distance probability under the shield, reachSafe and a run
under it, the learning query reach and its checks), each named in its comment.

Example::

    result = compile_file("examples/left_turn/model.ra")
    model = generate_uppaal_model(result.automaton, source_name="model.ra", model_name="model.xml")
"""

from __future__ import annotations

import dataclasses
from fractions import Fraction

from rac import ast, ir
from rac.model.data import ModelData, build_model_data
from rac.model_block import SETTINGS
from rac.scenario import load_scenario
from rac.targets.uppaal import (
    UppaalModel,
    _edge,
    _environment,
    _Generator,
    _Ids,
    _Location,
    _Template,
)
from rac.targets.uppaal_expr import NotRepresentable, double_literal
from rac.targets.uppaal_functions import _action_name, declared_names, emit_declarations

__all__ = ["generate_uppaal_model"]

#: Settings with a name in the paper (significands in the declarations): ``i2d(NAME)`` is the value.
PAPER_NAMES = {"collision_distance": "TD", "max_acceleration": "MA", "max_turn": "MT",
               "comfort_acceleration": "P1", "comfort_turn": "P2"}
_EGO = ("x", "y", "v", "acc", "head", "jerk", "turn")
_BOOL_FUNCTIONS = ("collide", "offroad", "goal")
_NUM_FUNCTIONS = ("mindist", "dist_goal")
_MATH = {"fabs": "fabs", "abs": "fabs", "sqrt": "sqrt", "fmin": "fmin", "fmax": "fmax"}

# precedence levels of the binding printer
_OR, _AND, _CMP, _ADD, _MUL, _UNARY, _ATOM = range(1, 8)
_LEVEL = {"||": _OR, "&&": _AND, "+": _ADD, "-": _ADD, "*": _MUL, "/": _MUL,
          **{op: _CMP for op in ast.COMPARISON_OPS}}


class _BindingPrinter:
    """A binding's expression in UPPAAL (and C) syntax; ``prev(e)`` reads a variable per ``e``."""

    def __init__(self, spec: ir.ModelSpec, period_seconds: str):
        self.spec = spec
        self.period_seconds = period_seconds
        self.prevs: dict[str, tuple[str, bool]] = {}  # printed argument -> (variable, is bool)

    def is_bool(self, expr: ast.Expr) -> bool:
        if isinstance(expr, ast.BoolLit):
            return True
        if isinstance(expr, ast.Unary):
            return expr.op == "!"
        if isinstance(expr, ast.Binary):
            return expr.op in ast.COMPARISON_OPS or expr.op in ast.LOGICAL_OPS
        if isinstance(expr, ast.Call):
            if expr.func == "prev":
                return self.is_bool(expr.args[0])
            return expr.func in _BOOL_FUNCTIONS
        return False

    def print(self, expr: ast.Expr) -> str:
        return self._expr(expr)[0]

    def _expr(self, expr: ast.Expr) -> tuple[str, int]:
        if isinstance(expr, ast.Number):
            return double_literal(expr.value), _ATOM
        if isinstance(expr, ast.BoolLit):
            return ("true" if expr.value else "false"), _ATOM
        if isinstance(expr, ast.Name):
            if expr.id in _EGO:
                return f"i2d({expr.id})", _ATOM
            if expr.id == "time":
                return f"count * {self.period_seconds}", _MUL
            if expr.id in PAPER_NAMES:
                return f"i2d({PAPER_NAMES[expr.id]})", _ATOM
            if expr.id == "sensor_error":
                return "THD", _ATOM
            if expr.id in SETTINGS:
                return double_literal(Fraction(getattr(self.spec, expr.id))), _ATOM
            raise NotRepresentable(f"`{expr.id}` cannot be read by a binding")
        if isinstance(expr, ast.Call):
            if expr.func == "prev":
                argument = self.print(expr.args[0])
                if argument not in self.prevs:
                    self.prevs[argument] = (f"prev{len(self.prevs)}", self.is_bool(expr.args[0]))
                return self.prevs[argument][0], _ATOM
            if expr.func in _BOOL_FUNCTIONS or expr.func in _NUM_FUNCTIONS:
                return f"{expr.func}()", _ATOM
            if expr.func in _MATH:
                return f"{_MATH[expr.func]}({', '.join(self.print(a) for a in expr.args)})", _ATOM
            raise NotRepresentable(f"`{expr.func}()` cannot be read by a binding")
        if isinstance(expr, ast.Unary):
            text, level = self._expr(expr.operand)
            return expr.op + (f"({text})" if level < _UNARY else text), _UNARY
        if isinstance(expr, ast.Binary):
            if expr.op == "imply":
                left, right = self._expr(expr.left), self._expr(expr.right)
                negated = "!" + (f"({left[0]})" if left[1] < _UNARY else left[0])
                return f"{negated} || {right[0] if right[1] > _OR else f'({right[0]})'}", _OR
            level = _LEVEL[expr.op]
            left, right = self._expr(expr.left), self._expr(expr.right)
            left_text = f"({left[0]})" if left[1] < level else left[0]
            right_text = f"({right[0]})" if right[1] <= level else right[0]
            return f"{left_text} {expr.op} {right_text}", level
        raise NotRepresentable("this part of a binding is not an expression")


class _ModelGenerator(_Generator):
    def __init__(self, automaton: ir.Automaton, data: ModelData, source_name: str, model_name: str):
        self.data = data
        super().__init__(automaton, source_name, model_name)

    def reserved_names(self):
        return (*declared_names(self.data), "MA", "MT", "THD", "MAXT", "UNIT_S", "PAPER", "prev")

    def _names(self) -> None:
        super()._names()
        n, g = self.n, self.g
        g["count"] = "count"  # the scenario declarations' sample index (reserved for the .ra names)
        g["scale"] = "SCALE"
        self.channels["decide"] = n.fresh("decide")
        for key, base in (("controller", "Controller"), ("action", "Action"), ("dynamics", "Dynamics"),
                          ("obstacle", "Obstacle"), ("start", "Start"), ("deciding", "Deciding"),
                          ("sensing", "Sensing"), ("init", "Init"), ("driving", "Running"), ("moving", "Moving"),
                          ("safe", "safe"), ("reach", "reach"), ("reach_safe", "reachSafe"),
                          ("read_inputs", "read_inputs"),
                          ("init_prevs", "init_prevs")):
            g[key] = n.fresh(base)

    # ------------------------------------------------------------ processes
    def _timer(self, ids: _Ids) -> _Template:
        g, ch = self.g, self.channels
        start = _Location(ids(), g["start"], -272, 0, committed=True)
        wait = _Location(ids(), g["wait"], 0, 0, f"{g['t']} <= {g['period']}")
        accrued = _Location(ids(), g["accrued"], 272, 0, committed=True)
        reading = _Location(ids(), g["reading"], 272, 170, committed=True)
        deciding = _Location(ids(), g["deciding"], 0, 340, committed=True)
        ending = _Location(ids(), g["ending"], 544, 170, committed=True)
        done = _Location(ids(), g["done"], 816, 170, f"{g['t']} <= {g['period']}")
        more, decide = f"{g['count']} < {g['steps']}", f"{g['count']} % DECIDE_EVERY == 0"
        settle = f"{g['settled']} = true"
        transitions = [
            _edge(ids, start, wait, sync=f"{ch['decide']}!", anchor=(-250, -30)),
            _edge(ids, wait, accrued, guard=f"{g['t']} >= {g['period']} && {more}",
                  sync=f"{ch['accrue']}!", assignment=f"{g['t']} = 0, {g['count']}++", anchor=(40, -60)),
            _edge(ids, accrued, reading, sync=f"{ch['read']}?", assignment=f"{g['settled']} = false",
                  anchor=(282, 70)),
            _edge(ids, reading, wait, guard=f"{more} && {g['count']} % DECIDE_EVERY != 0", sync=f"{ch['sense']}!",
                  assignment=settle, anchor=(60, 110)),
            _edge(ids, reading, deciding, guard=f"{more} && {decide}", sync=f"{ch['sense']}!",
                  assignment=settle, anchor=(150, 280)),
            _edge(ids, deciding, wait, sync=f"{ch['decide']}!", anchor=(-100, 170)),
            _edge(ids, reading, ending, guard=f"{g['count']} == {g['steps']}", sync=f"{ch['sense']}!",
                  assignment=settle, anchor=(330, 180)),
            _edge(ids, ending, done, sync=f"{ch['finish']}!", anchor=(620, 180)),
            _edge(ids, done, done, guard=f"{g['t']} >= {g['period']}", assignment=f"{g['t']} = 0",
                  nails=[(790, 240), (842, 240)], anchor=(780, 250)),
        ]
        return _Template(g["timer"], start.id, [start, wait, accrued, reading, deciding, ending, done], transitions,
                         declaration=f"clock {g['t']};", name_x=-300, name_y=-100)

    def _bindings(self) -> tuple[list[str], list[str]]:
        """The read! edge's input assignments and the prev(...) updates (also the initial values)."""
        spec = self.a.model
        assert spec is not None
        printer = _BindingPrinter(spec, double_literal(Fraction(self.a.period)))
        numeric = {i.name for i in self.a.numeric_inputs}
        assigns = []
        for binding in spec.bindings:
            try:
                text = printer.print(binding.expr)
            except NotRepresentable as exc:
                self._unrepresentable(f"the binding of `{binding.input}` cannot be written in UPPAAL: {exc}",
                                      binding.span, hints=[])
                continue
            name = self.n[binding.input]
            assigns.append(f"{name} = d2i({text})" if binding.input in numeric else f"{name} = {text}")
        self.prevs = printer.prevs
        return assigns, [f"{var} = {text}" for text, (var, _) in printer.prevs.items()]

    def _controller(self, ids: _Ids) -> _Template:
        """The bindings are evaluated in functions (as the paper's ``sense()``): an edge that compares
        or assigns doubles itself would exclude the model from symbolic analysis (reference §2)."""
        g, ch = self.g, self.channels
        assigns, prevs = self._bindings()

        def function(name: str, comment: str, statements: list[str]) -> list[str]:
            return [f"// {comment}", f"void {name}() {{", *(f"    {s};" for s in statements), "}"]

        declaration = "\n".join([
            *function(g["read_inputs"], "The bindings of the model block, at every sample (after sense_state()); "
                      "then prev(e) := e.", assigns + prevs),
            "",
            *function(g["init_prevs"], "prev(e) at the start: e in the initial state.", prevs),
        ])
        init = _Location(ids(), g["init"], -272, 0, committed=True)
        idle = _Location(ids(), g["idle"], 0, 0)
        sensing = _Location(ids(), g["sensing"], 340, 0, committed=True)
        transitions = [
            _edge(ids, init, idle, assignment=f"{g['init_prevs']}()", anchor=(-250, -30)),
            _edge(ids, idle, sensing, sync=f"{ch['accrue']}?", assignment="sense_state()", nails=[(170, -50)],
                  anchor=(140, -80)),
            _edge(ids, sensing, idle, sync=f"{ch['read']}!", assignment=f"{g['read_inputs']}()",
                  nails=[(170, 60)], anchor=(20, 80)),
        ]
        return _Template(g["controller"], init.id, [init, idle, sensing], transitions, declaration=declaration,
                         name_x=-300, name_y=-100)

    def _action(self, ids: _Ids) -> _Template:
        g, ch = self.g, self.channels
        idle = _Location(ids(), g["idle"], 0, 0)
        choosing = _Location(ids(), g["choosing"], 340, 0, committed=True)
        selects, assigns = [], []
        for action, var in zip(self.data.actions, ("j", "u")):
            name = _action_name(action.name)
            selects.append(f"{var} : int[0,{name}_COUNT-1]")
            assigns.append(f"{action.name} = {name}_VALUES[{var}]")
        transitions = [
            _edge(ids, idle, choosing, sync=f"{ch['decide']}?", nails=[(170, -50)], anchor=(140, -80)),
            _edge(ids, choosing, idle, select=", ".join(selects), assignment=", ".join(assigns), nails=[(170, 60)],
                  anchor=(20, 80), controllable=True),
        ]
        return _Template(g["action"], idle.id, [idle, choosing], transitions, name_x=-40, name_y=-100)

    def _dynamics(self, ids: _Ids) -> _Template:
        g = self.g
        # Saturated like sense_state(): the acceleration stops at +-MA and the speed at VMIN/VMAX
        # (the truth brakes to a stop instead of reversing), as rac's native integrator does.
        ode = ("true_x' == UNIT_S * true_v * cos(true_head) && true_y' == UNIT_S * true_v * sin(true_head) && "
               "true_v' == ((true_v >= i2d(MAX_SPEED) && true_acc > 0.0) || (true_v <= i2d(MIN_SPEED) && "
               "true_acc < 0.0) ? 0.0 : UNIT_S * true_acc) && "
               "true_acc' == ((true_acc >= i2d(MAX_ACC) && jerk > 0) || (true_acc <= -i2d(MAX_ACC) && jerk < 0) ? "
               "0.0 : UNIT_S * jerk / SCALE_D) && "
               "true_head' == UNIT_S * turn / SCALE_D")
        init = _Location(ids(), g["init"], -272, 0, committed=True)
        driving = _Location(ids(), g["driving"], 0, 0, ode)
        start = ("true_x = i2d(EGO_X0), true_y = i2d(EGO_Y0), true_v = i2d(EGO_V0), true_acc = i2d(EGO_ACC0), "
                 "true_head = i2d(EGO_HEAD0)")
        transitions = [_edge(ids, init, driving, assignment=start, anchor=(-250, -60))]
        return _Template(g["dynamics"], init.id, [init, driving], transitions,
                         declaration="hybrid clock true_x, true_y, true_v, true_acc, true_head;",
                         name_x=-300, name_y=-100)

    def _obstacle(self, ids: _Ids) -> _Template:
        g, ch = self.g, self.channels
        declaration = "\n".join([
            "// The obstacle's position (m): exact at every sample, straight motion in between.",
            "hybrid clock ox, oy;",
            "",
            "// The speed (m/s) of the waypoint at sample count (0 when the obstacle is absent).",
            "double speed() {",
            "    int32_t j;",
            "    double r;",
            "    r = 0.0;",
            "    j = obs_wp(i);",
            "    if (j >= 0) {",
            "        r = i2d(WP_VEL[j]);",
            "    }",
            "    return r;",
            "}",
            "",
            "void follow() {",
            "    ox = obs_x(i);",
            "    oy = obs_y(i);",
            "}",
        ])
        init = _Location(ids(), g["init"], -272, 0, committed=True)
        moving = _Location(ids(), g["moving"], 0, 0,
                           "ox' == UNIT_S * speed() * cos(obs_head(i)) && oy' == UNIT_S * speed() * sin(obs_head(i))")
        transitions = [
            _edge(ids, init, moving, assignment="follow()", anchor=(-200, -30)),
            _edge(ids, moving, moving, sync=f"{ch['accrue']}?", assignment="follow()",
                  nails=[(-30, -80), (30, -80)], anchor=(-20, -120)),
        ]
        return _Template(g["obstacle"], init.id, [init, moving], transitions, declaration=declaration,
                         name_x=-300, name_y=-100, parameter="const int32_t i")

    # ------------------------------------------------------------ queries
    def _standard_queries(self) -> list[dict[str, str]]:
        g, a = self.g, self.a
        safety = "!collide() && !offroad()"
        objective = " + ".join(self.n[r] for r in a.rewards)
        dyn = g["dynamics"]
        return [
            {"name": "Qa: sensor error (Pr of the sensed x drifting THD from the true x)",
             "formula": f"Pr[<=MAXT](<> fabs({dyn}.true_x - x / SCALE_D) >= THD)"},
            {"name": "Qb: a safe run exists", "formula": f"E[] {safety}"},
            {"name": "Qc: a safe run reaches the goal", "formula": f"E<> {safety} && goal()"},
            {"name": "Qd: the safety shield (most permissive safe strategy)",
             "formula": f"strategy {g['safe']} = control: A[] {safety}"},
            {"name": "Fig. 7: the distance to the nearest obstacle against 3*TD, unshielded",
             "formula": "simulate[<=MAXT;100]{mindist(), 3*TD / SCALE_D}"},
            {"name": "Fig. 7 under the shield: the distance against 3*TD",
             "formula": f"simulate[<=MAXT;100]{{mindist(), 3*TD / SCALE_D}} under {g['safe']}"},
            {"name": "unsafe distance under the shield: Pr of coming closer than 3*TD",
             "formula": f"Pr[<=MAXT](<> mindist() <= 3*TD / SCALE_D) under {g['safe']}"},
            {"name": "reachSafe: learning to reach the goal under the shield",
             "formula": (f"strategy {g['reach_safe']} = maxE({objective})[<=MAXT]{{{self.process}.location}}"
                         f"->{{x, y, v, head}}: <> goal() under {g['safe']}")},
            {"name": "a run under reachSafe (the learned trajectory)",
             "formula": f"simulate[<=MAXT;1]{{x, y, v, head}} under {g['reach_safe']}"},
            {"name": "learning: the rewards' sum, maximised under the shield",
             "formula": (f"strategy {g['reach']} = maxE({objective})[<=MAXT]{{{self.process}.location}}"
                         f"->{{x, y, v, head}}: <> {g['time']} >= MAXT under {g['safe']}")},
            {"name": "learned strategy is safe", "formula": f"A[] {safety} under {g['reach']}"},
            {"name": "learned strategy reaches the goal", "formula": f"A<> goal() under {g['reach']}"},
        ]

    def _vocabulary(self, unit: Fraction):
        return dataclasses.replace(super()._vocabulary(unit), model_functions=())

    # ------------------------------------------------------------ the whole model
    def run(self) -> UppaalModel:
        a, g, data = self.a, self.g, self.data
        spec = a.model
        assert spec is not None
        inputs, unit, period_units, accruals = self._prepare()
        queries = self._queries(unit) + self._standard_queries()
        ids = _Ids()
        templates = [self._timer(ids), self._controller(ids), self._action(ids), self._dynamics(ids)]
        if data.obstacle_count:
            templates.append(self._obstacle(ids))
        templates.append(self._automaton(ids, unit, accruals))
        if self.diagnostics:
            from rac.targets.uppaal import UppaalError

            raise UppaalError(self.diagnostics)
        env = _environment()
        settings = [
            ("MA", data.max_acc, "max_acceleration (significand)"),
            ("MT", data.max_turn, "max_turn (significand)"),
        ]
        declaration = env.get_template("model_declaration.j2").render(
            **self._declaration_args(inputs, unit, period_units),
            scenario=spec.scenario, process=self.process, unit_double=double_literal(unit),
            names={k: g[k] for k in ("period", "steps", "scale", "count", "settled", "time", "controller", "action",
                                     "dynamics", "obstacle")},
            scenario_declarations=emit_declarations(data), settings=settings,
            writer=g["controller"], value_arrays=False,
            thd=double_literal(spec.sensor_error), maxt=a.steps * period_units,
            prevs=[(var, "bool" if is_bool else "double", text) for text, (var, is_bool) in self.prevs.items()])
        obstacles = [f"{g['obstacle']}{i}" for i in range(data.obstacle_count)]
        system = env.get_template("model_system.j2").render(
            channels=self.channels, names=g, obstacles=obstacles,
            processes=[g["timer"], g["controller"], g["action"], g["dynamics"], *obstacles, self.process])
        return self._files(declaration, templates, system, queries)


def generate_uppaal_model(automaton: ir.Automaton, *, data: ModelData | None = None, source_name: str = "",
                          model_name: str = "") -> UppaalModel:
    """The whole UPPAAL model of ``automaton`` in the scenario of its ``model`` block, and its queries.

    ``data`` is the model's data when already built (else the scenario is loaded from
    ``automaton.model.scenario_path``). Raises :class:`rac.targets.uppaal.UppaalError` like
    :func:`rac.targets.uppaal.generate_uppaal`; :class:`rac.scenario.ScenarioError` or
    :class:`rac.model.ModelRangeError` when the scenario cannot be loaded or represented.
    """
    spec = automaton.model
    if spec is None:
        raise ValueError("the automaton has no `model` block")
    if data is None:
        data = build_model_data(load_scenario(spec.scenario_path), spec)
    return _ModelGenerator(automaton, data, source_name, model_name).run()
