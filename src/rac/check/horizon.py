"""How synthesised values depend on the horizon (``rac tune --horizon``, docs/tune.md): a file's text
at another horizon, and the line through the values found at several horizons, fitted and checked
with sympy's exact rationals.

The fit is a statement about the horizons the table holds, not a proof for every horizon: the line
goes through two of them and is then compared with every other one, so a third horizon is the least
that can contradict it (with two, :func:`fit_line` says that nothing was checked).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from fractions import Fraction

from rac.core.numbers import exact_decimal
from rac.core.source import SourceFile
from rac.lang import ast

__all__ = ["Fit", "at_horizon", "fit_line", "formula_text"]


def at_horizon(source: SourceFile, node: ast.Automaton, horizon: Fraction | None) -> str:
    """The text of ``source`` with the expression of ``node``'s ``horizon`` declaration replaced by
    ``horizon`` (an exact decimal): every other character, comments included, stays as it was.
    When the automaton declares no horizon (``--horizon`` gives it), ``horizon H`` is written right
    after its ``sample every`` declaration, on the same line, so that every other line keeps its number
    for diagnostics. ``horizon=None`` means one sample period (the ``sample every`` expression's
    text): a file without a horizon then resolves, and its period can be read. Raises ``ValueError``
    when the automaton declares neither a horizon nor a period, or ``horizon`` is not a finite decimal."""
    declarations = node.of(ast.HorizonDecl)
    samples = node.of(ast.SampleDecl)
    period = samples[0].period.span if samples else None
    if horizon is not None:
        literal = exact_decimal(horizon)
        if literal is None:
            raise ValueError(f"the horizon {horizon} is not a finite decimal")
    elif period is not None:
        literal = source.text[period.start:period.end]
    else:
        raise ValueError(f"automaton `{node.name.name}` has no `sample every` declaration")
    if declarations and declarations[0].length.span is not None:
        span = declarations[0].length.span
        return source.text[:span.start] + literal + source.text[span.end:]
    after = samples[0].span.end if samples and samples[0].span is not None else None
    if after is None:
        raise ValueError(f"automaton `{node.name.name}` has no `horizon` declaration to replace "
                         "and no `sample every` to write one after")
    return source.text[:after] + f" horizon {literal}" + source.text[after:]


@dataclass(frozen=True)
class Fit:
    """The line ``value = slope * H + intercept`` through the points (horizon, value), when one is
    known: ``slope``/``intercept`` are None with fewer than three points (two fix a line and check
    nothing) or when a point is off the line through the first two (``off`` is then that point and
    the line's value there)."""

    points: tuple[tuple[Fraction, Fraction], ...]
    slope: Fraction | None = None
    intercept: Fraction | None = None
    off: tuple[Fraction, Fraction, Fraction] | None = None

    @property
    def linear(self) -> bool:
        """Whether every point lies on the fitted line (at least three of them)."""
        return self.slope is not None


def fit_line(points: Sequence[tuple[Fraction, Fraction]]) -> Fit:
    """The line through the first two of ``points`` (distinct horizons, ascending), checked against
    every other one, all in sympy's exact rationals."""
    import sympy  # sympy: only when this runs; importing rac.check.horizon stays light

    distinct = tuple(sorted(dict(points).items()))
    if len(distinct) < 3:
        return Fit(distinct)
    h = sympy.Symbol("H")
    exact = [(sympy.Rational(x.numerator, x.denominator), sympy.Rational(y.numerator, y.denominator))
             for x, y in distinct]
    line = sympy.Poly(sympy.interpolate(exact[:2], h), h)
    for (x, y), (hx, hy) in zip(distinct[2:], exact[2:]):
        predicted = line.eval(hx)
        if predicted != hy:
            return Fit(distinct, off=(x, y, _fraction(predicted)))
    coefficients = line.all_coeffs()
    slope, intercept = (coefficients if len(coefficients) == 2 else [sympy.Integer(0), *coefficients])
    return Fit(distinct, _fraction(slope), _fraction(intercept))


def _fraction(value: object) -> Fraction:
    """A sympy Rational as a Fraction."""
    return Fraction(int(value.p), int(value.q))  # type: ignore[attr-defined]


def _coefficient(value: Fraction) -> str:
    """A decimal where it is exact and short, else the fraction (``1.6``, ``1/3``)."""
    decimal = exact_decimal(value)
    return decimal if decimal is not None and len(decimal) <= 12 else f"{value.numerator}/{value.denominator}"


def formula_text(fit: Fit, variable: str = "H") -> str:
    """The fitted line as ``1.6 * H + 50``: a slope of 1 writes ``H``, a zero slope or intercept is left
    out, a coefficient that is no short decimal is a fraction (``1/3 * H``)."""
    assert fit.slope is not None and fit.intercept is not None, "only a line that was found prints"
    slope, intercept = fit.slope, fit.intercept
    if slope == 0:
        return _coefficient(intercept)
    term = variable if abs(slope) == 1 else f"{_coefficient(abs(slope))} * {variable}"
    text = f"-{term}" if slope < 0 else term
    if intercept:
        text += f" {'-' if intercept < 0 else '+'} {_coefficient(abs(intercept))}"
    return text
