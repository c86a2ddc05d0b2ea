"""The names a checked automaton declares, where its problems go, and what the model block reads.

:class:`Scope` is shared by the resolver (:mod:`rac.check.resolve`), the model block
(:mod:`rac.check.model_block`) and the lowering of queries and bindings (:mod:`rac.check.queries`):
the automaton's symbols, whether it has a model block (its vocabulary is then legal in queries),
the settings as the model holds them, and the diagnostics.
"""

from __future__ import annotations

import difflib
from collections.abc import Callable
from dataclasses import dataclass, field
from fractions import Fraction

from rac.core.diagnostics import Diagnostic, Note, RacError, error
from rac.core.source import Span
from rac.lang import ast

__all__ = ["ModelContext", "Scope", "Symbol", "Unresolvable", "kind_word"]


class Unresolvable(RacError):
    """An expression could not be typed; its diagnostic is already recorded."""


@dataclass
class Symbol:
    """A name the automaton declares."""

    kind: str  # input | const | reward | location
    type: str  # bool | num
    span: Span | None
    value: Fraction | bool | None = None
    index: int = -1  # the input's, reward's or location's position (-1: not known yet)


@dataclass
class Scope:
    """What an expression may name, and where its problems go.

    ``symbols`` are the automaton's names; ``settings`` the model block's settings as the model
    holds them (None: no model block, or a model block whose settings did not check); ``has_model``
    whether the automaton has a model block (its vocabulary is then legal in queries).
    """

    automaton: str
    symbols: dict[str, Symbol]
    has_model: bool
    default_span: Span | None
    settings: dict[str, Fraction] | None = None
    diagnostics: list[Diagnostic] = field(default_factory=list)
    #: While the constants are evaluated in order: those declared further down, where (a constant may
    #: use only the ones above it, and "unknown name" alone did not say that the name exists).
    declared_below: dict[str, Span | None] = field(default_factory=dict)

    def error(self, code: str, message: str, span: Span | None, **kw) -> None:
        self.diagnostics.append(error(code, message, span or self.default_span, **kw))

    def unknown(self, name: str, span: Span | None, what: str = "name") -> None:
        if name in self.declared_below:
            below = Note(f"`{name}` is declared below", self.declared_below[name])
            self.error("E0101", f"unknown {what} `{name}`", span, notes=[below],
                       hints=["a constant may use only the constants declared above it: move this declaration "
                              f"below `{name}`'s"])
            return
        candidates = difflib.get_close_matches(name, list(self.symbols), n=1)
        hints = [f"did you mean `{candidates[0]}`?"] if candidates else [declare_hint(name, what)]
        self.error("E0101", f"unknown {what} `{name}`", span, hints=hints)



#: E0207's hint, for the automaton's expressions and the queries' alike.
DIVISION_BY_ZERO_HINT = "the divisor is 0 here: check the constants it is made of"


def declare_hint(name: str, what: str = "name") -> str:
    """The hint of E0101 for ``name`` (a ``what``: name, reward, location) with no declared name close to it."""
    if what == "reward":
        return f"correct the spelling, or declare it: `reward {name}`"
    if what == "location":
        return f"correct the spelling, or declare it: `location {name} {{ ... }}`"
    return "correct the spelling, or declare it in the automaton: an `input`, `const`, `param` or `reward`"

@dataclass
class ModelContext:
    """What resolving the ``model`` block reads of the automaton being resolved."""

    scope: Scope
    automaton: ast.Automaton
    #: The value of a constant expression (:class:`Unresolvable` after reporting why not).
    constant: Callable[[ast.Expr, str], Fraction]
    #: Spans of the block's settings the analyses point at ("model:exponent", "model:scenario").
    spans: dict[str, Span]


def kind_word(kind: str) -> str:
    """A symbol's kind as a message names it: ``"reward"`` is "a reward"."""
    return {"input": "an input", "const": "a constant", "reward": "a reward", "location": "a location"}[kind]
