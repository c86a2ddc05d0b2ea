"""The text of the reward automaton's labels in the UPPAAL model.

:class:`Labels` prints what the reward automaton's template says, location by location and edge
by edge: a location's rates as ODEs of its hybrid clocks, a guard over the inputs' significands,
an update of a reward's hybrid clock and integer mirror, the ``at end`` clauses of the ``finish?``
edge, and what the mirrors gain per sample. A threshold or update with no significand is reported
as E0801 through :class:`rac.targets.uppaal.significands.Significands`.
"""

from __future__ import annotations

from collections.abc import Iterable
from fractions import Fraction

from rac import ir
from rac.runtime.semantics import mirror_update
from rac.targets.uppaal.expr import NotRepresentable, print_exact_sum, print_guard, print_int_linear, print_real_linear
from rac.targets.uppaal.names import Names
from rac.targets.uppaal.significands import Accrual, Significands

__all__ = ["Labels"]


class Labels:
    """The labels of ``automaton``'s template: ``names`` are its UPPAAL names, ``mirrors`` each
    reward's integer mirror, ``numbers`` the representation its numbers are printed in.

    :attr:`truncating` becomes true once an update has a fractional coefficient (the mirror's
    integer division truncates; the declarations say so).
    """

    def __init__(self, automaton: ir.Automaton, names: Names, mirrors: dict[str, str], numbers: Significands):
        self.a = automaton
        self.n = names
        self.mirror = mirrors
        self.numbers = numbers
        self.scale = numbers.scale
        self.input_names = {i.name: names[i.name] for i in automaton.inputs}
        self.truncating = False

    # ------------------------------------------------------------ rates
    def ode(self, location: ir.Location, unit: Fraction, ended: str | None = None) -> str:
        """The location's invariant: each reward's rate as the ODE of its hybrid clock, per time unit;
        ``ended`` (the flag of ``episode ends when``): 0 once it is set, the run having ended."""
        parts = []
        for reward, rate in zip(self.a.rewards, location.rates):
            terms = [(coef * unit, self.n[name], self.scale) for name, coef in rate.terms]
            value = print_real_linear(rate.const * unit, terms)
            if ended is not None and (rate.const or rate.terms):
                value = f"({ended} ? 0.0 : {value})"
            parts.append(f"{self.n[reward]}' == {value}")
        return " && ".join(parts)

    def accrual(self, row: list[Accrual | None]) -> list[str]:
        """The ``accrue?`` self-loop's assignments of one location: each mirror plus what it gains."""
        parts = []
        for reward, accrual in zip(self.a.rewards, row):
            if accrual is None:
                continue
            const, terms = accrual
            if const == 0 and not terms:
                continue
            mirror = self.mirror[reward]
            parts.append(f"{mirror} = {print_exact_sum(const, [(Fraction(1), mirror), *terms])}")
        return parts

    def first_sample(self, location: ir.Location) -> list[str]:
        """The first sample's ``read?`` corrections: each hybrid clock whose rate reads inputs gains the
        inputs' part of the rate over one period (its ODE ran before the inputs held a value)."""
        corrections = []
        for reward, rate in zip(self.a.rewards, location.rates):
            if rate.terms:
                terms = [(coef * Fraction(self.a.period), self.n[name], self.scale) for name, coef in rate.terms]
                corrections.append(f"{self.n[reward]} = {self.n[reward]} + "
                                   f"{print_real_linear(Fraction(0), terms)}")
        return corrections

    # ------------------------------------------------------------ updates
    def update(self, assignment: ir.Assignment) -> list[str]:
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

    def updates(self, assignments: Iterable[ir.Assignment], span) -> str:
        """An edge's assignment label ("" after reporting E0801 at ``span``)."""
        try:
            return ", ".join(part for a in assignments for part in self.update(a))
        except NotRepresentable as exc:
            numbers = self.numbers
            numbers.unrepresentable(f"an update is not representable at base {numbers.base}, exponent "
                                    f"{numbers.exponent}: {exc}", span)
            return ""

    def guard(self, guard: ir.Guard, names: dict[str, str] | None = None, span=None) -> str:
        """A guard label over the inputs (``names``: how to print them, default their UPPAAL names);
        "" for ``true``, "false" after reporting E0801 at ``span``."""
        if isinstance(guard, ir.BConst) and guard.value:
            return ""
        try:
            return print_guard(guard, names or self.input_names, self.scale)
        except NotRepresentable as exc:
            numbers = self.numbers
            numbers.unrepresentable(f"a threshold is not representable at base {numbers.base}, exponent "
                                    f"{numbers.exponent}: {exc}", span)
            return "false"

    def end_updates(self) -> tuple[str, str]:
        """The ``finish?`` edge's guard and assignment."""
        clauses = self.a.end_clauses
        if len(clauses) == 1:
            clause = clauses[0]
            return self.guard(clause.guard, span=clause.span), self.updates(clause.updates, clause.span)
        parts = []
        for clause in clauses:
            guard = self.guard(clause.guard, span=clause.span)
            for assignment in clause.updates:
                try:
                    texts = self.update(assignment)
                except NotRepresentable as exc:
                    self.numbers.unrepresentable(f"an update is not representable: {exc}", clause.span)
                    continue
                if not guard:
                    parts += texts
                    continue
                for text in texts:
                    target, _, value = text.partition(" = ")
                    parts.append(f"{target} = ({guard}) ? {value} : {target}")
        return "", ", ".join(parts)
