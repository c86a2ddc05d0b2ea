"""The pipeline: text → AST → checked IR (+ diagnostics and facts). Targets start from its result.

After parsing, the compiler is a list of stages (:data:`STAGES`: names and types, the parameters'
synthesis, the analyses, the scenario), each a function from the :class:`Compilation` so far to the
next; the result is a :class:`CompileResult`."""

from __future__ import annotations

import os
import warnings
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import TYPE_CHECKING

from rac import ir
from rac.check.resolve import Resolver
from rac.core.caller import user_stacklevel
from rac.core.diagnostics import (
    CheckError,
    Diagnostic,
    Fact,
    RacCheckWarning,
    check_warning_text,
    error,
    leaves_undecided,
)
from rac.core.source import SourceFile
from rac.lang import ast
from rac.lang.parser import ParseFailure, parse_source, read_source, text_source
from rac.model.program import CheckedProgram, ProgramSource

if TYPE_CHECKING:
    from rac.check.analysis.discount import Discount
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
    #: What the analyses proved (``rac check`` prints each one's sentence, ``--format json`` them all).
    facts: tuple[Fact, ...] = ()
    #: With `param` declarations: the values synthesised for them (None without parameters, or when
    #: synthesis failed; the diagnostics then say why).
    synthesis: Synthesised | None = None
    #: With a `model` block: the scenario it names, loaded once by the checks
    #: (a :class:`rac.model.commonroad.Scenario`), and the model's data built from it at the block's
    #: base and exponent (a :class:`rac.model.data.ModelData`); None when not loaded.
    scenario: Scenario | None = None
    model_data: ModelData | None = None

    @property
    def proved(self) -> tuple[str, ...]:
        """The facts' sentences, as ``rac check`` prints them."""
        return tuple(fact.message for fact in self.facts)

    @property
    def ok(self) -> bool:
        return self.automaton is not None and not any(d.is_error for d in self.diagnostics)

    @property
    def undecided(self) -> bool:
        """A check stopped at its limit (W0405), or a required check could not be made (W1008), neither
        proved nor refuted: no error, but not a verdict."""
        return any(leaves_undecided(d) for d in self.diagnostics)

    def raise_for_errors(self, *, warn: bool = False) -> ir.Automaton:
        """The automaton, or :class:`CheckError` carrying the diagnostics. With ``warn`` (for a file
        loaded from Python, where no report is printed) its warnings become one
        :class:`~rac.core.diagnostics.RacCheckWarning`."""
        if not self.ok or self.automaton is None:
            raise CheckError(self.diagnostics, self.sources)
        text = check_warning_text(self.diagnostics) if warn else None
        if text is not None:  # at the line of the user's that loaded it: rac.load(...), the wrapper given a path
            warnings.warn(text, RacCheckWarning, stacklevel=user_stacklevel())
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


@dataclass(frozen=True)
class Settings:
    """How a file is compiled: ``analyse`` (False: parse and resolve only), ``progress`` (hears of a
    scenario whose load takes a while, :func:`rac.model.checks.check_scenario`), ``max_bytes``
    (the scenario load's memory budget; None: no limit) and ``discount`` (P2 of the return discounted
    by it checked too, ``rac check --discount``; None: not)."""

    analyse: bool = True
    progress: Callable[[str], None] | None = None
    max_bytes: int | None = None
    discount: Discount | None = None


@dataclass(frozen=True)
class Compilation:
    """The state between two stages: what the stages before found. Each stage returns a new one."""

    module: ast.Module
    automaton: ir.Automaton | None = None
    diagnostics: tuple[Diagnostic, ...] = ()
    facts: tuple[Fact, ...] = ()
    synthesis: Synthesised | None = None
    scenario: Scenario | None = None
    model_data: ModelData | None = None

    @property
    def failed(self) -> bool:
        """Whether a stage reported an error (the later stages then do nothing)."""
        return any(d.is_error for d in self.diagnostics)


def resolve_stage(state: Compilation, settings: Settings) -> Compilation:
    """Names and types: the AST's (first) automaton resolved into the IR (E01xx-E07xx)."""
    found = [error("E0107", "a file holds one automaton; this is a second one", extra.name.span,
                   hints=["move it to a file of its own"]) for extra in state.module.automata[1:]]
    resolver = Resolver(state.module.automata[0])
    automaton = resolver.run()
    return replace(state, automaton=automaton, diagnostics=(*state.diagnostics, *found, *resolver.diagnostics))


def parameter_stage(state: Compilation, settings: Settings) -> Compilation:
    """With `param` declarations: the automaton at the synthesised values (:mod:`rac.check.params`)."""
    if state.automaton is None or not state.automaton.parameters or not settings.analyse or state.failed:
        return state
    from rac.check.params import synthesise_parameters  # numpy and sympy: a syntax error never needs them

    # with --discount, one parameter's synthesis searches P2 of the discounted return too; where it does not
    # (several weights), its facts say so, where "every check holds" over the set claimed what E0410 may refute
    outcome = synthesise_parameters(state.module.automata[0], state.automaton.parameters,
                                    discount=settings.discount)
    return replace(state, automaton=outcome.automaton, diagnostics=(*state.diagnostics, *outcome.diagnostics),
                   facts=(*state.facts, *outcome.facts), synthesis=outcome.synthesised)


def analysis_stage(state: Compilation, settings: Settings) -> Compilation:
    """Behaviour, the priority order and the range (:mod:`rac.check.analysis`)."""
    if state.automaton is None or not settings.analyse or state.failed:
        return state
    from rac.check.analysis import analyse_automaton  # numpy and sympy: a syntax error never needs them

    facts: list[Fact] = []
    found = analyse_automaton(state.automaton, facts, discount=settings.discount)
    return replace(state, diagnostics=(*state.diagnostics, *found), facts=(*state.facts, *facts))


def scenario_stage(state: Compilation, settings: Settings) -> Compilation:
    """With a `model` block: its scenario loaded once and checked against the model
    (:func:`rac.model.checks.check_scenario`). Last: it checks the model's numbers, once the
    automaton is sound."""
    if state.automaton is None or state.automaton.model is None or not settings.analyse or state.failed:
        return state
    from rac.model.checks import check_scenario  # commonroad-io loads with the first scenario

    checked = check_scenario(state.automaton, settings.progress, settings.max_bytes)
    return replace(state, diagnostics=(*state.diagnostics, *checked.diagnostics),
                   facts=(*state.facts, *checked.facts), scenario=checked.scenario, model_data=checked.data)


#: The compiler after parsing: each stage takes what the earlier ones found and adds its own; a stage
#: does nothing once one before it reported an error (docs/architecture.md).
STAGES: tuple[tuple[str, Callable[[Compilation, Settings], Compilation]], ...] = (
    ("resolve", resolve_stage), ("parameters", parameter_stage), ("analysis", analysis_stage),
    ("scenario", scenario_stage))


def compile_source(source: SourceFile, *, analyse: bool = True, progress: Callable[[str], None] | None = None,
                   max_bytes: int | None = None, discount: Discount | None = None) -> CompileResult:
    """Parse one source, then run the :data:`STAGES` on it (only ``resolve`` when ``analyse=False``);
    ``progress`` hears of a scenario whose load takes a while (:func:`rac.model.checks.check_scenario`).
    ``max_bytes`` is the memory budget of loading the scenario (None: no limit): a scenario estimated
    to need more is refused before it loads (:class:`rac.core.resources.ScenarioTooLarge`, a
    ``MemoryError``). ``discount``: P2 of the discounted return checked too (:class:`Settings`)."""
    sources = {source.name: source}
    try:
        module = parse_source(source)
    except ParseFailure as failure:
        return CompileResult(None, (failure.diagnostic,), sources)
    settings = Settings(analyse, progress, max_bytes, discount)
    state = Compilation(module)
    for _, stage in STAGES:
        state = stage(state, settings)
    return CompileResult(None if state.failed else state.automaton, state.diagnostics, sources, module, state.facts,
                         state.synthesis, state.scenario, state.model_data)


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
                 max_bytes: int | None = None, discount: Discount | None = None) -> CompileResult:
    """Check one `.ra` file (``progress``, ``max_bytes`` and ``discount`` as in :func:`compile_source`).
    ``OSError`` propagates for files that cannot be read at all."""
    try:
        source = read_source(path)
    except ParseFailure as failure:
        return CompileResult(None, (failure.diagnostic,), _sources_of(failure))
    return compile_source(source, analyse=analyse, progress=progress, max_bytes=max_bytes, discount=discount)


def _sources_of(failure: ParseFailure) -> dict[str, SourceFile]:
    return {failure.source.name: failure.source} if failure.source is not None else {}
