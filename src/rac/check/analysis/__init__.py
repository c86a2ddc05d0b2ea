"""Static analyses of a checked automaton: behaviour (determinism, reachability), priorities, the int32
range, and the incentives (issue 25: p* and the loophole checks, with `goal when` or `episode ends when`)."""

from __future__ import annotations

from typing import TYPE_CHECKING

from rac import ir
from rac.core.diagnostics import Diagnostic, Fact

if TYPE_CHECKING:
    from rac.check.analysis.discount import Discount


def analyse_automaton(automaton: ir.Automaton, facts: list[Fact] | None = None, *,
                      discount: Discount | None = None) -> list[Diagnostic]:
    """Run every analysis; later ones run only when earlier ones found no error.

    What was proved is appended to ``facts`` as sentences (the CLI prints them). ``discount``: last, on an
    automaton without errors, P2 of the return discounted by it too (``rac check --discount``).
    """
    # numpy: importing any submodule loads this package first; these load only when the analyses run
    from rac.check.analysis.affine import moves
    from rac.check.analysis.behaviour import check_behaviour, input_space  # numpy: as above
    from rac.check.analysis.priority import check_priorities, check_ranges  # numpy: as above

    facts = facts if facts is not None else []
    # One input space and one set of moves serve every analysis (each costs a pass over every class).
    space, diagnostics = input_space(automaton)
    if space is None:
        return diagnostics
    diagnostics = check_behaviour(automaton, space)
    if any(d.is_error for d in diagnostics):
        return diagnostics
    facts.append(Fact("determinism", "deterministic: every location has at most one enabled edge for every input"))
    prepared = (space, moves(automaton, space))
    diagnostics += check_priorities(automaton, facts, prepared)
    model = automaton.model
    if model is not None:
        diagnostics += check_ranges(automaton, base=model.base, exponent=model.exponent, facts=facts,
                                    prepared=prepared)
    else:
        diagnostics += check_ranges(automaton, facts=facts, prepared=prepared)
    if automaton.goal is not None or automaton.episode_ends is not None:
        from rac.check.analysis.incentives import check_incentives  # numpy: as above

        diagnostics += check_incentives(automaton, space, facts)
    if discount is not None and not any(d.is_error for d in diagnostics):
        from rac.check.analysis.discount import check_discounted  # numpy: as above

        diagnostics += check_discounted(automaton, discount, facts, prepared)
    return diagnostics
