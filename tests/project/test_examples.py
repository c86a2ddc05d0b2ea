"""The examples do what they say, and the shipped `.ra` text is in `rac fmt`'s layout.

- examples/train_wrapper.py trains and prints a summary, deterministically for a seed;
- examples/generated_module.py compiles the Python target and agrees with the interpreter;
- examples/naive_driving.ra fails P2 (E0402) with the counterexample the docs describe;
- every shipped `.ra` file (stdlib/, examples/, benchmarks/) and every ```ra block of docs/*.md and
  README.md that is a complete automaton and parses is in `rac fmt`'s canonical layout.

Every block of the docs runs, or is compared with what rac prints: tests/project/test_doc_blocks.py (which
reads the blocks with :func:`code_blocks`).
"""

from __future__ import annotations

import json
import os
import re
import subprocess
import sys
from dataclasses import dataclass
from pathlib import Path

import pytest

import rac
from rac.cli.main import main as rac_main
from rac.compiler import compile_file, compile_text
from rac.lang.parser import ParseFailure, parse_text

REPO = Path(__file__).resolve().parents[2]
DOC_FILES = sorted((REPO / "docs").glob("*.md")) + [REPO / "README.md"]


def run_python(*args: str, timeout: float = 120) -> subprocess.CompletedProcess[str]:
    """``python ARGS`` from the repository root, importing the same rac as this test process."""
    rac_parent = str(Path(rac.__file__).resolve().parent.parent)
    paths = [rac_parent, *filter(None, os.environ.get("PYTHONPATH", "").split(os.pathsep))]
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(paths), "PYTHONIOENCODING": "utf-8"}
    return subprocess.run([sys.executable, *args], cwd=REPO, env=env, capture_output=True, text=True,
                          timeout=timeout)


# ---------------------------------------------------------------- markdown code blocks
@dataclass(frozen=True)
class Block:
    path: Path
    line: int  # 1-based line of the opening fence
    language: str
    text: str
    #: The code of an ``<!-- expect: CODE -->`` comment just before the fence, or of the
    #: ``<!-- case: CODE_name -->`` region the block is in.
    expect: str | None

    @property
    def id(self) -> str:
        return f"{self.path.relative_to(REPO)}:{self.line}"


_FENCE = re.compile(r"^(\s*)```(\w*)\s*$")
_EXPECT = re.compile(r"^<!--\s*expect:\s*([EW]\d{4})\s*-->$")
#: docs/checks.md marks each diagnostic example as ``<!-- case: E0402_name -->`` ... ``<!-- end case -->``.
_CASE = re.compile(r"^<!--\s*case:\s*(([EW]\d{4})_\w+)\s*-->$")
_END_CASE = re.compile(r"^<!--\s*end case\s*-->$")


def code_blocks(path: Path) -> list[Block]:
    blocks: list[Block] = []
    lines = path.read_text(encoding="utf-8").splitlines()
    i = 0
    while i < len(lines):
        match = _FENCE.match(lines[i])
        if not match:  # an opening fence without a language is a block too (language ""): checked like any
            i += 1
            continue
        start, indent, language = i, len(match.group(1)), match.group(2)
        j = i + 1
        while j < len(lines) and lines[j].strip() != "```":
            j += 1
        expect = None
        k = start - 1
        while k >= 0 and not lines[k].strip():
            k -= 1
        if k >= 0 and (found := _EXPECT.match(lines[k].strip())):
            expect = found.group(1)
        for previous in reversed(lines[:start]):  # inside a `case` region?
            if _END_CASE.match(previous.strip()):
                break
            if found := _CASE.match(previous.strip()):
                expect = found.group(2)
                break
        body = lines[start + 1:j]
        text = "\n".join(line[indent:] if line[:indent].strip() == "" else line.lstrip() for line in body)
        blocks.append(Block(path, start + 1, language, text + "\n", expect))
        i = j + 1
    return blocks


def _strip_comments(text: str) -> str:
    return re.sub(r"//[^\n]*", "", re.sub(r"/\*.*?\*/", "", text, flags=re.S))


def is_complete_automaton(block: Block) -> bool:
    """A ```ra block whose first code (after comments) is ``automaton``."""
    return block.language == "ra" and _strip_comments(block.text).lstrip().startswith("automaton")


RA_BLOCKS = [b for path in DOC_FILES for b in code_blocks(path) if is_complete_automaton(b)]


def test_the_docs_have_blocks_to_check() -> None:
    assert len([b for b in RA_BLOCKS if b.path.name == "language.md"]) >= 3
    assert any(b.expect == "E0402" for b in RA_BLOCKS)


# ---------------------------------------------------------------- rac fmt --check
#: Every `.ra` file the project ships (globbed, so new files are covered).
SHIPPED_RA = sorted([*REPO.glob("stdlib/**/*.ra"), *REPO.glob("examples/**/*.ra"), *REPO.glob("benchmarks/**/*.ra")])


def test_the_shipped_files_are_found() -> None:
    names = {p.name for p in SHIPPED_RA}
    assert {"driving.ra", "model.ra", "preanalysis.ra", "naive_driving.ra", "zam_ramp.ra"} <= names


@pytest.mark.parametrize("path", SHIPPED_RA, ids=lambda p: str(p.relative_to(REPO)))
def test_shipped_file_is_formatted(path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    status = rac_main(["fmt", "--check", str(path)])
    assert status == 0, f"`rac fmt --check {path.relative_to(REPO)}` fails:\n{capsys.readouterr().err}"


def _parses(block: Block) -> bool:
    try:
        parse_text(block.text, block.id)
    except ParseFailure:
        return False
    return True


#: The blocks `rac fmt` can read: the others show a syntax error (checked below), and fmt refuses them.
PARSED_BLOCKS = [b for b in RA_BLOCKS if _parses(b)]


def test_a_block_that_does_not_parse_shows_its_error() -> None:
    unparsed = [b for b in RA_BLOCKS if b not in PARSED_BLOCKS]
    assert unparsed, "the docs show no syntax error (checks.md's E0001-E0003 examples did)"
    assert all(b.expect is not None and b.expect < "E0100" for b in unparsed), [b.id for b in unparsed]


@pytest.mark.parametrize("block", PARSED_BLOCKS, ids=lambda b: b.id)
def test_ra_block_is_formatted(block: Block, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    source = tmp_path / "block.ra"
    source.write_text(block.text, encoding="utf-8")
    status = rac_main(["fmt", "--check", str(source)])
    assert status == 0, f"{block.id} is not in `rac fmt`'s layout:\n{capsys.readouterr().err}"


# ---------------------------------------------------------------- examples/naive_driving.ra
def test_naive_driving_fails_p2_with_a_counterexample() -> None:
    result = run_python("-m", "rac", "check", "examples/naive_driving.ra")
    assert result.returncode == 1, result.stdout + result.stderr
    out = result.stdout
    assert "error[E0402]: P2 no compensation fails" in out
    assert "counterexample" in out
    assert "stays in `Normal`, 299 samples" in out
    assert "`Normal` -> `Unsafe`" in out
    assert "sa = -60, pr = 130, co = 30; the objective = 80 > 0" in out


def test_naive_driving_counterexample_as_json(capsys: pytest.CaptureFixture[str]) -> None:
    assert rac_main(["check", "--format", "json", str(REPO / "examples" / "naive_driving.ra")]) == 1
    (report,) = json.loads(capsys.readouterr().out)
    (diagnostic,) = report["diagnostics"]
    assert diagnostic["code"] == "E0402"
    assert diagnostic["data"]["value"] == "80"
    run = diagnostic["data"]["run"]
    assert run[-1]["last_sample"] == 300 and run[-1]["to"] == "Unsafe"


# ---------------------------------------------------------------- examples/*.py
def test_train_wrapper_runs_and_summarises(tmp_path: Path) -> None:
    args = ("examples/train_wrapper.py", "--episodes", "60", "--report-every", "20", "--evaluate", "10",
            "--seed", "1", "--plot", str(tmp_path / "curve.png"))
    first = run_python(*args)
    assert first.returncode == 0, first.stdout + first.stderr
    lines = first.stdout.splitlines()
    assert sum(line.startswith("episodes ") for line in lines) == 3
    summary = [line for line in lines if line.startswith("summary:")]
    assert len(summary) == 1 and "mean return" in summary[0] and "goal reached" in summary[0]
    assert (tmp_path / "curve.png").exists() or "skipping the plot" in first.stdout

    second = run_python(*args)  # the same seed gives the same numbers

    def numbers(text: str) -> list[str]:
        return [line for line in text.splitlines() if not line.startswith(("done in", "wrote "))]

    assert numbers(second.stdout) == numbers(first.stdout)


def test_generated_module_agrees_with_the_interpreter(tmp_path: Path) -> None:
    result = run_python("examples/generated_module.py", "-o", str(tmp_path / "driving_ra.py"))
    assert result.returncode == 0, result.stdout + result.stderr
    assert "agree on all 300 samples" in result.stdout
    assert "it imports __future__, collections, math" in result.stdout
    assert (tmp_path / "driving_ra.py").exists()


def test_the_naive_weighted_reward_pays_for_ending_early_and_its_fix_does_not() -> None:
    # examples/weighted: a time penalty of 1 a sample and a collision that ends the episode: crashing
    # at the first sample returns -11 against -300 for the best safe run of the horizon (W1002, 289);
    # fixed.ra makes that crash cost 300 more and requires the check.
    naive = compile_file(REPO / "examples" / "weighted" / "naive.ra")
    warnings = [d for d in naive.diagnostics if d.code == "W1002"]
    assert naive.ok and len(warnings) == 1
    assert "earns 289 more than the best safe continuation" in warnings[0].message
    fixed = compile_file(REPO / "examples" / "weighted" / "fixed.ra")
    # its highway records 12 s of traffic under the 30 s horizon: W0728 says so, and nothing else is said
    assert fixed.ok and [d.code for d in fixed.diagnostics] == ["W0728"]
    assert [f.check for f in fixed.facts if f.check == "ending_early_never_pays"] == ["ending_early_never_pays"]
    # one penalty short of the hint, the requirement turns the loophole into an error
    text = (REPO / "examples" / "weighted" / "fixed.ra").read_text(encoding="utf-8")
    short = compile_text(text.replace("const COLLISION = 300", "const COLLISION = 288"), "short.ra")
    assert [d.code for d in short.diagnostics if d.is_error] == ["E1003"]


@pytest.mark.parametrize("samples", ["2", "5"])
def test_the_left_turn_model_holds_for_a_discounting_learner(samples: str, capsys: pytest.CaptureFixture[str]) -> None:
    """examples/left_turn/model.ra is what docs/python.md trains on: at its former 30 s horizon P2 failed
    for gamma = 0.99 (the discounted objective reached 85.9 while unsafe, so RacCallback warned), and the
    horizon ran 20 s past the scenario's 10 s of traffic and goal window (W0728). At 10 s it checks clean
    and holds discounted, per step of a decision (2 samples) or of 5."""
    path = str(REPO / "examples" / "left_turn" / "model.ra")
    assert rac_main(["check", path]) == 0
    out = capsys.readouterr()
    assert f"{path}: ok\n" in out.out and "warning[" not in out.out + out.err, out.out + out.err
    assert rac_main(["check", "--discount", "0.99", "--samples-per-step", samples, path]) == 0
    out = capsys.readouterr()
    assert "proved: P2 holds for `sa` under the discount (gamma = 0.99" in out.out, out.out + out.err
