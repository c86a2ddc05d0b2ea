"""rac.lang.syntax_errors: lark's exceptions become the documented E0001-E0003 diagnostics."""

from __future__ import annotations

from pathlib import Path

import pytest
from lark.exceptions import UnexpectedInput

from rac.core.source import SourceFile
from rac.lang.grammar import EXPRESSIONS, MODULE, lark_parser
from rac.lang.syntax_errors import syntax_error

DIAGNOSTICS = Path(__file__).resolve().parents[1] / "diagnostics"


def diagnose(text: str, rule: str = MODULE, name: str = "t.ra"):
    source = SourceFile(name, text)
    with pytest.raises(UnexpectedInput) as caught:
        lark_parser().parse(text, start=rule)
    return syntax_error(caught.value, source, rule), source


@pytest.mark.parametrize("case", ["E0001_missing_brace", "E0002_single_ampersand", "E0001_flow_single_equals"])
def test_the_message_of_the_documented_example(case: str) -> None:
    """The diagnostic's first line is the one the golden ``.expected`` file shows, at the same place."""
    text = (DIAGNOSTICS / f"{case}.ra").read_text(encoding="utf-8")
    diagnostic, _ = diagnose(text, name=f"{case}.ra")
    first = (DIAGNOSTICS / f"{case}.expected").read_text(encoding="utf-8").splitlines()[0]
    span = diagnostic.span
    assert first == f"{case}.ra:{span.line}:{span.column}: error[{diagnostic.code}]: {diagnostic.message}"


def test_single_ampersand_gets_the_hint() -> None:
    diagnostic, _ = diagnose("automaton A { input p : bool  input q : bool  edge * -> L when p & q }")
    assert diagnostic.code == "E0002"
    assert diagnostic.message == "unexpected character `&`"
    assert "logical and is written `&&` (or `and`)" in diagnostic.hints



@pytest.mark.parametrize(("char", "hint"), [
    ("#", "comments start with `//` (to the end of the line) or are written `/* ... */`"),
    ("@", "`.ra` has no use for `@`: delete it"),
    ("\v", "delete it: an invisible control character, perhaps pasted from another program")])
def test_a_character_the_language_has_no_use_for_gets_a_hint(char: str, hint: str) -> None:
    """Found by fuzzing: `#` (a Python comment), `@` or a control character was an E0002 without a hint."""
    diagnostic, _ = diagnose(f"automaton A {{ input p : bool {char} comment\n }}")
    assert diagnostic.code == "E0002" and diagnostic.hints == (hint,)

def test_missing_brace_is_an_unexpected_end_of_file() -> None:
    diagnostic, _ = diagnose("automaton A { input p : bool")
    assert (diagnostic.code, diagnostic.message) == ("E0001", "unexpected end of file")
    assert "check that every `{` has a matching `}`" in diagnostic.hints


def test_unterminated_block_comment() -> None:
    diagnostic, _ = diagnose("automaton A { /* never closed\n input p : bool }")
    assert (diagnostic.code, diagnostic.message) == ("E0003", "unterminated block comment")
    assert diagnostic.span.start == len("automaton A { ")


def test_expression_rule_names_the_unexpected_token() -> None:
    diagnostic, _ = diagnose("3 * * 4", EXPRESSIONS)
    assert diagnostic.code == "E0001"
    assert diagnostic.message.startswith("unexpected")
    assert diagnostic.message == "unexpected `*`"
    assert [note.message for note in diagnostic.notes] == ["expected an expression"]


@pytest.mark.parametrize(("text", "word"), [
    ("automaton A { inputx : bool }", "inputx"),            # was read as `input x : bool`
    ("automaton A { input x : boolean }", "boolean"),       # was `bool` and `ean`
    ("automaton A { input x : integer in [0, 1] }", "integer"),
    ("automaton A { input x : reals in [0, 1] }", "reals"),
    ("automaton A { rewardr }", "rewardr"),
    ("automaton A { horizon30 }", "horizon30"),
])
def test_a_word_that_begins_with_a_keyword_is_one_word(text: str, word: str) -> None:
    # where no name may stand, the contextual lexer used to match the keyword at the start of a
    # longer word and go on with the rest, so some such slips parsed as something else silently
    diagnostic, source = diagnose(text)
    assert diagnostic.code == "E0001"
    assert diagnostic.message == f"unexpected `{word}`"
    start = text.index(word)
    assert (diagnostic.span.column, diagnostic.span.end_column) == (start + 1, start + 1 + len(word))
    if word in ("boolean", "integer", "reals"):
        assert "an input's type is `bool`, `int in [LOW, HIGH]` or `real in [LOW, HIGH]`" in diagnostic.hints


@pytest.mark.parametrize("text", ["E[<=2; 20](max: v)", "E[<=2; 20](min: v)",
                                  "strategy s = maxE(sa)[<=4]{A.location}->{x}: <> goal()",
                                  "strategy s = minE(sa)[<=4]{A.location}->{x}: <> goal()"])
def test_the_word_alternations_still_read_as_words(text: str) -> None:
    lark_parser().parse(f"query Q: {text}\n", start="query_list")


CHAIN = "comparisons do not chain: `0 < d < 5` is written `0 < d && d < 5`"


@pytest.mark.parametrize("text", [
    "automaton A { input d : real in [0, 9]  edge * -> L when 0 < d < 5 }",
    "automaton A { input d : real in [0, 9]  edge * -> L when p && 2 <= d >= 1 do r += 1 }",
    "automaton A { input d : real in [0, 9]  assume (1 < d < 5) }",
    "automaton A { query Q: E<> 0 < sa <= 5 }",
])
def test_a_chained_comparison_gets_the_hint(text: str) -> None:
    """language.md: comparisons do not chain, `0 < d < 5` is a syntax error; the error says how to write it."""
    diagnostic, _ = diagnose(text)
    assert diagnostic.code == "E0001"
    assert CHAIN in diagnostic.hints


@pytest.mark.parametrize("text", [
    "automaton A { edge A -> B < 3 }",
    "automaton A { sample every < 3 }",
    "automaton A { edge * -> L when d < 5 && < 3 }",
])
def test_no_chain_hint_without_a_comparison_before(text: str) -> None:
    diagnostic, _ = diagnose(text)
    assert CHAIN not in diagnostic.hints


@pytest.mark.parametrize(("text", "char", "hint"), [
    ("automaton A { edge * -> L when d \u2264 3 }", "≤", "U+2264 (less-than or equal to) is not `<=`: write `<=`"),
    ("automaton A { edge L \u2192 M }", "→", "U+2192 (rightwards arrow) is not `->`: write `->`"),
    ("automaton A { edge L \u2013> M }", "–", "U+2013 (en dash) is not `-`: write `-`"),
    ("automaton A { horizon\u00a030 }", "\\xa0", "U+00A0 (no-break space) is not an ordinary space"),
    ("automaton A { horizon \u200b30 }", "\\u200b", "U+200B (zero width space) is invisible: delete it"),
    ('automaton A { model { scenario \u201cx.xml\u201d } }', "“", 'U+201C (left double quotation mark) is not `"`'),
])
def test_a_character_copied_from_a_pdf_or_a_web_page_gets_the_ascii_to_write(text: str, char: str, hint: str) -> None:
    """A no-break space, `≤`, `→`, a dash or a curly quote that looks like the ASCII the language needs (text
    copied from the paper, a web page or a word processor) was only "unexpected character"."""
    diagnostic, _ = diagnose(text)
    assert (diagnostic.code, diagnostic.message) == ("E0002", f"unexpected character `{char}`")
    assert any(h.startswith(hint) for h in diagnostic.hints), diagnostic.hints


IMPLY = "implication is written `imply`: `a imply b` (or `!a || b`)"


@pytest.mark.parametrize(("text", "found"), [
    ("automaton A { query Q: A[] Near => sa < 0 }", "="),
    ("automaton A { query Q: A[] Near ==> sa < 0 }", ">"),
    ("automaton A { query Q: A[] Near -> sa < 0 }", ">"),
    ("automaton A { assume collide -> isClose }", ">"),
    ("automaton A { edge L -> M when p => q }", "="),
])
def test_an_arrow_for_implication_gets_the_hint(text: str, found: str) -> None:
    """`=>`, `==>` and `->` between conditions (logic's arrows) were only "unexpected `=`" or "unexpected `>`"."""
    diagnostic, _ = diagnose(text)
    assert (diagnostic.code, diagnostic.message) == ("E0001", f"unexpected `{found}`")
    assert IMPLY in diagnostic.hints


@pytest.mark.parametrize("text", ["automaton A { edge L -> M when d - > 3 }", "automaton A { edge L -> M when d = 3 }",
                                  "automaton A { edge L -> M when d >> 3 }"])
def test_no_implication_hint_without_an_arrow(text: str) -> None:
    diagnostic, _ = diagnose(text)
    assert IMPLY not in diagnostic.hints


def test_a_non_ascii_letter_in_a_name_gets_the_hint() -> None:
    diagnostic, _ = diagnose("automaton Straße { }")
    assert (diagnostic.code, diagnostic.message) == ("E0002", "unexpected character `ß`")
    assert "names are ASCII identifiers: letters A-Z and a-z, digits and `_`" in diagnostic.hints


@pytest.mark.parametrize(("query", "hint"), [
    ("sup: sa", "rac has no `sup`, `inf` or `bounds` queries"),
    ("inf{Unsafe}: sa, pr", "rac has no `sup`, `inf` or `bounds` queries"),
    ("bounds: sa", "rac has no `sup`, `inf` or `bounds` queries"),
    ('saveStrategy("s.json", S)', "rac has no `saveStrategy` or `loadStrategy` queries"),
    ('strategy S = loadStrategy{p}->{d}("s.json")', "rac has no `saveStrategy` or `loadStrategy` queries"),
    ("strategy S = maxPr[<=3]{p}->{d}: <> p", "rac learns `minE` and `maxE` strategies only"),
    ("strategy S = control: A<> p", "a reachability objective is written `control: E<> p`"),
    ("E<> control: A[] p", "`control:` defines a strategy"),
    ("strategy S = {p} control: A[] p", "rac has no partially observed"),
    ("strategy S = control_t*(2, 1): A[] p", "rac has no time-optimal"),
    ("Pr[<=3](<> p) >= Pr[<=3](<> q)", "rac compares a probability with a constant only"),
    ("simulate 3 [<=3]{sa}", "a simulation is written `simulate[<=T; N]{e1, e2}`"),
    ("simulate[<=3; 3]{sa} : 2 : p", "rac keeps every simulated run"),
])
def test_an_uppaal_query_form_rac_lacks_gets_a_hint(query: str, hint: str) -> None:
    """UPPAAL accepts these queries; rac has no syntax for them, and the syntax error says what to write."""
    diagnostic, _ = diagnose(f"automaton A {{ query Q: {query}\n}}")
    assert diagnostic.code == "E0001"
    assert [h for h in diagnostic.hints if h.startswith(hint)], diagnostic.hints


@pytest.mark.parametrize("text", ["automaton A { query Q: E<> sup < 3 < 4\n}",
                                  "automaton A { query Q: A[] control < 1 < 2\n}",
                                  "automaton A { input sup : bool edge * -> L when sup : }"])
def test_a_name_that_is_an_uppaal_word_gets_no_query_hint(text: str) -> None:
    diagnostic, _ = diagnose(text)
    assert not [h for h in diagnostic.hints if h.startswith("rac has no") or "control:" in h], diagnostic.hints


@pytest.mark.parametrize(("text", "found", "keyword"), [
    ("automaton A { inital location L { } }", "inital", "initial"),
    ("automaton A { rewards r }", "rewards", "reward"),
    ("automaton A { Location L { } }", "Location", "location"),
    ("automaton A { egde * -> L when p }", "egde", "edge"),
    ("automaton A { edge * -> L wehn p }", "wehn", "when"),
    ("automaton A { sample evry 1 }", "evry", "every"),
    ("automaton A { objectve r }", "objectve", "objective"),
    ("automaton A { gaol when p }", "gaol", "goal"),
    ("automaton A { query Q: E<> L undr s\n}", "undr", "under"),
])
def test_a_misspelt_keyword_gets_the_word_meant(text: str, found: str, keyword: str) -> None:
    """A newcomer's most common slip: the message said only "unexpected `inital`" and listed what may
    follow, without saying which word was meant."""
    diagnostic, _ = diagnose(text)
    assert diagnostic.message == f"unexpected `{found}`"
    assert f"did you mean `{keyword}`?" in diagnostic.hints


@pytest.mark.parametrize("text", ["automaton A { var r }", "automaton A { at ned do r += 1 }",
                                  "automaton A { episode end when p }"])
def test_a_word_unlike_any_keyword_gets_no_guess(text: str) -> None:
    """No guess for a word far from every keyword, nor beside the hint showing a declaration's form."""
    diagnostic, _ = diagnose(text)
    assert not [h for h in diagnostic.hints if h.startswith("did you mean")], diagnostic.hints


_TIMED = ("automaton A {\n    input d : real in [0, 50]\n    reward r\n    objective r\n    sample every 0.1\n"
          "    horizon 30\n    initial location L { r' == 1 }\n    edge L -> L when d < 4 do r -= 1\n}\n")


@pytest.mark.parametrize(("slip", "found"), [("horizon 30", "horizon 30s"), ("sample every 0.1", "sample every 100ms"),
                                             ("in [0, 50]", "in [0, 50 m]")])
def test_a_unit_after_a_number_is_named(slip: str, found: str) -> None:
    # `horizon 30s` was "unexpected `s`, expected a declaration": the newcomer did not learn that numbers carry no unit
    diagnostic, _ = diagnose(_TIMED.replace(slip, found))
    assert diagnostic.code == "E0001"
    assert any(hint.startswith("numbers carry no unit: times are in seconds") for hint in diagnostic.hints)


@pytest.mark.parametrize("slip", ["edge L -> L do r -= 1 when d < 4", "at end do r += 5 when d < 4"])
def test_a_guard_after_the_updates_is_named(slip: str) -> None:
    diagnostic, _ = diagnose(_TIMED.replace("edge L -> L when d < 4 do r -= 1", slip))
    assert diagnostic.message == "unexpected `when`"
    assert any(hint.startswith("the guard comes before the updates") for hint in diagnostic.hints)


def test_no_unit_hint_for_a_name_on_the_next_line() -> None:
    diagnostic, _ = diagnose(_TIMED.replace("    horizon 30\n", "    horizon 30\n    s\n"))
    assert not any(hint.startswith("numbers carry no unit") for hint in diagnostic.hints)


@pytest.mark.parametrize(("old", "new", "hint"), [
    ("edge L -> L", "edge L => L", "an edge's arrow is `->`: `edge A -> B`"),
    ("when d < 4", "when d = 4", "equality is written `==`: `d == ...` (`=` assigns a reward after `do`)"),
    ("objective r", "objective 10r", "a product is written with `*`: `10 * r`")])
def test_a_first_files_slips_get_their_own_hint(old: str, new: str, hint: str) -> None:
    """`edge A => B` was told that implication is written `imply`; `when d = 4` and `objective 10r` got
    no hint at all."""
    diagnostic, _ = diagnose(_TIMED.replace(old, new))
    assert diagnostic.code == "E0001"
    assert hint in diagnostic.hints
    assert not any("imply" in h for h in diagnostic.hints)


def test_logics_arrow_in_a_query_still_says_imply() -> None:
    diagnostic, _ = diagnose(_TIMED.removesuffix("}\n") + "    query Q: A[] d > 1 => L\n}\n")
    assert "implication is written `imply`: `a imply b` (or `!a || b`)" in diagnostic.hints


@pytest.mark.parametrize(("declaration", "name", "value"), [
    ("input fast : bool = false", "fast", "false"),
    ("input d : real in [0, 10] = 5  // metres", "d", "5"),
    ("input a, b : bool = true", "a", "true"),
    ("input n : int in [0, 3]=2", "n", "2"),
])
def test_an_input_with_a_default_value_gets_the_hint(declaration: str, name: str, value: str) -> None:
    """language.md: inputs get their values from the environment or a binding at every sample, never a default."""
    diagnostic, _ = diagnose(f"automaton A {{\n  {declaration}\n  reward r\n}}\n")
    assert (diagnostic.code, diagnostic.message) == ("E0001", "unexpected `=`")
    assert (diagnostic.span.line, diagnostic.span.column) == (2, declaration.index("=") + 3)
    hint = next(h for h in diagnostic.hints if h.startswith("an input has no default value"))
    assert f"`bind {name} = EXPR`" in hint and f"`const {name} = {value}`" in hint


def test_no_input_default_hint_elsewhere() -> None:
    diagnostic, _ = diagnose("automaton A {\n  input fast : bool\n  reward r = 0\n}\n")
    assert not any("input has no default" in h for h in diagnostic.hints)


SLIPS = """automaton A {
    input p, q : bool
    const K = 5
    reward sa, pr
    priority sa > pr
    objective 10 * sa + pr
    sample every 0.1
    horizon 2
    initial location L { sa' == 1; pr' == 1 }
    location M { sa' == -1; pr' == 0 }
    edge * -> M when p do sa -= K
    edge M -> L when q && !p do sa = sa + 1, pr += 1
}
"""


@pytest.mark.parametrize(("slip", "written", "hint"), [
    # the product hint, `1 * pr`, was the only one: the flow after it lacked its `;`
    ("sa' == 1; pr' == 1 }", "sa' == 1 pr' == 1 }", "a location's flows are separated by `;`: "),
    ("sa' == -1; pr' == 0", "sa' == -1, pr' == 0", "a location's flows are separated by `;`, not `,`"),
    ("pr' == 1 }", "pr' == 1", "a `}` is missing before `location`: close the location's `{`"),
    ("    edge * -> M", "    }\n    edge * -> M", "the automaton was closed before this `edge`: a `}` above closes it"),
    ("10 * sa + pr", "10 * (sa + pr", "check that every `(` has a matching `)`"),
    ("edge * -> M", "edge * M", "an edge is written `edge FROM -> TO`, with `->`"),
    ("when p do sa -= K", "when p sa -= K", "updates follow `do`: `... do sa -= K`"),
    ("edge * -> M when p", "edge * -> M p", "a guard follows `when`: "),
    ("do sa = sa + 1", "do sa == sa + 1", "an update assigns with one `=`: `reward = expr`"),
    ("sa = sa + 1, pr += 1", "sa = sa + 1 pr += 1", "updates are separated by `,`: "),
    ("reward sa, pr", "reward sa pr", "names are separated by `,`: "),
    ("input p, q : bool", "input p, q bool", "a type follows `:`: `input NAME : bool`"),
    ("const K = 5", "const K 5", "a constant is written `const NAME = VALUE`"),
    ("priority sa > pr", "priority sa >= pr", "the priority order is written with `>` alone"),
    ("location M { sa' == -1; pr' == 0 }", "location M sa' == -1; pr' == 0", "a location's flows are written in "
                                                                              "braces"),
])
def test_a_missing_separator_or_keyword_gets_a_hint(slip: str, written: str, hint: str) -> None:
    """E0001 named the token the parser wanted (`expected `;` or `}``) and gave no hint, or a wrong one (a missing
    `;` between flows got "a product is written with `*`")."""
    assert slip in SLIPS
    lark_parser().parse(SLIPS, start=MODULE)  # the file parses as written
    diagnostic, _ = diagnose(SLIPS.replace(slip, written, 1))
    assert diagnostic.code == "E0001"
    assert any(h.startswith(hint) for h in diagnostic.hints), diagnostic.hints
    assert not any("a product is written" in h for h in diagnostic.hints), diagnostic.hints


def test_a_python_file_read_as_ra_source_says_to_import_it(tmp_path: Path) -> None:
    # a module written by `rac compile --target python`, given to rac.load or to the wrappers as a path, got the
    # language's hint for its first line ("comments start with `//`"), which said nothing of what the file is
    import rac
    from rac.targets.python import generate_python

    text = "automaton Lane { input off : bool\n reward r\n objective r\n sample every 1\n horizon 3\n" \
           " initial location L { r' == 1 } }\n"
    path = tmp_path / "lane_ra.py"
    path.write_text(generate_python(rac.loads(text).ir), encoding="utf-8")
    with pytest.raises(rac.CheckError) as caught:
        rac.load(path)
    [diagnostic] = caught.value.diagnostics
    assert diagnostic.code == "E0002" and diagnostic.hints == (
        "`lane_ra.py` is a Python file, not `.ra` source: rac check, rac.load and the wrappers read the `.ra` file; "
        "a module written by `rac compile --target python` is imported (`from lane_ra import Lane`), and an instance "
        "of its class goes to RewardAutomatonWrapper in place of the path",)
    diagnostic, _ = diagnose("import gymnasium\n", name="train.py")  # a script of one's own: its class unknown
    assert diagnostic.hints[0].startswith("`train.py` is a Python file") and "(`from train import its class`)" in \
        diagnostic.hints[0]
    diagnostic, _ = diagnose("# a comment\n", name="train.ra")  # a .ra file keeps the language's hint
    assert "Python" not in " ".join(diagnostic.hints)
