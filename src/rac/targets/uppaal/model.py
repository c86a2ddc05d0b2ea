"""The UPPAAL target with a ``model`` block: the whole model of the automaton in its scenario.

``rac compile --target uppaal FILE.ra -o out.xml`` on a file with a ``model`` block writes the
paper's model (Sections 3-5, Fig. 3 and Fig. 5) for the scenario the block names, instead of the
automaton alone (:mod:`rac.targets.uppaal.automaton`). Its processes, in the order of the ``system`` line:

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

from fractions import Fraction

from rac import ir
from rac.ir import expr as ie
from rac.ir import query as iq
from rac.ir.vocabulary import ACTIONS, EGO_STATE
from rac.model.data import ModelData
from rac.model.program import CheckedProgram
from rac.targets.uppaal.automaton import AutomatonGenerator, UppaalError, UppaalModel
from rac.targets.uppaal.declarations import DECIDE_EVERY, action_name, declared_names, emit_declarations
from rac.targets.uppaal.expr import NotRepresentable, QueryError, double_literal
from rac.targets.uppaal.layout import Ids, Location, Template, edge, environment
from rac.targets.uppaal.query import ModelNames, UppaalPrinter, Vocabulary
from rac.targets.uppaal.significands import NumericInput

__all__ = ["generate_uppaal_model", "model_vocabulary"]

#: The ego state's components that prev(e) may need from the previous sample (all but the actions
#: are always kept: they equal the current ones between samples, so they split no state).
_KEPT = tuple(name for name in EGO_STATE if name not in ACTIONS)


class _ModelGenerator(AutomatonGenerator):
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
                          ("read_inputs", "read_inputs"), ("keep_sample", "keep_sample"),
                          ("allowed", "ALLOWED"), ("allow_actions", "allow_actions"),
                          ("jerk_index", "j"), ("turn_index", "u")):  # the Action's select variables
            g[key] = n.fresh(base)
        # the processes `Obstacle0 = Obstacle(0);` ...: as global as the .ra names, so fresh like them
        self.obstacles = [n.fresh(f"{g['obstacle']}{i}") for i in range(self.data.obstacle_count)]

    # ------------------------------------------------------------ processes
    def _model_timer(self, ids: Ids, keeps: bool) -> Template:
        """``keeps``: the start edge calls ``keep_sample()`` — as the sender of the first ``decide!``,
        before the Action chooses, so ``prev(jerk)`` at the first sample reads the start's 0."""
        g, ch = self.g, self.channels
        start = Location(ids(), g["start"], -272, 0, committed=True)
        wait = Location(ids(), g["wait"], 0, 0, f"{g['t']} <= {g['period']}")
        accrued = Location(ids(), g["accrued"], 272, 0, committed=True)
        reading = Location(ids(), g["reading"], 272, 170, committed=True)
        deciding = Location(ids(), g["deciding"], 0, 340, committed=True)
        ending = Location(ids(), g["ending"], 544, 170, committed=True)
        done = Location(ids(), g["done"], 816, 170, f"{g['t']} <= {g['period']}")
        more, decide = f"{g['count']} < {g['steps']}", f"{g['count']} % {DECIDE_EVERY} == 0"
        settle = f"{g['settled']} = true"
        goes_on, last, finish = self.processes.ending()  # `episode ends when`
        transitions = [
            edge(ids, start, wait, sync=f"{ch['decide']}!", assignment=f"{g['keep_sample']}()" if keeps else "",
                  anchor=(-250, -30)),
            edge(ids, wait, accrued, guard=f"{g['t']} >= {g['period']} && {more}",
                  sync=f"{ch['accrue']}!", assignment=f"{g['t']} = 0, {g['count']}++", anchor=(40, -60)),
            edge(ids, accrued, reading, sync=f"{ch['read']}?", assignment=f"{g['settled']} = false",
                  anchor=(282, 70)),
            edge(ids, reading, wait, guard=f"{more} && {g['count']} % {DECIDE_EVERY} != 0{goes_on}",
                  sync=f"{ch['sense']}!", assignment=settle, anchor=(60, 110)),
            edge(ids, reading, deciding, guard=f"{more} && {decide}{goes_on}", sync=f"{ch['sense']}!",
                  assignment=settle, anchor=(150, 280)),
            edge(ids, deciding, wait, sync=f"{ch['decide']}!", anchor=(-100, 170)),
            edge(ids, reading, ending, guard=f"{g['count']} == {g['steps']}{last}", sync=f"{ch['sense']}!",
                  assignment=settle + finish, anchor=(330, 180)),
            edge(ids, ending, done, sync=f"{ch['finish']}!", anchor=(620, 180)),
            edge(ids, done, done, guard=f"{g['t']} >= {g['period']}", assignment=f"{g['t']} = 0",
                  nails=[(790, 240), (842, 240)], anchor=(780, 250)),
        ]
        return Template(g["timer"], start.id, [start, wait, accrued, reading, deciding, ending, done], transitions,
                         declaration=f"clock {g['t']};", name_x=-300, name_y=-100)

    def _inputs(self) -> list[NumericInput]:
        """The numeric inputs, without the automaton-alone Environment's values: here the Controller
        computes them (any significand), so a rate that reads one is checked as rac's engine checks
        it (its constant part), not at the values of its pieces (E0801 for a file `rac verify` runs)."""
        return self.numbers.inputs(self.n, self.array, self.select, chosen=False)

    def queries(self) -> tuple[iq.QueryDecl, ...]:
        """The file's queries, then the paper's standard ones (:mod:`rac.check.standard`)."""
        return self.a.queries + self.a.standard_queries

    def _vocabulary(self, unit: Fraction) -> Vocabulary:
        vocabulary = super()._vocabulary(unit)
        g = self.g
        model = ModelNames(dynamics=g["dynamics"], maxt="MAXT", timer=g["timer"], wait=g["wait"],
                           decide_every=DECIDE_EVERY, running=g["driving"])
        return Vocabulary(**{**vocabulary.__dict__, "model": model})

    def _bindings(self, printer: UppaalPrinter) -> str:
        """The declarations' bindings: ``read_inputs()`` assigns every input from its binding (a
        numeric input gets the significand ``d2i(e)``); ``prev(e)`` is ``e`` evaluated on the previous
        sample's state, which ``keep_sample()`` keeps in integers (the symbolic engine reads no double)."""
        spec, g, n = self.a.model, self.g, self.n
        assert spec is not None
        operands = ie.prev_operands([b.expr for b in spec.bindings])
        read = {r.name for e in operands for r in ie.refs(e) if r.is_model}
        kept = [c for c in (*_KEPT, "jerk", "turn") if c in _KEPT or c in read] if operands else []
        # collision sticky: collide() reads `crashed`, which keep_collision() has already set for this
        # sample when read_inputs() runs, so prev(collide()) needs the previous sample's `crashed` too
        crashed = ["crashed"] if self.data.sticky and any(
            isinstance(node, ie.Call) and node.name == "collide" for e in operands for node in ie.walk(e)) else []
        previous = {c: n.fresh(f"prev_{c}") for c in kept + crashed}
        now = {c: n.fresh(f"now_{c}") for c in kept + crashed}
        values = {operand: n.fresh(f"prev{i}") for i, operand in enumerate(operands)}
        printer.prevs = dict(values)
        numeric = {i.name for i in self.a.numeric_inputs}
        statements, locals_ = [], []
        if operands:
            locals_ += [f"int32_t {now[c]};" for c in kept] + [f"bool {now[c]};" for c in crashed]
            locals_ += [f"{'bool' if e.type == ie.BOOL else 'double'} {name};" for e, name in values.items()]
            statements += [f"{now[c]} = {c};" for c in kept + crashed]
            statements += [f"{c} = {previous[c]};" for c in kept + crashed]
            statements.append(f"{g['count']} = {g['count']} - 1;")
            statements += [self._bound(f"{name} = {{}};", e, printer, "prev(...) in a binding") for e, name in
                           values.items()]
            statements += [f"{c} = {now[c]};" for c in kept + crashed] + [f"{g['count']} = {g['count']} + 1;"]
        for binding in spec.bindings:
            target = self.n[binding.input]
            template = f"{target} = d2i({{}});" if binding.input in numeric else f"{target} = {{}};"
            statements.append(self._bound(template, binding.expr, printer, f"the binding of `{binding.input}`",
                                          binding.span))
        if operands:
            statements.append(f"{g['keep_sample']}();")
        lines = ["// ---- the bindings of the model block: the Controller calls "
                 f"{g['read_inputs']}() at every sample, after sense_state()"]
        if operands:
            lines += ["// prev(e) is e on the previous sample's state, which "
                      f"{g['keep_sample']}() keeps in integers (the symbolic engine reads no double)",
                      f"int32_t {', '.join(previous[c] for c in kept)};",
                      *(f"bool {previous[c]};" for c in crashed),
                      "",
                      f"void {g['keep_sample']}() {{", *(f"    {previous[c]} = {c};" for c in kept + crashed), "}",
                      ""]
        lines += [f"void {g['read_inputs']}() {{", *(f"    {line}" for line in locals_ + statements), "}"]
        return "\n".join(lines)

    def _allow(self, printer: UppaalPrinter) -> str:
        """``allow when e``: ``allow_actions()`` fills ``ALLOWED[j * TURN_COUNT + u]`` with ``e`` on the state
        each action pair leads to (``sense_state()`` on the state with that pair, at ``count + 1``) and
        restores the state; the Action calls it on ``decide?`` and its choice is guarded by the entry
        (a guard cannot call a function that assigns, so the mask is computed in an update)."""
        spec, g, data = self.a.model, self.g, self.data
        assert spec is not None
        if spec.allow is None:
            return ""
        jerk, turn = (action_name(a.name) for a in data.actions)
        size = len(data.actions[0].values) * len(data.actions[1].values)
        saved = {c: self.n.fresh(f"s_{c}") for c in ("x", "y", "v", "acc", "head", "jerk", "turn")}
        condition = self._bound(f"{g['allowed']}[j * {turn}_COUNT + u] = {{}};", spec.allow, printer,
                                "`allow when`", spec.allow.span or spec.span)
        body = [
            "int32_t j;", "int32_t u;", *(f"int32_t {name};" for name in saved.values()),
            *(f"{name} = {c};" for c, name in saved.items()),
            f"{g['count']} = {g['count']} + 1;",
            f"for (j = 0; j < {jerk}_COUNT; j++) {{",
            f"    for (u = 0; u < {turn}_COUNT; u++) {{",
            *(f"        {c} = {name};" for c, name in saved.items() if c not in ("jerk", "turn")),
            f"        jerk = {jerk}_VALUES[j];",
            f"        turn = {turn}_VALUES[u];",
            "        sense_state();",
            f"        {condition}",
            "    }",
            "}",
            *(f"{c} = {name};" for c, name in saved.items()),
            f"{g['count']} = {g['count']} - 1;",
        ]
        return "\n".join([
            "",
            "",
            "// ---- allow when: an action is allowed where the condition holds one sense period on; the Action",
            f"// calls {g['allow_actions']}() on its decide? edge, and its choice is guarded by {g['allowed']}",
            f"bool {g['allowed']}[{size}];",
            "",
            f"void {g['allow_actions']}() {{",
            *(f"    {line}" for line in body),
            "}",
        ])

    def _bound(self, template: str, expr: ie.Expr, printer: UppaalPrinter, what: str, span=None) -> str:
        try:
            return template.format(printer.binding(expr))
        except (QueryError, NotRepresentable) as exc:
            self.numbers.unrepresentable(f"{what} cannot be written in UPPAAL: {exc}", span, hints=[])
            return "// (not representable)"

    def _controller(self, ids: Ids) -> Template:
        """Senses on ``accrue?`` (``sense_state()``) and reads the inputs from the bindings on ``read!``
        (``read_inputs()``, in the declarations, as the paper's ``sense()``: an edge that compares or
        assigns doubles itself would exclude the model from symbolic analysis, reference §2)."""
        g, ch = self.g, self.channels
        init = Location(ids(), g["init"], -272, 0, committed=True)
        idle = Location(ids(), g["idle"], 0, 0)
        sensing = Location(ids(), g["sensing"], 340, 0, committed=True)
        sticky = self.data.sticky  # collision sticky: the start's and every sample's collision remembered
        transitions = [
            edge(ids, init, idle, anchor=(-250, -30), assignment="keep_collision()" if sticky else ""),
            edge(ids, idle, sensing, sync=f"{ch['accrue']}?",
                  assignment="sense_state(), keep_collision()" if sticky else "sense_state()", nails=[(170, -50)],
                  anchor=(140, -80)),
            edge(ids, sensing, idle, sync=f"{ch['read']}!", assignment=f"{g['read_inputs']}()",
                  nails=[(170, 60)], anchor=(20, 80)),
        ]
        return Template(g["controller"], init.id, [init, idle, sensing], transitions, name_x=-300, name_y=-100)

    def _action(self, ids: Ids) -> Template:
        g, ch = self.g, self.channels
        idle = Location(ids(), g["idle"], 0, 0)
        choosing = Location(ids(), g["choosing"], 340, 0, committed=True)
        selects, assigns = [], []
        # fresh select variables: one named like a .ra input would shadow it (UTAP warns)
        jerk_index, turn_index = g["jerk_index"], g["turn_index"]
        for action, var in zip(self.data.actions, (jerk_index, turn_index)):
            name = action_name(action.name)
            selects.append(f"{var} : int[0,{name}_COUNT-1]")
            assigns.append(f"{action.name} = {name}_VALUES[{var}]")
        guarded = self.a.model is not None and self.a.model.allow is not None
        turn = action_name(self.data.actions[1].name)
        transitions = [
            edge(ids, idle, choosing, sync=f"{ch['decide']}?", nails=[(170, -50)], anchor=(140, -80),
                  assignment=f"{g['allow_actions']}()" if guarded else ""),
            edge(ids, choosing, idle, select=", ".join(selects), assignment=", ".join(assigns), nails=[(170, 60)],
                  guard=f"{g['allowed']}[{jerk_index} * {turn}_COUNT + {turn_index}]" if guarded else "",
                  anchor=(20, 80), controllable=True),
        ]
        return Template(g["action"], idle.id, [idle, choosing], transitions, name_x=-40, name_y=-100)

    def _dynamics(self, ids: Ids) -> Template:
        g = self.g
        # Saturated like sense_state(): the acceleration stops at +-MA and the speed at VMIN/VMAX
        # (the truth brakes to a stop instead of reversing), as rac's native integrator does. The
        # saturation is the declarations' function saturated(): a conditional rate would need a
        # comparison of hybrid clocks as its condition, which UPPAAL's parser refuses.
        ode = ("true_x' == UNIT_S * true_v * cos(true_head) && true_y' == UNIT_S * true_v * sin(true_head) && "
               "true_v' == UNIT_S * saturated(true_v, true_acc, i2d(MIN_SPEED), i2d(MAX_SPEED)) && "
               "true_acc' == UNIT_S * saturated(true_acc, i2d(jerk), -i2d(MAX_ACC), i2d(MAX_ACC)) && "
               "true_head' == UNIT_S * i2d(turn)")
        init = Location(ids(), g["init"], -272, 0, committed=True)
        driving = Location(ids(), g["driving"], 0, 0, ode)
        start = ("true_x = i2d(EGO_X0), true_y = i2d(EGO_Y0), true_v = i2d(EGO_V0), true_acc = i2d(EGO_ACC0), "
                 "true_head = i2d(EGO_HEAD0)")
        transitions = [edge(ids, init, driving, assignment=start, anchor=(-250, -60))]
        return Template(g["dynamics"], init.id, [init, driving], transitions,
                         declaration="hybrid clock true_x, true_y, true_v, true_acc, true_head;",
                         name_x=-300, name_y=-100)

    def _obstacle(self, ids: Ids) -> Template:
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
        init = Location(ids(), g["init"], -272, 0, committed=True)
        moving = Location(ids(), g["moving"], 0, 0,
                           "ox' == UNIT_S * speed() * cos(obs_head(i)) && oy' == UNIT_S * speed() * sin(obs_head(i))")
        transitions = [
            edge(ids, init, moving, assignment="follow()", anchor=(-200, -30)),
            edge(ids, moving, moving, sync=f"{ch['accrue']}?", assignment="follow()",
                  nails=[(-30, -80), (30, -80)], anchor=(-20, -120)),
        ]
        return Template(g["obstacle"], init.id, [init, moving], transitions, declaration=declaration,
                         name_x=-300, name_y=-100, parameter="const int32_t i")

    # ------------------------------------------------------------ the whole model
    def run(self) -> UppaalModel:
        a, g, data = self.a, self.g, self.data
        spec = a.model
        assert spec is not None
        inputs, unit, period_units, accruals = self._prepare()
        printer = self._printer(unit)
        bindings = self._bindings(printer) + self._allow(printer)
        queries = self._queries(printer)
        ids = Ids()
        templates = [self._model_timer(ids, bool(printer.prevs)), self._controller(ids), self._action(ids),
                     self._dynamics(ids)]
        if data.obstacle_count:
            templates.append(self._obstacle(ids))
        templates.append(self.processes.automaton(ids, unit, accruals))
        if self.diagnostics:
            raise UppaalError(self.diagnostics)
        env = environment()
        settings = [
            ("MA", data.max_acc, "max_acceleration (significand)"),
            ("MT", data.max_turn, "max_turn (significand)"),
        ]
        declaration = env.get_template("model_declaration.j2").render(
            **self._declaration_args(inputs, unit, period_units),
            scenario=spec.scenario, process=self.process, unit_double=double_literal(unit),
            names={k: g[k] for k in ("period", "steps", "scale", "count", "settled", "time", "controller", "action",
                                     "dynamics", "obstacle", "ended") if k in g},
            scenario_declarations=emit_declarations(data), settings=settings,
            writer=g["controller"], value_arrays=False,
            thd=double_literal(spec.sensor_error), maxt=a.steps * period_units,
            bindings=bindings, conditions=self._conditions(printer))
        system = env.get_template("model_system.j2").render(
            channels=self.channels, names=g, obstacles=self.obstacles,
            processes=[g["timer"], g["controller"], g["action"], g["dynamics"], *self.obstacles, self.process])
        return self._files(declaration, templates, system, queries)


def generate_uppaal_model(automaton: ir.Automaton | CheckedProgram, *, data: ModelData | None = None,
                          source_name: str = "", model_name: str = "") -> UppaalModel:
    """The whole UPPAAL model of ``automaton`` in the scenario of its ``model`` block, and its queries.

    ``automaton`` is a :class:`rac.model.program.CheckedProgram` (``rac compile``: the model's data the
    checks built) or an :class:`rac.ir.Automaton`; ``data`` is the model's data when built otherwise
    (else, for an automaton, the scenario is loaded as ``rac check`` loads it, at the block's
    ``planning_problem``: :meth:`rac.model.program.CheckedProgram.of`). Raises
    :class:`rac.targets.uppaal.automaton.UppaalError` like
    :func:`rac.targets.uppaal.automaton.generate_uppaal`; :class:`rac.model.commonroad.ScenarioError` or
    :class:`rac.model.ModelRangeError` when the scenario cannot be loaded or represented (a
    :class:`rac.model.commonroad.PlanningProblemError` where ``rac check`` reports E0715).
    """
    checked, data = _model_of(automaton, data)
    return _ModelGenerator(checked, data, source_name, model_name).run()


def model_vocabulary(automaton: ir.Automaton | CheckedProgram, *, data: ModelData | None = None) -> Vocabulary:
    """The UPPAAL names of everything a query or binding reads in the whole model of ``automaton``
    (as :func:`generate_uppaal_model` names them, ``data`` as there): for printing more expressions
    over it."""
    checked, data = _model_of(automaton, data)
    return _ModelGenerator(checked, data, "", "").vocabulary()


def _model_of(source: ir.Automaton | CheckedProgram, data: ModelData | None) -> tuple[ir.Automaton, ModelData]:
    """The automaton and the model's data: ``data``, else the program's, else loaded by the checks'
    loader. ``ValueError`` without a `model` block."""
    automaton = source.automaton if isinstance(source, CheckedProgram) else source
    if automaton.model is None:
        raise ValueError("the automaton has no `model` block")
    if data is not None:
        return automaton, data
    program = source if isinstance(source, CheckedProgram) else CheckedProgram.of(automaton)
    return automaton, program.data
