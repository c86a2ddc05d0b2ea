"""The checker: a parsed module -> the IR. Scopes and symbols, name and type resolution, the
``model`` block, the queries (lowered to typed IR expressions), the paper's standard queries, and
the static analyses (determinism, reachability, priorities, worst cases).

May import: core, lang, ir.
"""
