"""The one lark parser of the `.ra` grammar (``grammar/rac.lark``) and its start rules.

Every parse goes through :func:`lark_parser`: a file, a list of expressions and a list of query
declarations are start rules of the same grammar, so they share one parse table (and one cache).
"""

from __future__ import annotations

from collections.abc import Iterator
from functools import lru_cache

from lark import Lark, Token
from lark.lark import PostLex

from rac.lang.resources import grammar_path

#: A whole `.ra` file: its automata.
MODULE = "start"
#: Expressions separated by commas (``mindist(), 3 * collision_distance``).
EXPRESSIONS = "expr_list"
#: Query declarations, one after another (``query Qb: E[] !collide()``).
QUERIES = "query_list"
START_RULES = (MODULE, EXPRESSIONS, QUERIES)


class _WholeWords(PostLex):
    """Lets the lexer see a name wherever it looks for a word of the language.

    The contextual lexer tries only the terminals the parser accepts next. Where no name may stand
    (the start of a declaration, an input's type) it then matched a keyword at the start of a longer
    word: `inputx : bool` declared the input `x`, and `boolean` became `bool` and `ean`. With names
    always tried, lark reads the whole word and takes it as the keyword only when it is one.
    """

    always_accept = ("NAME",)

    def process(self, stream: Iterator[Token]) -> Iterator[Token]:
        return stream


@lru_cache(maxsize=1)
def lark_parser() -> Lark:
    """The LALR parser of the grammar, built once per process with every start rule."""
    return Lark(
        grammar_path().read_text(encoding="utf-8"),
        parser="lalr",
        lexer="contextual",
        start=list(START_RULES),
        propagate_positions=True,
        maybe_placeholders=True,
        postlex=_WholeWords(),
        # The parse table is cached in the temp folder: saves ~0.1 s per `rac` start.
        cache=True,
    )


def literal_terminal(name: str) -> str | None:
    """The text of a terminal written as a literal string in the grammar (``RBRACE`` -> ``}``), else None."""
    for terminal in lark_parser().terminals:
        if terminal.name == name and terminal.pattern.type == "str":
            return str(terminal.pattern.value)
    return None


def terminal_regexp(name: str) -> str:
    """The regular expression of a terminal (``LINE_COMMENT``), as the lexer matches it."""
    terminals = {t.name: t for t in lark_parser().lexer_conf.terminals}
    return terminals[name].pattern.to_regexp()
