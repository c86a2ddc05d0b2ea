"""The UPPAAL target: a closed UPPAAL 5 model of one reward automaton, and its queries.

``rac compile --target uppaal FILE.ra -o out.xml`` writes ``out.xml`` (the model, with the
file's queries embedded) and ``out.q`` (the same queries, one per line). For a file with a
``model`` block it writes the whole model in the block's scenario instead
(:mod:`rac.targets.uppaal.model`, which reuses this module's generator). The automaton-alone
model has three processes:

- ``Timer`` — every sample period it broadcasts ``accrue``, waits for the Environment's
  ``read``, then broadcasts ``sense``; after the horizon's last sample it broadcasts ``finish``
  once, then idles (it keeps ticking, so the model never deadlocks);
- the reward automaton, named after the ``.ra`` automaton — one location per ``.ra`` location,
  the rates as ODEs of hybrid clocks (``sa' == 0.1``, per time unit), a ``accrue?`` self-loop
  that advances the integer mirrors of the rewards, one ``sense?`` edge per ``.ra`` edge, and a
  ``finish?`` self-loop for the ``at end`` clauses;
- ``Environment`` — on ``accrue?`` it moves to a committed location, from which it chooses every
  input with ``select`` (booleans ``int[0,1]``; numeric inputs an index into an array holding one
  significand per piece of :class:`rac.ir.inputs.InputSpace`), guarded by ``assume``, and
  broadcasts ``read``. Choosing on its own (sending) edge keeps every receiving edge
  deterministic, which statistical model checking requires.

Time: clock guards need integers, so the time unit is the largest duration that divides the
sample period, the horizon and every time bound of the queries (0.1 s for a period of 0.1 s
and a horizon of 30 s); rates are scaled to it.

Numbers: a real value ``v`` is held as the significand ``v * base**exponent`` (base 10, exponent 4,
or the ``model`` block's). The mirrors are exact when every rate times the period is a whole
number of significand units (else E0801) and every update has integer coefficients; an update
with a fractional coefficient truncates its result (integer division rounds towards zero).

Example::

    model = generate_uppaal(compile_file("stdlib/driving.ra").raise_for_errors(),
                            source_name="stdlib/driving.ra")
    Path("driving.xml").write_text(model.xml)
    Path("driving.q").write_text(model.queries)
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from dataclasses import dataclass
from fractions import Fraction
from pathlib import PurePath

from rac import ir
from rac.core.diagnostics import Diagnostic, error, short_number
from rac.core.numbers import INT32_MAX
from rac.ir import query as iq
from rac.ir.vocabulary import DEFAULT_BASE, DEFAULT_EXPONENT
from rac.runtime.semantics import first_sample_reads, mirror_accrual, mirror_update
from rac.targets.uppaal.expr import (
    NotRepresentable,
    QueryError,
    double_literal,
    int_literal,
    print_exact_sum,
    print_guard,
    print_int_linear,
    print_real_linear,
)
from rac.targets.uppaal.layout import Ids, Location, Template, Transition, edge, environment
from rac.targets.uppaal.names import Names, mirror_name
from rac.targets.uppaal.query import UppaalPrinter, Vocabulary, time_constants

__all__ = ["AutomatonGenerator", "UppaalError", "UppaalModel", "generate_uppaal",
           "queries_path", "vocabulary"]


_HINT_REPRESENTATION = ("add a `model` block with a larger `exponent`, or change the number so that it "
                        "is a whole multiple of 1/{scale}")


class UppaalError(Exception):
    """The automaton cannot be emitted as an UPPAAL model; carries the diagnostics (E0801, E0802)."""

    def __init__(self, diagnostics: Iterable[Diagnostic]):
        self.diagnostics = tuple(diagnostics)
        super().__init__("; ".join(f"{d.code}: {d.message}" for d in self.diagnostics))


@dataclass(frozen=True)
class UppaalModel:
    """The emitted files: the model (``.xml``, queries embedded) and the queries alone (``.q``)."""

    xml: str
    queries: str


# ---------------------------------------------------------------- the generator
@dataclass
class _Input:
    source: str
    name: str
    low: str
    high: str
    array: str
    values: list[int]
    pieces: str
    select: str

    @property
    def count(self) -> int:
        return len(self.values)

    @property
    def initializer(self) -> str:
        return "{" + ", ".join(int_literal(v) for v in self.values) + "}"


class AutomatonGenerator:
    def __init__(self, automaton: ir.Automaton, source_name: str, model_name: str):
        self.a = automaton
        self.source_name = " ".join(source_name.split()) or "<unnamed>"
        self.model_name = " ".join(model_name.split())
        model = automaton.model
        self.base = model.base if model is not None else DEFAULT_BASE
        self.exponent = model.exponent if model is not None else DEFAULT_EXPONENT
        self.scale = self.base ** self.exponent
        self.diagnostics: list[Diagnostic] = []
        self.truncating = False
        self._names()

    # ------------------------------------------------------------ diagnostics
    def _span(self, span):
        if span is not None:
            return span
        return self.a.source.name.span if self.a.source is not None else None

    def _unrepresentable(self, message: str, span, notes: Iterable[str] = (), hints: Iterable[str] | None = None):
        hint = _HINT_REPRESENTATION.format(scale=self.scale)
        self.diagnostics.append(error(
            "E0801", message, self._span(span), notes=list(notes),
            hints=list(hints) if hints is not None else [hint],
            data={"base": self.base, "exponent": self.exponent}))

    # ------------------------------------------------------------ names
    def reserved_names(self) -> Iterable[str]:
        """Names the rest of the model declares (none here; the whole model's scenario declarations)."""
        return ()

    def _names(self) -> None:
        a = self.a
        user = [a.name, *(i.name for i in a.inputs), *a.rewards, *a.location_names, *(n for n, _ in a.constants)]
        strategies = [q.query.name for q in self.queries() if isinstance(q.query, iq.STRATEGY_QUERIES)]
        names = Names([*user, *strategies], self.reserved_names())
        self.n = names
        self.process = names[a.name]
        self.mirror = {r: names.fresh(mirror_name(r)) for r in a.rewards}
        self.channels = {key: names.fresh(key) for key in ("accrue", "read", "sense", "finish")}
        self.g = {key: names.fresh(base) for key, base in (
            ("period", "PERIOD"), ("steps", "STEPS"), ("scale", "SCALE"), ("count", "count"),
            ("settled", "settled"), ("time", "time"), ("timer", "Timer"), ("environment", "Environment"),
            ("t", "t"), ("wait", "Wait"), ("accrued", "Accrued"), ("reading", "Reading"), ("ending", "Ending"),
            ("done", "Done"), ("idle", "Idle"), ("choosing", "Choosing"))}
        self.select = {}
        self.array = {}
        for item in a.inputs:
            if item.is_bool:
                self.select[item.name] = names.fresh(f"{item.name}_v")
            else:
                self.select[item.name] = names.fresh(f"{item.name}_i")
                self.array[item.name] = names.fresh(f"{item.name}_values")

    def queries(self) -> tuple[iq.QueryDecl, ...]:
        """The queries the model holds: the file's (the whole model adds the standard ones)."""
        return self.a.queries

    # ------------------------------------------------------------ time
    def _time_unit(self) -> Fraction:
        durations = [Fraction(self.a.period), Fraction(self.a.horizon)]
        for decl in self.queries():
            durations += [d for d in time_constants(decl.query) if d > 0]
        unit = durations[0]
        for d in durations[1:]:
            unit = Fraction(math.gcd(unit.numerator * d.denominator, d.numerator * unit.denominator),
                            unit.denominator * d.denominator)
        return unit

    # ------------------------------------------------------------ inputs
    def _inputs(self) -> list[_Input]:
        from rac.ir.inputs import InputSpace

        space = InputSpace(self.a)
        result = []
        for item in self.a.numeric_inputs:
            values = []
            for piece in space.pieces[item.name]:
                value = self._representative(item, piece)
                if value is None:
                    break  # one diagnostic per input: its first unrepresentable piece
                values.append(value)
            for bound in (item.low, item.high):
                try:
                    int_literal(bound * self.scale)
                except NotRepresentable:
                    self._unrepresentable(
                        f"the bound {_decimal(bound)} of input `{item.name}` is not representable as a 32-bit "  # type: ignore[arg-type]
                        f"significand at base {self.base}, exponent {self.exponent}", item.span,
                        notes=[f"its significand {_decimal(bound * self.scale)} is not a 32-bit integer"],
                        hints=["narrow the input's bounds, or lower the exponent of the number representation"])
                    break
            result.append(_Input(
                item.name, self.n[item.name], _decimal(item.low), _decimal(item.high),  # type: ignore[arg-type]
                self.array[item.name], values,
                ", ".join(p.describe(item.name) for p in space.pieces[item.name]), self.select[item.name]))
        return result

    def _representative(self, item: ir.Input, piece) -> int | None:
        """The significand the Environment chooses for one piece of a numeric input's range."""
        scale = self.scale
        if piece.is_point or item.kind == "int":
            value = piece.representative(item.kind == "int") * scale
            if value.denominator == 1:
                return value.numerator
            self._unrepresentable(
                f"input `{item.name}` compares with {_decimal(piece.low)}, which is not representable as a "
                f"significand at base {self.base}, exponent {self.exponent}", item.span,
                notes=[f"{_decimal(piece.low)} * {scale} = {_decimal(value)} is not an integer, "
                       "so the model cannot give the input that value"])
            return None
        low = math.floor(piece.low * scale) + 1
        high = math.ceil(piece.high * scale) - 1
        if low > high:
            self._unrepresentable(
                f"input `{item.name}` has no representable value in ({_decimal(piece.low)}, {_decimal(piece.high)}) "
                f"at base {self.base}, exponent {self.exponent}", item.span,
                notes=["the interval between two thresholds of its guards is narrower than one significand unit "
                       f"(1/{scale})"])
            return None
        middle = (piece.low + piece.high) / 2 * scale
        return min(max(round(middle), low), high)

    # ------------------------------------------------------------ rates
    def _accruals(self, inputs: list[_Input]) -> list[list[tuple[Fraction, list[tuple[Fraction, str]]] | None]]:
        """Per location and reward: (constant, [(coefficient, significand)]) that the mirror gains per sample."""
        period = Fraction(self.a.period)
        values = {i.source: i.values for i in inputs}
        Accrual = tuple[Fraction, list[tuple[Fraction, str]]]
        result: list[list[Accrual | None]] = []
        for location in self.a.locations:
            row: list[Accrual | None] = []
            for reward, rate in zip(self.a.rewards, location.rates):
                const, terms = mirror_accrual(rate, period, self.scale)
                bad = const.denominator != 1 or any(
                    (coef * v).denominator != 1 for coef, name in terms for v in values.get(name, []))
                if not bad and abs(const) > INT32_MAX:
                    self._unrepresentable(
                        f"reward rate `{reward}' == {_linear_text(rate)}` in location `{location.name}` adds "
                        f"{short_number(const)} significand units per sample, beyond the 32-bit integer range",
                        location.span, hints=["lower the rate, or the exponent of the number representation"])
                    row.append(None)
                    continue
                if bad:
                    if terms:
                        note = (f"one sample adds ({_linear_text(rate)}) * {_decimal(period)} to `{reward}`, which is "
                                "not a whole number of significand units for every value its inputs take")
                    else:
                        step = rate.const * period
                        note = (f"one sample adds {_decimal(rate.const)} * {_decimal(period)} = {_decimal(step)} to "
                                f"`{reward}`, that is {_decimal(step * self.scale)} significand units (1/{self.scale} "
                                "each): not a whole number")
                    self._unrepresentable(
                        f"reward rate `{reward}' == {_linear_text(rate)}` in location `{location.name}` is not "
                        f"representable in significands at exponent {self.exponent}", location.span,
                        notes=[note],
                        hints=[f"make rate * period a multiple of 1/{self.scale}, or add a `model` block with a "
                               "larger `exponent`"])
                    row.append(None)
                else:
                    row.append((const, [(c, self.n[name]) for c, name in terms]))
            result.append(row)
        return result

    def _ode(self, location: ir.Location, unit: Fraction) -> str:
        parts = []
        for reward, rate in zip(self.a.rewards, location.rates):
            terms = [(coef * unit, self.n[name], self.scale) for name, coef in rate.terms]
            parts.append(f"{self.n[reward]}' == {print_real_linear(rate.const * unit, terms)}")
        return " && ".join(parts)

    # ------------------------------------------------------------ updates
    def _update(self, assignment: ir.Assignment) -> list[str]:
        """The hybrid clock's and the mirror's assignment for one ``.ra`` update."""
        value = assignment.value
        const, terms = mirror_update(value, self.scale)
        hybrid_terms, mirror_terms = [], []
        for coef, name in terms:
            if name in self.mirror:
                hybrid_terms.append((coef, self.n[name], 1))
                mirror_terms.append((coef, self.mirror[name]))
            else:
                hybrid_terms.append((coef, self.n[name], self.scale))
                mirror_terms.append((coef, self.n[name]))
        if const.denominator != 1 or any(c.denominator != 1 for c, _ in mirror_terms):
            self.truncating = True
        reward = assignment.reward
        return [f"{self.n[reward]} = {print_real_linear(value.const, hybrid_terms)}",
                f"{self.mirror[reward]} = {print_int_linear(const, mirror_terms)}"]

    def _updates(self, assignments: Iterable[ir.Assignment], span) -> str:
        try:
            return ", ".join(part for a in assignments for part in self._update(a))
        except NotRepresentable as exc:
            self._unrepresentable(f"an update is not representable at base {self.base}, exponent "
                                  f"{self.exponent}: {exc}", span)
            return ""

    def _guard(self, guard: ir.Guard, names: dict[str, str] | None = None, span=None) -> str:
        if isinstance(guard, ir.BConst) and guard.value:
            return ""
        try:
            return print_guard(guard, names or self.input_names, self.scale)
        except NotRepresentable as exc:
            self._unrepresentable(f"a threshold is not representable at base {self.base}, exponent "
                                  f"{self.exponent}: {exc}", span)
            return "false"

    def _end_updates(self) -> tuple[str, str]:
        """The ``finish?`` edge's guard and assignment."""
        clauses = self.a.end_clauses
        if len(clauses) == 1:
            clause = clauses[0]
            return self._guard(clause.guard, span=clause.span), self._updates(clause.updates, clause.span)
        parts = []
        for clause in clauses:
            guard = self._guard(clause.guard, span=clause.span)
            for assignment in clause.updates:
                try:
                    texts = self._update(assignment)
                except NotRepresentable as exc:
                    self._unrepresentable(f"an update is not representable: {exc}", clause.span)
                    continue
                if not guard:
                    parts += texts
                    continue
                for text in texts:
                    target, _, value = text.partition(" = ")
                    parts.append(f"{target} = ({guard}) ? {value} : {target}")
        return "", ", ".join(parts)

    # ------------------------------------------------------------ vocabulary and queries
    def vocabulary(self) -> Vocabulary:
        """The emitted names of the automaton's vocabulary (:func:`vocabulary`), without generating the model."""
        self._inputs()
        return self._vocabulary(self._time_unit())

    def _vocabulary(self, unit: Fraction) -> Vocabulary:
        a = self.a
        strategies = {q.query.name: self.n[q.query.name] for q in self.queries()
                      if isinstance(q.query, iq.STRATEGY_QUERIES)}
        no_model = ("the automaton-alone UPPAAL model has no scenario-model names; `rac compile` emits the whole "
                    "model for a file with a `model` block" if a.model is not None else
                    "the automaton-alone UPPAAL model has no scenario-model names")
        return Vocabulary(
            automaton=a.name, process=self.process,
            locations={name: self.n[name] for name in a.location_names},
            bools={i.name: self.n[i.name] for i in a.bool_inputs},
            significands={i.name: self.n[i.name] for i in a.numeric_inputs},
            mirrors=dict(self.mirror), hybrids={r: self.n[r] for r in a.rewards},
            strategies=strategies, scale=self.scale, unit=unit, time=self.g["time"], settled=self.g["settled"],
            horizon=Fraction(a.horizon), period=Fraction(a.period), period_name=self.g["period"], no_model=no_model)

    def _printer(self, unit: Fraction) -> UppaalPrinter:
        """The printer of this model's queries; conditions get fresh function names."""
        printer = UppaalPrinter(self._vocabulary(unit))
        printer.fresh = lambda base: self.n.fresh(f"{base}{len(printer.conditions)}")
        return printer

    def _queries(self, printer: UppaalPrinter) -> list[dict[str, str]]:
        result = []
        for decl in self.queries():
            try:
                formula = printer.formula(decl.query)
            except QueryError as exc:
                self.diagnostics.append(error(
                    "E0802", f"query `{decl.name}` cannot be written over the UPPAAL model: {exc}",
                    self._span(decl.span), hints=_query_hints(str(exc))))
                continue
            except NotRepresentable as exc:
                self.diagnostics.append(error(
                    "E0801", f"query `{decl.name}` has a number that is not representable at base "
                    f"{self.base}, exponent {self.exponent}: {exc}", self._span(decl.span),
                    hints=[f"symbolic queries compare significands (value * {self.scale}); keep their constants "
                           f"within ±{short_number(Fraction(INT32_MAX, self.scale), 12)}"]))
                continue
            assert "\n" not in formula
            name = f"{decl.name}: {decl.title}" if decl.title else decl.name
            result.append({"name": name, "formula": formula})
        return result

    @staticmethod
    def _conditions(printer: UppaalPrinter) -> list[dict[str, str]]:
        """The conditions the symbolic queries call (functions returning bool), in order of appearance."""
        return [{"name": name, "body": body} for body, name in printer.conditions.items()]

    # ------------------------------------------------------------ templates
    def run(self) -> UppaalModel:
        inputs, unit, period_units, accruals = self._prepare()
        printer = self._printer(unit)
        queries = self._queries(printer)
        ids = Ids()
        templates = [self._timer(ids), self._automaton(ids, unit, accruals), self._environment(ids, inputs)]
        if self.diagnostics:
            raise UppaalError(self.diagnostics)
        g = self.g
        declaration = environment().get_template("declaration.j2").render(
            **self._declaration_args(inputs, unit, period_units),
            names={k: g[k] for k in ("period", "steps", "scale", "count", "settled", "time")},
            conditions=self._conditions(printer))
        system = environment().get_template("system.j2").render(
            channels=self.channels, processes=[g["timer"], self.process, g["environment"]])
        return self._files(declaration, templates, system, queries)

    def _prepare(self) -> tuple[list, Fraction, int, object]:
        """What both targets compute first: inputs, time unit, sample length in units, accruals."""
        inputs = self._inputs()
        self.input_names = {i.name: self.n[i.name] for i in self.a.inputs}
        unit = self._time_unit()
        period_units = int(Fraction(self.a.period) / unit)
        accruals = self._accruals(inputs)
        return inputs, unit, period_units, accruals

    def _declaration_args(self, inputs: list, unit: Fraction, period_units: int) -> dict[str, object]:
        """The declaration template's arguments shared by the automaton-alone and whole-model targets."""
        a = self.a
        return dict(
            source_name=self.source_name, automaton=a.name, unit_text=_seconds(unit),
            period_text=_seconds(Fraction(a.period)), period_units=period_units, steps=a.steps,
            end_units=a.steps * period_units, end_text=_seconds(a.steps * Fraction(a.period)),
            base=self.base, exponent=self.exponent, scale=self.scale, channels=self.channels,
            bool_inputs=[{"name": self.n[i.name]} for i in a.bool_inputs],
            numeric_inputs=inputs, hybrids=[self.n[r] for r in a.rewards],
            mirrors=[self.mirror[r] for r in a.rewards], truncating=self.truncating,
            constants=[self._constant(name, value) for name, value in a.constants])

    def _files(self, declaration: str, templates: list[Template], system: str,
               queries: list[dict[str, str]]) -> UppaalModel:
        """The ``.xml`` (declarations, templates, system line, queries) and the ``.q`` text."""
        env = environment()
        xml = env.get_template("model.xml.j2").render(
            declaration=declaration.rstrip("\n"), templates=templates, system=system.rstrip("\n"), queries=queries)
        q = env.get_template("queries.q.j2").render(
            automaton=self.a.name, source_name=self.source_name, model_name=self.model_name, queries=queries,
            queries_name=queries_path(self.model_name) if self.model_name else "")
        return UppaalModel(xml, q)

    def _constant(self, name: str, value: Fraction | bool) -> str:
        if isinstance(value, bool):
            return f"const bool {self.n[name]} = {'true' if value else 'false'};"
        if value.denominator == 1 and abs(value) <= INT32_MAX:
            return f"const int32_t {self.n[name]} = {value.numerator};"
        try:
            return f"const double {self.n[name]} = {double_literal(value)};"
        except NotRepresentable:
            return f"// {self.n[name]} = {short_number(value)} (no UPPAAL literal)"

    def _timer(self, ids: Ids) -> Template:
        g, ch = self.g, self.channels
        wait = Location(ids(), g["wait"], 0, 0, f"{g['t']} <= {g['period']}")
        accrued = Location(ids(), g["accrued"], 272, 0, committed=True)
        reading = Location(ids(), g["reading"], 272, 170, committed=True)
        ending = Location(ids(), g["ending"], 544, 170, committed=True)
        done = Location(ids(), g["done"], 816, 170, f"{g['t']} <= {g['period']}")
        transitions = [
            edge(ids, wait, accrued, guard=f"{g['t']} >= {g['period']} && {g['count']} < {g['steps']}",
                  sync=f"{ch['accrue']}!", assignment=f"{g['t']} = 0, {g['count']}++", anchor=(40, -60)),
            edge(ids, accrued, reading, sync=f"{ch['read']}?", assignment=f"{g['settled']} = false",
                  anchor=(282, 70)),
            edge(ids, reading, wait, guard=f"{g['count']} < {g['steps']}", sync=f"{ch['sense']}!",
                  assignment=f"{g['settled']} = true", nails=[(0, 170)], anchor=(40, 180)),
            edge(ids, reading, ending, guard=f"{g['count']} == {g['steps']}", sync=f"{ch['sense']}!",
                  assignment=f"{g['settled']} = true", anchor=(330, 180)),
            edge(ids, ending, done, sync=f"{ch['finish']}!", anchor=(620, 180)),
            edge(ids, done, done, guard=f"{g['t']} >= {g['period']}", assignment=f"{g['t']} = 0",
                  nails=[(790, 240), (842, 240)], anchor=(780, 250)),
        ]
        return Template(g["timer"], wait.id, [wait, accrued, reading, ending, done], transitions,
                         declaration=f"clock {g['t']};", name_x=-40, name_y=-100)

    def _environment(self, ids: Ids, inputs: list[_Input]) -> Template:
        g, ch, a = self.g, self.channels, self.a
        idle = Location(ids(), g["idle"], 0, 0)
        choosing = Location(ids(), g["choosing"], 340, 0, committed=True)
        selects, assigns, names = [], [], {}
        numeric = {i.source: i for i in inputs}
        for item in a.inputs:
            var = self.select[item.name]
            if item.is_bool:
                selects.append(f"{var} : int[0,1]")
                assigns.append(f"{self.n[item.name]} = {var}")
                names[item.name] = var
            else:
                data = numeric[item.name]
                selects.append(f"{var} : int[0,{max(data.count - 1, 0)}]")
                assigns.append(f"{self.n[item.name]} = {data.array}[{var}]")
                names[item.name] = f"{data.array}[{var}]"
        transitions = [
            edge(ids, idle, choosing, sync=f"{ch['accrue']}?", nails=[(170, -50)], anchor=(140, -80)),
            edge(ids, choosing, idle, select=", ".join(selects), guard=self._guard(a.assume, names),
                  sync=f"{ch['read']}!", assignment=", ".join(assigns), nails=[(170, 60)], anchor=(20, 80)),
        ]
        return Template(g["environment"], idle.id, [idle, choosing], transitions, name_x=-40, name_y=-100)

    def _automaton(self, ids: Ids, unit: Fraction, accruals) -> Template:
        a, g, ch = self.a, self.g, self.channels
        count = len(a.locations)
        radius = max(200, 70 * count)
        locations = []
        for i, location in enumerate(a.locations):
            angle = -math.pi / 2 + 2 * math.pi * i / count
            x, y = round(radius * math.cos(angle)), round(radius * math.sin(angle))
            if count == 1:
                x, y = 0, 0
            locations.append(Location(ids(), self.n[location.name], x, y, self._ode(location, unit)))
        # Rates that read inputs: the first sample's accrual uses that sample's inputs (nothing is held yet),
        # so it happens on read? at the first sample instead of on accrue?.
        first_reads = first_sample_reads(a)
        loops: list[list[dict]] = [[] for _ in a.locations]
        edges: list[tuple[int, int, dict]] = []
        for i, row in enumerate(accruals):
            parts = []
            for reward, accrual in zip(a.rewards, row):
                if accrual is None:
                    continue
                const, terms = accrual
                if const == 0 and not terms:
                    continue
                mirror = self.mirror[reward]
                parts.append(f"{mirror} = {print_exact_sum(const, [(Fraction(1), mirror), *terms])}")
            if parts:
                loops[i].append({"guard": f"{g['count']} > 0" if first_reads else "",
                                 "sync": f"{ch['accrue']}?", "assignment": ", ".join(parts)})
            if first_reads and i == a.initial:
                corrections = []
                for reward, rate in zip(a.rewards, a.locations[i].rates):
                    if rate.terms:
                        terms = [(coef * Fraction(a.period), self.n[name], self.scale) for name, coef in rate.terms]
                        corrections.append(f"{self.n[reward]} = {self.n[reward]} + "
                                           f"{print_real_linear(Fraction(0), terms)}")
                loops[i].append({"guard": f"{g['count']} == 1", "sync": f"{ch['read']}?",
                                 "assignment": ", ".join(parts + corrections)})
        for ra_edge in a.all_edges():
            label = {"guard": self._guard(ra_edge.guard, span=ra_edge.span), "sync": f"{ch['sense']}?",
                     "assignment": self._updates(ra_edge.updates, ra_edge.span)}
            if ra_edge.source == ra_edge.target:
                loops[ra_edge.source].append(label)
            else:
                edges.append((ra_edge.source, ra_edge.target, label))
        if a.end_clauses:
            guard, assignment = self._end_updates()
            for i in range(count):
                loops[i].append({"guard": guard, "sync": f"{ch['finish']}?", "assignment": assignment})
        transitions = []
        for source, target, label in edges:
            transitions.append(self._straight(ids, locations[source], locations[target], label))
        for i, labels in enumerate(loops):
            transitions += self._loops(ids, locations[i], labels, count)
        by_id = {t.id: t for t in transitions}
        ordered = sorted(by_id, key=lambda k: int(k[2:]))
        return Template(self.process, locations[a.initial].id, locations, [by_id[k] for k in ordered],
                         name_x=-radius - 100, name_y=-radius - 100)

    @staticmethod
    def _straight(ids: Ids, source: Location, target: Location, label: dict) -> Transition:
        """An edge between two locations, bent a little to its right so that A→B and B→A stay apart."""
        dx, dy = target.x - source.x, target.y - source.y
        length = math.hypot(dx, dy) or 1.0
        nx, ny = dy / length, -dx / length
        bend = 40
        nail = (round((source.x + target.x) / 2 + nx * bend), round((source.y + target.y) / 2 + ny * bend))
        return edge(ids, source, target, nails=[nail], anchor=nail, **label)

    @staticmethod
    def _loops(ids: Ids, location: Location, labels: list[dict], count: int) -> list[Transition]:
        """Self-loops fanned out away from the centre of the circle of locations."""
        direction = math.atan2(location.y, location.x) if (location.x or location.y) and count > 1 else -math.pi / 2
        spread = math.radians(50)
        result = []
        for j, label in enumerate(labels):
            angle = direction + (j - (len(labels) - 1) / 2) * spread
            nails = []
            for side in (-1, 1):
                phi = angle + side * math.radians(15)
                nails.append((round(location.x + 80 * math.cos(phi)), round(location.y + 80 * math.sin(phi))))
            anchor = (round(location.x + 95 * math.cos(angle)), round(location.y + 95 * math.sin(angle)))
            if math.cos(angle) < -0.3:
                anchor = (anchor[0] - 170, anchor[1])
            result.append(edge(ids, location, location, nails=nails, anchor=anchor, **label))
        return result


def _decimal(value: Fraction) -> str:
    """A rational for messages: its exact decimal when it has a short one (``0.00001``), else rounded."""
    if value.denominator == 1:
        return str(value.numerator)
    rest, places = value.denominator, 0
    for prime in (2, 5):
        count = 0
        while rest % prime == 0:
            rest, count = rest // prime, count + 1
        places = max(places, count)
    if rest != 1 or places > 12:
        return short_number(value)
    digits = str(abs(value.numerator) * 10**places // value.denominator).rjust(places + 1, "0")
    return ("-" if value < 0 else "") + f"{digits[:-places]}.{digits[-places:]}"


def _linear_text(linear: ir.Linear) -> str:
    parts = [_decimal(linear.const)] if linear.const or not linear.terms else []
    for name, coefficient in linear.terms:
        parts.append(name if coefficient == 1 else f"{_decimal(coefficient)}*{name}")
    return " + ".join(parts)


def _seconds(value: Fraction) -> str:
    return short_number(value)


def _query_hints(message: str) -> list[str]:
    if "compares a probability" in message:
        return ["write `>=` or `<=`, or ask for the probability's value and compare it yourself"]
    if "`rac compile` emits the whole model" in message:
        return ["`generate_uppaal` emits the automaton alone; `generate_uppaal_model` (and `rac compile`) the "
                "whole model of the automaton in its scenario"]
    if "prev(" in message:
        return ["`rac verify` answers statistical queries that read `prev(...)`; bind the value to an input "
                "to read it in UPPAAL"]
    if "ground truth" in message:
        return ["the true state is continuous: read it in Pr, E[..](max: ..) or simulate"]
    if "scenario model" in message:
        return ["`--target uppaal` emits the automaton alone, without its scenario model: leave the query out, "
                "or bind the condition to an input of the automaton"]
    if "symbolic" in message or "time" in message:
        return ["symbolic queries (A[], E<>, E[], A<>, -->, control:) read integer mirrors and significands; "
                "use Pr, E[..](max: ..) or simulate for other expressions"]
    return []


def vocabulary(automaton: ir.Automaton) -> Vocabulary:
    """The UPPAAL names of the automaton's vocabulary in the emitted model (process, locations,
    inputs, hybrid clocks, mirrors) and its time unit: what to look for in verifyta's output."""
    return AutomatonGenerator(automaton, "", "").vocabulary()


def queries_path(model: str) -> str:
    """The ``.q`` file written beside a model: ``out.xml`` -> ``out.q``."""
    return str(PurePath(model).with_suffix(".q"))


def generate_uppaal(automaton: ir.Automaton, *, source_name: str = "", model_name: str = "") -> UppaalModel:
    """The UPPAAL 5 model of ``automaton`` alone and its queries (deterministic text).

    ``source_name`` (the ``.ra`` file) and ``model_name`` (the ``.xml`` file, for the command line
    shown in the ``.q`` file) only appear in comments. Raises :class:`UppaalError` (E0801: a number
    is not representable as a significand; E0802: a query cannot be written over the model).
    """
    return AutomatonGenerator(automaton, source_name, model_name).run()

