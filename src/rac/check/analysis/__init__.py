"""Static analyses of a checked automaton: behaviour (determinism, reachability) and priorities."""

from __future__ import annotations

from rac import ir
from rac.core.diagnostics import Diagnostic


def analyse_automaton(automaton: ir.Automaton, facts: list[str] | None = None) -> list[Diagnostic]:
    """Run every analysis; later ones run only when earlier ones found no error.

    What was proved is appended to ``facts`` as sentences (the CLI prints them).
    """
    from rac.check.analysis.behaviour import check_behaviour
    from rac.check.analysis.priority import check_priorities, check_ranges

    facts = facts if facts is not None else []
    diagnostics = check_behaviour(automaton)
    if any(d.is_error for d in diagnostics):
        return diagnostics
    facts.append("deterministic: every location has at most one enabled edge for every input")
    diagnostics += check_priorities(automaton, facts)
    model = automaton.model
    if model is not None:
        diagnostics += check_ranges(automaton, base=model.base, exponent=model.exponent, facts=facts)
    else:
        diagnostics += check_ranges(automaton, facts=facts)
    return diagnostics
