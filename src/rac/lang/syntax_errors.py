"""Syntax errors in user terms: lark's exceptions become diagnostics (E0001-E0003).

Terminals are named as a reader knows them (``NAME`` is "a name", a literal terminal its text),
long lists of alternatives are summarised ("a declaration", "an expression", "an operator"), and
a few common slips get a hint. The same translation serves every start rule of the grammar.
"""

from __future__ import annotations

import dataclasses
import difflib
import re
import unicodedata
from pathlib import PurePath

from lark import Token
from lark.exceptions import UnexpectedCharacters, UnexpectedEOF, UnexpectedInput, UnexpectedToken
from lark.parsers.lalr_interactive_parser import InteractiveParser

from rac.core.diagnostics import Diagnostic, error
from rac.core.source import SourceFile, Span
from rac.lang.grammar import MODULE, lark_parser, literal_terminal

__all__ = ["syntax_error"]

# How terminals are named in messages. Literal terminals are shown as their text.
_TERMINAL_WORDS = {
    "NAME": "a name",
    "NUMBER": "a number",
    "CMP_OP": "a comparison (`<`, `<=`, `==`, ...)",
    "ADD_OP": "`+` or `-`",
    "MUL_OP": "`*` or `/`",
    "ASSIGN_OP": "`=`, `+=` or `-=`",
    "OR_OP": "`||`",
    "OR_WORD": "`||`",
    "AND_OP": "`&&`",
    "AND_WORD": "`&&`",
    "NUMERIC_TYPE": "`real` or `int`",
    "OPTIMISE": "`maxE` or `minE`",
    "MAXMIN": "`max` or `min`",
    "A_BOX": "`A[]`",
    "E_BOX": "`E[]`",
    "A_DIAMOND": "`A<>`",
    "E_DIAMOND": "`E<>`",
    "PR_OPEN": "`Pr[`",
    "E_OPEN": "`E[`",
    "STRING": 'a file name in quotes (`"..."`)',
    "$END": "end of file",
}
_DECLARATION_WORDS = ("input", "assume", "const", "param", "reward", "priority", "objective", "sample",
                      "horizon", "initial", "location", "edge", "at", "episode", "goal", "collision", "require",
                      "query", "model")
_EXPRESSION_START = {"a name", "a number", "`true`", "`false`", "`(`", "`-`", "`!`", "`not`"}


def _describe_terminal(name: str) -> str:
    if name in _TERMINAL_WORDS:
        return _TERMINAL_WORDS[name]
    literal = literal_terminal(name)
    return f"`{literal}`" if literal is not None else name.lower()


def _describe_expected(expected: set[str]) -> str:
    words = {_describe_terminal(t) for t in expected}
    declaration_words = {f"`{w}`" for w in _DECLARATION_WORDS}
    parts: list[str] = []
    if len(words & declaration_words) >= 5:
        words -= declaration_words
        parts.append("a declaration (`input`, `reward`, `location`, `edge`, `query`, ...)")
    if len(words & _EXPRESSION_START) >= 4:
        words -= _EXPRESSION_START
        parts.append("an expression")
    operators = {w for w in words if w.startswith("`") and any(c in w for c in "+-*/<>=&|")}
    if len(operators) >= 4:
        words -= operators
        parts.append("an operator")
    parts.extend(sorted(words))
    if len(parts) == 1:
        return parts[0]
    return ", ".join(parts[:-1]) + " or " + parts[-1]


def _token_text(token: Token) -> str:
    if token.type == "$END":
        return "end of file"
    return f"`{token.value}`"


#: The words before an unexpected token that name one of issue 25's declarations, with its form.
_DECLARATION_FORMS = {"goal": "goal when CONDITION", "collision": "collision when CONDITION",
                      "episode": "episode ends when CONDITION", "ends": "episode ends when CONDITION"}
_REQUIRE_CHECK = re.compile(r"\brequire\s+[A-Za-z_][A-Za-z0-9_]*\s*$")
#: The operand of ``&&``, ``||`` or a guard that the unexpected token continues: the text after the last of them.
_OPERAND_START = re.compile(r".*(?:&&|\|\||[({}:\n]|\b(?:when|and|or|not|imply|assume)\b)", re.DOTALL)
#: A comparison operator (not the arrow of an edge or of ``-->``).
_COMPARISON = re.compile(r"(?<!-)(?:<=|>=|==|!=|<|>)")


def _chained_comparison(found_type: str, expected: set[str], before: str) -> bool:
    """Whether a comparison operator follows a comparison, as in ``0 < d < 5``."""
    if found_type != "CMP_OP" or "CMP_OP" in expected:
        return False
    start = _OPERAND_START.match(before)
    return _COMPARISON.search(before[start.end() if start else 0:]) is not None


#: The query a syntax error interrupts: the text after its ``query NAME:``, up to the unexpected token.
_QUERY_SO_FAR = re.compile(r"\bquery\s+[A-Za-z_][A-Za-z0-9_]*\s*:(?P<text>[^\n]*)$")
_NO_SAVE_LOAD = ("rac has no `saveStrategy` or `loadStrategy` queries: `rac verify` saves every strategy it "
                 "computes in its output folder (`S.shield.npz`, `S.strategy.npz`)")
#: UPPAAL query forms rac has no syntax for: (the text of the query before the unexpected token, the
#: token; regular expressions matched in full) and what to write instead.
_UPPAAL_ONLY_QUERIES = (
    (r"\s*(?:sup|inf|bounds)\s*(?:\{.*\})?\s*", r"[:{]",
     "rac has no `sup`, `inf` or `bounds` queries: check a bound with `A[] e <= c`, or estimate the "
     "expected extreme with `E[<=T; N](max: e)`"),
    (r"\s*(?:strategy\s+[A-Za-z_][A-Za-z0-9_]*\s*=\s*)?", r"saveStrategy|loadStrategy",
     _NO_SAVE_LOAD),
    (r"\s*saveStrategy\s*\(.*", r".*",
     _NO_SAVE_LOAD),
    (r"\s*strategy\s+[A-Za-z_][A-Za-z0-9_]*\s*=\s*", r"minPr|maxPr",
     "rac learns `minE` and `maxE` strategies only"),
    (r"\s*strategy\s+[A-Za-z_][A-Za-z0-9_]*\s*=\s*", r"control_t",
     "rac has no time-optimal `control_t*` strategies: write `control: A[] p` or `control: E<> p`"),
    (r"\s*(?:strategy\s+[A-Za-z_][A-Za-z0-9_]*\s*=\s*)?", r"\{",
     "rac has no partially observed `{obs} control:` strategies: write `strategy S = control: A[] p`"),
    (r".*\bcontrol\s*:\s*", r"A",
     "a reachability objective is written `control: E<> p` (the UPPAAL target prints it as UPPAAL 5's "
     "`control: A<> p`)"),
    (r"(?!\s*strategy\b).*\bcontrol\s*", r":",
     "`control:` defines a strategy: `strategy S = control: A[] p` (rac has no collaborative "
     "`E<> control:` queries)"),
    (r"\s*Pr\s*\[.*\)\s*(?:<=|>=)\s*Pr\s*", r"\[",
     "rac compares a probability with a constant only: ask for each probability in a query of its own"),
    (r"\s*simulate\s*", r"[0-9].*",
     "a simulation is written `simulate[<=T; N]{e1, e2}` (UPPAAL 5 rejects the old form `simulate N [<=T]`)"),
    (r"\s*simulate\s*\[.*\}\s*", r":",
     "rac keeps every simulated run: it has no `: K : condition` filter; simulate `N` runs and select them "
     "from the CSV file"),
)


def _uppaal_query_hint(found: str, before: str) -> str | None:
    """The hint for a query form UPPAAL accepts and rac does not, when ``before`` ends inside one."""
    query = _QUERY_SO_FAR.search(before)
    if query is None:
        return None
    for text, token, hint in _UPPAAL_ONLY_QUERIES:
        if re.fullmatch(text, query["text"]) and re.fullmatch(token, found):
            return hint
    return None


def _misspelt_keyword(found: str, expected: set[str]) -> str | None:
    """The keyword the parser expects that the word ``found`` misspells (`inital`, `Location`, `rewards`,
    `wehn`), or None: a name where a keyword must stand is a newcomer's most common slip, and the list of
    what may follow does not say which word was meant."""
    if not found.isidentifier():
        return None
    words = [w for w in (literal_terminal(t) for t in expected) if w is not None and w.isidentifier()]
    # the keywords the grammar reads as names in some places (`goal`, `step`, `ends`) count too
    words += [w for w in _DECLARATION_WORDS if "NAME" in expected and f"`{w}`" not in words]
    words = [w for w in words if w != found]
    for word in words:  # a capital or a plural: `Location`, `rewards`, `inputs`
        if found.lower() in (word, word + "s"):
            return word
    close = difflib.get_close_matches(found.lower(), words, n=1, cutoff=0.75)
    return close[0] if close else None


#: Units a newcomer writes after a number (`horizon 30s`, `sample every 100ms`, `in [0, 50 m]`): numbers carry none.
_UNITS = {"s", "sec", "secs", "second", "seconds", "ms", "min", "h", "hz", "m", "km", "kmh", "mps", "kph"}
#: A number at the end of the text before the unexpected token (the unit's number).
_NUMBER_BEFORE = re.compile(r"(?<![A-Za-z_0-9.])[0-9]+(?:\.[0-9]+)?(?:[eE][-+]?[0-9]+)?[ \t]*$")
#: A declaration's `do` before the unexpected token, on the same line: `at end do r += 1 when g`.
_DO_BEFORE = re.compile(r"\bdo\b[^\n]*$")
#: A whole input declaration before the unexpected token: `input fast : bool` before `= false`.
_INPUT_BEFORE = re.compile(r"\binput\s+(?P<names>[A-Za-z_][A-Za-z0-9_]*(?:\s*,\s*[A-Za-z_][A-Za-z0-9_]*)*)\s*:\s*"
                           r"(?:bool|(?:real|int)(?:\s+in\s*\[[^\]\n]*\])?)\s*$")


def _syntax_hints(found: str, expected: set[str], before: str = "", found_type: str = "", after: str = "") -> list[str]:
    """Hints for the usual slips; ``before`` is the text before the unexpected token, ``after`` the rest of
    its line from it on, ``found_type`` its terminal."""
    hints = []
    # `a => b`, `a ==> b`, `a -> b` (logic's and other languages' arrows; `->` is only an edge's): the lexer
    # reads `=` then `>`, `==` then `>`, or `-` then `>`
    words = {_describe_terminal(t) for t in expected}
    if found == "=" and after.startswith("=>") and "`->`" in words:  # `edge A => B`: the arrow, not logic's
        hints.append("an edge's arrow is `->`: `edge A -> B`")
    elif (found == "=" and after.startswith("=>")) or (found == ">" and before.endswith(("-", "=="))):
        hints.append("implication is written `imply`: `a imply b` (or `!a || b`)")
    elif found == "=" and "CMP_OP" in expected:  # `when gap = 5`
        operand = re.search(r"([A-Za-z_][A-Za-z0-9_]*)\s*$", before)
        hints.append(f"equality is written `==`: `{operand.group(1) if operand else 'a'} == ...` "
                     "(`=` assigns a reward after `do`)")
    previous = before.split()[-1] if before.split() else ""
    form = previous in _DECLARATION_FORMS and bool(words & {"`when`", "`ends`"})
    if form:
        hints.append(f"the declaration is written `{_DECLARATION_FORMS[previous]}`")
    if previous == "require" and "a name" in words:
        hints.append("write `require CHECK` (e.g. `require ending_early_never_pays`) or `require risk <= BOUND`")
    if _REQUIRE_CHECK.search(before) and "`<=`" in words and found != "}":
        hints.append("a requirement's bound is written `require risk <= BOUND`, with `<=`; "
                     "the other requirements take none")
    if {"BOOL", "NUMERIC_TYPE"} <= expected:
        hints.append("an input's type is `bool`, `int in [LOW, HIGH]` or `real in [LOW, HIGH]`")
    if found == "=" and "`==`" in words:
        hints.append("a flow is written `reward' == rate`, with `==`")
    if found == ":=":
        hints.append("assignments are written `reward = expr` (UPPAAL's `:=` is old syntax)")
    if found in ("{", "}") and "RBRACE" in expected:
        hints.append("check that every `{` has a matching `}`")
    if found == "=" and (declared := _INPUT_BEFORE.search(before)):  # `input fast : bool = false`
        name = re.split(r"\s*,\s*", declared["names"])[0]
        value = re.split(r"//|/\*", after[1:])[0].strip() or "VALUE"
        hints.append(f"an input has no default value: it gets one at every sample, from the environment "
                     f"(`ra.step({{\"{name}\": ...}})`) or from a `model` block's binding (`bind {name} = EXPR`); "
                     f"for a fixed value declare a constant instead: `const {name} = {value}`")
    if found == ";":  # UPPAAL's declarations end in `;`, rac's do not (a `}` may follow either way)
        hints.append("declarations need no `;` at their end: `;` only separates the flows of a location "
                     "(and a query's bound from its number of runs)")
    if found.lower() in _UNITS and _NUMBER_BEFORE.search(before):
        hints.append("numbers carry no unit: times are in seconds (`horizon 30`, `sample every 0.1` for 100 ms), "
                     "distances in metres, speeds in m/s")
    elif found_type == "NAME" and not _STATEMENT_AFTER.match(after) and (number := _NUMBER_BEFORE.search(before)):
        # `objective 10sa + pr`; not `sa' == 1 pr' == 1` nor `do a += 1 b += 1`, a separator missing (below)
        hints.append(f"a product is written with `*`: `{number.group(0).strip()} * {found}`")
    if found == "when" and _DO_BEFORE.search(before):
        hints.append("the guard comes before the updates: `edge A -> B when GUARD do UPDATE, ...`, "
                     "`at end when GUARD do UPDATE, ...`")
    keyword = None if form else _misspelt_keyword(found, expected)  # the form shows the word already
    if keyword is not None:
        hints.append(f"did you mean `{keyword}`?")
    if _chained_comparison(found_type, expected, before):
        hints.append("comparisons do not chain: `0 < d < 5` is written `0 < d && d < 5`")
    uppaal = _uppaal_query_hint(found, before)
    if uppaal is not None:
        hints.append(uppaal)
    hints.extend(_separator_hints(found, expected, before, found_type, after))
    if found == "<" and not before.strip():  # `rac simulate scenario.xml`: the scenario given for the automaton
        hints.append("this looks like an XML file (a CommonRoad scenario?): rac reads a `.ra` file, whose `model` "
                     "block names the scenario with `scenario \"FILE.xml\"`")
    return hints


#: A flow (`pr' == ...`) or an update (`co += 1`) from the unexpected token on: what follows a missing separator.
_STATEMENT_AFTER = re.compile(r"[A-Za-z_][A-Za-z0-9_]*\s*(?:'|[-+]?=(?!=))")
#: The words that begin a declaration: one met where a `}` or a `)` was due says which of them is missing.
_DECLARATION_TYPES = {"INPUT", "ASSUME", "CONST", "PARAM", "REWARD", "PRIORITY", "OBJECTIVE", "SAMPLE", "HORIZON",
                      "INITIAL", "LOCATION", "EDGE", "AT", "EPISODE", "GOAL", "COLLISION", "REQUIRE", "QUERY", "MODEL"}


def _separator_hints(found: str, expected: set[str], before: str, found_type: str, after: str) -> list[str]:
    """Hints for a missing or wrong separator or keyword, where the parser's note names only the token it wanted
    (`expected `;` or `}``): a flow, an update or a name after another without its `;` or `,`, a `}` or `)` not
    closed, an edge without `->`, `when` or `do`, a constant without `=`, a location without braces."""
    words = {_describe_terminal(t) for t in expected}
    declaration = found in _DECLARATION_WORDS and (found_type in _DECLARATION_TYPES or found_type == "NAME")
    statement = bool(_STATEMENT_AFTER.match(after))
    if expected == {"SEMICOLON", "RBRACE"}:  # inside a location's braces
        if found == ",":
            return ["a location's flows are separated by `;`, not `,`: `{ sa' == 1; pr' == 0 }`"]
        if declaration:
            return [f"a `}}` is missing before `{found}`: close the location's `{{` (check that every `{{` has a "
                    "matching `}`)"]
        if statement:
            return ["a location's flows are separated by `;`: `{ sa' == 1; pr' == 0 }`"]
    if expected <= {"$END", "AUTOMATON"} and declaration:
        return [f"the automaton was closed before this `{found}`: a `}}` above closes it too early (check that every "
                "`{` has a matching `}`)"]
    if expected == {"RPAR"}:
        return ["check that every `(` has a matching `)`"]
    if "`->`" in words and found_type == "NAME":
        return ["an edge is written `edge FROM -> TO`, with `->`"]
    if "DO" in expected and found_type == "NAME" and statement and not _DO_BEFORE.search(before):
        return [f"updates follow `do`: `... do {after.split('//')[0].strip()}`"]
    if ("WHEN" in expected and "DO" in expected and found not in ("}", ",") and not declaration
            and _misspelt_keyword(found, expected) is None):  # `whn` has its own hint
        return ["a guard follows `when`: `edge A -> B when GUARD do UPDATE`"]
    if found == "=" and before.endswith("=") and _DO_BEFORE.search(before):  # `do sa == sa - 1`
        return ["an update assigns with one `=`: `reward = expr` (`==` compares, in a guard)"]
    if expected == {"COLON", "COMMA"}:
        return ["a type follows `:`: `input NAME : bool`"]
    if "COMMA" in expected and found_type == "NAME" and not declaration:
        if statement and _DO_BEFORE.search(before):
            return ["updates are separated by `,`: `do pr += 100, co += 1`"]
        if not statement:
            return ["names are separated by `,`: `reward sa, pr, co`"]
    if expected == {"EQUAL"} and re.search(r"\bconst\s+[A-Za-z_][A-Za-z0-9_]*\s*$", before):
        return ["a constant is written `const NAME = VALUE`"]
    if expected == {"NAME"} and found == "=" and before.rstrip().endswith(">"):
        return ["the priority order is written with `>` alone: `priority sa > pr > co`"]
    if expected == {"LBRACE"} and re.search(r"\blocation\s+[A-Za-z_][A-Za-z0-9_]*\s*$", before):
        return ["a location's flows are written in braces: `location L { sa' == 1; pr' == 0 }`"]
    return []


#: Comments, strings (whose text may hold ``//`` or ``/*``) and an unclosed ``/*``, lexed like the grammar.
_COMMENT_SCAN = re.compile(r'(?P<line>//[^\n]*)|(?P<block>/\*.*?\*/)|(?P<string>"[^"\n]*")|(?P<open>/\*)', re.DOTALL)


def _unterminated_comment(text: str) -> int | None:
    """Offset of the first ``/*`` that is never closed (lexed like the grammar does), if any."""
    for match in _COMMENT_SCAN.finditer(text):
        if match.lastgroup == "open":
            return match.start()
    return None


def _acceptable(exc: UnexpectedInput, source: SourceFile, rule: str, at_end: bool) -> set[str]:
    """The terminals the parser really accepts at the error (LALR tables over-approximate)."""
    parser = _parser_before_end(source, rule) if at_end else getattr(exc, "interactive_parser", None)
    accepted: set[str] = set()
    if parser is not None:
        try:
            accepted = set(parser.accepts())
        except UnexpectedInput:
            accepted = set()
    return accepted or set(getattr(exc, "expected", None) or getattr(exc, "allowed", None) or ())


def _parser_before_end(source: SourceFile, rule: str) -> InteractiveParser | None:
    """The parser of ``rule`` after the last token of ``source``, before the end of the text.

    At the end lark first reduces what the end may follow, then fails: the rules that stop at the
    end of the text (an expression list, a query list) share their parse states with the same
    rules inside a file, so the reductions would lose what could still follow the last token
    (an operator, a `}`). Only taken on an error, so a good parse pays nothing.
    """
    parser = lark_parser().parse_interactive(source.text, start=rule)
    try:
        parser.exhaust_lexer()
    except UnexpectedInput:
        return None
    return parser


def _end_of_text(source: SourceFile) -> Span:
    """Where "unexpected end of file" points: just after the last non-blank character."""
    end = len(source.text.rstrip())
    return source.span(end, end)


_CHARACTER_HINTS = {
    "&": "logical and is written `&&` (or `and`)",
    "|": "logical or is written `||` (or `or`)",
    '"': 'a file name is written in double quotes on one line: `scenario "left_turn.xml"`',
    "#": "comments start with `//` (to the end of the line) or are written `/* ... */`",
}
#: Characters that look like the ASCII a `.ra` file needs, as a copy from a paper, a web page or a word
#: processor brings them (``≤`` from a PDF, a no-break space from a browser): what to write instead.
_LOOKALIKES = {
    **dict.fromkeys("\u00a0\u1680\u2000\u2001\u2002\u2003\u2004\u2005\u2006\u2007\u2008\u2009\u200a"
                    "\u202f\u205f\u3000", "an ordinary space"),
    **dict.fromkeys("\u200b\u200c\u200d\u2060\ufeff", "nothing (it is invisible)"),
    **dict.fromkeys("\u2028\u2029\u0085", "an ordinary line break"),
    "≤": "`<=`", "≦": "`<=`", "⩽": "`<=`", "≥": "`>=`", "≧": "`>=`", "⩾": "`>=`", "≠": "`!=`",
    "→": "`->`", "⟶": "`->`", "⇒": "`imply`", "⟹": "`imply`", "∧": "`&&`", "∨": "`||`", "¬": "`!`",
    "×": "`*`", "·": "`*`", "∙": "`*`", "÷": "`/`", "∕": "`/`",
    **dict.fromkeys("\u2010\u2011\u2012\u2013\u2014\u2212", "`-`"),
    **dict.fromkeys("\u2018\u2019\u2032", "`'`"),
    **dict.fromkeys("\u201c\u201d\u201e\u2033", '`"`'),
}


def _lookalike_hint(char: str) -> str | None:
    """The hint for a character that looks like ASCII the language has (a no-break space, `≤`), or None."""
    instead = _LOOKALIKES.get(char)
    if instead is None:
        return None
    which = f"U+{ord(char):04X} ({unicodedata.name(char, 'a Unicode character').lower()})"
    if instead.startswith("nothing"):
        return (f"{which} is invisible: delete it (such characters come with text copied from a web page or a word "
                "processor)")
    return (f"{which} is not {instead}: write {instead} (such characters come with text copied from a PDF, a web "
            "page or a word processor)")


def syntax_error(exc: UnexpectedInput, source: SourceFile, rule: str = MODULE) -> Diagnostic:
    """The diagnostic of a syntax error lark raised while parsing ``source`` from the start rule ``rule``; for a
    Python file (``.py``), with the hint :func:`_python_file_hint` instead of the language's."""
    found = _syntax_error(exc, source, rule)
    hint = _python_file_hint(source)
    return found if hint is None else dataclasses.replace(found, hints=(hint,))


def _python_file_hint(source: SourceFile) -> str | None:
    """What to do with a Python file read as `.ra` source, or None for another file: a module generated by ``rac
    compile --target python`` given to ``rac.load`` or to the wrappers as a path (its syntax error's hints, "comments
    start with `//`" for its first line, said nothing of that)."""
    path = PurePath(source.name)
    if path.suffix.lower() != ".py":
        return None
    named = re.search(r'^__all__ = \["(\w+)"\]', source.text, re.MULTILINE)  # a generated module names its class
    cls = named.group(1) if named else "its class"
    return (f"`{path.name}` is a Python file, not `.ra` source: rac check, rac.load and the wrappers read the `.ra` "
            f"file; a module written by `rac compile --target python` is imported (`from {path.stem} import {cls}`), "
            f"and an instance of its class goes to RewardAutomatonWrapper in place of the path")


def _syntax_error(exc: UnexpectedInput, source: SourceFile, rule: str) -> Diagnostic:
    at_end = isinstance(exc, UnexpectedEOF) or (isinstance(exc, UnexpectedToken) and exc.token.type == "$END")
    if at_end:
        where = len(source.text)
    elif isinstance(exc, UnexpectedToken) and exc.token.start_pos is not None:
        where = exc.token.start_pos
    else:
        where = getattr(exc, "pos_in_stream", None) or 0
    comment = _unterminated_comment(source.text)
    if comment is not None and comment <= where:
        # Without its `*/` the lexer reads `/*` as a division and a product: say what happened.
        return error("E0003", "unterminated block comment", source.span(comment, comment + 2),
                     hints=["close the comment with `*/`"])
    expected = _acceptable(exc, source, rule, at_end)
    notes = [f"expected {_describe_expected(expected)}"] if expected else []
    if isinstance(exc, UnexpectedCharacters):
        start = where  # the character's offset (pos_in_stream)
        char = source.text[start]
        shown = repr(char)[1:-1] if not char.isprintable() or char == " " else char
        hints = [_CHARACTER_HINTS[char]] if char in _CHARACTER_HINTS else []
        lookalike = _lookalike_hint(char)
        if lookalike is not None:
            hints.append(lookalike)
        if not char.isascii() and (char.isalnum() or char == "_"):
            hints.append("names are ASCII identifiers: letters A-Z and a-z, digits and `_`")
        if not hints:  # a control character or another the language has no use for: only deleting it helps
            hints.append(f"`.ra` has no use for `{shown}`: delete it" if char.isprintable() else
                         "delete it: an invisible control character, perhaps pasted from another program")
        return error("E0002", f"unexpected character `{shown}`", source.span(start, start + 1),
                     notes=notes, hints=hints)
    if at_end:
        hints = ["check that every `{` has a matching `}`"] if "RBRACE" in expected else []
        return error("E0001", "unexpected end of file", _end_of_text(source), notes=notes, hints=hints)
    if isinstance(exc, UnexpectedToken):
        start = where
        end = exc.token.end_pos or start + len(exc.token.value)
        return error("E0001", f"unexpected {_token_text(exc.token)}", source.span(start, end), notes=notes,
                     hints=_syntax_hints(str(exc.token.value), expected, source.text[:start], exc.token.type,
                                         source.text[start:].split("\n", 1)[0]))
    return error("E0001", "syntax error", _end_of_text(source))
