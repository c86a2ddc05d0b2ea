"""The paper's standard queries over a file's scenario model, in ``.ra`` syntax, checked like the file's.

For a file with a ``model`` block, ``rac verify --standard`` answers the pre-analysis queries
(Table 1: Qa-Qd) and Fig. 7's simulations, and ``rac compile --target uppaal`` writes them into the
emitted model together with the learning queries (Table 2). Both read the one list below, lowered
by the checker (:func:`rac.check.queries.lower_queries`) against the automaton, so that the engine
answers exactly the queries the emitted model holds. ``MAXT`` stands for the horizon in seconds,
``OBJECTIVE`` for the automaton's objective and ``PROCESS`` for its name. The names in them are the
scenario model's, also where the automaton declares one of the same name (an input ``x``).
"""

from __future__ import annotations

import dataclasses
import re
from collections.abc import Iterable
from dataclasses import dataclass
from fractions import Fraction

from rac import ir
from rac.check.queries import lower_queries
from rac.core.numbers import exact_decimal
from rac.core.source import SourceFile
from rac.ir import expr as ie
from rac.ir import query as iq
from rac.ir.text import format_checked
from rac.lang.parser import parse_queries

__all__ = ["STANDARD", "StandardQuery", "at_horizon", "objective_expression", "standard_queries"]


@dataclass(frozen=True)
class StandardQuery:
    name: str
    text: str
    #: What the query asks, in words.
    title: str
    #: Answered by ``rac verify --standard`` (the learning queries are in the emitted model only:
    #: ``rac experiment`` runs the paper's learning experiment).
    verify: bool = True


#: Every standard query, in order (a strategy is defined before the queries that use it).
STANDARD: tuple[StandardQuery, ...] = (
    StandardQuery("Qa", "Pr[<=MAXT](<> fabs(true_x - x) >= sensor_error)",
                  "sensor error: Pr of the sensed x drifting sensor_error from the true x"),
    StandardQuery("Qb", "E[] !collide() && !offroad()", "a run that is never unsafe exists"),
    StandardQuery("Qc", "E<> !collide() && !offroad() && goal()", "a safe state in the goal is reachable"),
    StandardQuery("Qd", "strategy safe = control: A[] !collide() && !offroad()",
                  "the safety shield (the most permissive safe strategy)"),
    StandardQuery("Fig7", "simulate[<=MAXT;100]{mindist(), 3 * collision_distance}",
                  "the distance to the nearest obstacle against 3*TD, unshielded (the paper's Fig. 7)"),
    StandardQuery("Fig7_safe", "simulate[<=MAXT;100]{mindist(), 3 * collision_distance} under safe",
                  "the same under the shield"),
    StandardQuery("Unsafe_safe", "Pr[<=MAXT](<> mindist() <= 3 * collision_distance) under safe",
                  "Pr of coming closer than 3*TD under the shield"),
    StandardQuery("reachSafe", "strategy reachSafe = maxE(OBJECTIVE)[<=MAXT]{PROCESS.location}->{x, y, v, head}: "
                  "<> goal() under safe", "learning to reach the goal under the shield", verify=False),
    StandardQuery("reachSafe_run", "simulate[<=MAXT;1]{x, y, v, head} under reachSafe",
                  "a run under reachSafe (the learned trajectory)", verify=False),
    StandardQuery("reach", "strategy reach = maxE(OBJECTIVE)[<=MAXT]{PROCESS.location}->{x, y, v, head}: "
                  "<> time >= MAXT", "learning without the shield: the objective, maximised", verify=False),
    StandardQuery("reach_safe", "A[] !collide() && !offroad() under reach", "the learned strategy is safe",
                  verify=False),
    StandardQuery("reach_goal", "A<> goal() under reach", "the learned strategy reaches the goal", verify=False),
)
_STRATEGIES = ("safe", "reachSafe", "reach")
#: The standard queries that read ``MAXT`` only as their time bound ``[<=MAXT]`` (:func:`at_horizon`).
_BOUND_ONLY = frozenset(q.name for q in STANDARD if q.text.count("MAXT") == q.text.count("[<=MAXT"))


def standard_queries(automaton: ir.Automaton, horizon: Fraction | None = None, *,
                     verify_only: bool = False) -> tuple[iq.QueryDecl, ...]:
    """The standard queries of ``automaton`` (it has a ``model`` block), checked and lowered.

    ``horizon`` is ``MAXT`` in seconds (default: the automaton's). A strategy of the file's own
    queries with the name of a standard one (``safe``) leaves the standard one renamed (``safe_``).
    With ``verify_only``, the queries ``rac verify --standard`` answers.
    """
    taken = {d.query.name for d in automaton.queries if isinstance(d.query, iq.STRATEGY_QUERIES)}
    rename = {}
    for name in _STRATEGIES:
        fresh = name
        while fresh in taken:
            fresh += "_"
        rename[name] = fresh
    maxt = _decimal(horizon if horizon is not None else Fraction(automaton.horizon))
    lines = []
    chosen = [q for q in STANDARD if q.verify or not verify_only]
    for query in chosen:
        # the objective is put in after checking: its rewards may be named like the model's names
        text = query.text.replace("MAXT", maxt).replace("OBJECTIVE", "0").replace("PROCESS", automaton.name)
        for name in _STRATEGIES:
            text = _rename(text, name, rename[name])
        lines.append(f"query {query.name}: {text}")
    # The header line keeps each query on the line reports have always given it (the JSON `location`).
    source = SourceFile("<standard queries>", "// the standard queries\n" + "\n".join(lines) + "\n")
    decls = parse_queries(source)
    lowered = lower_queries(automaton, decls, titles={q.name: q.title for q in chosen},
                            sources={source.name: source}, model_first=True)
    objective = objective_expression(automaton)
    return tuple(_with_objective(decl, objective) for decl in lowered)


def at_horizon(decls: Iterable[iq.QueryDecl], horizon: Fraction) -> tuple[iq.QueryDecl, ...]:
    """Standard queries as :func:`standard_queries` lowered them (:attr:`rac.ir.Automaton.standard_queries`)
    with ``MAXT`` = ``horizon`` seconds: the time bound of each replaced in the IR and in the text,
    the same queries as :func:`standard_queries` at ``horizon`` without lowering them again.
    ``ValueError`` for a query that is not a standard one or reads ``MAXT`` elsewhere than in its
    bound (``reach``'s ``<> time >= MAXT``)."""
    found = []
    for decl in decls:
        if decl.name not in _BOUND_ONLY:
            raise ValueError(f"`{decl.name}`: not a standard query whose only MAXT is its time bound")
        query = decl.query
        if isinstance(query, iq.ProbabilityQuery | iq.ExpectationQuery | iq.SimulateQuery | iq.LearnStrategy) \
                and query.bound.kind == "time":
            old, new = f"[<={_decimal(query.bound.limit)}", f"[<={_decimal(horizon)}"
            if old not in decl.text:
                raise ValueError(f"`{decl.name}`: its text {decl.text!r} does not show its bound {old}]")
            decl = dataclasses.replace(decl, query=dataclasses.replace(query, bound=iq.Bound("time", horizon)),
                                       text=decl.text.replace(old, new, 1))
        found.append(decl)
    return tuple(found)


def objective_expression(automaton: ir.Automaton) -> ie.Expr:
    """The automaton's objective as a checked expression over its rewards (``10*sa + 5*pr + co``)."""
    terms: list[ie.Expr] = []
    for name, coefficient in automaton.objective.terms:
        ref = ie.Ref(ie.RefKind.REWARD, name, ie.NUM, automaton.rewards.index(name))
        terms.append(ref if coefficient == 1 else ie.Binary("*", ie.Const(coefficient), ref))
    if automaton.objective.const or not terms:
        terms.append(ie.Const(automaton.objective.const))
    total = terms[0]
    for term in terms[1:]:
        total = ie.Binary("+", total, term)
    return total


def _with_objective(decl: iq.QueryDecl, objective: ie.Expr) -> iq.QueryDecl:
    if not isinstance(decl.query, iq.LearnStrategy):
        return decl
    query = dataclasses.replace(decl.query, objective=objective)
    text = decl.text.replace("maxE(0)", f"maxE({format_checked(objective)})")
    return dataclasses.replace(decl, query=query, text=text)


def _rename(text: str, old: str, new: str) -> str:
    return re.sub(rf"(?<![\w.]){old}(?!\w)", new, text) if old != new else text


def _decimal(value: Fraction) -> str:
    return exact_decimal(value) or repr(float(value))
