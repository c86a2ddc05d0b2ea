"""The pipeline: text → AST → checked IR (+ diagnostics). Targets start from its result."""

from __future__ import annotations

import os
from collections.abc import Callable
from dataclasses import dataclass, field
from fractions import Fraction
from pathlib import Path
from typing import TYPE_CHECKING

from rac import ir
from rac.check.resolve import Resolver
from rac.core.diagnostics import CheckError, Diagnostic, error, short_number
from rac.core.numbers import exact_text
from rac.core.source import SourceFile
from rac.lang import ast
from rac.lang.parser import ParseFailure, parse_source, read_source, text_source
from rac.model.program import CheckedProgram, ProgramSource

if TYPE_CHECKING:
    from rac.check.analysis.synthesis import Synthesised
    from rac.model.commonroad import Scenario
    from rac.model.data import ModelData


@dataclass(frozen=True)
class CompileResult(ProgramSource):
    """What checking one file produced: the IR when there are no errors, and every diagnostic;
    :meth:`checked` gives the :class:`~rac.model.program.CheckedProgram` the other stages read."""

    automaton: ir.Automaton | None
    diagnostics: tuple[Diagnostic, ...]
    sources: dict[str, SourceFile] = field(default_factory=dict)
    module: ast.Module | None = None
    #: What the analyses proved, as sentences (printed by ``rac check``).
    facts: tuple[str, ...] = ()
    #: With `param` declarations: the values synthesised for them (None without parameters, or when
    #: synthesis failed; the diagnostics then say why).
    synthesis: Synthesised | None = None
    #: With a `model` block: the scenario it names, loaded once by the checks
    #: (a :class:`rac.model.commonroad.Scenario`), and the model's data built from it at the block's
    #: base and exponent (a :class:`rac.model.data.ModelData`); None when not loaded.
    scenario: Scenario | None = None
    model_data: ModelData | None = None

    @property
    def ok(self) -> bool:
        return self.automaton is not None and not any(d.is_error for d in self.diagnostics)

    def raise_for_errors(self) -> ir.Automaton:
        """The automaton, or :class:`CheckError` carrying the diagnostics."""
        if not self.ok or self.automaton is None:
            raise CheckError(self.diagnostics, self.sources)
        return self.automaton

    def checked(self) -> CheckedProgram:
        """The automaton with the scenario and model's data the checks loaded, or
        :class:`CheckError` carrying the diagnostics. Checked with ``analyse=False`` (nothing loaded),
        a `model` block's scenario is loaded now, by the checks' own loader
        (:meth:`~rac.model.program.CheckedProgram.of`)."""
        automaton = self.raise_for_errors()
        if automaton.model is not None and self.model_data is None:
            return CheckedProgram.of(automaton)
        return CheckedProgram(automaton, self.model_data, self.scenario)


def compile_source(source: SourceFile, *, analyse: bool = True, progress: Callable[[str], None] | None = None,
                   max_bytes: int | None = None) -> CompileResult:
    """Parse, resolve and (unless ``analyse=False``) run every static check on one source;
    ``progress`` hears of a scenario whose load takes a while (:func:`rac.model.checks.check_scenario`).
    ``max_bytes`` is the memory budget of loading the scenario (None: no limit): a scenario estimated
    to need more is refused before it loads (:class:`rac.core.resources.ScenarioTooLarge`, a
    ``MemoryError``)."""
    sources = {source.name: source}
    try:
        module = parse_source(source)
    except ParseFailure as failure:
        return CompileResult(None, (failure.diagnostic,), sources)
    diagnostics: list[Diagnostic] = []
    for extra in module.automata[1:]:
        diagnostics.append(error("E0107", "a file holds one automaton; this is a second one",
                                 extra.name.span, hints=["move it to a file of its own"]))
    resolver = Resolver(module.automata[0])
    automaton = resolver.run()
    diagnostics.extend(resolver.diagnostics)
    facts: list[str] = []
    scenario: Scenario | None = None
    model_data: ModelData | None = None
    synthesis: Synthesised | None = None
    if automaton is not None and analyse and automaton.parameters and not any(d.is_error for d in diagnostics):
        automaton, found, synthesis = synthesise_parameters(module.automata[0], automaton.parameters, facts)
        diagnostics.extend(found)
    if automaton is not None and analyse and not any(d.is_error for d in diagnostics):
        from rac.check.analysis import analyse_automaton

        diagnostics.extend(analyse_automaton(automaton, facts))
        if automaton.model is not None and not any(d.is_error for d in diagnostics):
            # The scenario comes last: it checks the model's numbers, once the automaton is sound.
            from rac.model.checks import check_scenario

            checked = check_scenario(automaton, progress, max_bytes)
            diagnostics.extend(checked.diagnostics)
            facts.extend(checked.facts)
            scenario, model_data = checked.scenario, checked.data
    if any(d.is_error for d in diagnostics):
        automaton = None
    return CompileResult(automaton, tuple(diagnostics), sources, module, tuple(facts), synthesis, scenario,
                         model_data)


def synthesise_parameters(node: ast.Automaton, parameters: tuple[ir.Parameter, ...], facts: list[str]
                          ) -> tuple[ir.Automaton | None, list[Diagnostic], Synthesised | None]:
    """The automaton at the synthesised values of its parameters (one: the least value; several
    weights: the lexicographically least integer point), the diagnostics, and what was synthesised."""
    from rac.check.params import nonlinear_use

    place = nonlinear_use(node, {p.name for p in parameters})
    if place is not None:
        name, span, how = place
        return None, [error("E0407", f"not yet: parameter `{name}` cannot be synthesised here: {how}", span,
                            hints=[f"write `const {name} = ...` instead"])], None
    if len(parameters) == 1:
        return _synthesised(node, parameters[0], facts)
    return _synthesised_weights(node, parameters, facts)


def _synthesised_weights(node: ast.Automaton, parameters: tuple[ir.Parameter, ...], facts: list[str]
                         ) -> tuple[ir.Automaton | None, list[Diagnostic], Synthesised | None]:
    """Several parameters, weights of the objective: the automaton at the lexicographically least integer
    point of the exact polyhedron where every check holds, or None and why there is none."""
    from rac.check.analysis import analyse_automaton
    from rac.check.analysis.synthesis import Synthesised
    from rac.check.analysis.weights import Unsupported, synthesise_region
    from rac.check.analysis.worst import Unfinished

    names = [p.name for p in parameters]
    listed = ", ".join(names)

    def resolve(point: tuple[Fraction, ...]) -> ir.Automaton | None:
        return Resolver(node, dict(zip(names, point))).run()

    try:
        region = synthesise_region(resolve, parameters)
    except Unsupported as where:
        name = where.name
        span = next(p.span for p in parameters if p.name == name)
        return None, [error("E0407", f"not yet: parameter `{name}` cannot be synthesised here: with several "
                            f"parameters, each must be a weight of the objective only, and it appears in "
                            f"{where.where}", span,
                            notes=[f"the parameters synthesised together: {listed}"],
                            hints=[f"write `const {name} = ...`, or synthesise it alone"])], None
    except Unfinished as stop:
        return None, [error("E0407", f"not yet: parameters {listed} cannot be synthesised here: the worst-run "
                            f"search stopped: {stop.reason}", parameters[0].span,
                            hints=["write the values as `const`"])], None
    bounds = _bounds_text(parameters)
    if region.point is None:
        witness = resolve(region.witness)
        assert witness is not None
        failing = [d for d in analyse_automaton(witness, []) if d.is_error]
        at = ", ".join(f"{n} = {short_number(x)}" for n, x in zip(names, region.witness))
        return None, [error("E0406", f"no values of parameters {listed} ({bounds}) pass every check",
                            parameters[0].span, notes=[*region.cuts, f"the checks at {at} follow"],
                            hints=["widen the parameters' bounds, or change what they cannot compensate"]),
                      *failing], None
    point = region.point
    chosen = ", ".join(f"{n} = {short_number(x)}" for n, x in zip(names, point))
    first = names[region.order[0]]
    how = (f"the lexicographically least integer weights, `{first}` first" if region.integer
           else f"the lexicographically least values, `{first}` first (no integer point)")
    inequalities = tuple(region.describe())
    if inequalities:
        sentence = (f"synthesised: every check holds exactly where {' and '.join(inequalities)} ({bounds}); "
                    f"checked with {chosen}, {how}")
    else:
        sentence = f"synthesised: every check holds for all values ({bounds}); checked with {chosen}, {how}"
    facts.append(sentence)
    shown = ", ".join("(" + ", ".join(exact_text(x) for x in v) + ")" for v in region.vertices[:8])
    more = f" and {len(region.vertices) - 8} more" if len(region.vertices) > 8 else ""
    vertices = f"the set of ({listed}) has {len(region.vertices)} vertices, each checked: {shown}{more}"
    facts.append(vertices)
    return resolve(point), [], Synthesised(tuple(zip(names, point)), inequalities, sentence, (vertices,))


def _synthesised(node: ast.Automaton, parameter: ir.Parameter, facts: list[str]
                 ) -> tuple[ir.Automaton | None, list[Diagnostic], Synthesised | None]:
    """The automaton at the least value of its parameter for which every check holds (the fact saying
    so goes to ``facts``), or None and why there is none (E0406 and the checks failing at the value
    that shows it, or E0407 where the search cannot be exact)."""
    from rac.check.analysis import analyse_automaton
    from rac.check.analysis.synthesis import Synthesised, Unfinished, synthesise, unsupported

    name = parameter.name

    def resolve(value: Fraction) -> ir.Automaton | None:
        return Resolver(node, {name: value}).run()

    low, high = resolve(parameter.low), resolve(parameter.high)
    assert low is not None and high is not None, "the file resolved at the low bound"
    reason = unsupported(low, high)
    if reason is None:
        try:
            result = synthesise(resolve, parameter)
        except Unfinished as stop:
            reason = f"the worst-run search stopped: {stop.reason}"
    if reason is not None:
        return None, [error("E0407", f"not yet: parameter `{name}` cannot be synthesised here: {reason}",
                            parameter.span, hints=[f"write `const {name} = ...` instead"])], None
    least = result.least
    if least is None:
        witness = resolve(result.witness)
        assert witness is not None
        failing = [d for d in analyse_automaton(witness, []) if d.is_error]
        what = ("no value" if result.empty else
                f"no least value (the values that pass form {result.interval()})")
        return None, [error("E0406", f"{what} of parameter `{name}` in [{short_number(parameter.low)}, "
                            f"{short_number(parameter.high)}] passes every check", parameter.span,
                            notes=[*result.cuts, f"the checks at {name} = {short_number(result.witness)} follow"],
                            hints=["widen the parameter's bounds, or change what it cannot compensate"]),
                      *failing], None
    if result.whole:
        sentence = (f"synthesised: every check holds for every value of {name} in {result.interval()}; "
                    f"checked with {name} = {short_number(least)}")
    else:
        sentence = (f"synthesised: {result.describe()} (every check holds for {name} in {result.interval()}); "
                    f"checked with {name} = {short_number(least)}")
    facts.append(sentence)
    return resolve(least), [], Synthesised(((name, least),), () if result.whole else (result.describe(exact=True),),
                                           sentence)


def _bounds_text(parameters: tuple[ir.Parameter, ...]) -> str:
    """``w1, w2 in [1, 100]; P in [0, 5]``: the declared bounds, names with the same bounds together."""
    groups: dict[tuple[Fraction, Fraction], list[str]] = {}
    for p in parameters:
        groups.setdefault((p.low, p.high), []).append(p.name)
    return "; ".join(f"{', '.join(names)} in [{short_number(low)}, {short_number(high)}]"
                     for (low, high), names in groups.items())


def compile_text(text: str, name: str | os.PathLike[str] = "<string>", *, analyse: bool = True,
                 progress: Callable[[str], None] | None = None, max_bytes: int | None = None) -> CompileResult:
    """Check `.ra` source given as a string (at most 1 MB as UTF-8, like a file: E0005); ``progress``
    and ``max_bytes`` as in :func:`compile_source`.

    ``TypeError`` when ``text`` is not a ``str``, or ``name`` neither a ``str`` nor a path.
    """
    try:
        source = text_source(text, name)
    except ParseFailure as failure:
        return CompileResult(None, (failure.diagnostic,), _sources_of(failure))
    return compile_source(source, analyse=analyse, progress=progress, max_bytes=max_bytes)


def compile_file(path: str | Path, *, analyse: bool = True, progress: Callable[[str], None] | None = None,
                 max_bytes: int | None = None) -> CompileResult:
    """Check one `.ra` file (``progress`` and ``max_bytes`` as in :func:`compile_source`). ``OSError``
    propagates for files that cannot be read at all."""
    try:
        source = read_source(path)
    except ParseFailure as failure:
        return CompileResult(None, (failure.diagnostic,), _sources_of(failure))
    return compile_source(source, analyse=analyse, progress=progress, max_bytes=max_bytes)


def _sources_of(failure: ParseFailure) -> dict[str, SourceFile]:
    return {failure.source.name: failure.source} if failure.source is not None else {}
