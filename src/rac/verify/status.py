"""What a query's answer can be, and how it was reached: the one owner of ``rac verify``'s statuses.

Light on purpose (no numpy): ``rac sweep`` and the CLI's exit codes read it without loading the engine.
"""

from __future__ import annotations

__all__ = ["METHODS", "NOT_APPLICABLE", "NOT_SATISFIED", "SATISFIED", "STATUSES", "UNDECIDED", "UNKNOWN", "UNSUPPORTED",
           "VALUE", "VERDICTS"]

#: A query's ``status`` (:attr:`QueryResult.status`; the JSON's ``status``). ``not_applicable``: the query
#: depends on a strategy that provably does not exist (its defining query is not satisfied), so there is
#: nothing to decide; the failed defining query, not this one, sets the exit code.
SATISFIED, NOT_SATISFIED, VALUE, UNKNOWN, UNSUPPORTED, NOT_APPLICABLE = (
    "satisfied", "not satisfied", "value", "unknown", "unsupported", "not_applicable")
STATUSES: tuple[str, ...] = (SATISFIED, NOT_SATISFIED, VALUE, UNKNOWN, UNSUPPORTED, NOT_APPLICABLE)
#: The statuses that answer a yes/no query (a value query, ``Pr[<=T](<> p)`` or ``simulate``, has none of them).
VERDICTS: tuple[str, ...] = (SATISFIED, NOT_SATISFIED, UNKNOWN, UNSUPPORTED, NOT_APPLICABLE)
#: The statuses of a query that was not decided: ``rac verify`` never exits 0 with one of them.
UNDECIDED: tuple[str, ...] = (UNKNOWN, UNSUPPORTED)
#: How a verdict was reached (:attr:`QueryResult.method`), as the text output says it.
METHODS: dict[str, str] = {
    # the automaton-level analysis, valid in the model because its bindings satisfy the `assume`s
    "compositional": "decided on the automaton alone (every input sequence within the assumptions)",
    # a witness or counterexample found while the graph was built layer by layer, before it was complete
    "on the fly": "found on the fly, before the whole graph was built",
    # a witness found by a bounded search (random runs, a beam), replayed with the scalar model
    "witness search": "found by a bounded witness search and replayed",
    # a beam search of the product of model and automaton toward where the automaton alone fails
    "product search": "found by a bounded search of the product, guided by the automaton's own counterexample",
    # a formula that reads no state (constants, settings, `deadlock` without `allow when`): its one value; or
    # `p --> q` decided by a side that reads none (`p --> true`, `false --> q`)
    "constant": "decided without exploring: what decides the formula reads no state, so it has the same value in "
                "every state",
    # `A<> p` with `p` true at the start, `E[] p` with `p` false there: every run begins in the initial state
    "initial state": "decided in the initial state, where every run begins",
    # the complete graph up to the horizon
    "exhaustive": "decided on the complete graph up to the horizon",
    # the runtime shield searching the whole horizon from the start; the shield then computed state by state
    "on demand": "decided by a search of the whole horizon from the start (the model is too large to explore)",
    "simulation": "estimated by simulation",
    # `Pr[..](..) >= 0` (or `<= 1`, `> 1`, `< 0`): true or false of every probability
    "probability bounds": "decided by the bounds of every probability, 0 and 1",
    "learning": "learned",
    # the best strategy under the shield, by a backward pass over its decision graph (rac verify --exact)
    "exact optimum": "computed exactly by a backward pass over the shielded decision graph",
    # the one run of a deterministic model under a learned strategy
    "strategy run": "decided on the strategy's one run",
}
