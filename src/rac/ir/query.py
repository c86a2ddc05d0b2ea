"""Checked queries: UPPAAL's query forms over typed, resolved expressions (:mod:`rac.ir.expr`).

The checker lowers every ``query NAME: ...`` of a file (and the paper's standard queries) into
these nodes: expressions resolved and typed, time bounds and run counts evaluated to numbers,
``under S`` checked to name a strategy defined by an earlier query. The engine
(:mod:`rac.verify.runner`) and the UPPAAL targets answer and print them; :attr:`QueryDecl.text` is the
query as the user wrote it (canonical ``.ra`` syntax), for reports.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from fractions import Fraction
from typing import Union

from rac.core.source import Span
from rac.ir.expr import Expr

__all__ = ["Bound", "ControlStrategy", "ExpectationQuery", "LeadsToQuery", "LearnStrategy", "PathQuery",
           "ProbabilityQuery", "Query", "QueryDecl", "SimulateQuery", "STRATEGY_QUERIES", "query_exprs"]


@dataclass(frozen=True)
class Bound:
    """``[<=T]`` (``kind`` "time", ``limit`` in seconds) or ``[#<=K]`` (``kind`` "steps")."""

    kind: str
    limit: Fraction


@dataclass(frozen=True)
class PathQuery:
    """``A[] p``, ``E<> p``, ``E[] p``, ``A<> p`` (optionally ``under S``)."""

    quantifier: str
    expr: Expr
    under: str | None = None


@dataclass(frozen=True)
class LeadsToQuery:
    """``p --> q``."""

    left: Expr
    right: Expr
    under: str | None = None


@dataclass(frozen=True)
class ProbabilityQuery:
    """``Pr[<=T;N](<> p)`` or ``([] p)``, optionally compared with a threshold (``>= 0.9``)."""

    bound: Bound
    runs: int | None
    path: str
    expr: Expr
    compare: tuple[str, Fraction] | None = None
    under: str | None = None


@dataclass(frozen=True)
class ExpectationQuery:
    """``E[<=T;N](max: e)`` or ``(min: e)``."""

    bound: Bound
    runs: int
    aggregate: str
    expr: Expr
    under: str | None = None


@dataclass(frozen=True)
class SimulateQuery:
    """``simulate[<=T;N]{e1, e2, ...}``; ``labels`` are the expressions as written (column names)."""

    bound: Bound
    runs: int | None
    exprs: tuple[Expr, ...]
    labels: tuple[str, ...] = ()
    under: str | None = None


@dataclass(frozen=True)
class ControlStrategy:
    """``strategy S = control: A[] p`` (or ``E<> p``)."""

    name: str
    goal: str
    expr: Expr
    under: str | None = None


@dataclass(frozen=True)
class LearnStrategy:
    """``strategy S = maxE(e)[<=T]{d...}->{c...}: <> p under S0`` (or ``minE``).

    ``labels`` are the observations as written: the discrete ones, then the continuous ones.
    """

    name: str
    optimise: str
    objective: Expr
    bound: Bound
    discrete: tuple[Expr, ...]
    continuous: tuple[Expr, ...]
    path: str
    expr: Expr
    under: str | None = None
    labels: tuple[str, ...] = ()


Query = Union[PathQuery, LeadsToQuery, ProbabilityQuery, ExpectationQuery, SimulateQuery, ControlStrategy,
              LearnStrategy]
#: The query forms that define a strategy (usable by later queries ``under`` its name).
STRATEGY_QUERIES = (ControlStrategy, LearnStrategy)


def query_exprs(query: Query) -> list[Expr]:
    """Every expression of a query: its formula(s), objective and observations."""
    found: list[Expr] = []
    for name in ("expr", "left", "right", "objective"):
        value = getattr(query, name, None)
        if value is not None:
            found.append(value)
    for name in ("exprs", "discrete", "continuous"):
        found.extend(getattr(query, name, ()))
    return found


@dataclass(frozen=True)
class QueryDecl:
    """``query NAME: ...``: the checked query, its text in canonical ``.ra`` syntax and its span."""

    name: str
    query: Query
    text: str
    span: Span | None = field(default=None, compare=False)
    #: What the query asks, in words, when it is one of the standard queries (else "").
    title: str = ""
