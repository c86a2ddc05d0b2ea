"""Static analyses of a checked automaton: behaviour (determinism, reachability) and priorities."""

from __future__ import annotations

from rac import ir
from rac.diagnostics import Diagnostic


def analyse_automaton(automaton: ir.Automaton) -> list[Diagnostic]:
    """Run every analysis; later ones run only when earlier ones found no error."""
    from rac.analysis.behaviour import check_behaviour
    from rac.analysis.priority import check_priorities, check_ranges

    diagnostics = check_behaviour(automaton)
    if any(d.is_error for d in diagnostics):
        return diagnostics
    diagnostics += check_priorities(automaton)
    diagnostics += check_ranges(automaton)
    return diagnostics
