"""``rac tune``: the synthesised `param` values written back as constants, shown (``--print``) or
tabulated over horizons (``--horizon``), end to end through the ``rac`` entry point (issue 14)."""

from __future__ import annotations

import json
import re
from fractions import Fraction
from pathlib import Path

import pytest

from rac.check.analysis.synthesis import Synthesised
from rac.check.horizon import Fit, fit_line, formula_text
from rac.cli.main import main
from rac.cli.tune import tuned_text
from rac.compiler import compile_file, compile_text
from rac.core.source import SourceFile
from rac.lang.format import format_module
from rac.lang.parser import parse_source, parse_text
from rac.lang.resources import stdlib_dir

DRIVING = (stdlib_dir() / "driving.ra").read_text(encoding="utf-8")
CONST = "const PENALTY = 100"
PARAM = "param PENALTY in [0, 1000]"
assert CONST in DRIVING and "horizon 30" in DRIVING


def write(path: Path, text: str) -> Path:
    path.write_text(text, encoding="utf-8")
    return path


@pytest.fixture
def param_file(tmp_path: Path) -> Path:
    """stdlib/driving.ra with its penalty to be synthesised (as written, not in rac fmt's layout)."""
    return write(tmp_path / "driving_param.ra", DRIVING.replace(CONST, PARAM))


def at_horizon(text: str, horizon: str) -> str:
    return text.replace("horizon 30", f"horizon {horizon}")


def proved(capsys: pytest.CaptureFixture[str], path: Path) -> list[str]:
    """What ``rac check PATH`` prints as proved (it must pass)."""
    capsys.readouterr()
    assert main(["check", str(path)]) == 0, capsys.readouterr().out
    return [line.strip() for line in capsys.readouterr().out.splitlines() if line.strip().startswith("proved:")]


# ---------------------------------------------------------------- writing back
def test_write_back_replaces_only_the_param_line_and_proves_the_same(
        param_file: Path, capsys: pytest.CaptureFixture[str]) -> None:
    before = param_file.read_text(encoding="utf-8")
    proofs = proved(capsys, param_file)
    assert proofs[0].startswith("proved: synthesised: PENALTY >= 98")
    assert main(["tune", str(param_file)]) == 0
    out = capsys.readouterr().out
    assert f"wrote {param_file}:" in out and "+    const PENALTY = 98  // large enough" in out
    old, new = before.splitlines(), param_file.read_text(encoding="utf-8").splitlines()
    k = next(i for i, line in enumerate(old) if PARAM in line)
    # Every line but the declaration's is kept as it was, comments included.
    assert new[:k] == old[:k] and new[k + 2:] == old[k + 1:]
    assert new[k] == "    // rac tune: param PENALTY in [0, 1000]; every check holds for PENALTY >= 98"
    assert new[k + 1] == old[k].replace(PARAM, "const PENALTY = 98")
    # The tuned file proves what the parametrised one did, now of a constant.
    assert proved(capsys, param_file) == proofs[1:]


def test_a_file_in_fmt_layout_stays_in_it_with_its_comments(tmp_path: Path) -> None:
    # stdlib/driving.ra's declaration has a trailing comment continued on the line below, in its column
    layout = DRIVING.replace(CONST, PARAM).replace(" " * 25 + "// compensate", " " * 32 + "// compensate")
    path = write(tmp_path / "driving.ra", layout)
    assert format_module(parse_text(layout)) == layout
    assert main(["tune", str(path)]) == 0
    text = path.read_text(encoding="utf-8")
    assert format_module(parse_text(text)) == text  # `rac fmt --check` clean
    assert main(["fmt", "--check", str(path)]) == 0
    comments = [c.text for c in parse_text(text).comments]
    assert comments == [c.text for c in parse_text(DRIVING).comments][:6] + [
        "// rac tune: param PENALTY in [0, 1000]; every check holds for PENALTY >= 98",
        *[c.text for c in parse_text(DRIVING).comments][6:]]
    assert "    const PENALTY = 98  // large enough that progress and comfort can never\n" \
           "                        // compensate an unsafe moment within the horizon\n" in text


def test_crlf_line_ends_stay(tmp_path: Path) -> None:
    path = tmp_path / "crlf.ra"
    path.write_bytes(DRIVING.replace(CONST, PARAM).replace("\n", "\r\n").encode("utf-8"))
    assert main(["tune", str(path)]) == 0
    data = path.read_bytes()
    assert b"\r\n    const PENALTY = 98  // large enough" in data
    assert data.count(b"\n") == data.count(b"\r\n") == DRIVING.count("\n") + 1


def test_a_fraction_is_written_exactly_and_checks(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    text = DRIVING.replace(CONST, PARAM).replace("do sa = sa - PENALTY", "do sa = sa - 3 * PENALTY")
    path = write(tmp_path / "thirds.ra", text)
    proofs = proved(capsys, path)
    assert main(["tune", str(path)]) == 0
    tuned = path.read_text(encoding="utf-8")
    assert "    const PENALTY = 98 / 3  // large enough" in tuned
    assert proved(capsys, path) == proofs[1:]
    assert compile_file(path).automaton is not None


def test_a_symlinked_file_is_written_through_and_stays_a_link(param_file: Path) -> None:
    link = param_file.parent / "link.ra"
    link.symlink_to(param_file.name)
    assert main(["tune", str(link)]) == 0
    assert link.is_symlink()
    assert "const PENALTY = 98" in param_file.read_text(encoding="utf-8")


def test_print_writes_nothing(param_file: Path, capsys: pytest.CaptureFixture[str]) -> None:
    before = param_file.read_bytes()
    capsys.readouterr()
    assert main(["tune", "--print", str(param_file)]) == 0
    out = capsys.readouterr().out
    assert param_file.read_bytes() == before
    assert f"{param_file}: PENALTY = 98" in out
    assert "synthesised: PENALTY >= 98 (every check holds for PENALTY in [98, 1000])" in out
    assert "+    const PENALTY = 98  // large enough" in out and "would write" in out


def test_json_gives_the_values_the_set_and_where_it_wrote(param_file: Path,
                                                           capsys: pytest.CaptureFixture[str]) -> None:
    synthesis = compile_file(param_file).synthesis
    assert synthesis is not None
    capsys.readouterr()
    assert main(["tune", "--print", "--format", "json", str(param_file)]) == 0
    report = json.loads(capsys.readouterr().out)
    assert report["values"] == [{"name": "PENALTY", "exact": "98", "float": 98.0}]
    assert report["inequalities"] == list(synthesis.inequalities) == ["PENALTY >= 98"]
    assert report["sentence"] == synthesis.sentence and report["written"] is None
    assert main(["tune", "--format", "json", str(param_file)]) == 0
    assert json.loads(capsys.readouterr().out)["written"] == str(param_file)


# ---------------------------------------------------------------- refusals
@pytest.mark.parametrize(("code", "change"), [
    ("E0406", ("horizon 30", "horizon 300")),  # the int32 range of `sa` leaves no value
    ("E0407", ("dgoal < 2", "dgoal < PENALTY")),  # in a guard: synthesis would not be exact
])
def test_a_failing_synthesis_leaves_the_file_untouched(tmp_path: Path, capsys: pytest.CaptureFixture[str],
                                                       code: str, change: tuple[str, str]) -> None:
    path = write(tmp_path / "failing.ra", DRIVING.replace(CONST, PARAM).replace(*change))
    before = path.read_bytes()
    capsys.readouterr()
    assert main(["tune", str(path)]) == 1
    out = capsys.readouterr().out
    assert f"error[{code}]: " in out and "nothing was tuned or written" in out
    assert path.read_bytes() == before
    assert main(["tune", "--format", "json", str(path)]) == 1
    report = json.loads(capsys.readouterr().out)
    assert not report["ok"] and code in [d["code"] for d in report["diagnostics"]]
    assert path.read_bytes() == before


TINY = """automaton Small {
    input bad : bool
    param P in [0, 1]
    reward sa, pr
    priority sa > pr
    objective 10 * sa + pr
    sample every 1
    horizon 5
    initial location Ok { sa' == 1; pr' == 1 }
    location Bad { sa' == 0; pr' == 1 }
    edge * -> Bad when bad do sa = sa - (1 + P * 6e307)
    edge * -> Ok when !bad
}
"""


@pytest.mark.parametrize("show", [[], ["--print"]])
def test_a_value_no_ra_number_holds_is_not_written_and_says_so(tmp_path: Path, capsys: pytest.CaptureFixture[str],
                                                                show: list[str]) -> None:
    # `sa -= 1 + P * 6e307` checks with P in [0, 1] and synthesises P = 3 / 4e307 = 7.5e-308, below what a `.ra`
    # number holds: the tuned text (`const P = 3 / 4000...0`, 308 digits) did not parse, and rac tune ended with an
    # internal error (exit 3). It is E0015 at the declaration, with the value, why, the synthesis and what to do.
    path = write(tmp_path / "tiny.ra", TINY)
    assert compile_file(path).ok
    capsys.readouterr()
    assert main(["tune", *show, str(path)]) == 1
    out = capsys.readouterr().out
    assert ("tiny.ra:3:5: error[E0015]: cannot write `P` back as a constant: its synthesised value, 7.5e-308, is "
            "below 1e-307 in size, the smallest number other than 0 that a `.ra` file (and a double) holds; nothing "
            "was written") in out, out
    assert "= note: synthesised: 7.5e-308 <= P" in out and "`P * 1e-300` where it is used" in out
    assert path.read_text(encoding="utf-8") == TINY
    assert main(["tune", *show, "--format", "json", str(path)]) == 1
    report = json.loads(capsys.readouterr().out)
    assert not report["ok"] and [d["code"] for d in report["diagnostics"]] == ["E0015"]
    assert path.read_text(encoding="utf-8") == TINY


def test_a_file_without_param_is_a_usage_error(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = write(tmp_path / "driving.ra", DRIVING)
    capsys.readouterr()
    assert main(["tune", str(path)]) == 2
    err = capsys.readouterr().err
    assert "declares no `param`" in err and "param PENALTY in [0, 1000]" in err
    assert path.read_text(encoding="utf-8") == DRIVING


@pytest.mark.parametrize("horizon", [[], ["--horizon", "10,30"]])
def test_a_param_in_a_second_automaton_is_e0107(tmp_path: Path, capsys: pytest.CaptureFixture[str],
                                                horizon: list[str]) -> None:
    """The second automaton is the file's error (E0107, as `rac check` reports it), not a missing `param`."""
    second = DRIVING.replace("automaton Driving", "automaton Second").replace(CONST, PARAM)
    path = write(tmp_path / "two.ra", DRIVING + "\n" + second)
    line = (DRIVING + "\n").count("\n") + second[:second.index("automaton Second")].count("\n") + 1
    capsys.readouterr()
    assert main(["tune", *horizon, str(path)]) == 1
    out = capsys.readouterr().out
    assert f"two.ra:{line}:11: error[E0107]: a file holds one automaton; this is a second one" in out
    assert "^^^^^^" in out and "= hint: move it to a file of its own" in out and "declares no `param`" not in out
    assert path.read_text(encoding="utf-8") == DRIVING + "\n" + second


@pytest.mark.parametrize(("option", "message"), [
    ("--horizon=10,25.05", "25.05 s is not a whole number of sample periods"),
    ("--horizon=-30", "the horizon `-30` must be more than 0 s"),
    ("--horizon=0", "the horizon `0` must be more than 0 s"),
    ("--horizon=10,abc", "`abc` is not a horizon"),
    ("--horizon=30,,60", "`` is not a horizon"),
    ("--horizon=30,60,30.0", "the horizon `30.0` is given twice"),  # it was synthesised twice, two equal rows
])
def test_bad_horizons_are_usage_errors_naming_them(param_file: Path, capsys: pytest.CaptureFixture[str],
                                                   option: str, message: str) -> None:
    capsys.readouterr()
    assert main(["tune", option, str(param_file)]) == 2
    assert message in capsys.readouterr().err


# ---------------------------------------------------------------- the horizon table
def test_the_horizon_table_and_its_formula(param_file: Path, tmp_path: Path,
                                           capsys: pytest.CaptureFixture[str]) -> None:
    before = param_file.read_bytes()
    capsys.readouterr()
    assert main(["tune", "--horizon", "10,30,60,120,300", str(param_file)]) == 0
    out = capsys.readouterr().out
    assert param_file.read_bytes() == before  # --horizon implies --print
    rows = {cells[0]: cells[1:] for line in out.splitlines() if line.startswith("| ")
            for cells in [[c.strip() for c in line.strip("|").split("|")]]}
    values = {h: rows[h][0] for h in ("10", "30", "60", "120")}
    assert values == {"10": "66", "30": "98", "60": "146", "120": "242"}
    # each equals what `rac check` synthesises at that horizon
    for horizon, value in values.items():
        separate = write(tmp_path / f"at_{horizon}.ra", at_horizon(param_file.read_text(encoding="utf-8"), horizon))
        assert f"checked with PENALTY = {value}" in proved(capsys, separate)[0]
    assert rows["300"][0] == "none" and rows["300"][1].startswith("E0406")
    assert ("PENALTY >= 1.6 * H + 50 (H the horizon in seconds): checked against 4 horizons (10, 30, 60, 120)"
            in out.splitlines())


def test_the_horizon_table_as_json(param_file: Path, capsys: pytest.CaptureFixture[str]) -> None:
    capsys.readouterr()
    assert main(["tune", "--horizon", "10,30,60,300", "--format", "json", str(param_file)]) == 0
    report = json.loads(capsys.readouterr().out)
    rows = {row["horizon"]: row for row in report["horizons"]}
    assert [rows[h]["values"][0]["exact"] for h in ("10", "30", "60")] == ["66", "98", "146"]
    assert rows["300"]["values"] is None and rows["300"]["error"]["codes"][0] == "E0406"
    (formula,) = report["formulas"]
    assert formula["formula"] == "PENALTY >= 1.6 * H + 50" and formula["checked"] == 3
    assert Fraction(formula["slope"]["exact"]) == Fraction(8, 5) and report["written"] is None


def test_horizon_tabulates_a_file_that_declares_no_horizon(tmp_path: Path,
                                                          capsys: pytest.CaptureFixture[str]) -> None:
    """--horizon gives the horizon: a file without a `horizon` line is tabulated (the line written after
    `sample every` in each row's text), not refused with E0105; the file itself is left as it was."""
    text = re.sub(r"\n *horizon 30[^\n]*", "", DRIVING.replace(CONST, PARAM))
    assert "horizon" not in re.sub(r"//[^\n]*", "", text)
    path = write(tmp_path / "no_horizon.ra", text)
    capsys.readouterr()
    assert main(["tune", "--horizon", "10,30,60", str(path)]) == 0
    out = capsys.readouterr().out
    assert "| 30 | 98 | PENALTY >= 98 |" in out and "PENALTY >= 1.6 * H + 50" in out
    assert path.read_text(encoding="utf-8") == text
    assert main(["tune", "--horizon", "10,25.05", str(path)]) == 2  # the period is still read
    assert "25.05 s is not a whole number of sample periods" in capsys.readouterr().err


def test_two_horizons_give_no_formula(param_file: Path, capsys: pytest.CaptureFixture[str]) -> None:
    capsys.readouterr()
    assert main(["tune", "--horizon", "10,30", str(param_file)]) == 0
    out = capsys.readouterr().out
    assert "a line through 2 points proves nothing" in out and ">= 1.6" not in out


def test_three_weights_are_written_back_and_prove_the_same(tmp_path: Path,
                                                            capsys: pytest.CaptureFixture[str]) -> None:
    text = DRIVING.replace(CONST, CONST + "\n    param w1, w2, w3 in [1, 100]").replace(
        "objective 10 * sa + 5 * pr + co", "objective w1 * sa + w2 * pr + w3 * co")
    path = write(tmp_path / "weights.ra", text)
    proofs = proved(capsys, path)
    assert proofs[0].startswith("proved: synthesised: every check holds exactly where 7 * w1 >= 13 * w2 + 3 * w3")
    assert main(["tune", str(path)]) == 0
    lines = path.read_text(encoding="utf-8").splitlines()
    k = lines.index("    // rac tune: param w1, w2, w3 in [1, 100]; every check holds for 7 * w1 >= 13 * w2 + 3 * w3")
    # (the declaration's trailing comment, here the penalty's, stays on its last line)
    assert lines[k + 1:k + 3] == ["    const w1 = 3", "    const w2 = 1"]
    assert lines[k + 3].startswith("    const w3 = 1  // large enough")
    # Everything the synthesis proved of the set is gone with the parameters; the rest is the same.
    assert proved(capsys, path) == proofs[2:]


def test_no_horizon_with_a_value_exits_1(param_file: Path, capsys: pytest.CaptureFixture[str]) -> None:
    capsys.readouterr()
    assert main(["tune", "--horizon", "300,600,900", str(param_file)]) == 1
    out = capsys.readouterr().out
    assert out.count("| none |") == 3 and "PENALTY: no horizon has a value (no formula)" in out


def test_a_row_that_cannot_be_synthesised_says_which_parameter_and_why(tmp_path: Path,
                                                                       capsys: pytest.CaptureFixture[str]) -> None:
    """Each row's reason is the error's message up to its details: for E0407 that was `not yet`, which
    named neither the parameter nor what stops its synthesis."""
    text = DRIVING.replace(CONST, PARAM + "\n    param BONUS in [0, 10]")
    path = write(tmp_path / "two_params.ra", text)
    capsys.readouterr()
    assert main(["tune", "--horizon", "10,30", str(path)]) == 1
    rows = [line for line in capsys.readouterr().out.splitlines() if line.startswith("| 10 ")]
    assert rows == ["| 10 | none | none | E0407: not yet: parameter `PENALTY` cannot be synthesised here |"]


# ---------------------------------------------------------------- the pieces
def test_several_names_become_one_const_line_each() -> None:
    text = DRIVING.replace(CONST, "param PENALTY, BONUS in [0, 1000]").replace("pr = pr + 100", "pr = pr + BONUS")
    source = SourceFile("two.ra", text)
    synthesis = Synthesised((("PENALTY", Fraction(98)), ("BONUS", Fraction(7, 2))), ("PENALTY >= 98",), "")
    lines = tuned_text(source, parse_source(source), synthesis).splitlines()
    k = lines.index("    // rac tune: param PENALTY, BONUS in [0, 1000]; every check holds for PENALTY >= 98")
    assert lines[k + 1] == "    const PENALTY = 98"
    assert lines[k + 2] == "    const BONUS = 7 / 2  // large enough that progress and comfort can never"
    assert lines[k + 3] == " " * 25 + "// compensate an unsafe moment within the horizon"
    assert compile_text("\n".join(lines), "two.ra").ok


def test_the_fit_is_exact_and_says_when_it_is_not_a_line() -> None:
    h = [Fraction(x) for x in (10, 20, 30)]
    line = fit_line([(h[0], Fraction(1, 3)), (h[1], Fraction(2, 3)), (h[2], Fraction(1))])
    assert line.linear and (line.slope, line.intercept) == (Fraction(1, 30), 0)
    assert formula_text(line) == "1/30 * H"
    bent = fit_line([(h[0], Fraction(1)), (h[1], Fraction(2)), (h[2], Fraction(4))])
    assert not bent.linear and bent.off == (h[2], Fraction(4), Fraction(3))
    assert not fit_line([(h[0], Fraction(1)), (h[1], Fraction(2))]).linear
    assert formula_text(Fit((), Fraction(-1), Fraction(-5, 2))) == "-H - 2.5"
    assert formula_text(Fit((), Fraction(0), Fraction(7))) == "7"
    assert re.fullmatch(r"2 \* H \+ 1", formula_text(Fit((), Fraction(2), Fraction(1))))


def test_the_tuned_value_passes_e0801(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """With weight 9 on `sa` the least penalty is 950/9, and `sa -= 950/9` is `(9*sa - 9500000) / 9` in the
    UPPAAL model's 32-bit significands, which leaves int32 (E0801): `rac check` failed at the value it chose
    and `rac tune` wrote nothing, though every significand above it passes. The value is now the least
    whole number of significands above it (1/10000), and the tuned file passes `rac check` and compiles."""
    text = DRIVING.replace(CONST, PARAM).replace("objective 10 * sa", "objective 9 * sa")
    path = write(tmp_path / "weight9.ra", text)
    assert main(["tune", "--format", "json", str(path)]) == 0
    document = json.loads(capsys.readouterr().out)
    assert [v["exact"] for v in document["values"]] == ["263889/2500"]  # 105.5556, the next significand
    assert Fraction(263889, 2500) - Fraction(950, 9) < Fraction(1, 10_000)
    assert "the least value the significands hold exactly" in document["sentence"]
    assert "const PENALTY = 263889 / 2500" in path.read_text(encoding="utf-8")
    assert main(["check", str(path)]) == 0
    assert main(["compile", "--target", "uppaal", str(path), "-o", str(tmp_path / "weight9.xml")]) == 0


@pytest.mark.parametrize("form", ["text", "json"])
def test_horizons_interrupted_keep_the_rows_synthesised(param_file: Path, capsys: pytest.CaptureFixture[str],
                                                        monkeypatch: pytest.MonkeyPatch, form: str) -> None:
    """Ctrl-C (or SIGTERM) at the third horizon: under --format json the document was main's bare
    `{"interrupted": true}`, the two horizons synthesised before it (minutes, at long horizons) dropped."""
    from rac.cli import tune

    real, calls = tune._synthesised, []

    def stopped_at_the_third(*args: object, **kwargs: object) -> object:
        calls.append(1)
        if len(calls) == 3:
            raise KeyboardInterrupt
        return real(*args, **kwargs)

    monkeypatch.setattr(tune, "_synthesised", stopped_at_the_third)
    code = main(["tune", "--horizon", "10,30,60", "--format", form, str(param_file)])
    out, err = capsys.readouterr()
    assert code == 130
    where = "above" if form == "text" else "in the JSON document"
    assert f"rac tune: interrupted; 2 horizons synthesised before it ({where}; no formula)" in err
    if form == "json":
        document = json.loads(out)
        assert [row["horizon"] for row in document["horizons"]] == ["10", "30"]
        assert document["interrupted"] is True and document["ok"] is False and document["formulas"] == []
    else:
        assert "| 10 | 66 |" in out and "| 30 | 98 |" in out and "(H the horizon in seconds)" not in out
