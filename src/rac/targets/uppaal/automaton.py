"""The UPPAAL target: a closed UPPAAL 5 model of one reward automaton, and its queries.

``rac compile --target uppaal FILE.ra -o out.xml`` writes ``out.xml`` (the model, with the
file's queries embedded) and ``out.q`` (the same queries, one per line). For a file with a
``model`` block it writes the whole model in the block's scenario instead
(:mod:`rac.targets.uppaal.model`, which reuses this module's generator). The automaton-alone
model has three processes:

- ``Timer`` — every sample period it broadcasts ``accrue``, waits for the Environment's
  ``read``, then broadcasts ``sense``; after the horizon's last sample it broadcasts ``finish``
  once, then idles (it keeps ticking, so the model never deadlocks). With ``episode ends when
  COND``, a sample whose inputs satisfy COND is the last one: its ``sense`` edge goes to the same
  ending (``finish``, so the ``at end`` clauses apply to that sample's inputs) and sets ``ended``,
  which stops the hybrid clocks (every rate reads ``ended ? 0.0 : rate``); no ``accrue`` or
  ``sense`` follows;
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

The generator composes three helpers (the whole model's generator inherits them):
:class:`rac.targets.uppaal.significands.Significands` (the numbers as significands, and E0801),
:class:`rac.targets.uppaal.labels.Labels` (the reward automaton's labels) and
:class:`rac.targets.uppaal.processes.Processes` (the templates of the three processes).

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
from rac.core.diagnostics import Diagnostic, RacError, error, short_number
from rac.core.numbers import INT32_MAX
from rac.ir import query as iq
from rac.targets.uppaal.expr import NotRepresentable, QueryError, double_literal
from rac.targets.uppaal.labels import Labels
from rac.targets.uppaal.layout import Ids, Template, environment
from rac.targets.uppaal.names import Names, mirror_name
from rac.targets.uppaal.processes import Processes
from rac.targets.uppaal.query import Condition, UppaalPrinter, Vocabulary, time_bound
from rac.targets.uppaal.significands import Accrual, NumericInput, Significands

__all__ = ["AutomatonGenerator", "UppaalError", "UppaalModel", "generate_uppaal",
           "queries_path", "vocabulary"]


class UppaalError(RacError):
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
class AutomatonGenerator:
    """The generator of one automaton's UPPAAL model: its names, time unit, queries and the files.

    The numbers go through :attr:`numbers` (:class:`Significands`), the reward automaton's labels
    through :attr:`labels`, the process templates through :attr:`processes`; every E0801 and E0802
    is collected in :attr:`diagnostics`, and :meth:`run` raises :class:`UppaalError` with them. The
    whole model's generator (:mod:`rac.targets.uppaal.model`) overrides :meth:`reserved_names`,
    :meth:`queries`, the names and the vocabulary, and :meth:`run`.
    """

    def __init__(self, automaton: ir.Automaton, source_name: str, model_name: str):
        self.a = automaton
        self.source_name = " ".join(source_name.split()) or "<unnamed>"
        self.model_name = " ".join(model_name.split())
        self.diagnostics: list[Diagnostic] = []
        self.numbers = Significands(automaton, self.diagnostics)
        self._names()
        self.labels = Labels(automaton, self.n, self.mirror, self.numbers)
        self.processes = Processes(automaton, self.n, self.process, self.g, self.channels, self.select, self.labels)

    # ------------------------------------------------------------ names
    def reserved_names(self) -> Iterable[str]:
        """Names the rest of the model declares (none here; the whole model's scenario declarations)."""
        return ()

    def _names(self) -> None:
        a = self.a
        user = [*(i.name for i in a.inputs), *a.rewards, *a.location_names, *(n for n, _ in a.constants)]
        strategies = [q.query.name for q in self.queries() if isinstance(q.query, iq.STRATEGY_QUERIES)]
        names = Names([*user, *strategies], self.reserved_names())
        self.n = names
        # The .ra keeps the automaton's name apart from its other names, UPPAAL does not (a template's
        # name is as global as a constant's): a namesake keeps its name, the template gets a fresh one.
        self.process = names.fresh(a.name)
        self.mirror = {r: names.fresh(mirror_name(r)) for r in a.rewards}
        self.channels = {key: names.fresh(key) for key in ("accrue", "read", "sense", "finish")}
        # `episode ends when`: a flag set where a sample ends the run (the hybrid clocks' rates are 0 after it)
        ended = {"ended": names.fresh("ended")} if a.ending is not None else {}
        self.g = {key: names.fresh(base) for key, base in (
            ("period", "PERIOD"), ("steps", "STEPS"), ("scale", "SCALE"), ("count", "count"),
            ("settled", "settled"), ("time", "time"), ("timer", "Timer"), ("environment", "Environment"),
            ("t", "t"), ("wait", "Wait"), ("accrued", "Accrued"), ("reading", "Reading"), ("ending", "Ending"),
            ("done", "Done"), ("idle", "Idle"), ("choosing", "Choosing"),
            ("location", "loc"))} | ended  # location: the parameter of a condition that reads the location index
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
        """The model's time unit: the largest duration dividing the period, the horizon and the queries'
        time bounds, except a bound that would make the unit so fine that a duration in units leaves
        int32 (``Pr[<=0.123456789]`` with a horizon of 3 s): that query gets E0802 (:meth:`UppaalPrinter.formula`)."""
        unit = _divisor(Fraction(self.a.period), Fraction(self.a.horizon))
        longest = max(Fraction(self.a.period), Fraction(self.a.horizon))
        for decl in self.queries():
            bound = time_bound(decl.query)
            if bound is None or bound <= 0:
                continue
            finer = _divisor(unit, bound)
            if max(longest, bound) / finer <= INT32_MAX:
                unit, longest = finer, max(longest, bound)
        return unit

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
            strategies=strategies, scale=self.numbers.scale, unit=unit, count=self.g["count"],
            settled=self.g["settled"], horizon=Fraction(a.horizon), period=Fraction(a.period),
            period_name=self.g["period"], steps_name=self.g["steps"], no_model=no_model,
            location_parameter=self.g["location"])

    def _printer(self, unit: Fraction) -> UppaalPrinter:
        """The printer of this model's queries; conditions get fresh function names."""
        printer = UppaalPrinter(self._vocabulary(unit))
        printer.fresh = lambda base: self.n.fresh(f"{base}{len(printer.conditions)}")
        return printer

    def _queries(self, printer: UppaalPrinter) -> list[dict[str, str]]:
        """The queries' names and formulas; E0802 or E0801 for a query that cannot be written."""
        numbers = self.numbers
        result = []
        for decl in self.queries():
            try:
                formula = printer.formula(decl.query)
            except QueryError as exc:
                self.diagnostics.append(error(
                    "E0802", f"query `{decl.name}` cannot be written over the UPPAAL model: {exc}",
                    numbers.span(decl.span), hints=_query_hints(str(exc))))
                continue
            except NotRepresentable as exc:
                self.diagnostics.append(error(
                    "E0801", f"query `{decl.name}` has a number that is not representable at base "
                    f"{numbers.base}, exponent {numbers.exponent}: {exc}", numbers.span(decl.span),
                    hints=[f"symbolic queries compare significands (value * {numbers.scale}); keep their constants "
                           f"within ±{short_number(Fraction(INT32_MAX, numbers.scale), 12)}"]))
                continue
            assert "\n" not in formula
            name = f"{decl.name}: {decl.title}" if decl.title else decl.name
            result.append({"name": name, "formula": formula})
        return result

    @staticmethod
    def _conditions(printer: UppaalPrinter) -> list[Condition]:
        """The conditions the symbolic queries call (functions returning bool), in order of appearance."""
        return list(printer.conditions.values())

    # ------------------------------------------------------------ templates
    def run(self) -> UppaalModel:
        """The model and its queries; raises :class:`UppaalError` with every diagnostic."""
        inputs, unit, period_units, accruals = self._prepare()
        printer = self._printer(unit)
        queries = self._queries(printer)
        ids = Ids()
        processes = self.processes
        templates = [processes.timer(ids), processes.automaton(ids, unit, accruals), processes.environment(ids, inputs)]
        if self.diagnostics:
            raise UppaalError(self.diagnostics)
        g = self.g
        declaration = environment().get_template("declaration.j2").render(
            **self._declaration_args(inputs, unit, period_units),
            names={k: g[k] for k in ("period", "steps", "scale", "count", "settled", "time", "ended") if k in g},
            conditions=self._conditions(printer))
        system = environment().get_template("system.j2").render(
            channels=self.channels, processes=[g["timer"], self.process, g["environment"]])
        return self._files(declaration, templates, system, queries)

    def _prepare(self) -> tuple[list[NumericInput], Fraction, int, list[list[Accrual | None]]]:
        """What both targets compute first: inputs, time unit, sample length in units, accruals."""
        inputs = self._inputs()
        unit = self._time_unit()
        period_units = int(Fraction(self.a.period) / unit)
        accruals = self.numbers.accruals(inputs, self.n)
        return inputs, unit, period_units, accruals

    def _inputs(self) -> list[NumericInput]:
        """The numeric inputs and their significands (E0801 for those that have none)."""
        return self.numbers.inputs(self.n, self.array, self.select)

    def _declaration_args(self, inputs: list[NumericInput], unit: Fraction, period_units: int) -> dict[str, object]:
        """The declaration template's arguments shared by the automaton-alone and whole-model targets."""
        a, numbers = self.a, self.numbers
        return dict(
            source_name=self.source_name, automaton=a.name, unit_text=_seconds(unit),
            period_text=_seconds(Fraction(a.period)), period_units=period_units, steps=a.steps,
            end_units=a.steps * period_units, end_text=_seconds(a.steps * Fraction(a.period)),
            base=numbers.base, exponent=numbers.exponent, scale=numbers.scale, channels=self.channels,
            bool_inputs=[{"name": self.n[i.name]} for i in a.bool_inputs],
            numeric_inputs=inputs, hybrids=[self.n[r] for r in a.rewards],
            mirrors=[self.mirror[r] for r in a.rewards], truncating=self.labels.truncating,
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
    if "time unit so fine" in message:
        return ["write a bound with fewer decimals, such as a multiple of the sample period"]
    if "time units of" in message:
        return ["bound the query by the horizon"]
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


def _divisor(a: Fraction, b: Fraction) -> Fraction:
    """The largest duration of which both ``a`` and ``b`` are whole multiples."""
    return Fraction(math.gcd(a.numerator * b.denominator, b.numerator * a.denominator), a.denominator * b.denominator)
